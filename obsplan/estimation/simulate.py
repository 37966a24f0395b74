"""Monte Carlo of the EKF and the augmented KF along a trajectory (paper section 7).

``monte_carlo`` simulates ``runs`` seeded truths (process and measurement noise, multi-rate
schedule), runs both filters batched over the runs (one Python loop over samples, numpy over
runs), and returns statistics over the runs, the posterior Cramér–Rao bound along the same path,
and the full history of run 0 for figures. At each sample the filters first update with the
sensors that report, then predict to the next sample (prediction at the trajectory's sample rate).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from obsplan.errors import ConfigError
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.crlb import CRLBResult, posterior_crlb
from obsplan.estimation.ekf import ExtendedKalmanFilter
from obsplan.estimation.kf import AugmentedKalmanFilter
from obsplan.estimation.schedule import make_schedule, sample_rate
from obsplan.estimation.stats import FilterStats, StatsAccumulator, nees_bounds
from obsplan.estimation.truth import TruthSimulator, run_generators
from obsplan.trajectory import Trajectory

FILTERS = ("ekf", "kf")


@dataclass(frozen=True, eq=False)
class RunHistory:
    """Everything about one run (run 0), for figures.

    Attributes
    ----------
    t : ndarray, shape (N,)
    truth : ndarray, shape (N, 2n)
        True ``(p, p')``.
    estimate, std : dict[str, ndarray (N, 2n)]
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
        """``|p̂ - p|`` of filter ``name`` over time, shape (N,) [m]."""
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, :n] - self.truth[:, :n], axis=1)

    def vel_error(self, name: str) -> np.ndarray:
        """``|p̂' - p'|`` of filter ``name`` over time, shape (N,) [m/s]."""
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, n:] - self.truth[:, n:], axis=1)


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Result of :func:`monte_carlo`.

    Attributes
    ----------
    runs, seed : int
    t : ndarray, shape (N,)
    ekf, kf : FilterStats or None
        None for a filter that was not run.
    crlb_pos_std_t : ndarray, shape (N,)
        Posterior CRB on the position standard deviation ``sqrt(tr P_pp)`` [m].
    crlb_final_pos_std : float
    crlb : CRLBResult
    example : RunHistory
        Run 0.
    wall_s : float
        Wall time of the simulation [s].
    """

    runs: int
    seed: int
    t: np.ndarray
    ekf: FilterStats | None
    kf: FilterStats | None
    crlb_pos_std_t: np.ndarray
    crlb_final_pos_std: float
    crlb: CRLBResult
    example: RunHistory
    wall_s: float
    config: EstimationConfig

    def stats(self, name: str) -> FilterStats:
        """The statistics of ``"ekf"`` or ``"kf"`` (error if that filter was not run)."""
        s = getattr(self, name)
        if s is None:
            raise ConfigError(f"filter {name!r} was not run; pass filters=(..., {name!r})")
        return s

    def to_dict(self) -> dict:
        """The stable keys of PRODUCT.md ``obsplan simulate --json``, then extras."""
        return {
            "runs": int(self.runs),
            "seed": int(self.seed),
            "ekf": None if self.ekf is None else self.ekf.to_dict(),
            "kf": None if self.kf is None else self.kf.to_dict(),
            "crlb_final_pos_std": float(self.crlb_final_pos_std),
            "duration_s": float(self.t[-1] - self.t[0]),
            "samples": int(self.t.size),
            "wall_s": float(self.wall_s),
            "config": self.config.to_dict(),
        }


def _initial_errors(
    config: EstimationConfig, gens: list[np.random.Generator], P0: np.ndarray, P0_kf: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """Initial error of ``(p, v[, v_f])`` per run and, when sampled, of the KF's two extras."""
    R = len(gens)
    if not isinstance(config.init_error, str):
        return np.tile(config.init_error, (R, 1)), None
    L = np.linalg.cholesky(P0)
    ma = P0_kf.shape[0]
    Le = np.sqrt(np.diag(P0_kf)[ma - 2 :])
    ex, ee = [], []
    for g in gens:  # first draws of each run's stream
        ex.append(L @ g.standard_normal(P0.shape[0]))
        ee.append(Le * g.standard_normal(2))
    return np.array(ex), np.array(ee)


def monte_carlo(
    traj: Trajectory,
    config: EstimationConfig,
    runs: int = 50,
    seed: int = 0,
    progress: bool = False,
    filters: Sequence[str] = FILTERS,
    record_every: int | None = None,
) -> MonteCarloResult:
    """Monte Carlo of the filters along ``traj``.

    Parameters
    ----------
    traj
        The path (its samples are the model steps; its ``p'`` is the inertial velocity).
    config
        Model, sensors' rates and noises, covariances, initial error, truth options.
    runs
        Number of independent runs (each with its own stream spawned from ``seed``).
    seed
        Seed of every random draw.
    progress
        Show a progress bar over samples.
    filters
        Any of ``"ekf"``, ``"kf"``.
    record_every
        Statistics are recorded every this many samples (and at the last one); by default
        ``max(1, N // 5000)``, so long runs keep ~5000 points (time resolution of the
        convergence time). ``MonteCarloResult.t`` holds the recorded times.

    Returns
    -------
    MonteCarloResult
    """
    import time

    t_start = time.perf_counter()
    model = config.model
    if int(runs) < 1:
        raise ConfigError(f"runs must be a positive number of runs, got {runs!r}")
    runs = int(runs)
    filters = tuple(filters)
    bad = [f for f in filters if f not in FILTERS]
    if bad or not filters:
        raise ConfigError(f"filters must be a non-empty subset of {FILTERS}, got {filters!r}")
    if traj.dim != model.dim:
        raise ConfigError(f"the model is {model.dim}D but the trajectory is {traj.dim}D")
    dt = 1.0 / sample_rate(traj)
    cov = config.covariances(dt)
    schedule = make_schedule(traj, model.sensors, config.rates_hz)
    gens = run_generators(seed, runs)
    err0, extra_err = _initial_errors(config, gens, cov["p0_ekf"], cov["p0_kf"])
    truth = TruthSimulator(
        traj,
        model,
        config.current_array,
        cov["q_ekf"] if config.process_noise else None,
        dict(config.noise),
        schedule,
        gens,
        dict(config.dropout),
    )
    noise = dict(config.noise)
    x0 = truth.state(0)
    xhat0 = x0 + err0
    N, n = traj.n_samples, model.dim
    stride = max(1, N // 5000) if record_every is None else int(record_every)
    if stride < 1:
        raise ConfigError(
            f"record_every must be a positive number of samples, got {record_every!r}"
        )
    rec = np.zeros(N, dtype=bool)
    rec[::stride] = True
    rec[-1] = True
    rec_idx = np.cumsum(rec) - 1
    Nr = int(rec.sum())
    t_rec = traj.t[rec]
    flt: dict[str, object] = {}
    states: dict[str, object] = {}
    acc: dict[str, StatsAccumulator] = {}
    readings0 = truth.readings(0)
    if "ekf" in filters:
        flt["ekf"] = ExtendedKalmanFilter(model, traj, cov["q_ekf"], noise)
        states["ekf"] = flt["ekf"].init(xhat0, cov["p0_ekf"])
    if "kf" in filters:
        kf = AugmentedKalmanFilter(model, traj, cov["q_kf"], noise, config.y0_mode)
        extra0 = None
        if extra_err is not None:
            prel = x0[:, :n] - model.beacon_array
            nu = x0[:, n : 2 * n] + (x0[:, 2 * n : 3 * n] if model.current else 0.0)
            true_extra = np.column_stack([np.sum(prel * nu, axis=1), np.sum(nu**2, axis=1)])
            # p, v of the KF start where the EKF's do; the extras get their own prior draw
            extra0 = true_extra + extra_err
        flt["kf"] = kf
        states["kf"] = kf.init(xhat0, cov["p0_kf"], readings0["range"][:, 0], extra0)
    for name in filters:
        acc[name] = StatsAccumulator(Nr, runs, n, config.convergence_threshold_m)
    hist_est = {name: np.zeros((Nr, 2 * n)) for name in filters}
    hist_std = {name: np.zeros((Nr, 2 * n)) for name in filters}
    hist_truth = np.zeros((Nr, 2 * n))
    range_rep = schedule.reports("range")
    range_m = np.full(int(range_rep.sum()), np.nan)
    ir = 0

    bar = tqdm(total=N, disable=not progress, unit="step", desc="monte carlo", leave=False)
    for k in range(N):
        rd = readings0 if k == 0 else truth.readings(k)
        record = rec[k]
        if record:
            j = rec_idx[k]
            x = truth.state(k)
            nav_true = np.hstack(
                [x[:, :n], x[:, n : 2 * n] + (x[:, 2 * n :] if model.current else 0.0)]
            )
            hist_truth[j] = nav_true[0]
        if "range" in rd:
            range_m[ir] = rd["range"][0, 0]
            ir += 1
        for name in filters:
            f = flt[name]
            st = f.update(states[name], rd) if name == "ekf" else f.update(states[name], k, rd)
            if record:
                est, P = f.nav(st)
                acc[name].record(j, est - nav_true, P)
                hist_est[name][j] = est[0]
                hist_std[name][j] = np.sqrt(np.clip(np.diagonal(P[0]), 0.0, None))
            states[name] = f.predict(st, k) if k < N - 1 else st
        if k < N - 1:
            truth.advance(k)
        if k % 1000 == 999:
            bar.update(1000)
    bar.update(N - bar.n)
    bar.close()

    crlb = posterior_crlb(traj, config, schedule)
    bounds = nees_bounds(runs, 2 * n)
    stats = {name: acc[name].finish(t_rec, bounds) for name in filters}
    example = RunHistory(
        t=t_rec.copy(),
        truth=hist_truth,
        estimate=hist_est,
        std=hist_std,
        range_t=traj.t[range_rep],
        range_m=range_m,
    )
    return MonteCarloResult(
        runs=runs,
        seed=int(seed),
        t=t_rec.copy(),
        ekf=stats.get("ekf"),
        kf=stats.get("kf"),
        crlb_pos_std_t=crlb.pos_std_t[rec],
        crlb_final_pos_std=crlb.final_pos_std,
        crlb=crlb,
        example=example,
        wall_s=time.perf_counter() - t_start,
        config=config,
    )
