"""Extended Kalman filter on the nonlinear model (paper section 7, eqs. 4–5, 28–30, 48–49).

State ``x = (p, v[, v_f])`` of :class:`obsplan.model.VehicleModel`, exact ZOH prediction
(``VehicleModel.transition``) and the model's outputs ``h``/``H`` (range in the model's
``range_form``, DVL, depth), batched over runs. At each sample the filter first updates jointly
with the sensors that report, linearised once at the prior, then predicts to the next sample with
the input held over the interval.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from obsplan.estimation import kalman
from obsplan.estimation.sensors import OutputModel, output_model, to_outputs
from obsplan.model import VehicleModel
from obsplan.trajectory import Trajectory


class EKFState(NamedTuple):
    """Batched EKF state: estimates ``x`` (R, m) and covariances ``P`` (R, m, m)."""

    x: np.ndarray
    P: np.ndarray


@dataclass(frozen=True, eq=False)
class ExtendedKalmanFilter:
    """Batched EKF bound to the inputs and step times of one trajectory.

    Parameters
    ----------
    model
        Vehicle model (sensors, current, beacon, range form).
    traj
        Supplies the inputs ``u_k`` [m/s²] and steps ``dt_k`` [s] for prediction.
    q
        Process-noise covariance per step, shape ``(m, m)``.
    noise
        Measurement standard deviation per sensor (range [m] on ``r``, DVL [m/s], depth [m]).
    """

    model: VehicleModel
    traj: Trajectory
    q: np.ndarray
    noise: dict[str, float]
    _out: OutputModel = field(init=False, repr=False)
    _lin: np.ndarray = field(init=False, repr=False)
    _steps: dict = field(init=False, repr=False)

    def __post_init__(self) -> None:
        out = output_model(self.model)
        object.__setattr__(self, "_out", out)
        object.__setattr__(self, "_lin", out.linear_rows)
        object.__setattr__(self, "_steps", {})  # (F, G) per step length: a cache, not state

    @property
    def state_dim(self) -> int:
        return self.model.state_dim

    def init(self, x0: np.ndarray, P0: np.ndarray) -> EKFState:
        """Initial state from estimates ``x0`` (R, m) and a common covariance ``P0`` (m, m)."""
        x0 = np.array(x0, dtype=float, ndmin=2)
        return EKFState(x0, np.broadcast_to(P0, (x0.shape[0], *P0.shape)).copy())

    def predict(self, st: EKFState, k: int) -> EKFState:
        """Propagate from sample ``k`` to ``k + 1`` with ``u_k`` held on the interval."""
        dt = float(self.traj.t[k + 1] - self.traj.t[k])
        FG = self._steps.get(dt)
        if FG is None:
            FG = self._steps.setdefault(dt, self.model.transition(dt))
        F, G = FG
        return EKFState(*kalman.predict(st.x, st.P, F, G @ self.traj.u[k], self.q))

    def update(self, st: EKFState, readings: dict[str, np.ndarray]) -> EKFState:
        """Update with device readings (per sensor, shape (R, k); NaN or absent = no report)."""
        if not readings:
            return st
        y, var = to_outputs(self.model, readings, self.noise)
        return self.update_outputs(st, y, var)

    def update_outputs(self, st: EKFState, y: np.ndarray, var: np.ndarray) -> EKFState:
        """Update with outputs ``y`` (R, p) in the model's form and variances ``var`` (R, p)."""
        rows = np.flatnonzero(np.any(np.isfinite(y), axis=0))
        if rows.size == 0:
            return st
        out = self._out
        x = st.x
        if np.all(self._lin[rows]):
            H = out.g[rows]
            hx = out.c[rows] + x @ H.T
        else:  # one linearisation at the prior for every row: the joint EKF update
            h0, H0 = out.evaluate(x)
            H, hx = H0[:, rows], h0[:, rows]
        return EKFState(*kalman.update(x, st.P, H, y[:, rows] - hx, var[:, rows]))

    def nav(self, st: EKFState) -> tuple[np.ndarray, np.ndarray]:
        """Navigation estimate ``(p, p')`` (R, 2n) and its covariance (R, 2n, 2n)."""
        n = self.model.dim
        if not self.model.current:
            return st.x[:, : 2 * n], st.P[:, : 2 * n, : 2 * n]
        T = kalman.nav_matrix(n, True, self.state_dim)
        return st.x @ T.T, T @ st.P @ T.T
