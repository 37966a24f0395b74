"""Results of a Monte Carlo: statistics per filter, the bound, the truth, run 0's history.

Shards of runs (``run_start``) merge exactly (:func:`merge_monte_carlo`): every statistic is
recomputed from summed sufficient statistics and concatenated per-run arrays. A result carries
what ``obsplan simulate`` prints (:meth:`MonteCarloResult.summary`), its ``--json``
(:meth:`MonteCarloResult.to_dict`) and its figures (:meth:`MonteCarloResult.plot`, drawn by
:mod:`obsplan.estimation.montecarlo.plots`).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np
from matplotlib.figure import Figure

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import CRLBResult
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.guidance import Guidance
from obsplan.estimation.montecarlo.history import RunHistory
from obsplan.estimation.montecarlo.plots import plot_monte_carlo, scenario_figure
from obsplan.estimation.montecarlo.stats import FilterStats, StatsSums, TruthStats, filter_stats

#: The figures of :meth:`MonteCarloResult.plot`, by kind.
PLOT_KINDS = ("errors", "run")


@dataclass(frozen=True, eq=False, repr=False)
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
        """The statistics of filter ``name`` (error if that filter was not run).

        Parameters
        ----------
        name : str
            A filter that was run, e.g. ``"ekf"`` (a key of ``filters``).

        Returns
        -------
        FilterStats
            That filter's statistics over the runs.

        Raises
        ------
        ConfigError
            If filter ``name`` was not run.
        """
        s = (self.filters or {}).get(name)
        if s is None:
            raise ConfigError(f"filter {name!r} was not run; pass filters=(..., {name!r})")
        return s

    def filter_dict(self, name: str) -> dict | None:
        """Filter ``name``'s statistics (:meth:`FilterStats.to_dict`) with its ``lost_runs``:
        runs whose final position error exceeds
        :data:`~obsplan.estimation.channel.LOST_FACTOR` times the posterior CRB's final
        position std; None for a filter not run.

        Parameters
        ----------
        name : str
            The filter.

        Returns
        -------
        dict or None
            JSON-ready statistics.
        """
        s = (self.filters or {}).get(name)
        if s is None:
            return None
        return {**s.to_dict(), "lost_runs": s.lost_runs(self.crlb_final_pos_std)}

    def to_dict(self) -> dict:
        """The stable keys of ``obsplan simulate --json``, then extras.

        Returns
        -------
        dict
            JSON-ready values: ``runs``, ``seed``, ``ekf`` and ``kf`` (None for a filter not run),
            ``crlb_final_pos_std`` [m] (None if not finite), ``duration_s`` [s], ``samples``
            and ``trajectory_samples`` (recorded and path samples), ``run_start``, ``wall_s``
            [s], ``config``, ``mode``, ``guidance``, ``truth``; then every other filter that was
            run, by name.
        """
        crlb = float(self.crlb_final_pos_std)
        out = {
            "runs": int(self.runs),
            "seed": int(self.seed),
            "ekf": self.filter_dict("ekf"),
            "kf": self.filter_dict("kf"),
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
        for name in self.filters or {}:
            if name not in ("ekf", "kf"):
                out[name] = self.filter_dict(name)
        return out

    def filter_stats(self) -> dict[str, FilterStats]:
        """Every filter's statistics, by name, in the order they were run.

        Returns
        -------
        dict[str, FilterStats]
            ``ekf``, ``kf`` and any other filter that was run
            (:func:`~obsplan.estimation.montecarlo.stats.filter_stats`).
        """
        return filter_stats(self)

    def summary(self, title: str = "Monte Carlo") -> str:
        """What ``obsplan simulate`` prints: per filter the final error and standard deviation,
        the RMSE, the NEES, the convergence; the bound; the true paths against the limits.

        Parameters
        ----------
        title
            How the first line names the path (``obsplan simulate``: the trajectory file).

        Returns
        -------
        str
            Lines for the terminal; errors and standard deviations in metres.
        """
        cfg = self.config
        stats = self.filter_stats()
        lines = [
            f"{title}: {self.runs} runs, seed {self.seed}, {self.t[-1] - self.t[0]:.1f} s, "
            f"sensors {','.join(cfg.model.sensors)}",
            f"{'filter':8s} {'final err':>10s} {'final std':>10s} {'RMSE':>9s} {'NEES':>7s} "
            f"{'conv. time':>11s} {'converged':>9s}",
        ]
        for name, s in stats.items():
            conv = "never" if s.convergence_time is None else f"{s.convergence_time:.1f} s"
            lines.append(
                f"{name.upper():8s} {s.final_pos_err:9.3f}m {s.final_pos_std:9.3f}m "
                f"{s.rmse_pos:8.3f}m {s.nees_mean:7.2f} {conv:>11s} "
                f"{100 * s.converged_fraction:8.0f}%"
            )
        lo, hi = next(iter(stats.values())).nees_bounds
        lines.append(
            f"CRB final position std {self.crlb_final_pos_std:.3f} m; consistent NEES in "
            f"[{lo:.2f}, {hi:.2f}] (95 %, dof {2 * cfg.model.dim}); "
            f"convergence: error below {cfg.convergence_threshold_m:g} m"
        )
        tr = self.truth
        if tr is not None:
            steer = f" (steered on the {self.guidance.navigation.upper()})" if self.guidance else ""
            lines.append(
                f"{self.mode}{steer}: true paths' closest approach {tr.closest_range_m:.2f} m "
                f"over all runs, tracking error {tr.tracking_rmse_m:.3f} m RMS, final drift "
                f"{tr.final_drift_rms_m:.3f} m RMS, {100 * tr.any_violation_fraction:.1f} % of "
                "runs break a limit"
                + (f" ({broken})" if (broken := tr.breaks_words()) else "")
                + (
                    f"; {tr.runs_inside_min_range} runs inside min_range"
                    if tr.limits is not None and tr.limits.min_range is not None
                    else ""
                )
            )
        return "\n".join(lines)

    def plot(self, kind: str = "errors", ax=None) -> Figure:
        """A figure of the runs (:mod:`obsplan.estimation.montecarlo.plots`).

        Parameters
        ----------
        kind
            ``"errors"``: each filter's position RMSE over the runs and its mean standard
            deviation over time, with the posterior CRB (``monte_carlo.png`` of ``obsplan
            simulate``); ``"run"``: six panels of run 0 like the paper's figures (paths, error
            norms, position and velocity standard deviations, RMSE, range readings).
        ax
            A matplotlib Axes to draw ``"errors"`` into; None: a new figure.

        Returns
        -------
        Figure
            The figure drawn (``ax.figure`` when ``ax`` is given); nothing is shown or saved.

        Raises
        ------
        ConfigError
            An unknown kind, ``ax`` with ``"run"``, or ``"run"`` of a shard without run 0.
        """
        if kind == "errors":
            return plot_monte_carlo(self, ax=ax)
        if kind != "run":
            raise ConfigError(f"plot kind {kind!r}: one of {', '.join(PLOT_KINDS)}")
        if ax is not None:
            raise ConfigError('plot("run") draws six panels of its own: give no ax')
        if self.example is None:
            raise ConfigError("this result holds no run 0 (a shard of later runs): plot 'errors'")
        return scenario_figure(None, self)

    def __repr__(self) -> str:
        stats = self.filter_stats()
        errs = ", ".join(f"{k} {_m(s.final_pos_err)}" for k, s in stats.items())
        return (
            f"<MonteCarloResult {self.runs} runs, seed {self.seed}, {self.mode}; final position "
            f"error {errs}; bound {_m(self.crlb_final_pos_std)}>"
        )

    def _repr_html_(self) -> str:
        head = "".join(
            f"<th>{c}</th>"
            for c in ("filter", "final err [m]", "final std [m]", "RMSE [m]", "NEES", "converged")
        )
        rows = "".join(
            f"<tr><td>{html.escape(name.upper())}</td><td>{s.final_pos_err:.3g}</td>"
            f"<td>{s.final_pos_std:.3g}</td><td>{s.rmse_pos:.3g}</td><td>{s.nees_mean:.3g}</td>"
            f"<td>{100 * s.converged_fraction:.0f} %</td></tr>"
            for name, s in self.filter_stats().items()
        )
        return (
            f"<p><b>MonteCarloResult</b> {self.runs} runs, seed {self.seed}, "
            f"{html.escape(self.mode)}; CRB final position std "
            f"{_m(self.crlb_final_pos_std)}</p><table><tr>{head}</tr>{rows}</table>"
        )


def _m(x: float) -> str:
    return f"{x:.3g} m" if math.isfinite(x) else "n/a"


def merge_monte_carlo(parts: Sequence[MonteCarloResult]) -> MonteCarloResult:
    """Merge shards of one Monte Carlo (same path, configuration, seed and filters) exactly.

    The shards' runs must be disjoint and together contiguous (``run_start`` of one is where the
    previous ends, in any order); statistics are recomputed from the summed sufficient
    statistics, so the result equals the unsharded
    :func:`~obsplan.estimation.montecarlo.simulate.monte_carlo` to round-off; the per-run arrays
    (filters' and truth's) are concatenated in run order. Run 0's history is kept from the shard
    that computed it.

    Parameters
    ----------
    parts : sequence of MonteCarloResult
        The shards, in any order: the same seed, recorded times, filters, configuration, mode
        and guidance, all with or all without truth statistics.

    Returns
    -------
    MonteCarloResult
        One result over all the shards' runs (``runs`` summed, ``run_start`` the first shard's,
        ``wall_s`` summed [s]).

    Raises
    ------
    ConfigError
        If ``parts`` is empty, the shards differ in any of the above, or their runs are not
        contiguous.
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
    the truth's statistics ``truth``.

    Parameters
    ----------
    setup : PathSetup
        The path's setup after its runs: configuration, filters, recorded times, the summed
        statistics and per-run information of each filter, and run 0's history if it was run.
    runs : int
        Number of runs collected [runs].
    seed : int
        Seed of the random streams.
    run_start : int
        First run of the seed's streams collected here (runs ``run_start .. run_start+runs-1``).
    wall : float
        Wall time of the simulation of this path [s].
    crlb : CRLBResult
        The posterior CRB along the path (its samples; only the recorded ones are kept in
        ``crlb_pos_std_t``).
    truth : TruthStats or None
        The runs' true paths against the plan and the limits.
    mode : str, optional
        ``"open-loop"`` or ``"closed-loop"``.
    guidance : Guidance or None, optional
        The guidance law of a closed-loop result.

    Returns
    -------
    MonteCarloResult
        The statistics of every filter of ``setup``, the bound and the truth; ``example`` holds
        run 0's history if it was recorded, else None.
    """
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
