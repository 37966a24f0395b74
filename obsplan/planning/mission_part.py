"""The mission's constraints in the planning NLP (a :class:`~obsplan.planning.blocks
.FormulationPart`).

Each survey line is flown in a fixed window of nodes ``k0 .. k1``: the schedule's time at the
line's start and end (:mod:`obsplan.planning.mission_schedule`, the lawn-mower's timing), widened
to the nodes just outside, which lie on the run-in and run-out. With ``e`` the line's direction,
``n`` its normal(s), ``r_k = p_k - a`` the node's position from the line's start ``a`` and
``v_k`` its velocity, at every node of the window:

* cross-track ``|n·r_k| <= tol - a_n h²/8``: between nodes the path is a parabola whose
  cross-track component bends by at most ``a_n h²/8`` from its chord (``a_n`` the largest
  acceleration across the line), so the tolerance holds on the continuous path;
* way on ``e·v_k >= lo`` and speed ``|v_k|² <= hi²``: linear and convex in ``v``, which is linear
  in time between nodes, so both hold on the continuous path;
* heading cone ``|n·v_k| <= tan(heading_tol) e·v_k`` (convex: exact between nodes too);

and coverage end to end: ``e·r_k0 <= 0`` and ``e·r_k1 >= length`` (with way on, the path passes
every station of the line inside the window). Waypoints: ``|p(t_i) - w_i| <= radius`` at the
schedule's passing time (the exact path at that time, :meth:`~obsplan.planning.grid.Grid
.sample_operator`). End region: ``|p_N - position| <= radius`` and ``|v_N| <= speed`` (``v_N = 0``
for a speed of 0). Rows are in units of order 1 (the tolerances, ``L_p``, ``v_max``).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from obsplan.planning.blocks import ConstraintBlock, FormulationPart
from obsplan.planning.grid import Grid, apply_operator
from obsplan.planning.mission_schedule import mission_schedule
from obsplan.planning.problem import PlanningProblem


def line_nodes(pb: PlanningProblem, window: tuple[float, float]) -> tuple[int, int]:
    """The nodes ``(k0, k1)`` of a line's window ``(t0, t1)`` [s]: the last node at or before
    the start and the first at or after the end (node 0, the fixed start, excluded)."""
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


def _line_blocks(pb, grid: Grid, p, v, i: int, a, b, window) -> list[ConstraintBlock]:
    """The constraints of survey line ``i`` from ``a`` to ``b`` (module docstring)."""
    m = pb.mission
    lo, hi = m.speed_band(pb.limits.speed)
    k0, k1 = line_nodes(pb, window)
    length = float(np.linalg.norm(b - a))
    e = (b - a) / length
    nrm = _normals(e)
    ar = ca.DM((a - grid.beacon)[:, None])
    K = k1 - k0 + 1
    r = p[:, k0 : k1 + 1] - ca.repmat(ar, 1, K)
    vw = v[:, k0 : k1 + 1]
    a_n = float(np.max(np.abs(nrm) @ grid.a)) if grid.n == 2 else float(np.linalg.norm(grid.a))
    room = 1.0 - a_n * grid.h**2 / 8.0 / m.cross_track
    tan = math.tan(math.radians(m.heading_tol))
    along_r = ca.mtimes(ca.DM(e[None, :]), r)
    along_v = ca.mtimes(ca.DM(e[None, :]), vw) / grid.v_max
    cross = ca.mtimes(ca.DM(nrm), r) / m.cross_track
    side = ca.mtimes(ca.DM(nrm), vw) / grid.v_max
    inf = np.full(K, np.inf)
    out = [
        ConstraintBlock(
            f"line{i}_coverage",
            ca.vertcat(along_r[0] / grid.Lp, along_r[K - 1] / grid.Lp),
            np.array([-np.inf, length / grid.Lp]),
            np.array([0.0, np.inf]),
        ),
        ConstraintBlock(f"line{i}_way_on", along_v.T, np.full(K, lo / grid.v_max), inf),
        ConstraintBlock(
            f"line{i}_speed",
            ca.sum1(vw**2).T / grid.v_max**2,
            -inf,
            np.full(K, (hi / grid.v_max) ** 2),
        ),
    ]
    if grid.n == 2:
        out.append(
            ConstraintBlock(f"line{i}_cross_track", cross.T, np.full(K, -room), np.full(K, room))
        )
        cone = ca.vertcat(side - tan * along_v, -side - tan * along_v)
        out.append(
            ConstraintBlock(
                f"line{i}_heading", ca.vec(cone), np.full(2 * K, -np.inf), np.zeros(2 * K)
            )
        )
    else:
        out.append(
            ConstraintBlock(f"line{i}_cross_track", ca.sum1(cross**2).T, -inf, np.full(K, room**2))
        )
        cone = ca.sum1(side**2) - tan**2 * along_v**2
        out.append(ConstraintBlock(f"line{i}_heading", cone.T, -inf, np.zeros(K)))
    return out


def _point_blocks(pb, grid: Grid, W, p, v) -> list[ConstraintBlock]:
    """Waypoints at the schedule's passing times and the end region."""
    m = pb.mission
    out = []
    if m.waypoints:
        times = np.array(mission_schedule(pb).waypoint_times)
        if m.windows:
            win = np.array(m.windows)
            times = np.clip(times, win[:, 0], win[:, 1])
        Mp, cp, _, _ = grid.sample_operator(times)
        pts = apply_operator(Mp, cp, ca.vec(W), grid.n)
        goal = ca.DM((np.array(m.waypoints) - grid.beacon).T)
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
    """The mission's constraints on the path ``W`` (None without a ``[mission]``)."""
    m = pb.mission
    if m is None:
        return None
    sched = mission_schedule(pb)
    _, p, v = grid.si_nodes(W)
    blocks: list[ConstraintBlock] = []
    if m.kind == "survey":
        for i, ((a, b), window) in enumerate(
            zip(m.segments(grid.n), sched.line_windows, strict=True)
        ):
            blocks += _line_blocks(pb, grid, p, v, i, a, b, window)
    blocks += _point_blocks(pb, grid, W, p, v)
    return FormulationPart("mission", constraints=tuple(blocks))
