"""The vehicle and the beacon planned jointly (``beacon.motion = "planned"`` without
``vehicle.path``): rounds that plan the vehicle for the beacon's path, then the beacon for the
vehicle's, kept while they lower the beacon planner's objective."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from obsplan import load_problem
from obsplan.cli import main
from obsplan.core.errors import ProblemError
from obsplan.model.beacon import BeaconPath, read_beacon_path
from obsplan.planning.beacon import beacon_objective, plan_beacon, range_epoch_times
from obsplan.planning.missions.check import mission_check
from obsplan.planning.plan import (
    JOINT_ROUNDS,
    JOINT_TOL,
    plan_moving_beacon,
    vehicle_problem,
    vehicle_trajectory,
)
from obsplan.planning.problem.feasibility import check_limits
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.trajectory.sampled import read_csv, resample


def _joint(**changes):
    """asv-survey cut to two 100 m lines, the vehicle planned too (no ``vehicle.path``)."""
    return load_problem("asv-survey").with_changes(
        vehicle={"path": None},
        start={"position": [-70.0, 25.0]},
        horizon={"duration": 420.0, "steps": 84},
        mission={"lines": [[-50.0, 25.0, 50.0, 25.0], [50.0, -25.0, -50.0, -25.0]]},
        validation={"runs": 4, "max_runs": 4},
        **changes,
    )


def test_the_vehicles_problem_holds_the_planned_beacon_in_memory():
    pb = _joint()
    path = BeaconPath(np.array([0.0, 420.0]), np.array([[0.0, 0.0], [30.0, -10.0]]))
    pbv = vehicle_problem(pb, path)
    assert pbv.beacon_motion.motion == "path" and pbv.beacon_path is path
    assert np.array_equal(pbv.beacon_start, [0.0, 0.0])
    assert pbv.vehicle.path is None and pbv.limits.min_range == 0.0  # the craft keeps clear
    assert pbv.mission == pb.mission and pbv.horizon == pb.horizon
    with pytest.raises(ProblemError, match=r"^beacon\.path: a path given in memory"):
        pbv.to_dict()  # no file to name in a problem file
    short = BeaconPath(np.array([0.0, 100.0]), np.zeros((2, 2)))
    with pytest.raises(ProblemError, match=r"^beacon\.path: "):
        vehicle_problem(pb, short)  # it must cover the horizon


@pytest.fixture(scope="module")
def joint_result():
    return plan_moving_beacon(_joint(), plan_beacon, validate=False)


@pytest.mark.slow
def test_joint_rounds_lower_the_objective_and_keep_every_limit(joint_result):
    r, pb = joint_result, joint_result.problem
    j = r.joint
    assert j is not None and 0 <= j.rounds <= JOINT_ROUNDS
    # a round is kept only when it lowered the objective by more than JOINT_TOL
    for before, after in zip(j.objectives[:-1], j.objectives[1:], strict=True):
        assert after <= before * (1.0 - JOINT_TOL)
    lawn = vehicle_trajectory(pb)
    assert r.baseline_vehicle is not None
    assert np.array_equal(r.baseline_vehicle.p, lawn.p)  # the baselines' vehicle
    if j.rounds == 0:
        assert j.vehicle_solve is None and np.array_equal(r.vehicle.p, lawn.p)
        return
    assert j.vehicle_solve is not None and j.vehicle_solve.success and r.success
    assert not np.array_equal(r.vehicle.p, lawn.p)
    # the planned vehicle flies its mission within its limits, from its start
    assert check_limits(r.vehicle, pb).ok()
    chk = mission_check(r.vehicle, pb.mission_context)
    assert chk is not None and chk.complete
    assert np.allclose(r.vehicle.p[0], pb.p0)
    # the craft keeps its limits from the planned vehicle's path, not the lawn-mower's
    assert r.planned_breaks == ""
    fine = resample(r.vehicle, pb.validation.dt)
    gap = np.linalg.norm(fine.p[:, :2] - r.solve.path.position(fine.t)[:, :2], axis=1)
    assert gap.min() >= pb.beacon_motion.min_distance * (1.0 - 1e-6)
    # the pair's objective, recomputed from the paths, is the one the craft planner reported
    # for the planned vehicle (1e-6: the recursion's round-off against the planner's own value)
    cfg = estimation_config(pb, r.solve.path)
    w = chk.line_mask(range_epoch_times(fine, cfg)).astype(float)
    got = beacon_objective(fine, cfg, r.solve.path, w)
    assert got == pytest.approx(r.solve.objective, rel=1e-6)
    if r.distance_margin_m == 0:  # no keep-out re-solve after the rounds: the last round's
        assert got == pytest.approx(j.objectives[-1], rel=1e-6)


@pytest.mark.slow
def test_the_joint_report_and_files(joint_result, tmp_path):
    r = joint_result
    files = {p.name for p in r.save(tmp_path / "out")}
    assert {"plan.csv", "beacon.csv", "report.json", "path.png"} <= files
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    joint = report["solver"]["joint"]
    assert joint["rounds"] == r.joint.rounds
    assert joint["objectives"] == [float(x) for x in r.joint.objectives]
    assert report["solver"]["success"] == bool(r.solve.success)
    assert np.allclose(read_csv(tmp_path / "out" / "plan.csv").p, r.vehicle.p)
    beacon = read_beacon_path(tmp_path / "out" / "beacon.csv", 2)
    assert np.allclose(beacon.positions, r.solve.positions)
    text = r.summary()
    assert "planned jointly" in text and f"joint rounds kept: {r.joint.rounds}" in text
    rms = [f"{math.sqrt(x):.4g}" for x in r.joint.objectives]
    assert " -> ".join(rms) in text


def test_obsplan_plan_refuses_a_joint_replan_before_any_output(tmp_path, capsys):
    path = tmp_path / "joint.toml"
    path.write_text(_joint().to_toml())
    code = main(["plan", str(path), "--out", str(tmp_path / "o"), "--replan", "60"])
    assert code == 2
    assert "--replan" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
