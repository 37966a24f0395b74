"""The numpy Kalman filter and RTS smoother equal the joint Gaussian posterior (batch least
squares over all nodes at once), to round-off."""

from __future__ import annotations

import numpy as np

from obsplan.estimation.filters import linear


def _T(F, i, s):
    """Transition from node ``s`` to node ``i`` (``s <= i``)."""
    T = np.eye(F.shape[1])
    for t in range(s, i):
        T = F[t] @ T
    return T


def test_filter_and_smoother_equal_the_joint_posterior():
    rng = np.random.default_rng(4)
    M, m, B = 7, 3, 2
    h = rng.uniform(0.5, 1.5, M - 1)
    F = np.array([[[1.0, d, 0.5 * d * d], [0.0, 1.0, d], [0.0, 0.0, 1.0]] for d in h])
    q = np.array([0.3, 2.0])  # one noise level per model of the batch
    P0 = np.diag([4.0, 1.0, 0.5])
    x0 = np.array([1.0, -0.5, 0.2])
    y = rng.standard_normal((M, B)) * 3
    r = 0.7
    # forward filter and smoother, the library's steps
    x = np.tile(x0, (B, 1))
    P = np.tile(P0, (B, 1, 1))
    xf, Pf, xp, Pp = (np.empty((M, B, m)), np.empty((M, B, m, m)), np.empty((M, B, m)),
                      np.empty((M, B, m, m)))  # fmt: skip
    for k in range(M):
        if k:
            Q = np.zeros((B, m, m))
            Q[:, 2, 2] = q
            x, P = linear.predict(x, P, F[k - 1], Q)
        xp[k], Pp[k] = x, P
        x, P, S, e = linear.update_component(x, P, 0, y[k], r)
        assert np.all(S > 0) and np.allclose(P, np.swapaxes(P, 1, 2), rtol=0, atol=0)
        xf[k], Pf[k] = x, P
    xs, Ps = linear.rts_smooth(xf, Pf, xp, Pp, F)
    # the joint prior of all node states, then conditioning on every reading at once
    for b in range(B):
        Phi = [np.eye(m)]
        for k in range(M - 1):
            Phi.append(F[k] @ Phi[-1])
        mean = np.concatenate([f @ x0 for f in Phi])
        cov = np.zeros((M * m, M * m))
        # x_k = Φ_k x0 + Σ_{j<k} Φ_{k←j+1} w_j, w_j ~ N(0, diag(0, 0, q_b))
        W = np.zeros((m, m))
        W[2, 2] = q[b]
        for i in range(M):
            for j in range(M):
                c = Phi[i] @ P0 @ Phi[j].T
                for s in range(1, min(i, j) + 1):  # noise entering at node s
                    c = c + _T(F, i, s) @ W @ _T(F, j, s).T
                cov[i * m : (i + 1) * m, j * m : (j + 1) * m] = c
        H = np.zeros((M, M * m))
        H[np.arange(M), np.arange(M) * m] = 1.0
        S = H @ cov @ H.T + r * np.eye(M)
        K = np.linalg.solve(S, H @ cov).T
        post = mean + K @ (y[:, b] - H @ mean)
        post_cov = cov - K @ H @ cov
        np.testing.assert_allclose(xs[:, b].ravel(), post, rtol=1e-9, atol=1e-9)
        blocks = np.array([post_cov[k * m : (k + 1) * m, k * m : (k + 1) * m] for k in range(M)])
        np.testing.assert_allclose(Ps[:, b], blocks, rtol=1e-9, atol=1e-9)
        # at the last node the filter is the smoother
        np.testing.assert_allclose(xf[-1, b], post[-m:], rtol=1e-9, atol=1e-9)
