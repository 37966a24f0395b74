"""Keep-out margins: the loop's responses, the deviation bound, tightening and the re-solve."""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from obsplan.core.errors import ProblemError
from obsplan.estimation.montecarlo.guidance import Guidance
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem.feasibility import check_limits, range_extremes
from obsplan.planning.problem.parse import LOCALISE_PROBLEM, problem_from_dict, problem_to_dict
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.problem.validation_setup import validation_guidance
from obsplan.planning.solver.formulation import build_formulation
from obsplan.planning.solver.margins import (
    LoopResponse,
    PathCovariance,
    box_margins,
    confidence_quantile,
    deviation_bound,
    keep_out,
    keepout_margins,
    keeps_margins,
    path_covariance,
    path_loop_covariance,
    solve_with_keepout,
    start_limited_s,
    start_reach,
    tighten,
)
from obsplan.planning.solver.solve import SolveResult
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.tuning import tuned, tuning


def test_loop_response_of_a_critically_damped_loop_matches_its_closed_form():
    w = 0.2
    loop = LoopResponse.of(Guidance(accel=(0.05,), speed=None, kp=w**2, kd=2 * w))
    # g(t) = t e^{-wt} >= 0: ∫ g = 1/w², ∫ g² = 1/(4 w³)
    assert loop.cum_abs[-1] == pytest.approx(1 / w**2, rel=1e-4)
    assert loop.l2 == pytest.approx(1 / (4 * w**3), rel=1e-4)
    assert loop.weight(np.array([-1.0]))[0] == 0.0


def test_deviation_bound_under_a_constant_covariance_is_the_steady_response():
    w = 0.2
    loop = LoopResponse.of(Guidance(accel=(0.05,), speed=None, kp=w**2, kd=2 * w))
    J = 2001
    sp, sv = 0.3, 0.02
    cov = PathCovariance(
        time=np.linspace(0.0, 1000.0, J),
        pos=np.tile(np.eye(2) * sp**2, (J, 1, 1)),
        vel=np.tile(np.eye(2) * sv**2, (J, 1, 1)),
    )
    dirs = np.array([[1.0, 0.0], [0.6, 0.8]])
    times = np.array([[1000.0], [0.0]])
    got = deviation_bound(cov, loop, 0.0, times, dirs)
    # long after the start: Kp ∫g (σp + Kd/Kp σv) = σp + 2/w σv; at t = 0 nothing has acted yet
    assert got[0] == pytest.approx(sp + 2 / w * sv, rel=1e-3)
    assert got[1] == 0.0
    q = 1e-6
    with_noise = deviation_bound(cov, loop, q, times, dirs)
    np.testing.assert_allclose(with_noise - got, math.sqrt(q / (4 * w**3)), rtol=1e-3)


def test_path_covariance_starts_at_the_prior_and_shrinks_with_ranges(short_problem, lawnmower):
    cov = path_covariance(lawnmower, short_problem)
    v0 = short_problem.validation.init_pos_error**2
    np.testing.assert_allclose(cov.pos[0], np.eye(2) * v0)
    assert cov.pos.shape == (cov.time.size, 2, 2)
    assert np.trace(cov.pos[-1]) < 0.25 * np.trace(cov.pos[0])


def test_margins_scale_with_the_confidence_quantile_and_zero_disables(short_problem, lawnmower):
    m = keepout_margins(lawnmower, short_problem)
    assert m.k == pytest.approx(3.0902, abs=1e-4)
    assert np.all(m.range_points > 0) and np.all(m.box > 0)
    assert np.all((m.accel_reserve >= 0) & (m.accel_reserve <= tuning().reserve_cap))
    low = replace(short_problem, limits=replace(short_problem.limits, keepout_confidence=0.9))
    m9 = keepout_margins(lawnmower, low)
    ratio = confidence_quantile(0.9) / confidence_quantile(0.999)
    np.testing.assert_allclose(m9.range_points, ratio * m.range_points, rtol=1e-9)
    off = replace(short_problem, limits=replace(short_problem.limits, keepout_confidence=0.0))
    m0 = keepout_margins(lawnmower, off)
    assert m0.k == 0 and not m0.range_points.any() and not m0.box.any()


def test_the_reserves_are_the_linearised_loops_stds_between_floor_and_cap(short_problem, lawnmower):
    """Per interval, the acceleration reserve is ``k`` times the largest std of the feedback
    command over the epochs acting on it (the linearised loop), clipped to [floor, cap]; the
    speed reserve ``k`` times the filter's velocity std plus the estimated velocity's, capped."""
    pb = short_problem
    m = keepout_margins(lawnmower, pb)
    g = validation_guidance(pb, at_sea=True)
    lc = path_loop_covariance(lawnmower, pb, g)
    cmd = lc.command_std(g.kp, g.kd)
    t = pb.times
    a = np.asarray(pb.accel, float)
    floor, cap = tuning().reserve_floor, tuning().reserve_cap
    for i in (5, 20, pb.horizon.steps - 1):  # the epochs from the last at or before t_i
        lo = np.searchsorted(lc.time, t[i], side="right") - 1
        hi = max(np.searchsorted(lc.time, t[i + 1], side="left") - 1, lo)
        want = np.clip(m.k * cmd[lo : hi + 1].max(axis=0) / a, floor, cap)
        np.testing.assert_allclose(m.accel_reserve[:, i], want, rtol=1e-12)
        vel = lc.std("filter", "vel").max(axis=1) + lc.std("estimated", "vel").max(axis=1)
        assert m.speed[i] == pytest.approx(min(m.k * vel[lo : hi + 1].max(), m.speed_cap))
    # once the filter has converged the linear reserve is below the floor: the floor holds
    assert np.all(m.accel_reserve >= floor)
    assert np.any(m.k * cmd[lc.time > 60].max(axis=0) / a < floor)


def test_tighten_moves_only_the_limit_bounds(short_problem, lawnmower):
    form = build_formulation(short_problem)
    m = keepout_margins(lawnmower, short_problem)
    tight = tighten(form, m)
    row = sum(
        c.size for c in form.constraints[: [c.name for c in form.constraints].index("min_range")]
    )
    K = 2 * short_problem.horizon.steps
    np.testing.assert_allclose(
        tight.lbg[row : row + K] - form.lbg[row : row + K], m.range_points / form.grid.Lp
    )
    changed = np.flatnonzero(tight.lbg != form.lbg)
    assert changed.min() >= row and changed.max() < row + K
    # the speed rows |V|² <= 1 become (1 - reserve / v_max)², nothing else of ubg moves
    names = [c.name for c in form.constraints]
    srow = sum(c.size for c in form.constraints[: names.index("speed")])
    N = short_problem.horizon.steps
    assert np.any(m.speed > 0)
    np.testing.assert_allclose(
        tight.ubg[srow : srow + N], (1 - m.speed / form.grid.v_max) ** 2, rtol=1e-12
    )
    moved = np.flatnonzero(tight.ubg != form.ubg)
    assert moved.min() >= srow and moved.max() < srow + N
    assert np.all(tight.lbx >= form.lbx) and np.all(tight.ubx <= form.ubx)
    assert np.any(tight.ubx < form.ubx)
    assert keeps_margins(form, lawnmower)


def test_keep_out_returns_a_feasible_path_that_keeps_its_margins(short_problem, lawnmower):
    path, rep, _ = keep_out(short_problem, lawnmower)
    assert check_limits(path, short_problem).ok()
    if rep.held:
        # "held": no margin recomputed on the path grew past what counts as unchanged between
        # rounds (margin_atol_m on the distances, reserve_atol of the acceleration bound)
        again = keepout_margins(path, short_problem)
        atol = tuning().reserve_atol
        again = replace(again, accel_reserve=np.maximum(again.accel_reserve - atol, 0.0))
        assert keeps_margins(tighten(build_formulation(short_problem), again), path, tol=1e-3)
    assert rep.planned_closest_range_m == pytest.approx(range_extremes(path, [0, 0])[0])
    assert rep.to_dict()["confidence"] == 0.999


def test_keepout_confidence_is_read_written_and_checked():
    data = problem_to_dict(load_problem(LOCALISE_PROBLEM))
    assert data["limits"]["keepout_confidence"] == 0.999
    data["limits"]["keepout_confidence"] = 0.99
    assert problem_from_dict(data).limits.keepout_confidence == 0.99
    for bad in (1.0, -0.1, 2):
        data["limits"]["keepout_confidence"] = bad
        with pytest.raises(ProblemError, match="limits.keepout_confidence"):
            problem_from_dict(data)


@pytest.mark.slow
def test_a_mission_plan_keeps_its_speed_reserve_and_its_waypoints():
    """With a mission the speed reserve still tightens the plan (the true vehicle holds the
    speed limit) and the path returned still passes every waypoint: a re-solve that the
    reserve made miss one is not kept. Whether IPOPT finishes the reserved re-solve depends on
    the machine's BLAS path; when it does not, the report says the reserve was dropped."""
    from pathlib import Path

    from obsplan.planning.missions.check import completes_mission
    from obsplan.planning.solver.solve import solve

    path = Path(__file__).resolve().parents[1] / "problems/suite/missions/waypoints.toml"
    pb = load_problem(path)
    assert pb.mission is not None and pb.limits.speed is not None
    nominal = solve(pb, progress=False).trajectory
    assert nominal is not None and completes_mission(nominal, pb.mission_context)
    assert np.any(keepout_margins(nominal, pb).speed > 0)
    kept, report, _ = keep_out(pb, nominal)
    assert completes_mission(kept, pb.mission_context), report
    dropped = "speed reserve did not fit" in report.note
    assert (report.max_speed_margin_mps > 0) != dropped, report  # kept, or said


@pytest.mark.slow
def test_keep_out_never_trades_the_mission_for_its_margins():
    """On a survey with no time to spare the tightened re-solves may stop unfinished: a path they
    return is kept only if it still completes the mission (independent check)."""
    from pathlib import Path

    from obsplan.planning.missions.check import completes_mission
    from obsplan.planning.solver.solve import solve

    path = (
        Path(__file__).resolve().parents[1] / "problems/suite/missions/survey-no-time-to-spare.toml"
    )
    pb = load_problem(path)
    nominal = solve(pb, progress=False).trajectory
    assert nominal is not None and completes_mission(nominal, pb.mission_context)
    kept, report, _ = keep_out(pb, nominal)
    assert completes_mission(kept, pb.mission_context), report


def test_the_plans_speed_reserve_is_never_inflated_past_the_guidances_cap(short_problem, lawnmower):
    """The fixed point inflates every margin by 10 % between rounds; the speed reserve stops at
    the guidance's own cap (a plan slower than the guidance's floor gains nothing)."""
    from obsplan.estimation.montecarlo.guidance import SPEED_RESERVE_CAP

    m = keepout_margins(lawnmower, short_problem)
    cap = SPEED_RESERVE_CAP * short_problem.limits.speed
    assert m.speed_cap == pytest.approx(cap)
    assert np.isclose(m.speed.max(), cap)  # the prior's velocity std reaches the cap early on
    grown = m.maximum(m, 1.1)
    assert grown.speed.max() <= cap + 1e-12
    assert np.all(grown.range_points >= 1.1 * m.range_points - 1e-12)  # the others do grow


@pytest.mark.slow
def test_a_mission_with_no_room_for_the_speed_reserve_keeps_every_other_margin():
    """The default survey on a horizon whose timing needs more speed than the reserve leaves:
    the path returned still completes the mission, and the report says what was kept (a
    re-solve without the speed reserve, its other margins, or the nominal plan)."""
    from obsplan.planning.missions.check import completes_mission
    from obsplan.planning.solver.solve import solve

    pb = load_problem()
    pb = replace(pb, horizon=Horizon(duration=780.0, steps=195))
    nominal = solve(pb, progress=False).trajectory
    assert nominal is not None and completes_mission(nominal, pb.mission_context)
    margins = keepout_margins(nominal, pb)
    # lines, turns and run-in (about 656 m) in 780 s need 0.84 m/s on average: more than the
    # 0.7 m/s that a reserve at its cap leaves of the 1 m/s bound
    assert margins.speed.max() == pytest.approx(margins.speed_cap)
    kept, report, best = keep_out(pb, nominal)
    assert completes_mission(kept, pb.mission_context)
    if best is None:
        assert "nominal plan is returned" in report.note and kept is nominal
    else:
        assert report.max_speed_margin_mps == 0.0
        assert "speed reserve did not fit" in report.note
        assert report.max_range_margin_m > 0 and report.max_box_margin_m > 0


@pytest.mark.parametrize("reserve_free_fits", [True, False])
def test_keep_out_drops_only_the_speed_reserve_when_it_does_not_fit(
    short_problem, lawnmower, monkeypatch, reserve_free_fits
):
    """The fallback's logic, with the re-solve replaced by one that fails whenever the speed
    reserve is asked for: the margins are re-solved once without it (every other margin
    kept) and the report says so; if that fails too, the nominal plan is returned."""
    from types import SimpleNamespace

    import obsplan.planning.solver.margins as margins_mod

    asked = []

    def fake_resolve(form, margins, guess, label):
        asked.append(margins)
        if np.any(margins.speed > 0) or not reserve_free_fits:
            why = "IPOPT found the constraints locally infeasible (9 iterations)"
            return SimpleNamespace(status="Infeasible_Problem_Detected", note=why), None, False
        return SimpleNamespace(status="Solve_Succeeded", note=""), guess, True

    monkeypatch.setattr(margins_mod, "_resolve", fake_resolve)
    kept, report, best = keep_out(short_problem, lawnmower)
    assert report.statuses[0] == "Infeasible_Problem_Detected"
    assert np.any(asked[0].speed > 0) and not np.any(asked[1].speed > 0)
    # the other margins of the second attempt are the first's
    assert np.array_equal(asked[1].range_points, asked[0].range_points)
    assert np.array_equal(asked[1].box, asked[0].box)
    assert np.array_equal(asked[1].accel_reserve, asked[0].accel_reserve)
    if reserve_free_fits:
        assert best is not None and report.held
        assert report.max_speed_margin_mps == 0.0
        assert "speed reserve did not fit" in report.note
        assert all(not np.any(m.speed > 0) for m in asked[1:])  # never asked for again
    else:
        assert best is None and kept is lawnmower and len(asked) == 2
        assert "nominal plan is returned" in report.note
        # with the reason the last re-solve stopped, in words
        assert "(Infeasible_Problem_Detected: IPOPT found the constraints locally" in report.note


@pytest.mark.parametrize(
    ("start", "resolve"),
    [
        ("Maximum_Iterations_Exceeded", "Solve_Succeeded"),
        ("Solve_Succeeded", "Maximum_Iterations_Exceeded"),
    ],
)
def test_the_headline_status_is_the_flown_paths(
    short_problem, lawnmower, monkeypatch, start, resolve
):
    """The kept path's status, iterations and success are the keep-out re-solve's (the path
    flown), not those of the start it was re-solved from, which the note and ``starts`` keep: a
    converged re-solve of a stalled start is a success, a stalled re-solve of a converged start
    is not."""
    from types import SimpleNamespace

    import obsplan.planning.solver.margins as margins_mod

    nominal = SolveResult(
        short_problem, lawnmower, start == "Solve_Succeeded", start, 1000, 1.0, 0.5, 0.5,
        "circle", (), 0.1,
        chosen="circle", note="from the start",
    )  # fmt: skip
    moved = replace(lawnmower, p=lawnmower.p + 0.0)
    why = "" if resolve == "Solve_Succeeded" else "stopped at IPOPT's iteration limit (17 ...)"
    outcome = SimpleNamespace(
        status=resolve, iterations=17, note=why, success=resolve == "Solve_Succeeded"
    )
    monkeypatch.setattr(margins_mod, "solve", lambda pb, **kw: nominal)
    report = SimpleNamespace(wall_s=0.5)
    monkeypatch.setattr(margins_mod, "keep_out", lambda pb, traj: (moved, report, outcome))
    kept, _ = solve_with_keepout(short_problem)
    assert kept.trajectory is moved
    assert (kept.status, kept.iterations) == (resolve, 17)
    words = f" ({why})" if why else ""
    assert kept.note == f"from the start; keep-out re-solve: {resolve}{words}"
    assert kept.chosen == "circle + keep-out margins"
    assert kept.success == (resolve == "Solve_Succeeded")
    assert kept.to_dict()["status"] == resolve
    assert kept.to_dict()["success"] == kept.success


@pytest.mark.parametrize("converges_after", [1, 2, 5])
def test_an_unconverged_re_solve_is_continued_from_its_own_iterate(
    short_problem, lawnmower, monkeypatch, converges_after
):
    """A keep-out re-solve that stops at IPOPT's iteration limit without keeping its margins is
    re-run warm from its own iterate, at most ``continue_unconverged`` times (the tuning's, read
    when the re-solve runs); one that converged or kept its margins is not."""
    from types import SimpleNamespace

    import obsplan.planning.solver.margins as margins_mod

    margins = keepout_margins(lawnmower, short_problem)
    form = build_formulation(short_problem)
    calls = []

    def fake_run_start(ctx, label, guess):
        calls.append((label, guess))
        done = len(calls) > converges_after
        traj = replace(lawnmower, p=lawnmower.p + len(calls))  # a new iterate each run
        status = "Solve_Succeeded" if done else "Maximum_Iterations_Exceeded"
        ok = SimpleNamespace(ok=lambda: True)
        outcome = SimpleNamespace(status=status, limits=ok, mission_complete=True, note="")
        return outcome, traj

    monkeypatch.setattr(margins_mod, "run_start", fake_run_start)
    monkeypatch.setattr(margins_mod, "keeps_margins", lambda tight, traj: traj.p[0, 0] > 1e9)
    outcome, traj, keeps = margins_mod._resolve(form, margins, lawnmower, "round 1")
    limit = tuning().continue_unconverged
    runs = min(converges_after, limit) + 1
    assert len(calls) == runs and not keeps
    assert calls[0] == ("round 1", lawnmower)
    for k in range(1, runs):  # each continuation starts from the previous run's iterate
        assert calls[k][0] == f"round 1 (continued {k})"
        assert np.array_equal(calls[k][1].p, lawnmower.p + k)
    done = converges_after <= limit
    assert outcome.status == ("Solve_Succeeded" if done else "Maximum_Iterations_Exceeded")
    # kept at once: no continuation
    calls.clear()
    monkeypatch.setattr(margins_mod, "keeps_margins", lambda tight, traj: True)
    assert margins_mod._resolve(form, margins, lawnmower, "round 1")[2]
    assert len(calls) == 1
    # the limit is the tuning in force when the re-solve runs
    calls.clear()
    monkeypatch.setattr(margins_mod, "keeps_margins", lambda tight, traj: traj.p[0, 0] > 1e9)
    with tuned(continue_unconverged=0):
        assert not margins_mod._resolve(form, margins, lawnmower, "round 1")[2]
    assert len(calls) == 1


#: 3D range-only (no depth gauge: the depth is known only as well as the ranges pin it), 2 m
#: below the depth band's top with a 1 m prior: its depth margin at 99.9 % is wider than that.
SURFACE_START = """
[vehicle]
dim = 3
sensors = ["range"]
[beacon]
position = [0.0, 0.0, 40.0]
[start]
position = [-60.0, 50.0, 4.0]
velocity = [0.0, 0.0, 0.0]
[limits]
accel = [0.05, 0.05, 0.02]
speed = 1.0
depth = [2.0, 30.0]
area = { x = [-100.0, 100.0], y = [-100.0, 100.0] }
[horizon]
duration = 150.0
steps = 50
[objective]
starts = 1
"""


def test_start_reach_is_the_accelerated_then_cruising_distance():
    pb = problem_from_dict(tomllib.loads(SURFACE_START))
    grid = Grid.from_problem(pb)
    t = grid.times[1:]
    d = start_reach(grid, 2, 1.0, 0.02)  # from rest: 1 m/s after 50 s
    np.testing.assert_allclose(d, np.where(t <= 50.0, 0.01 * t**2, 25.0 + (t - 50.0)), rtol=1e-12)
    moving = replace(grid, v0=np.array([0.0, 0.0, -0.5]))  # heading for the limit: back first
    early = -0.5 * t[:3] + 0.01 * t[:3] ** 2
    np.testing.assert_allclose(start_reach(moving, 2, 1.0, 0.02)[:3], early, rtol=1e-12)


def test_a_start_inside_its_margin_gets_margins_that_grow_in_and_a_plan_that_keeps_them():
    pb = problem_from_dict(tomllib.loads(SURFACE_START))
    form = build_formulation(pb)
    plan = baselines(pb)["lawnmower"].trajectory
    m = keepout_margins(plan, pb)
    grid = form.grid
    accel = 0.02 * (1.0 - m.accel_reserve[2].max())
    reach = start_reach(grid, 2, 1.0, accel)
    share = tuning().box_share
    full = np.minimum(m.box[2], share * 28.0)
    # the precondition: the full depth margin is out of the vehicle's reach at some nodes
    assert np.any(2.0 + full > 4.0 + reach)
    lo, hi = box_margins(form, m)[2]
    room = 4.0 - 2.0 - form.grid.a[2] * grid.h**2 / 8.0 + tuning().start_reach_share * reach
    np.testing.assert_allclose(lo, np.minimum(full, room), atol=1e-9)
    assert np.all(2.0 + lo < 4.0 + reach) and np.any(lo < full)
    # far from the limits (the area; the band's deep side) the margins are the full ones
    np.testing.assert_allclose(hi, np.minimum(m.box[2], share * 28.0))
    for axis in (0, 1):
        a_lo, a_hi = box_margins(form, m)[axis]
        np.testing.assert_allclose(a_lo, np.minimum(m.box[axis], share * 200.0))
    path, rep, outcome = keep_out(pb, plan)
    assert outcome is not None, rep.note  # the tightened re-solve ran: it was infeasible before
    assert check_limits(path, pb).ok()
    assert "the start is closer to the limit than its margin" in rep.note
    assert start_limited_s(form, m) > 0.0


def test_a_limit_narrower_than_twice_its_margin_is_named_with_its_fix():
    """The depth band (or an area axis) that is narrower than twice the largest margin the plan
    must keep from it is named, with the sensor that would help; a wider one is not."""
    from obsplan.planning.solver.margins import narrow_limits

    pb = problem_from_dict(tomllib.loads(SURFACE_START))
    m = keepout_margins(baselines(pb)["lawnmower"].trajectory, pb)
    deep, wide = float(m.box[2].max()), float(m.box[0].max())
    assert deep > 0 and wide > 0

    def limits(depth: float, width: float):
        x0 = float(pb.p0[0])  # the area keeps the start
        area = replace(pb.limits.area, x=(x0 - 0.5 * width, x0 + 0.5 * width))
        return replace(pb, limits=replace(pb.limits, depth=(2.0, 2.0 + depth), area=area))

    assert narrow_limits(limits(2 * deep + 0.1, 2 * wide + 0.1), m) == []
    (words,) = narrow_limits(limits(2 * deep - 0.1, 2 * wide + 0.1), m)
    assert words.startswith(f"the depth band ({2 * deep - 0.1:.3g} m) is narrower than twice")
    assert f"({deep:.3g} m, 3.09 sigma" in words and "add a depth gauge (vehicle.sensors)" in words
    (words,) = narrow_limits(limits(2 * deep + 0.1, 2 * wide - 0.1), m)
    assert words.startswith("the area's x range") and "depth gauge" not in words
