"""A newcomer's first ten minutes, through the installed ``obsplan`` command.

``obsplan plan --out DIR`` with no problem file must produce ``plan.csv``, ``report.json`` and the
figures, and ``obsplan analyze DIR/plan.csv --json`` must read the plan back. Run through the
console script in a subprocess, as a user would, at reduced size (the full default problem is the
README's first command).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SMALL = ["--steps", "24", "--starts", "1", "--runs", "3", "--quiet"]


def _obsplan() -> list[str]:
    exe = shutil.which("obsplan", path=str(Path(sys.executable).parent))
    return [exe] if exe else [sys.executable, "-m", "obsplan"]


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [*_obsplan(), *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
def test_plan_then_analyze_reads_the_plan_back(tmp_path):
    out = tmp_path / "first-plan"
    res = _run(["plan", "--out", str(out), *SMALL], cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "planned" in res.stdout and "lawnmower" in res.stdout  # the summary table
    for name in ("plan.csv", "report.json", "path.png", "gramian.png", "filters.png"):
        assert (out / name).stat().st_size > 0, name
    report = json.loads((out / "report.json").read_text())
    assert report["solver"]["success"] is True

    res = _run(["analyze", str(out / "plan.csv"), "--json"], cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    back = json.loads(res.stdout)
    assert back["dim"] == 2 and back["sensors"] == ["range"] and back["current"] is False
    assert set(back["lwo"]) == {"along_trajectory", "full_rank_fraction", "min_rank", "state_dim"}
    assert set(back["gramian"]) == {
        "full_rank",
        "rank",
        "dim",
        "full_rank_from_t",
        "min_eig",
        "log_det",
        "condition",
        # beside the stable keys: the exact structural interval (observability/structural.py)
        "rank_tol",
        "rank_exact",
        "full_rank_interval_exact",
        "full_rank_from_t_exact",
    }
    # the planner maximised the Gramian's smallest eigenvalue: reading the plan back must find
    # it full rank, with the same fixed-scale λ_min the report gave (same path, same scales)
    assert back["gramian"]["full_rank"] is True
    planned = report["metrics"]["planned"]["min_eig"]
    assert back["gramian"]["min_eig"] == pytest.approx(planned, rel=1e-6)


def test_second_plan_into_the_same_folder_is_refused(tmp_path):
    out = tmp_path / "keep"
    out.mkdir()
    (out / "precious.txt").write_text("user results")
    res = _run(["plan", "--out", str(out), *SMALL], cwd=tmp_path)
    assert res.returncode == 2
    assert "--force" in res.stderr and "Traceback" not in res.stderr
    assert (out / "precious.txt").read_text() == "user results"
