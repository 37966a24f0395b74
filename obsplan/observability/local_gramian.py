"""The local observability Gramian: the vehicle's own model linearised about a path.

The augmented model of :mod:`obsplan.observability.gramian` is exact and linear in its state, but
it is the model of the augmented Kalman filter. Its range row is the displacement ``d`` from the
constant-velocity extrapolation of the start (eq. 21), so it reads a straight leg at constant
speed as silent (``d = 0``) however its bearing to the beacon turns, and a sample's position
information grows with ``|d|²/r²``, which a range cannot carry. The EKF linearises the vehicle's
own model ``x = (p, v[, v_f])`` (``p' = v [+ v_f]``, ``v' = u``) about its estimate; along a
path, with ``u = (p - b)/|p - b|`` the line of sight and ``τ = t - t_0``, its rows referred to
``x(t_0)`` (``Φ(τ) = I + Aτ``, ``A² = 0`` as eq. 26) are

* range:                ``H Φ = (uᵀ, τ uᵀ, [τ uᵀ])``
* DVL (water-profiling, or no current): ``(0, I, [0])``; bottom-lock with current: ``(0, I, I)``
* depth:                ``(e_zᵀ, τ e_zᵀ, [τ e_zᵀ])``

and its Gramian ``∫ Φᵀ Hᵀ W H Φ dt`` is the local observability Gramian of the path (Krener and
Ide 2009; Hausman et al., RA-L 2017): with ``W`` each row's information rate (rate / variance;
a range carries ``1/σ_r²`` along the line of sight at any distance) it is the Fisher information
the samples carry about ``x(t_0)`` without process noise, what an EKF on the true path can
extract. It depends on where the beacon is, and a turning bearing excites it where the
augmented Gramian sees nothing.

Each interval is integrated by Simpson's rule on the exact quadratic path (the line of sight at
its start, midpoint and end): exact for the DVL and depth rows (degree 2 in ``σ``); for the
range rows the error is of order ``h⁴`` times the fourth derivative of the bearing, ``(h ω)⁴``
relative for a bearing rate ``ω`` (below 1e-4 for a 3 s step at 10 m from the beacon at 1 m/s).
Units are the metric scales of :mod:`obsplan.observability.scaling` (``p/L``, ``v T/L``,
``t/T``; outputs ``r/L``, ``v T/L``, ``p_z/L``), as the augmented Gramian's.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property

import casadi as ca
import numpy as np

from obsplan.model.vehicle import VehicleModel
from obsplan.observability.gramian import AugmentedModel
from obsplan.observability.scaling import Scales
from obsplan.trajectory.sampled import Trajectory

#: Simpson's rule: the nodes of an interval as fractions of it, and their weights.
SIMPSON_NODES = (0.0, 0.5, 1.0)
SIMPSON_WEIGHTS = (1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0)
#: The line of sight is ``q / sqrt(|q|² + δ²)`` with this ``δ`` [m]: the direction is undefined at
#: the beacon itself, which a plan with ``limits.min_range = 0`` may cross. A guard against the
#: 0/0, not a model: 1 nm is below double precision's resolution of ``|q|²`` (in the metric
#: scales) for any point more than 0.1 m from the beacon, so the rows there are bit-identical to
#: the unguarded ones, and at the beacon they and their derivatives stay finite.
LOS_FLOOR_M = 1e-9


@dataclass(frozen=True)
class LinearisedModel:
    """The vehicle's model ``x' = A x + B u`` (``x = (p, v[, v_f])``) with the rows of its
    sensors linearised about a path (module docstring)."""

    dim: int
    sensors: tuple[str, ...]
    current: bool

    @cached_property
    def _augmented(self) -> AugmentedModel:
        # x is the augmented state's leading block: z = (x, p_0ᵀν_0, |ν_0|²) (eq. 20); built
        # once per model (every property below and each window's re-anchoring read it)
        return AugmentedModel(dim=self.dim, sensors=self.sensors, current=self.current)

    @property
    def state_dim(self) -> int:
        """``2n``, or ``3n`` with current."""
        return self._augmented.state_dim - 2

    @property
    def state_names(self) -> tuple[str, ...]:
        return self._augmented.state_names[: self.state_dim]

    @property
    def A(self) -> np.ndarray:
        """Dynamics matrix (``p' = v``, with current ``p' = v + v_f``)."""
        m = self.state_dim
        return self._augmented.A[:m, :m]

    @property
    def n_outputs(self) -> int:
        """Range, then DVL axes, then depth: the rows of the augmented model, in its order."""
        return self._augmented.n_outputs

    def velocity_rows(self) -> np.ndarray:
        """The DVL rows ``(n, m)`` (none without a DVL): constant along any path, the augmented
        model's.

        Returns
        -------
        ndarray, shape (n, m) or (0, m)
            The DVL rows of ``H Φ``, ``m`` the state dimension.
        """
        k = self.dim if any(s.startswith("dvl") for s in self.sensors) else 0
        C = self._augmented.output_matrix(np.zeros(self.dim), 0.0)
        return C[1 : 1 + k, : self.state_dim]

    def rows(self, los, tau):
        """``H Φ`` of every output at line of sight ``los`` and elapsed time ``tau``: numpy,
        batched (``los`` (K, n), ``tau`` (K,) -> (K, n_outputs, m)), or CasADi SX (``los``
        (n, 1), ``tau`` scalar -> (n_outputs, m)).

        Parameters
        ----------
        los : ndarray, shape (K, n), or casadi.SX, shape (n, 1)
            Unit line of sight from the beacon to the vehicle.
        tau : ndarray, shape (K,), or casadi.SX scalar
            Elapsed time ``t - t_0`` (in the scales of the caller, normally nondimensional).

        Returns
        -------
        ndarray, shape (K, n_outputs, m), or casadi.SX, shape (n_outputs, m)
            The rows: range, then DVL axes, then depth.
        """
        n = self.dim
        nv = 2 if self.current else 1
        depth = "depth" in self.sensors
        ez = np.eye(n)[n - 1]
        if isinstance(los, np.ndarray):
            tau = np.asarray(tau, float)[:, None]

            def kinematic(vec):  # (K, n) -> (K, m)
                return np.concatenate([vec, *([tau * vec] * nv)], axis=1)

            vel = self.velocity_rows()
            out = [kinematic(los)[:, None], np.broadcast_to(vel, (los.shape[0], *vel.shape))]
            if depth:
                out.append(kinematic(np.broadcast_to(ez, los.shape))[:, None])
            return np.concatenate(out, axis=1)

        def kinematic_sx(vec):
            return ca.vertcat(vec, *([tau * vec] * nv)).T

        vel = self.velocity_rows()
        parts = [kinematic_sx(los)]
        if vel.shape[0]:
            parts.append(ca.DM(vel))
        if depth:
            parts.append(kinematic_sx(ca.DM(ez)))
        return ca.vertcat(*parts)


def linearised_model(model: VehicleModel) -> LinearisedModel:
    """The linearised model of a vehicle model (its sensors and current; not its beacon).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.

    Returns
    -------
    LinearisedModel
        Its model linearised about a path (module docstring).
    """
    return LinearisedModel(dim=model.dim, sensors=tuple(model.sensors), current=model.current)


def local_interval_gramians(
    traj: Trajectory,
    lm: LinearisedModel,
    beacon: np.ndarray,
    row_weights: np.ndarray,
    scales: Scales,
    calibration: bool = False,
) -> np.ndarray:
    """Contribution of every interval of ``traj`` to the local Gramian about ``x(t_0)``,
    ``∫ Φᵀ Hᵀ W H Φ`` by Simpson's rule (module docstring), shape ``(N-1, m, m)``.

    ``row_weights`` (n_outputs,) are each row's information rate in ``scales``
    (:func:`~obsplan.observability.windowed.local_row_weights`); ``beacon`` [m]. With
    ``calibration`` the parameters of a range ``k |p - b| + β`` join ``x(t_0)``: the scale
    ``k`` (its column ``|p - b| / L`` at ``k = 1``) and the bias ``β / L`` (column 1), on the
    range row only, so the Gramian is ``(N-1, m + 2, m + 2)``
    (:mod:`obsplan.observability.calibration`).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    lm : LinearisedModel
        The linearised model (sensors and current).
    beacon : ndarray, shape (n,)
        Beacon position [m].
    row_weights : ndarray, shape (n_outputs,)
        Information rate of each output row, in ``scales``.
    scales : Scales
        Nondimensionalisation (length [m] and time [s]).
    calibration : bool, optional
        Add the range's scale and bias as the last two parameters.

    Returns
    -------
    ndarray, shape (N-1, m, m), or (N-1, m + 2, m + 2) with ``calibration``
        The contribution of every interval, symmetric positive semi-definite.

    Raises
    ------
    ValueError
        If the model and the trajectory differ in dimension.
    """
    if lm.dim != traj.dim:
        raise ValueError(f"model is {lm.dim}D but the trajectory is {traj.dim}D")
    L, T = scales.length_m, scales.time_s
    tr = traj.scaled(L, T)
    p = tr.p - np.asarray(beacon, float) / L
    h = tr.dt
    tau = tr.t - tr.t[0]
    w = np.asarray(row_weights, float)
    d2 = (LOS_FLOOR_M / L) ** 2
    m = lm.state_dim + (2 if calibration else 0)
    G = np.zeros((h.size, m, m))
    for s, c in zip(SIMPSON_NODES, SIMPSON_WEIGHTS, strict=True):
        sh = (s * h)[:, None]
        q = p[:-1] + sh * tr.v[:-1] + 0.5 * sh**2 * tr.u[:-1]
        rho = np.sqrt(np.sum(q**2, axis=1, keepdims=True) + d2)
        R = lm.rows(q / rho, tau[:-1] + s * h)
        if calibration:  # the range row (output 0) on (k, β / L): (ρ / L, 1)
            R = np.concatenate([R, np.zeros((*R.shape[:2], 2))], axis=2)
            R[:, 0, -2] = rho[:, 0]
            R[:, 0, -1] = 1.0
        G += (c * h)[:, None, None] * np.einsum("kri,r,krj->kij", R, w, R)
    return G


@cache
def local_interval_gramian_function(lm: LinearisedModel) -> ca.Function:
    """CasADi ``vec G_k = g(p_a, p_m, p_b, tau0, h, w, d2)``: :func:`local_interval_gramians` of
    one interval from its positions relative to the beacon at its start, midpoint and end (n
    each), its start time from ``t_0`` and its length, the row weights (n_outputs) and the line of
    sight's floor ``(LOS_FLOOR_M / L)²``, all in the metric scales. Output: column-major ``vec``
    of the ``m × m`` contribution.

    Parameters
    ----------
    lm : LinearisedModel
        The linearised model (sensors and current).

    Returns
    -------
    casadi.Function
        The interval's contribution, built once per model (cached).
    """
    n = lm.dim
    ps = [ca.SX.sym(f"p{i}", n) for i in range(3)]
    tau0, h = ca.SX.sym("tau0"), ca.SX.sym("h")
    w = ca.SX.sym("w", lm.n_outputs)
    d2 = ca.SX.sym("d2")
    G = ca.SX.zeros(lm.state_dim, lm.state_dim)
    for q, s, c in zip(ps, SIMPSON_NODES, SIMPSON_WEIGHTS, strict=True):
        R = lm.rows(q / ca.sqrt(ca.sumsqr(q) + d2), tau0 + s * h)
        G += c * h * (R.T @ ca.diag(w) @ R)
    return ca.Function("local_interval_gramian", [*ps, tau0, h, w, d2], [ca.vec(G)])
