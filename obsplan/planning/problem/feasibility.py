"""Independent (numpy-only) check that a path respects a problem's limits and dynamics.

Used on every solver output and every baseline, and by the tests, without CasADi: the planner's
constraints are verified here on the continuous path, not only at the nodes. The tolerances are
``Tuning.limit_rtol`` and ``Tuning.consistency_tol``, read at call time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.model.beacon import BeaconPath
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.tuning import tuning
from obsplan.trajectory.relative import relative_trajectory
from obsplan.trajectory.sampled import Trajectory


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
    range : float
        Largest excursion [m] of ``|p(t) - b|`` below ``limits.min_range`` or above
        ``limits.max_range`` (exact extremes of the quartic ``|p(t) - b|²`` between nodes).
    water_speed : float
        ``(v_min - min_t |p'(t) - v_f|) / v_min`` (relative; exact: the squared speed is a convex
        quadratic between nodes); 0 without a minimum speed.
    start : float
        Distance [m] + speed mismatch [m/s] of the first sample from the problem's start.
    consistency_pos, consistency_vel : float
        One-step integration mismatch [m], [m/s].
    """

    accel: float
    speed: float
    box: float
    range: float
    water_speed: float
    start: float
    consistency_pos: float
    consistency_vel: float

    def ok(self, rtol: float | None = None, box_tol_m: float | None = None) -> bool:
        """True when every limit holds to ``rtol`` (default ``Tuning.limit_rtol``; the
        box and ranges to ``box_tol_m``, default ``100 rtol`` [m]) and the samples are
        consistent (``Tuning.consistency_tol``).

        Parameters
        ----------
        rtol : float or None, optional
            Relative tolerance of the acceleration, speed and water-speed limits; None:
            ``Tuning.limit_rtol``.
        box_tol_m : float or None, optional
            Tolerance [m] of the area, depth band and range limits; None: ``100 rtol``.

        Returns
        -------
        bool
            True when every violation is within its tolerance, the first sample within 1e-6 of
            the start and the samples consistent.
        """
        tun = tuning()
        if rtol is None:
            rtol = tun.limit_rtol
        btol = rtol * 100.0 if box_tol_m is None else box_tol_m
        return (
            self.accel <= rtol
            and self.speed <= rtol
            and self.box <= btol
            and self.range <= btol
            and self.water_speed <= rtol
            and self.start <= 1e-6
            and self.consistency_pos <= tun.consistency_tol
            and self.consistency_vel <= tun.consistency_tol
        )

    def to_dict(self) -> dict:
        """The violations for ``report.json``.

        Returns
        -------
        dict of str to float
            Every field by name (relative, [m] or [m/s] as in the class docstring).
        """
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


def _interval_extremes(c: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Min and max over ``s`` in ``[0, h_k]`` of ``|c0 + c1 s + c2 s²|²`` per interval.

    ``c`` has shape ``(3, K, n)``. The derivative is the cubic ``2 (c0 + c1 s + c2 s²)·(c1 +
    2 c2 s)``; its real roots inside the interval and the two ends are the candidates.
    """
    c0, c1, c2 = c
    coef = np.stack(
        [
            2 * np.einsum("ki,ki->k", c2, c2),
            3 * np.einsum("ki,ki->k", c1, c2),
            np.einsum("ki,ki->k", c1, c1) + 2 * np.einsum("ki,ki->k", c0, c2),
            np.einsum("ki,ki->k", c0, c1),
        ],
        axis=1,
    )

    def f(s):
        q = c0 + c1 * s[:, None] + c2 * s[:, None] ** 2
        return np.einsum("ki,ki->k", q, q)

    lo = np.minimum(f(np.zeros_like(h)), f(h))
    hi = np.maximum(f(np.zeros_like(h)), f(h))
    for k in np.flatnonzero(np.any(coef != 0, axis=1)):
        roots = np.roots(coef[k])
        roots = roots[np.abs(roots.imag) <= 1e-12 * max(1.0, h[k])].real
        roots = roots[(roots > 0) & (roots < h[k])]
        if roots.size:
            q = c0[k] + np.outer(roots, c1[k]) + np.outer(roots**2, c2[k])
            vals = np.einsum("ri,ri->r", q, q)
            lo[k] = min(lo[k], vals.min())
            hi[k] = max(hi[k], vals.max())
    return lo, hi


def range_extremes(traj: Trajectory, beacon) -> tuple[float, float]:
    """Exact ``(min, max)`` of ``|p(t) - b|`` [m] over the continuous path.

    Parameters
    ----------
    traj : Trajectory
        The path (exact quadratics between its samples).
    beacon : array_like, shape (n,), or BeaconPath
        Beacon position ``b`` [m], or its known path ``b(t)`` (then the distance to where it
        is at each time, exact on the relative path of
        :func:`~obsplan.trajectory.relative.relative_trajectory`).

    Returns
    -------
    near : float
        Least distance to the beacon [m].
    far : float
        Greatest distance to the beacon [m].
    """
    if isinstance(beacon, BeaconPath):
        traj, _ = relative_trajectory(traj, beacon, "beacon.path")
        beacon = np.zeros(traj.dim)
    rel = traj.p - np.asarray(beacon, float)
    c = np.stack([rel[:-1], traj.v[:-1], 0.5 * traj.u[:-1]])
    lo, hi = _interval_extremes(c, traj.dt)
    return float(np.sqrt(max(lo.min(), 0.0))), float(np.sqrt(hi.max()))


def beacon_of(pb: PlanningProblem) -> np.ndarray | BeaconPath:
    """The beacon the vehicle's distance limits are to: its known path when it moves on one
    (``beacon.motion = "path"``), else its position.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    ndarray, shape (n,), or BeaconPath
        What :func:`range_extremes` takes.
    """
    path = pb.beacon_path
    return np.asarray(pb.beacon, float) if path is None else path


def min_water_speed(traj: Trajectory, current: np.ndarray) -> float:
    """Exact ``min_t |p'(t) - v_f|`` [m/s] over the continuous path.

    Parameters
    ----------
    traj : Trajectory
        The path (velocity linear between its samples).
    current : ndarray, shape (n,)
        Ocean current ``v_f`` [m/s].

    Returns
    -------
    float
        The least speed through the water [m/s].
    """
    w = traj.v[:-1] - np.asarray(current, float)
    u = traj.u[:-1]
    uu = np.einsum("ki,ki->k", u, u)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(uu > 0, -np.einsum("ki,ki->k", w, u) / uu, 0.0)
    s = np.clip(s, 0.0, traj.dt)
    inner = w + u * s[:, None]
    ends = np.linalg.norm(traj.v - np.asarray(current, float), axis=1)
    return float(min(np.linalg.norm(inner, axis=1).min(), ends.min()))


def check_limits(traj: Trajectory, pb: PlanningProblem) -> LimitCheck:
    """Check ``traj`` against the limits, start and dynamics of ``pb`` (see :class:`LimitCheck`).

    Parameters
    ----------
    traj : Trajectory
        The path (a plan or a baseline), checked on the continuous path between its samples.
    pb : PlanningProblem
        The problem: its ``limits``, acceleration bounds, start state and current.

    Returns
    -------
    LimitCheck
        The largest violation of each limit (0 when satisfied); :meth:`LimitCheck.ok` judges it.
    """
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
    lim = pb.limits
    rng = 0.0
    if lim.min_range > 0 or lim.max_range is not None:
        near, far = range_extremes(traj, beacon_of(pb))
        rng = max(rng, lim.min_range - near)
        if lim.max_range is not None:
            rng = max(rng, far - lim.max_range)
    water = 0.0
    if lim.min_speed > 0:
        water = (lim.min_speed - min_water_speed(traj, pb.current_array)) / lim.min_speed
    start = float(np.linalg.norm(traj.p[0] - pb.p0) + np.linalg.norm(traj.v[0] - pb.v0))
    pe, ve = traj.consistency_error()
    return LimitCheck(
        accel=max(acc, 0.0),
        speed=max(speed, 0.0),
        box=max(box, 0.0),
        range=max(rng, 0.0),
        water_speed=max(water, 0.0),
        start=start,
        consistency_pos=pe,
        consistency_vel=ve,
    )
