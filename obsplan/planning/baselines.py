"""Baseline paths under the same limits, horizon and start as a planning problem.

Every baseline starts at the problem's start state, lasts the horizon, is sampled on the planning
grid (so every metric is computed the same way as for the plan) and is built by exact integration
of piecewise-constant inputs that respect the acceleration and speed limits:

* ``lawnmower``: :func:`obsplan.generators.lawnmower_within_limits`, legs at the speed limit (or
  the fastest speed whose turns at the acceleration limit fit the area) and turns at the
  acceleration limit, covering the problem's :meth:`~PlanningProblem.coverage_area` from the start
  (3D: at the start depth).
* ``circle``: about the beacon through the start (constant depth in 3D), accelerating
  tangentially from the start speed to the fastest speed whose centripetal and tangential
  accelerations stay within the limit.
* ``straight``: from the start along its velocity (or, at rest, perpendicular to the beacon
  direction: a non-radial line), accelerating at the limit to the fastest cruise that stays in
  the area.
* ``paper-lawnmower``: the paper's Fig. 3 (2D) / Fig. 6 (3D) lawn-mower
  (:func:`obsplan.generators.paper_lawnmower`) time-scaled so that its speed or acceleration
  reaches the limits, translated to the start, continued straight if shorter than the horizon;
  only when its (scaled) start velocity equals the problem's.

A baseline that cannot be built for a problem (e.g. a start velocity not tangent to the circle) is
left out, with the reason in :func:`baseline_notes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsplan import generators
from obsplan.errors import ConfigError, ProblemError
from obsplan.planning.problem import Area, PlanningProblem
from obsplan.trajectory import Trajectory

#: Velocity mismatch [m/s] below which two start velocities are "the same".
_START_TOL = 1e-6


@dataclass(frozen=True)
class Baseline:
    """A named baseline path with a one-line description."""

    name: str
    trajectory: Trajectory
    description: str


def _ray_to_box(p: np.ndarray, e: np.ndarray, area: Area) -> float:
    """Distance from ``p`` along unit ``e`` (xy) to the boundary of ``area`` [m]."""
    out = math.inf
    for k, (lo, hi) in enumerate((area.x, area.y)):
        if e[k] > 1e-12:
            out = min(out, (hi - p[k]) / e[k])
        elif e[k] < -1e-12:
            out = min(out, (lo - p[k]) / e[k])
    return max(out, 0.0)


def _check_grid(traj: Trajectory, pb: PlanningProblem, name: str) -> Trajectory:
    t = pb.times
    if traj.n_samples != t.size or not np.allclose(traj.t, t, rtol=0, atol=1e-9 * t[-1]):
        raise ConfigError(f"baseline {name}: not on the planning grid")  # pragma: no cover
    return Trajectory(t=t, p=traj.p, v=traj.v, u=traj.u)


def lawnmower_baseline(pb: PlanningProblem) -> Baseline:
    """Lawn-mower at the limits over the coverage area (see module docstring)."""
    a = float(np.min(pb.accel[:2]))  # |u| <= a keeps every axis within its bound
    area = pb.coverage_area()
    p0, v0 = pb.p0, pb.v0
    s0 = float(np.linalg.norm(v0[:2]))
    if s0 > 0:
        heading = math.atan2(v0[1], v0[0])
    else:
        heading = 0.0 if area.x[1] - p0[0] >= p0[0] - area.x[0] else math.pi
    e = np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-e[1], e[0]])
    room_left, room_right = _ray_to_box(p0, left, area), _ray_to_box(p0, -left, area)
    first_turn = "left" if room_left >= room_right else "right"
    height = max(room_left, room_right)
    ahead = _ray_to_box(p0, e, area)
    # the fastest speed <= v_max whose turns (radius v^2/a, spacing 2 v^2/a) fit the area
    # (90 % of the room, leaving space for the chord margin below)
    speed = min(pb.limits.speed, math.sqrt(0.45 * a * height), math.sqrt(0.45 * a * ahead))
    speed = max(speed * (1 - 1e-9), s0)
    radius = speed**2 / a
    # chord inputs fly a turn up to radius (w h)^2 / 6 outside the arc (generators docstring):
    # keep that margin inside the area
    margin = 1.5 * radius * (speed / radius * pb.horizon.dt) ** 2 / 6.0
    try:
        traj = generators.lawnmower_within_limits(
            p0[:2],
            ahead + radius - margin,
            height - margin,
            speed,
            a,
            pb.horizon.duration,
            pb.horizon.dt,
            heading=heading,
            first_turn=first_turn,  # type: ignore[arg-type]
            z=float(p0[2]) if pb.dim == 3 else None,
            z_speed=0.0,
            initial_speed=s0,
        )
    except ConfigError as exc:
        raise ProblemError(
            f"limits.area: no lawn-mower baseline fits between the start and the area's edges "
            f"({exc}); enlarge the area or move the start towards a corner"
        ) from None
    lay = generators.lawnmower_layout(ahead + radius - margin, height - margin, speed, a)
    desc = (
        f"lawn-mower covering {lay.covered_width:.4g} m x {lay.covered_height:.4g} m "
        f"({lay.n_legs} legs) at {speed:.3g} m/s, turns of radius {radius:.3g} m at {a:g} m/s^2"
    )
    return Baseline("lawnmower", _check_grid(traj, pb, "lawnmower"), desc)


def _fly_velocity(pb: PlanningProblem, vel) -> Trajectory:
    """Chord inputs ``u_k = (v*(t_{k+1}) - v*(t_k)) / h`` of an analytic velocity, integrated."""
    t = pb.times
    V = vel(t)
    u = np.diff(V, axis=0) / np.diff(t)[:, None]
    return Trajectory.from_inputs(t, pb.p0, V[0], u)


def circle_baseline(pb: PlanningProblem) -> Baseline | None:
    """Circle about the beacon through the start (see module docstring); None if impossible."""
    b = np.asarray(pb.beacon, float)
    rel = (pb.p0 - b)[:2]
    rho = float(np.linalg.norm(rel))
    if rho < 1e-6:
        return None
    a = float(np.min(pb.accel[:2]))
    tangent = np.array([-rel[1], rel[0]]) / rho
    v0 = pb.v0[:2]
    s0 = float(np.dot(v0, tangent))
    if np.linalg.norm(v0 - s0 * tangent) > _START_TOL or (pb.dim == 3 and abs(pb.v0[2]) > 0):
        return None
    sign = 1.0 if s0 >= 0 else -1.0
    s0 = abs(s0)
    # at cruise the centripetal acceleration is 0.8 a; while speeding up at 0.6 a the total stays
    # <= sqrt(0.36 + 0.64) a = a
    vc = max(min(pb.limits.speed, math.sqrt(0.8 * a * rho)), s0)
    at = 0.6 * a
    t_ramp = (vc - s0) / at
    th0 = math.atan2(rel[1], rel[0])

    def vel(t: np.ndarray) -> np.ndarray:
        tr = np.minimum(t, t_ramp)
        s = s0 + at * tr
        arc = s0 * tr + 0.5 * at * tr**2 + vc * np.maximum(t - t_ramp, 0.0)
        th = th0 + sign * arc / rho
        out = np.column_stack([-np.sin(th), np.cos(th)]) * (sign * s)[:, None]
        if pb.dim == 3:
            out = np.column_stack([out, np.zeros_like(t)])
        return out

    traj = _fly_velocity(pb, vel)
    desc = f"circle about the beacon, radius {rho:.3g} m, cruise {vc:.3g} m/s"
    return Baseline("circle", traj, desc)


def straight_baseline(pb: PlanningProblem) -> Baseline:
    """Straight line from the start (see module docstring)."""
    b = np.asarray(pb.beacon, float)
    v0 = pb.v0
    s0 = float(np.linalg.norm(v0))
    if s0 > 0:
        e = v0 / s0
    else:
        # the horizontal direction with the most room among the axes and the two tangents to
        # the beacon circle, excluding radial ones (a radial line is trivially unobservable)
        rel = (pb.p0 - b)[:2]
        cands = [np.array(c, float) for c in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        if np.linalg.norm(rel) > 0:
            tang = np.array([-rel[1], rel[0]]) / np.linalg.norm(rel)
            cands += [tang, -tang]
            cands = [c for c in cands if abs(c @ rel) < 0.999 * np.linalg.norm(rel)]
        area = pb.limits.area
        e2 = max(cands, key=lambda c: _ray_to_box(pb.p0, c, area) if area else 0.0)
        e = np.zeros(pb.dim)
        e[:2] = e2
    a = float(np.min(pb.accel[np.abs(e) > 1e-12]))
    a_line = a / float(np.max(np.abs(e)))  # per-axis |a_line e_i| <= a_i
    a_line = min(a_line, float(np.min(pb.accel[np.abs(e) > 1e-12] / np.abs(e[np.abs(e) > 1e-12]))))
    T = pb.horizon.duration
    room = math.inf
    if pb.limits.area is not None:
        room = _ray_to_box(pb.p0, e[:2], pb.limits.area) if np.linalg.norm(e[:2]) > 0 else room
    if pb.limits.depth is not None and abs(e[2]) > 1e-12:
        lo, hi = pb.limits.depth
        room = min(room, ((hi if e[2] > 0 else lo) - pb.p0[2]) / e[2])

    def dist(v: float) -> float:
        tr = min((v - s0) / a_line, T)
        return s0 * tr + 0.5 * a_line * tr**2 + v * max(T - tr, 0.0)

    vmax = pb.limits.speed
    v = vmax
    if dist(vmax) > 0.98 * room:  # bisection on the cruise speed to stay in the area
        lo_v, hi_v = s0, vmax
        for _ in range(60):
            mid = 0.5 * (lo_v + hi_v)
            lo_v, hi_v = (mid, hi_v) if dist(mid) <= 0.98 * room else (lo_v, mid)
        v = lo_v
    h = pb.horizon.dt
    acc = np.zeros(pb.horizon.steps)
    s = s0
    for k in range(acc.size):
        acc[k] = min(a_line, max(0.0, (v - s) / h))
        s += acc[k] * h
    if s0 == 0 and not np.any(acc):
        acc[0] = min(a_line, 1e-3)
    traj = generators.straight(pb.p0, e, s0, accel=acc, duration=T, dt=h)
    desc = f"straight line, cruise {v:.3g} m/s"
    return Baseline("straight", _check_grid(traj, pb, "straight"), desc)


def paper_lawnmower_baseline(pb: PlanningProblem) -> Baseline | None:
    """The paper's lawn-mower time-scaled to the limits (see module docstring); None if n/a."""
    h = pb.horizon.dt
    s = 1.0
    # t -> s t divides speeds by s and accelerations by s^2; the chord inputs depend on the
    # sampling step h / s, so iterate to the fixed point (converges in a few steps)
    for _ in range(8):
        ref = generators.paper_lawnmower(pb.dim, dt=h / s)
        speed = float(np.max(np.linalg.norm(ref.v, axis=1)))
        accel = float(np.max(np.abs(ref.u[:-1]) / pb.accel))
        s_new = max(speed / pb.limits.speed, math.sqrt(accel))
        if abs(s_new - s) <= 1e-12 * s:
            break
        s = s_new
    ref = generators.paper_lawnmower(pb.dim, dt=h / s)
    v_start = ref.v[0] / s
    if np.linalg.norm(v_start - pb.v0) > _START_TOL:
        return None
    scaled = Trajectory(t=ref.t * s, p=ref.p - ref.p[0] + pb.p0, v=ref.v / s, u=ref.u / s**2)
    N = pb.horizon.steps
    if scaled.n_samples < N + 1:
        remaining = pb.horizon.duration - scaled.t[-1]
        if not np.isclose(scaled.t[-1] / h, round(scaled.t[-1] / h), atol=1e-6):
            return None
        scaled = generators.then_straight(scaled, duration=remaining, dt=h)
    scaled = scaled.window(0, N + 1)
    desc = f"paper lawn-mower (Fig. {3 if pb.dim == 2 else 6}) time-scaled by {s:.3g}"
    return Baseline("paper-lawnmower", _check_grid(scaled, pb, "paper-lawnmower"), desc)


def baselines(pb: PlanningProblem) -> dict[str, Baseline]:
    """Every baseline that can be built for ``pb``, by name (lawn-mower first)."""
    out: dict[str, Baseline] = {"lawnmower": lawnmower_baseline(pb)}
    for fn in (circle_baseline, straight_baseline, paper_lawnmower_baseline):
        bl = fn(pb)
        if bl is not None:
            out[bl.name] = bl
    return out
