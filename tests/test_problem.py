"""Problem files: loading, documentation, and one clear error naming the field for each bad case."""

from __future__ import annotations

import copy
import re
from dataclasses import replace
from pathlib import Path

import pytest

from obsplan.core.errors import ProblemError
from obsplan.planning.problem.parse import (
    DEFAULT_PROBLEM,
    PROBLEMS_DIR,
    load_problem,
    problem_from_dict,
    problem_to_dict,
)
from obsplan.planning.problem.schema import KF_PCRB_WEIGHT, SCHEMA
from obsplan.planning.problem.validation_setup import estimation_config, validation_guidance

DOCS = Path(__file__).resolve().parents[1] / "docs" / "problem-files.md"

BASE = {
    "vehicle": {"dim": 2, "sensors": ["range"]},
    "start": {"position": [-80.0, 60.0], "velocity": [0.5, 0.0]},
    "limits": {"accel": 0.05, "speed": 1.0, "area": {"x": [-110.0, 110.0], "y": [-110.0, 110.0]}},
    "horizon": {"duration": 600.0, "steps": 200},
}


def _with(path: str, value) -> dict:
    d = copy.deepcopy(BASE)
    *secs, key = path.split(".")
    node = d
    for s in secs:
        node = node.setdefault(s, {})
    node[key] = value
    return d


def test_default_problem_loads_with_documented_defaults():
    pb = load_problem()
    assert pb.dim == 2 and pb.vehicle.sensors == ("range",)
    assert pb.objective.kind == "pcrb-position"
    assert pb.objective_mode == "lines-and-final"  # auto on a survey
    without = replace(pb, mission=None)
    assert without.objective_mode == "average-and-final"  # auto on free localisation
    assert pb.limits.min_range == 5.0  # the schema default
    assert pb.horizon.dt == pytest.approx(3.0)
    assert pb.scales.length_m == 100.0 and pb.scales.time_s == 100.0  # [scales] defaults
    assert load_problem(DEFAULT_PROBLEM) == pb


@pytest.mark.parametrize("path", sorted(PROBLEMS_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_problem_loads(path):
    pb = load_problem(path)
    assert pb.horizon.steps >= 2
    assert pb.model.dim == pb.dim


def test_shipped_problem_set():
    names = {p.stem for p in PROBLEMS_DIR.glob("*.toml")}
    assert {
        "default",
        "range3d",
        "range-dvl3d",
        "range-dvl-water-current2d",
        "lowrate-range",
    } <= names


def test_minimal_dict_fills_defaults():
    pb = problem_from_dict(BASE)
    assert pb.validation.runs == 50 and pb.objective.starts == 4
    assert pb.beacon == (0.0, 0.0)
    assert pb.limits.accel == (0.05, 0.05)  # one number applies to every axis


@pytest.mark.parametrize(
    ("path", "value", "field", "hint"),
    [
        ("limits.acceleration", 0.1, "limits.acceleration", "unknown key"),
        ("horizon.step", 10, "horizon.step", "unknown key"),
        ("solver.tol", 1e-6, "solver", "unknown section"),
        ("horizon.steps", "ten", "horizon.steps", "integer"),
        ("horizon.steps", 10.5, "horizon.steps", "integer"),
        ("limits.speed", "fast", "limits.speed", "number"),
        ("vehicle.current", 1, "vehicle.current", "true or false"),
        ("start.position", [1.0, 2.0, 3.0], "start.position", "2 finite numbers"),
        ("limits.accel", [0.05], "limits.accel", "2 finite numbers"),
        ("start.velocity", [1.5, 0.0], "start.velocity", "exceeds limits.speed"),
        ("limits.accel", 0.0, "limits.accel", "> 0"),
        ("limits.accel", [0.05, 0.0], "limits.accel", "> 0"),
        ("horizon.steps", 1, "horizon.steps", "at least 2"),
        ("horizon.duration", 0.0, "horizon.duration", "> 0"),
        ("limits.area", {"x": [0.0, 10.0], "y": [0.0, 10.0]}, "limits.area", "does not contain"),
        ("limits.area", {"x": [0.0, 10.0]}, "limits.area.y", "missing"),
        ("limits.depth", [0.0, 10.0], "limits.depth", "dim = 3"),
        ("vehicle.sensors", ["range", "sonar"], "vehicle.sensors", "unknown sensor"),
        ("vehicle.sensors", ["dvl"], "vehicle.sensors", "range"),
        ("objective.kind", "a-optimal", "objective.kind", "unknown objective"),
        ("objective.starts", 0, "objective.starts", "at least 1"),
        ("validation.dt", 0.7, "validation.dt", "must divide"),
        ("validation.range_rate", 20.0, "validation.range_rate", "faster than"),
        ("vehicle.current_velocity", [0.1, 0.0], "vehicle.current_velocity", "current = false"),
        ("scales.length_m", -1.0, "scales.length_m", "positive"),
        ("objective.mode", "sometimes", "objective.mode", "must be one of"),
        ("limits.min_range", -1.0, "limits.min_range", ">= 0"),
        ("limits.min_range", 150.0, "start.position", "inside limits.min_range"),
        ("limits.min_range", 99.9, "horizon.steps", "use more horizon.steps"),
        ("limits.max_range", 50.0, "start.position", "beyond"),
        ("limits.max_range", 3.0, "limits.max_range", "above limits.min_range"),
        ("limits.min_speed", 2.0, "limits.min_speed", "below limits.speed"),
        ("limits.min_speed", 0.6, "start.velocity", "through the water"),
        ("horizon.steps", 100000, "horizon.steps", "limit of 5000"),
        ("limits.accel", 1e-12, "limits.accel", "range noise"),
        ("validation.runs", 100000, "validation.runs", "at most"),
        ("validation.ekf_update", "third-order", "validation.ekf_update", "second-order"),
        ("validation.navigation", "ukf", "validation.navigation", "ekf, gsf"),
        ("objective.pcrb_weight", 1.0, "objective.pcrb_weight", "only kf-position-std"),
        ("beacon.position", [-80.0, 60.0], "start.position", "inside limits.min_range"),
    ],
)
def test_bad_field_is_named(path, value, field, hint):
    with pytest.raises(ProblemError) as exc:
        problem_from_dict(_with(path, value))
    msg = str(exc.value)
    assert field in msg, msg
    assert hint in msg, msg


@pytest.mark.parametrize("value", [-1.0, float("nan")])
def test_kf_pcrb_weight_is_a_finite_non_negative_number(value):
    d = _with("objective.kind", "kf-position-std")
    d["objective"]["pcrb_weight"] = value
    with pytest.raises(ProblemError, match=r"objective\.pcrb_weight.*finite"):
        problem_from_dict(d)
    d["objective"]["pcrb_weight"] = 0.0
    assert problem_from_dict(d).objective.resolved_pcrb_weight == 0.0
    del d["objective"]["pcrb_weight"]
    assert problem_from_dict(d).objective.resolved_pcrb_weight == KF_PCRB_WEIGHT


def test_ekf_update_reaches_the_validation_filters():
    assert estimation_config(problem_from_dict(BASE)).ekf_update == "second-order"
    pb = problem_from_dict(_with("validation.ekf_update", "first-order"))
    cfg = estimation_config(pb)
    assert cfg.ekf_update == "first-order" and cfg.to_dict()["ekf_update"] == "first-order"


def test_navigation_reaches_the_guidance():
    assert validation_guidance(problem_from_dict(BASE)).navigation == "gsf"
    g = validation_guidance(problem_from_dict(_with("validation.navigation", "ekf")))
    assert g.navigation == "ekf" and g.to_dict()["navigation"] == "ekf"


def test_objective_mode_only_for_timed_objectives():
    d = _with("objective.kind", "gramian-min-eig")
    d["objective"]["mode"] = "final"
    with pytest.raises(ProblemError, match=r"objective\.mode: gramian-min-eig has no time mode"):
        problem_from_dict(d)


def test_problem_to_dict_round_trips_every_shipped_problem():
    for path in [*PROBLEMS_DIR.glob("*.toml"), *(PROBLEMS_DIR / "suite").glob("*.toml")]:
        pb = load_problem(path)
        d = problem_to_dict(pb)
        assert problem_from_dict(d) == pb, path
        assert problem_to_dict(problem_from_dict(d)) == d


def test_missing_required_field_is_named():
    d = copy.deepcopy(BASE)
    del d["limits"]["speed"]
    with pytest.raises(ProblemError, match=r"limits\.speed: missing"):
        problem_from_dict(d)


def test_depth_band_must_contain_the_start():
    d = _with("vehicle.dim", 3)
    d["start"] = {"position": [-80.0, 60.0, 50.0]}
    d["limits"]["depth"] = [0.0, 40.0]
    with pytest.raises(ProblemError, match=r"limits\.depth: band \[0, 40\] m does not contain"):
        problem_from_dict(d)
    d["start"]["position"][2] = 10.0
    assert problem_from_dict(d).limits.depth == (0.0, 40.0)


def test_lwo_objective_refused_where_structurally_impossible():
    d = _with("vehicle.dim", 3)
    d["start"] = {"position": [-80.0, 60.0, 10.0]}
    d["objective"] = {"kind": "lwo-condition"}
    with pytest.raises(ProblemError, match=r"objective\.kind: lwo-condition is impossible.*3D"):
        problem_from_dict(d)
    d["vehicle"]["sensors"] = ["range", "dvl-water"]  # eq. 44: rank 6 is reachable
    assert problem_from_dict(d).objective.kind == "lwo-condition"


def test_gramian_objective_refused_with_bottom_lock_and_current():
    d = _with("vehicle.sensors", ["range", "dvl-bottom"])
    d["vehicle"]["current"] = True
    d["objective"] = {"kind": "gramian-min-eig"}
    with pytest.raises(ProblemError, match=r"objective\.kind: gramian-min-eig is impossible"):
        problem_from_dict(d)
    d["objective"] = {"kind": "kf-position-std"}
    assert problem_from_dict(d).vehicle.current


def test_structural_check_runs_in_the_loader_and_in_solve_not_on_construction(monkeypatch):
    from dataclasses import replace

    from obsplan.planning import solve
    from obsplan.planning.problem import checks

    d = _with("vehicle.dim", 3)
    d["start"] = {"position": [-80.0, 60.0, 10.0]}
    pb = problem_from_dict(d)  # range-only 3D with the default pcrb-position: possible
    calls: list[str] = []
    real = checks._structure_error.__wrapped__

    def counted(kind, model):
        calls.append(kind)
        return real(kind, model)

    monkeypatch.setattr(checks, "_structure_error", counted)
    impossible = replace(pb, objective=replace(pb.objective, kind="lwo-condition"))
    assert calls == []  # construction: the cheap checks only, no CasADi rank run
    with pytest.raises(ProblemError, match=r"objective\.kind: lwo-condition is impossible"):
        solve(impossible)  # refused before any solver work
    assert calls == ["lwo-condition"]


def test_file_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        "[horizon]\nduration = 600.0\nsteps = 1\n[limits]\naccel=0.05\nspeed=1.0\n"
        "[start]\nposition=[0.0, 1.0]\n"
    )
    with pytest.raises(ProblemError, match=r"bad\.toml: horizon\.steps: must be at least 2"):
        load_problem(bad)
    broken = tmp_path / "broken.toml"
    broken.write_text("[horizon\n")
    with pytest.raises(ProblemError, match="not valid TOML"):
        load_problem(broken)
    with pytest.raises(ProblemError, match="not found"):
        load_problem(tmp_path / "missing.toml")


def test_docs_document_every_field_with_unit_and_default():
    text = DOCS.read_text()
    for section, fields in SCHEMA.items():
        assert f"[{section}]" in text, section
        for f in fields:
            row = [line for line in text.splitlines() if line.startswith(f"| `{f.name}`")]
            assert row, f"{section}.{f.name} not documented"
            assert any(f.unit in r for r in row), f"{section}.{f.name}: unit missing"
    assert re.search(r"gramian-min-eig", text)


def test_docs_tables_are_generated_from_the_schema():
    from obsplan.planning.problem.schema import schema_markdown

    assert schema_markdown() in DOCS.read_text()
    # one source: the README links to the tables instead of repeating them
    readme = (DOCS.parents[1] / "README.md").read_text()
    assert "| `runs` |" not in readme and "docs/problem-files.md" in readme


def test_docs_field_tables_are_exactly_the_schema_regenerated():
    # stronger than inclusion: a field removed from SCHEMA must not linger in a document
    from obsplan.planning.problem.schema import update_field_tables

    text = DOCS.read_text()
    assert update_field_tables(text) == text, f"{DOCS.name}: run update_field_tables"
    stale = DOCS.read_text().replace("| `runs` |", "| `old_runs` |", 1)
    assert "old_runs" not in update_field_tables(stale)
    assert update_field_tables(stale) == DOCS.read_text()


def test_rates_of_sensors_not_fitted_do_not_veto_the_filter_step():
    # range-only at a 0.5 s filter step: the default DVL rate (10 Hz) must not matter ...
    pb = problem_from_dict(_with("validation.dt", 0.5))
    assert pb.validation.dt == 0.5
    # ... but a fitted DVL at 10 Hz cannot be served by a 0.5 s filter step
    data = _with("validation.dt", 0.5)
    data["vehicle"]["sensors"] = ["range", "dvl-water"]
    with pytest.raises(ProblemError, match=r"validation\.dvl_rate"):
        problem_from_dict(data)
