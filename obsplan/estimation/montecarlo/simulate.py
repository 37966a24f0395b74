"""Monte Carlo of the filters along a trajectory (paper section 7), open or closed loop.

``monte_carlo`` simulates seeded truths (process and measurement noise, multi-rate schedule), runs
the filters over the measurement epochs (exact composed predictions between them,
:mod:`obsplan.estimation.epochs`), and returns statistics over the runs, the posterior
Cramér–Rao bound along the same path, the truth's statistics (closest range, tracking error,
limit violations) and the history of run 0 for figures. At each epoch the filters update with
the sensors that report; statistics are taken at the recorded samples (after the update at an
epoch, from the prediction in between).

Two modes:

* open loop (``guidance=None``, the default here and the paper's setting): the vehicle flies the
  path's accelerations blind, the truth is the path plus the process-noise deviation;
* closed loop (a :class:`~obsplan.estimation.montecarlo.guidance.Guidance`): the vehicle steers its
  EKF estimate onto the path (:mod:`obsplan.estimation.montecarlo.closedloop`), as a vehicle at sea
  does; what the planning validation uses.

Work is proportional to the epochs and records, plus the truth's process noise (normals per step,
summed by a compiled recursion; in closed loop the guidance at every step). Run ``r`` draws from
streams that depend only on ``(seed, r)`` (:mod:`obsplan.estimation.montecarlo.truth`), so
``monte_carlo(..., runs=k, run_start=s)`` computes runs ``s .. s+k-1`` of the seed and
:func:`merge_monte_carlo` merges such shards into exactly the unsharded result.

A moving beacon (``EstimationConfig.beacon_path``) is fixed per path at the epochs, at each
range's transmission (:mod:`obsplan.estimation.epochs`, "A moving beacon"), and at the samples
for the truth's closest approach; every filter, the truth and the bound use those positions.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from tqdm import tqdm

from obsplan.core.errors import ConfigError
from obsplan.estimation import jitcache
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.columns import TM_ACCEL
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.estimation.montecarlo.guidance import Guidance, TruthLimits
from obsplan.estimation.montecarlo.results import (
    MonteCarloResult,
    RunHistory,
    build_result,
    merge_monte_carlo,
)
from obsplan.estimation.montecarlo.runs import (
    BATCH,
    DEFAULT_FILTERS,
    FILTERS,
    PathSetup,
    RunDraws,
    check_filters,
    check_runs,
    draw_run,
    make_filter,
    nav_of,
    start_of,
)
from obsplan.estimation.montecarlo.stats import TruthStats
from obsplan.estimation.montecarlo.truth import (
    STREAM_PROCESS,
    noisy_readings,
    open_loop_truth,
    run_rng,
)
from obsplan.trajectory.sampled import Trajectory

__all__ = [
    "BATCH",
    "DEFAULT_FILTERS",
    "FILTERS",
    "MonteCarloResult",
    "RunHistory",
    "make_filter",
    "merge_monte_carlo",
    "monte_carlo",
    "monte_carlo_paths",
]


def monte_carlo(
    traj: Trajectory,
    config: EstimationConfig,
    runs: int = 50,
    seed: int = 0,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    record_every: int | None = None,
    run_start: int = 0,
    *,
    guidance: Guidance | None = None,
    limits: TruthLimits | None = None,
    lines: np.ndarray | None = None,
) -> MonteCarloResult:
    """Monte Carlo of the filters along ``traj``.

    Parameters
    ----------
    traj : Trajectory
        The path (its samples are the model steps; its ``p'`` is the inertial velocity).
    config : EstimationConfig
        Model, sensors' rates and noises, covariances, initial error, truth options.
    runs : int, optional
        Number of independent runs.
    seed : int, optional
        Seed of every random draw (an integer ≥ 0).
    progress : bool, optional
        Show a progress bar over runs.
    filters : sequence of str, optional
        Names from :data:`FILTERS` (default :data:`DEFAULT_FILTERS`).
    record_every : int or None, optional
        Statistics are recorded every this many samples (and at the last one); by default
        ``max(1, N // 1000)``, so long runs keep ~1000 points (the time resolution of the
        convergence time). ``MonteCarloResult.t`` holds the recorded times.
    run_start : int, optional
        Index of the first run in the seed's streams: runs ``run_start .. run_start+runs-1``
        are computed (shards of one Monte Carlo, merged by :func:`merge_monte_carlo`).
    guidance : Guidance or None, optional
        Fly the path in closed loop with this guidance law (module docstring); ``None``: open
        loop.
    limits : TruthLimits or None, optional
        Limits the true paths are checked against (``MonteCarloResult.truth``).
    lines : ndarray of bool, shape (N,), optional
        Boolean mask (N,) of the samples of a per-run subset RMSE (e.g. on survey lines).

    Returns
    -------
    MonteCarloResult
        Statistics per filter, the bound, the true paths; ``summary()``, ``plot()`` and
        ``to_dict()`` give what ``obsplan simulate`` prints, draws and writes (``--json``).

    Raises
    ------
    ConfigError
        For bad runs, seed, filters or masks, or a model of another dimension than the path.

    Notes
    -----
    The defaults are those of a plain Monte Carlo of the filters, the paper's setting: open
    loop (no ``guidance``), the EKF and the augmented KF, the EKF update of ``config``
    (first-order unless ``ekf_update="second-order"``), one batch of ``runs``. A planning
    problem's validation (``obsplan plan``, ``report.json``) flies every path in closed loop,
    steered on the Gaussian sum's estimate, with the second-order EKF, in batches until its
    verdicts are decided: to reproduce those numbers use ``obsplan.validate(trajectory,
    problem)``, not this function. (These defaults stay: the paper's tables and figures, and
    every caller of this function, depend on them.)

    Examples
    --------
    >>> from obsplan import EstimationConfig, make_model, monte_carlo
    >>> from obsplan.trajectory import generators
    >>> traj = generators.circle(30.0, 1.5, 20.0).sample(0.1)
    >>> cfg = EstimationConfig.paper(make_model(2, "range"), 0.1)
    >>> res = monte_carlo(traj, cfg, runs=4, seed=0, filters=("ekf",))
    >>> res.runs, "ekf" in res.to_dict()
    (4, True)
    """
    return monte_carlo_paths(
        [traj],
        config,
        runs,
        seed,
        progress,
        filters,
        record_every,
        run_start,
        guidance=guidance,
        limits=limits,
        lines=None if lines is None else [lines],
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
    *,
    guidance: Guidance | None = None,
    limits: TruthLimits | None = None,
    lines: Sequence[np.ndarray | None] | None = None,
) -> list[MonteCarloResult]:
    """:func:`monte_carlo` of several paths with the same runs on every path.

    Each result equals ``monte_carlo(path, ...)``; open loop, paths on the same time grid share
    every random draw and the truth's process-noise deviation, which are then computed once per
    run. ``lines`` holds one mask (or None) per path.

    Parameters
    ----------
    paths : sequence of Trajectory
        The paths, at least one.
    config : EstimationConfig
        Model, sensors' rates and noises, covariances, initial error, truth options.
    runs : int, optional
        Number of independent runs per path.
    seed : int, optional
        Seed of every random draw (an integer ≥ 0).
    progress : bool, optional
        Show a progress bar over runs.
    filters : sequence of str, optional
        Names from :data:`FILTERS`.
    record_every : int or None, optional
        Record stride in samples (:func:`monte_carlo`).
    run_start : int, optional
        Index of the first run in the seed's streams.
    guidance : Guidance or None, optional
        Fly every path in closed loop with this guidance law; ``None``: open loop.
    limits : TruthLimits or None, optional
        Limits the true paths are checked against.
    lines : sequence of (ndarray of bool or None), optional
        One mask (or None) per path of the samples of the subset RMSE.

    Returns
    -------
    list of MonteCarloResult
        One result per path, in order.

    Raises
    ------
    ConfigError
        For no path, bad runs, seed or filters, or not one mask per path.
    """
    runs, seed, run_start = check_runs(runs, seed, run_start)
    names = check_filters(filters)
    if not paths:
        raise ConfigError("monte_carlo_paths needs at least one path")
    masks = [None] * len(paths) if lines is None else list(lines)
    if len(masks) != len(paths):
        raise ConfigError(f"lines: expected one mask (or None) per path, got {len(masks)}")
    if guidance is not None:
        return [
            _closed_loop(
                tr,
                config,
                runs,
                seed,
                progress,
                names,
                record_every,
                run_start,
                guidance,
                limits,
                mask,
            )
            for tr, mask in zip(paths, masks, strict=True)
        ]
    return _open_loop(
        paths, config, runs, seed, progress, names, record_every, run_start, limits, masks
    )


def _bar(runs: int, progress: bool, closed_loop: bool) -> tqdm:
    """The progress bar over runs; labelled while the first batch compiles the filters (a
    cold numba cache: about a minute, :mod:`obsplan.estimation.jitcache`)."""
    desc = jitcache.compile_note(closed_loop) if progress else None
    return tqdm(total=runs, desc=desc, disable=not progress, unit="run", leave=False)


def _advance(bar: tqdm, n: int) -> None:
    if getattr(bar, "desc", ""):  # the first batch compiled what it needed (unset if disabled)
        bar.set_description_str("", refresh=False)
    bar.update(n)


def _closed_loop(
    traj, config, runs, seed, progress, names, record_every, run_start, guidance, limits, mask
) -> MonteCarloResult:
    """One path in closed loop: batches of runs (:class:`ClosedLoop`), merged exactly."""
    crlb = posterior_crlb(traj, config)
    parts = []
    with _bar(runs, progress, closed_loop=True) as bar:
        for c0 in range(run_start, run_start + runs, BATCH):
            k = min(BATCH, run_start + runs - c0)
            loop = ClosedLoop(
                traj,
                config,
                k,
                seed,
                c0,
                guidance=guidance,
                limits=limits,
                record_every=record_every,
                lines=mask,
                filters=names,
            )
            parts.append(loop.result(crlb))
            _advance(bar, k)
    return merge_monte_carlo(parts)


def _open_loop(
    paths, config, runs, seed, progress, names, record_every, run_start, limits, masks
) -> list[MonteCarloResult]:
    t_start = time.perf_counter()
    model = config.model
    jobs = [
        PathSetup(tr, config, names, record_every, runs, mask, limits)
        for tr, mask in zip(paths, masks, strict=True)
    ]
    groups: dict[bytes, list[PathSetup]] = {}
    for job in jobs:
        groups.setdefault(job.grid, []).append(job)
        job.tm = []
    bar = _bar(runs, progress, closed_loop=False)
    for c0 in range(run_start, run_start + runs, BATCH):
        chunk = range(c0, min(c0 + BATCH, run_start + runs))
        for group in groups.values():
            first = group[0]
            plan, L = first.plan, first.L
            navs = np.stack([job.nav for job in group])
            draws = []
            for i in chunk:
                z = None
                if L.shape[1]:
                    z = run_rng(seed, i, STREAM_PROCESS).standard_normal(
                        (first.traj.n_samples - 1, L.shape[1])
                    )
                delta, tm = open_loop_truth(
                    first.traj,
                    model,
                    L,
                    z,
                    plan.points,
                    first.expo,
                    navs,
                    first.box,
                    first.sample_beacons,
                )
                for job, row in zip(group, tm, strict=True):
                    job.tm.append(row)
                draws.append((draw_run(first, seed, i), delta))
            for job in group:
                _run_batch(job, chunk, run_start, draws)
        _advance(bar, len(chunk))
    bar.close()

    wall = (time.perf_counter() - t_start) / len(jobs)
    out = []
    for job in jobs:
        tm = np.array(job.tm)
        if limits is not None:  # the plan's own inputs, flown blind: the same in every run
            tm[:, TM_ACCEL] = np.max(np.abs(job.traj.u[:-1]) / limits.accel_bounds(model.dim))
        truth = TruthStats.from_metrics(tm, limits)
        crlb = posterior_crlb(job.traj, config, job.schedule)
        out.append(build_result(job, runs, seed, run_start, wall, crlb, truth))
    return out


def _run_batch(job: PathSetup, chunk, run_start: int, draws: list[tuple[RunDraws, np.ndarray]]):
    """The runs of ``chunk`` on one path, every filter batched over them."""
    model, plan = job.model, job.plan
    n = model.dim
    noise = dict(job.config.noise)
    Ys, truths, starts = [], [], []
    for dr, delta in draws:
        x = job.nominal + delta
        bs = job.ctx.beacons
        Ys.append(
            noisy_readings(
                model,
                x[plan.epoch_pt],
                plan.reports,
                noise,
                dr.readings,
                bs,
                channel=job.config.channel,
                cdraws=dr.channel,
                rho=job.rho_epochs,
                rho_dot=job.rho_dot_epochs,
            )
        )
        truths.append(nav_of(model, x[plan.rec_pt]))
        starts.append(start_of(model, x[0], dr, Ys[-1][0, 0], bs[0]))
    Y = np.stack(Ys, axis=2)
    truth_rec = np.stack(truths)
    ex_run = chunk.index(0) if 0 in chunk else -1
    sl = slice(chunk.start - run_start, chunk.stop - run_start)
    Nr = job.records.size
    for name, f in job.filters.items():
        batch = RunBatch(job.ctx, [f.start(*st) for st in starts], Y)
        ex = np.zeros((2, Nr, 2 * n)) if ex_run >= 0 else None
        f.run(batch, RunRecord(truth_rec, job.sums[name], job.info[name][sl], ex_run, ex))
        if ex is not None:
            job.hist[name] = ex
    if ex_run >= 0:
        job.hist["truth"] = truth_rec[ex_run]
        job.hist["range"] = Y[job.range_rows, 0, ex_run].copy()
