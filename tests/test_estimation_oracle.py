"""The epoch-based Monte Carlo reproduces a plain per-step recursion (same seeds) to 1e-9.

The oracle below is written from the equations, step by step, with nothing from the library's
filters: per-step truth ``δ_{k+1} = F δ_k + L_k z_k``, readings where the schedule says so, the EKF
with a joint update linearised at the prior and a prediction at every sample, and the augmented
KF in the paper's coordinates ``(p, v[, v_f], α, β, [β_a], e, f, g)`` with the output row of
eq. 21 plus the process-noise coupling (``kf.py``), its per-step noise gain evaluated at the
per-step prediction. The library composes predictions between epochs and runs the KF in chain
coordinates; both are exact reformulations, so the two agree to round-off. With the physical
process noise (an intensity) the oracle adds per step its own closed-form ``Q(h)`` and truth
factor, and for the KF the integral over the step of the coupled noise (4-point Gauss–Legendre,
exact for its degree-6 integrand) with the continuous-time gains; the library integrates over the
whole gap between epochs at once. A second oracle is
filterpy (``ExtendedKalmanFilter`` / ``KalmanFilter``, Joseph updates) doing the same per-step
recursion with its own ``h``, Jacobian and matrices.

Tolerance: 1e-9 relative to each array's magnitude (the reformulations differ only in rounding,
measured ~1e-12 over these runs).
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FpEKF
from filterpy.kalman import KalmanFilter as FpKF

from obsplan.estimation import EstimationConfig, Guidance, monte_carlo
from obsplan.estimation.filters.gsf import DEFAULT_SPLIT, split_1d, split_columns
from obsplan.estimation.schedule import make_schedule
from obsplan.model.vehicle import SENSORS, make_model
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory

TOL = 1e-9


def rng(seed, *key):
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


def joint_update(x, P, H, y, hx, R):
    """Joint Kalman update, Joseph form: (I-KH) P (I-KH)ᵀ + K R Kᵀ."""
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    x = x + K @ (y - hx)
    IKH = np.eye(x.size) - K @ H
    return x, IKH @ P @ IKH.T + K @ R @ K.T


def guide_step(traj, model, guidance, xe, k, h):
    """The guidance law of guidance.py, in plain numpy: the command at sample k from the EKF's
    estimate xe, and whether it saturated."""
    n = model.dim
    p_hat = xe[:n]
    v_hat = xe[n : 2 * n] + (xe[2 * n : 3 * n] if model.current else 0.0)
    u = traj.u[k] + guidance.kp * (traj.p[k] - p_hat) + guidance.kd * (traj.v[k] - v_hat)
    amax = guidance.bounds(n)
    sat = bool(np.any(np.abs(u) > amax))
    u = np.clip(u, -amax, amax)
    vmax = guidance.speed
    vp = v_hat + h * u
    if vmax is not None and np.linalg.norm(vp) > vmax * (1 + 1e-9):
        sat = True  # the end-of-step velocity projected onto the speed ball, then the box
        u = np.clip((vmax * vp / np.linalg.norm(vp) - v_hat) / h, -amax, amax)
    return u, sat


def path_metrics(traj, model, X):
    """Closest range (on the chords between samples), tracking RMSE, final drift, max speed."""
    n = model.dim
    b = model.beacon_array
    p = X[:, :n]
    nu = X[:, n : 2 * n] + (X[:, 2 * n :] if model.current else 0.0)
    close = np.linalg.norm(p - b, axis=1).min()
    for a, c in zip(p[:-1], p[1:], strict=True):
        s = np.clip(-((a - b) @ (c - a)) / max((c - a) @ (c - a), 1e-300), 0.0, 1.0)
        close = min(close, np.linalg.norm(a + s * (c - a) - b))
    err = np.linalg.norm(p - traj.p, axis=1)
    return np.array([close, np.sqrt(np.mean(err**2)), err[-1], np.linalg.norm(nu, axis=1).max()])


def mixture_prior(model, P0):
    """The Gaussian sum's members at the prior (gsf.py): offsets (G, m), the members'
    covariance and log weights, from the library's 1D split and split columns."""
    n = model.dim
    k, s = DEFAULT_SPLIT[n]
    w1, mu = split_1d(k, s)
    D = np.linalg.cholesky(P0)[:, split_columns(model)]
    idx = list(itertools.product(range(k), repeat=n))
    offsets = np.array([D @ mu[list(i)] for i in idx])
    lw = np.log([np.prod(w1[list(i)]) for i in idx])
    return offsets, P0 - (1.0 - s * s) * D @ D.T, lw


def mixture(xs, Ps, lw):
    """Mean and covariance of a Gaussian sum (members' spread included)."""
    w = np.exp(lw - lw.max())
    w /= w.sum()
    x = w @ xs
    dx = xs - x
    return x, np.einsum("g,gij->ij", w, Ps + dx[:, :, None] * dx[:, None, :])


def reference(
    traj, cfg, runs, seed, record_every, backend="numpy", guidance=None, navigation="ekf"
):
    """Per-step Monte Carlo of the EKF and the augmented KF (module docstring); with a
    ``guidance`` the EKF's estimate steers the truth (closed loop) and the KF filters the
    applied inputs. ``navigation = "gsf"``: a Gaussian sum of such EKFs (members weighted by
    their innovations' likelihoods) steers instead, its mixture is reported as ``gsf`` and the
    EKF runs afterwards on the same readings and applied inputs."""
    model = cfg.model
    n, mx, N = model.dim, model.state_dim, traj.n_samples
    dt = float(np.median(traj.dt))
    cov = cfg.covariances(dt)
    q, qk, P0e, P0k = cov["q_ekf"], cov["q_kf"], cov["p0_ekf"], cov["p0_kf"]
    continuous = not cfg.per_step_noise
    if continuous:  # the intensities of the physical noise, from the configuration's scalars
        qa = (3.1622776601683794e-4 if cfg.accel_noise is None else cfg.accel_noise) ** 2
        qf = cfg.current_noise**2
        q = np.diag([0.0] * n + [qa] * n + ([qf] * n if model.current else []))
        qk = np.zeros((mx + 2, mx + 2))
        qk[:mx, :mx] = q
    sched = make_schedule(traj, model.sensors, cfg.rates_hz)
    rec = np.zeros(N, bool)
    rec[::record_every] = True
    rec[-1] = True
    b = model.beacon_array
    vf_true = cfg.current_array
    nominal = np.hstack(
        [traj.p, traj.v - vf_true, np.tile(vf_true, (N, 1))] if model.current else [traj.p, traj.v]
    )
    qd = np.diag(q)
    assert np.count_nonzero(q - np.diag(qd)) == 0  # the test configurations use a diagonal q
    L = np.zeros((mx, int(np.sum(qd > 0))))
    L[np.flatnonzero(qd > 0), np.arange(L.shape[1])] = np.sqrt(qd[qd > 0])
    if continuous:
        L = np.zeros((mx, 2 * int(np.sum(qd > 0))))

    def step_noise(h):
        """Per-step truth factor and EKF covariance of a step h."""
        if not continuous:
            return L, q
        Lk = np.zeros_like(L)
        col = 0
        for j in np.flatnonzero(qd > 0):  # two normals per white source, in state order
            i = j % n
            Lk[i, col] = np.sqrt(qd[j] * h**3 / 3.0)
            Lk[j, col] = np.sqrt(qd[j] * h) * np.sqrt(3.0) / 2.0
            Lk[j, col + 1] = np.sqrt(qd[j] * h) / 2.0
            col += 2
        Qk = np.zeros((mx, mx))
        for j in np.flatnonzero(qd > 0):
            i = j % n
            Qk[i, i] += qd[j] * h**3 / 3.0
            Qk[i, j] += qd[j] * h**2 / 2.0
            Qk[j, i] += qd[j] * h**2 / 2.0
            Qk[j, j] += qd[j] * h
        return Lk, Qk

    sig = dict(cfg.noise)
    sr = sig["range"]
    aug = cfg.y0_mode == "augment"
    names = ("ekf", "kf") + (("gsf",) if navigation == "gsf" else ())
    out = {f: {"se": [], "var": [], "nees": [], "est": None, "std": None} for f in names}
    out["truth"] = {"metrics": [], "sat": []}
    truth0 = None
    for r in range(runs):
        g0 = rng(seed, r, 0)
        if isinstance(cfg.init_error, str):
            err0 = np.linalg.cholesky(P0e) @ g0.standard_normal(mx)
        else:
            err0 = np.asarray(cfg.init_error)
        if cfg.process_noise and L.shape[1]:
            z = rng(seed, r, 1).standard_normal((N - 1, L.shape[1]))
        else:
            z = np.zeros((N - 1, 0))
        # reading draws: normals and dropouts, applied where the truth is known
        draws = {}
        for j, s_ in enumerate(model.sensors):
            ks = np.flatnonzero(sched.mask[:, j])
            w = n if s_.startswith("dvl") else 1
            e = rng(seed, r, 2, SENSORS.index(s_)).standard_normal((ks.size, w))
            drop = np.zeros(ks.size, bool)
            p_drop = cfg.dropout.get(s_, 0.0)
            if p_drop > 0:
                drop = rng(seed, r, 3, SENSORS.index(s_)).random(ks.size) < p_drop
                if s_ == "range":
                    drop &= ks != 0
            draws[s_] = {int(k): (e[i], drop[i]) for i, k in enumerate(ks)}
        Y = {s_: {} for s_ in model.sensors}

        def read(k, xk, draws=draws, Y=Y):
            for s_ in model.sensors:
                if k not in draws[s_]:
                    continue
                e, dropped = draws[s_][k]
                if s_ == "range":
                    clean = np.array([np.linalg.norm(xk[:n] - b)])
                elif s_ == "dvl-bottom":
                    clean = xk[n : 2 * n] + (xk[2 * n :] if model.current else 0.0)
                elif s_ == "dvl-water":
                    clean = xk[n : 2 * n]
                else:
                    clean = xk[2:3]
                val = clean + sig[s_] * e
                Y[s_][k] = np.full_like(val, np.nan) if dropped else val

        x0 = nominal[0]
        xhat0 = x0 + err0
        prel0, nu0 = x0[:n] - b, x0[n : 2 * n] + (x0[2 * n :] if model.current else 0.0)
        if isinstance(cfg.init_error, str):
            ex0 = np.array([prel0 @ nu0, nu0 @ nu0]) + np.sqrt(np.diag(P0k)[-2:]) * (
                g0.standard_normal(2)
            )
        else:
            ph, nh = xhat0[:n] - b, xhat0[n : 2 * n] + (xhat0[2 * n :] if model.current else 0)
            ex0 = np.array([ph @ nh, nh @ nh])
        Tn = np.zeros((2 * n, mx))
        Tn[:, : 2 * n] = np.eye(2 * n)
        if model.current:
            Tn[n:, 2 * n :] = np.eye(n)

        # ------------------------------------------------------------------ EKF
        def ekf_rows(x, k, Y=Y):
            H, hx, y, R = [], [], [], []
            for s in model.sensors:
                val = Y[s].get(k)
                if val is None or not np.all(np.isfinite(val)):
                    continue
                if s == "range":
                    rel = x[:n] - b
                    row = np.zeros(mx)
                    if model.range_form == "half-squared":
                        row[:n] = rel
                        H.append(row)
                        hx.append(0.5 * rel @ rel)
                        y.append(0.5 * val[0] ** 2 - 0.5 * sr**2)
                        R.append(val[0] ** 2 * sr**2 + 0.5 * sr**4)
                    else:
                        rho = np.linalg.norm(rel)
                        row[:n] = rel / rho
                        H.append(row)
                        hx.append(rho)
                        y.append(val[0])
                        R.append(sr**2)
                elif s.startswith("dvl"):
                    for i in range(n):
                        row = np.zeros(mx)
                        row[n + i] = 1.0
                        if s == "dvl-bottom" and model.current:
                            row[2 * n + i] = 1.0
                        H.append(row)
                        hx.append(row @ x)
                        y.append(val[i])
                        R.append(sig[s] ** 2)
                else:
                    row = np.zeros(mx)
                    row[2] = 1.0
                    H.append(row)
                    hx.append(x[2])
                    y.append(val[0])
                    R.append(sig[s] ** 2)
            return np.array(H), np.array(hx), np.array(y), np.diag(R)

        def kf_rows(x, k, m, idx, y0, var0, d, Y=Y):
            tau = traj.t[k] - traj.t[0]
            H, y, R = [], [], []
            for s in model.sensors:
                val = Y[s].get(k)
                if val is None or not np.all(np.isfinite(val)):
                    continue
                if s == "range":
                    if k == 0:
                        continue  # the anchor
                    row = np.zeros(m)
                    row[:n] = d[k]
                    row[idx["a"]], row[idx["b"]] = tau, 0.5 * tau**2  # eq. 21
                    if aug:
                        row[idx["ba"]] = 1.0
                    row[idx["e"]] = 1.0  # the process-noise coupling e
                    H.append(row)
                    y.append(0.5 * val[0] ** 2 - 0.5 * sr**2 - y0 + 0.5 * d[k] @ d[k])
                    R.append(val[0] ** 2 * sr**2 + 0.5 * sr**4 + (0.0 if aug else var0))
                elif s.startswith("dvl"):
                    for i in range(n):
                        row = np.zeros(m)
                        row[n + i] = 1.0
                        if s == "dvl-bottom" and model.current:
                            row[2 * n + i] = 1.0
                        H.append(row)
                        y.append(val[i])
                        R.append(sig[s] ** 2)
                else:
                    row = np.zeros(m)
                    row[2] = 1.0
                    H.append(row)
                    y.append(val[0] - b[2])
                    R.append(sig[s] ** 2)
            return np.array(H), np.array(y), np.diag(R)

        res = {}
        X = np.zeros((N, mx))
        X[0] = x0
        u_app = np.array(traj.u, dtype=float)
        n_sat = 0

        def advance(k, x_nav, steer, truth, X=X, u_app=u_app, z=z):
            """Step k -> k + 1: the command from the estimate ``x_nav`` (with a guidance
            ``steer``), the truth (if ``truth``); returns F, G, the step's Q and the saturation."""
            h = traj.t[k + 1] - traj.t[k]
            F, G = model.transition(h)
            Lk, Qe = step_noise(h)
            sat = False
            if steer is not None:
                u_app[k], sat = guide_step(traj, model, steer, x_nav, k, h)
            if truth:
                X[k + 1] = F @ X[k] + G @ u_app[k] + (Lk @ z[k] if z.shape[1] else 0.0)
            return F, G, Qe, sat

        if navigation == "gsf":  # truth and the Gaussian sum step by step, then the EKF
            assert backend == "numpy"
            offsets, Pc, lw = mixture_prior(model, P0e)
            xs, Ps = xhat0 + offsets, np.repeat(Pc[None], offsets.shape[0], axis=0)
            ests, covs = [], []
            for k in range(N):
                read(k, X[k])
                for g in range(xs.shape[0]):
                    H, hx, y, R = ekf_rows(xs[g], k)
                    if H.size:
                        S = H @ Ps[g] @ H.T + R
                        nu = y - hx
                        lw[g] -= 0.5 * (np.linalg.slogdet(S)[1] + nu @ np.linalg.solve(S, nu))
                        xs[g], Ps[g] = joint_update(xs[g], Ps[g], H, y, hx, R)
                xm, Pm = mixture(xs, Ps, lw)
                if rec[k]:
                    ests.append(Tn @ xm)
                    covs.append(Tn @ Pm @ Tn.T)
                if k < N - 1:
                    F, G, Qe, sat = advance(k, xm, guidance, True)
                    n_sat += sat
                    xs = xs @ F.T + G @ u_app[k]
                    Ps = F @ Ps @ F.T + Qe
            res["gsf"] = (np.array(ests), np.array(covs))
        # truth and EKF, step by step (in closed loop the EKF's estimate steers the truth, unless
        # the Gaussian sum did: then the EKF runs on its path and readings)
        steer = guidance if navigation == "ekf" else None
        x, P = xhat0.copy(), P0e.copy()
        fp = None
        if backend == "filterpy":
            fp = FpEKF(dim_x=mx, dim_z=1, dim_u=n)
            fp.x, fp.P, fp.Q = x.copy(), P.copy(), q
        ests, covs = [], []
        for k in range(N):
            if navigation == "ekf":
                read(k, X[k])
            H, hx, y, R = ekf_rows(fp.x if fp else x, k)
            if H.size:
                if fp:
                    fp.update(y, lambda xx, H=H: H, lambda xx, hx=hx: hx, R=R)
                else:
                    x, P = joint_update(x, P, H, y, hx, R)
            if rec[k]:
                xx, PP = (fp.x, fp.P) if fp else (x, P)
                ests.append(Tn @ xx)
                covs.append(Tn @ PP @ Tn.T)
            if k < N - 1:
                F, G, Qe, sat = advance(k, fp.x if fp else x, steer, navigation == "ekf")
                n_sat += sat
                if fp:
                    fp.F, fp.B, fp.Q = F, G, Qe
                    fp.predict(u=u_app[k])
                else:
                    x, P = F @ x + G @ u_app[k], F @ P @ F.T + Qe
        res["ekf"] = (np.array(ests), np.array(covs))
        nav_true = np.hstack([X[:, :n], X[:, n : 2 * n] + (X[:, 2 * n :] if model.current else 0)])
        out["truth"]["metrics"].append(path_metrics(traj, model, X))
        out["truth"]["sat"].append(n_sat)
        # the applied inputs' displacement d and its rate, integrated step by step
        d = np.zeros((N, n))
        dd = np.zeros((N, n))
        for k in range(N - 1):
            h = traj.t[k + 1] - traj.t[k]
            d[k + 1] = d[k] + dd[k] * h + 0.5 * u_app[k] * h**2
            dd[k + 1] = dd[k] + u_app[k] * h

        # KF in the paper's coordinates plus (β_a), e, f, g
        mz = mx + 2
        idx = {"a": mx, "b": mx + 1}
        m = mz + (1 if aug else 0) + 3
        if aug:
            idx["ba"] = mz
        idx["e"], idx["f"], idx["g"] = m - 3, m - 2, m - 1
        y0 = 0.5 * Y["range"][0][0] ** 2 - 0.5 * sr**2
        var0 = Y["range"][0][0] ** 2 * sr**2 + 0.5 * sr**4
        zk = np.zeros(m)
        zk[:n] = xhat0[:n] - b
        zk[n:mx] = xhat0[n:mx]
        zk[mx : mx + 2] = ex0
        Pk = np.zeros((m, m))
        Pk[:mz, :mz] = P0k
        if aug:
            Pk[mz, mz] = var0
        fk = None
        if backend == "filterpy":
            fk = FpKF(dim_x=m, dim_z=1, dim_u=n)
            fk.x, fk.P = zk.copy(), Pk.copy()
        ests, covs = [], []
        Tk = np.zeros((2 * n, m))
        Tk[:, :mx] = Tn
        for k in range(N):
            H, y, R = kf_rows(None, k, m, idx, y0, var0, d)
            if H.size:
                if fk:
                    fk.update(y, R=R, H=H)
                else:
                    zk, Pk = joint_update(zk, Pk, H, y, H @ zk, R)
            if rec[k]:
                zz, PP = (fk.x, fk.P) if fk else (zk, Pk)
                est = Tk @ zz
                est[:n] += b
                ests.append(est)
                covs.append(Tk @ PP @ Tk.T)
            if k < N - 1:
                h = traj.t[k + 1] - traj.t[k]
                F = np.eye(m)
                F[:n, n : 2 * n] += h * np.eye(n)
                if model.current:
                    F[:n, 2 * n : 3 * n] += h * np.eye(n)
                F[idx["e"], idx["f"]], F[idx["e"], idx["g"]], F[idx["f"], idx["g"]] = (
                    h,
                    h * h,
                    2 * h,
                )
                Bu = np.zeros(m)
                Bu[:n] = 0.5 * h**2 * u_app[k]
                Bu[n : 2 * n] = h * u_app[k]
                zc = fk.x if fk else zk
                zpred = F @ zc + Bu
                # noise gain at the noise-free prediction of the step's end
                cp = zpred[:n] - d[k + 1]
                cv = zpred[n : 2 * n] + (zpred[2 * n : 3 * n] if model.current else 0) - dd[k + 1]
                Gam = np.zeros((m, mz))
                Gam[:mz, :mz] = np.eye(mz)
                if cfg.kf_coupling:
                    Gam[idx["e"], :n] = cp
                    Gam[idx["f"], :n] = cv
                    Gam[idx["f"], n : 2 * n] = cp
                    Gam[idx["g"], n : 2 * n] = cv
                    if model.current:
                        Gam[idx["f"], 2 * n : 3 * n] = cp
                        Gam[idx["g"], 2 * n : 3 * n] = cv
                Qk = Gam @ qk @ Gam.T
                if continuous:  # ∫_0^h Φ(h - s) Γ(s) W Γ(s)ᵀ Φ(h - s)ᵀ ds, gains at time s
                    Qk = np.zeros((m, m))
                    gx, gw = np.polynomial.legendre.leggauss(4)
                    for xs, ws in zip(gx, gw, strict=True):
                        sg = 0.5 * h * (xs + 1.0)
                        lag = h - sg
                        Fl = np.eye(m)
                        Fl[:n, n : 2 * n] += lag * np.eye(n)
                        if model.current:
                            Fl[:n, 2 * n : 3 * n] += lag * np.eye(n)
                        Fl[idx["e"], idx["f"]], Fl[idx["e"], idx["g"]] = lag, lag**2
                        Fl[idx["f"], idx["g"]] = 2 * lag
                        cps = (
                            zc[:n]
                            - d[k]
                            + sg
                            * (zc[n : 2 * n] + (zc[2 * n : 3 * n] if model.current else 0) - dd[k])
                        )
                        cvs = zc[n : 2 * n] + (zc[2 * n : 3 * n] if model.current else 0) - dd[k]
                        Gs = np.zeros((m, mz))
                        Gs[:mz, :mz] = np.eye(mz)
                        if cfg.kf_coupling:  # ḟ = 2g + (p - d)·w_ν,  ġ = (ν - ḋ)·w_ν
                            for cols in [range(n, 2 * n)] + (
                                [range(2 * n, 3 * n)] if model.current else []
                            ):
                                Gs[idx["f"], list(cols)] = cps
                                Gs[idx["g"], list(cols)] = cvs
                        Qk += 0.5 * h * ws * (Fl @ Gs @ qk @ Gs.T @ Fl.T)
                if fk:
                    fk.F, fk.Q = F, Qk
                    fk.B = np.zeros((m, n))
                    fk.predict(u=np.zeros(n))
                    fk.x = fk.x + Bu
                else:
                    zk, Pk = zpred, F @ Pk @ F.T + Qk
        res["kf"] = (np.array(ests), np.array(covs))

        nt = nav_true[rec]
        if r == 0:
            truth0 = nt
        for f, (est, C) in res.items():
            e = est - nt
            out[f]["se"].append(np.sum(e[:, :n] ** 2, axis=1))
            out[f]["var"].append(np.trace(C[:, :n, :n], axis1=1, axis2=2))
            out[f]["nees"].append(
                np.einsum("ki,ki->k", e, np.linalg.solve(C, e[..., None])[..., 0])
            )
            if r == 0:
                out[f]["est"] = est
                out[f]["std"] = np.sqrt(np.diagonal(C, axis1=1, axis2=2))
    return out, truth0, traj.t[rec]


def close(a, b, name):
    a, b = np.asarray(a), np.asarray(b)
    scale = max(float(np.max(np.abs(b))), 1e-300)
    err = float(np.max(np.abs(a - b))) / scale
    assert err <= TOL, f"{name}: relative difference {err:.2e} > {TOL:g}"


def check(traj, cfg, runs=3, seed=7, record_every=7, backend="numpy", guidance=None):
    nav = "ekf" if guidance is None else guidance.navigation
    names = ("ekf", "kf") + (("gsf",) if nav == "gsf" else ())
    mc = monte_carlo(
        traj, cfg, runs=runs, seed=seed, record_every=record_every, guidance=guidance, filters=names
    )
    ref, truth0, t_rec = reference(traj, cfg, runs, seed, record_every, backend, guidance, nav)
    np.testing.assert_array_equal(mc.t, t_rec)
    close(mc.example.truth, truth0, "truth of run 0")
    for f in names:
        st, o = mc.stats(f), ref[f]
        close(mc.example.estimate[f], o["est"], f"{f} estimate of run 0")
        close(mc.example.std[f], o["std"], f"{f} std of run 0")
        close(st.rmse_pos_t, np.sqrt(np.mean(o["se"], axis=0)), f"{f} rmse_pos_t")
        close(st.pos_std_t, np.sqrt(np.mean(o["var"], axis=0)), f"{f} pos_std_t")
        close(st.nees_t, np.mean(o["nees"], axis=0), f"{f} nees_t")
    tr, want = mc.truth, np.array(ref["truth"]["metrics"])
    close(tr.closest_range_runs, want[:, 0], "closest range")
    close(tr.tracking_rmse_runs, want[:, 1], "tracking RMSE")
    close(tr.final_drift_runs, want[:, 2], "final drift")
    close(tr.max_speed_runs, want[:, 3], "max speed")
    steps = traj.n_samples - 1
    np.testing.assert_array_equal(np.rint(tr.saturated_fraction_runs * steps), ref["truth"]["sat"])
    return mc


def circle(duration=40.0, dt=0.1, dim=2):
    return (
        gen.circle_z(30.0, 1.5, duration, z0=3.0, z_amp=2.0, z_period=20.0).sample(dt)
        if dim == 3
        else (gen.circle(30.0, 1.5, duration, center=(5.0, -3.0)).sample(dt))
    )


CASES = {
    "2d-range-1hz": (2, "range", False, "half-squared", {"range": 1.0}),
    "2d-plain-range": (2, "range", False, "range", {"range": 2.0}),
    "2d-range-every-step": (2, "range", False, "half-squared", {}),
    "3d-range-dvl-depth": (
        3,
        "range,dvl-bottom,depth",
        False,
        "half-squared",
        {"range": 1.0, "dvl-bottom": 5.0, "depth": 2.0},
    ),
    "2d-current-water": (
        2,
        "range,dvl-water",
        True,
        "half-squared",
        {"range": 1.0, "dvl-water": 5.0},
    ),
    "3d-current-bottom": (3, "range,dvl-bottom", True, "range", {"range": 0.5}),
    "multirate-case-b": (3, "range,dvl", False, "half-squared", {"range": 0.2}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_epoch_monte_carlo_equals_per_step_recursion(case):
    dim, sensors, current, form, rates = CASES[case]
    model = make_model(
        dim, sensors, current=current, beacon=[2.0, -1.0, -4.0][:dim], range_form=form
    )
    cfg = EstimationConfig.paper(model, 0.1, rates_hz=rates)
    check(circle(dim=dim), cfg)


def test_dropout_inflate_uncoupled_fixed_offset():
    model = make_model(2, "range,dvl-water")
    cfg = EstimationConfig.paper(
        model,
        0.1,
        rates_hz={"range": 2.0, "dvl-water": 5.0},
        dropout={"range": 0.3, "dvl-water": 0.2},
        y0_mode="inflate",
        kf_coupling=False,
        init_error=np.array([1.0, -0.5, 0.05, 0.02]),
    )
    mc = check(circle(), cfg)
    assert np.isnan(mc.example.range_m).sum() > 0  # dropped readings were exercised


def test_irregular_steps():
    """Non-uniform steps: composed predictions and the Gauss rule on irregular points."""
    rng_ = np.random.default_rng(3)
    t = np.concatenate([[0.0], np.cumsum(rng_.uniform(0.05, 0.2, 300))])
    u = np.column_stack([0.05 * np.sin(0.2 * t), 0.05 * np.cos(0.15 * t)])
    traj = Trajectory.from_inputs(t, [40.0, -10.0], [0.3, 1.0], u)
    cfg = EstimationConfig.paper(make_model(2, "range"), 0.1, rates_hz={"range": 0.7})
    check(traj, cfg, record_every=5)


def test_long_segments_use_the_gauss_rule():
    """Range every 10 s on a 20 Hz grid: 200-step segments, where the KF's coupled noise is
    summed by the 5-node rule instead of step by step."""
    traj = gen.circle(40.0, 1.2, 120.0).sample(0.05)
    cfg = EstimationConfig.paper(make_model(2, "range"), 0.05, rates_hz={"range": 0.1})
    cfg = replace(cfg, q_kf=cfg.q_kf * 1e4, q_ekf=cfg.q_ekf * 1e4)  # a noise that matters
    check(traj, cfg, runs=2, record_every=37)


@pytest.mark.parametrize("case", ["2d-range-1hz", "3d-range-dvl-depth", "2d-current-water"])
def test_filterpy_is_a_second_oracle(case):
    dim, sensors, current, form, rates = CASES[case]
    model = make_model(
        dim, sensors, current=current, beacon=[2.0, -1.0, -4.0][:dim], range_form=form
    )
    cfg = EstimationConfig.paper(model, 0.1, rates_hz=rates)
    check(circle(duration=20.0, dim=dim), cfg, runs=2, backend="filterpy")


def test_kf_with_noise_on_the_extras_and_a_full_q():
    """The KF's general paths: noise on (p0·ν0, |ν0|²) (the paper's Q_KF has it; mapped into
    the chain coordinates by J(τ)) and a q_kf with correlated entries (not diagonal)."""
    model = make_model(2, "range")
    cfg = EstimationConfig.paper(model, 0.1, rates_hz={"range": 0.5})
    qk = cfg.q_kf.copy()
    qk[4, 4] = qk[5, 5] = 1e-8
    qk[0, 2] = qk[2, 0] = 0.5 * np.sqrt(qk[0, 0] * qk[2, 2])  # p_x, v_x correlated
    check(circle(), replace(cfg, q_kf=qk), record_every=5)


# ----------------------------------------------------------------------------- physical noise
@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_physical_noise_equals_per_step_recursion(case):
    """The continuous white acceleration (and with a current its random walk) integrated over
    whole gaps equals the oracle's per-step exact discretisation; a noise 10x the default so
    that the coupling of the KF matters."""
    dim, sensors, current, form, rates = CASES[case]
    model = make_model(
        dim, sensors, current=current, beacon=[2.0, -1.0, -4.0][:dim], range_form=form
    )
    cfg = EstimationConfig(
        model=model, rates_hz=rates, accel_noise=3e-3, current_noise=1e-3 if current else 0.0
    )
    check(circle(dim=dim), cfg)


@pytest.mark.slow
def test_physical_noise_on_irregular_steps_and_long_gaps():
    """Non-uniform steps (the truth's factor scales with each step) and 10 s gaps on a 20 Hz
    grid (the KF's coupled noise integrated by the Gauss–Legendre rule of the whole gap)."""
    rng_ = np.random.default_rng(5)
    t = np.concatenate([[0.0], np.cumsum(rng_.uniform(0.05, 0.2, 300))])
    u = np.column_stack([0.05 * np.sin(0.2 * t), 0.05 * np.cos(0.15 * t)])
    traj = Trajectory.from_inputs(t, [40.0, -10.0], [0.3, 1.0], u)
    cfg = EstimationConfig(model=make_model(2, "range"), rates_hz={"range": 0.7}, accel_noise=2e-3)
    check(traj, cfg, record_every=5)
    cfg = EstimationConfig(model=make_model(2, "range"), rates_hz={"range": 0.1}, accel_noise=3e-3)
    check(gen.circle(40.0, 1.2, 120.0).sample(0.05), cfg, runs=2, record_every=37)


# ----------------------------------------------------------------------------- closed loop
#: Bounds near the circle's own acceleration (0.075 m/s² in 2D) and speed (1.5 m/s): the
#: feedback on the prior's error saturates both, so every branch of the law is exercised.
GUIDANCE = Guidance.from_limits(0.09, speed=1.55, error_scale_m=0.5)


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_closed_loop_equals_the_per_step_loop(case):
    """EKF + guidance + truth step by step in numpy (the truth as x_{k+1} = F x_k + G u_k +
    L_k z_k, the guidance from the oracle's own EKF) against the kernel's decomposition
    x = x_plan + c + δ; the KF on the applied inputs; the truth's metrics; to 1e-9."""
    dim, sensors, current, form, rates = CASES[case]
    model = make_model(
        dim, sensors, current=current, beacon=[2.0, -1.0, -4.0][:dim], range_form=form
    )
    cfg = EstimationConfig(model=model, rates_hz=rates, accel_noise=3e-3)
    mc = check(circle(dim=dim), cfg, guidance=GUIDANCE)
    assert mc.mode == "closed-loop"
    assert np.all(mc.truth.saturated_fraction_runs > 0)  # the saturation was exercised


@pytest.mark.slow
@pytest.mark.parametrize("case", ["2d-range-1hz", "2d-current-water", "3d-current-bottom"])
def test_closed_loop_steered_on_the_gaussian_sum(case):
    """The vehicle steers on the Gaussian sum's mixture mean: in numpy, every member an EKF
    (joint update at its prior, weight times its innovations' likelihood), the guidance from the
    mixture, the EKF afterwards on the same true path, readings and applied inputs; against the
    kernel (the members shifted by the corrections' response, the EKF passive); to 1e-9."""
    dim, sensors, current, form, rates = CASES[case]
    model = make_model(
        dim, sensors, current=current, beacon=[2.0, -1.0, -4.0][:dim], range_form=form
    )
    cfg = EstimationConfig(model=model, rates_hz=rates, accel_noise=3e-3)
    mc = check(circle(dim=dim), cfg, guidance=replace(GUIDANCE, navigation="gsf"))
    assert mc.to_dict()["guidance"]["navigation"] == "gsf"
    assert np.all(mc.truth.saturated_fraction_runs > 0)


def test_closed_loop_with_the_paper_noise_and_filterpy():
    model = make_model(2, "range,dvl-water", current=True)
    cfg = EstimationConfig.paper(model, 0.1, rates_hz={"range": 1.0, "dvl-water": 5.0})
    check(circle(duration=20.0), cfg, runs=2, backend="filterpy", guidance=GUIDANCE)
