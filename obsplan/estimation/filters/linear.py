"""Batched linear Kalman filter steps and the Rauch–Tung–Striebel smoother, in numpy.

For many independent linear-Gaussian models at once (a batch of ``B`` models with a shared
transition, e.g. one per axis and per noise hypothesis of a track fit,
:mod:`obsplan.io.tracks`): means ``x`` (B, m), covariances ``P`` (B, m, m).

* prediction ``x⁺ = F x``, ``P⁺ = F P Fᵀ + Q``;
* update with a scalar measurement of one state component ``c``: ``S = P_cc + r``,
  ``K = P_{:,c} / S``, ``x⁺ = x + K e``, ``P⁺ = P - K Kᵀ S`` (symmetrised), ``e = y - x_c``;
* smoother, backwards from the last node: ``C = P_f Fᵀ P_p⁻¹`` (a solve with the predicted
  covariance), ``x_s = x_f + C (x_s⁺ - x_p⁺)``, ``P_s = P_f + C (P_s⁺ - P_p⁺) Cᵀ``.

The compiled filters of the Monte Carlo (:mod:`obsplan.estimation.kernels`) run the same
equations on their own sparse structure; this module is for small dense models in numpy.
"""

from __future__ import annotations

import numpy as np


def predict(
    x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(F x, F P Fᵀ + Q)`` of a batch.

    Parameters
    ----------
    x : ndarray, shape (B, m)
        Means.
    P : ndarray, shape (B, m, m)
        Covariances.
    F : ndarray, shape (m, m)
        Transition shared by the batch.
    Q : ndarray, shape (B, m, m) or (m, m), optional
        Process noise of the step (none if omitted).

    Returns
    -------
    x : ndarray, shape (B, m)
        Predicted means.
    P : ndarray, shape (B, m, m)
        Predicted covariances.
    """
    x = x @ F.T
    P = F @ P @ F.T
    if Q is not None:
        P = P + Q
    return x, P


def update_component(
    x: np.ndarray, P: np.ndarray, c: int, y: np.ndarray | float, r: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Update a batch with a scalar reading ``y`` of state component ``c`` (variance ``r``).

    Parameters
    ----------
    x : ndarray, shape (B, m)
        Prior means.
    P : ndarray, shape (B, m, m)
        Prior covariances.
    c : int
        Index of the state component read.
    y : float or ndarray, shape (B,)
        The reading(s), in the unit of that component.
    r : float or ndarray, shape (B,)
        Variance of the reading.

    Returns
    -------
    x : ndarray, shape (B, m)
        Posterior means.
    P : ndarray, shape (B, m, m)
        Posterior covariances (exactly symmetric).
    S : ndarray, shape (B,)
        Innovation variance.
    e : ndarray, shape (B,)
        Innovation ``y - x_c``.
    """
    S = P[:, c, c] + r
    e = y - x[:, c]
    K = P[:, :, c] / S[:, None]
    x = x + K * e[:, None]
    P = P - K[:, :, None] * K[:, None, :] * S[:, None, None]
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    return x, P, S, e


def log_likelihood(S: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Gaussian log-likelihood of innovations ``e`` of variances ``S``, elementwise.

    Parameters
    ----------
    S : ndarray
        Innovation variances.
    e : ndarray
        Innovations, same shape.

    Returns
    -------
    ndarray
        ``-½ (log(2π S) + e²/S)``, same shape.
    """
    return -0.5 * (np.log(2 * np.pi * S) + e * e / S)


def rts_smooth(
    xf: np.ndarray, Pf: np.ndarray, xp: np.ndarray, Pp: np.ndarray, F: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rauch–Tung–Striebel smoother of a batch of filtered runs.

    Parameters
    ----------
    xf, Pf : ndarray, shapes (M, B, m), (M, B, m, m)
        Filtered moments at the ``M`` nodes.
    xp, Pp : ndarray, shapes (M, B, m), (M, B, m, m)
        Predicted moments at the nodes (entry 0 is not used).
    F : ndarray, shape (M - 1, m, m)
        Transition from node ``k`` to ``k + 1``.

    Returns
    -------
    xs : ndarray, shape (M, B, m)
        Smoothed means.
    Ps : ndarray, shape (M, B, m, m)
        Smoothed covariances.
    """
    xs = xf.copy()
    Ps = Pf.copy()
    for k in range(xf.shape[0] - 2, -1, -1):
        # C = Pf Fᵀ Pp⁻¹, by a solve with the symmetric Pp
        C = np.swapaxes(np.linalg.solve(Pp[k + 1], (Pf[k] @ F[k].T).swapaxes(1, 2)), 1, 2)
        xs[k] = xf[k] + np.einsum("bij,bj->bi", C, xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ np.swapaxes(C, 1, 2)
    return xs, Ps
