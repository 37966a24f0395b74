"""The command-line rows about inputs: encodings, magnitudes, geodetic ranges, damaged logs, files.

Each test is one row of the table of inputs that used to end in a traceback, a silent loss or a
misleading message. Through :func:`obsplan.cli.main`, in-process: a refusal is exit 2 with one
line on stderr naming what is wrong, before any work and with nothing written; an accepted input
either runs (small cases) or reaches the long computation, which is replaced by a sentinel.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.trajectory.sampled import Trajectory, read_csv, write_csv

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "problems" / "localise.toml"
EXAMPLES = ROOT / "examples"


class Reached(Exception):
    """The verb accepted its inputs and got to its long computation."""


def _stop(*args, **kwargs):
    raise Reached


def run(argv: list[str], capsys) -> tuple[int | str, str, str]:
    """Exit code (or ``"reached"``), stdout and stderr of ``main(argv)``."""
    try:
        code: int | str = main([str(a) for a in argv])
    except Reached:
        code = "reached"
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "Warning" not in err, err
    return code, out, err


def refused(argv: list[str], capsys, *needles: str) -> str:
    """Exit 2, one line on stderr containing every needle; returns the line."""
    code, _, err = run(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def stop_long_work(monkeypatch):
    monkeypatch.setattr("obsplan.cli.plan.plan", _stop)
    monkeypatch.setattr("obsplan.cli.simulate.monte_carlo", _stop)


@pytest.fixture
def traj2(tmp_path) -> Path:
    t = np.linspace(0.0, 60.0, 21)
    u = 0.05 * np.c_[np.sin(t / 10), np.cos(t / 10)]
    return write_csv(Trajectory.from_inputs(t, [-80.0, 60.0], [0.0, 0.5], u), tmp_path / "t.csv")


# ------------------------------------------------------------------ row 7: huge tables
def test_row7_a_table_beyond_the_row_limit_is_refused_before_parsing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("obsplan.core.csvtable.MAX_ROWS", 1000)
    big = tmp_path / "big.csv"
    t = np.arange(5000.0)
    np.savetxt(big, np.c_[t, 0.1 * t, 0.2 * t], delimiter=",", header="t,px,py", comments="")
    for argv in (["analyze", big], ["import", big, "--out", tmp_path / "o.csv"]):
        line = refused(argv, capsys, "5,000 rows", "1,000 rows", "GB of memory")
        assert "subsample or split" in line
    assert not (tmp_path / "o.csv").exists()


# ------------------------------------------------------------------ row 9: encodings, huge noise
@pytest.mark.parametrize(
    "content,needle",
    [
        (b'[problem]\nname = "caf\xe9"\n', "line 2, column 12: byte 0xe9 is not UTF-8"),
        (b"\x89PNG\r\n\x1a\n\x00\x00garbage", "not a text file"),
        ("[problem]\n".encode("utf-16"), "saved as UTF-16 text"),
    ],
    ids=["latin-1", "binary", "utf-16"],
)
def test_row9_toml_in_another_encoding_or_binary(tmp_path, capsys, content, needle):
    p = tmp_path / "p.toml"
    p.write_bytes(content)
    refused(["plan", p, "--out", tmp_path / "o"], capsys, needle, "p.toml")
    refused(["sweep", p, "--out", tmp_path / "s"], capsys, needle)
    assert not (tmp_path / "o").exists() and not (tmp_path / "s").exists()


def test_row9_absurd_noise_and_a_scheduler_that_is_no_address(tmp_path, traj2, capsys):
    refused(["simulate", traj2, "--noise", "range=1e200", "--runs", "2"], capsys, "1e+200")
    sweep = ROOT / "problems" / "sweeps" / "beacon-placement.toml"
    refused(
        ["sweep", sweep, "--out", tmp_path / "s", "--scheduler", "notaurl"],
        capsys,
        "--scheduler notaurl",
        "tcp://HOST:8786",
    )


# ------------------------------------------------------------------ row 10: geodetic ranges
def test_row10_beacon_at_the_antipode_of_the_origin(tmp_path, capsys):
    pytest.importorskip("pymap3d")
    text = (EXAMPLES / "geodetic.toml").read_text(encoding="utf-8")
    lat = text.split("geodetic = [")[1].split(",")[0]
    p = tmp_path / "far.toml"
    p.write_text(text.replace(f"geodetic = [{lat}", f"geodetic = [{-float(lat)!r}", 1))
    refused(["plan", p, "--out", tmp_path / "o"], capsys, "beacon.geodetic", "km from the origin")


def _write_tlog(path: Path, t, p, v, kind: str, damage: np.ndarray | None = None) -> Path:
    mav2 = pytest.importorskip("pymavlink.dialects.v20.ardupilotmega")
    m = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    raw = bytearray()
    for k, tk in enumerate(t):
        ms = int(round(tk * 1000))
        if kind == "LOCAL_POSITION_NED":
            msg = mav2.MAVLink_local_position_ned_message(ms, *p[k], *v[k])
        else:
            lat, lon, depth = p[k]
            cm = [int(round(x * 100)) for x in v[k]]
            alt = int(round(-depth * 1000))
            msg = mav2.MAVLink_global_position_int_message(
                ms, int(round(lat * 1e7)), int(round(lon * 1e7)), alt, alt, *cm, 0
            )
        raw += struct.pack(">Q", 1_700_000_000_000_000 + ms * 1000) + msg.pack(m)
    if damage is not None:
        rng = np.random.default_rng(0)
        for i in damage:
            raw[int(i)] = int(rng.integers(0, 256))
    path.write_bytes(bytes(raw))
    return path


def test_row10_a_log_near_pisa_imported_about_an_origin_at_sydney(tmp_path, capsys):
    pytest.importorskip("pymap3d")
    t = np.arange(60.0)
    p = np.c_[43.7 + 1e-6 * t, np.full(60, 10.3), np.full(60, 5.0)]
    log = _write_tlog(tmp_path / "g.tlog", t, p, np.zeros((60, 3)), "GLOBAL")
    out = tmp_path / "o.csv"
    refused(
        ["import", log, "--out", out, "--origin", "-33.9,151.2"],
        capsys,
        "GLOBAL_POSITION_INT (sample 0)",
        "km from the origin (-33.9, 151.2)",
    )
    assert not out.exists()
    # about its own first fix (the default) the same log is fine
    code, _, err = run(["import", log, "--out", out], capsys)
    assert code == 0, err
    refused(
        ["analyze", out, "--origin", "-33.9,151.2", "--beacon-geodetic", "43.7,10.3"],
        capsys,
        "--beacon-geodetic",
        "within 50 km",
    )


# ------------------------------------------------------------------ row 11: damaged MAVLink logs
def _survey_log(tmp_path: Path, name: str, damage=None) -> Path:
    t = np.arange(301.0)
    p = np.c_[0.5 * t, 10 * np.sin(t / 30), np.full(t.size, 4.0)]
    v = np.c_[np.full(t.size, 0.5), np.cos(t / 30) / 3, np.zeros(t.size)]
    return _write_tlog(tmp_path / name, t, p, v, "LOCAL_POSITION_NED", damage)


def test_row11_a_damaged_log_says_what_was_lost_and_refuses_below_90_percent(tmp_path, capsys):
    whole = _survey_log(tmp_path, "whole.tlog")
    size = whole.stat().st_size
    code, _, err = run(["import", whole, "--out", tmp_path / "w.csv"], capsys)
    assert code == 0 and "warning" not in err, err
    # 200 consecutive bytes damaged: a few messages lost, said on stderr
    burst = _survey_log(tmp_path, "burst.tlog", np.arange(size // 3, size // 3 + 200))
    code, _, err = run(["import", burst, "--out", tmp_path / "b.csv"], capsys)
    assert code == 0, err
    warn = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warn) == 1 and "could not be decoded" in warn[0] and "of about 301" in warn[0]
    read = int(warn[0].split("; ")[1].split()[0])
    assert 250 <= read < 301
    # 200 bytes spread over the log: most messages fail their checksum -> refused
    spread = np.random.default_rng(1).choice(size, 200, replace=False)
    scattered = _survey_log(tmp_path, "spread.tlog", spread)
    refused(["import", scattered, "--out", tmp_path / "s.csv"], capsys, "below the 90 %")
    assert not (tmp_path / "s.csv").exists()


# ------------------------------------------------------------------ row 16: magnitudes
def test_row16_huge_values_are_refused_by_column_and_option(tmp_path, traj2, capsys):
    lines = traj2.read_text().splitlines()
    cells = lines[2].split(",")
    cells[1] = "1e300"
    bad = tmp_path / "big.csv"
    bad.write_text("\n".join([*lines[:2], ",".join(cells), *lines[3:]]) + "\n")
    refused(["analyze", bad], capsys, "row 3, column 'px'", "1e+300 m is beyond")
    refused(["analyze", traj2, "--beacon", "1e300,0"], capsys, "--beacon '1e300,0'", "beyond")


# ------------------------------------------------------------------ row 17: one line each
def test_row17_a_byte_order_mark_in_a_toml_is_not_content(tmp_path, capsys, stop_long_work):
    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf" + DEFAULT.read_bytes())
    code, _, err = run(["plan", p, "--out", tmp_path / "o"], capsys)
    assert code == "reached", err


def test_row17_comment_lines_in_a_csv_are_skipped(tmp_path, traj2, capsys):
    text = traj2.read_text()
    commented = tmp_path / "c.csv"
    commented.write_text("# logged by a test\n" + text.replace("\n", "\n# a note\n", 3))
    code, out, err = run(["analyze", commented, "--json"], capsys)
    assert code == 0, err
    code, ref, _ = run(["analyze", traj2, "--json"], capsys)
    assert json.loads(out) == json.loads(ref)
    header_out = tmp_path / "h.csv"
    header_out.write_text("# " + text)
    refused(["analyze", header_out], capsys, "the header is commented out", "remove the '#'")


def test_row17_duplicated_column_and_bad_init_error(tmp_path, traj2, capsys):
    lines = traj2.read_text().splitlines()
    dup = tmp_path / "dup.csv"
    dup.write_text("\n".join([lines[0].replace(",uy", ",ux"), *lines[1:]]) + "\n")
    refused(["analyze", dup], capsys, "column 'ux' appears 2 times", "columns 6 and 7")
    refused(
        ["simulate", traj2, "--init-error", "nan,0,0,0", "--runs", "2"],
        capsys,
        "init_error",
        "nan, 0, 0, 0 (not all finite)",
    )


def test_row17_a_bad_ros2_metadata_file_is_one_line(tmp_path, capsys):
    pytest.importorskip("rosbags")
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: [oops\n")
    refused(["import", bag, "--out", tmp_path / "o.csv"], capsys, "not a readable ROS bag")


# ------------------------------------------------------------------ row 18: figure metric typo
def test_row18_a_typo_in_the_figure_metrics_is_an_error(tmp_path, capsys):
    sweep = tmp_path / "s.toml"
    base = DEFAULT.as_posix()
    sweep.write_text(
        f'[sweep]\nbase = "{base}"\n[axes]\n"validation.seed" = [0, 1]\n'
        '[figures]\nmetrics = ["ekf.rmse"]\n'
    )
    refused(
        ["sweep", sweep, "--out", tmp_path / "o"],
        capsys,
        "figures.metrics: unknown metric 'ekf.rmse'",
        "did you mean 'ekf.rmse_pos'",
    )
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ row 19: export --depth
def test_row19_export_depth_is_refused_or_used(tmp_path, traj2, capsys):
    mission = tmp_path / "m.plan"
    origin = ["--origin", "43.7,10.3"]
    refused(["export", traj2, "--qgc", mission, *origin, "--depth", "-5"], capsys, "--depth -5")
    plan3d = ROOT / "tests" / "data" / "range3d-plan.csv"
    refused(["export", plan3d, "--qgc", mission, *origin, "--depth", "5"], capsys, "3D plan")
    refused(["export", traj2, "--waypoints", tmp_path / "w.csv", "--depth", "5"], capsys, "--qgc")
    assert not mission.exists()
    pytest.importorskip("pymap3d")
    code, _, err = run(["export", traj2, "--qgc", mission, *origin, "--depth", "5"], capsys)
    assert code == 0, err
    items = json.loads(mission.read_text())["mission"]["items"]
    alts = {it["params"][6] for it in items if it["command"] == 16}
    assert alts == {-5.0}  # ArduSub: altitude = -depth


# ------------------------------------------------------------------ row 20: our own waypoints
@pytest.mark.parametrize("geodetic", [False, True], ids=["metric", "geodetic"])
def test_row20_import_reads_the_waypoint_csv_of_export(tmp_path, traj2, capsys, geodetic):
    if geodetic:
        pytest.importorskip("pymap3d")
    wp = tmp_path / "wp.csv"
    extra = ["--geodetic", "--origin", "43.7,10.3"] if geodetic else []
    code, _, err = run(["export", traj2, "--waypoints", wp, "--every", "6", *extra], capsys)
    assert code == 0, err
    out = tmp_path / "back.csv"
    argv = ["import", wp, "--out", out, *(["--origin", "43.7,10.3"] if geodetic else [])]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    back, orig = read_csv(out, check=False), read_csv(traj2)
    # the waypoints are on the plan: the fit passes through them (1e-7 deg is ~1 cm)
    np.testing.assert_allclose(back.p[0], orig.p[0], atol=0.02)
    np.testing.assert_allclose(back.p[-1], orig.p[-1], atol=0.02)


# ------------------------------------------------------------------ row 21: shipped samples
def test_row21_the_readme_samples_exist_and_are_what_their_script_writes(tmp_path):
    pytest.importorskip("pymavlink")
    pytest.importorskip("pymap3d")
    subprocess.run(
        [sys.executable, str(EXAMPLES / "make_samples.py"), "--out", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    for name in ("log.csv", "dive.tlog", "geodetic.toml"):
        assert (tmp_path / name).read_bytes() == (EXAMPLES / name).read_bytes(), name


def test_row21_the_geodetic_sample_is_the_default_problem_geodetically():
    pytest.importorskip("pymap3d")
    from obsplan.planning.problem.parse import load_problem

    geo = load_problem(EXAMPLES / "geodetic.toml")
    np.testing.assert_allclose(geo.beacon, [0.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(geo.start_position, [-80.0, 60.0], atol=1e-3)
    assert geo.limits == load_problem(DEFAULT).limits


# ------------------------------------------------------------------ row 34: figures
def _fake_validation(end: float, runs: int = 5):
    from types import SimpleNamespace

    t = np.linspace(0.0, 600.0, 61)
    ekf = SimpleNamespace(
        rmse_pos_t=np.linspace(1.0, end, t.size), rmse_pos=float(np.mean([1.0, end])),
        final_pos_err=end, flagged_runs=3,
    )  # fmt: skip
    return SimpleNamespace(
        result=SimpleNamespace(
            t=t, ekf=ekf, kf=None, crlb_pos_std_t=np.full(t.size, 0.05), runs=runs, seed=0
        )
    )


def test_row34_path_figure_draws_the_min_range_and_zooms_on_loops_at_the_beacon():
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    from obsplan.planning.figures import plot_filter_errors, plot_paths
    from obsplan.planning.problem.parse import load_problem
    from obsplan.trajectory import generators

    pb = load_problem(DEFAULT)
    loops = generators.circle(radius=5.5, speed=0.5, duration=200.0).sample(1.0)
    mower = generators.lawnmower((-80.0, 60.0), 160.0, 40.0, 4, 1.0).sample(1.0)
    fig = plot_paths({"planned": loops, "lawnmower": mower}, pb)
    ax = fig.axes[0]
    circles = [p for p in ax.patches if isinstance(p, Circle)]
    assert [c.radius for c in circles] == [pb.limits.min_range]
    assert pb.name in ax.get_title()
    (inset,) = ax.child_axes  # the zoom on the beacon
    lo, hi = inset.get_xlim()
    assert hi - lo < 0.25 * np.ptp(mower.p[:, 0]) and lo < pb.beacon[0] < hi
    plt.close(fig)
    far = generators.circle(radius=60.0, speed=0.5, duration=200.0).sample(1.0)
    fig = plot_paths({"planned": far, "lawnmower": mower}, pb)
    assert not fig.axes[0].child_axes  # nothing hides under the marker: no inset
    plt.close(fig)

    # filters.png: the problem's name, and a note when the plan's curve ends above
    val = {"planned": _fake_validation(0.3), "lawnmower": _fake_validation(0.2)}
    fig = plot_filter_errors(val, problem=pb.name)
    title = fig.axes[0].get_title()
    assert title.startswith(pb.name) and "at the end: plan 0.3 m > lawn-mower 0.2 m" in title
    assert "led by its 3 flagged runs" in title and "mean final error, 0.3 vs 0.2 m" in title
    plt.close(fig)
    val["planned"] = _fake_validation(0.1)
    fig = plot_filter_errors(val, problem=pb.name)
    assert "at the end" not in fig.axes[0].get_title()
    plt.close(fig)


# ------------------------------------------------------------------------------ sweeps
def _baselines_sweep(folder: Path, positions: list, name: str = "rows") -> Path:
    """A cheap sweep file: baselines only (no solver) of the free localisation problem, 20 steps,
    2 Monte Carlo runs, one task per beacon position (about a second each)."""
    f = folder / f"{name}.toml"
    f.write_text(
        f'[sweep]\nname = "{name}"\nbase = "{DEFAULT.as_posix()}"\nmode = "baselines"\n'
        "[base.horizon]\nsteps = 20\n[base.validation]\nruns = 2\n"
        f'[axes]\n"beacon.position" = {json.dumps(positions)}\n'
    )
    return f


def _reports(out: Path) -> dict[Path, int]:
    return {p: p.stat().st_mtime_ns for p in out.glob("tasks/*/report.json")}


def test_row24_the_code_fingerprint_follows_the_computing_code_not_the_cli(tmp_path):
    from obsplan.sweeps.spec import PACKAGE_DIR, code_fingerprint

    fingerprint = code_fingerprint.__wrapped__  # uncached: the copy below changes
    copy = tmp_path / "obsplan"
    shutil.copytree(PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    base = fingerprint(copy)
    assert base == code_fingerprint()  # a copy of this installation's sources: the same code
    cli = copy / "cli" / "sweep.py"
    cli.write_text(cli.read_text() + "\n# other wording\n")
    assert fingerprint(copy) == base  # the command line computes no part of a task
    kernel = copy / "estimation" / "filters" / "ekf.py"
    kernel.write_text(kernel.read_text() + "\n# a changed filter\n")
    assert fingerprint(copy) != base


@pytest.mark.slow
def test_row24_a_resume_after_the_code_changed_refuses_then_force_computes_again(
    tmp_path, capsys, monkeypatch
):
    import pandas as pd

    import obsplan.sweeps.spec as specs
    from obsplan.sweeps import read_table

    f = _baselines_sweep(tmp_path, [[0.0, 0.0], [50.0, 0.0]])
    out = tmp_path / "out"
    argv = ["sweep", f, "--out", out, "--workers", "1", "--quiet", "--no-figures"]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    before, reports = read_table(out), _reports(out)
    assert len(reports) == 2

    real = specs.code_fingerprint()
    monkeypatch.setattr(specs, "code_fingerprint", lambda: "0123456789abcdef")  # code changed
    refused(
        argv,
        capsys,
        "2 finished tasks were computed by other obsplan code",
        real,
        "0123456789abcdef",
        "new folder",
        "--force",
    )
    assert _reports(out) == reports  # nothing ran,
    pd.testing.assert_frame_equal(read_table(out), before)  # nothing was rewritten

    code, _, err = run([*argv, "--force"], capsys)
    assert code == 0, err
    after = read_table(out)
    assert after["status"].tolist() == ["done", "done"]
    assert set(after["task_id"]).isdisjoint(before["task_id"])  # new ids: computed again
    assert set(reports) < set(_reports(out))  # the old results stay beside the new ones
    assert json.loads((out / "sweep.json").read_text())["code"] == "0123456789abcdef"
    code, stdout, _ = run(argv, capsys)  # the same code again: a plain resume
    assert code == 0 and "2 already done, 0 to run" in stdout


def test_row28_a_failed_task_among_done_ones_changes_no_column_type(tmp_path, capsys):
    """The table as the command line rewrites it from the stored reports (JSON: a missing value
    is null), with one task failed as a runner that raised leaves it."""
    import pandas as pd

    from obsplan.sweeps import expand, load_sweep, read_table, run_task
    from obsplan.sweeps.run import _failure, _store
    from obsplan.sweeps.spec import code_fingerprint
    from obsplan.sweeps.store import write_manifest

    f = _baselines_sweep(tmp_path, [[0.0, 0.0], [50.0, 0.0]])
    out = tmp_path / "out"
    spec = load_sweep(f)
    ok, bad = expand(spec)
    # the sweep's own writers, as a run whose second task raised leaves the folder
    write_manifest(out, {"code": code_fingerprint(), "sweep": spec.to_dict(), "tasks": []})
    _store(out, ok, run_task(ok), 1)
    _store(out, bad, _failure(RuntimeError("out of memory"), 2), 2)
    code, stdout, err = run(["sweep", f, "--out", out, "--quiet", "--no-figures"], capsys)
    assert code == 1 and "1 done, 1 failed of 2 tasks" in stdout, err
    for table in (read_table(out), pd.read_csv(out / "results.csv")):
        assert table.columns[2] == "beacon.position [m]"  # an axis column names its unit
    df = read_table(out)
    assert str(df["task"].dtype) == "Int64" and str(df["attempts"].dtype) == "Int64"
    assert df["attempts"].tolist() == [1, 2]
    assert str(df["error"].dtype) == "string" and pd.isna(df.loc[0, "error"])
    assert "the task raised (attempt 2): RuntimeError: out of memory" in df.loc[1, "error"]
    metric = "metrics.lawnmower.min_eig"
    assert df[metric].dtype == np.float64 and np.isnan(df.loc[1, metric])
    assert str(df["status"].dtype) == "string"


def test_row28_plan_columns_keep_their_types_with_a_failed_task():
    """``solver.success`` stays boolean and ``solver.iterations`` an integer beside a task that
    left no report (the row builder, on reports of the shape plan mode stores)."""
    from obsplan.sweeps import expand, sweep_from_dict
    from obsplan.sweeps.table import build_table

    spec = sweep_from_dict(
        {
            "sweep": {"name": "t", "base": str(DEFAULT)},
            "axes": {"limits.accel": [0.02, 0.05], "objective.kind": ["gramian-min-eig"]},
        }
    )
    done, failed = expand(spec)
    meta = {"status": "done", "error": None, "attempts": 1, "wall_s": 1.5, "worker": "h:1"}
    stored = {
        done.id: {"sweep": meta, "solver": {"success": True, "iterations": 41, "status": "x"}},
        failed.id: {"sweep": {**meta, "status": "failed", "error": "E: boom"}},
    }
    df = build_table([done, failed], stored)
    assert str(df["solver.success"].dtype) == "boolean" and pd_isna(df.loc[1, "solver.success"])
    assert str(df["solver.iterations"].dtype) == "Int64"
    assert df.loc[0, "solver.iterations"] == 41 and pd_isna(df.loc[1, "solver.iterations"])
    assert str(df["solver.status"].dtype) == "string"
    assert df.columns[2:4].tolist() == ["limits.accel [m/s^2]", "objective.kind"]


def pd_isna(v) -> bool:
    import pandas as pd

    return bool(pd.isna(v))


@pytest.mark.slow
@pytest.mark.parametrize("bokeh", [True, False])
def test_row30_the_dashboard_link_only_when_the_scheduler_has_bokeh(
    bokeh, tmp_path, capsys, monkeypatch
):
    import obsplan.sweeps.run as run_module

    # asked of the scheduler (here the local cluster's, in this process) by value
    monkeypatch.setattr(run_module, "has_bokeh", lambda: bokeh)
    f = _baselines_sweep(tmp_path, [[0.0, 0.0]])
    code, stdout, err = run(
        ["sweep", f, "--out", tmp_path / "o", "--workers", "1", "--no-figures"], capsys
    )
    assert code == 0, err
    assert ("dashboard: http" in stdout) is bokeh, stdout


def test_row30_has_bokeh_says_whether_bokeh_imports():
    import importlib.util

    from obsplan.sweeps.run import has_bokeh

    assert has_bokeh() is (importlib.util.find_spec("bokeh") is not None)


@pytest.mark.slow
@pytest.mark.parametrize("verb", ["simulate", "sweep"])
def test_row31_a_cold_cache_labels_the_first_monte_carlo(verb, tmp_path, traj2):
    """The installed command with an empty numba cache: the progress bar names the compile step
    before compiling (the process is stopped there: the compile itself takes a minute). A sweep
    on a local cluster says that its workers compile."""
    # the process group is killed: its temporary files go to a folder of this test's
    (tmp_path / "tmp").mkdir()
    env = {
        **os.environ,
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
        "MPLBACKEND": "Agg",
        "TMPDIR": str(tmp_path / "tmp"),
    }
    args = {
        "simulate": [traj2, "--runs", "2"],
        "sweep": [
            _baselines_sweep(tmp_path, [[0.0, 0.0]]),
            "--out",
            tmp_path / "o",
            "--workers",
            "1",
        ],
    }[verb]
    needle = {
        "simulate": b"compiling the filters once (about",
        "sweep": b"rows: the workers are compiling the filters once (about",
    }[verb]
    cmd = [str(Path(sys.executable).with_name("obsplan")), verb, *map(str, args)]
    proc = subprocess.Popen(
        cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, env=env, start_new_session=True
    )
    seen = b""
    try:
        deadline = time.monotonic() + 120.0  # generous: importing takes seconds on a loaded CI
        assert proc.stderr is not None
        while needle not in seen and time.monotonic() < deadline:
            chunk = proc.stderr.read1(4096)
            if not chunk:
                break
            seen += chunk
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert needle in seen, seen.decode(errors="replace")[-2000:]


def test_row31_cache_state_and_folder(tmp_path, monkeypatch):
    import numba
    from numba.core.caching import UserProvidedCacheLocator

    from obsplan.estimation import jitcache

    monkeypatch.setattr(jitcache, "compiled_in_process", lambda name: False)
    cache = tmp_path / "cache"
    assert jitcache.cache_is_cold(("kernels",), cache)  # nothing cached
    source = jitcache.HERE / "kernels.py"
    folder = cache / UserProvidedCacheLocator.get_suitable_cache_subpath(str(source))
    folder.mkdir(parents=True)
    index = folder / "kernels.predict-1.py311.nbi"
    index.write_bytes(b"")
    assert not jitcache.cache_is_cold(("kernels",), cache)  # newer than its source
    old = source.stat().st_mtime - 10.0
    os.utime(index, (old, old))
    assert jitcache.cache_is_cold(("kernels",), cache)  # the source changed since
    assert jitcache.cache_is_cold(("kernels", "montecarlo.loop_kernels"), cache)

    # the default folder: the user's cache, set for numba and for the processes started later
    monkeypatch.setattr(numba.config, "CACHE_DIR", numba.config.CACHE_DIR)  # restored after
    monkeypatch.setenv("NUMBA_CACHE_DIR", "placeholder")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        want = tmp_path / "xdg" / "obsplan" / "numba" / jitcache.kernel_fingerprint()
        assert jitcache.configure() == want and want.is_dir()
        assert os.environ["NUMBA_CACHE_DIR"] == str(want) == numba.config.CACHE_DIR
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert jitcache.configure() == tmp_path / "mine"  # the user's choice is kept


def test_kernel_cache_folder_changes_with_any_source_the_kernels_inline(tmp_path, monkeypatch):
    """numba checks only the defining file's time stamp; a change in a file a kernel inlines
    from (a callee, a constant) must still lead to a fresh cache folder."""
    from obsplan.estimation import jitcache

    copy = tmp_path / "estimation"
    shutil.copytree(jitcache.HERE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(jitcache, "HERE", copy)
    before = jitcache.kernel_fingerprint()
    assert jitcache.kernel_fingerprint() == before  # a pure function of the sources
    channel = copy / "channel.py"  # constants the kernels compile in (LATE_PRIOR, ...)
    channel.write_text(channel.read_text() + "\n# changed\n")
    changed = jitcache.kernel_fingerprint()
    assert changed != before
    guidance = copy / "montecarlo" / "guidance.py"
    guidance.write_text(guidance.read_text() + "\n# changed\n")
    assert jitcache.kernel_fingerprint() not in (before, changed)
