"""`obsplan analyze TRAJ.csv --beacon-path B.csv`: a moving beacon on the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.trajectory.sampled import Trajectory, write_csv


@pytest.fixture()
def line_csv(tmp_path):
    """A straight constant-velocity line: unobservable with a fixed beacon."""
    t = np.arange(0.0, 200.0 + 1e-9, 1.0)
    traj = Trajectory.from_inputs(t, [-100.0, 30.0], [1.0, 0.2], np.zeros((t.size, 2)))
    return write_csv(traj, tmp_path / "line.csv")


def write_beacon(path, t, b, extra=False):
    cols = ["t", "bx", "by", "bz"][: 1 + b.shape[1]] + (["heading"] if extra else [])
    rows = np.column_stack([t, b, np.zeros(len(t))] if extra else [t, b])
    path.write_text(
        ",".join(cols) + "\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows)
    )
    return path


def circle(t, dim=2):
    b = np.zeros((t.size, dim))
    b[:, 0], b[:, 1] = 40 * np.cos(0.05 * t), 40 * np.sin(0.05 * t)
    return b


def run_json(capsys, *args):
    assert main(["analyze", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_circling_beacon_makes_the_line_observable(line_csv, tmp_path, capsys):
    tb = np.arange(-5.0, 210.0, 0.7)  # sampled at other times than the trajectory
    ship = write_beacon(tmp_path / "ship.csv", tb, circle(tb), extra=True)
    fixed = run_json(capsys, line_csv)
    out = run_json(capsys, line_csv, "--beacon-path", ship)
    assert fixed["gramian"]["full_rank"] is False and "beacon_motion" not in fixed
    assert out["beacon_motion"] == "path" and out["beacon_path"] == str(ship)
    assert out["lwo"]["along_trajectory"] is True and out["gramian"]["full_rank"] is True
    assert out["gramian"]["rank_exact"] is None  # not computed for a moving beacon


def test_trailing_beacon_leaves_it_unobservable(line_csv, tmp_path, capsys):
    tb = np.arange(-5.0, 210.0, 0.7)
    b = np.c_[-100.0 + tb, 30.0 + 0.2 * tb] + [10.0, -20.0]
    ship = write_beacon(tmp_path / "trail.csv", tb, b)
    out = run_json(capsys, line_csv, "--beacon-path", ship, "--sensors", "range,dvl-water")
    assert out["lwo"]["along_trajectory"] is False and out["gramian"]["full_rank"] is False


def test_human_summary_says_the_beacon_moves(line_csv, tmp_path, capsys):
    tb = np.arange(0.0, 201.0, 1.0)
    ship = write_beacon(tmp_path / "ship.csv", tb, circle(tb))
    assert main(["analyze", str(line_csv), "--beacon-path", str(ship)]) == 0
    out = capsys.readouterr().out
    assert "moving beacon" in out and "rank 6 of 6" in out


@pytest.mark.parametrize(
    "content,extra,match",
    [
        ("t,bx,by\n10,0,0\n300,1,1\n", [], "covers t = 10..300 s but t = 0..200 s is needed"),
        ("t,bx,by,bz\n0,0,0,0\n300,1,1,1\n", [], "column 'bz' makes it a 3D beacon path"),
        ("t,bx\n0,0\n300,1\n", [], "missing column(s) by"),
        ("t,bx,by\n0,0,0\n0,1,1\n", [], "row 3, column 't'"),
        ("t,bx,by\n0,0,0\n300,1,1\n", ["--beacon", "1,2"], "not both"),
    ],
)
def test_bad_beacon_path_is_one_line_and_exit_2(line_csv, tmp_path, capsys, content, extra, match):
    ship = tmp_path / "ship.csv"
    ship.write_text(content)
    assert main(["analyze", str(line_csv), "--beacon-path", str(ship), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("obsplan analyze: error:")
    assert match in err and "--beacon-path" in err and "Traceback" not in err


def test_missing_beacon_file_exit_2(line_csv, tmp_path, capsys):
    assert main(["analyze", str(line_csv), "--beacon-path", str(tmp_path / "no.csv")]) == 2
    assert "no.csv" in capsys.readouterr().err
