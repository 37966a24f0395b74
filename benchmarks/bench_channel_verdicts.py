"""Do the plans' verdicts hold at sea? Every shipped problem planned and validated as
``obsplan plan`` does, with the ideal channel and with ``--channel at-sea``.

Run (minutes per problem on one core):

    MPLBACKEND=Agg python benchmarks/bench_channel_verdicts.py [FILE ...] [--json out.json]

Without files: every problem of ``problems/*.toml`` whose vehicle is planned (a fixed beacon or
one on a known path; a planned beacon's problems are ``plan_moving_beacon``'s). For each,
``plan(pb)`` (the ideal channel) and
``plan(pb.with_changes(validation={"channel": "at-sea"}))`` (what ``obsplan plan --channel at-sea``
runs: planned on the expected information of the pings that
arrive, validated through the channel with the gate and scale state it turns on), each
validated in batches until every verdict is decided or ``validation.max_runs`` is reached.
Per problem and channel it prints the plan's EKF RMSE and EKF final error against the
lawn-mower's (ratio and outcome at 95 %: ``better``, ``worse`` or ``tie``), the runs, and
whether the at-sea verdict holds where the ideal one is a decided win. The issue's aim: the
plan beats the lawn-mower on both in the preset wherever it does with the ideal channel.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402

METRICS = ("ekf.rmse_pos", "ekf.final_pos_err")


def _row(path: Path, channel: str) -> dict:
    pb = load_problem(path)
    if channel != "ideal":
        pb = pb.with_changes(validation={"channel": channel})
    t0 = time.perf_counter()
    res = plan(pb)
    comp = res.verdict.comparisons.get("lawnmower", {})
    out: dict = {
        "problem": path.stem,
        "channel": channel,
        "runs": res.verdict.runs,
        "converged": res.success,
        "wall_s": time.perf_counter() - t0,
    }
    for m in METRICS:
        c = comp.get(m)
        out[m] = None if c is None else {"ratio": c.ratio, "outcome": c.outcome}
    return out


def _cell(c: dict | None) -> str:
    return "-" if c is None else f"{c['ratio']:.2f}x {c['outcome']}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    files = args.files or [
        f
        for f in sorted((ROOT / "problems").glob("*.toml"))
        if load_problem(f).beacon_motion.motion != "planned"
    ]
    rows = []
    for f in files:
        for ch in ("ideal", "at-sea"):
            rows.append(_row(f, ch))
            print(f"{f.stem} {ch}: {rows[-1]['wall_s']:.0f} s", file=sys.stderr)
    print(
        "| problem | channel | runs | EKF RMSE vs lawn-mower | EKF final vs lawn-mower | "
        "holds at sea |"
    )
    print("|---|---|---:|---|---|---|")
    missed = []
    for ideal, sea in zip(rows[::2], rows[1::2], strict=True):
        for r in (ideal, sea):
            holds = ""
            if r is sea:
                won = [m for m in METRICS if (ideal[m] or {}).get("outcome") == "better"]
                lost = [m for m in won if (sea[m] or {}).get("outcome") != "better"]
                holds = "yes" if not lost else "no: " + ", ".join(lost)
                if lost:
                    missed.append(f"{r['problem']}: {', '.join(lost)}")
            print(
                f"| {r['problem']} | {r['channel']} | {r['runs']} | "
                f"{_cell(r['ekf.rmse_pos'])} | {_cell(r['ekf.final_pos_err'])} | {holds} |"
            )
    print()
    print("aim (decided ideal wins still decided wins at sea): " + ("met" if not missed else ""))
    for m in missed:
        print(f"- missed: {m}")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
