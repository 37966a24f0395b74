"""Kalman filter on the augmented linear model (eqs. 19–24; DVL/depth rows of eq. 41).

State ``z = (p - b, v[, v_f], p0ᵀν0, |ν0|²)`` (``observability.gramian.AugmentedModel``,
positions relative to the beacon ``b``), dynamics ``z' = A z + B u`` discretised exactly
(``A² = 0``: ``Φ = I + A dt``, ``Γ = B dt + A B dt²/2``, eq. 26) and outputs
``C(t) = AugmentedModel.output_matrix(d, t - t0)`` with the range row fed by

    ȳ = y - y0 + ½|d|²                                                            (eq. 19)

where ``y = ½ r²`` is computed from the range reading (see :mod:`obsplan.estimation.sensors`),
``y0`` is the reading at the first sample and ``d`` the displacement of the known inputs (eq. 15).

The anchor's noise
------------------
``ȳ_k = C_k z + ε_k - ε_0``: the error ``ε_0`` of ``y0`` enters every later output, so the noises
are correlated and a plain KF that treats them as independent averages ``ε_0`` away and becomes
over-confident. ``y0_mode="augment"`` (default) appends the constant ``β = -ε_0`` to the state
with prior variance ``var(y0)`` and a ``1`` in the range row: the model is then exactly linear
Gaussian (the range update at ``t0`` is skipped: ``ȳ_0 ≡ 0`` carries no information). The price is
one more state, and ``β`` is only known to ``±σ_y0`` until the path makes it observable (it is, on
paths that make the Gramian full rank: its column is the constant 1). ``y0_mode="inflate"`` keeps
the paper's state and adds ``var(y0)`` to each ``R`` instead.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from obsplan.errors import ConfigError
from obsplan.estimation import kalman
from obsplan.estimation.config import Y0Mode
from obsplan.model import VehicleModel
from obsplan.observability.gramian import AugmentedModel, augmented_model
from obsplan.trajectory import Trajectory


class KFState(NamedTuple):
    """Batched KF state: ``z`` (R, m), ``P`` (R, m, m), anchor ``y0`` (R,) [m²], ``var0`` (R,)."""

    z: np.ndarray
    P: np.ndarray
    y0: np.ndarray
    var0: np.ndarray


def input_displacement(traj: Trajectory) -> np.ndarray:
    """``d(t_k, t_0)`` of eq. 15 from the inputs alone (exact ZOH), shape (N, n) [m]."""
    z = np.zeros(traj.dim)
    return Trajectory.from_inputs(traj.t, z, z, traj.u).p


@dataclass(frozen=True, eq=False)
class AugmentedKalmanFilter:
    """Batched augmented KF bound to one trajectory's inputs and times.

    Parameters
    ----------
    model
        Vehicle model (sensors, current, beacon); the KF always uses ``ȳ`` built from ``½ r²``.
    traj
        Supplies ``u_k``, ``dt_k`` and the input displacement ``d_k``.
    q
        Per-step process-noise covariance of the augmented state, shape ``(2n+2, 2n+2)`` (or
        ``(3n+2, ...)`` with current), without ``β``.
    noise
        Standard deviation per sensor (range [m] on ``r``).
    y0_mode
        ``"augment"`` or ``"inflate"`` (module docstring).
    """

    model: VehicleModel
    traj: Trajectory
    q: np.ndarray
    noise: dict[str, float]
    y0_mode: Y0Mode = "augment"
    aug: AugmentedModel = field(init=False, repr=False)
    _d: np.ndarray = field(init=False, repr=False)
    _A: np.ndarray = field(init=False, repr=False)
    _B: np.ndarray = field(init=False, repr=False)
    _Q: np.ndarray = field(init=False, repr=False)
    _steps: dict = field(init=False, repr=False)

    def __post_init__(self) -> None:
        aug = augmented_model(self.model)
        object.__setattr__(self, "aug", aug)
        object.__setattr__(self, "_d", input_displacement(self.traj))
        m = self.state_dim
        A, B, Q = np.zeros((m, m)), np.zeros((m, aug.dim)), np.zeros((m, m))
        ma = aug.state_dim
        A[:ma, :ma], B[:ma], Q[:ma, :ma] = aug.A, aug.B, self.q
        object.__setattr__(self, "_A", A)
        object.__setattr__(self, "_B", B)
        object.__setattr__(self, "_Q", Q)
        object.__setattr__(self, "_steps", {})  # (F, G) per step length: a cache, not state

    @property
    def state_dim(self) -> int:
        """Augmented state size, plus one for ``β`` when ``y0_mode == "augment"``."""
        return augmented_model(self.model).state_dim + (self.y0_mode == "augment")

    def _y(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sig = self.noise["range"]
        return 0.5 * r**2 - 0.5 * sig**2, r**2 * sig**2 + 0.5 * sig**4

    def init(
        self, x0: np.ndarray, P0: np.ndarray, r0: np.ndarray, extra0: np.ndarray | None = None
    ) -> KFState:
        """Initial state.

        Parameters
        ----------
        x0 : (R, state_dim of the model)
            Initial estimate of ``(p, v[, v_f])`` (absolute positions).
        P0 : (2n+2, 2n+2) or (3n+2, 3n+2)
            Initial covariance of ``z`` (``β``'s variance is added from the anchor).
        r0 : (R,)
            Range reading at the first sample [m] (the anchor ``y0``).
        extra0 : (R, 2), optional
            Initial estimates of ``(p0ᵀν0, |ν0|²)``; by default computed from ``x0``.
        """
        x0 = np.array(x0, dtype=float, ndmin=2)
        R, n = x0.shape[0], self.model.dim
        r0 = np.broadcast_to(np.asarray(r0, float).reshape(-1), (R,))
        if not np.all(np.isfinite(r0)):
            raise ConfigError(
                "the augmented KF needs a range reading at the first sample (the anchor y0 of "
                "eq. 19); make the range report at t0"
            )
        prel = x0[:, :n] - self.model.beacon_array
        nu = x0[:, n : 2 * n] + (x0[:, 2 * n : 3 * n] if self.model.current else 0.0)
        if extra0 is None:
            extra0 = np.column_stack([np.einsum("ri,ri->r", prel, nu), np.sum(nu**2, axis=1)])
        m, ma = self.state_dim, self.aug.state_dim
        z = np.zeros((R, m))
        z[:, :n] = prel
        z[:, n : ma - 2] = x0[:, n:]
        z[:, ma - 2 : ma] = extra0
        y0, var0 = self._y(r0)
        P = np.zeros((R, m, m))
        P[:, :ma, :ma] = P0
        if self.y0_mode == "augment":
            P[:, m - 1, m - 1] = var0
        return KFState(z, P, y0.copy(), var0.copy())

    def predict(self, st: KFState, k: int) -> KFState:
        """Propagate from sample ``k`` to ``k + 1`` (exact: ``Φ = I + A dt``, eq. 26)."""
        dt = float(self.traj.t[k + 1] - self.traj.t[k])
        FG = self._steps.get(dt)
        if FG is None:
            FG = (
                np.eye(self.state_dim) + self._A * dt,
                self._B * dt + self._A @ self._B * (0.5 * dt**2),
            )
            self._steps[dt] = FG
        F, G = FG
        Gu = G @ self.traj.u[k]
        z, P = kalman.predict(st.z, st.P, F, Gu, self._Q)
        return KFState(z, P, st.y0, st.var0)

    def update(self, st: KFState, k: int, readings: dict[str, np.ndarray]) -> KFState:
        """Update at sample ``k`` with device readings (per sensor (R, k); NaN = no report)."""
        if not readings:
            return st
        d = self._d[k]
        tau = float(self.traj.t[k] - self.traj.t[0])
        C = self.aug.output_matrix(d, tau)
        if self.y0_mode == "augment":
            C = np.column_stack([C, np.zeros(C.shape[0])])
            C[0, -1] = 1.0
        rows, ys, vs = [], [], []
        row = 0
        R = st.z.shape[0]
        for s in self.model.sensors:
            width = self.model.dim if s.startswith("dvl") else 1
            val = readings.get(s)
            if val is not None and not (s == "range" and k == 0):  # ȳ_0 ≡ 0: the anchor
                if s == "range":
                    y, var = self._y(val[:, 0])
                    y = y - st.y0 + 0.5 * float(d @ d)
                    if self.y0_mode == "inflate":
                        var = var + st.var0
                    ys.append(y[:, None])
                    vs.append(var[:, None])
                else:
                    ref = self.model.beacon_array[2] if s == "depth" else 0.0
                    ys.append(val - ref)
                    vs.append(np.full((R, width), self.noise[s] ** 2))
                rows.extend(range(row, row + width))
            row += width
        if not rows:
            return st
        H = C[rows]
        y = np.hstack(ys)
        z, P = kalman.update(st.z, st.P, H, y - st.z @ H.T, np.hstack(vs))
        return KFState(z, P, st.y0, st.var0)

    def nav(self, st: KFState) -> tuple[np.ndarray, np.ndarray]:
        """Navigation estimate ``(p, p')`` (R, 2n) with absolute positions, and its covariance."""
        n = self.model.dim
        T = kalman.nav_matrix(n, self.model.current, self.state_dim)
        est = st.z @ T.T
        est[:, :n] += self.model.beacon_array
        if not self.model.current:
            return est, st.P[:, : 2 * n, : 2 * n]
        return est, T @ st.P @ T.T
