"""Guidance of the simulated vehicle (closed loop) and the limits its true path is checked against.

A vehicle at sea does not fly its planned accelerations blind: it steers its *estimate* onto the
plan. :class:`Guidance` is the law the closed-loop Monte Carlo
(:mod:`obsplan.estimation.montecarlo.closedloop`) applies at every filter step ``k`` (step ``h``):

    u = sat(u_ref + Kp (p_ref - p̂) + Kd (v_ref - v̂))

with ``p̂``, ``v̂`` the navigation filter's estimate of the position and inertial velocity
``p' = v (+ v_f)`` after the update at ``k`` and ``(p_ref, v_ref, u_ref)`` the reference (the plan,
or a replanned path). The navigation filter (:attr:`Guidance.navigation`) is the EKF or the
Gaussian sum (its mixture's mean): where the range geometry is ambiguous an EKF can lock onto a
wrong branch, and a vehicle steering on it flies its error into the true path (measured on three
plans in ``benchmarks/bench_closed_loop_divergence.py``). Saturation, in this order:

1. per axis, ``|u_i| <= accel_i`` (the vehicle's acceleration bound);
2. with a speed bound, if the estimated velocity at the step's end ``v⁺ = v̂ + h u`` is faster
   than it, ``v⁺`` is projected onto the speed ball (its direction kept, ``v_max v⁺/|v⁺|``),
   ``u = (v⁺ - v̂)/h``, and the box of 1. applies again. The projection is continuous and keeps
   the turn: a path flown at the speed bound keeps its lateral acceleration and loses only the
   ``O(h |u|²/v)`` along-track excess (scaling ``u`` down instead would fly such a path
   straight). The acceleration bound always holds; the speed bound holds as far as the box
   allows.

**Gains** (:meth:`Guidance.from_limits`): critically damped (``ζ = 1``, no overshoot),
``Kp = ω²``, ``Kd = 2ω``, with the natural frequency chosen so that the feedback on a typical
position error ``e`` uses half of the smallest acceleration bound, ``Kp e = a_min / 2``:
``ω = sqrt(a_min / (2 e))``. The other half is left for the plan's own acceleration and the
velocity feedback. With the default problem (0.05 m/s², ``e`` = 1 m, the validation's prior
position std) ``ω = 0.16 rad/s``: the loop corrects drifts within ~30 s while the estimate's
error, which it cannot see, passes into the truth filtered at that bandwidth.

**Speed reserve** (per run, recomputed from the navigation filter's covariance after every update):
the estimated speed is bounded by ``v_max - speed_k σ_v`` instead of ``v_max`` (``σ_v`` the largest
per-axis std of the estimated inertial velocity). The true velocity is the estimate's minus its
error, so the *true* speed then holds ``v_max`` at the confidence of ``speed_k`` (the validation
sets it from ``limits.keepout_confidence``; the planner keeps the same reserve in the plan,
:mod:`obsplan.planning.solver.margins`). Bounding the estimated speed at ``v_max`` itself lets the
true vehicle exceed it by its velocity error in most runs. The reserve takes at most
:data:`SPEED_RESERVE_CAP` of the bound: slowing a path more than that (a prior's wide velocity std)
makes its tracking error, not its speed, the larger risk. A path planned at the bound without the
reserve (a baseline) lags it by a few metres instead.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from obsplan.core.errors import ConfigError

#: Largest fraction of the speed bound the speed reserve takes (module docstring).
SPEED_RESERVE_CAP = 0.3
#: Filters a vehicle can steer on (:attr:`Guidance.navigation`).
NAVIGATION_FILTERS = ("ekf", "gsf")


def _axes(value: float | Sequence[float]) -> tuple[float, ...]:
    """One bound per axis from a number or a sequence (checked by :func:`_positive`)."""
    return (cast(float, value),) if np.isscalar(value) else tuple(cast(Sequence[float], value))


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ConfigError(f"{name} must be a positive number, got {value!r}")
    return v


def _pair(value, name: str) -> tuple[float, float] | None:
    if value is None:
        return None
    lo, hi = (float(x) for x in value)
    if not (lo < hi) or math.isnan(lo) or math.isnan(hi):
        raise ConfigError(f"{name} must be an interval (low, high) with low < high, got {value!r}")
    return (lo, hi)


@dataclass(frozen=True)
class Guidance:
    """Feed-forward plus PD feedback on the estimated state, saturated (module docstring).

    Parameters
    ----------
    accel : float or tuple of float
        Acceleration bound per axis [m/s²] (one number applies to every axis).
    speed : float or None
        Bound on the estimated speed ``|p̂'|`` [m/s] (``None``: none).
    kp : float
        Position gain [1/s²].
    kd : float
        Velocity gain [1/s].
    speed_k : float, optional
        Velocity stds kept below the speed bound (module docstring, "Speed reserve"); 0: none.
    on_truth : bool, optional
        A diagnostic, not a vehicle: feed back the *true* state instead of the estimate (perfect
        navigation, the filter passive). Flying the plan's geometry faithfully without feeding
        the filter's error into the truth separates the two
        (``benchmarks/bench_closed_loop_divergence.py``).
    navigation : {"ekf", "gsf"}, optional
        The filter the vehicle steers on (:data:`NAVIGATION_FILTERS`): ``"ekf"``, or ``"gsf"``
        (the Gaussian-sum EKF's mixture mean and covariance: an EKF that locks onto a wrong
        branch of the range geometry steers the true vehicle away with it).
    """

    accel: tuple[float, ...]
    speed: float | None
    kp: float
    kd: float
    speed_k: float = 0.0
    on_truth: bool = False
    navigation: str = "ekf"

    def __post_init__(self) -> None:
        acc = _axes(self.accel)
        object.__setattr__(
            self, "accel", tuple(_positive(a, "guidance accel") for a in acc) or (math.inf,)
        )
        if self.speed is not None:
            object.__setattr__(self, "speed", _positive(self.speed, "guidance speed"))
        for name in ("kp", "kd"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"guidance {name} must be a gain >= 0, got {v!r}")
            object.__setattr__(self, name, v)
        k = float(self.speed_k)
        if not (math.isfinite(k) and k >= 0):
            raise ConfigError(f"guidance speed_k must be >= 0, got {self.speed_k!r}")
        object.__setattr__(self, "speed_k", k)
        if self.navigation not in NAVIGATION_FILTERS:
            raise ConfigError(
                f"guidance navigation must be one of {', '.join(NAVIGATION_FILTERS)}, "
                f"got {self.navigation!r}"
            )

    @classmethod
    def from_limits(
        cls,
        accel: float | Sequence[float],
        speed: float | None = None,
        error_scale_m: float = 1.0,
        speed_k: float = 0.0,
        navigation: str = "ekf",
    ) -> Guidance:
        """Critically damped gains from the limits (module docstring).

        Parameters
        ----------
        accel : float or sequence of float
            Acceleration bound per axis [m/s²].
        speed : float or None, optional
            Speed bound [m/s] or ``None``.
        error_scale_m : float, optional
            Typical position error [m] (e.g. the prior position std): the feedback on it uses
            half of the smallest acceleration bound.
        speed_k : float, optional
            Velocity stds kept below the speed bound (module docstring, "Speed reserve").
        navigation : {"ekf", "gsf"}, optional
            The filter steered on (:attr:`navigation`).

        Returns
        -------
        Guidance
            The guidance with ``Kp = ω²``, ``Kd = 2ω``.
        """
        acc = _axes(accel)
        a_min = min(_positive(a, "guidance accel") for a in acc)
        omega = math.sqrt(a_min / (2.0 * _positive(error_scale_m, "error_scale_m")))
        return cls(
            accel=acc,
            speed=speed,
            kp=omega**2,
            kd=2.0 * omega,
            speed_k=speed_k,
            navigation=navigation,
        )

    @property
    def natural_frequency(self) -> float:
        """``ω = sqrt(Kp)`` [rad/s]."""
        return math.sqrt(self.kp)

    def bounds(self, dim: int) -> np.ndarray:
        """The acceleration bound of each of ``dim`` axes [m/s²], shape (dim,).

        Parameters
        ----------
        dim : int
            Spatial dimension of the vehicle.

        Returns
        -------
        ndarray, shape (dim,)
            The bounds [m/s²].

        Raises
        ------
        ConfigError
            If there are several bounds but not ``dim``.
        """
        a = np.asarray(self.accel, float)
        if a.size == 1:
            return np.full(dim, float(a[0]))
        if a.size != dim:
            raise ConfigError(f"guidance accel has {a.size} bounds for a {dim}D vehicle")
        return a

    def to_dict(self) -> dict:
        """The guidance as a plain mapping (for JSON outputs).

        Returns
        -------
        dict
            Each field by name (bounds as lists).
        """
        return {
            "accel": list(self.accel),
            "speed": self.speed,
            "kp": self.kp,
            "kd": self.kd,
            "speed_k": self.speed_k,
            "on_truth": self.on_truth,
            "navigation": self.navigation,
        }


@dataclass(frozen=True)
class TruthLimits:
    """Limits the *true* path of every run is checked against
    (:class:`~obsplan.estimation.montecarlo.stats.TruthStats`).

    Parameters
    ----------
    accel : tuple of float or None
        Per-axis acceleration bound [m/s²] of the applied inputs.
    speed : float or None
        Bound on the true speed over ground ``|p'|`` [m/s].
    area : tuple of (float, float) or None
        ``((x_min, x_max), (y_min, y_max))`` [m] the path must stay in.
    depth : tuple of float or None
        ``(z_min, z_max)`` [m] (3D; ``z`` is depth).
    min_range, max_range : float or None
        Keep-out radius around the beacon and largest distance to it [m].
    rtol : float
        Relative slack on the speed, acceleration and range bounds (0: strict).
    atol_m : float
        Slack [m] on the area and depth bounds (0: strict).
    """

    accel: tuple[float, ...] | None = None
    speed: float | None = None
    area: tuple[tuple[float, float], tuple[float, float]] | None = None
    depth: tuple[float, float] | None = None
    min_range: float | None = None
    max_range: float | None = None
    rtol: float = 0.0
    atol_m: float = 0.0

    def __post_init__(self) -> None:
        if self.accel is not None:
            acc = _axes(self.accel)
            object.__setattr__(self, "accel", tuple(_positive(a, "limits accel") for a in acc))
        for name in ("speed", "min_range", "max_range"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _positive(getattr(self, name), f"limits {name}"))
        if self.area is not None:
            x, y = self.area
            object.__setattr__(self, "area", (_pair(x, "limits area x"), _pair(y, "limits area y")))
        object.__setattr__(self, "depth", _pair(self.depth, "limits depth"))
        for name in ("rtol", "atol_m"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"limits {name} must be >= 0, got {v!r}")
            object.__setattr__(self, name, v)

    def box(self) -> np.ndarray:
        """Rows x, y (the area) and z (the depth band) as ``(low, high)``, ±inf where unlimited,
        shape (3, 2) (the kernels' layout).

        Returns
        -------
        ndarray, shape (3, 2)
            The bounds [m].
        """
        b = np.tile([-np.inf, np.inf], (3, 1))
        if self.area is not None:
            b[0], b[1] = self.area
        if self.depth is not None:
            b[2] = self.depth
        return b

    def accel_bounds(self, dim: int) -> np.ndarray:
        """Per-axis acceleration bound, shape (dim,) (inf: none).

        Parameters
        ----------
        dim : int
            Spatial dimension of the vehicle.

        Returns
        -------
        ndarray, shape (dim,)
            The bounds [m/s²].
        """
        if self.accel is None:
            return np.full(dim, np.inf)
        a = np.asarray(self.accel, float)
        return np.full(dim, float(a[0])) if a.size == 1 else a

    def to_dict(self) -> dict:
        """The limits as a plain mapping (for JSON outputs).

        Returns
        -------
        dict
            Each field by name (None where unlimited).
        """
        return {
            "accel": None if self.accel is None else list(self.accel),
            "speed": self.speed,
            "area": None if self.area is None else [list(a) for a in self.area],
            "depth": None if self.depth is None else list(self.depth),
            "min_range": self.min_range,
            "max_range": self.max_range,
            "rtol": self.rtol,
            "atol_m": self.atol_m,
        }
