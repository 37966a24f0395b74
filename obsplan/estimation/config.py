"""Configuration of the filters and of the Monte Carlo: noises, rates, covariances, initial error.

Process noise
-------------
By default process noise is **physical**: white acceleration noise of intensity ``accel_noise``
[m/s²/√Hz] on each axis (PSD ``q = accel_noise²``), and with an unknown current an optional random
walk of the current of intensity ``current_noise`` [m/s/√s] (default 0: the model's current is
constant, eq. 29). Over any span ``h`` the covariance it adds is exact, per axis on ``(p, v)``

    Q(h) = q [[h³/3, h²/2], [h²/2, h]]

(and ``q_f [[h³/3, h²/2], [h²/2, h]]`` on ``(p, v_f)`` for the current, since ``p' = v + v_f``),
the integral ``∫ e^{As} W e^{Aᵀs} ds`` of the intensity ``W = diag(0, q, q_f)`` with ``A² = 0``.
So results do not depend on the filter step: the truth, the EKF, the augmented KF, the Gaussian
sum, the posterior CRB and the planner's covariance recursion all integrate the same ``W``
(:class:`ProcessNoise`). Nothing else is included: no white position noise (a vehicle's position
is the integral of its velocity; the paper's ``1e-3 Ts`` on ``p`` is a discretisation artefact)
and no noise on the KF's extras ``(α, β)`` (constants of the truth). The default
:data:`DEFAULT_ACCEL_NOISE` ``= sqrt(1e-7) ≈ 3.2e-4 m/s²/√Hz`` gives at the default validation
step 0.1 s the velocity variance per step ``q h = 1e-8 = (1e-3 · 0.1)² m²/s²`` of the paper's
``Q`` at that step.

The paper's per-step setting (below) is kept as a preset, :meth:`EstimationConfig.paper`: giving
``q_ekf``/``q_kf`` selects it (their intensity then changes with the step: on one plan going from
dt 0.1 s to 2 s raised the lawn-mower's final bound from 0.95 to 2.20 m).

Paper defaults (section 7) for a model step ``Ts`` [s]:

* range noise ``σ_r = 0.1 m`` (``R = (0.1 m)²``), DVL ``σ = 1e-3 m/s`` (``R_DVL = 1e-6 I``);
  depth ``σ = 0.05 m`` (the paper has no depth gauge; a typical pressure sensor);
* ``Q_EKF = diag(1e-3 Ts · 1_n, 1e-3 Ts · 1_n)²`` per model step;
* ``Q_KF = diag(1e-3 Ts · 1_n, 1e-3 Ts · 1_n, 0, 0)²`` per model step. The paper puts
  ``(1e-6)²`` on ``p0ᵀν0`` and ``|ν0|²``; they are constants of the truth, and once the way process
  noise enters the KF's output is modelled (:mod:`obsplan.estimation.filters.kf`) that fictitious
  noise only makes the KF under-confident on long runs (measured on a 600 s circle at 10 Hz, 50
  runs: NEES 2.3–2.7 after 400 s against the 95 % band [3.25, 4.82]; 3.7–4.0 without it), so it is
  0;
* ``P_EKF = diag(1_n, 0.1 · 1_n)``, ``P_KF = diag(1_n, 0.1 · 1_n, 1, 1)``.

With an ocean current the state has a ``v_f`` block: its process noise is 0 (the current is
constant, eq. 29) and its prior variance is ``(0.1 m/s)²`` per axis; the truth uses
:data:`DEFAULT_CURRENT` unless ``true_current`` is given.

Every field can be overridden with :func:`dataclasses.replace` or the constructor; covariances are
given as a diagonal (vector) or a full matrix in the state order of the filter
(``VehicleModel.state_names`` for the EKF, ``AugmentedModel.state_names`` for the KF).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

import numpy as np

from obsplan.core.csvtable import COLUMN_LIMITS
from obsplan.core.errors import ConfigError
from obsplan.core.textfiles import check_magnitude
from obsplan.estimation.channel import (
    BIAS_PRIOR_STD_M,
    CHANNEL_PRESETS,
    SCALE_PRIOR_STD,
    Channel,
    default_gate,
    gate_nis,
)
from obsplan.estimation.kalman import integrated_noise
from obsplan.estimation.schedule import Schedule, make_schedule
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import SENSOR_ALIASES, SENSORS, VehicleModel
from obsplan.observability.gramian import augmented_model
from obsplan.trajectory.sampled import Trajectory

#: Largest sensor noise standard deviation accepted (m or m/s): beyond it no reading says
#: anything about a vehicle, and squares of it overflow the filters.
MAX_NOISE_STD = 1e6
#: Paper noise levels: range [m], DVL [m/s], depth [m] (depth is not in the paper).
DEFAULT_NOISE: Mapping[str, float] = MappingProxyType(
    {"range": 0.1, "dvl-bottom": 1e-3, "dvl-water": 1e-3, "depth": 0.05}
)
#: True ocean current of current scenarios [m/s] (2D uses the first two components).
DEFAULT_CURRENT: tuple[float, float, float] = (0.1, -0.05, 0.0)
#: Prior standard deviation of each current component [m/s].
CURRENT_PRIOR_STD = 0.1
#: Position error [m] below which a filter counts as converged (see FilterStats).
DEFAULT_CONVERGENCE_M = 0.5
#: Default white-acceleration intensity [m/s²/√Hz]: at the default filter step 0.1 s its velocity
#: variance per step ``q h`` is the paper's ``(1e-3 · 0.1)² = 1e-8 m²/s²`` (module docstring).
DEFAULT_ACCEL_NOISE = math.sqrt(1e-7)

Y0Mode = Literal["augment", "inflate"]
#: The EKF's range update (:mod:`obsplan.estimation.filters.ekf`).
EkfUpdate = Literal["first-order", "second-order"]
#: ``EkfUpdate`` values; the first is ``EstimationConfig``'s default (the paper's EKF), problem
#: files default to the second (``validation.ekf_update``).
EKF_UPDATES: tuple[str, ...] = ("first-order", "second-order")


def _sensor_key(model: VehicleModel, key: str, fieldname: str) -> str:
    raw = str(key).strip().lower()
    if raw == "dvl":  # the alias means "the model's DVL", whichever mode it is in
        dvls = [s for s in model.sensors if s.startswith("dvl")]
        name = dvls[0] if dvls else SENSOR_ALIASES["dvl"]
    else:
        name = SENSOR_ALIASES.get(raw, raw)
    if name not in SENSORS:
        raise ConfigError(f"{fieldname}: unknown sensor {key!r}; choose from {', '.join(SENSORS)}")
    if name not in model.sensors:
        raise ConfigError(
            f"{fieldname}: sensor {name!r} is not in the model's sensors "
            f"({', '.join(model.sensors)}); add it to the sensors or remove it here"
        )
    return name


def _check_beacon_path(model: VehicleModel, path: object) -> None:
    """Refuse a beacon path that is not a :class:`BeaconPath` of the model's dimension, or one
    given with a fixed beacon away from the origin (which of the two would be meant?)."""
    if path is None:
        return
    if not isinstance(path, BeaconPath):
        raise ConfigError("beacon_path must be a BeaconPath (obsplan.model.beacon) or None")
    if path.dim != model.dim:
        raise ConfigError(
            f"beacon_path is {path.dim}D but the model is {model.dim}D; give "
            f"{'t,bx,by,bz' if model.dim == 3 else 't,bx,by'}"
        )
    if np.any(model.beacon_array != 0.0):
        raise ConfigError(
            f"beacon_path replaces the model's fixed beacon, but the model has one at "
            f"{model.beacon}; build the model without a beacon (the origin)"
        )


def _matrix(value: object, m: int, fieldname: str, definite: bool) -> np.ndarray:
    """A covariance from a diagonal or a full matrix, checked for shape, symmetry and sign."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 1:
        if a.shape != (m,):
            raise ConfigError(f"{fieldname}: expected {m} diagonal entries, got {a.shape[0]}")
        a = np.diag(a)
    elif a.shape != (m, m):
        raise ConfigError(
            f"{fieldname}: expected a vector of {m} variances or a {m}x{m} matrix, got shape "
            f"{a.shape}"
        )
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{fieldname}: entries must be finite")
    if not np.allclose(a, a.T, rtol=1e-10, atol=0.0):
        raise ConfigError(f"{fieldname}: the matrix must be symmetric")
    ev = np.linalg.eigvalsh(a)
    scale = max(float(np.max(np.abs(ev))), 1e-300)
    if definite and ev[0] <= 0:
        raise ConfigError(f"{fieldname}: must be positive definite (a variance is <= 0)")
    if ev[0] < -1e-12 * scale:
        raise ConfigError(f"{fieldname}: must be positive semi-definite (a variance is < 0)")
    return a


def paper_covariances(model: VehicleModel, dt: float) -> dict[str, np.ndarray]:
    """The paper's ``Q_EKF``, ``Q_KF``, ``P_EKF``, ``P_KF`` (section 7) for step ``dt`` [s].

    Returns a dict with keys ``q_ekf``, ``p0_ekf`` (``state_dim`` × ``state_dim``) and ``q_kf``,
    ``p0_kf`` (augmented ``state_dim`` squared), SI units.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (dimension and current).
    dt : float
        Filter step [s].

    Returns
    -------
    dict of str to ndarray
        The four diagonal covariances: per-step process noise ``(1e-3 dt)²`` on position [m²]
        and velocity [m²/s²], initial variances 1 m² and 0.1 m²/s² (and the current's prior).

    Raises
    ------
    ConfigError
        If ``dt`` is not a positive number.
    """
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"dt must be a positive step in seconds, got {dt!r}")
    n = model.dim
    q_pv = [(1e-3 * dt) ** 2] * (2 * n)
    cur_q = [0.0] * n if model.current else []
    cur_p = [CURRENT_PRIOR_STD**2] * n if model.current else []
    p_pv = [1.0] * n + [0.1] * n
    return {
        "q_ekf": np.diag(q_pv + cur_q),
        "q_kf": np.diag(q_pv + cur_q + [0.0, 0.0]),  # module docstring: not the paper's 1e-12
        "p0_ekf": np.diag(p_pv + cur_p),
        "p0_kf": np.diag(p_pv + cur_p + [1.0, 1.0]),
    }


@dataclass(frozen=True, eq=False)
class ProcessNoise:
    """The process noise of a configuration, in the form the truth, filters and bounds integrate.

    Attributes
    ----------
    continuous : bool
        True: ``q_ekf`` and ``q_kf`` are intensities ``W`` of white noise on the state's
        derivative [m²/s³ on ``v``, ``v_f``] and the covariance added over a span ``h`` is
        ``Q(h) = h W + h²/2 (A W + W Aᵀ) + h³/3 A W Aᵀ`` (exact, ``A² = 0``; module docstring).
        False: they are covariances added at the end of every filter step (the paper's).
    q_ekf : ndarray, shape (state_dim, state_dim)
        On ``(p, v[, v_f])``.
    q_kf : ndarray, shape (state_dim + 2, state_dim + 2)
        On the paper's augmented state ``(p - b, v[, v_f], α, β)``.
    dim : int
        Spatial dimension ``n``.
    current : bool
        Whether the state has the current block ``v_f``.
    """

    continuous: bool
    q_ekf: np.ndarray
    q_kf: np.ndarray
    dim: int
    current: bool

    def step_covariance(self, h: float) -> np.ndarray:
        """Covariance added on ``(p, v[, v_f])`` over one filter step of ``h`` [s].

        Parameters
        ----------
        h : float
            Step [s] (ignored in the per-step setting).

        Returns
        -------
        ndarray, shape (state_dim, state_dim)
            ``Q(h)`` [SI units of the state, squared].
        """
        if not self.continuous:
            return np.array(self.q_ekf, dtype=float)
        return integrated_noise(self.q_ekf, self.dim, self.current, float(h))

    def step_covariance_kf(self, h: float) -> np.ndarray:
        """Covariance added on ``(p - b, v[, v_f], α, β)`` over one filter step of ``h`` [s].

        Parameters
        ----------
        h : float
            Step [s] (ignored in the per-step setting).

        Returns
        -------
        ndarray, shape (state_dim + 2, state_dim + 2)
            ``Q(h)`` of the augmented state (zero on ``α``, ``β``).
        """
        if not self.continuous:
            return np.array(self.q_kf, dtype=float)
        return integrated_noise(self.q_kf, self.dim, self.current, float(h))


@dataclass(frozen=True, eq=False)
class EstimationConfig:
    """Filters and truth simulation for one vehicle model.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (dimension, sensors, current, beacon, range form of the EKF output).
    rates_hz : mapping of str to float, optional
        Report rate of each sensor [Hz]; a sensor not listed reports at every trajectory sample.
        The filters predict at the trajectory's sample rate; a rate above it is an error.
    noise : mapping of str to float, optional
        Measurement standard deviation per sensor: range [m] (on the range, whatever the filter's
        output form), DVL [m/s], depth [m]. Missing sensors use :data:`DEFAULT_NOISE`.
    accel_noise : float or None, optional
        Intensity of the white acceleration noise [m/s²/√Hz] of the truth and the filters
        (module docstring); ``None``: :data:`DEFAULT_ACCEL_NOISE` ``= sqrt(1e-7)``, which at the
        default filter step 0.1 s adds the paper's velocity variance ``(1e-3 · 0.1)²`` per step.
        Cannot be combined with ``q_ekf``/``q_kf``.
    current_noise : float, optional
        Intensity of a random walk of the current [m/s/√s] (models with a current only);
        default 0, a constant current (eq. 29).
    q_ekf, q_kf : ndarray or None, optional
        The paper's setting instead of the physical noise: per-step process-noise covariances
        (diagonal vector or matrix) added at every filter step, so their intensity depends on the
        step (:meth:`paper` gives the paper's values). Giving either selects this mode; the other
        one, if ``None``, is :func:`paper_covariances` at the trajectory's median step.
    p0_ekf, p0_kf : ndarray or None, optional
        Initial covariances (diagonal vector or matrix); ``None`` uses :func:`paper_covariances`.
    init_error : "sample" or ndarray, shape (state_dim,), optional
        ``"sample"`` to draw the initial estimation error of ``(p, v[, v_f])`` from
        ``N(0, p0_ekf)`` in each run, or a fixed offset ``x̂0 - x0`` of length ``state_dim``.
    true_current : tuple of float or None, optional
        True current ``v_f`` [m/s] of the truth when the model has a current (default
        :data:`DEFAULT_CURRENT`); must be ``None`` otherwise.
    process_noise : bool, optional
        If true the truth is driven by the process noise the filters model (``accel_noise``, or
        ``q_ekf`` per step in the paper's setting).
    y0_mode : {"augment", "inflate"}, optional
        How the KF handles the noise of the anchor range ``y0`` in ``ȳ = y - y0 + ½|d|²``:
        ``"augment"`` (default) adds the constant ``β = y0,true - y0,meas`` to the KF state with
        prior variance ``var(y0)``, which is exact; ``"inflate"`` adds ``var(y0)`` to every
        later ``R`` and ignores the correlation (over-confident: the common error is averaged
        as if independent).
    convergence_threshold_m : float, optional
        Position error [m] for the convergence time and converged fraction.
    dropout : mapping of str to float, optional
        Probability per sensor that a scheduled report is missing (NaN; the update is skipped).
        The anchor range at the first sample is never dropped.
    kf_coupling : bool, optional
        Model how process noise enters the augmented KF's output (default; see
        :mod:`obsplan.estimation.filters.kf`). ``False`` is the paper's output model, over-confident
        on long runs with process noise.
    monitor_window_s : float or None, optional
        The final stretch [s] over which the divergence monitor averages one run's NEES against
        the 99.9 % bound (:mod:`obsplan.estimation.montecarlo.stats`); ``None``: 10 % of the
        duration.
    ekf_update : {"first-order", "second-order"}, optional
        The EKF's (and the Gaussian sum's components') range update: ``"first-order"``
        (default, the paper's EKF) or ``"second-order"``, the Gaussian second-order filter's,
        which adds the range's curvature over the prior to the prediction and the variance
        (:mod:`obsplan.estimation.filters.ekf`).
    beacon_path : BeaconPath or None, optional
        A beacon moving along a known path (a ship's GPS track, linearly interpolated) instead of
        the model's fixed beacon (which must then be the origin, the default). The truth, the
        filters and the posterior CRB range to it; the path must cover every trajectory it is
        used on and have the model's dimension (:mod:`obsplan.estimation.epochs`, "A moving
        beacon"). None (default): the model's fixed beacon.
    channel : Channel, optional
        The acoustic channel the truth's ranges go through (:mod:`obsplan.estimation.channel`);
        the filters do not know it. Default the ideal channel (Gaussian ranges). Its loss
        probability is the range's ``dropout``: give it in one place (a channel with a dropout
        and ``dropout["range"]`` is an error).
    gate : float, "auto" or "off", optional
        The filters' innovation gate on the ranges: a confidence in (0, 1) of the chi-square
        quantile of one degree of freedom, ``"off"`` (or 1), or ``"auto"`` (default: on at
        :data:`~obsplan.estimation.channel.GATE_PROBABILITY` when the channel has outliers,
        off otherwise; :func:`~obsplan.estimation.channel.default_gate`).
    scale_state : "auto", "on" or "off", optional
        A range-scale state in the EKF, the Gaussian sum and the augmented KF (a sound-speed
        error estimated, prior std :data:`~obsplan.estimation.channel.SCALE_PRIOR_STD`):
        ``"auto"`` (default) adds it when the channel is not ideal (ranges at sea have an
        unknown sound speed), never on the ideal channel (whose numbers stay those of before).
    bias_state : "auto", "on" or "off", optional
        A range-bias state in the EKF, the Gaussian sum and the augmented KF (a clock offset
        estimated, prior std :data:`~obsplan.estimation.channel.BIAS_PRIOR_STD_M`; the KF's
        row :mod:`obsplan.estimation.filters.kf`, "A range bias"): ``"auto"`` (default) adds
        it when the channel has a clock offset.
    range_times : ndarray or None, optional
        A ping schedule [s, on the path's clock: from the mission's start for a plan], strictly
        increasing (e.g. the range times of a logged mission): the ranges report there (the
        first sample at or after each, :func:`~obsplan.estimation.schedule.make_schedule`)
        instead of at ``rates_hz["range"]``. None (default): the rate.

    Instances pickle (the model is rebuilt from its parameters), so they can be shipped to worker
    processes.
    """

    model: VehicleModel
    rates_hz: Mapping[str, float] = field(default_factory=dict)
    noise: Mapping[str, float] = field(default_factory=dict)
    q_ekf: np.ndarray | None = None
    q_kf: np.ndarray | None = None
    p0_ekf: np.ndarray | None = None
    p0_kf: np.ndarray | None = None
    init_error: str | np.ndarray = "sample"
    true_current: tuple[float, ...] | None = None
    process_noise: bool = True
    y0_mode: Y0Mode = "augment"
    convergence_threshold_m: float = DEFAULT_CONVERGENCE_M
    dropout: Mapping[str, float] = field(default_factory=dict)
    kf_coupling: bool = True
    monitor_window_s: float | None = None
    accel_noise: float | None = None
    current_noise: float = 0.0
    ekf_update: EkfUpdate = "first-order"
    beacon_path: BeaconPath | None = None
    channel: Channel = CHANNEL_PRESETS["ideal"]
    gate: float | str = "auto"
    scale_state: str = "auto"
    range_times: np.ndarray | None = None
    bias_state: str = "auto"

    def __reduce__(self):
        # the model may hold CasADi symbols (not picklable) and the mappings are read-only
        # proxies: rebuild both from plain values
        m = self.model
        model_args = (m.dim, m.sensors, m.current, m.beacon, m.range_form)
        values = {
            f: getattr(self, f)
            for f in (
                "q_ekf",
                "q_kf",
                "p0_ekf",
                "p0_kf",
                "init_error",
                "true_current",
                "process_noise",
                "y0_mode",
                "convergence_threshold_m",
                "kf_coupling",
                "monitor_window_s",
                "accel_noise",
                "current_noise",
                "ekf_update",
                "beacon_path",
                "channel",
                "gate",
                "scale_state",
                "range_times",
                "bias_state",
            )
        }
        for f in ("rates_hz", "noise", "dropout"):
            values[f] = dict(getattr(self, f))
        return (_rebuild_config, (model_args, values))

    def __post_init__(self) -> None:
        model = self.model
        if not isinstance(model, VehicleModel):
            raise ConfigError("model must be a VehicleModel (see obsplan.model.vehicle.make_model)")
        rates: dict[str, float] = {}
        for k, v in dict(self.rates_hz).items():
            name = _sensor_key(model, k, "rates_hz")
            val = float(v)
            if not (np.isfinite(val) and val > 0):
                raise ConfigError(f"rates_hz[{name!r}] must be a positive rate in Hz, got {v!r}")
            rates[name] = val
        noise: dict[str, float] = {}
        for k, v in dict(self.noise).items():
            name = _sensor_key(model, k, "noise")
            val = float(v)
            if not (np.isfinite(val) and 0 < val <= MAX_NOISE_STD):
                raise ConfigError(
                    f"noise[{name!r}] must be a positive standard deviation of at most "
                    f"{MAX_NOISE_STD:g} (m or m/s), got {v!r}"
                )
            noise[name] = val
        full_noise = {s: noise.get(s, DEFAULT_NOISE[s]) for s in model.sensors}
        drop: dict[str, float] = {}
        for k, v in dict(self.dropout).items():
            name = _sensor_key(model, k, "dropout")
            val = float(v)
            if not (0.0 <= val < 1.0):
                raise ConfigError(f"dropout[{name!r}] must be a probability in [0, 1), got {v!r}")
            drop[name] = val
        object.__setattr__(self, "rates_hz", MappingProxyType(rates))
        object.__setattr__(self, "noise", MappingProxyType(full_noise))
        object.__setattr__(self, "dropout", MappingProxyType(drop))
        _check_beacon_path(model, self.beacon_path)
        self._check_channel(drop)
        self._check_range_times()

        mx = model.state_dim
        mz = augmented_model(model).state_dim
        for name, m, definite in (
            ("q_ekf", mx, False),
            ("q_kf", mz, False),
            ("p0_ekf", mx, True),
            ("p0_kf", mz, True),
        ):
            val = getattr(self, name)
            if val is not None:
                object.__setattr__(self, name, _matrix(val, m, name, definite))

        if isinstance(self.init_error, str):
            if self.init_error != "sample":
                raise ConfigError(
                    f"init_error must be 'sample' or an offset of {mx} numbers "
                    f"({', '.join(model.state_names)}), got {self.init_error!r}"
                )
        else:
            e = np.asarray(self.init_error, float).reshape(-1)
            if e.shape != (mx,) or not np.all(np.isfinite(e)):
                got = (
                    f"{e.size} numbers"
                    if e.shape != (mx,)
                    else f"{', '.join(f'{x:g}' for x in e)} (not all finite)"
                )
                raise ConfigError(
                    f"init_error: expected {mx} finite numbers ({', '.join(model.state_names)}), "
                    f"got {got}"
                )
            for name, x in zip(model.state_names, e, strict=True):
                # the limits of a trajectory's position and velocity columns: an error of 1e9 m
                # overflows the filters' squares into a NaN NEES
                limit, unit = COLUMN_LIMITS[name[0] + name[-1]]
                check_magnitude(float(x), f"init_error {name}", limit, unit, error=ConfigError)
            e.setflags(write=False)
            object.__setattr__(self, "init_error", e)

        if model.current:
            vf = DEFAULT_CURRENT[: model.dim] if self.true_current is None else self.true_current
            vf_arr = np.asarray(vf, float).reshape(-1)
            if vf_arr.shape != (model.dim,) or not np.all(np.isfinite(vf_arr)):
                raise ConfigError(
                    f"true_current: expected {model.dim} finite components [m/s], got {vf!r}"
                )
            object.__setattr__(self, "true_current", tuple(float(c) for c in vf_arr))
        elif self.true_current is not None:
            raise ConfigError("true_current is set but the model has no current (current=False)")
        self._check_process_noise()
        if self.ekf_update not in EKF_UPDATES:
            choices = " or ".join(repr(u) for u in EKF_UPDATES)
            raise ConfigError(f"ekf_update must be {choices}, got {self.ekf_update!r}")
        if self.y0_mode not in ("augment", "inflate"):
            raise ConfigError(f"y0_mode must be 'augment' or 'inflate', got {self.y0_mode!r}")
        thr = float(self.convergence_threshold_m)
        if not (np.isfinite(thr) and thr > 0):
            raise ConfigError("convergence_threshold_m must be a positive distance in metres")
        if self.monitor_window_s is not None:
            win = float(self.monitor_window_s)
            if not (np.isfinite(win) and win >= 0):
                raise ConfigError(
                    f"monitor_window_s must be a duration >= 0 s (or None for 10 % of the run), "
                    f"got {self.monitor_window_s!r}"
                )

    def _check_range_times(self) -> None:
        """A ping schedule: finite, strictly increasing, at least one ping; kept read-only."""
        if self.range_times is None:
            return
        rt = np.array(self.range_times, dtype=float).ravel()
        if rt.size == 0 or not np.all(np.isfinite(rt)) or np.any(np.diff(rt) <= 0):
            raise ConfigError(
                "range_times must be finite ping times [s], strictly increasing, at least one"
            )
        rt.setflags(write=False)
        object.__setattr__(self, "range_times", rt)

    def _check_channel(self, drop: Mapping[str, float]) -> None:
        if not isinstance(self.channel, Channel):
            raise ConfigError("channel must be a Channel (obsplan.estimation.channel)")
        if self.channel.dropout > 0 and "range" in drop:
            raise ConfigError(
                "dropout['range'] and the channel's dropout are the same loss of pings: give one"
            )
        for f in ("scale_state", "bias_state"):
            if getattr(self, f) not in ("auto", "on", "off"):
                raise ConfigError(f"{f} must be 'auto', 'on' or 'off', got {getattr(self, f)!r}")
        g = self.gate
        if isinstance(g, str):
            if g not in ("auto", "off"):
                raise ConfigError(
                    f"gate must be a confidence in (0, 1], 'auto' or 'off', got {g!r}"
                )
        elif isinstance(g, bool) or not (0.0 < float(g) <= 1.0):
            raise ConfigError(f"gate must be a confidence in (0, 1], 'auto' or 'off', got {g!r}")
        else:
            object.__setattr__(self, "gate", float(g))

    def schedule(self, traj: Trajectory) -> Schedule:
        """Which sensor reports at which sample of ``traj``: the rates, or the ping schedule
        ``range_times`` for the range (:func:`~obsplan.estimation.schedule.make_schedule`).

        Parameters
        ----------
        traj : Trajectory
            The path whose samples are the filters' steps.

        Returns
        -------
        Schedule
            The report mask.
        """
        return make_schedule(traj, self.model.sensors, self.rates_hz, self.range_times)

    @property
    def scale_prior_std(self) -> float | None:
        """The prior std of the filters' range-scale state, None without one."""
        on = self.scale_state == "on" or (self.scale_state == "auto" and not self.channel.is_ideal)
        return SCALE_PRIOR_STD if on else None

    @property
    def bias_prior_std(self) -> float | None:
        """The prior std [m] of the EKF's and the Gaussian sum's range-bias state, None without
        one."""
        on = self.bias_state == "on" or (
            self.bias_state == "auto" and self.channel.clock_offset_s != 0.0
        )
        return BIAS_PRIOR_STD_M if on else None

    @property
    def gate_probability(self) -> float | None:
        """The confidence of the filters' range gate, None when there is none."""
        if self.gate == "auto":
            return default_gate(self.channel)
        if self.gate == "off" or float(self.gate) >= 1.0:
            return None
        return float(self.gate)

    @property
    def gate_nis(self) -> float:
        """The NIS threshold of the range gate (``inf``: no gate)."""
        return gate_nis(self.gate_probability)

    def _check_process_noise(self) -> None:
        per_step = self.q_ekf is not None or self.q_kf is not None
        if self.accel_noise is not None:
            a = float(self.accel_noise)
            if not (math.isfinite(a) and a >= 0):
                raise ConfigError(
                    f"accel_noise must be an intensity >= 0 in m/s²/√Hz, got {self.accel_noise!r}"
                )
            if per_step:
                raise ConfigError(
                    "accel_noise and q_ekf/q_kf are two settings of the same process noise: give "
                    "the physical intensity accel_noise or the paper's per-step covariances, not "
                    "both"
                )
            object.__setattr__(self, "accel_noise", a)
        c = float(self.current_noise)
        if not (math.isfinite(c) and c >= 0):
            raise ConfigError(
                f"current_noise must be an intensity >= 0 in m/s/√s, got {self.current_noise!r}"
            )
        if c > 0 and not self.model.current:
            raise ConfigError("current_noise is set but the model has no current (current=False)")
        if c > 0 and per_step:
            raise ConfigError(
                "current_noise needs the physical process noise: remove q_ekf/q_kf (the paper's "
                "per-step setting has a constant current)"
            )
        object.__setattr__(self, "current_noise", c)

    @property
    def per_step_noise(self) -> bool:
        """True in the paper's per-step setting (``q_ekf``/``q_kf`` given), False for the
        physical intensity ``accel_noise``."""
        return self.q_ekf is not None or self.q_kf is not None

    def process_noise_model(self, dt: float | None = None) -> ProcessNoise:
        """The :class:`ProcessNoise` every consumer integrates.

        ``dt`` [s] is needed only in the per-step setting when one of ``q_ekf``/``q_kf`` is
        ``None`` (it is then the paper's at step ``dt``).

        Parameters
        ----------
        dt : float or None, optional
            Filter step [s].

        Returns
        -------
        ProcessNoise
            Continuous intensities, or the per-step covariances.

        Raises
        ------
        ConfigError
            In the per-step setting with a missing ``q_ekf``/``q_kf`` and no ``dt``.
        """
        model = self.model
        n = model.dim
        if self.per_step_noise:
            if self.q_ekf is None or self.q_kf is None:
                if dt is None:
                    raise ConfigError("process_noise_model: the per-step setting needs a step dt")
                cov = paper_covariances(model, dt)
            qe = cov["q_ekf"] if self.q_ekf is None else self.q_ekf
            qk = cov["q_kf"] if self.q_kf is None else self.q_kf
            return ProcessNoise(False, np.array(qe), np.array(qk), n, model.current)
        a = DEFAULT_ACCEL_NOISE if self.accel_noise is None else float(self.accel_noise)
        w = [0.0] * n + [a * a] * n + ([self.current_noise**2] * n if model.current else [])
        return ProcessNoise(True, np.diag(w), np.diag(w + [0.0, 0.0]), n, model.current)

    @classmethod
    def paper(cls, model: VehicleModel, dt: float, **overrides: object) -> EstimationConfig:
        """The paper's section-7 defaults for model step ``dt`` [s] (``Ts = 0.01`` s in the paper).

        The paper's per-step process noise (module docstring), kept for its figures and tables;
        ``overrides`` are any other fields (e.g. ``init_error``, ``rates_hz``).

        Parameters
        ----------
        model : VehicleModel
            The vehicle model.
        dt : float
            Model step [s].
        **overrides
            Other fields of the configuration.

        Returns
        -------
        EstimationConfig
            The configuration with the paper's ``Q`` and ``P0`` (:func:`paper_covariances`).
        """
        cov = paper_covariances(model, dt)
        kwargs: dict[str, object] = {**cov, **overrides}
        return cls(model=model, **kwargs)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ resolution
    def covariances(self, dt: float) -> dict[str, np.ndarray]:
        """``q_ekf, q_kf, p0_ekf, p0_kf`` for filter step ``dt`` [s].

        ``q_*`` are the covariances added per step of ``dt`` (with the physical noise its exact
        ``Q(dt)``, a full matrix); ``None`` entries are the paper's for step ``dt``.

        Parameters
        ----------
        dt : float
            Filter step [s].

        Returns
        -------
        dict of str to ndarray
            ``q_ekf``, ``p0_ekf`` (``state_dim`` square) and ``q_kf``, ``p0_kf`` (augmented).
        """
        cov = paper_covariances(self.model, dt)
        out = {k: (cov[k] if getattr(self, k) is None else getattr(self, k)) for k in cov}
        if not self.per_step_noise:
            pn = self.process_noise_model()
            out["q_ekf"] = pn.step_covariance(dt)
            out["q_kf"] = pn.step_covariance_kf(dt)
        return out

    @property
    def current_array(self) -> np.ndarray:
        """True current ``v_f`` [m/s], shape ``(n,)`` (zeros without current)."""
        if self.true_current is None:
            return np.zeros(self.model.dim)
        return np.asarray(self.true_current, float)

    def to_dict(self) -> dict:
        """JSON-friendly summary (rates, noises, flags).

        Returns
        -------
        dict
            Sensors, rates [Hz], noises, the flags, the initial error, the true current [m/s]
            and the process noise model and intensities; with a ``beacon_path`` also
            ``"beacon_motion": "path"`` and its time span [s].
        """
        out = {
            "sensors": list(self.model.sensors),
            "current": bool(self.model.current),
            "rates_hz": dict(self.rates_hz),
            "noise": dict(self.noise),
            "process_noise": bool(self.process_noise),
            "init_error": (
                self.init_error
                if isinstance(self.init_error, str)
                else [float(x) for x in self.init_error]
            ),
            "y0_mode": self.y0_mode,
            "ekf_update": self.ekf_update,
            "true_current": None if self.true_current is None else list(self.true_current),
            "kf_coupling": bool(self.kf_coupling),
            "monitor_window_s": self.monitor_window_s,
            "process_noise_model": "per-step" if self.per_step_noise else "continuous",
            "accel_noise": (
                None
                if self.per_step_noise
                else (DEFAULT_ACCEL_NOISE if self.accel_noise is None else self.accel_noise)
            ),
            "current_noise": float(self.current_noise),
        }
        if not self.channel.is_ideal or self.gate_probability is not None:
            out["channel"] = self.channel.to_dict()
            out["gate"] = self.gate_probability
            out["scale_state"] = self.scale_prior_std is not None
            out["bias_state"] = self.bias_prior_std is not None
        if self.range_times is not None:
            out["range_pings"] = int(self.range_times.size)
        if self.beacon_path is not None:
            out["beacon_motion"] = "path"
            out["beacon_path_span_s"] = [self.beacon_path.start, self.beacon_path.end]
        return out


def _rebuild_config(model_args: tuple, values: dict) -> EstimationConfig:
    dim, sensors, current, beacon, range_form = model_args
    model = VehicleModel(
        dim=dim, sensors=sensors, current=current, beacon=beacon, range_form=range_form
    )
    return EstimationConfig(model=model, **values)
