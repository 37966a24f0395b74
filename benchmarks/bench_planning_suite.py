"""The planner's honest verdict: every shipped problem and the problem suite, planned and validated.

Run (minutes; the full validation Monte Carlo of every path):

    MPLBACKEND=Agg python benchmarks/bench_planning_suite.py [--runs N] [--json out.json] [FILES...]

For each problem (default: ``problems/*.toml`` then ``problems/suite/*.toml``) this runs
``obsplan.plan`` exactly as ``obsplan plan`` does and prints: solver status, solve time, and the
planned path's ratio to the lawn-mower and to the best *fitted* baseline (the lowest value of that
metric among the lawn-mower, circle, straight line and the paper's lawn-mower) of the EKF and KF
position RMSE, the EKF final error and the final posterior CRB, the closest approach to the
beacon, whether the plan beats every baseline on the headline metrics, and the baselines that
could not be fitted, and whether it beats the lawn-mower and the circle on EKF and KF RMSE and
final error (the acceptance of the observability objectives). ``--objective gramian`` keeps the
problems whose objective kind starts with ``gramian``. Medians of the ratios to the lawn-mower
are over ``problems/suite``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.verdict import metric_value  # noqa: E402

#: (column, verdict metric key) of the ratios reported.
RATIOS = (
    ("EKF rmse", "ekf.rmse_pos"),
    ("EKF final", "ekf.final_pos_err"),
    ("KF rmse", "kf.rmse_pos"),
    ("KF final", "kf.final_pos_err"),
    ("bound final", "crlb.final_pos_std"),
)
#: The acceptance of the observability objectives: the plan beats these baselines on these.
ACCEPT_BASELINES = ("lawnmower", "circle")
ACCEPT_METRICS = ("ekf.rmse_pos", "ekf.final_pos_err", "kf.rmse_pos", "kf.final_pos_err")


def run_one(path: Path, runs: int | None) -> dict:
    pb = load_problem(path)
    t0 = time.perf_counter()
    res = plan(pb, runs=runs)
    wall = time.perf_counter() - t0
    row: dict = {
        "problem": str(path.relative_to(ROOT)),
        "objective": f"{pb.objective.kind}"
        + (f"/{pb.objective_mode}" if pb.objective.kind.endswith(("position", "std")) else ""),
        "status": res.solve.status,
        "success": bool(res.success),
        "solve_s": res.solve.wall_s,
        "wall_s": wall,
        "closest_m": res.metrics["planned"].closest_approach_m if res.trajectory else None,
        "beats_all": res.verdict.beats_all,
        "not_fitted": sorted(res.not_fitted),
        "lawnmower": {},
        "best": {},
        "accept": _accepts(res),
        "notes": list(res.verdict.notes),
    }
    v = res.validation
    if "planned" in v:
        for _, key in RATIOS:
            p = metric_value(v["planned"], key)
            base = {k: metric_value(x, key) for k, x in v.items() if k != "planned"}
            lm = base.get("lawnmower")
            finite = [b for b in base.values() if b is not None]
            row["lawnmower"][key] = None if p is None or not lm else p / lm
            row["best"][key] = None if p is None or not finite else p / min(finite)
    return row


def _accepts(res) -> bool:
    """The plan beats the lawn-mower and the circle (where fitted) on EKF and KF RMSE and final
    error."""
    comps = res.verdict.comparisons
    fitted = [b for b in ACCEPT_BASELINES if b in comps]
    return bool(fitted) and all(comps[b][k].better for b in fitted for k in ACCEPT_METRICS)


def fmt(x: float | None) -> str:
    return "   -  " if x is None else f"{x:6.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", help="problem files (default: shipped and suite)")
    ap.add_argument("--runs", type=int, default=None, help="override validation.runs")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument(
        "--objective",
        metavar="PREFIX",
        help="only problems whose objective.kind starts with PREFIX (e.g. gramian, lwo)",
    )
    args = ap.parse_args(argv)
    files = [Path(f).resolve() for f in args.files] or sorted((ROOT / "problems").glob("*.toml"))
    if not args.files:
        files += sorted((ROOT / "problems" / "suite").glob("*.toml"))
    if args.objective:
        files = [f for f in files if load_problem(f).objective.kind.startswith(args.objective)]
    rows = []
    head = (
        f"{'problem':34s} {'objective':34s} {'status':26s} {'solve':>6s}  "
        + "  ".join(f"{c:>13s}" for c, _ in RATIOS)
        + f"  {'closest':>7s}  verdict"
    )
    print("ratios planned/lawn-mower | planned/best baseline")
    print(head)
    print("-" * len(head))
    for f in files:
        r = run_one(f, args.runs)
        rows.append(r)
        cells = "  ".join(
            f"{fmt(r['lawnmower'].get(k))}|{fmt(r['best'].get(k))}" for _, k in RATIOS
        )
        verdict = "beats all" if r["beats_all"] else "LOSES"
        verdict += "; beats lawn-mower+circle on EKF/KF rmse+final" if r["accept"] else ""
        if r["not_fitted"]:
            verdict += f" (not fitted: {', '.join(r['not_fitted'])})"
        closest = "-" if r["closest_m"] is None else f"{r['closest_m']:.1f}"
        print(
            f"{r['problem'][-34:]:34s} {r['objective'][:34]:34s} {r['status'][:26]:26s} "
            f"{r['solve_s']:6.1f}  {cells}  {closest:>7s}  {verdict}",
            flush=True,
        )
        for note in r["notes"]:
            print(f"    {note}", flush=True)
    suite = [r for r in rows if "/suite/" in r["problem"]] or rows
    print()
    print(f"medians over {len(suite)} suite problems, planned / lawn-mower:")
    for col, key in RATIOS:
        vals = [r["lawnmower"][key] for r in suite if r["lawnmower"].get(key) is not None]
        if vals:
            print(f"  {col:12s} {statistics.median(vals):.3f}  (worst {max(vals):.3f})")
    wins = sum(r["beats_all"] and r["success"] for r in rows)
    print(f"solver success and a win on every headline metric: {wins} of {len(rows)} problems")
    acc = sum(r["accept"] for r in rows)
    print(f"beats lawn-mower and circle on EKF/KF RMSE and final error: {acc} of {len(rows)}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
