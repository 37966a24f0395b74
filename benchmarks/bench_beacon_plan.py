"""Planning the beacon: time, convergence and what the plan buys, against holding and circling.

    python benchmarks/bench_beacon_plan.py [--runs N] [--seed S] [--sigma M] [--cases NAMES]

The scenario: the vehicle flies a 4-line lawn-mower (200 m lines, 50 m apart, 1 m/s,
about 1,036 s, sampled every 0.5 s), a range every 10 s of noise ``--sigma`` (0.3 m); the craft
starts from rest at the survey's centre, ``|v| <= 2`` m/s, ``|a_i| <= 0.2`` m/s², at least 5 m
horizontally from the vehicle, within 400 m of it. Cases: 2D and 3D (vehicle 50 m down, craft at
the surface), range only and with a bottom-lock DVL at 1 Hz (3D: and a depth gauge).

For each case :func:`obsplan.planning.beacon.plan_beacon` plans with its default starts (the
table: wall time of the whole planning, the chosen start's iterations and status, the objective
[m²] and its ratio to holding station and to the best circle), against

* ``hold``: the craft holding its start;
* ``circle``: the best of circles about the centre of radius 30, 60, 90 and 120 m, both ways,
  each fitted onto the craft's limits from its start (:func:`~obsplan.planning.beacon
  .flyable_path`), best by the planner's objective;

then the posterior CRB (mean and final position std [m]) and a seeded Monte Carlo of the EKF
(open loop, ``--runs`` runs; ``--ekf-update``, default the second-order update that problem files
use, steadier on close passes) on each: RMSE over time and final error [m], and the
planned path's ratios to the circle's and holding's.
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

from obsplan.estimation.bounds.crlb import posterior_crlb  # noqa: E402
from obsplan.estimation.config import EstimationConfig  # noqa: E402
from obsplan.estimation.montecarlo.simulate import monte_carlo  # noqa: E402
from obsplan.model.beacon import BeaconPath, BeaconVehicle  # noqa: E402
from obsplan.model.vehicle import make_model  # noqa: E402
from obsplan.planning.beacon import beacon_objective, flyable_path, plan_beacon  # noqa: E402
from obsplan.trajectory.generators import lawnmower  # noqa: E402

CASES = {
    "2d-range": (2, ("range",)),
    "2d-dvl": (2, ("range", "dvl-bottom")),
    "3d-range": (3, ("range",)),
    "3d-dvl-depth": (3, ("range", "dvl-bottom", "depth")),
}
CENTRE = (100.0, 75.0)


def setup(dim: int, sensors: tuple[str, ...], sigma: float):
    traj = lawnmower((0.0, 0.0), 200.0, 50.0, 4, 1.0, z=-50.0 if dim == 3 else None).sample(0.5)
    model = make_model(dim=dim, sensors=sensors)
    rates = {s: (0.1 if s == "range" else 1.0) for s in model.sensors}
    cfg = EstimationConfig(model=model, rates_hz=rates, noise={"range": sigma})
    start = list(CENTRE) + ([0.0] if dim == 3 else [])
    craft = BeaconVehicle(
        start=start, speed=2.0, accel=0.2, velocity=[0.0, 0.0], min_distance=5.0, max_range=400.0
    )
    return traj, cfg, craft


def circle(traj, dim: int, radius: float, ccw: bool) -> BeaconPath:
    t = np.append(np.arange(traj.t[0], traj.t[-1], 1.0), traj.t[-1])
    th = (1.0 if ccw else -1.0) * 1.5 / radius * t
    xy = np.column_stack([CENTRE[0] + radius * np.cos(th), CENTRE[1] + radius * np.sin(th)])
    if dim == 3:
        xy = np.column_stack([xy, np.zeros(t.size)])
    return BeaconPath(t, xy)


def best_circle(traj, cfg, craft, dim: int) -> tuple[str, BeaconPath, float]:
    best = ("", None, np.inf)
    for r in (30.0, 60.0, 90.0, 120.0):
        for ccw in (True, False):
            path, ok = flyable_path(traj, craft, circle(traj, dim, r, ccw))
            if not ok:
                continue
            obj = beacon_objective(traj, cfg, path)
            if obj < best[2]:
                best = (f"{r:.0f} m {'ccw' if ccw else 'cw'}", path, obj)
    return best  # type: ignore[return-value]


def ekf(traj, cfg, path: BeaconPath, runs: int, seed: int, update: str):
    cfg = replace(cfg, beacon_path=path, ekf_update=update)
    res = monte_carlo(traj, cfg, runs=runs, seed=seed, filters=("ekf",))
    return res.ekf.rmse_pos, res.ekf.final_pos_err


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sigma", type=float, default=0.3)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--ekf-update", default="second-order", choices=("first-order", "second-order"))
    args = ap.parse_args()
    plan_rows, mc_rows = [], []
    for name in args.cases.split(","):
        dim, sensors = CASES[name]
        traj, cfg, craft = setup(dim, sensors, args.sigma)
        plan = plan_beacon(traj, craft, cfg)
        hold = BeaconPath.fixed(craft.start.tolist(), traj.t[0], traj.t[-1])
        label, circ, circ_obj = best_circle(traj, cfg, craft, dim)
        plan_rows.append(
            f"| {name} | {plan.wall_s:.1f} | {plan.iterations} | {plan.status} | "
            f"{sum(s.success for s in plan.starts)}/{len(plan.starts)} | {plan.objective:.4g} | "
            f"{plan.objective / plan.hold_objective:.2f} | {plan.objective / circ_obj:.2f} "
            f"({label}) |"
        )
        paths = {"planned": plan.path, "circle": circ, "hold": hold}
        crb = {k: posterior_crlb(traj, replace(cfg, beacon_path=p)) for k, p in paths.items()}
        mc = {k: ekf(traj, cfg, p, args.runs, args.seed, args.ekf_update) for k, p in paths.items()}
        for k in paths:
            ratio = (
                f"{mc['planned'][0] / mc[k][0]:.2f} / {mc['planned'][1] / mc[k][1]:.2f}"
                if k != "planned"
                else "-"
            )
            mc_rows.append(
                f"| {name} | {k} | {crb[k].mean_pos_std:.3f} | {crb[k].final_pos_std:.3f} | "
                f"{mc[k][0]:.3f} | {mc[k][1]:.3f} | {ratio} |"
            )
        print(plan.summary(), flush=True)
    print()
    print(
        "| case | wall s | iterations | status | converged starts | objective m^2 | "
        "/ hold | / best circle |"
    )
    print("|---|---:|---:|---|---:|---:|---:|---|")
    print("\n".join(plan_rows))
    print()
    print(
        f"EKF ({args.ekf_update}), {args.runs} runs, seed {args.seed}, sigma_r {args.sigma} m "
        "(open loop)"
    )
    print(
        "| case | beacon | PCRB mean std | PCRB final std | EKF RMSE | EKF final | "
        "planned / this (RMSE / final) |"
    )
    print("|---|---|---:|---:|---:|---:|---|")
    print("\n".join(mc_rows))


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
