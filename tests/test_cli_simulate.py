"""``obsplan simulate``: JSON keys, figures, exit codes."""

from __future__ import annotations

import json

import pytest

from obsplan import generators as gen
from obsplan.cli import main
from obsplan.trajectory import write_csv


@pytest.fixture(scope="module")
def csv_2d(tmp_path_factory):
    path = tmp_path_factory.mktemp("traj") / "circle.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0, 0.1), path)
    return path


def test_json_has_the_stable_keys(csv_2d, capsys):
    assert main(["simulate", str(csv_2d), "--runs", "3", "--seed", "4", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert list(d)[:5] == ["runs", "seed", "ekf", "kf", "crlb_final_pos_std"]
    for name in ("ekf", "kf"):
        assert list(d[name])[:4] == ["final_pos_err", "rmse_pos", "final_pos_std", "nees_mean"]
        assert all(isinstance(d[name][k], float) for k in list(d[name])[:4])
    assert d["runs"] == 3 and d["seed"] == 4


def test_table_rates_and_figures(csv_2d, tmp_path, capsys):
    out = tmp_path / "figs"
    code = main(
        [
            "simulate",
            str(csv_2d),
            "--runs",
            "2",
            "--rates",
            "range=1",
            "--quiet",
            "--sensors",
            "range,dvl",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "EKF" in text and "KF" in text and "CRB" in text
    assert (out / "estimation.png").stat().st_size > 10_000
    assert (out / "monte_carlo.png").is_file()


@pytest.mark.parametrize(
    "args,match",
    [
        (["--rates", "range=-1"], "must be a positive rate"),
        (["--rates", "range"], "expected SENSOR=NUMBER"),
        (["--sensors", "range,sonar"], "unknown sensor"),
        (["--noise", "range=-0.1"], "positive standard deviation"),
        (["--init-error", "1,2"], "init_error: expected 4"),
        (["--runs", "0"], "at least 1 run"),
        (["--beacon", "1,2,3"], "beacon"),
    ],
)
def test_bad_options_exit_2(csv_2d, capsys, args, match):
    assert main(["simulate", str(csv_2d), "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1


def test_missing_file_exit_2(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "nope.csv")]) == 2
    assert "not found" in capsys.readouterr().err


def test_out_folder_with_user_files_is_not_overwritten(csv_2d, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "estimation.png").write_bytes(b"the user's own figure")
    code = main(["simulate", str(csv_2d), "--runs", "2", "--quiet", "--out", str(out)])
    assert code == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "estimation.png").read_bytes() == b"the user's own figure"
    assert (
        main(["simulate", str(csv_2d), "--runs", "2", "--quiet", "--out", str(out), "--force"]) == 0
    )
    assert (out / "estimation.png").read_bytes() != b"the user's own figure"


def test_dt_resamples_a_coarse_plan_onto_the_filter_grid(tmp_path, capsys):
    path = tmp_path / "coarse.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0, 1.0), path)  # 1 s samples, like a plan.csv
    assert main(["simulate", str(path), "--runs", "2", "--dt", "0.1", "--json"]) == 0
    fine = json.loads(capsys.readouterr().out)
    assert main(["simulate", str(path), "--runs", "2", "--json"]) == 0
    coarse = json.loads(capsys.readouterr().out)
    # ten times the range updates along the same path: the bound on the final position shrinks
    assert fine["crlb_final_pos_std"] < coarse["crlb_final_pos_std"]
    assert main(["simulate", str(path), "--runs", "2", "--dt", "0.3"]) == 2
    assert "--dt = 0.3 s must divide" in capsys.readouterr().err
