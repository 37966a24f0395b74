"""Generators of the motion classes of the paper's Tables 1–3, as analytic paths in continuous time.

Every generator returns an :class:`~obsplan.trajectory.analytic.AnalyticPath` (lines, arcs,
parabolas and a z motion in continuous time); ``path.sample(dt)`` flies it as a held-input
:class:`~obsplan.trajectory.sampled.Trajectory` (chord inputs on curved paths, the acceleration
at interval midpoints on straight lines and parabolas: see :mod:`obsplan.trajectory.analytic`),
and :func:`obsplan.observability.lwo.lwo_path_report` checks the path itself between samples.

* :func:`straight`, :func:`parabola`: constant-acceleration motion (or an acceleration profile
  along a line);
* :func:`circle`, :func:`circle_z`: horizontal circles, flat or with a motion along z;
* :func:`lawnmower`, :func:`lawnmower_within_limits`, :func:`paper_lawnmower`: parallel legs
  joined by semicircular turns.

Three functions join *sampled* trajectories and so take ``dt`` and return a Trajectory:
:func:`then_straight` (a straight leg from a trajectory's sampled final state),
:func:`circle_then_straight` (a circle shifted by its sampling error so that the leg starts
exactly at the exit point) and :func:`concat` (trajectories joined end to start).

Units are SI: positions [m], speeds [m/s], accelerations [m/s²], times [s], angles [rad].
``dt`` defaults to 0.01 s, the paper's 100 Hz (section 7).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.trajectory.analytic import (
    DT,
    AnalyticPath,
    SineProfile,
    _Arc,
    _end,
    _Line,
    _Parabola,
    _positive,
    _profile_values,
    _ProfileLine,
    _Segment,
    _ZLine,
    _ZSine,
)
from obsplan.trajectory.sampled import Trajectory

#: Relative velocity mismatch tolerated where two trajectories are joined.
JOIN_TOL: float = 1e-6

#: A point or direction: a sequence of 2 or 3 numbers, or an array.
Vec = Sequence[float] | np.ndarray
#: Along-line acceleration: a number, a callable ``a(t)`` (array in, array out) or an array.
AccelProfile = float | Callable[..., Any] | Sequence[float] | np.ndarray

__all__ = [
    "DT",
    "AnalyticPath",
    "LawnmowerLayout",
    "SineProfile",
    "circle",
    "circle_then_straight",
    "circle_z",
    "concat",
    "lawnmower",
    "lawnmower_layout",
    "lawnmower_within_limits",
    "turn_onto_end",
    "paper_lawnmower",
    "parabola",
    "sine_profile",
    "straight",
    "then_straight",
]


# ------------------------------------------------------------------ argument checks
def _finite(name: str, value: float) -> float:
    try:
        val = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(val):
        raise ConfigError(f"{name} must be a finite number, got {value!r}")
    return val


def _vector(name: str, value: Vec, dims: tuple[int, ...] = (2, 3)) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a list of numbers, got {value!r}") from None
    if arr.size not in dims or not np.all(np.isfinite(arr)):
        want = " or ".join(str(d) for d in dims)
        raise ConfigError(f"{name} must have {want} finite coordinates [m], got {value!r}")
    return arr


# ------------------------------------------------------------------ straight lines
def sine_profile(mean: float, amplitude: float, period: float, phase: float = 0.0) -> SineProfile:
    """Acceleration profile ``mean + amplitude sin(2π t / period + phase)`` for :func:`straight`.

    Parameters
    ----------
    mean, amplitude : float
        [m/s²]. With ``|amplitude| < |mean|`` the acceleration varies and is never zero, which
        the range-only LWO test needs at every sample (eq. 36: ``det O = -3 u_x² q²``).
    period : float
        [s], positive.
    phase : float, optional
        [rad].

    Returns
    -------
    SineProfile
        A callable ``a(t)`` [m/s²] of times [s] (array in, array out), with closed-form integrals.
    """
    return SineProfile(
        _finite("mean", mean),
        _finite("amplitude", amplitude),
        _positive("period", period),
        _finite("phase", phase),
    )


#: Times at which a callable acceleration profile is checked when a line is built [count].
_PROBES = 257


def _not_moving() -> ConfigError:
    return ConfigError("speed0 and accel are both zero: the vehicle would not move")


def _held_pieces(
    p: np.ndarray, e: np.ndarray, s0: float, accel: Sequence[float] | np.ndarray, duration: float
) -> tuple[_Line, ...]:
    """One constant-acceleration piece per value of ``accel``, each ``duration / len`` long."""
    try:
        a = np.asarray(accel, float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"accel must be a number, a callable or numbers, got {accel!r}") from None
    if a.size == 0:
        raise ConfigError("accel array must have at least one value (one per interval)")
    if not np.all(np.isfinite(a)):
        raise ConfigError("accel must be finite at every sample")
    if s0 == 0.0 and not np.any(a):
        raise _not_moving()
    h = duration / a.size
    speeds = s0 + h * np.concatenate([[0.0], np.cumsum(a[:-1])])
    dist = np.concatenate([[0.0], np.cumsum(speeds * h + 0.5 * a * h**2)[:-1]])
    return tuple(
        _Line(p if k == 0 else p + dist[k] * e, e, float(speeds[k]), float(a[k]), h)
        for k in range(a.size)
    )


def straight(
    p0: Vec,
    direction: Vec,
    speed0: float,
    *,
    accel: AccelProfile = 0.0,
    duration: float,
) -> AnalyticPath:
    """Straight line from ``p0`` along ``direction``: constant speed, constant or varying accel.

    Parameters
    ----------
    p0 : shape (n,)
        Start position [m], n = 2 or 3. The line is radial (through a beacon at the origin) when
        ``direction`` is parallel to ``p0``.
    direction : shape (n,)
        Direction of motion (normalised here; must be non-zero).
    speed0 : float
        Initial speed along ``direction`` [m/s], ``>= 0``.
    accel : float, callable or array_like, optional
        Acceleration along ``direction`` [m/s²]: a number (0 = constant speed), a callable of
        time ``a(t)`` (see :func:`sine_profile`; checked at 257 times here, and at every sample
        when sampled) or an array, a piecewise-constant profile whose values are held on
        consecutive equal intervals of ``duration / len(accel)`` (e.g. one per step of a
        planning grid: sampling at that step gives exactly these inputs).
    duration : float
        Length [s], positive.

    Returns
    -------
    AnalyticPath
        ``n``-D, lasting ``duration``, with midpoint inputs: ``sample(dt)`` holds ``a`` (a
        number), ``a`` at each interval's midpoint (a callable; speed error O(dt²)) or the
        array's values (sampled at ``duration / len(accel)``). Inputs, velocities and
        displacements are all parallel to ``direction``: exactly straight.
    """
    duration = _positive("duration", duration)
    p = _vector("p0", p0)
    e = _vector("direction", direction, (p.size,))
    norm = float(np.linalg.norm(e))
    if norm == 0.0:
        raise ConfigError("direction must be a non-zero vector")
    e = e / norm
    s0 = _finite("speed0", speed0)
    if s0 < 0:
        raise ConfigError(f"speed0 must be >= 0 (reverse direction instead), got {speed0!r}")
    segs: tuple[_Segment, ...]
    if callable(accel):
        probe = _profile_values(accel, np.linspace(0.0, duration, _PROBES))
        if s0 == 0.0 and not np.any(probe):
            raise _not_moving()
        segs = (_ProfileLine(p, e, s0, accel, duration),)
    elif np.ndim(accel) == 0:
        a = _finite("accel", accel)  # type: ignore[arg-type]
        if s0 == 0.0 and a == 0.0:
            raise _not_moving()
        segs = (_Line(p, e, s0, a, duration),)
    else:
        segs = _held_pieces(p, e, s0, accel, duration)  # type: ignore[arg-type]
    return AnalyticPath(segs, inputs="midpoint", t_end=duration)


def parabola(p0: Vec, v0: Vec, accel: Vec, *, duration: float) -> AnalyticPath:
    """Constant acceleration in any direction: ``p(t) = p0 + v0 t + ½ a t²`` (a parabola).

    Parameters
    ----------
    p0, v0, accel : shape (n,)
        Start position [m], start velocity [m/s] and the constant acceleration [m/s²]; with
        ``accel`` parallel to ``v0`` the path is a straight line (use :func:`straight`).
    duration : float
        Length [s], positive.

    Returns
    -------
    AnalyticPath
        One ``n``-D piece lasting ``duration``, with midpoint inputs: ``sample(dt)`` holds
        ``accel`` for the whole path, exactly the held-input trajectory of the parabola.
    """
    duration = _positive("duration", duration)
    p = _vector("p0", p0)
    v = _vector("v0", v0, (p.size,))
    a = _vector("accel", accel, (p.size,))
    if not (np.any(v) or np.any(a)):
        raise ConfigError("v0 and accel are both zero: the vehicle would not move")
    return AnalyticPath((_Parabola(p, v, a, duration),), inputs="midpoint")


# ------------------------------------------------------------------ joining sampled trajectories
def then_straight(
    traj: Trajectory,
    *,
    duration: float,
    accel: AccelProfile = 0.0,
    direction: Vec | None = None,
    dt: float = DT,
) -> Trajectory:
    """Continue ``traj`` with a straight leg tangent to its final velocity.

    The leg starts from the *sampled* final state of ``traj`` (which may be any trajectory, e.g.
    a time-scaled one), so it takes ``dt`` and returns samples.

    Parameters
    ----------
    traj : Trajectory
        Trajectory to extend; its final speed must be non-zero.
    duration, accel : float; float, callable or array_like, optional
        As in :func:`straight`: the leg's length [s] and acceleration along it [m/s²].
    direction : shape (n,), optional
        Direction of the leg; it must be parallel to the final velocity (relative mismatch
        ``<= JOIN_TOL``). Use it to make a leg *exactly* radial, e.g. ``traj.p[-1]``.
    dt : float, optional
        Sampling interval of the leg [s].

    Returns
    -------
    Trajectory
        ``traj`` followed by ``straight(traj.p[-1], e, |traj.v[-1]|, ...).sample(dt)`` (its first
        sample replacing ``traj``'s last), ``n``-D.
    """
    v_end = traj.v[-1]
    speed = float(np.linalg.norm(v_end))
    if speed == 0.0:
        raise ConfigError(
            "then_straight: the trajectory ends at rest; give a direction with "
            "straight() and concat() instead"
        )
    e = v_end / speed if direction is None else _vector("direction", direction, (traj.dim,))
    e = e / np.linalg.norm(e)
    if np.linalg.norm(speed * e - v_end) > JOIN_TOL * speed:
        raise ConfigError(
            "then_straight: direction is not parallel to the final velocity; the "
            "join would need an infinite acceleration"
        )
    leg = straight(traj.p[-1], e, speed, accel=accel, duration=duration).sample(dt)
    return traj.then(leg)


def concat(*trajs: Trajectory) -> Trajectory:
    """Join trajectories end to start (:meth:`Trajectory.then`), checking positions and velocities.

    Parameters
    ----------
    *trajs
        Sampled trajectories (e.g. ``path.sample(dt)``), all 2D or all 3D; each must start where
        the previous one ends, with its final velocity.

    Returns
    -------
    Trajectory
        The samples of all, each trajectory's first sample replacing the previous one's last;
        times shifted to follow on.

    Raises
    ------
    ConfigError
        If fewer than one trajectory is given, or if a position gap or a velocity jump (relative
        ``> JOIN_TOL``) would make the result dynamically inconsistent.
    """
    if not trajs:
        raise ConfigError("concat needs at least one trajectory")
    out = trajs[0]
    for i, nxt in enumerate(trajs[1:], start=1):
        if nxt.dim != out.dim:
            raise ConfigError(f"concat: trajectory {i} is {nxt.dim}D, the previous ones {out.dim}D")
        scale = max(1.0, float(np.linalg.norm(out.v[-1])))
        jump = float(np.linalg.norm(nxt.v[0] - out.v[-1]))
        if jump > JOIN_TOL * scale:
            raise ConfigError(
                f"concat: trajectory {i} starts with velocity {nxt.v[0].tolist()} m/s but the "
                f"previous one ends with {out.v[-1].tolist()} m/s; start it from the final state"
            )
        gap = float(np.linalg.norm(nxt.p[0] - out.p[-1]))
        if gap > JOIN_TOL * max(1.0, float(np.abs(out.p).max())):
            raise ConfigError(
                f"concat: trajectory {i} starts {gap:.3g} m from where the previous one ends"
            )
        out = out.then(nxt)
    return out


# ------------------------------------------------------------------ circles
def _circle_plane(center: Vec, z: float | None) -> tuple[np.ndarray, int]:
    c = _vector("center", center)
    if c.size == 3:
        if z is not None and _finite("z", z) != c[2]:
            raise ConfigError(f"center has height {c[2]:g} m but z = {z!r}; give the height once")
        return c, 3
    if z is None:
        return c, 2
    return np.array([c[0], c[1], _finite("z", z)]), 3


def _circle_arc(
    radius: float, speed: float, duration: float, c: np.ndarray, phase: float, ccw: bool
) -> _Arc:
    dim = c.size
    e1, e2 = np.eye(dim)[0], np.eye(dim)[1]
    omega = (1.0 if ccw else -1.0) * speed / radius
    return _Arc(c=c, e1=e1, e2=e2, r=radius, phi0=phase, omega=omega, T=duration)


def circle(
    radius: float,
    speed: float,
    duration: float,
    *,
    center: Vec = (0.0, 0.0),
    phase: float = 0.0,
    z: float | None = None,
    ccw: bool = True,
) -> AnalyticPath:
    """Horizontal circle at constant speed (eq. 37; eq. 46 in 3D).

    Parameters
    ----------
    radius, speed : float
        Radius ρ [m] and speed ρω [m/s], both positive.
    duration : float
        Length [s]; one lap lasts ``2π radius / speed``.
    center : shape (2,) or (3,)
        Centre [m]; the beacon's position (origin) by default, as in eq. 37.
    phase : float, optional
        Angle of the start point from the x axis [rad].
    z : float or None, optional
        Height of the plane [m] for a 3D circle (``z = 0``: in the beacon's plane; ``z ≠ 0``: out
        of it, eq. 46 with ``q_z = z``). A 3-element ``center`` also gives a 3D circle.
    ccw : bool, optional
        Counter-clockwise (seen from +z) if true.

    Returns
    -------
    AnalyticPath
        One arc, 2D or 3D, lasting ``duration``, with chord inputs: ``sample(dt)`` has velocities
        exact at the samples and a radius error ``<= radius (ω dt)²/6``, ``ω = speed/radius``.
    """
    duration = _positive("duration", duration)
    radius, speed = _positive("radius", radius), _positive("speed", speed)
    c, _ = _circle_plane(center, z)
    return AnalyticPath((_circle_arc(radius, speed, duration, c, _finite("phase", phase), ccw),))


def circle_z(
    radius: float,
    speed: float,
    duration: float,
    *,
    z0: float,
    z_motion: Literal["sine", "straight"] = "sine",
    z_amp: float | None = None,
    z_period: float | None = None,
    z_speed: float | None = None,
    z_phase: float = 0.0,
    center: Vec = (0.0, 0.0),
    phase: float = 0.0,
    ccw: bool = True,
) -> AnalyticPath:
    """Circle in (x, y) combined with a motion along z (the 3D rows of Tables 1–2, Figs. 5 and 8).

    ``z(t) = z0 + z_amp sin(2π t / z_period + z_phase)`` (``z_motion="sine"``) or
    ``z(t) = z0 + z_speed t`` (``"straight"``, constant vertical speed, as in Fig. 5).

    Parameters
    ----------
    radius, speed, duration, center, phase, ccw : as for circle
        The horizontal circle, as in :func:`circle` (``center`` has 2 coordinates).
    z0 : float
        Height at ``t = 0`` (sine: the mid height) [m].
    z_motion : {"sine", "straight"}, optional
        The motion along z: a sine about ``z0`` or a constant vertical speed.
    z_amp, z_period : float, optional
        Amplitude [m] (non-zero) and period [s] of the sine. A period equal to the lap time
        ``2π radius / speed`` puts the path in a tilted plane: planar, hence never globally
        observable with range only.
    z_speed : float, optional
        Vertical speed [m/s] (non-zero) of the straight motion. Note ``u_z = 0`` then.
    z_phase : float, optional
        Phase of the sine [rad].

    Returns
    -------
    AnalyticPath
        3D: one arc in (x, y) and the z motion, lasting ``duration``, with chord inputs.
    """
    duration = _positive("duration", duration)
    radius, speed = _positive("radius", radius), _positive("speed", speed)
    c = _vector("center", center, (2,))
    z0 = _finite("z0", z0)
    zm: _ZLine | _ZSine
    if z_motion == "sine":
        if z_amp is None or z_period is None or z_speed is not None:
            raise ConfigError(
                "circle_z with z_motion='sine' needs z_amp and z_period (and no z_speed)"
            )
        amp, period = _finite("z_amp", z_amp), _positive("z_period", z_period)
        if amp == 0.0:
            raise ConfigError("z_amp must be non-zero (use circle(..., z=z0) for a flat circle)")
        zm = _ZSine(z0, amp, 2.0 * np.pi / period, _finite("z_phase", z_phase))
    elif z_motion == "straight":
        if z_speed is None or z_amp is not None or z_period is not None:
            raise ConfigError(
                "circle_z with z_motion='straight' needs z_speed (and no z_amp, z_period)"
            )
        w = _finite("z_speed", z_speed)
        if w == 0.0:
            raise ConfigError("z_speed must be non-zero (use circle(..., z=z0) for a flat circle)")
        zm = _ZLine(z0, w)
    else:
        raise ConfigError(f"z_motion must be 'sine' or 'straight', got {z_motion!r}")
    arc = _circle_arc(radius, speed, duration, c, _finite("phase", phase), ccw)
    return AnalyticPath((arc,), zm)


def circle_then_straight(
    radius: float,
    speed: float,
    *,
    circle_duration: float,
    straight_duration: float,
    radial: bool = False,
    straight_accel: AccelProfile = 0.0,
    exit_distance: float | None = None,
    dt: float = DT,
) -> Trajectory:
    """2D circle then a tangent straight leg, radial or not (Tables 1–2, "Circular + Straight").

    The leg leaves the circle tangentially along +x, so the velocity is continuous. The sampled
    circle is shifted by its O(dt²) integration error (``<= radius (ω dt)²/3``) so that the leg
    starts exactly at the exit point: the result depends on ``dt`` beyond sampling one path, so
    this function takes ``dt`` and returns samples.

    * ``radial=False``: circle centred on the beacon (origin); the leg starts at ``(0, -radius)``
      and runs along ``y = -radius``, at distance ``radius`` from the beacon.
    * ``radial=True``: a tangent to a circle centred on the beacon is never radial, so the circle
      is centred at ``(exit_distance, radius)`` (default ``exit_distance = 2 radius``); the leg
      starts at ``(exit_distance, 0)`` and runs outwards along the x axis, through the beacon's
      line of sight (exactly radial: its direction is the unit vector of its start point).

    Parameters
    ----------
    radius, speed : float
        Circle radius [m] and speed [m/s].
    circle_duration, straight_duration : float
        Durations [s] of the two parts; the circle ends at the exit point.
    radial : bool, optional
        Make the leg radial (see above).
    straight_accel : float, callable or array_like, optional
        Acceleration along the leg [m/s²], as ``accel`` of :func:`straight`.
    exit_distance : float or None, optional
        Distance of the exit point from the beacon [m] (``radial=True`` only).
    dt : float, optional
        Sampling interval [s] of both parts.

    Returns
    -------
    Trajectory
        2D, lasting ``circle_duration + straight_duration``: the circle's chord inputs, then the
        leg's midpoint inputs.
    """
    radius, speed = _positive("radius", radius), _positive("speed", speed)
    T = _positive("circle_duration", circle_duration)
    if radial:
        D = 2.0 * radius if exit_distance is None else _positive("exit_distance", exit_distance)
        center = (D, radius)
    else:
        if exit_distance is not None:
            raise ConfigError("exit_distance only applies to radial=True")
        center = (0.0, 0.0)
    phase_end = -0.5 * np.pi  # exit point straight below the centre, moving along +x (ccw)
    circ = circle(radius, speed, T, center=center, phase=phase_end - speed / radius * T).sample(dt)
    # shift by the O(dt²) integration error so that the leg starts exactly at the exit point
    exit_point = np.array([center[0], center[1] - radius])
    circ = circ.translated(exit_point - circ.p[-1])
    direction = exit_point if radial else None
    return then_straight(
        circ, duration=straight_duration, accel=straight_accel, direction=direction, dt=dt
    )


# ------------------------------------------------------------------ lawn-mowers
def _rot2(heading: float, dim: int) -> tuple[np.ndarray, np.ndarray]:
    h = np.zeros(dim)
    h[:2] = (math.cos(heading), math.sin(heading))
    left = np.zeros(dim)
    left[:2] = (-math.sin(heading), math.cos(heading))
    return h, left


def _tangent_arc(p: np.ndarray, v: np.ndarray, side: np.ndarray, r: float, sweep: float) -> _Arc:
    """Arc of radius ``r`` leaving ``p`` with velocity ``v``, centre at ``p + r side``."""
    speed = float(np.linalg.norm(v))
    return _Arc(
        c=p + r * side, e1=-side, e2=v / speed, r=r, phi0=0.0, omega=speed / r, T=sweep * r / speed
    )


def _turn_onto(start: Vec, velocity: Vec, heading: float, accel: float) -> _Arc | None:
    """The arc a vehicle at ``start`` [m] moving at ``velocity`` [m/s] flies at constant speed
    and centripetal acceleration ``accel`` [m/s²] (radius ``|v|² / accel``) to turn onto
    ``heading`` [rad] the shorter way (left when opposite); None when it already flies along
    ``heading`` (to 1e-9 rad) or is at rest. Only x and y are used."""
    p = np.asarray(start, float)[:2]
    v = np.asarray(velocity, float)[:2]
    s0 = float(np.linalg.norm(v))
    a = _positive("accel", accel)
    if s0 == 0.0:
        return None
    e = v / s0
    turn = math.atan2(
        e[0] * math.sin(heading) - e[1] * math.cos(heading),
        e[0] * math.cos(heading) + e[1] * math.sin(heading),
    )
    if abs(turn) < 1e-9:
        return None
    left = np.array([-e[1], e[0]])
    return _tangent_arc(p, v, left if turn > 0 else -left, s0**2 / a, abs(turn))


def turn_onto_end(start: Vec, velocity: Vec, heading: float, accel: float) -> np.ndarray:
    """Where a vehicle is once it has turned onto ``heading`` the shorter way at constant speed.

    The first leg's start of :func:`lawnmower_within_limits` with ``initial_velocity``.

    Parameters
    ----------
    start : shape (2,) or (3,)
        Position [m] (x and y are used).
    velocity : shape (2,) or (3,)
        Velocity [m/s] (x and y are used).
    heading : float
        Direction to turn onto, from the x axis [rad].
    accel : float
        Centripetal acceleration of the turn [m/s²], positive (radius ``|v|² / accel``).

    Returns
    -------
    ndarray, shape (2,)
        End of the turn [m]: ``start`` itself at rest or already on the heading.
    """
    arc = _turn_onto(start, velocity, heading, accel)
    return np.asarray(start, float)[:2].copy() if arc is None else _end(arc)[0]


def _lawnmower_segments(
    start: np.ndarray,
    heading: float,
    leg_length: float,
    spacing: float,
    lanes: Sequence[int],
    speed: float,
    first_turn: str,
    initial_speed: float | None,
    initial_accel: float | None,
    start_with_circle: bool,
) -> list[_Segment]:
    """Legs on ``lanes`` (lateral offsets in units of ``spacing``) joined by semicircles."""
    h, left = _rot2(heading, start.size)
    lateral = left if first_turn == "left" else -left
    r = 0.5 * spacing
    segs: list[_Segment] = []
    p = start.copy()
    if start_with_circle:
        segs.append(_tangent_arc(p, speed * h, -lateral, r, 2.0 * np.pi))
        p = _end(segs[-1])[0]
    if initial_speed is not None:
        s0 = initial_speed
        a = (speed**2 - s0**2) / (2.0 * leg_length) if initial_accel is None else initial_accel
        T_acc = (speed - s0) / a if a != 0 else 0.0
        d_acc = s0 * T_acc + 0.5 * a * T_acc**2
        if T_acc < 0 or d_acc > leg_length * (1 + 1e-12):
            raise ConfigError(
                f"initial_accel {a:g} m/s² cannot bring initial_speed {s0:g} m/s to speed "
                f"{speed:g} m/s within the first leg ({leg_length:g} m)"
            )
        if T_acc > 0:
            segs.append(_Line(p, h, s0, a, T_acc))
            p = _end(segs[-1])[0]
        rest = leg_length - d_acc
        if rest > 1e-12 * leg_length:
            segs.append(_Line(p, h, speed, 0.0, rest / speed))
            p = _end(segs[-1])[0]
    else:
        segs.append(_Line(p, h, speed, 0.0, leg_length / speed))
        p = _end(segs[-1])[0]
    d = h
    for prev, lane in zip(lanes[:-1], lanes[1:], strict=True):
        side = lateral if lane > prev else -lateral
        segs.append(_tangent_arc(p, speed * d, side, r, np.pi))
        p = _end(segs[-1])[0]
        d = -d
        segs.append(_Line(p, d, speed, 0.0, leg_length / speed))
        p = _end(segs[-1])[0]
    return segs


def _segments_path(segs: Sequence[_Segment], z: float | None, z_speed: float) -> AnalyticPath:
    """Pieces in (x, y), with a constant vertical speed from height ``z`` if given."""
    if z is None:
        return AnalyticPath(tuple(segs))
    w = _finite("z_speed", z_speed)
    return AnalyticPath(tuple(segs), _ZLine(_finite("z", z), w))


def _check_turn(turn: str, first_turn: str) -> None:
    if turn != "semicircle":
        raise ConfigError(f"turn must be 'semicircle' (the only turn implemented), got {turn!r}")
    if first_turn not in ("left", "right"):
        raise ConfigError(f"first_turn must be 'left' or 'right', got {first_turn!r}")


def lawnmower(
    start: Vec,
    leg_length: float,
    spacing: float,
    n_legs: int,
    speed: float,
    *,
    heading: float = 0.0,
    turn: str = "semicircle",
    first_turn: Literal["left", "right"] = "left",
    z: float | None = None,
    z_speed: float = 0.0,
    start_with_circle: bool = False,
    initial_speed: float | None = None,
    initial_accel: float | None = None,
) -> AnalyticPath:
    """Lawn-mower: ``n_legs`` parallel legs at constant speed joined by semicircular turns.

    Covered area: the legs span a ``leg_length × (n_legs - 1) spacing`` rectangle whose first
    leg starts at ``start`` and runs along ``heading``; the next legs are stacked to the
    ``first_turn`` side. Turns have radius ``spacing / 2`` (centripetal acceleration
    ``2 speed² / spacing``) and bulge ``spacing / 2`` beyond the leg ends.

    Parameters
    ----------
    start : shape (2,)
        Start of the first leg [m] (x, y).
    leg_length, spacing : float
        Leg length [m] and distance between legs [m].
    n_legs : int
        Number of legs, ``>= 1``.
    speed : float
        Cruise speed [m/s].
    heading : float, optional
        Direction of the first leg from the x axis [rad].
    turn : {"semicircle"}, optional
        Only ``"semicircle"``.
    first_turn : {"left", "right"}, optional
        Side (``"left"`` or ``"right"`` of the first leg) the next legs are stacked on.
    z, z_speed : float or None; float, optional
        For a 3D lawn-mower: start height [m] and constant vertical speed [m/s] (Fig. 6's
        "straight motion along z"; ``u_z = 0``).
    start_with_circle : bool, optional
        Fly one full circle of radius ``spacing / 2`` (outside the area) before the first leg.
    initial_speed, initial_accel : float or None, optional
        Start the first leg at ``initial_speed`` [m/s] (e.g. 0, from rest as in Fig. 3) and
        accelerate at ``initial_accel`` [m/s²] (default: the constant value reaching ``speed`` at
        the end of the first leg), then cruise.

    Returns
    -------
    AnalyticPath
        2D (3D with ``z``), with chord inputs: legs and turns as separate pieces.
    """
    _check_turn(turn, first_turn)
    p = _vector("start", start, (2,))
    L, s = _positive("leg_length", leg_length), _positive("spacing", spacing)
    v = _positive("speed", speed)
    if int(n_legs) != n_legs or n_legs < 1:
        raise ConfigError(f"n_legs must be a positive integer, got {n_legs!r}")
    if initial_speed is not None:
        if start_with_circle:
            raise ConfigError(
                "start_with_circle and initial_speed cannot be combined: the "
                "circle is flown at speed"
            )
        initial_speed = _finite("initial_speed", initial_speed)
        if initial_speed < 0:
            raise ConfigError(f"initial_speed must be >= 0, got {initial_speed!r}")
        if initial_accel is not None:
            initial_accel = _positive("initial_accel", initial_accel)
    segs = _lawnmower_segments(
        p,
        _finite("heading", heading),
        L,
        s,
        list(range(int(n_legs))),
        v,
        first_turn,
        initial_speed,
        initial_accel,
        start_with_circle,
    )
    return _segments_path(segs, z, z_speed)


@dataclass(frozen=True)
class LawnmowerLayout:
    """Geometry of a lawn-mower that respects an acceleration limit (:func:`lawnmower_layout`).

    Attributes
    ----------
    spacing
        Distance between legs [m] = ``2 speed² / accel_max`` (turns exactly at the limit).
    turn_radius
        ``spacing / 2`` [m].
    n_legs
        Legs per sweep: as many as fit in ``area_height``.
    leg_length
        ``area_width - spacing`` [m], so legs plus turns span exactly ``area_width``.
    covered_width, covered_height
        Extent of the path [m]: ``area_width`` along the legs (turns included) and
        ``(n_legs - 1) spacing <= area_height`` across them.
    turn_accel
        Centripetal acceleration in the turns [m/s²] (``<= accel_max``).
    """

    spacing: float
    turn_radius: float
    n_legs: int
    leg_length: float
    covered_width: float
    covered_height: float
    turn_accel: float

    def to_dict(self) -> dict:
        """The layout as a plain mapping (for JSON outputs).

        Returns
        -------
        dict
            Each attribute by name: lengths [m], ``n_legs``, ``turn_accel`` [m/s²].
        """
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def lawnmower_layout(
    area_width: float, area_height: float, speed: float, accel_max: float
) -> LawnmowerLayout:
    """Tightest lawn-mower of an area at ``speed`` whose turns stay within ``accel_max``.

    Parameters
    ----------
    area_width, area_height : float
        Area along / across the legs [m].
    speed, accel_max : float
        Cruise speed [m/s] and acceleration limit [m/s²], positive.

    Returns
    -------
    LawnmowerLayout
        Spacing, legs and extent (lengths [m], acceleration [m/s²]).

    Raises
    ------
    ConfigError
        If the area is too small for two legs with turns at ``accel_max``.
    """
    W, H = _positive("area_width", area_width), _positive("area_height", area_height)
    v, a = _positive("speed", speed), _positive("accel_max", accel_max)
    s = 2.0 * v**2 / a
    if H < s or W <= s:
        raise ConfigError(
            f"the area {W:g} m × {H:g} m is too small: turns at speed {v:g} m/s within accel_max "
            f"{a:g} m/s² need a spacing of {s:g} m (area_height >= spacing, area_width > "
            "spacing); lower the speed or enlarge the area"
        )
    n = int(math.floor(H / s * (1 + 1e-12))) + 1
    return LawnmowerLayout(
        spacing=s,
        turn_radius=0.5 * s,
        n_legs=n,
        leg_length=W - s,
        covered_width=W,
        covered_height=(n - 1) * s,
        turn_accel=v**2 / (0.5 * s),
    )


def lawnmower_within_limits(
    start: Vec,
    area_width: float,
    area_height: float,
    speed: float,
    accel_max: float,
    duration: float,
    *,
    heading: float = 0.0,
    first_turn: Literal["left", "right"] = "left",
    z: float | None = None,
    z_speed: float = 0.0,
    initial_speed: float | None = None,
    initial_velocity: Vec | None = None,
) -> AnalyticPath:
    """Baseline lawn-mower "at the limits", flown for exactly ``duration``.

    Legs at ``speed``, turns at exactly ``accel_max`` (:func:`lawnmower_layout`; the inputs stay
    within ``accel_max`` to round-off, ~1e-15 relative). The first leg
    starts at ``start`` (a point of the area's near edge, ``turn_radius`` from its corner) along
    ``heading``; the covered rectangle is ``area_width`` along ``heading`` (starting
    ``turn_radius`` behind ``start``) by ``covered_height`` towards ``first_turn``. After the last
    leg the pattern sweeps back over the same legs, and so on, until ``duration`` (truncated
    there).

    Parameters
    ----------
    start : shape (2,)
        Start of the first leg [m].
    area_width, area_height : float
        Area along / across ``heading`` [m].
    speed, accel_max : float
        Cruise speed [m/s] and acceleration limit [m/s²].
    duration : float
        Exact length [s].
    heading : float, optional
        Direction of the first leg from the x axis [rad].
    first_turn : {"left", "right"}, optional
        Side (``"left"`` or ``"right"`` of the first leg) the next legs are stacked on.
    z, z_speed : float or None; float, optional
        Optional height [m] and constant vertical speed [m/s] (3D).
    initial_speed : float or None, optional
        Start the first leg at this speed [m/s] and accelerate at ``accel_max`` to ``speed``.
    initial_velocity : shape (2,), optional
        A moving start [m/s]: from ``start`` the vehicle first turns onto ``heading`` at
        ``accel_max`` and its speed (:func:`turn_onto_end`), and the first leg starts where that
        turn ends, at that speed (``initial_speed`` is then ``|initial_velocity|``).

    Returns
    -------
    AnalyticPath
        2D (3D with ``z``), lasting exactly ``duration`` (its ``t_end``), with chord inputs.
    """
    duration = _positive("duration", duration)
    lay = lawnmower_layout(area_width, area_height, speed, accel_max)
    _check_turn("semicircle", first_turn)
    p = _vector("start", start, (2,))
    lead: list[_Segment] = []
    if initial_velocity is not None:
        v0 = _vector("initial_velocity", initial_velocity, (2,))
        initial_speed = float(np.linalg.norm(v0))
        arc = _turn_onto(p, v0, heading, accel_max)
        if arc is not None:
            lead.append(arc)
            p = _end(arc)[0]
    if initial_speed is not None:
        initial_speed = _finite("initial_speed", initial_speed)
        if not 0 <= initial_speed <= speed:
            raise ConfigError(f"initial_speed must be in [0, speed], got {initial_speed!r}")
    sweep = list(range(lay.n_legs))
    back = sweep[-2::-1] + sweep[1:]  # one return sweep and one forward sweep
    lanes = sweep[:]
    # enough lanes to fill the duration (each leg + turn takes at least leg_length / speed)
    per_lane = (lay.leg_length + np.pi * lay.turn_radius) / speed
    while len(lanes) * per_lane < duration + per_lane:
        lanes += back
    segs = _lawnmower_segments(
        p,
        _finite("heading", heading),
        lay.leg_length,
        lay.spacing,
        lanes,
        speed,
        first_turn,
        initial_speed,
        None if initial_speed is None else accel_max,
        False,
    )
    path = _segments_path(lead + segs, z, z_speed)
    # the pieces flown before `duration` (one starting exactly there included)
    flown = int(np.count_nonzero(path.breakpoints[:-1] <= duration))
    return AnalyticPath(path.segments[:flown], path.z, t_end=duration)


def paper_lawnmower(
    dim: int = 2,
    *,
    speed: float = 2.0,
    leg_length: float = 160.0,
    spacing: float = 30.0,
    n_legs: int = 5,
    z_speed: float = -0.01,
) -> AnalyticPath:
    """Paper-like lawn-mower of Figs. 3 (2D) and 6 (3D): straight legs joined by circular arcs.

    The paper gives only the start states (section 7.1–7.2): Fig. 3 starts at ``(-80, 60)`` m from
    rest, Fig. 6 at ``(-80, 60, 5)`` m with ``v0 = (2, 0, 0)`` m/s. We take legs along +x of
    ``leg_length`` stacked towards -y (over the beacon) every ``spacing``, semicircular turns, and
    cruise ``speed``. In 2D the first leg accelerates from rest (constant acceleration reaching
    ``speed`` at its end) and the first turn is the "circular motion" after which the Gramian is
    full rank; in 3D the vehicle starts at ``speed`` with the constant vertical speed ``z_speed``
    (Fig. 6's "straight motion along z"; the paper does not state its value).

    Parameters
    ----------
    dim : {2, 3}, optional
        2 (Fig. 3) or 3 (Fig. 6).
    speed : float, optional
        Cruise speed [m/s].
    leg_length, spacing : float, optional
        Leg length [m] and distance between legs [m].
    n_legs : int, optional
        Number of legs.
    z_speed : float, optional
        Vertical speed [m/s] (3D only).

    Returns
    -------
    AnalyticPath
        ``dim``-D, with chord inputs (:func:`lawnmower`). In 2D its pieces are: the accelerating
        first leg, then (turn, leg) four times; the turns are semicircles of radius
        ``spacing / 2`` centred at ``(±80, 45)``, ``(±80, -15)``.
    """
    if dim == 2:
        return lawnmower(
            (-80.0, 60.0),
            leg_length,
            spacing,
            n_legs,
            speed,
            first_turn="right",
            initial_speed=0.0,
        )
    if dim == 3:
        return lawnmower(
            (-80.0, 60.0),
            leg_length,
            spacing,
            n_legs,
            speed,
            first_turn="right",
            z=5.0,
            z_speed=z_speed,
        )
    raise ConfigError(f"dim must be 2 or 3, got {dim!r}")
