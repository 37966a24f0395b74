"""The EKF's linearisation stress of a plan and the runs on which the EKF lost track, with and
without ``objective.linearisation_bound``.

Run (minutes per problem):

    MPLBACKEND=Agg python benchmarks/bench_linearisation.py FILE [FILE ...] [--kind KIND]
                                                           [--runs 1000] [--json out.json]

For each problem file (with ``--kind``, its ``objective.kind`` replaced: e.g.
``problems/suite/gramian-offset-beacon.toml --kind gramian-log-det``) the script plans twice as
``obsplan plan`` does (keep-out margins included), with the bound off (``linearisation_bound =
0``) and on (the file's ``linearisation_bound`` if it sets one above 0, else 0.25, whatever
the kind's default), validates both plans and the
baselines over the same ``--runs`` closed-loop runs (one batch, no adaptive runs: rare losses
need many runs), and prints per path: the peak and mean linearisation stress ``b / σ_r``
(:mod:`obsplan.planning.objectives.linearisation`) over the range epochs, the EKF's position RMSE
(the verdict's), the median of its per-run RMSEs, the runs whose RMSE is over 5x that median
("lost"), the worst run, the Gaussian-sum filter's RMSE beside it, and the EKF's mean final
position error. A lost run of a few
percent of the runs decides an RMSE verdict: 50 runs do not see a 1 % loss (0.6 chance).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.baselines.vehicle import baselines  # noqa: E402
from obsplan.planning.objectives.linearisation import linearisation_stress  # noqa: E402
from obsplan.planning.problem.schema import LINEARISATION_BOUND  # noqa: E402
from obsplan.planning.solver.margins import solve_with_keepout  # noqa: E402
from obsplan.planning.validation.validate import validate_paths  # noqa: E402

#: The baselines of the acceptance (validated once: every path flies the same runs).
BASELINES = ("lawnmower", "circle")
#: A run is counted lost when its EKF RMSE is over this multiple of the median run's.
LOST_FACTOR = 5.0


def _row(name: str, traj, v, pb) -> dict:
    f = v.result.filters
    e = np.asarray(f["ekf"].rmse_pos_runs, float)
    med = float(np.median(e))
    b = linearisation_stress(traj, pb)
    return {
        "path": name,
        "stress_max": float(b.max()),
        "stress_mean": float(b.mean()),
        "ekf_rmse": float(f["ekf"].rmse_pos),
        "ekf_final": float(f["ekf"].final_pos_err),
        "ekf_median_run": med,
        "lost": int(np.sum(e > LOST_FACTOR * med)),
        "worst_run": float(e.max()),
        "gsf_rmse": float(f["gsf"].rmse_pos) if "gsf" in f else None,
    }


def run(path: str, kind: str | None, runs: int) -> list[dict]:
    pb = load_problem(path)
    if kind is not None:
        pb = replace(pb, objective=replace(pb.objective, kind=kind))
    rows: list[dict] = []
    base = None
    own = pb.objective.linearisation_bound
    on = own if own is not None and own > 0 else LINEARISATION_BOUND
    for label, bound in (("bound off", 0.0), ("bound on", on)):
        q = replace(pb, objective=replace(pb.objective, linearisation_bound=bound))
        t0 = time.perf_counter()
        res, _ = solve_with_keepout(q)
        wall = time.perf_counter() - t0
        paths = {"planned": res.trajectory}
        if base is None:  # the same runs on every path: the baselines once
            base = {k: b.trajectory for k, b in baselines(pb).items() if k in BASELINES}
            paths.update(base)
        val = validate_paths(paths, q, runs=runs)
        for name, v in val.items():
            r = _row(name, paths[name], v, pb)
            r.update(
                problem=path,
                kind=q.objective.kind,
                plan=label if name == "planned" else "",
                bound=q.objective.resolved_linearisation_bound,
                status=res.status,
                solve_s=wall if name == "planned" else None,
            )
            rows.append(r)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", help="problem files")
    ap.add_argument("--kind", default=None, help="replace objective.kind")
    ap.add_argument("--runs", type=int, default=1000, help="closed-loop runs (default 1000)")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    head = (
        f"{'problem / path':44s} {'b/sr max':>8s} {'mean':>6s} {'EKF rmse':>8s} "
        f"{'median':>7s} {'lost':>5s} {'worst':>7s} {'GSF rmse':>8s} {'EKF final':>9s}"
    )
    out: list[dict] = []
    for f in args.files:
        rows = run(f, args.kind, args.runs)
        out += rows
        print(f"\n{f} ({rows[0]['kind']}, {args.runs} closed-loop runs)")
        print(head)
        for r in rows:
            if r["path"] == "planned":
                name = f"planned, {r['plan']} ({r['bound']:g}), {r['status']}, {r['solve_s']:.0f} s"
            else:
                name = r["path"]
            gsf = "-" if r["gsf_rmse"] is None else f"{r['gsf_rmse']:.3f}"
            print(
                f"{name[:44]:44s} {r['stress_max']:8.3f} {r['stress_mean']:6.3f} "
                f"{r['ekf_rmse']:8.3f} {r['ekf_median_run']:7.3f} {r['lost']:5d} "
                f"{r['worst_run']:7.2f} {gsf:>8s} {r['ekf_final']:9.3f}"
            )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
