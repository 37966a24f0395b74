"""Covariance of the closed loop, linearised: the estimated and the true deviation from a path.

The guidance (:mod:`obsplan.estimation.montecarlo.guidance`) steers the navigation estimate onto the
reference, ``u = u_ref - Kp ε_p - Kd ε_v`` with ``ε = T x̂ - x_ref`` the *estimated* deviation
(``T`` the rows of position and inertial velocity, 2n). Between two measurement epochs the
estimate moves with the known input, so ``ε`` obeys the loop alone, sample by sample
(zero-order hold on the filter step ``Δ``, as :mod:`obsplan.estimation.montecarlo.loop_kernels`
flies it):

    ε_{k+1} = Φ ε_k,    Φ = [[I - ½Δ²Kp, Δ - ½Δ²Kd], [-Δ Kp, 1 - Δ Kd]] ⊗ I_n,

and the feedback command ``-[Kp Kd] ε`` moves only with the filter's corrections at the epochs.
With ``e = x̂ - x`` the filter's error, a scalar update of the row ``r`` (variance ``ρ``, gain
``K = P rᵀ / s``, ``s = r P rᵀ + ρ``, ``P = Cov e``) and its reading noise ``ν`` give

    ε⁺ = ε - T K r e + T K ν,    e⁺ = (I - K r) e + K ν,

a rank-one map of the joint state ``z = (ε, e)``: ``z⁺ = (I - g r̃) z + g ν`` with
``g = (T K, K)`` and ``r̃ = (0, r)``, so with ``c = C r̃ᵀ`` its covariance becomes
``C - (g̃ cᵀ + c g̃ᵀ) / s + g̃ g̃ᵀ / s``, ``g̃ = s g = (T c_e, c_e)``. Between the epochs ``e`` is
predicted as the filter predicts it (``F(t) = I + A t + ½A²t²`` and the process noise of the gap,
from the same recursion step as the posterior CRB, :mod:`obsplan.estimation.bounds.riccati`). The
true deviation is ``δ = T x - x_ref = ε - T e``.

With ``P`` the posterior CRB along the reference (the EKF's covariance where it is efficient)
this is the exact second moment of the linearised closed loop, with no saturation: every
correction ``K ν - K r e`` is the innovation times the gain, and the innovations are white. It is
much tighter than a bound that ignores how ``ε`` and ``e`` are correlated: a slowly varying
estimation error moves the true vehicle, not the command (``ε`` stays small while ``δ ≈ -T e``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.estimation.bounds.riccati import Epochs, RecursionModel, recursion_step


@dataclass(frozen=True, eq=False)
class LoopCovariance:
    """Second moments of the linearised closed loop after each epoch's update.

    Attributes
    ----------
    time : ndarray (J,)
        Epoch times [s] from the start.
    estimated : ndarray (J, 2n, 2n)
        ``Cov ε``, the estimated deviation ``(p̂ - p_ref, v̂ - v_ref)`` [m², m²/s, m²/s²].
    true : ndarray (J, 2n, 2n)
        ``Cov δ``, the true deviation ``(p - p_ref, v - v_ref)``.
    filter : ndarray (J, 2n, 2n)
        ``T P Tᵀ``, the filter's own covariance of position and inertial velocity.
    """

    time: np.ndarray
    estimated: np.ndarray
    true: np.ndarray
    filter: np.ndarray

    @property
    def n(self) -> int:
        return int(self.estimated.shape[1]) // 2

    def command_std(self, kp: float, kd: float) -> np.ndarray:
        """Std of the feedback command ``-(Kp ε_p + Kd ε_v)`` per epoch and axis [m/s²],
        shape (J, n).

        Parameters
        ----------
        kp : float
            The guidance's position gain [1/s²].
        kd : float
            Its velocity gain [1/s].

        Returns
        -------
        ndarray, shape (J, n)
            The standard deviation of the command [m/s²].
        """
        n, C = self.n, self.estimated
        i = np.arange(n)
        var = kp**2 * C[:, i, i] + 2 * kp * kd * C[:, i, n + i] + kd**2 * C[:, n + i, n + i]
        return np.sqrt(np.maximum(var, 0.0))

    def std(self, which: str, block: str) -> np.ndarray:
        """Per-axis std of ``which`` (``"estimated"``, ``"true"``, ``"filter"``) of ``block``
        (``"pos"`` [m] or ``"vel"`` [m/s]), shape (J, n).

        Parameters
        ----------
        which : {"estimated", "true", "filter"}
            The covariance: of the estimated deviation, of the true deviation, or the filter's.
        block : {"pos", "vel"}
            Position or velocity.

        Returns
        -------
        ndarray, shape (J, n)
            The standard deviations, per epoch and axis.
        """
        n = self.n
        C = getattr(self, which)
        i = np.arange(n) + (0 if block == "pos" else n)
        return np.sqrt(np.maximum(C[:, i, i], 0.0))


def loop_gain_matrix(kp: float, kd: float, dt: float, n: int) -> np.ndarray:
    """``Φ`` of the module docstring: one filter step ``dt`` [s] of the estimated deviation under
    the guidance's feedback (zero-order hold), shape (2n, 2n).

    Parameters
    ----------
    kp : float
        Position gain [1/s²].
    kd : float
        Velocity gain [1/s].
    dt : float
        Filter step [s].
    n : int
        Spatial dimension.

    Returns
    -------
    ndarray, shape (2n, 2n)
        The transition ``Φ`` of ``(ε_p, ε_v)``.
    """
    a = np.array(
        [
            [1.0 - 0.5 * dt**2 * kp, dt - 0.5 * dt**2 * kd],
            [-dt * kp, 1.0 - dt * kd],
        ]
    )
    return np.kron(a, np.eye(n))


def loop_covariance(
    model: RecursionModel,
    epochs: Epochs,
    P0: np.ndarray,
    h: np.ndarray,
    rho: np.ndarray,
    kp: float,
    kd: float,
    mask: np.ndarray | None = None,
) -> LoopCovariance:
    """The closed loop's covariances (module docstring) at every epoch, after its update.

    Parameters
    ----------
    model, epochs : RecursionModel, Epochs
        The recursion's structure and epochs (:mod:`obsplan.estimation.bounds.riccati`); the times
        of ``epochs`` in seconds.
    P0 : ndarray (m, m)
        The filter's prior at the first sample; the estimate starts on the reference (``ε = 0``).
    h : ndarray (len(model.range_support), J)
        Range row at each epoch (as for
        :func:`~obsplan.estimation.bounds.riccati.run_recursion`).
    rho : ndarray (1, J)
        Range variance at each epoch.
    kp, kd : float
        The guidance's gains [1/s²], [1/s].
    mask : ndarray (J, S), optional
        Override of ``epochs.mask``.

    Returns
    -------
    LoopCovariance
        The estimated, true and filter covariances after each epoch's update.
    """
    m, n = model.m, model.n
    T = np.asarray(model.nav, float)
    A = np.asarray(model.A, float)
    A2 = A @ A
    M = epochs.mask if mask is None else np.asarray(mask, float)
    J = epochs.count
    h = np.asarray(h, float)
    rho = np.asarray(rho, float).reshape(-1)
    gap = epochs.gap.astype(float)
    # the process noise of every gap: the recursion's prediction of a zero covariance
    step = recursion_step(model, epochs.max_gap).map(J)
    Q = np.asarray(
        step(
            np.zeros((m, m * J)),
            np.zeros((h.shape[0], J)),
            np.ones((1, J)),
            np.zeros((model.n_sensors, J)),
            gap[None, :],
            epochs.dt[None, :],
            epochs.time[None, :],
        )[0]
    ).reshape(m, J, m)
    support = np.asarray(model.range_support, int)
    two = 2 * n
    C = np.zeros((two + m, two + m))
    C[two:, two:] = np.asarray(P0, float)
    E = np.hstack([np.eye(two), -T])  # δ = ε - T e
    est = np.empty((J, two, two))
    true = np.empty((J, two, two))
    filt = np.empty((J, two, two))
    steps: dict[tuple[float, int], np.ndarray] = {}  # repeats on uniform grids

    def update(C: np.ndarray, r: np.ndarray, var: float) -> np.ndarray:
        """One scalar row's rank-one update of the joint covariance (module docstring)."""
        c = C[:, two:] @ r  # C r̃ᵀ
        s = float(r @ c[two:]) + var
        gt = np.concatenate([T @ c[two:], c[two:]])
        return C + (np.outer(gt, gt) - np.outer(gt, c) - np.outer(c, gt)) / s

    for j in range(J):
        if M[j, model.range_sensor] != 0.0:
            r = np.zeros(m)
            r[support] = h[:, j]
            C = update(C, r, float(rho[j]))
        for r, var, sensor in zip(model.rows, model.row_var, model.row_sensor, strict=True):
            if M[j, sensor] != 0.0:
                C = update(C, np.asarray(r, float), float(var))
        C = 0.5 * (C + C.T)
        est[j] = C[:two, :two]
        true[j] = E @ C @ E.T
        filt[j] = T @ C[two:, two:] @ T.T
        if j == J - 1:
            break
        k, dt = int(epochs.gap[j]), float(epochs.dt[j])
        G = steps.get((dt, k))
        if G is None:  # the gap's transition: the loop on ε, the filter's prediction on e
            t = k * dt
            G = np.zeros_like(C)
            G[:two, :two] = np.linalg.matrix_power(loop_gain_matrix(kp, kd, dt, n), k)
            G[two:, two:] = np.eye(m) + A * t + 0.5 * A2 * t**2
            steps[(dt, k)] = G
        C = G @ C @ G.T
        C[two:, two:] += Q[:, j, :]
    return LoopCovariance(
        time=np.asarray(epochs.time, float), estimated=est, true=true, filter=filt
    )
