"""The vehicle's posterior CRB along its fixed path as a function of the beacon at the range epochs.

The vehicle flies a known path, so everything in its covariance recursion is fixed except the
range rows, which depend on where the beacon is at each range epoch. The recursion is the
posterior CRB of the validation (:func:`obsplan.estimation.bounds.crlb.posterior_crlb`): state
``(p, v[, v_f])``, the configuration's prior, process noise, sensors, rates and noises
(:func:`~obsplan.estimation.bounds.crlb.pcrb_model_of`), the filter grid of the vehicle's samples
(:func:`~obsplan.estimation.bounds.riccati.make_epochs` of its schedule), the regularised range
information (:func:`~obsplan.estimation.bounds.crlb.range_information`) at ``p(t_k) - b_k``.

Why not :class:`~obsplan.planning.objectives.estimator.CovarianceObjective`: it is welded to the
vehicle's planning grid (its range rows are an affine map of the vehicle's decision variables, its
epochs those of a ``PlanningProblem``), and it steps the recursion at every filter epoch. With a
DVL at 10 Hz that is 10,000 symbolic epochs for a 1,000 s survey, of which only the 100 range
epochs depend on the beacon. Here everything between two range epochs is folded, numerically and
exactly, into one *gap element* ``(A, C, J)``, the map

    P ↦ A P (I + J P)⁻¹ Aᵀ + C,

which a prediction ``(F, Q, 0)`` and a measurement update ``(I, 0, hᵀh/σ²)`` both are, and which
composes associatively (Särkkä & García-Fernández, IEEE TAC 2021, the parallel Kalman filter):
``e_i`` then ``e_j`` is ``A = A_j (I + C_i J_j)⁻¹ A_i``, ``C = A_j (I + C_i J_j)⁻¹ C_i A_jᵀ + C_j``,
``J = A_iᵀ (I + J_j C_i)⁻¹ J_j A_i + J_i``. ``I + J P`` has eigenvalues ≥ 1 for ``P, J ⪰ 0``, so
the folding loses no precision (checked against the posterior CRB to 1e-9 in the tests). The
symbolic recursion then has one range update and at most two gap elements per range epoch.

The objective
-------------
With ``P⁺_k`` the covariance after every update at range epoch ``k`` and ``P⁻_{k+1}`` the one
just before the next range epoch (at the last range epoch: the covariance at the path's last
sample), the per-epoch value is the trapezoid ``e_k = ½ (tr P⁺_pp,k + tr P⁻_pp,k+1)`` [m²], the
mean position variance over the gap that follows the ping (exact when it grows linearly), and

    J = Σ_k w_k e_k / Σ_k w_k + tr P_pp(t_f)        [m²]

with ``w_k`` the caller's weights (e.g. 1 on the survey lines, 0 in the turns). The mean is the
bound on the EKF's mean squared position error over the (weighted) survey; the final term is the
error at recovery, which the validation judges too. Both in m², so neither needs a reference
value to be added to the other. Variances rather than standard deviations (the EKF's
``rmse_pos`` averages a root): smooth at any value, additive over time, and they weigh the worst
stretches of the survey more.

Beacon at transmission: each range is taken to the beacon at ``t_k - r_k/c``
(:func:`~obsplan.estimation.epochs.epoch_beacons`); :class:`RangeRecursion` takes those positions
as its input, the planner computes them (:mod:`obsplan.planning.beacon.craft`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import pcrb_model_of, range_information
from obsplan.estimation.bounds.riccati import RecursionModel, faulhaber, make_epochs
from obsplan.estimation.channel import CHANNEL_PRESETS, Channel
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.epochs import epoch_beacons, nominal_states
from obsplan.estimation.schedule import sample_rate
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.trajectory.sampled import Trajectory

Element = tuple[np.ndarray, np.ndarray, np.ndarray]


def _identity(m: int) -> Element:
    return np.eye(m), np.zeros((m, m)), np.zeros((m, m))


def combine(first: Element, second: Element) -> Element:
    """The gap element of ``first`` then ``second`` (module docstring).

    Parameters
    ----------
    first, second : tuple of ndarray, each (m, m)
        Elements ``(A, C, J)``: ``P ↦ A P (I + J P)⁻¹ Aᵀ + C``.

    Returns
    -------
    tuple of ndarray
        The composed element ``(A, C, J)``.
    """
    A1, C1, J1 = first
    A2, C2, J2 = second
    eye = np.eye(A1.shape[0])
    left = np.linalg.solve(eye + J2 @ C1, A2.T).T  # A2 (I + C1 J2)^-1, C and J symmetric
    A = left @ A1
    C = left @ C1 @ A2.T + C2
    J = A1.T @ np.linalg.solve(eye + J2 @ C1, J2) @ A1 + J1
    return A, 0.5 * (C + C.T), 0.5 * (J + J.T)


def apply_element(e: Element, P):
    """``A P (I + J P)⁻¹ Aᵀ + C`` for a numeric or CasADi ``P`` (m, m).

    Parameters
    ----------
    e : tuple of ndarray
        The element ``(A, C, J)``.
    P : ndarray or casadi.SX, shape (m, m)
        A covariance.

    Returns
    -------
    ndarray or casadi.SX, shape (m, m)
        The mapped covariance, symmetrised.
    """
    A, C, J = e
    m = A.shape[0]
    if isinstance(P, np.ndarray):
        X = P if not J.any() else np.linalg.solve(np.eye(m) + P @ J, P)
        out = A @ X @ A.T + C
        return 0.5 * (out + out.T)
    X = P if not J.any() else ca.solve(ca.DM.eye(m) + P @ ca.DM(J), P)
    out = ca.DM(A) @ X @ ca.DM(A.T) + ca.DM(C)
    return 0.5 * (out + out.T)


def _prediction(rec: RecursionModel, k: int, dt: float) -> Element:
    """Element of ``k`` filter steps of ``dt`` [s]: ``F = I + A k dt`` and the noise of
    :mod:`obsplan.estimation.bounds.riccati` (continuous intensity or per step)."""
    A = np.asarray(rec.A, float)
    q = np.asarray(rec.q, float)
    T = k * dt
    if rec.continuous:
        I0, I1, I2 = T, T**2 / 2, T**3 / 3
    else:
        S = faulhaber(float(k), 2)
        I0, I1, I2 = S[0], dt * S[1], dt**2 * S[2]
    Q = I0 * q + I1 * (A @ q + q @ A.T) + I2 * (A @ q @ A.T)
    return np.eye(A.shape[0]) + A * T, Q, np.zeros_like(A)


def _updates(rec: RecursionModel, mask: np.ndarray) -> Element:
    """Element of the constant rows (DVL, depth) reporting in ``mask`` (S,)."""
    m = rec.m
    J = np.zeros((m, m))
    for row, var, sensor in zip(rec.rows, rec.row_var, rec.row_sensor, strict=True):
        if mask[sensor]:
            J += np.outer(row, row) / var
    return np.eye(m), np.zeros((m, m)), J


@dataclass(frozen=True, eq=False)
class RangeRecursion:
    """The posterior CRB along a fixed vehicle path, as a function of the beacon at its range
    epochs (module docstring).

    Attributes
    ----------
    times : ndarray, shape (E,)
        Range epochs [s] (the samples of the vehicle's path where the range reports).
    positions : ndarray, shape (E, n)
        The vehicle's (nominal) positions there [m].
    sigma : float
        Range noise [m].
    P0 : ndarray, shape (m, m)
        Prior at the first sample (the first sample is always a range epoch).
    after : tuple of Element
        Per range epoch, the constant-row updates at that epoch.
    gaps : tuple of Element
        Per range epoch, everything up to just before the next range epoch (the last: up to and
        including the updates at the path's last sample).
    model : VehicleModel
        The vehicle model.
    channel : Channel
        The acoustic channel: a recursion on the expected information of pings it loses
        (:meth:`~obsplan.estimation.channel.Channel.expected_variance`).
    """

    times: np.ndarray
    positions: np.ndarray
    sigma: float
    P0: np.ndarray
    after: tuple[Element, ...]
    gaps: tuple[Element, ...]
    model: VehicleModel
    channel: Channel = CHANNEL_PRESETS["ideal"]

    @property
    def n(self) -> int:
        """Spatial dimension."""
        return int(self.model.dim)

    @property
    def count(self) -> int:
        """Number of range epochs ``E``."""
        return int(self.times.size)

    def traces(self, B):
        """``(tr P⁺_pp, tr P⁻_pp)`` per range epoch for the beacon positions ``B`` (n, E) [m²].

        ``P⁺`` after every update at the epoch, ``P⁻`` just before the next range epoch (the last
        entry: at the path's last sample, after its updates).

        Parameters
        ----------
        B : ndarray or casadi.SX, shape (n, E)
            Beacon positions the ranges are taken to [m].

        Returns
        -------
        post, prior_next : list of float or casadi.SX
            The two traces per epoch [m²].
        """
        rel = self.positions.T - B
        h, rho = range_information(rel, self.sigma)
        rho = self.channel.expected_variance(rho, rel)
        n = self.n
        P = self.P0 if isinstance(B, np.ndarray) else ca.DM(self.P0)
        post, nxt = [], []
        for k in range(self.count):
            hk = h[:, k]
            Ph = P[:, :n] @ hk
            s = hk.T @ Ph[:n] + rho[0, k]
            P = P - (Ph @ Ph.T) / s if not isinstance(B, np.ndarray) else P - np.outer(Ph, Ph) / s
            P = apply_element(self.after[k], P)
            post.append(_trace_pp(P, n))
            P = apply_element(self.gaps[k], P)
            nxt.append(_trace_pp(P, n))
        return post, nxt

    def objective(self, B, weights: np.ndarray):
        """``J`` of the module docstring [m²] for beacon positions ``B`` (n, E).

        Parameters
        ----------
        B : ndarray or casadi.SX, shape (n, E)
            Beacon positions at the range epochs [m].
        weights : ndarray, shape (E,)
            Weight of each range epoch, ``>= 0`` with a positive sum.

        Returns
        -------
        float or casadi.SX
            The objective [m²].
        """
        mean, final = self.terms(B, weights)
        return mean + final

    def terms(self, B, weights: np.ndarray):
        """The two terms of ``J``: the weighted mean of the per-epoch values and the final
        position variance [m²].

        Parameters
        ----------
        B : ndarray or casadi.SX, shape (n, E)
            Beacon positions at the range epochs [m].
        weights : ndarray, shape (E,)
            Weight of each range epoch, ``>= 0`` with a positive sum.

        Returns
        -------
        mean, final : float or casadi.SX
            ``Σ w_k e_k / Σ w_k`` and ``tr P_pp(t_f)`` [m²].
        """
        post, nxt = self.traces(B)
        w = np.asarray(weights, float) / float(np.sum(weights))
        mean = sum(0.5 * wk * (a + b) for wk, a, b in zip(w, post, nxt, strict=True) if wk > 0)
        return mean, nxt[-1]

    def beacons_on_path(self, path: BeaconPath) -> np.ndarray:
        """The positions ``B`` (n, E) a known beacon path gives the ranges (at transmission,
        :func:`~obsplan.estimation.epochs.epoch_beacons`) [m].

        Parameters
        ----------
        path : BeaconPath
            The beacon's path, covering the range epochs.

        Returns
        -------
        ndarray, shape (n, E)
            Beacon positions [m].
        """
        return epoch_beacons(self.model, path, self.times, self.positions).T


def _trace_pp(P, n: int):
    return sum(P[i, i] for i in range(n))


def range_recursion(vehicle: Trajectory, config: EstimationConfig) -> RangeRecursion:
    """The :class:`RangeRecursion` of ``vehicle`` flown with the sensors of ``config``.

    The filter grid is the vehicle's samples and the schedule ``config.rates_hz`` on it, as
    :func:`~obsplan.estimation.bounds.crlb.posterior_crlb` has them; ``config.beacon_path`` is
    ignored (the beacon is the unknown).

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's fixed path (the noise-free truth).
    config : EstimationConfig
        Sensors (``range`` required), rates, noises, prior and process noise.

    Returns
    -------
    RangeRecursion
        The folded recursion.

    Raises
    ------
    ConfigError
        A model without a range sensor.
    """
    model = config.model
    if "range" not in model.sensors:
        raise ConfigError("planning the beacon needs the range sensor in config.model.sensors")
    dt = 1.0 / sample_rate(vehicle)
    rec = pcrb_model_of(config, dt)
    sched = config.schedule(vehicle)
    epochs = make_epochs(vehicle.t, sched.mask)
    ri = model.sensors.index("range")
    is_range = epochs.mask[:, ri] > 0
    xs = nominal_states(vehicle, model, config.current_array)
    after, gaps = [], []
    J = epochs.count
    gap: Element | None = None
    for j in range(J):
        if is_range[j]:
            if gap is not None:
                gaps.append(gap)
            after.append(_updates(rec, epochs.mask[j]))
            gap = _identity(rec.m)
        else:
            assert gap is not None  # epoch 0 is always a range epoch (make_schedule)
            gap = combine(gap, _updates(rec, epochs.mask[j]))
        if j < J - 1:
            gap = combine(gap, _prediction(rec, int(epochs.gap[j]), float(epochs.dt[j])))
    assert gap is not None
    gaps.append(gap)
    idx = epochs.index[is_range]
    cov = config.covariances(dt)
    return RangeRecursion(
        times=vehicle.t[idx].copy(),
        positions=xs[idx, : model.dim].copy(),
        sigma=float(config.noise["range"]),
        P0=np.asarray(cov["p0_ekf"], float),
        after=tuple(after),
        gaps=tuple(gaps),
        model=model,
        channel=config.channel,
    )
