"""Benchmark of the observability core on a long trajectory (run once: ~1 min on one core).

    python benchmarks/bench_observability.py [--samples 60000] [--no-quad-vec]

Timings are of the machine it runs on: run it on a quiet one (the tables in the README say
under which load they were measured).

Prints three tables:

1. the exact Gramian (``gramian()``: the closed form evaluated in numpy, vectorised over the
   intervals) and the planner's CasADi function of the same closed form mapped over the
   intervals, against two independent quadratures of ``∫ Φᵀ Cᵀ C Φ`` with ``C`` written from
   eqs. 21/41: 4-point Gauss-Legendre per interval (exact for the degree-6 polynomial integrand)
   vectorised in numpy (the baseline of the ``x Gauss`` column: the acceptance asks ``gramian()``
   within 2x of it), and ``scipy.integrate.quad_vec`` over the whole horizon with every sample
   time as a breakpoint; wall time (best of 3, measured in one run) and relative (Frobenius)
   error of each;
2. the LWO evaluation along the trajectory (matrices, then ranks);
3. the rank tolerances: the largest "zero" eigenvalue of rank-deficient Gramians and the
   smallest real one of weakly observable cases, beside ``RANK_TOL``; the same for O and
   ``LWO_RANK_TOL``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import quad_vec

from obsplan.model.vehicle import make_model
from obsplan.observability.gramian import (
    augmented_model,
    cumulative_gramians,
    gramian,
    interval_gramian_function,
    rank_scales,
)
from obsplan.observability.lwo import (
    LWO_RANK_TOL,
    _dimensionless,
    lwo_matrices,
    lwo_ranks,
)
from obsplan.observability.scaling import DEFAULT_SCALES, RANK_TOL, equilibrated_eigvals
from obsplan.trajectory.sampled import Trajectory


def test_path(n: int, dt: float = 0.01, dim: int = 3) -> Trajectory:
    """Circle in (x, y) with a z oscillation, piecewise-constant inputs, exactly integrated."""
    t = np.arange(n) * dt
    rho, w = 50.0, 0.1
    u = np.zeros((n, dim))
    u[:, 0] = -rho * w**2 * np.cos(w * t)
    u[:, 1] = -rho * w**2 * np.sin(w * t)
    if dim == 3:
        u[:, 2] = 0.05 * np.sin(0.37 * t)
    p0, v0 = np.zeros(dim), np.zeros(dim)
    p0[0], p0[-1], v0[1] = rho, -10.0, rho * w
    return Trajectory.from_inputs(t, p0, v0, u)


def c_phi_rows(d, tau, n, m, sensors, current):
    """Rows of C Φ (eqs. 21, 26, 41), batched: d (..., n), tau (...) -> (..., rows, m)."""
    shape = tau.shape
    rows = []
    r = np.zeros((*shape, m))
    r[..., :n] = d
    r[..., n : 2 * n] = tau[..., None] * d
    if current:
        r[..., 2 * n : 3 * n] = tau[..., None] * d
    r[..., -2], r[..., -1] = tau, 0.5 * tau**2
    rows.append(r)
    if any(s.startswith("dvl") for s in sensors):
        for i in range(n):
            r = np.zeros((*shape, m))
            r[..., n + i] = 1.0
            if current and "dvl-bottom" in sensors:
                r[..., 2 * n + i] = 1.0
            rows.append(r)
    if "depth" in sensors:
        r = np.zeros((*shape, m))
        r[..., n - 1] = 1.0
        r[..., 2 * n - 1] = tau
        if current:
            r[..., 3 * n - 1] = tau
        rows.append(r)
    return np.stack(rows, axis=-2)


def gauss_gramian(tr: Trajectory, sensors, current) -> np.ndarray:
    n = tr.dim
    m = (3 if current else 2) * n + 2
    x, w = np.polynomial.legendre.leggauss(4)
    h = tr.dt[:, None]
    s = 0.5 * h * (x + 1.0)  # (K, 4)
    d0 = tr.displacement()[:-1, None, :]
    e = (tr.v - tr.v[0])[:-1, None, :]
    u = tr.u[:-1, None, :]
    d = d0 + e * s[..., None] + 0.5 * u * s[..., None] ** 2
    tau = (tr.t[:-1] - tr.t[0])[:, None] + s
    R = c_phi_rows(d, tau, n, m, sensors, current)  # (K, 4, rows, m)
    wts = 0.5 * h * w  # (K, 4)
    return np.einsum("kq,kqri,kqrj->ij", wts, R, R)


def quad_vec_gramian(tr: Trajectory, sensors, current) -> np.ndarray:
    n = tr.dim
    m = (3 if current else 2) * n + 2
    t, p, v, u = tr.t, tr.p, tr.v, tr.u

    def f(time_):
        k = min(max(int(np.searchsorted(t, time_, side="right")) - 1, 0), len(t) - 2)
        s = time_ - t[k]
        d = p[k] + v[k] * s + 0.5 * u[k] * s**2 - p[0] - v[0] * (time_ - t[0])
        R = c_phi_rows(d, np.asarray(time_ - t[0]), n, m, sensors, current)
        return R.T @ R

    G, _ = quad_vec(f, t[0], t[-1], points=t[1:-1], epsabs=0.0, epsrel=1e-12, limit=10 * len(t))
    return G


def timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def casadi_mapped_gramian(tr: Trajectory, aug) -> np.ndarray:
    """The planner's CasADi function mapped over every interval, summed (the old numeric path)."""
    K, m = tr.n_samples - 1, aug.state_dim
    d = tr.displacement()[:-1]
    e = (tr.v - tr.v[0])[:-1]
    tau0 = (tr.t - tr.t[0])[:-1]
    fn = interval_gramian_function(aug).map(K, "serial")
    out = np.asarray(fn(d.T, e.T, tr.u[:-1].T, tau0[None, :], tr.dt[None, :]))
    return out.reshape(m, K, m).sum(axis=1)


def best(fn, *args, repeat=3):
    out, tt = None, np.inf
    for _ in range(repeat):
        out, t1 = timed(fn, *args)
        tt = min(tt, t1)
    return out, tt


def table_gramian(tr: Trajectory, use_quad_vec: bool) -> None:
    print(f"\n1. Exact Gramian vs quadrature, {tr.n_samples} samples ({tr.duration:g} s), 3D")
    print(f"{'sensors':28s} {'method':30s} {'time [s]':>9s} {'rel. error':>11s} {'x Gauss':>8s}")
    sc = tr.scaled(DEFAULT_SCALES.length_m, DEFAULT_SCALES.time_s)
    for sensors, current in ((("range",), False), (("range", "dvl-bottom", "depth"), True)):
        model = make_model(tr.dim, sensors, current)
        aug = augmented_model(model)
        gramian(tr.window(0, 100), model)  # build the CasADi function outside the timing
        casadi_mapped_gramian(sc.window(0, 100), aug)
        G, t_exact = best(gramian, tr, model)
        Gg, tg = best(gauss_gramian, sc, model.sensors, current)
        Gc, tc = best(casadi_mapped_gramian, sc, aug, repeat=1)
        rows = [
            ("gramian() (numpy closed form)", G, t_exact),
            ("CasADi function, mapped", 0.5 * (Gc + Gc.T), tc),
            ("Gauss-Legendre 4/interval", 0.5 * (Gg + Gg.T), tg),
        ]
        if use_quad_vec:
            Gq, tq = timed(quad_vec_gramian, sc, model.sensors, current)
            rows.append(("scipy quad_vec", 0.5 * (Gq + Gq.T), tq))
        ref = rows[-1][1]
        for name, M, tt in rows:
            err = "(ref)" if M is ref else f"{rel(M, ref):.2e}"
            print(f"{','.join(sensors):28s} {name:30s} {tt:9.3f} {err:>11s} {tt / tg:8.2f}")
        if use_quad_vec:
            print(f"{'':28s} {'gramian() vs Gauss':30s} {'':9s} {rel(G, rows[2][1]):11.2e}")


def table_lwo(tr: Trajectory) -> None:
    print(f"\n2. LWO along the trajectory ({tr.n_samples} samples)")
    print(
        f"{'sensors':28s} {'matrices [s]':>12s} {'ranks [s]':>10s} {'min rank':>9s} {'full %':>7s}"
    )
    for sensors in ("range", "range,dvl-bottom,depth"):
        model = make_model(tr.dim, sensors)
        lwo_ranks(tr.window(0, 50), model)  # build the CasADi functions outside the timing
        O, t_o = timed(lwo_matrices, tr, model)
        r, t_r = timed(lwo_ranks, tr, model)
        full = 100 * np.mean(r == model.state_dim)
        print(f"{sensors:28s} {t_o:12.3f} {t_r:10.3f} {int(r.min()):9d} {full:7.1f}")


def line(n, dt, dim, kind, q=20.0, seed=0):
    rng = np.random.default_rng(seed)
    b = rng.standard_normal(dim)
    b /= np.linalg.norm(b)
    nrm = rng.standard_normal(dim)
    nrm -= (nrm @ b) * b
    nrm /= np.linalg.norm(nrm)
    t = np.arange(n) * dt
    a = {
        "zero": np.zeros(n),
        "constant": np.full(n, 0.02),
        "varying": 0.02 * np.sign(np.sin(2 * np.pi * t / (n * dt / 3) + 0.3)),
    }[kind]
    return Trajectory.from_inputs(t, -60 * b + q * nrm, 0.5 * b, a[:, None] * b)


def table_tolerances(n: int) -> None:
    dt = 0.01
    print(f"\n3. Rank tolerances on {n}-sample paths at 100 Hz")
    print(f"   Gramian (RANK_TOL = {RANK_TOL:g}): eigenvalues of the equilibrated G(t_N, t_0)")
    print(f"   {'case':44s} {'rank':>5s} {'largest zero':>13s} {'smallest real':>14s}")
    cases = []
    for dim in (2, 3):
        for kind, r_range, r_dvl in (
            ("zero", 2, dim + 2),
            ("constant", 3, dim + 2),
            ("varying", 4, dim + 3),
        ):
            tr = line(n, dt, dim, kind)
            cases.append((f"{dim}D line, {kind} accel, range", tr, make_model(dim), r_range))
            cases.append(
                (f"{dim}D line, {kind} accel, range+dvl", tr, make_model(dim, "range,dvl"), r_dvl)
            )
    circ = test_path(n, dt)
    cases.append(
        ("3D circle+z, range+dvl-bottom+current", circ, make_model(3, "range,dvl-bottom", True), 8)
    )
    cases.append(("3D circle+z, range", circ, make_model(3), 8))
    cases.append(
        (
            "2D circle, range+dvl-water+current",
            test_path(n, dt, dim=2),
            make_model(2, "range,dvl-water", True),
            8,
        )
    )
    worst_zero, weakest = 0.0, np.inf
    for name, tr, model, expected in cases:
        aug = augmented_model(model)
        G = cumulative_gramians(tr, aug, rank_scales(tr))[-1]
        ev = equilibrated_eigvals(0.5 * (G + G.T))
        m = aug.state_dim
        zero = float(ev[m - expected - 1]) if expected < m else float("nan")
        real = float(ev[m - expected])
        worst_zero = max(worst_zero, zero) if expected < m else worst_zero
        weakest = min(weakest, real)
        rank = int(np.sum(ev > RANK_TOL))
        flag = "" if rank == expected else f"  <-- expected {expected}"
        print(f"   {name:44s} {rank:5d} {zero:13.1e} {real:14.1e}{flag}")
    print(
        f"   margins: RANK_TOL / largest zero = {RANK_TOL / worst_zero:.0e}, "
        f"smallest real / RANK_TOL = {weakest / RANK_TOL:.0e}"
    )
    print(f"   LWO (LWO_RANK_TOL = {LWO_RANK_TOL:g}): σ_k/σ_max of dimensionless O over samples")
    for q, expected in ((0.0, 2), (1e-3, 4), (0.1, 4)):
        tr = line(n, dt, 2, "constant", q=q)
        O = _dimensionless(tr, make_model(2), 0)
        s = np.linalg.svd(O, compute_uv=False)
        ratio = s / s[:, :1]
        r = lwo_ranks(tr, make_model(2))
        kth = ratio[:, expected - 1].min()
        nxt = ratio[:, expected].max() if expected < 4 else float("nan")
        print(
            f"   2D line {q:g} m from the beacon: ranks {sorted(set(r.tolist()))} "
            f"(expected {expected}); min σ_{expected}/σ_1 = {kth:.1e}, "
            f"max σ_{expected + 1}/σ_1 = {nxt:.1e}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=60_000)
    ap.add_argument("--no-quad-vec", action="store_true", help="skip the slow quad_vec column")
    args = ap.parse_args()
    tr = test_path(args.samples)
    table_gramian(tr, not args.no_quad_vec)
    table_lwo(tr)
    table_tolerances(args.samples)


if __name__ == "__main__":
    main()
