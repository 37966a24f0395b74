"""Gaussian-sum EKF for the range-only geometry: the prior split over the velocity.

Why
---
With range only, a straight leg is observable only through the curvature of the range: a path
mirrored about the line through the beacon along the leg, or rotated about the beacon when the
inputs are small, gives almost the same ranges. The posterior is then a banana or a ring, not a
Gaussian, and the EKF, started with a velocity prior as wide as the speed (the paper's
``P_v = 0.1 (m/s)²``), locks onto a wrong branch while its covariance shrinks: measured on a
straight accelerating non-radial line (600 s, 1 Hz range, 50 runs) the EKF ends 54–109 m off on
average with a reported std of 2 m. An iterated EKF and a UKF do no better there (same Gaussian
assumption: 60–128 m and 52–94 m); a Gaussian sum does (5–21 m, consistent NEES in the median run;
``docs/readme/estimation.md``).

What
----
The prior ``N(x̂0, P0)`` is split along the velocity columns ``d_j = L e_j`` of ``L = chol(P0)``
(:func:`split_columns`: the current's, with a water-profiling DVL that reads the velocity through
the water):
with a 1D split ``Σ_i w_i N(μ_i, s²) ≈ N(0, 1)`` (``k`` points on a grid, weights ``∝ N(μ_i; 0,
1 - s²)``, ``Σ w_i μ_i² = 1 - s²`` so the mixture keeps the prior's covariance exactly), component
``(i_1..i_n)`` has mean ``x̂0 + Σ_j μ_{i_j} d_j``, covariance ``P0 - (1 - s²) Σ_j d_j d_jᵀ`` and
weight ``Π_j w_{i_j}``. Each component is an EKF (:mod:`obsplan.estimation.filters.ekf`, same
prediction and updates); its weight is multiplied by the likelihood of its innovations; the estimate
and the covariance reported are the mixture's (its mean, and the weighted covariances plus the
spread of the means, so an unresolved ambiguity shows in the covariance instead of being hidden).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.config import EstimationConfig, ProcessNoise
from obsplan.estimation.filters.base import Filter, FilterRun, register
from obsplan.estimation.filters.ekf import (
    ExtendedKalmanFilter,
    calibration_prior,
    pad_calibration,
)
from obsplan.model.vehicle import VehicleModel

#: Points per velocity axis and component std (whitened) by dimension: 25 components in 2D,
#: 27 in 3D (measured in 2D: 3 points per axis leave 7 of 50 runs inconsistent on a straight
#: line where 5 points leave 4).
DEFAULT_SPLIT = {2: (5, 0.4), 3: (3, 0.5)}


def split_1d(k: int, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights and means of ``k`` components of std ``s`` whose mixture has mean 0, variance 1.

    Parameters
    ----------
    k : int
        Number of components.
    s : float
        Standard deviation of each component (whitened), in (0, 1).

    Returns
    -------
    w : ndarray, shape (k,)
        Weights, summing to 1.
    mu : ndarray, shape (k,)
        Means, on a symmetric grid.

    Raises
    ------
    ConfigError
        If ``k > 1`` and ``s`` is not in (0, 1).
    """
    if k == 1:
        return np.ones(1), np.zeros(1)
    if not 0.0 < s < 1.0:
        raise ConfigError(f"the component std of a split must be in (0, 1), got {s!r}")
    sw = np.sqrt(1.0 - s * s)
    mu = (np.arange(k) - (k - 1) / 2.0) * (2.2 * sw / (k - 1))
    w = np.exp(-0.5 * (mu / sw) ** 2)
    w /= w.sum()
    mu *= sw / np.sqrt(np.sum(w * mu * mu))
    return w, mu


def split_columns(model: VehicleModel) -> slice:
    """The columns of ``chol(P0)`` the prior is split along: the part of the inertial velocity
    ``p' = v (+ v_f)`` no linear sensor reads. A water-profiling DVL reads ``v`` to the mm/s,
    which would merge a split over ``v`` at its first reading: with a current it is ``v_f``'s
    (the lower-triangular factor's columns from ``2n`` move only ``v_f``, hence ``p'``).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (sensors and current).

    Returns
    -------
    slice
        The current's columns ``2n:3n`` (current and water-profiling DVL), else the velocity's
        ``n:2n``.
    """
    n = model.dim
    if model.current and "dvl-water" in model.sensors:
        return slice(2 * n, 3 * n)
    return slice(n, 2 * n)


@register
class GaussianSumFilter(Filter):
    """Gaussian-sum EKF (module docstring).

    Parameters
    ----------
    model, q, p0, noise
        As for :class:`~obsplan.estimation.filters.ekf.ExtendedKalmanFilter`.
    split : tuple of (int, float) or None, optional
        ``(points per velocity axis, component std)``; default :data:`DEFAULT_SPLIT`.
    second_order : bool, optional
        The components' range update (as for the EKF).
    scale_std, bias_std : float or None, optional
        The components' range-scale and range-bias states (as for the EKF; not split).
    """

    name = "gsf"
    description = "Gaussian-sum EKF, prior split over the velocity (range-only geometry)"

    def __init__(
        self,
        model: VehicleModel,
        q: np.ndarray,
        p0: np.ndarray,
        noise: dict[str, float],
        split: tuple[int, float] | None = None,
        second_order: bool = False,
        scale_std: float | None = None,
        bias_std: float | None = None,
    ) -> None:
        self.ekf = ExtendedKalmanFilter(model, q, p0, noise, second_order, scale_std, bias_std)
        self.model = model
        self.state_dim = self.ekf.state_dim
        k, s = DEFAULT_SPLIT[model.dim] if split is None else split
        n = model.dim
        w1, mu = split_1d(int(k), float(s))
        L = np.linalg.cholesky(np.asarray(p0, float))
        D = L[:, split_columns(model)]
        offsets, weights = [], []
        for idx in itertools.product(range(len(w1)), repeat=n):
            offsets.append(D @ mu[list(idx)])
            weights.append(np.prod(w1[list(idx)]))
        self.offsets = np.array(offsets)
        self.log_weights = np.log(np.array(weights))
        shrink = 0.0 if len(w1) == 1 else 1.0 - s * s
        cov = np.asarray(p0, float) - shrink * (D @ D.T)
        # the split is over the velocity: the range's calibration is not split
        _, variances = calibration_prior(scale_std, bias_std)
        self.offsets = np.hstack([self.offsets, np.zeros((self.offsets.shape[0], len(variances)))])
        self.component_cov = pad_calibration(cov, variances)

    @classmethod
    def from_config(
        cls, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise
    ) -> GaussianSumFilter:
        """The Gaussian sum of ``config`` (as the EKF's, default split).

        Parameters
        ----------
        config : EstimationConfig
            The model, sensor noises and filter options.
        cov : dict of str to ndarray
            Initial covariances ``p0_ekf``, ``p0_kf`` (:meth:`EstimationConfig.covariances
            <obsplan.estimation.config.EstimationConfig.covariances>`).
        pn : ProcessNoise
            Process noise: per-step covariances or intensities, as the epoch plan it runs on.

        Returns
        -------
        GaussianSumFilter
            The filter.
        """
        second = config.ekf_update == "second-order"
        noise, scale, bias = dict(config.noise), config.scale_prior_std, config.bias_prior_std
        return cls(config.model, pn.q_ekf, cov["p0_ekf"], noise, None, second, scale, bias)

    @property
    def components(self) -> int:
        return int(self.offsets.shape[0])

    def start(
        self, xhat0: np.ndarray, extra0: np.ndarray | None = None, r0: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Components ``(X0, P0, log w0)`` around the estimate ``xhat0``.

        Parameters
        ----------
        xhat0 : ndarray, shape (state_dim of the model,)
            Initial estimate of ``(p, v[, v_f])`` [m, m/s] (absolute positions).
        extra0 : ndarray, shape (2,), optional
            Initial estimates of ``(p0ᵀν0, |ν0|²)`` (the augmented KF's extra states).
        r0 : float, optional
            Range reading at the first sample [m] (the augmented KF's anchor ``y0``).

        Returns
        -------
        X0 : ndarray, shape (C, state_dim)
            The components' means.
        P0 : ndarray, shape (C, state_dim, state_dim)
            Their covariances (all equal).
        log_w0 : ndarray, shape (C,)
            Their log weights.
        """
        C = self.components
        x0 = np.append(np.asarray(xhat0, float), self.ekf.calibration_nominal)
        X0 = x0[None, :] + self.offsets
        P0 = np.ascontiguousarray(
            np.broadcast_to(self.component_cov, (C, *self.component_cov.shape))
        )
        return np.ascontiguousarray(X0), P0.copy(), self.log_weights.copy()

    def run(self, batch: RunBatch, record: RunRecord) -> None:
        """Filter a batch of runs (as :meth:`ExtendedKalmanFilter.run`): the EKF's kernel on
        every run's components, which it mixes by their weights.

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`), readings and, in
            closed loop, input corrections.
        record : RunRecord
            The truth at the records and the arrays the statistics are written into.
        """
        X0, P0, lw0 = self._members(batch.states)
        self.ekf._batch(batch, record, X0, P0, lw0, self.components)

    def _members(self, states: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The runs' components side by side: ``X0`` (m, R C), ``P0`` (m, m, R C), ``lw0``."""
        X0 = np.ascontiguousarray(np.concatenate([st[0] for st in states], axis=0).T)
        P0 = np.ascontiguousarray(
            np.concatenate([st[1] for st in states], axis=0).transpose(1, 2, 0)
        )
        return X0, P0, np.concatenate([st[2] for st in states])

    # ------------------------------------------------------------------ epoch by epoch
    def begin(self, batch: RunBatch) -> FilterRun:
        """The runs' components at epoch 0, before its update (:meth:`Filter.begin`).

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`) and readings.

        Returns
        -------
        FilterRun
            The runs at epoch 0, not yet updated.
        """
        X0, P0, lw0 = self._members(batch.states)
        return self.ekf._begin(batch, X0, P0, lw0, self.components)

    def predict(self, run: FilterRun) -> None:
        """Predict every component to the next epoch (:meth:`Filter.predict`).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).
        """
        self.ekf.predict(run)

    def update(self, run: FilterRun) -> None:
        """Update every component and its weight at the current epoch (:meth:`Filter.update`).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).
        """
        self.ekf.update(run)
