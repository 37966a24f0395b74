"""Every count that drives memory or time is refused before its work (``obsplan/core/budget.py``).

Each class of count is generated over several members, each far from the others (just over the
limit, absurd, the issue's own case): survey lines from ``mission.spacing`` (1e-7 m over a 200 m
area grew to 11.6 GB in a minute; 1e-2 m took 106 s to refuse), given lines, waypoints (300,000
ran for minutes) and their windows, polygon corners, ``validation.max_runs`` / ``--max-runs`` (a
verdict that never decides doubled its runs for hours), names (a 1 MB ``problem.name`` made a 5 s
run take 88 s), ``sweep --workers`` (100,000 printed nothing and ignored SIGTERM).

Each must be refused through the command line with exit 2, one line on stderr naming its field
or option, nothing written, within :data:`REFUSE_S` of the call (the imports done beforehand).
A hang or a runaway allocation is cut by :func:`deadline` (SIGALRM) instead of hanging the suite.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import obsplan.sweeps.run  # noqa: F401 - the sweep verb's imports are not the refusal's time
from obsplan.cli import main
from obsplan.core import budget
from obsplan.sweeps.run import default_workers

ROOT = Path(__file__).resolve().parents[1]
LOCALISE = ROOT / "problems" / "localise.toml"
SURVEY = ROOT / "problems" / "default.toml"
GENERATED = ROOT / "problems" / "suite" / "missions" / "survey-generated.toml"
WAYPOINTS = ROOT / "problems" / "suite" / "missions" / "waypoints.toml"
#: Seconds a refusal may take once the modules are imported (each took a minute or more, or
#: never ended, before; the largest member reads a 1.3 MB problem file).
REFUSE_S = 3.0
#: Seconds after which a call is cut (a regression: a hang or a runaway allocation).
CUT_S = 30


class Hung(Exception):
    """The call ran past :data:`CUT_S`."""


@contextlib.contextmanager
def deadline(seconds: float) -> Iterator[None]:
    def alarm(signum, frame):
        raise Hung(f"no refusal within {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def edited(path: Path, tmp: Path, *subs: tuple[str, str]) -> Path:
    """``path`` with each ``(pattern, replacement)`` applied once (a whole line, multiline)."""
    text = path.read_text()
    for pattern, repl in subs:
        text, n = re.subn(pattern, lambda m, r=repl: r, text, count=1, flags=re.M)
        assert n == 1, pattern
    out = tmp / "p.toml"
    out.write_text(text)
    return out


def refused_fast(argv: list[str], needle: str, tmp: Path, capsys) -> str:
    """``obsplan argv``: exit 2 within REFUSE_S, one line on stderr naming ``needle``, no ``out``
    folder."""
    capsys.readouterr()
    t0 = time.perf_counter()
    with deadline(CUT_S):
        code = main([str(a) for a in argv])
    took = time.perf_counter() - t0
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err[-600:]
    assert len(lines) == 1 and "Traceback" not in err, err[-600:]
    assert f"{needle}:" in lines[0] or f"{needle} " in lines[0], lines[0]
    assert took < REFUSE_S, f"{took:.1f} s to refuse: {lines[0]}"
    assert not (tmp / "out").exists()
    return lines[0]


def _rows(rows: list[list[float]]) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{x:g}" for x in r) + "]" for r in rows) + "]"


# ------------------------------------------------------------------------------ survey lines
@pytest.mark.parametrize("spacing", ["1e-7", "1e-2", "1e-300", "0.3"])
def test_lines_from_a_spacing_are_counted_before_any_is_made(spacing, tmp_path, capsys):
    # 200 m across the heading: 2e9, 2e4, 2e302 and 666 lines
    problem = edited(GENERATED, tmp_path, (r"^spacing = .*$", f"spacing = {spacing}"))
    line = refused_fast(
        ["plan", problem, "--out", tmp_path / "out"], "mission.spacing", tmp_path, capsys
    )
    assert f"limit of {budget.MAX_LINES} lines" in line and "use a spacing of at least" in line


@pytest.mark.parametrize("corners", [budget.MAX_POLYGON_CORNERS + 1, 50_000])
def test_polygon_corners_are_counted(corners, tmp_path, capsys):
    angles = [2 * math.pi * k / corners for k in range(corners)]
    poly = _rows([[100 * math.cos(a), 100 * math.sin(a)] for a in angles])
    problem = edited(
        GENERATED, tmp_path, (r"^area = \{ x = \[-100.*$", f"area = {{ polygon = {poly} }}")
    )
    refused_fast(
        ["plan", problem, "--out", tmp_path / "out"], "mission.area.polygon", tmp_path, capsys
    )


@pytest.mark.parametrize("n", [budget.MAX_LINES + 1, 10_000, 30_000])
def test_given_lines_are_counted(n, tmp_path, capsys):
    lines = _rows([[-80.0, 60.0 - k * 1e-3, 90.0, 60.0 - k * 1e-3] for k in range(n)])
    problem = edited(
        SURVEY,
        tmp_path,
        (r"^lines = \[\[-80.*$", f"lines = {lines}"),
        (r"^ *\[90.0, 20.0.*$", ""),
        (r"^ *\[-80.0, -20.0.*$", ""),
    )
    refused_fast(["plan", problem, "--out", tmp_path / "out"], "mission.lines", tmp_path, capsys)


# ------------------------------------------------------------------------------ waypoints
@pytest.mark.parametrize("n", [budget.MAX_WAYPOINTS + 1, 5_000, 100_000])
def test_waypoints_are_counted_before_they_are_read(n, tmp_path, capsys):
    points = _rows([[float(k % 100), float(k // 100 % 100)] for k in range(n)])
    problem = edited(
        WAYPOINTS,
        tmp_path,
        (r"^waypoints = .*$", f"waypoints = {points}"),
        (r"^windows = .*$", ""),
    )
    refused_fast(
        ["plan", problem, "--out", tmp_path / "out"], "mission.waypoints", tmp_path, capsys
    )


@pytest.mark.parametrize("n", [budget.MAX_WAYPOINTS + 1, 50_000])
def test_waypoint_windows_are_counted(n, tmp_path, capsys):
    windows = _rows([[0.0, 900.0]] * n)
    problem = edited(WAYPOINTS, tmp_path, (r"^windows = .*$", f"windows = {windows}"))
    refused_fast(["plan", problem, "--out", tmp_path / "out"], "mission.windows", tmp_path, capsys)


# ------------------------------------------------------------------------------ Monte Carlo runs
@pytest.mark.parametrize(
    "max_runs, dt",
    [
        (budget.MAX_RUNS + 1, "0.1"),
        (10**9, "0.1"),
        (2**62, "0.1"),
        (budget.MAX_RUNS, "0.001"),  # within the count, beyond memory: 6e5 samples a run
    ],
    ids=["just-over", "1e9", "2^62", "memory"],
)
def test_validation_max_runs_is_bounded(max_runs, dt, tmp_path, capsys):
    problem = edited(
        LOCALISE,
        tmp_path,
        (r"^runs = .*$", f"runs = 2\nmax_runs = {max_runs}"),
        (r"^dt = .*$", f"dt = {dt}"),
    )
    refused_fast(
        ["plan", problem, "--out", tmp_path / "out"], "validation.max_runs", tmp_path, capsys
    )


@pytest.mark.parametrize(
    "max_runs, memory",
    [(budget.MAX_RUNS + 1, None), (10**12, None), (budget.MAX_RUNS, "1G")],
    ids=["just-over", "1e12", "memory"],
)
def test_the_max_runs_option_is_bounded(max_runs, memory, tmp_path, capsys, monkeypatch):
    if memory is not None:  # the file's own max_runs (400) fits; the option's 10,000 does not
        monkeypatch.setenv("OBSPLAN_MAX_MEMORY", memory)
    argv = ["plan", LOCALISE, "--runs", "2", "--max-runs", str(max_runs)]
    refused_fast([*argv, "--out", tmp_path / "out"], "--max-runs", tmp_path, capsys)


# ------------------------------------------------------------------------------ names
@pytest.mark.parametrize("length", [budget.MAX_NAME_CHARS + 1, 10_000, 1_000_000])
def test_a_problem_name_is_bounded(length, tmp_path, capsys):
    problem = edited(LOCALISE, tmp_path, (r"^name = .*$", f'name = "{"n" * length}"'))
    line = refused_fast(
        ["plan", problem, "--out", tmp_path / "out"], "problem.name", tmp_path, capsys
    )
    assert len(line) < 400  # the name is counted, not repeated


@pytest.mark.parametrize("length", [budget.MAX_NAME_CHARS + 1, 1_000_000])
def test_a_sweep_name_is_bounded(length, tmp_path, capsys):
    sweep = tmp_path / "s.toml"
    sweep.write_text(
        f'[sweep]\nname = "{"s" * length}"\nbase = {json.dumps(str(LOCALISE))}\n'
        '[axes]\n"limits.speed" = [1.0]\n'
    )
    refused_fast(["sweep", sweep, "--out", tmp_path / "out"], "sweep.name", tmp_path, capsys)


# ------------------------------------------------------------------------------ sweep workers
@pytest.mark.parametrize(
    "workers",
    [0, budget.MAX_WORKERS_PER_CORE * default_workers() + 1, 48 * default_workers(), 100_000],
    ids=["zero", "just-over", "48-per-core", "100000"],
)
def test_local_workers_are_bounded_by_the_cores(workers, tmp_path, capsys):
    sweep = tmp_path / "s.toml"
    sweep.write_text(
        f'[sweep]\nname = "s"\nbase = {json.dumps(str(LOCALISE))}\n[axes]\n"limits.speed" = [1.0]\n'
    )
    line = refused_fast(
        ["sweep", sweep, "--out", tmp_path / "out", "--workers", str(workers)],
        "--workers",
        tmp_path,
        capsys,
    )
    if workers > 0:
        assert "per core" in line and "--scheduler" in line


def test_the_limits_are_the_documented_ones():
    """The field tables (generated from the schema) state the budget's limits."""
    doc = (ROOT / "docs" / "problem-files.md").read_text()
    for field, limit in (
        ("name", f"at most {budget.MAX_NAME_CHARS} characters"),
        ("lines", f"at most {budget.MAX_LINES} lines"),
        ("spacing", f"at most {budget.MAX_LINES} lines"),
        ("waypoints", f"at most {budget.MAX_WAYPOINTS}"),
        ("max_runs", f"At most {budget.MAX_RUNS:,}"),
    ):
        row = next(r for r in doc.splitlines() if r.startswith(f"| `{field}` |"))
        assert limit in row, row
