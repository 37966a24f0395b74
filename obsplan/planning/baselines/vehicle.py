"""Baseline paths under the same limits, horizon and start as a planning problem.

Every baseline starts at the problem's start state, lasts the horizon, is sampled on the planning
grid (so every metric is computed the same way as for the plan) and is built by exact integration
of piecewise-constant inputs that respect the acceleration and speed limits:

* ``lawnmower``: :func:`obsplan.trajectory.generators.lawnmower_within_limits`, legs at the speed
  limit (or the fastest speed whose turns at the acceleration limit fit the area) and turns at the
  acceleration limit, covering the problem's :meth:`~PlanningProblem.coverage_area` from the start
  (3D: at the start depth).
* ``circle``: about the beacon through the start (constant depth in 3D), accelerating
  tangentially from the start speed to the fastest speed whose centripetal and tangential
  accelerations stay within the limit.
* ``straight``: from the start along its velocity (or, at rest, perpendicular to the beacon
  direction: a non-radial line), accelerating at the limit to the fastest cruise that stays in
  the area.
* ``paper-lawnmower``: the paper's Fig. 3 (2D) / Fig. 6 (3D) lawn-mower
  (:func:`obsplan.trajectory.generators.paper_lawnmower`) time-scaled so that its speed or
  acceleration reaches the limits, translated to the start, continued straight if shorter than the
  horizon; only when its (scaled) start velocity equals the problem's.

Every baseline must satisfy the problem's limits on the continuous path
(:func:`~obsplan.planning.problem.feasibility.check_limits`: area, depth, distance to the beacon,
speed through the water). The lawn-mower tries its leg directions and, when a leg or turn would pass
inside ``limits.min_range``, slightly slower cruise speeds (which shift its legs) until one fits
(``Tuning.lawnmower_speed_step``, ``Tuning.lawnmower_speed_tries``).
A baseline that cannot be built for a problem (e.g. a start velocity not tangent to the circle)
is not silently dropped: :func:`unfitted_baselines` gives the reason, and reports show it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import ConfigError, ProblemError
from obsplan.planning.missions.check import mission_check
from obsplan.planning.missions.lawnmower import mission_lawnmower, planner_lawnmower
from obsplan.planning.missions.schedule import planner_schedule
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.feasibility import beacon_of, check_limits, range_extremes
from obsplan.planning.problem.sections import Area
from obsplan.planning.tuning import cache_per_tuning, tuning
from obsplan.trajectory import generators
from obsplan.trajectory.sampled import Trajectory

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
        raise BaselineUnfit(f"{name}: its samples do not fall on the planning grid")
    return Trajectory(t=t, p=traj.p, v=traj.v, u=traj.u)


class BaselineUnfit(ProblemError):
    """A baseline cannot be built for a problem (the message says why)."""


def lawnmower_baseline(pb: PlanningProblem) -> Baseline:
    """Lawn-mower at the limits over the coverage area (see module docstring).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its start state, limits, horizon (the planning grid) and coverage area.

    Returns
    -------
    Baseline
        ``"lawnmower"``, sampled on the planning grid ``pb.times``, within every limit.

    Raises
    ------
    BaselineUnfit
        If no variant fits the limits (the message names the limit).
    """
    area = pb.coverage_area()
    p0, v0 = pb.p0, pb.v0
    s0 = float(np.linalg.norm(v0[:2]))
    # the longest room first, then the other axis directions, each at the cruise speeds in turn;
    # a moving start first along its velocity at every speed, then turning onto each of those
    # (legs along the velocity may not fit: a diagonal pattern leaves a box by its corners)
    first = 0.0 if area.x[1] - p0[0] >= p0[0] - area.x[0] else math.pi
    axes = [first, math.pi - first, 0.5 * math.pi, -0.5 * math.pi]
    tun = tuning()
    # cruise-speed factors, fastest first: each changes the leg spacing 2 v² / a
    factors = tuple(1.0 - tun.lawnmower_speed_step * i for i in range(tun.lawnmower_speed_tries))
    tries = [(f, h) for f in factors for h in axes]
    if s0 > 0:
        tries = [(f, math.atan2(v0[1], v0[0])) for f in factors] + tries
    last: str = ""
    for factor, heading in tries:
        try:
            bl = _lawnmower(pb, area, heading, factor)
        except BaselineUnfit as exc:
            last = str(exc)
            continue
        if check_limits(bl.trajectory, pb).ok():
            return bl
        last = _violation_words(bl.trajectory, pb)
    raise BaselineUnfit(f"lawn-mower: {last}")


def _violation_words(traj: Trajectory, pb: PlanningProblem) -> str:
    """Which limit a baseline path breaks, in words."""
    chk = check_limits(traj, pb)
    lim = pb.limits
    parts = []
    if chk.range > 0:
        near, far = range_extremes(traj, beacon_of(pb))
        if near < lim.min_range:
            parts.append(
                f"passes {near:.3g} m from the beacon (limits.min_range = {lim.min_range:g} m)"
            )
        if lim.max_range is not None and far > lim.max_range:
            parts.append(
                f"goes {far:.4g} m from the beacon (limits.max_range = {lim.max_range:g} m)"
            )
    if chk.box > 0:
        parts.append(f"leaves the area or depth band by {chk.box:.3g} m")
    if chk.speed > 0:
        parts.append(f"exceeds limits.speed by {100 * chk.speed:.2g} %")
    if chk.accel > 0:
        parts.append(f"exceeds limits.accel by {100 * chk.accel:.2g} %")
    if chk.water_speed > 0:
        parts.append(f"drops below limits.min_speed = {lim.min_speed:g} m/s")
    return "; ".join(parts) or "violates a limit"


def _lawnmower(pb: PlanningProblem, area: Area, heading: float, factor: float) -> Baseline:
    a = float(np.min(pb.accel[:2]))  # |u| <= a keeps every axis within its bound
    v0 = pb.v0
    s0 = float(np.linalg.norm(v0[:2]))
    e = np.array([math.cos(heading), math.sin(heading)])
    # a moving start turns onto the heading first (at its speed and the acceleration bound): the
    # legs start where that turn ends
    leg0 = generators.turn_onto_end(pb.p0[:2], v0[:2], heading, a)
    left = np.array([-e[1], e[0]])
    room_left, room_right = _ray_to_box(leg0, left, area), _ray_to_box(leg0, -left, area)
    first_turn = "left" if room_left >= room_right else "right"
    height = max(room_left, room_right)
    ahead = _ray_to_box(leg0, e, area)
    # the fastest speed <= v_max whose turns (radius v^2/a, spacing 2 v^2/a) fit the area
    # (90 % of the room, leaving space for the chord margin below). On a coarse planning grid
    # the turns are flown at a lower acceleration, so that each lasts at least 4 planning steps
    # (turn time pi v / a_turn >= 4 h): the spacing is then 8 h v / pi.
    h = pb.horizon.dt
    room = min(height, ahead)
    speed = min(pb.limits.speed, math.sqrt(0.45 * a * room), 0.9 * math.pi * room / (8.0 * h))
    speed = max(speed * factor * (1 - 1e-9), s0)
    if speed <= 0:
        raise BaselineUnfit("no room to fly a leg from the start inside the area")
    a = min(a, math.pi * speed / (4.0 * h))
    radius = speed**2 / a
    # chord inputs fly a turn up to radius (w h)^2 / 6 outside the arc (analytic.py docstring):
    # keep that margin inside the area
    margin = 1.5 * radius * (speed / radius * pb.horizon.dt) ** 2 / 6.0
    turn_time = math.pi * radius / speed
    if h > 0.25 * turn_time * (1 + 1e-9):
        raise BaselineUnfit(
            f"the planning step horizon.duration / horizon.steps = {h:.3g} s is too coarse "
            f"for its turns ({turn_time:.3g} s each at the start speed); use more horizon.steps"
        )
    try:
        traj = generators.lawnmower_within_limits(
            pb.p0[:2],
            ahead + radius - margin,
            height - margin,
            speed,
            a,
            pb.horizon.duration,
            heading=heading,
            first_turn=first_turn,  # type: ignore[arg-type]
            z=float(pb.p0[2]) if pb.dim == 3 else None,
            z_speed=0.0,
            initial_velocity=v0[:2],
        ).sample(pb.horizon.dt)
    except ConfigError as exc:
        where = "limits.area" if pb.limits.area is not None else "the default coverage area"
        raise BaselineUnfit(
            f"it does not fit between the start and the edges of {where} ({exc})"
        ) from None
    lay = generators.lawnmower_layout(ahead + radius - margin, height - margin, speed, a)
    desc = (
        f"lawn-mower covering {lay.covered_width:.4g} m x {lay.covered_height:.4g} m "
        f"({lay.n_legs} legs) at {speed:.3g} m/s, turns of radius {radius:.3g} m at {a:g} m/s^2"
    )
    if not np.allclose(leg0, pb.p0[:2], rtol=0, atol=1e-9):
        desc += ", after a turn from the moving start onto its first leg"
    return Baseline("lawnmower", _check_grid(traj, pb, "lawnmower"), desc)


def _fly_velocity(pb: PlanningProblem, vel) -> Trajectory:
    """Chord inputs ``u_k = (v*(t_{k+1}) - v*(t_k)) / h`` of an analytic velocity, integrated."""
    t = pb.times
    V = vel(t)
    u = np.diff(V, axis=0) / np.diff(t)[:, None]
    return Trajectory.from_inputs(t, pb.p0, V[0], u)


def circle_baseline(pb: PlanningProblem) -> Baseline | None:
    """Circle about the beacon through the start (see module docstring); None if impossible
    (:func:`circle_unfit_reason` says why).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its start state (the velocity must be tangent to the circle), beacon,
        limits and horizon.

    Returns
    -------
    Baseline or None
        ``"circle"``, sampled on the planning grid ``pb.times``; None when the start velocity is
        not tangent to the circle, the start is above the beacon or the circle breaks a limit
        (:func:`unfitted_baselines` gives the reason).
    """
    try:
        return _circle(pb)
    except BaselineUnfit:
        return None


def _circle(pb: PlanningProblem) -> Baseline:
    b = pb.beacon_start
    rel = (pb.p0 - b)[:2]
    rho = float(np.linalg.norm(rel))
    if rho < 1e-6:
        raise BaselineUnfit("circle: the start is above the beacon (no circle through it)")
    a = float(np.min(pb.accel[:2]))
    tangent = np.array([-rel[1], rel[0]]) / rho
    v0 = pb.v0[:2]
    s0 = float(np.dot(v0, tangent))
    if np.linalg.norm(v0 - s0 * tangent) > _START_TOL or (pb.dim == 3 and abs(pb.v0[2]) > 0):
        raise BaselineUnfit(
            "circle: the start velocity is not tangent to the circle about the beacon through "
            "the start"
        )
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
    if not check_limits(traj, pb).ok():
        raise BaselineUnfit(f"circle: {_violation_words(traj, pb)}")
    desc = f"circle about the beacon, radius {rho:.3g} m, cruise {vc:.3g} m/s"
    return Baseline("circle", traj, desc)


def straight_baseline(pb: PlanningProblem) -> Baseline:
    """Straight line from the start (see module docstring).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its start state, beacon, limits (area and depth band bound the cruise
        speed) and horizon.

    Returns
    -------
    Baseline
        ``"straight"``, sampled on the planning grid ``pb.times``.

    Raises
    ------
    BaselineUnfit
        If the line breaks a limit (the message names it).
    """
    b = pb.beacon_start
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
    line = generators.straight(pb.p0, e, s0, accel=acc, duration=T)  # acc: one per step
    traj = _check_grid(line.sample(h), pb, "x")
    if not check_limits(traj, pb).ok():
        raise BaselineUnfit(f"straight: {_violation_words(traj, pb)}")
    desc = f"straight line, cruise {v:.3g} m/s"
    return Baseline("straight", traj, desc)


def paper_lawnmower_baseline(pb: PlanningProblem) -> Baseline:
    """The paper's lawn-mower time-scaled to the limits (see module docstring).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its dimension (Fig. 3 in 2D, Fig. 6 in 3D), start state, limits and horizon.

    Returns
    -------
    Baseline
        ``"paper-lawnmower"``, sampled on the planning grid ``pb.times`` (continued straight
        when the scaled pattern is shorter than the horizon).

    Raises
    ------
    BaselineUnfit
        When the start velocity does not match or the scaled path breaks a limit.
    """
    h = pb.horizon.dt
    path = generators.paper_lawnmower(pb.dim)
    coarse = path.sample(0.5)
    s_est = max(
        float(np.max(np.linalg.norm(coarse.v, axis=1))) / pb.limits.speed,
        math.sqrt(float(np.max(np.abs(coarse.u[:-1]) / pb.accel))),
    )
    if s_est * coarse.t[-1] / h > tuning().paper_max_oversampling * pb.horizon.steps:
        raise BaselineUnfit(
            f"paper-lawnmower: at these limits the paper's pattern takes {s_est * coarse.t[-1]:.3g}"
            f" s to fly, {s_est * coarse.t[-1] / pb.horizon.duration:.3g} times the horizon"
        )
    s = 1.0
    # t -> s t divides speeds by s and accelerations by s^2; the chord inputs depend on the
    # sampling step h / s, so iterate to the fixed point (converges in a few steps)
    for _ in range(30):
        ref = path.sample(h / s)
        speed = float(np.max(np.linalg.norm(ref.v, axis=1)))
        accel = float(np.max(np.abs(ref.u[:-1]) / pb.accel))
        # a hair above the fixed point, so that round-off keeps the path inside the limits
        s_new = max(speed / pb.limits.speed, math.sqrt(accel)) * (1 + 1e-9)
        if abs(s_new - s) <= 1e-12 * s:
            break
        s = s_new
    ref = path.sample(h / s)
    v_start = ref.v[0] / s
    if np.linalg.norm(v_start - pb.v0) > _START_TOL:
        raise BaselineUnfit(
            f"paper-lawnmower: its start velocity {np.round(v_start, 4).tolist()} m/s (time-scaled)"
            f" differs from start.velocity {list(pb.start_velocity)}"
        )
    scaled = Trajectory(t=ref.t * s, p=ref.p - ref.p[0] + pb.p0, v=ref.v / s, u=ref.u / s**2)
    N = pb.horizon.steps
    if scaled.n_samples < N + 1:
        remaining = pb.horizon.duration - scaled.t[-1]
        if not np.isclose(scaled.t[-1] / h, round(scaled.t[-1] / h), atol=1e-6):
            raise BaselineUnfit("paper-lawnmower: its duration is not on the planning grid")
        scaled = generators.then_straight(scaled, duration=remaining, dt=h)
    scaled = scaled.window(0, N + 1)
    desc = f"paper lawn-mower (Fig. {3 if pb.dim == 2 else 6}) time-scaled by {s:.3g}"
    traj = _check_grid(scaled, pb, "paper-lawnmower")
    if not check_limits(traj, pb).ok():
        raise BaselineUnfit(f"paper-lawnmower: {_violation_words(traj, pb)}")
    return Baseline("paper-lawnmower", traj, desc)


#: Every baseline, in report order.
BASELINES = ("lawnmower", "circle", "straight", "paper-lawnmower")
#: The baselines of a problem with a ``[mission]``: they fly the same mission.
MISSION_BASELINES = ("lawnmower", "lawnmower-accel")


def _mission_baseline(pb: PlanningProblem, accelerated: bool, planner: bool = False) -> Baseline:
    """The mission's (accelerated) lawn-mower (:mod:`obsplan.planning.missions.lawnmower`);
    ``planner``: on the planner's schedule, with its lead-in (a start of the planner)."""
    name = "lawnmower-accel" if accelerated else "lawnmower"
    if planner:
        name += "+lead-in"
    try:
        traj, desc = (planner_lawnmower if planner else mission_lawnmower)(
            pb.mission_context, accelerated
        )
    except ProblemError as exc:
        raise BaselineUnfit(f"{name}: {exc}") from None
    if not check_limits(traj, pb).ok():
        raise BaselineUnfit(f"{name}: {_violation_words(traj, pb)}")
    chk = mission_check(traj, pb.mission_context)
    if chk is None or not chk.complete:
        raise BaselineUnfit(f"{name}: its path on the planning grid does not complete the mission")
    return Baseline(name, _check_grid(traj, pb, name), desc)


def mission_starts(pb: PlanningProblem) -> list[Baseline]:
    """The planner's starts for ``pb``'s mission: the (accelerated) lawn-mower on the planner's
    schedule (:func:`~obsplan.planning.missions.schedule.planner_schedule`), which meets its line
    windows: the baselines themselves when the survey has no lead-in. Those that do not fit are
    left out (the baselines then, if neither fits).

    Parameters
    ----------
    pb : PlanningProblem
        A problem with a ``[mission]`` (its :attr:`~PlanningProblem.mission_context`).

    Returns
    -------
    list of Baseline
        ``"lawnmower+lead-in"`` and ``"lawnmower-accel+lead-in"`` (those that fit), or else the
        fitted :data:`MISSION_BASELINES`; possibly empty.
    """
    out = []
    if planner_schedule(pb.mission_context).lead_in > 0:
        for accelerated in (False, True):
            try:
                out.append(_mission_baseline(pb, accelerated, planner=True))
            except BaselineUnfit:
                pass
    if not out:  # the lawn-mowers themselves (with a lead-in: off its windows, on its lines)
        fitted = _all(pb)[0]
        out = [fitted[k] for k in MISSION_BASELINES if k in fitted]
    return out


def _all_mission(pb: PlanningProblem) -> tuple[dict[str, Baseline], dict[str, str]]:
    fitted: dict[str, Baseline] = {}
    unfit: dict[str, str] = {}
    for name in MISSION_BASELINES:
        try:
            fitted[name] = _mission_baseline(pb, name == "lawnmower-accel")
        except BaselineUnfit as exc:
            unfit[name] = str(exc).split(": ", 1)[-1]
    for name in BASELINES[1:]:
        unfit[name] = "does not fly the mission"
    return fitted, unfit


@cache_per_tuning
def _all(pb: PlanningProblem) -> tuple[dict[str, Baseline], dict[str, str]]:
    if pb.mission is not None:
        return _all_mission(pb)
    fitted: dict[str, Baseline] = {}
    unfit: dict[str, str] = {}
    builders = {
        "lawnmower": lawnmower_baseline,
        "circle": _circle,
        "straight": straight_baseline,
        "paper-lawnmower": paper_lawnmower_baseline,
    }
    for name in BASELINES:
        try:
            fitted[name] = builders[name](pb)
        except BaselineUnfit as exc:
            unfit[name] = str(exc).split(": ", 1)[-1]
    return fitted, unfit


def baselines(pb: PlanningProblem) -> dict[str, Baseline]:
    """Every baseline that fits ``pb``, by name (lawn-mower first).

    See :func:`unfitted_baselines` for the others.

    Parameters
    ----------
    pb : PlanningProblem
        The problem; with a ``[mission]`` the baselines are the mission's lawn-mowers
        (:data:`MISSION_BASELINES`), otherwise :data:`BASELINES`.

    Returns
    -------
    dict of str to Baseline
        Name -> baseline, in report order; every path on the planning grid ``pb.times``.
        Cached per problem and tuning.
    """
    return dict(_all(pb)[0])


def unfitted_baselines(pb: PlanningProblem) -> dict[str, str]:
    """Baselines that cannot be built for ``pb``: name -> the reason, in words.

    Parameters
    ----------
    pb : PlanningProblem
        The problem (as for :func:`baselines`).

    Returns
    -------
    dict of str to str
        Name -> why it does not fit (e.g. the limit it breaks, or ``"does not fly the
        mission"`` for the free-flight baselines of a mission problem).
    """
    return dict(_all(pb)[1])
