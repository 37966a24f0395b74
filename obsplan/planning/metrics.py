"""Metrics of a path, computed the same way for the planned path and every baseline.

``min_eig``, ``log_det``, ``condition``: of the exact augmented Gramian in the problem's fixed
scales (:func:`obsplan.observability.gramian.gramian`,
:func:`obsplan.observability.scaling.psd_metrics`).
``pcrb_final_pos_std``, ``pcrb_mean_pos_std``: the posterior Cramér–Rao bound on the position
[m] at the end and averaged over the validation's filter samples (the ``pcrb-position``
objective's two modes, the same recursion as the validation's bound).
``kf_final_pos_std``, ``kf_mean_pos_std``: the augmented KF's predicted position std [m] (the
``kf-position-std`` objective's two modes).
``closest_approach_m`` / ``farthest_m``: exact extremes of ``|p(t) - b|`` on the continuous path.
``objective``: the value of the problem's own objective, in its own sign (larger is better for
the Gramian and LWO objectives, smaller for the covariance objectives).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from obsplan.model import VehicleModel
from obsplan.observability.gramian import gramian
from obsplan.observability.scaling import numerical_rank, psd_metrics
from obsplan.planning.feasibility import LimitCheck, check_limits, range_extremes
from obsplan.planning.objectives import (
    CovarianceObjective,
    Grid,
    covariance_objective,
    lwo_conditions,
    lwo_softmin,
    reference_path,
    timed_value,
)
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

#: Objectives for which a smaller value is better.
MINIMISED = ("pcrb-position", "kf-position-std")


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


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

    @property
    def within_limits(self) -> bool:
        return self.limits.ok()

    def to_dict(self) -> dict:
        """JSON-safe (``null`` for non-finite values)."""
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
            "objective": _num(self.objective),
            "within_limits": bool(self.within_limits),
            "limit_violation": self.limits.to_dict(),
        }


@cache
def _covariance(pb: PlanningProblem, kind: str) -> CovarianceObjective:
    return covariance_objective(pb, kind)


def covariance_stds(traj: Trajectory, pb: PlanningProblem, kind: str) -> tuple[float, float]:
    """``(mission-average, final)`` position std [m] of the ``kind`` recursion along ``traj``.

    ``kind`` is ``"pcrb-position"`` or ``"kf-position-std"``; ``traj`` must be on the problem's
    planning grid (N + 1 samples).
    """
    grid = Grid.from_problem(pb)
    return _covariance(pb, kind).evaluate(grid, grid.from_trajectory(traj))


def kf_final_pos_std(traj: Trajectory, pb: PlanningProblem) -> float:
    """Predicted final position std ``sqrt(tr P_pp)`` [m] of the augmented KF along ``traj``."""
    return covariance_stds(traj, pb, "kf-position-std")[1]


def lwo_condition(traj: Trajectory, pb: PlanningProblem) -> float:
    """``min_k λ_min(O_kᵀO_k) / (tr(O_kᵀO_k)/m)`` in the problem's scales (the LWO objective)."""
    from obsplan.observability.lwo import lwo_matrices

    L, T = pb.scales.length_m, pb.scales.time_s
    b = np.asarray(pb.beacon, float)
    tr = Trajectory(t=traj.t / T, p=(traj.p - b) / L, v=traj.v * T / L, u=traj.u * T**2 / L)
    m = pb.model
    nd = VehicleModel(dim=m.dim, sensors=m.sensors, current=m.current, range_form=m.range_form)
    O = lwo_matrices(tr, nd, 0)
    M = np.swapaxes(O, 1, 2) @ O
    ev = np.linalg.eigvalsh(M)
    return float(np.min(ev[:, 0] / (np.trace(M, axis1=1, axis2=2) / M.shape[-1])))


def gramian_metrics(traj: Trajectory, pb: PlanningProblem) -> tuple[float, float, float]:
    """``(min_eig, log_det, condition)`` of the scaled Gramian; ``(0, -inf, inf)`` when the
    unit-invariant rank test finds it rank deficient (round-off must not read as information:
    a 3D lawn-mower at constant depth has a 1e-17 "lambda_min" at N = 1000)."""
    G = gramian(traj, pb.model, pb.scales)
    if numerical_rank(G) < G.shape[0]:
        return 0.0, float("-inf"), float("inf")
    return psd_metrics(G)


def objective_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The problem's objective evaluated (numerically, without lifting variables) on ``traj``."""
    kind = pb.objective.kind
    if kind == "gramian-min-eig":
        return gramian_metrics(traj, pb)[0]
    if kind == "gramian-log-det":
        return gramian_metrics(traj, pb)[1]
    if kind == "lwo-condition":
        grid = Grid.from_problem(pb)
        return lwo_softmin(lwo_conditions(grid, pb, grid.from_trajectory(traj)))
    avg, final = covariance_stds(traj, pb, kind)
    return timed_value(pb.objective_mode, avg, final, _reference_stds(pb, kind))


@cache
def _reference_stds(pb: PlanningProblem, kind: str) -> tuple[float, float]:
    return covariance_stds(reference_path(pb), pb, kind)


def better(a: float, b: float, pb: PlanningProblem) -> bool:
    """True when objective value ``a`` is strictly better than ``b`` for ``pb``."""
    if not math.isfinite(a):
        return False
    if not math.isfinite(b):
        return True
    if pb.objective.kind in MINIMISED:
        return a < b
    return a > b


def path_metrics(traj: Trajectory, pb: PlanningProblem) -> PathMetrics:
    """All metrics of ``traj`` (on the planning grid) for problem ``pb``."""
    min_eig, log_det, cond = gramian_metrics(traj, pb)
    pcrb_mean, pcrb_final = covariance_stds(traj, pb, "pcrb-position")
    kf_mean, kf_final = covariance_stds(traj, pb, "kf-position-std")
    near, far = range_extremes(traj, pb.beacon)
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
    )
