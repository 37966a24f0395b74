"""Per-step cost of the filters against plain filterpy loops doing the same work (Markdown).

    python benchmarks/bench_filters.py [--steps 6000] [--runs 20] [--fp-runs 3]

Problem: the paper's 2D circle (Fig. 2), range at every 0.01 s step (the paper's configuration),
paper's R/Q/P0. One "filter step" is one prediction and one range update. Implementations:

* filterpy 2.0, one object per run and a Python loop over steps, with its own ``h(x)`` and
  Jacobian written in plain numpy (nothing from obsplan): ``ExtendedKalmanFilter`` on
  ``(p, v)``; ``KalmanFilter`` on the paper's augmented state with the anchor and the
  process-noise coupling ``(e, f, g)`` of ``obsplan.estimation.filters.kf`` (its per-step ``Q``
  built in numpy from the predicted state), the same model obsplan's KF runs;
* obsplan's compiled filters (``ExtendedKalmanFilter.run`` etc.) on the same readings, the runs
  batched in one call as in ``monte_carlo``, statistics at ~1000 records included;
* obsplan's whole ``monte_carlo`` (truth, readings, both filters, bound) per run-step.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter as FpEKF
from filterpy.kalman import KalmanFilter as FpKF

from obsplan.estimation import EstimationConfig, monte_carlo
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.epochs import RunContext, epoch_plan, input_displacement, record_samples
from obsplan.estimation.montecarlo.simulate import make_filter
from obsplan.estimation.schedule import make_schedule
from obsplan.model.vehicle import make_model
from obsplan.trajectory import generators as gen

SIG = 0.1


def setup(steps: int, runs: int):
    traj = gen.circle(51.0, 2.6, steps * 0.01, center=(0.0, 2.0)).sample(0.01)
    cfg = EstimationConfig.paper(make_model(2, "range"), 0.01)
    cov = cfg.covariances(0.01)
    rng = np.random.default_rng(0)
    r = np.linalg.norm(traj.p, axis=1)[:, None] + SIG * rng.standard_normal((traj.n_samples, runs))
    x0 = np.hstack([traj.p[0], traj.v[0]]) + rng.normal(0, 0.5, (runs, 4))
    return traj, cfg, cov, r, x0


def filterpy_ekf(traj, cov, r, x0, runs) -> float:
    h = 0.01
    F = np.array([[1, 0, h, 0], [0, 1, 0, h], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    B = np.array([[0.5 * h * h, 0], [0, 0.5 * h * h], [h, 0], [0, h]])

    def hx(x):
        return np.array([0.5 * (x[0] ** 2 + x[1] ** 2)])

    def H(x):
        return np.array([[x[0], x[1], 0.0, 0.0]])

    N = traj.n_samples
    t0 = time.perf_counter()
    for j in range(runs):
        e = FpEKF(dim_x=4, dim_z=1, dim_u=2)
        e.x, e.P, e.Q, e.F, e.B = x0[j].copy(), cov["p0_ekf"].copy(), cov["q_ekf"], F, B
        for k in range(N):
            y = 0.5 * r[k, j] ** 2 - 0.5 * SIG**2
            e.update(np.array([y]), H, hx, R=np.array([[r[k, j] ** 2 * SIG**2 + 0.5 * SIG**4]]))
            e.predict(u=traj.u[k])
    return (time.perf_counter() - t0) / (N * runs) * 1e6


def filterpy_kf(traj, cov, r, x0, runs) -> float:
    """The augmented KF in the paper's coordinates plus the anchor and (e, f, g)."""
    h, N = 0.01, traj.n_samples
    d, dd = input_displacement(traj)
    m, mz = 10, 6  # (p, v, α, β, β_a, e, f, g)
    F = np.eye(m)
    F[0, 2] = F[1, 3] = h
    F[7, 8], F[7, 9], F[8, 9] = h, h * h, 2 * h
    B = np.zeros((m, 2))
    B[:2], B[2:4] = 0.5 * h * h * np.eye(2), h * np.eye(2)
    t0 = time.perf_counter()
    for j in range(runs):
        f = FpKF(dim_x=m, dim_z=1, dim_u=2)
        p, v = x0[j, :2], x0[j, 2:]
        f.x = np.concatenate([p, v, [p @ v, v @ v], np.zeros(4)])
        y0 = 0.5 * r[0, j] ** 2 - 0.5 * SIG**2
        P = np.zeros((m, m))
        P[:mz, :mz] = cov["p0_kf"]
        P[6, 6] = r[0, j] ** 2 * SIG**2 + 0.5 * SIG**4
        f.P, f.F, f.B = P, F, B
        for k in range(N):
            if k:
                tau = traj.t[k] - traj.t[0]
                C = np.zeros((1, m))
                C[0, :2], C[0, 4], C[0, 5], C[0, 6], C[0, 7] = d[k], tau, 0.5 * tau**2, 1, 1
                y = 0.5 * r[k, j] ** 2 - 0.5 * SIG**2 - y0 + 0.5 * d[k] @ d[k]
                f.update(np.array([y]), R=np.array([[r[k, j] ** 2 * SIG**2 + 0.5 * SIG**4]]), H=C)
            if k < N - 1:
                zp = F @ f.x + B @ traj.u[k]
                cp, cv = zp[:2] - d[k + 1], zp[2:4] - dd[k + 1]
                G = np.zeros((m, mz))
                G[:mz, :mz] = np.eye(mz)
                G[7, :2], G[8, :2], G[8, 2:4], G[9, 2:4] = cp, cv, cp, cv
                f.Q = G @ cov["q_kf"] @ G.T
                f.predict(u=traj.u[k])
    return (time.perf_counter() - t0) / (N * runs) * 1e6


def obsplan_filters(traj, cfg, cov, r, x0, runs) -> dict[str, float]:
    """obsplan's compiled filters on the same readings, all runs in one batch (as
    ``monte_carlo`` does, up to ``simulate.BATCH`` runs per call)."""
    model = cfg.model
    sched = make_schedule(traj, model.sensors, {})
    rec = record_samples(traj.n_samples, None)
    plan = epoch_plan(traj, sched, rec)
    d, dd = input_displacement(traj)
    ctx = RunContext(plan, traj.t[rec], np.hstack([d, dd])[plan.epochs], 0.5, 18.47, 0.1)
    truth = np.broadcast_to(np.hstack([traj.p, traj.v])[rec], (runs, rec.size, 4)).copy()
    Y = np.ascontiguousarray(r[plan.epochs, None, :runs])
    out = {}
    for name in ("ekf", "kf", "gsf"):
        f = make_filter(name, cfg, cov, cfg.process_noise_model())
        sums = np.zeros((2, rec.size, 7))
        info = np.zeros((runs, 10))
        states = [f.start(x0[j], None, float(Y[0, 0, j])) for j in range(runs)]
        first = RunBatch(ctx, states[:1], Y[:, :, :1])
        f.run(first, RunRecord(truth[:1], sums, info[:1]))  # compile / load
        t0 = time.perf_counter()
        f.run(RunBatch(ctx, states, Y), RunRecord(truth, sums, info))
        out[name] = (time.perf_counter() - t0) / (traj.n_samples * runs) * 1e6
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--runs", type=int, default=32, help="runs timed for obsplan (one batch)")
    ap.add_argument("--fp-runs", type=int, default=3, help="runs timed for filterpy")
    a = ap.parse_args()
    traj, cfg, cov, r, x0 = setup(a.steps, max(a.runs, a.fp_runs))
    fp_e = filterpy_ekf(traj, cov, r, x0, a.fp_runs)
    fp_k = filterpy_kf(traj, cov, r, x0, a.fp_runs)
    ours = obsplan_filters(traj, cfg, cov, r, x0, a.runs)
    monte_carlo(traj.window(0, 200), cfg, runs=2)
    t0 = time.perf_counter()
    monte_carlo(traj, cfg, runs=a.runs, seed=0)
    mc = (time.perf_counter() - t0) / (traj.n_samples * a.runs) * 1e6
    print(f"\nµs per filter step per run (2D range at every 0.01 s step, {a.steps} steps)\n")
    print("| implementation | EKF | KF (augmented, coupled) | Gaussian sum (25 EKFs) |")
    print("|---|---:|---:|---:|")
    print(f"| filterpy 2.0, loop over steps ({a.fp_runs} runs) | {fp_e:.1f} | {fp_k:.1f} | - |")
    print(
        f"| obsplan compiled filters ({a.runs} runs) | {ours['ekf']:.3f} | {ours['kf']:.3f} | "
        f"{ours['gsf']:.2f} |"
    )
    print(
        f"| ratio filterpy / obsplan | {fp_e / ours['ekf']:.0f}x | {fp_k / ours['kf']:.0f}x | - |"
    )
    print(f"\nWhole monte_carlo (truth, readings, EKF + KF, bound): {mc:.3f} µs per step per run")


if __name__ == "__main__":
    main()
