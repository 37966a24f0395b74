"""The EKF's linearisation stress along a path, and the planner's penalty on it
(``objective.linearisation_bound``).

The EKF linearises the range at its prior. The range's curvature over the prior has the mean

    b = ½ tr(M P_pp) = tr((I - u uᵀ) P_pp) / (2 r)                              [m]

(``M`` the range's Hessian, ``u`` the unit line of sight beacon -> vehicle, ``r`` the range,
``P_pp`` the prior position covariance): the variance across the line of sight over twice the
range. The first-order EKF takes it for information; the second-order update (the default,
``validation.ekf_update``) adds it to the predicted range, and its variance to the reading's,
computed with the filter's own covariance: right while the error is inside it. When ``b`` is a
sizeable part of the range noise ``σ_r``, the update rests on that correction, and a run whose
error across the line of sight is larger than the filter believes is pulled onto a wrong solution.
A path that creeps along the line of sight far from the beacon lets the variance across it grow
(from the prior's velocity uncertainty and the process noise) until it is. The observability
objectives (the windowed Gramians, the LWO conditioning) are blind to it: they value information
whatever estimate it is read about.

Measured with the second-order EKF by ``benchmarks/bench_linearisation.py`` (1000 closed-loop
runs, the same runs on every path; a run is *lost* when its EKF RMSE is over 5x the median run's),
``gramian-log-det`` on two suite geometries (``suite/gramian-offset-beacon.toml``: 2D range-only,
beacon off the survey centre; ``suite/gramian-slow-range.toml``: 0.2 Hz ranges): unbounded, the
plans peaked at ``b = 0.48`` and ``0.68 σ_r`` in their first minute and lost the EKF on 8 runs of
1000 each (worst runs 30 and 36 m; EKF RMSE 1.68 and 2.43 m against the lawn-mower's 0.49 and
0.72 m, the median run ahead of it); the lawn-mower and the circle (``b <= 0.19`` and ``0.24 σ_r``)
lost none. Bounded at ``0.25 σ_r``, the same problems: EKF RMSE 0.32 and 0.62 m, 3 and 0 runs over
5x the median (worst 3.5 and 3.4 m). ``gramian-min-eig`` on the same two lost more bounded than
unbounded (1 -> 5 and 2 -> 5 runs, EKF RMSE 0.34 -> 0.40 and 0.63 -> 0.74 m): its plans close on
the beacon along the line of sight however the opening is bounded (the mirror image of the path
about it fits the ranges as well: a global ambiguity, which a local stress does not see), so the
default bound is ``gramian-log-det``'s alone
(:data:`~obsplan.planning.problem.schema.LINEARISATION_KINDS`). The recursion runs over every epoch
of every sensor, so the bound costs most with a 10 Hz DVL (``range-dvl3d.toml``: 15 s -> 44 s per
``obsplan plan`` solve).

``b`` is evaluated on the posterior CRB's recursion (:func:`~obsplan.planning.
estimator_objectives.pcrb_objective`: the validation's prior, process noise, rates and noises,
what the EKF's covariance follows on a nominal run) at every range epoch after the first. The
penalty is ``c Σ_j max(0, b_j / (κ σ_r) - 1)²`` (``c``: ``Tuning.linearisation_penalty``): one
scalar, whose gradient is one reverse sweep of the recursion (a constraint per epoch needs the
recursion's dense Jacobian: the first trial took minutes to build where the penalty adds nothing
measurable), and elastic where the bound cannot hold (a start close to the beacon with a wide prior
is above it before the vehicle can move).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from obsplan.estimation.bounds.riccati import run_recursion
from obsplan.planning.objectives.estimator import covariance_objective
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import FormulationPart
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory


def _stress_function(n: int, m: int) -> ca.Function:
    """``(P (m, m), rel (n,)) -> tr((I - u uᵀ) P_pp) / (2 r)`` [m]."""
    P = ca.SX.sym("P", m, m)
    rel = ca.SX.sym("rel", n)
    Ppp = P[:n, :n]
    r2 = ca.sumsqr(rel)
    b = (ca.trace(Ppp) - ca.bilin(Ppp, rel, rel) / r2) / (2.0 * ca.sqrt(r2))
    return ca.Function("linearisation_stress", [P, rel], [b])


def stress_expr(pb: PlanningProblem, grid: Grid, W):
    """``b / σ_r`` (module docstring) at every range epoch after the first, from the path ``W``
    (intrinsic units): an ndarray of shape (J,) for an ndarray ``W``, else a CasADi column.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: the posterior CRB's recursion (its ``[validation]``) and
        ``validation.range_std``.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    ndarray, shape (J,), or casadi.MX
        The stress in range standard deviations (dimensionless), one per range epoch.
    """
    cov = covariance_objective(pb, "pcrb-position")
    h, rho = cov.rows(grid, W)  # h: the positions relative to the beacon at the epochs
    P_prior, _ = run_recursion(cov.model, cov.epochs, cov.P0, h, rho, cov.mask)
    n, m, J = cov.model.n, cov.model.m, cov.epochs.count
    # P_prior's block j is the prior at epoch j + 1, where the range is linearised
    each = _stress_function(n, m).map("linearisation_stress", "serial", J - 1, [], [])
    b = each(P_prior[:, : m * (J - 1)], h[:, 1:]) / pb.validation.range_std
    idx = np.flatnonzero(cov.mask[1:, cov.model.range_sensor] > 0)
    if isinstance(W, np.ndarray):
        return np.asarray(b, float).reshape(-1)[idx]
    return b.T[idx.tolist()]


def linearisation_stress(traj: Trajectory, pb: PlanningProblem) -> np.ndarray:
    """The EKF's linearisation stress ``b / σ_r`` (module docstring) along ``traj`` (on the
    problem's planning grid) at every range epoch after the first, shape (J,) [-].

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    ndarray, shape (J,)
        ``b / σ_r`` at each range epoch after the first (dimensionless).
    """
    grid = Grid.from_problem(pb)
    return np.asarray(stress_expr(pb, grid, grid.from_trajectory(traj)), float)


def penalty_expr(pb: PlanningProblem, grid: Grid, W, bound: float):
    """``c Σ_j max(0, b_j / (bound σ_r) - 1)²`` on the path ``W`` (CasADi or float; ``c`` the
    cost of an excess of the whole bound at one range epoch, ``Tuning.linearisation_penalty``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.
    bound : float
        ``κ``: the stress allowed, in range standard deviations.

    Returns
    -------
    float or casadi.MX
        The penalty, in the units of the normalised objective.
    """
    x = stress_expr(pb, grid, W) / bound - 1.0
    penalty = tuning().linearisation_penalty
    if isinstance(W, np.ndarray):
        return penalty * float(np.sum(np.maximum(x, 0.0) ** 2))
    return penalty * ca.sumsqr(ca.fmax(x, 0.0))


def penalty_bound(pb: PlanningProblem) -> float:
    """``κ`` of the problem's linearisation penalty [range stds]: the resolved
    ``objective.linearisation_bound``, 0 when it is off or the vehicle has no range.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    float
        The bound the planner's penalty holds; 0: no penalty in the NLP.
    """
    if "range" not in pb.model.sensors:
        return 0.0
    return max(pb.objective.resolved_linearisation_bound, 0.0)


def linearisation_part(pb: PlanningProblem, grid: Grid, W: ca.MX) -> FormulationPart | None:
    """The penalty of ``objective.linearisation_bound`` (None when it is 0 or the vehicle has no
    range).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.linearisation_bound`` (resolved) and its sensors.
    grid : Grid
        The planning grid of the problem.
    W : casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    FormulationPart or None
        ``"linearisation"`` with the penalty of :func:`penalty_expr`; None when it does not
        apply.
    """
    bound = penalty_bound(pb)
    if bound <= 0:
        return None
    return FormulationPart("linearisation", penalty=penalty_expr(pb, grid, W, bound))
