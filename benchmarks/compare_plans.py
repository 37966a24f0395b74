"""Record what ``obsplan plan`` prints and reports for every shipped problem, and compare two
records.

A change that should not change behaviour (a refactoring, a move of modules) is checked with it:

    python benchmarks/compare_plans.py record --out before.json      # on the old code
    python benchmarks/compare_plans.py record --out after.json       # on the new code
    python benchmarks/compare_plans.py compare before.json after.json

``record`` runs ``python -m obsplan plan FILE --out TMP --quiet`` on each problem (by default every
``*.toml`` under ``problems/`` and ``problems/suite/``), in the working tree it is run from, and
keeps per problem the printed table and verdict words and the whole ``report.json``, without the
wall-clock times (``wall_s``, ``build_s`` and the timings of the first printed line), which differ
from run to run. ``compare`` prints every difference, to the last digit (floats compared exactly,
as their ``repr``), and exits 1 if there is any. Both runs must be on the same machine: IPOPT's
iterates depend on the CPU's BLAS kernels.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: report.json keys that are wall-clock times (everything else must be bit-identical)
TIMING_KEYS = frozenset({"wall_s", "build_s"})
#: the timings printed on the plan's first line ("5.2 s solve, 47.0 s total")
TIMING_WORDS = re.compile(r"[0-9.]+ s (solve|total)")


def default_problems() -> list[Path]:
    """Every problem file shipped in the repository (``problems/`` and ``problems/suite/``)."""
    root = REPO / "problems"
    files = sorted(root.glob("*.toml")) + sorted((root / "suite").rglob("*.toml"))
    return files


def strip_timings(x: object) -> object:
    """``x`` (a report.json tree) without its wall-clock entries."""
    if isinstance(x, dict):
        return {k: strip_timings(v) for k, v in x.items() if k not in TIMING_KEYS}
    if isinstance(x, list):
        return [strip_timings(v) for v in x]
    return x


def run_one(problem: Path, out: Path) -> dict:
    """Plan ``problem`` with the CLI of the working tree; its table, words and report."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(REPO))
    proc = subprocess.run(
        [sys.executable, "-m", "obsplan", "plan", str(problem), "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        cwd=REPO,
        env=env,
    )
    lines = [
        TIMING_WORDS.sub("<time>", line)
        for line in proc.stdout.splitlines()
        if not line.startswith("wrote ")
    ]
    report_file = out / "report.json"
    report = json.loads(report_file.read_text()) if report_file.exists() else None
    return {
        "exit": proc.returncode,
        "stdout": lines,
        "stderr_tail": proc.stderr.strip().splitlines()[-3:] if proc.returncode else [],
        "report": strip_timings(report),
    }


def record(problems: list[Path], out_file: Path) -> int:
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, problem in enumerate(problems):
            t0 = time.perf_counter()
            results[str(problem.resolve().relative_to(REPO))] = run_one(
                problem, Path(tmp) / f"p{i}"
            )
            key = str(problem.resolve().relative_to(REPO))
            print(
                f"{i + 1:3d}/{len(problems)} {key}: exit {results[key]['exit']}, "
                f"{time.perf_counter() - t0:.0f} s",
                flush=True,
            )
            # after each problem: a long record stopped early still compares what it has
            out_file.write_text(json.dumps(results, indent=1, sort_keys=True))
    print(f"wrote {out_file}")
    return 0


def differences(a: object, b: object, path: str = "") -> list[str]:
    """Every place where two report trees differ (floats exactly, by their repr)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'after' if k not in a else 'before'}")
            else:
                out += differences(a[k], b[k], f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items before, {len(b)} after"]
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in differences(x, y, f"{path}[{i}]")
        ]
    if repr(a) != repr(b):
        return [f"{path}: {a!r} before, {b!r} after"]
    return []


def compare(before: Path, after: Path) -> int:
    a, b = json.loads(before.read_text()), json.loads(after.read_text())
    bad = 0
    for key in sorted(set(a) | set(b)):
        if key not in a or key not in b:
            print(f"{key}: only in {'after' if key not in a else 'before'}")
            bad += 1
            continue
        diff = differences(a[key], b[key])
        status = "same" if not diff else f"{len(diff)} difference(s)"
        print(f"{key}: {status}")
        for d in diff[:20]:
            print(f"    {d}")
        bad += bool(diff)
    print(f"{len(set(a) | set(b)) - bad} of {len(set(a) | set(b))} problems identical")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="verb", required=True)
    r = sub.add_parser("record", help="plan every problem and keep what plan printed and reported")
    r.add_argument("problems", nargs="*", type=Path, help="problem files (default: all shipped)")
    r.add_argument("--out", type=Path, required=True, help="the record (JSON)")
    c = sub.add_parser("compare", help="compare two records, to the last digit")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = ap.parse_args(argv)
    if args.verb == "record":
        return record(args.problems or default_problems(), args.out)
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
