"""The ``Examples`` of every public function of ``obsplan`` (``obsplan.__all__``) run as doctests.

Each public function documents its use with a numpydoc ``Examples`` section; running them keeps
the examples true (an example whose output changed fails here).
"""

from __future__ import annotations

import doctest
import inspect
import tempfile

import pytest

import obsplan

FUNCTIONS = [name for name in obsplan.__all__ if inspect.isfunction(getattr(obsplan, name, None))]


def test_the_public_functions_are_found():
    assert {"analyze", "monte_carlo", "plan", "sweep", "read_csv"} <= set(FUNCTIONS)


@pytest.mark.slow
@pytest.mark.parametrize("name", FUNCTIONS)
def test_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that write files use temporary folders anyway
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # the system temp folder, for this process and its children (a sweep's Dask workers): an
    # example must leave nothing there
    system_tmp = tmp_path / "system-tmp"
    system_tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(system_tmp))
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    func = getattr(obsplan, name)
    doc = inspect.getdoc(func) or ""
    assert "\nExamples\n--------\n" in doc, f"obsplan.{name} has no numpydoc Examples section"
    tests = doctest.DocTestFinder(recurse=False).find(func, f"obsplan.{name}", globs={})
    assert tests and tests[0].examples, f"obsplan.{name}: its Examples hold no >>> example"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    out: list[str] = []
    for t in tests:
        runner.run(t, out=out.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, "".join(out)
    left = sorted(p.name for p in system_tmp.iterdir())
    assert not left, f"obsplan.{name}'s example left {left} in the temp folder"
