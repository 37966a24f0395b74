"""Figures of a plan: the path beside the baselines, Gramian eigenvalues, filter errors.

Functions take ``ax=None`` and return the Figure (Agg backend in scripts and tests).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from obsplan.observability.gramian import cumulative_gramians
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory
from obsplan.validation import PathValidation

_STYLE = {
    "planned": {"color": "tab:green", "lw": 2.0},
    "lawnmower": {"color": "tab:orange", "lw": 1.5},
    "circle": {"color": "tab:purple", "lw": 1.0},
    "straight": {"color": "tab:gray", "lw": 1.0},
    "paper-lawnmower": {"color": "tab:brown", "lw": 1.0},
}


def _ax(ax):
    if ax is None:
        fig = plt.figure(figsize=(6, 4.8))
        ax = fig.add_subplot(111)
    return ax.figure, ax


def plot_paths(
    paths: Mapping[str, Trajectory], pb: PlanningProblem, ax=None, names: tuple[str, ...] = ()
) -> Figure:
    """Horizontal view (x, y) [m] of the paths (default: planned and lawn-mower), beacon, area."""
    fig, ax = _ax(ax)
    names = names or tuple(n for n in ("planned", "lawnmower") if n in paths)
    for name in names:
        tr = paths[name]
        st = _STYLE.get(name, {"lw": 1.0})
        ax.plot(tr.p[:, 0], tr.p[:, 1], label=name, **st)
    ax.plot(*pb.p0[:2], "ko", ms=5, label="start")
    ax.plot(pb.beacon[0], pb.beacon[1], "r^", ms=9, label="beacon")
    if pb.limits.area is not None:
        a = pb.limits.area
        ax.add_patch(
            plt.Rectangle((a.x[0], a.y[0]), a.width, a.height, fill=False, ls="--", color="0.5")
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{pb.objective.kind}: planned path vs lawn-mower", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_gramian_eigs(paths: Mapping[str, Trajectory], pb: PlanningProblem, ax=None) -> Figure:
    """Smallest eigenvalue of the scaled Gramian ``G(t, t_0)`` over time, each path."""
    fig, ax = _ax(ax)
    for name, tr in paths.items():
        G = cumulative_gramians(tr, pb.model, pb.scales)[1:]
        lam = np.linalg.eigvalsh(0.5 * (G + np.swapaxes(G, 1, 2)))[:, 0]
        ax.semilogy(tr.t[1:], np.maximum(lam, 1e-16), label=name, **_STYLE.get(name, {}))
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$\lambda_{min}$ of scaled Gramian")
    ax.set_title(f"scales L = {pb.scales.length_m:g} m, T = {pb.scales.time_s:g} s", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_filter_errors(
    validation: Mapping[str, PathValidation], ax=None, names: tuple[str, ...] = ()
) -> Figure:
    """Position RMSE over the runs for the EKF (solid) and KF (dashed), each path."""
    fig, ax = _ax(ax)
    names = names or tuple(n for n in ("planned", "lawnmower") if n in validation)
    for name in names:
        r = validation[name].result
        st = _STYLE.get(name, {})
        if r.ekf is not None:
            ax.semilogy(r.t, r.ekf.rmse_pos_t, ls="-", label=f"{name} EKF", **st)
        if r.kf is not None:
            ax.semilogy(r.t, r.kf.rmse_pos_t, ls="--", label=f"{name} KF", **st)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("position RMSE [m]")
    some = next(iter(validation.values())).result if validation else None
    if some is not None:
        ax.set_title(f"{some.runs} Monte Carlo runs, seed {some.seed}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Save and close."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
