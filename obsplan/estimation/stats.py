"""Statistics over Monte Carlo runs: RMSE, standard deviations, NEES with χ² bounds, convergence.

Everything is on the navigation state ``(p, p')`` (position and inertial velocity, dof ``2n``),
the same for both filters. Over ``M`` runs the average NEES at one time, times ``M``, is
``χ²(M·2n)`` for a consistent filter, which gives the 95 % interval of :func:`nees_bounds`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2


def nees_bounds(runs: int, dof: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` interval of the run-averaged NEES of a consistent filter."""
    a = 0.5 * (1.0 - level)
    k = runs * dof
    return float(chi2.ppf(a, k) / runs), float(chi2.ppf(1.0 - a, k) / runs)


def convergence_time(t: np.ndarray, err: np.ndarray, threshold: float) -> float | None:
    """First time after which ``err`` stays at or below ``threshold`` (None if it ends above)."""
    above = np.flatnonzero(~(err <= threshold))
    if above.size == 0:
        return float(t[0])
    last = int(above[-1])
    return None if last == t.size - 1 else float(t[last + 1])


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


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
    rmse_pos_t, rmse_vel_t, pos_std_t, vel_std_t, nees_t : ndarray, shape (N,)
        RMS over runs of the position / velocity error, ``sqrt(mean tr P)`` of position / velocity,
        run-averaged NEES.
    rmse_pos_axes_t, pos_std_axes_t : ndarray, shape (N, n)
        The same per axis.
    final_pos_err_runs : ndarray, shape (runs,)
        ``|p̂ - p|`` of each run at the last sample [m].
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

    def to_dict(self) -> dict:
        """The stable keys of ``obsplan simulate --json`` first, then the extras (no arrays)."""
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
        }


class StatsAccumulator:
    """Accumulates per-sample statistics over the runs without storing every run's history."""

    def __init__(self, n_samples: int, runs: int, dim: int, threshold: float) -> None:
        N, n = n_samples, dim
        self.n, self.R, self.thr = n, runs, threshold
        self.se_pos = np.zeros(N)
        self.se_vel = np.zeros(N)
        self.var_pos = np.zeros(N)
        self.var_vel = np.zeros(N)
        self.nees = np.zeros(N)
        self.se_pos_axes = np.zeros((N, n))
        self.var_pos_axes = np.zeros((N, n))
        self.last_above = np.full(runs, -1)
        self.final_pos_err = np.zeros(runs)
        self.final_vel_err = np.zeros(runs)
        self.final_pos_std = np.zeros(runs)
        self.nonfinite = np.zeros(runs, dtype=bool)

    def record(self, k: int, err: np.ndarray, cov: np.ndarray) -> None:
        """Errors ``(p̂ - p, p̂' - p')`` (R, 2n) and covariances (R, 2n, 2n) at sample ``k``."""
        n, R = self.n, self.R
        ep, ev = err[:, :n], err[:, n:]
        d2 = ep * ep
        pos2 = d2.sum(axis=1)
        dP = np.diagonal(cov, axis1=1, axis2=2)
        dPp = dP[:, :n]
        self.se_pos[k] = pos2.sum() / R
        self.se_vel[k] = np.einsum("ri,ri->", ev, ev) / R
        self.se_pos_axes[k] = d2.sum(axis=0) / R
        self.var_pos_axes[k] = dPp.sum(axis=0) / R
        self.var_pos[k] = self.var_pos_axes[k].sum()
        self.var_vel[k] = dP[:, n:].sum() / R
        try:
            sol = np.linalg.solve(cov, err[:, :, None])[:, :, 0]
            self.nees[k] = np.einsum("ri,ri->", err, sol) / R
        except np.linalg.LinAlgError:
            self.nees[k] = np.nan
        self.nonfinite |= ~np.isfinite(pos2)
        pos = np.sqrt(pos2)
        self.last_above[~(pos <= self.thr)] = k
        self.final_pos_err = pos
        self.final_vel_err = np.sqrt((ev * ev).sum(axis=1))
        self.final_pos_std = np.sqrt(dPp.sum(axis=1))

    def finish(self, t: np.ndarray, bounds: tuple[float, float]) -> FilterStats:
        """Freeze into :class:`FilterStats` (``t``: sample times, ``bounds``: NEES interval)."""
        N = t.size
        rmse_pos_t = np.sqrt(self.se_pos)
        nees_t = self.nees
        inside = (nees_t >= bounds[0]) & (nees_t <= bounds[1])
        return FilterStats(
            rmse_pos=float(np.mean(rmse_pos_t)),
            final_pos_err=float(np.mean(self.final_pos_err)),
            final_pos_std=float(np.mean(self.final_pos_std)),
            nees_mean=float(np.mean(nees_t)),
            convergence_time=convergence_time(t, rmse_pos_t, self.thr),
            converged_fraction=float(np.mean(self.last_above < N - 1)),  # never above at the end
            threshold_m=float(self.thr),
            nees_bounds=bounds,
            nees_inside_fraction=float(np.mean(inside)),
            diverged_runs=int(self.nonfinite.sum()),
            final_vel_err=float(np.mean(self.final_vel_err)),
            rmse_pos_t=rmse_pos_t,
            rmse_vel_t=np.sqrt(self.se_vel),
            pos_std_t=np.sqrt(self.var_pos),
            vel_std_t=np.sqrt(self.var_vel),
            nees_t=nees_t,
            rmse_pos_axes_t=np.sqrt(self.se_pos_axes),
            pos_std_axes_t=np.sqrt(self.var_pos_axes),
            final_pos_err_runs=self.final_pos_err.copy(),
        )
