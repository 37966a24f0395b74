"""What a planning problem is: the problem file's fields (:mod:`~.schema`), its sections and the
frozen :class:`~.definition.PlanningProblem` checked on construction (:mod:`~.definition`,
:mod:`~.checks`), a problem's file mapping both ways by the file's rules (:mod:`~.mapping`: the
problem's ``from_dict``, ``with_changes``, ``to_toml``), files in (:mod:`~.parse`: load_problem,
the shipped problems), the independent check of a path against its limits (:mod:`~.feasibility`),
and its ``[validation]`` as the estimation stage's objects (:mod:`~.validation_setup`).

Imports :mod:`obsplan.planning.missions` and the stages below planning.
"""

from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.sections import (
    Area,
    Horizon,
    Limits,
    ObjectiveSpec,
    ValidationSpec,
    VehicleSpec,
)

__all__ = [
    "Area",
    "Horizon",
    "Limits",
    "ObjectiveSpec",
    "PlanningProblem",
    "ValidationSpec",
    "VehicleSpec",
]
