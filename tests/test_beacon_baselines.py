"""The beacon baselines (obsplan.planning.baselines.beacon) keep the craft's limits, and the
flow of a planned beacon (plan_moving_beacon) validates a beacon path against them and writes
beacon.csv beside plan.csv."""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from obsplan import load_problem
from obsplan.cli import main
from obsplan.core.errors import ProblemError
from obsplan.core.textfiles import toml_text
from obsplan.model.beacon import BeaconPath, BeaconVehicle, read_beacon_path
from obsplan.planning.baselines.beacon import (
    BEACON_BASELINES,
    beacon_baselines,
    bound_score,
    craft_limit_breaks,
    orbit_radius,
)
from obsplan.planning.plan import plan, plan_moving_beacon, vehicle_trajectory
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.trajectory.sampled import read_csv, resample

#: Round-off slack of the limit checks (the paths are integrated in floating point).
SLACK = 1e-9


def _setup(name: str):
    pb = load_problem(name)
    craft = pb.beacon_vehicle
    fine = resample(vehicle_trajectory(pb), pb.validation.dt)
    cfg = estimation_config(pb, BeaconPath.fixed(craft.start.tolist(), 0.0, pb.horizon.duration))
    return pb, craft, fine, cfg


@pytest.mark.parametrize("name", ["asv-survey", "asv-survey3d"])
def test_every_baseline_flies_within_the_crafts_speed_and_acceleration(name):
    pb, craft, fine, cfg = _setup(name)
    bls = beacon_baselines(fine, craft, cfg, step=pb.validation.dt)
    assert tuple(bls) == BEACON_BASELINES
    for bl in bls.values():
        p, v = bl.path, bl.velocities
        assert p.start == 0.0 and p.end == pytest.approx(pb.horizon.duration)
        assert np.max(np.linalg.norm(v[:, :2], axis=1)) <= craft.speed * (1 + SLACK)
        acc = np.abs(np.diff(v[:, :2], axis=0)) / np.diff(p.times)[:, None]
        assert np.all(acc <= craft.accel * (1 + SLACK)), bl.name
        # the positions are those of the velocities (constant acceleration on each interval)
        mid = 0.5 * (v[1:] + v[:-1]) * np.diff(p.times)[:, None]
        assert np.allclose(np.diff(p.positions, axis=0), mid, atol=1e-9)
        assert np.allclose(p.positions[0, :2], craft.start[:2])
        if pb.dim == 3:  # at the craft's depth
            assert np.all(p.positions[:, 2] == craft.start[2])
        # the limits the tracker does not enforce are checked, and said in words
        assert bl.breaks == craft_limit_breaks(p, v, craft, fine)
    assert np.all(bls["beacon-fixed"].path.positions == bls["beacon-fixed"].path.positions[0])


def test_the_circle_keeps_min_distance_when_a_radius_allows_it():
    pb, craft, fine, cfg = _setup("asv-survey")
    bls = beacon_baselines(fine, craft, cfg, step=pb.validation.dt, centre=np.zeros(2))
    assert bls["beacon-circle"].within_limits
    # centred on the survey: every knot at one radius once the transit is over
    r = np.linalg.norm(bls["beacon-circle"].path.positions[-200:], axis=1)
    assert np.ptp(r) < 0.05 * np.mean(r)  # 5 %: the tracker's lag behind the circling point


def test_a_craft_too_slow_to_follow_is_said_to_break_its_limits():
    pb, craft, fine, cfg = _setup("asv-survey")
    slow = BeaconVehicle(
        start=craft.start, speed=0.3, accel=craft.accel, velocity=np.zeros(2), min_distance=10.0
    )
    trail = beacon_baselines(fine, slow, cfg, step=pb.validation.dt)["beacon-trail"]
    assert "min_distance" in trail.breaks or trail.within_limits
    far = BeaconVehicle(
        start=craft.start, speed=0.3, accel=craft.accel, velocity=np.zeros(2), max_range=60.0
    )
    fixed = beacon_baselines(fine, far, cfg, step=pb.validation.dt)["beacon-fixed"]
    assert "max_range" in fixed.breaks


def test_orbit_radius_is_one_and_a_half_vertical_separations_in_3d():
    pb, craft, fine, _ = _setup("asv-survey3d")
    assert orbit_radius(fine, craft) == pytest.approx(1.5 * 30.0, rel=1e-6)
    pb2, craft2, fine2, _ = _setup("asv-survey")
    assert orbit_radius(fine2, craft2) == 50.0


@dataclass(frozen=True)
class _GivenPath:
    """A beacon path computed another way (a baseline), in the planner's result form."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    path: BeaconPath
    success: bool = True
    status: str = "Solve_Succeeded"
    iterations: int = 0
    wall_s: float = 0.0
    objective: float | None = None


def _best_baseline(
    vehicle, craft, config, *, weights=None, guesses=(), guess_labels=None, truth_margins=None
):
    """Not a planner: the guess with the lowest bound (the flow's path is what is tested; the
    re-solve with the truth margins returns its one guess, the path it was given)."""
    scores = [bound_score(vehicle, g, config) for g in guesses]
    g = guesses[int(np.argmin(scores))]
    v = np.vstack([g.segment_velocities, g.segment_velocities[-1:]])
    return _GivenPath(g.times, g.positions, v, g)


def test_the_flow_validates_a_beacon_path_against_every_baseline(tmp_path):
    pb = load_problem("asv-survey").with_changes(validation={"runs": 6, "max_runs": 6})
    result = plan_moving_beacon(pb, _best_baseline)
    assert set(result.validation) == {"planned", *BEACON_BASELINES}
    assert all(v.result.runs == 6 for v in result.validation.values())
    files = result.save(tmp_path / "out")
    assert {f.name for f in files} >= {"plan.csv", "beacon.csv", "report.json", "path.png"}
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert set(report["verdict"]["baselines"]) == set(BEACON_BASELINES)
    assert set(report["validation"]) == {"mode", "channel", "planned", *BEACON_BASELINES}
    assert report["validation"]["channel"]["name"] == "ideal"
    for name in BEACON_BASELINES:
        assert "ekf.rmse_pos_lines" in report["verdict"]["baselines"][name]
        assert report["verdict"]["outcomes"][name] in ("beats", "ties", "loses")
    # the planned path is the best baseline: against it, every comparison is an exact tie
    same = [
        n
        for n in BEACON_BASELINES
        if np.array_equal(result.baselines[n].path.positions, result.solve.positions)
    ]
    assert len(same) == 1 and report["verdict"]["outcomes"][same[0]] == "ties"

    assert report["solver"]["success"] is True and report["beacon"]["motion"] == "planned"
    # the flow's planning time (not the validation's) is reported beside the planner's
    assert 0 < report["solver"]["planning_s"] < result.wall_s
    assert np.array_equal(read_csv(tmp_path / "out" / "plan.csv").p, result.vehicle.p)
    back = read_beacon_path(tmp_path / "out" / "beacon.csv", 2)
    assert np.array_equal(back.positions, result.solve.positions)
    header = (tmp_path / "out" / "beacon.csv").read_text().splitlines()[0]
    assert header == "t,bx,by,vbx,vby"
    assert "the planned beacon" in result.summary()


def test_plan_and_validate_refuse_a_moving_beacon_and_say_what_to_use():
    with pytest.raises(ProblemError, match=r"plan_moving_beacon"):
        plan(load_problem("asv-survey"), validate=False)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            {"vehicle": {"path": None}, "objective": {"kind": "gramian-min-eig"}},
            r'^objective\.kind: "gramian-min-eig" is not built for the vehicle planned jointly',
        ),
    ],
)
def test_unsupported_moving_beacon_flows_are_refused(edit, match):
    pb = load_problem("asv-survey").with_changes(**edit)
    with pytest.raises(ProblemError, match=match):
        plan_moving_beacon(pb, _best_baseline, validate=False)


def _small_asv(tmp_path) -> Path:
    """asv-survey cut to two 100 m lines (a short horizon: a few seconds to plan)."""
    pb = load_problem("asv-survey").with_changes(
        start={"position": [-70.0, 25.0]},
        horizon={"duration": 420.0, "steps": 84},
        mission={"lines": [[-50.0, 25.0, 50.0, 25.0], [50.0, -25.0, -50.0, -25.0]]},
        validation={"runs": 4, "max_runs": 4},
    )
    path = tmp_path / "asv-small.toml"
    path.write_text(pb.to_toml())
    return path


@pytest.mark.slow
def test_obsplan_plan_writes_the_beacon_plan_and_its_verdict(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["plan", str(_small_asv(tmp_path)), "--out", str(out), "--quiet"])
    report = json.loads((out / "report.json").read_text())
    assert code == (0 if report["solver"]["success"] else 1)
    assert {"plan.csv", "beacon.csv", "report.json", "path.png", "filters.png"} <= {
        p.name for p in out.iterdir()
    }
    for key in ("validation", "verdict"):
        names = report[key] if key == "validation" else report[key]["baselines"]
        assert set(BEACON_BASELINES) <= set(names)
    assert "ekf.rmse_pos_lines" in report["verdict"]["baselines"]["beacon-circle"]
    said = capsys.readouterr().out
    assert "the planned beacon" in said and "beacon-orbit" in said
    beacon = read_beacon_path(out / "beacon.csv", 2)
    assert beacon.start == 0.0 and beacon.end == pytest.approx(420.0)
    assert np.array_equal(read_csv(out / "plan.csv").p[0], [-70.0, 25.0])


def test_obsplan_plan_refuses_a_joint_objective_it_cannot_plan_before_any_output(tmp_path, capsys):
    path = tmp_path / "joint.toml"
    data = tomllib.loads(load_problem("asv-survey").to_toml())
    del data["vehicle"]["path"]
    data["objective"]["kind"] = "lwo-condition"
    path.write_text(toml_text(data))
    assert main(["plan", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "objective.kind" in err and "planned jointly" in err and "pcrb-position" in err
    assert not (tmp_path / "o").exists()


def test_a_beacon_plans_report_names_its_channel():
    """At sea the beacon's report says the channel (``validation.channel``, the interface of
    the fixed beacon's) and every filter its rejected ranges."""
    pb = load_problem("asv-survey").with_changes(
        validation={"runs": 4, "max_runs": 4, "channel": "at-sea"}
    )
    report = plan_moving_beacon(pb, _best_baseline).to_dict()
    ch = report["validation"]["channel"]
    assert ch["name"] == "at-sea" and ch["gate"] == 0.999 and ch["scale_state"] is True
    assert report["validation"]["planned"]["ekf"]["ranges_rejected"] > 0
