"""Independent (numpy-only) check that a path respects a problem's limits and dynamics.

Used on every solver output and every baseline, and by the tests, without CasADi: the planner's
constraints are verified here on the continuous path, not only at the nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

#: Relative tolerance on every limit (acceleration, speed, box) for "within limits": IPOPT
#: satisfies bounds to ~1e-8 relative (bound_relax_factor, constraint tolerance), so 1e-6 flags
#: only real violations.
LIMIT_RTOL: float = 1e-6
#: Dynamic consistency: one-step mismatch [m] and [m/s] (exact integration gives ~1e-12).
CONSISTENCY_TOL: float = 1e-6


@dataclass(frozen=True)
class LimitCheck:
    """Largest violation of each limit on the continuous path (0 when satisfied).

    Attributes
    ----------
    accel : float
        ``max_k,i (|u_k,i| - a_i) / a_i`` (relative).
    speed : float
        ``(max_t |p'(t)| - v_max) / v_max`` (relative; exact from the nodes, speed is convex
        between them).
    box : float
        Largest excursion [m] of ``p(t)`` outside the depth band or operating area, using the
        exact quadratic between nodes.
    start : float
        Distance [m] + speed mismatch [m/s] of the first sample from the problem's start.
    consistency_pos, consistency_vel : float
        One-step integration mismatch [m], [m/s].
    """

    accel: float
    speed: float
    box: float
    start: float
    consistency_pos: float
    consistency_vel: float

    def ok(self, rtol: float = LIMIT_RTOL, box_tol_m: float | None = None) -> bool:
        """True when every limit holds to ``rtol`` and the samples are consistent."""
        btol = rtol * 100.0 if box_tol_m is None else box_tol_m
        return (
            self.accel <= rtol
            and self.speed <= rtol
            and self.box <= btol
            and self.start <= 1e-6
            and self.consistency_pos <= CONSISTENCY_TOL
            and self.consistency_vel <= CONSISTENCY_TOL
        )

    def to_dict(self) -> dict:
        return {k: float(getattr(self, k)) for k in self.__dataclass_fields__}


def _axis_extremes(traj: Trajectory, axis: int) -> tuple[float, float]:
    """Exact min and max of ``p_axis(t)`` over the piecewise-quadratic path."""
    p, v, u = traj.p[:, axis], traj.v[:, axis], traj.u[:, axis]
    h = traj.dt
    lo, hi = float(p.min()), float(p.max())
    vk, uk, pk = v[:-1], u[:-1], p[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(uk != 0, -vk / uk, -1.0)
    inside = (s > 0) & (s < h)
    if np.any(inside):
        ext = pk[inside] + vk[inside] * s[inside] + 0.5 * uk[inside] * s[inside] ** 2
        lo, hi = min(lo, float(ext.min())), max(hi, float(ext.max()))
    return lo, hi


def check_limits(traj: Trajectory, pb: PlanningProblem) -> LimitCheck:
    """Check ``traj`` against the limits, start and dynamics of ``pb`` (see :class:`LimitCheck`)."""
    a = pb.accel
    acc = float(np.max((np.abs(traj.u[:-1]) - a) / a))
    speed = float(np.max(np.linalg.norm(traj.v, axis=1)) - pb.limits.speed) / pb.limits.speed
    box = 0.0
    boxes = []
    if pb.limits.area is not None:
        boxes += [(0, pb.limits.area.x), (1, pb.limits.area.y)]
    if pb.limits.depth is not None:
        boxes.append((2, pb.limits.depth))
    for axis, (lo, hi) in boxes:
        mn, mx = _axis_extremes(traj, axis)
        box = max(box, lo - mn, mx - hi)
    start = float(np.linalg.norm(traj.p[0] - pb.p0) + np.linalg.norm(traj.v[0] - pb.v0))
    pe, ve = traj.consistency_error()
    return LimitCheck(
        accel=max(acc, 0.0),
        speed=max(speed, 0.0),
        box=max(box, 0.0),
        start=start,
        consistency_pos=pe,
        consistency_vel=ve,
    )
