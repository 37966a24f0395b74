"""The estimators' guards: the planner may not buy one estimator's information with another's
(``objective.kf_guard``, ``objective.ekf_guard``).

The validation flies every plan with the EKF, the Gaussian sum *and* the augmented KF
(:mod:`obsplan.estimation.filters.kf`), and the verdict compares all of them with the baselines.
No objective scores all of them:

* the observability objectives (the Gramians, the LWO conditioning) score how well the state is
  determined by the ranges, not an estimator's error: a plan can raise the smallest eigenvalue or
  the log-determinant of the Gramian where the EKF's bound (the posterior CRB, which adds the
  prior and the process noise, and weighs every epoch alike) gets worse than on the lawn-mower;
* every objective but ``kf-position-std`` scores information an EKF can use; the augmented KF
  reads the same ranges through another model (a linear one on the half-squared range, with the
  anchor state of eqs. 20-24), whose covariance can grow where the EKF's shrinks: close to the
  beacon its range rows carry ``R = r² σ_r² + ½ σ_r⁴`` less information per metre, and it has no
  absolute range.

A guard bounds one estimator's predicted position std along the plan — the augmented KF's exact
Riccati recursion (``"kf"``) or the posterior CRB (``"ekf"``), the recursions of
:func:`~obsplan.planning.objectives.estimator.covariance_objective` — by ``g`` times its value on
the reference path (:func:`~obsplan.planning.transcription.guesses.reference_path`, the
lawn-mower), over the mission and at its end, with the penalty

    c [max(0, K̄ / (g K̄_ref) - 1)² + max(0, K_N / (g K_N,ref) - 1)²]

(``K̄`` the mean over the samples, what the RMSE averages; ``K_N`` the last, the final error's;
``c`` ``Tuning.guard_penalty``). A penalty rather than a constraint for the same reasons as the
linearisation bound's (:mod:`obsplan.planning.objectives.linearisation`): one scalar whose
gradient is one reverse sweep of the recursion, and elastic where the bound cannot hold. Its
curvature is dense (the std is a function of the whole path), so an NLP with it runs a
limited-memory Hessian even for an objective with an exact one
(:func:`obsplan.planning.solver.formulation.build_formulation`).

When they apply. ``objective.<estimator>_guard = g > 0`` puts the penalty in every solve. Unset
(the default), the problem is solved without them and re-solved with the guard of each
estimator whose predicted std, mean or final, exceeds the lawn-mower's on the kept plan, at
``g = 1`` for the KF (:data:`~obsplan.planning.problem.schema.KF_GUARD`) and ``g = 0.95`` for
the EKF (:data:`~obsplan.planning.problem.schema.EKF_GUARD`: its error sits above its bound, so a
bound held at exactly the lawn-mower's ties at best): :func:`engages`,
:func:`~obsplan.planning.solver.margins.solve_with_keepout`, which keeps the plan without them
where the guarded one raises an unguarded estimator's prediction above both the lawn-mower's and
its own. Not always on: a penalty's mere presence changes
IPOPT's path (another Hessian, a gradient wherever an iterate passes above the bound), so it
would move plans that never traded an estimator. ``0`` turns a guard off. The KF's guard is off
for ``kf-position-std`` (it plans for the KF), the EKF's for both estimator objectives
(``pcrb-position`` plans for the bound itself, ``kf-position-std`` weighs it in), and both for a
moving beacon (no recursion of the planner follows it).

The predictions are the recursions with the gains taken on the nominal path, which a closed-loop
run follows to within its estimation error. docs/problem-files.md ("The estimators' guards") has
the evidence, with the command that measures it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from obsplan.planning.objectives.estimator import covariance_objective, reference_stds
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.schema import EKF_GUARD, KF_GUARD, OBJECTIVE_KINDS
from obsplan.planning.transcription.blocks import FormulationPart
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory

#: The recursion the augmented KF's guard runs.
KF_KIND = "kf-position-std"
#: The recursion each estimator's guard runs (:func:`covariance_objective`).
RECURSIONS = {"kf": KF_KIND, "ekf": "pcrb-position"}
#: The default bound of each guard, a multiple of the lawn-mower's std.
DEFAULT_BOUNDS = {"kf": KF_GUARD, "ekf": EKF_GUARD}
#: The predicted std, a multiple of the lawn-mower's, above which a default guard engages: the
#: lawn-mower's own (a plan predicted to do no worse than it is left alone).
ENGAGE_ABOVE = {"kf": 1.0, "ekf": 1.0}
#: What each guard holds, in words.
HELD = {"kf": "the augmented KF's predicted std", "ekf": "the EKF's bound (posterior CRB)"}
#: Each estimator's short name.
SHORT = {"kf": "KF", "ekf": "EKF"}
#: The estimators, in the order they are evaluated and reported.
ESTIMATORS = ("ekf", "kf")


def bound_of(pb: PlanningProblem, estimator: str) -> float | None:
    """``objective.<estimator>_guard`` of ``pb`` (None: unset).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    estimator : {"ekf", "kf"}
        The guard.

    Returns
    -------
    float or None
        The bound, a multiple of the lawn-mower's std; None when unset (the default).
    """
    return getattr(pb.objective, f"{estimator}_guard")


def guard_ratios(pb: PlanningProblem, grid: Grid, W, estimator: str = "kf"):
    """``(K̄ / K̄_ref, K_N / K_N,ref)``: the estimator's predicted mean and final position std on
    the path ``W`` relative to the reference path's (CasADi expressions, or floats for an
    ndarray).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its ``[validation]`` (the filters' priors, noises, rates) and reference path.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables (intrinsic units).
    estimator : {"kf", "ekf"}, optional
        The recursion (:data:`RECURSIONS`).

    Returns
    -------
    mean_ratio, final_ratio : float or casadi.MX
        Dimensionless; 1 on the reference path.
    """
    kind = RECURSIONS[estimator]
    avg, final = covariance_objective(pb, kind).evaluate(grid, W)
    ref = reference_stds(pb, kind)
    return avg / max(float(ref[0]), 1e-12), final / max(float(ref[1]), 1e-12)


def guard_ratios_of(
    traj: Trajectory, pb: PlanningProblem, estimator: str = "kf"
) -> tuple[float, float]:
    """:func:`guard_ratios` on a path (numbers).

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.
    estimator : {"kf", "ekf"}, optional
        The recursion (:data:`RECURSIONS`).

    Returns
    -------
    mean_ratio, final_ratio : float
        The estimator's predicted mean and final position std relative to the reference path's.
    """
    grid = Grid.from_problem(pb)
    a, f = guard_ratios(pb, grid, grid.from_trajectory(traj), estimator)
    return float(a), float(f)


def penalty_expr(pb: PlanningProblem, grid: Grid, W, bound: float, estimator: str = "kf"):
    """``c [max(0, K̄/(g K̄_ref) - 1)² + max(0, K_N/(g K_N,ref) - 1)²]`` on ``W`` (module
    docstring; ``g = bound``, ``c`` = ``Tuning.guard_penalty``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.
    bound : float
        ``g``: the std allowed, as a multiple of the reference path's.
    estimator : {"kf", "ekf"}, optional
        The recursion (:data:`RECURSIONS`).

    Returns
    -------
    float or casadi.MX
        The penalty, in the units of the normalised objective.
    """
    a, f = guard_ratios(pb, grid, W, estimator)
    c = tuning().guard_penalty
    if isinstance(W, np.ndarray):
        x = np.array([float(a), float(f)]) / bound - 1.0
        return c * float(np.sum(np.maximum(x, 0.0) ** 2))
    return c * ca.sumsqr(ca.fmax(ca.vertcat(a, f) / bound - 1.0, 0.0))


def predicts(pb: PlanningProblem) -> bool:
    """Whether the planner's recursions follow the estimators on ``pb``: a range sensor and a
    fixed beacon (what every guard needs, and what judging one guard's cost to the other
    estimator needs).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    bool
    """
    return "range" in pb.model.sensors and pb.beacon_path is None


def applies(pb: PlanningProblem, estimator: str = "kf") -> bool:
    """Whether the planner can guard ``estimator`` on ``pb``: :func:`predicts`, the guard not
    set to 0, and an objective that does not plan for that estimator already (the KF's guard: any
    but ``kf-position-std``; the EKF's: the observability objectives).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    estimator : {"kf", "ekf"}, optional
        The guard.

    Returns
    -------
    bool
    """
    kind = pb.objective.kind
    plans_for_it = kind == KF_KIND if estimator == "kf" else OBJECTIVE_KINDS[kind].timed
    return bound_of(pb, estimator) != 0 and not plans_for_it and predicts(pb)


def engages(traj: Trajectory, pb: PlanningProblem) -> dict[str, tuple[bool, tuple[float, float]]]:
    """Which default guards (``objective.<estimator>_guard`` unset) engage on a plan solved
    without them: the estimator's predicted std, mission mean or final, above
    :data:`ENGAGE_ABOVE` times the lawn-mower's (they then re-solve with the bound at
    :data:`DEFAULT_BOUNDS`).

    Parameters
    ----------
    traj : Trajectory
        The plan solved without the default guards, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    dict
        Per estimator whose default guard applies (:func:`applies`, and not set explicitly), in
        the order of :data:`ESTIMATORS`: ``(engaged, ratios)``, ``ratios`` :func:`guard_ratios_of`
        on ``traj``. Empty when none does.
    """
    out = {}
    for est in ESTIMATORS:
        if applies(pb, est) and bound_of(pb, est) is None:
            ratios = guard_ratios_of(traj, pb, est)
            out[est] = (max(ratios) > ENGAGE_ABOVE[est], ratios)
    return out


def _part(pb: PlanningProblem, grid: Grid, W: ca.MX, estimator: str) -> FormulationPart | None:
    bound = bound_of(pb, estimator)
    if bound is None or not applies(pb, estimator):
        return None
    penalty = penalty_expr(pb, grid, W, float(bound), estimator)
    return FormulationPart(f"{estimator}_guard", penalty=penalty)


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
    return _part(pb, grid, W, "kf")


def ekf_guard_part(pb: PlanningProblem, grid: Grid, W: ca.MX) -> FormulationPart | None:
    """The penalty of an explicit ``objective.ekf_guard = g > 0``, on the posterior CRB (None
    when it is unset, 0, or the guard does not apply: :func:`applies`; the unset default engages
    by a re-solve with ``g`` = :data:`~obsplan.planning.problem.schema.EKF_GUARD`,
    :func:`engages`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.ekf_guard``, its objective, sensors and beacon.
    grid : Grid
        The planning grid of the problem.
    W : casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    FormulationPart or None
        ``"ekf_guard"`` with the penalty of :func:`penalty_expr`; None when it does not apply.
    """
    return _part(pb, grid, W, "ekf")
