"""Matplotlib figures of estimation runs and Gramian rank (like the paper's Figs. 1–9).

Every function takes ``ax=None`` (a new figure is made when None) and returns the Figure; nothing
is shown. Use the Agg backend in scripts and tests (``MPLBACKEND=Agg``).

The figures of a whole result read it through :class:`MonteCarloData` (what a
:class:`~obsplan.estimation.montecarlo.results.MonteCarloResult` has), so that this module sits
below the result, whose ``plot()`` draws them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.history import RunHistory
from obsplan.estimation.montecarlo.stats import FilterStats, filter_stats
from obsplan.trajectory.sampled import Trajectory


class MonteCarloData(Protocol):
    """What the figures read of a Monte Carlo result
    (:class:`~obsplan.estimation.montecarlo.results.MonteCarloResult`)."""

    @property
    def runs(self) -> int: ...

    @property
    def seed(self) -> int: ...

    @property
    def t(self) -> np.ndarray: ...

    @property
    def ekf(self) -> FilterStats | None: ...

    @property
    def kf(self) -> FilterStats | None: ...

    @property
    def filters(self) -> dict | None: ...

    @property
    def crlb_pos_std_t(self) -> np.ndarray: ...

    @property
    def example(self) -> RunHistory | None: ...

    @property
    def config(self) -> EstimationConfig: ...


COLORS = {"ekf": "tab:red", "kf": "tab:blue", "gsf": "tab:orange", "truth": "k", "crlb": "tab:gray"}
LABELS = {"ekf": "EKF", "kf": "KF (augmented)", "gsf": "Gaussian-sum EKF"}
_AXES = "xyz"
_MORE_COLORS = ("tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


def _color(name: str) -> str:
    """A filter's colour; filters added later get the next free one."""
    if name not in COLORS:
        COLORS[name] = _MORE_COLORS[(len(COLORS) - 5) % len(_MORE_COLORS)]
    return COLORS[name]


def _label(name: str) -> str:
    return LABELS.get(name, name.upper())


def _ax(ax, projection: str | None = None):
    if ax is None:
        fig = plt.figure(figsize=(6, 4.5))
        ax = fig.add_subplot(111, projection=projection)
    return ax.figure, ax


def close(fig: Figure) -> None:
    """Release a figure's memory.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure to close.
    """
    plt.close(fig)


def plot_trajectory_estimates(hist: RunHistory, ax=None, beacon=None) -> Figure:
    """True path and each filter's estimated path (run 0), in the plane or in 3D (panel a).

    Parameters
    ----------
    hist : RunHistory
        Run 0's history (truth, each filter's estimate and std).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.
    beacon : array_like, shape (n,) or (M, n), optional
        Beacon position [m], or a moving beacon's path (drawn as a line, its start marked);
        None: the origin.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    n = hist.truth.shape[1] // 2
    fig, ax = _ax(ax, "3d" if n == 3 and ax is None else None)
    is3d = getattr(ax, "name", "") == "3d"
    k = 3 if is3d else 2

    def draw(p, **kw):
        ax.plot(*[p[:, i] for i in range(k)], **kw)

    draw(hist.truth, color=COLORS["truth"], lw=1.5, label="true")
    for name, est in hist.estimate.items():
        draw(est, color=_color(name), lw=1.0, ls="--", label=_label(name))
    b = np.zeros(n) if beacon is None else np.asarray(beacon, float)
    if b.ndim == 2:  # a moving beacon: its path, from its first position
        draw(b, color="g", lw=0.8, label="beacon path")
        b = b[0]
    ax.scatter(*b[:k], marker="^", color="g", s=40, label="beacon")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if is3d:
        ax.set_zlabel("z [m]")
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)
    return fig


def plot_error_norms(hist: RunHistory, ax=None, velocity: bool = False) -> Figure:
    """``|p̂ - p|`` (or ``|p̂' - p'|``) of each filter over time, run 0 (panel b).

    Parameters
    ----------
    hist : RunHistory
        Run 0's history (truth, each filter's estimate and std).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.
    velocity : bool, optional
        Plot the velocity error [m/s] instead of the position error [m].

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _ax(ax)
    for name in hist.estimate:
        e = hist.vel_error(name) if velocity else hist.pos_error(name)
        ax.semilogy(hist.t, np.maximum(e, 1e-6), color=_color(name), label=_label(name))
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|velocity error| [m/s]" if velocity else "|position error| [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def plot_std(hist: RunHistory, ax=None, velocity: bool = False) -> Figure:
    """Per-axis standard deviations of each filter (run 0): position (c) or velocity (d).

    Parameters
    ----------
    hist : RunHistory
        Run 0's history (truth, each filter's estimate and std).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.
    velocity : bool, optional
        Plot the velocity std [m/s] instead of the position std [m].

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _ax(ax)
    n = hist.truth.shape[1] // 2
    off = n if velocity else 0
    styles = ["-", "--", ":"]
    for name, std in hist.std.items():
        for i in range(n):
            ax.semilogy(
                hist.t,
                np.maximum(std[:, off + i], 1e-9),
                color=_color(name),
                ls=styles[i],
                label=f"{_label(name)} σ_{'v' if velocity else 'p'}{_AXES[i]}",
            )
    ax.set_xlabel("t [s]")
    ax.set_ylabel("std of velocity [m/s]" if velocity else "std of position [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return fig


def plot_gramian_rank(t: np.ndarray, rank: np.ndarray, full: int, ax=None) -> Figure:
    """Rank of the augmented Gramian ``G(t, t0)`` over time, with the full rank marked.

    Parameters
    ----------
    t : ndarray, shape (K,)
        Times [s].
    rank : ndarray of int, shape (K,)
        Rank at those times.
    full : int
        Full rank (the augmented state's dimension).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _ax(ax)
    ax.step(t, rank, where="post", color="tab:green", label="rank G(t, t0)")
    ax.axhline(full, color="k", ls=":", lw=1, label=f"full rank = {full}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("rank")
    ax.set_ylim(-0.2, full + 0.5)
    ax.legend(fontsize=8)
    return fig


def plot_range_measurements(hist: RunHistory, ax=None) -> Figure:
    """The range readings of run 0 [m] (Fig. 9d).

    Parameters
    ----------
    hist : RunHistory
        Run 0's history (truth, each filter's estimate and std).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _ax(ax)
    ax.plot(hist.range_t, hist.range_m, ".", ms=3, color="tab:purple", label="range reading")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("range [m]")
    ax.legend(fontsize=8)
    return fig


def plot_monte_carlo(result: MonteCarloData, ax=None) -> Figure:
    """RMSE of position over the runs for each filter with its mean std and the CRB.

    Parameters
    ----------
    result : MonteCarloData
        A Monte Carlo result (:class:`~obsplan.estimation.montecarlo.results.MonteCarloResult`).
    ax : matplotlib.axes.Axes or None, optional
        Axes to draw on; None: a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    fig, ax = _ax(ax)
    for name, s in filter_stats(result).items():
        ax.semilogy(result.t, s.rmse_pos_t, color=_color(name), label=f"{_label(name)} RMSE")
        ax.semilogy(result.t, s.pos_std_t, color=_color(name), ls=":", label=f"{_label(name)} std")
    ax.semilogy(result.t, result.crlb_pos_std_t, color=COLORS["crlb"], ls="--", label="CRB")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("position [m]")
    ax.set_title(f"{result.runs} runs, seed {result.seed}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def scenario_figure(
    traj: Trajectory | None,
    result: MonteCarloData,
    rank_t: np.ndarray | None = None,
    rank: np.ndarray | None = None,
    full_rank: int | None = None,
    title: str = "",
) -> Figure:
    """Six panels like the paper's figures: (a) paths, (b) error norms, (c) position std,
    (d) velocity std, (e) Gramian rank (without ``rank``: the runs' RMSE), (f) range readings.

    Parameters
    ----------
    traj : Trajectory or None
        The path flown; not drawn: run 0's history holds the true path.
    result : MonteCarloData
        Its Monte Carlo result, with run 0's history.
    rank_t : ndarray, shape (K,), optional
        Times [s] of the Gramian ranks.
    rank : ndarray of int, shape (K,), optional
        Gramian rank at those times; without the three rank arguments panel (e) shows the
        RMSE of :func:`plot_monte_carlo`.
    full_rank : int, optional
        Full rank of the Gramian.
    title : str, optional
        Title of the figure.

    Returns
    -------
    matplotlib.figure.Figure
        The new figure.

    Raises
    ------
    ValueError
        If the result holds no run history.
    """
    hist = result.example
    if hist is None:
        raise ValueError("the result holds no run history (monte_carlo keeps run 0's history)")
    n = hist.truth.shape[1] // 2 if traj is None else traj.dim
    fig = plt.figure(figsize=(13, 8))
    ax_a = fig.add_subplot(2, 3, 1, projection="3d" if n == 3 else None)
    path = result.config.beacon_path
    beacon = result.config.model.beacon if path is None else path.position(hist.t)
    plot_trajectory_estimates(hist, ax=ax_a, beacon=beacon)
    plot_error_norms(hist, ax=fig.add_subplot(2, 3, 2))
    plot_std(hist, ax=fig.add_subplot(2, 3, 3))
    plot_std(hist, ax=fig.add_subplot(2, 3, 4), velocity=True)
    ax_e = fig.add_subplot(2, 3, 5)
    if rank is not None and rank_t is not None and full_rank is not None:
        plot_gramian_rank(rank_t, rank, full_rank, ax=ax_e)
    else:
        plot_monte_carlo(result, ax=ax_e)
    plot_range_measurements(hist, ax=fig.add_subplot(2, 3, 6))
    for ax, letter in zip(fig.axes, "abcdef", strict=False):
        ax.set_title(f"({letter})", loc="left", fontsize=9)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    if n == 3:  # tight_layout ignores the 3D axes' z label, which then overlaps panel (b)
        fig.subplots_adjust(wspace=0.45)
    return fig


def save(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Save ``fig`` to ``path`` (parent folders created) and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        The image file; its suffix chooses the format.
    dpi : int, optional
        Resolution [dots per inch].

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    close(fig)
    return path
