"""Configuration of the filters and of the Monte Carlo: noises, rates, covariances, initial error.

Paper defaults (section 7) for a model step ``Ts`` [s]:

* range noise ``σ_r = 0.1 m`` (``R = (0.1 m)²``), DVL ``σ = 1e-3 m/s`` (``R_DVL = 1e-6 I``);
  depth ``σ = 0.05 m`` (the paper has no depth gauge; a typical pressure sensor);
* ``Q_EKF = diag(1e-3 Ts · 1_n, 1e-3 Ts · 1_n)²`` per model step;
* ``Q_KF = diag(1e-3 Ts · 1_n, 1e-3 Ts · 1_n, 0, 0)²`` per model step. The paper puts
  ``(1e-6)²`` on ``p0ᵀν0`` and ``|ν0|²``; they are constants of the truth, and once the way process
  noise enters the KF's output is modelled (:mod:`obsplan.estimation.kf`) that fictitious noise
  only makes the KF under-confident on long runs (measured on a 600 s circle at 10 Hz, 50 runs:
  NEES 2.3–2.7 after 400 s against the 95 % band [3.25, 4.82]; 3.7–4.0 without it), so it is 0;
* ``P_EKF = diag(1_n, 0.1 · 1_n)``, ``P_KF = diag(1_n, 0.1 · 1_n, 1, 1)``.

With an ocean current the state has a ``v_f`` block: its process noise is 0 (the current is
constant, eq. 29) and its prior variance is ``(0.1 m/s)²`` per axis; the truth uses
:data:`DEFAULT_CURRENT` unless ``true_current`` is given.

Every field can be overridden with :func:`dataclasses.replace` or the constructor; covariances are
given as a diagonal (vector) or a full matrix in the state order of the filter
(``VehicleModel.state_names`` for the EKF, ``AugmentedModel.state_names`` for the KF).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

import numpy as np

from obsplan.errors import ConfigError
from obsplan.model import SENSOR_ALIASES, SENSORS, VehicleModel
from obsplan.observability.gramian import augmented_model

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

Y0Mode = Literal["augment", "inflate"]


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
class EstimationConfig:
    """Filters and truth simulation for one vehicle model.

    Parameters
    ----------
    model
        The vehicle model (dimension, sensors, current, beacon, range form of the EKF output).
    rates_hz
        Report rate of each sensor [Hz]; a sensor not listed reports at every trajectory sample.
        The filters predict at the trajectory's sample rate; a rate above it is an error.
    noise
        Measurement standard deviation per sensor: range [m] (on the range, whatever the filter's
        output form), DVL [m/s], depth [m]. Missing sensors use :data:`DEFAULT_NOISE`.
    q_ekf, q_kf, p0_ekf, p0_kf
        Per-step process-noise and initial covariances (diagonal vector or matrix); ``None`` uses
        :func:`paper_covariances` at the trajectory's median step.
    init_error
        ``"sample"`` to draw the initial estimation error of ``(p, v[, v_f])`` from
        ``N(0, p0_ekf)`` in each run, or a fixed offset ``x̂0 - x0`` of length ``state_dim``.
    true_current
        True current ``v_f`` [m/s] of the truth when the model has a current (default
        :data:`DEFAULT_CURRENT`); must be ``None`` otherwise.
    process_noise
        If true the truth is driven by process noise of covariance ``q_ekf``.
    y0_mode
        How the KF handles the noise of the anchor range ``y0`` in ``ȳ = y - y0 + ½|d|²``:
        ``"augment"`` (default) adds the constant ``β = y0,true - y0,meas`` to the KF state with
        prior variance ``var(y0)``, which is exact; ``"inflate"`` adds ``var(y0)`` to every
        later ``R`` and ignores the correlation (over-confident: the common error is averaged
        as if independent).
    convergence_threshold_m
        Position error [m] for the convergence time and converged fraction.
    dropout
        Probability per sensor that a scheduled report is missing (NaN; the update is skipped).
        The anchor range at the first sample is never dropped.
    kf_coupling
        Model how process noise enters the augmented KF's output (default; see
        :mod:`obsplan.estimation.kf`). ``False`` is the paper's output model, over-confident on
        long runs with process noise.
    monitor_window_s
        The final stretch [s] over which the divergence monitor averages one run's NEES against
        the 99.9 % bound (:mod:`obsplan.estimation.stats`); ``None``: 10 % of the duration.

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
            )
        }
        for f in ("rates_hz", "noise", "dropout"):
            values[f] = dict(getattr(self, f))
        return (_rebuild_config, (model_args, values))

    def __post_init__(self) -> None:
        model = self.model
        if not isinstance(model, VehicleModel):
            raise ConfigError("model must be a VehicleModel (see obsplan.model.make_model)")
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
            if not (np.isfinite(val) and val > 0):
                raise ConfigError(
                    f"noise[{name!r}] must be a positive standard deviation, got {v!r}"
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
                raise ConfigError(
                    f"init_error: expected {mx} finite numbers ({', '.join(model.state_names)}), "
                    f"got shape {np.shape(self.init_error)}"
                )
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

    @classmethod
    def paper(cls, model: VehicleModel, dt: float, **overrides: object) -> EstimationConfig:
        """The paper's section-7 defaults for model step ``dt`` [s] (``Ts = 0.01`` s in the paper).

        ``overrides`` are any other fields (e.g. ``init_error``, ``rates_hz``).
        """
        cov = paper_covariances(model, dt)
        kwargs: dict[str, object] = {**cov, **overrides}
        return cls(model=model, **kwargs)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ resolution
    def covariances(self, dt: float) -> dict[str, np.ndarray]:
        """``q_ekf, q_kf, p0_ekf, p0_kf`` with ``None`` replaced by the paper's for step ``dt``."""
        cov = paper_covariances(self.model, dt)
        return {k: (cov[k] if getattr(self, k) is None else getattr(self, k)) for k in cov}

    @property
    def current_array(self) -> np.ndarray:
        """True current ``v_f`` [m/s], shape ``(n,)`` (zeros without current)."""
        if self.true_current is None:
            return np.zeros(self.model.dim)
        return np.asarray(self.true_current, float)

    def to_dict(self) -> dict:
        """JSON-friendly summary (rates, noises, flags)."""
        return {
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
            "true_current": None if self.true_current is None else list(self.true_current),
            "kf_coupling": bool(self.kf_coupling),
            "monitor_window_s": self.monitor_window_s,
        }


def _rebuild_config(model_args: tuple, values: dict) -> EstimationConfig:
    dim, sensors, current, beacon, range_form = model_args
    model = VehicleModel(
        dim=dim, sensors=sensors, current=current, beacon=beacon, range_form=range_form
    )
    return EstimationConfig(model=model, **values)
