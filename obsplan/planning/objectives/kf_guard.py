"""The augmented KF's guard: the planner may not buy the EKF's bound with the KF's
(``objective.kf_guard``).

The validation flies every plan with the EKF, the Gaussian sum *and* the augmented KF
(:mod:`obsplan.estimation.filters.kf`), and the verdict compares all of them with the baselines.
Every objective but ``kf-position-std`` scores information an EKF can use (the posterior CRB, the
Gramians, the LWO conditioning); the augmented KF reads the same ranges through another model (a
linear one on the half-squared range, with the anchor state of eqs. 20-24), whose covariance can
grow where the EKF's shrinks: close to the beacon its range rows carry ``R = r² σ_r² + ½ σ_r⁴``
less information per metre, and it has no absolute range. Nothing in those objectives sees it.

The guard bounds the KF's predicted position std along the plan (its exact Riccati recursion,
:func:`~obsplan.planning.objectives.estimator.kf_objective`) by ``g`` times its value on the
reference path (:func:`~obsplan.planning.transcription.guesses.reference_path`, the lawn-mower),
over the mission and at its end, with the penalty

    c [max(0, K̄ / (g K̄_ref) - 1)² + max(0, K_N / (g K_N,ref) - 1)²]

(``K̄`` the mean over the filter samples, what ``kf.rmse_pos`` averages; ``K_N`` the last,
``kf.final_pos_err``'s; ``c`` ``Tuning.kf_guard_penalty``). A penalty rather than a constraint
for the same reasons as the linearisation bound's (:mod:`obsplan.planning.objectives.
linearisation`): one scalar whose gradient is one reverse sweep of the recursion, and elastic
where the bound cannot hold. Its curvature is dense (the KF's std is a function of the whole
path), so an NLP with it runs a limited-memory Hessian even for an objective with an exact one
(:func:`obsplan.planning.solver.formulation.build_formulation`).

When it applies. ``objective.kf_guard = g > 0`` puts the penalty in every solve. Unset (the
default), the problem is solved without it and re-solved with ``g = 1``
(:data:`~obsplan.planning.problem.schema.KF_GUARD`) only when the kept plan's predicted KF std,
mean or final, exceeds the lawn-mower's (:func:`engages`;
:func:`~obsplan.planning.solver.margins.solve_with_keepout`, which also keeps the plan without
the guard where the guarded one raises the EKF's bound). Not always on: the penalty's mere
presence changes IPOPT's path (another Hessian, a gradient wherever an iterate passes above the
bound), so it would move plans that never traded the KF. ``0`` turns it off; ``kf-position-std``
plans for the KF itself and a moving beacon has no KF recursion in the planner: off there.

The KF's prediction is its Riccati recursion with the gains taken on the nominal path, which a
closed-loop run follows to within its estimation error. docs/problem-files.md ("The augmented
KF's guard") has the evidence, with the command that measures it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from obsplan.planning.objectives.estimator import covariance_objective, reference_stds
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.schema import KF_GUARD
from obsplan.planning.transcription.blocks import FormulationPart
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory

#: The recursion the guard runs: the augmented KF's.
KF_KIND = "kf-position-std"


def guard_ratios(pb: PlanningProblem, grid: Grid, W):
    """``(K̄ / K̄_ref, K_N / K_N,ref)``: the KF's predicted mean and final position std on the
    path ``W`` relative to the reference path's (CasADi expressions, or floats for an ndarray).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its ``[validation]`` (the KF's prior, noises, rates) and reference path.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables (intrinsic units).

    Returns
    -------
    mean_ratio, final_ratio : float or casadi.MX
        Dimensionless; 1 on the reference path.
    """
    avg, final = covariance_objective(pb, KF_KIND).evaluate(grid, W)
    ref = reference_stds(pb, KF_KIND)
    return avg / max(float(ref[0]), 1e-12), final / max(float(ref[1]), 1e-12)


def guard_ratios_of(traj: Trajectory, pb: PlanningProblem) -> tuple[float, float]:
    """:func:`guard_ratios` on a path (numbers).

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    mean_ratio, final_ratio : float
        The KF's predicted mean and final position std relative to the reference path's.
    """
    grid = Grid.from_problem(pb)
    a, f = guard_ratios(pb, grid, grid.from_trajectory(traj))
    return float(a), float(f)


def penalty_expr(pb: PlanningProblem, grid: Grid, W, bound: float):
    """``c [max(0, K̄/(g K̄_ref) - 1)² + max(0, K_N/(g K_N,ref) - 1)²]`` on ``W`` (module
    docstring; ``g = bound``, ``c`` = ``Tuning.kf_guard_penalty``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.
    bound : float
        ``g``: the KF's std allowed, as a multiple of the reference path's.

    Returns
    -------
    float or casadi.MX
        The penalty, in the units of the normalised objective.
    """
    a, f = guard_ratios(pb, grid, W)
    c = tuning().kf_guard_penalty
    if isinstance(W, np.ndarray):
        x = np.array([float(a), float(f)]) / bound - 1.0
        return c * float(np.sum(np.maximum(x, 0.0) ** 2))
    return c * ca.sumsqr(ca.fmax(ca.vertcat(a, f) / bound - 1.0, 0.0))


def applies(pb: PlanningProblem) -> bool:
    """Whether the planner can guard the augmented KF on ``pb``: a range sensor, a fixed beacon,
    an objective other than ``kf-position-std`` and ``objective.kf_guard`` not 0.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    bool
    """
    return (
        pb.objective.kf_guard != 0
        and pb.objective.kind != KF_KIND
        and "range" in pb.model.sensors
        and pb.beacon_path is None
    )


def engages(traj: Trajectory, pb: PlanningProblem) -> tuple[bool, tuple[float, float] | None]:
    """Whether the default guard (``objective.kf_guard`` unset) engages on a plan solved
    without it: its predicted KF std, mission mean or final, above
    :data:`~obsplan.planning.problem.schema.KF_GUARD` times the lawn-mower's.

    Parameters
    ----------
    traj : Trajectory
        The plan solved without the guard, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    engaged : bool
        False too when the guard does not apply (:func:`applies`) or is set explicitly.
    ratios : tuple of float or None
        :func:`guard_ratios_of` on ``traj``; None when not evaluated (the default guard does
        not apply).
    """
    if not applies(pb) or pb.objective.kf_guard is not None:
        return False, None
    ratios = guard_ratios_of(traj, pb)
    return max(ratios) > KF_GUARD, ratios


def kf_guard_part(pb: PlanningProblem, grid: Grid, W: ca.MX) -> FormulationPart | None:
    """The penalty of an explicit ``objective.kf_guard = g > 0`` (None when it is unset, 0, or
    the guard does not apply: :func:`applies`; the unset default engages by a re-solve with
    ``g`` = :data:`~obsplan.planning.problem.schema.KF_GUARD`, :func:`engages`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.kf_guard``, its sensors and beacon.
    grid : Grid
        The planning grid of the problem.
    W : casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    FormulationPart or None
        ``"kf_guard"`` with the penalty of :func:`penalty_expr`; None when it does not apply.
    """
    bound = pb.objective.kf_guard
    if bound is None or not applies(pb):
        return None
    return FormulationPart("kf_guard", penalty=penalty_expr(pb, grid, W, float(bound)))
