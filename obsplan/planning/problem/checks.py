"""Checks of a planning problem: the cheap ones run on construction, the structural ones before
any solver work.

:func:`check_values` is what ``PlanningProblem.__post_init__`` runs: types and ranges that the
parser cannot see, and infeasible combinations (a start faster than the speed limit, a zero
acceleration bound, fewer than 2 steps, a depth band or operating area that does not contain the
start, a start too close to the beacon for the planner's between-node margin).
:func:`check_structure` refuses objectives that the sensors make impossible for every input; it
costs a CasADi rank computation (cached per objective kind and vehicle), so the loader
(:mod:`obsplan.planning.problem.parse`) and :func:`~obsplan.planning.solver.solve.solve` run it,
construction does not. Every error is a :class:`~obsplan.core.errors.ProblemError` naming
``section.field`` and the fix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from functools import cache
from typing import TypeVar

import numpy as np

from obsplan.core import budget
from obsplan.core.errors import ConfigError, InputError, ProblemError, field_error
from obsplan.estimation.channel import CHANNEL_PRESETS, channel_preset
from obsplan.estimation.config import EKF_UPDATES
from obsplan.estimation.montecarlo.guidance import NAVIGATION_FILTERS
from obsplan.model.vehicle import VehicleModel, parse_sensors
from obsplan.observability.gramian import augmented_model, gramian, rank_scales
from obsplan.observability.lwo import lwo_structural_max_rank
from obsplan.observability.scaling import numerical_rank
from obsplan.planning.missions.order import MAX_FREE_LINES, free_order
from obsplan.planning.missions.schedule import check_mission_geometry, mission_fit_error
from obsplan.planning.missions.spec import MISSION_KINDS, MISSION_ORDERS
from obsplan.planning.problem.schema import (
    BEACON_MOTIONS,
    LAWNMOWER_PATH,
    LINE_MODES,
    MAX_DURATION_S,
    MAX_MAGNITUDE,
    MAX_STEPS,
    MODES,
    OBJECTIVE_KINDS,
    OBJECTIVES,
    PROCESS_NOISE_MODELS,
    SCHEMA,
    TIMED_OBJECTIVES,
    VALIDATION_MODES,
)
from obsplan.planning.problem.sections import CHANNEL_KEYS, ProblemData, ValidationSpec
from obsplan.trajectory.sampled import Trajectory, read_csv, resample

P = TypeVar("P", bound=ProblemData)


def check_values(pb: ProblemData) -> None:
    """The cheap checks of a problem (no solver work), in the order the loader reports them.

    Whether the mission fits the horizon is checked once its lines are in the order flown: a
    ``mission.order = "free"`` is resolved by the loader (:func:`order_lines`), and
    :func:`check_structure` refuses a problem whose free order was never resolved.

    Parameters
    ----------
    pb : ProblemData
        The problem's sections (a :class:`~obsplan.planning.problem.definition.PlanningProblem`
        being constructed).

    Raises
    ------
    ProblemError
        Naming the ``section.field`` at fault and the fix.
    """
    budget.check_name_length(pb.name, "problem.name", ProblemError)
    _check_vehicle(pb)
    _check_motion(pb)
    _check_horizon(pb)
    _check_beacon_motion(pb)  # a known path is read before the start is checked against it
    _check_range_and_speed_limits(pb)
    _check_objective(pb)
    _check_validation(pb)
    _check_budget(pb)
    if pb.objective.mode in LINE_MODES and (pb.mission is None or not pb.mission.lines):
        raise field_error(
            "objective.mode",
            f'"{pb.objective.mode}" averages over survey lines: it needs a [mission] with lines',
        )
    if pb.mission is not None:
        _check_mission(pb)
        if not unordered(pb):
            mission_fit_error(pb.mission_context)


def _check_beacon_motion(pb: ProblemData) -> None:
    """A moving beacon: its path covers the horizon, its craft's limits hold at its start, the
    vehicle's given path fits the problem."""
    bm, T = pb.beacon_motion, pb.horizon.duration
    if bm.motion not in BEACON_MOTIONS:
        raise field_error(
            "beacon.motion", f"must be one of {', '.join(BEACON_MOTIONS)}, got {bm.motion!r}"
        )
    if not bm.moving:
        if pb.vehicle.path is not None:
            raise field_error("vehicle.path", "is for a moving beacon (beacon.motion); remove it")
        return
    if bm.motion == "path":
        try:
            path = pb.beacon_path
        except InputError as exc:
            raise field_error("beacon.path", str(exc).removeprefix("beacon.path: ")) from None
        assert path is not None
        path.check_covers(0.0, T, where="beacon.path", error=ProblemError)
    else:
        _check_craft(pb)
    if pb.vehicle.path is not None and pb.vehicle.path != LAWNMOWER_PATH:
        vehicle_path(pb)


def _check_craft(pb: ProblemData) -> None:
    """The planned beacon's craft: its limits, and its start against the vehicle's."""
    bm = pb.beacon_motion
    if bm.speed is not None and not (math.isfinite(bm.speed) and bm.speed > 0):
        raise field_error("beacon.speed", f"must be > 0 m/s, got {bm.speed}")
    if bm.accel is not None and not all(math.isfinite(a) and a > 0 for a in bm.accel):
        raise field_error("beacon.accel", f"every bound must be > 0 m/s^2, got {list(bm.accel)}")
    if not (math.isfinite(bm.min_distance) and bm.min_distance >= 0):
        raise field_error("beacon.min_distance", f"must be >= 0 m (0: none), got {bm.min_distance}")
    if bm.max_range is not None and not (math.isfinite(bm.max_range) and bm.max_range > 0):
        raise field_error("beacon.max_range", f"must be > 0 m, got {bm.max_range}")
    try:
        craft = pb.beacon_vehicle
    except InputError as exc:
        field = "velocity" if "velocity" in str(exc) else "area" if "area" in str(exc) else ""
        raise field_error(f"beacon.{field or 'position'}", str(exc)) from None
    assert craft is not None
    d = float(np.linalg.norm(pb.p0[:2] - craft.start[:2]))
    if d < craft.min_distance:
        raise field_error(
            "beacon.min_distance",
            f"the vehicle starts {d:.4g} m (horizontally) from the craft, inside "
            f"beacon.min_distance = {craft.min_distance:g} m; move one of the starts",
        )
    r = float(np.linalg.norm(pb.p0 - craft.start))
    if craft.max_range is not None and r > craft.max_range:
        raise field_error(
            "beacon.max_range",
            f"the vehicle starts {r:.4g} m from the craft, beyond beacon.max_range = "
            f"{craft.max_range:g} m",
        )


def vehicle_path(pb: ProblemData) -> Trajectory:
    """The trajectory CSV of ``vehicle.path``, checked against the problem.

    Parameters
    ----------
    pb : ProblemData
        A problem whose ``vehicle.path`` is a trajectory CSV (not ``"lawnmower"``).

    Returns
    -------
    Trajectory
        The path: of the vehicle's dimension, from t = 0 to ``horizon.duration``, starting at
        ``start.position``, every interval a multiple of ``validation.dt``.

    Raises
    ------
    ProblemError
        On ``vehicle.path``: a file that does not read, or a path that does not fit.
    """
    name = pb.vehicle.path
    assert name is not None and name != LAWNMOWER_PATH
    try:
        traj = read_csv(name)
    except (InputError, OSError) as exc:
        raise field_error("vehicle.path", str(exc)) from None
    T = pb.horizon.duration
    if traj.dim != pb.dim:
        raise field_error("vehicle.path", f"{name} is {traj.dim}D but vehicle.dim = {pb.dim}")
    if abs(traj.t[0]) > 1e-9 or abs(traj.t[-1] - T) > 1e-6 * max(1.0, T):
        raise field_error(
            "vehicle.path",
            f"{name} runs t = {traj.t[0]:g}..{traj.t[-1]:g} s; it must run from 0 to "
            f"horizon.duration = {T:g} s",
        )
    if float(np.linalg.norm(traj.p[0] - pb.p0)) > 1e-6 * max(1.0, float(np.linalg.norm(pb.p0))):
        raise field_error(
            "vehicle.path",
            f"{name} starts at {traj.p[0].tolist()}, not at start.position = {list(pb.p0)}",
        )
    try:
        resample(traj, pb.validation.dt)
    except InputError as exc:
        raise field_error("vehicle.path", f"{name}: {exc}") from None
    return traj


def unordered(pb: ProblemData) -> bool:
    """``mission.order = "free"`` and the lines not yet put in the order flown.

    Parameters
    ----------
    pb : ProblemData
        The problem.

    Returns
    -------
    bool
        True when the mission's free order is still to be resolved (:func:`order_lines`).
    """
    m = pb.mission
    return m is not None and m.order == "free" and bool(m.lines) and not m.flown_as


def order_lines(pb: P) -> P:
    """``pb`` with a free line order resolved (:func:`~obsplan.planning.missions.order.free_order`,
    then the mission's fit checked); any other problem unchanged. The loader runs it.

    Parameters
    ----------
    pb : ProblemData
        The problem (a :class:`~obsplan.planning.problem.definition.PlanningProblem`: the copy is
        checked again on construction).

    Returns
    -------
    ProblemData
        Of the type of ``pb``: its mission's ``lines`` in the order and direction flown, and
        ``flown_as`` set.

    Raises
    ------
    ProblemError
        On ``horizon.duration`` or ``mission.lead_in`` when the ordered mission does not fit the
        horizon.
    """
    if not unordered(pb):
        return pb
    return replace(pb, mission=free_order(pb.mission_context))


def _check_mission(pb: ProblemData) -> None:
    """The mission's fields against each other and the limits (the horizon: in
    :func:`~obsplan.planning.missions.schedule.mission_fit_error`)."""
    m, n = pb.mission, pb.dim
    assert m is not None
    if m.kind not in MISSION_KINDS:
        raise field_error(
            "mission.kind", f"must be one of {', '.join(MISSION_KINDS)}, got {m.kind!r}"
        )
    if m.order not in MISSION_ORDERS:
        raise field_error("mission.order", f'must be "given" or "free", got {m.order!r}')
    if m.flown_as and sorted(i for i, _ in m.flown_as) != list(range(len(m.lines))):
        raise field_error(
            "mission.flown_as",
            f"names {len(m.flown_as)} lines flown, not a reordering of the {len(m.lines)} lines; "
            'give the lines as given with order = "free" and flown_as empty (it is resolved)',
        )
    if m.order == "free" and len(m.lines) > MAX_FREE_LINES:
        raise field_error(
            "mission.order",
            f'"free" searches the order of up to {MAX_FREE_LINES} lines, the mission has '
            f'{len(m.lines)}; use order = "given" (generated lines are flown boustrophedon) or '
            "split the survey",
        )
    if not 0.0 <= m.shift < 0.5:
        raise field_error(
            "mission.shift",
            f"must be in [0, 0.5) (a fraction of each line's time), got {m.shift:g}",
        )
    if isinstance(m.lead_in, str):
        if m.lead_in != "auto":
            raise field_error(
                "mission.lead_in", f'must be a time in s or "auto", got {m.lead_in!r}'
            )
    elif not (math.isfinite(m.lead_in) and m.lead_in >= 0):
        raise field_error("mission.lead_in", f'must be a time >= 0 s or "auto", got {m.lead_in!r}')
    budget.check_lines(len(m.lines), "mission.lines", error=ProblemError)
    budget.check_waypoints(len(m.waypoints), "mission.waypoints", ProblemError)
    budget.check_waypoints(len(m.windows), "mission.windows", ProblemError)
    if m.kind == "survey" and not m.lines:
        raise field_error("mission.lines", "a survey needs lines (or mission.area + spacing)")
    if m.kind == "waypoints" and not m.waypoints:
        raise field_error("mission.waypoints", 'kind = "waypoints" needs mission.waypoints')
    if m.kind == "survey" and m.waypoints:
        raise field_error("mission.waypoints", 'waypoints need mission.kind = "waypoints"')
    if m.windows and len(m.windows) != len(m.waypoints):
        raise field_error(
            "mission.windows",
            f"expected one window per waypoint ({len(m.waypoints)}), got {len(m.windows)}",
        )
    for i, (t0, t1) in enumerate(m.windows):
        if not 0 <= t0 < t1:
            raise field_error(f"mission.windows[{i}]", f"must be 0 <= t0 < t1 s, got [{t0}, {t1}]")
    for i, ln in enumerate(m.lines):
        if len(ln) != 2 * n:
            raise field_error(
                f"mission.lines[{i}]", f"expected {2 * n} numbers (vehicle.dim = {n})"
            )
    for i, w in enumerate(m.waypoints):
        if len(w) != n:
            raise field_error(f"mission.waypoints[{i}]", f"expected {n} numbers")
    check_mission_geometry(m, n)
    _check_mission_tolerances(pb)


def _check_mission_tolerances(pb: ProblemData) -> None:
    m, lim = pb.mission, pb.limits
    assert m is not None
    if not m.cross_track > 0:
        raise field_error("mission.cross_track", f"must be > 0 m, got {m.cross_track}")
    if not 0 < m.heading_tol < 90:
        raise field_error("mission.heading_tol", f"must be in (0, 90) deg, got {m.heading_tol}")
    if not m.radius > 0:
        raise field_error("mission.radius", f"must be > 0 m, got {m.radius}")
    lo, hi = m.speed_band(lim.speed)
    if not 0 < lo < hi or hi > lim.speed * (1 + 1e-12):
        raise field_error(
            "mission.speed",
            f"[{lo:g}, {hi:g}] m/s must satisfy 0 < lo < hi <= limits.speed = {lim.speed:g}",
        )
    if lim.min_speed > lo:
        raise field_error(
            "mission.speed", f"lo = {lo:g} m/s is below limits.min_speed = {lim.min_speed:g}"
        )
    margin = float(np.linalg.norm(pb.accel)) * pb.horizon.dt**2 / 8.0
    if margin >= 0.5 * m.cross_track:
        raise field_error(
            "horizon.steps",
            f"between nodes the path may leave a line by |a| h^2 / 8 = {margin:.3g} m at the "
            f"planning step h = {pb.horizon.dt:.3g} s, too much of mission.cross_track = "
            f"{m.cross_track:g} m; use more horizon.steps",
        )
    _check_altitude_band(pb)
    if m.end is not None:
        if len(m.end.position) != pb.dim:
            raise field_error("mission.end.position", f"expected {pb.dim} numbers")
        if not m.end.radius > 0:
            raise field_error("mission.end.radius", f"must be > 0 m, got {m.end.radius}")
        if m.end.speed is not None and not m.end.speed >= 0:
            raise field_error("mission.end.speed", f"must be >= 0 m/s, got {m.end.speed}")
        if m.end.speed is not None and lim.min_speed > m.end.speed:
            raise field_error(
                "mission.end.speed", f"is below limits.min_speed = {lim.min_speed:g} m/s"
            )
    _check_lines_inside(pb)


def _check_altitude_band(pb: ProblemData) -> None:
    """An altitude band: 3D survey lines at its middle above the seabed, wider than the path
    may bend vertically between nodes."""
    m = pb.mission
    assert m is not None
    if m.altitude is None:
        if m.seabed is not None:
            raise field_error("mission.seabed", "is for an altitude band; give mission.altitude")
        return
    if pb.dim != 3:
        raise field_error("mission.altitude", "an altitude band needs vehicle.dim = 3")
    if m.kind != "survey":
        raise field_error("mission.altitude", 'is for survey lines (kind = "survey")')
    if m.seabed is None:
        raise field_error("mission.seabed", "missing; the altitude band is above it: {depth = d}")
    lo, hi = m.altitude
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise field_error(
            "mission.altitude", f"must be [lo, hi] with 0 < lo < hi m, got {m.altitude}"
        )
    row = m.altitude_row()
    assert row is not None
    w, half = row
    mid = 0.5 * (lo + hi)
    for i, (a, b) in enumerate(m.segments(3)):
        for pt in (a, b):
            # 1e-6 m: the round-off of a line computed from the seabed and written back
            if abs(float(m.seabed.depth_at(pt[:2])) - pt[2] - mid) > 1e-6:
                raise field_error(
                    f"mission.lines[{i}]",
                    f"its depth {pt[2]:g} m is not the seabed's minus the band's middle "
                    f"({mid:g} m); give the lines as horizontal tracks [x0, y0, x1, y1]",
                )
    bend = float(np.abs(w) @ np.asarray(pb.accel, float)) * pb.horizon.dt**2 / 8.0
    if bend >= 0.5 * half:
        raise field_error(
            "horizon.steps",
            f"between nodes the altitude may change by {bend:.3g} m at the planning step "
            f"h = {pb.horizon.dt:.3g} s, too much of the half width {half:g} m of "
            "mission.altitude; use more horizon.steps or a wider band",
        )


def _check_lines_inside(pb: ProblemData) -> None:
    """Every line inside the operating area and depth band and clear of the beacon."""
    m, lim = pb.mission, pb.limits
    assert m is not None
    b = np.asarray(pb.beacon, float)
    for i, (a, e) in enumerate(m.segments(pb.dim)):
        where = f"mission.lines[{i}]"
        for pt in (a, e):
            if lim.area is not None and not (
                lim.area.x[0] <= pt[0] <= lim.area.x[1] and lim.area.y[0] <= pt[1] <= lim.area.y[1]
            ):
                raise field_error(where, f"leaves limits.area at ({pt[0]:g}, {pt[1]:g}) m")
            if lim.depth is not None and not lim.depth[0] <= pt[2] <= lim.depth[1]:
                raise field_error(where, f"depth {pt[2]:g} m is outside limits.depth")
        d = e - a
        s = float(np.clip((b - a) @ d / (d @ d), 0.0, 1.0))
        near = float(np.linalg.norm(a + s * d - b))
        if lim.min_range > 0 and near < lim.min_range + m.cross_track:
            raise field_error(
                where,
                f"passes {near:.3g} m from the beacon: within limits.min_range = "
                f"{lim.min_range:g} m plus mission.cross_track; move the line",
            )


def _check_vehicle(pb: ProblemData) -> None:
    veh, lim = pb.vehicle, pb.limits
    n = veh.dim
    if n not in (2, 3):
        raise field_error("vehicle.dim", f"must be 2 or 3, got {n!r}")
    if veh.range_form not in ("half-squared", "range"):
        raise field_error(
            "vehicle.range_form", f'must be "half-squared" or "range", got {veh.range_form!r}'
        )
    try:
        sensors = parse_sensors(veh.sensors)
        VehicleModel(dim=n, sensors=sensors, current=veh.current)
    except ConfigError as exc:
        raise field_error("vehicle.sensors", str(exc)) from None
    for where, vec in (
        ("vehicle.current_velocity", veh.current_velocity),
        ("beacon.position", pb.beacon),
        ("start.position", pb.start_position),
        ("start.velocity", pb.start_velocity),
        ("limits.accel", lim.accel),
    ):
        if len(vec) != n or not all(math.isfinite(float(x)) for x in vec):
            raise field_error(
                where, f"expected {n} finite numbers (vehicle.dim = {n}), got {vec!r}"
            )
    if any(x != 0.0 for x in veh.current_velocity) and not veh.current:
        raise field_error(
            "vehicle.current_velocity",
            "is non-zero but vehicle.current = false; set current = true to model it",
        )


def _check_motion(pb: ProblemData) -> None:
    lim, n = pb.limits, pb.dim
    if any(not a > 0 for a in lim.accel):
        raise field_error("limits.accel", f"every bound must be > 0 m/s^2, got {list(lim.accel)}")
    if not lim.speed > 0:
        raise field_error("limits.speed", f"must be > 0 m/s, got {lim.speed}")
    for where, vec in (
        ("beacon.position", pb.beacon),
        ("start.position", pb.start_position),
        ("start.velocity", pb.start_velocity),
        ("limits.accel", lim.accel),
        ("limits.speed", (lim.speed,)),
    ):
        if any(abs(float(x)) > MAX_MAGNITUDE for x in vec):
            raise field_error(
                where, f"{list(vec)} is beyond {MAX_MAGNITUDE:g} in SI units; check the units"
            )
    speed0 = float(np.linalg.norm(pb.v0))
    if speed0 > lim.speed:
        raise field_error(
            "start.velocity",
            f"start speed {speed0:.4g} m/s exceeds limits.speed = {lim.speed:g} m/s; "
            "lower the start velocity or raise the limit",
        )
    if lim.depth is not None:
        if n != 3:
            raise field_error("limits.depth", "a depth band needs vehicle.dim = 3")
        lo, hi = lim.depth
        z0 = pb.start_position[2]
        if not lo <= z0 <= hi:
            raise field_error(
                "limits.depth",
                f"band [{lo:g}, {hi:g}] m does not contain the start depth "
                f"start.position[2] = {z0:g} m",
            )
    if lim.area is not None:
        a = lim.area
        x0, y0 = pb.start_position[0], pb.start_position[1]
        if not (a.x[0] <= x0 <= a.x[1] and a.y[0] <= y0 <= a.y[1]):
            raise field_error(
                "limits.area",
                f"x = [{a.x[0]:g}, {a.x[1]:g}], y = [{a.y[0]:g}, {a.y[1]:g}] m does not contain "
                f"the start ({x0:g}, {y0:g}) m",
            )


def _check_horizon(pb: ProblemData) -> None:
    hor = pb.horizon
    if not (math.isfinite(hor.duration) and hor.duration > 0):
        raise field_error("horizon.duration", f"must be > 0 s, got {hor.duration}")
    if hor.duration > MAX_DURATION_S:
        raise field_error(
            "horizon.duration",
            f"{hor.duration:g} s is beyond the planner's range ({MAX_DURATION_S:g} s, "
            f"{MAX_DURATION_S / 86400:.3g} days); plan the mission in shorter pieces",
        )
    if hor.steps < 2:
        raise field_error("horizon.steps", f"must be at least 2, got {hor.steps}")
    if hor.steps > MAX_STEPS:
        raise field_error(
            "horizon.steps",
            f"{hor.steps} exceeds the planner's limit of {MAX_STEPS} constant-acceleration "
            f"intervals (the solve would take hours); use at most {MAX_STEPS} "
            f"(a step of {hor.duration / MAX_STEPS:.3g} s or longer)",
        )


def _check_objective(pb: ProblemData) -> None:
    obj, val = pb.objective, pb.validation
    if obj.kind not in OBJECTIVES:
        raise field_error(
            "objective.kind", f"unknown objective {obj.kind!r}; choose from {', '.join(OBJECTIVES)}"
        )
    if obj.mode not in MODES:
        raise field_error("objective.mode", f"must be one of {', '.join(MODES)}, got {obj.mode!r}")
    if obj.mode != "auto" and obj.kind not in TIMED_OBJECTIVES:
        raise field_error(
            "objective.mode",
            f"{obj.kind} has no time mode (only {', '.join(TIMED_OBJECTIVES)} do); remove "
            'objective.mode or set it to "auto"',
        )
    if obj.starts < 1:
        raise field_error("objective.starts", f"must be at least 1, got {obj.starts}")
    budget.check_starts(obj.starts, "objective.starts", ProblemError)
    if obj.max_iter < 1:
        raise field_error("objective.max_iter", f"must be at least 1, got {obj.max_iter}")
    budget.check_iterations(obj.max_iter, "objective.max_iter", ProblemError)
    if obj.tol is not None and not 0 < obj.tol < 1:
        raise field_error("objective.tol", f"must be in (0, 1), got {obj.tol}")
    if obj.pcrb_weight is not None:
        if obj.kind != "kf-position-std":
            raise field_error(
                "objective.pcrb_weight",
                f"only kf-position-std has a posterior-CRB weight, not {obj.kind}; remove it",
            )
        if not (np.isfinite(obj.pcrb_weight) and obj.pcrb_weight >= 0):
            raise field_error(
                "objective.pcrb_weight",
                f"must be a finite number >= 0 (0: the KF's std alone), got {obj.pcrb_weight}",
            )
    lb = obj.linearisation_bound
    if lb is not None and not (np.isfinite(lb) and lb >= 0):
        raise field_error(
            "objective.linearisation_bound",
            f"must be a finite number of range stds >= 0 (0: off), got {lb}",
        )
    for est, what in (("kf", "KF std"), ("ekf", "posterior CRB")):
        kg = getattr(obj, f"{est}_guard")
        if kg is not None and not (np.isfinite(kg) and kg >= 0):
            raise field_error(
                f"objective.{est}_guard",
                f"must be a finite multiple of the lawn-mower's {what} >= 0 (0: off), got {kg}",
            )
    if obj.robust_aggregate not in ("worst", "mean"):
        raise field_error(
            "objective.robust_aggregate", f'must be "worst" or "mean", got {obj.robust_aggregate!r}'
        )
    if (obj.robust_prior or obj.robust_range_noise) and obj.kind not in TIMED_OBJECTIVES:
        raise field_error(
            "objective.robust_prior" if obj.robust_prior else "objective.robust_range_noise",
            f"robust planning needs an estimator objective ({', '.join(TIMED_OBJECTIVES)}), not "
            f"{obj.kind}; change objective.kind or remove the robust_* fields",
        )
    for name in ("stress_prior", "stress_range_noise"):
        if not getattr(val, name) > 0:
            raise field_error(
                f"validation.{name}", f"must be a multiple > 0, got {getattr(val, name)}"
            )
    if obj.seed < 0 or val.seed < 0:
        raise field_error("objective.seed" if obj.seed < 0 else "validation.seed", "must be >= 0")
    _check_windows(pb)


def _check_windows(pb: ProblemData) -> None:
    obj = pb.objective
    if obj.weights not in ("information", "none"):
        raise field_error(
            "objective.weights", f'must be "information" or "none", got {obj.weights!r}'
        )
    if obj.system not in ("auto", "linearised", "augmented"):
        raise field_error(
            "objective.system",
            f'must be "auto", "linearised" or "augmented", got {obj.system!r}',
        )
    if obj.anchor not in ("start", "current"):
        raise field_error("objective.anchor", f'must be "start" or "current", got {obj.anchor!r}')
    for name, names in (("window", ("auto", "mission")), ("stride", ("auto",))):
        val = getattr(obj, name)
        if isinstance(val, str):
            if val not in names:
                choices = " or ".join(f'"{n}"' for n in names)
                raise field_error(
                    f"objective.{name}", f"must be a length in s or {choices}, got {val!r}"
                )
        elif not 0 < val <= MAX_DURATION_S:
            raise field_error(f"objective.{name}", f"must be a positive length in s, got {val!r}")


def _check_channel(val: ValidationSpec) -> None:
    """``validation.channel``, its ``channel_*`` fields and ``gate``: errors name the field."""
    if val.channel not in CHANNEL_PRESETS:
        names = ", ".join(CHANNEL_PRESETS)
        raise field_error("validation.channel", f"must be one of {names}, got {val.channel!r}")
    if val.stress_channel is not None and val.stress_channel not in CHANNEL_PRESETS:
        names = ", ".join(CHANNEL_PRESETS)
        raise field_error(
            "validation.stress_channel",
            f"must be one of {names} (or left out: no channel row), got {val.stress_channel!r}",
        )
    for key, name in CHANNEL_KEYS.items():
        v = getattr(val, key)
        if v is not None:
            try:
                channel_preset("ideal", **{name: v})
            except ConfigError as exc:
                raise field_error(f"validation.{key}", str(exc).split(" ", 2)[-1]) from None
    for f in ("scale_state", "bias_state"):
        if getattr(val, f) not in ("auto", "on", "off"):
            raise field_error(
                f"validation.{f}", f'must be "auto", "on" or "off", got {getattr(val, f)!r}'
            )
    g = val.gate
    if isinstance(g, str) and g not in ("auto", "off") or not isinstance(g, str) and not 0 < g < 1:
        raise field_error(
            "validation.gate", f'must be a confidence in (0, 1), "auto" or "off", got {g!r}'
        )


def _check_validation(pb: ProblemData) -> None:
    hor, val = pb.horizon, pb.validation
    _check_channel(val)
    if val.runs < 1:
        raise field_error("validation.runs", f"must be at least 1, got {val.runs}")
    for name in (
        "dt",
        "range_rate",
        "range_std",
        "dvl_rate",
        "dvl_std",
        "depth_rate",
        "depth_std",
        "init_pos_error",
        "init_vel_error",
    ):
        x = getattr(val, name)
        if not (math.isfinite(x) and x > 0):
            raise field_error(f"validation.{name}", f"must be > 0, got {x}")
    if not (math.isfinite(val.accel_noise) and val.accel_noise >= 0):
        raise field_error(
            "validation.accel_noise",
            f"must be an intensity >= 0 in m/s^2/sqrt(Hz), got {val.accel_noise}",
        )
    if val.mode not in VALIDATION_MODES:
        raise field_error(
            "validation.mode", f"must be one of {', '.join(VALIDATION_MODES)}, got {val.mode!r}"
        )
    if val.process_noise_model not in PROCESS_NOISE_MODELS:
        raise field_error(
            "validation.process_noise_model",
            f"must be one of {', '.join(PROCESS_NOISE_MODELS)}, got {val.process_noise_model!r}",
        )
    if val.ekf_update not in EKF_UPDATES:
        raise field_error(
            "validation.ekf_update",
            f"must be one of {', '.join(EKF_UPDATES)}, got {val.ekf_update!r}",
        )
    if val.navigation not in NAVIGATION_FILTERS:
        raise field_error(
            "validation.navigation",
            f"must be one of {', '.join(NAVIGATION_FILTERS)}, got {val.navigation!r}",
        )
    if val.max_runs < 1:
        raise field_error("validation.max_runs", f"must be at least 1, got {val.max_runs}")
    budget.check_max_runs(val.max_runs, "validation.max_runs", ProblemError)
    ratio = hor.dt / val.dt
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
        raise field_error(
            "validation.dt",
            f"the filter step {val.dt:g} s must divide the planning step "
            f"horizon.duration / horizon.steps = {hor.dt:g} s",
        )
    fitted = {"range_rate": True}
    fitted["dvl_rate"] = any(s.startswith("dvl") for s in pb.model.sensors)
    fitted["depth_rate"] = "depth" in pb.model.sensors
    for name in ("range_rate", "dvl_rate", "depth_rate"):
        # a sensor that is not fitted keeps its default rate and must not veto the filter step
        if fitted[name] and getattr(val, name) > 1.0 / val.dt * (1 + 1e-9):
            raise field_error(
                f"validation.{name}",
                f"{getattr(val, name):g} Hz is faster than the filter step "
                f"validation.dt = {val.dt:g} s allows",
            )
    if hor.duration * val.range_rate < 2:
        raise field_error(
            "validation.range_rate",
            f"gives fewer than 2 ranges over horizon.duration = {hor.duration:g} s",
        )
    _check_ping_times(pb)


#: How far ``validation.range_rate`` may be from a ping schedule's mean rate (a factor).
PING_RATE_FACTOR = 1.5


def _check_ping_times(pb: ProblemData) -> None:
    """``validation.range_times``: a readable schedule with 2 pings in the horizon, and
    ``range_rate`` its mean rate (the Gramian and LWO objectives weigh ranges by the rate)."""
    if pb.validation.range_times is None:
        return
    try:
        t = pb.range_times
    except InputError as exc:
        raise field_error(
            "validation.range_times", str(exc).removeprefix("validation.range_times: ")
        ) from None
    assert t is not None
    T, rate = pb.horizon.duration, pb.validation.range_rate
    inside = int(np.sum(t <= T))
    if inside < 2:
        raise field_error(
            "validation.range_times",
            f"has {inside} ping(s) within horizon.duration = {T:g} s; the filters need at least 2",
        )
    mean = inside / T
    if not (mean / PING_RATE_FACTOR <= rate <= mean * PING_RATE_FACTOR):
        raise field_error(
            "validation.range_rate",
            f"{rate:g} Hz, but validation.range_times has {inside} pings in "
            f"{T:g} s ({mean:.3g} Hz on average); set range_rate = {mean:.3g}",
        )


def _check_budget(pb: ProblemData) -> None:
    lim, hor, val, n = pb.limits, pb.horizon, pb.validation, pb.dim
    reach = 0.5 * min(lim.accel) * hor.duration**2
    if reach < val.range_std:
        raise field_error(
            "limits.accel",
            f"at {min(lim.accel):g} m/s^2 the inputs move the vehicle at most {reach:.3g} m over "
            f"the horizon (a T^2 / 2), less than the range noise validation.range_std = "
            f"{val.range_std:g} m: no path can excite the observability; raise the limit or "
            "lengthen horizon.duration",
        )
    samples = hor.duration / val.dt + 1
    budget.check_monte_carlo(
        val.runs,
        samples,
        n,
        "validation.runs",
        "a longer validation.dt",
        ProblemError,
        samples_field="validation.dt",
    )
    # the doubling validation may reach max_runs: its cost is bounded now, not after hours
    budget.check_monte_carlo(
        val.max_runs, samples, n, "validation.max_runs", "a longer validation.dt", ProblemError
    )
    obj = pb.objective
    cost = budget.planning_cost(hor.steps, obj.starts, obj.max_iter)
    budget.check_cost(cost, "objective.starts", "use fewer starts or steps", ProblemError)


def _margins(pb: ProblemData) -> tuple[float, float]:
    """Between-node margins of the range and speed limits (see
    :mod:`obsplan.planning.solver.formulation`).

    Returns ``(tau, a_norm)``: the planner enforces the limits at nodes and midpoints, each point
    covering ``±tau = h/4`` of the path, where the distance to the beacon moves by at most
    ``|v| tau + a_norm tau² / 2`` and the speed by at most ``a_norm tau``.
    """
    return pb.horizon.dt / 4.0, float(np.linalg.norm(pb.accel))


#: ``limits.min_range`` when a problem does not set it [m] (the schema's default).
DEFAULT_MIN_RANGE: float = next(s.default for s in SCHEMA["limits"] if s.name == "min_range")


def check_start_clear(
    start: Sequence[float] | np.ndarray,
    beacon: Sequence[float] | np.ndarray,
    min_range: float = DEFAULT_MIN_RANGE,
    *,
    where: str = "start.position",
    fix: str = "move the start away from the beacon or lower limits.min_range",
) -> float:
    """Refuse a start closer to the beacon than ``min_range`` (the geometry every plan refuses:
    a range of 0 has no bearing, and an EKF linearised there diverges); returns the distance.

    Parameters
    ----------
    start, beacon
        Positions [m].
    min_range
        The least distance [m] (a problem's ``limits.min_range``; default the schema's).
    where
        What the error names first: ``start.position`` for a problem, an option elsewhere
        (``obsplan simulate --beacon``).
    fix
        What to do about it, for the message.

    Returns
    -------
    float
        The distance from ``start`` to ``beacon`` [m].

    Raises
    ------
    ProblemError
        ``"<where>: the start is r m from the beacon, inside limits.min_range = ... m; <fix>"``.
    """
    r0 = float(np.linalg.norm(np.asarray(start, float) - np.asarray(beacon, float)))
    if r0 < min_range:
        raise field_error(
            where,
            f"the start is {r0:.4g} m from the beacon, inside limits.min_range = "
            f"{min_range:g} m; {fix}",
        )
    return r0


def _check_range_and_speed_limits(pb: ProblemData) -> None:
    lim = pb.limits
    for name in ("min_range", "min_speed"):
        x = getattr(lim, name)
        if not (math.isfinite(x) and x >= 0):
            raise field_error(f"limits.{name}", f"must be >= 0 (0 disables it), got {x}")
    c = lim.keepout_confidence
    if not (isinstance(c, int | float) and math.isfinite(c) and 0 <= c < 1):
        raise field_error(
            "limits.keepout_confidence",
            f"must be a probability in [0, 1) such as 0.999 (0 disables the margins), got {c!r}",
        )
    r0 = check_start_clear(pb.p0, pb.beacon_start, lim.min_range)
    tau, a = _margins(pb)
    s0 = float(np.linalg.norm(pb.v0))
    need = lim.min_range + s0 * tau + 0.5 * a * tau**2 if lim.min_range > 0 else 0.0
    if r0 < need:
        raise field_error(
            "horizon.steps",
            f"the start is {r0:.4g} m from the beacon; between nodes the planner keeps "
            f"limits.min_range = {lim.min_range:g} m with a margin |v0| h/4 + |a| h^2/32 = "
            f"{need - lim.min_range:.3g} m at the planning step h = {pb.horizon.dt:.3g} s, which "
            "the start does not have: use more horizon.steps (a shorter step), or move the "
            "start away from the beacon",
        )
    if lim.max_range is not None:
        if not (math.isfinite(lim.max_range) and lim.max_range > lim.min_range):
            raise field_error(
                "limits.max_range",
                f"must be a distance above limits.min_range = {lim.min_range:g} m, got "
                f"{lim.max_range}",
            )
        reach = r0 + s0 * tau + 0.5 * a * tau**2
        if reach > lim.max_range:
            raise field_error(
                "start.position",
                f"the start is {r0:.4g} m from the beacon, beyond (or too close to) "
                f"limits.max_range = {lim.max_range:g} m; move the start or raise max_range",
            )
    if lim.min_speed > 0:
        if lim.min_speed >= lim.speed:
            raise field_error(
                "limits.min_speed",
                f"{lim.min_speed:g} m/s must be below limits.speed = {lim.speed:g} m/s",
            )
        w0 = float(np.linalg.norm(pb.v0 - pb.current_array))
        need_w = lim.min_speed + a * tau
        if w0 < need_w:
            raise field_error(
                "start.velocity",
                f"the speed through the water at the start, |v0 - v_f| = {w0:.4g} m/s, is below "
                f"limits.min_speed = {lim.min_speed:g} m/s plus the planner's between-node "
                f"margin ({need_w:.4g} m/s in all); start the vehicle moving or lower min_speed",
            )


def check_structure(pb: ProblemData) -> None:
    """Refuse an objective that the sensors make impossible for every input (before solving).

    Parameters
    ----------
    pb : ProblemData
        The problem: its ``objective.kind`` against its vehicle's sensors and current.

    Raises
    ------
    ProblemError
        On ``objective.kind`` when the structural rank its kind needs
        (:attr:`~obsplan.planning.problem.schema.ObjectiveKind.structure`) is out of reach; on
        ``mission.order`` when a free line order was never resolved (:func:`order_lines`).
    """
    if unordered(pb):
        raise field_error(
            "mission.order",
            '"free": the lines were never put in the order flown; build the problem with '
            "load_problem or problem_from_dict (they order them), or order them with "
            "obsplan.planning.problem.checks.order_lines",
        )
    veh = pb.vehicle
    model = VehicleModel(dim=veh.dim, sensors=parse_sensors(veh.sensors), current=veh.current)
    msg = _structure_error(pb.objective.kind, model)
    if msg is not None:
        raise field_error("objective.kind", msg)


@cache
def _structure_error(kind: str, model: VehicleModel) -> str | None:
    need = OBJECTIVE_KINDS[kind].structure
    if need == "lwo":
        r = lwo_structural_max_rank(model)
        if r < model.state_dim:
            return (
                f"{kind} is impossible with sensors {','.join(model.sensors)} in "
                f"{model.dim}D: the LWO matrix has rank at most {r} < {model.state_dim} for every "
                "state and input (e.g. 3D range-only, eq. 38); add a DVL or depth sensor, or use "
                "a gramian-* objective"
            )
    elif need == "gramian":
        r, m = gramian_generic_rank(model)
        if r < m:
            return (
                f"{kind} is impossible with sensors {','.join(model.sensors)}"
                f"{' and an unknown current' if model.current else ''}: the augmented Gramian has "
                f"rank {r} < {m} for every input (section 4.3); use kf-position-std or change "
                "the sensors"
            )
    return None


@cache
def gramian_generic_rank(model: VehicleModel) -> tuple[int, int]:
    """Rank of the augmented Gramian for a generic (seeded random) input, and its size.

    The Gramian's rank is the same for almost every input, so one random, richly exciting input
    gives the structural rank: a deficit here is a deficit for every input (e.g. an unknown
    current with bottom-lock DVL, section 4.3).

    Returns
    -------
    (rank, state_dim) of the augmented model.
    """
    rng = np.random.default_rng(12345)
    n = model.dim
    t = np.linspace(0.0, 100.0, 41)
    traj = Trajectory.from_inputs(
        t, rng.normal(size=n) * 10, rng.normal(size=n), rng.normal(size=(40, n))
    )
    aug = augmented_model(model)
    return int(numerical_rank(gramian(traj, aug, rank_scales(traj)))), aug.state_dim
