"""``obsplan plan``: outputs, report keys, strict JSON, overwrite protection, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from obsplan.cli import main
from obsplan.trajectory import read_csv

SMALL = ["--steps", "20", "--starts", "1", "--runs", "2", "--quiet"]


def _strict_json(path: Path) -> dict:
    def bad(x):
        raise ValueError(f"non-strict JSON constant {x}")

    return json.loads(path.read_text(), parse_constant=bad)


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan") / "out"
    code = main(["plan", "--out", str(out), *SMALL])
    return code, out


def test_default_problem_writes_plan_report_and_figures(default_run, capsys):
    code, out = default_run
    assert code == 0
    for name in ("plan.csv", "report.json", "path.png", "gramian.png", "filters.png"):
        assert (out / name).is_file(), name
    traj = read_csv(out / "plan.csv")
    assert traj.n_samples == 21 and traj.dim == 2
    rep = _strict_json(out / "report.json")
    assert set(rep["solver"]) >= {"success", "status", "iterations", "wall_s"}
    assert rep["solver"]["success"] is True
    assert rep["problem"]["name"] == "default: 2D range-only"  # no PROBLEM: the default file
    assert {"planned", "lawnmower", "circle", "straight"} <= set(rep["metrics"])
    for m in rep["metrics"].values():
        assert set(m) >= {"min_eig", "log_det", "condition", "kf_final_pos_std"}
    for v in rep["validation"].values():
        assert {"rmse_pos", "final_pos_err", "nees_mean"} <= set(v["ekf"]) & set(v["kf"])
    # the straight line has a singular Gramian: log_det is null, not -Infinity
    assert rep["metrics"]["straight"]["log_det"] is None


def test_refuses_non_empty_out_without_force(default_run, capsys):
    _, out = default_run
    code = main(["plan", "--out", str(out), *SMALL])
    assert code == 2
    assert "--force" in capsys.readouterr().err
    assert main(["plan", "--out", str(out), "--force", "--no-validate", *SMALL]) == 0
    rep = _strict_json(out / "report.json")
    assert rep["validation"] == {}


def test_summary_table_printed(tmp_path, capsys):
    code = main(["plan", "--out", str(tmp_path / "o"), "--no-validate", *SMALL])
    assert code == 0
    text = capsys.readouterr().out
    assert "planned" in text and "lawnmower" in text and "min_eig" in text


def test_bad_problem_file_exit_2_names_field(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        "[start]\nposition = [0.0, 50.0]\nvelocity = [2.0, 0.0]\n"
        "[limits]\naccel = 0.05\nspeed = 1.0\n[horizon]\nduration = 100.0\nsteps = 10\n"
    )
    code = main(["plan", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert "start.velocity" in err and "limits.speed" in err
    assert not (tmp_path / "o").exists()


def test_failed_solve_exits_1(tmp_path, capsys):
    prob = tmp_path / "p.toml"
    prob.write_text(
        Path("problems/default.toml")
        .read_text()
        .replace("seed = 0\n", "seed = 0\nmax_iter = 1\n", 1)
    )
    code = main(["plan", str(prob), "--out", str(tmp_path / "o"), "--no-validate", *SMALL])
    assert code == 1
    assert "no start converged" in capsys.readouterr().err
    rep = _strict_json(tmp_path / "o" / "report.json")
    assert rep["solver"]["success"] is False
    assert rep["solver"]["status"] == "Maximum_Iterations_Exceeded"
