"""Observability-aware trajectory planning (issue #4): problems, objectives, solver, baselines.

Public API: :func:`plan` -> :class:`PlanResult`, :func:`load_problem`, :class:`PlanningProblem`,
:func:`solve` -> :class:`SolveResult`, :func:`baselines`, :func:`path_metrics`.
"""

from __future__ import annotations

from obsplan.planning.baselines import Baseline, baselines
from obsplan.planning.metrics import PathMetrics, path_metrics
from obsplan.planning.plan import PlanResult, plan
from obsplan.planning.problem import (
    OBJECTIVES,
    PlanningProblem,
    load_problem,
    problem_from_dict,
)
from obsplan.planning.solve import SolveResult, solve

__all__ = [
    "OBJECTIVES",
    "Baseline",
    "PathMetrics",
    "PlanResult",
    "PlanningProblem",
    "SolveResult",
    "baselines",
    "load_problem",
    "path_metrics",
    "plan",
    "problem_from_dict",
    "solve",
]
