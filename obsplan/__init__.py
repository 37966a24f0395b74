"""obsplan: observability-aware trajectory planning for single-beacon range localisation.

The public API in one place (see README.md): build or read a :class:`Trajectory`, judge it with
:func:`analyze`, estimate along it with :func:`monte_carlo`, and plan one with :func:`plan`.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from obsplan.version import __version__

if TYPE_CHECKING:
    from obsplan.estimation import EstimationConfig, MonteCarloResult, monte_carlo
    from obsplan.model import VehicleModel, make_model
    from obsplan.observability.analyze import ObservabilityReport, analyze
    from obsplan.planning import PlanningProblem, PlanResult, load_problem, plan
    from obsplan.sweeps import sweep
    from obsplan.trajectory import Trajectory, read_csv, write_csv


def __getattr__(name: str):
    # the public names are imported on first use: `import obsplan` (and the `obsplan` command,
    # which must install its signal handlers before the heavy imports) stays fast
    if name in ("EstimationConfig", "MonteCarloResult", "monte_carlo"):
        from obsplan import estimation as mod
    elif name in ("VehicleModel", "make_model"):
        from obsplan import model as mod
    elif name in ("ObservabilityReport", "analyze"):
        import obsplan.observability.analyze  # noqa: F401 (the package re-exports analyze())

        mod = sys.modules["obsplan.observability.analyze"]
    elif name in ("PlanningProblem", "PlanResult", "load_problem", "plan"):
        from obsplan import planning as mod
    elif name == "sweep":  # parameter studies need pandas and Dask
        from obsplan import sweeps as mod
    elif name in ("Trajectory", "read_csv", "write_csv"):
        from obsplan import trajectory as mod
    else:
        raise AttributeError(f"module 'obsplan' has no attribute {name!r}")
    value = getattr(mod, name)
    globals()[name] = value
    return value


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
