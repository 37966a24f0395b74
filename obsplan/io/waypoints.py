"""Waypoints for autopilots that fly straight legs, and QGroundControl ``.plan`` missions.

A plan is a piecewise-quadratic path: on each hold ``[t_k, t_{k+1})`` the position is
``p_k + v_k τ + ½ u_k τ²``. An autopilot flies straight legs between waypoints, so the vehicle
leaves the planned path. :func:`waypoints_from_trajectory` chooses waypoints on the planned path
(every ``every`` seconds, or every ``spacing`` metres along it) and computes, **exactly** from
the quadratic pieces, per leg:

* ``cross_track``: the largest distance from the planned path to the straight leg (the segment
  between the two waypoints) — how far a vehicle following the leg is from the planned path;
* ``schedule_error``: the largest distance between the planned position at time ``t`` and the
  point of the leg flown at constant speed on schedule, ``a + (t - t_a)/(t_b - t_a) (b - a)`` —
  what also matters for the ranges' timing.

Both maxima are found from the quartic ``|q(τ)|²`` of a quadratic vector ``q`` on each piece
(roots of its cubic derivative, plus the piece ends; for the segment distance the piece is split
where the projection leaves the segment), not by sampling.

``speed`` of a waypoint is the constant speed that flies its outgoing leg on schedule (leg length
/ leg duration; the last waypoint repeats the last leg's). Geodetic output needs an origin
(:mod:`obsplan.model.frames`); a straight leg in the local frame and the one an autopilot draws
between two latitude/longitude points differ by far less than a millimetre over legs of a few
hundred metres.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from obsplan.core.atomic import atomic_file
from obsplan.core.csvtable import read_table, write_table
from obsplan.core.errors import InputError, TrajectoryFormatError
from obsplan.core.textfiles import read_json
from obsplan.model.frames import local_to_geodetic
from obsplan.trajectory.sampled import Trajectory, grid_times, position_at

#: MAVLink MAV_CMD_NAV_WAYPOINT, MAV_CMD_DO_CHANGE_SPEED.
NAV_WAYPOINT = 16
DO_CHANGE_SPEED = 178
#: MAV_FRAME_GLOBAL_RELATIVE_ALT (altitude relative to home: ArduSub's depth is -altitude),
#: MAV_FRAME_MISSION (for DO commands).
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_MISSION = 2
#: MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_TYPE_SUBMARINE.
FIRMWARE_ARDUPILOT = 3
VEHICLE_SUBMARINE = 12
#: Most waypoints an export writes (a mission of this size is already unusual).
MAX_WAYPOINTS = 100_000


@dataclass(frozen=True, eq=False)
class Waypoints:
    """Waypoints on a planned path with the tracking error of each straight leg.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Times of the waypoints [s].
    p : ndarray, shape (K, n)
        Positions in the local frame [m] (north, east[, down]).
    speed : ndarray, shape (K,)
        Speed to fly the outgoing leg on schedule [m/s] (the last repeats the last leg's).
    cross_track : ndarray, shape (K - 1,)
        Largest distance from the planned path to each straight leg [m].
    schedule_error : ndarray, shape (K - 1,)
        Largest distance between the planned position and the on-schedule point of each leg [m].
    origin : GeodeticOrigin or None
    """

    t: np.ndarray
    p: np.ndarray
    speed: np.ndarray
    cross_track: np.ndarray
    schedule_error: np.ndarray
    origin: Any = None

    @property
    def dim(self) -> int:
        return int(self.p.shape[1])

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def max_cross_track(self) -> float:
        return float(self.cross_track.max()) if self.cross_track.size else 0.0

    @property
    def max_schedule_error(self) -> float:
        return float(self.schedule_error.max()) if self.schedule_error.size else 0.0


# --------------------------------------------------------------------- exact tracking errors
def _max_sq(c0: np.ndarray, c1: np.ndarray, c2: np.ndarray, lo: float, hi: float) -> float:
    """max over τ in [lo, hi] of |c0 + c1 τ + c2 τ²|² (exact: critical points of the quartic)."""
    # d/dτ |f|² = 2 f·f', f' = c1 + 2 c2 τ: the cubic below
    coeffs = [2 * c2 @ c2, 3 * c1 @ c2, c1 @ c1 + 2 * c0 @ c2, c0 @ c1]
    cand = [lo, hi]
    scale = max(abs(x) for x in coeffs)
    if scale > 0:
        lead = next(i for i, x in enumerate(coeffs) if abs(x) > 1e-14 * scale)
        if lead < 3:
            for r in np.roots(coeffs[lead:]):
                if abs(r.imag) <= 1e-9 * max(1.0, abs(r.real)) and lo < r.real < hi:
                    cand.append(float(r.real))
    tau = np.asarray(cand)
    f = c0[None, :] + np.outer(tau, c1) + np.outer(tau**2, c2)
    return float(np.max(np.sum(f * f, axis=1)))


def _quadratic_roots(a: float, b: float, c: float, lo: float, hi: float) -> list[float]:
    """Real roots of a τ² + b τ + c strictly inside (lo, hi)."""
    scale = max(abs(a), abs(b), abs(c))
    if scale == 0:
        return []
    coeffs = [a, b, c]
    lead = next(i for i, x in enumerate(coeffs) if abs(x) > 1e-14 * scale)
    if lead == 2:
        return []
    out = []
    for r in np.roots(coeffs[lead:]):
        if abs(r.imag) <= 1e-12 * max(1.0, abs(r.real)) and lo < r.real < hi:
            out.append(float(r.real))
    return sorted(out)


def _pieces(traj: Trajectory, ta: float, tb: float):
    """Quadratic pieces (p_k, v_k, ½u_k, τ_lo, τ_hi, t_k) of the path on [ta, tb]."""
    t = traj.t
    k0 = max(int(np.searchsorted(t, ta, side="right")) - 1, 0)
    k1 = min(int(np.searchsorted(t, tb, side="left")), t.size - 1)
    for k in range(k0, max(k1, k0 + 1)):
        lo = max(ta, t[k]) - t[k]
        hi = min(tb, t[k + 1] if k + 1 < t.size else tb) - t[k]
        if hi > lo or (hi == lo and ta == tb):
            yield traj.p[k], traj.v[k], 0.5 * traj.u[k], lo, hi, t[k]


def leg_errors(traj: Trajectory, ta: float, tb: float) -> tuple[float, float]:
    """``(cross_track, schedule_error)`` [m] of the straight leg from ``p(ta)`` to ``p(tb)``.

    Parameters
    ----------
    traj : Trajectory
        The planned path (piecewise quadratic between samples).
    ta, tb : float
        Times of the leg's start and end waypoints [s], ``ta < tb``.

    Returns
    -------
    cross_track : float
        Largest distance from the planned path to the segment ``[p(ta), p(tb)]`` [m].
    schedule_error : float
        Largest distance between the planned position and the on-schedule point of the leg [m].
    """
    a, b = position_at(traj, np.array([ta, tb]))
    d = b - a
    L = float(np.linalg.norm(d))
    rate = d / (tb - ta)
    cross = sched = 0.0
    for pk, vk, hk, lo, hi, tk in _pieces(traj, ta, tb):
        # schedule: p(t) - (a + (t - ta) rate), t = tk + τ
        c0 = pk - a - (tk - ta) * rate
        sched = max(sched, _max_sq(c0, vk - rate, hk, lo, hi))
        # cross-track: distance to the segment [a, b]
        r0 = pk - a
        if L == 0.0:
            cross = max(cross, _max_sq(r0, vk, hk, lo, hi))
            continue
        e = d / L
        s0, s1, s2 = r0 @ e, vk @ e, hk @ e  # along-leg coordinate s(τ) = s0 + s1 τ + s2 τ²
        cuts = sorted({lo, hi, *_quadratic_roots(s2, s1, s0, lo, hi)})
        cuts = sorted({*cuts, *_quadratic_roots(s2, s1, s0 - L, lo, hi)})
        for x0, x1 in zip(cuts[:-1], cuts[1:], strict=False):
            mid = 0.5 * (x0 + x1)
            s_mid = s0 + s1 * mid + s2 * mid * mid
            if s_mid < 0:  # before the leg: distance to a
                q = (r0, vk, hk)
            elif s_mid > L:  # beyond it: distance to b
                q = (pk - b, vk, hk)
            else:  # beside it: perpendicular distance
                q = (r0 - s0 * e, vk - s1 * e, hk - s2 * e)
            cross = max(cross, _max_sq(*q, x0, x1))
    return math.sqrt(cross), math.sqrt(sched)


def _arc_length(traj: Trajectory, per_interval: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Dense table (times, cumulative path length [m]) by 5-point Gauss–Legendre on sub-steps."""
    t = traj.t
    fine = np.concatenate(
        [np.linspace(t[k], t[k + 1], per_interval, endpoint=False) for k in range(t.size - 1)]
        + [t[-1:]]
    )
    x, w = np.polynomial.legendre.leggauss(5)
    a, b = fine[:-1], fine[1:]
    tq = 0.5 * (b - a)[:, None] * x[None, :] + 0.5 * (a + b)[:, None]
    k = np.clip(np.searchsorted(t, tq.ravel(), side="right") - 1, 0, t.size - 2)
    tau = tq.ravel() - t[k]
    speed = np.linalg.norm(traj.v[k] + traj.u[k] * tau[:, None], axis=1).reshape(tq.shape)
    seg = 0.5 * (b - a) * (speed @ w)
    return fine, np.concatenate([[0.0], np.cumsum(seg)])


def waypoints_from_trajectory(
    traj: Trajectory,
    *,
    every: float | None = None,
    spacing: float | None = None,
    origin: Any = None,
) -> Waypoints:
    """Waypoints on ``traj`` every ``every`` seconds or every ``spacing`` metres along it.

    The first and last samples of the plan are always waypoints. Exactly one of ``every`` and
    ``spacing`` must be given.

    Parameters
    ----------
    traj : Trajectory
        The planned path.
    every : float or None, optional
        Time between waypoints [s].
    spacing : float or None, optional
        Path length between waypoints [m].
    origin : GeodeticOrigin or None, optional
        Origin of the local frame, kept for geodetic output.

    Returns
    -------
    Waypoints
        Times, positions and speeds of the waypoints, with each leg's exact tracking errors.

    Raises
    ------
    InputError
        Neither or both given, a non-positive value, or more than :data:`MAX_WAYPOINTS`.
    """
    if (every is None) == (spacing is None):
        raise InputError("give exactly one of --every SECONDS and --spacing METRES")
    value, name = (every, "--every") if every is not None else (cast(float, spacing), "--spacing")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{name} {value!r}: must be a positive number")
    t0, t1 = float(traj.t[0]), float(traj.t[-1])
    if every is not None:
        count = math.floor((t1 - t0) / every * (1 + 1e-12))
        if count + 2 > MAX_WAYPOINTS:
            raise InputError(
                f"--every {every:g} s gives {count + 2} waypoints, more than {MAX_WAYPOINTS}; "
                f"choose at least {(t1 - t0) / (MAX_WAYPOINTS - 2):.3g} s"
            )
        times = t0 + every * np.arange(count + 1)
    else:
        ft, s = _arc_length(traj)
        count = math.floor(s[-1] / spacing * (1 + 1e-12))
        if count + 2 > MAX_WAYPOINTS:
            raise InputError(
                f"--spacing {spacing:g} m gives {count + 2} waypoints along {s[-1]:.4g} m, more "
                f"than {MAX_WAYPOINTS}; choose at least {s[-1] / (MAX_WAYPOINTS - 2):.3g} m"
            )
        # invert s(t) (non-decreasing) on the dense table
        times = np.interp(spacing * np.arange(count + 1), s, ft)
    # the end is always a waypoint; drop a last one that falls within 1e-9 of it
    times = times[times < t1 - 1e-9 * max(1.0, abs(t1))]
    times = grid_times(np.unique(np.r_[times, t0, t1]))
    p = position_at(traj, times)
    legs = np.diff(times)
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / legs
    errs = np.array([leg_errors(traj, a, b) for a, b in zip(times[:-1], times[1:], strict=True)])
    return Waypoints(
        t=times,
        p=p,
        speed=np.r_[speed, speed[-1:]],
        cross_track=errs[:, 0],
        schedule_error=errs[:, 1],
        origin=origin,
    )


# --------------------------------------------------------------------- files
_METRIC = ("t", "x", "y", "z")
_GEODETIC = ("t", "latitude", "longitude", "depth")
_LEG = ("speed", "leg_cross_track", "leg_schedule_error")


def waypoint_columns(dim: int, geodetic: bool) -> list[str]:
    """Header of the waypoint CSV: ``t,x,y[,z]`` or ``t,latitude,longitude[,depth]``, then
    ``speed,leg_cross_track,leg_schedule_error``.

    Parameters
    ----------
    dim : int
        Spatial dimension (2 or 3).
    geodetic : bool
        Latitude, longitude and depth instead of local positions.

    Returns
    -------
    list of str
        The column names.
    """
    base = (_GEODETIC if geodetic else _METRIC)[: 1 + dim]
    return [*base, *_LEG]


def waypoint_rows(wp: Waypoints, geodetic: bool) -> tuple[list[str], np.ndarray]:
    """Header and numeric rows of the waypoint CSV (geodetic rows need ``wp.origin``).

    Parameters
    ----------
    wp : Waypoints
        The waypoints.
    geodetic : bool
        Write latitude [deg], longitude [deg] and depth [m] instead of local positions [m].

    Returns
    -------
    header : list of str
        :func:`waypoint_columns`.
    rows : ndarray, shape (K, len(header))
        One row per waypoint; the leg columns of the last are 0.

    Raises
    ------
    InputError
        If ``geodetic`` and the waypoints have no origin.
    """
    if geodetic:
        if wp.origin is None:
            raise InputError(
                "geodetic waypoints need an origin: give --origin LAT,LON[,ALT] or plan a "
                "problem with an [origin] section"
            )
        lat, lon, depth = local_to_geodetic(wp.p, wp.origin, "waypoint")
        pos = np.column_stack([lat, lon, depth][: wp.dim])
    else:
        pos = wp.p
    # the leg columns of the last waypoint repeat nothing: there is no outgoing leg
    leg = np.column_stack([np.r_[wp.cross_track, 0.0], np.r_[wp.schedule_error, 0.0]])
    rows = np.column_stack([wp.t, pos, wp.speed, leg])
    return waypoint_columns(wp.dim, geodetic), rows


def write_waypoints_csv(wp: Waypoints, path: str | Path, geodetic: bool = False) -> Path:
    """Write the waypoint CSV (exact ``repr`` floats; atomic). Columns: :func:`waypoint_columns`;
    ``leg_*`` of a waypoint are the tracking errors [m] of its outgoing leg (0 for the last).

    Parameters
    ----------
    wp : Waypoints
        The waypoints.
    path : str or Path
        The CSV file.
    geodetic : bool, optional
        Latitude, longitude and depth instead of local positions (needs ``wp.origin``).

    Returns
    -------
    Path
        ``path``.
    """
    header, rows = waypoint_rows(wp, geodetic)
    return write_table(path, header, rows)


def read_waypoints_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read a waypoint CSV back: ``{column: values}`` for every column of the header.

    Parameters
    ----------
    path : str or Path
        A CSV written by :func:`write_waypoints_csv`.

    Returns
    -------
    dict of str to ndarray, shape (K,)
        Each column of :func:`waypoint_columns` (local or geodetic, 2D or 3D, by the header).

    Raises
    ------
    TrajectoryFormatError
        For a missing column or a bad cell.
    """
    table = read_table(path, ",".join(waypoint_columns(2, False)))
    geodetic = "latitude" in table.columns
    dim = 3 if ("depth" if geodetic else "z") in table.columns else 2
    cols = waypoint_columns(dim, geodetic)
    data = table.numbers(cols)
    return {c: data[:, i] for i, c in enumerate(cols)}


def qgc_plan(
    wp: Waypoints,
    *,
    depth_2d: float = 0.0,
    acceptance_radius: float = 1.0,
    speed_change: float = 0.01,
) -> dict:
    """A QGroundControl plan (``fileType "Plan"``) of the waypoints for an ArduSub vehicle.

    Each waypoint is a ``SimpleItem`` with command 16 (NAV_WAYPOINT), frame 3
    (GLOBAL_RELATIVE_ALT: altitude relative to home at the surface, so ``altitude = -depth``)
    and params ``[hold 0 s, acceptance radius, pass radius 0, yaw null (unchanged), lat, lon,
    alt]``; a command 178 (DO_CHANGE_SPEED, ground speed [m/s]) item precedes a leg whose speed
    differs by more than ``speed_change`` from the previous one. ``depth_2d`` [m] is the depth
    of a 2D plan. The planned home is the origin.

    Parameters
    ----------
    wp : Waypoints
        The waypoints, with their geodetic origin.
    depth_2d : float, optional
        Depth of a 2D plan's waypoints [m], >= 0.
    acceptance_radius : float, optional
        Distance at which the autopilot counts a waypoint reached [m].
    speed_change : float, optional
        Smallest change of leg speed that gets a DO_CHANGE_SPEED item [m/s].

    Returns
    -------
    dict
        The plan document, ready for :func:`json.dumps`.

    Raises
    ------
    InputError
        Without an origin, or for a non-positive acceptance radius or a negative depth.
    """
    if wp.origin is None:
        raise InputError(
            "a QGroundControl mission needs geodetic waypoints: give --origin LAT,LON[,ALT] or "
            "plan a problem with an [origin] section"
        )
    if not (math.isfinite(acceptance_radius) and acceptance_radius > 0):
        raise InputError(
            f"acceptance radius {acceptance_radius!r}: must be a positive number of metres"
        )
    if not (math.isfinite(depth_2d) and depth_2d >= 0):
        raise InputError(f"depth {depth_2d!r}: must be a number of metres >= 0 (0: the surface)")
    lat, lon, depth = local_to_geodetic(wp.p, wp.origin, "waypoint")
    if wp.dim == 2:
        depth = np.full(lat.size, float(depth_2d))
    items: list[dict] = []
    last_speed = None

    def add(command: int, frame: int, params: list, alt: float | None = None) -> None:
        item = {
            "autoContinue": True,
            "command": command,
            "doJumpId": len(items) + 1,
            "frame": frame,
            "params": params,
            "type": "SimpleItem",
        }
        if alt is not None:
            item.update({"AMSLAltAboveTerrain": None, "Altitude": alt, "AltitudeMode": 1})
        items.append(item)

    for k in range(len(wp)):
        if k > 0 and (last_speed is None or abs(wp.speed[k - 1] - last_speed) > speed_change):
            last_speed = float(wp.speed[k - 1])
            add(DO_CHANGE_SPEED, FRAME_MISSION, [1, last_speed, -1, 0, 0, 0, 0])
        alt = -float(depth[k])
        add(
            NAV_WAYPOINT,
            FRAME_GLOBAL_RELATIVE_ALT,
            [0, float(acceptance_radius), 0, None, float(lat[k]), float(lon[k]), alt],
            alt,
        )
    o = wp.origin
    cruise = float(np.median(wp.speed))
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "obsplan",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {
            "version": 2,
            "firmwareType": FIRMWARE_ARDUPILOT,
            "vehicleType": VEHICLE_SUBMARINE,
            "cruiseSpeed": cruise,
            "hoverSpeed": cruise,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": [o.latitude, o.longitude, o.altitude],
            "items": items,
        },
    }


def write_qgc_plan(wp: Waypoints, path: str | Path, **options: Any) -> Path:
    """Write :func:`qgc_plan` as JSON (atomic).

    Parameters
    ----------
    wp : Waypoints
        The waypoints, with their geodetic origin.
    path : str or Path
        The ``.plan`` file.
    **options
        Keyword arguments of :func:`qgc_plan`.

    Returns
    -------
    Path
        ``path``.
    """
    doc = qgc_plan(wp, **options)
    path = Path(path)
    with atomic_file(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path


def _finite(x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
        raise ValueError(x)
    return float(x)


def read_qgc_plan(path: str | Path) -> dict[str, np.ndarray]:
    """The waypoints of a ``.plan`` file: ``latitude``, ``longitude``, ``altitude`` and the
    ground ``speed`` in force on the leg to each waypoint (NaN before any DO_CHANGE_SPEED).

    Parameters
    ----------
    path : str or Path
        The ``.plan`` file.

    Returns
    -------
    dict of str to ndarray, shape (K,)
        ``latitude`` and ``longitude`` [deg], ``altitude`` [m] (``-depth`` for ArduSub) and
        ``speed`` [m/s].

    Raises
    ------
    TrajectoryFormatError
        For a file that is not a QGroundControl plan or an item that is not a valid waypoint.
    """
    path = Path(path)
    doc = read_json(path, "a QGroundControl plan (.plan)", error=TrajectoryFormatError)
    try:
        if doc.get("fileType") != "Plan":
            raise ValueError('fileType is not "Plan"')
        items = doc["mission"]["items"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise TrajectoryFormatError(f"{path}: not a QGroundControl plan: {exc}") from None
    lat, lon, alt, speed = [], [], [], []
    current = math.nan
    if not isinstance(items, list):
        raise TrajectoryFormatError(f"{path}: mission.items must be a list")
    for k, it in enumerate(items):
        try:
            command = it.get("command")
            if command == DO_CHANGE_SPEED:
                current = _finite(it["params"][1])
            elif command == NAV_WAYPOINT:
                pr = it["params"]
                lat.append(_finite(pr[4]))
                lon.append(_finite(pr[5]))
                alt.append(_finite(pr[6]))
                speed.append(current)
        except (KeyError, IndexError, TypeError, ValueError, AttributeError):
            raise TrajectoryFormatError(
                f"{path}: mission item {k + 1} is not a SimpleItem with 7 numeric params"
            ) from None
    return {
        "latitude": np.asarray(lat),
        "longitude": np.asarray(lon),
        "altitude": np.asarray(alt),
        "speed": np.asarray(speed),
    }
