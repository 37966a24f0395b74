"""Parameter studies on Dask (``obsplan sweep``): sweep files, tasks, execution, table, figures.

Public API: :func:`sweep` -> pandas DataFrame, :func:`load_sweep` -> :class:`SweepSpec`,
:func:`expand` -> list of :class:`Task`, :func:`read_table`, :func:`redraw_figures`,
:func:`local_cluster`, :func:`sharded_monte_carlo`. Imports every stage up to planning (a task
is a plan and its validation); nothing of :mod:`obsplan.io` or the command line.
"""

from __future__ import annotations

from obsplan.sweeps.figures import plot_metric, redraw_figures, study_figures
from obsplan.sweeps.montecarlo import shard_bounds, sharded_monte_carlo
from obsplan.sweeps.run import ClusterError, SweepStart, dask_client, local_cluster, sweep
from obsplan.sweeps.spec import (
    SweepFileError,
    SweepSpec,
    Task,
    expand,
    load_sweep,
    sweep_from_dict,
)
from obsplan.sweeps.table import comparable, read_table
from obsplan.sweeps.tasks import run_task, worker_threads

__all__ = [
    "ClusterError",
    "SweepFileError",
    "SweepSpec",
    "SweepStart",
    "Task",
    "comparable",
    "dask_client",
    "expand",
    "load_sweep",
    "local_cluster",
    "plot_metric",
    "read_table",
    "redraw_figures",
    "run_task",
    "shard_bounds",
    "sharded_monte_carlo",
    "study_figures",
    "sweep",
    "sweep_from_dict",
    "worker_threads",
]
