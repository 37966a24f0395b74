"""EKF on the nonlinear model: oracle against filterpy, exact batched h/H, Joseph PSD, NaN skip."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FpEKF

from obsplan import generators as gen
from obsplan.estimation import kalman
from obsplan.estimation.config import paper_covariances
from obsplan.estimation.ekf import ExtendedKalmanFilter
from obsplan.estimation.sensors import output_model, to_outputs, true_readings
from obsplan.model import make_model


@pytest.mark.parametrize(
    "dim,sensors,current,form",
    [
        (2, "range", False, "half-squared"),
        (2, "range", False, "range"),  # not quadratic: CasADi fallback
        (3, "range,dvl-bottom,depth", True, "half-squared"),
        (3, "range,dvl-water", True, "half-squared"),
    ],
)
def test_output_model_matches_casadi(dim, sensors, current, form):
    model = make_model(
        dim, sensors, current=current, beacon=[3.0, -2.0, 1.0][:dim], range_form=form
    )
    x = np.random.default_rng(0).normal(scale=40.0, size=(7, model.state_dim))
    h, H = output_model(model).evaluate(x)
    for r in range(7):
        np.testing.assert_allclose(h[r], np.asarray(model.h(x[r])).ravel(), rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(H[r], np.asarray(model.H(x[r])), rtol=1e-12, atol=1e-12)


def test_half_squared_reading_is_unbiased():
    """y = ½ r_m² - ½ σ² is unbiased for ½ r² (the -½σ² corrects E[ε²])."""
    model = make_model(2, "range")
    rng = np.random.default_rng(1)
    r, sig, n = 50.0, 2.0, 400_000
    y, var = to_outputs(
        model, {"range": (r + sig * rng.standard_normal(n))[:, None]}, {"range": sig}
    )
    se = np.sqrt(r**2 * sig**2 / n)
    assert abs(y.mean() - 0.5 * r**2) < 4 * se
    # variance r²σ² + ½σ⁴ (exact for Gaussian ε at the true r)
    assert y.var() == pytest.approx(r**2 * sig**2 + 0.5 * sig**4, rel=0.02)
    assert var.mean() == pytest.approx(r**2 * sig**2 + 0.5 * sig**4, rel=0.02)


def _fp_ekf(model, q, P0, x0):
    f = FpEKF(dim_x=model.state_dim, dim_z=model.output_dim, dim_u=model.dim)
    f.x = x0.copy()
    f.P = P0.copy()
    f.Q = q
    return f


def test_ekf_matches_filterpy_oracle():
    """Same measurements, same model: filterpy's EKF (Joseph update) and ours agree."""
    traj = gen.circle(30.0, 1.5, 20.0, 0.1)
    model = make_model(2, "range")
    cov = paper_covariances(model, 0.1)
    noise = {"range": 0.1}
    ours = ExtendedKalmanFilter(model, traj, cov["q_ekf"], noise)
    rng = np.random.default_rng(2)
    x0 = np.hstack([traj.p[0], traj.v[0]]) + [0.7, -0.5, 0.1, 0.05]
    st = ours.init(x0[None], cov["p0_ekf"])
    fp = _fp_ekf(model, cov["q_ekf"], cov["p0_ekf"], x0)
    out = output_model(model)
    for k in range(traj.n_samples):
        r = np.linalg.norm(traj.p[k]) + 0.1 * rng.standard_normal()
        y, var = to_outputs(model, {"range": np.array([[r]])}, noise)
        st = ours.update_outputs(st, y, var)
        fp.update(
            y[0],
            lambda x: out.evaluate(x[None])[1][0],
            lambda x: out.evaluate(x[None])[0][0],
            R=np.diag(var[0]),
        )
        np.testing.assert_allclose(st.x[0], fp.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(st.P[0], fp.P, rtol=1e-8, atol=1e-12)
        if k < traj.n_samples - 1:
            F, G = model.transition(0.1)
            st = ours.predict(st, k)
            fp.F, fp.B = F, G
            fp.predict(u=traj.u[k])
            np.testing.assert_allclose(st.P[0], fp.P, rtol=1e-9, atol=1e-14)


def test_nan_reading_skips_that_run_only():
    traj = gen.circle(30.0, 1.5, 5.0, 0.1)
    model = make_model(3, "range,dvl-water", current=True)
    cov = paper_covariances(model, 0.1)
    f = ExtendedKalmanFilter(model, traj, cov["q_ekf"], {"range": 0.1, "dvl-water": 1e-3})
    x0 = np.zeros((3, model.state_dim))
    x0[:, :2] = traj.p[0]
    x0[:, 3:5] = traj.v[0]
    st = f.init(x0, cov["p0_ekf"])
    rd = true_readings(model, x0)
    rd["range"][1] = np.nan  # run 1 has no range
    rd["dvl-water"][2] = np.nan  # run 2 has no DVL
    new = f.update(st, rd)
    assert not np.allclose(new.P[0], st.P[0])
    # run 1: only the DVL rows acted, so the position block is untouched
    np.testing.assert_array_equal(new.P[1][:3, :3], st.P[1][:3, :3])
    assert not np.allclose(new.P[1][3:6, 3:6], st.P[1][3:6, 3:6])
    # run 2: range only: the velocity block of the prior is kept where the range says nothing
    assert not np.allclose(new.P[2][:3, :3], st.P[2][:3, :3])
    all_nan = {k: np.full_like(v, np.nan) for k, v in rd.items()}
    same = f.update(st, all_nan)
    np.testing.assert_array_equal(same.P, st.P)
    np.testing.assert_array_equal(same.x, st.x)


def test_joseph_update_keeps_psd_with_precise_measurements():
    """Measurements 1e8 times more precise than the prior (DVL vs a loose prior) keep P PSD."""
    rng = np.random.default_rng(3)
    m = 6
    A = rng.standard_normal((4, m, m))
    P = A @ A.transpose(0, 2, 1) * 1e4 + np.eye(m)
    x = np.zeros((4, m))
    for _ in range(200):
        H = rng.standard_normal((2, m))
        x, P = kalman.update(x, P, H, rng.standard_normal((4, 2)), np.full(2, 1e-4))
        np.testing.assert_array_equal(P, np.swapaxes(P, 1, 2))
        ev = np.linalg.eigvalsh(P)
        assert ev.min() > 0.0


def test_joint_update_equals_sequential_scalar_updates():
    rng = np.random.default_rng(4)
    m, R = 7, 5
    A = rng.standard_normal((R, m, m))
    P = A @ A.transpose(0, 2, 1) + np.eye(m)
    x = rng.standard_normal((R, m))
    H = rng.standard_normal((3, m))
    innov = rng.standard_normal((R, 3))
    innov[1, 2] = np.nan  # a missing row in one run
    var = rng.uniform(0.1, 1.0, 3)
    xj, Pj = kalman.update(x, P, H, innov, var)
    xs, Ps = x, P
    for i in range(3):
        # sequential: innovation of row i re-linearised at the current estimate (linear model)
        nu = innov[:, i] - np.einsum("j,rj->r", H[i], xs - x)
        xs, Ps = kalman.update_scalar(xs, Ps, H[i], nu, np.full(R, var[i]))
    np.testing.assert_allclose(xj, xs, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Pj, Ps, rtol=1e-10, atol=1e-12)
