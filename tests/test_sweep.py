"""Sweep files, task expansion, identity, the results table and the verb's input errors.

Everything here runs without a Dask cluster (tests/test_sweep_dask.py runs sweeps on real ones).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from obsplan.cli import main
from obsplan.core.outputs import write_marker
from obsplan.planning.problem.parse import problem_from_dict
from obsplan.sweeps import SweepFileError, expand, load_sweep, sweep, sweep_from_dict
from obsplan.sweeps.spec import apply_axes, combinations, parse_path, set_fields, unique_tasks
from obsplan.sweeps.table import build_table, comparable, flatten

ROOT = Path(__file__).resolve().parents[1]
SWEEPS = ROOT / "problems" / "sweeps"

#: A small 2D base problem (inline [base]); tasks built from it are valid problems.
BASE = {
    "vehicle": {"dim": 2, "sensors": ["range"]},
    "start": {"position": [-80.0, 60.0]},
    "limits": {"accel": 0.05, "speed": 1.0},
    "horizon": {"duration": 120.0, "steps": 12},
    "objective": {"starts": 1},
    "validation": {"runs": 2, "dt": 1.0},
}


def spec_of(axes: dict, **sweep_keys) -> object:
    return sweep_from_dict({"sweep": {"name": "t", **sweep_keys}, "base": BASE, "axes": axes})


# ------------------------------------------------------------------------------ shipped studies
@pytest.mark.parametrize("name", ["vertical-excitation3d", "beacon-placement"])
def test_shipped_studies_expand_into_valid_problems(name):
    spec = load_sweep(SWEEPS / f"{name}.toml")
    tasks = expand(spec)  # raises if any task is not a valid problem
    n = math.prod(len(a.values) for a in spec.axes)
    assert len(tasks) == n == 12
    assert len({t.id for t in tasks}) == n  # every combination is a different problem
    assert spec.mode == "plan"


def test_every_shipped_sweep_is_tested():
    assert sorted(p.stem for p in SWEEPS.glob("*.toml")) == [
        "beacon-placement",
        "vertical-excitation3d",
    ]


def test_vertical_study_sets_the_vertical_bound_only():
    tasks = expand(load_sweep(SWEEPS / "vertical-excitation3d.toml"))
    accel = {tuple(t.problem["limits"]["accel"]) for t in tasks}
    # range3d.toml's horizontal bounds are kept; only the z component varies
    assert {a[:2] for a in accel} == {(0.05, 0.05)}
    assert sorted({a[2] for a in accel}) == [0.0005, 0.002, 0.005, 0.02]


# ------------------------------------------------------------------------------ expansion
def test_product_and_zip_order():
    spec = spec_of({"limits.accel": [0.02, 0.05], "limits.speed": [0.5, 1.0, 1.5]})
    combos = combinations(spec)
    assert len(combos) == 6
    assert combos[0] == {"limits.accel": 0.02, "limits.speed": 0.5}
    assert combos[1] == {"limits.accel": 0.02, "limits.speed": 1.0}  # last axis fastest
    z = spec_of({"limits.accel": [0.02, 0.05], "limits.speed": [0.5, 1.0]}, combine="zip")
    assert combinations(z) == [
        {"limits.accel": 0.02, "limits.speed": 0.5},
        {"limits.accel": 0.05, "limits.speed": 1.0},
    ]


def test_zip_needs_equal_lengths():
    with pytest.raises(
        SweepFileError, match=r"zip needs axes of equal length.*limits\.accel has 2"
    ):
        spec_of({"limits.accel": [0.02, 0.05], "limits.speed": [1.0]}, combine="zip")


def test_toml_dotted_keys_and_quoted_paths_are_the_same(tmp_path):
    (tmp_path / "base.toml").write_text(
        "[start]\nposition = [-80.0, 60.0]\n[limits]\naccel = 0.05\nspeed = 1.0\n"
        "[horizon]\nduration = 120.0\nsteps = 12\n"
    )
    dotted = tmp_path / "a.toml"
    dotted.write_text('[sweep]\nbase = "base.toml"\n[axes]\nlimits.speed = [0.5, 1.0]\n')
    quoted = tmp_path / "b.toml"
    quoted.write_text('[sweep]\nbase = "base.toml"\n[axes]\n"limits.speed" = [0.5, 1.0]\n')
    ids_a = [t.id for t in expand(load_sweep(dotted))]
    ids_b = [t.id for t in expand(load_sweep(quoted))]
    assert ids_a == ids_b and len(ids_a) == 2


def test_component_axis_expands_a_scalar_and_fills_default_zeros():
    spec = spec_of({"limits.accel.1": [0.01], "beacon.position[0]": [30.0]})
    (task,) = expand(spec)
    assert task.problem["limits"]["accel"] == [0.05, 0.01]  # scalar base expanded per axis
    assert task.problem["beacon"]["position"] == [30.0, 0.0]  # omitted beacon: origin


def test_generators():
    spec = spec_of(
        {
            "validation.seed": {"range": 3},
            "limits.speed": {"linspace": [0.1, 0.3, 3]},
            "limits.accel": {"geomspace": [0.01, 1.0, 3]},
        }
    )
    values = {a.path: a.values for a in spec.axes}
    assert values["validation.seed"] == (0, 1, 2)
    # rounded to 12 significant digits: the same task as the hand-written 0.2
    assert values["limits.speed"] == (0.1, 0.2, 0.3)
    assert values["limits.accel"] == (0.01, 0.1, 1.0)
    assert spec_of({"validation.seed": {"range": [2, 8, 3]}}).axes[0].values == (2, 5)


@pytest.mark.parametrize(
    "axes, match",
    [
        ({"limits.acel": [0.1]}, r"axes\.limits\.acel: unknown field 'acel' of \[limits\]"),
        ({"limit.accel": [0.1]}, r"axes\.limit\.accel: unknown section 'limit'"),
        ({"limits": [0.1]}, r"axes\.limits: an axis is a field path section\.field"),
        ({"limits.speed.0": [0.1]}, r"limits\.speed has no part '0'"),
        ({"limits.accel": []}, r"axes\.limits\.accel: no values"),
        ({"limits.accel": 0.1}, r"axes\.limits\.accel: expected a list of values"),
        ({"validation.seed": {"range": 2.5}}, r"range takes an integer N"),
        ({"limits.accel": {"geomspace": [0.0, 1.0, 3]}}, r"geomspace needs start and stop > 0"),
        ({"limits.accel": {"linspace": [0.0, 1.0]}}, r"linspace takes \[start, stop, count\]"),
        ({"limits.accel": {"between": [0.0, 1.0]}}, r"has exactly one of range, linspace"),
    ],
)
def test_bad_axes_name_the_axis(axes, match):
    with pytest.raises(SweepFileError, match=match):
        spec_of(axes)


@pytest.mark.parametrize(
    "data, match",
    [
        ({"sweep": {"mode": "fast"}, "base": BASE, "axes": {"limits.speed": [1.0]}}, "sweep.mode"),
        (
            {"sweep": {"modes": "plan"}, "base": BASE, "axes": {"limits.speed": [1.0]}},
            "sweep.modes",
        ),
        ({"sweep": {}, "axes": {"limits.speed": [1.0]}}, "no base problem"),
        ({"sweep": {}, "base": BASE, "axes": {}}, r"\[axes\] is empty"),
        ({"sweep": {}, "base": {"limit": {}}, "axes": {"limits.speed": [1.0]}}, "base.limit"),
        ({"sweep": {}, "base": BASE, "axis": {}}, "axis: unknown table"),
        ({"sweep": {"base": "nowhere.toml"}, "axes": {"limits.speed": [1.0]}}, "not found"),
    ],
)
def test_bad_sweep_tables(data, match):
    with pytest.raises(SweepFileError, match=match):
        sweep_from_dict(data)


def test_a_typo_in_the_50th_task_is_an_error_naming_task_and_field(tmp_path):
    steps = [12] * 49 + [1]  # the 50th task has one planning step
    spec = spec_of(
        {"validation.seed": {"range": 50}, "horizon.steps": steps, "limits.speed": [1.0] * 50},
        combine="zip",
    )
    with pytest.raises(SweepFileError) as err:
        expand(spec)
    msg = str(err.value)
    assert msg.startswith("task 50 of the sweep (validation.seed = 49, horizon.steps = 1")
    assert "horizon.steps: must be at least 2, got 1" in msg
    # nothing ran and nothing was written
    out = tmp_path / "out"
    with pytest.raises(SweepFileError, match="task 50"):
        sweep(spec, out)
    assert not out.exists()


def test_errors_count_the_other_invalid_tasks():
    spec = spec_of({"limits.speed": [-1.0, 1.0, -2.0, 0.0]})
    with pytest.raises(
        SweepFileError, match=r"task 1 .*limits\.speed.*\(and 2 more invalid tasks\)"
    ):
        expand(spec)


# ------------------------------------------------------------------------------ identity
def test_task_identity_is_the_resolved_problem_mode_and_version():
    scalar = expand(spec_of({"limits.accel": [0.05]}))[0]
    vector = expand(spec_of({"limits.accel": [[0.05, 0.05]]}))[0]
    assert scalar.id == vector.id  # the same resolved problem, written two ways
    renamed = expand(spec_of({"problem.name": ["other label"], "limits.accel": [0.05]}))[0]
    assert renamed.id == scalar.id  # the name is a label
    baselines = expand(spec_of({"limits.accel": [0.05]}, mode="baselines"))[0]
    assert baselines.id != scalar.id
    changed = expand(spec_of({"limits.accel": [0.0501]}))[0]
    assert changed.id != scalar.id
    # the same sweep expanded twice: the same ids (a stable hash, not Python's salted hash())
    assert expand(spec_of({"limits.accel": [0.05]}))[0].id == scalar.id


def test_duplicate_combinations_are_one_task_on_two_rows():
    spec = spec_of({"limits.accel": [0.05, [0.05, 0.05], 0.02]})
    tasks = expand(spec)
    assert len(tasks) == 3 and len(unique_tasks(tasks)) == 2
    df = build_table(tasks, {})
    assert list(df["status"]) == ["pending"] * 3
    assert df["task_id"].iloc[0] == df["task_id"].iloc[1] != df["task_id"].iloc[2]


def test_resolved_problem_round_trips():
    for task in expand(spec_of({"limits.accel": [0.02, 0.05], "validation.seed": [0, 1]})):
        pb = problem_from_dict(task.problem)
        assert pb.limits.speed == 1.0 and pb.validation.seed == task.axes["validation.seed"]


def test_apply_axes_leaves_the_base_untouched():
    spec = spec_of({"limits.accel.0": [0.01]})
    before = json.dumps(spec.base, sort_keys=True)
    raw = apply_axes(spec.base, spec, {"limits.accel.0": 0.01})
    assert raw["limits"]["accel"] == [0.01, 0.05]
    assert json.dumps(spec.base, sort_keys=True) == before


def test_parse_path_forms():
    assert parse_path("limits.accel.2") == ("limits", "accel", 2)
    assert parse_path("limits.accel[2]") == ("limits", "accel", 2)
    assert parse_path("limits.area.x") == ("limits", "area", "x")
    assert parse_path("limits.area.x.1") == ("limits", "area", "x", 1)


# ------------------------------------------------------------------------------ table
def test_flatten_is_generic():
    report = {
        "solver": {"success": True, "starts": [{"label": "a", "wall_s": 1.0}, {"label": "b"}]},
        "metrics": {"planned": {"min_eig": 0.5, "log_det": float("-inf")}},
        "new_key": {"nested": {"deep": [1, 2]}},
    }
    flat = flatten(report)
    assert flat == {
        "solver.success": True,
        "solver.starts.0.label": "a",
        "solver.starts.0.wall_s": 1.0,
        "solver.starts.1.label": "b",
        "metrics.planned.min_eig": 0.5,
        "metrics.planned.log_det": None,  # non-finite -> missing
        "new_key.nested.deep": "[1, 2]",
    }


def test_table_rows_from_stored_reports_and_comparable_columns():
    tasks = expand(spec_of({"limits.accel": [0.02, 0.05], "beacon.position": [[0.0, 0.0]]}))
    stored = {
        tasks[0].id: {
            "sweep": {
                "status": "done",
                "error": None,
                "attempts": 1,
                "wall_s": 2.5,
                "worker": "h:1",
            },
            "solver": {"success": True, "wall_s": 2.0},
            "metrics": {"planned": {"min_eig": 1e-4}},
        }
    }
    df = build_table(tasks, stored)
    # axis columns are named by path and unit
    assert list(df.columns[:4]) == [
        "task_id",
        "task",
        "limits.accel [m/s^2]",
        "beacon.position [m]",
    ]
    assert df["beacon.position [m]"].tolist() == ["[0.0, 0.0]"] * 2
    assert df["status"].tolist() == ["done", "pending"]
    assert df.loc[0, "metrics.planned.min_eig"] == 1e-4
    assert pd.isna(df.loc[1, "metrics.planned.min_eig"])
    kept = set(comparable(df).columns)
    assert {"task_wall_s", "solver.wall_s", "worker", "attempts"}.isdisjoint(kept)
    assert {"solver.success", "metrics.planned.min_eig", "status"} <= kept


# ------------------------------------------------------------------------------ the verb's errors
def write_sweep(tmp_path: Path, axes: str, name: str = "t") -> Path:
    f = tmp_path / f"{name}.toml"
    f.write_text(
        f'[sweep]\nname = "{name}"\nbase = "{(ROOT / "problems" / "localise.toml").as_posix()}"\n'
        f"[axes]\n{axes}\n"
    )
    return f


def test_cli_bad_task_exits_2_naming_task_and_field(tmp_path, capsys):
    f = write_sweep(tmp_path, '"limits.speed" = [1.0, -1.0]')
    assert main(["sweep", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "task 2 of the sweep (limits.speed = -1.0)" in err and "limits.speed" in err
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_cli_refuses_a_foreign_folder_and_another_sweeps_folder(tmp_path, capsys):
    f = write_sweep(tmp_path, '"limits.speed" = [1.0]')
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("the user's file")
    assert main(["sweep", str(f), "--out", str(mine)]) == 2
    assert "not an obsplan output folder" in capsys.readouterr().err
    assert main(["sweep", str(f), "--out", str(mine), "--force"]) == 2  # --force does not help
    assert "not an obsplan output folder" in capsys.readouterr().err
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    assert (mine / "notes.txt").read_text() == "the user's file"
    other = tmp_path / "other"
    other.mkdir()
    (other / "sweep.json").write_text(json.dumps({"sweep": {"name": "another"}}))
    # a sweep.json alone does not make a sweep's folder: its marker does (the user's otherwise)
    assert main(["sweep", str(f), "--out", str(other), "--force"]) == 2
    assert "not an obsplan output folder" in capsys.readouterr().err
    write_marker(other, "sweep", record=False)
    assert main(["sweep", str(f), "--out", str(other)]) == 2
    assert "holds the results of sweep 'another'" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, match",
    [
        (["sweep"], "give a SWEEP.toml"),
        (["sweep", "x.toml"], "give --out DIR"),
        (["sweep", "nowhere.toml", "--out", "o"], "sweep file not found"),
        (["sweep", "--report", "nowhere"], "holds no sweep"),
        (["sweep", "x.toml", "--report", "o"], "give it alone"),
    ],
)
def test_cli_usage_errors_exit_2(argv, match, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert match in capsys.readouterr().err


def test_cli_workers_and_scheduler_exclude_each_other(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "x.toml", "--out", "o", "--workers", "2", "--scheduler", "tcp://h:1"])
    assert exc.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_cli_unreachable_scheduler_exits_2(tmp_path, capsys, monkeypatch):
    import socket

    import obsplan.sweeps.run as run

    monkeypatch.setattr(run, "CONNECT_TIMEOUT_S", 1.0)  # nothing listens: fail fast
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # free once closed: connection refused
    f = write_sweep(tmp_path, '"limits.speed" = [1.0]')
    code = main(
        ["sweep", str(f), "--out", str(tmp_path / "o"), "--scheduler", f"tcp://127.0.0.1:{port}"]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "cannot reach a Dask scheduler there" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()  # nothing written before the cluster was reached


def test_invalid_toml_is_named(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[sweep\n")
    with pytest.raises(SweepFileError, match=r"bad\.toml: not valid TOML"):
        load_sweep(bad)
    (tmp_path / "broken.toml").write_text("[start\n")
    ok = tmp_path / "ok.toml"
    ok.write_text('[sweep]\nbase = "broken.toml"\n[axes]\n"limits.speed" = [1.0]\n')
    with pytest.raises(SweepFileError, match=r"sweep\.base: .*broken\.toml: not valid TOML"):
        load_sweep(ok)


@pytest.mark.slow
def test_default_workers_follow_the_cpu_affinity():
    """A sweep pinned to one core (``taskset``, a batch allocation) starts one worker, not one per
    core of the machine."""
    if shutil.which("taskset") is None or len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs taskset and two cores")
    code = "from obsplan.sweeps.run import default_workers; print(default_workers())"
    out = subprocess.run(
        ["taskset", "-c", "0", sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert out.stdout.strip() == "1"


def test_set_fields_writes_paths_as_axes_do():
    from obsplan.planning import load_problem
    from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict

    base = problem_to_dict(load_problem(ROOT / "problems/range3d.toml"))
    out = set_fields(base, {"limits.accel.2": 0.01, "objective.kind": "pcrb-position"})
    pb = problem_from_dict(out)
    assert pb.limits.accel[2] == 0.01 and pb.objective.kind == "pcrb-position"
    assert base == problem_to_dict(load_problem(ROOT / "problems/range3d.toml"))  # not mutated
    with pytest.raises(SweepFileError, match="objective"):
        set_fields(base, {"objective.kinds": "pcrb-position"})
