"""Independent check that a path completes its problem's mission, on the continuous path.

Numpy only, and independent of the planner's constraints: the path (piecewise-constant inputs,
exact quadratics between samples) is evaluated at ``check_subsamples`` points per interval. For each
survey line (in the order flown: ``mission.lines``, which ``order = "free"`` may have
reordered and reversed) the *pass* is the stretch of the path from the last time it is at or
before the line's start (along the line) to the first time after it reaches the line's end;
over the part of the pass between the two ends:

* ``coverage``: the fraction of the line's length (``coverage_bins`` stations) passed within
  the cross-track tolerance;
* ``max_cross_track_m``: the largest distance from the line;
* ``max_heading_err_deg``: the largest angle between the velocity and the line's direction;
* ``speed_range_mps``: the smallest and largest speed;
* ``altitude_range_m`` (with an altitude band): the smallest and largest altitude above the
  seabed; the cross-track is then the horizontal distance from the line's track.

A line is complete when its coverage is 1 and the three errors are within ``mission.cross_track``,
``mission.heading_tol`` and ``mission.speed`` (and the altitude inside ``mission.altitude``).
Waypoints are complete when passed in order within
``mission.radius`` (inside their windows, if any), the end region when ``|p(T) - position| <=
radius`` (and ``|v(T)| <= speed``).

``check_subsamples``, ``coverage_bins`` and the tolerances' relative slack ``check_rtol`` are
:class:`~obsplan.planning.tuning.Tuning`'s, read at call time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from obsplan.planning.missions.spec import MissionContext, Seabed
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True)
class LineCheck:
    """One survey line: see the module docstring; ``pass_s`` is the pass's ``(t0, t1)`` [s];
    ``line`` its index in ``mission.lines`` as given and ``reversed`` whether it is flown from
    its second point to its first (``mission.order = "free"``)."""

    coverage: float
    max_cross_track_m: float
    max_heading_err_deg: float
    speed_range_mps: tuple[float, float]
    pass_s: tuple[float, float]
    complete: bool
    line: int = 0
    reversed: bool = False
    altitude_range_m: tuple[float, float] | None = None

    def to_dict(self) -> dict:
        """The line's entry in the ``mission.lines`` of ``report.json``.

        Returns
        -------
        dict
            The fields as JSON numbers, booleans and lists (``altitude_range_m`` only with an
            altitude band).
        """
        out = {
            "coverage": float(self.coverage),
            "max_cross_track_m": float(self.max_cross_track_m),
            "max_heading_err_deg": float(self.max_heading_err_deg),
            "speed_range_mps": [float(self.speed_range_mps[0]), float(self.speed_range_mps[1])],
            "pass_s": [float(self.pass_s[0]), float(self.pass_s[1])],
            "complete": bool(self.complete),
            "line": int(self.line),
            "reversed": bool(self.reversed),
        }
        if self.altitude_range_m is not None:
            out["altitude_range_m"] = [float(x) for x in self.altitude_range_m]
        return out


@dataclass(frozen=True)
class PointCheck:
    """A waypoint or the end region: closest distance [m] (at the end for the region), when
    [s], the final speed [m/s] for the region, and whether it is met."""

    distance_m: float
    time_s: float
    speed_mps: float | None
    complete: bool

    def to_dict(self) -> dict:
        """The point's entry in ``report.json`` (a waypoint, or the mission's ``end``).

        Returns
        -------
        dict
            The fields as JSON numbers and booleans (``speed_mps`` None for a waypoint).
        """
        return {
            "distance_m": float(self.distance_m),
            "time_s": float(self.time_s),
            "speed_mps": None if self.speed_mps is None else float(self.speed_mps),
            "complete": bool(self.complete),
        }


@dataclass(frozen=True)
class MissionCheck:
    """Whether a path completes the mission, line by line and point by point."""

    complete: bool
    lines: tuple[LineCheck, ...]
    waypoints: tuple[PointCheck, ...]
    end: PointCheck | None
    mission_time_s: float
    path_length_m: float

    def to_dict(self) -> dict:
        """The ``mission`` entry of ``report.json``.

        Returns
        -------
        dict
            ``complete``, ``lines`` and ``waypoints`` (lists of their entries), ``end`` (None
            without an end region), ``mission_time_s`` [s] and ``path_length_m`` [m].
        """
        return {
            "complete": bool(self.complete),
            "lines": [ln.to_dict() for ln in self.lines],
            "waypoints": [w.to_dict() for w in self.waypoints],
            "end": None if self.end is None else self.end.to_dict(),
            "mission_time_s": float(self.mission_time_s),
            "path_length_m": float(self.path_length_m),
        }

    def line_mask(self, t: np.ndarray) -> np.ndarray:
        """Boolean mask of the times ``t`` [s] inside a line's pass.

        Parameters
        ----------
        t : ndarray, shape (J,)
            Times [s] from the start of the path.

        Returns
        -------
        ndarray of bool, shape (J,)
            True where ``t`` falls inside some line's ``pass_s`` (ends included, 1e-9 s slack).
        """
        t = np.asarray(t, float)
        mask = np.zeros(t.size, bool)
        for ln in self.lines:
            mask |= (t >= ln.pass_s[0] - 1e-9) & (t <= ln.pass_s[1] + 1e-9)
        return mask


def _dense(traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, positions and velocities at ``check_subsamples`` points per interval (and the
    end)."""
    h = np.diff(traj.t)
    subsamples = tuning().check_subsamples
    sig = np.arange(subsamples) / subsamples
    s = h[:, None] * sig[None, :]  # (K, S)
    t = (traj.t[:-1, None] + s).reshape(-1)
    p = traj.p[:-1, None, :] + traj.v[:-1, None, :] * s[..., None]
    p = p + 0.5 * traj.u[:-1, None, :] * s[..., None] ** 2
    v = traj.v[:-1, None, :] + traj.u[:-1, None, :] * s[..., None]
    n = traj.p.shape[1]
    t = np.append(t, traj.t[-1])
    p = np.vstack([p.reshape(-1, n), traj.p[-1:]])
    v = np.vstack([v.reshape(-1, n), traj.v[-1:]])
    return t, p, v


def _line(
    t: np.ndarray,
    p: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    first: int,
    tol,
    band: tuple[Seabed, tuple[float, float]] | None = None,
) -> tuple[LineCheck, int]:
    """The check of the line ``a -> b`` on the dense path from index ``first`` (``band``: the
    seabed and the altitude band)."""
    m_tol, h_tol, (lo, hi) = tol
    tun = tuning()
    rtol = tun.check_rtol
    length = float(np.linalg.norm(b - a))
    e = (b - a) / length
    r = p[first:] - a
    s = r @ e
    if band is None:
        c = np.linalg.norm(r - s[:, None] * e[None, :], axis=1)
    else:  # the horizontal distance from the track
        eh = e[:2] / np.linalg.norm(e[:2])
        c = np.abs(r[:, 0] * -eh[1] + r[:, 1] * eh[0])
    reached = np.flatnonzero(s >= length)
    ib = int(reached[0]) if reached.size else int(np.argmax(s))
    before = np.flatnonzero(s[: ib + 1] <= 0.0)
    ia = int(before[-1]) if before.size else 0
    seg = slice(ia, ib + 1)
    ss, cc, vv = s[seg], c[seg], v[first:][seg]
    ok = cc <= m_tol * (1 + rtol) + 1e-9
    alt = None
    if band is not None:
        seabed, (alt_lo, alt_hi) = band
        pp = p[first:][seg]
        alt = seabed.depth_at(pp[:, :2]) - pp[:, 2]
        ok &= (alt >= alt_lo * (1 - rtol) - 1e-9) & (alt <= alt_hi * (1 + rtol) + 1e-9)
    # stations passed within tolerance: every step between two samples within tolerance
    # covers the stations between them
    edges = np.linspace(0.0, length, tun.coverage_bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    cover = np.zeros(tun.coverage_bins + 1, int)
    both = ok[:-1] & ok[1:]
    lo_s = np.minimum(ss[:-1], ss[1:])[both]
    hi_s = np.maximum(ss[:-1], ss[1:])[both]
    np.add.at(cover, np.searchsorted(centres, lo_s, side="left"), 1)
    np.add.at(cover, np.searchsorted(centres, hi_s, side="right"), -1)
    coverage = float(np.mean(np.cumsum(cover)[:-1] > 0))
    on = (ss >= 0.0) & (ss <= length)
    if not np.any(on):
        on = np.ones_like(ss, bool)
    along = vv[on] @ e
    perp = np.linalg.norm(vv[on] - along[:, None] * e[None, :], axis=1)
    heading = np.degrees(np.arctan2(perp, along))
    speed = np.linalg.norm(vv[on], axis=1)
    check = LineCheck(
        coverage=coverage,
        max_cross_track_m=float(np.max(cc[on])),
        max_heading_err_deg=float(np.max(np.abs(heading))),
        speed_range_mps=(float(np.min(speed)), float(np.max(speed))),
        pass_s=(float(t[first + ia]), float(t[first + ib])),
        complete=False,
        altitude_range_m=None if alt is None else (float(np.min(alt[on])), float(np.max(alt[on]))),
    )
    done = (
        coverage >= 1.0
        and reached.size > 0
        and check.max_cross_track_m <= m_tol * (1 + rtol) + 1e-9
        and check.max_heading_err_deg <= h_tol * (1 + rtol) + 1e-9
        and check.speed_range_mps[0] >= lo * (1 - rtol)
        and check.speed_range_mps[1] <= hi * (1 + rtol)
        and (alt is None or bool(np.all(ok[on])))
    )
    return LineCheck(**{**check.__dict__, "complete": bool(done)}), first + ib


def mission_check(traj: Trajectory, ctx: MissionContext) -> MissionCheck | None:
    """The mission check of ``traj`` for ``ctx`` (None when ``ctx`` has no mission).

    Parameters
    ----------
    traj : Trajectory
        The path, evaluated between its samples as exact quadratics of its piecewise-constant
        inputs.
    ctx : MissionContext
        The mission and the numbers it is flown under (dimension, speed limit for the default
        speed band).

    Returns
    -------
    MissionCheck or None
        The check line by line and point by point; None without a mission.
    """
    m = ctx.mission
    if m is None:
        return None
    t, p, v = _dense(traj)
    n = ctx.dim
    rtol = tuning().check_rtol
    lines: list[LineCheck] = []
    last_t = 0.0
    first = 0
    if m.kind == "survey":
        tol = (m.cross_track, m.heading_tol, m.speed_band(ctx.speed_limit))
        band = (m.seabed, m.altitude) if m.altitude is not None and m.seabed is not None else None
        flown = m.flown_as or tuple((i, False) for i in range(len(m.lines)))
        for (a, b), (given, rev) in zip(m.segments(n), flown, strict=True):
            ln, first = _line(t, p, v, a, b, first, tol, band)
            lines.append(replace(ln, line=given, reversed=rev))
            last_t = ln.pass_s[1]
    points: list[PointCheck] = []
    for i, w in enumerate(m.waypoints):
        d = np.linalg.norm(p - np.asarray(w, float), axis=1)
        allowed = np.arange(t.size) >= first
        if m.windows:
            t0, t1 = m.windows[i]
            allowed &= (t >= t0) & (t <= t1)
        if not np.any(allowed):
            points.append(PointCheck(math.inf, math.nan, None, False))
            continue
        j = int(np.flatnonzero(allowed)[np.argmin(d[allowed])])
        points.append(PointCheck(float(d[j]), float(t[j]), None, d[j] <= m.radius * (1 + rtol)))
        first, last_t = j, float(t[j])
    end = None
    if m.end is not None:
        goal = np.asarray(m.end.position, float)
        d = np.linalg.norm(p - goal, axis=1)
        speed = float(np.linalg.norm(v[-1]))
        ok = d[-1] <= m.end.radius * (1 + rtol)
        if m.end.speed is not None:
            ok = ok and speed <= m.end.speed * (1 + rtol) + 1e-9
        outside = np.flatnonzero(d > m.end.radius)
        arrive = float(t[outside[-1] + 1]) if outside.size and outside[-1] + 1 < t.size else 0.0
        end = PointCheck(float(d[-1]), arrive if ok else float(t[-1]), speed, bool(ok))
        last_t = max(last_t, end.time_s)
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    complete = (
        all(x.complete for x in lines)
        and all(x.complete for x in points)
        and (end is None or end.complete)
    )
    return MissionCheck(
        complete=bool(complete),
        lines=tuple(lines),
        waypoints=tuple(points),
        end=end,
        mission_time_s=float(last_t),
        path_length_m=float(steps.sum()),
    )


def completes_mission(traj: Trajectory, ctx: MissionContext) -> bool:
    """``traj`` completes ``ctx``'s mission (True without one).

    Parameters
    ----------
    traj : Trajectory
        The path.
    ctx : MissionContext
        The mission and the numbers it is flown under.

    Returns
    -------
    bool
        :attr:`MissionCheck.complete` of :func:`mission_check`, or True without a mission.
    """
    chk = mission_check(traj, ctx)
    return chk is None or chk.complete
