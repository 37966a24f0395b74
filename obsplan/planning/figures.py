"""Figures of a plan: the path beside the baselines (with the mission's lines, tolerance bands,
waypoints and end region), the speed along the path, Gramian eigenvalues, filter errors.

Functions take ``ax=None`` and return the Figure (Agg backend in scripts and tests).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from obsplan.model.beacon import BeaconPath
from obsplan.observability.gramian import cumulative_gramians
from obsplan.planning.missions.check import mission_check
from obsplan.planning.missions.schedule import mission_schedule
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.validation.validate import PathValidation
from obsplan.trajectory.sampled import Trajectory

_STYLE = {
    "planned": {"color": "tab:green", "lw": 2.0},
    "lawnmower": {"color": "tab:orange", "lw": 1.5},
    "circle": {"color": "tab:purple", "lw": 1.0},
    "straight": {"color": "tab:gray", "lw": 1.0},
    "paper-lawnmower": {"color": "tab:brown", "lw": 1.0},
    "lawnmower-accel": {"color": "tab:red", "lw": 1.0},
}


def _ax(ax):
    if ax is None:
        fig = plt.figure(figsize=(6, 4.8))
        ax = fig.add_subplot(111)
    return ax.figure, ax


def plot_paths(
    paths: Mapping[str, Trajectory], pb: PlanningProblem, ax=None, names: tuple[str, ...] = ()
) -> Figure:
    """The paths (default: planned and lawn-mower) with the beacon, start and operating area.

    Horizontal view [m]; in 3D (when ``ax`` is None) a second panel shows depth ``z`` over time
    with the depth band. With a geodetic problem (``pb.origin``) the horizontal view is a map:
    east to the right, north up.

    Parameters
    ----------
    paths : Mapping of str to Trajectory
        Paths by name (``"planned"``, baseline names), positions in the problem's local frame
        [m].
    pb : PlanningProblem
        The problem: beacon, start, ``limits.area``, ``limits.min_range``, depth band and the
        mission's lines, waypoints and end region are drawn from it.
    ax : matplotlib.axes.Axes, optional
        Axes to draw the horizontal view on; None makes a new figure (with the depth panel in
        3D).
    names : tuple of str, optional
        Which of ``paths`` to draw; empty: ``"planned"`` and ``"lawnmower"`` when present, else
        all.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of ``ax`` (or the new one).
    """
    names = names or tuple(n for n in ("planned", "lawnmower") if n in paths) or tuple(paths)
    depth_panel = pb.dim == 3 and ax is None
    if ax is None:
        fig = plt.figure(figsize=(11, 4.8) if depth_panel else (6, 4.8))
        ax = fig.add_subplot(1, 2, 1) if depth_panel else fig.add_subplot(111)
    fig = ax.figure
    geo = getattr(pb, "origin", None) is not None
    ix, iy = (1, 0) if geo else (0, 1)  # a map: east (y) across, north (x) up
    for name in names:
        tr = paths[name]
        ax.plot(tr.p[:, ix], tr.p[:, iy], label=name, **_STYLE.get(name, {"lw": 1.0}))
    ax.plot(pb.p0[ix], pb.p0[iy], "ko", ms=5, label="start")
    ax.plot(pb.beacon[ix], pb.beacon[iy], "r^", ms=9, label="beacon")
    _min_range_circle(ax, pb, ix, iy, label=True)
    if pb.limits.area is not None:
        a = pb.limits.area
        lo = (a.x[0], a.y[0]) if not geo else (a.y[0], a.x[0])
        w, h = (a.width, a.height) if not geo else (a.height, a.width)
        ax.add_patch(
            plt.Rectangle(lo, w, h, fill=False, ls="--", color="0.5", label="operating area")
        )
    _draw_mission(ax, pb, ix, iy)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("y = east [m]" if geo else "x [m]")
    ax.set_ylabel("x = north [m]" if geo else "y [m]")
    ax.set_title(
        f"{_problem_title(pb)}{pb.objective.kind}: planned path vs lawn-mower (horizontal)",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    _beacon_zoom(ax, paths, names, pb, ix, iy)
    if depth_panel:
        az = fig.add_subplot(1, 2, 2)
        for name in names:
            tr = paths[name]
            az.plot(tr.t, tr.p[:, 2], label=name, **_STYLE.get(name, {"lw": 1.0}))
        az.plot(0.0, pb.p0[2], "ko", ms=5, label="start")
        az.axhline(pb.beacon[2], color="r", ls=":", lw=1, label="beacon depth")
        if pb.limits.depth is not None:
            for k, z in enumerate(pb.limits.depth):
                az.axhline(z, color="0.5", ls="--", lw=1, label="depth band" if k == 0 else None)
        _draw_altitude_band(az, paths[names[0]], pb)
        az.invert_yaxis()  # z is depth (north-east-down): down is down
        az.set_xlabel("t [s]")
        az.set_ylabel("z = depth [m]")
        az.set_title("depth over time", fontsize=9)
        az.grid(True, alpha=0.3)
        az.legend(fontsize=7)
        fig.tight_layout()
    return fig


def _draw_altitude_band(az, tr: Trajectory, pb: PlanningProblem) -> None:
    """On the depth panel: the seabed under ``tr`` and, over its line passes, the depths of
    the mission's altitude band."""
    m = pb.mission
    if m is None or m.altitude is None or m.seabed is None:
        return
    sb = m.seabed.depth_at(tr.p[:, :2])
    az.plot(tr.t, sb, color="saddlebrown", lw=1, label="seabed under the path")
    chk = mission_check(tr, pb.mission_context)
    lo, hi = m.altitude
    for k, ln in enumerate(chk.lines if chk is not None else ()):
        on = (tr.t >= ln.pass_s[0]) & (tr.t <= ln.pass_s[1])
        az.fill_between(
            tr.t[on],
            sb[on] - hi,
            sb[on] - lo,
            color="tab:blue",
            alpha=0.2,
            label=f"mission.altitude {lo:g}-{hi:g} m on the lines" if k == 0 else None,
        )


def _draw_mission(ax, pb: PlanningProblem, ix: int, iy: int) -> None:
    """The mission's lines with their cross-track bands, waypoints and end region."""
    m = pb.mission
    if m is None:
        return
    for i, (a, b) in enumerate(m.segments(pb.dim)):
        e = (b - a)[:2] / np.linalg.norm((b - a)[:2])
        off = np.array([-e[1], e[0]]) * m.cross_track
        band = np.array([a[:2] + off, b[:2] + off, b[:2] - off, a[:2] - off])
        label = f"survey line +-{m.cross_track:g} m" if i == 0 else None
        ax.add_patch(plt.Polygon(band[:, [ix, iy]], color="tab:blue", alpha=0.25, label=label))
        ax.annotate(
            "",
            xy=(b[ix], b[iy]),
            xytext=(a[ix], a[iy]),
            arrowprops={"arrowstyle": "->", "color": "tab:blue", "lw": 0.8},
        )
    for i, w in enumerate(m.waypoints):
        label = f"waypoint (r = {m.radius:g} m)" if i == 0 else None
        ax.add_patch(
            plt.Circle((w[ix], w[iy]), m.radius, fill=False, color="tab:blue", label=label)
        )
    if m.end is not None:
        c = m.end.position
        ax.add_patch(
            plt.Circle((c[ix], c[iy]), m.end.radius, fill=False, ls=":", color="k", label="end")
        )


def plot_speed(paths: Mapping[str, Trajectory], pb: PlanningProblem, ax=None) -> Figure:
    """Speed ``|v(t)|`` [m/s] of each path, with the speed limit and, with a survey, the band
    ``mission.speed`` over the lines' passes (shaded: the plan's own, which may shift from the
    schedule's windows, or the schedule's without a plan).

    Parameters
    ----------
    paths : Mapping of str to Trajectory
        Paths by name; ``"planned"``, when present and complete, gives the shaded passes.
    pb : PlanningProblem
        The problem: ``limits.speed`` and the mission's speed band and schedule.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; None makes a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of ``ax`` (or the new one).
    """
    fig, ax = _ax(ax)
    for name, tr in paths.items():
        ax.plot(tr.t, np.linalg.norm(tr.v, axis=1), label=name, **_STYLE.get(name, {"lw": 1.0}))
    ax.axhline(pb.limits.speed, color="k", ls="--", lw=1, label="limits.speed")
    m = pb.mission
    if m is not None and m.lines:
        lo, hi = m.speed_band(pb.limits.speed)
        windows = mission_schedule(pb.mission_context).line_windows
        if "planned" in paths:
            chk = mission_check(paths["planned"], pb.mission_context)
            if chk is not None and chk.complete:
                windows = tuple(ln.pass_s for ln in chk.lines)
        for k, (t0, t1) in enumerate(windows):
            ax.fill_between(
                [t0, t1],
                lo,
                hi,
                color="tab:blue",
                alpha=0.15,
                label="mission.speed on the lines" if k == 0 else None,
            )
    ax.set_xlabel("t [s]")
    ax.set_ylabel("speed [m/s]")
    ax.set_title("speed along the path", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def _problem_title(pb: PlanningProblem) -> str:
    return f"{pb.name}\n" if getattr(pb, "name", "") else ""


def _min_range_circle(ax, pb: PlanningProblem, ix: int, iy: int, label: bool) -> None:
    """The circle ``|p - b| = limits.min_range`` the path keeps out of (none when 0)."""
    r = float(pb.limits.min_range or 0.0)
    if r <= 0:
        return
    centre = (pb.beacon[ix], pb.beacon[iy])
    ax.add_patch(
        plt.Circle(
            centre,
            r,
            fill=False,
            ls=":",
            lw=1.0,
            color="tab:red",
            label=f"min range {r:g} m" if label else None,
        )
    )


#: A path that comes within this fraction of the view's size of the beacon gets a zoomed inset.
ZOOM_FRACTION = 0.08


def _beacon_zoom(ax, paths, names, pb: PlanningProblem, ix: int, iy: int) -> None:
    """An inset zoomed on the beacon when a path loops close to it (the loops at the minimum
    range would otherwise hide under the beacon's marker)."""
    b = np.array([pb.beacon[ix], pb.beacon[iy]])
    pts = np.concatenate([paths[n].p[:, [ix, iy]] for n in names])
    extent = float(np.max(np.ptp(np.vstack([pts, b]), axis=0)))
    near = [paths[n].p[:, [ix, iy]] for n in names]
    closest = min(float(np.min(np.linalg.norm(q - b, axis=1))) for q in near)
    if extent <= 0 or closest > ZOOM_FRACTION * extent:
        return
    half = max(4.0 * max(closest, float(pb.limits.min_range or 0.0)), 0.02 * extent)
    inset = ax.inset_axes((0.62, 0.02, 0.36, 0.36))
    for name in names:
        q = paths[name].p[:, [ix, iy]]
        inset.plot(q[:, 0], q[:, 1], **_STYLE.get(name, {"lw": 1.0}))
    inset.plot(*b, "r^", ms=5)
    _min_range_circle(inset, pb, ix, iy, label=False)
    inset.set_xlim(b[0] - half, b[0] + half)
    inset.set_ylim(b[1] - half, b[1] + half)
    inset.set_aspect("equal", adjustable="box")
    inset.tick_params(labelsize=6)
    inset.set_title(f"near the beacon (±{half:.3g} m)", fontsize=6)
    ax.indicate_inset_zoom(inset, edgecolor="0.4")


def plot_gramian_eigs(paths: Mapping[str, Trajectory], pb: PlanningProblem, ax=None) -> Figure:
    """Smallest eigenvalue of the scaled Gramian ``G(t, t_0)`` over time, each path.

    Parameters
    ----------
    paths : Mapping of str to Trajectory
        Paths by name.
    pb : PlanningProblem
        The problem: its vehicle model and scales (``pb.scales``, length [m] and time [s]) of
        the augmented Gramian.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; None makes a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of ``ax`` (or the new one); the eigenvalue axis is logarithmic
        (dimensionless, scaled Gramian).
    """
    fig, ax = _ax(ax)
    for name, tr in paths.items():
        G = cumulative_gramians(tr, pb.model, pb.scales)[1:]
        lam = np.linalg.eigvalsh(0.5 * (G + np.swapaxes(G, 1, 2)))[:, 0]
        ax.semilogy(tr.t[1:], np.maximum(lam, 1e-16), label=name, **_STYLE.get(name, {}))
    ax.set_xlabel("t [s]")
    ax.set_ylabel(r"$\lambda_{min}$ of scaled Gramian")
    ax.set_title(
        r"smallest eigenvalue of the scaled augmented Gramian $G(t, t_0)$ (eq. 25)"
        f"\nL = {pb.scales.length_m:g} m, T = {pb.scales.time_s:g} s",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_filter_errors(
    validation: Mapping[str, PathValidation],
    ax=None,
    names: tuple[str, ...] = (),
    problem: str = "",
) -> Figure:
    """Position RMSE over the runs for the EKF (solid) and KF (dashed), and the posterior CRB
    on the position std (dotted), of each path; ``problem`` (its name) heads the title.

    The curves are the RMSE over the runs at each time: a root mean square, which a few runs far
    off (flagged: their errors leave the filter's own covariance) dominate. The verdict's "EKF
    RMSE" is its time average over the mission and its "final error" the mean error at the end;
    when the plan's EKF curve ends above the lawn-mower's, a note under the title gives those
    numbers and the flagged runs, so the figure and the verdict tell one story.

    Parameters
    ----------
    validation : Mapping of str to PathValidation
        The Monte Carlo validation of each path, by name
        (:func:`~obsplan.planning.validation.validate.validate_paths`).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; None makes a new figure.
    names : tuple of str, optional
        Which paths to draw; empty: ``"planned"`` and ``"lawnmower"`` when present, else all.
    problem : str, optional
        The problem's name, heading the title; empty for none.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of ``ax`` (or the new one); errors and bounds in metres, log scale.
    """
    fig, ax = _ax(ax)
    names = (
        names or tuple(n for n in ("planned", "lawnmower") if n in validation) or tuple(validation)
    )
    for name in names:
        r = validation[name].result
        st = _STYLE.get(name, {})
        if r.ekf is not None:
            ax.semilogy(r.t, r.ekf.rmse_pos_t, ls="-", label=f"{name} EKF", **st)
        if r.kf is not None:
            ax.semilogy(r.t, r.kf.rmse_pos_t, ls="--", label=f"{name} KF", **st)
        ax.semilogy(r.t, r.crlb_pos_std_t, ls=":", label=f"{name} bound (PCRB)", **st)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("position RMSE / bound [m]")
    some = next(iter(validation.values())).result if validation else None
    if some is not None:
        head = f"{problem}\n" if problem else ""
        note = _crossing_note(validation, names)
        ax.set_title(
            f"{head}{some.runs} Monte Carlo runs, seed {some.seed}" + (f"\n{note}" if note else ""),
            fontsize=7 if note else 9,
        )
        if note:
            fig.subplots_adjust(top=0.74)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def _crossing_note(validation: Mapping[str, PathValidation], names: tuple[str, ...]) -> str:
    """When the plan's EKF RMSE curve ends above the lawn-mower's, say what the table compares
    (time averages and final errors), so the figure and the verdict tell one story."""
    if not {"planned", "lawnmower"} <= set(names):
        return ""
    plan, mower = validation["planned"].result.ekf, validation["lawnmower"].result.ekf
    if plan is None or mower is None:
        return ""
    if not plan.rmse_pos_t[-1] > mower.rmse_pos_t[-1]:
        return ""
    flagged = int(getattr(plan, "flagged_runs", 0) or 0)
    led = f", led by its {flagged} flagged runs" if flagged else ""
    return (
        f"EKF RMSE at the end: plan {plan.rmse_pos_t[-1]:.3g} m > lawn-mower "
        f"{mower.rmse_pos_t[-1]:.3g} m\n(a root mean square over the runs{led});\n"
        f"the verdict compares the mean final error, {plan.final_pos_err:.3g} vs "
        f"{mower.final_pos_err:.3g} m,\nand the mission RMSE, {plan.rmse_pos:.3g} vs "
        f"{mower.rmse_pos:.3g} m"
    )


def plot_beacon_paths(
    vehicle: Trajectory,
    beacons: Mapping[str, BeaconPath],
    pb: PlanningProblem,
    ax=None,
    links: int = 12,
    baseline_vehicle: Trajectory | None = None,
) -> Figure:
    """The vehicle's path and the beacon's paths (planned and baselines), with range links.

    Horizontal view [m]: the vehicle (black), ``"planned"`` bold, each baseline thin, the mission's
    lines, and ``links`` range links (grey) from the vehicle to the planned beacon (the first path
    without one) at evenly spaced times.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path [m].
    beacons : Mapping of str to BeaconPath
        The beacon's paths by name (``"planned"``, baseline names).
    pb : PlanningProblem
        The problem (its mission, start and title).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on; None makes a new figure.
    links : int, optional
        Number of range links drawn.
    baseline_vehicle : Trajectory or None, optional
        The path the vehicle flies with the baselines' beacons when it differs from
        ``vehicle`` (planned jointly: the lawn-mower), drawn dashed; None: ``vehicle``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of ``ax`` (or the new one).
    """
    if ax is None:
        fig = plt.figure(figsize=(7, 5.6))
        ax = fig.add_subplot(111)
    fig = ax.figure
    ax.plot(vehicle.p[:, 0], vehicle.p[:, 1], color="k", lw=1.5, label="vehicle")
    if baseline_vehicle is not None:
        q = baseline_vehicle.p
        ax.plot(q[:, 0], q[:, 1], color="0.45", lw=1.0, ls=":", label="vehicle with baselines")
    ax.plot(pb.p0[0], pb.p0[1], "ko", ms=5, label="vehicle start")
    others = iter(("tab:blue", "tab:orange", "tab:purple", "tab:red", "tab:brown", "tab:pink"))
    for name, path in beacons.items():
        style: dict = {"lw": 2.2, "color": "tab:green", "zorder": 3}
        if name != "planned":  # the baselines behind the plan, none in its colour
            style = {"lw": 0.8, "alpha": 0.7, "color": next(others, "0.5")}
        ax.plot(path.positions[:, 0], path.positions[:, 1], label=name, **style)
    if beacons:
        shown = beacons.get("planned", next(iter(beacons.values())))
        t = np.linspace(max(vehicle.t[0], shown.start), min(vehicle.t[-1], shown.end), links)
        b = shown.position(t)
        for k, tk in enumerate(t):
            i = int(np.argmin(np.abs(vehicle.t - tk)))
            ax.plot(
                [vehicle.p[i, 0], b[k, 0]],
                [vehicle.p[i, 1], b[k, 1]],
                color="0.3",
                lw=0.7,
                ls="--",
                zorder=4,
                label="range links" if k == 0 else None,
            )
        ax.plot(shown.positions[0, 0], shown.positions[0, 1], "r^", ms=9, label="beacon start")
    _draw_mission(ax, pb, 0, 1)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{_problem_title(pb)}the vehicle and the beacon's paths", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Save and close.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure; it is closed after saving.
    path : str or Path
        The image file (its format from the suffix); missing parent folders are created.
    dpi : int, optional
        Resolution [dots per inch].

    Returns
    -------
    Path
        ``path``, as a :class:`~pathlib.Path`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
