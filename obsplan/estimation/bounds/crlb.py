"""Bounds along a path: the posterior Cramér–Rao bound and the rank of the sampled Gramian.

Posterior CRB (Tichavský et al. 1998) for ``x_{k+1} = F_k x_k + w_k``, ``w ~ N(0, Q)``, and
measurements with Gaussian noise: ``J_{k+1} = (F J_k⁻¹ Fᵀ + Q)⁻¹ + E[Hᵀ R⁻¹ H]``, ``J_0 = P_0⁻¹``.
It is run in covariance form (``P = J⁻¹``) at the measurement epochs
(:mod:`obsplan.estimation.bounds.riccati`, the same recursion the planner's ``pcrb-position``
objective optimises) with the Jacobians at the noise-free truth along the path, which is exact
without process noise and the usual approximation of the expectation with it. No estimator with the
same prior ``P_0`` and the same readings has a smaller error covariance.

Range information. A reading ``r + ε``, ``ε ~ N(0, σ_r²)``, carries the Fisher information
``u uᵀ / σ_r²`` about ``p`` (``u = (p - b)/r``), whatever form a filter feeds it in. At the
beacon ``∇r`` is undefined; the bound uses ``(p - b)(p - b)ᵀ / (σ_r² (r² + r_ε²))`` with
``r_ε =`` :data:`RANGE_REG_M`, which differs from ``u uᵀ/σ_r²`` by less than ``r_ε²/r²`` (1e-6
beyond 1 m) and tends to no information (a finite bound) at the beacon.

A moving beacon (``EstimationConfig.beacon_path``): the same information at ``p(t_k) - b_k``,
``b_k`` the beacon each epoch's range is taken to (at its transmission,
:func:`~obsplan.estimation.epochs.epoch_beacons`), the dynamics being the vehicle's own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.estimation.bounds.riccati import (
    RecursionModel,
    constant_rows,
    make_epochs,
    run_recursion,
)
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.epochs import epoch_beacons, nominal_states
from obsplan.estimation.schedule import Schedule, sample_rate
from obsplan.estimation.sensors import output_model
from obsplan.model.vehicle import VehicleModel
from obsplan.observability.gramian import augmented_model, rank_scales
from obsplan.observability.scaling import Scales, numerical_rank
from obsplan.trajectory.sampled import Trajectory

#: Regularisation length of the range information at the beacon [m] (module docstring).
RANGE_REG_M = 1e-3


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
        ``pos_std_t`` at the last sample [m].
    mean_pos_std : float
        Time average of ``pos_std_t`` over the samples [m] (the mission-average bound).
    """

    t: np.ndarray
    pos_std_t: np.ndarray
    vel_std_t: np.ndarray
    pos_std_axes_t: np.ndarray
    final_pos_std: float
    mean_pos_std: float


def nav_rows(model: VehicleModel) -> np.ndarray:
    """Rows of ``(p, p')`` in the state ``(p, v[, v_f])``, shape (2n, state_dim).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (dimension and current).

    Returns
    -------
    ndarray, shape (2n, state_dim)
        The map to position [m] and inertial velocity ``v (+ v_f)`` [m/s].
    """
    n, m = model.dim, model.state_dim
    T = np.zeros((2 * n, m))
    T[:n, :n] = np.eye(n)
    T[n:, n : 2 * n] = np.eye(n)
    if model.current:
        T[n:, 2 * n :] = np.eye(n)
    return T


def pcrb_model(
    model: VehicleModel, q: np.ndarray, noise: dict[str, float], continuous: bool = False
) -> RecursionModel:
    """The :class:`~obsplan.estimation.bounds.riccati.RecursionModel` of the posterior CRB.

    State ``(p, v[, v_f])`` of ``model``, process noise ``q`` (per-step covariance, or the
    intensity of the physical noise when ``continuous``), the model's constant DVL and depth rows
    with the noise of ``noise`` (std per sensor); the range row is per epoch
    (:func:`range_information`).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (sensors and current).
    q : ndarray, shape (state_dim, state_dim)
        Process noise: per-step covariance, or intensity [m²/s³ on ``v``] when ``continuous``.
    noise : dict of str to float
        Standard deviation per sensor (range [m], DVL [m/s], depth [m]).
    continuous : bool, optional
        ``q`` is an intensity of the physical noise.

    Returns
    -------
    RecursionModel
        The model of the covariance recursion.
    """
    n, m = model.dim, model.state_dim
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    if model.current:
        A[:n, 2 * n :] = np.eye(n)
    out = output_model(model)
    rows, var, which = constant_rows(model.sensors, out.g, noise, model.output_slices)
    return RecursionModel(
        A=A,
        q=np.asarray(q, float),
        nav=nav_rows(model),
        rows=rows,
        row_var=var,
        row_sensor=which,
        range_sensor=model.sensors.index("range"),
        n_sensors=len(model.sensors),
        range_support=tuple(range(n)),
        continuous=bool(continuous),
    )


def pcrb_model_of(config: EstimationConfig, dt: float) -> RecursionModel:
    """:func:`pcrb_model` of a configuration on a filter grid of step ``dt`` [s]: its process noise
    (:meth:`~obsplan.estimation.config.EstimationConfig.process_noise_model`; none when
    ``process_noise`` is off) and noises. The posterior CRB and the planner's objective use it.

    Parameters
    ----------
    config : EstimationConfig
        The configuration (model, noises, process noise).
    dt : float
        Step of the filter grid [s].

    Returns
    -------
    RecursionModel
        The model of the covariance recursion.
    """
    pn = config.process_noise_model(dt)
    q = pn.q_ekf if config.process_noise else np.zeros_like(pn.q_ekf)
    return pcrb_model(config.model, q, dict(config.noise), continuous=pn.continuous)


def range_information(rel, sigma: float):
    """Range row ``h`` (n, J) (its position entries) and variance ``ρ`` (1, J) at positions
    ``rel`` (n, J) relative to the beacon.

    ``h hᵀ / ρ`` is the regularised Fisher information of the module docstring. Works on numpy
    arrays and on CasADi expressions (the planner's objective).

    Parameters
    ----------
    rel : ndarray or casadi.MX, shape (n, J)
        Positions relative to the beacon [m], one column per epoch.
    sigma : float
        Standard deviation of the range noise [m].

    Returns
    -------
    h : ndarray or casadi.MX, shape (n, J)
        The range row's position entries (``rel`` itself).
    rho : ndarray or casadi.MX, shape (1, J)
        Its variance ``σ² (|rel|² + r_ε²)`` [m⁴].
    """
    import casadi as ca

    if isinstance(rel, np.ndarray):
        return rel, sigma**2 * (np.sum(rel**2, axis=0, keepdims=True) + RANGE_REG_M**2)
    return rel, sigma**2 * (ca.sum1(rel**2) + RANGE_REG_M**2)


def posterior_crlb(
    traj: Trajectory, config: EstimationConfig, schedule: Schedule | None = None
) -> CRLBResult:
    """Posterior CRB of ``(p, p')`` along ``traj`` with the sensors, rates and noises of ``config``.

    The prior is ``config.p0_ekf`` (paper default if None); the configuration's process noise
    when ``config.process_noise`` (:func:`pcrb_model_of`).

    Parameters
    ----------
    traj : Trajectory
        The path (the noise-free truth).
    config : EstimationConfig
        Sensors, rates, noises, prior and process noise.
    schedule : Schedule or None, optional
        Which sensor reports at which sample; None: from ``config.rates_hz``.

    Returns
    -------
    CRLBResult
        The bound's standard deviations at every sample.
    """
    model = config.model
    dt = 1.0 / sample_rate(traj)
    cov = config.covariances(dt)
    if schedule is None:
        schedule = config.schedule(traj)
    epochs = make_epochs(traj.t, schedule.mask)
    rec = pcrb_model_of(config, dt)
    xs = nominal_states(traj, model, config.current_array)
    n = model.dim
    t_ep = traj.t[epochs.index]
    beacons = epoch_beacons(model, config.beacon_path, t_ep, xs[epochs.index, :n])
    rel = (xs[epochs.index, :n] - beacons).T
    h, rho = range_information(rel, config.noise["range"])
    _, D = run_recursion(rec, epochs, cov["p0_ekf"], h, rho)
    var = epochs.sample_values(np.asarray(D))  # (2n, N)
    var = np.maximum(var, 0.0)
    pos_std = np.sqrt(var[:n].sum(axis=0))
    return CRLBResult(
        t=traj.t.copy(),
        pos_std_t=pos_std,
        vel_std_t=np.sqrt(var[n:].sum(axis=0)),
        pos_std_axes_t=np.sqrt(var[:n].T),
        final_pos_std=float(pos_std[-1]),
        mean_pos_std=float(np.mean(pos_std)),
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

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    config : EstimationConfig
        The model and the sensors' rates.
    scales : Scales or None, optional
        Nondimensionalisation; None: :func:`~obsplan.observability.gramian.rank_scales`.

    Returns
    -------
    ndarray of int, shape (N,)
        Rank of the sampled Gramian up to each sample (0 before any reading).
    """
    model = config.model
    aug = augmented_model(model)
    sched = config.schedule(traj)
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
