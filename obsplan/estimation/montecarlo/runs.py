"""What the runs of a Monte Carlo share on one path, and what each run draws.

:class:`PathSetup` holds everything independent of the runs (schedule, epochs, records, filters,
nominal states, the truth's noise factor); :func:`draw_run` the draws of one run from its seeded
streams (:mod:`obsplan.estimation.montecarlo.truth`), so the open-loop Monte Carlo
(:mod:`obsplan.estimation.montecarlo.simulate`) and the closed loop
(:mod:`obsplan.estimation.montecarlo.closedloop`) see the same runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.columns import N_INFO
from obsplan.estimation.epochs import (
    RunContext,
    epoch_beacons,
    epoch_plan,
    input_displacement,
    nominal_states,
    record_samples,
    sample_beacons,
)
from obsplan.estimation.filters import ekf, gsf, kf  # noqa: F401  (they register their filters)
from obsplan.estimation.filters.base import REGISTRY, make_filter
from obsplan.estimation.filters.kf import AugmentedKalmanFilter
from obsplan.estimation.montecarlo.guidance import TruthLimits
from obsplan.estimation.montecarlo.stats import (
    MONITOR_LEVEL,
    MONITOR_WINDOW_FRACTION,
    chi2_quantile,
)
from obsplan.estimation.montecarlo.truth import (
    STREAM_INIT,
    channel_draws,
    reading_draws,
    run_rng,
    truth_factor,
)
from obsplan.estimation.schedule import sample_rate

#: The estimators the Monte Carlo can run, by name: their one-line descriptions
#: (:data:`obsplan.estimation.filters.base.REGISTRY` holds the classes).
FILTERS: dict[str, str] = {name: cls.description for name, cls in REGISTRY.items()}
#: What the Monte Carlo runs unless told otherwise.
DEFAULT_FILTERS: tuple[str, ...] = ("ekf", "kf")
#: Runs per kernel call: the kernels vectorise over the runs of a batch; Ctrl-C is honoured
#: between batches.
BATCH = 32


def check_filters(filters: Sequence[str]) -> tuple[str, ...]:
    """The filters to run, checked against :data:`FILTERS`.

    Parameters
    ----------
    filters : sequence of str
        Filter names.

    Returns
    -------
    tuple of str
        The names, in the order given.

    Raises
    ------
    ConfigError
        For an empty list, an unknown name or a name given twice.
    """
    out = tuple(filters)
    bad = [f for f in out if f not in FILTERS]
    if bad or not out or len(set(out)) != len(out):
        raise ConfigError(
            f"filters must be a non-empty list of distinct names from {', '.join(FILTERS)}, "
            f"got {filters!r}"
        )
    return out


def check_runs(runs: int, seed: int, run_start: int) -> tuple[int, int, int]:
    """The run count, seed and first run index of a Monte Carlo, checked.

    Parameters
    ----------
    runs : int
        Number of runs, >= 1.
    seed : int
        Seed of the random streams, >= 0.
    run_start : int
        Index of the first run (a shard of a larger Monte Carlo), >= 0.

    Returns
    -------
    runs, seed, run_start : int
        The three as Python integers.

    Raises
    ------
    ConfigError
        If one is not an integer in its range (a bool is not an integer here).
    """
    if isinstance(runs, bool) or int(runs) != runs or int(runs) < 1:
        raise ConfigError(f"runs must be a positive number of runs, got {runs!r}")
    if isinstance(seed, bool) or int(seed) != seed or int(seed) < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(run_start, bool) or int(run_start) != run_start or int(run_start) < 0:
        raise ConfigError(f"run_start must be an integer >= 0, got {run_start!r}")
    return int(runs), int(seed), int(run_start)


def _lines_weights(lines: np.ndarray | None, n_samples: int, records: np.ndarray) -> np.ndarray:
    if lines is None:
        return np.zeros(records.size)
    mask = np.asarray(lines)
    if mask.shape != (n_samples,) or mask.dtype != bool:
        raise ConfigError(
            f"lines must be a boolean mask of the path's {n_samples} samples, got shape "
            f"{mask.shape} and type {mask.dtype}"
        )
    return mask[records].astype(float)


class PathSetup:
    """Everything one path needs for its runs: schedule, epochs, records, filters, truth factor.

    Parameters
    ----------
    traj, config : Trajectory, EstimationConfig
        The path (its samples are the filter steps) and the configuration.
    names : sequence of str
        Filters to run (names of :data:`FILTERS`).
    record_every : int or None
        Record stride (:func:`~obsplan.estimation.epochs.record_samples`).
    runs : int
        Number of runs (sizes the per-run info).
    lines : ndarray of bool, shape (N,), optional
        Boolean mask (N,) of the samples of the subset RMSE (e.g. on survey lines), or None.
    limits : TruthLimits, optional
        The truth's limits (for the area and depth bounds), or None.

    Raises
    ------
    ConfigError
        If the model and the path differ in dimension, or ``lines`` is not a mask of the path's
        samples.
    """

    def __init__(self, traj, config, names, record_every, runs, lines=None, limits=None):
        model = config.model
        if traj.dim != model.dim:
            raise ConfigError(f"the model is {model.dim}D but the trajectory is {traj.dim}D")
        n = model.dim
        self.traj, self.config, self.model = traj, config, model
        dt = 1.0 / sample_rate(traj)
        self.cov = config.covariances(dt)
        self.noise = pn = config.process_noise_model(dt)
        self.schedule = config.schedule(traj)
        self.records = record_samples(traj.n_samples, record_every)
        self.plan = plan = epoch_plan(
            traj, self.schedule, self.records, rules="kf" in names, continuous=pn.continuous
        )
        self.t_rec = traj.t[self.records]
        d, dd = input_displacement(traj)
        window = (
            MONITOR_WINDOW_FRACTION * traj.duration
            if config.monitor_window_s is None
            else float(config.monitor_window_s)
        )
        self.ctx = RunContext(
            plan=plan,
            t_rec=self.t_rec,
            d_epochs=np.ascontiguousarray(np.hstack([d, dd])[plan.epochs]),
            threshold_m=float(config.convergence_threshold_m),
            nees_bound=chi2_quantile(MONITOR_LEVEL, 2 * n),
            window_s=window,
            rec_w=_lines_weights(lines, traj.n_samples, self.records),
            beacons=epoch_beacons(
                model, config.beacon_path, traj.t[plan.epochs], traj.p[plan.epochs]
            ),
            gate_nis=config.gate_nis,
        )
        #: the path's nominal range at the epochs (the channel's loss growing with range)
        rel = traj.p[plan.epochs] - self.ctx.beacons
        self.rho_epochs = np.linalg.norm(rel, axis=1)
        #: and its range rate (the channel's ping jitter); a moving beacon's velocity included
        vb = np.zeros_like(rel)
        if self.ctx.beacons.shape[0] > 1 and plan.epochs.size > 1:
            vb = np.gradient(self.ctx.beacons, traj.t[plan.epochs], axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rd = np.einsum("ki,ki->k", rel, traj.v[plan.epochs] - vb) / self.rho_epochs
        self.rho_dot_epochs = np.where(self.rho_epochs > 0, rd, 0.0)
        #: the beacon at every sample (the truth's closest approach); one row if it is fixed
        self.sample_beacons = sample_beacons(model, config.beacon_path, traj.t)
        self.filters = {name: make_filter(name, config, self.cov, pn) for name in names}
        for f in self.filters.values():
            if isinstance(f, AugmentedKalmanFilter):
                f.origin = self.ctx.beacons[0].copy()
        self.states = nominal_states(traj, model, config.current_array)
        self.nominal = self.states[plan.points]
        self.nav = np.ascontiguousarray(np.hstack([traj.p, traj.v]))  # nominal (p, p')
        Nr = self.records.size
        self.sums = {name: np.zeros((2, Nr, 3 + 2 * n)) for name in names}
        self.info = {name: np.zeros((runs, N_INFO)) for name in names}
        self.hist: dict = {}
        self.tm: list[np.ndarray] = []  # the truth metrics of the runs (filled by the caller)
        self.range_rows = np.flatnonzero(plan.reports[:, 0])
        mx = model.state_dim
        self.L, self.expo = truth_factor(pn.continuous, pn.q_ekf, n, model.current)
        if not config.process_noise:
            self.L = np.zeros((mx, 0))
        self.L0 = np.linalg.cholesky(self.cov["p0_ekf"])
        self.extra_std = np.sqrt(np.diag(self.cov["p0_kf"])[-2:])
        self.limits = limits
        self.box = (limits or TruthLimits()).box()
        # paths on the same time grid have the same schedule, records and truth deviation
        self.grid = traj.t.tobytes()


@dataclass(frozen=True, eq=False)
class RunDraws:
    """The draws of one run that do not depend on its path (module docstring of truth.py).

    Attributes
    ----------
    run : int
    err0 : (state_dim,)
        Initial estimation error ``x̂0 - x0``.
    extra_err : (2,) or None
        Error of the KF's extras ``(p0ᵀν0, |ν0|²)`` (``init_error="sample"`` only).
    readings : list
        Per sensor, the noise normals and dropout mask (:func:`truth.reading_draws`).
    channel : tuple of ndarray or None
        The acoustic channel's uniforms at the range reports (:func:`truth.channel_draws`);
        None for the ideal channel.
    """

    run: int
    err0: np.ndarray
    extra_err: np.ndarray | None
    readings: list
    channel: tuple | None = None


def draw_run(setup: PathSetup, seed: int, run: int) -> RunDraws:
    """Run ``run``'s initial error and reading draws from its streams (the process noise is
    drawn by the caller: all at once in open loop, block by block in closed loop).

    Parameters
    ----------
    setup : PathSetup
        The path's shared setup (epochs, priors).
    seed : int
        The Monte Carlo's seed.
    run : int
        Run index.

    Returns
    -------
    RunDraws
        The run's initial errors and reading draws.
    """
    config, model = setup.config, setup.model
    g0 = run_rng(seed, run, STREAM_INIT)
    extra_err = None
    if isinstance(config.init_error, str):
        err0 = setup.L0 @ g0.standard_normal(model.state_dim)
        extra_err = setup.extra_std * g0.standard_normal(2)
    else:
        err0 = np.asarray(config.init_error, float)
    rd = reading_draws(model, setup.plan.reports, dict(config.dropout), seed, run)
    cd = channel_draws(model, setup.plan.reports, config.channel, seed, run)
    return RunDraws(run=run, err0=err0, extra_err=extra_err, readings=rd, channel=cd)


def start_of(model, x0: np.ndarray, draws: RunDraws, r0: float, beacon0=None):
    """``(x̂0, extra0, r0)`` of a run that starts at the true state ``x0`` with first range
    reading ``r0``: the filters' common start
    (:meth:`~obsplan.estimation.filters.ekf.ExtendedKalmanFilter.start`).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.
    x0 : ndarray, shape (state_dim,)
        True initial state ``(p, v[, v_f])`` [m, m/s].
    draws : RunDraws
        The run's draws (its initial errors).
    r0 : float
        First range reading [m].
    beacon0 : ndarray, shape (n,), optional
        The beacon of the first range [m] (``ctx.beacons[0]``, a moving beacon's); None: the
        model's.

    Returns
    -------
    tuple
        ``(x̂0, extra0, r0)``: the initial estimate, the KF's extras (None unless sampled) and
        the anchor range.
    """
    n = model.dim
    extra0 = None
    if draws.extra_err is not None:
        # p, v of the KF start where the EKF's do; the extras get their own prior draw
        prel = x0[:n] - (model.beacon_array if beacon0 is None else beacon0)
        nu = x0[n : 2 * n] + (x0[2 * n : 3 * n] if model.current else 0.0)
        extra0 = np.array([prel @ nu, nu @ nu]) + draws.extra_err
    return (x0 + draws.err0, extra0, float(r0))


def nav_of(model, x: np.ndarray) -> np.ndarray:
    """``(p, p')`` of states ``x`` (..., state_dim) -> (..., 2n).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (dimension, current).
    x : ndarray, shape (..., state_dim)
        States ``(p, v[, v_f])``.

    Returns
    -------
    ndarray, shape (..., 2n)
        Position [m] and inertial velocity ``v (+ v_f)`` [m/s].
    """
    n = model.dim
    nu = x[..., n : 2 * n] + (x[..., 2 * n : 3 * n] if model.current else 0.0)
    return np.concatenate([x[..., :n], nu], axis=-1)
