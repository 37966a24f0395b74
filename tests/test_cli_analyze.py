"""`obsplan analyze`: JSON keys, summary, one-line errors with exit 2, consistency warning."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.trajectory.sampled import Trajectory, write_csv


@pytest.fixture()
def circle_csv(tmp_path):
    t = np.arange(200) * 0.25
    w, r = 0.1, 50.0
    u = np.c_[-r * w**2 * np.cos(w * t), -r * w**2 * np.sin(w * t)]
    traj = Trajectory.from_inputs(t, [r, 0.0], [0.0, r * w], u)
    return write_csv(traj, tmp_path / "circle.csv")


def test_json_output(circle_csv, capsys):
    assert main(["analyze", str(circle_csv), "--json", "--sensors", "range,dvl-water"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"dim", "sensors", "current", "lwo", "gramian"}
    assert out["sensors"] == ["range", "dvl-water"] and out["dim"] == 2
    assert out["lwo"]["along_trajectory"] is True
    assert out["gramian"]["full_rank"] is True and out["gramian"]["dim"] == 6


def test_options_reach_the_analysis(circle_csv, capsys):
    args = ["analyze", str(circle_csv), "--json", "--current", "--sensors", "range,dvl-bottom"]
    assert main([*args, "--beacon", "1,2", "--length-scale", "10", "--time-scale", "5"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["current"] is True and out["gramian"]["dim"] == 8
    assert out["gramian"]["full_rank"] is False  # (w, -w) kernel with bottom lock


def test_human_summary(circle_csv, capsys):
    assert main(["analyze", str(circle_csv)]) == 0
    out = capsys.readouterr().out
    assert "LWO along trajectory" in out and "YES" in out and "rank 6 of 6" in out


@pytest.mark.parametrize(
    "content,args,match",
    [
        ("t,px,py,vx,vy,ux\n0,0,0,0,0,0\n1,0,0,0,0,0\n", [], "missing column(s) uy"),
        ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n1,0,x,0,0,0,0\n", [], "row 3, column 'py'"),
        ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n1,0,0,NaN,0,0,0\n", [], "not finite"),
        ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n0,0,0,0,0,0,0\n", [], "does not increase"),
        ("t,px,py,pz,vx,vy,ux,uy\n0,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0\n", [], "mixed 2D/3D"),
        ("t,px,py,vx,vy,ux,uy\n0,1,0,1,0,0,0\n1,2,0,1,0,0,0\n", ["--beacon", "0,0,0"], "2D"),
        ("t,px,py,vx,vy,ux,uy\n0,1,0,1,0,0,0\n1,2,0,1,0,0,0\n", ["--beacon", "a,b"], "--beacon"),
        ("t,px,py,vx,vy,ux,uy\n0,1,0,1,0,0,0\n1,2,0,1,0,0,0\n", ["--sensors", "sonar"], "sonar"),
        (
            "t,px,py,vx,vy,ux,uy\n0,1,0,1,0,0,0\n1,2,0,1,0,0,0\n",
            ["--sensors", "range,depth"],
            "dim",
        ),
        (
            "t,px,py,vx,vy,ux,uy\n0,1,0,1,0,0,0\n1,2,0,1,0,0,0\n",
            ["--time-scale", "-1"],
            "--time-scale",
        ),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, content, args, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    assert main(["analyze", str(path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("obsplan analyze: error:")
    assert match in err and "Traceback" not in err


def test_inconsistent_inputs_print_a_warning(tmp_path, capsys):
    path = tmp_path / "incons.csv"
    path.write_text("t,px,py,vx,vy,ux,uy\n0,0,0,1,0,0,0\n1,5,0,1,0,0,0\n2,6,0,1,0,0,0\n")
    assert main(["analyze", str(path), "--json"]) == 0
    captured = capsys.readouterr()
    assert "warning:" in captured.err and "up to 4 m in position" in captured.err
    json.loads(captured.out)


def test_console_entry_point_without_traceback(tmp_path):
    """The real process: exit status 2 and a single line on stderr for a binary file."""
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from obsplan.cli import main; sys.exit(main(sys.argv[1:]))",
            "analyze",
            str(path),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


# ---------------------------------------------------------------- rows of the CLI issue
def test_negative_first_beacon_coordinate_needs_no_equals_sign(circle_csv, capsys):
    """``--beacon -50,10`` used to be read as an unknown option ("expected one argument")."""
    assert main(["analyze", str(circle_csv), "--json", "--beacon=-50,10"]) == 0
    with_equals = json.loads(capsys.readouterr().out)
    assert main(["analyze", str(circle_csv), "--json", "--beacon", "-50,10"]) == 0
    assert json.loads(capsys.readouterr().out) == with_equals
    assert main(["analyze", str(circle_csv), "--json", "--beacon", "-5e1,-1e1"]) == 0
    assert json.loads(capsys.readouterr().out)["gramian"]["rank"] == 6


@pytest.mark.parametrize("sep", [";", "\t"])
def test_semicolon_and_tab_files_are_read(circle_csv, tmp_path, capsys, sep):
    assert main(["analyze", str(circle_csv), "--json"]) == 0
    ref = json.loads(capsys.readouterr().out)
    other = tmp_path / "other.csv"
    other.write_text(circle_csv.read_text().replace(",", sep))
    assert main(["analyze", str(other), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == ref


@pytest.mark.parametrize(
    "content,match",
    [
        ("0,0,0,1,0,0,0\n1,1,0,1,0,0,0\n", "looks like data, not a header"),
        ("t,px,py,px,vx,vy,ux,uy\n0,0,0,0,1,0,0,0\n1,1,0,1,1,0,0,0\n", "'px' appears 2 times"),
    ],
)
def test_headerless_and_duplicated_columns_exit_2_with_the_fix(tmp_path, capsys, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err


def test_ctrl_c_exits_130_with_one_line(circle_csv, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("obsplan.cli.analyze.analyze", interrupted)
    assert main(["analyze", str(circle_csv)]) == 130
    err = capsys.readouterr().err.strip()
    assert err == "obsplan analyze: interrupted; nothing was written"
