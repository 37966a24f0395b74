"""Measurements: batched evaluation of the model's ``h``/``H``, noisy readings and their units.

Evaluating ``h`` and ``H`` for many runs per step through CasADi costs ~140 µs per call for 100 runs
(almost all of it numpy↔DM conversion), more than the whole Kalman update. Every output of the
model is at most quadratic in the state except the plain range ``|p - b|``, so
:class:`OutputModel` takes the exact Taylor coefficients ``h(0)``, ``H(0)`` and the (constant)
Hessian of each quadratic row from the model's CasADi ``H`` once, and evaluates
``h(x) = h(0) + H(0) x + ½ xᵀ M x`` and ``H(x) = H(0) + xᵀ M`` in numpy: exact, not an
approximation. Rows that are not quadratic (``range_form="range"``) fall back to the model's
CasADi ``h``/``H`` mapped over the runs.

Devices report the range ``r`` [m] with noise ``σ_r`` (docs/design.md). For the paper's output
``y = ½ r²`` the reading is converted as ``y = ½ r_m² - ½ σ_r²`` (unbiased:
``E[½ (r + ε)²] = ½ r² + ½ σ_r²``) with variance ``r_m² σ_r² + ½ σ_r⁴`` (exact for Gaussian ``ε``
when ``r_m`` is replaced by ``r``; first order otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from obsplan.model.vehicle import VehicleModel


@dataclass(frozen=True, eq=False)
class OutputModel:
    """Batched ``h(x)`` and ``H(x)`` of a vehicle model.

    Attributes
    ----------
    c : ndarray, shape (p,)
        ``h(0)``.
    g : ndarray, shape (p, m)
        ``H(0)``.
    M : ndarray, shape (p, m, m)
        Hessians of the quadratic rows (zero for linear rows).
    quadratic : ndarray of bool, shape (p,)
        Rows evaluated exactly from ``c, g, M``; the others use CasADi.
    """

    model: VehicleModel
    c: np.ndarray
    g: np.ndarray
    M: np.ndarray
    quadratic: np.ndarray

    @property
    def linear_rows(self) -> np.ndarray:
        """Rows whose Jacobian is constant (``M = 0`` and quadratic), shape (p,) bool."""
        return self.quadratic & ~np.any(self.M != 0, axis=(1, 2))

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``h`` and ``H`` at states ``x`` of shape ``(R, m)``.

        Parameters
        ----------
        x : ndarray, shape (R, m)
            States of ``R`` runs (position [m], velocity [m/s][, current [m/s]]).

        Returns
        -------
        h : ndarray, shape (R, p)
            Outputs, in the model's form (range term [m² or m], DVL [m/s], depth [m]).
        H : ndarray, shape (R, p, m)
            Their Jacobians with respect to the state.
        """
        x = np.asarray(x, float)
        xM = np.einsum("rj,ijk->rik", x, self.M)  # (R, p, m)
        H = self.g[None] + xM
        h = self.c[None] + x @ self.g.T + 0.5 * np.einsum("rik,rk->ri", xM, x)
        if not np.all(self.quadratic):
            hc, Hc = _casadi_eval(self.model, x)
            rows = ~self.quadratic
            h[:, rows] = hc[:, rows]
            H[:, rows] = Hc[:, rows]
        return h, H


def _casadi_eval(model: VehicleModel, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R, m = x.shape
    p = model.output_dim
    h = np.asarray(model.h.map(R)(x.T)).T
    H = np.asarray(model.H.map(R)(x.T)).reshape(p, R, m).transpose(1, 0, 2)
    return h, H


@cache
def output_model(model: VehicleModel) -> OutputModel:
    """Build the :class:`OutputModel` of ``model`` from its CasADi ``H`` (cached per model).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.

    Returns
    -------
    OutputModel
        Its batched ``h`` and ``H``.
    """
    x = model.x_sym
    m, p = model.state_dim, model.output_dim
    Hx = model.H(x)
    quadratic = np.zeros(p, dtype=bool)
    hess_rows = []
    for i in range(p):
        hess = ca.jacobian(Hx[i, :].T, x)
        quadratic[i] = not ca.depends_on(hess, x)
        hess_rows.append(hess)
    fn = ca.Function("taylor0", [x], [model.h(x), Hx, ca.vertcat(*hess_rows)])
    c, g, M = (np.asarray(a, float) for a in fn(np.zeros(m)))
    M = M.reshape(p, m, m)
    M[~quadratic] = 0.0
    return OutputModel(model=model, c=c.reshape(p), g=g.reshape(p, m), M=M, quadratic=quadratic)


# ---------------------------------------------------------------------- readings


def to_outputs(
    model: VehicleModel, readings: dict[str, np.ndarray], noise: dict[str, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Convert device readings to the model's stacked outputs and their variances.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (its sensors, output order and range form).
    readings : dict of str to ndarray, shape (R, k)
        Per sensor, shape ``(R, k)``; NaN where a reading is missing. Sensors absent from the
        dict are missing for every run.
    noise : dict of str to float
        Standard deviation per sensor (range in metres on ``r``).

    Returns
    -------
    y, var : ndarray, shape (R, p)
        Outputs in the model's form (``½ r²`` or ``r`` for the range) and their variances; NaN
        outputs mean "no update".
    """
    R = next(iter(readings.values())).shape[0] if readings else 0
    y = np.full((R, model.output_dim), np.nan)
    var = np.ones((R, model.output_dim))
    for s, sl in model.output_slices.items():
        if s not in readings:
            continue
        val = readings[s]
        sig = noise[s]
        if s == "range" and model.range_form == "half-squared":
            y[:, sl] = 0.5 * val**2 - 0.5 * sig**2
            var[:, sl] = np.where(np.isfinite(val), val**2 * sig**2 + 0.5 * sig**4, 1.0)
        else:
            y[:, sl] = val
            var[:, sl] = sig**2
    return y, var
