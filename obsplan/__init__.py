"""obsplan: observability-aware trajectory planning for single-beacon range localisation.

The public API in one place (see README.md): build or read a :class:`Trajectory`, judge it with
:func:`analyze`, estimate along it with :func:`monte_carlo`; load a problem with
:func:`load_problem` (a :class:`PlanningProblem`, edited with ``with_changes``; its sections
:class:`VehicleSpec`, :class:`Area`, :class:`Limits`, :class:`Horizon`, :class:`ObjectiveSpec`,
:class:`ValidationSpec`), plan a path with :func:`plan` (a :class:`PlanResult`: ``summary()``,
``plot()``, ``save()``, ``to_dict()``) and validate any path as the plan is validated with
:func:`validate` (a :class:`ValidationResult`); study many with :func:`sweep`.

Names (every one imported on first use):

=========================  ========================================================================
``Area``                   a problem's operating area (``limits.area``)
``EstimationConfig``       the filters' noises, rates, prior and process noise
``Horizon``                a problem's horizon: duration [s] and steps
``Limits``                 a problem's limits: acceleration, speed, depth, area, distances
``MonteCarloResult``       a Monte Carlo's statistics: ``summary()``, ``plot()``, ``to_dict()``
``ObjectiveSpec``          a problem's objective: kind, mode, starts, weights, windows
``ObservabilityReport``    both observability verdicts of a trajectory
``PlanResult``             a plan and its validation: ``summary()``, ``plot()``, ``save()``
``PlanningProblem``        a checked planning problem: ``with_changes()``, ``to_toml()``
``Trajectory``             a sampled path: times, positions, velocities, held inputs
``ValidationResult``       a given path validated as a plan is (:func:`validate`)
``ValidationSpec``         a problem's Monte Carlo validation settings
``VehicleModel``           the vehicle's model: dimension, sensors, current, beacon
``VehicleSpec``            a problem's vehicle: dimension, sensors, current
``__version__``            the package's version
``analyze``                LWO and Gramian observability of a trajectory
``load_problem``           a problem file, or a shipped problem by name
``make_model``             a :class:`VehicleModel` from a dimension and sensor names
``monte_carlo``            EKF/KF Monte Carlo along a trajectory (open loop by default)
``plan``                   solve a problem, compare with the baselines, validate
``read_csv``               a trajectory CSV
``sweep``                  a parameter study on Dask
``validate``               a given path validated exactly as :func:`plan` validates its plan
``write_csv``              a trajectory as CSV
=========================  ========================================================================
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from obsplan.version import __version__

if TYPE_CHECKING:
    from obsplan.estimation import EstimationConfig, MonteCarloResult, monte_carlo
    from obsplan.model.vehicle import VehicleModel, make_model
    from obsplan.observability.analyze import ObservabilityReport, analyze
    from obsplan.planning import (
        Area,
        Horizon,
        Limits,
        ObjectiveSpec,
        PlanningProblem,
        PlanResult,
        ValidationResult,
        ValidationSpec,
        VehicleSpec,
        load_problem,
        plan,
        validate,
    )
    from obsplan.sweeps import sweep
    from obsplan.trajectory.sampled import Trajectory, read_csv, write_csv


#: The names the planning package gives the facade.
_PLANNING = frozenset(
    {
        "Area",
        "Horizon",
        "Limits",
        "ObjectiveSpec",
        "PlanResult",
        "PlanningProblem",
        "ValidationResult",
        "ValidationSpec",
        "VehicleSpec",
        "load_problem",
        "plan",
        "validate",
    }
)


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
    elif name in _PLANNING:
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


#: The public names, sorted (the table of the module docstring says what each is).
__all__ = [
    "Area",
    "EstimationConfig",
    "Horizon",
    "Limits",
    "MonteCarloResult",
    "ObjectiveSpec",
    "ObservabilityReport",
    "PlanResult",
    "PlanningProblem",
    "Trajectory",
    "ValidationResult",
    "ValidationSpec",
    "VehicleModel",
    "VehicleSpec",
    "__version__",
    "analyze",
    "load_problem",
    "make_model",
    "monte_carlo",
    "plan",
    "read_csv",
    "sweep",
    "validate",
    "write_csv",
]
