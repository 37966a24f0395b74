"""The planned beacon's receding horizon (``obsplan plan P --replan EVERY`` with
``beacon.motion = "planned"`` and ``vehicle.path``): the craft re-plans from its own state for the
vehicle's estimate, inside the closed-loop Monte Carlo, and its ranges come from the new path."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from obsplan import load_problem
from obsplan.cli import main
from obsplan.core.errors import ConfigError, ProblemError
from obsplan.estimation.epochs import epoch_beacons
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.model.beacon import BeaconPath
from obsplan.planning.baselines.beacon import craft_limit_breaks
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.beacon import plan_beacon, planning_step
from obsplan.planning.beacon_replan import (
    _resolve,
    beacon_replan_monte_carlo,
    beacon_replan_times,
    craft_at,
    predicted_vehicle,
    splice,
)
from obsplan.planning.plan import (
    _on_lines,
    check_beacon_replan,
    plan_moving_beacon,
    vehicle_trajectory,
)
from obsplan.planning.problem.validation_setup import (
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.planning.replan import recovery_steps
from obsplan.trajectory.sampled import resample


def _small(**changes):
    """asv-survey cut to two 100 m lines (a short horizon: seconds to plan)."""
    return load_problem("asv-survey").with_changes(
        start={"position": [-70.0, 25.0]},
        horizon={"duration": 420.0, "steps": 84},
        mission={"lines": [[-50.0, 25.0, 50.0, 25.0], [50.0, -25.0, -50.0, -25.0]]},
        validation={"runs": 2, "max_runs": 2},
        **changes,
    )


def _setup(pb):
    craft = pb.beacon_vehicle
    T = pb.horizon.duration
    config = estimation_config(pb, BeaconPath.fixed(craft.start.tolist(), 0.0, T))
    return craft, config


def _never(*args, **kwargs):
    raise AssertionError("the planner must not run")


# ---------------------------------------------------------------------- refusals (fast)


@pytest.mark.parametrize("every", [15.0, 0.0, -10.0, math.nan, 5.0])
def test_a_period_off_the_crafts_step_is_refused_naming_replan(every):
    pb = _small()
    craft, config = _setup(pb)
    fine = _on_lines(pb, _vehicle(pb), config)[0]
    assert planning_step(fine, config) == pytest.approx(10.0)  # the ping interval
    with pytest.raises(ConfigError, match="--replan"):
        beacon_replan_times(fine, config, every)
    with pytest.raises(ConfigError, match="--replan"):
        check_beacon_replan(pb, every)


def _vehicle(pb):
    return vehicle_trajectory(pb)


def test_replan_times_are_multiples_of_every_with_a_step_left():
    pb = _small()
    _, config = _setup(pb)
    fine = _on_lines(pb, _vehicle(pb), config)[0]
    T = float(fine.t[-1])
    assert np.array_equal(beacon_replan_times(fine, config, 100.0), [100.0, 200.0, 300.0, 400.0])
    assert np.array_equal(beacon_replan_times(fine, config, 410.0), [410.0])  # one step left
    assert beacon_replan_times(fine, config, 420.0).size == 0
    assert beacon_replan_times(fine, config, 1000.0).size == 0
    with pytest.raises(ConfigError, match="--replan .*shorter than the horizon"):
        check_beacon_replan(pb, 1000.0)
    assert T == 420.0


def test_joint_planning_with_replan_is_refused_before_any_work():
    pb = _small(vehicle={"path": None})
    with pytest.raises(ConfigError, match=r"--replan .*vehicle\.path"):
        check_beacon_replan(pb, 100.0)
    with pytest.raises(ConfigError, match="--replan"):
        plan_moving_beacon(pb, _never, replan=100.0)


def test_replan_without_validation_is_refused():
    with pytest.raises(ProblemError, match="validate=True"):
        plan_moving_beacon(_small(), _never, validate=False, replan=100.0)


@pytest.mark.parametrize("extra", [["--replan", "15"], ["--replan", "60", "--no-validate"]])
def test_cli_bad_beacon_replan_exits_2_without_output(tmp_path, capsys, extra):
    path = tmp_path / "asv.toml"
    path.write_text(_small().to_toml())
    code = main(["plan", str(path), "--out", str(tmp_path / "o"), "--quiet", *extra])
    assert code == 2
    assert "--replan" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------------- pieces (fast)


def test_the_predicted_vehicle_joins_its_path_from_the_estimate():
    pb = _small()
    _, config = _setup(pb)
    fine = _on_lines(pb, _vehicle(pb), config)[0]
    k = 100
    exact = np.concatenate([fine.p[k], fine.v[k]])
    same = predicted_vehicle(pb, fine, k, exact)
    assert np.allclose(same.p, fine.p[k:], atol=1e-12) and np.allclose(same.v, fine.v[k:])
    off = exact + np.array([3.0, -2.0, 0.05, -0.02])
    pred = predicted_vehicle(pb, fine, k, off)
    assert np.allclose(np.concatenate([pred.p[0], pred.v[0]]), off)
    m = math.ceil(recovery_steps(pb) * pb.horizon.dt / pb.validation.dt)
    assert np.allclose(pred.p[m:], fine.p[k + m :], atol=1e-6)  # on its path after the window
    assert np.allclose(pred.v[m:], fine.v[k + m :], atol=1e-8)
    assert not np.allclose(pred.p[1], fine.p[k + 1])


def _loop(pb, fine, config, beacon: BeaconPath, run: int = 0, mask=None):
    return ClosedLoop(
        fine,
        replace(config, beacon_path=beacon),
        1,
        pb.validation.seed,
        run,
        guidance=validation_guidance(pb),
        limits=truth_limits(pb),
        lines=mask,
    )


def _circle(T: float) -> BeaconPath:
    t = np.linspace(0.0, T, 211)
    return BeaconPath(t, np.column_stack([60 * np.cos(t / 40.0), 60 * np.sin(t / 40.0)]))


def test_set_beacon_changes_only_the_future_and_the_same_path_changes_nothing():
    pb = _small()
    _, config = _setup(pb)
    fine = _on_lines(pb, _vehicle(pb), config)[0]
    T = float(fine.t[-1])
    circ = _circle(T)
    plain = _loop(pb, fine, config, circ).result()
    loop = _loop(pb, fine, config, circ)
    loop.advance(200.0)
    loop.set_beacon(circ)  # the path in force again: nothing may change
    again = loop.result()
    assert np.array_equal(again.ekf.rmse_pos_runs, plain.ekf.rmse_pos_runs)
    assert np.array_equal(again.ekf.final_pos_err_runs, plain.ekf.final_pos_err_runs)
    assert again.ekf.final_pos_err == plain.ekf.final_pos_err

    loop = _loop(pb, fine, config, circ)
    loop.advance(200.0)
    before = loop.setup.ctx.beacons.copy()
    moved = BeaconPath(circ.times, circ.positions + np.array([25.0, -10.0]))
    loop.set_beacon(moved)
    ep = loop.setup.plan.epochs
    past, fut = ep <= loop.k, ep > loop.k
    assert np.array_equal(loop.setup.ctx.beacons[past], before[past])
    ref = epoch_beacons(config.model, moved, fine.t[ep[fut]], fine.p[ep[fut]])
    assert np.array_equal(loop.setup.ctx.beacons[fut], ref)
    assert loop.setup.sample_beacons[loop.k + 1 :] == pytest.approx(
        moved.position(fine.t[loop.k + 1 :])
    )
    other = loop.result()
    assert other.ekf.final_pos_err != plain.ekf.final_pos_err  # the ranges came from the new path


def test_set_beacon_needs_a_moving_beacon():
    pb = load_problem("localise").with_changes(horizon={"steps": 20}, validation={"runs": 1})
    config = estimation_config(pb)
    base = next(iter(baselines(pb).values())).trajectory
    loop = ClosedLoop(
        resample(base, pb.validation.dt),
        config,
        1,
        0,
        0,
        guidance=validation_guidance(pb),
    )
    with pytest.raises(ConfigError, match="moving beacon"):
        loop.set_beacon(BeaconPath.fixed([0.0, 0.0], 0.0, pb.horizon.duration))


# ---------------------------------------------------------------------- end to end (slow)


@pytest.fixture(scope="module")
def planned():
    pb = _small()
    r = plan_moving_beacon(pb, plan_beacon, validate=False)
    craft, config = _setup(pb)
    fine, _, mask = _on_lines(pb, r.vehicle, config)
    return pb, r, craft, config, fine, mask


@pytest.mark.slow
def test_no_replan_time_gives_exactly_the_one_shot_validation(planned):
    pb, r, _, config, fine, mask = planned
    res = beacon_replan_monte_carlo(pb, fine, r.solve, 1000.0, config, mask=mask, runs=2)
    assert res.times == () and res.solves == ()
    a, b = res.validation["replanned"].result, res.validation["one-shot"].result
    assert np.array_equal(a.ekf.rmse_pos_runs, b.ekf.rmse_pos_runs)
    assert np.array_equal(a.ekf.rmse_pos_lines_runs, b.ekf.rmse_pos_lines_runs)
    assert np.array_equal(a.ekf.final_pos_err_runs, b.ekf.final_pos_err_runs)
    assert a.ekf.rmse_pos == b.ekf.rmse_pos and a.ekf.final_pos_err == b.ekf.final_pos_err
    assert a.kf.rmse_pos == b.kf.rmse_pos


@pytest.mark.slow
def test_a_resolve_starts_at_the_crafts_state_keeps_its_limits_and_moves_the_ranges(planned):
    pb, r, craft, config, fine, mask = planned
    loop = _loop(pb, fine, config, r.solve.path, mask=mask)
    loop.advance(100.0)
    snap = loop.snapshot()
    job = {
        "problem": pb,
        "craft": craft,
        "fine": fine,
        "config": config,
        "step": planning_step(fine, config),
        "mask": mask,
    }
    in_force = (r.solve.times, r.solve.positions, r.solve.velocities)
    out, new = _resolve(job, in_force, 100.0, snap.k, snap.estimate[0], snap.covariance[0], 0)
    assert out.success and out.t == 100.0 and new is not None, out
    here = craft_at(craft, in_force, 100.0)
    assert new.times[0] == 100.0
    assert np.array_equal(new.positions[0], here.start)  # continuity: exactly the craft's state
    assert np.array_equal(new.velocities[0, :2], here.velocity)
    rest = predicted_vehicle(pb, fine, snap.k, snap.estimate[0][:4])
    assert craft_limit_breaks(new.path, new.velocities, craft, rest) == ""
    assert craft_limit_breaks(new.path, new.velocities, craft, fine.window(snap.k)) == ""
    joined = splice(in_force, new, 100.0)
    before = joined[0] < 100.0
    assert np.array_equal(joined[1][before], r.solve.positions[r.solve.times < 100.0])
    old = loop.setup.ctx.beacons.copy()
    loop.set_beacon(BeaconPath(joined[0], joined[1]))
    ep = loop.setup.plan.epochs
    assert np.array_equal(loop.setup.ctx.beacons[ep <= snap.k], old[ep <= snap.k])
    assert not np.allclose(loop.setup.ctx.beacons[ep > snap.k + 20], old[ep > snap.k + 20])


@pytest.mark.slow
def test_cli_beacon_replan_writes_the_report_and_prints_it(tmp_path, capsys):
    path = tmp_path / "asv.toml"
    path.write_text(_small().to_toml())
    out = tmp_path / "o"
    code = main(["plan", str(path), "--out", str(out), "--quiet", "--replan", "200"])
    assert code == 0
    text = capsys.readouterr().out
    rep = json.loads((out / "report.json").read_text())["replan"]
    assert rep["what"] == "beacon" and rep["every_s"] == 200.0 and rep["times_s"] == [200.0, 400.0]
    assert rep["solves"] == 2 * 2  # two runs, two replan times
    assert rep["done"] + rep["failures"] + rep["kept"] == rep["solves"]
    assert set(rep["validation"]) == {"replanned", "one-shot"}
    assert rep["validation"]["replanned"]["runs"] == 2
    assert "one-shot" in json.dumps(rep["verdict"])
    assert "beacon replanning every 200 s: 4 re-solves" in text
    assert "replanned  EKF rmse" in text and "EKF rmse on lines" in text
