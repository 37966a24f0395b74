"""Shifting line windows (``mission.shift``): the zones of each survey line's constraints, the
relaxation of the flexible run-in and run-out, and plans that use them."""

from __future__ import annotations

import re
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from obsplan.core.errors import ProblemError
from obsplan.planning.missions.lawnmower import planner_lawnmower
from obsplan.planning.missions.schedule import planner_schedule
from obsplan.planning.plan import plan
from obsplan.planning.problem.parse import (
    DEFAULT_PROBLEM,
    PROBLEMS_DIR,
    load_problem,
    problem_from_dict,
)
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.transcription.mission import (
    LineZone,
    _Line,
    line_nodes,
    line_zones,
    mission_part,
)

SURVEYS = [
    p
    for p in [DEFAULT_PROBLEM, *sorted((PROBLEMS_DIR / "suite" / "missions").glob("*.toml"))]
    if load_problem(p).mission.kind == "survey"
]


def _shifted(pb, shift: float):
    return replace(pb, mission=replace(pb.mission, shift=shift))


def _small(shift: float) -> dict:
    return {
        "vehicle": {"dim": 2, "sensors": ["range"]},
        "beacon": {"position": [0.0, 0.0]},
        "start": {"position": [-60.0, 30.0], "velocity": [0.0, 0.0]},
        "limits": {"accel": 0.05, "speed": 1.0},
        "horizon": {"duration": 420.0, "steps": 140},
        "mission": {
            "kind": "survey",
            "lines": [[-40.0, 30.0, 40.0, 30.0], [40.0, -10.0, -40.0, -10.0]],
            "speed": [0.3, 1.0],
            "shift": shift,
        },
        "objective": {"starts": 1},
        "validation": {"runs": 5},
    }


@pytest.mark.parametrize("shift", [-0.1, 0.5, 0.9])
def test_a_shift_outside_its_range_names_the_field(shift):
    with pytest.raises(ProblemError, match=re.escape("mission.shift")):
        problem_from_dict(_small(shift))


@pytest.mark.parametrize("path", SURVEYS, ids=lambda p: p.stem)
def test_fixed_windows_are_the_schedules_nodes(path):
    pb = _shifted(load_problem(path), 0.0)
    for zone, win in zip(
        line_zones(pb), planner_schedule(pb.mission_context).line_windows, strict=True
    ):
        k0, k1 = line_nodes(pb, win)
        assert zone == LineZone(k0, k0, k1, k1)
    grid = Grid.from_problem(pb)
    names = [c.name for c in mission_part(pb, grid, ca.MX.sym("W", 3 * pb.dim, grid.N)).constraints]
    assert not any("run_" in n for n in names)


@pytest.mark.parametrize("path", SURVEYS, ids=lambda p: p.stem)
def test_shifting_zones_hold_the_schedule_and_never_overlap(path):
    pb = _shifted(load_problem(path), 0.3)
    zones = line_zones(pb)
    wins = planner_schedule(pb.mission_context).line_windows
    for z, win in zip(zones, wins, strict=True):
        k0, k1 = line_nodes(pb, win)
        assert 1 <= z.first <= k0 and k1 <= z.last <= pb.horizon.steps
        assert k0 <= z.k0 <= z.k1 <= k1  # the strict core inside the schedule's window
        # the shift is bounded by its fraction of the line's time (a node of rounding)
        d = 0.3 * (win[1] - win[0])
        assert z.first * pb.horizon.dt >= win[0] - d - pb.horizon.dt
        assert z.last * pb.horizon.dt <= win[1] + d + pb.horizon.dt
    for a, b in zip(zones, zones[1:], strict=False):
        assert a.last < b.first  # a node is held to one line's rows at most
    # some line of every shipped survey gets a zone wider than its fixed window
    assert any(z.first < z.k0 or z.last > z.k1 for z in zones)


@pytest.mark.slow
@pytest.mark.parametrize("path", SURVEYS, ids=lambda p: p.stem)
def test_both_lawnmowers_meet_every_row_of_a_shifted_mission(path):
    # the lawn-mowers on the planner's schedule are its starts: a zone reaches only where they
    # meet it
    pb = _shifted(load_problem(path), 0.3)
    grid = Grid.from_problem(pb)
    Wsym = ca.MX.sym("W", 3 * pb.dim, grid.N)
    part = mission_part(pb, grid, Wsym)
    assert any("run_" in c.name for c in part.constraints)
    paths = [planner_lawnmower(pb.mission_context)[0]]
    if planner_schedule(pb.mission_context).headroom > 0:
        paths.append(planner_lawnmower(pb.mission_context, accelerated=True)[0])
    for traj in paths:
        W = grid.from_trajectory(traj)
        for c in part.constraints:
            g = np.asarray(ca.Function("g", [Wsym], [c.g])(W)).ravel()
            # 1e-9: the rows are in units of order 1; the lawn-mowers fly the lines exactly
            assert np.all(g >= c.lb - 1e-9) and np.all(g <= c.ub + 1e-9), c.name


def _node(line: _Line, grid: Grid, along: np.ndarray, cross: float, heading_deg: float):
    """Numeric nodes ``p - b`` and ``v`` (n, K) at the given along-line positions [m], off the
    line by ``cross`` [m], at 0.6 m/s ``heading_deg`` off the line's direction."""
    e, n = line.e, line.nrm[0]
    p = (line.ar[:, None] + np.outer(e, along) + cross * n[:, None]).copy()
    ang = np.radians(heading_deg)
    v = np.repeat((0.6 * (np.cos(ang) * e + np.sin(ang) * n))[:, None], along.size, axis=1)
    return ca.DM(p), ca.DM(v)


def test_the_relaxation_frees_nodes_well_before_the_line_and_holds_those_at_it():
    pb = load_problem()
    grid = Grid.from_problem(pb)
    a, b = pb.mission.segments(2)[0]
    ln = _Line(pb, grid, a, b)
    step = 0.6 * grid.h
    # 10 m off the track crabbing at 45 deg, all three nodes 10 m and more before the start
    p, v = _node(ln, grid, np.array([-10.0 - step, -10.0, -10.0 + step]), 10.0, 45.0)
    assert float(ca.mmax(ln.flex_rows(p, v, 1, end=False))) <= 0.0
    # the same node with its next node on the line: the segment reaches the line, rows hold
    p, v = _node(ln, grid, np.array([-2 * step, -step, 0.5]), 10.0, 45.0)
    assert float(ca.mmax(ln.flex_rows(p, v, 1, end=False))) > 0.5
    # on the line within tolerance: held, and met
    p, v = _node(ln, grid, np.array([5.0, 5.0 + step, 5.0 + 2 * step]), 1.0, 5.0)
    assert float(ca.mmax(ln.flex_rows(p, v, 1, end=False))) <= 0.0
    # past the end in a run-out zone, freed; just before the end, held
    L = ln.length
    p, v = _node(ln, grid, np.array([L + 10.0, L + 10.0 + step, L + 10.0 + 2 * step]), 10.0, 45)
    assert float(ca.mmax(ln.flex_rows(p, v, 1, end=True))) <= 0.0
    p, v = _node(ln, grid, np.array([L - 1.0, L + 10.0, L + 10.0 + step]), 10.0, 45.0)
    assert float(ca.mmax(ln.flex_rows(p, v, 1, end=True))) > 0.5


@pytest.mark.slow
def test_a_shifted_plan_completes_the_survey_within_its_shifted_windows():
    pb = problem_from_dict(_small(0.3))
    res = plan(pb, validate=False, processes=1)
    chk = res.missions["planned"]
    assert chk.complete  # the independent check on the continuous path
    h = pb.horizon.dt
    for ln, win in zip(chk.lines, planner_schedule(pb.mission_context).line_windows, strict=True):
        d = 0.3 * (win[1] - win[0])
        assert win[0] - d - h <= ln.pass_s[0] and ln.pass_s[1] <= win[1] + d + h
    # at least as good as its starts (the lawn-mowers) on its own objective
    assert res.metrics["planned"].objective < res.metrics["lawnmower"].objective
