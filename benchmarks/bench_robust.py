"""Robust planning under mismatch: the nominal and the robust plan met with a wider prior and a
noisier range than planned for.

Run (minutes):

    MPLBACKEND=Agg python benchmarks/bench_robust.py [FILES...] [--prior 5] [--range-noise 3]
                                                     [--runs N] [--json out.json]

For every problem (default: the shipped single problems, ``problems/*.toml``, whose objective is
an estimator objective, the only kinds robust planning applies to) it plans twice as
``obsplan plan`` does — nominal, and robust (``objective.robust_prior = [1, PRIOR]``,
``robust_range_noise = [1, RANGE_NOISE]``, ``robust_aggregate = "worst"``) — and re-validates
every path of each plan, without replanning, with the prior std times ``PRIOR`` and the range
std times ``RANGE_NOISE`` (the report's robustness row, ``validation.stress_prior`` /
``stress_range_noise``). It prints, per problem and plan, the planned / lawn-mower ratios of the
EKF RMSE and final error under the mismatch with their verdicts (``B`` better, ``W`` worse,
decided at 95 %; ``t`` a tie), and whether the robust plan beats the lawn-mower on both where
the nominal plan did.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.problem.schema import TIMED_OBJECTIVES  # noqa: E402

METRICS = (("EKF rmse", "ekf.rmse_pos"), ("EKF final", "ekf.final_pos_err"))
LETTER = {"better": "B", "worse": "W", "tie": "t"}


def stressed(path: Path, prior: float, noise: float, robust: bool, runs: int | None):
    """The plan of ``path`` (robust or nominal) and its robustness row under the mismatch."""
    pb = load_problem(path)
    val = replace(pb.validation, stress_prior=prior, stress_range_noise=noise)
    obj = pb.objective
    if robust:
        obj = replace(
            obj,
            robust_prior=(1.0, prior),
            robust_range_noise=(1.0, noise),
            robust_aggregate="worst",
        )
    pb = replace(pb, validation=val, objective=obj)
    t0 = time.perf_counter()
    res = plan(pb, runs=runs)
    wall = time.perf_counter() - t0
    assert res.robustness is not None
    verdict = res.robustness.to_dict()["verdict"]["baselines"]["lawnmower"]
    row = {"status": res.solve.status, "wall_s": wall}
    for _, key in METRICS:
        v = verdict[key]
        row[key] = {"ratio": v["ratio"], "outcome": v["outcome"]}
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", help="problem files (default: the shipped single ones)")
    ap.add_argument("--prior", type=float, default=5.0, help="multiple of the prior std")
    ap.add_argument("--range-noise", type=float, default=3.0, help="multiple of the range std")
    ap.add_argument("--runs", type=int, default=None, help="override validation.runs")
    ap.add_argument("--json", default=None, help="also write the rows as JSON")
    args = ap.parse_args(argv)
    files = [Path(f) for f in args.files] or sorted((ROOT / "problems").glob("*.toml"))
    files = [f for f in files if load_problem(f).objective.kind in TIMED_OBJECTIVES]
    rows = []
    print(
        f"mismatch: prior x{args.prior:g}, range noise x{args.range_noise:g}; planned / "
        "lawn-mower (verdict)"
    )
    head = f"{'problem':34} {'plan':8} {'status':18} {'wall s':>7}"
    for name, _ in METRICS:
        head += f" {name:>14}"
    print(head)
    for f in files:
        out = {"problem": str(f.relative_to(ROOT) if f.is_absolute() else f)}
        for robust in (False, True):
            r = stressed(f, args.prior, args.range_noise, robust, args.runs)
            out["robust" if robust else "nominal"] = r
            line = f"{f.name:34} {'robust' if robust else 'nominal':8} {r['status']:18} "
            line += f"{r['wall_s']:7.0f}"
            for _, key in METRICS:
                line += f" {r[key]['ratio']:9.2f} ({LETTER.get(r[key]['outcome'], '?')})"
            print(line, flush=True)
        nom_wins = all(out["nominal"][k]["outcome"] == "better" for _, k in METRICS)
        rob_wins = all(out["robust"][k]["outcome"] == "better" for _, k in METRICS)
        out["nominal_wins"], out["robust_wins"] = nom_wins, rob_wins
        rows.append(out)
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    need = [r for r in rows if r["nominal_wins"]]
    print()
    print(
        f"robust plan beats the lawn-mower on both under the mismatch: "
        f"{sum(r['robust_wins'] for r in rows)} of {len(rows)} problems; where the nominal plan "
        f"did: {sum(r['robust_wins'] for r in need)} of {len(need)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
