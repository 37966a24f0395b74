"""The planned beacon's verdict against every beacon baseline, on the shipped ASV problems and
variants the planner was not tuned on.

    python benchmarks/bench_beacon_verdict.py [--cases NAMES] [--runs N] [--max-runs M]
                                              [--no-validate]

Each case is a problem with ``beacon.motion = "planned"`` flown by ``obsplan plan``'s flow
(:func:`obsplan.planning.plan.plan_moving_beacon` with
:func:`obsplan.planning.beacon.plan_beacon`): the baselines, the planner, the bounds, then the
closed-loop Monte Carlo in batches until every verdict is decided at 95 % or ``--max-runs``.

Cases (:data:`CASES`): the shipped ``asv-survey`` (2D) and ``asv-survey3d`` (3D, depth gauge),
and variants made from them: other survey sizes and spacings, the craft starting off the
survey's centre, a ping every 20 or 30 s, a range noise of 1 m.

Printed per case: the flow's planning time [s] (baselines, planner and bounds: not the
validation) and the planner's; the posterior CRB of the position (std [m], mean over the lines
and at the end) with the planned beacon and with the circle, and with ``--floor`` the least
final std any path of the craft gives (the planner's optimum of the final term alone: nan
without); then per baseline the ratios
planned / baseline of the EKF's RMSE over the lines and of its final error, each with its
95 % interval and ``better`` / ``worse`` (decided) or ``tie``; the planned EKF's NEES (mean
and its 95 % band, and the fraction of epochs inside it); and the acceptance's medians over
the cases, per metric: the ratio to the best of ``beacon-fixed``, ``-circle``, ``-trail`` and
``-greedy``, and to ``beacon-fixed``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning.beacon import plan_beacon  # noqa: E402
from obsplan.planning.beacon.recursion import RangeRecursion  # noqa: E402
from obsplan.planning.plan import plan_moving_beacon  # noqa: E402
from obsplan.planning.problem.parse import load_problem  # noqa: E402


def _lines(n: int, length: float, spacing: float, z: float | None) -> list[list[float]]:
    """``n`` lines of ``length`` m, ``spacing`` m apart, centred on the origin, alternating."""
    out = []
    for i in range(n):
        y = (0.5 * (n - 1) - i) * spacing
        a, b = (-0.5 * length, 0.5 * length)[:: 1 if i % 2 == 0 else -1]
        out.append([a, y, b, y] if z is None else [a, y, z, b, y, z])
    return out


def _survey(n: int, length: float, spacing: float, dim: int, duration: float) -> dict:
    z = 30.0 if dim == 3 else None
    start = [-0.5 * length - 20.0, 0.5 * (n - 1) * spacing] + ([30.0] if dim == 3 else [])
    return {
        "mission": {"lines": _lines(n, length, spacing, z)},
        "start": {"position": start},
        "horizon": {"duration": duration, "steps": int(duration / 5.0)},
    }


#: name -> (shipped problem, changes for :meth:`PlanningProblem.with_changes`).
CASES: dict[str, tuple[str, dict]] = {
    "asv-survey": ("asv-survey", {}),
    "asv-survey3d": ("asv-survey3d", {}),
    # 3 lines 300 m long and 80 m apart; the craft starts 120 m off the centre
    "wide-offcentre": (
        "asv-survey",
        {**_survey(3, 300.0, 80.0, 2, 1400.0), "beacon": {"position": [120.0, 90.0]}},
    ),
    # the shipped 2D survey with a ping every 20 s and 1 m of range noise
    "ping20-sigma1": ("asv-survey", {"validation": {"range_rate": 0.05, "range_std": 1.0}}),
    # 3D: 5 lines 150 m long, 30 m apart, a ping every 30 s, the craft starting off a corner
    "3d-ping30-corner": (
        "asv-survey3d",
        {
            **_survey(5, 150.0, 30.0, 3, 1500.0),
            "beacon": {"position": [-90.0, -70.0, 0.0]},
            "validation": {"range_rate": 1.0 / 30.0},
        },
    ),
}
METRICS = (("ekf.rmse_pos_lines", "RMSE lines"), ("ekf.final_pos_err", "final"))
OPERATOR = ("beacon-fixed", "beacon-circle", "beacon-trail", "beacon-greedy")


def final_floor(pb) -> float:
    """The least final position std [m] of the vehicle any path of the craft gives (on the
    planner's optimum of the final term alone: this script swaps the recursion's objective
    for its final term, from the same starts)."""
    original = RangeRecursion.objective

    def final_only(self, B, weights):
        return self.terms(B, weights)[1]

    RangeRecursion.objective = final_only  # type: ignore[method-assign]
    try:
        res = plan_moving_beacon(pb, plan_beacon, validate=False)
    finally:
        RangeRecursion.objective = original  # type: ignore[method-assign]
    return res.bounds["planned"].final_pos_std


def run_case(name: str, args) -> dict:
    base, changes = CASES[name]
    pb = load_problem(base)
    if changes:
        pb = pb.with_changes(**changes)
    if args.max_runs is not None:
        pb = pb.with_changes(validation={"max_runs": args.max_runs})
    t0 = time.perf_counter()
    res = plan_moving_beacon(pb, plan_beacon, validate=not args.no_validate, runs=args.runs)
    wall = time.perf_counter() - t0
    floor = final_floor(pb) if args.floor else float("nan")
    return {"name": name, "result": res, "wall": wall, "floor": floor}


def _cell(c) -> str:
    if c is None or c.ratio is None:
        return "-"
    ci = "" if c.ci is None else f" [{c.ci[0]:.2f}, {c.ci[1]:.2f}]"
    return f"{c.ratio:.2f}{ci} {c.outcome}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--runs", type=int, default=None, help="first batch (problem's default)")
    ap.add_argument("--max-runs", type=int, default=None, help="cap (problem's default)")
    ap.add_argument("--no-validate", action="store_true", help="planning and bounds only")
    ap.add_argument(
        "--floor", action="store_true", help="also the final bound's floor (plans again)"
    )
    args = ap.parse_args()
    rows, verdicts, medians = [], [], {m: ([], []) for m, _ in METRICS}
    for name in args.cases.split(","):
        out = run_case(name, args)
        res = out["result"]
        b = res.bounds
        rows.append(
            f"| {name} | {res.planning_s:.1f} | {res.solve.wall_s:.1f} | "
            f"{len(res.solve.starts)} | {res.solve.status} | {b['planned'].lines_pos_std:.3f} | "
            f"{b['beacon-circle'].lines_pos_std:.3f} | {b['planned'].final_pos_std:.3f} | "
            f"{b['beacon-circle'].final_pos_std:.3f} | {out['floor']:.3f} |"
        )
        print(f"{name}: {out['wall']:.0f} s in all", flush=True)
        if args.no_validate:
            continue
        comps = res.verdict.comparisons
        runs = res.verdict.runs
        ekf = res.validation["planned"].result.ekf
        for bl, cs in comps.items():
            verdicts.append(
                f"| {name} | {runs} | {bl} | "
                + " | ".join(_cell(cs.get(m)) for m, _ in METRICS)
                + " |"
            )
        verdicts.append(
            f"| {name} | {runs} | planned EKF NEES | mean {ekf.nees_mean:.2f} in "
            f"[{ekf.nees_bounds[0]:.2f}, {ekf.nees_bounds[1]:.2f}] | "
            f"{ekf.nees_inside_fraction:.0%} of epochs inside |"
        )
        for m, _ in METRICS:
            r = {bl: comps[bl][m].ratio for bl in OPERATOR if bl in comps and m in comps[bl]}
            r = {k: v for k, v in r.items() if v is not None}
            if r:
                medians[m][0].append(max(r.values()))  # against the best: the largest ratio
                if "beacon-fixed" in r:
                    medians[m][1].append(r["beacon-fixed"])
    print()
    print(
        "| case | flow planning s | planner s | starts | status | PCRB lines planned | "
        "circle | PCRB final planned | circle | floor |"
    )
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    print("\n".join(rows))
    if args.no_validate:
        return
    print()
    print("planned / baseline, EKF (closed loop), 95 % interval and outcome")
    print("| case | runs | baseline | " + " | ".join(t for _, t in METRICS) + " |")
    print("|---|---:|---|---|---|")
    print("\n".join(verdicts))
    print()
    print("| metric | median ratio to the best operator path | median ratio to beacon-fixed |")
    print("|---|---:|---:|")
    for m, title in METRICS:
        best, fixed = medians[m]
        if best:
            print(f"| {title} | {statistics.median(best):.2f} | {statistics.median(fixed):.2f} |")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
