"""Statistics over Monte Carlo runs: RMSE, standard deviations, NEES with χ² bounds, convergence,
and the divergence monitor.

Everything is on the navigation state ``(p, p')`` (position and inertial velocity, dof ``2n``),
the same for every filter. Over ``M`` runs the average NEES at one time, times ``M``, is
``χ²(M·2n)`` for a consistent filter, which gives the 95 % interval of :func:`nees_bounds`.

Divergence monitor
------------------
A run is *flagged* when its own NEES, averaged over the records of its final ``window`` (default
10 % of the duration), is above the 99.9 % quantile of ``χ²(2n)``, or when its estimate becomes
non-finite. For a consistent filter that average has mean ``2n`` and is less spread than one
sample, which exceeds the quantile 0.1 % of the time; ending far above it means the covariance no
longer describes the error: the estimate has left the truth's basin (the mirror of a straight leg,
a lost linearisation) while the filter still claims to know where it is. An inconsistent
transient that the filter recovers from (the EKF's first seconds from a far initial estimate) is
not flagged. The statistics are reported over all runs (the stable keys) and separately over the
unflagged and the flagged runs.

Sufficient statistics
---------------------
The kernels add every run's per-record squares to the sums of its group (:class:`StatsSums`), and
keep a few numbers per run; :class:`FilterStats` is computed from those alone, so shards of runs
merge exactly by adding sums (:meth:`StatsSums.merge`), never by averaging averages.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import chdtri

from obsplan.core.errors import ConfigError
from obsplan.estimation.channel import LOST_FACTOR
from obsplan.estimation.columns import (
    COL_AXES,
    COL_NEES,
    COL_SE_VEL,
    COL_VAR_VEL,
    INFO_FINAL_POS,
    INFO_FINAL_STD,
    INFO_FINAL_VEL,
    INFO_FLAG_TIME,
    INFO_FLAGGED,
    INFO_LAST_ABOVE,
    INFO_NIS,
    INFO_NONFINITE,
    INFO_RANGES_REJECTED,
    INFO_RANGES_USED,
    INFO_REACQUIRED,
    INFO_RMSE_LINES,
    INFO_RMSE_POS,
    N_TM,
    TM_ACCEL,
    TM_AREA_OUT,
    TM_CLOSEST,
    TM_DEPTH_OUT,
    TM_FARTHEST,
    TM_SAMPLES,
    TM_SAT,
    TM_SPEED_MAX,
    TM_TRACK_LAST,
    TM_TRACK_SS,
)
from obsplan.estimation.montecarlo.guidance import TruthLimits

#: Quantile of one run's NEES above which the monitor counts a record as inconsistent.
MONITOR_LEVEL = 0.999
#: Default monitor window as a fraction of the duration.
MONITOR_WINDOW_FRACTION = 0.1


def chi2_quantile(p: float, dof: float) -> float:
    """``p``-quantile of ``χ²(dof)``.

    Parameters
    ----------
    p : float
        Probability, in (0, 1).
    dof : float
        Degrees of freedom.

    Returns
    -------
    float
        The quantile.
    """
    return float(chdtri(dof, 1.0 - p))


def nees_bounds(runs: int, dof: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` interval of the run-averaged NEES of a consistent filter.

    Parameters
    ----------
    runs : int
        Number of runs ``M`` averaged.
    dof : int
        Dimension of the state the NEES is of (``2n`` for ``(p, p')``).
    level : float, optional
        Probability of the interval.

    Returns
    -------
    lo, hi : float
        The bounds; NaN for no runs.
    """
    if runs < 1:
        return (float("nan"), float("nan"))
    a = 0.5 * (1.0 - level)
    k = runs * dof
    return chi2_quantile(a, k) / runs, chi2_quantile(1.0 - a, k) / runs


def convergence_time(t: np.ndarray, err: np.ndarray, threshold: float) -> float | None:
    """First time after which ``err`` stays at or below ``threshold`` (None if it ends above).

    Parameters
    ----------
    t : ndarray, shape (Nr,)
        Recorded times [s].
    err : ndarray, shape (Nr,)
        An error at those times (e.g. the position RMSE [m]); NaN counts as above.
    threshold : float
        Convergence threshold, in the unit of ``err``.

    Returns
    -------
    float or None
        The time [s] (``t[0]`` if never above), or None if the last value is above.
    """
    above = np.flatnonzero(~(err <= threshold))
    if above.size == 0:
        return float(t[0])
    last = int(above[-1])
    return None if last == t.size - 1 else float(t[last + 1])


def empty_metrics(runs: int) -> np.ndarray:
    """The kernels' truth metrics (runs, N_TM) before any sample.

    Parameters
    ----------
    runs : int
        Number of runs (or paths).

    Returns
    -------
    ndarray, shape (runs, N_TM)
        Zeros, the closest range ``inf`` (layout: :mod:`obsplan.estimation.columns`).
    """
    tm = np.zeros((runs, N_TM))
    tm[:, TM_CLOSEST] = np.inf
    return tm


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _rms(x: np.ndarray) -> float | None:
    """RMS over runs of per-run RMS values (None when undefined)."""
    x = np.asarray(x, float)
    return _num(float(np.sqrt(np.mean(x**2)))) if x.size and np.all(np.isfinite(x)) else None


@dataclass(frozen=True, eq=False)
class StatsSums:
    """Sufficient statistics of one filter over a set of runs.

    Attributes
    ----------
    sums : ndarray, shape (2, Nr, 3 + 2n)
        Per record, summed over the runs of group 0 (unflagged) and 1 (flagged): NEES,
        ``|p̂' - p'|²``, ``tr P_vv``, then ``(p̂_i - p_i)²`` and ``P_pp,ii`` per axis.
    info : ndarray, shape (runs, N_INFO)
        Per run (in run order): final ``|p̂ - p|``, final ``|p̂' - p'|``, final
        ``sqrt(tr P_pp)``, index of the last record above the convergence threshold (-1: none),
        non-finite (0/1), flagged (0/1), flag time [s] (NaN), mean normalised innovation squared,
        position RMSE over the records, and over the records of a given subset (NaN: none).
    """

    sums: np.ndarray
    info: np.ndarray

    @property
    def dim(self) -> int:
        return (self.sums.shape[2] - COL_AXES) // 2

    @staticmethod
    def merge(parts: Sequence[StatsSums]) -> StatsSums:
        """The statistics of the union of disjoint sets of runs (parts in run order).

        Parameters
        ----------
        parts : sequence of StatsSums
            Statistics recorded on the same grid.

        Returns
        -------
        StatsSums
            The sums added, the per-run rows concatenated.

        Raises
        ------
        ConfigError
            If the parts were recorded on different grids.
        """
        shapes = {p.sums.shape for p in parts}
        if len(shapes) != 1:
            raise ConfigError(f"cannot merge statistics recorded on different grids: {shapes}")
        return StatsSums(
            sums=np.sum([p.sums for p in parts], axis=0),
            info=np.concatenate([p.info for p in parts], axis=0),
        )


@dataclass(frozen=True, eq=False)
class GroupStats:
    """Statistics over a group of runs (those the monitor did, or did not, flag).

    Attributes
    ----------
    runs : int
    rmse_pos, final_pos_err, final_pos_std, nees_mean, nees_inside_fraction : float
        As in :class:`FilterStats`, over this group (NaN when it is empty).
    nees_bounds : (float, float)
        95 % interval of the run-averaged NEES for ``runs`` runs.
    converged_fraction : float
    convergence_time : float or None
        First time [s] after which this group's RMSE stays below the threshold.
    rmse_pos_t, pos_std_t, nees_t : ndarray, shape (Nr,)
    """

    runs: int
    rmse_pos: float
    final_pos_err: float
    final_pos_std: float
    nees_mean: float
    nees_bounds: tuple[float, float]
    nees_inside_fraction: float
    converged_fraction: float
    convergence_time: float | None
    rmse_pos_t: np.ndarray
    pos_std_t: np.ndarray
    nees_t: np.ndarray

    def to_dict(self) -> dict:
        """The group's summary (for JSON outputs; no arrays).

        Returns
        -------
        dict
            ``runs`` and the scalar statistics (None where not finite).
        """
        return {
            "runs": int(self.runs),
            "rmse_pos": _num(self.rmse_pos),
            "final_pos_err": _num(self.final_pos_err),
            "final_pos_std": _num(self.final_pos_std),
            "nees_mean": _num(self.nees_mean),
            "nees_bounds": [_num(b) for b in self.nees_bounds],
            "nees_inside_fraction": _num(self.nees_inside_fraction),
            "converged_fraction": _num(self.converged_fraction),
            "convergence_time": self.convergence_time,
        }


def _group(
    sums: np.ndarray, info: np.ndarray, dof: int, t: np.ndarray, threshold: float
) -> GroupStats:
    R = info.shape[0]
    n = dof // 2
    Nr = sums.shape[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        se_pos = sums[:, COL_AXES : COL_AXES + n].sum(axis=1) / R
        var_pos = sums[:, COL_AXES + n :].sum(axis=1) / R
        nees_t = sums[:, COL_NEES] / R
        bounds = nees_bounds(R, dof)
        inside = (nees_t >= bounds[0]) & (nees_t <= bounds[1])
        rmse_pos_t = np.sqrt(se_pos)
    empty = R == 0
    return GroupStats(
        runs=R,
        rmse_pos=float("nan") if empty else float(np.mean(rmse_pos_t)),
        final_pos_err=float("nan") if empty else float(np.mean(info[:, INFO_FINAL_POS])),
        final_pos_std=float("nan") if empty else float(np.mean(info[:, INFO_FINAL_STD])),
        nees_mean=float("nan") if empty else float(np.mean(nees_t)),
        nees_bounds=bounds,
        nees_inside_fraction=float("nan") if empty else float(np.mean(inside)),
        converged_fraction=(
            float("nan") if empty else float(np.mean(info[:, INFO_LAST_ABOVE] < Nr - 1))
        ),
        convergence_time=None if empty else convergence_time(t, rmse_pos_t, threshold),
        rmse_pos_t=rmse_pos_t,
        pos_std_t=np.sqrt(var_pos),
        nees_t=nees_t,
    )


@dataclass(frozen=True, eq=False)
class FilterStats:
    """Monte Carlo statistics of one filter (metres, m/s, seconds).

    Attributes
    ----------
    rmse_pos : float
        Time average of ``rmse_pos_t`` [m].
    final_pos_err, final_pos_std : float
        Mean over runs, at the last sample, of ``|p̂ - p|`` and ``sqrt(tr P_pp)`` [m].
    nees_mean : float
        Time average of the run-averaged NEES of ``(p, p')`` (dof ``2n``).
    convergence_time : float or None
        First time [s] after which ``rmse_pos_t`` stays below the threshold; None if never.
    converged_fraction : float
        Fraction of runs whose own error stays below the threshold from some time on.
    nees_bounds : (float, float)
        95 % interval of the run-averaged NEES at one time.
    nees_inside_fraction : float
        Fraction of samples whose run-averaged NEES is inside ``nees_bounds``.
    diverged_runs : int
        Runs whose estimate became non-finite.
    rmse_pos_t, rmse_vel_t, pos_std_t, vel_std_t, nees_t : ndarray, shape (Nr,)
        RMS over runs of the position / velocity error, ``sqrt(mean tr P)`` of position / velocity,
        run-averaged NEES, at the recorded times.
    rmse_pos_axes_t, pos_std_axes_t : ndarray, shape (Nr, n)
        The same per axis.
    final_pos_err_runs : ndarray, shape (runs,)
        ``|p̂ - p|`` of each run at the last sample [m].
    rmse_pos_runs : ndarray, shape (runs,)
        Each run's position RMSE over the recorded samples, ``sqrt(mean_t |p̂ - p|²)`` [m].
    rmse_pos_lines_runs : ndarray, shape (runs,)
        The same over the recorded samples of the subset given to the Monte Carlo (``lines``,
        e.g. the samples flown on survey lines); NaN without one.
    flagged_runs : int
        Runs the divergence monitor flagged (module docstring; includes the non-finite ones).
    run_flagged : ndarray of bool, shape (runs,)
    run_flag_time : ndarray, shape (runs,)
        Time [s] at which the monitor flagged each run (NaN if it did not).
    nis_mean : float
        Mean over runs and updates of the normalised innovation squared (1 if consistent).
    unflagged, flagged : GroupStats
        The statistics over the runs the monitor did not flag, and over those it flagged.
    ranges_used_runs, ranges_rejected_runs, reacquired_runs : ndarray, shape (runs,)
        Each run's ranges the filter used, those its innovation gate rejected, and its
        re-acquisitions (:mod:`obsplan.estimation.channel`).
    sums : StatsSums
        The sufficient statistics everything above is computed from (for exact merging).
    """

    rmse_pos: float
    final_pos_err: float
    final_pos_std: float
    nees_mean: float
    convergence_time: float | None
    converged_fraction: float
    threshold_m: float
    nees_bounds: tuple[float, float]
    nees_inside_fraction: float
    diverged_runs: int
    final_vel_err: float
    rmse_pos_t: np.ndarray
    rmse_vel_t: np.ndarray
    pos_std_t: np.ndarray
    vel_std_t: np.ndarray
    nees_t: np.ndarray
    rmse_pos_axes_t: np.ndarray
    pos_std_axes_t: np.ndarray
    final_pos_err_runs: np.ndarray
    rmse_pos_runs: np.ndarray
    rmse_pos_lines_runs: np.ndarray
    flagged_runs: int
    run_flagged: np.ndarray
    run_flag_time: np.ndarray
    nis_mean: float
    unflagged: GroupStats
    flagged: GroupStats
    ranges_used_runs: np.ndarray
    ranges_rejected_runs: np.ndarray
    reacquired_runs: np.ndarray
    sums: StatsSums

    def lost_runs(self, bound: float) -> int:
        """Runs whose final position error exceeds
        :data:`~obsplan.estimation.channel.LOST_FACTOR` times ``bound`` (or is not finite).

        Parameters
        ----------
        bound : float
            The final position bound [m] (the posterior CRB's std of the path).

        Returns
        -------
        int
            The number of lost runs.
        """
        err = self.final_pos_err_runs
        return int(np.sum(~(err <= LOST_FACTOR * float(bound))))

    @classmethod
    def from_sums(cls, s: StatsSums, t: np.ndarray, threshold: float) -> FilterStats:
        """Statistics over all runs of ``s`` recorded at times ``t``.

        Parameters
        ----------
        s : StatsSums
            The sufficient statistics.
        t : ndarray, shape (Nr,)
            Recorded times [s].
        threshold : float
            Convergence threshold on the position error [m].

        Returns
        -------
        FilterStats
            The statistics over all runs and per monitor group.
        """
        n = s.dim
        info = s.info
        R = info.shape[0]
        total = s.sums[0] + s.sums[1]
        flag = info[:, INFO_FLAGGED] > 0
        se_axes = total[:, COL_AXES : COL_AXES + n] / R
        var_axes = total[:, COL_AXES + n :] / R
        rmse_pos_t = np.sqrt(se_axes.sum(axis=1))
        nees_t = total[:, COL_NEES] / R
        bounds = nees_bounds(R, 2 * n)
        inside = (nees_t >= bounds[0]) & (nees_t <= bounds[1])
        return cls(
            rmse_pos=float(np.mean(rmse_pos_t)),
            final_pos_err=float(np.mean(info[:, INFO_FINAL_POS])),
            final_pos_std=float(np.mean(info[:, INFO_FINAL_STD])),
            nees_mean=float(np.mean(nees_t)),
            convergence_time=convergence_time(t, rmse_pos_t, threshold),
            converged_fraction=float(np.mean(info[:, INFO_LAST_ABOVE] < t.size - 1)),
            threshold_m=float(threshold),
            nees_bounds=bounds,
            nees_inside_fraction=float(np.mean(inside)),
            diverged_runs=int(np.sum(info[:, INFO_NONFINITE] > 0)),
            final_vel_err=float(np.mean(info[:, INFO_FINAL_VEL])),
            rmse_pos_t=rmse_pos_t,
            rmse_vel_t=np.sqrt(total[:, COL_SE_VEL] / R),
            pos_std_t=np.sqrt(var_axes.sum(axis=1)),
            vel_std_t=np.sqrt(total[:, COL_VAR_VEL] / R),
            nees_t=nees_t,
            rmse_pos_axes_t=np.sqrt(se_axes),
            pos_std_axes_t=np.sqrt(var_axes),
            final_pos_err_runs=info[:, INFO_FINAL_POS].copy(),
            rmse_pos_runs=info[:, INFO_RMSE_POS].copy(),
            rmse_pos_lines_runs=info[:, INFO_RMSE_LINES].copy(),
            flagged_runs=int(flag.sum()),
            run_flagged=flag,
            run_flag_time=info[:, INFO_FLAG_TIME].copy(),
            nis_mean=float(np.nanmean(info[:, INFO_NIS])) if R else float("nan"),
            unflagged=_group(s.sums[0], info[~flag], 2 * n, t, threshold),
            flagged=_group(s.sums[1], info[flag], 2 * n, t, threshold),
            ranges_used_runs=info[:, INFO_RANGES_USED].copy(),
            ranges_rejected_runs=info[:, INFO_RANGES_REJECTED].copy(),
            reacquired_runs=info[:, INFO_REACQUIRED].copy(),
            sums=s,
        )

    def to_dict(self) -> dict:
        """The stable keys of ``obsplan simulate --json`` first, then the extras (no arrays).

        Returns
        -------
        dict
            Scalar statistics (None where not finite) and the ``unflagged`` and ``flagged``
            groups (:meth:`GroupStats.to_dict`); ``ranges_used``, ``ranges_rejected`` and
            ``reacquisitions`` are means per run.
        """
        return {
            "final_pos_err": _num(self.final_pos_err),
            "rmse_pos": _num(self.rmse_pos),
            "final_pos_std": _num(self.final_pos_std),
            "nees_mean": _num(self.nees_mean),
            "convergence_time": self.convergence_time,
            "converged_fraction": _num(self.converged_fraction),
            "threshold_m": float(self.threshold_m),
            "nees_bounds": [float(b) for b in self.nees_bounds],
            "nees_inside_fraction": _num(self.nees_inside_fraction),
            "final_pos_err_median": _num(float(np.median(self.final_pos_err_runs))),
            "final_vel_err": _num(self.final_vel_err),
            "diverged_runs": int(self.diverged_runs),
            "flagged_runs": int(self.flagged_runs),
            "nis_mean": _num(self.nis_mean),
            "rmse_pos_lines": _rms(self.rmse_pos_lines_runs),
            "unflagged": self.unflagged.to_dict(),
            "flagged": self.flagged.to_dict(),
            "ranges_used": _num(_mean(self.ranges_used_runs)),
            "ranges_rejected": _num(_mean(self.ranges_rejected_runs)),
            "reacquisitions": _num(_mean(self.reacquired_runs)),
        }


def _mean(x: np.ndarray) -> float:
    return float(np.mean(x)) if x.size else float("nan")


@dataclass(frozen=True, eq=False)
class TruthStats:
    """The runs' *true* paths against their reference (the plan) and the vehicle's limits.

    Per-run arrays (shape (runs,), in run order) merge exactly by concatenation
    (:meth:`merge`); the summaries are computed from them.

    Attributes
    ----------
    closest_range_runs : ndarray
        ``min_t |p - b|`` [m] over the filter samples, each step refined to the chord between
        its samples: the constant-acceleration arc of a step of ``h`` deviates from its chord by
        at most ``|u| h²/8`` (6e-5 m at 0.05 m/s² and 0.1 s), so the sampling cannot hide an
        entry deeper than that.
    farthest_range_runs : ndarray
        ``max_t |p - b|`` [m].
    tracking_rmse_runs : ndarray
        ``sqrt(mean_t |p - p_ref|²)`` over the samples [m]: how far the vehicle flies from the
        path it was told to fly (open loop: the process-noise drift).
    final_drift_runs : ndarray
        ``|p - p_ref|`` at the last sample [m].
    max_speed_runs : ndarray
        ``max_t |p'|`` [m/s].
    area_excursion_runs, depth_excursion_runs : ndarray
        Largest distance outside the area box and the depth band [m] (0: inside or no bound).
    saturated_fraction_runs : ndarray
        Fraction of the steps at which the guidance saturated its command (0 in open loop).
    accel_ratio_runs : ndarray
        ``max_t max_i |u_i| / accel_i`` of the applied inputs (0 without an acceleration limit).
    limits : TruthLimits or None
        What the paths were checked against.
    """

    closest_range_runs: np.ndarray
    farthest_range_runs: np.ndarray
    tracking_rmse_runs: np.ndarray
    final_drift_runs: np.ndarray
    max_speed_runs: np.ndarray
    area_excursion_runs: np.ndarray
    depth_excursion_runs: np.ndarray
    saturated_fraction_runs: np.ndarray
    accel_ratio_runs: np.ndarray
    limits: TruthLimits | None = None

    @classmethod
    def from_metrics(cls, tm: np.ndarray, limits: TruthLimits | None) -> TruthStats:
        """From the kernels' per-run metrics ``tm`` (runs, N_TM).

        Parameters
        ----------
        tm : ndarray, shape (runs, N_TM)
            The metrics (layout: :mod:`obsplan.estimation.columns`).
        limits : TruthLimits or None
            The limits the paths are judged against.

        Returns
        -------
        TruthStats
            The per-run arrays.
        """
        steps = np.maximum(tm[:, TM_SAMPLES] - 1.0, 1.0)
        return cls(
            closest_range_runs=np.sqrt(tm[:, TM_CLOSEST]),
            farthest_range_runs=np.sqrt(tm[:, TM_FARTHEST]),
            tracking_rmse_runs=np.sqrt(tm[:, TM_TRACK_SS] / np.maximum(tm[:, TM_SAMPLES], 1.0)),
            final_drift_runs=np.sqrt(tm[:, TM_TRACK_LAST]),
            max_speed_runs=np.sqrt(tm[:, TM_SPEED_MAX]),
            area_excursion_runs=tm[:, TM_AREA_OUT].copy(),
            depth_excursion_runs=tm[:, TM_DEPTH_OUT].copy(),
            saturated_fraction_runs=tm[:, TM_SAT] / steps,
            accel_ratio_runs=tm[:, TM_ACCEL].copy(),
            limits=limits,
        )

    @staticmethod
    def merge(parts: Sequence[TruthStats]) -> TruthStats:
        """The union of disjoint sets of runs (parts in run order).

        Parameters
        ----------
        parts : sequence of TruthStats
            The parts, with the same limits.

        Returns
        -------
        TruthStats
            The per-run arrays concatenated.
        """
        names = [f for f in TruthStats.__dataclass_fields__ if f.endswith("_runs")]
        cat = {f: np.concatenate([getattr(p, f) for p in parts]) for f in names}
        return TruthStats(**cat, limits=parts[0].limits)

    @property
    def runs(self) -> int:
        return int(self.closest_range_runs.size)

    @property
    def closest_range_m(self) -> float:
        """The true closest range over all runs [m]."""
        return float(np.min(self.closest_range_runs))

    @property
    def tracking_rmse_m(self) -> float:
        """RMS over runs and samples of ``|p - p_ref|`` [m]."""
        return float(np.sqrt(np.mean(self.tracking_rmse_runs**2)))

    @property
    def final_drift_rms_m(self) -> float:
        """RMS over runs of the final ``|p - p_ref|`` [m]."""
        return float(np.sqrt(np.mean(self.final_drift_runs**2)))

    @property
    def runs_inside_min_range(self) -> int:
        """Runs whose true path enters the keep-out radius ``limits.min_range`` (0 without)."""
        return int(np.sum(self.violations().get("min_range", np.zeros(self.runs, bool))))

    def violations(self) -> dict[str, np.ndarray]:
        """Per limit that is set, which runs break it on their true path, (runs,) bool.

        Returns
        -------
        dict of str to ndarray of bool, shape (runs,)
            Keys among ``accel``, ``speed``, ``area``, ``depth``, ``min_range``,
            ``max_range``; empty without limits.
        """
        lim = self.limits
        out: dict[str, np.ndarray] = {}
        if lim is None:
            return out
        r = 1.0 + lim.rtol
        if lim.accel is not None:
            out["accel"] = self.accel_ratio_runs > r
        if lim.speed is not None:
            out["speed"] = self.max_speed_runs > lim.speed * r
        if lim.area is not None:
            out["area"] = self.area_excursion_runs > lim.atol_m
        if lim.depth is not None:
            out["depth"] = self.depth_excursion_runs > lim.atol_m
        if lim.min_range is not None:
            out["min_range"] = self.closest_range_runs < lim.min_range * (1.0 - lim.rtol)
        if lim.max_range is not None:
            out["max_range"] = self.farthest_range_runs > lim.max_range * r
        return out

    def excess_runs(self) -> dict[str, np.ndarray]:
        """Per limit that is set, by how much each run's true path goes past it, (runs,), 0
        where it stays within: the acceleration as a fraction of its bound (``max_i |u_i| /
        accel_i - 1``), the speed [m/s], the area box and the depth band [m, the excursions],
        ``min_range`` and ``max_range`` [m, radial]. The same comparisons as
        :meth:`violations`: a run breaks a limit exactly where its excess is positive (at
        ``rtol = atol_m = 0``).

        Returns
        -------
        dict of str to ndarray, shape (runs,)
            The excess per limit, >= 0; empty without limits.
        """
        lim = self.limits
        out: dict[str, np.ndarray] = {}
        if lim is None:
            return out
        if lim.accel is not None:
            out["accel"] = self.accel_ratio_runs - 1.0
        if lim.speed is not None:
            out["speed"] = self.max_speed_runs - lim.speed
        if lim.area is not None:
            out["area"] = self.area_excursion_runs.copy()
        if lim.depth is not None:
            out["depth"] = self.depth_excursion_runs.copy()
        if lim.min_range is not None:
            out["min_range"] = lim.min_range - self.closest_range_runs
        if lim.max_range is not None:
            out["max_range"] = self.farthest_range_runs - lim.max_range
        return {k: np.maximum(v, 0.0) for k, v in out.items()}

    @property
    def worst_excess(self) -> dict[str, float]:
        """Per limit, the largest excess over the runs (:meth:`excess_runs`; 0: never broken)."""
        return {k: float(np.max(v, initial=0.0)) for k, v in self.excess_runs().items()}

    @property
    def violation_fraction(self) -> dict[str, float]:
        """Per limit, the fraction of runs that break it."""
        return {k: float(np.mean(v)) for k, v in self.violations().items()}

    def breaks_words(self) -> str:
        """``"speed in 100.0 % (by up to 0.00087 m/s), depth in 8.0 % (by up to 1.2 m)"``: every
        limit some run's true path breaks, the fraction of runs and the worst excess ("" if
        none).

        Returns
        -------
        str
            The limits broken, comma-separated.
        """
        worst = self.worst_excess
        words = []
        for name, frac in self.violation_fraction.items():
            if frac <= 0:
                continue
            x = worst.get(name, 0.0)
            if name == "accel":  # a ratio to the bound; the others in their own units
                by = f"{100 * x:.2g} % of the bound"
            else:
                by = f"{x:.2g} {'m/s' if name == 'speed' else 'm'}"
            words.append(f"{name} in {100 * frac:.1f} % (by up to {by})")
        return ", ".join(words)

    @property
    def any_violation_runs(self) -> int:
        """Runs that break any limit on their true path."""
        v = self.violations()
        if not v:
            return 0
        return int(np.sum(np.any(np.stack(list(v.values())), axis=0)))

    @property
    def any_violation_fraction(self) -> float:
        """Fraction of runs that break any limit on their true path."""
        return self.any_violation_runs / self.runs if self.runs else 0.0

    def to_dict(self) -> dict:
        """The summary of the true paths (for JSON outputs; no per-run arrays).

        Returns
        -------
        dict
            Closest range [m], tracking RMSE and final drift [m], largest speed [m/s],
            saturated fraction, the violations and excesses per limit, and the limits.
        """
        return {
            "runs": self.runs,
            "closest_range_m": _num(self.closest_range_m),
            "runs_inside_min_range": self.runs_inside_min_range,
            "tracking_rmse_m": _num(self.tracking_rmse_m),
            "final_drift_rms_m": _num(self.final_drift_rms_m),
            "max_speed": _num(float(np.max(self.max_speed_runs))),
            "saturated_fraction": _num(float(np.mean(self.saturated_fraction_runs))),
            "violation_fraction": self.violation_fraction,
            "worst_excess": {k: _num(v) for k, v in self.worst_excess.items()},
            "any_violation_fraction": self.any_violation_fraction,
            "limits": None if self.limits is None else self.limits.to_dict(),
        }


def filter_stats(result: Any) -> dict[str, FilterStats]:
    """Every filter's statistics of a Monte Carlo result, by name.

    Parameters
    ----------
    result
        A :class:`~obsplan.estimation.montecarlo.results.MonteCarloResult` (anything with its
        ``filters``, ``ekf`` and ``kf``).

    Returns
    -------
    dict[str, FilterStats]
        ``ekf``, ``kf`` and any other filter that was run, in the order they were run.
    """
    stats = dict(getattr(result, "filters", None) or {})
    for name in ("ekf", "kf"):
        if name not in stats and getattr(result, name, None) is not None:
            stats[name] = getattr(result, name)
    return stats
