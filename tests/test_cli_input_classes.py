"""Issue 49, by class: every member of a class of bad input ends in one line, never a traceback.

Each test generates several members of one class (parametrised, or drawn by hypothesis) and runs
them through :func:`obsplan.cli.main` in-process: a refusal is exit 2 with exactly one line on
stderr naming the file, field or option at fault, before any work and with nothing written.

* (a) the readers: files nested thousands of levels deep, integers of thousands of digits,
  devices, named pipes and folders where a file is expected (never opened: a FIFO would hang);
* (b) magnitudes: numbers no vehicle problem has, in problem files, options, imported tracks and
  geodetic output, and the scales that made the Gramian's metrics meaningless;
* (c) options that do not apply to the input given, and the beacon at the trajectory's start;
* (d) two sweep axes that set the same field (or a field and a part of it);
* (e) words: the culprit named (``validation.dt``, a log's own latitude, a device, a manifest of
  another kind), and a closed stdout ending a verb quietly with exit 141.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import signal
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from obsplan.cli import EXIT_CLOSED_OUTPUT, VERBS, build_parser, main
from obsplan.cli.common import option_limits, verb_parser
from obsplan.core.outputs import write_marker
from obsplan.trajectory.sampled import Trajectory, write_csv

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "problems" / "localise.toml"
FEW = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def files_3d() -> Path:
    """A 3D plan CSV (a problem refused by its own fields never meets its dimension)."""
    return ROOT / "tests" / "data" / "range3d-plan.csv"


class Reached(Exception):
    """The verb accepted its inputs and got to its long computation."""


def _stop(*args, **kwargs):
    raise Reached


class Hung(Exception):
    """A reader blocked (on a named pipe) for longer than the guard allows."""


@contextlib.contextmanager
def no_hang(seconds: int = 20):
    """Fail instead of blocking forever: a refusal is instantaneous, opening a FIFO is not."""

    def _alarm(signum, frame):
        raise Hung(f"blocked for {seconds} s")

    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run(argv: list, capsys) -> tuple[int | str, str, str]:
    """Exit code (or ``"reached"``), stdout and stderr of ``main(argv)``."""
    try:
        with no_hang():
            code: int | str = main([str(a) for a in argv])
    except Reached:
        code = "reached"
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err


def refused(argv: list, capsys, *needles: str) -> str:
    """Exit 2 and exactly one line on stderr containing every needle; returns the line."""
    code, _, err = run(argv, capsys)
    assert code == 2, (argv, code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


@pytest.fixture
def stop_long_work(monkeypatch):
    monkeypatch.setattr("obsplan.cli.plan.plan", _stop)
    monkeypatch.setattr("obsplan.cli.simulate.monte_carlo", _stop)
    monkeypatch.setattr("obsplan.planning.validation.validate.validate_paths", _stop)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """A trajectory, a position-only track, a 3D plan, a far plan and a sweep's folder."""
    tmp = tmp_path_factory.mktemp("inputs")
    t = np.linspace(0.0, 60.0, 21)
    u = 0.05 * np.c_[np.sin(t / 10), np.cos(t / 10)]
    traj = write_csv(Trajectory.from_inputs(t, [-80.0, 60.0], [0.0, 0.5], u), tmp / "traj.csv")
    far = Trajectory.from_inputs(t, [100e3, 0.0], [0.0, 0.5], u)  # 100 km north of the origin
    track = tmp / "track.csv"
    track.write_text("t,px,py\n" + "".join(f"{k},{0.9 * k},{(k % 5) * 0.1}\n" for k in range(30)))
    sweep_out = tmp / "sweep-out"
    sweep_out.mkdir()
    return {
        "traj": traj,
        "far": write_csv(far, tmp / "far.csv"),
        "track": track,
        "sweep_out": sweep_out,
        "tmp": tmp,
    }


def _sweep_file(folder: Path, axes: str, base: str | None = None, name: str = "s") -> Path:
    f = folder / f"{name}.toml"
    base = DEFAULT.as_posix() if base is None else base
    f.write_text(f'[sweep]\nbase = "{base}"\n[axes]\n{axes}\n')
    return f


# ============================================================== (a) the readers
def _nested(style: str, depth: int) -> str:
    if style == "array":
        return "[" * depth + "]" * depth
    if style == "inline":
        return "{a = " * depth + "1" + "}" * depth
    return "[" + "{a = [" * depth + "]}" * depth + "]"


@FEW
@given(
    where=st.sampled_from(["problem", "sweep", "sweep.base", "axis"]),
    style=st.sampled_from(["array", "inline", "mixed"]),
    depth=st.integers(65, 6000),
)
def test_a_deep_nesting_in_any_toml_is_one_line_naming_the_file(
    tmp_path_factory, capsys, where, style, depth
):
    """5,000 levels used to be a RecursionError; 65 to a few hundred reached the loaders (and a
    deep copy of a sweep's base) before: both are the reader's refusal now."""
    tmp = tmp_path_factory.mktemp("deep")
    deep = tmp / "deep.toml"
    value = _nested(style, depth)
    if where == "axis":
        sweep = _sweep_file(tmp, f'"limits.speed" = [{value}]')
        refused(["sweep", sweep, "--out", tmp / "o"], capsys, str(sweep), "levels deep")
        return
    deep.write_text(f"{DEFAULT.read_text()}\n[problem.extra]\nx = {value}\n")
    if where == "problem":
        refused(["plan", deep, "--out", tmp / "o"], capsys, str(deep), "levels deep")
    elif where == "sweep":
        deep.write_text(f"x = {value}\n")
        refused(["sweep", deep, "--out", tmp / "o"], capsys, str(deep), "levels deep")
    else:
        sweep = _sweep_file(tmp, '"limits.speed" = [1.0]', deep.as_posix())
        refused(["sweep", sweep, "--out", tmp / "o"], capsys, "sweep.base", "levels deep")
    assert not (tmp / "o").exists()


@pytest.mark.parametrize("kind", ["dotted-header", "huge-integer"])
@pytest.mark.parametrize("verb", ["plan", "sweep"])
def test_a_dotted_headers_and_huge_integers(tmp_path, capsys, kind, verb):
    """A table header 5,000 keys long parses (tomllib does not recurse on it) but would exhaust
    the stack of whatever walks it; an integer of 5,000 digits is a ValueError of Python's."""
    f = tmp_path / "f.toml"
    text = DEFAULT.read_text() if verb == "plan" else _sweep_file(tmp_path, "x = 1").read_text()
    extra = {
        "dotted-header": f"\n[problem.{'.'.join(['x'] * 5000)}]\ny = 1\n",
        "huge-integer": f"\n[validation.extra]\nseed = {'7' * 5000}\n",
    }[kind]
    f.write_text(text + extra)
    needle = "levels deep" if kind == "dotted-header" else "not valid TOML: Exceeds the limit"
    refused([verb, f, "--out", tmp_path / "o"], capsys, str(f), needle)


@pytest.mark.parametrize("kind", ["/dev/zero", "fifo", "folder"])
@pytest.mark.parametrize(
    "verb", ["analyze", "plan", "sweep", "sweep.base", "import", "import.tlog", "export", "problem"]
)
def test_a_devices_pipes_and_folders_are_refused_by_kind_without_opening(
    tmp_path, files, capsys, kind, verb
):
    """``/dev/zero`` never ends and a named pipe blocks its reader forever (``analyze FIFO``
    used to hang in the row count; ``sweep.base = "/dev/zero"`` said "not found"): each is
    refused by its kind without being opened, and a folder as a folder."""
    if verb == "import.tlog" and kind != "fifo":
        pytest.skip("a folder is a ROS 2 bag; /dev/zero has no .tlog name")
    if kind == "/dev/zero":
        if not Path("/dev/zero").exists():
            pytest.skip("no /dev/zero")
        path, words = Path("/dev/zero"), "is not a regular file (a character device)"
    elif kind == "fifo":
        path = tmp_path / ("log.tlog" if verb == "import.tlog" else "pipe")
        words = "is not a regular file (a named pipe (FIFO))"
        os.mkfifo(path)
    else:
        path, words = tmp_path / "folder", "is a folder, not a file"
        path.mkdir()
    out = tmp_path / "out"
    argv = {
        "analyze": ["analyze", path],
        "plan": ["plan", path, "--out", out],
        "sweep": ["sweep", path, "--out", out],
        "sweep.base": ["sweep", _sweep_file(tmp_path, '"limits.speed" = [1.0]', str(path))],
        "import": ["import", path, "--out", tmp_path / "o.csv", "--format", "csv"],
        "import.tlog": ["import", path, "--out", tmp_path / "o.csv"],
        "export": ["export", path, "--waypoints", tmp_path / "w.csv"],
        "problem": ["simulate", files["traj"], "--problem", path, "--runs", "2"],
    }[verb]
    if verb == "sweep.base":
        argv += ["--out", out]
    needles = [f"{path} {words}"] + (["sweep.base: "] if verb == "sweep.base" else [])
    line = refused(argv, capsys, *needles)
    assert "not found" not in line
    assert not out.exists() and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize(
    "content,needle",
    [
        ("[" * 5000 + "]" * 5000, "levels deep"),
        ("1" * 5000, "not valid JSON"),
        (b"\x89PNG\r\n\x1a\n\x00garbage", "not a text file"),
        ("{not json", "not valid JSON"),
    ],
    ids=["deep", "huge-integer", "binary", "broken"],
)
@pytest.mark.parametrize("which", ["report.json", "sweep.json"])
def test_a_json_read_back_breaks_in_one_line(tmp_path, files, capsys, content, needle, which):
    """The report.json beside a plan (export's origin) and a sweep's sweep.json (--report,
    resuming) are user files too."""
    folder = tmp_path / "dir"
    folder.mkdir()
    target = folder / which
    if isinstance(content, bytes):
        target.write_bytes(content)
    else:
        target.write_text(content)
    if which == "report.json":
        plan = folder / "plan.csv"
        plan.write_bytes(files["traj"].read_bytes())
        argv = ["export", plan, "--waypoints", tmp_path / "w.csv", "--geodetic"]
    else:
        write_marker(folder, "sweep")
        argv = ["sweep", "--report", folder]
    refused(argv, capsys, str(target), needle)


# ============================================================== (b) magnitudes
@pytest.mark.parametrize(
    "field,value,needle",
    [
        ("scales.length_m", "1e300", "scales.length_m: 1e+300 m is beyond ±1e+07 m"),
        ("scales.length_m", "1e-300", "scales.length_m: 1e-300 m is below 1e-07 m"),
        ("scales.time_s", "1e300", "scales.time_s: 1e+300 s is beyond"),
        ("validation.range_std", "1e300", "validation.range_std: 1e+300 m is beyond"),
        ("validation.init_pos_error", "1e200", "validation.init_pos_error: 1e+200 m is beyond"),
        ("validation.accel_noise", "1e300", "validation.accel_noise: 1e+300"),
        ("limits.max_range", "1e12", "limits.max_range: 1e+12 m is beyond"),
        (
            "objective.linearisation_bound",
            "1e300",
            "objective.linearisation_bound: 1e+300 sigma_r is beyond",
        ),
    ],
)
def test_b_huge_numbers_in_a_problem_file(tmp_path, capsys, stop_long_work, field, value, needle):
    """``[scales] length_m = 1e300`` used to be an OverflowError in the planner: every number of
    the file is judged by the one rule before any arithmetic."""
    section, name = field.split(".")
    text, n = re.subn(rf"^{name} = .*$", f"{name} = {value}", DEFAULT.read_text(), flags=re.M)
    if n == 0 and f"[{section}]" in text:
        text = text.replace(f"[{section}]\n", f"[{section}]\n{name} = {value}\n", 1)
    elif n == 0:
        text += f"\n[{section}]\n{name} = {value}\n"
    p = tmp_path / "p.toml"
    p.write_text(text)
    refused(["plan", p, "--out", tmp_path / "o"], capsys, str(p), needle)
    refused(["simulate", files_3d(), "--problem", p], capsys, str(p), needle)
    assert not (tmp_path / "o").exists()


def _float_options() -> list[tuple[str, str]]:
    parser = build_parser()
    return [
        (verb, action.option_strings[-1])
        for verb in VERBS
        for action in verb_parser(parser, verb)._actions
        if action.type is float
    ]


def test_b_every_float_option_has_a_limit():
    """A new number option cannot escape the rule: the table names each one."""
    missing = [opt for _, opt in _float_options() if opt not in option_limits()]
    assert not missing, missing


@FEW
@given(
    pick=st.sampled_from(_float_options()),
    size=st.sampled_from(["huge", "tiny", "nan", "inf"]),
)
def test_b_every_float_option_beyond_its_limit_is_refused_by_name(files, capsys, pick, size):
    verb, option = pick
    limit, unit = option_limits()[option]
    value = {"huge": 1e3 * limit, "tiny": 1e-3 / limit, "nan": "nan", "inf": "-inf"}[size]
    inputs = {
        "analyze": [files["traj"]],
        "simulate": [files["traj"]],
        "plan": [DEFAULT],
        "import": [files["track"], "--out", files["tmp"] / "never.csv"],
        "estimate": [files["track"], "--out", files["tmp"] / "never.csv"],
        "export": [files["traj"], "--qgc", files["tmp"] / "never.plan", "--origin", "43.7,10.3"],
    }[verb]
    words = {"huge": "is beyond", "tiny": "is below", "nan": "not a finite", "inf": "not a finite"}
    line = refused([verb, *inputs, f"{option}={value}"], capsys, option, words[size])
    assert size in ("nan", "inf") or unit in line
    assert not (files["tmp"] / "never.csv").exists()


@pytest.mark.parametrize(
    "argv,needles",
    [
        (["analyze", "{traj}", "--length-scale", "1e300"], ["--length-scale", "beyond ±1e+07 m"]),
        (["analyze", "{traj}", "--time-scale", "1e-300"], ["--time-scale", "below 1e-07 s"]),
        # within range each, but together they push the Gramian below round-off: the numerics
        # that printed "min_eig 0, log_det -inf" on a full-rank Gramian refuse them
        (
            ["analyze", "{traj}", "--length-scale", "1e7", "--time-scale", "1e-7"],
            ["--length-scale 1e+07, --time-scale 1e-07", "full rank", "below round-off"],
        ),
        (["simulate", "{traj}", "--init-error", "1e9,0,0,0"], ["init_error px", "1e+09 m"]),
        (["simulate", "{traj}", "--init-error", "0,0,0,1e300"], ["init_error vy", "m/s"]),
        (["import", "{track}", "--out", "{tmp}/o.csv", "--position-std", "1e12"], ["--position"]),
        (
            ["export", "{traj}", "--qgc", "{tmp}/m.plan", "--origin", "43,10", "--depth", "1e9"],
            ["--depth", "±20000 m"],
        ),
        (
            ["export", "{far}", "--qgc", "{tmp}/m.plan", "--origin", "43,10"],
            ["far.csv (sample 0)", "100.0 km from the origin", "within 50 km"],
        ),
        (
            ["export", "{far}", "--waypoints", "{tmp}/w.csv", "--geodetic", "--origin", "43,10"],
            ["far.csv (sample 0)", "100.0 km"],
        ),
    ],
    ids=[
        "length-scale",
        "time-scale",
        "scales-together",
        "init-error-p",
        "init-error-v",
        "position-std",
        "depth",
        "qgc-100km",
        "geodetic-100km",
    ],
)
def test_b_huge_options_scales_and_geodetic_ranges(tmp_path, files, capsys, argv, needles):
    pytest.importorskip("pymap3d")
    where = {**{k: str(v) for k, v in files.items()}, "tmp": str(tmp_path)}
    refused([a.format(**where) for a in argv], capsys, *needles)
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("interval", [1e-12, 1e-9, 1e-7])
@pytest.mark.parametrize("verb", ["import", "analyze"])
def test_b_a_track_fitted_to_absurd_motion_is_an_error_not_a_warning(
    tmp_path, capsys, verb, interval
):
    """A track sampled every 1e-12 s (a time column in another unit) fits "exactly" with
    accelerations of 1e18 m/s²: it used to warn, exit 0 and then analyse as observable."""
    track = tmp_path / "fast.csv"
    track.write_text(
        "t,px,py\n" + "".join(f"{k * interval!r},{0.9 * k},{(k % 5) * 0.1}\n" for k in range(30))
    )
    argv = [verb, track] + (["--out", tmp_path / "o.csv"] if verb == "import" else [])
    refused(argv, capsys, str(track), "the fit needs a", f"{interval:.3g} s apart", "is beyond")
    assert not (tmp_path / "o.csv").exists()


# ============================================================== (c) options that do not apply
NOT_APPLYING = [
    (["import", "{track}", "--out", "{tmp}/o.csv", "--topic", "/odom"], "--topic", "is a CSV"),
    (["import", "{track}", "--out", "{tmp}/o.csv", "--ros-frame", "ned"], "--ros-frame", "CSV"),
    (
        ["import", "{track}", "--out", "{tmp}/o.csv", "--message", "LOCAL_POSITION_NED"],
        "--message",
        "is a CSV",
    ),
    (
        ["import", "{track}", "--out", "{tmp}/o.csv", "--origin", "43,10"],
        "--origin",
        "has local positions",
    ),
    (
        ["import", "{track}", "--out", "{tmp}/o.csv", "--velocity-std", "0.1"],
        "--velocity-std",
        "has no velocities",
    ),
    (
        ["import", "{tmp}/log.tlog", "--out", "{tmp}/o.csv", "--topic", "/odom"],
        "--topic",
        "is a MAVLink log",
    ),
    (
        ["import", "{tmp}/run.bag", "--out", "{tmp}/o.csv", "--message", "GLOBAL_POSITION_INT"],
        "--message",
        "is a ROS bag",
    ),
    (["analyze", "{traj}", "--origin", "43,10"], "--origin", "no --beacon-geodetic"),
    (["simulate", "{traj}", "--origin", "43,10"], "--origin", "no --beacon-geodetic"),
    (
        ["simulate", "{traj}", "--problem", "{default}", "--origin", "43,10"],
        "--origin",
        "[origin] is used",
    ),
    (
        ["simulate", "{traj}", "--open-loop", "--navigation", "ekf"],
        "--navigation",
        "--open-loop flies blind",
    ),
    (
        ["export", "{traj}", "--waypoints", "{tmp}/w.csv", "--origin", "43,10"],
        "--origin",
        "no --geodetic or --qgc",
    ),
    (
        ["export", "{traj}", "--waypoints", "{tmp}/w.csv", "--acceptance-radius", "2"],
        "--acceptance-radius",
        "no --qgc",
    ),
    (["export", "{traj}", "--waypoints", "{tmp}/w.csv", "--depth", "5"], "--depth", "no --qgc"),
    (
        ["export", "{traj}", "--qgc", "{tmp}/m.plan", "--origin", "43,10", "--geodetic"],
        "--geodetic",
        "no --waypoints",
    ),
    (["paper", "--force"], "--force", "no --out"),
    (["paper", "--no-figures", "--json"], "--no-figures", "no --out"),
    (["sweep", "--report", "{sweep_out}", "--workers", "2"], "--workers", "--report only"),
    (["sweep", "--report", "{sweep_out}", "--retry-failed"], "--retry-failed", "--report"),
    (["sweep", "--report", "{sweep_out}", "--no-figures"], "--no-figures", "--report"),
]


@pytest.mark.parametrize(
    "argv,option,instead", NOT_APPLYING, ids=[f"{c[0][0]} {c[1]}" for c in NOT_APPLYING]
)
def test_c_an_option_that_does_not_apply_is_refused(
    tmp_path, files, capsys, stop_long_work, argv, option, instead
):
    where = {**{k: str(v) for k, v in files.items()}, "tmp": str(tmp_path)}
    where["default"] = str(DEFAULT)
    line = refused([a.format(**where) for a in argv], capsys, option, instead)
    said = line.split("error: ", 1)[1]
    assert said.startswith(option), line
    assert said.endswith(": remove it") or "drop --problem" in said, line
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    "start,args,needle",
    [
        ([-80.0, 60.0], ["--beacon", "-80,60"], "--beacon -80,60: the start is 0 m"),
        ([-80.0, 60.0], ["--beacon", "-79,60"], "--beacon -79,60: the start is 1 m"),
        ([-80.0, 60.0], ["--beacon", "-80,64.99"], "the start is 4.99 m"),
        ([0.0, 3.0], ["--problem", str(DEFAULT)], "beacon.position of --problem"),
        ([0.0, 3.0], [], "the beacon (at the origin: no --beacon given): the start is 3 m"),
    ],
    ids=["at-start", "1m", "4.99m", "problem", "default-beacon"],
)
def test_c_simulate_refuses_the_geometry_plan_refuses(
    tmp_path, capsys, stop_long_work, start, args, needle
):
    """A beacon inside limits.min_range of the trajectory's start (used to run with a
    diverging EKF): the check of a problem's start (planning/problem/checks.py
    check_start_clear), reused with its words."""
    t = np.linspace(0.0, 60.0, 21)
    u = 0.05 * np.c_[np.sin(t / 10), np.cos(t / 10)]
    traj = write_csv(Trajectory.from_inputs(t, start, [0.0, 0.5], u), tmp_path / "t.csv")
    same = "from the beacon, inside limits.min_range = 5 m"
    refused(["simulate", traj, "--runs", "2", *args], capsys, needle, same)
    near = tmp_path / "near.toml"  # plan's own refusal of the same geometry, in the same words
    near.write_text(DEFAULT.read_text().replace("position = [0.0, 0.0]", "position = [-81, 60]"))
    refused(["plan", near, "--out", tmp_path / "o"], capsys, "start.position: the start is", same)


def test_c_simulate_accepts_a_beacon_beyond_min_range(tmp_path, files, capsys, stop_long_work):
    code, _, err = run(["simulate", files["traj"], "--runs", "2", "--beacon", "-86,60"], capsys)
    assert code == "reached", err


# ============================================================== (d) duplicate sweep axes
SAME_FIELD = [
    ('"limits.speed" = [1.0]', "limits.speed = [2.0]", '"limits.speed"', "limits.speed"),
    (
        '"limits.accel.0" = [0.01]',
        '"limits.accel[0]" = [0.02]',
        '"limits.accel.0"',
        '"limits.accel[0]"',
    ),
    ("limits.accel.0 = [0.01]", '"limits.accel.0" = [0.02]', "limits.accel.0", '"limits.accel.0"'),
    (
        '"beacon.position" = [[0.0, 0.0]]',
        "beacon.position = [[1.0, 0.0]]",
        '"beacon.position"',
        "beacon.position",
    ),
    (
        '"validation.seed" = {range = 2}',
        "validation.seed = [5]",
        '"validation.seed"',
        "validation.seed",
    ),
]
OVERLAPPING = [
    ('"limits.accel" = [0.05]', '"limits.accel.1" = [0.01]', "limits.accel.1", "limits.accel"),
    ("limits.accel.0 = [0.01]", '"limits.accel" = [0.05]', "limits.accel.0", "limits.accel"),
    (
        '"limits.area" = [{x = [-100.0, 100.0], y = [-100.0, 100.0]}]',
        '"limits.area.x" = [[-90.0, 90.0]]',
        "limits.area.x",
        "limits.area",
    ),
    (
        '"limits.area.x" = [[-90.0, 90.0]]',
        '"limits.area.x.0" = [-95.0]',
        "limits.area.x.0",
        "limits.area.x",
    ),
    (
        '"beacon.position.0" = [5.0]',
        '"beacon.position" = [[1.0, 0.0]]',
        "beacon.position.0",
        "beacon.position",
    ),
]


@pytest.mark.parametrize(
    "first,second,one,other,words",
    [(*c, "both set") for c in SAME_FIELD] + [(*c, "overlap") for c in OVERLAPPING],
)
@pytest.mark.parametrize("order", ["as written", "swapped"])
def test_d_two_axes_setting_one_field_are_refused_naming_both(
    tmp_path, capsys, first, second, one, other, words, order
):
    """``"limits.speed"`` and ``limits.speed`` are two TOML keys for one field: the sweep kept
    one of them silently; a field and a part of it overwrote each other."""
    if order == "swapped":
        first, second = second, first
    sweep = _sweep_file(tmp_path, f"{first}\n{second}")
    line = refused(["sweep", sweep, "--out", tmp_path / "o"], capsys, str(sweep), "axes: ", words)
    for spelling in (one, other):
        assert spelling in line, (spelling, line)
    assert not (tmp_path / "o").exists()


def test_d_distinct_components_and_bare_component_keys_are_axes():
    from obsplan.sweeps.spec import sweep_from_dict

    spec = sweep_from_dict(
        {
            "sweep": {"base": str(DEFAULT)},
            "axes": {"limits": {"accel": {"0": [0.01, 0.02], "1": [0.03]}}, "vehicle.dim": [2]},
        }
    )
    assert [a.keys for a in spec.axes] == [
        ("limits", "accel", 0),
        ("limits", "accel", 1),
        ("vehicle", "dim"),
    ]


# ============================================================== (e) words
def test_e_a_tiny_filter_step_is_blamed_on_validation_dt(tmp_path, capsys):
    p = tmp_path / "p.toml"
    p.write_text(DEFAULT.read_text().replace("dt = 0.1 ", "dt = 1e-6 "))
    for argv in (["plan", p, "--out", tmp_path / "o"], ["simulate", files_3d(), "--problem", p]):
        line = refused(argv, capsys, "validation.dt: 6e+08 samples per run")
        assert "validation.runs" not in line


def _tlog(path: Path, lat: np.ndarray) -> Path:
    mav2 = pytest.importorskip("pymavlink.dialects.v20.ardupilotmega")
    m = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    raw = bytearray()
    for k, la in enumerate(lat):
        msg = mav2.MAVLink_global_position_int_message(
            1000 * k, int(round(la * 1e7)), int(10.3e7), -5000, -5000, 0, 0, 0, 0
        )
        raw += struct.pack(">Q", 1_700_000_000_000_000 + k * 1_000_000) + msg.pack(m)
    path.write_bytes(bytes(raw))
    return path


@pytest.mark.parametrize("bad", [0, 7])
@pytest.mark.parametrize("source", ["tlog", "waypoint-csv"])
def test_e_a_latitude_of_the_logs_own_fixes_is_blamed_on_the_log(tmp_path, capsys, bad, source):
    """Without --origin the origin is the first fix: a latitude of 200° there is the log's,
    never an "origin" the user did not give."""
    pytest.importorskip("pymap3d")
    lat = 43.7 + 1e-6 * np.arange(20.0)
    lat[bad] = 200.0
    if source == "tlog":
        log = _tlog(tmp_path / "dive.tlog", lat)
        where = f"{log}: GLOBAL_POSITION_INT (sample {bad})"
    else:
        log = tmp_path / "wp.csv"
        rows = "".join(f"{3.0 * k},{float(la)!r},10.3,1.0\n" for k, la in enumerate(lat))
        log.write_text("t,latitude,longitude,speed\n" + rows)
        where = f"{log} (sample {bad})"
    line = refused(["import", log, "--out", tmp_path / "o.csv"], capsys, where, "latitude 200")
    assert "origin:" not in line and "--origin" not in line


def test_e_a_manifest_of_another_kind_is_named(tmp_path, files, capsys):
    sweep = _sweep_file(tmp_path, '"limits.speed" = [1.0]')
    for i, doc in enumerate(([1, 2], "sweep", {"other": 1}, {"sweep": [1]}, {"sweep": {}})):
        out = tmp_path / f"o{i}"
        out.mkdir()
        write_marker(out, "sweep")
        (out / "sweep.json").write_text(json.dumps(doc))
        refused(["sweep", "--report", out], capsys, f"{out / 'sweep.json'}: not the manifest")
        if not (isinstance(doc, dict) and isinstance(doc.get("sweep"), dict)):
            refused(["sweep", sweep, "--out", out], capsys, "not the manifest of an obsplan sweep")


class ClosedPipe:
    """A stdout whose reader went away: every write is EPIPE."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    def flush(self) -> None:
        pass


@pytest.mark.parametrize(
    "argv",
    [
        ["analyze", "{traj}", "--json"],
        ["analyze", "{traj}"],
        ["import", "{track}", "--out", "{tmp}/o.csv", "--json"],
        ["export", "{traj}", "--waypoints", "{tmp}/w.csv", "--json"],
        ["simulate", "{traj}", "--runs", "2", "--json"],
    ],
    ids=lambda a: " ".join(a[::2]),
)
def test_e_a_closed_stdout_ends_any_verb_quietly(tmp_path, files, capsys, monkeypatch, argv):
    """``obsplan paper --json | head -c 10`` used to print "failed: Broken pipe" and exit 1, the
    code of a failed computation."""
    where = {**{k: str(v) for k, v in files.items()}, "tmp": str(tmp_path)}
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    code = main([a.format(**where) for a in argv])
    monkeypatch.undo()
    _, err = capsys.readouterr()
    assert err == "", err
    assert code == EXIT_CLOSED_OUTPUT


def test_e_paper_json_into_a_closed_pipe_exits_141_with_nothing_on_stderr(monkeypatch):
    """The same in-process for ``paper --json`` (its tables replaced: the pipe is the point)."""
    monkeypatch.setattr("obsplan.cli.paper.all_rows", lambda quick: [])
    monkeypatch.setattr("obsplan.cli.paper.claims", lambda quick: [])
    monkeypatch.setattr("obsplan.cli.paper.structural", lambda quick: [])
    monkeypatch.setattr("obsplan.cli.paper.render_tables", lambda *a: "tables")
    monkeypatch.setattr("obsplan.cli.paper.paper_report", lambda quick: {"rows": [1] * 10})
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert main(["paper", "--json", "--quick", "--quiet"]) == EXIT_CLOSED_OUTPUT


def test_e_a_real_closed_pipe_exits_141_with_nothing_on_stderr(files):
    """A real process whose stdout's reader is gone before the verb writes: exit 141 and an
    empty stderr, not even from the interpreter's last flush."""
    read, write = os.pipe()
    os.close(read)
    cmd = [sys.executable, "-c", "import sys; from obsplan.cli import main; sys.exit(main())"]
    proc = subprocess.Popen(
        [*cmd, "analyze", str(files["traj"]), "--json"], stdout=write, stderr=subprocess.PIPE
    )
    os.close(write)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_CLOSED_OUTPUT and err == b"", err


def test_e_a_broken_pipe_that_is_not_the_output_is_a_failure(files, capfd, monkeypatch):
    """A BrokenPipeError of anything else (a worker's pipe) while stdout and stderr are open is
    a failure like any OSError: exit 1, one line."""

    def boom(args):
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    monkeypatch.setattr("obsplan.cli.analyze.run", boom)
    capfd.readouterr()
    assert main(["analyze", str(files["traj"])]) == 1
    err = capfd.readouterr().err
    assert err.strip() == "obsplan analyze: failed: Broken pipe", err
