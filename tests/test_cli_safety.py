"""Output folders, bounded work and leftovers through ``main(argv)``: nothing of the user's is lost.

A fake home folder with files; every verb with ``--out ~ --force`` and ``--out . --force`` (HOME
pointed at it) exits 2 before any work and leaves every file; then the other rows about output
folders (inputs, links, ``""``, ``/proc``, a killed run's leftovers) and about the cost budget
(starts, iterations, runs, sweep tasks, rows).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from obsplan.cli import main
from obsplan.core import budget, interrupts
from obsplan.core.atomic import dead_leftovers, staging_dir
from obsplan.core.outputs import MARKER, write_marker
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "problems" / "localise.toml"
SMALL = ["--steps", "40", "--starts", "1", "--runs", "2", "--quiet"]
#: The free localisation problem of the small runs (the default survey refuses 40 steps).
LOCALISE = str(ROOT / "problems" / "localise.toml")


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>"
        for p in sorted(folder.rglob("*"))
    }


@pytest.fixture
def home(tmp_path, monkeypatch):
    """A fake home folder with the user's files (dotfiles, documents), HOME pointed at it."""
    h = tmp_path / "home"
    (h / "Documents").mkdir(parents=True)
    (h / ".bashrc").write_text("export PS1='$ '\n")
    (h / "Documents" / "thesis.tex").write_text("\\documentclass{article}\n")
    (h / "plan.csv").write_text("the user's own plan.csv\n")
    monkeypatch.setenv("HOME", str(h))
    return h


@pytest.fixture
def inputs(tmp_path):
    """A trajectory, a position-only track and a sweep file, outside the home folder."""
    d = tmp_path / "in"
    d.mkdir()
    traj = gen.circle(30.0, 1.5, 20.0).sample(0.1)
    write_csv(traj, d / "traj.csv")
    rows = "\n".join(f"{t:.1f},{p[0]:.4f},{p[1]:.4f}" for t, p in zip(traj.t, traj.p, strict=True))
    (d / "track.csv").write_text("t,px,py\n" + rows + "\n")
    (d / "s.toml").write_text(
        f'[sweep]\nname = "s"\nbase = "{DEFAULT.as_posix()}"\n[axes]\n"limits.speed" = [1.0]\n'
    )
    return d


def _verbs(inputs: Path, out: str) -> dict[str, list[str]]:
    return {
        "plan": ["plan", LOCALISE, "--out", out, "--force", *SMALL],
        "simulate": ["simulate", str(inputs / "traj.csv"), "--runs", "2", "--quiet", "--out", out],
        "paper": ["paper", "--quick", "--no-figures", "--quiet", "--out", out, "--force"],
        "import": ["import", str(inputs / "track.csv"), "--out", out, "--force"],
        "export": ["export", str(inputs / "traj.csv"), "--waypoints", out, "--force"],
        "sweep": ["sweep", str(inputs / "s.toml"), "--out", out, "--force", "--quiet"],
    }


@pytest.fixture
def no_work(monkeypatch):
    """Every verb's work replaced by a failure: a refusal must come before it."""

    def never(*a, **k):
        raise AssertionError("work started before the output was checked")

    for target in (
        "obsplan.cli.plan.plan",
        "obsplan.cli.simulate.monte_carlo",
        "obsplan.cli.paper.all_rows",
        "obsplan.cli.import_track.fit_track",
        "obsplan.io.waypoints.waypoints_from_trajectory",
        "obsplan.sweeps.run.dask_client",
    ):
        monkeypatch.setattr(target, never)


@pytest.mark.parametrize("verb", ["plan", "simulate", "paper", "import", "export", "sweep"])
@pytest.mark.parametrize("where", ["~", "."])
def test_home_and_working_folder_survive_every_verb(
    verb, where, home, inputs, no_work, monkeypatch, capsys
):
    monkeypatch.chdir(home)
    before = _snapshot(home)
    out = str(home) if where == "~" else "."
    argv = _verbs(inputs, out)[verb]
    if verb == "simulate":
        argv.append("--force")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "home folder" in err or "working folder" in err or "is a folder" in err, err
    assert _snapshot(home) == before


@pytest.mark.parametrize("verb", ["plan", "simulate", "paper", "sweep"])
def test_parents_of_the_working_folder_are_refused_before_work(
    verb, home, inputs, no_work, monkeypatch, capsys
):
    work = home / "Documents"
    monkeypatch.chdir(work)
    before = _snapshot(home)
    for out in ("..", str(home.parent), "/"):
        argv = _verbs(inputs, out)[verb] + (["--force"] if verb == "simulate" else [])
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "which obsplan never writes over" in err, err
    assert _snapshot(home) == before


@pytest.mark.slow
def test_force_replaces_only_an_obsplan_output(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert main(["plan", LOCALISE, "--out", str(mine), "--force", "--no-validate", *SMALL]) == 2
    assert "not an obsplan output folder" in capsys.readouterr().err
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    # what obsplan wrote carries the marker, with the files it wrote
    out = tmp_path / "res"
    assert main(["plan", LOCALISE, "--out", str(out), "--no-validate", *SMALL]) == 0
    assert (out / MARKER).is_file()
    # a file the user added there keeps the folder (the marker lists what obsplan wrote)
    (out / "stale.txt").write_text("from before")
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 2
    assert "stale.txt" in capsys.readouterr().err
    assert (out / "stale.txt").read_text() == "from before"
    # a file an earlier run wrote (in its marker) that this run does not write goes: whole
    write_marker(out, "plan")
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == 0
    assert not (out / "stale.txt").exists() and (out / "plan.csv").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine", "res"]


def test_the_default_problem_folder_is_never_replaced(tmp_path, monkeypatch, capsys):
    """``plan --out problems --force`` (no PROBLEM given: problems/default.toml is read)."""
    monkeypatch.chdir(ROOT)
    before = _snapshot(ROOT / "problems")
    survey = ["--steps", "96", "--starts", "1", "--runs", "2", "--quiet"]  # the default survey
    assert main(["plan", "--out", "problems", "--force", *survey]) == 2
    err = capsys.readouterr().err
    assert "problems" in err and "Traceback" not in err
    assert _snapshot(ROOT / "problems") == before
    # even in a folder with the marker, the input it holds keeps it
    res = tmp_path / "res"
    res.mkdir()
    write_marker(res, "plan")
    (res / "default.toml").write_text(DEFAULT.read_text())
    monkeypatch.chdir(tmp_path)
    assert main(["plan", "res/default.toml", "--out", "res", "--force", *SMALL]) == 2
    assert "holds the input" in capsys.readouterr().err


def test_a_link_is_refused_and_nothing_is_left(tmp_path, capsys):
    real = tmp_path / "real"
    real.mkdir()
    write_marker(real, "plan")
    (real / "plan.csv").write_text("old")
    link = tmp_path / "LINK"
    link.symlink_to(real, target_is_directory=True)
    assert main(["plan", LOCALISE, "--out", str(link), "--force", "--no-validate", *SMALL]) == 2
    err = capsys.readouterr().err
    assert "symbolic link" in err and str(real) in err
    assert link.is_symlink() and (real / "plan.csv").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["LINK", "real"]
    # a file output through a link too
    target = tmp_path / "real" / "wp.csv"
    target.write_text("x")
    (tmp_path / "wp.csv").symlink_to(target)
    traj = tmp_path / "t.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0).sample(0.5), traj)
    assert main(["export", str(traj), "--waypoints", str(tmp_path / "wp.csv"), "--force"]) == 2
    assert "symbolic link" in capsys.readouterr().err and target.read_text() == "x"


@pytest.mark.parametrize("verb", ["plan", "simulate", "paper", "sweep", "import", "export"])
def test_an_empty_out_is_refused(verb, inputs, tmp_path, no_work, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = _verbs(inputs, "")[verb]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is empty" in err and err.count("\n") == 1, err


def test_an_unwritable_place_is_refused_before_work(inputs, tmp_path, no_work, capsys):
    if not Path("/proc").is_dir():
        pytest.skip("no /proc")
    for verb in ("sweep", "plan", "paper"):
        assert main(_verbs(inputs, "/proc/x")[verb]) == 2
        assert "cannot write" in capsys.readouterr().err


def test_paper_force_replaces_the_folder_whole(tmp_path, capsys):
    out = tmp_path / "paper"
    argv = ["paper", "--quick", "--no-figures", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    assert (out / MARKER).is_file()
    (out / "fig1.png").write_bytes(b"an old figure")
    assert main([*argv, "--force"]) == 2  # a file the marker does not list is the user's
    assert "fig1.png" in capsys.readouterr().err
    write_marker(out, "paper")  # as a run with figures recorded it
    assert main([*argv, "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "tables.json", "tables.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["paper"]


@pytest.mark.slow
def test_a_killed_runs_leftovers_are_removed_by_the_next_run(tmp_path, capsys):
    """``kill -9`` mid-write leaves a staging folder; the next run there removes it."""
    out = tmp_path / "o"
    code = (
        "import os, sys, time\n"
        "from obsplan.core.outputs import OutputDir\n"
        "o = OutputDir(sys.argv[1], False)\n"
        "s = o.stage(); (s / 'plan.csv').write_text('half')\n"
        "print(s, flush=True); time.sleep(60)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE)
    staged = Path(proc.stdout.readline().decode().strip())
    assert staged.is_dir()
    assert dead_leftovers(out) == []  # the writer is alive: not a leftover
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert dead_leftovers(out) == [staged]
    # a live run's staging folder beside it is not touched
    live = staging_dir(out)
    assert main(["plan", LOCALISE, "--out", str(out), "--no-validate", *SMALL]) == 0
    assert not staged.exists() and live.is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["o", live.name])
    os.rmdir(live)


# ------------------------------------------------------------------------------ the budget
@pytest.mark.parametrize(
    "argv_tail, field",
    [
        (["--starts", "1000000"], "--starts"),
        (["--runs", "100000"], "--runs"),
    ],
)
def test_plan_options_beyond_the_limits_exit_2_before_work(
    argv_tail, field, tmp_path, no_work, capsys
):
    assert main(["plan", LOCALISE, "--out", str(tmp_path / "o"), *argv_tail]) == 2
    err = capsys.readouterr().err
    assert field in err and "more than the limit of" in err and err.count("\n") == 1, err


@pytest.mark.parametrize(
    "section, line, field",
    [
        ("objective", "starts = 1000000", "objective.starts"),
        ("objective", "max_iter = 1000000000000", "objective.max_iter"),
        ("validation", "runs = 100000", "validation.runs"),
    ],
)
def test_problem_fields_beyond_the_limits_exit_2(section, line, field, tmp_path, no_work, capsys):
    key = line.split("=")[0].strip()
    out, current = [], None
    for raw in DEFAULT.read_text().splitlines():
        if raw.startswith("["):
            current = raw.strip("[] ")
        if current == section and raw.split("=")[0].strip() == key:
            continue  # the default's own value, replaced below
        out.append(raw)
        if raw.strip() == f"[{section}]":
            out.append(line)
    prob = tmp_path / "p.toml"
    prob.write_text("\n".join(out) + "\n")
    assert main(["plan", str(prob), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert field in err and "limit" in err and "Traceback" not in err, err


@pytest.mark.parametrize(
    "axis", ["{range = 100000000}", "{linspace = [0.5, 1.5, 1000000]}", "{range = [0, 400]}"]
)
def test_a_sweep_beyond_the_task_limit_exits_2_at_once(axis, tmp_path, capsys):
    import tracemalloc

    f = tmp_path / "s.toml"
    extra = '\n"limits.accel" = {range = [1, 400]}' if "400" in axis else ""
    f.write_text(
        f'[sweep]\nname = "s"\nbase = "{DEFAULT.as_posix()}"\n[axes]\n'
        f'"validation.seed" = {axis}{extra}\n'
    )
    tracemalloc.start()
    assert main(["sweep", str(f), "--out", str(tmp_path / "o")]) == 2
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    err = capsys.readouterr().err
    assert "tasks, more than the limit of 100000 tasks" in err, err
    assert peak < 100 * 2**20  # the task list was never built
    assert not (tmp_path / "o").exists()


def test_a_huge_trajectory_file_is_refused_before_it_is_read(tmp_path, capsys):
    path = tmp_path / "big.csv"
    row = b"0,1,2,0,0,0,0\n"
    n = budget.MAX_ROWS + 100_000
    with path.open("wb") as fh:
        fh.write(b"t,px,py,vx,vy,ux,uy\n")
        fh.write(row * n)
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err
    assert "rows" in err and f"limit of {budget.MAX_ROWS:,}" in err, err


def test_the_memory_and_time_limits_are_read_from_the_environment(monkeypatch):
    monkeypatch.setenv("OBSPLAN_MAX_MEMORY", "1M")
    assert budget.max_memory() == 2**20
    with pytest.raises(Exception, match="OBSPLAN_MAX_MEMORY"):
        budget.check_monte_carlo(100, 10_000, 2, "--runs")
    monkeypatch.setenv("OBSPLAN_MAX_MEMORY", "lots")
    with pytest.raises(Exception, match="OBSPLAN_MAX_MEMORY='lots'"):
        budget.max_memory()
    monkeypatch.delenv("OBSPLAN_MAX_MEMORY")
    monkeypatch.setenv("OBSPLAN_MAX_HOURS", "0.001")
    with pytest.raises(Exception, match="OBSPLAN_MAX_HOURS"):
        budget.check_monte_carlo(1000, 100_000, 2, "--runs")
    monkeypatch.delenv("OBSPLAN_MAX_HOURS")
    budget.check_monte_carlo(1000, 100_000, 2, "--runs")  # within the defaults


# ------------------------------------------------------------------------------ late signals
def _signal_self(sig):
    def fake(*a, **k):
        os.kill(os.getpid(), sig)  # main's handler turns it into an interruption
        time.sleep(1.0)  # the handler runs at the next bytecode
        return ""

    return fake


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_after_the_folder_was_swapped_in_undoes_it(sig, code, tmp_path, monkeypatch):
    out = tmp_path / "o"
    assert main(["plan", LOCALISE, "--out", str(out), "--no-validate", *SMALL]) == 0
    before = _snapshot(out)
    # printing the summary comes after the commit
    monkeypatch.setattr("obsplan.planning.results.PlanResult.summary", _signal_self(sig))
    assert main(["plan", LOCALISE, "--out", str(out), "--force", "--no-validate", *SMALL]) == code
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["o"]
    # a new folder is removed again
    assert main(["plan", LOCALISE, "--out", str(tmp_path / "new"), "--no-validate", *SMALL]) == code
    assert [p.name for p in tmp_path.iterdir()] == ["o"]


def test_a_signal_after_a_file_was_written_undoes_it(tmp_path, monkeypatch):
    traj = tmp_path / "t.csv"
    write_csv(gen.circle(30.0, 1.5, 20.0).sample(0.5), traj)
    wp = tmp_path / "wp.csv"
    wp.write_text("the old waypoints")
    monkeypatch.setattr("obsplan.cli.export.json.dumps", _signal_self(signal.SIGTERM))
    argv = ["export", str(traj), "--waypoints", str(wp), "--force", "--json"]
    assert main(argv) == 143
    assert wp.read_text() == "the old waypoints"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv", "wp.csv"]
    wp.unlink()
    assert main(argv) == 143
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]
    # the call reported its signal: nothing of it is left to interrupt the caller's later work
    # (a script, a notebook, the next test in the same process)
    assert interrupts.pending() is None
    interrupts.check()
