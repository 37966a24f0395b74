"""Results of a Monte Carlo: statistics per filter, the bound, the truth, run 0's history.

Shards of runs (``run_start``) merge exactly (:func:`merge_monte_carlo`): every statistic is
recomputed from summed sufficient statistics and concatenated per-run arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import CRLBResult
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.guidance import Guidance
from obsplan.estimation.montecarlo.stats import FilterStats, StatsSums, TruthStats


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
    """Result of :func:`~obsplan.estimation.montecarlo.simulate.monte_carlo` (picklable).

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
        :func:`~obsplan.estimation.montecarlo.simulate.monte_carlo_paths`, is divided among them).
    config : EstimationConfig
    run_start : int
        First run of the seed's streams computed here (runs ``run_start .. run_start+runs-1``).
    filters : dict[str, FilterStats]
        Every filter that was run, by name (``ekf``/``kf`` are also attributes).
    truth : TruthStats or None
        The runs' true paths against the plan and the limits (closest range, tracking error,
        violations; per-run arrays for paired comparisons).
    mode : str
        ``"open-loop"`` (the plan's inputs flown blind) or ``"closed-loop"`` (guided on the EKF's
        estimate, :mod:`obsplan.estimation.montecarlo.closedloop`).
    guidance : Guidance or None
        The guidance law of a closed-loop result.
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
    truth: TruthStats | None = None
    mode: str = "open-loop"
    guidance: Guidance | None = None

    def stats(self, name: str) -> FilterStats:
        """The statistics of filter ``name`` (error if that filter was not run)."""
        s = (self.filters or {}).get(name)
        if s is None:
            raise ConfigError(f"filter {name!r} was not run; pass filters=(..., {name!r})")
        return s

    def to_dict(self) -> dict:
        """The stable keys of ``obsplan simulate --json``, then extras."""
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
            "mode": self.mode,
            "guidance": None if self.guidance is None else self.guidance.to_dict(),
            "truth": None if self.truth is None else self.truth.to_dict(),
        }
        for name, s in (self.filters or {}).items():
            if name not in ("ekf", "kf"):
                out[name] = s.to_dict()
        return out


def merge_monte_carlo(parts: Sequence[MonteCarloResult]) -> MonteCarloResult:
    """Merge shards of one Monte Carlo (same path, configuration, seed and filters) exactly.

    The shards' runs must be disjoint and together contiguous (``run_start`` of one is where the
    previous ends, in any order); statistics are recomputed from the summed sufficient
    statistics, so the result equals the unsharded
    :func:`~obsplan.estimation.montecarlo.simulate.monte_carlo` to round-off; the per-run arrays
    (filters' and truth's) are concatenated in run order. Run 0's history is kept from the shard
    that computed it.
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
        if p.mode != first.mode or p.guidance != first.guidance:
            raise ConfigError("cannot merge open-loop and closed-loop results (or guidances)")
        if (p.truth is None) != (first.truth is None):
            raise ConfigError("cannot merge results with and without truth statistics")
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
            StatsSums.merge([cast(dict, p.filters)[name].sums for p in parts]), first.t, thr
        )
        for name in cast(dict, first.filters)  # merged results carry their filters
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
        truth=None
        if first.truth is None
        else TruthStats.merge([cast(TruthStats, p.truth) for p in parts]),
        mode=first.mode,
        guidance=first.guidance,
    )


def build_result(setup, runs, seed, run_start, wall, crlb, truth, mode="open-loop", guidance=None):
    """The :class:`MonteCarloResult` of the runs whose statistics ``setup`` (a
    :class:`~obsplan.estimation.montecarlo.runs.PathSetup`) collected, with the bound ``crlb`` and
    the truth's statistics ``truth``."""
    config, names = setup.config, list(setup.filters)
    t_rec, plan = setup.t_rec, setup.plan
    stats = {
        name: FilterStats.from_sums(
            StatsSums(sums=setup.sums[name], info=setup.info[name]),
            t_rec,
            config.convergence_threshold_m,
        )
        for name in names
    }
    example = None
    if "truth" in setup.hist:
        example = RunHistory(
            t=t_rec.copy(),
            truth=setup.hist["truth"],
            estimate={name: setup.hist[name][0] for name in names},
            std={name: setup.hist[name][1] for name in names},
            range_t=setup.traj.t[plan.epochs[setup.range_rows]],
            range_m=setup.hist["range"],
        )
    return MonteCarloResult(
        runs=runs,
        seed=seed,
        t=t_rec.copy(),
        ekf=stats.get("ekf"),
        kf=stats.get("kf"),
        crlb_pos_std_t=crlb.pos_std_t[setup.records],
        crlb_final_pos_std=crlb.final_pos_std,
        crlb=crlb,
        example=example,
        wall_s=wall,
        config=config,
        run_start=run_start,
        filters=stats,
        truth=truth,
        mode=mode,
        guidance=guidance,
    )
