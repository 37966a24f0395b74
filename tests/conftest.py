"""Fixtures shared by the planner's tests, and the order the test processes take the files in."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from xdist.scheduler import LoadScopeScheduling

from obsplan.estimation import jitcache
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.sections import Horizon


@pytest.fixture(scope="session")
def short_problem():
    """The free-localisation problem on a 120 s horizon of 40 steps."""
    pb = load_problem(LOCALISE_PROBLEM)
    return replace(pb, horizon=Horizon(duration=120.0, steps=40))


@pytest.fixture(scope="session")
def lawnmower(short_problem):
    """The lawn-mower baseline of :func:`short_problem`."""
    return baselines(short_problem)["lawnmower"].trajectory


_PAGE = "tests/test_readme.py::test_every_block_of_a_docs_page_runs_in_order_from_a_fresh_folder"
#: Work units of the longest run time, longest first (``pytest --durations=0`` on 2 cores; a
#: unit is a test file, or one page of the documentation in test_readme.py). The test processes
#: take units in this order, then the others in collection order: long ones started last would
#: leave one process running alone at the end. The order only balances the processes: a unit
#: missing here still runs.
LONGEST_FIRST = (
    "tests/test_sweep_dask.py",
    "tests/test_output_safety.py",
    f"{_PAGE}[guides/sweeps.md]",
    "tests/test_package_data.py",
    "tests/test_signals.py",
    "tests/test_pool_signals.py",
    "tests/test_planning.py",
    "tests/test_guards.py",
    "tests/test_filters.py",
    "tests/test_notebooks.py",
    f"{_PAGE}[guides/moving-beacon.md]",
    "tests/test_readme.py::test_every_readme_block_runs_in_order_from_a_fresh_folder",
    "tests/test_cli_plan.py",
    "tests/test_margins.py",
    "tests/test_missions.py",
    f"{_PAGE}[guides/real-inputs.md]",
    f"{_PAGE}[guides/command-line.md]",
)


def work_unit(nodeid: str) -> str:
    """The unit one test process runs ``nodeid`` in: its file, so that a file's module fixtures
    (a plan, a validation) are computed once; test_readme.py's tests one by one (they share
    nothing, and together they are the longest file)."""
    file = nodeid.split("::", 1)[0]
    return nodeid if file.endswith("test_readme.py") else file


class FileScheduling(LoadScopeScheduling):
    """pytest-xdist's ``--dist loadfile``, with :func:`work_unit` as the unit."""

    def _split_scope(self, nodeid: str) -> str:
        return work_unit(nodeid)


def pytest_xdist_make_scheduler(config: pytest.Config, log) -> FileScheduling | None:
    return FileScheduling(config, log) if config.getoption("dist") == "loadfile" else None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {unit: i for i, unit in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(work_unit(item.nodeid), len(rank)))  # stable


#: A closed-loop plan's Monte Carlo compiles every numba kernel, once each
#: (tests/test_kernel_signatures.py).
_COMPILE = (
    "import obsplan; pb = obsplan.load_problem('localise').with_changes("
    "horizon={'steps': 20}, objective={'starts': 1}); "
    "obsplan.plan(pb, runs=2, max_runs=2, processes=1)"
)


def pytest_configure(config: pytest.Config) -> None:
    """With test processes (``-n``) and a cold numba cache (a fresh machine, or an edited
    kernel), compile the kernels once before the processes start: otherwise each test process,
    and each process a test starts (Dask workers, the command line), compiles them at the same
    time, about a minute of CPU each, and the first units run minutes late."""
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", default=None):
        return
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    folder = Path(chosen) if chosen else jitcache.user_cache_dir() / jitcache.kernel_fingerprint()
    if jitcache.cache_is_cold(jitcache.KERNEL_SOURCES, folder):
        # not checked: a failure here is one the tests themselves report
        env = {**os.environ, "MPLBACKEND": "Agg"}
        subprocess.run([sys.executable, "-c", _COMPILE], env=env, capture_output=True, timeout=900)
