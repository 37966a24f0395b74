"""One logged mission filtered and smoothed: an EKF with an innovation gate and re-acquisition,
then the Rauch–Tung–Striebel smoother, in numpy.

**Model.** The state is ``x = (p, v[, v_f])`` of :class:`~obsplan.model.vehicle.VehicleModel`.
Between rows the filter predicts with the exact ZOH discretisation
(:meth:`VehicleModel.transition <obsplan.model.vehicle.VehicleModel.transition>`) of the
logged inputs (held; zero when the log has only DVL velocities, which then carry the velocity)
and the exact covariance of white acceleration noise of density ``accel_std``
(:func:`obsplan.estimation.kalman.integrated_noise`). At a row it updates with the readings of
that row, the range first and linearised at the prior, then the DVL and depth rows, each a
scalar update in the Joseph form (kept symmetric). Readings, their variances, ``h`` and ``H``
come from the estimation floor (:func:`obsplan.estimation.sensors.to_outputs`,
:func:`~obsplan.estimation.sensors.output_model`) with the paper's range output
``y = ½ |p - b|²``: a moving beacon is handled by evaluating the range row at the position
relative to the row's beacon. The range update is the Gaussian second-order one by default
(the range's curvature ``M`` over the prior adds ``½ tr(M P)`` to the predicted reading and
``½ tr((M P)²)`` to its variance, as :mod:`obsplan.estimation.filters.ekf`): a replay starts
from a guess metres to tens of metres off, where the first-order update is overconfident.

**The gate.** A range is used when its normalised innovation squared ``NIS = ν² / s`` is at most
the chi-square quantile of one degree of freedom at :data:`GATE_PROBABILITY` = 0.999 (10.83):
a correct range is rejected once in a thousand (a mission of a few hundred ranges loses none or
one), while a range off by more than 3.3 innovation standard deviations, the late arrivals of
multipath (too long by metres to tens of metres), is rejected. A looser 0.99 gate (6.63) would
throw away ten times more good ranges; a tighter one lets more multipath through.

**One rule with the Monte Carlo's filters.** The decision is
:func:`obsplan.estimation.kernels.gate_action`, the one the Monte Carlo's EKF and Gaussian sum
take, with their late-arrival-aware form (:mod:`obsplan.estimation.channel`, "The innovation
gate"): multipath only ever lengthens a range, so a range *shorter* than predicted beyond the
gate says the filter is wrong, and the filter re-acquires on it at once (below) instead of
rejecting it; and a range inside the gate is weighed by
:func:`~obsplan.estimation.kernels.late_weight`, the posterior probability ``β`` that it is the
direct arrival and not a late one (prior 0.1, excess up to 30 m): the update is the
moment-matched mixture of "updated" and "not updated", ``x += β K ν`` and ``P = β P⁺ + (1-β) P⁻
+ β(1-β) (K ν)(K ν)ᵀ`` (``P⁺`` the Joseph update), so a doubtful long range moves the track
little and the covariance says so. Without a gate (``gate_probability = 1``) every range is used
with its full weight.

**Re-acquisition.** A gate can also lock the filter out: after a long dropout, or from a bad
initial guess, every range looks like an outlier and the filter dead-reckons on silently. After
:data:`REACQUIRE_AFTER` = 5 consecutive rejections the filter is declared lost: an isotropic
position variance is added to the next range's prior, just enough to put that range's NIS on
the gate (``hᵀ ΔP h = ν²/γ - s``), and that range is used. Five in a row is the choice because
independent multipath at a 10 % rate gives five in a row once in 1e5 ranges, so
re-acquisition almost never fires on outliers, while a lost filter is back within five ranges
(one or two minutes at one range every 10-30 s). The widened prior is stored as the prediction
of that row, i.e. as process
noise of that step, so the smoother stays consistent. Two alternatives were measured
(``tests/test_replay.py``): scaling the whole covariance (position and velocity) by the same
factor let a filter started 57 m off with a 2 m std wander to 460 m instead of recovering,
because the inflated velocity was then pulled by single ranges; a robust weight (the next range
down-weighted to the gate) is bounded by the prior's small covariance, so an overconfident filter
stays lost for many ranges. Position only, isotropic, brings that filter back to ~16 m.

**Smoother.** :func:`obsplan.estimation.filters.linear.rts_smooth` over the stored predicted and
filtered moments and the transitions; rejected ranges stay out of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from obsplan.core.budget import check_log_rows
from obsplan.core.errors import InputError
from obsplan.estimation import kalman
from obsplan.estimation.channel import (
    BIAS_PRIOR_STD_M,
    GATE_PROBABILITY,
    LATE_MAX_M,
    REACQUIRE_AFTER,
    SCALE_PRIOR_STD,
)
from obsplan.estimation.config import CURRENT_PRIOR_STD
from obsplan.estimation.filters import linear
from obsplan.estimation.filters.ekf import calibration_prior, pad_calibration
from obsplan.estimation.kernels import GATE_REACQUIRE, GATE_USE, gate_action, late_weight
from obsplan.estimation.replay.log import MissionLog
from obsplan.estimation.replay.result import ReplayResult
from obsplan.estimation.sensors import OutputModel, output_model, to_outputs
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel

#: Default range noise [m]: a sound-speed error of ~0.1 % at hundreds of metres plus timing.
DEFAULT_RANGE_STD = 1.0
#: Default DVL noise [m/s] (a typical 300-600 kHz DVL at survey speed).
DEFAULT_DVL_STD = 0.02
#: Default depth-gauge noise [m].
DEFAULT_DEPTH_STD = 0.1
#: Default white-acceleration density [m/s²/√Hz]: the error of logged inputs (or, in a DVL-only
#: log, the unknown accelerations between DVL readings) over a survey's gentle manoeuvres.
DEFAULT_ACCEL_STD = 0.01
#: Prior standard deviation of the velocity [m/s] when the log has no DVL reading to start from.
DEFAULT_INIT_VELOCITY_STD = 1.0


@dataclass(frozen=True)
class ReplayConfig:
    """Noises, the initial guess, the gate and the beacon of a replay.

    Attributes
    ----------
    range_std : float
        Range noise [m].
    dvl_std : float
        DVL noise per axis [m/s].
    depth_std : float
        Depth noise [m].
    accel_std : float
        White-acceleration density of the process noise [m/s²/√Hz].
    init : tuple of float or None
        Initial position guess [m], shape ``(n,)``; None: :func:`default_init`.
    init_std : float or None
        Its standard deviation per axis [m]; None: the first range (the guess may be anywhere
        on the circle of the first range).
    init_velocity : tuple of float or None
        Initial velocity guess [m/s], shape ``(n,)``; None: the first DVL reading when the log
        starts with one (std three times the DVL noise), else at rest.
    init_velocity_std : float
        Its standard deviation per axis [m/s] (not used when the first DVL reading gives it).
    current : bool
        Estimate an unknown constant current ``v_f`` (prior std
        :data:`~obsplan.estimation.config.CURRENT_PRIOR_STD` per axis).
    gate_probability : float
        Confidence of the NIS gate, in (0, 1); 1 disables the gate.
    reacquire_after : int or None
        Consecutive rejections before re-acquisition; None never re-acquires.
    second_order : bool
        The Gaussian second-order range update (module docstring).
    beacon : tuple of float or None
        A fixed beacon [m], shape ``(n,)``; None: the origin (unless the log or
        ``beacon_path`` gives a moving one).
    beacon_path : BeaconPath or None
        A moving beacon, read at each range's time.
    scale_state : bool
        Estimate the ranges' scale ``k`` (a sound-speed error; prior ``N(1,``
        :data:`~obsplan.estimation.channel.SCALE_PRIOR_STD` ``²)``), constant.
    bias_state : bool
        Estimate a range bias ``β`` [m] (a clock offset; prior ``N(0,``
        :data:`~obsplan.estimation.channel.BIAS_PRIOR_STD_M` ``²)``), constant.
    """

    range_std: float = DEFAULT_RANGE_STD
    dvl_std: float = DEFAULT_DVL_STD
    depth_std: float = DEFAULT_DEPTH_STD
    accel_std: float = DEFAULT_ACCEL_STD
    init: tuple[float, ...] | None = None
    init_std: float | None = None
    init_velocity: tuple[float, ...] | None = None
    init_velocity_std: float = DEFAULT_INIT_VELOCITY_STD
    current: bool = False
    gate_probability: float = GATE_PROBABILITY
    reacquire_after: int | None = REACQUIRE_AFTER
    second_order: bool = True
    beacon: tuple[float, ...] | None = None
    beacon_path: BeaconPath | None = None
    scale_state: bool = False
    bias_state: bool = False

    def __post_init__(self) -> None:
        for name in ("range_std", "dvl_std", "depth_std", "accel_std"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} (--{name.replace('_', '-')}): {v!r} must be positive")
        for name in ("init_std", "init_velocity_std"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} (--{name.replace('_', '-')}): {v!r} must be positive")
        if not 0.0 < self.gate_probability <= 1.0:
            raise InputError(f"gate_probability: {self.gate_probability!r} must be in (0, 1]")
        if self.reacquire_after is not None and self.reacquire_after < 1:
            raise InputError(f"reacquire_after: {self.reacquire_after!r} must be at least 1")
        if self.beacon is not None and self.beacon_path is not None:
            raise InputError("give a fixed beacon or a beacon path, not both")

    @property
    def gate_nis(self) -> float:
        """The NIS threshold: the chi-square quantile of one degree of freedom (inf: no gate)."""
        p = self.gate_probability
        return math.inf if p >= 1.0 else float(chi2.ppf(p, 1))


def beacon_rows(log: MissionLog, config: ReplayConfig) -> np.ndarray:
    """The beacon's position at every row of ``log``, shape ``(N, n)`` [m] (NaN where unneeded).

    Parameters
    ----------
    log : MissionLog
        The log; its own beacon columns win when present.
    config : ReplayConfig
        The fixed beacon or the beacon path (refused if the log has beacon columns).

    Returns
    -------
    ndarray, shape (N, n)
        Beacon positions [m]; with a path, at the rows with a range (NaN elsewhere).

    Raises
    ------
    InputError
        Beacon columns and a configured beacon at once, a beacon of another dimension, or a
        path that does not cover the ranges' times.
    """
    n = log.dim
    if log.beacon is not None:
        if config.beacon is not None or config.beacon_path is not None:
            raise InputError(
                f"{log.source} has beacon columns (bx,by[,bz]); remove --beacon/--beacon-path "
                "or the columns"
            )
        return np.array(log.beacon)
    if config.beacon_path is not None:
        path = config.beacon_path
        if path.dim != n:
            raise InputError(f"the beacon path is {path.dim}D but {log.source} is {n}D")
        out = np.full((log.n_rows, n), np.nan)
        rows = log.range_rows
        path.check_covers(float(log.t[rows[0]]), float(log.t[rows[-1]]), "--beacon-path")
        out[rows] = path.position(log.t[rows])
        return out
    b = np.zeros(n) if config.beacon is None else np.asarray(config.beacon, float)
    if b.shape != (n,):
        raise InputError(f"the beacon needs {n} coordinates for the {n}D log {log.source}")
    return np.repeat(b[None], log.n_rows, axis=0)


def default_init(log: MissionLog, beacons: np.ndarray) -> np.ndarray:
    """The documented guess without ``init``: on the first range's sphere, north of the beacon.

    The beacon at the first range plus that range horizontally along ``+x`` (north); in 3D at
    the first logged depth (or the beacon's depth), the horizontal distance reduced to keep the
    range. Any point of the circle is as good a guess before the vehicle has moved; the filter
    needs the excitation of the path, not the guess, to pick the right one.

    Parameters
    ----------
    log : MissionLog
        The log (its first range and depth).
    beacons : ndarray, shape (N, n)
        The beacon per row (:func:`beacon_rows`).

    Returns
    -------
    ndarray, shape (n,)
        The position guess [m].
    """
    k = int(log.range_rows[0])
    r, b = float(log.ranges[k]), beacons[k]
    p = b.copy()
    horizontal = r
    if log.dim == 3:
        if log.depth is not None and np.any(np.isfinite(log.depth)):
            p[2] = float(log.depth[np.isfinite(log.depth)][0])
        horizontal = math.sqrt(max(r * r - (p[2] - b[2]) ** 2, 0.0))
    p[0] += horizontal
    return p


def _start(
    log: MissionLog, config: ReplayConfig, model: VehicleModel, beacons: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Initial mean and covariance (:class:`ReplayConfig` ``init``, ``init_std``)."""
    n, m = log.dim, model.state_dim
    x0, P0 = np.zeros(m), np.zeros((m, m))
    p0 = default_init(log, beacons)
    if config.init is not None:
        p0 = _coordinates(config.init, n, "--init", log.source)
    first_range = float(log.ranges[log.range_rows[0]])
    sp = config.init_std if config.init_std is not None else max(first_range, 1.0)
    x0[:n] = p0
    P0[:n, :n] = sp**2 * np.eye(n)
    sv = config.init_velocity_std
    if config.init_velocity is not None:
        x0[n : 2 * n] = _coordinates(config.init_velocity, n, "--init-velocity", log.source)
    elif log.dvl is not None and np.isfinite(log.dvl[0, 0]):
        x0[n : 2 * n], sv = log.dvl[0], 3.0 * config.dvl_std  # the first DVL reading, widened
    P0[n : 2 * n, n : 2 * n] = sv**2 * np.eye(n)
    if model.current:
        P0[2 * n :, 2 * n :] = CURRENT_PRIOR_STD**2 * np.eye(n)
    return x0, P0


def _coordinates(value: tuple[float, ...], n: int, option: str, source: str) -> np.ndarray:
    out = np.asarray(value, float)
    if out.shape != (n,):
        raise InputError(
            f"{option} needs {n} coordinates for the {n}D log {source}, got {len(out)}"
        )
    return out


def joseph_update(
    x: np.ndarray, P: np.ndarray, h: np.ndarray, nu: float, r: float, beta: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """A scalar update in the Joseph form, ``P⁺ = (I - k hᵀ) P (I - k hᵀ)ᵀ + r k kᵀ``, symmetrised.

    Parameters
    ----------
    x : ndarray, shape (m,)
        Prior mean.
    P : ndarray, shape (m, m)
        Prior covariance.
    h : ndarray, shape (m,)
        Jacobian of the reading.
    nu : float
        Innovation (reading minus prediction), in the reading's unit.
    r : float
        Variance of the reading (and any second-order term).
    beta : float, optional
        Probability that the reading is the one modelled (the late-arrival weight, module
        docstring); 1: the ordinary update.

    Returns
    -------
    x : ndarray, shape (m,)
        Posterior mean.
    P : ndarray, shape (m, m)
        Posterior covariance, symmetric and positive semi-definite (Joseph form; with
        ``beta < 1`` the moment-matched mixture of it and the prior).
    """
    b = P @ h
    s = float(h @ b) + r
    k = b / s
    A = np.eye(x.size) - np.outer(k, h)
    P_upd = kalman.symmetrize(A @ P @ A.T + r * np.outer(k, k))
    if beta == 1.0:
        return x + k * nu, P_upd
    step = k * nu
    mixed = beta * P_upd + (1.0 - beta) * P + beta * (1.0 - beta) * np.outer(step, step)
    return x + beta * step, kalman.symmetrize(mixed)


@dataclass
class _Gate:
    """The gate's threshold, its run of rejections and the per-range record."""

    nis_max: float
    reacquire_after: int | None
    run: int = 0

    def judge(
        self, nu: float, s: float, hPh: float, r: float, late: float
    ) -> tuple[bool, float, float]:
        """``(use, inflation, beta)``: use the range, after widening the prior so that ``hᵀ P h``
        grows by the factor ``inflation`` (>= 1; 1: no re-acquisition), with the late-arrival
        weight ``beta`` (1 without a gate or on re-acquisition); the rule is
        :func:`~obsplan.estimation.kernels.gate_action` (module docstring). ``late``: the
        extent of a late arrival's innovation in the reading's unit."""
        act = gate_action(nu * nu / s, self.nis_max, self.run, self.reacquire_after or 0, nu < 0)
        if act == GATE_USE:
            self.run = 0
            beta = late_weight(nu, s, late)[0] if math.isfinite(self.nis_max) else 1.0
            return True, 1.0, beta
        if act == GATE_REACQUIRE:
            self.run = 0
            return True, max(1.0, (nu * nu / self.nis_max - r) / hPh) if hPh > 0 else 1.0, 1.0
        self.run += 1
        return False, 1.0, 1.0


def _range_row(
    om: OutputModel, x: np.ndarray, P: np.ndarray, b: np.ndarray, y: float, r: float, second: bool
) -> tuple[float, np.ndarray, float, float]:
    """``(ν, h, r, hᵀ P h)`` of the range reading ``y`` (half-squared, with its variance ``r``)
    relative to the beacon ``b``, with the second-order terms when ``second``."""
    n = b.size
    xr = x.copy()
    xr[:n] -= b
    hx, H = om.evaluate(xr[None])
    nu, h = y - float(hx[0, 0]), H[0, 0]
    if second:
        MP = om.M[0] @ P
        nu -= 0.5 * float(np.trace(MP))
        r += 0.5 * float(np.sum(MP * MP.T))
    return nu, h, r, float(h @ P @ h)


@dataclass(frozen=True)
class _Calibration:
    """The range's calibration states after the model's ``m`` states: their names, indices
    (-1: absent), nominal values and prior variances."""

    m: int
    scale: bool
    bias: bool

    @property
    def names(self) -> tuple[str, ...]:
        return ("range_scale",) * self.scale + ("range_bias",) * self.bias

    @property
    def size(self) -> int:
        return int(self.scale) + int(self.bias)

    @property
    def ks(self) -> int:
        return self.m if self.scale else -1

    @property
    def kb(self) -> int:
        return self.m + self.size - 1 if self.bias else -1

    def pad(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x, P)`` with the calibration's nominal values and prior variances appended (the
        Monte Carlo filters' priors, :func:`~obsplan.estimation.filters.ekf.calibration_prior`)."""
        nominal, var = calibration_prior(
            SCALE_PRIOR_STD if self.scale else None, BIAS_PRIOR_STD_M if self.bias else None
        )
        return np.append(x, nominal), pad_calibration(P, var)

    def predicted_range(self, x: np.ndarray, b: np.ndarray) -> float:
        """``k |p - b| + β`` [m] at the state ``x``."""
        k = x[self.ks] if self.scale else 1.0
        return k * float(np.linalg.norm(x[: b.size] - b)) + (x[self.kb] if self.bias else 0.0)


def _calibrated_range_row(
    cal: _Calibration, x: np.ndarray, P: np.ndarray, b: np.ndarray, y: float, r: float, second: bool
) -> tuple[float, np.ndarray, float, float]:
    """:func:`_range_row` with the calibration states: the half-squared reading ``y`` against
    ``½ r̃²``, ``r̃ = k ρ + β``, its gradient ``r̃ g`` and Hessian ``g gᵀ + r̃ ∇²r̃`` over the
    whole state (``g = ∇r̃``). The Monte Carlo EKF's row,
    :func:`obsplan.estimation.kernels.calibrated_row`, in numpy: that one is a numba kernel on the
    batched workspace, and the replay is numpy throughout (no compile for one log)."""
    n, m = b.size, x.size
    rel = x[:n] - b
    rho = float(np.linalg.norm(rel))
    u = rel / rho
    k = x[cal.ks] if cal.scale else 1.0
    rt = cal.predicted_range(x, b)
    g = np.zeros(m)
    g[:n] = k * u
    Hr = np.zeros((m, m))
    Hr[:n, :n] = k * (np.eye(n) - np.outer(u, u)) / rho
    if cal.scale:
        g[cal.ks] = rho
        Hr[:n, cal.ks] = Hr[cal.ks, :n] = u
    if cal.bias:
        g[cal.kb] = 1.0
    h = rt * g
    nu = y - 0.5 * rt * rt
    if second:
        HP = (np.outer(g, g) + rt * Hr) @ P
        nu -= 0.5 * float(np.trace(HP))
        r += 0.5 * float(np.sum(HP * HP.T))
    return nu, h, r, float(h @ P @ h)


def replay(log: MissionLog, config: ReplayConfig | None = None) -> ReplayResult:
    """Filter and smooth one logged mission (module docstring).

    Parameters
    ----------
    log : MissionLog
        The log.
    config : ReplayConfig or None, optional
        Noises, initial guess, gate and beacon; None: the defaults.

    Returns
    -------
    ReplayResult
        Filtered and smoothed states and covariances per row, and per range its residual, NIS
        and whether it was used.

    Raises
    ------
    InputError
        A log beyond :data:`~obsplan.core.budget.MAX_LOG_ROWS` rows, a beacon or guess that
        does not fit the log (:func:`beacon_rows`, :class:`ReplayConfig`).
    """
    config = config or ReplayConfig()
    check_log_rows(log.n_rows, log.source)
    beacons = beacon_rows(log, config)
    model = VehicleModel(dim=log.dim, sensors=log.sensors, current=config.current)
    om = output_model(model)
    cal = _Calibration(model.state_dim, config.scale_state, config.bias_state)
    x, P = cal.pad(*_start(log, config, model, beacons))
    noise = {"range": config.range_std, "depth": config.depth_std}
    noise |= {"dvl-bottom": config.dvl_std, "dvl-water": config.dvl_std}
    readings = {"range": log.ranges[:, None]}
    if log.dvl is not None:
        readings[f"dvl-{log.dvl_mode}"] = log.dvl
    if log.depth is not None:
        readings["depth"] = log.depth[:, None]
    Y, V = to_outputs(model, readings, noise)
    filt = _filter(log, config, model, om, cal, beacons, x, P, Y, V)
    xs, Ps = linear.rts_smooth(
        filt["xf"][:, None],
        filt["Pf"][:, None],
        filt["xp"][:, None],
        filt["Pp"][:, None],
        filt["F"],
    )
    Ps = kalman.symmetrize(Ps[:, 0])
    return _result(log, config, model, cal, beacons, filt, xs[:, 0], Ps)


def _filter(log, config, model, om, cal, beacons, x, P, Y, V) -> dict[str, np.ndarray]:
    """The forward pass: stored predicted/filtered moments, transitions and the gate's record
    (the calibration states ``cal`` constant: identity transition, no process noise)."""
    N, n, m = log.n_rows, log.dim, model.state_dim + cal.size
    mx = model.state_dim
    xp, xf = np.empty((N, m)), np.empty((N, m))
    Pp, Pf = np.empty((N, m, m)), np.empty((N, m, m))
    F = np.empty((max(N - 1, 0), m, m))
    W = np.zeros((m, m))
    W[n : 2 * n, n : 2 * n] = config.accel_std**2 * np.eye(n)
    gate = _Gate(config.gate_nis, config.reacquire_after)
    R = log.range_rows.size
    rec = {k: np.zeros(R) for k in ("residual", "nis", "inflation")}
    rec["used"] = np.zeros(R, bool)
    u = np.zeros(n)
    lin = [o for o in range(1, model.output_dim) if om.linear_rows[o]]
    g_lin = {o: np.append(om.g[o], np.zeros(cal.size)) for o in lin}

    def row(x, P, b, y, r):
        if cal.size:
            return _calibrated_range_row(cal, x, P, b, y, r, config.second_order)
        return _range_row(om, x, P, b, y, r, config.second_order)

    j = 0
    for k in range(N):
        if k > 0:
            dt = float(log.t[k] - log.t[k - 1])
            Fx, Gk = model.transition(dt)
            Fk = np.eye(m)
            Fk[:mx, :mx] = Fx
            F[k - 1] = Fk
            x = Fk @ x
            x[:mx] += Gk @ u
            Qk = np.zeros((m, m))
            Qk[:mx, :mx] = kalman.integrated_noise(W[:mx, :mx], n, model.current, dt)
            P = kalman.symmetrize(Fk @ P @ Fk.T + Qk)
        if log.u is not None and np.isfinite(log.u[k, 0]):
            u = log.u[k]  # held from this row on
        if np.isfinite(Y[k, 0]):
            b = beacons[k]
            nu, h, r, hPh = row(x, P, b, Y[k, 0], V[k, 0])
            s = hPh + r
            # the half-squared reading's late extent: ½(r + e)² - ½r² ≈ r e (as the kernels')
            use, alpha, beta = gate.judge(nu, s, hPh, r, LATE_MAX_M * float(log.ranges[k]))
            rec["residual"][j] = log.ranges[k] - cal.predicted_range(x, b)
            rec["nis"][j] = nu * nu / s
            rec["used"][j], rec["inflation"][j] = use, alpha
            if alpha > 1.0:  # re-acquisition: the widened prior is this row's prediction
                P = P.copy()
                P[:n, :n] += (alpha - 1.0) * hPh / float(h[:n] @ h[:n]) * np.eye(n)
                nu, h, r, hPh = row(x, P, b, Y[k, 0], V[k, 0])
            xp[k], Pp[k] = x, P
            if use:
                x, P = joseph_update(x, P, h, nu, r, beta)
            j += 1
        else:
            xp[k], Pp[k] = x, P
        for o in lin:  # linear rows (om.linear_rows): h = c + g x exactly
            if np.isfinite(Y[k, o]):
                go = g_lin[o]
                x, P = joseph_update(x, P, go, Y[k, o] - om.c[o] - float(go @ x), V[k, o])
        xf[k], Pf[k] = x, P
    return {"xp": xp, "Pp": Pp, "xf": xf, "Pf": Pf, "F": F, **rec}


def _result(log, config, model, cal, beacons, filt, xs, Ps) -> ReplayResult:
    rows = log.range_rows
    n = log.dim
    predicted = [cal.predicted_range(xs[k], beacons[k]) for k in rows]
    smoothed = log.ranges[rows] - np.array(predicted)
    return ReplayResult(
        t=log.t,
        state_names=(*model.state_names, *cal.names),
        dim=n,
        sensors=log.sensors,
        x_filt=filt["xf"],
        P_filt=filt["Pf"],
        x_smooth=xs,
        P_smooth=Ps,
        range_rows=rows,
        ranges=log.ranges[rows],
        beacons=beacons[rows],
        residual=filt["residual"],
        residual_smoothed=smoothed,
        nis=filt["nis"],
        used=filt["used"],
        inflation=filt["inflation"],
        gate_probability=config.gate_probability,
        gate_nis=config.gate_nis,
        truth=log.truth,
        source=log.source,
    )
