"""EKF building blocks: exact batched h/H, unbiased readings, the Joseph update of the kernels."""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.estimation import kernels
from obsplan.estimation.sensors import output_model, to_outputs
from obsplan.model.vehicle import make_model


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
    # variance r²σ² + ½σ⁴ (exact for Gaussian ε at the true r); 2 % = ~9 standard errors of a
    # variance estimated from 400k samples
    assert y.var() == pytest.approx(r**2 * sig**2 + 0.5 * sig**4, rel=0.02)
    assert var.mean() == pytest.approx(r**2 * sig**2 + 0.5 * sig**4, rel=0.02)


def _ws(m, B):
    ws, iw, _ = kernels.workspaces(m, B, 1, np.zeros(1), np.zeros((2, 2)))
    return ws, iw


def _set_row(ws, iw, idx, vals, nu, r, ok):
    """One sparse row for every member: values (nnz, B), innovations, variances, validity."""
    iw[: len(idx)] = idx
    ws[kernels.WS_VAL, : len(idx)] = vals
    ws[kernels.WS_SC, kernels.SC_NU] = nu
    ws[kernels.WS_SC, kernels.SC_R] = r
    ws[kernels.WS_SC, kernels.SC_OK] = ok


def test_joseph_update_keeps_psd_with_precise_measurements():
    """Measurements 1e8 times more precise than the prior (DVL vs a loose prior) keep P
    exactly symmetric and positive definite over 200 updates, for every member of a batch; a
    member without the reading is left exactly as it was."""
    rng = np.random.default_rng(3)
    m, B = 6, 3
    A = rng.standard_normal((B, m, m))
    P = np.ascontiguousarray((A @ A.transpose(0, 2, 1) * 1e4 + np.eye(m)).transpose(1, 2, 0))
    X = np.zeros((m, B))
    ws, iw = _ws(m, B)
    P_skip = P[:, :, 2].copy()
    for _ in range(200):
        idx = rng.choice(m, 3, replace=False)
        _set_row(
            ws,
            iw,
            idx,
            rng.standard_normal((3, B)),
            rng.standard_normal(B),
            1e-4,
            np.array([1.0, 1.0, 0.0]),
        )
        ws[kernels.WS_SC, kernels.SC_NU, 2] = 0.0  # what the kernels set for a missing reading
        kernels.update_rows(X, P, iw, ws, 3)
        for b in range(2):
            np.testing.assert_array_equal(P[:, :, b], P[:, :, b].T)
            assert np.linalg.eigvalsh(P[:, :, b]).min() > 0.0
    np.testing.assert_array_equal(P[:, :, 2], P_skip)
    np.testing.assert_array_equal(X[:, 2], 0.0)


def test_sequential_scalar_rows_equal_the_joint_update():
    """Rows processed one by one (kernel) equal the joint update of a linear model (numpy)."""
    rng = np.random.default_rng(4)
    m = 7
    A = rng.standard_normal((m, m))
    P = A @ A.T + np.eye(m)
    x = rng.standard_normal(m)
    H = rng.standard_normal((3, m))
    y = rng.standard_normal(3)
    var = rng.uniform(0.1, 1.0, 3)
    S = H @ P @ H.T + np.diag(var)
    K = np.linalg.solve(S, H @ P).T
    xj = x + K @ (y - H @ x)
    Pj = P - K @ S @ K.T
    Xs, Ps = x[:, None].copy(), P[:, :, None].copy()
    ws, iw = _ws(m, 1)
    for i in range(3):
        _set_row(ws, iw, np.arange(m), H[i][:, None], y[i] - H[i] @ Xs[:, 0], var[i], 1.0)
        kernels.update_rows(Xs, Ps, iw, ws, m)
    np.testing.assert_allclose(Xs[:, 0], xj, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Ps[:, :, 0], Pj, rtol=1e-10, atol=1e-12)


def test_predict_composes_the_per_step_transition():
    """``predict`` over a segment equals ``F P Fᵀ + Q`` with the dense ``F`` of its entries."""
    from obsplan.estimation.kalman import Transition

    rng = np.random.default_rng(5)
    m, n = 7, 2
    tr = Transition.build(
        [(0, 2, 1.0, 1), (1, 3, 1.0, 1), (4, 5, 1.0, 1), (4, 6, 1.0, 2), (5, 6, 2.0, 1)]
    )
    A = rng.standard_normal((m, m))
    P = A @ A.T
    x = rng.standard_normal(m)
    T = 0.37
    tab = np.zeros((1, kernels.TAB_G + 2 * n))
    tab[0, kernels.TAB_T] = T
    tab[0, kernels.TAB_G :] = rng.standard_normal(2 * n)
    ws, _ = _ws(m, 1)
    Q = rng.standard_normal((m, m))
    Q = Q @ Q.T
    F = tr.matrix(m, T)
    g = np.zeros(m)
    g[: 2 * n] = tab[0, kernels.TAB_G :]
    x_ref, P_ref = F @ x + g, F @ P @ F.T + Q
    X, PP = x[:, None].copy(), P[:, :, None].copy()
    kernels.predict(X, PP, tab, 0, n, tr.packed(), np.ascontiguousarray(Q[:, :, None]), ws)
    np.testing.assert_allclose(X[:, 0], x_ref, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(PP[:, :, 0], P_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(PP[:, :, 0], PP[:, :, 0].T)
    with pytest.raises(ValueError, match="upper triangular"):
        Transition.build([(2, 0, 1.0, 1)])
