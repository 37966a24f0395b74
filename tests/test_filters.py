"""Every filter against the same cases: an independent numpy recursion per filter, and the
agreements theory requires between filters.

Each case is a path with readings at every sample (so every sample is an epoch and every
segment one step), drawn once and given to all filters. For each filter a plain numpy
recursion written from the equations (nothing of the library's filters; joint updates, one
step at a time) must reproduce:

* the compiled batch run (:meth:`Filter.run`): the history of run 0 at the records (estimate
  and std of ``(p, p')``);
* the epoch-by-epoch interface (:meth:`Filter.begin`, :meth:`Filter.predict`,
  :meth:`Filter.update`, :meth:`Filter.state`, :meth:`Filter.covariance`): every run's state
  and covariance at the last epoch.

The references: the EKF of ``(p, v)`` with the half-squared range linearised at the prior
(and, for the second-order update, either range form with the curvature's mean and variance
over the prior from the range's Hessian);
the augmented KF in its chain coordinates ``(p - b, v, κ, φ, γ)`` with ``ȳ = dᵀ p + κ``
(the uncoupled output model: without noise on ``(α, β)`` its chain has no noise); the Gaussian
sum as independent EKFs from the filter's own split, weighted by their innovations'
likelihoods and mixed. Tolerance 1e-9 relative to each array's magnitude (the compiled
filters run sequential scalar Joseph updates and composed predictions: the same equations in
a different order, measured ~1e-13 here).

Theory: a Gaussian sum of one component is the EKF (to 1e-12, the same arithmetic).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from obsplan.core.errors import ConfigError
from obsplan.estimation import EstimationConfig
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.channel import BIAS_PRIOR_STD_M, SCALE_PRIOR_STD
from obsplan.estimation.columns import N_INFO
from obsplan.estimation.filters.base import REGISTRY, Filter, make_filter
from obsplan.estimation.filters.gsf import GaussianSumFilter
from obsplan.estimation.montecarlo.runs import PathSetup, draw_run, nav_of, start_of
from obsplan.estimation.montecarlo.simulate import FILTERS
from obsplan.estimation.montecarlo.truth import noisy_readings
from obsplan.model.vehicle import make_model
from obsplan.trajectory import generators as gen

TOL = 1e-9
RUNS = 3


def _case(
    name: str,
    range_form: str = "half-squared",
    ekf_update: str = "first-order",
    scale_state: str = "auto",
    bias_state: str = "auto",
):
    if name == "circle-2d-range":
        traj = gen.circle(30.0, 1.5, 12.0, center=(4.0, -2.0)).sample(0.1)
        model = make_model(2, "range", beacon=(1.0, 3.0), range_form=range_form)
    else:  # a climbing turn in 3D with DVL and depth, beacon off the origin and above
        traj = gen.circle_z(25.0, 1.0, 10.0, z0=10.0, z_amp=2.0, z_period=20.0).sample(0.1)
        model = make_model(3, "range,dvl,depth", beacon=(5.0, -3.0, 2.0), range_form=range_form)
    cfg = replace(
        EstimationConfig.paper(model, 0.1),
        kf_coupling=False,
        process_noise=False,
        ekf_update=ekf_update,
        scale_state=scale_state,
        bias_state=bias_state,
    )
    setup = PathSetup(traj, cfg, tuple(REGISTRY), None, RUNS)
    plan = setup.plan
    assert plan.n_epochs == traj.n_samples  # readings at every sample: one step per segment
    Ys, truths, starts = [], [], []
    for r in range(RUNS):
        dr = draw_run(setup, seed=5, run=r)
        x = setup.nominal  # no process noise in the truth: the nominal path
        Ys.append(
            noisy_readings(cfg.model, x[plan.epoch_pt], plan.reports, dict(cfg.noise), dr.readings)
        )
        truths.append(nav_of(cfg.model, x[plan.rec_pt]))
        starts.append(start_of(cfg.model, x[0], dr, Ys[-1][0, 0]))
    return traj, cfg, setup, np.stack(Ys, axis=2), np.stack(truths), starts


CASES = ("circle-2d-range", "turn-3d-dvl-depth")


@pytest.fixture(scope="module", params=CASES)
def case(request):
    return _case(request.param)


# ----------------------------------------------------------------------------- references
def _step(x, h, u, n):
    """Exact ZOH step of ``(p, v, ...)`` with input ``u`` held over ``h``: F x + B u."""
    x = x.copy()
    x[:n] += h * x[n : 2 * n] + 0.5 * h * h * u
    x[n : 2 * n] += h * u
    return x


def _F(m, n, h):
    F = np.eye(m)
    F[:n, n : 2 * n] = h * np.eye(n)
    return F


def _linear_rows(model, m, bz=0.0):
    """Rows after the range: DVL on ``v`` then depth on ``p_z`` (``bz``: the state's offset)."""
    n, rows = model.dim, []
    for s in model.sensors:
        if s.startswith("dvl"):
            for i in range(n):
                H = np.zeros(m)
                H[n + i] = 1.0
                rows.append((H, 0.0, s))
        elif s == "depth":
            H = np.zeros(m)
            H[n - 1] = 1.0
            rows.append((H, bz, s))
    return rows


def _joint(x, P, H, nu, R):
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    IKH = np.eye(x.size) - K @ H
    ll = -0.5 * (nu @ np.linalg.solve(S, nu) + np.log(np.linalg.det(S)))
    return x + K @ nu, IKH @ P @ IKH.T + K @ R @ K.T, ll


def _range_function(x, beacon, range_form, ks=-1, kb=-1):
    """The predicted range ``h`` (``r̃ = k ρ + β``, or ``½ r̃²`` half-squared), its gradient
    and its Hessian over the whole state ``x``."""
    n, m = beacon.size, x.size
    rel = x[:n] - beacon
    rho = np.linalg.norm(rel)
    u = rel / rho
    k = x[ks] if ks >= 0 else 1.0
    rt = k * rho + (x[kb] if kb >= 0 else 0.0)
    g = np.zeros(m)  # the gradient of r̃
    g[:n] = k * u
    Hr = np.zeros((m, m))  # the Hessian of r̃
    Hr[:n, :n] = k * (np.eye(n) - np.outer(u, u)) / rho
    if ks >= 0:
        g[ks] = rho
        Hr[:n, ks] = Hr[ks, :n] = u
    if kb >= 0:
        g[kb] = 1.0
    if range_form == "half-squared":
        return 0.5 * rt * rt, rt * g, np.outer(g, g) + rt * Hr
    return rt, g, Hr


def _ekf_update(model, cfg, x, P, y, ks=-1, kb=-1):
    """The EKF's joint update; ``ks``, ``kb >= 0``: ``x[ks]`` is the range scale ``k`` and
    ``x[kb]`` the range bias ``β``: the range row predicts ``r̃ = k ρ + β`` (``½ r̃²``
    half-squared), and the second-order terms take the Hessian over ``(p, k, β)``."""
    n, m, s = model.dim, x.size, cfg.noise["range"]
    rows, nus, Rs = [], [], []
    if np.isfinite(y[0]):
        h, H, G = _range_function(x, model.beacon_array, model.range_form, ks, kb)
        idx = list(range(n)) + [i for i in (ks, kb) if i >= 0]
        if model.range_form == "half-squared":
            nu = 0.5 * y[0] ** 2 - 0.5 * s * s - h
            R = y[0] ** 2 * s * s + 0.5 * s**4
        else:
            nu, R = y[0] - h, s * s
        if cfg.ekf_update == "second-order":  # Gaussian second-order filter
            GP = G[np.ix_(idx, idx)] @ P[np.ix_(idx, idx)]
            nu -= 0.5 * np.trace(GP)
            R += 0.5 * np.trace(GP @ GP)
        rows.append(H)
        nus.append(nu)
        Rs.append(R)
    for o, (H, off, sensor) in enumerate(_linear_rows(model, m), start=1):
        if np.isfinite(y[o]):
            rows.append(H)
            nus.append(y[o] - H @ x - off)
            Rs.append(cfg.noise[sensor] ** 2)
    if not rows:
        return x, P, 0.0
    return _joint(x, P, np.array(rows), np.array(nus), np.diag(Rs))


def _ekf_ref(traj, cfg, setup, starts_x, ks=-1, kb=-1):
    """Members (x, P, readings (E, outputs)) -> their histories: per sample (x, P, summed
    log-likelihood); ``ks``, ``kb``: the indices of the range scale and bias (-1: none),
    constant."""
    model, n = cfg.model, cfg.model.dim
    q = setup.noise.q_ekf
    c = (ks >= 0) + (kb >= 0)
    q = np.pad(q, ((0, c), (0, c)))
    out = []
    for x, P, Yr in starts_x:
        ll, hist = 0.0, []
        for k in range(traj.n_samples):
            if k:
                h = traj.t[k] - traj.t[k - 1]
                x = _step(x, h, traj.u[k - 1], n)
                F = _F(x.size, n, h)
                P = F @ P @ F.T + q
            x, P, dl = _ekf_update(model, cfg, x, P, Yr[k], ks, kb)
            ll += dl
            hist.append((x, P, ll))
        out.append(hist)
    return out


def _nav(model, x, P, off):
    n = model.dim
    assert not model.current  # the cases have no current: (p, p') = (p, v)
    return x[: 2 * n] + np.r_[np.broadcast_to(off, (n,)), np.zeros(n)], P[: 2 * n, : 2 * n]


def ref_ekf(filt, traj, cfg, setup, Y, states):
    members = [(s[0], s[1], Y[:, :, r]) for r, s in enumerate(states)]
    hist = _ekf_ref(traj, cfg, setup, members, filt.scale_index, filt.bias_index)
    return [[_nav(cfg.model, x, P, 0.0) for x, P, _ in h] for h in hist], [
        (h[-1][0], h[-1][1]) for h in hist
    ]


def ref_gsf(filt, traj, cfg, setup, Y, states):
    hists, finals = [], []
    for r, (X0, P0, lw0) in enumerate(states):
        C = len(lw0)
        members = [(X0[c], P0[c], Y[:, :, r]) for c in range(C)]
        comps = _ekf_ref(traj, cfg, setup, members, filt.ekf.scale_index, filt.ekf.bias_index)
        run = []
        for k in range(traj.n_samples):
            lw = np.array([lw0[c] + comps[c][k][2] for c in range(len(lw0))])
            w = np.exp(lw - lw.max())
            w /= w.sum()
            xs = np.array([comps[c][k][0] for c in range(len(lw0))])
            mean = w @ xs
            cov = sum(
                w[c] * (comps[c][k][1] + np.outer(xs[c] - mean, xs[c] - mean))
                for c in range(len(lw0))
            )
            run.append((mean, cov))
        hists.append([_nav(cfg.model, x, P, 0.0) for x, P in run])
        finals.append(run[-1])
    return hists, finals


def ref_kf(filt, traj, cfg, setup, Y, states):
    model, n = cfg.model, cfg.model.dim
    mx, m, ks, kb = model.state_dim, filt.state_dim, filt.scale_index, filt.bias_index
    s = cfg.noise["range"]
    qk = setup.noise.q_kf
    assert not np.any(qk[mx:]) and not np.any(qk[:, mx:])  # no noise on (α, β): none on the chain
    Q = np.zeros((m, m))
    Q[:mx, :mx] = qk[:mx, :mx]
    bz = model.beacon_array[-1] if n == 3 else 0.0
    hists, finals = [], []
    for r, (z, P, y0, _) in enumerate(states):
        Yr = Y[:, :, r]
        d, dd = np.zeros(n), np.zeros(n)
        run = []
        for k in range(traj.n_samples):
            if k:
                h = traj.t[k] - traj.t[k - 1]
                u = traj.u[k - 1]
                z = _step(z, h, u, n)
                d, dd = d + h * dd + 0.5 * h * h * u, dd + h * u
                F = _F(m, n, h)
                F[mx, mx + 1], F[mx, mx + 2], F[mx + 1, mx + 2] = h, h * h, 2 * h
                z = np.r_[z[:mx], F[mx:, mx:] @ z[mx:]]
                P = F @ P @ F.T + Q
            rows, nus, Rs = [], [], []
            if k and np.isfinite(Yr[k, 0]):
                H = np.zeros(m)
                ym = 0.5 * Yr[k, 0] ** 2 - 0.5 * s * s - y0  # the measured y - y0
                H[:n], H[mx] = d, 1.0
                R = Yr[k, 0] ** 2 * s * s + 0.5 * s**4
                nu = ym + 0.5 * d @ d - H @ z
                if ks >= 0:  # y - y0 = (1 + g) A, A = hᵀz - ½|d|²: Gaussian moments of g A
                    hA = H.copy()
                    A = hA @ z - 0.5 * d @ d
                    pga, paa = hA @ P[:, ks], hA @ P @ hA
                    H = (1.0 + z[ks]) * hA
                    H[ks] = A
                    nu = ym - (1.0 + z[ks]) * A - pga
                    R += P[ks, ks] * paa + pga**2
                if kb >= 0:  # + β (R_t - R_0), linearised (module kf, "A range bias")
                    W = (H[:n] @ z[:n] + H[mx] * z[mx]) - (1.0 + (z[ks] if ks >= 0 else 0.0)) * (
                        0.5 * d @ d
                    )
                    beta = z[kb]
                    R0 = np.sqrt(2 * y0 + s * s) - beta
                    Rt = np.sqrt(R0**2 + 2 * W)
                    H = (1.0 + beta / Rt) * H
                    H[kb] = Rt - R0 + beta * (1.0 - R0 / Rt)
                    nu -= beta * (Rt - R0)
                rows.append(H)
                nus.append(nu)
                Rs.append(R)
            for o, (H, off, sensor) in enumerate(_linear_rows(model, m, bz), start=1):
                if np.isfinite(Yr[k, o]):
                    rows.append(H)
                    nus.append(Yr[k, o] - H @ z - off)
                    Rs.append(cfg.noise[sensor] ** 2)
            if rows:
                z, P, _ = _joint(z, P, np.array(rows), np.array(nus), np.diag(Rs))
            run.append(_nav(model, z, P, model.beacon_array))
            last = (z, P)
        hists.append(run)
        finals.append(last)
    return hists, finals


REFERENCES = {"ekf": ref_ekf, "kf": ref_kf, "gsf": ref_gsf}


def close(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    scale = max(float(np.max(np.abs(b))), 1e-300)
    err = float(np.max(np.abs(a - b))) / scale
    assert err <= TOL, f"{what}: relative difference {err:.2e} > {TOL:g}"


# ----------------------------------------------------------------------------- tests
def test_every_registered_filter_has_a_reference_and_a_description():
    assert set(REFERENCES) == set(REGISTRY) == set(FILTERS)
    for name, cls in REGISTRY.items():
        assert issubclass(cls, Filter) and cls.name == name and FILTERS[name] == cls.description


def test_unknown_filter_names_the_choices():
    cfg = EstimationConfig.paper(make_model(2, "range"), 0.1)
    with pytest.raises(ConfigError, match="unknown filter 'ukf'; choose from ekf"):
        make_filter("ukf", cfg, cfg.covariances(0.1), cfg.process_noise_model())


@pytest.mark.parametrize("name", list(REGISTRY))
def test_filter_matches_its_reference(case, name):
    traj, cfg, setup, Y, truth, starts = case
    f = setup.filters[name]
    states = [f.start(*st) for st in starts]
    hists, finals = REFERENCES[name](f, traj, cfg, setup, Y, states)
    rec = setup.records

    # the compiled batch: run 0's history at the records
    n2 = 2 * cfg.model.dim
    sums = np.zeros((2, rec.size, 3 + n2))
    info = np.zeros((RUNS, N_INFO))
    ex = np.zeros((2, rec.size, n2))
    f.run(RunBatch(setup.ctx, states, Y), RunRecord(truth, sums, info, 0, ex))
    est = np.array([hists[0][k][0] for k in rec])
    std = np.array([np.sqrt(np.diag(hists[0][k][1])) for k in rec])
    close(ex[0], est, f"{name} batch estimate")
    close(ex[1], std, f"{name} batch std")
    err2 = np.array(
        [[(hists[r][k][0] - truth[r, j]) ** 2 for j, k in enumerate(rec)] for r in range(RUNS)]
    )
    close(
        sums[0, :, 3 : 3 + cfg.model.dim].sum(axis=1)
        + sums[1, :, 3 : 3 + cfg.model.dim].sum(axis=1),
        err2[:, :, : cfg.model.dim].sum(axis=(0, 2)),
        f"{name} squared position errors",
    )

    # epoch by epoch: every run's state and covariance at the last epoch
    run = f.filter_all(f.begin(RunBatch(setup.ctx, states, Y)))
    assert run.epoch == traj.n_samples - 1
    X, P = f.state(run), f.covariance(run)
    assert X.shape == (f.state_dim, RUNS) and P.shape == (f.state_dim, f.state_dim, RUNS)
    for r, (x_ref, P_ref) in enumerate(finals):
        close(X[:, r], x_ref, f"{name} state, run {r}")
        close(P[:, :, r], P_ref, f"{name} covariance, run {r}")


def _matches_reference(name, f, traj, cfg, setup, Y, truth, states):
    """Filter ``f`` (registered as ``name``) batch and epoch by epoch against its numpy
    reference on the readings ``Y``: run 0's estimate and std at the records, every run's
    final state and covariance; returns the filter's final ``(X, P)``."""
    hists, finals = REFERENCES[name](f, traj, cfg, setup, Y, states)
    rec = setup.records
    n2 = 2 * cfg.model.dim
    sums, ex = np.zeros((2, rec.size, 3 + n2)), np.zeros((2, rec.size, n2))
    f.run(RunBatch(setup.ctx, states, Y), RunRecord(truth, sums, np.zeros((RUNS, N_INFO)), 0, ex))
    close(ex[0], np.array([hists[0][k][0] for k in rec]), f"{name} batch estimate")
    close(ex[1], np.array([np.sqrt(np.diag(hists[0][k][1])) for k in rec]), f"{name} std")
    run = f.filter_all(f.begin(RunBatch(setup.ctx, states, Y)))
    X, P = f.state(run), f.covariance(run)
    for r, (x_ref, P_ref) in enumerate(finals):
        close(X[:, r], x_ref, f"{name} state, run {r}")
        close(P[:, :, r], P_ref, f"{name} covariance, run {r}")
    return X, P


@pytest.mark.parametrize("case_name", CASES)
def test_kf_scale_state_matches_its_reference(case_name):
    """The augmented KF with a range-scale state ``g = k² - 1`` (the bilinear row ``(1 + g) A``
    by its Gaussian moments), batch and epoch by epoch, against the numpy recursion; the state
    is the chain's plus one, with the prior ``(2 σ_s)²`` and no correlation."""
    traj, cfg, setup, Y, truth, starts = _case(case_name, scale_state="on")
    f = setup.filters["kf"]
    mx = cfg.model.state_dim
    assert f.state_dim == mx + 4 and f.scale_index == mx + 3
    states = [f.start(*st) for st in starts]
    P0 = states[0][1]
    assert P0[mx + 3, mx + 3] == pytest.approx((2 * SCALE_PRIOR_STD) ** 2)
    assert not np.any(P0[mx + 3, : mx + 3]) and states[0][0][mx + 3] == 0.0
    X, P = _matches_reference("kf", f, traj, cfg, setup, Y, truth, states)
    # the readings are unscaled: the scale's estimate stays near 0 (g = k² - 1 at k = 1),
    # within 4 of its posterior stds
    c, sc = X[mx + 3], np.sqrt(P[mx + 3, mx + 3])
    assert np.all(np.abs(c) < 4 * sc) and np.all(sc < 2 * SCALE_PRIOR_STD)


@pytest.mark.parametrize("scale_state", ["off", "on"])
@pytest.mark.parametrize("case_name", CASES)
def test_kf_bias_state_matches_its_reference(case_name, scale_state):
    """The augmented KF with a range-bias state ``β_r`` (the row's entry ``r_m - r_0``, exact
    for the difference of the squared ranges; module kf, "A range bias"), alone and after a
    scale state, on ranges 2 m long (the anchor's too), batch and epoch by epoch, against the
    numpy recursion; the bias's estimate is consistent with the 2 m."""
    traj, cfg, setup, Y, truth, starts = _case(case_name, scale_state=scale_state, bias_state="on")
    Y = Y.copy()
    Y[:, 0, :] += 2.0
    starts = [(x0, extra0, Y[0, 0, r]) for r, (x0, extra0, _) in enumerate(starts)]
    f = setup.filters["kf"]
    mx, kb = cfg.model.state_dim, f.bias_index
    assert f.state_dim == mx + 4 + (scale_state == "on") and kb == f.state_dim - 1
    states = [f.start(*st) for st in starts]
    P0 = states[0][1]
    assert P0[kb, kb] == pytest.approx(BIAS_PRIOR_STD_M**2) and not np.any(P0[kb, :kb])
    assert states[0][0][kb] == 0.0
    X, P = _matches_reference("kf", f, traj, cfg, setup, Y, truth, states)
    assert np.all(np.abs(X[kb] - 2.0) < 4 * np.sqrt(P[kb, kb]))
    assert np.all(np.sqrt(P[kb, kb]) < BIAS_PRIOR_STD_M)


SECOND_ORDER = [(c, f) for c in CASES for f in ("half-squared", "range")]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ekf", "gsf"])
@pytest.mark.parametrize("case_name, range_form", SECOND_ORDER)
def test_second_order_update_matches_its_reference(case_name, range_form, name):
    """The second-order range update (the EKF and the Gaussian sum's components), batch and
    epoch by epoch, against the numpy recursion with the Hessian of either range form; and it
    is a different filter from the first-order one on the same readings."""
    traj, cfg, setup, Y, truth, starts = _case(case_name, range_form, "second-order")
    f = setup.filters[name]
    assert f.ekf.second_order if name == "gsf" else f.second_order
    states = [f.start(*st) for st in starts]
    hists, finals = REFERENCES[name](f, traj, cfg, setup, Y, states)
    rec = setup.records
    n2 = 2 * cfg.model.dim
    sums, info = np.zeros((2, rec.size, 3 + n2)), np.zeros((RUNS, N_INFO))
    ex = np.zeros((2, rec.size, n2))
    f.run(RunBatch(setup.ctx, states, Y), RunRecord(truth, sums, info, 0, ex))
    close(ex[0], np.array([hists[0][k][0] for k in rec]), f"{name} second-order estimate")
    close(ex[1], np.array([np.sqrt(np.diag(hists[0][k][1])) for k in rec]), f"{name} std")
    run = f.filter_all(f.begin(RunBatch(setup.ctx, states, Y)))
    for r, (x_ref, P_ref) in enumerate(finals):
        close(f.state(run)[:, r], x_ref, f"{name} second-order state, run {r}")
        close(f.covariance(run)[:, :, r], P_ref, f"{name} second-order covariance, run {r}")
    # the first-order filter on the same readings ends elsewhere: the update is not a no-op
    first = replace(cfg, ekf_update="first-order")
    f1 = PathSetup(traj, first, (name,), None, RUNS).filters[name]
    run1 = f1.filter_all(f1.begin(RunBatch(setup.ctx, states, Y)))
    gap = np.max(np.abs(f1.covariance(run1) - f.covariance(run))) / np.max(np.abs(P_ref))
    assert gap > 1e3 * TOL


CALIBRATIONS = {"scale": ("on", "off"), "bias": ("off", "on"), "scale and bias": ("on", "on")}


@pytest.mark.slow
@pytest.mark.parametrize("calibration", list(CALIBRATIONS))
@pytest.mark.parametrize("ekf_update", ["first-order", "second-order"])
@pytest.mark.parametrize("name", ["ekf", "gsf"])
@pytest.mark.parametrize("case_name, range_form", SECOND_ORDER)
def test_ekf_calibration_states_match_their_reference(
    case_name, range_form, name, ekf_update, calibration
):
    """The EKF and the Gaussian sum's components with a range-scale state ``k`` (prior
    ``N(1, σ_s²)``) and/or a range-bias state ``β`` (prior ``N(0, σ_β²)``), constant, on ranges
    1 % long and 2 m late, batch and epoch by epoch, against the numpy recursion; second order
    with the Hessian over ``(p, k, β)``, whose cross terms ``∂²h/∂p∂k`` (``u``; half-squared
    also the products of the gradient) couple the calibration's covariance with the position's.
    """
    scale, bias = CALIBRATIONS[calibration]
    traj, cfg, setup, Y, truth, starts = _case(case_name, range_form, ekf_update, scale, bias)
    Y = Y.copy()
    Y[:, 0, :] = 1.01 * Y[:, 0, :] + 2.0
    f = setup.filters[name]
    ekf = f.ekf if name == "gsf" else f
    ks, kb, mx = ekf.scale_index, ekf.bias_index, cfg.model.state_dim
    assert (ks >= 0, kb >= 0) == (scale == "on", bias == "on")
    assert ekf.state_dim == mx + (ks >= 0) + (kb >= 0) and max(ks, kb) == ekf.state_dim - 1
    assert ekf.second_order == (ekf_update == "second-order")
    _matches_reference(name, f, traj, cfg, setup, Y, truth, [f.start(*st) for st in starts])


@pytest.mark.parametrize("range_form", ["half-squared", "range"])
def test_the_reference_range_row_is_the_functions_derivatives(range_form):
    """The reference's gradient and Hessian of the calibrated range over ``(p, v, k, β)`` are
    the central differences of the function itself (step 1e-4: truncation ~1e-8, rounding
    ~1e-12 / 1e-8 on the Hessian; tolerance 1e-5 relative)."""
    beacon = np.array([1.0, -2.0, 3.0])
    x = np.array([21.0, 9.0, -4.0, 0.5, 0.2, 0.0, 1.013, 2.4])
    ks, kb, eps = 6, 7, 1e-4

    def h(z):
        return _range_function(z, beacon, range_form, ks, kb)[0]

    _, H, G = _range_function(x, beacon, range_form, ks, kb)
    E = np.eye(x.size) * eps
    grad = np.array([(h(x + E[i]) - h(x - E[i])) / (2 * eps) for i in range(x.size)])
    hess = np.array(
        [
            [
                (h(x + E[i] + E[j]) - h(x + E[i] - E[j]) - h(x - E[i] + E[j]) + h(x - E[i] - E[j]))
                / (4 * eps * eps)
                for j in range(x.size)
            ]
            for i in range(x.size)
        ]
    )
    np.testing.assert_allclose(H, grad, rtol=1e-5, atol=1e-5 * np.abs(H).max())
    np.testing.assert_allclose(G, hess, rtol=1e-5, atol=1e-5 * np.abs(G).max())


def test_second_order_terms_are_the_moments_of_the_range_over_the_prior():
    """What the second-order update adds, checked on the range itself: for ``δ ~ N(0, P)`` the
    remainder ``q = |p̂ + δ - b| - ρ - uᵀδ`` has mean ``½ tr(M P)`` and variance
    ``½ tr((M P)²)``. The neglected terms are (std / range)² ≈ 1 % of them here; 2e6 samples
    leave a sampling error under 0.3 %; tolerance 3 %."""
    rng = np.random.default_rng(7)
    b, p_hat = np.array([1.0, -2.0]), np.array([21.0, 9.0])
    A = rng.normal(size=(2, 2))
    P = A @ A.T + 0.5 * np.eye(2)
    rel = p_hat - b
    rho = np.linalg.norm(rel)
    u = rel / rho
    M = (np.eye(2) - np.outer(u, u)) / rho
    MP = M @ P
    d = rng.multivariate_normal(np.zeros(2), P, 2_000_000)
    q = np.linalg.norm(p_hat + d - b, axis=1) - rho - d @ u
    assert q.mean() == pytest.approx(0.5 * np.trace(MP), rel=0.03)
    assert q.var() == pytest.approx(0.5 * np.trace(MP @ MP), rel=0.03)


def test_second_order_is_a_checked_choice():
    model = make_model(2, "range")
    with pytest.raises(ConfigError, match="ekf_update must be 'first-order' or 'second-order'"):
        EstimationConfig(model=model, ekf_update="third-order")  # type: ignore[arg-type]


def test_predict_then_update_is_checked():
    traj, cfg, setup, Y, truth, starts = _case(CASES[0])
    f = setup.filters["ekf"]
    run = f.begin(RunBatch(setup.ctx, [f.start(*st) for st in starts], Y))
    f.update(run)
    with pytest.raises(ConfigError, match="updated already"):
        f.update(run)


def test_gaussian_sum_of_one_component_is_the_ekf(case):
    traj, cfg, setup, Y, truth, starts = case
    cov = setup.cov
    e = setup.filters["ekf"]
    g = GaussianSumFilter(cfg.model, setup.noise.q_ekf, cov["p0_ekf"], dict(cfg.noise), (1, 0.5))
    assert g.components == 1
    out = {}
    for f in (e, g):
        Nr, n2 = setup.records.size, 2 * cfg.model.dim
        sums, info, ex = np.zeros((2, Nr, 3 + n2)), np.zeros((RUNS, N_INFO)), np.zeros((2, Nr, n2))
        batch = RunBatch(setup.ctx, [f.start(*st) for st in starts], Y)
        f.run(batch, RunRecord(truth, sums, info, 1, ex))
        out[f.name] = (sums, info, ex)
    for a, b, what in zip(out["gsf"], out["ekf"], ("sums", "info", "history"), strict=True):
        np.testing.assert_allclose(
            a, b, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(b)), err_msg=what
        )
