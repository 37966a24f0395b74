"""Bounds along a path: the posterior Cramér–Rao bound and the rank of the sampled Gramian.

Posterior CRB (Tichavský et al. 1998) for ``x_{k+1} = F_k x_k + w_k``, ``w ~ N(0, Q)``, and
measurements with Gaussian noise: ``J_{k+1} = (F J_k⁻¹ Fᵀ + Q)⁻¹ + E[Hᵀ R⁻¹ H]``, ``J_0 = P_0⁻¹``.
It is run here in covariance form (``P = J⁻¹``, a Kalman covariance recursion) with the Jacobians at
the noise-free truth along the path, which is exact without process noise and the usual
approximation of the expectation with it. The range information is that of ``r`` with noise
``σ_r``: ``∇r ∇rᵀ/σ_r²``, equal to the half-squared form ``(p-b)(p-b)ᵀ / (r² σ_r²)``. No estimator
with the same prior ``P_0`` and the same readings has a smaller error covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.estimation import kalman
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.schedule import Schedule, make_schedule, sample_rate
from obsplan.estimation.sensors import output_model, to_outputs, true_readings
from obsplan.estimation.truth import nominal_states
from obsplan.observability.gramian import augmented_model, rank_scales
from obsplan.observability.scaling import Scales, numerical_rank
from obsplan.trajectory import Trajectory


@dataclass(frozen=True, eq=False)
class CRLBResult:
    """Posterior CRB along a path.

    Attributes
    ----------
    t : ndarray, shape (N,)
    pos_std_t, vel_std_t : ndarray, shape (N,)
        ``sqrt(tr)`` of the bound on the position [m] and inertial-velocity [m/s] covariance.
    pos_std_axes_t : ndarray, shape (N, n)
    final_pos_std : float
    """

    t: np.ndarray
    pos_std_t: np.ndarray
    vel_std_t: np.ndarray
    pos_std_axes_t: np.ndarray
    final_pos_std: float


def posterior_crlb(
    traj: Trajectory, config: EstimationConfig, schedule: Schedule | None = None
) -> CRLBResult:
    """Posterior CRB of ``(p, p')`` along ``traj`` with the sensors, rates and noises of ``config``.

    The prior is ``config.p0_ekf`` (paper default if None); process noise ``q_ekf`` when
    ``config.process_noise``.
    """
    model = config.model
    cov = config.covariances(1.0 / sample_rate(traj))
    if schedule is None:
        schedule = make_schedule(traj, model.sensors, config.rates_hz)
    q = cov["q_ekf"] if config.process_noise else np.zeros_like(cov["q_ekf"])
    xs = nominal_states(traj, model, config.current_array)
    noise = dict(config.noise)
    n, N, m = model.dim, traj.n_samples, model.state_dim
    # Jacobians and variances at the truth for every sample at once
    _, H = output_model(model).evaluate(xs)
    y, var = to_outputs(model, true_readings(model, xs), noise)
    if model.range_form == "half-squared":
        var[:, 0] = (2.0 * y[:, 0] + noise["range"] ** 2) * noise["range"] ** 2  # r² σ_r²
    rows_of = model.output_slices
    report = np.zeros((N, model.output_dim), dtype=bool)
    for j, s in enumerate(model.sensors):
        report[:, rows_of[s]] = schedule.mask[:, j : j + 1]
    T = kalman.nav_matrix(n, model.current, m)
    P = cov["p0_ekf"].copy()
    pos = np.zeros((N, n))
    vel = np.zeros(N)
    F_cache: dict[float, np.ndarray] = {}
    for k in range(N):
        for i in np.flatnonzero(report[k]):
            h = H[k, i]
            b = P @ h
            P = P - np.outer(b, b) / (h @ b + var[k, i])
        P = kalman.symmetrize(P)
        d = np.diag(T @ P @ T.T)
        pos[k] = d[:n]
        vel[k] = d[n:].sum()
        if k < N - 1:
            dt = float(traj.t[k + 1] - traj.t[k])
            F = F_cache.get(dt)
            if F is None:
                F = F_cache.setdefault(dt, model.transition(dt)[0])
            P = F @ P @ F.T + q
    pos_std = np.sqrt(pos.sum(axis=1))
    return CRLBResult(
        t=traj.t.copy(),
        pos_std_t=pos_std,
        vel_std_t=np.sqrt(vel),
        pos_std_axes_t=np.sqrt(pos),
        final_pos_std=float(pos_std[-1]),
    )


def sampled_rank_over_time(
    traj: Trajectory, config: EstimationConfig, scales: Scales | None = None
) -> np.ndarray:
    """Rank of the augmented model's *sampled* observability Gramian at each sample, shape (N,).

    ``Σ_j (C_j Φ_j)ᵀ (C_j Φ_j)`` over the samples where each sensor reports (multi-rate case B,
    Fig. 9b), with ``C = AugmentedModel.output_matrix`` and ``Φ = I + A τ`` (eq. 26), in the
    trajectory's own scales (:func:`~obsplan.observability.gramian.rank_scales`, as the continuous
    rank test) unless ``scales`` is given; rank by the unit-invariant test of
    :mod:`obsplan.observability.scaling`. With every sensor at the sample rate it tracks the
    continuous Gramian's rank.
    """
    model = config.model
    aug = augmented_model(model)
    sched = make_schedule(traj, model.sensors, config.rates_hz)
    scales = rank_scales(traj) if scales is None else scales
    tr = traj.scaled(scales.length_m, scales.time_s)
    d = tr.displacement()
    tau = tr.t - tr.t[0]
    m = aug.state_dim
    rows_of = model.output_slices  # output_matrix stacks its rows in the same sensor order
    G = np.zeros((traj.n_samples, m, m))
    acc = np.zeros((m, m))
    for k in range(traj.n_samples):
        C = aug.output_matrix(d[k], float(tau[k]))
        keep = np.zeros(C.shape[0], dtype=bool)
        for j, s in enumerate(model.sensors):
            if sched.mask[k, j]:
                keep[rows_of[s]] = True
        if keep.any():
            CP = C[keep] @ (np.eye(m) + aug.A * tau[k])
            acc = acc + CP.T @ CP
        G[k] = acc
    ranks = np.zeros(traj.n_samples, dtype=int)
    nz = np.flatnonzero(np.abs(G).sum(axis=(1, 2)) > 0)
    if nz.size:
        ranks[nz] = numerical_rank(G[nz])
    return ranks
