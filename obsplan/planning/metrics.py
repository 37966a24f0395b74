"""Metrics of a path, computed the same way for the planned path and every baseline.

``min_eig``, ``log_det``, ``condition``: of the exact augmented Gramian in the problem's fixed
scales (:func:`obsplan.observability.gramian.gramian`,
:func:`obsplan.observability.scaling.psd_metrics`).
``kf_final_pos_std``: the planning KF's predicted final position standard deviation [m] (the
Riccati recursion of :mod:`obsplan.planning.objectives`, evaluated numerically).
``objective``: the value of the problem's own objective, in its own sign (larger is better for
the Gramian and LWO objectives, smaller for ``kf-position-std``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from obsplan.model import VehicleModel
from obsplan.observability.gramian import gramian
from obsplan.observability.scaling import psd_metrics
from obsplan.planning.feasibility import LimitCheck, check_limits
from obsplan.planning.objectives import Grid, kf_position_std_expr
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class PathMetrics:
    """Observability and estimation metrics of one path (see module docstring)."""

    min_eig: float
    log_det: float
    condition: float
    kf_final_pos_std: float | None
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
            "kf_final_pos_std": _num(self.kf_final_pos_std),
            "objective": _num(self.objective),
            "within_limits": bool(self.within_limits),
            "limit_violation": self.limits.to_dict(),
        }


@cache
def _kf_function(pb: PlanningProblem) -> ca.Function:
    grid = Grid.from_problem(pb)
    W = ca.MX.sym("W", 3 * grid.n, grid.N)
    return ca.Function("kf_std", [W], [kf_position_std_expr(grid, pb, W)])


def kf_final_pos_std(traj: Trajectory, pb: PlanningProblem) -> float:
    """Predicted final position std ``sqrt(tr P_pp)`` [m] of the augmented KF along ``traj``.

    ``traj`` must be on the problem's planning grid (N + 1 samples).
    """
    grid = Grid.from_problem(pb)
    U, P, V = grid.from_trajectory(traj)
    return float(_kf_function(pb)(np.vstack([U, P, V])))


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


def objective_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The problem's objective evaluated (numerically, without lifting variables) on ``traj``."""
    kind = pb.objective.kind
    if kind == "gramian-min-eig":
        return psd_metrics(gramian(traj, pb.model, pb.scales))[0]
    if kind == "gramian-log-det":
        return psd_metrics(gramian(traj, pb.model, pb.scales))[1]
    if kind == "lwo-condition":
        return lwo_condition(traj, pb)
    return kf_final_pos_std(traj, pb)


def better(a: float, b: float, pb: PlanningProblem) -> bool:
    """True when objective value ``a`` is strictly better than ``b`` for ``pb``."""
    if pb.objective.kind == "kf-position-std":
        return a < b
    return a > b


def path_metrics(traj: Trajectory, pb: PlanningProblem) -> PathMetrics:
    """All metrics of ``traj`` (on the planning grid) for problem ``pb``."""
    min_eig, log_det, cond = psd_metrics(gramian(traj, pb.model, pb.scales))
    kf = kf_final_pos_std(traj, pb)
    return PathMetrics(
        min_eig=min_eig,
        log_det=log_det,
        condition=cond,
        kf_final_pos_std=kf,
        objective=objective_value(traj, pb),
        limits=check_limits(traj, pb),
    )
