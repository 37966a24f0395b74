"""Building blocks of the planning NLP and the interface every objective implements.

The NLP is assembled by :func:`obsplan.planning.solver.formulation.build_formulation` from blocks:

* the path ``W`` (:mod:`obsplan.planning.transcription.grid`) and its *path constraints* (dynamics
  and limits), always first in ``x`` and ``g`` (the projection onto the limits uses only those);
* the objective's :class:`ObjectiveTerm`: its normalised expression, its lifting variables
  (:class:`VariableBlock`) and constraints (:class:`ConstraintBlock`), its Hessian mode and the
  map from the solver's ``f`` back to the objective's value;
* then every :class:`FormulationPart` that a module adds to the problems it applies to (survey
  lines with timing variables, a covariance-dependent keep-out margin, a penalty on the EKF's
  linearisation stress, ...): variables appended after the objective's, constraints after the
  objective's, penalties added to ``f`` (and left out of the objective's value).

An objective plugs in as an :class:`Objective` registered by kind in
:data:`obsplan.planning.objectives.registry.REGISTRY`: ``nlp(ctx)`` gives the symbolic part,
``value(traj, pb)`` the same objective computed numerically on a path (used to judge every
candidate, never read from lifting variables).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import casadi as ca
import numpy as np

from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.grid import Grid
from obsplan.trajectory.sampled import Trajectory

Hessian = Literal["exact", "exact-without-penalty", "limited-memory", "limited-memory-sr1"]


def no_variables(W: np.ndarray) -> np.ndarray:
    """The initial values of an empty variable block.

    Parameters
    ----------
    W : ndarray, shape (3n, N)
        A path in intrinsic units (not read).

    Returns
    -------
    ndarray, shape (0,)
        No values.
    """
    return np.zeros(0)


@dataclass(frozen=True, eq=False)
class VariableBlock:
    """Decision variables appended after the path ``W``.

    Attributes
    ----------
    name : str
    sym : casadi.MX
        Column of pure symbols (``ca.MX.sym``, or a ``vertcat`` of them), size ``k``.
    lb, ub : ndarray
        Bounds, shape ``(k,)``.
    init : callable
        ``W (3n, N) -> (k,)``: initial values from a path in intrinsic units (a guess).
    """

    name: str
    sym: ca.MX
    lb: np.ndarray
    ub: np.ndarray
    init: Callable[[np.ndarray], np.ndarray]

    @property
    def size(self) -> int:
        return int(self.sym.numel())


@dataclass(frozen=True, eq=False)
class ConstraintBlock:
    """Constraints ``lb <= g <= ub`` on ``W`` and any variable blocks.

    Attributes
    ----------
    name : str
    g : casadi.MX
        Column, size ``m``, in units of order 1 (intrinsic or normalised).
    lb, ub : ndarray
        Shape ``(m,)``; equal for equalities.
    """

    name: str
    g: ca.MX
    lb: np.ndarray
    ub: np.ndarray

    @property
    def size(self) -> int:
        return int(self.lb.size)


@dataclass(frozen=True, eq=False)
class FormulationPart:
    """Variables and constraints that a module appends to the NLP (after the objective's), and a
    penalty (scalar, in the units of the normalised objective, ``None``: none) added to ``f``."""

    name: str
    variables: tuple[VariableBlock, ...] = ()
    constraints: tuple[ConstraintBlock, ...] = ()
    penalty: ca.MX | None = None


#: ``(problem, grid, W) -> part or None`` (None: the part does not apply to this problem).
PartBuilder = Callable[[PlanningProblem, Grid, ca.MX], "FormulationPart | None"]


@dataclass(frozen=True, eq=False)
class NLPContext:
    """What an objective's symbolic builder sees.

    Attributes
    ----------
    problem : PlanningProblem
    grid : Grid
    W : casadi.MX
        The path variables, shape ``(3n, N)``, intrinsic units.
    reference : Trajectory
        The normalisation path (:func:`obsplan.planning.transcription.guesses.reference_path`).
    W_ref : ndarray
        ``reference`` on the grid, intrinsic units, shape ``(3n, N)``.
    parts : mapping
        The :class:`FormulationPart` of this NLP by name (built before the objective, so that an
        objective can use their variables, e.g. a mission's line times).
    """

    problem: PlanningProblem
    grid: Grid
    W: ca.MX
    reference: Trajectory
    W_ref: np.ndarray
    parts: Mapping[str, FormulationPart] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class ObjectiveTerm:
    """The symbolic part of an objective.

    Attributes
    ----------
    f : casadi.MX
        Scalar that IPOPT minimises: the objective divided by its magnitude on the reference path
        and signed (a maximised objective is negated), so that it is of order 1.
    to_objective : callable
        The solver's ``f`` -> the objective in the user's sign and units.
    variables : tuple of VariableBlock
        Lifting variables (e.g. a Cholesky factor), placed right after ``W``.
    constraints : tuple of ConstraintBlock
        The lifting's constraints, placed right after the path constraints.
    hessian : {"exact", "limited-memory", "limited-memory-sr1"}
        IPOPT's Hessian: exact, or a limited-memory quasi-Newton update (BFGS, or SR1 for a
        non-convex objective on which BFGS stalls) when the exact one is dense or slow to build.
    """

    f: ca.MX
    to_objective: Callable[[float], float]
    variables: tuple[VariableBlock, ...] = ()
    constraints: tuple[ConstraintBlock, ...] = ()
    hessian: Hessian = "exact"


@dataclass(frozen=True)
class Objective:
    """One ``objective.kind``: its symbolic part for the NLP and its numeric value on a path.

    Attributes
    ----------
    kind : str
        As declared in :data:`obsplan.planning.problem.schema.OBJECTIVE_KINDS` (sense, time mode,
        default tolerance, structural rank).
    nlp : callable
        ``NLPContext -> ObjectiveTerm``.
    value : callable
        ``(trajectory on the planning grid, problem) -> float``, in the user's sign and units.
    """

    kind: str
    nlp: Callable[[NLPContext], ObjectiveTerm]
    value: Callable[[Trajectory, PlanningProblem], float]
