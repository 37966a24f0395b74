"""Fuzzing ``main(argv)``: random argument lists end in an exit code, never a traceback.

Any argument list must give exit 0, 1 or 2 (or argparse's own SystemExit 0/2 for ``--help`` and
unknown options). The long computations are replaced by a sentinel so that the fuzz covers
parsing, input checks and output checks, not planner runs: reaching the sentinel means the
verb accepted its inputs and checked its outputs first.
"""

from __future__ import annotations

import contextlib
import io
import uuid
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from obsplan.cli import main
from obsplan.trajectory.sampled import Trajectory, write_csv

ROOT = Path(__file__).resolve().parents[1]
_TMP = Path()  # set by the fixture below: pytest's tmp_path, cleaned up by pytest
FILES: dict[str, str] = {}


@pytest.fixture(scope="module", autouse=True)
def _fuzz_files(tmp_path_factory):
    global _TMP
    _TMP = tmp_path_factory.mktemp("fuzz-cli")
    FILES.update(_files())
    yield
    FILES.clear()
    _TMP = Path()


class Reached(Exception):
    """The verb got as far as its long computation."""


def _stop(*args, **kwargs):
    raise Reached


def _files() -> dict[str, str]:
    import numpy as np

    t = np.linspace(0.0, 60.0, 21)
    u = 0.05 * np.c_[np.sin(t / 10), np.cos(t / 10)]
    tr = Trajectory.from_inputs(t, [-80.0, 60.0], [0.0, 0.5], u)
    files = {"traj": write_csv(tr, _TMP / "traj.csv")}
    tr3 = Trajectory.from_inputs(t, [1.0, 2.0, 3.0], [0.5, 0, 0], np.c_[u, 0.01 * u[:, 0]])
    files["traj3"] = write_csv(tr3, _TMP / "traj3.csv")
    track = _TMP / "track.csv"
    track.write_text("t,px,py\n" + "".join(f"{k},{k * 0.9},{(k % 5) * 0.1}\n" for k in range(30)))
    files["track"] = track
    bad = _TMP / "bad.csv"
    bad.write_text("t;px\n0;1,5\n")
    files["bad"] = bad
    badtoml = _TMP / "bad.toml"
    badtoml.write_text("[limits]\naccel = -1\n")
    files["badtoml"] = badtoml
    # encodings: a Latin-1 problem, one with a byte-order mark, a UTF-16 trajectory, a comment
    default = (ROOT / "problems" / "localise.toml").read_text(encoding="utf-8")
    for key, data in (
        ("latin1toml", default.encode("latin-1", errors="replace")),
        ("bomtoml", b"\xef\xbb\xbf" + default.encode("utf-8")),
        ("utf16", files["traj"].read_text().encode("utf-16")),
        ("commented", ("# a comment\n" + files["traj"].read_text()).encode("utf-8")),
        ("huge", files["traj"].read_text().replace("\n0.0,-80.0,", "\n0.0,-8e300,").encode()),
    ):
        files[key] = _TMP / f"{key}.{'toml' if 'toml' in key else 'csv'}"
        files[key].write_bytes(data)
    (_TMP / "afile").write_text("x")
    files.update(
        {
            "default": ROOT / "problems" / "localise.toml",
            "3d": ROOT / "problems" / "range3d.toml",
            "missing": _TMP / "missing.csv",
            "folder": _TMP,
            "underfile": _TMP / "afile" / "x",
        }
    )
    return {k: str(v) for k, v in files.items()}


NUMBERS = (
    st.sampled_from(
        [
            "0",
            "1",
            "2",
            "-1",
            "3",
            "0.1",
            "1e-7",
            "1e9",
            "nan",
            "inf",
            "-inf",
            "1e400",
            "",
            "x",
            "-50,10",
            "-50,10,5",
            "a,b",
            "0,0",
            "43.7,10.3",
            "-33.9,151.2,4",
            "91,0",
            "1,2,3,4",
            "range",
            "range,dvl",
            "range,depth",
            "sonar",
            "range=0.1",
            "range=-1",
            "range=1e200",
            "1e300",
            "1e300,0",
            "-1e12,5",
            "dvl=10",
            "sample",
            "1,2,3,4",
            "ekf",
            "kf,ekf",
            "ukf",
        ]  # fmt: skip
    )
    | st.integers(-(10**6), 10**6).map(str)
    | st.floats(allow_nan=True).map(repr)
)
OPTIONS = {
    "analyze": ["--sensors", "--beacon", "--beacon-geodetic", "--origin", "--length-scale",
                "--time-scale", "--json", "--current"],
    "simulate": ["--sensors", "--beacon", "--rates", "--noise", "--dt", "--runs", "--seed",
                 "--init-error", "--json", "--quiet", "--out", "--force", "--problem",
                 "--filters", "--no-process-noise", "--origin", "--beacon-geodetic"],
    "plan": ["--out", "--force", "--runs", "--steps", "--starts", "--no-validate", "--quiet"],
    "import": ["--out", "--force", "--format", "--grid", "--position-std", "--velocity-std",
               "--max-gap", "--json", "--topic", "--message", "--origin", "--ros-frame"],
    "export": ["--waypoints", "--qgc", "--every", "--spacing", "--geodetic", "--origin",
               "--depth", "--acceptance-radius", "--force", "--json"],
}  # fmt: skip
FLAGS = {
    "--json", "--current", "--quiet", "--force", "--no-validate", "--geodetic",
    "--no-process-noise",
}  # fmt: skip
PATH_OPTIONS = {"--out", "--waypoints", "--qgc", "--problem"}
#: Plausible values, drawn more often than the noise of NUMBERS so that verbs also succeed.
GOOD = {
    "--sensors": ["range", "range,dvl-water", "range,depth"],
    "--beacon": ["-50,10", "0,0", "10,-20,5"],
    # near the origin, 60 km north, the antipode
    "--beacon-geodetic": ["43.7001,10.3001", "-33.9,151.2,4", "44.24,10.3", "-43.7,-169.7"],
    "--origin": ["43.7,10.3", "-33.9,151.2", "43.7,10.3,2"],
    "--length-scale": ["100", "10"],
    "--time-scale": ["100", "-1"],
    "--rates": ["range=1", "range=0.5"],
    "--noise": ["range=0.2"],
    "--dt": ["0.1", "1e-7", "0.3"],
    "--runs": ["2", "1", "0"],
    "--seed": ["0", "7", "-1"],
    "--init-error": ["sample", "1,1,0.1,0.1"],
    "--filters": ["ekf", "kf", "ekf,kf"],
    "--steps": ["10", "2", "100000"],
    "--starts": ["1", "0"],
    "--format": ["auto", "csv", "mavlink", "rosbag"],
    "--grid": ["3", "1e-9", "-1"],
    "--position-std": ["0.05", "0"],
    "--velocity-std": ["0.05"],
    "--max-gap": ["10", "0.5"],
    "--topic": ["/odom"],
    "--message": ["LOCAL_POSITION_NED"],
    "--ros-frame": ["enu", "ned"],
    "--every": ["10", "1e-9", "-3"],
    "--spacing": ["5", "0"],
    "--depth": ["5", "nan"],
    "--acceptance-radius": ["1", "-1"],
}


@st.composite
def argvs(draw) -> list[str]:
    verb = draw(st.sampled_from([*OPTIONS] * 5 + ["bogus"]))
    argv = [verb]
    if verb != "bogus" and draw(st.integers(0, 9)):
        kind = {
            "plan": ["default", "default", "3d", "badtoml", "missing", "traj", "latin1toml",
                     "bomtoml"],
        }.get(
            verb, ["traj", "traj", "traj3", "track", "track", "bad", "missing", "folder",
                   "utf16", "commented", "huge"]
        )  # fmt: skip
        argv.append(FILES[draw(st.sampled_from(kind))])
    for _ in range(draw(st.integers(0, 5))):
        opt = draw(st.sampled_from(OPTIONS.get(verb, ["--help"]) * 4 + ["--bogus", "--help"]))
        argv.append(opt)
        if opt in FLAGS:
            continue
        if opt in PATH_OPTIONS:
            fresh = str(_TMP / "out" / uuid.uuid4().hex / ("o.csv" if opt != "--out" else "o"))
            pick = ["fresh", "fresh", "file", "folder", "underfile", "sys"]
            if opt == "--problem":
                pick = ["default", "3d", "badtoml", "missing", "latin1toml", "bomtoml"]
            which = draw(st.sampled_from(pick))
            argv.append(
                {"fresh": fresh, "file": FILES["traj"], "sys": "/sys/obsplan-fuzz"}.get(
                    which, FILES.get(which, fresh)
                )
            )
        elif opt in GOOD and draw(st.integers(0, 2)):
            argv.append(draw(st.sampled_from(GOOD[opt])))
        else:
            argv.append(draw(NUMBERS))
    return argv


@settings(
    max_examples=500,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@pytest.mark.slow
@given(argvs())
def test_fuzz_main_argv(argv):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("obsplan.cli.plan.plan", _stop)
        mp.setattr("obsplan.cli.simulate.monte_carlo", _stop)
        mp.setattr("obsplan.planning.validation.validate.validate_paths", _stop)
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv)
        except Reached:
            return
        except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
            assert exc.code in (0, 2), (argv, err.getvalue())
            return
    assert code in (0, 1, 2), (argv, code, err.getvalue())
    text = err.getvalue()
    assert "Traceback" not in text
    if code == 2:
        assert len(text.strip().splitlines()) >= 1 and "error:" in text, (argv, text)
