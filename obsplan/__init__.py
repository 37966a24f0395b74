"""obsplan: observability-aware trajectory planning for single-beacon range localisation.

The public API in one place (see README.md): build or read a :class:`Trajectory`, judge it with
:func:`analyze`, estimate along it with :func:`monte_carlo`, and plan one with :func:`plan`.
"""

from __future__ import annotations

from obsplan.estimation import EstimationConfig, MonteCarloResult, monte_carlo
from obsplan.model import VehicleModel, make_model
from obsplan.observability.analyze import ObservabilityReport, analyze
from obsplan.planning import PlanningProblem, PlanResult, load_problem, plan
from obsplan.trajectory import Trajectory, read_csv, write_csv
from obsplan.version import __version__


def __getattr__(name: str):
    # obsplan.sweep (parameter studies) needs pandas and Dask: imported on first use only
    if name == "sweep":
        from obsplan.sweeps import sweep

        return sweep
    raise AttributeError(f"module 'obsplan' has no attribute {name!r}")


__all__ = [
    "EstimationConfig",
    "MonteCarloResult",
    "ObservabilityReport",
    "PlanResult",
    "PlanningProblem",
    "Trajectory",
    "VehicleModel",
    "__version__",
    "analyze",
    "load_problem",
    "make_model",
    "monte_carlo",
    "plan",
    "read_csv",
    "sweep",
    "write_csv",
]
