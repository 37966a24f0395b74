"""Planning the beacon (obsplan.planning.beacon): the recursion it optimises is the posterior CRB,
its plans keep every limit of the craft, and on a lawn-mower survey they beat holding station and
the best circle on the bound."""

from __future__ import annotations

import math
import pickle
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from obsplan.core.errors import InputError
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import EstimationConfig
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.model.vehicle import make_model
from obsplan.planning.beacon import (
    beacon_objective,
    flyable_path,
    plan_beacon,
    range_epoch_times,
)
from obsplan.planning.beacon.planner import PATH_TOLERANCE_M
from obsplan.planning.beacon.recursion import range_recursion
from obsplan.planning.solver.ipopt import SUCCESS_STATUS
from obsplan.trajectory.generators import lawnmower
from obsplan.trajectory.sampled import position_at

PING_S = 10.0
CRAFT_LIMITS = {"speed": 2.0, "accel": 0.2, "min_distance": 5.0, "max_range": 400.0}
AREA = [[-100.0, 300.0], [-100.0, 250.0]]


def survey(dim: int = 2, dt: float = 1.0, legs: int = 4, depth: float = -50.0):
    """A survey lawn-mower: legs of 200 m, 50 m apart, at 1 m/s (3D: at ``depth``)."""
    return lawnmower((0.0, 0.0), 200.0, 50.0, legs, 1.0, z=depth if dim == 3 else None).sample(dt)


def config(sensors=("range",), dim: int = 2, current: bool = False, sigma: float = 0.3):
    model = make_model(dim=dim, sensors=sensors, current=current)
    rates = {"range": 1.0 / PING_S}
    for s in model.sensors:
        if s != "range":
            rates[s] = 1.0
    return EstimationConfig(model=model, rates_hz=rates, noise={"range": sigma})


def craft(dim: int = 2, **changes) -> BeaconVehicle:
    """From rest at the survey's centre (the surface, z = 0, in 3D)."""
    start = [100.0, 75.0] + ([0.0] if dim == 3 else [])
    kw = {**CRAFT_LIMITS, "area": AREA, **changes}
    return BeaconVehicle(start=start, velocity=[0.0, 0.0], **kw)


def circling(traj, radius: float, ccw: bool, dim: int) -> BeaconPath:
    """A circle of ``radius`` about (100, 75) at 1.5 m/s (not flyable from the start)."""
    t = np.arange(traj.t[0], traj.t[-1] + 1.0, 1.0)
    t[-1] = traj.t[-1]
    th = (1.0 if ccw else -1.0) * 1.5 / radius * t
    xy = np.column_stack([100 + radius * np.cos(th), 75 + radius * np.sin(th)])
    if dim == 3:
        xy = np.column_stack([xy, np.zeros(t.size)])
    return BeaconPath(t, xy)


# ---------------------------------------------------------------------- the recursion


@pytest.mark.parametrize(
    "sensors, dim, current",
    [
        (("range",), 2, False),
        (("range", "dvl-bottom"), 2, False),
        (("range",), 2, True),
        (("range", "dvl-water", "depth"), 3, False),
    ],
)
def test_recursion_equals_the_posterior_crb(sensors, dim, current):
    # the folded recursion (one element per gap between range epochs) against the validation's
    # bound, epoch by epoch, on a moving beacon; 1e-9: both are exact, the folding reorders
    # round-off only (measured 2e-13)
    traj = survey(dim, dt=0.5, legs=2)
    cfg = config(sensors, dim, current)
    path = circling(traj, 60.0, True, dim)
    rec = range_recursion(traj, cfg)
    post, _ = rec.traces(rec.beacons_on_path(path))
    ref = posterior_crlb(traj, replace(cfg, beacon_path=path))
    var = ref.pos_std_t**2
    idx = np.searchsorted(traj.t, rec.times)
    np.testing.assert_allclose(post, var[idx], rtol=1e-9)
    _, nxt = rec.traces(rec.beacons_on_path(path))
    assert nxt[-1] == pytest.approx(var[-1], rel=1e-9)
    np.testing.assert_array_equal(rec.times, range_epoch_times(traj, cfg))


@pytest.mark.parametrize("sensors, dim", [(("range",), 2), (("range", "dvl-water", "depth"), 3)])
def test_casadi_objective_equals_numpy(sensors, dim):
    # the planner optimises the CasADi expression; the numpy one is the reference above.
    # 1e-12: the same arithmetic, in another order
    traj = survey(dim, dt=1.0, legs=2)
    cfg = config(sensors, dim)
    rec = range_recursion(traj, cfg)
    B = rec.beacons_on_path(circling(traj, 40.0, False, dim))
    w = np.linspace(0.0, 1.0, rec.count)
    x = ca.SX.sym("b", B.shape[0], B.shape[1])
    f = ca.Function("f", [x], [rec.objective(x, w)])
    assert float(f(B)) == pytest.approx(rec.objective(B, w), rel=1e-12)


def test_bad_inputs_are_named():
    traj = survey(2, legs=1)
    cfg = config()
    with pytest.raises(InputError, match="weights"):
        plan_beacon(traj, craft(), cfg, weights=np.ones(3))
    with pytest.raises(InputError, match="3D"):
        plan_beacon(traj, craft(dim=3), cfg)
    with pytest.raises(InputError, match="step"):
        plan_beacon(traj, craft(), cfg, step=0.0)


# ---------------------------------------------------------------------- a 2D range-only plan


@pytest.fixture(scope="module")
def planned():
    traj = survey(2, dt=1.0)
    cfg = config()
    c = craft()
    return traj, cfg, c, plan_beacon(traj, c, cfg)


def _check_limits(traj, c: BeaconVehicle, plan) -> None:
    """Every limit on a grid 10x finer than the plan's samples. The path's samples are exact;
    between them the linear interpolation is within PATH_TOLERANCE_M of the path, which is the
    tolerance of the distances."""
    tol = PATH_TOLERANCE_M
    np.testing.assert_allclose(plan.positions[0, :2], c.start[:2], atol=1e-9)
    np.testing.assert_allclose(plan.velocities[0, :2], c.velocity, atol=1e-9)
    assert plan.times[0] == traj.t[0] and plan.times[-1] == traj.t[-1]
    speed = np.linalg.norm(plan.velocities[:, :2], axis=1)
    assert np.all(speed <= c.speed * (1 + 1e-6))
    assert np.all(np.abs(plan.accelerations) <= np.asarray(c.accel) * (1 + 1e-6))
    # the samples are on the held-acceleration dynamics
    dt = np.diff(plan.times)[:, None]
    k = np.clip(np.searchsorted(plan.node_times, plan.times[:-1], side="right") - 1, 0, None)
    a = plan.accelerations[k]
    pred = plan.positions[:-1, :2] + plan.velocities[:-1, :2] * dt + 0.5 * a * dt**2
    np.testing.assert_allclose(plan.positions[1:, :2], pred, atol=1e-6)
    t = np.linspace(traj.t[0], traj.t[-1], 10 * plan.times.size)
    b = plan.path.position(t)
    p = position_at(traj, t)
    area = np.asarray(AREA)
    assert np.all(b[:, :2] >= area[:, 0] - tol) and np.all(b[:, :2] <= area[:, 1] + tol)
    horizontal = np.linalg.norm(p[:, :2] - b[:, :2], axis=1)
    assert np.all(horizontal >= c.min_distance - tol)
    assert np.all(np.linalg.norm(p - b, axis=1) <= c.max_range + tol)
    if c.dim == 3:
        np.testing.assert_array_equal(plan.positions[:, 2], c.start[2])
        np.testing.assert_array_equal(plan.velocities[:, 2], 0.0)


@pytest.mark.slow
def test_plan_keeps_every_limit(planned):
    traj, _, c, plan = planned
    _check_limits(traj, c, plan)


@pytest.mark.slow
def test_success_means_solve_succeeded(planned):
    *_, plan = planned
    assert plan.success == (plan.status == SUCCESS_STATUS)
    for s in plan.starts:
        assert s.success == (s.status == SUCCESS_STATUS)
        assert (s.reason == "") == s.success
    assert any(s.success for s in plan.starts)
    assert plan.success  # a converged start exists, so the plan is one


@pytest.mark.slow
def test_plan_is_no_worse_than_any_start(planned):
    # the best converged start is returned (by construction); each solve started from its fitted
    # start, so the plan is no worse than any of them either. 1e-12: round-off of the objective
    *_, plan = planned
    for s in plan.starts:
        assert s.initial_objective is not None
        assert plan.objective <= s.initial_objective * (1 + 1e-12)
        if s.success:
            assert plan.objective <= s.objective * (1 + 1e-12)
    assert plan.objective < plan.hold_objective
    assert plan.label in {s.label for s in plan.starts}
    assert plan.summary().startswith("beacon plan: converged")


@pytest.mark.slow
def test_objective_on_the_sampled_path_is_the_planned_one(planned):
    # the estimation ranges to the linearly interpolated samples (within 1 mm of the plan) at
    # transmission: the objective there is the planned one to 1e-4 (a millimetre over ranges of
    # tens of metres turns each bearing by < 1e-4 rad)
    traj, cfg, _, plan = planned
    assert beacon_objective(traj, cfg, plan.path) == pytest.approx(plan.objective, rel=1e-4)


@pytest.mark.slow
def test_planned_beacon_beats_holding_and_the_best_circle(planned):
    # the optimised craft must beat the usual paths on the bound it optimises: against
    # circles of 30-120 m both ways, each fitted onto the craft's limits from its start
    traj, cfg, c, plan = planned
    hold = BeaconPath.fixed(c.start.tolist(), traj.t[0], traj.t[-1])
    circles = []
    for radius in (30.0, 60.0, 90.0, 120.0):
        for ccw in (True, False):
            path, ok = flyable_path(traj, c, circling(traj, radius, ccw, 2))
            assert ok
            circles.append(path)
    objective = [beacon_objective(traj, cfg, p) for p in circles]
    best = circles[int(np.argmin(objective))]
    assert plan.objective < min(objective)
    assert plan.objective < beacon_objective(traj, cfg, hold)

    def bound(path):
        return posterior_crlb(traj, replace(cfg, beacon_path=path))

    mine, circle, held = bound(plan.path), bound(best), bound(hold)
    assert mine.mean_pos_std < circle.mean_pos_std < held.mean_pos_std
    assert mine.final_pos_std < held.final_pos_std


@pytest.mark.slow
def test_plan_pickles(planned):
    *_, plan = planned
    back = pickle.loads(pickle.dumps(plan))
    np.testing.assert_array_equal(back.positions, plan.positions)
    np.testing.assert_array_equal(back.path.times, plan.path.times)
    assert back.starts == plan.starts and back.objective == plan.objective


# ---------------------------------------------------------------------- 3D


@pytest.mark.slow
def test_3d_plan_at_the_surface_for_a_vehicle_at_depth():
    # the vehicle 50 m down with a DVL and a depth gauge, the craft at the surface
    traj = survey(3, dt=1.0, legs=2)
    cfg = config(("range", "dvl-bottom", "depth"), 3)
    c = craft(dim=3)
    plan = plan_beacon(traj, c, cfg, circles=False, guesses=[circling(traj, 60.0, True, 3)])
    assert plan.success == (plan.status == SUCCESS_STATUS)
    assert plan.positions.shape[1] == 3
    _check_limits(traj, c, plan)
    assert plan.objective < plan.hold_objective
    assert math.isfinite(plan.objective)


def test_a_start_that_stops_says_why_and_the_plan_is_not_a_success():
    # three iterations cannot converge: every start stops at the limit, says so in words, and
    # the plan returned (the best of them) is not called a success
    traj = survey(2, dt=1.0, legs=1)
    seen = []
    plan = plan_beacon(
        traj, craft(), config(), max_iter=3, callback=lambda i, label, s: seen.append(label)
    )
    assert seen == [s.label for s in plan.starts] and seen[0] == "hold"
    assert not plan.success and plan.status == "Maximum_Iterations_Exceeded"
    for s in plan.starts:
        assert not s.success and "iteration limit" in s.reason
    assert "NOT converged" in plan.summary()


def test_circle_starts_only_without_guesses_and_a_repeated_start_is_not_re_solved():
    # a few iterations suffice: what is checked is which starts run, not where they end
    traj = survey(2, dt=1.0, legs=1)
    c, cfg = craft(), config()
    alone = plan_beacon(traj, c, cfg, max_iter=3)
    assert [s.label for s in alone.starts][0] == "hold"
    assert sum(s.label.startswith("circle-") for s in alone.starts) == 4
    # the caller's guesses (the flow's baselines include a circle) replace the circle starts;
    # one of them holds the start, which once fitted is the "hold" start itself
    holding = BeaconPath.fixed(c.start.tolist(), traj.t[0], traj.t[-1])
    guided = plan_beacon(
        traj,
        c,
        cfg,
        max_iter=3,
        guesses=[holding, circling(traj, 60.0, True, 2)],
        guess_labels=["still", "round"],
    )
    labels = [s.label for s in guided.starts]
    assert labels == ["hold", "still", "round"]
    hold, still, rnd = guided.starts
    assert still.same_as == "hold" and hold.same_as == "" and rnd.same_as == ""
    assert (still.objective, still.iterations, still.status, still.reason) == (
        hold.objective,
        hold.iterations,
        hold.status,
        hold.reason,
    )
    assert rnd.initial_objective != hold.initial_objective
    assert "the same start as 'hold'" in guided.summary()
    # circles=True still adds them to the guesses
    both = plan_beacon(traj, c, cfg, max_iter=3, guesses=[holding], circles=True)
    assert sum(s.label.startswith("circle-") for s in both.starts) == 4


def test_the_objective_is_the_mean_term_plus_the_final_term():
    traj = survey(2, dt=1.0, legs=1)
    rec = range_recursion(traj, config())
    B = rec.positions.T + np.array([[30.0], [40.0]])
    w = np.linspace(0.0, 1.0, rec.count)
    mean, final = rec.terms(B, w)
    post, nxt = rec.traces(B)
    # the trapezoid over each gap, weighted, and the variance at the path's end
    expected = sum(wk * 0.5 * (a + b) for wk, a, b in zip(w, post, nxt, strict=True)) / w.sum()
    assert mean == pytest.approx(expected, rel=1e-12)  # the same sums in another order
    assert final == nxt[-1]
    assert rec.objective(B, w) == pytest.approx(mean + final, rel=1e-15)
