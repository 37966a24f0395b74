"""``obsplan plan``: outputs, report keys, strict JSON, overwrite protection, exit codes."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.core.outputs import MARKER, write_marker
from obsplan.trajectory.sampled import read_csv

SMALL = ["--steps", "20", "--starts", "1", "--runs", "2", "--max-runs", "2", "--quiet"]
PROBLEMS = Path(__file__).resolve().parents[1] / "problems"
#: The free localisation problem: the small CLI runs (a mission refuses 20 steps).
LOCALISE = str(PROBLEMS / "localise.toml")


def _strict_json(path: Path) -> dict:
    def bad(x):
        raise ValueError(f"non-strict JSON constant {x}")

    return json.loads(path.read_text(), parse_constant=bad)


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan") / "out"
    code = main(["plan", LOCALISE, "--out", str(out), *SMALL])
    return code, out


@pytest.mark.slow
def test_default_survey_plans_and_reports_its_mission(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["plan", "--out", str(out), "--steps", "96", "--runs", "2", "--quiet"]) == 0
    assert (out / "speed.png").is_file()
    doc = _strict_json(out / "report.json")
    assert doc["mission"]["planned"]["complete"] is True
    assert len(doc["mission"]["lawnmower"]["lines"]) == 3
    assert "mission" in capsys.readouterr().out


def test_a_small_plan_writes_plan_report_and_figures(default_run, capsys):
    code, out = default_run
    assert code == 0
    for name in ("plan.csv", "report.json", "path.png", "gramian.png", "filters.png"):
        assert (out / name).is_file(), name
    traj = read_csv(out / "plan.csv")
    assert traj.n_samples == 21 and traj.dim == 2
    rep = _strict_json(out / "report.json")
    assert set(rep["solver"]) >= {"success", "status", "iterations", "wall_s"}
    assert rep["solver"]["success"] is True
    assert rep["problem"]["name"] == "localise: 2D range-only, free localisation"
    assert rep["mission"] == {}  # no [mission]
    assert {"planned", "lawnmower", "circle", "straight"} <= set(rep["metrics"])
    for m in rep["metrics"].values():
        assert set(m) >= {"min_eig", "log_det", "condition", "kf_final_pos_std"}
    assert rep["validation"]["mode"] == "closed-loop"  # the default
    for name, v in rep["validation"].items():
        if name in ("mode", "channel"):
            continue
        assert {"rmse_pos", "final_pos_err", "nees_mean"} <= set(v["ekf"]) & set(v["kf"])
        truth = v["truth"]
        assert truth["closest_range_m"] > 0 and truth["tracking_rmse_m"] > 0
        assert 0 <= truth["runs_inside_min_range"] <= v["runs"]
        assert 0 <= truth["any_violation_fraction"] <= 1
        # every checked limit has its worst excess, positive exactly where some run broke it
        assert set(truth["worst_excess"]) == set(truth["violation_fraction"])
        for lim, frac in truth["violation_fraction"].items():
            assert (truth["worst_excess"][lim] > 0) == (frac > 0), (name, lim)
    # the straight line has a singular Gramian: log_det is null, not -Infinity
    assert rep["metrics"]["straight"]["log_det"] is None


def test_refuses_non_empty_out_without_force(default_run, capsys):
    _, out = default_run
    code = main(["plan", LOCALISE, "--out", str(out), *SMALL])
    assert code == 2
    assert "--force" in capsys.readouterr().err
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 0
    rep = _strict_json(out / "report.json")
    assert rep["validation"] == {}


def test_summary_table_printed(tmp_path, capsys):
    code = main(["plan", LOCALISE, "--out", str(tmp_path / "o"), "--no-validate", *SMALL])
    assert code == 0
    text = capsys.readouterr().out
    assert "planned" in text and "lawnmower" in text and "PCRB avg" in text
    # without validation nothing says the plan is better, and the words say so
    assert "no validation was run" in text


def test_verdict_in_words_and_in_the_report(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["plan", LOCALISE, "--out", str(out), "--runs", "3", *SMALL])
    assert code == 0
    text = capsys.readouterr().out
    rep = _strict_json(out / "report.json")
    verdict = rep["verdict"]
    assert set(verdict["baselines"]) == set(rep["validation"]) - {"planned", "mode", "channel"}
    for comps in verdict["baselines"].values():
        assert {"ekf.rmse_pos", "ekf.final_pos_err", "kf.rmse_pos"} <= set(comps)
        for c in comps.values():
            assert c["better"] == (
                c["planned"] is not None and (c["baseline"] is None or c["planned"] < c["baseline"])
            )
            # an interval of the ratio that excludes 1 on the side of "better" decides
            assert isinstance(c["decided"], bool)
            if c["ci"] is not None:
                lo, hi = c["ci"]
                assert lo <= hi
                assert c["decided"] == ((hi < 1) if c["better"] else (lo > 1))
    # every tie is printed, in words
    for tie in verdict["ties"]:
        assert tie in text
    # every loss in the report is printed, in words
    for loss in verdict["losses"]:
        assert loss in text
    if verdict["beats_all"] and not verdict["losses"]:
        # "beats" only when every verdict is decided; ahead with ties says so
        won = "the plan beats every validated baseline on every metric"
        assert (won in text) == (not verdict["ties"])
        assert ("not decidedly on the ties below" in text) == bool(verdict["ties"])


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
        (PROBLEMS / "localise.toml")
        .read_text()
        .replace("seed = 0\n", "seed = 0\nmax_iter = 1\n", 1)
    )
    code = main(["plan", str(prob), "--out", str(tmp_path / "o"), "--no-validate", *SMALL])
    assert code == 1
    rep = _strict_json(tmp_path / "o" / "report.json")
    assert rep["solver"]["success"] is False
    # the status is the flown path's (a stalled start's or re-solve's, or a guess returned
    # unchanged), and the words name it
    flown = rep["solver"]["status"]
    assert flown in ("Maximum_Iterations_Exceeded", "Guess_Returned")
    assert f"not a converged solution (solver.status {flown})" in capsys.readouterr().err


# ---------------------------------------------------------------- rows of the CLI issue


def test_times_are_written_on_the_planning_grid(default_run):
    _, out = default_run
    times = [line.split(",")[0] for line in (out / "plan.csv").read_text().splitlines()[1:]]
    assert times[:3] == ["0.0", "30.0", "60.0"] and times[-1] == "600.0"
    assert all(len(s) <= 6 for s in times)  # never 56.99999999999999


def test_simulate_with_the_problem_reproduces_the_plan_validation(tmp_path, capsys):
    """``simulate plan.csv --problem P.toml`` runs exactly the validation of ``plan``."""
    out = tmp_path / "plan"
    assert main(["plan", str(PROBLEMS / "localise.toml"), "--out", str(out), *SMALL]) == 0
    capsys.readouterr()
    rep = _strict_json(out / "report.json")["validation"]["planned"]
    figs = tmp_path / "figs"
    args = ["simulate", str(out / "plan.csv"), "--problem", str(PROBLEMS / "localise.toml")]
    assert main([*args, "--runs", "2", "--json", "--out", str(figs)]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert sim["runs"] == rep["runs"] == 2 and sim["seed"] == rep["seed"]
    for f in ("ekf", "kf"):
        for key in ("rmse_pos", "final_pos_err", "final_pos_std", "nees_mean"):
            # same path, configuration, runs and seed: equal up to the times' grid rounding
            assert sim[f][key] == pytest.approx(rep[f][key], rel=1e-9), (f, key)
    assert sim["crlb_final_pos_std"] == pytest.approx(rep["crlb_final_pos_std"], rel=1e-9)
    assert {"filters.png", "estimation.png", "monte_carlo.png"} <= {p.name for p in figs.iterdir()}


def test_force_replaces_the_results_folder_whole(tmp_path, capsys):
    """The old filters.png no longer stays beside a new plan written with --no-validate."""
    out = tmp_path / "results"
    out.mkdir()
    for name in ("filters.png", "plan.csv"):
        (out / name).write_text("old")
    write_marker(out, "plan")  # an earlier obsplan output (these files): --force may replace it
    (out / "notes.txt").write_text("the user's")  # but not a file the user added
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 2
    assert "notes.txt" in capsys.readouterr().err
    (out / "notes.txt").unlink()
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {MARKER, "plan.csv", "report.json", "path.png", "gramian.png"}
    assert (out / "plan.csv").read_text() != "old"
    assert [p.name for p in tmp_path.iterdir()] == ["results"]  # no staging or old copy left


@pytest.mark.parametrize("case", ["under-a-file", "read-only-folder", "sys"])
def test_unwritable_out_is_refused_before_planning(tmp_path, capsys, monkeypatch, case):
    def never(*a, **k):
        raise AssertionError("the plan ran before the output folder was checked")

    monkeypatch.setattr("obsplan.cli.plan.plan", never)
    if case == "under-a-file":
        (tmp_path / "f").write_text("x")
        out, extra = tmp_path / "f" / "out", []
    elif case == "read-only-folder":
        out, extra = tmp_path / "ro", ["--force"]
        out.mkdir()
        (out / "keep.txt").write_text("mine")
        write_marker(out, "plan")
        out.chmod(0o555)
    else:
        out, extra = Path("/sys/obsplan-test-out"), []
        if not Path("/sys").is_dir():
            pytest.skip("no /sys")
    try:
        code = main(["plan", LOCALISE, "--out", str(out), *extra, *SMALL])
    finally:
        if case == "read-only-folder":
            out.chmod(0o755)
    if case == "sys" and code != 2:
        pytest.skip("/sys is writable here")
    assert code == 2
    err = capsys.readouterr().err
    assert {"under-a-file": "is a file", "read-only-folder": "read-only", "sys": "cannot write"}[
        case
    ] in err
    if case == "read-only-folder":
        assert (out / "keep.txt").read_text() == "mine"


@pytest.mark.slow
def test_interrupt_while_writing_leaves_nothing(tmp_path, capsys, monkeypatch):
    """Ctrl-C after plan.csv is written but before the figures: no half-written folder."""
    import obsplan.planning.results as results

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(results, "save_figure", interrupted)
    out = tmp_path / "o"
    assert main(["plan", LOCALISE, "--out", str(out), "--no-validate", *SMALL]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    # an existing results folder replaced with --force is left untouched
    out.mkdir()
    (out / "plan.csv").write_text("old plan")
    write_marker(out, "plan")
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 130
    assert [p.name for p in tmp_path.iterdir()] == ["o"]
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "plan.csv"]
    assert (out / "plan.csv").read_text() == "old plan"


@pytest.mark.parametrize("existing", [True])
def test_ctrl_c_during_the_solve_exits_130_and_writes_nothing(tmp_path, existing):
    """SIGINT to the real process while IPOPT runs: exit 130, DIR untouched (``existing``;
    an absent DIR staying absent is ``test_interrupt_while_writing_leaves_nothing``)."""
    from _interrupt import interrupt_after

    out = tmp_path / "o"
    extra = []
    if existing:
        out.mkdir()
        (out / "plan.csv").write_text("old plan")
        write_marker(out, "plan")
        extra = ["--force"]
    # the free localisation problem at N = 1000 (a coarse pass, then 4 fine starts): tens of
    # seconds
    code, err = interrupt_after(
        ["plan", LOCALISE, "--out", str(out), "--steps", "1000", *extra], b"starts", 1.0
    )
    assert code == 130, err
    assert "Traceback" not in err
    if existing:
        assert sorted(p.name for p in out.iterdir()) == [MARKER, "plan.csv"]
        assert (out / "plan.csv").read_text() == "old plan"
    else:
        assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_3d_path_figure_has_a_depth_view_and_the_area_in_the_legend():
    from obsplan.planning.figures import plot_gramian_eigs, plot_paths
    from obsplan.planning.problem.parse import load_problem
    from obsplan.trajectory import generators as gen

    pb = load_problem(PROBLEMS / "range3d.toml")
    path = gen.circle_z(
        30.0, 1.0, 120.0, center=(-80.0, 30.0), z0=10.0, z_amp=2.0, z_period=60.0
    ).sample(1.0)
    fig = plot_paths({"planned": path}, pb)
    ax_xy, ax_z = fig.axes
    assert ax_z.get_ylabel() == "z = depth [m]" and ax_z.yaxis_inverted()
    assert "operating area" in [t.get_text() for t in ax_xy.get_legend().get_texts()]
    assert "depth band" in [t.get_text() for t in ax_z.get_legend().get_texts()]
    assert np.allclose(ax_z.lines[0].get_ydata(), path.p[:, 2])
    g = plot_gramian_eigs({"planned": path}, pb)
    assert "smallest eigenvalue of the scaled augmented Gramian" in g.axes[0].get_title()


def test_force_never_deletes_the_problem_file(tmp_path, capsys):
    res = tmp_path / "res"
    res.mkdir()
    write_marker(res, "plan")  # even an obsplan output folder is kept when it holds the input
    prob = res / "p.toml"
    prob.write_text((PROBLEMS / "localise.toml").read_text())
    assert main(["plan", str(prob), "--out", str(res), "--force", *SMALL]) == 2
    assert "holds the input" in capsys.readouterr().err
    assert prob.is_file()


def test_limit_breaks_names_each_limit_its_share_of_runs_and_worst_excess():
    from obsplan.estimation.montecarlo.guidance import TruthLimits
    from obsplan.estimation.montecarlo.stats import TruthStats

    z = np.zeros(4)
    tr = TruthStats(
        closest_range_runs=np.array([6.0, 4.5, 7.0, 8.0]),  # one run 0.5 m inside 5 m
        farthest_range_runs=np.full(4, 50.0),
        tracking_rmse_runs=z,
        final_drift_runs=z,
        max_speed_runs=np.array([0.99, 1.0009, 1.002, 0.5]),  # two runs over 1 m/s
        area_excursion_runs=z,
        depth_excursion_runs=z,
        saturated_fraction_runs=z,
        accel_ratio_runs=np.full(4, 0.9),
        limits=TruthLimits(accel=0.05, speed=1.0, min_range=5.0, area=((-9, 9), (-9, 9))),
    )
    assert tr.breaks_words() == (
        "speed in 50.0 % (by up to 0.002 m/s), min_range in 25.0 % (by up to 0.5 m)"
    )
    within = replace(tr, max_speed_runs=np.full(4, 0.9), closest_range_runs=np.full(4, 9.0))
    assert within.breaks_words() == ""
