"""Missions: every shipped mission problem planned and validated, and the planner's speed on two
surveys.

Run (minutes; the validation Monte Carlo of every path):

    MPLBACKEND=Agg python benchmarks/bench_missions.py [--runs N] [--json out.json] [FILES...]
    MPLBACKEND=Agg python benchmarks/bench_missions.py --speed
    MPLBACKEND=Agg python benchmarks/bench_missions.py --shift 0.2 --mode lines   # variants

Verdict table (default: ``problems/default.toml`` and ``problems/suite/missions/*.toml``): for each
problem, ``obsplan.plan`` exactly as ``obsplan plan`` runs it; the schedule's speed headroom
(``1 - v_c / hi``, :mod:`obsplan.planning.missions.schedule`); whether the plan and each
lawn-mower complete the mission (the independent check, :mod:`obsplan.planning.missions.check`);
and the plan's ratios to the plain lawn-mower (``lm``) and the accelerated one (``acc``) of the
EKF RMSE over the lines' samples, the EKF final error, the KF RMSE and the EKF RMSE. Medians are
over the survey problems whose lines leave at least 30 % speed headroom.

Speed table (``--speed``): the solve (``obsplan.planning.solver.solve``, its default worker
processes) of the default 3-line 2D survey at N = 300 and of the 6-line 3D survey with DVL
(``problems/suite/missions/survey-dvl3d.toml``) at N = 600: status, wall time, CPU time (this
process and the worker processes; the machine is shared, so the wall time depends on the load,
printed beside it), the construction time and each start's IPOPT iterations.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.baselines.vehicle import baselines  # noqa: E402
from obsplan.planning.missions.check import completes_mission  # noqa: E402
from obsplan.planning.missions.schedule import mission_schedule  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.problem.sections import Horizon  # noqa: E402
from obsplan.planning.solver.solve import solve  # noqa: E402
from obsplan.planning.validation.verdict import metric_value  # noqa: E402

#: (column, verdict metric key) of the ratios reported.
RATIOS = (
    ("EKF lines", "ekf.rmse_pos_lines"),
    ("EKF final", "ekf.final_pos_err"),
    ("KF rmse", "kf.rmse_pos"),
    ("EKF rmse", "ekf.rmse_pos"),
)
HEADROOM = 0.3


def run_one(
    path: Path, runs: int | None, shift: float | None = None, mode: str | None = None
) -> dict:
    pb = load_problem(path)
    if shift is not None and pb.mission is not None and pb.mission.lines:
        pb = replace(pb, mission=replace(pb.mission, shift=shift))
    if mode is not None and pb.mission is not None and pb.mission.lines:
        pb = replace(pb, objective=replace(pb.objective, mode=mode))
    res = plan(pb, runs=runs)
    row: dict = {
        "problem": str(path.relative_to(ROOT)),
        "kind": pb.mission.kind if pb.mission else None,
        "lines": len(pb.mission.lines) if pb.mission else 0,
        "headroom": mission_schedule(pb.mission_context).headroom,
        "status": res.solve.status,
        "solve_s": res.solve.wall_s,
        "complete": {k: c.complete for k, c in res.missions.items()},
        "beats_lawnmower": None,
        "ratios": {},
    }
    v = res.validation
    if "planned" in v:
        for base in ("lawnmower", "lawnmower-accel"):
            if base not in v:
                continue
            out = {}
            for _, key in RATIOS:
                p, b = metric_value(v["planned"], key), metric_value(v[base], key)
                out[key] = None if p is None or not b else p / b
            row["ratios"][base] = out
        lm = row["ratios"].get("lawnmower", {})
        keys = ["ekf.final_pos_err", "kf.rmse_pos"] + (
            ["ekf.rmse_pos_lines"] if row["lines"] else []
        )
        row["beats_lawnmower"] = all(lm.get(k) is not None and lm[k] < 1 for k in keys)
    return row


def fmt(x: float | None) -> str:
    return "   -  " if x is None else f"{x:6.2f}"


def verdict_table(rows: list[dict]) -> None:
    cols = " ".join(f"{c:>9} lm {'acc':>5}" for c, _ in RATIOS)
    print(f"{'problem':<44} {'headroom':>8} {'status':<16} {'solve s':>7} {'complete':>9} {cols}")
    for r in rows:
        done = "".join("Y" if r["complete"].get(k) else "n" for k in ("planned", "lawnmower"))
        acc = r["ratios"].get("lawnmower-accel", {})
        lm = r["ratios"].get("lawnmower", {})
        vals = " ".join(f"{fmt(lm.get(k)):>12} {fmt(acc.get(k))}" for _, k in RATIOS)
        print(
            f"{r['problem']:<44} {r['headroom']:8.2f} {r['status']:<16} {r['solve_s']:7.1f} "
            f"{done:>9} {vals}"
        )
    sel = [r for r in rows if r["lines"] and r["headroom"] >= HEADROOM]
    print(f"\nmedians over {len(sel)} surveys with >= {HEADROOM:.0%} speed headroom, planned / lm:")
    for col, key in RATIOS:
        vals = [
            r["ratios"]["lawnmower"][key] for r in sel if r["ratios"].get("lawnmower", {}).get(key)
        ]
        if vals:
            print(f"  {col:<10} {statistics.median(vals):.2f}  (n = {len(vals)})")
    below = [
        r["ratios"]["lawnmower-accel"]["ekf.rmse_pos_lines"] < 1
        for r in sel
        if r["ratios"].get("lawnmower-accel", {}).get("ekf.rmse_pos_lines") is not None
    ]
    print(f"  below the accelerated lawn-mower on EKF lines: {sum(below)} of {len(below)}")
    beats = [r["beats_lawnmower"] for r in rows]
    print(
        f"plan completes the mission on {sum(r['complete'].get('planned', False) for r in rows)}"
        f" of {len(rows)}; beats the plain lawn-mower (EKF lines, EKF final, KF rmse) on "
        f"{sum(bool(b) for b in beats)} of {len(rows)}"
    )


def _cpu_s() -> float:
    """CPU time [s] of this process and of its reaped children (the starts' worker processes)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def speed_table() -> None:
    cases = (
        ("3-line 2D survey", ROOT / "problems" / "default.toml", 300),
        (
            "6-line 3D survey, DVL",
            ROOT / "problems" / "suite" / "missions" / "survey-dvl3d.toml",
            600,
        ),
    )
    print(
        f"{'case':<24} {'N':>5} {'status':<18} {'wall s':>7} {'cpu s':>7} {'build s':>7} "
        f"{'iterations':>10} {'complete':>9} {'load':>5}"
    )
    for name, path, steps in cases:
        pb = load_problem(path)
        pb = replace(pb, horizon=Horizon(pb.horizon.duration, steps))
        bls = baselines(pb)
        load = os.getloadavg()[0]
        c0 = _cpu_s()
        t0 = time.perf_counter()
        res = solve(pb, baselines=bls)
        wall = time.perf_counter() - t0
        cpu = _cpu_s() - c0
        done = res.trajectory is not None and completes_mission(res.trajectory, pb.mission_context)
        iters = "/".join(str(s.iterations) for s in res.starts)
        print(
            f"{name:<24} {steps:5d} {res.status:<18} {wall:7.1f} {cpu:7.1f} {res.build_s:7.1f} "
            f"{iters:>10} {str(done):>9} {load:5.1f}"
        )
    print(
        "wall: the solve (build, then the starts in parallel worker processes); cpu: user + "
        "system time of this process and the workers; load: the 1-minute load average before"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", help="problem files (default: the mission problems)")
    ap.add_argument("--runs", type=int, default=None, help="override validation.runs")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument("--speed", action="store_true", help="the speed table only")
    ap.add_argument(
        "--shift", type=float, default=None, help="override mission.shift of the surveys"
    )
    ap.add_argument(
        "--mode", default=None, help="override objective.mode of the surveys (e.g. lines)"
    )
    args = ap.parse_args(argv)
    if args.speed:
        speed_table()
        return 0
    files = [Path(f).resolve() for f in args.files] or [
        ROOT / "problems" / "default.toml",
        *sorted((ROOT / "problems" / "suite" / "missions").glob("*.toml")),
    ]
    rows = []
    for f in files:
        rows.append(run_one(f, args.runs, args.shift, args.mode))
        print(f"done {f.name}", file=sys.stderr, flush=True)
    verdict_table(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
