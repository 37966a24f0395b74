"""``[beacon] motion`` and ``[vehicle] path`` in the problem file: each motion, each error, and
the round trip through ``to_toml`` / ``with_changes``."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from obsplan import PlanningProblem, load_problem
from obsplan.core.errors import ProblemError
from obsplan.core.textfiles import toml_text
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem.parse import problem_from_dict
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.trajectory.sampled import write_csv

ASV = "asv-survey"


def _data(name: str = ASV) -> dict:
    return tomllib.loads(load_problem(name).to_toml())


def _write_beacon_csv(path: Path, t1: float, dim: int = 2) -> Path:
    cols = "t,bx,by" + (",bz" if dim == 3 else "")
    rows = [f"{t},{10 + 0.5 * t},{-20.0}" + (",0.0" if dim == 3 else "") for t in (0.0, t1)]
    path.write_text(cols + "\n" + "\n".join(rows) + "\n")
    return path


def test_the_default_motion_is_fixed_and_writes_as_before():
    pb = load_problem("default")
    assert pb.beacon_motion.motion == "fixed" and not pb.beacon_motion.moving
    assert pb.beacon_path is None and pb.beacon_vehicle is None and pb.vehicle.path is None
    d = pb.to_dict()
    # the canonical mapping of a fixed-beacon problem is what it was: sweeps hash it
    assert d["beacon"] == {"position": [0.0, 0.0]}
    assert "path" not in d["vehicle"] and "min_range" in d["limits"]
    assert estimation_config(pb).beacon_path is None


@pytest.mark.parametrize("name", ["asv-survey", "asv-survey3d"])
def test_planned_motion_makes_the_craft_and_round_trips(name):
    pb = load_problem(name)
    craft = pb.beacon_vehicle
    assert pb.beacon_motion.motion == "planned" and pb.vehicle.path == "lawnmower"
    assert craft is not None and craft.dim == pb.dim
    assert craft.speed == 2.0 and np.array_equal(craft.accel, [0.2, 0.2])
    assert np.array_equal(craft.start, pb.beacon)
    # limits.min_range is replaced by the craft's horizontal min_distance
    assert pb.limits.min_range == 0.0 and pb.limits.max_range is None
    assert PlanningProblem.from_dict(tomllib.loads(pb.to_toml())) == pb
    moved = pb.with_changes(beacon={"speed": 1.5, "accel": [0.1, 0.3], "area": None})
    assert moved.beacon_vehicle.speed == 1.5
    assert np.array_equal(moved.beacon_vehicle.accel, [0.1, 0.3])
    assert PlanningProblem.from_dict(tomllib.loads(moved.to_toml())) == moved


def test_a_planned_beacon_has_no_path_to_validate_with_until_planned():
    with pytest.raises(ProblemError, match=r"^beacon\.motion: .*no path until it is planned"):
        estimation_config(load_problem(ASV))


def test_path_motion_reads_the_csv_relative_to_the_problem_file(tmp_path):
    data = _data()
    data["beacon"] = {"motion": "path", "path": "ship.csv"}
    del data["vehicle"]["path"]
    _write_beacon_csv(tmp_path / "ship.csv", 1200.0)
    (tmp_path / "p.toml").write_text(_toml(data))
    pb = load_problem(tmp_path / "p.toml")
    assert pb.beacon_motion.motion == "path"
    assert Path(pb.beacon_motion.path) == tmp_path / "ship.csv"
    cfg = estimation_config(pb)
    assert cfg.beacon_path is not None and cfg.model.beacon == (0.0, 0.0)
    assert np.allclose(cfg.beacon_path.position(600.0), [[310.0, -20.0]])
    assert PlanningProblem.from_dict(tomllib.loads(pb.to_toml())) == pb


def test_a_path_that_does_not_cover_the_horizon_is_refused_naming_beacon_path(tmp_path):
    data = _data()
    data["beacon"] = {"motion": "path", "path": str(_write_beacon_csv(tmp_path / "s.csv", 600.0))}
    with pytest.raises(ProblemError, match=r"^beacon\.path: covers t = 0\.\.600 s"):
        problem_from_dict(data)


def test_a_missing_path_file_is_refused_naming_beacon_path(tmp_path):
    data = _data()
    data["beacon"] = {"motion": "path", "path": str(tmp_path / "nowhere.csv")}
    with pytest.raises(ProblemError, match=r"^beacon\.path: "):
        problem_from_dict(data)


def _toml(data: dict) -> str:
    return toml_text(data)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            {"beacon": {"motion": "drifting"}},
            r"^beacon\.motion: must be one of fixed, path, planned",
        ),
        ({"beacon": {"speed": None}}, r"^beacon\.speed: missing"),
        ({"beacon": {"accel": None}}, r"^beacon\.accel: missing"),
        ({"beacon": {"accel": [0.2, 0.2, 0.2]}}, r"^beacon\.accel: expected 2 finite numbers"),
        ({"beacon": {"accel": -0.1}}, r"^beacon\.accel: every bound must be > 0"),
        ({"beacon": {"speed": 0.0}}, r"^beacon\.speed: must be > 0"),
        ({"beacon": {"velocity": [3.0, 0.0]}}, r"^beacon\.velocity: .*exceeds its speed"),
        ({"beacon": {"min_distance": 500.0}}, r"^beacon\.min_distance: the vehicle starts"),
        ({"beacon": {"max_range": 20.0}}, r"^beacon\.max_range: the vehicle starts"),
        ({"beacon": {"path": "ship.csv"}}, r'^beacon\.path: .*motion = "path"'),
        ({"beacon": {"area": {"x": [50.0, 60.0], "y": [0.0, 1.0]}}}, r"^beacon\.area: .*outside"),
        ({"limits": {"min_range": 5.0}}, r"^limits\.min_range: .*beacon\.min_distance"),
        ({"limits": {"max_range": 500.0}}, r"^limits\.max_range: .*beacon\.max_range"),
    ],
)
def test_planned_motion_field_errors_name_the_field(edit, match):
    with pytest.raises(ProblemError, match=match):
        load_problem(ASV).with_changes(**edit)


@pytest.mark.parametrize(
    "field", ["speed", "accel", "velocity", "area", "max_range", "min_distance"]
)
def test_craft_fields_are_refused_for_a_fixed_beacon(field):
    value = {"area": {"x": [0.0, 1.0], "y": [0.0, 1.0]}, "velocity": [0.0, 0.0]}.get(field, 1.0)
    with pytest.raises(ProblemError, match=rf'^beacon\.{field}: .*motion = "planned"'):
        load_problem("default").with_changes(beacon={field: value})


def test_vehicle_path_is_refused_with_a_fixed_beacon():
    with pytest.raises(ProblemError, match=r"^vehicle\.path: .*moving beacon"):
        load_problem("default").with_changes(vehicle={"path": "lawnmower"})


def test_a_planned_beacon_needs_its_start():
    data = _data()
    del data["beacon"]["position"]
    with pytest.raises(ProblemError, match=r"^beacon\.position: missing"):
        problem_from_dict(data)


def test_a_known_path_has_no_fixed_position(tmp_path):
    data = _data()
    path = str(_write_beacon_csv(tmp_path / "s.csv", 1200.0))
    data["beacon"] = {"motion": "path", "path": path, "position": [0.0, 0.0]}
    with pytest.raises(ProblemError, match=r"^beacon\.position: .*no fixed position"):
        problem_from_dict(data)


def test_vehicle_path_csv_is_read_relative_to_the_problem_file_and_checked(tmp_path):
    pb = load_problem(ASV)
    write_csv(baselines(pb)["lawnmower"].trajectory, tmp_path / "auv.csv")
    data = _data()
    data["vehicle"]["path"] = "auv.csv"
    (tmp_path / "p.toml").write_text(_toml(data))
    assert Path(load_problem(tmp_path / "p.toml").vehicle.path) == tmp_path / "auv.csv"
    data["horizon"]["duration"] = 1000.0
    data["horizon"]["steps"] = 200
    data["vehicle"]["path"] = str(tmp_path / "auv.csv")
    with pytest.raises(ProblemError, match=r"^vehicle\.path: .*must run from 0 to"):
        problem_from_dict(data)
    data = _data()
    data["vehicle"]["path"] = str(tmp_path / "missing.csv")
    with pytest.raises(ProblemError, match=r"^vehicle\.path: "):
        problem_from_dict(data)
