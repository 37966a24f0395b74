"""Objective values and metrics of a path, computed numerically and the same way for the planned
path and every baseline.

``objective``: the value of the problem's own objective (its registered
:attr:`~obsplan.planning.transcription.blocks.Objective.value`), in its own sign (larger is better
for the Gramian and LWO objectives, smaller for the covariance objectives; :func:`better`).
``min_eig``, ``log_det``, ``condition``: of the exact augmented Gramian in the problem's fixed
scales (:func:`~obsplan.planning.objectives.gramian.gramian_metrics`).
``pcrb_final_pos_std``, ``pcrb_mean_pos_std``: the posterior Cramér–Rao bound on the position
[m] at the end and averaged over the validation's filter samples (the ``pcrb-position``
objective's two modes, the same recursion as the validation's bound).
``kf_final_pos_std``, ``kf_mean_pos_std``: the augmented KF's predicted position std [m] (the
``kf-position-std`` objective's two modes).
``closest_approach_m`` / ``farthest_m``: exact extremes of ``|p(t) - b|`` on the continuous path.
``ekf_linearisation_stress``: the peak over the range epochs of the range's curvature over the
EKF's prior in range stds, ``tr((I - u uᵀ) P_pp) / (2 r σ_r)`` (:mod:`obsplan.planning
.linearisation`): unbounded log-det plans peaking at 0.48-0.68 lost the EKF on 8 runs in 1000,
the lawn-mower and the circle (at most 0.24) on none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from obsplan.planning.objectives.estimator import covariance_stds
from obsplan.planning.objectives.gramian import gramian_metrics
from obsplan.planning.objectives.linearisation import linearisation_stress
from obsplan.planning.objectives.registry import objective_of
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.feasibility import (
    LimitCheck,
    beacon_of,
    check_limits,
    range_extremes,
)
from obsplan.planning.problem.schema import MINIMISED
from obsplan.trajectory.sampled import Trajectory


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def objective_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The problem's objective evaluated (numerically, without lifting variables) on ``traj``.

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem: its ``objective.kind`` and settings.

    Returns
    -------
    float
        The value in the objective's own sign and units (:func:`better` compares two).
    """
    return objective_of(pb).value(traj, pb)


def kf_final_pos_std(traj: Trajectory, pb: PlanningProblem) -> float:
    """Predicted final position std ``sqrt(tr P_pp)`` [m] of the augmented KF along ``traj``.

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem: its vehicle model, ``[validation]`` and ``[scales]``.

    Returns
    -------
    float
        The std at the end of the horizon [m].
    """
    return covariance_stds(traj, pb, "kf-position-std")[1]


@dataclass(frozen=True)
class PathMetrics:
    """Observability and estimation metrics of one path (see module docstring)."""

    min_eig: float
    log_det: float
    condition: float
    pcrb_final_pos_std: float
    pcrb_mean_pos_std: float
    kf_final_pos_std: float | None
    kf_mean_pos_std: float | None
    closest_approach_m: float
    farthest_m: float
    objective: float
    limits: LimitCheck
    ekf_linearisation_stress: float = math.nan

    @property
    def within_limits(self) -> bool:
        return self.limits.ok()

    def to_dict(self) -> dict:
        """JSON-safe (``null`` for non-finite values).

        Returns
        -------
        dict
            Every metric by name, ``within_limits`` and ``limit_violation``
            (:meth:`~obsplan.planning.problem.feasibility.LimitCheck.to_dict`).
        """
        return {
            "min_eig": _num(self.min_eig),
            "log_det": _num(self.log_det),
            "condition": _num(self.condition),
            "pcrb_final_pos_std": _num(self.pcrb_final_pos_std),
            "pcrb_mean_pos_std": _num(self.pcrb_mean_pos_std),
            "kf_final_pos_std": _num(self.kf_final_pos_std),
            "kf_mean_pos_std": _num(self.kf_mean_pos_std),
            "closest_approach_m": _num(self.closest_approach_m),
            "farthest_m": _num(self.farthest_m),
            "ekf_linearisation_stress": _num(self.ekf_linearisation_stress),
            "objective": _num(self.objective),
            "within_limits": bool(self.within_limits),
            "limit_violation": self.limits.to_dict(),
        }


def better(a: float, b: float, pb: PlanningProblem) -> bool:
    """True when objective value ``a`` is strictly better than ``b`` for ``pb``.

    Parameters
    ----------
    a, b : float
        Two values of ``pb``'s objective (:func:`objective_value`).
    pb : PlanningProblem
        The problem: its ``objective.kind`` says whether smaller or larger is better.

    Returns
    -------
    bool
        A non-finite ``a`` is never better; a finite ``a`` beats a non-finite ``b``.
    """
    if not math.isfinite(a):
        return False
    if not math.isfinite(b):
        return True
    if pb.objective.kind in MINIMISED:
        return a < b
    return a > b


def path_metrics(traj: Trajectory, pb: PlanningProblem) -> PathMetrics:
    """All metrics of ``traj`` (on the planning grid) for problem ``pb``.

    Parameters
    ----------
    traj : Trajectory
        The path (the plan or a baseline), on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    PathMetrics
        The metrics of the module docstring and the limit check.
    """
    min_eig, log_det, cond = gramian_metrics(traj, pb)
    pcrb_mean, pcrb_final = covariance_stds(traj, pb, "pcrb-position")
    kf_mean, kf_final = None, None
    if pb.beacon_path is None:  # the planning KF's recursion is a fixed beacon's
        kf_mean, kf_final = covariance_stds(traj, pb, "kf-position-std")
    near, far = range_extremes(traj, beacon_of(pb))
    return PathMetrics(
        min_eig=min_eig,
        log_det=log_det,
        condition=cond,
        pcrb_final_pos_std=pcrb_final,
        pcrb_mean_pos_std=pcrb_mean,
        kf_final_pos_std=kf_final,
        kf_mean_pos_std=kf_mean,
        closest_approach_m=near,
        farthest_m=far,
        objective=objective_value(traj, pb),
        limits=check_limits(traj, pb),
        ekf_linearisation_stress=_peak_stress(traj, pb),
    )


def _peak_stress(traj: Trajectory, pb: PlanningProblem) -> float:
    """The largest EKF linearisation stress ``b / σ_r`` along ``traj`` (NaN with no range epoch
    after the first)."""
    b = linearisation_stress(traj, pb)
    return float(b.max()) if b.size else math.nan
