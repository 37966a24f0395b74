"""The shipped problems are package data: every install has them, by name, and can copy one out.

The fast tests read the package in place; the slow one builds a wheel of the repository,
installs it (not editable) into a folder outside the clone and runs the main job from there, as
a user who installed obsplan from an index would.
"""

from __future__ import annotations

import fnmatch
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from obsplan.cli import main
from obsplan.planning.problem.parse import (
    DEFAULT_PROBLEM,
    PROBLEMS_DIR,
    load_problem,
    problem_to_dict,
    shipped_file,
    shipped_files,
)
from obsplan.sweeps import load_sweep

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "obsplan"


def test_the_shipped_files_are_the_package_data_and_the_clones_problems():
    assert PROBLEMS_DIR == PACKAGE / "problems" and DEFAULT_PROBLEM.is_file()
    assert (ROOT / "problems").resolve() == PROBLEMS_DIR.resolve()  # the clone's link
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]["obsplan"]
    files = sorted(p.relative_to(PACKAGE).as_posix() for p in PROBLEMS_DIR.rglob("*"))
    files = [f for f in files if (PACKAGE / f).is_file()]
    missed = [f for f in files if not any(fnmatch.fnmatch(f, pat) for pat in patterns)]
    assert files and not missed, f"not in the wheel's package data: {missed}"


def test_every_shipped_file_is_listed_by_name_and_loads():
    files = shipped_files()
    top = [n for n in files if "/" not in n]  # the problems first, by name; then the folders
    assert list(files)[: len(top)] == sorted(top) and {"default", "localise"} <= set(top)
    assert "suite/far-start" in files
    for name, path in files.items():
        if name.startswith("sweeps/"):
            assert load_sweep(path).name
        else:
            assert load_problem(name) == load_problem(path)  # by name, from anywhere


def test_the_verb_lists_every_file_and_copies_one_that_plans_the_same(tmp_path, capsys):
    assert main(["problems"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in shipped_files())
    assert main(["problems", "suite/far-start"]) == 0
    assert capsys.readouterr().out == shipped_file("suite/far-start").read_text()
    copy = tmp_path / "my.toml"
    assert main(["problems", "copy", "default", str(copy)]) == 0
    assert copy.read_text() == DEFAULT_PROBLEM.read_text()
    assert problem_to_dict(load_problem(copy)) == problem_to_dict(load_problem())


def test_a_copied_sweep_names_its_base_by_an_absolute_path_and_runs_from_elsewhere(tmp_path):
    name = next(n for n in shipped_files() if n.startswith("sweeps/"))
    copy = tmp_path / "elsewhere" / "study.toml"
    assert main(["problems", "copy", name, str(copy)]) == 0
    base = tomllib.loads(copy.read_text())["sweep"]["base"]
    assert Path(base).is_absolute() and Path(base).is_file()
    assert load_sweep(copy).name == load_sweep(shipped_file(name)).name


@pytest.mark.parametrize(
    "argv, words",
    [
        (["problems", "copy", "no-such-problem", "x.toml"], "no shipped file 'no-such-problem'"),
        (["problems", "copy", "default"], "copy needs NAME and FILE"),
        (["problems", "default", "x.toml"], "copy NAME FILE to copy one"),
        (["problems", "copy", "default", "a.toml", "b.toml"], "copy needs NAME and FILE"),
        (["problems", "suite/no-such"], "no shipped file 'suite/no-such'"),
    ],
)
def test_bad_requests_exit_2_with_one_line(argv, words, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]


def test_a_copy_never_replaces_a_file_without_force(tmp_path, capsys):
    mine = tmp_path / "mine.toml"
    mine.write_text("# my own problem\n")
    assert main(["problems", "copy", "localise", str(mine)]) == 2
    assert mine.read_text() == "# my own problem\n"
    assert "--force" in capsys.readouterr().err
    assert main(["problems", "copy", "localise", str(mine), "--force"]) == 0
    assert mine.read_text() == (PROBLEMS_DIR / "localise.toml").read_text()


@pytest.mark.slow
def test_an_installed_wheel_runs_the_main_job_outside_the_clone(tmp_path):
    wheels = tmp_path / "wheels"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(wheels)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr
    (wheel,) = wheels.glob("obsplan-*.whl")
    site = tmp_path / "site"
    inst = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), wheel],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert inst.returncode == 0, inst.stderr
    work = tmp_path / "work"
    work.mkdir()
    # the installed copy, not the clone: its dependencies from this environment
    env = dict(os.environ, PYTHONPATH=str(site), MPLBACKEND="Agg")

    def obsplan(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "obsplan", *args],
            capture_output=True,
            text=True,
            cwd=work,
            env=env,
            timeout=1200,
        )

    where = subprocess.run(
        [sys.executable, "-c", "import obsplan; print(obsplan.__file__)"],
        capture_output=True,
        text=True,
        cwd=work,
        env=env,
    )
    assert Path(where.stdout.strip()).is_relative_to(site)
    first = obsplan("plan", "--out", "x", "--runs", "4", "--max-runs", "4", "--quiet")
    assert first.returncode == 0, first.stderr
    assert {"plan.csv", "report.json", "path.png"} <= {p.name for p in (work / "x").iterdir()}
    # the wheel carries its problem files (that a copy plans the same is checked in-process
    # above: a second plan here would only repeat it)
    copy = obsplan("problems", "copy", "default", "my.toml")
    assert copy.returncode == 0, copy.stderr
    installed = site / "obsplan" / "problems" / "default.toml"
    assert (work / "my.toml").read_text() == installed.read_text() == DEFAULT_PROBLEM.read_text()
