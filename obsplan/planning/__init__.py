"""Observability-aware trajectory planning: problems, objectives, solver, baselines, validation.

The rooms, from the bottom up (each imports only those before it, and the stages below
planning): the floor :mod:`~.tuning` (the planner's numeric tuning knobs, docs/tuning.md),
:mod:`~.missions`, :mod:`~.problem`, :mod:`~.baselines`, :mod:`~.transcription`,
:mod:`~.objectives`, :mod:`~.solver`, :mod:`~.validation`, then :mod:`~.figures`,
:mod:`~.replan`, :mod:`~.results` and :mod:`~.plan` on top.

Public API: :func:`plan` -> :class:`PlanResult`, :func:`validate` -> :class:`ValidationResult`
(a given path validated as :func:`plan` validates its plan), :func:`plan_moving_beacon` ->
:class:`BeaconPlanResult` (a planned beacon for a vehicle on a given path, or both jointly),
:func:`load_problem`,
:class:`PlanningProblem` and its sections, :func:`solve` -> :class:`SolveResult`,
:func:`baselines`, :func:`path_metrics`, :func:`estimation_config` (the validation's filter
configuration of a problem). The modules form
one-way rooms (docs/design.md; ``tests/test_architecture.py`` holds their order).
"""

from __future__ import annotations

from obsplan.planning.baselines.vehicle import Baseline, baselines
from obsplan.planning.objectives.evaluate import PathMetrics, path_metrics
from obsplan.planning.plan import plan, plan_moving_beacon, validate
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import load_problem, problem_from_dict
from obsplan.planning.problem.schema import OBJECTIVES
from obsplan.planning.problem.sections import (
    Area,
    Horizon,
    Limits,
    ObjectiveSpec,
    ValidationSpec,
    VehicleSpec,
)
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.planning.results import BeaconPlanResult, PlanResult, ValidationResult
from obsplan.planning.solver.solve import SolveResult, solve

__all__ = [
    "OBJECTIVES",
    "Area",
    "Baseline",
    "BeaconPlanResult",
    "Horizon",
    "Limits",
    "ObjectiveSpec",
    "PathMetrics",
    "PlanResult",
    "PlanningProblem",
    "SolveResult",
    "ValidationResult",
    "ValidationSpec",
    "VehicleSpec",
    "baselines",
    "estimation_config",
    "load_problem",
    "path_metrics",
    "plan",
    "plan_moving_beacon",
    "problem_from_dict",
    "solve",
    "validate",
]
