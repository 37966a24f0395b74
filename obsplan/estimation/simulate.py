"""Monte Carlo of the filters along a trajectory (paper section 7).

``monte_carlo`` simulates seeded truths (process and measurement noise, multi-rate schedule), runs
the filters over the measurement epochs (exact composed predictions between them,
:mod:`obsplan.estimation.epochs`), and returns statistics over the runs, the posterior
Cramér–Rao bound along the same path and the history of run 0 for figures. At each epoch the
filters update with the sensors that report; statistics are taken at the recorded samples (after
the update at an epoch, from the prediction in between).

Work is proportional to the epochs and records, plus the truth's process noise (one normal per
state and step, summed by a compiled recursion). Run ``r`` draws from streams that depend only on
``(seed, r)`` (:mod:`obsplan.estimation.truth`), so ``monte_carlo(..., runs=k, run_start=s)``
computes runs ``s .. s+k-1`` of the seed and :func:`merge_monte_carlo` merges such shards into
exactly the unsharded result.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from obsplan.errors import ConfigError
from obsplan.estimation.config import EstimationConfig, ProcessNoise
from obsplan.estimation.crlb import CRLBResult, posterior_crlb
from obsplan.estimation.ekf import ExtendedKalmanFilter
from obsplan.estimation.epochs import RunContext, epoch_plan, input_displacement, record_samples
from obsplan.estimation.gsf import GaussianSumFilter
from obsplan.estimation.kf import AugmentedKalmanFilter
from obsplan.estimation.schedule import make_schedule, sample_rate
from obsplan.estimation.stats import (
    MONITOR_LEVEL,
    MONITOR_WINDOW_FRACTION,
    N_INFO,
    FilterStats,
    StatsSums,
    chi2_quantile,
)
from obsplan.estimation.truth import (
    STREAM_INIT,
    STREAM_PROCESS,
    noisy_readings,
    nominal_states,
    reading_draws,
    run_rng,
    truth_deviation,
    truth_factor,
)
from obsplan.trajectory import Trajectory

#: The estimators ``monte_carlo`` can run, by name.
FILTERS: dict[str, str] = {
    "ekf": "extended Kalman filter on the nonlinear model",
    "kf": "Kalman filter on the augmented linear model (process-noise coupling modelled)",
    "gsf": "Gaussian-sum EKF, prior split over the velocity (range-only geometry)",
}
#: What ``monte_carlo`` runs unless told otherwise.
DEFAULT_FILTERS: tuple[str, ...] = ("ekf", "kf")
#: Runs per kernel call: the kernels vectorise over the runs of a batch; Ctrl-C is honoured
#: between batches.
BATCH = 32


def make_filter(name: str, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise):
    """The estimator ``name`` of :data:`FILTERS` for ``config`` (priors in ``cov``, process
    noise ``pn``: per-step covariances or intensities, as the epoch plan it runs on)."""
    noise = dict(config.noise)
    if name == "ekf":
        return ExtendedKalmanFilter(config.model, pn.q_ekf, cov["p0_ekf"], noise)
    if name == "kf":
        return AugmentedKalmanFilter(
            config.model, pn.q_kf, cov["p0_kf"], noise, config.y0_mode, config.kf_coupling
        )
    if name == "gsf":
        return GaussianSumFilter(config.model, pn.q_ekf, cov["p0_ekf"], noise)
    raise ConfigError(f"unknown filter {name!r}; choose from {', '.join(FILTERS)}")


@dataclass(frozen=True, eq=False)
class RunHistory:
    """Everything about one run (run 0), for figures.

    Attributes
    ----------
    t : ndarray, shape (Nr,)
        Recorded times [s].
    truth : ndarray, shape (Nr, 2n)
        True ``(p, p')``.
    estimate, std : dict[str, ndarray (Nr, 2n)]
        Per filter, the estimate of ``(p, p')`` and its per-component standard deviation.
    range_t, range_m : ndarray
        Times [s] and values [m] of the range readings (NaN where dropped).
    """

    t: np.ndarray
    truth: np.ndarray
    estimate: dict[str, np.ndarray]
    std: dict[str, np.ndarray]
    range_t: np.ndarray
    range_m: np.ndarray

    def pos_error(self, name: str) -> np.ndarray:
        """``|p̂ - p|`` of filter ``name`` over time, shape (Nr,) [m]."""
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, :n] - self.truth[:, :n], axis=1)

    def vel_error(self, name: str) -> np.ndarray:
        """``|p̂' - p'|`` of filter ``name`` over time, shape (Nr,) [m/s]."""
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, n:] - self.truth[:, n:], axis=1)


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Result of :func:`monte_carlo` (picklable).

    Attributes
    ----------
    runs, seed : int
    t : ndarray, shape (Nr,)
        Recorded times [s].
    ekf, kf : FilterStats or None
        None for a filter that was not run.
    crlb_pos_std_t : ndarray, shape (Nr,)
        Posterior CRB on the position standard deviation ``sqrt(tr P_pp)`` [m].
    crlb_final_pos_std : float
    crlb : CRLBResult
    example : RunHistory or None
        Run 0 (None for a shard that does not contain it).
    wall_s : float
        Wall time of the simulation [s] (summed over merged shards; a pass over several paths,
        :func:`monte_carlo_paths`, is divided among them).
    config : EstimationConfig
    run_start : int
        First run of the seed's streams computed here (runs ``run_start .. run_start+runs-1``).
    filters : dict[str, FilterStats]
        Every filter that was run, by name (``ekf``/``kf`` are also attributes).
    """

    runs: int
    seed: int
    t: np.ndarray
    ekf: FilterStats | None
    kf: FilterStats | None
    crlb_pos_std_t: np.ndarray
    crlb_final_pos_std: float
    crlb: CRLBResult
    example: RunHistory | None
    wall_s: float
    config: EstimationConfig
    run_start: int = 0
    filters: dict | None = None

    def stats(self, name: str) -> FilterStats:
        """The statistics of filter ``name`` (error if that filter was not run)."""
        s = (self.filters or {}).get(name)
        if s is None:
            raise ConfigError(f"filter {name!r} was not run; pass filters=(..., {name!r})")
        return s

    def to_dict(self) -> dict:
        """The stable keys of PRODUCT.md ``obsplan simulate --json``, then extras."""
        crlb = float(self.crlb_final_pos_std)
        out = {
            "runs": int(self.runs),
            "seed": int(self.seed),
            "ekf": None if self.ekf is None else self.ekf.to_dict(),
            "kf": None if self.kf is None else self.kf.to_dict(),
            "crlb_final_pos_std": crlb if np.isfinite(crlb) else None,
            "duration_s": float(self.crlb.t[-1] - self.crlb.t[0]),
            "samples": int(self.t.size),
            "trajectory_samples": int(self.crlb.t.size),
            "run_start": int(self.run_start),
            "wall_s": float(self.wall_s),
            "config": self.config.to_dict(),
        }
        for name, s in (self.filters or {}).items():
            if name not in ("ekf", "kf"):
                out[name] = s.to_dict()
        return out


def _check_filters(filters: Sequence[str]) -> tuple[str, ...]:
    out = tuple(filters)
    bad = [f for f in out if f not in FILTERS]
    if bad or not out or len(set(out)) != len(out):
        raise ConfigError(
            f"filters must be a non-empty list of distinct names from {', '.join(FILTERS)}, "
            f"got {filters!r}"
        )
    return out


def _check_runs(runs: int, seed: int, run_start: int) -> tuple[int, int, int]:
    if isinstance(runs, bool) or int(runs) != runs or int(runs) < 1:
        raise ConfigError(f"runs must be a positive number of runs, got {runs!r}")
    if isinstance(seed, bool) or int(seed) != seed or int(seed) < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(run_start, bool) or int(run_start) != run_start or int(run_start) < 0:
        raise ConfigError(f"run_start must be an integer >= 0, got {run_start!r}")
    return int(runs), int(seed), int(run_start)


class _Path:
    """Everything one path needs for its runs (its filters, epochs, sums)."""

    def __init__(self, traj, config, names, record_every, runs):
        model = config.model
        if traj.dim != model.dim:
            raise ConfigError(f"the model is {model.dim}D but the trajectory is {traj.dim}D")
        n = model.dim
        self.traj = traj
        dt = 1.0 / sample_rate(traj)
        self.cov = config.covariances(dt)
        self.noise = pn = config.process_noise_model(dt)
        self.schedule = make_schedule(traj, model.sensors, config.rates_hz)
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
        )
        self.filters = {name: make_filter(name, config, self.cov, pn) for name in names}
        self.nominal = nominal_states(traj, model, config.current_array)[plan.points]
        Nr = self.records.size
        self.sums = {name: np.zeros((2, Nr, 3 + 2 * n)) for name in names}
        self.info = {name: np.zeros((runs, N_INFO)) for name in names}
        self.hist: dict = {}
        self.range_rows = np.flatnonzero(plan.reports[:, 0])
        mx = model.state_dim
        self.L, self.expo = truth_factor(pn.continuous, pn.q_ekf, n, model.current)
        if not config.process_noise:
            self.L = np.zeros((mx, 0))
        self.L0 = np.linalg.cholesky(self.cov["p0_ekf"])
        self.extra_std = np.sqrt(np.diag(self.cov["p0_kf"])[-2:])
        # paths on the same time grid have the same schedule, records and truth deviation
        self.grid = traj.t.tobytes()


def monte_carlo(
    traj: Trajectory,
    config: EstimationConfig,
    runs: int = 50,
    seed: int = 0,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    record_every: int | None = None,
    run_start: int = 0,
) -> MonteCarloResult:
    """Monte Carlo of the filters along ``traj``.

    Parameters
    ----------
    traj
        The path (its samples are the model steps; its ``p'`` is the inertial velocity).
    config
        Model, sensors' rates and noises, covariances, initial error, truth options.
    runs
        Number of independent runs.
    seed
        Seed of every random draw (an integer ≥ 0).
    progress
        Show a progress bar over runs.
    filters
        Names from :data:`FILTERS` (default :data:`DEFAULT_FILTERS`).
    record_every
        Statistics are recorded every this many samples (and at the last one); by default
        ``max(1, N // 1000)``, so long runs keep ~1000 points (the time resolution of the
        convergence time). ``MonteCarloResult.t`` holds the recorded times.
    run_start
        Index of the first run in the seed's streams: runs ``run_start .. run_start+runs-1``
        are computed (shards of one Monte Carlo, merged by :func:`merge_monte_carlo`).

    Returns
    -------
    MonteCarloResult
    """
    return monte_carlo_paths(
        [traj], config, runs, seed, progress, filters, record_every, run_start
    )[0]


def monte_carlo_paths(
    paths: Sequence[Trajectory],
    config: EstimationConfig,
    runs: int = 50,
    seed: int = 0,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    record_every: int | None = None,
    run_start: int = 0,
) -> list[MonteCarloResult]:
    """:func:`monte_carlo` of several paths in one pass, with the same runs on every path.

    Each result equals ``monte_carlo(path, ...)``; paths on the same time grid share every random
    draw and the truth's process-noise deviation, which are then computed once per run.
    """
    t_start = time.perf_counter()
    model = config.model
    runs, seed, run_start = _check_runs(runs, seed, run_start)
    names = _check_filters(filters)
    if not paths:
        raise ConfigError("monte_carlo_paths needs at least one path")
    jobs = [_Path(tr, config, names, record_every, runs) for tr in paths]
    mx = model.state_dim
    sampled = isinstance(config.init_error, str)
    noise, dropout = dict(config.noise), dict(config.dropout)
    groups: dict[bytes, list[_Path]] = {}
    for job in jobs:
        groups.setdefault(job.grid, []).append(job)

    bar = tqdm(total=runs, disable=not progress, unit="run", leave=False)
    for c0 in range(run_start, run_start + runs, BATCH):
        chunk = range(c0, min(c0 + BATCH, run_start + runs))
        for group in groups.values():
            first = group[0]
            plan, L = first.plan, first.L
            draws = []
            for i in chunk:
                g0 = run_rng(seed, i, STREAM_INIT)
                extra_err = None
                if sampled:
                    err0 = first.L0 @ g0.standard_normal(mx)
                    extra_err = first.extra_std * g0.standard_normal(2)
                else:
                    err0 = np.asarray(config.init_error)
                delta = np.zeros((plan.points.size, mx))
                if L.shape[1]:
                    z = run_rng(seed, i, STREAM_PROCESS).standard_normal(
                        (first.traj.n_samples - 1, L.shape[1])
                    )
                    delta = truth_deviation(first.traj, model, L, z, plan.points, first.expo)
                rd = reading_draws(model, plan.reports, dropout, seed, i)
                draws.append((err0, extra_err, delta, rd))
            for job in group:
                _run_batch(job, chunk, run_start, model, noise, draws)
        bar.update(len(chunk))
    bar.close()

    wall = (time.perf_counter() - t_start) / len(jobs)
    return [_result(job, config, names, runs, seed, run_start, wall) for job in jobs]


def _run_batch(job, chunk, run_start, model, noise, draws) -> None:
    """The runs of ``chunk`` on one path, every filter batched over them."""
    n = model.dim
    plan = job.plan
    Ys, truths, starts = [], [], []
    for err0, extra_err, delta, rd in draws:
        x = job.nominal + delta
        Ys.append(noisy_readings(model, x[plan.epoch_pt], plan.reports, noise, rd))
        xr = x[plan.rec_pt]
        truths.append(
            np.hstack([xr[:, :n], xr[:, n : 2 * n] + (xr[:, 2 * n :] if model.current else 0.0)])
        )
        x0 = x[0]
        extra0 = None
        if extra_err is not None:
            # p, v of the KF start where the EKF's do; the extras get their own prior draw
            prel = x0[:n] - model.beacon_array
            nu = x0[n : 2 * n] + (x0[2 * n : 3 * n] if model.current else 0.0)
            extra0 = np.array([prel @ nu, nu @ nu]) + extra_err
        starts.append((x0 + err0, extra0, float(Ys[-1][0, 0])))
    Y = np.stack(Ys, axis=2)
    truth_rec = np.stack(truths)
    ex_run = chunk.index(0) if 0 in chunk else -1
    sl = slice(chunk.start - run_start, chunk.stop - run_start)
    Nr = job.records.size
    for name, f in job.filters.items():
        states = [f.start(*st) for st in starts]
        ex = np.zeros((2, Nr, 2 * n)) if ex_run >= 0 else None
        f.run(job.ctx, states, Y, truth_rec, job.sums[name], job.info[name][sl], ex_run, ex)
        if ex is not None:
            job.hist[name] = ex
    if ex_run >= 0:
        job.hist["truth"] = truth_rec[ex_run]
        job.hist["range"] = Y[job.range_rows, 0, ex_run].copy()


def _result(job, config, names, runs, seed, run_start, wall) -> MonteCarloResult:
    traj, plan, t_rec = job.traj, job.plan, job.t_rec
    crlb = posterior_crlb(traj, config, job.schedule)
    stats = {
        name: FilterStats.from_sums(
            StatsSums(sums=job.sums[name], info=job.info[name]),
            t_rec,
            config.convergence_threshold_m,
        )
        for name in names
    }
    example = None
    if "truth" in job.hist:
        example = RunHistory(
            t=t_rec.copy(),
            truth=job.hist["truth"],
            estimate={name: job.hist[name][0] for name in names},
            std={name: job.hist[name][1] for name in names},
            range_t=traj.t[plan.epochs[job.range_rows]],
            range_m=job.hist["range"],
        )
    return MonteCarloResult(
        runs=runs,
        seed=seed,
        t=t_rec.copy(),
        ekf=stats.get("ekf"),
        kf=stats.get("kf"),
        crlb_pos_std_t=crlb.pos_std_t[job.records],
        crlb_final_pos_std=crlb.final_pos_std,
        crlb=crlb,
        example=example,
        wall_s=wall,
        config=config,
        run_start=run_start,
        filters=stats,
    )


def merge_monte_carlo(parts: Sequence[MonteCarloResult]) -> MonteCarloResult:
    """Merge shards of one Monte Carlo (same path, configuration, seed and filters) exactly.

    The shards' runs must be disjoint and together contiguous (``run_start`` of one is where the
    previous ends, in any order); statistics are recomputed from the summed sufficient
    statistics, so the result equals the unsharded :func:`monte_carlo` to round-off. Run 0's
    history is kept from the shard that computed it.
    """
    parts = sorted(parts, key=lambda p: p.run_start)
    if not parts:
        raise ConfigError("merge_monte_carlo needs at least one result")
    first = parts[0]
    for p in parts[1:]:
        if p.seed != first.seed:
            raise ConfigError(f"cannot merge results of seeds {first.seed} and {p.seed}")
        if p.t.shape != first.t.shape or not np.array_equal(p.t, first.t):
            raise ConfigError("cannot merge results recorded at different times")
        if set(p.filters or {}) != set(first.filters or {}):
            raise ConfigError("cannot merge results of different filters")
        if p.config.to_dict() != first.config.to_dict():
            raise ConfigError("cannot merge results of different configurations")
    for a, b in zip(parts[:-1], parts[1:], strict=False):
        if b.run_start != a.run_start + a.runs:
            raise ConfigError(
                f"shards must cover contiguous runs: runs {a.run_start}.."
                f"{a.run_start + a.runs - 1} "
                f"are followed by a shard starting at run {b.run_start}"
            )
    thr = first.config.convergence_threshold_m
    stats = {
        name: FilterStats.from_sums(
            StatsSums.merge([p.filters[name].sums for p in parts]), first.t, thr
        )
        for name in first.filters
    }
    example = next((p.example for p in parts if p.example is not None), None)
    return MonteCarloResult(
        runs=sum(p.runs for p in parts),
        seed=first.seed,
        t=first.t,
        ekf=stats.get("ekf"),
        kf=stats.get("kf"),
        crlb_pos_std_t=first.crlb_pos_std_t,
        crlb_final_pos_std=first.crlb_final_pos_std,
        crlb=first.crlb,
        example=example,
        wall_s=sum(p.wall_s for p in parts),
        config=first.config,
        run_start=first.run_start,
        filters=stats,
    )
