"""The example scripts run as a user would run them, in a subprocess, and print sane numbers."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NUMBER = r"([-+0-9.eE]+|nan|inf)"


def _run(script: str, *args: str, cwd: Path, timeout: float = 120.0) -> str:
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("OBSPLAN_QUICK", None)  # the --quick flag alone must be enough
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=cwd,  # not the repository: the script must not depend on the working directory
    )
    assert proc.returncode == 0, f"{script} exited {proc.returncode}:\n{proc.stderr[-3000:]}"
    return proc.stdout


def _value(out: str, label: str) -> float:
    m = re.search(rf"^{re.escape(label)}\s*{NUMBER}", out, flags=re.MULTILINE)
    assert m, f"no line starting {label!r} in:\n{out}"
    return float(m.group(1))


@pytest.mark.slow
def test_quickstart_quick(tmp_path):
    out = _run("quickstart.py", "--quick", cwd=tmp_path)
    assert re.search(r"^solver: \w+, \d+ iterations$", out, flags=re.MULTILINE), out
    m = re.search(rf"^objective: planned {NUMBER}, lawn-mower {NUMBER}$", out, re.MULTILINE)
    assert m, out
    planned, mower = float(m.group(1)), float(m.group(2))
    # the lawn-mower is one of the plan's candidates: the plan is never worse (it is 2 by
    # definition of the relative objective)
    assert math.isfinite(planned) and planned <= mower and mower == 2.0
    m = re.search(rf"^mission-average bound: planned {NUMBER} m, lawn-mower {NUMBER} m$", out, re.M)
    assert m and 0 < float(m.group(1)) <= float(m.group(2)), out
    assert "LWO along the path: True" in out
    assert "Gramian full rank: True" in out
    errs = [
        _value(out, "EKF final position error:"),
        _value(out, "KF final position error:"),
        _value(out, "CRB final position std:"),
    ]
    # initial errors are ~1 m per axis; an observable path must not leave the filters worse off
    assert all(math.isfinite(e) and 0.0 <= e < 2.0 for e in errs), errs
