"""Baselines that fly a problem's mission: the schedule of
:mod:`obsplan.planning.missions.schedule` flown on the planning grid.

* ``lawnmower``: the plain lawn-mower over the mission's lines (or the straight legs through its
  waypoints) at the schedule's constant speed with the tightest turns;
* ``lawnmower-accel``: the same with sinusoidally accelerated lines (the paper's remedy for
  range-only observability), in the same line windows.

The planning grid holds piecewise-constant inputs: on an interval inside a constant-velocity
piece (a straight at constant speed, a hold) the input is zero and the path is exact. Between
two such intervals (a turn, a speed change, an accelerated line) the inputs are the chords of
the schedule's velocity, corrected by the least change (least squares, per axis) that ends the
stretch exactly on the schedule's state: so every straight, and every line's run-in and run-out,
is flown exactly on its track.
"""

from __future__ import annotations

import numpy as np

from obsplan.core.errors import ProblemError
from obsplan.planning.missions.schedule import (
    MissionSchedule,
    build_schedule,
    mission_schedule,
    planner_schedule,
)
from obsplan.planning.missions.spec import MissionContext
from obsplan.trajectory.sampled import Trajectory


def _free_intervals(sched: MissionSchedule, t: np.ndarray) -> np.ndarray:
    """True for the intervals ``[t_k, t_k+1]`` inside one constant-velocity piece."""
    starts = np.array([pc.t0 for pc in sched.pieces])
    ends = np.array([pc.t0 + pc.dur for pc in sched.pieces])
    i0 = np.clip(np.searchsorted(starts, t[:-1], side="right") - 1, 0, len(starts) - 1)
    free = np.zeros(t.size - 1, bool)
    for k, i in enumerate(i0):
        pc = sched.pieces[i]
        free[k] = pc.constant and t[k + 1] <= ends[i] + 1e-9 * max(1.0, t[-1])
    return free


def _correct(u_ref: np.ndarray, h: float, x0: tuple, x1: tuple) -> np.ndarray:
    """Inputs nearest ``u_ref`` (m, n) taking state ``x0 = (p, v)`` to ``x1`` in m steps of
    ``h`` exactly (zero-order hold)."""
    m = u_ref.shape[0]
    if m < 2:
        return u_ref
    j = np.arange(m)
    A = np.vstack([np.full(m, h), h * h * (m - j - 0.5)])  # v and p gained per unit input
    p0, v0 = x0
    p1, v1 = x1
    b = np.vstack([v1 - v0, p1 - p0 - m * h * v0])  # (2, n)
    resid = b - A @ u_ref
    return u_ref + A.T @ np.linalg.solve(A @ A.T, resid)


def fly_schedule(sched: MissionSchedule, ctx: MissionContext) -> Trajectory:
    """The schedule flown on the planning grid of ``ctx`` (module docstring).

    Parameters
    ----------
    sched : MissionSchedule
        The schedule to fly (:func:`~obsplan.planning.missions.schedule.mission_schedule`,
        :func:`~obsplan.planning.missions.schedule.build_schedule`).
    ctx : MissionContext
        The start state and the planning grid (horizon and steps).

    Returns
    -------
    Trajectory
        On the planning grid ``ctx.times``, from ``ctx``'s start, with piecewise-constant inputs
        [m/s²].
    """
    t = ctx.times
    n, h, N = ctx.dim, ctx.dt, ctx.steps
    P, V = sched.state(t, n)
    P[0], V[0] = ctx.p0, ctx.v0
    u = np.diff(V, axis=0) / h
    free = _free_intervals(sched, t)
    u[free] = 0.0
    k = 0
    while k < N:
        if free[k]:
            k += 1
            continue
        kb = k
        while kb < N and not free[kb]:
            kb += 1
        if kb - k < 2 and kb < N:
            kb += 1  # two steps at least to reach a state exactly
        if kb < N or (kb == N and free[N - 1]):
            u[k:kb] = _correct(u[k:kb], h, (P[k], V[k]), (P[kb], V[kb]))
        k = kb
    return Trajectory.from_inputs(t, ctx.p0, ctx.v0, u)


def mission_lawnmower(ctx: MissionContext, accelerated: bool = False) -> tuple[Trajectory, str]:
    """The (accelerated) lawn-mower of ``ctx``'s mission and its description.

    Parameters
    ----------
    ctx : MissionContext
        The mission and the start, limits and horizon it is flown under.
    accelerated : bool, optional
        The ``lawnmower-accel`` variant: each line flown with a sinusoidal speed in the same
        window.

    Returns
    -------
    traj : Trajectory
        The path on the planning grid ``ctx.times``.
    description : str
        One line for reports (speed, turn radius, mission time).

    Raises
    ------
    ProblemError
        For the accelerated one when the lines leave no speed headroom (the schedule flies them
        at the top of ``mission.speed``).
    """
    return _lawnmower(ctx, mission_schedule(ctx), accelerated)


def planner_lawnmower(ctx: MissionContext, accelerated: bool = False) -> tuple[Trajectory, str]:
    """:func:`mission_lawnmower` on the planner's schedule (its lead-in at rest, its lines at
    its speed: :func:`~obsplan.planning.missions.schedule.planner_schedule`): the planner's
    starts, which meet its line windows. Without a lead-in, the lawn-mower itself.

    Parameters
    ----------
    ctx : MissionContext
        The mission and the start, limits and horizon it is flown under.
    accelerated : bool, optional
        Sinusoidally accelerated lines (as :func:`mission_lawnmower`).

    Returns
    -------
    traj : Trajectory
        The path on the planning grid ``ctx.times``.
    description : str
        One line for reports (with the lead-in at rest, if any).

    Raises
    ------
    ProblemError
        As :func:`mission_lawnmower`, and on ``mission.lead_in`` when the lead-in does not fit.
    """
    return _lawnmower(ctx, planner_schedule(ctx), accelerated)


def _lawnmower(
    ctx: MissionContext, base: MissionSchedule, accelerated: bool
) -> tuple[Trajectory, str]:
    m = ctx.mission
    assert m is not None
    if accelerated and not m.lines:
        raise ProblemError("the mission has no survey lines to accelerate on")
    sched = (
        build_schedule(ctx, base.speed, accelerated=accelerated, delay=base.lead_in or None)
        if accelerated
        else base
    )
    traj = fly_schedule(sched, ctx)
    what = f"{len(m.lines)} survey lines" if m.kind == "survey" else f"{len(m.waypoints)} waypoints"
    radius = base.speed**2 / (float(np.min(ctx.accel)))
    desc = (
        f"lawn-mower over the mission's {what} at {base.speed:.3g} m/s, turns of radius "
        f">= {radius:.3g} m, mission flown in {base.end_s:.0f} s"
    )
    if base.lead_in > 0:
        desc += f", after {base.lead_in:.0f} s at rest"
    if accelerated:
        amp = max((pc.amp for pc in sched.pieces if pc.cycles), default=0.0)
        if amp <= 0:
            raise ProblemError("the lines leave no speed headroom to accelerate in")
        desc += f", lines accelerated sinusoidally (+-{amp:.2g} m/s)"
    return traj, desc
