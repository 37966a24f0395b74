"""The epoch recursion of obsplan.estimation.bounds.riccati against a plain per-step recursion.

The closed-form composition (Faulhaber sums, the moments of a nilpotent A, a noise that varies
with time) must give the covariance of the per-step filter recursion at every sample, to
round-off (1e-10 relative: a few hundred steps of 10-flop updates on O(1) numbers).
"""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.estimation.bounds.riccati import RecursionModel, faulhaber, make_epochs, run_recursion


def integrated(A, W, h):
    """``∫_0^h F(u) W F(u)ᵀ du`` by a 3-point Gauss–Legendre rule: the integrand is a polynomial
    of degree <= 4 in ``u`` (``A³ = 0``) and the rule is exact to degree 5."""
    x, w = np.polynomial.legendre.leggauss(3)
    acc = np.zeros_like(W)
    for xi, wi in zip(x, w, strict=True):
        u = 0.5 * h * (xi + 1.0)
        F = np.eye(A.shape[0]) + A * u + 0.5 * A @ A * u**2
        acc += 0.5 * h * wi * (F @ W @ F.T)
    return acc


def per_step(model: RecursionModel, t, mask, P0, H, rho):
    """Update at each sample where a sensor reports, then predict one step (the reference)."""
    A = model.A
    P = P0.copy()
    out = []
    for k in range(t.size):
        if mask[k, model.range_sensor]:
            h = np.zeros(model.m)
            h[list(model.range_support)] = H[:, k]
            Ph = P @ h
            P = P - np.outer(Ph, Ph) / (h @ Ph + rho[k])
        for r, v, s in zip(model.rows, model.row_var, model.row_sensor, strict=True):
            if mask[k, s]:
                Ph = P @ r
                P = P - np.outer(Ph, Ph) / (r @ Ph + v)
        out.append(np.diag(model.nav @ P @ model.nav.T))
        if k + 1 < t.size:
            dt = t[k + 1] - t[k]
            F = np.eye(model.m) + A * dt + 0.5 * A @ A * dt**2
            tau = t[k + 1] - t[0]  # noise enters at the end of the step
            if model.continuous:  # an intensity constant in time (q1 = q2 = 0 here)
                P = F @ P @ F.T + integrated(A, model.q, dt)
            else:
                P = F @ P @ F.T + model.q + tau * model.q1 + tau**2 * model.q2
    return np.array(out).T


def random_spd(rng, m):
    X = rng.standard_normal((m, m))
    return X @ X.T / m + np.eye(m)


@pytest.mark.parametrize(
    "chain,continuous",
    [(False, False), (True, False), (False, True), (True, True)],
    ids=["pcrb-like", "kf-chain", "pcrb-continuous", "kf-chain-continuous"],
)
def test_epoch_recursion_equals_the_per_step_recursion(chain, continuous):
    rng = np.random.default_rng(3)
    n = 2
    if chain:  # p' = v, kappa' = phi, phi' = 2 gamma: A^2 != 0, A^3 = 0
        m = 2 * n + 3
        A = np.zeros((m, m))
        A[:n, n : 2 * n] = np.eye(n)
        A[4, 5], A[5, 6] = 1.0, 2.0
        G = rng.standard_normal((m, m)) * 1e-2
        q0, q1, q2 = G @ G.T, 1e-3 * np.eye(m), 1e-5 * (G + G.T) @ (G + G.T).T
        if continuous:  # the per-step reference integrates a time-invariant intensity
            q1 = q2 = None
        support = (0, 1, 4)
    else:
        m = 2 * n
        A = np.zeros((m, m))
        A[:n, n:] = np.eye(n)
        q0, q1, q2 = 1e-4 * np.eye(m), None, None
        support = (0, 1)
    nav = np.zeros((2 * n, m))
    nav[:, : 2 * n] = np.eye(2 * n)
    rows = np.zeros((n, m))
    rows[:, n : 2 * n] = np.eye(n)  # a DVL on v
    model = RecursionModel(
        A=A,
        q=q0,
        q1=q1,
        q2=q2,
        nav=nav,
        rows=rows,
        row_var=np.full(n, 0.01),
        row_sensor=(1, 1),
        range_sensor=0,
        n_sensors=2,
        range_support=support,
        continuous=continuous,
    )
    # an irregular grid (two step lengths) with range every 7 samples and DVL every 3
    t = np.concatenate([np.arange(40) * 0.1, 4.0 + np.arange(1, 31) * 0.25])
    N = t.size
    mask = np.zeros((N, 2), bool)
    mask[::7, 0] = True
    mask[::3, 1] = True
    epochs = make_epochs(t, mask)
    assert epochs.gap.sum() == N and epochs.count < N
    H = rng.standard_normal((len(support), N))
    rho = rng.uniform(0.5, 2.0, N)
    P0 = random_spd(rng, m)
    _, D = run_recursion(model, epochs, P0, H[:, epochs.index], rho[None, epochs.index])
    got = epochs.sample_values(np.asarray(D))
    want = per_step(model, t, mask, P0, H, rho)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-13)


def test_faulhaber_sums():
    for k in range(1, 12):
        want = [sum(i**p for i in range(k)) for p in range(7)]
        assert faulhaber(float(k)) == pytest.approx(want, rel=1e-14)
