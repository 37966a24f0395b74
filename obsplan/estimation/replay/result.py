"""The result of a replayed log: filtered and smoothed track, ranges used and rejected.

:class:`ReplayResult` carries what ``obsplan estimate`` prints (:meth:`ReplayResult.summary`),
its ``estimate.json`` (:meth:`ReplayResult.to_dict`), its ``track.csv`` and ``ranges.csv``
(:meth:`ReplayResult.track_table`, :meth:`ReplayResult.range_table`) and its figures
(:meth:`ReplayResult.plot`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from obsplan.core.errors import ConfigError
from obsplan.estimation.channel import SOUND_SPEED

#: The figures of :meth:`ReplayResult.plot`, by kind.
PLOT_KINDS = ("track", "ranges")


@dataclass(frozen=True, eq=False, repr=False)
class ReplayResult:
    """Result of :func:`~obsplan.estimation.replay.smoother.replay` (picklable).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Row times [s].
    state_names : tuple of str
        Names of the ``m`` states (``px, py, vx, vy[, vfx, vfy][, range_scale][, range_bias]``:
        the range's calibration states last, when the replay estimated them).
    dim : int
        Spatial dimension ``n``.
    sensors : tuple of str
        The sensors the log read.
    x_filt, x_smooth : ndarray, shape (N, m)
        Filtered and smoothed means [m, m/s].
    P_filt, P_smooth : ndarray, shape (N, m, m)
        Their covariances.
    range_rows : ndarray of int, shape (R,)
        The rows with a range.
    ranges : ndarray, shape (R,)
        The ranges [m].
    beacons : ndarray, shape (R, n)
        The beacon at each range [m].
    residual : ndarray, shape (R,)
        Range minus the filter's predicted range, before the update [m].
    residual_smoothed : ndarray, shape (R,)
        Range minus the smoothed range [m].
    nis : ndarray, shape (R,)
        Normalised innovation squared of each range (before any re-acquisition).
    used : ndarray of bool, shape (R,)
        Whether the gate let the range in.
    inflation : ndarray, shape (R,)
        Factor by which a re-acquisition widened ``hᵀ P h`` of that range (1: none).
    gate_probability, gate_nis : float
        The gate's confidence and its NIS threshold.
    truth : ndarray, shape (N, n) or None
        True positions [m], when the log has them.
    source : str
        The log's name.
    """

    t: np.ndarray
    state_names: tuple[str, ...]
    dim: int
    sensors: tuple[str, ...]
    x_filt: np.ndarray
    P_filt: np.ndarray
    x_smooth: np.ndarray
    P_smooth: np.ndarray
    range_rows: np.ndarray
    ranges: np.ndarray
    beacons: np.ndarray
    residual: np.ndarray
    residual_smoothed: np.ndarray
    nis: np.ndarray
    used: np.ndarray
    inflation: np.ndarray
    gate_probability: float
    gate_nis: float
    truth: np.ndarray | None
    source: str = "log"

    # ------------------------------------------------------------------ counts
    @property
    def ranges_used(self) -> int:
        """Number of ranges the gate let in."""
        return int(np.count_nonzero(self.used))

    @property
    def ranges_rejected(self) -> int:
        """Number of ranges the gate rejected."""
        return int(self.used.size - np.count_nonzero(self.used))

    @property
    def reacquisitions(self) -> int:
        """Number of re-acquisitions (covariance inflations after a run of rejections)."""
        return int(np.count_nonzero(self.inflation > 1.0))

    # ------------------------------------------------------------------ statistics
    @property
    def calibration(self) -> dict[str, dict[str, float]]:
        """The range's calibration states the replay estimated (constant: the smoothed values):
        ``{"range_scale": {"estimate", "std"}, "range_bias_m": {...}}``, each only when
        estimated; empty otherwise.

        Returns
        -------
        dict of str to dict of str to float
            The scale (dimensionless) and the bias [m], with their standard deviations.
        """
        out = {}
        for state, key in (("range_scale", "range_scale"), ("range_bias", "range_bias_m")):
            if state in self.state_names:
                i = self.state_names.index(state)
                est, var = self.x_smooth[-1, i], self.P_smooth[-1, i, i]
                out[key] = {"estimate": float(est), "std": float(np.sqrt(max(var, 0.0)))}
        return out

    def std(self, which: str = "smoothed") -> np.ndarray:
        """Standard deviation of every state at every row.

        Parameters
        ----------
        which : {"smoothed", "filtered"}, optional
            The covariances read.

        Returns
        -------
        ndarray, shape (N, m)
            ``sqrt(diag P)`` [m, m/s].
        """
        P = self._pick(which)[1]
        return np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0.0, None))

    def _pick(self, which: str) -> tuple[np.ndarray, np.ndarray]:
        if which == "smoothed":
            return self.x_smooth, self.P_smooth
        if which == "filtered":
            return self.x_filt, self.P_filt
        raise ConfigError(f"which must be 'smoothed' or 'filtered', got {which!r}")

    def position_errors(self, which: str = "smoothed") -> np.ndarray | None:
        """Estimated minus true position per row, shape ``(N, n)`` [m]; None without truth.

        Parameters
        ----------
        which : {"smoothed", "filtered"}, optional
            The estimate.

        Returns
        -------
        ndarray, shape (N, n) or None
            The errors [m].
        """
        if self.truth is None:
            return None
        return self._pick(which)[0][:, : self.dim] - self.truth

    def rmse(self, which: str = "smoothed") -> float | None:
        """Root-mean-square position error over the rows [m]; None without truth.

        Parameters
        ----------
        which : {"smoothed", "filtered"}, optional
            The estimate.

        Returns
        -------
        float or None
            ``sqrt(mean |p̂ - p|²)`` [m].
        """
        e = self.position_errors(which)
        return None if e is None else float(np.sqrt(np.mean(np.sum(e * e, axis=1))))

    def within_3sigma(self, which: str = "smoothed") -> float | None:
        """Fraction of (row, axis) position errors within three standard deviations.

        Parameters
        ----------
        which : {"smoothed", "filtered"}, optional
            The estimate.

        Returns
        -------
        float or None
            The fraction in [0, 1]; None without truth.
        """
        e = self.position_errors(which)
        if e is None:
            return None
        return float(np.mean(np.abs(e) <= 3.0 * self.std(which)[:, : self.dim]))

    # ------------------------------------------------------------------ outputs
    def to_dict(self) -> dict:
        """The ``estimate.json`` of ``obsplan estimate``.

        Returns
        -------
        dict
            ``rows``, ``dim``, ``sensors``, ``ranges`` (total, used, rejected,
            reacquisitions), ``gate`` (probability, nis), ``final_pos_std`` [m] (smoothed and
            filtered), with truth ``rmse_pos`` [m] (smoothed and filtered), and with the
            range's calibration states ``calibration`` (:attr:`calibration`).
        """
        n = self.dim
        out: dict = {
            "source": self.source,
            "rows": int(self.t.size),
            "dim": n,
            "sensors": list(self.sensors),
            "ranges": {
                "total": int(self.used.size),
                "used": self.ranges_used,
                "rejected": self.ranges_rejected,
                "reacquisitions": self.reacquisitions,
            },
            "gate": {"probability": self.gate_probability, "nis": _finite(self.gate_nis)},
            "final_pos_std": {
                w: float(np.sqrt(np.sum(self.std(w)[-1, :n] ** 2)))
                for w in ("smoothed", "filtered")
            },
        }
        if self.truth is not None:
            out["rmse_pos"] = {w: self.rmse(w) for w in ("smoothed", "filtered")}
        if self.calibration:
            out["calibration"] = self.calibration
        return out

    def summary(self) -> str:
        """A few lines for the terminal: counts, final standard deviations, RMSE with truth.

        Returns
        -------
        str
            The summary.
        """
        d = self.to_dict()
        r = d["ranges"]
        lines = [
            f"replay of {self.source}: {d['rows']} rows, {d['dim']}D, sensors "
            f"{', '.join(self.sensors)}",
            f"  ranges: {r['total']} ({r['used']} used, {r['rejected']} rejected by the NIS gate "
            f"at {self.gate_probability:g}; {r['reacquisitions']} re-acquisitions)",
            f"  final position std: smoothed {d['final_pos_std']['smoothed']:.3g} m, filtered "
            f"{d['final_pos_std']['filtered']:.3g} m",
        ]
        cal = d.get("calibration", {})
        if cal:
            said = []
            if "range_scale" in cal:
                k = cal["range_scale"]
                said.append(
                    f"scale {k['estimate']:.4f} ± {k['std']:.4f} (a sound speed "
                    f"{100 * (k['estimate'] - 1):+.2f} % off)"
                )
            if "range_bias_m" in cal:
                b = cal["range_bias_m"]
                said.append(
                    f"bias {b['estimate']:+.2f} ± {b['std']:.2f} m (a clock offset of "
                    f"{1e3 * b['estimate'] / SOUND_SPEED:+.2f} ms)"
                )
            lines.append("  ranges' " + ", ".join(said) + " (smoothed, 1σ)")
        if "rmse_pos" in d:
            e = d["rmse_pos"]
            lines.append(
                f"  position RMSE vs truth: smoothed {e['smoothed']:.3g} m, filtered "
                f"{e['filtered']:.3g} m"
            )
        return "\n".join(lines)

    def track_table(self) -> tuple[list[str], np.ndarray]:
        """The ``track.csv``: ``t``, the smoothed states and their std's, then the filtered.

        Returns
        -------
        header : list of str
            ``t, px, ..., px_std, ..., px_filt, ..., px_filt_std, ...``.
        rows : ndarray, shape (N, 1 + 4 m)
            Times [s], means and standard deviations [m, m/s].
        """
        names = list(self.state_names)
        header = ["t", *names, *(f"{s}_std" for s in names)]
        header += [f"{s}_filt" for s in names] + [f"{s}_filt_std" for s in names]
        cols = [self.t[:, None], self.x_smooth, self.std("smoothed"), self.x_filt]
        return header, np.hstack([*cols, self.std("filtered")])

    def range_table(self) -> tuple[list[str], np.ndarray]:
        """The ``ranges.csv``: one row per range.

        Returns
        -------
        header : list of str
            ``t, range, residual, residual_smoothed, nis, used``.
        rows : ndarray, shape (R, 6)
            Times [s], ranges and residuals [m], NIS, used (1) or rejected (0).
        """
        header = ["t", "range", "residual", "residual_smoothed", "nis", "used"]
        rows = np.column_stack(
            [
                self.t[self.range_rows],
                self.ranges,
                self.residual,
                self.residual_smoothed,
                self.nis,
                self.used.astype(float),
            ]
        )
        return header, rows

    def plot(self, kind: str = "track") -> Figure:
        """A figure of the replay.

        Parameters
        ----------
        kind : {"track", "ranges"}, optional
            ``"track"``: the plan view (filtered, smoothed, truth, beacon) and each position
            axis against time, smoothed with its 3σ band (errors against truth when the log has
            it); ``"ranges"``: the range residuals, rejected ones marked, and the NIS against
            the gate.

        Returns
        -------
        matplotlib.figure.Figure
            The figure.

        Raises
        ------
        ConfigError
            An unknown ``kind``.
        """
        if kind == "track":
            return self._plot_track()
        if kind == "ranges":
            return self._plot_ranges()
        raise ConfigError(f"kind must be one of {', '.join(PLOT_KINDS)}, got {kind!r}")

    def _plot_track(self) -> Figure:
        n = self.dim
        fig = Figure(figsize=(11, 2.6 * n), layout="constrained")
        gs = fig.add_gridspec(n, 2)
        ax = fig.add_subplot(gs[:, 0])
        ax.plot(self.x_filt[:, 1], self.x_filt[:, 0], lw=0.8, label="filtered")
        ax.plot(self.x_smooth[:, 1], self.x_smooth[:, 0], lw=1.2, label="smoothed")
        if self.truth is not None:
            ax.plot(self.truth[:, 1], self.truth[:, 0], "k--", lw=0.8, label="truth")
        ax.plot(self.beacons[:, 1], self.beacons[:, 0], "r^", ms=4, label="beacon")
        ax.set(xlabel="y east [m]", ylabel="x north [m]", title="track", aspect="equal")
        ax.legend(fontsize=8)
        std_s, std_f = self.std("smoothed"), self.std("filtered")
        for i in range(n):
            a = fig.add_subplot(gs[i, 1])
            name = self.state_names[i]
            ref = np.zeros(self.t.size) if self.truth is None else self.truth[:, i]
            lab = "" if self.truth is None else " error"
            a.fill_between(
                self.t, -3 * std_s[:, i], 3 * std_s[:, i], alpha=0.25, label="±3σ smoothed"
            )
            a.plot(self.t, 3 * std_f[:, i], "C0:", lw=0.7, label="3σ filtered")
            if self.truth is not None:
                a.plot(self.t, self.x_filt[:, i] - ref, "C0", lw=0.7, label="filtered")
                a.plot(self.t, self.x_smooth[:, i] - ref, "C1", lw=1.0, label="smoothed")
            a.set(ylabel=f"{name}{lab} [m]")
            if i == 0:
                a.legend(fontsize=7, ncol=2)
        a.set(xlabel="t [s]")
        return fig

    def _plot_ranges(self) -> Figure:
        fig = Figure(figsize=(10, 5), layout="constrained")
        a1, a2 = fig.subplots(2, 1, sharex=True)
        t = self.t[self.range_rows]
        u = self.used
        a1.plot(t[u], self.residual[u], ".", ms=4, label="used (filter)")
        a1.plot(t[~u], self.residual[~u], "rx", ms=5, label="rejected")
        a1.plot(t, self.residual_smoothed, "k.", ms=2, label="smoothed")
        a1.set(ylabel="range residual [m]", title="ranges")
        a1.legend(fontsize=8)
        a2.semilogy(t[u], np.maximum(self.nis[u], 1e-6), ".", ms=4)
        a2.semilogy(t[~u], np.maximum(self.nis[~u], 1e-6), "rx", ms=5)
        if math.isfinite(self.gate_nis):
            a2.axhline(self.gate_nis, color="r", lw=0.8, label=f"gate ({self.gate_probability:g})")
            a2.legend(fontsize=8)
        a2.set(xlabel="t [s]", ylabel="NIS")
        return fig

    def __repr__(self) -> str:
        return (
            f"ReplayResult({self.source!r}: {self.t.size} rows, {self.used.size} ranges, "
            f"{self.ranges_rejected} rejected)"
        )


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None
