"""``obsplan simulate``: JSON keys, figures, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from obsplan.cli import main
from obsplan.core.outputs import MARKER, write_marker
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


@pytest.fixture(scope="module")
def csv_2d(tmp_path_factory):
    path = tmp_path_factory.mktemp("traj") / "circle.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0).sample(0.1), path)
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
        (["--accel-noise", "-1"], "intensity >= 0"),
        (["--accel-noise", "1e-3", "--paper-noise"], "two settings of the same process noise"),
        (["--accel", "0"], "positive bound"),
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
    # --force does not replace a folder obsplan did not make
    args = ["simulate", str(csv_2d), "--runs", "2", "--quiet", "--out", str(out), "--force"]
    assert main(args) == 2
    assert "not an obsplan output" in capsys.readouterr().err
    assert (out / "estimation.png").read_bytes() == b"the user's own figure"
    write_marker(out, "simulate")  # an earlier obsplan output is replaced
    assert main(args) == 0
    assert (out / "estimation.png").read_bytes() != b"the user's own figure"


def test_dt_resamples_a_coarse_plan_onto_the_filter_grid(tmp_path, capsys):
    path = tmp_path / "coarse.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0).sample(1.0), path)  # 1 s samples, like a plan.csv
    assert main(["simulate", str(path), "--runs", "2", "--dt", "0.1", "--json"]) == 0
    fine = json.loads(capsys.readouterr().out)
    assert main(["simulate", str(path), "--runs", "2", "--json"]) == 0
    coarse = json.loads(capsys.readouterr().out)
    # ten times the range updates along the same path: the bound on the final position shrinks
    assert fine["crlb_final_pos_std"] < coarse["crlb_final_pos_std"]
    assert main(["simulate", str(path), "--runs", "2", "--dt", "0.3"]) == 2
    assert "--dt = 0.3 s must divide" in capsys.readouterr().err


# ---------------------------------------------------------------- rows of the CLI issue
def test_negative_seed_is_refused_with_the_fix(csv_2d, capsys):
    assert main(["simulate", str(csv_2d), "--seed", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--seed -1: a seed must be a non-negative integer" in err and err.count("\n") == 1


def test_absurd_resampling_is_refused_before_allocating(csv_2d, capsys):
    """``--dt 1e-7`` used to end in a MemoryError of 89 GiB; now one line with the limit."""
    import tracemalloc

    tracemalloc.start()
    code = main(["simulate", str(csv_2d), "--dt", "1e-7", "--quiet"])
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert code == 2
    err = capsys.readouterr().err
    assert "more than the limit of 2000000 samples per run" in err and "--dt >=" in err
    assert peak < 50 * 2**20  # nothing near the 89 GiB was attempted (50 MiB: imports etc.)
    assert main(["simulate", str(csv_2d), "--runs", "100000000", "--quiet"]) == 2
    assert "more than the limit of 10000 Monte Carlo runs" in capsys.readouterr().err


@pytest.mark.parametrize("where", ["under-a-file", "sys"])
def test_unwritable_out_is_refused_before_any_work(csv_2d, tmp_path, capsys, where, monkeypatch):
    out = {"under-a-file": csv_2d / "figs", "sys": Path("/sys/obsplan-test-out")}[where]
    if where == "sys" and not Path("/sys").is_dir():
        pytest.skip("no /sys")

    def never(*a, **k):
        raise AssertionError("the simulation ran before the output was checked")

    monkeypatch.setattr("obsplan.cli.simulate.monte_carlo", never)
    code = main(["simulate", str(csv_2d), "--runs", "2", "--quiet", "--out", str(out)])
    if where == "sys" and code != 2:
        pytest.skip("/sys is writable here")
    assert code == 2
    cap = capsys.readouterr()
    assert "cannot write" in cap.err or "is a file" in cap.err
    assert cap.out == ""


def test_force_replaces_the_figure_folder_whole(csv_2d, tmp_path, capsys):
    out = tmp_path / "figs"
    out.mkdir()
    (out / "stale.png").write_bytes(b"from an earlier run")
    write_marker(out, "simulate")  # an earlier run wrote it (the marker lists it)
    args = ["simulate", str(csv_2d), "--runs", "2", "--quiet", "--out", str(out), "--force"]
    assert main(args) == 0
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "estimation.png", "monte_carlo.png"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left


def test_filters_option_and_problem_conflicts(csv_2d, capsys):
    assert main(["simulate", str(csv_2d), "--runs", "2", "--json", "--filters", "ekf"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ekf"] is not None and d["kf"] is None
    assert main(["simulate", str(csv_2d), "--filters", "ukf9"]) == 2
    assert "filters" in capsys.readouterr().err
    prob = str(PROBLEMS / "localise.toml")
    assert main(["simulate", str(csv_2d), "--problem", prob, "--dt", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "--dt cannot be combined with --problem" in err and "validation.dt" in err
    assert main(["simulate", str(csv_2d), "--problem", str(PROBLEMS / "range3d.toml")]) == 2
    assert "is 3D (vehicle.dim)" in capsys.readouterr().err


@pytest.mark.slow
def test_ctrl_c_during_the_monte_carlo_exits_130_and_writes_nothing(csv_2d, tmp_path):
    out = tmp_path / "figs"
    from _interrupt import interrupt_after

    code, err = interrupt_after(
        ["simulate", str(csv_2d), "--runs", "10000", "--out", str(out)], b"run", 0.5
    )
    assert code == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_force_never_deletes_the_input_trajectory(csv_2d, tmp_path, capsys):
    res = tmp_path / "res"
    res.mkdir()
    write_marker(res, "plan")  # an obsplan output folder, yet it holds the input
    traj = res / "plan.csv"
    traj.write_bytes(csv_2d.read_bytes())
    args = ["simulate", str(traj), "--runs", "2", "--quiet", "--out", str(res), "--force"]
    assert main(args) == 2
    assert "holds the input" in capsys.readouterr().err and traj.is_file()


def test_closed_loop_by_default_open_loop_on_request(csv_2d, capsys):
    """The default flies the path in closed loop (the truth steered on the EKF's estimate) and
    reports the true paths; --open-loop flies the inputs blind; the physical process noise is the
    default and the paper's per-step setting is reachable."""
    base = ["simulate", str(csv_2d), "--runs", "3", "--json", "--beacon", "5,5"]
    assert main(base) == 0
    closed = json.loads(capsys.readouterr().out)
    assert closed["mode"] == "closed-loop" and closed["guidance"]["kp"] > 0
    assert closed["truth"]["closest_range_m"] > 0 and closed["truth"]["tracking_rmse_m"] > 0
    assert closed["config"]["process_noise_model"] == "continuous"
    assert main([*base, "--open-loop", "--paper-noise"]) == 0
    opened = json.loads(capsys.readouterr().out)
    assert opened["mode"] == "open-loop" and opened["guidance"] is None
    assert opened["config"]["process_noise_model"] == "per-step"
    assert main([*base, "--accel-noise", "0.01"]) == 0
    assert json.loads(capsys.readouterr().out)["config"]["accel_noise"] == 0.01
    prob = str(PROBLEMS / "localise.toml")
    assert main(["simulate", str(csv_2d), "--problem", prob, "--accel-noise", "0.01"]) == 2
    assert "validation.accel_noise" in capsys.readouterr().err
