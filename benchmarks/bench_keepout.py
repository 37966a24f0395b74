"""Keep-out margins in closed loop: how often the *true* vehicle breaks its limits.

    python benchmarks/bench_keepout.py [--runs 1000] [--problems a.toml b.toml ...] [--cache DIR]

For every problem (default: the shipped ``problems/*.toml`` and ``problems/suite/*.toml``):
the plan without margins (``solve``, ``limits.keepout_confidence = 0``) and with them
(``keep_out`` on that plan, the problem's confidence), then the closed-loop Monte Carlo of both
and of the lawn-mower (guidance on the EKF's estimate,
:func:`obsplan.planning.problem.validation_setup.validation_guidance` with ``at_sea``;
the same seed and runs for every path). Prints a Markdown table: runs whose true path enters
``min_range``, the true closest range over all runs, runs breaking any limit, EKF RMSE and final
error, and the re-solve's rounds, whether the margins held, the largest margin and acceleration
reserve, and its time. ``--cache`` keeps the nominal plans (pickles) between invocations.
"""

from __future__ import annotations

import argparse
import pickle
import time
from dataclasses import replace
from pathlib import Path

from obsplan.estimation.montecarlo.simulate import monte_carlo_paths
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem.validation_setup import (
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.planning.solver.margins import keep_out
from obsplan.planning.solver.solve import solve
from obsplan.trajectory.sampled import resample

ROOT = Path(__file__).resolve().parents[1]


def nominal_plan(pb, path: Path, cache: Path | None):
    file = None if cache is None else cache / f"{path.parent.name}-{path.stem}.pkl"
    if file is not None and file.exists():
        return pickle.loads(file.read_bytes())
    off = replace(pb, limits=replace(pb.limits, keepout_confidence=0.0))
    tr = solve(off, processes=1).trajectory
    if file is not None:
        file.write_bytes(pickle.dumps(tr))
    return tr


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--problems", nargs="*")
    ap.add_argument("--cache", type=Path)
    args = ap.parse_args()
    files = (
        [Path(p) for p in args.problems]
        if args.problems
        else sorted([*ROOT.glob("problems/*.toml"), *ROOT.glob("problems/suite/*.toml")])
    )
    if args.cache:
        args.cache.mkdir(parents=True, exist_ok=True)
    print(f"closed loop, {args.runs} runs, seed {args.seed}\n")
    print(
        "| problem | path | inside min_range | closest [m] | any limit | EKF RMSE [m] | "
        "EKF final [m] | rounds | held | max margin [m] | max reserve | keep-out [s] |"
    )
    print("|" + "---|" * 12)
    for f in files:
        pb = load_problem(f)
        nominal = nominal_plan(pb, f, args.cache)
        if nominal is None:
            print(f"| {f.stem} | no plan | | | | | | | | | | |")
            continue
        t0 = time.perf_counter()
        kept, rep, _ = keep_out(pb, nominal)
        wall = time.perf_counter() - t0
        paths = {"nominal": nominal, "margins": kept, "lawnmower": None}
        bl = baselines(pb)
        if "lawnmower" in bl:
            paths["lawnmower"] = bl["lawnmower"].trajectory
        cfg = estimation_config(pb)
        for name, tr in paths.items():
            if tr is None:
                continue
            (res,) = monte_carlo_paths(
                [resample(tr, pb.validation.dt)],
                cfg,
                runs=args.runs,
                seed=args.seed,
                guidance=validation_guidance(pb, at_sea=True),
                limits=truth_limits(pb),
                filters=("ekf",),
            )
            T = res.truth
            extra = (
                f"{rep.rounds} | {rep.held} | {rep.max_range_margin_m:.2f} | "
                f"{rep.max_accel_reserve:.2f} | {wall:.1f}"
                if name == "margins"
                else " | | | |"
            )
            print(
                f"| {f.stem} | {name} | {T.runs_inside_min_range}/{T.runs} | "
                f"{T.closest_range_m:.3f} | {T.any_violation_fraction:.3f} | "
                f"{res.ekf.rmse_pos:.4f} | {res.ekf.final_pos_err:.4f} | {extra} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
