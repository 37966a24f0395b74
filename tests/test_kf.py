"""Augmented KF: eqs. 19–21 on noise-free data, oracle against filterpy, the y0 anchor, PSD."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from obsplan import generators as gen
from obsplan.errors import ConfigError
from obsplan.estimation.config import paper_covariances
from obsplan.estimation.kf import AugmentedKalmanFilter, input_displacement
from obsplan.estimation.sensors import true_readings
from obsplan.model import make_model


def test_ybar_is_linear_in_the_true_augmented_state():
    """ȳ = y - y0 + ½|d|² equals C(t) z_true exactly (eqs. 19–21, DVL and depth rows, beacon)."""
    traj = gen.circle_z(20.0, 1.5, 60.0, 0.1, z0=4.0, z_amp=1.0, z_period=30.0, center=(3.0, -2.0))
    model = make_model(3, "range,dvl-water,depth", beacon=(1.0, 2.0, -3.0))
    f = AugmentedKalmanFilter(
        model, traj, np.zeros((8, 8)), {"range": 0.1, "dvl-water": 1e-3, "depth": 0.05}
    )
    d = input_displacement(traj)
    np.testing.assert_allclose(d, traj.displacement(), atol=1e-9)
    b = model.beacon_array
    p0, v0 = traj.p[0] - b, traj.v[0]
    y0 = 0.5 * np.sum(p0**2)
    for k in range(0, traj.n_samples, 37):
        z = np.concatenate([traj.p[k] - b, traj.v[k], [p0 @ v0, v0 @ v0]])
        C = f.aug.output_matrix(d[k], traj.t[k] - traj.t[0])
        ybar = 0.5 * np.sum((traj.p[k] - b) ** 2) - y0 + 0.5 * d[k] @ d[k]
        assert C[0] @ z == pytest.approx(ybar, rel=1e-10, abs=1e-8)
        np.testing.assert_allclose(C[1:4] @ z, traj.v[k])
        assert C[4] @ z == pytest.approx(traj.p[k, 2] - b[2])


def test_kf_matches_filterpy_oracle():
    """Same measurements: filterpy's KalmanFilter (Joseph update) and our batched KF agree."""
    traj = gen.circle(30.0, 1.5, 30.0, 0.1)
    model = make_model(2, "range,dvl-water")
    cov = paper_covariances(model, 0.1)
    noise = {"range": 0.1, "dvl-water": 1e-3}
    ours = AugmentedKalmanFilter(model, traj, cov["q_kf"], noise, y0_mode="augment")
    rng = np.random.default_rng(5)
    x0 = np.hstack([traj.p[0], traj.v[0]]) + [0.5, -0.5, 0.05, 0.0]
    x_true = np.hstack([traj.p, traj.v])
    r = np.linalg.norm(traj.p, axis=1) + 0.1 * rng.standard_normal(traj.n_samples)
    dvl = traj.v + 1e-3 * rng.standard_normal(traj.v.shape)
    st = ours.init(x0[None], cov["p0_kf"], r[:1])
    m = ours.state_dim
    fp = KalmanFilter(dim_x=m, dim_z=3, dim_u=2)
    fp.x, fp.P = st.z[0].copy(), st.P[0].copy()
    Q = np.zeros((m, m))
    Q[:6, :6] = cov["q_kf"]
    fp.Q = Q
    d = input_displacement(traj)
    for k in range(traj.n_samples):
        rd = {"range": r[k : k + 1, None], "dvl-water": dvl[k : k + 1]}
        st = ours.update(st, k, rd)
        C = np.column_stack([ours.aug.output_matrix(d[k], traj.t[k]), [1.0, 0, 0]])
        ybar = 0.5 * r[k] ** 2 - 0.005 - st.y0[0] + 0.5 * d[k] @ d[k]
        if k == 0:  # the anchor: no range update
            fp.update(dvl[k], R=np.eye(2) * 1e-6, H=C[1:])
        else:
            R = np.diag([r[k] ** 2 * 0.01 + 0.5e-4, 1e-6, 1e-6])
            fp.update(np.concatenate([[ybar], dvl[k]]), R=R, H=C)
        np.testing.assert_allclose(st.z[0], fp.x, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(st.P[0], fp.P, rtol=1e-7, atol=1e-12)
        if k < traj.n_samples - 1:
            st = ours.predict(st, k)
            F = np.eye(m) + ours._A * 0.1
            fp.F, fp.B = F, ours._B * 0.1 + ours._A @ ours._B * 0.005
            fp.predict(u=traj.u[k])
    assert np.linalg.norm(st.z[0, :2] - x_true[-1, :2]) < 1.0


def test_kf_needs_the_anchor_range():
    traj = gen.circle(30.0, 1.5, 5.0, 0.1)
    model = make_model(2, "range")
    cov = paper_covariances(model, 0.1)
    f = AugmentedKalmanFilter(model, traj, cov["q_kf"], {"range": 0.1})
    with pytest.raises(ConfigError, match="anchor y0"):
        f.init(np.zeros((1, 4)), cov["p0_kf"], np.array([np.nan]))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ekf", "kf"])
def test_covariance_stays_symmetric_psd_over_100k_steps(name):
    """100,000 steps of 2D range at 100 Hz (a circle, 1000 s): P symmetric, eigenvalues > 0."""
    from obsplan.estimation.ekf import ExtendedKalmanFilter

    traj = gen.circle(51.0, 2.6, 1000.0, 0.01)
    assert traj.n_samples > 100_000
    model = make_model(2, "range")
    cov = paper_covariances(model, 0.01)
    rng = np.random.default_rng(7)
    x = np.hstack([traj.p, traj.v])
    r = np.linalg.norm(traj.p, axis=1)[:, None, None] + 0.1 * rng.standard_normal(
        (traj.n_samples, 1, 1)
    )
    x0 = x[:1] + [0.5, -0.5, 0.02, 0.0]
    if name == "ekf":
        f = ExtendedKalmanFilter(model, traj, cov["q_ekf"], {"range": 0.1})
        st = f.init(x0, cov["p0_ekf"])
        upd = lambda st, k: f.update(st, {"range": r[k]})  # noqa: E731
    else:
        f = AugmentedKalmanFilter(model, traj, cov["q_kf"], {"range": 0.1})
        st = f.init(x0, cov["p0_kf"], r[0, :, 0])
        upd = lambda st, k: f.update(st, k, {"range": r[k]})  # noqa: E731
    worst = np.inf
    for k in range(traj.n_samples):
        st = upd(st, k)
        if k % 5000 == 0 or k == traj.n_samples - 1:
            P = st.P[0]
            np.testing.assert_allclose(P, P.T, rtol=0, atol=1e-15 * np.abs(P).max())
            ev = np.linalg.eigvalsh(P)
            worst = min(worst, ev[0] / ev[-1])
            assert ev[0] > 0
        if k < traj.n_samples - 1:
            st = f.predict(st, k)
    assert np.isfinite(worst)


def test_true_readings_dvl_bottom_with_current():
    model = make_model(2, "range,dvl-bottom", current=True)
    x = np.array([[3.0, 4.0, 1.0, 2.0, 0.1, -0.2]])
    rd = true_readings(model, x)
    assert rd["range"][0, 0] == pytest.approx(5.0)
    np.testing.assert_allclose(rd["dvl-bottom"][0], [1.1, 1.8])
