"""Per-step cost of the filters and wall time of a Monte Carlo (prints Markdown tables).

    python benchmarks/bench_filters.py [--runs 100] [--steps 2000] [--mc-steps 60000]

Problem: the paper's 2D circle (Fig. 2), range only, 100 Hz, paper's R/Q/P0. One "filter step" is
one update with the range plus one prediction. Implementations:

* filterpy: ``KalmanFilter`` (augmented KF) / ``ExtendedKalmanFilter``, one object per run, a
  Python loop over runs (its update uses the Joseph form too);
* plain loop: obsplan's filters with a batch of one run, a Python loop over runs;
* batched: obsplan's filters on all runs at once (what ``monte_carlo`` does).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter as FpEKF
from filterpy.kalman import KalmanFilter as FpKF

from obsplan import generators as gen
from obsplan.estimation import EstimationConfig, monte_carlo
from obsplan.estimation.config import paper_covariances
from obsplan.estimation.ekf import ExtendedKalmanFilter
from obsplan.estimation.kf import AugmentedKalmanFilter, input_displacement
from obsplan.estimation.sensors import output_model, to_outputs
from obsplan.model import make_model


def _setup(steps: int, runs: int):
    traj = gen.circle(51.0, 2.6, steps * 0.01, 0.01, center=(0.0, 2.0))
    model = make_model(2, "range")
    cov = paper_covariances(model, 0.01)
    rng = np.random.default_rng(0)
    r = np.linalg.norm(traj.p, axis=1)[:, None] + 0.1 * rng.standard_normal((traj.n_samples, runs))
    x0 = np.hstack([traj.p[0], traj.v[0]]) + rng.normal(0, 0.5, (runs, 4))
    return traj, model, cov, r, x0


def bench_filterpy(traj, model, cov, r, x0, runs):
    noise = {"range": 0.1}
    out = output_model(model)
    F, G = model.transition(0.01)
    d = input_displacement(traj)
    kf_obj = AugmentedKalmanFilter(model, traj, cov["q_kf"], noise, "inflate")
    N = traj.n_samples
    t_ekf = t_kf = 0.0
    for j in range(runs):
        e = FpEKF(dim_x=4, dim_z=1, dim_u=2)
        e.x, e.P, e.Q, e.F, e.B = x0[j].copy(), cov["p0_ekf"].copy(), cov["q_ekf"], F, G
        t0 = time.perf_counter()
        for k in range(N):
            y, var = to_outputs(model, {"range": r[k, j : j + 1, None]}, noise)
            e.update(
                y[0],
                lambda x: out.evaluate(x[None])[1][0],
                lambda x: out.evaluate(x[None])[0][0],
                R=var,
            )
            e.predict(u=traj.u[k])
        t_ekf += time.perf_counter() - t0
        st = kf_obj.init(x0[j : j + 1], cov["p0_kf"], r[0, j : j + 1])
        f = FpKF(dim_x=6, dim_z=1, dim_u=2)
        f.x, f.P, f.Q = st.z[0].copy(), st.P[0].copy(), cov["q_kf"]
        f.F, f.B = np.eye(6) + kf_obj._A * 0.01, kf_obj._B * 0.01 + kf_obj._A @ kf_obj._B * 5e-5
        t0 = time.perf_counter()
        for k in range(N):
            if k:
                C = kf_obj.aug.output_matrix(d[k], traj.t[k])[:1]
                rr = r[k, j]
                yb = 0.5 * rr**2 - 0.005 - st.y0[0] + 0.5 * d[k] @ d[k]
                f.update(np.array([yb]), R=np.array([[rr**2 * 0.01 + st.var0[0]]]), H=C)
            f.predict(u=traj.u[k])
        t_kf += time.perf_counter() - t0
    return t_ekf / (N * runs) * 1e6, t_kf / (N * runs) * 1e6


def bench_ours(traj, model, cov, r, x0, batch: int, runs: int):
    noise = {"range": 0.1}
    ekf = ExtendedKalmanFilter(model, traj, cov["q_ekf"], noise)
    kf = AugmentedKalmanFilter(model, traj, cov["q_kf"], noise, "inflate")
    N = traj.n_samples
    t_ekf = t_kf = 0.0
    for j0 in range(0, runs, batch):
        sl = slice(j0, j0 + batch)
        st = ekf.init(x0[sl], cov["p0_ekf"])
        t0 = time.perf_counter()
        for k in range(N):
            st = ekf.update(st, {"range": r[k, sl, None]})
            st = ekf.predict(st, k) if k < N - 1 else st
        t_ekf += time.perf_counter() - t0
        sk = kf.init(x0[sl], cov["p0_kf"], r[0, sl])
        t0 = time.perf_counter()
        for k in range(N):
            sk = kf.update(sk, k, {"range": r[k, sl, None]})
            sk = kf.predict(sk, k) if k < N - 1 else sk
        t_kf += time.perf_counter() - t0
    return t_ekf / (N * runs) * 1e6, t_kf / (N * runs) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--loop-runs", type=int, default=5, help="runs timed for the loop variants")
    ap.add_argument("--mc-steps", type=int, default=60000)
    ap.add_argument("--mc-runs", type=int, default=100)
    a = ap.parse_args()
    traj, model, cov, r, x0 = _setup(a.steps, a.runs)
    fp = bench_filterpy(traj, model, cov, r, x0, a.loop_runs)
    loop = bench_ours(traj, model, cov, r, x0, 1, a.loop_runs)
    bat = bench_ours(traj, model, cov, r, x0, a.runs, a.runs)
    print(
        f"\nµs per filter step per run (2D range-only circle, {a.steps} steps; batched over "
        f"{a.runs} runs)\n"
    )
    print("| implementation | EKF | KF (augmented) |")
    print("|---|---:|---:|")
    for name, (e, k) in (
        ("filterpy, loop over runs", fp),
        ("obsplan, plain loop", loop),
        (f"obsplan, batched ({a.runs} runs)", bat),
    ):
        print(f"| {name} | {e:.1f} | {k:.1f} |")
    for label, sensors, dim in (("2D range only", "range", 2), ("3D range + DVL", "range,dvl", 3)):
        if dim == 2:
            tr = gen.circle(51.0, 2.6, a.mc_steps * 0.01, 0.01, center=(0.0, 2.0))
        else:
            tr = gen.circle_z(50.0, 2.6, a.mc_steps * 0.01, 0.01, z0=5.0, z_amp=2.0, z_period=60.0)
        cfg = EstimationConfig.paper(make_model(dim, sensors), 0.01)
        t0 = time.perf_counter()
        res = monte_carlo(tr, cfg, runs=a.mc_runs, seed=0)
        wall = time.perf_counter() - t0
        print(
            f"\nMonte Carlo, {label}: {a.mc_runs} runs x {tr.n_samples - 1} steps, both filters "
            f"+ truth + CRB: {wall:.1f} s wall ({wall / (tr.n_samples * a.mc_runs) * 1e6:.1f} "
            f"µs per step per run); EKF final error {res.ekf.final_pos_err:.3f} m, KF "
            f"{res.kf.final_pos_err:.3f} m"
        )


if __name__ == "__main__":
    main()
