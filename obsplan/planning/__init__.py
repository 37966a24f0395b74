"""Observability-aware trajectory planning: problems, objectives, solver, baselines, validation.

Public API: :func:`plan` -> :class:`PlanResult`, :func:`load_problem`, :class:`PlanningProblem`,
:func:`solve` -> :class:`SolveResult`, :func:`baselines`, :func:`path_metrics`,
:func:`estimation_config` (the validation's filter configuration of a problem). The modules form
one-way rooms (docs/design.md; ``tests/test_architecture.py`` holds their order).
"""

from __future__ import annotations

from obsplan.planning.baselines import Baseline, baselines
from obsplan.planning.evaluate import PathMetrics, path_metrics
from obsplan.planning.parse import load_problem, problem_from_dict
from obsplan.planning.plan import PlanResult, plan
from obsplan.planning.problem import PlanningProblem
from obsplan.planning.schema import OBJECTIVES
from obsplan.planning.solve import SolveResult, solve
from obsplan.planning.validation_setup import estimation_config

__all__ = [
    "OBJECTIVES",
    "Baseline",
    "PathMetrics",
    "PlanResult",
    "PlanningProblem",
    "SolveResult",
    "baselines",
    "estimation_config",
    "load_problem",
    "path_metrics",
    "plan",
    "problem_from_dict",
    "solve",
]
