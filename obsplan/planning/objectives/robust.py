"""Robust planning: an estimator objective over a family of conditions, worst case or mean.

A plan tuned to the stated prior and range noise can hug the beacon where the filter, told a
wider prior or facing noisier ranges, diverges. With ``objective.robust_prior`` (multiples of the
validation's prior std, ``init_pos_error`` and ``init_vel_error``) and/or
``objective.robust_range_noise`` (multiples of ``range_std``), every combination of the listed
multiples is a *condition*: the problem with its ``[validation]`` scaled so. The problem's
estimator objective (``pcrb-position`` or ``kf-position-std``, with its time mode) is evaluated
under each condition's configuration (the same recursion as the nominal objective,
:mod:`obsplan.planning.objectives.estimator`) and divided by its value on the reference path
under the same condition, so that every condition weighs 1 on the lawn-mower. They combine by
``objective.robust_aggregate``:

* ``"worst"``: ``min s`` subject to ``s >= J_c(W) / J_c(ref)`` for every condition ``c`` (an
  epigraph: smooth constraints instead of a non-smooth max);
* ``"mean"``: the mean of ``J_c(W) / J_c(ref)``.

The value on a path (used to judge every candidate) is the same aggregate computed numerically;
it is dimensionless, 1 on the reference path.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from functools import cache

import casadi as ca
import numpy as np

from obsplan.planning.objectives.estimator import covariance_expr, covariance_value
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import (
    ConstraintBlock,
    NLPContext,
    Objective,
    ObjectiveTerm,
    VariableBlock,
)
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.transcription.guesses import reference_path
from obsplan.planning.tuning import cache_per_tuning
from obsplan.trajectory.sampled import Trajectory


def is_robust(pb: PlanningProblem) -> bool:
    """True when the problem asks to plan for a family of conditions.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.robust_prior`` and ``objective.robust_range_noise``.

    Returns
    -------
    bool
        Either list is non-empty.
    """
    return bool(pb.objective.robust_prior or pb.objective.robust_range_noise)


def conditions(pb: PlanningProblem) -> tuple[tuple[float, float], ...]:
    """``(prior multiple, range-noise multiple)`` of every condition, in order.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    tuple of (float, float)
        Every combination of ``robust_prior`` and ``robust_range_noise`` (an empty list counts
        as ``(1,)``), prior multiples outermost.
    """
    priors = pb.objective.robust_prior or (1.0,)
    noises = pb.objective.robust_range_noise or (1.0,)
    return tuple(itertools.product(priors, noises))


def scaled_problem(pb: PlanningProblem, prior: float, range_noise: float) -> PlanningProblem:
    """``pb`` with its validation's prior std times ``prior`` and range std times
    ``range_noise`` (and no robust fields: the nominal objective of that condition).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    prior : float
        Multiple of ``validation.init_pos_error`` and ``init_vel_error``.
    range_noise : float
        Multiple of ``validation.range_std``.

    Returns
    -------
    PlanningProblem
        The condition's problem.
    """
    val = pb.validation
    val = replace(
        val,
        init_pos_error=val.init_pos_error * prior,
        init_vel_error=val.init_vel_error * prior,
        range_std=val.range_std * range_noise,
    )
    obj = replace(pb.objective, robust_prior=(), robust_range_noise=())
    return replace(pb, validation=val, objective=obj)


@cache
def condition_problems(pb: PlanningProblem) -> tuple[PlanningProblem, ...]:
    """The problem of every condition (:func:`conditions`).

    Parameters
    ----------
    pb : PlanningProblem
        The robust problem.

    Returns
    -------
    tuple of PlanningProblem
        :func:`scaled_problem` of each condition, in order (cached per problem).
    """
    return tuple(scaled_problem(pb, a, b) for a, b in conditions(pb))


@cache_per_tuning
def _reference_values(pb: PlanningProblem) -> tuple[float, ...]:
    ref = reference_path(pb)
    return tuple(max(covariance_value(ref, c), 1e-12) for c in condition_problems(pb))


def condition_values(traj: Trajectory, pb: PlanningProblem) -> np.ndarray:
    """Each condition's objective on ``traj`` relative to its value on the reference path.

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The robust problem.

    Returns
    -------
    ndarray, shape (C,)
        One ratio per condition (dimensionless, 1 on the reference path).
    """
    refs = _reference_values(pb)
    vals = [covariance_value(traj, c) for c in condition_problems(pb)]
    return np.asarray(vals) / np.asarray(refs)


def robust_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The aggregate (worst or mean) of :func:`condition_values` on ``traj`` [-].

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The robust problem: ``objective.robust_aggregate``.

    Returns
    -------
    float
        The largest ratio (``"worst"``) or their mean (``"mean"``); smaller is better.
    """
    v = condition_values(traj, pb)
    return float(np.max(v) if pb.objective.robust_aggregate == "worst" else np.mean(v))


def robust_term(ctx: NLPContext) -> ObjectiveTerm:
    """The conditions' recursions on ``ctx.W``, combined as the module docstring says.

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built: the robust problem, the grid and ``W``.

    Returns
    -------
    ObjectiveTerm
        The mean of the ratios, or the epigraph variable ``s`` with one constraint per
        condition; limited-memory Hessian.
    """
    pb, grid = ctx.problem, ctx.grid
    refs = _reference_values(pb)
    terms = []
    for cpb, ref in zip(condition_problems(pb), refs, strict=True):
        terms.append(covariance_expr(cpb, grid, ctx.W) / ref)
    if pb.objective.robust_aggregate == "mean":
        return ObjectiveTerm(
            f=sum(terms) / len(terms), to_objective=float, hessian="limited-memory"
        )
    s = ca.MX.sym("robust_epigraph")
    start = _epigraph_start(pb, grid)
    g = ca.vertcat(*[s - t for t in terms])
    m = len(terms)
    return ObjectiveTerm(
        f=s,
        to_objective=float,
        variables=(VariableBlock("robust_epigraph", s, np.zeros(1), np.full(1, np.inf), start),),
        constraints=(ConstraintBlock("robust_epigraph", g, np.zeros(m), np.full(m, np.inf)),),
        hessian="limited-memory",
    )


def _epigraph_start(pb: PlanningProblem, grid: Grid):
    """Initial ``s``: the worst condition on the guess (feasible for the epigraph)."""

    def init(W: np.ndarray) -> np.ndarray:
        return np.array([robust_value(grid.to_trajectory(W), pb)])

    return init


ROBUST = Objective("robust", robust_term, robust_value)
