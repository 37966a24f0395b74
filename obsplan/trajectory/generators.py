"""Trajectory generators for the motion classes of the paper's Tables 1–3.

Every generator returns a :class:`~obsplan.trajectory.sampled.Trajectory` built by integrating
piecewise-constant inputs exactly (:meth:`Trajectory.from_inputs`), so every sample is dynamically
consistent (``consistency_error() ≈ 1e-12``): the observability verdicts, which depend on ``u``
only through the trajectory, are verdicts on a path the double integrator really flies.

Curved paths are defined by an analytic velocity ``v*(t)`` and flown with the chord inputs

    u_k = (v*(t_{k+1}) - v*(t_k)) / (t_{k+1} - t_k),

so the sampled velocities equal ``v*(t_k)`` (to round-off) and each position step is the
trapezoidal rule of ``v*``: the position error is O(dt²). On a circle each step is shorter than
the arc's chord by the factor ``1 - (ω dt)²/12``, so the radius error is at most ``ρ (ω dt)²/6``:
measured on the paper's circle (ρ = 50 m, 2.6 m/s, one lap) 2.3e-6 m with ``dt = 0.01 s`` and
2.3e-4 m with ``dt = 0.1 s`` (``tests/test_generators.py``). Chord inputs never exceed the
analytic acceleration (``|u_k| = 2|v| sin(ω dt/2)/dt ≤ |v| ω``), so turns flown at an acceleration
limit stay within it.

Straight lines take their inputs along the line only, so they are exactly straight (radial lines
stay exactly radial); a callable acceleration profile is sampled at interval midpoints
(speed error O(dt²)).

Smooth paths. ``circle_path``, ``circle_z_path``, ``lawnmower_path`` and ``paper_lawnmower_path``
return the analytic path (:class:`AnalyticPath`: lines, arcs and a z motion, with positions,
velocities and accelerations at any time) that ``circle``, ``circle_z``, ``lawnmower`` and
``paper_lawnmower`` sample: ``path.sample(dt)`` is the generator's trajectory, bit for bit. The
two are different inputs for the LWO test: the held-input trajectory has a constant input on each
interval, the path a smooth one (``obsplan.observability.lwo.lwo_path_report`` checks it between
samples).

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
from obsplan.trajectory.sampled import Trajectory

#: Default sampling interval [s] (the paper's T_s = 0.01 s, section 7).
DT: float = 0.01
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
    "circle_path",
    "circle_then_straight",
    "circle_z",
    "circle_z_path",
    "concat",
    "lawnmower",
    "lawnmower_layout",
    "lawnmower_path",
    "lawnmower_within_limits",
    "turn_onto_end",
    "paper_lawnmower",
    "paper_lawnmower_path",
    "parabola",
    "sine_profile",
    "straight",
    "then_straight",
]


# ------------------------------------------------------------------ argument checks
def _positive(name: str, value: float) -> float:
    try:
        val = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(val) and val > 0):
        raise ConfigError(f"{name} must be a positive number, got {value!r}")
    return val


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


def _check_timing(duration: float, dt: float) -> tuple[float, float]:
    dt = _positive("dt", dt)
    duration = _positive("duration", duration)
    if duration <= dt:
        raise ConfigError(
            f"duration ({duration:g} s) must be longer than dt ({dt:g} s); "
            "lengthen the duration or reduce dt"
        )
    return duration, dt


def _time_grid(duration: float, dt: float) -> np.ndarray:
    """``0, dt, 2dt, ...`` ending exactly at ``duration`` (a shorter last step if needed)."""
    ratio = duration / dt
    n = round(ratio) if abs(ratio - round(ratio)) < 1e-6 else math.ceil(ratio)
    t = np.arange(n + 1, dtype=float) * dt
    t[-1] = duration
    return t


# ------------------------------------------------------------------ analytic paths
@dataclass(frozen=True)
class _Line:
    """``p0 + e (s0 τ + ½ a τ²)`` for ``τ ∈ [0, T]``."""

    p0: np.ndarray
    e: np.ndarray
    s0: float
    a: float
    T: float

    def pos(self, tau: np.ndarray) -> np.ndarray:
        return self.p0 + np.outer(self.s0 * tau + 0.5 * self.a * tau**2, self.e)

    def vel(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(self.s0 + self.a * tau, self.e)

    def acc(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(np.full(np.shape(tau), self.a), self.e)


@dataclass(frozen=True)
class _Arc:
    """``c + r (cos θ e1 + sin θ e2)``, ``θ = φ0 + ω τ`` for ``τ ∈ [0, T]`` (e1 ⟂ e2, unit)."""

    c: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    r: float
    phi0: float
    omega: float
    T: float

    def pos(self, tau: np.ndarray) -> np.ndarray:
        th = self.phi0 + self.omega * tau
        return self.c + self.r * (np.outer(np.cos(th), self.e1) + np.outer(np.sin(th), self.e2))

    def vel(self, tau: np.ndarray) -> np.ndarray:
        th = self.phi0 + self.omega * tau
        return (self.r * self.omega) * (
            np.outer(-np.sin(th), self.e1) + np.outer(np.cos(th), self.e2)
        )

    def acc(self, tau: np.ndarray) -> np.ndarray:
        th = self.phi0 + self.omega * tau
        return (-self.r * self.omega**2) * (
            np.outer(np.cos(th), self.e1) + np.outer(np.sin(th), self.e2)
        )


_Segment = _Line | _Arc


def _end(seg: _Segment) -> tuple[np.ndarray, np.ndarray]:
    T = np.array([seg.T])
    return seg.pos(T)[0], seg.vel(T)[0]


def _tangent_arc(p: np.ndarray, v: np.ndarray, side: np.ndarray, r: float, sweep: float) -> _Arc:
    """Arc of radius ``r`` leaving ``p`` with velocity ``v``, centre at ``p + r side``."""
    speed = float(np.linalg.norm(v))
    return _Arc(
        c=p + r * side, e1=-side, e2=v / speed, r=r, phi0=0.0, omega=speed / r, T=sweep * r / speed
    )


def _piecewise(segments: Sequence[_Segment]) -> tuple[Callable, Callable, float]:
    """Global ``pos(t)``, ``vel(t)`` of consecutive segments, and the total duration [s]."""
    starts = np.concatenate([[0.0], np.cumsum([s.T for s in segments])])

    def evaluate(t: np.ndarray, which: str) -> np.ndarray:
        t = np.asarray(t, float)
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segments) - 1)
        out = np.empty((t.size, segments[0].pos(np.zeros(1)).shape[1]))
        for i in np.unique(idx):
            sel = idx == i
            out[sel] = getattr(segments[i], which)(t[sel] - starts[i])
        return out

    return (lambda t: evaluate(t, "pos")), (lambda t: evaluate(t, "vel")), float(starts[-1])


def _fly(t: np.ndarray, p0: np.ndarray, vel: Callable[[np.ndarray], np.ndarray]) -> Trajectory:
    """Fly the analytic velocity ``vel`` with chord inputs (velocity exact at the samples)."""
    V = vel(t)
    u = np.diff(V, axis=0) / np.diff(t)[:, None]
    return Trajectory.from_inputs(t, p0, V[0], u)


def _add_z(
    vel_xy: Callable[[np.ndarray], np.ndarray], vz: Callable[[np.ndarray], np.ndarray]
) -> Callable[[np.ndarray], np.ndarray]:
    return lambda t: np.column_stack([vel_xy(t)[:, :2], vz(t)])


# ------------------------------------------------------------------ smooth paths
@dataclass(frozen=True)
class _ZLine:
    """``z(t) = z0 + w t``: a straight (constant-speed) motion along z, ``u_z = 0``."""

    z0: float
    w: float

    @property
    def start(self) -> float:
        return self.z0

    def pos(self, t: np.ndarray) -> np.ndarray:
        return self.z0 + self.w * np.asarray(t)

    def vel(self, t: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t), self.w)

    def acc(self, t: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(t))


@dataclass(frozen=True)
class _ZSine:
    """``z(t) = z0 + amp sin(Ω t + phase)``."""

    z0: float
    amp: float
    Om: float
    ph: float

    @property
    def start(self) -> float:
        return self.z0 + self.amp * math.sin(self.ph)

    def pos(self, t: np.ndarray) -> np.ndarray:
        return self.z0 + self.amp * np.sin(self.Om * np.asarray(t) + self.ph)

    def vel(self, t: np.ndarray) -> np.ndarray:
        return self.amp * self.Om * np.cos(self.Om * t + self.ph)

    def acc(self, t: np.ndarray) -> np.ndarray:
        return -self.amp * self.Om**2 * np.sin(self.Om * np.asarray(t) + self.ph)


@dataclass(frozen=True)
class AnalyticPath:
    """A smooth path: consecutive lines and arcs (pieces), optionally with a motion along z.

    The path the generators sample (module docstring). Within a piece, position, velocity and
    acceleration are analytic in time; at a breakpoint the acceleration may jump (a leg meets a
    turn). Picklable (no closures).

    Attributes
    ----------
    segments
        The pieces, in order; each lasts its ``T`` [s] from the previous one's end.
    z
        Motion along z for a path whose pieces are in (x, y); None for a 2D path or a path whose
        pieces are already 3D (a circle in a plane ``z = const``).
    """

    segments: tuple[_Segment, ...]
    z: _ZLine | _ZSine | None = None

    @property
    def dim(self) -> int:
        """2 or 3."""
        return 3 if self.z is not None else int(self.segments[0].pos(np.zeros(1)).shape[1])

    @property
    def breakpoints(self) -> np.ndarray:
        """Start time of every piece and the end time, shape ``(n_pieces + 1,)`` [s]."""
        return np.concatenate([[0.0], np.cumsum([s.T for s in self.segments])])

    @property
    def duration(self) -> float:
        """Length of the path [s]."""
        return float(self.breakpoints[-1])

    def evaluate(
        self, t: np.ndarray | float, piece: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at times ``t`` [s], each (N, dim).

        ``piece=None``: the piece that contains each time (right-continuous at breakpoints);
        ``piece=i``: the formulas of piece ``i`` (e.g. its limit at its end time).
        """
        t = np.atleast_1d(np.asarray(t, float))
        starts = self.breakpoints
        if piece is None:
            idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segments) - 1)
        elif not 0 <= int(piece) < len(self.segments):
            raise ConfigError(f"piece must be in 0..{len(self.segments) - 1}, got {piece!r}")
        else:
            idx = np.full(t.size, int(piece))
        out = [np.empty((t.size, self.dim)) for _ in range(3)]
        for i in np.unique(idx):
            sel, seg = idx == i, self.segments[i]
            tau = t[sel] - starts[i]
            for arr, f in zip(out, (seg.pos, seg.vel, seg.acc), strict=True):
                val = f(tau)
                arr[sel, : val.shape[1]] = val
        if self.z is not None:
            for arr, f in zip(out, (self.z.pos, self.z.vel, self.z.acc), strict=True):
                arr[:, 2] = f(t)
        return out[0], out[1], out[2]

    def sample(self, dt: float = DT, duration: float | None = None) -> Trajectory:
        """The held-input trajectory of the path: chord inputs (module docstring), sampled at
        ``dt`` [s] for ``duration`` [s] (default: the whole path)."""
        dt = _positive("dt", dt)
        _, vel, total = _piecewise(self.segments)
        t = _time_grid(total if duration is None else duration, dt)
        p0 = self.segments[0].pos(np.zeros(1))[0]
        if self.z is None:
            return _fly(t, p0, vel)
        return _fly(t, np.append(p0, self.z.start), _add_z(vel, self.z.vel))


# ------------------------------------------------------------------ straight lines
@dataclass(frozen=True)
class SineProfile:
    """``mean + amplitude sin(2π t / period + phase)`` [m/s²]; call it with times [s]."""

    mean: float
    amplitude: float
    period: float
    phase: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return self.mean + self.amplitude * np.sin(
            2.0 * np.pi * np.asarray(t) / self.period + self.phase
        )

    def __repr__(self) -> str:
        extra = f", phase={self.phase:g}" if self.phase else ""
        return f"sine_profile({self.mean:g}, {self.amplitude:g}, {self.period:g}{extra})"


def sine_profile(mean: float, amplitude: float, period: float, phase: float = 0.0) -> SineProfile:
    """Acceleration profile ``mean + amplitude sin(2π t / period + phase)`` for :func:`straight`.

    Parameters
    ----------
    mean, amplitude
        [m/s²]. With ``|amplitude| < |mean|`` the acceleration varies and is never zero, which
        the range-only LWO test needs at every sample (eq. 36: ``det O = -3 u_x² q²``).
    period
        [s], positive.
    phase
        [rad].
    """
    return SineProfile(
        _finite("mean", mean),
        _finite("amplitude", amplitude),
        _positive("period", period),
        _finite("phase", phase),
    )


def _accel_samples(accel: AccelProfile, t: np.ndarray) -> np.ndarray:
    """The along-line acceleration on each interval, shape ``(N-1,)`` [m/s²]."""
    K = t.size - 1
    if callable(accel):
        mid = 0.5 * (t[:-1] + t[1:])  # midpoint: speed error O(dt²)
        try:
            a = np.broadcast_to(np.asarray(accel(mid), float), (K,)).copy()
        except (TypeError, ValueError):  # a scalar-only callable
            try:
                a = np.array([float(accel(float(s))) for s in mid])
            except (TypeError, ValueError) as exc:
                raise ConfigError(
                    "accel: the callable must map times [s] to accelerations [m/s²] "
                    f"(an array of the same shape, or one number per time): {exc}"
                ) from None
    elif np.ndim(accel) == 0:
        a = np.full(K, _finite("accel", accel))  # type: ignore[arg-type]
    else:
        a = np.asarray(accel, float).reshape(-1)
        if a.size not in (K, K + 1):
            raise ConfigError(
                f"accel array must have one value per interval ({K}) or per sample ({K + 1}), "
                f"got {a.size}"
            )
        a = a[:K]
    if not np.all(np.isfinite(a)):
        raise ConfigError("accel must be finite at every sample")
    return a


def straight(
    p0: Vec,
    direction: Vec,
    speed0: float,
    *,
    accel: AccelProfile = 0.0,
    duration: float,
    dt: float = DT,
) -> Trajectory:
    """Straight line from ``p0`` along ``direction``: constant speed, constant or varying accel.

    Parameters
    ----------
    p0 : shape (n,)
        Start position [m], n = 2 or 3. The line is radial (through a beacon at the origin) when
        ``direction`` is parallel to ``p0``.
    direction : shape (n,)
        Direction of motion (normalised here; must be non-zero).
    speed0
        Initial speed along ``direction`` [m/s], ``>= 0``.
    accel
        Acceleration along ``direction`` [m/s²]: a number (0 = constant speed), a callable of
        time ``a(t)`` (sampled at interval midpoints; see :func:`sine_profile`) or an array with
        one value per interval (or per sample).
    duration, dt
        Length [s] and sampling interval [s].

    Returns
    -------
    Trajectory
        Inputs, velocities and displacements all parallel to ``direction``: exactly straight.
    """
    duration, dt = _check_timing(duration, dt)
    p = _vector("p0", p0)
    e = _vector("direction", direction, (p.size,))
    norm = float(np.linalg.norm(e))
    if norm == 0.0:
        raise ConfigError("direction must be a non-zero vector")
    e = e / norm
    s0 = _finite("speed0", speed0)
    if s0 < 0:
        raise ConfigError(f"speed0 must be >= 0 (reverse direction instead), got {speed0!r}")
    t = _time_grid(duration, dt)
    a = _accel_samples(accel, t)
    if s0 == 0.0 and not np.any(a):
        raise ConfigError("speed0 and accel are both zero: the vehicle would not move")
    return Trajectory.from_inputs(t, p, s0 * e, np.outer(a, e))


def parabola(p0: Vec, v0: Vec, accel: Vec, *, duration: float, dt: float = DT) -> Trajectory:
    """Constant acceleration in any direction: ``p(t) = p0 + v0 t + ½ a t²`` (a parabola).

    Parameters
    ----------
    p0, v0, accel : shape (n,)
        Start position [m], start velocity [m/s] and the constant acceleration [m/s²]; with
        ``accel`` parallel to ``v0`` the path is a straight line (use :func:`straight`).
    duration, dt
        Length [s] and sampling interval [s].

    Returns
    -------
    Trajectory
        One input held for the whole path: exactly the held-input trajectory of the parabola.
    """
    duration, dt = _check_timing(duration, dt)
    p = _vector("p0", p0)
    v = _vector("v0", v0, (p.size,))
    a = _vector("accel", accel, (p.size,))
    if not (np.any(v) or np.any(a)):
        raise ConfigError("v0 and accel are both zero: the vehicle would not move")
    t = _time_grid(duration, dt)
    return Trajectory.from_inputs(t, p, v, np.tile(a, (t.size - 1, 1)))


def then_straight(
    traj: Trajectory,
    *,
    duration: float,
    accel: AccelProfile = 0.0,
    direction: Vec | None = None,
    dt: float = DT,
) -> Trajectory:
    """Continue ``traj`` with a straight leg tangent to its final velocity.

    Parameters
    ----------
    traj
        Trajectory to extend; its final speed must be non-zero.
    duration, accel, dt
        As in :func:`straight`.
    direction : shape (n,), optional
        Direction of the leg; it must be parallel to the final velocity (relative mismatch
        ``<= JOIN_TOL``). Use it to make a leg *exactly* radial, e.g. ``traj.p[-1]``.
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
    leg = straight(traj.p[-1], e, speed, accel=accel, duration=duration, dt=dt)
    return traj.then(leg)


def concat(*trajs: Trajectory) -> Trajectory:
    """Join trajectories end to start (:meth:`Trajectory.then`), checking positions and velocities.

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
    dt: float = DT,
    *,
    center: Vec = (0.0, 0.0),
    phase: float = 0.0,
    z: float | None = None,
    ccw: bool = True,
) -> Trajectory:
    """Horizontal circle at constant speed (eq. 37; eq. 46 in 3D).

    Parameters
    ----------
    radius, speed
        Radius ρ [m] and speed ρω [m/s], both positive.
    duration, dt
        Length [s] and sampling interval [s]; one lap lasts ``2π radius / speed``.
    center : shape (2,) or (3,)
        Centre [m]; the beacon's position (origin) by default, as in eq. 37.
    phase
        Angle of the start point from the x axis [rad].
    z
        Height of the plane [m] for a 3D circle (``z = 0``: in the beacon's plane; ``z ≠ 0``: out
        of it, eq. 46 with ``q_z = z``). A 3-element ``center`` also gives a 3D circle.
    ccw
        Counter-clockwise (seen from +z) if true.

    Returns
    -------
    Trajectory
        Velocities exact at the samples; radius error ``<= radius (ω dt)²/6``, ``ω = speed/radius``.
    """
    duration, dt = _check_timing(duration, dt)
    path = circle_path(radius, speed, duration, center=center, phase=phase, z=z, ccw=ccw)
    return path.sample(dt)


def circle_path(
    radius: float,
    speed: float,
    duration: float,
    *,
    center: Vec = (0.0, 0.0),
    phase: float = 0.0,
    z: float | None = None,
    ccw: bool = True,
) -> AnalyticPath:
    """The smooth path that :func:`circle` samples (same parameters, no ``dt``)."""
    duration = _positive("duration", duration)
    radius, speed = _positive("radius", radius), _positive("speed", speed)
    c, _ = _circle_plane(center, z)
    return AnalyticPath((_circle_arc(radius, speed, duration, c, _finite("phase", phase), ccw),))


def circle_z(
    radius: float,
    speed: float,
    duration: float,
    dt: float = DT,
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
) -> Trajectory:
    """Circle in (x, y) combined with a motion along z (the 3D rows of Tables 1–2, Figs. 5 and 8).

    ``z(t) = z0 + z_amp sin(2π t / z_period + z_phase)`` (``z_motion="sine"``) or
    ``z(t) = z0 + z_speed t`` (``"straight"``, constant vertical speed, as in Fig. 5).

    Parameters
    ----------
    radius, speed, duration, dt, center, phase, ccw
        The horizontal circle, as in :func:`circle` (``center`` has 2 coordinates).
    z0
        Height at ``t = 0`` (sine: the mid height) [m].
    z_amp, z_period
        Amplitude [m] (non-zero) and period [s] of the sine. A period equal to the lap time
        ``2π radius / speed`` puts the path in a tilted plane: planar, hence never globally
        observable with range only.
    z_speed
        Vertical speed [m/s] (non-zero) of the straight motion. Note ``u_z = 0`` then.
    """
    duration, dt = _check_timing(duration, dt)
    return circle_z_path(
        radius,
        speed,
        duration,
        z0=z0,
        z_motion=z_motion,
        z_amp=z_amp,
        z_period=z_period,
        z_speed=z_speed,
        z_phase=z_phase,
        center=center,
        phase=phase,
        ccw=ccw,
    ).sample(dt)


def circle_z_path(
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
    """The smooth path that :func:`circle_z` samples (same parameters, no ``dt``)."""
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

    The leg leaves the circle tangentially along +x, so the velocity is continuous. The circle is
    shifted by its O(dt²) integration error (``<= radius (ω dt)²/3``) so that the leg starts
    exactly at the exit point.

    * ``radial=False``: circle centred on the beacon (origin); the leg starts at ``(0, -radius)``
      and runs along ``y = -radius``, at distance ``radius`` from the beacon.
    * ``radial=True``: a tangent to a circle centred on the beacon is never radial, so the circle
      is centred at ``(exit_distance, radius)`` (default ``exit_distance = 2 radius``); the leg
      starts at ``(exit_distance, 0)`` and runs outwards along the x axis, through the beacon's
      line of sight (exactly radial: its direction is the unit vector of its start point).

    Parameters
    ----------
    radius, speed
        Circle radius [m] and speed [m/s].
    circle_duration, straight_duration
        Durations [s] of the two parts; the circle ends at the exit point.
    straight_accel
        Acceleration along the leg [m/s²], as ``accel`` of :func:`straight`.
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
    circ = circle(radius, speed, T, dt, center=center, phase=phase_end - speed / radius * T)
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
    """Where a vehicle at ``start`` [m] moving at ``velocity`` [m/s] is, shape (2,) [m], once it
    has turned onto ``heading`` [rad] the shorter way at constant speed and centripetal
    acceleration ``accel`` [m/s²] (``start`` itself at rest or already on the heading): the
    first leg's start of :func:`lawnmower_within_limits` with ``initial_velocity``."""
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


def _fly_segments(
    segs: Sequence[_Segment],
    dt: float,
    z: float | None,
    z_speed: float,
    duration: float | None = None,
) -> Trajectory:
    return _segments_path(segs, z, z_speed).sample(dt, duration)


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
    dt: float = DT,
    *,
    heading: float = 0.0,
    turn: str = "semicircle",
    first_turn: Literal["left", "right"] = "left",
    z: float | None = None,
    z_speed: float = 0.0,
    start_with_circle: bool = False,
    initial_speed: float | None = None,
    initial_accel: float | None = None,
) -> Trajectory:
    """Lawn-mower: ``n_legs`` parallel legs at constant speed joined by semicircular turns.

    Covered area: the legs span a ``leg_length × (n_legs - 1) spacing`` rectangle whose first
    leg starts at ``start`` and runs along ``heading``; the next legs are stacked to the
    ``first_turn`` side. Turns have radius ``spacing / 2`` (centripetal acceleration
    ``2 speed² / spacing``) and bulge ``spacing / 2`` beyond the leg ends.

    Parameters
    ----------
    start : shape (2,)
        Start of the first leg [m] (x, y).
    leg_length, spacing
        Leg length [m] and distance between legs [m].
    n_legs
        Number of legs, ``>= 1``.
    speed
        Cruise speed [m/s].
    heading
        Direction of the first leg from the x axis [rad].
    turn
        Only ``"semicircle"``.
    z, z_speed
        For a 3D lawn-mower: start height [m] and constant vertical speed [m/s] (Fig. 6's
        "straight motion along z"; ``u_z = 0``).
    start_with_circle
        Fly one full circle of radius ``spacing / 2`` (outside the area) before the first leg.
    initial_speed, initial_accel
        Start the first leg at ``initial_speed`` [m/s] (e.g. 0, from rest as in Fig. 3) and
        accelerate at ``initial_accel`` [m/s²] (default: the constant value reaching ``speed`` at
        the end of the first leg), then cruise.
    """
    dt = _positive("dt", dt)
    return lawnmower_path(
        start,
        leg_length,
        spacing,
        n_legs,
        speed,
        heading=heading,
        turn=turn,
        first_turn=first_turn,
        z=z,
        z_speed=z_speed,
        start_with_circle=start_with_circle,
        initial_speed=initial_speed,
        initial_accel=initial_accel,
    ).sample(dt)


def lawnmower_path(
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
    """The smooth path that :func:`lawnmower` samples (same parameters, no ``dt``): legs and
    semicircular turns as separate pieces."""
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
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def lawnmower_layout(
    area_width: float, area_height: float, speed: float, accel_max: float
) -> LawnmowerLayout:
    """Tightest lawn-mower of an area at ``speed`` whose turns stay within ``accel_max``.

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
    dt: float = DT,
    *,
    heading: float = 0.0,
    first_turn: Literal["left", "right"] = "left",
    z: float | None = None,
    z_speed: float = 0.0,
    initial_speed: float | None = None,
    initial_velocity: Vec | None = None,
) -> Trajectory:
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
    area_width, area_height
        Area along / across ``heading`` [m].
    speed, accel_max
        Cruise speed [m/s] and acceleration limit [m/s²].
    duration, dt
        Exact length [s] and sampling interval [s].
    z, z_speed
        Optional height [m] and constant vertical speed [m/s] (3D).
    initial_speed
        Start the first leg at this speed [m/s] and accelerate at ``accel_max`` to ``speed``.
    initial_velocity : shape (2,), optional
        A moving start [m/s]: from ``start`` the vehicle first turns onto ``heading`` at
        ``accel_max`` and its speed (:func:`turn_onto_end`), and the first leg starts where that
        turn ends, at that speed (``initial_speed`` is then ``|initial_velocity|``).
    """
    duration, dt = _check_timing(duration, dt)
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
    return _fly_segments(lead + segs, dt, z, z_speed, duration=duration)


def paper_lawnmower(
    dim: int = 2,
    dt: float = DT,
    *,
    speed: float = 2.0,
    leg_length: float = 160.0,
    spacing: float = 30.0,
    n_legs: int = 5,
    z_speed: float = -0.01,
) -> Trajectory:
    """Paper-like lawn-mower of Figs. 3 (2D) and 6 (3D): straight legs joined by circular arcs.

    The paper gives only the start states (section 7.1–7.2): Fig. 3 starts at ``(-80, 60)`` m from
    rest, Fig. 6 at ``(-80, 60, 5)`` m with ``v0 = (2, 0, 0)`` m/s. We take legs along +x of
    ``leg_length`` stacked towards -y (over the beacon) every ``spacing``, semicircular turns, and
    cruise ``speed``. In 2D the first leg accelerates from rest (constant acceleration reaching
    ``speed`` at its end) and the first turn is the "circular motion" after which the Gramian is
    full rank; in 3D the vehicle starts at ``speed`` with the constant vertical speed ``z_speed``
    (Fig. 6's "straight motion along z"; the paper does not state its value).
    """
    dt = _positive("dt", dt)
    path = paper_lawnmower_path(
        dim, speed=speed, leg_length=leg_length, spacing=spacing, n_legs=n_legs, z_speed=z_speed
    )
    return path.sample(dt)


def paper_lawnmower_path(
    dim: int = 2,
    *,
    speed: float = 2.0,
    leg_length: float = 160.0,
    spacing: float = 30.0,
    n_legs: int = 5,
    z_speed: float = -0.01,
) -> AnalyticPath:
    """The smooth path that :func:`paper_lawnmower` samples (same parameters, no ``dt``).

    In 2D its pieces are: the accelerating first leg, then (turn, leg) four times; the turns are
    semicircles of radius ``spacing / 2`` centred at ``(±80, 45)``, ``(±80, -15)``.
    """
    if dim == 2:
        return lawnmower_path(
            (-80.0, 60.0),
            leg_length,
            spacing,
            n_legs,
            speed,
            first_turn="right",
            initial_speed=0.0,
        )
    if dim == 3:
        return lawnmower_path(
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
