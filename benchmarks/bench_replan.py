"""Receding-horizon replanning: re-solve times, and the replanned plan against the one-shot plan.

Run (minutes):

    MPLBACKEND=Agg python benchmarks/bench_replan.py [--problem FILE] [--runs 20] [--every 60]
                                                     [--processes 2] [--json out.json]

The problem defaults to the *median suite problem*: ``problems/suite/*.toml`` sorted by
``(horizon.steps, horizon.duration, file name)``, the middle one (with the 19 suite problems
``gramian-depth3d``: 3D range + depth gauge, 600 s, N = 200, ``gramian-min-eig``; N = 200 is
the size of the speed requirement). The script

1. plans it one-shot as ``obsplan plan`` does (:func:`obsplan.planning.solver.margins
   .solve_with_keepout`) and builds the replanning NLP once (with the plan's keep-out margins);
2. flies the one-shot plan in closed loop (the same runs and seed) and prints, at every replan
   time, the spread over the runs of the navigation filter's position std: what a re-solve
   started from the filter's covariance could adapt to;
3. flies the replanned closed-loop Monte Carlo (:func:`~obsplan.planning.replan
   .replan_monte_carlo`): every ``--every`` s each run re-solves from its navigation filter's
   estimate;
4. prints the re-solve times (wall and CPU: the machine is shared, CPU time is what one solve
   costs on an idle core), iterations and failures, then the EKF/KF errors of the replanned plan,
   the one-shot plan and every baseline (same runs and seed, all in closed loop), the paired
   difference of the EKF final error (replanned - one-shot, with two standard errors), and the
   verdict in words.

``--stress PRIOR RANGE`` flies every run (steps 2-4) in a world the plan was not made for: the
validation's prior std times ``PRIOR`` and its range std times ``RANGE`` (the truth and the
filters, as ``validation.stress_prior`` / ``stress_range_noise`` do), while the one-shot plan, the
replanner's NLP and its keep-out margins stay those of the problem file: what re-solving from the
estimate buys when the run departs from what was planned for. With heavy-tailed errors (an EKF
that lost track) the means decide the verdict, so the script also prints the per-run medians and
how many runs the divergence monitor flagged. ``--told`` builds the replanner (its objective's
noise weights and windows, its keep-out margins) for that world instead: what a replanner that had
learned the condition exactly would re-solve; the one-shot plan stays the problem file's.
``--clairvoyant`` re-solves from each run's true state instead of its estimate (``replan_from=
"truth"``, which no vehicle can do): the most that re-solving from a better-known state could buy
in that world, the bound for any replanner that re-solves the same objective.
``--channel NAME`` sends every run's ranges (steps 2-4) through that acoustic channel
(``validation.channel``, e.g. ``at-sea``: pings lost, late and scaled, the filters gated with
the scale state), again with the problem file's plan and replanner unless ``--told``: the
receding horizon measured where the world departs from the plan.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.estimation.montecarlo.closedloop import ClosedLoop  # noqa: E402
from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.baselines.vehicle import baselines  # noqa: E402
from obsplan.planning.objectives.robust import scaled_problem  # noqa: E402
from obsplan.planning.problem.validation_setup import estimation_config, truth_limits  # noqa: E402
from obsplan.planning.replan import (  # noqa: E402
    Replanner,
    replan_guidance,
    replan_monte_carlo,
    replan_nodes,
)
from obsplan.planning.solver.margins import solve_with_keepout  # noqa: E402
from obsplan.planning.validation.verdict import metric_value, paired_noise  # noqa: E402
from obsplan.trajectory.sampled import resample  # noqa: E402

COLUMNS = (
    ("EKF rmse", "ekf.rmse_pos"),
    ("EKF final", "ekf.final_pos_err"),
    ("KF rmse", "kf.rmse_pos"),
    ("KF final", "kf.final_pos_err"),
)


def median_suite_problem() -> Path:
    """The middle of ``problems/suite`` sorted by (steps, duration, name)."""
    files = sorted((ROOT / "problems" / "suite").glob("*.toml"))
    keyed = []
    for f in files:
        pb = load_problem(f)
        keyed.append((pb.horizon.steps, pb.horizon.duration, f.name, f))
    keyed.sort()
    return keyed[len(keyed) // 2][3]


def covariance_spread(pb, plan, every: float, runs: int) -> list[tuple[float, ...]]:
    """What a re-solve could learn from the filter: at every replan time, the spread over the
    one-shot plan's closed-loop runs of the navigation filter's position std ``sqrt(tr P_pp)``
    (median, 10th and 90th percentiles) and the RMS of its true position error."""
    val = pb.validation
    loop = ClosedLoop(
        resample(plan, val.dt),
        estimation_config(pb),
        runs,
        val.seed,
        0,
        guidance=replan_guidance(pb),
        limits=truth_limits(pb),
    )
    n, rows = pb.dim, []
    for k in replan_nodes(pb, every):
        t = float(k) * pb.horizon.dt
        loop.advance(t)
        snap = loop.snapshot()
        std = np.sqrt(np.trace(snap.covariance[:, :n, :n], axis1=1, axis2=2))
        err = np.linalg.norm(snap.estimate[:, :n] - snap.truth[:, :n], axis=1)
        rows.append((t, _q(std, 0.5), _q(std, 0.1), _q(std, 0.9), float(np.sqrt(np.mean(err**2)))))
    return rows


def _q(x: np.ndarray, q: float) -> float:
    return float(np.quantile(x, q)) if x.size else float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", type=Path, default=None)
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--every", type=float, default=60.0)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument(
        "--stress",
        type=float,
        nargs=2,
        metavar=("PRIOR", "RANGE"),
        default=(1.0, 1.0),
        help="fly the runs with the prior std and the range std times these (module docstring)",
    )
    ap.add_argument(
        "--told",
        action="store_true",
        help="with --stress: the replanner is built for the stressed world (module docstring)",
    )
    ap.add_argument(
        "--channel",
        default=None,
        help="fly the runs' ranges through this acoustic channel (module docstring)",
    )
    ap.add_argument(
        "--clairvoyant",
        action="store_true",
        help="re-solve from each run's true state, not its estimate (module docstring)",
    )
    args = ap.parse_args()
    if args.told and tuple(args.stress) == (1.0, 1.0) and args.channel is None:
        ap.error("--told needs --stress PRIOR RANGE or --channel (a world other than the file's)")
    path = args.problem or median_suite_problem()
    pb = load_problem(path)
    world = scaled_problem(pb, *args.stress) if tuple(args.stress) != (1.0, 1.0) else pb
    if args.channel is not None:
        world = world.with_changes(validation={"channel": args.channel})
    print(
        f"problem {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: "
        f"{pb.dim}D {'+'.join(pb.vehicle.sensors)}, {pb.horizon.duration:g} s, "
        f"N = {pb.horizon.steps}, objective {pb.objective.kind}; runs {args.runs}, "
        f"replan every {args.every:g} s; load average {os.getloadavg()[0]:.1f} "
        f"on {os.cpu_count()} cores"
    )
    if world is not pb:
        channel = world.validation.channel_model()
        print(
            f"stress: the runs fly with the prior std x{args.stress[0]:g}, the range std "
            f"x{args.stress[1]:g} and the channel {channel.name} ({channel.describe()}); the "
            "plan is the problem file's, the replanner "
            + ("is built for that world" if args.told else "the problem file's")
        )
    if args.clairvoyant:
        print("clairvoyant: every re-solve starts from the run's true state (no vehicle can)")
    t0 = time.perf_counter()
    bls = baselines(pb)
    res, _ = solve_with_keepout(pb, baselines=bls, processes=args.processes)  # as `obsplan plan`
    print(f"one-shot solve: {res.status}, {time.perf_counter() - t0:.1f} s wall")
    if res.trajectory is None:
        print("no one-shot plan: nothing to replan")
        return 1
    spread = covariance_spread(world, res.trajectory, args.every, args.runs)
    print()
    print("what a re-solve could learn: the navigation filter's position std over the one-shot")
    print("plan's closed-loop runs at each replan time (a covariance-started re-solve adapts only")
    print("to how much it varies from run to run)")
    print(f"{'t [s]':>8} {'median [m]':>11} {'p10':>8} {'p90':>8} {'p90/p10':>8} {'err rms':>8}")
    for t, med, lo, hi, rms in spread:
        print(f"{t:>8.0f} {med:>11.4f} {lo:>8.4f} {hi:>8.4f} {hi / lo:>8.3f} {rms:>8.4f}")
    rp = Replanner(world if args.told else pb, plan=res.trajectory)
    out = replan_monte_carlo(
        world,
        res.trajectory,
        args.every,
        baselines={k: b.trajectory for k, b in bls.items()},
        runs=args.runs,
        processes=args.processes,
        replanner=rp,
        replan_from="truth" if args.clairvoyant else "estimate",
    )
    wall, cpu = out.solve_times(), out.solve_times(cpu=True)
    iters = np.array([s.iterations for s in out.solves], float)
    print()
    print(f"{'re-solves':<22} {'median':>8} {'p90':>8} {'max':>8}")
    print(f"{'wall [s]':<22} {_q(wall, 0.5):>8.3f} {_q(wall, 0.9):>8.3f} {wall.max():>8.3f}")
    print(f"{'CPU [s]':<22} {_q(cpu, 0.5):>8.3f} {_q(cpu, 0.9):>8.3f} {cpu.max():>8.3f}")
    it = (_q(iters, 0.5), _q(iters, 0.9), iters.max())
    print(f"{'IPOPT iterations':<22} {it[0]:>8.0f} {it[1]:>8.0f} {it[2]:>8.0f}")
    kept = sum(s.kept_warm_start for s in out.solves)
    print(
        f"{len(out.solves)} re-solves, {out.failures} failed (plan in force kept), "
        f"{kept} kept the warm start, {out.unconverged_flown} flown unconverged (iteration "
        f"budget); NLP + solver built once in {out.build_s:.2f} s; "
        f"replanned Monte Carlo {out.wall_s:.1f} s"
    )
    statuses: dict[str, int] = {}
    for s in out.solves:
        statuses[s.status] = statuses.get(s.status, 0) + 1
    print("statuses:", ", ".join(f"{k} {v}" for k, v in sorted(statuses.items())))
    print()
    head = f"{'path':<12}" + "".join(f" {c:>10}" for c, _ in COLUMNS) + f" {'closest':>8}"
    print(head)
    print("-" * len(head))
    for name, v in out.validation.items():
        vals = [metric_value(v, key) for _, key in COLUMNS]
        truth = v.result.truth
        closest = float(np.min(truth.closest_range_runs)) if truth is not None else float("nan")
        cells = "".join(f" {'-' if x is None else format(x, '.4g'):>10}" for x in vals)
        print(f"{name:<12}{cells} {closest:>8.2f}")
    print()
    print("per run (the means above weigh every run; an EKF that lost track dominates them):")
    print(f"{'path':<12} {'EKF final median':>17} {'EKF flagged runs':>17}  worst 3 EKF final")
    for name, v in out.validation.items():
        ekf = v.result.ekf
        if ekf is not None:
            med = float(np.median(ekf.final_pos_err_runs))
            worst = ", ".join(f"{x:.3g}" for x in np.sort(ekf.final_pos_err_runs)[-3:])
            print(f"{name:<12} {med:>17.4g} {ekf.flagged_runs:>17d}  {worst}")
    ra = out.validation["replanned"].result.ekf
    rb = out.validation["one-shot"].result.ekf
    if ra is not None and rb is not None:
        better = float(np.mean(ra.final_pos_err_runs < rb.final_pos_err_runs))
        print(f"replanned EKF final error below the one-shot's in {100 * better:.1f} % of the runs")
    a, b = out.validation["replanned"], out.validation["one-shot"]
    ea, eb = metric_value(a, "ekf.final_pos_err"), metric_value(b, "ekf.final_pos_err")
    noise = paired_noise(a, b, "ekf.final_pos_err")
    verdict = out.verdict  # a property that bootstraps every comparison: once
    print()
    if ea is not None and eb is not None:
        # the word comes from the verdict's interval, not the sign of the difference
        outcome = verdict.comparisons["one-shot"]["ekf.final_pos_err"].outcome
        word = {
            "better": "beats",
            "worse": "does NOT beat",
            "tie": "ties (within the Monte Carlo noise) with",
        }[outcome]
        print(
            f"EKF final error: replanned {ea:.4g} m vs one-shot {eb:.4g} m "
            f"(ratio {ea / eb:.3f}, paired difference {ea - eb:+.3g} m, two standard errors "
            f"{'-' if noise is None else format(noise, '.2g')} m): replanning {word} the "
            "one-shot plan"
        )
    for line in verdict.summary():
        print(line)
    if args.json is not None:
        doc = {
            "problem": str(path),
            "runs": args.runs,
            "stress": {
                "prior": args.stress[0],
                "range_noise": args.stress[1],
                "replanner_told": bool(args.told),
            },
            "replan_from": "truth" if args.clairvoyant else "estimate",
            **out.to_dict(),
        }
        args.json.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
