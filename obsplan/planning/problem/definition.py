"""A planning problem: what a problem file holds, checked on construction.

Files and mappings become a :class:`PlanningProblem` in :mod:`obsplan.planning.problem.parse`.
Construction runs the cheap checks of :mod:`obsplan.planning.problem.checks` (unknown kinds,
infeasible combinations such as a start faster than the speed limit, a depth band or operating
area that does not contain the start, a mission that does not fit the horizon); the structural
rank checks, which cost CasADi work, run in the loader and in ``solve()``. A free line order
(``mission.order = "free"``) is resolved by the loader, not here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from obsplan.planning.problem.checks import check_values
from obsplan.planning.problem.sections import ProblemData


@dataclass(frozen=True)
class PlanningProblem(ProblemData):
    """A complete planning problem (the sections of :class:`ProblemData`), checked on construction.

    Build it with :func:`~obsplan.planning.problem.parse.load_problem` /
    :func:`~obsplan.planning.problem.parse.problem_from_dict` (which also order free survey lines
    and run the structural checks), or directly: ``__post_init__`` runs the loader's cheap checks
    (:func:`~obsplan.planning.problem.checks.check_values`, no solver work).
    """

    def __post_init__(self) -> None:
        check_values(self)

    def with_changes(self, **sections: Any) -> PlanningProblem:
        """A copy with whole sections replaced (``horizon=Horizon(...)``, ``objective=...``).

        Parameters
        ----------
        **sections
            Section name -> its new value (a field of :class:`ProblemData`).

        Returns
        -------
        PlanningProblem
            The copy, checked on construction as any problem.

        Raises
        ------
        ProblemError
            When the changed problem fails the construction checks.
        """
        return replace(self, **sections)
