"""Where and why the EKF the vehicle steers on diverges: the same runs in closed and open loop.

    MPLBACKEND=Agg python benchmarks/bench_closed_loop_divergence.py [PROBLEM.toml] [--runs N]
        [--every S]

Plans the problem as ``obsplan plan`` does (keep-out margins included), then flies the plan ``N``
times four times with the same seeded noise: in closed loop steered on the EKF's estimate, open
loop (the same kernel with zero gains and no speed bound: the planned accelerations flown blind),
as a diagnostic with the same guidance fed the *true* state (``Guidance.on_truth``: the plan's
geometry flown faithfully, the EKF passive), which separates the geometry from the feedback of the
filter's error into the truth, and in closed loop steered on the Gaussian sum's mixture mean
(``validation.navigation = "gsf"``, the default: the EKF passive on the path it flies). Every ``S``
seconds it takes a snapshot of every run and prints, for the runs whose EKF ends more than 1 m off
when steered on it, the median position error and the median error of the velocity across the line
of sight (the direction a range does not see), in closed and open loop, beside the plan's range to
the beacon; then the runs whose EKF ends diverged, inside ``min_range`` and the EKF's errors in
each mode. Default problem: ``problems/suite/short-horizon.toml``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.estimation.montecarlo.closedloop import ClosedLoop  # noqa: E402
from obsplan.estimation.montecarlo.guidance import Guidance  # noqa: E402
from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.problem.validation_setup import (  # noqa: E402
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.planning.solver.margins import solve_with_keepout  # noqa: E402
from obsplan.trajectory.sampled import resample  # noqa: E402

#: A run whose final EKF position error exceeds this [m] counts as diverged.
DIVERGED_M = 1.0


def fly(fine, pb, guidance, runs, every):
    """Snapshots ``(t, estimate, truth)`` every ``every`` s and the final statistics."""
    loop = ClosedLoop(
        fine,
        estimation_config(pb),
        runs=runs,
        seed=pb.validation.seed,
        guidance=guidance,
        limits=truth_limits(pb),
        filters=("ekf",),
    )
    times, est, tru = [], [], []
    for t in np.arange(0.0, fine.t[-1] + 1e-9, every):
        loop.advance(float(fine.t[np.argmin(np.abs(fine.t - t))]))
        s = loop.snapshot()
        times.append(s.t)
        est.append(s.estimate)
        tru.append(s.truth)
    return np.array(times), np.array(est), np.array(tru), loop.result()


def cross_velocity_error(est, tru, beacon, n):
    """|velocity error across the estimated line of sight| [m/s], (T, R)."""
    rel = est[..., :n] - beacon
    los = rel / np.linalg.norm(rel, axis=-1, keepdims=True)
    ev = est[..., n : 2 * n] - tru[..., n : 2 * n]
    along = np.sum(ev * los, axis=-1, keepdims=True)
    return np.linalg.norm(ev - along * los, axis=-1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", nargs="?", default=str(ROOT / "problems/suite/short-horizon.toml"))
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--every", type=float, default=4.0, help="snapshot step [s]")
    args = ap.parse_args(argv)
    pb = load_problem(args.problem)
    t0, c0 = time.perf_counter(), time.process_time()
    res, _ = solve_with_keepout(pb)
    if res.trajectory is None:
        print(f"no plan: {res.status}")
        return 1
    fine = resample(res.trajectory, pb.validation.dt)
    law = validation_guidance(pb, at_sea=True)
    assert law is not None
    closed = replace(law, navigation="ekf")
    blind = Guidance(accel=closed.accel, speed=None, kp=0.0, kd=0.0, navigation="ekf")
    on_truth = replace(closed, on_truth=True)
    on_gsf = replace(law, navigation="gsf")
    n, b = pb.dim, np.asarray(pb.beacon, float)
    t, e_cl, x_cl, r_cl = fly(fine, pb, closed, args.runs, args.every)
    _, e_ol, x_ol, r_ol = fly(fine, pb, blind, args.runs, args.every)
    *_, r_tr = fly(fine, pb, on_truth, args.runs, args.every)
    *_, r_gs = fly(fine, pb, on_gsf, args.runs, args.every)
    err_cl = np.linalg.norm(e_cl[..., :n] - x_cl[..., :n], axis=-1)
    err_ol = np.linalg.norm(e_ol[..., :n] - x_ol[..., :n], axis=-1)
    bad = r_cl.ekf.final_pos_err_runs > DIVERGED_M
    plan_r = np.linalg.norm(
        np.stack([np.interp(t, fine.t, fine.p[:, i]) for i in range(n)], 1) - b, axis=1
    )
    vt_cl = cross_velocity_error(e_cl, x_cl, b, n)
    vt_ol = cross_velocity_error(e_ol, x_ol, b, n)
    print(
        f"{Path(args.problem).name}: {args.runs} runs, {int(bad.sum())} end diverged in closed loop"
    )
    print(
        "| t [s] | plan range [m] | closed: error [m] | closed: cross-LOS vel. error [m/s] "
        "| open: error [m] | open: cross-LOS vel. error [m/s] |"
    )
    print("|---:|---:|---:|---:|---:|---:|")
    if bad.any():
        for j in range(t.size):
            print(
                f"| {t[j]:.0f} | {plan_r[j]:.1f} | {np.median(err_cl[j, bad]):.2f} | "
                f"{np.median(vt_cl[j, bad]):.3f} | {np.median(err_ol[j, bad]):.2f} | "
                f"{np.median(vt_ol[j, bad]):.3f} |"
            )
    print()
    print("| mode | runs diverged | runs inside min_range | EKF RMSE [m] | EKF final [m] |")
    print("|---|---:|---:|---:|---:|")
    modes = (
        ("closed loop, steered on the EKF", r_cl),
        ("open loop", r_ol),
        ("guided on the truth", r_tr),
        ("closed loop, steered on the Gaussian sum", r_gs),
    )
    for name, r in modes:
        print(
            f"| {name} | {int(np.sum(r.ekf.final_pos_err_runs > DIVERGED_M))} | "
            f"{r.truth.runs_inside_min_range} | {r.ekf.rmse_pos:.3f} | {r.ekf.final_pos_err:.3f} |"
        )
    inside = np.flatnonzero(r_cl.truth.closest_range_runs < pb.limits.min_range)
    if inside.size:
        print(
            f"closed-loop runs inside min_range: {inside.tolist()}, diverged: "
            f"{bad[inside].tolist()}, largest error on the way [m]: "
            f"{np.round(err_cl[:, inside].max(axis=0), 1).tolist()}"
        )
    print(f"wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
