"""The objective registry: every ``objective.kind`` and its implementation.

Each entry is an :class:`~obsplan.planning.transcription.blocks.Objective`: the symbolic part for
the NLP (``nlp(ctx) -> ObjectiveTerm``: the expression normalised on the reference path, lifting
variables with bounds and initial values, extra constraints, Hessian mode, map back to the
user's value) and the value computed numerically on a path (``value(traj, pb)``). The kinds'
declared properties (sense, time mode, default tolerance, structural rank) are in
:data:`obsplan.planning.problem.schema.OBJECTIVE_KINDS`; a test checks that the two tables name the
same kinds.

A new objective is a module beside these (importing :mod:`obsplan.planning.transcription.blocks`,
:mod:`obsplan.planning.transcription.grid` and what it needs below them), one entry here and one in
:data:`~obsplan.planning.problem.schema.OBJECTIVE_KINDS`; nothing else in the planner changes.
"""

from __future__ import annotations

from obsplan.planning.objectives.estimator import KF_POSITION_STD, PCRB_POSITION
from obsplan.planning.objectives.gramian import GRAMIAN_LOG_DET, GRAMIAN_MIN_EIG
from obsplan.planning.objectives.lwo import LWO_CONDITION
from obsplan.planning.objectives.robust import ROBUST, is_robust
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import Objective

#: ``objective.kind`` -> its implementation.
REGISTRY: dict[str, Objective] = {
    o.kind: o
    for o in (PCRB_POSITION, GRAMIAN_MIN_EIG, GRAMIAN_LOG_DET, LWO_CONDITION, KF_POSITION_STD)
}


def objective_of(pb: PlanningProblem) -> Objective:
    """The registered implementation of ``pb.objective.kind`` (over the family of conditions
    of :mod:`obsplan.planning.objectives.robust` when the problem asks for robust planning).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.kind`` and its robust settings.

    Returns
    -------
    Objective
        The entry of :data:`REGISTRY`, or :data:`~obsplan.planning.objectives.robust.ROBUST`.
    """
    return ROBUST if is_robust(pb) else REGISTRY[pb.objective.kind]
