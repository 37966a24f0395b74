"""The mission's constraints in the planning NLP (a :class:`~obsplan.planning.transcription.blocks
.FormulationPart`).

Each survey line is flown in a window of nodes ``k0 .. k1``: the schedule's time at the line's
start and end (:func:`~obsplan.planning.missions.schedule.planner_schedule`: the lawn-mower's
timing after a lead-in, the lines faster), widened to
the nodes just outside, which lie on the run-in and run-out. With ``mission.shift`` the window
widens to flexible run-in and run-out zones around a strict core (:func:`line_zones`): there a
node's rows are relaxed by a smooth ``max(0, x)`` of how far it and its neighbours are off the
line's ends, so they hold wherever a segment of the path reaches the line. With ``e`` the
line's direction, ``n`` its normal(s), ``r_k = p_k - a`` the node's position from the line's
start ``a`` and ``v_k`` its velocity, at every node of the window:

* cross-track ``|n·r_k| <= tol - a_n h²/8``: between nodes the path is a parabola whose
  cross-track component bends by at most ``a_n h²/8`` from its chord (``a_n`` the largest
  acceleration across the line), so the tolerance holds on the continuous path;
* way on ``e·v_k >= lo`` and speed ``|v_k|² <= hi²``: linear and convex in ``v``, which is linear
  in time between nodes, so both hold on the continuous path;
* heading cone ``|n·v_k| <= tan(heading_tol) e·v_k`` (convex: exact between nodes too);

With an altitude band (3D, :class:`~obsplan.planning.missions.spec.Seabed`) the cross-track
row is two linear rows instead: the horizontal distance from the track ``|n_h·r_k| <= tol -
a_h h²/8`` (``n_h`` the track's horizontal normal) and the altitude ``|w·r_k| <= half -
(|w|·a) h²/8`` (``w`` the altitude's gradient, ``half`` the band's half width); both linear in
the position, so the parabola bound holds them between nodes too.

and coverage end to end: ``e·r_k0 <= 0`` and ``e·r_k1 >= length`` (with way on, the path passes
every station of the line inside the window). Waypoints: ``|p(t_i) - w_i| <= radius`` at the
schedule's passing time (the exact path at that time,
:meth:`~obsplan.planning.transcription.grid.Grid .sample_operator`). End region: ``|p_N - position|
<= radius`` and ``|v_N| <= speed`` (``v_N = 0`` for a speed of 0). Rows are in units of order 1 (the
tolerances, ``L_p``, ``v_max``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from obsplan.core.errors import ProblemError
from obsplan.planning.missions.lawnmower import planner_lawnmower
from obsplan.planning.missions.schedule import planner_schedule
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import ConstraintBlock, FormulationPart
from obsplan.planning.transcription.grid import Grid, apply_operator
from obsplan.planning.tuning import cache_per_tuning, tuning


def line_nodes(pb: PlanningProblem, window: tuple[float, float]) -> tuple[int, int]:
    """The nodes ``(k0, k1)`` of a line's window ``(t0, t1)`` [s]: the last node at or before
    the start and the first at or after the end (node 0, the fixed start, excluded).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its planning step ``h`` [s] and number of steps ``N``.
    window : tuple of float
        The line's window ``(t0, t1)`` [s].

    Returns
    -------
    k0 : int
        ``floor(t0 / h)``, at least 1.
    k1 : int
        ``ceil(t1 / h)``, at most ``N``.
    """
    h, N = pb.horizon.dt, pb.horizon.steps
    k0 = max(1, int(math.floor(window[0] / h + 1e-9)))
    k1 = min(N, int(math.ceil(window[1] / h - 1e-9)))
    return k0, k1


def _normals(e: np.ndarray) -> np.ndarray:
    """Unit normals of direction ``e`` as rows: (1, 2) in 2D, (2, 3) in 3D."""
    if e.size == 2:
        return np.array([[-e[1], e[0]]])
    a = np.array([0.0, 0.0, 1.0]) if abs(e[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    n1 = np.cross(e, a)
    n1 /= np.linalg.norm(n1)
    return np.vstack([n1, np.cross(e, n1)])


@dataclass(frozen=True)
class LineZone:
    """The nodes of one survey line's constraints.

    ``k0 .. k1`` is the strict core (every row held); ``first`` and ``last`` the coverage nodes
    (the line's earliest start and latest end: ``along <= 0`` at ``first``, ``>= length`` at
    ``last``); the nodes ``first .. k0 - 1`` and ``k1 + 1 .. last`` are the flexible run-in and
    run-out zones, where the rows hold once the path nears the line (module docstring). Without
    a shift ``first = k0`` and ``last = k1``.
    """

    first: int
    k0: int
    k1: int
    last: int


class _Line:
    """Survey line ``a -> b`` and its normalised quantities at nodes (module docstring)."""

    def __init__(self, pb: PlanningProblem, grid: Grid, a: np.ndarray, b: np.ndarray):
        m = pb.mission
        assert m is not None
        self.grid = grid
        self.lo, self.hi = m.speed_band(pb.limits.speed)
        self.length = float(np.linalg.norm(b - a))
        self.e = (b - a) / self.length
        self.nrm = _normals(self.e)
        self.ar = a - grid.beacon
        a_n = (
            float(np.max(np.abs(self.nrm) @ grid.a))
            if grid.n == 2
            else float(np.linalg.norm(grid.a))
        )
        self.room = 1.0 - a_n * grid.h**2 / 8.0 / m.cross_track
        self.tan = math.tan(math.radians(m.heading_tol))
        self.tol = m.cross_track
        # the altitude band's linear rows (module docstring): directions, tolerances, rooms
        band = m.altitude_row() if grid.n == 3 else None
        self.band = band is not None
        if band is not None:
            w, half = band
            eh = self.e[:2] / np.linalg.norm(self.e[:2])
            self.box_dirs = np.vstack([[-eh[1], eh[0], 0.0], w])
            tols = np.array([m.cross_track, half])
            bend = np.abs(self.box_dirs) @ grid.a * grid.h**2 / 8.0
            self.box_tol = tols
            self.box_room = 1.0 - bend / tols
        # parabola overshoot along the line between nodes, and the relaxation's width [m]: a row
        # is relaxed once a node and its neighbours are this far, and more, off the line's ends
        self.overshoot = float(np.linalg.norm(grid.a)) * grid.h**2 / 8.0
        self.width = tuning().flex_width * grid.v_max * grid.h

    def along(self, p, k0: int, k1: int):
        """Along-line position [m] of nodes ``k0 .. k1`` (row)."""
        r = p[:, k0 : k1 + 1] - ca.repmat(ca.DM(self.ar[:, None]), 1, k1 - k0 + 1)
        return ca.mtimes(ca.DM(self.e[None, :]), r)

    def rows(self, p, v, k0: int, k1: int) -> dict:
        """The normalised quantities of nodes ``k0 .. k1``: along position (in ``Lp``), along
        and side velocity (in ``v_max``), cross-track (in tolerances), squared speed."""
        g = self.grid
        K = k1 - k0 + 1
        r = p[:, k0 : k1 + 1] - ca.repmat(ca.DM(self.ar[:, None]), 1, K)
        vw = v[:, k0 : k1 + 1]
        return {
            "along_r": ca.mtimes(ca.DM(self.e[None, :]), r),
            "along_v": ca.mtimes(ca.DM(self.e[None, :]), vw) / g.v_max,
            "cross": ca.mtimes(ca.DM(self.nrm), r) / self.tol,
            "side": ca.mtimes(ca.DM(self.nrm), vw) / g.v_max,
            "speed2": ca.sum1(vw**2) / g.v_max**2,
            **(
                {"box": ca.mtimes(ca.DM(self.box_dirs / self.box_tol[:, None]), r)}
                if self.band
                else {}
            ),
        }

    def relaxation(self, p, k: int, end: bool):
        """How far node ``k`` is off the line's start (``end``: past its end), in widths beyond
        the strict band: a smooth ``max(0, x)`` that is ~0 within ``overshoot`` of the end (at
        the strict edge ``exp(-sharpness) / sharpness`` of one width,
        ``Tuning.flex_sharpness``)."""
        sharpness = tuning().flex_sharpness
        s = self.along(p, k, k)[0]
        off = (s - self.length) if end else -s
        x = sharpness * ((off - self.overshoot) / self.width - 1.0)
        return (ca.fmax(x, 0) + ca.log1p(ca.exp(-ca.fabs(x)))) / sharpness

    def strict_blocks(self, p, v, i: int, zone: LineZone) -> list[ConstraintBlock]:
        """Coverage at the zone's ends and every row at the core's nodes."""
        g = self.grid
        k0, k1 = zone.k0, zone.k1
        K = k1 - k0 + 1
        q = self.rows(p, v, k0, k1)
        s_first = self.along(p, zone.first, zone.first)[0]
        s_last = self.along(p, zone.last, zone.last)[0]
        inf = np.full(K, np.inf)
        lo, hi, room, tan = self.lo, self.hi, self.room, self.tan
        out = [
            ConstraintBlock(
                f"line{i}_coverage",
                ca.vertcat(s_first / g.Lp, s_last / g.Lp),
                np.array([-np.inf, self.length / g.Lp]),
                np.array([0.0, np.inf]),
            ),
            ConstraintBlock(f"line{i}_way_on", q["along_v"].T, np.full(K, lo / g.v_max), inf),
            ConstraintBlock(f"line{i}_speed", q["speed2"].T, -inf, np.full(K, (hi / g.v_max) ** 2)),
        ]
        if g.n == 2:
            out.append(
                ConstraintBlock(
                    f"line{i}_cross_track", q["cross"].T, np.full(K, -room), np.full(K, room)
                )
            )
            side, av = q["side"], q["along_v"]
            cone = ca.vertcat(side - tan * av, -side - tan * av)
            out.append(
                ConstraintBlock(
                    f"line{i}_heading", ca.vec(cone), np.full(2 * K, -np.inf), np.zeros(2 * K)
                )
            )
        elif self.band:
            box_room = np.tile(self.box_room, K)
            out.append(
                ConstraintBlock(f"line{i}_cross_track", ca.vec(q["box"]), -box_room, box_room)
            )
            cone = ca.sum1(q["side"] ** 2) - tan**2 * q["along_v"] ** 2
            out.append(ConstraintBlock(f"line{i}_heading", cone.T, -inf, np.zeros(K)))
        else:
            out.append(
                ConstraintBlock(
                    f"line{i}_cross_track", ca.sum1(q["cross"] ** 2).T, -inf, np.full(K, room**2)
                )
            )
            cone = ca.sum1(q["side"] ** 2) - tan**2 * q["along_v"] ** 2
            out.append(ConstraintBlock(f"line{i}_heading", cone.T, -inf, np.zeros(K)))
        return out

    def flex_rows(self, p, v, k: int, end: bool):
        """Node ``k``'s rows in a flexible zone, each ``<= 0``: every row of the core, relaxed
        by the least relaxation of ``k`` and its neighbours (a segment that reaches the line
        holds its rows at both ends), per width off the end
        (``Tuning.flex_relax_cross``, ``flex_relax_vel``)."""
        g = self.grid
        tun = tuning()
        q = self.rows(p, v, k, k)
        av, side, cross = q["along_v"][0], q["side"], q["cross"]
        base = [-av + self.lo / g.v_max, q["speed2"][0] - (self.hi / g.v_max) ** 2]
        vel = []
        if g.n == 2:
            cr = [cross[0] - self.room, -cross[0] - self.room]
            vel = [side[0] - self.tan * av, -side[0] - self.tan * av]
            relax_c = tun.flex_relax_cross
        elif self.band:
            box = q["box"]
            cr = [sign * box[j] - self.box_room[j] for j in range(2) for sign in (1, -1)]
            vel = [ca.sumsqr(side) - self.tan**2 * av**2]
            relax_c = tun.flex_relax_cross
        else:
            cr = [ca.sumsqr(cross) - self.room**2]
            vel = [ca.sumsqr(side) - self.tan**2 * av**2]
            relax_c = tun.flex_relax_cross**2
        out = []
        for j in (k - 1, k, k + 1):
            if not 0 <= j <= g.N:
                continue
            r = self.relaxation(p, j, end)
            out += [c - relax_c * r for c in cr]
            out += [c - tun.flex_relax_vel * r for c in base + vel]
        return ca.vertcat(*out)


@cache_per_tuning
def line_zones(pb: PlanningProblem) -> tuple[LineZone, ...]:
    """The nodes of every survey line's constraints (:class:`LineZone`).

    The core is the planner's window (:func:`~obsplan.planning.missions.schedule
    .planner_schedule`; the nodes just before its start and just after its end).
    With ``mission.shift`` each line may start up to ``shift`` of its scheduled time earlier or
    later, and end so too; the zones of consecutive lines meet at most at the middle of the
    time between them (a path beside one line is not held to the other's rows), and a zone
    only reaches nodes where both lawn-mowers on the planner's schedule meet its rows (they are
    its starts).

    Parameters
    ----------
    pb : PlanningProblem
        A problem with a survey ``[mission]``: its planning grid, ``mission.shift`` and planner's
        schedule.

    Returns
    -------
    tuple of LineZone
        One per survey line, in the order flown (cached per problem and tuning).
    """
    m = pb.mission
    assert m is not None
    h, N = pb.horizon.dt, pb.horizon.steps
    wins = planner_schedule(pb.mission_context).line_windows
    zones = []
    for i, (t0, t1) in enumerate(wins):
        k0, k1 = line_nodes(pb, (t0, t1))
        d = m.shift * (t1 - t0)
        lo_t = t0 - d if i == 0 else max(t0 - d, 0.5 * (wins[i - 1][1] + t0))
        hi_t = t1 + d if i == len(wins) - 1 else min(t1 + d, 0.5 * (t1 + wins[i + 1][0]))
        first = min(k0, max(1, int(math.floor(lo_t / h + 1e-9)) + (i > 0)))
        last = max(k1, min(N, int(math.ceil(hi_t / h - 1e-9)) - (i < len(wins) - 1)))
        c0 = max(first, min(k1, int(math.floor((t0 + d) / h + 1e-9))))
        c1 = min(last, max(c0, int(math.ceil((t1 - d) / h - 1e-9))))
        zones.append(LineZone(first, c0 if d > 0 else k0, c1 if d > 0 else k1, last))
    if m.shift > 0:
        zones = _trim_to_lawnmowers(pb, zones)
    return tuple(zones)


def _trim_to_lawnmowers(pb: PlanningProblem, zones: list[LineZone]) -> list[LineZone]:
    """Shrink each flexible zone to the nodes next to the core where both lawn-mowers meet its
    rows (to 1e-9). The zone still reaches the schedule's own window (the lawn-mowers are on the
    line there), so its coverage nodes lie before the line's start and past its end."""
    grid = Grid.from_problem(pb)
    paths = [grid.from_trajectory(planner_lawnmower(pb.mission_context, accelerated=False)[0])]
    if planner_schedule(pb.mission_context).headroom > 0:
        try:
            paths.append(
                grid.from_trajectory(planner_lawnmower(pb.mission_context, accelerated=True)[0])
            )
        except ProblemError:
            pass
    nodes = [(ca.DM(p), ca.DM(v)) for _, p, v in (grid.si_nodes(W) for W in paths)]
    assert pb.mission is not None
    out = []
    for (a, b), z in zip(pb.mission.segments(grid.n), zones, strict=True):
        ln = _Line(pb, grid, a, b)
        first = z.k0
        while first > z.first and _meets(ln, nodes, first - 1, False):
            first -= 1
        last = z.k1
        while last < z.last and _meets(ln, nodes, last + 1, True):
            last += 1
        out.append(LineZone(first, z.k0, z.k1, last))
    return out


def _meets(ln: _Line, nodes, k: int, end: bool) -> bool:
    """Every path of ``nodes`` meets node ``k``'s flexible rows (to 1e-9: units of order 1)."""
    return all(float(ca.mmax(ln.flex_rows(p, v, k, end))) <= 1e-9 for p, v in nodes)


def _line_blocks(pb, grid: Grid, p, v, i: int, a, b, zone: LineZone) -> list[ConstraintBlock]:
    """The constraints of survey line ``i`` from ``a`` to ``b`` (module docstring)."""
    ln = _Line(pb, grid, a, b)
    out = ln.strict_blocks(p, v, i, zone)
    for end, ks in ((False, range(zone.first, zone.k0)), (True, range(zone.k1 + 1, zone.last + 1))):
        if len(ks):
            g = ca.vertcat(*[ln.flex_rows(p, v, k, end) for k in ks])
            name = f"line{i}_run_{'out' if end else 'in'}"
            out.append(ConstraintBlock(name, g, np.full(g.numel(), -np.inf), np.zeros(g.numel())))
    return out


def _point_blocks(pb, grid: Grid, W, p, v) -> list[ConstraintBlock]:
    """Waypoints at the schedule's passing times and the end region."""
    m = pb.mission
    out = []
    if m.waypoints:
        times = np.array(planner_schedule(pb.mission_context).waypoint_times)
        if m.windows:
            win = np.array(m.windows)
            times = np.clip(times, win[:, 0], win[:, 1])
        Mp, cp, _, _ = grid.sample_operator(times)
        pts = apply_operator(Mp, cp, ca.vec(W), grid.n)
        # pts are relative to the beacon at the passing times
        goal = ca.DM((np.array(m.waypoints) - grid.beacon).T - grid.beacon_offset(times))
        g = ca.sum1((pts - goal) ** 2).T / m.radius**2
        J = times.size
        out.append(ConstraintBlock("waypoints", g, np.full(J, -np.inf), np.ones(J)))
    if m.end is not None:
        goal = ca.DM(np.asarray(m.end.position, float) - grid.beacon)
        g = ca.sumsqr(p[:, grid.N] - goal) / m.end.radius**2
        out.append(ConstraintBlock("end_region", g, np.array([-np.inf]), np.ones(1)))
        if m.end.speed is not None:
            vn = v[:, grid.N] / grid.v_max
            if m.end.speed == 0:
                z = np.zeros(grid.n)
                out.append(ConstraintBlock("end_speed", vn, z, z.copy()))
            else:
                cap = np.array([(m.end.speed / grid.v_max) ** 2])
                out.append(ConstraintBlock("end_speed", ca.sumsqr(vn), np.array([-np.inf]), cap))
    return out


def mission_part(pb: PlanningProblem, grid: Grid, W: ca.MX) -> FormulationPart | None:
    """The mission's constraints on the path ``W`` (None without a ``[mission]``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem and its ``[mission]``.
    grid : Grid
        The planning grid (intrinsic units of ``W``).
    W : casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    FormulationPart or None
        ``"mission"``: every line's, waypoint's and end region's constraint blocks, rows of
        order 1; None without a mission.
    """
    m = pb.mission
    if m is None:
        return None
    _, p, v = grid.si_nodes(W)
    blocks: list[ConstraintBlock] = []
    if m.kind == "survey":
        for i, ((a, b), zone) in enumerate(zip(m.segments(grid.n), line_zones(pb), strict=True)):
            blocks += _line_blocks(pb, grid, p, v, i, a, b, zone)
    blocks += _point_blocks(pb, grid, W, p, v)
    return FormulationPart("mission", constraints=tuple(blocks))
