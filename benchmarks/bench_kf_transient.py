"""Where a plan's filter verdicts are decided: the predicted position std of the augmented KF and
the EKF's bound (the posterior CRB) along the plan and the baselines, over time.

Run (about 20 s per problem):

    MPLBACKEND=Agg python benchmarks/bench_kf_transient.py FILE [FILE ...] [--kind KIND]
                                                          [--at 30 60 120 240] [--json out.json]

For each problem file (with ``--kind``, its ``objective.kind`` replaced) the script plans as
``obsplan plan`` does (keep-out margins included, no Monte Carlo) and runs, along the plan and
every baseline that fits, the two covariance recursions the planner's estimator objectives use
(:mod:`obsplan.planning.objectives.estimator`: ``kf-position-std``'s augmented KF and
``pcrb-position``'s bound, on the validation's filter samples, prior, process noise, rates and
noises). It prints per path and recursion the std ``sqrt(tr P_pp)`` [m] at the ``--at`` times,
its peak and when, its mission mean (what the RMSE verdicts average) and its final value.

The KF RMSE is a mission average, and the augmented KF's std first *grows* (its range output
informs the position only through the displacement from the start's constant-velocity
extrapolation), so its first minutes can decide that verdict while the EKF's bound, and every
criterion built for the EKF, rate the same minutes better on the plan.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.baselines.vehicle import baselines  # noqa: E402
from obsplan.planning.objectives.estimator import kf_objective, pcrb_objective  # noqa: E402
from obsplan.planning.solver.margins import solve_with_keepout  # noqa: E402
from obsplan.planning.transcription.grid import Grid  # noqa: E402

#: The recursions compared, by label.
RECURSIONS = {"KF": kf_objective, "PCRB": pcrb_objective}


def run(path: str, kind: str | None, at: list[float]) -> list[dict]:
    pb = load_problem(path)
    if kind is not None:
        pb = replace(pb, objective=replace(pb.objective, kind=kind))
    res, _ = solve_with_keepout(pb)
    paths = {"planned": res.trajectory}
    paths.update({k: b.trajectory for k, b in baselines(pb).items()})
    grid = Grid.from_problem(pb)
    t = pb.filter_times - pb.filter_times[0]
    idx = [int(np.argmin(np.abs(t - a))) for a in at]
    rows: list[dict] = []
    for label, build in RECURSIONS.items():
        rec = build(pb)
        for name, traj in paths.items():
            if traj is None:
                continue
            std = rec.std_series(grid, grid.from_trajectory(traj))
            k = int(np.argmax(std))
            rows.append(
                {
                    "problem": path,
                    "kind": pb.objective.kind,
                    "status": res.status,
                    "recursion": label,
                    "path": name,
                    "at_s": [float(t[i]) for i in idx],
                    "std_at": [float(std[i]) for i in idx],
                    "peak": float(std[k]),
                    "peak_s": float(t[k]),
                    "mean": float(np.mean(std)),
                    "final": float(std[-1]),
                }
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", help="problem files")
    ap.add_argument("--kind", default=None, help="replace objective.kind")
    ap.add_argument(
        "--at", type=float, nargs="+", default=[30.0, 60.0, 120.0, 240.0], help="times [s]"
    )
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    out: list[dict] = []
    for f in args.files:
        rows = run(f, args.kind, args.at)
        out += rows
        at = "  ".join(f"{a:>6g}s" for a in rows[0]["at_s"])
        print(f"\n{f} ({rows[0]['kind']}, {rows[0]['status']}): predicted position std [m]")
        print(f"{'recursion / path':24s} {at}  {'peak':>6s} {'at':>6s} {'mean':>6s} {'final':>6s}")
        for r in rows:
            vals = "  ".join(f"{v:7.3f}" for v in r["std_at"])
            print(
                f"{r['recursion'] + ' ' + r['path']:24s} {vals}  {r['peak']:6.3f} "
                f"{r['peak_s']:5.0f}s {r['mean']:6.3f} {r['final']:6.3f}"
            )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
