"""Monte Carlo speed and quality: the acceptance cases, with a step-by-step oracle beside them.

    python benchmarks/bench_monte_carlo.py [--quick] [--skip-oracle] [--skip-plan]

Prints Markdown tables (timings are of the machine it runs on; say under which load):

1. compile cost of the numba kernels: a fresh process with an empty cache (compiles) and one
   with the cache filled (loads), each running a tiny Monte Carlo;
2. wall time of ``monte_carlo`` (EKF + augmented KF + posterior CRB) on the acceptance cases,
   the bound alone, and a plain step-by-step recursion doing the same work (numpy, batched over
   runs: truth at every step, prediction at every step, the same updates, the same statistics;
   an independent prototype, not obsplan's code) with the ratio;
3. closed loop (guidance on the EKF estimate at every filter step, the passive KF on the applied
   inputs) against open loop on the same cases, with the truth's final drift in both;
3b. the validation part of the default ``obsplan plan`` (its paths: the plan and the baselines)
   in one pass, and as one ``validate_paths`` call per path;
4. ``gramian()`` on 60,000 samples against a numpy 4-point Gauss–Legendre rule;
5. consistency: the KF's NEES with and without the process-noise coupling (range3d plan, a
   600 s 2D circle), the EKF's divergence monitor and the Gaussian sum on a straight line.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from obsplan.estimation import EstimationConfig, Guidance, monte_carlo
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.schedule import make_schedule
from obsplan.model.vehicle import make_model
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory, read_csv

HERE = Path(__file__).resolve().parent


# ----------------------------------------------------------------------------- 1. compile
def compile_cost() -> list[tuple[str, float]]:
    code = (
        "import time; t = time.perf_counter();"
        "from obsplan.trajectory import generators as gen;"
        "from obsplan.estimation import EstimationConfig, Guidance, monte_carlo;"
        "from obsplan.model.vehicle import make_model;"
        "tr = gen.circle(30.0, 1.5, 20.0).sample(0.1);"
        "monte_carlo(tr, EstimationConfig.paper(make_model(2, 'range'), 0.1), runs=2,"
        " filters=('ekf', 'kf', 'gsf'));"
        "print(time.perf_counter() - t)"
    )
    out = []
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for label in ("first call, empty cache (compiles)", "first call, cache filled (loads)"):
            r = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            )
            out.append((label, float(r.stdout.strip().splitlines()[-1])))
    return out


# ----------------------------------------------------------------------------- 2. oracle
def step_by_step(traj: Trajectory, cfg: EstimationConfig, runs: int, seed: int = 0) -> float:
    """Wall time of a plain per-step Monte Carlo of the EKF and the coupled augmented KF
    (numpy, batched over runs), recording ~1000 samples like ``monte_carlo``."""
    t0 = time.perf_counter()
    model = cfg.model
    n, mx, N = model.dim, model.state_dim, traj.n_samples
    dt = float(np.median(traj.dt))
    cov = cfg.covariances(dt)
    sched = make_schedule(traj, model.sensors, cfg.rates_hz)
    stride = max(1, N // 1000)
    rec = np.zeros(N, bool)
    rec[::stride] = True
    rec[-1] = True
    rng = np.random.default_rng(seed)
    q, qk = cov["q_ekf"], cov["q_kf"]
    Lq = np.sqrt(np.diag(q))
    sig = dict(cfg.noise)
    sr = sig["range"]
    R = runs
    nominal = np.hstack([traj.p, traj.v])
    delta = np.zeros((R, mx))
    xe = nominal[0] + rng.standard_normal((R, mx)) @ np.linalg.cholesky(cov["p0_ekf"]).T
    Pe = np.broadcast_to(cov["p0_ekf"], (R, mx, mx)).copy()
    # KF in paper coordinates + (β_a, e, f, g)
    mz = mx + 2
    m = mz + 4
    ia, ie = mz, mz + 1
    z = np.zeros((R, m))
    z[:, :mx] = xe
    Pk = np.zeros((R, m, m))
    Pk[:, :mz, :mz] = cov["p0_kf"]
    d = np.zeros(n)
    dd = np.zeros(n)
    y0 = var0 = None
    lin_rows = [(s, sl) for s, sl in model.output_slices.items() if s != "range"]
    se = np.zeros(rec.sum())
    nees = np.zeros(rec.sum())
    j = 0
    eye_m = np.eye(m)
    for k in range(N):
        x_true = nominal[k] + delta
        rep = sched.mask[k]
        if rep.any():
            # readings
            r_m = np.linalg.norm(x_true[:, :n] - model.beacon_array, axis=1)
            r_m = r_m + sr * rng.standard_normal(R)
            H_e, inn_e, var_e = [], [], []
            H_k, inn_k, var_k = [], [], []
            if rep[0]:
                rel = xe[:, :n] - model.beacon_array
                h = np.zeros((R, mx))
                h[:, :n] = rel
                H_e.append(h)
                inn_e.append(0.5 * r_m**2 - 0.5 * sr**2 - 0.5 * np.sum(rel**2, axis=1))
                var_e.append(r_m**2 * sr**2 + 0.5 * sr**4)
                yv, vv = 0.5 * r_m**2 - 0.5 * sr**2, r_m**2 * sr**2 + 0.5 * sr**4
                if k == 0:
                    y0, var0 = yv, vv
                    z[:, ia] = 0.0
                    Pk[:, ia, ia] = var0
                else:
                    tau = traj.t[k] - traj.t[0]
                    c = np.zeros(m)
                    c[:n] = d
                    c[mx], c[mx + 1], c[ia], c[ie] = tau, 0.5 * tau**2, 1.0, 1.0
                    H_k.append(np.broadcast_to(c, (R, m)))
                    inn_k.append(yv - y0 + 0.5 * d @ d - z @ c)
                    var_k.append(vv)
            for i, (s, sl) in enumerate(lin_rows, start=1):
                if not rep[i]:
                    continue
                for a in range(sl.stop - sl.start):
                    col = (n + a) if s.startswith("dvl") else 2
                    yv = x_true[:, col] + sig[s] * rng.standard_normal(R)
                    h = np.zeros((R, mx))
                    h[:, col] = 1.0
                    H_e.append(h)
                    inn_e.append(yv - xe[:, col])
                    var_e.append(np.full(R, sig[s] ** 2))
                    hk = np.zeros((R, m))
                    hk[:, col] = 1.0
                    H_k.append(hk)
                    inn_k.append(yv - (model.beacon_array[2] if col == 2 else 0.0) - z[:, col])
                    var_k.append(np.full(R, sig[s] ** 2))
            for H, inn, var, xs in ((H_e, inn_e, var_e, "e"), (H_k, inn_k, var_k, "k")):
                if not H:
                    continue
                Hm = np.stack(H, axis=1)
                nu = np.stack(inn, axis=1)
                Rm = np.stack(var, axis=1)
                X, P = (xe, Pe) if xs == "e" else (z, Pk)
                PHt = P @ np.swapaxes(Hm, 1, 2)
                S = Hm @ PHt
                S[:, np.arange(S.shape[1]), np.arange(S.shape[1])] += Rm
                K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, 1, 2)), 1, 2)
                X = X + (K @ nu[:, :, None])[:, :, 0]
                IKH = np.eye(P.shape[1]) - K @ Hm
                P = IKH @ P @ np.swapaxes(IKH, 1, 2) + K @ (Rm[:, :, None] * np.swapaxes(K, 1, 2))
                if xs == "e":
                    xe, Pe = X, P
                else:
                    z, Pk = X, P
        if rec[k]:
            e = xe - x_true
            se[j] = np.mean(np.sum(e[:, :n] ** 2, axis=1))
            nees[j] = np.mean(np.einsum("ri,ri->r", e, np.linalg.solve(Pe, e[..., None])[..., 0]))
            j += 1
        if k < N - 1:
            h = traj.t[k + 1] - traj.t[k]
            F, G = model.transition(h)
            delta = delta @ F.T + rng.standard_normal((R, mx)) * Lq
            xe = xe @ F.T + G @ traj.u[k]
            Pe = F @ Pe @ F.T + q
            Fk = eye_m.copy()
            Fk[:mx, :mx] = F
            Fk[ie, ie + 1], Fk[ie, ie + 2], Fk[ie + 1, ie + 2] = h, h * h, 2 * h
            Bu = np.zeros(m)
            Bu[:mx] = G @ traj.u[k]
            zp = z @ Fk.T + Bu
            dd_next = dd + traj.u[k] * h
            d = d + dd * h + 0.5 * traj.u[k] * h**2
            dd = dd_next
            cp, cv = zp[:, :n] - d, zp[:, n : 2 * n] - dd
            Gm = np.zeros((R, m, mz))
            Gm[:, :mz, :mz] = np.eye(mz)
            Gm[:, ie, :n] = cp
            Gm[:, ie + 1, :n] = cv
            Gm[:, ie + 1, n : 2 * n] = cp
            Gm[:, ie + 2, n : 2 * n] = cv
            z = zp
            Pk = Fk @ Pk @ Fk.T + Gm @ qk @ np.swapaxes(Gm, 1, 2)
    return time.perf_counter() - t0


def acceptance_cases(quick: bool):
    T = 60.0 if quick else 600.0
    tr2 = gen.circle(51.0, 2.6, T, center=(0.0, 2.0)).sample(0.01)
    tr3 = gen.circle_z(50.0, 2.6, T, z0=5.0, z_amp=4.0, z_period=90.0).sample(0.01)
    m2, m3 = make_model(2, "range"), make_model(3, "range,dvl")
    one_hz = EstimationConfig.paper(m2, 0.01, rates_hz={"range": 1.0})
    return [
        ("2D range 1 Hz, 100 runs", tr2, one_hz, 100, 1.0),
        (
            "paper: range every 0.01 s step, 100 runs",
            tr2,
            EstimationConfig.paper(m2, 0.01),
            100,
            2.0,
        ),
        (
            "3D range + DVL at 5 Hz, 100 runs",
            tr3,
            EstimationConfig.paper(m3, 0.01, rates_hz={"range": 5.0, "dvl-bottom": 5.0}),
            100,
            3.0,
        ),
        ("2D range 1 Hz, 10 runs", tr2, one_hz, 10, 0.2),
    ]


# ----------------------------------------------------------------------------- 3. closed loop
#: Bounds above the acceptance circle's own acceleration (2.6²/51 = 0.13 m/s²) and speed.
CLOSED_GUIDANCE = Guidance.from_limits(0.2, speed=3.0, error_scale_m=1.0)


def closed_vs_open(quick: bool) -> list[tuple[str, float, float, float, float]]:
    """Wall time of monte_carlo open and closed loop on the acceptance cases, and the RMS final
    drift of the true path from the plan in each."""
    out = []
    for label, traj, cfg, runs, _ in acceptance_cases(quick):
        monte_carlo(traj.window(0, 300), cfg, runs=2, guidance=CLOSED_GUIDANCE)  # compile/load
        t0 = time.perf_counter()
        o = monte_carlo(traj, cfg, runs=runs, seed=0)
        t_open = time.perf_counter() - t0
        t0 = time.perf_counter()
        c = monte_carlo(traj, cfg, runs=runs, seed=0, guidance=CLOSED_GUIDANCE)
        t_closed = time.perf_counter() - t0
        out.append((label, t_open, t_closed, o.truth.final_drift_rms_m, c.truth.final_drift_rms_m))
    return out


# ----------------------------------------------------------------------------- 3b. validation
def validation_case() -> tuple[float, float, int]:
    from obsplan.planning import load_problem, plan
    from obsplan.planning.problem.parse import LOCALISE_PROBLEM
    from obsplan.planning.validation.validate import validate_paths

    pb = load_problem(LOCALISE_PROBLEM)
    res = plan(pb, validate=False)
    paths = {}
    if res.solve.trajectory is not None:
        paths["planned"] = res.solve.trajectory
    paths.update({k: b.trajectory for k, b in res.baselines.items() if b.trajectory is not None})
    t0 = time.perf_counter()
    validate_paths(paths, pb)
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    for name, tr in paths.items():
        validate_paths({name: tr}, pb)
    each = time.perf_counter() - t0
    return one, each, len(paths)


# ----------------------------------------------------------------------------- 4. gramian
def gramian_case() -> list[tuple[str, float, float]]:
    sys.path.insert(0, str(HERE))
    from bench_observability import gauss_gramian, test_path

    from obsplan.observability.gramian import gramian
    from obsplan.observability.scaling import DEFAULT_SCALES

    out = []
    for dim, sensors, current in (
        (2, ("range",), False),
        (3, ("range", "dvl-bottom", "depth"), True),
    ):
        tr = test_path(60_000, dim=dim)
        sc = tr.scaled(DEFAULT_SCALES.length_m, DEFAULT_SCALES.time_s)
        model = make_model(dim, sensors, current)
        gramian(tr.window(0, 100), model)
        ours = min(_timed(gramian, tr, model) for _ in range(3))
        gauss = min(_timed(gauss_gramian, sc, model.sensors, current) for _ in range(3))
        out.append((f"{dim}D {','.join(sensors)}{' + current' if current else ''}", ours, gauss))
    return out


def _timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


# ----------------------------------------------------------------------------- 5. quality
def quality(quick: bool) -> list[str]:
    from obsplan.planning import load_problem
    from obsplan.planning.problem.validation_setup import estimation_config
    from obsplan.trajectory.sampled import resample

    rows = []
    runs = 20 if quick else 50
    pb = load_problem(str(HERE.parent / "problems" / "range3d.toml"))
    plan3 = resample(
        read_csv(HERE.parent / "tests" / "data" / "range3d-plan.csv", check=False), pb.validation.dt
    )
    circle = gen.circle(51.0, 2.6, 600.0, center=(0.0, 2.0)).sample(0.1)
    for label, traj, cfg in (
        ("range3d.toml plan, dt 0.1 s", plan3, estimation_config(pb)),
        ("2D circle 600 s, dt 0.1 s", circle, EstimationConfig.paper(make_model(2), 0.1)),
    ):
        for coupling in (True, False):
            r = monte_carlo(
                traj, replace(cfg, kf_coupling=coupling), runs=runs, seed=0, filters=("kf",)
            )
            k = r.kf
            rows.append(
                f"| {label} | KF, coupling {'on' if coupling else 'off'} | {k.nees_mean:.2f} | "
                f"[{k.nees_bounds[0]:.2f}, {k.nees_bounds[1]:.2f}] | {k.nees_inside_fraction:.2f} "
                f"| {k.final_pos_err:.3f} | {k.final_pos_std:.3f} | - |"
            )
    line = gen.straight((-100.0, 30.0), (1.0, 0.0), 1.0, accel=0.005, duration=200.0).sample(0.1)
    cfg = EstimationConfig.paper(make_model(2), 0.1, rates_hz={"range": 1.0})
    r = monte_carlo(line, cfg, runs=runs, seed=0, filters=("ekf", "gsf"))
    late = r.t >= r.t[-1] - 20.0
    for name in ("ekf", "gsf"):
        s = r.stats(name)
        u = s.unflagged
        rows.append(
            f"| straight line 200 s, 1 Hz | {name.upper()} | {s.nees_mean:.3g} (unflagged, last "
            f"20 s: {u.nees_t[late].mean():.2f}) | [{u.nees_bounds[0]:.2f}, {u.nees_bounds[1]:.2f}]"
            f" | {u.nees_inside_fraction:.2f} | {s.final_pos_err:.3f} (median "
            f"{np.median(s.final_pos_err_runs):.3f}) | {s.final_pos_std:.3f} | {s.flagged_runs} |"
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="60 s paths, fewer runs (a smoke test)")
    ap.add_argument("--skip-oracle", action="store_true", help="no step-by-step recursion")
    ap.add_argument("--skip-plan", action="store_true", help="no default-plan validation")
    a = ap.parse_args()

    print("\n### Compile cost of the kernels (EKF, KF, Gaussian sum, truth)\n")
    print("| process | wall [s] |\n|---|---:|")
    for label, t in compile_cost():
        print(f"| {label} | {t:.2f} |")

    print("\n### Monte Carlo wall time (EKF + augmented KF + posterior CRB)\n")
    print(
        "| case | monte_carlo [s] | of which the bound [s] | target [s] | step-by-step "
        "recursion [s] | ratio |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for label, traj, cfg, runs, target in acceptance_cases(a.quick):
        monte_carlo(traj.window(0, 300), cfg, runs=2)  # compile/load outside the timing
        t0 = time.perf_counter()
        posterior_crlb(traj, cfg)
        t_bound = time.perf_counter() - t0
        t0 = time.perf_counter()
        monte_carlo(traj, cfg, runs=runs, seed=0)
        wall = time.perf_counter() - t0
        oracle = float("nan") if a.skip_oracle else step_by_step(traj, cfg, runs)
        print(
            f"| {label}, {traj.n_samples - 1} steps | {wall:.2f} | {t_bound:.2f} | {target:g} "
            f"| {oracle:.1f} | {oracle / wall:.0f}x |"
        )

    print("\n### Closed loop against open loop (EKF + augmented KF + bound, same runs)\n")
    print(
        "| case | open loop [s] | closed loop [s] | ratio | final drift open [m] | "
        "final drift closed [m] |\n|---|---:|---:|---:|---:|---:|"
    )
    for label, t_open, t_closed, d_open, d_closed in closed_vs_open(a.quick):
        print(
            f"| {label} | {t_open:.2f} | {t_closed:.2f} | {t_closed / t_open:.1f}x | "
            f"{d_open:.2f} | {d_closed:.3f} |"
        )

    if not a.skip_plan:
        one, each, k = validation_case()
        print("\n### Validation of the default `obsplan plan` (its paths, 50 runs, dt 0.1 s)\n")
        print("| how | wall [s] |\n|---|---:|")
        print(f"| `validate_paths` of all {k} paths in one pass (target <= 1 s) | {one:.2f} |")
        print(f"| one `validate_paths` call per path | {each:.2f} |")

    print("\n### `gramian()` on 60,000 samples against a numpy 4-point Gauss–Legendre rule\n")
    print(
        "| model | gramian() [s] | Gauss–Legendre [s] | ratio (target <= 2) |\n|---|---:|---:|---:|"
    )
    for label, ours, gauss in gramian_case():
        print(f"| {label} | {ours:.3f} | {gauss:.3f} | {ours / gauss:.2f} |")

    print("\n### Consistency (seed 0)\n")
    print(
        "| path | filter | NEES | 95 % band | inside | final error [m] | final std [m] | flagged |"
    )
    print("|---|---|---:|---|---:|---:|---:|---:|")
    for row in quality(a.quick):
        print(row)


if __name__ == "__main__":
    main()
