"""The notebooks: committed without outputs, and executed top to bottom in quick mode.

Each notebook is run by nbclient in a ``python3`` kernel (the venv's ipykernel) with
``OBSPLAN_QUICK=1`` (reduced horizons, sweeps, Monte Carlo runs and planner sizes) and
``MPLBACKEND=Agg``; a cell that raises fails the test with its traceback. Every notebook must
render at least one figure. Budget: the three notebooks together in under 3 minutes.
"""

from __future__ import annotations

import time
from pathlib import Path

import nbformat
import pytest

#: end-to-end: the slow tier (docs/development.md)
pytestmark = pytest.mark.slow


NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = ("excitation_requirements", "paper_tour", "planning_tour")
#: Seconds a single cell may take in quick mode before the run is abandoned.
CELL_TIMEOUT_S = 300


def _read(name: str) -> nbformat.NotebookNode:
    return nbformat.read(NOTEBOOK_DIR / f"{name}.ipynb", as_version=4)


def test_every_notebook_is_listed():
    found = sorted(p.stem for p in NOTEBOOK_DIR.glob("*.ipynb"))
    assert found == sorted(NOTEBOOKS)


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_is_valid_and_stripped(name):
    nb = _read(name)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, f"{name} has no code cells"
    for i, cell in enumerate(code):
        assert cell.get("outputs") == [], f"{name}: code cell {i} has committed outputs"
        assert cell.get("execution_count") is None, f"{name}: code cell {i} has an execution count"
    assert nb.metadata["kernelspec"]["name"] == "python3"
    # every notebook honours the quick switch
    assert any("OBSPLAN_QUICK" in c.source for c in code), f"{name} ignores OBSPLAN_QUICK"


@pytest.mark.slow
@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_executes_quick(name, monkeypatch, tmp_path):
    from nbclient import NotebookClient

    monkeypatch.setenv("OBSPLAN_QUICK", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # keep matplotlib/IPython caches out of the user's home
    monkeypatch.setenv("MPLCONFIGDIR", str(tmp_path / "mpl"))
    # the kernel's system temp folder (and its Dask workers'): a notebook must leave nothing there
    system_tmp = tmp_path / "system-tmp"
    system_tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(system_tmp))
    nb = _read(name)
    client = NotebookClient(
        nb,
        timeout=CELL_TIMEOUT_S,
        kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOK_DIR)}},
    )
    t0 = time.perf_counter()
    client.execute()  # raises CellExecutionError (with the traceback) on any error; the
    # kernel has stopped when it returns
    wall = time.perf_counter() - t0
    left = sorted(p.name for p in system_tmp.iterdir())
    assert not left, f"{name} left {left} in the temp folder"
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert images, f"{name} rendered no figure"
    streams = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "quick mode: True" in streams, f"{name} did not run in quick mode"
    print(f"{name}: {wall:.1f} s, {len(images)} figures")
