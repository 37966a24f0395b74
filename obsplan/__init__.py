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
    from obsplan.model.vehicle import VehicleModel, make_model
    from obsplan.observability.analyze import ObservabilityReport, analyze
    from obsplan.planning import PlanningProblem, PlanResult, load_problem
    from obsplan.planning.plan import plan
    from obsplan.sweeps import sweep
    from obsplan.trajectory.sampled import Trajectory, read_csv, write_csv


def __getattr__(name: str):
    # the public names are imported on first use: `import obsplan` (and the `obsplan` command,
    # which must install its signal handlers before the heavy imports) stays fast
    if name in ("EstimationConfig", "MonteCarloResult", "monte_carlo"):
        import obsplan.estimation  # noqa: F401

        mod = sys.modules["obsplan.estimation"]
    elif name in ("VehicleModel", "make_model"):
        import obsplan.model.vehicle  # noqa: F401

        mod = sys.modules["obsplan.model.vehicle"]
    elif name in ("ObservabilityReport", "analyze"):
        import obsplan.observability.analyze  # noqa: F401 (the package re-exports analyze())

        mod = sys.modules["obsplan.observability.analyze"]
    elif name in ("PlanningProblem", "PlanResult", "load_problem", "plan"):
        import obsplan.planning  # noqa: F401

        mod = sys.modules["obsplan.planning"]
    elif name == "sweep":  # parameter studies need pandas and Dask
        import obsplan.sweeps  # noqa: F401

        mod = sys.modules["obsplan.sweeps"]
    elif name in ("Trajectory", "read_csv", "write_csv"):
        import obsplan.trajectory.sampled  # noqa: F401

        mod = sys.modules["obsplan.trajectory.sampled"]
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
