"""Batched Kalman predict and update, shared by the EKF and the augmented KF.

Arrays are batched over independent runs: states ``x`` of shape ``(R, m)``, covariances ``P`` of
shape ``(R, m, m)``. Measurements have independent noises (diagonal ``R``, as every sensor here):
:func:`update` processes the rows of a sample jointly (one small solve per run), which for a
linear(ised) model equals :func:`update_scalar` row after row; a NaN reading (or a run where the
sensor did not report) leaves that run's state and covariance untouched.

The covariance update is the Joseph form ``P⁺ = (I - k hᵀ) P (I - k hᵀ)ᵀ + r k kᵀ``, evaluated with
outer products only: with ``b = P h`` and ``s = hᵀ b + r`` it equals ``P - k bᵀ - b kᵀ + s k kᵀ``
(valid for any gain ``k``, so an error in ``k`` changes ``P⁺`` only to second order), computed as
``P - (k wᵀ + w kᵀ)``, ``w = b - s k/2``, which is exactly symmetric. The prediction symmetrises.
"""

from __future__ import annotations

import numpy as np


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + Pᵀ)/2`` over the last two axes."""
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def predict(
    x: np.ndarray, P: np.ndarray, F: np.ndarray, Gu: np.ndarray, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``x⁺ = F x + G u``, ``P⁺ = F P Fᵀ + Q``.

    Parameters
    ----------
    x : (R, m)
    P : (R, m, m)
    F : (m, m)
        Transition matrix of the step.
    Gu : (m,) or (R, m)
        Input contribution ``G u`` of the step.
    Q : (m, m)
        Process-noise covariance of the step.
    """
    R, m = x.shape
    x = x @ F.T + Gu
    # F P Fᵀ as two (R m × m)(m × m) GEMMs: much faster than broadcasting F over the batch
    Ft = F.T
    PFt = (P.reshape(R * m, m) @ Ft).reshape(R, m, m)
    FPFt = (np.swapaxes(PFt, 1, 2).reshape(R * m, m) @ Ft).reshape(R, m, m)  # (F (P Fᵀ))ᵀ
    return x, symmetrize(FPFt) + Q


def update_scalar(
    x: np.ndarray,
    P: np.ndarray,
    h: np.ndarray,
    innov: np.ndarray,
    var: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """One scalar measurement update (Joseph form) for every run.

    Parameters
    ----------
    x : (R, m)
    P : (R, m, m)
    h : (m,) or (R, m)
        Measurement row (Jacobian row for the EKF).
    innov : (R,)
        Innovation ``y - ŷ``; NaN where the run has no reading (no update).
    var : (R,) or scalar
        Measurement variance ``r``.

    Returns
    -------
    x, P
        Updated arrays (new objects).
    """
    valid = np.isfinite(innov)
    if not np.any(valid):
        return x, P
    if h.ndim == 1:  # one row for every run (linear model): plain matmuls
        R, m = x.shape
        b = (P.reshape(R * m, m) @ h).reshape(R, m)
        s = b @ h + var
    else:
        b = np.einsum("rij,rj->ri", P, h)
        s = np.einsum("ri,ri->r", h, b) + var
    s = np.where(valid, s, 1.0)
    k = b / s[:, None]
    nu = innov
    if not np.all(valid):
        k[~valid] = 0.0
        nu = np.where(valid, innov, 0.0)
    x = x + k * nu[:, None]
    # Joseph: P - k bᵀ - b kᵀ + s k kᵀ = P - (k wᵀ + w kᵀ) with w = b - s k / 2; a matrix plus its
    # transpose is exactly symmetric in floating point, so P stays symmetric bit for bit
    w = b - (0.5 * s)[:, None] * k
    kw = k[:, :, None] * w[:, None, :]
    P = P - (kw + np.swapaxes(kw, 1, 2))
    return x, P


def nav_matrix(n: int, current: bool, m: int) -> np.ndarray:
    """``T`` with ``T x = (p, p')``: position and inertial velocity ``v (+ v_f)``, shape (2n, m).

    Both filters order their states ``(p, v[, v_f], ...)``, so the same map gives the navigation
    state of either; errors, standard deviations and NEES are reported on ``(p, p')``.
    """
    T = np.zeros((2 * n, m))
    T[:, : 2 * n] = np.eye(2 * n)
    if current:
        T[n:, 2 * n : 3 * n] = np.eye(n)
    return T


def update(
    x: np.ndarray,
    P: np.ndarray,
    H: np.ndarray,
    innov: np.ndarray,
    var: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint measurement update of several rows with independent noises (Joseph form).

    Equivalent to :func:`update_scalar` row after row for a linear(ised) model, with a third of
    the numpy calls: one ``p × p`` solve per run instead of ``p`` rank-one updates.

    Parameters
    ----------
    x : (R, m)
    P : (R, m, m)
    H : (p, m) or (R, p, m)
        Measurement rows (Jacobian rows for the EKF).
    innov : (R, p)
        Innovations; NaN where a run has no reading of that row (the row is dropped for that run
        by zeroing it, which removes it from the update exactly).
    var : (R, p) or (p,)
        Measurement variances.
    """
    if H.shape[-2] == 1:  # one row: no solve needed
        v = np.broadcast_to(var, innov.shape)[:, 0]
        return update_scalar(x, P, H[..., 0, :], innov[:, 0], v)
    valid = np.isfinite(innov)
    if not valid.all():
        if not valid.any():
            return x, P
        H = H * valid[..., None]
        innov = np.where(valid, innov, 0.0)
        var = np.where(valid, var, 1.0)
    R, m = x.shape
    if H.ndim == 2:
        B = (P.reshape(R * m, m) @ H.T).reshape(R, m, H.shape[0])  # P Hᵀ
    else:
        B = P @ np.swapaxes(H, -1, -2)
    S = H @ B
    idx = np.arange(S.shape[-1])
    S[:, idx, idx] += var
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(B, 1, 2)), 1, 2)  # S symmetric
    x = x + (K @ innov[:, :, None])[:, :, 0]
    # Joseph: P - K Bᵀ - B Kᵀ + K S Kᵀ = P - (K Wᵀ + W Kᵀ), W = B - K S / 2 (exactly symmetric)
    W = B - 0.5 * (K @ S)
    KW = K @ np.swapaxes(W, 1, 2)
    return x, P - (KW + np.swapaxes(KW, 1, 2))
