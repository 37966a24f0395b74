"""Analytic paths: smooth motions in continuous time, and the held-input trajectories sampling them.

An :class:`AnalyticPath` is a sequence of pieces (lines, arcs, parabolas, lines with an
acceleration profile), optionally with a motion along z, whose positions, velocities and
accelerations are known at any time (:meth:`AnalyticPath.evaluate`). :meth:`AnalyticPath.sample`
turns it into a :class:`~obsplan.trajectory.sampled.Trajectory` by integrating piecewise-constant
inputs exactly (:meth:`Trajectory.from_inputs`), so every sample is dynamically consistent
(``consistency_error() ≈ 1e-12``): the observability verdicts, which depend on ``u`` only through
the trajectory, are verdicts on a path the double integrator really flies. The path chooses its
inputs (``AnalyticPath.inputs``):

* ``"chord"`` (curved paths: circles, lawn-mowers) flies the analytic velocity ``v*(t)`` with the
  chord inputs

      u_k = (v*(t_{k+1}) - v*(t_k)) / (t_{k+1} - t_k),

  so the sampled velocities equal ``v*(t_k)`` (to round-off) and each position step is the
  trapezoidal rule of ``v*``: the position error is O(dt²). On a circle each step is shorter than
  the arc's chord by the factor ``1 - (ω dt)²/12``, so the radius error is at most ``ρ (ω dt)²/6``:
  measured on the paper's circle (ρ = 50 m, 2.6 m/s, one lap) 2.3e-6 m with ``dt = 0.01 s`` and
  2.3e-4 m with ``dt = 0.1 s`` (``tests/test_generators.py``). Chord inputs never exceed the
  analytic acceleration (``|u_k| = 2|v| sin(ω dt/2)/dt ≤ |v| ω``), so turns flown at an
  acceleration limit stay within it.
* ``"midpoint"`` (straight lines, parabolas) holds the path's acceleration at the middle of each
  interval, ``u_k = p''((t_k + t_{k+1}) / 2)``: exact for constant-acceleration pieces (the
  held-input trajectory *is* the path), speed error O(dt²) for an acceleration profile. Lines take
  their inputs along the line only, so they are exactly straight (radial lines stay exactly
  radial).

The held-input trajectory and the path are different inputs for the LWO test: the trajectory has
a constant input on each interval, the path a smooth one
(:func:`obsplan.observability.lwo.lwo_path_report` checks it between samples).

Units are SI: positions [m], speeds [m/s], accelerations [m/s²], times [s], angles [rad].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.trajectory.sampled import Trajectory

#: Default sampling interval [s] (the paper's T_s = 0.01 s, section 7).
DT: float = 0.01

__all__ = ["DT", "AnalyticPath", "SineProfile"]


# ------------------------------------------------------------------ sampling grid
def _positive(name: str, value: float) -> float:
    try:
        val = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(val) and val > 0):
        raise ConfigError(f"{name} must be a positive number, got {value!r}")
    return val


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


# ------------------------------------------------------------------ acceleration profiles
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

    def integral(self, t: np.ndarray, order: int) -> np.ndarray:
        """``∫_0^t a`` (order 1, [m/s]) or ``∫_0^t ∫_0^s a`` (order 2, [m]) at times ``t`` [s].

        Parameters
        ----------
        t : ndarray
            Times [s] from the start of the profile.
        order : int
            1 for the velocity gained, 2 for the distance gained (any other value: 2).

        Returns
        -------
        ndarray, shape of ``t``
            The integral, in closed form [m/s] or [m].
        """
        t = np.asarray(t, float)
        w = 2.0 * np.pi / self.period
        c0, s0 = math.cos(self.phase), math.sin(self.phase)
        if order == 1:
            return self.mean * t + self.amplitude / w * (c0 - np.cos(w * t + self.phase))
        return (
            0.5 * self.mean * t**2
            + self.amplitude / w * c0 * t
            - self.amplitude / w**2 * (np.sin(w * t + self.phase) - s0)
        )

    def __repr__(self) -> str:
        extra = f", phase={self.phase:g}" if self.phase else ""
        return f"sine_profile({self.mean:g}, {self.amplitude:g}, {self.period:g}{extra})"


def _profile_values(accel: Callable[..., Any], t: np.ndarray) -> np.ndarray:
    """A callable acceleration profile at times ``t`` [s], shape ``t.shape`` [m/s²], finite."""
    t = np.asarray(t, float)
    try:
        a = np.broadcast_to(np.asarray(accel(t), float), t.shape).copy()
    except (TypeError, ValueError):  # a scalar-only callable
        try:
            a = np.array([float(accel(float(s))) for s in t.reshape(-1)]).reshape(t.shape)
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                "accel: the callable must map times [s] to accelerations [m/s²] "
                f"(an array of the same shape, or one number per time): {exc}"
            ) from None
    if not np.all(np.isfinite(a)):
        raise ConfigError("accel must be finite at every sample")
    return a


def _profile_integral(accel: Callable[..., Any], tau: np.ndarray, order: int) -> np.ndarray:
    """``∫_0^τ a`` (order 1) or ``∫_0^τ (τ - s) a(s) ds`` (order 2): closed form for a
    :class:`SineProfile`, adaptive quadrature for any other callable."""
    tau = np.asarray(tau, float)
    if isinstance(accel, SineProfile):
        return accel.integral(tau, order)
    from scipy.integrate import quad

    def f(s: float, end: float) -> float:
        return float(_profile_values(accel, np.array([s]))[0]) * (1.0 if order == 1 else end - s)

    flat = [quad(f, 0.0, float(x), args=(float(x),), limit=200)[0] for x in tau.reshape(-1)]
    return np.array(flat, float).reshape(tau.shape)


# ------------------------------------------------------------------ pieces
@dataclass(frozen=True)
class _Line:
    """``p0 + e (s0 τ + ½ a τ²)`` for ``τ ∈ [0, T]``."""

    p0: np.ndarray
    e: np.ndarray
    s0: float
    a: float
    T: float

    def start_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.p0, self.s0 * self.e

    def pos(self, tau: np.ndarray) -> np.ndarray:
        return self.p0 + np.outer(self.s0 * tau + 0.5 * self.a * tau**2, self.e)

    def vel(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(self.s0 + self.a * tau, self.e)

    def acc(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(np.full(np.shape(tau), self.a), self.e)


@dataclass(frozen=True)
class _ProfileLine:
    """``p0 + e (s0 τ + ∫∫ a)`` for ``τ ∈ [0, T]``: a line with the acceleration profile
    ``a(τ)`` along it (a callable of time, e.g. a :class:`SineProfile`)."""

    p0: np.ndarray
    e: np.ndarray
    s0: float
    accel: Callable[..., Any]
    T: float

    def start_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.p0, self.s0 * self.e

    def pos(self, tau: np.ndarray) -> np.ndarray:
        s = self.s0 * tau + _profile_integral(self.accel, tau, 2)
        return self.p0 + np.outer(s, self.e)

    def vel(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(self.s0 + _profile_integral(self.accel, tau, 1), self.e)

    def acc(self, tau: np.ndarray) -> np.ndarray:
        return np.outer(_profile_values(self.accel, tau), self.e)


@dataclass(frozen=True)
class _Parabola:
    """``p0 + v0 τ + ½ a τ²`` for ``τ ∈ [0, T]`` (constant acceleration in any direction)."""

    p0: np.ndarray
    v0: np.ndarray
    a: np.ndarray
    T: float

    def start_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.p0, self.v0

    def pos(self, tau: np.ndarray) -> np.ndarray:
        return self.p0 + np.outer(tau, self.v0) + np.outer(0.5 * np.asarray(tau) ** 2, self.a)

    def vel(self, tau: np.ndarray) -> np.ndarray:
        return self.v0 + np.outer(tau, self.a)

    def acc(self, tau: np.ndarray) -> np.ndarray:
        return np.tile(self.a, (np.size(tau), 1))


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

    def start_state(self) -> tuple[np.ndarray, np.ndarray]:
        zero = np.zeros(1)
        return self.pos(zero)[0], self.vel(zero)[0]

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


_Segment = _Line | _ProfileLine | _Parabola | _Arc


def _end(seg: _Segment) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and velocity [m/s] of a piece at its end."""
    T = np.array([seg.T])
    return seg.pos(T)[0], seg.vel(T)[0]


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


# ------------------------------------------------------------------ the path
@dataclass(frozen=True)
class AnalyticPath:
    """A smooth path: consecutive pieces (lines, arcs, ...), optionally with a motion along z.

    What the generators of :mod:`obsplan.trajectory.generators` return. Within a piece, position,
    velocity and acceleration are analytic in time; at a breakpoint the acceleration may jump (a
    leg meets a turn). :meth:`sample` gives the held-input trajectory (module docstring).
    Picklable (no closures) unless a piece holds a user's callable acceleration profile.

    Attributes
    ----------
    segments
        The pieces, in order; each lasts its ``T`` [s] from the previous one's end.
    z
        Motion along z for a path whose pieces are in (x, y); None for a 2D path or a path whose
        pieces are already 3D (a circle in a plane ``z = const``).
    inputs
        How :meth:`sample` chooses the held inputs: ``"chord"`` (velocity exact at the samples)
        or ``"midpoint"`` (acceleration at each interval's midpoint); see the module docstring.
    t_end
        Time [s] at which the path ends, inside its last piece; None: at the end of the last
        piece.
    """

    segments: tuple[_Segment, ...]
    z: _ZLine | _ZSine | None = None
    inputs: Literal["chord", "midpoint"] = "chord"
    t_end: float | None = None

    @property
    def dim(self) -> int:
        """2 or 3."""
        return 3 if self.z is not None else int(self.segments[0].pos(np.zeros(1)).shape[1])

    def _starts(self) -> np.ndarray:
        """Start time of every piece and the end of the last one [s] (``t_end`` ignored)."""
        return np.concatenate([[0.0], np.cumsum([s.T for s in self.segments])])

    @property
    def breakpoints(self) -> np.ndarray:
        """Start time of every piece and the end time, shape ``(n_pieces + 1,)`` [s]."""
        starts = self._starts()
        if self.t_end is None:
            return starts
        first = starts[:-1]
        return np.append(first[first < self.t_end], self.t_end)

    @property
    def duration(self) -> float:
        """Length of the path [s]."""
        return float(self.breakpoints[-1])

    def _column(self, t: np.ndarray, which: str, piece: int | None = None) -> np.ndarray:
        """Positions, velocities or accelerations (``which``) at times ``t`` [s], (N, dim)."""
        starts = self._starts()
        if piece is None:
            idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segments) - 1)
        elif not 0 <= int(piece) < len(self.segments):
            raise ConfigError(f"piece must be in 0..{len(self.segments) - 1}, got {piece!r}")
        else:
            idx = np.full(t.size, int(piece))
        out = np.empty((t.size, self.dim))
        for i in np.unique(idx):
            sel = idx == i
            val = getattr(self.segments[i], which)(t[sel] - starts[i])
            out[sel, : val.shape[1]] = val
        if self.z is not None:
            out[:, 2] = getattr(self.z, which)(t)
        return out

    def evaluate(
        self, t: np.ndarray | float, piece: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s] and acceleration [m/s²] at times ``t`` [s], each (N, dim).

        ``piece=None``: the piece that contains each time (right-continuous at breakpoints);
        ``piece=i``: the formulas of piece ``i`` (e.g. its limit at its end time).

        Parameters
        ----------
        t : float or ndarray, shape (N,)
            Times [s] from the start of the path.
        piece : int or None, optional
            Index of the piece whose formulas are used; None: the piece containing each time.

        Returns
        -------
        pos : ndarray, shape (N, dim)
            Positions [m].
        vel : ndarray, shape (N, dim)
            Velocities [m/s].
        acc : ndarray, shape (N, dim)
            Accelerations [m/s²].

        Raises
        ------
        ConfigError
            If ``piece`` is not the index of a piece.
        """
        t = np.atleast_1d(np.asarray(t, float))
        pos, vel, acc = (self._column(t, w, piece) for w in ("pos", "vel", "acc"))
        return pos, vel, acc

    def sample(self, dt: float = DT, duration: float | None = None) -> Trajectory:
        """The held-input trajectory of the path (module docstring).

        Parameters
        ----------
        dt : float, optional
            Sampling interval [s], positive; the paper's 0.01 s (100 Hz, section 7) by default.
        duration : float or None, optional
            Length [s] to sample, longer than ``dt``; default: the whole path
            (:attr:`duration`). Samples are ``0, dt, 2dt, ...`` and the last one is exactly at
            ``duration`` (a shorter last step if ``dt`` does not divide it).

        Returns
        -------
        Trajectory
            ``N = ceil(duration / dt) + 1`` samples (times (N,) [s], positions, velocities and
            inputs (N, dim)), integrated exactly from the path's start state: chord inputs
            (velocities exact at the samples) or midpoint inputs, as :attr:`inputs` says.
        """
        total, dt = _check_timing(self.duration if duration is None else duration, dt)
        t = _time_grid(total, dt)
        if self.inputs == "chord":
            V = self._column(t, "vel")
            u = np.diff(V, axis=0) / np.diff(t)[:, None]
            p0 = self.segments[0].pos(np.zeros(1))[0]
            if self.z is not None:
                p0 = np.append(p0, self.z.start)
            return Trajectory.from_inputs(t, p0, V[0], u)
        p0, v0 = self.segments[0].start_state()
        if self.z is not None:
            p0 = np.append(p0, self.z.start)
            v0 = np.append(v0, self.z.vel(np.zeros(1))[0])
        return Trajectory.from_inputs(t, p0, v0, self._column(0.5 * (t[:-1] + t[1:]), "acc"))
