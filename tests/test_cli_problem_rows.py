"""The CLI rows of the issue that are about problem validation (planner/problem code).

Each problem below used to hang, run into a MemoryError or be accepted with NaN results. The
command line must refuse it at once: exit 2, one line naming the field and the fix, no output
folder. They run as real processes with a timeout, so a hang fails the test instead of the
suite (60 s: a refusal is instantaneous; the margin is for a loaded 2-core machine).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

DEFAULT = Path(__file__).resolve().parents[1] / "problems" / "localise.toml"
TIMEOUT_S = 60


def obsplan(*args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-c", "import sys; from obsplan.cli import main; sys.exit(main())"]
    return subprocess.run(
        [*cmd, *args], capture_output=True, text=True, timeout=TIMEOUT_S, check=False
    )


def edited(tmp_path: Path, pattern: str, repl: str) -> Path:
    text, n = re.subn(pattern, repl, DEFAULT.read_text(), count=1, flags=re.MULTILINE)
    assert n == 1, pattern
    path = tmp_path / "p.toml"
    path.write_text(text)
    return path


def assert_refused(proc: subprocess.CompletedProcess, field: str, out: Path) -> None:
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip()
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err and "np.float64(" not in err, err
    assert field in err, err
    assert not out.exists()


CASES = [
    (r"^accel = .*$", "accel = 1e-12", "limits.accel"),  # hung in the paper lawn-mower
    (r"^steps = .*$", "steps = 100000", "horizon.steps"),  # hung in the build
    (r"^runs = .*$", "runs = 100000", "validation.runs"),  # MemoryError
    (r"^position = \[0\.0, 0\.0\].*$", "position = [-80.0, 60.0]", "beacon"),  # at the start
    # found by tests/test_fuzz_loaders.py: an OverflowError in the min_range check
    (r"^duration = .*$", "duration = 1.0726246343954078e+157", "horizon.duration"),
]


@pytest.fixture(scope="module")
def refusals(tmp_path_factory):
    """Every case of CASES run at once (the processes in parallel: each mostly imports)."""
    cmd = [sys.executable, "-c", "import sys; from obsplan.cli import main; sys.exit(main())"]
    procs = []
    for i, (pattern, repl, _) in enumerate(CASES):
        tmp = tmp_path_factory.mktemp(f"case{i}")
        args = ["plan", str(edited(tmp, pattern, repl)), "--out", str(tmp / "out"), "--quiet"]
        pipes = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True}
        procs.append((tmp / "out", subprocess.Popen([*cmd, *args], **pipes)))
    results = []
    for out, proc in procs:
        try:
            stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate()
            stderr = f"hung: no refusal within {TIMEOUT_S} s\n{stderr}"
        results.append(
            (subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), out)
        )
    return results


@pytest.mark.slow
@pytest.mark.parametrize("i", range(len(CASES)), ids=[c[2] for c in CASES])
def test_problem_is_refused_at_once(refusals, i):
    proc, out = refusals[i]
    assert_refused(proc, CASES[i][2], out)


def test_two_steps_are_planned_or_refused_for_the_real_reason(tmp_path):
    """``--steps 2`` used to blame limits.area ("enlarge the area", with np.float64 noise)."""
    out = tmp_path / "out"
    proc = obsplan("plan", "--steps", "2", "--no-validate", "--quiet", "--out", str(out))
    if proc.returncode == 2:
        err = proc.stderr.strip()
        assert len(err.splitlines()) == 1 and "np.float64(" not in err, err
        assert "horizon.steps" in err or "--steps" in err, err
        assert not out.exists()
    else:
        assert proc.returncode in (0, 1), proc.stderr
        assert (out / "report.json").is_file()


def test_a_trajectory_starting_at_the_beacon_gets_no_nan(tmp_path):
    """``simulate`` with the beacon at the start: a finite bound or a clear refusal."""
    from obsplan.trajectory.sampled import Trajectory, write_csv

    t = np.linspace(0.0, 120.0, 121)
    u = 0.05 * np.c_[np.sin(t / 20), np.cos(t / 20)]
    path = write_csv(Trajectory.from_inputs(t, [-80.0, 60.0], [0.0, 0.0], u), tmp_path / "p.csv")
    proc = obsplan("simulate", str(path), "--beacon", "-80,60", "--runs", "2", "--json")
    if proc.returncode == 2:
        assert "beacon" in proc.stderr and "Traceback" not in proc.stderr
        return
    assert proc.returncode == 0, proc.stderr
    assert "Warning" not in proc.stderr and "nan" not in proc.stdout.lower()
    d = json.loads(proc.stdout)
    assert d["crlb_final_pos_std"] is not None and np.isfinite(d["crlb_final_pos_std"])
    assert d["ekf"]["nees_mean"] < 1e4  # not the 5.7e6 of an EKF linearised at the beacon
