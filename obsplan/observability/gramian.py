"""Global observability: the augmented LTV model and its exact observability Gramian (eqs. 14–27).

Augmented model
---------------
Integrating ``p' = ν``, ``ν' = u`` (``ν = v``, or ``v + v_f`` with current) gives
``p(t) = p0 + ν0 (t - t0) + d(t, t0)`` (eqs. 14–15) and hence (eqs. 18–21)

    ``ȳ(t) = y(t) - y0 + ½|d|² = dᵀ p(t) + (t - t0) p0ᵀν0 + ½ (t - t0)² |ν0|²``

with positions relative to the beacon. The augmented state is ``z = (p, v, p0ᵀν0, |ν0|²)``
(eq. 20) or, with current, ``z = (p, v, v_f, p0ᵀν0, |ν0|²)``; ``z' = A z + B u`` (eq. 23) with
``A²= 0`` so ``Φ(τ) = I + A τ`` (eq. 26). Output rows of each sensor, referred to ``z(t0)``:

* range (eq. 21):      ``C Φ = (dᵀ, τ dᵀ, [τ dᵀ], τ, τ²/2)``           (τ = t - t0)
* DVL (eq. 41):        ``C Φ = (0, I, [0], 0, 0)``   (water-profiling, or no current)
                       ``C Φ = (0, I, I, 0, 0)``     (bottom-lock with current: ``v + v_f``)
* depth:               ``C Φ = (e_zᵀ, τ e_zᵀ, [τ e_zᵀ], 0, 0)``

With current the range and bottom-lock rows have identical ``v`` and ``v_f`` columns, so the
direction ``(δv, δv_f) = (w, -w)`` is in the kernel of every row: the Gramian is rank deficient
for *every* input (the paper's claim of section 4.3, shown here by construction).

The Gramian does not depend on the beacon or on ``p0``, ``v0``: only on the inputs. Radial and
non-radial straight lines with the same acceleration profile have the same Gramian.

Moving beacon
-------------
With a beacon on a known path ``b(t)`` the range is ``½|r|²`` with ``r = p - b`` and
``r(t) = r0 + ρ0 τ + d_r(t)``, ``ρ = ν - b'``, where ``d_r = d - (b(t) - b0 - b'0 τ)`` is known
(the displacement due to the relative input ``u - b''``). The same algebra as eqs. 18–21 gives
``ȳ = d_rᵀ r(t) + τ r0ᵀρ0 + ½ τ² |ρ0|²`` plus the known ``-τ d_rᵀ b'0``, which a Gramian does
not see: the augmented state is ``(r, v, [v_f], r0ᵀρ0, |ρ0|²)`` and every row above keeps its
form with ``d`` replaced by ``d_r`` (DVL rows read ``v``, the depth row ``p_z = r_z + b_z``
differs from ``r_z`` by a known term). Since ``b`` is known, ``(r0, ρ0)`` and ``(p0, ν0)``
determine each other. So the functions below that take ``beacon_path`` compute today's Gramian
of :func:`~obsplan.trajectory.relative.relative_trajectory`: the piecewise-linear beacon path
is exact there (the union of the trajectory's samples and the path's knots makes the relative
input held; the impulses of ``b''`` at the knots are jumps of ``ρ``, inside ``d_r`` and ``e``),
and no ``b''`` is needed. Per-interval and per-sample results are given on the trajectory's own
intervals and samples (the sub-intervals of an interval summed).

Exact Gramian
-------------
On an interval ``[t_k, t_k + h)`` with constant input, ``d(t_k + σ) = d_k + e_k σ + ½ u_k σ²``
(``e_k = ν_k - ν_0``), so every row of ``C Φ`` is a cubic in σ: ``r(σ) = Σ_i R_i σ^i``. Then

    G_k = ∫_0^h r rᵀ dσ = Σ_{i,j} R_i R_jᵀ h^{i+j+1} / (i+j+1)                  (eq. 25, exactly)

which is built once as a CasADi function (:func:`interval_gramian_function`) for the planner,
and evaluated numerically here from the same row coefficients (``AugmentedModel._row_coeffs``)
in numpy, vectorised over the intervals, as ``G_k = V_kᵀ V_k`` with ``V_k = Rᵀ D L1`` (``L1`` the
Cholesky factor of the 4 × 4 Hilbert matrix, ``D = diag(h^{i+½})``). Sums run on the
nondimensionalised trajectory (see :mod:`obsplan.observability.scaling`), so entries stay O(1)
over long horizons and the cumulative sum ``G(t_k, t_0) = Σ_{j<k} G_j`` is the exact Gramian at
every sample.

Note on eq. 27's companion claim ``G(t, t0) = Σ G(t_{i+1}, t_i)``: the terms of a correct
decomposition are the t0-referenced integrals above; the Gramians of windows re-anchored at
``t_i`` (whose ``C`` uses ``d(t, t_i)``, ``t - t_i``) are Gramians of a *different* augmented state
and do not sum to ``G(t, t0)``. The paper's conclusion survives (a full-rank window makes
``x(t_i)``, hence ``x(t0)``, observable) but the identity does not; see ``tests/test_gramian.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.observability.scaling import (
    DEFAULT_SCALES,
    RANK_TOL,
    ScaleError,
    Scales,
    numerical_rank,
    psd_metrics,
)
from obsplan.trajectory.relative import relative_trajectory
from obsplan.trajectory.sampled import Trajectory

_AXES = "xyz"


@dataclass(frozen=True)
class AugmentedModel:
    """The augmented LTV model ``z' = A z + B u``, ``ȳ = C(t) z`` for one sensor configuration."""

    dim: int
    sensors: tuple[str, ...]
    current: bool

    @property
    def state_dim(self) -> int:
        """``2n + 2``, or ``3n + 2`` with current."""
        return (3 if self.current else 2) * self.dim + 2

    @property
    def state_names(self) -> tuple[str, ...]:
        axes = _AXES[: self.dim]
        names = [f"p{a}" for a in axes] + [f"v{a}" for a in axes]
        if self.current:
            names += [f"vf{a}" for a in axes]
        return (*names, "p0.nu0", "|nu0|^2")

    @property
    def A(self) -> np.ndarray:
        """Dynamics matrix (eq. 23; with current ``p' = v + v_f``)."""
        n, m = self.dim, self.state_dim
        A = np.zeros((m, m))
        A[:n, n : 2 * n] = np.eye(n)
        if self.current:
            A[:n, 2 * n : 3 * n] = np.eye(n)
        return A

    @property
    def B(self) -> np.ndarray:
        n = self.dim
        B = np.zeros((self.state_dim, n))
        B[n : 2 * n] = np.eye(n)
        return B

    @property
    def n_outputs(self) -> int:
        k = 1
        if any(s.startswith("dvl") for s in self.sensors):
            k += self.dim
        if "depth" in self.sensors:
            k += 1
        return k

    def output_matrix(self, d: np.ndarray, tau: float) -> np.ndarray:
        """``C(t)`` (not multiplied by Φ) for displacement ``d`` and elapsed time ``tau``.

        The rows are the range (``ȳ``), then DVL (n rows) and depth rows where present. Used by the
        augmented Kalman filter; shape ``(n_outputs, state_dim)``.

        Parameters
        ----------
        d : ndarray, shape (n,)
            Displacement ``d(t, t0)`` due to the inputs (eq. 15) [m, or nondimensional].
        tau : float
            Elapsed time ``t - t0`` [s, or nondimensional].

        Returns
        -------
        ndarray, shape (n_outputs, state_dim)
            The output matrix of the augmented state ``z(t)``.
        """
        n, m = self.dim, self.state_dim
        rows = [np.concatenate([d, np.zeros(m - n - 2), [tau, 0.5 * tau**2]])]
        if any(s.startswith("dvl") for s in self.sensors):
            c = np.zeros((n, m))
            c[:, n : 2 * n] = np.eye(n)
            if self.current and "dvl-bottom" in self.sensors:
                c[:, 2 * n : 3 * n] = np.eye(n)
            rows.extend(c)
        if "depth" in self.sensors:
            cz = np.zeros(m)
            cz[n - 1] = 1.0
            rows.append(cz)
        return np.vstack(rows)

    def _row_coeffs(self, d, e, u, tau0, xp: _Backend | None = None) -> list[list]:
        """Cubic coefficients ``[R_0..R_3]`` of every row of ``C Φ`` on one interval.

        ``xp`` says how to build rows: CasADi SX column vectors (default, for the planner) or
        numpy rows batched over intervals (:func:`interval_gramians`); the formulas are these.
        """
        xp = _CASADI if xp is None else xp
        n, m = self.dim, self.state_dim
        z = xp.zeros(n)
        nv = 2 if self.current else 1  # how many velocity-like blocks see τ dᵀ

        def row(pos, vel, alpha, beta):
            return xp.cat([pos, *([vel] * nv), xp.scalar(alpha), xp.scalar(beta)])

        rows = [
            [
                row(d, xp.times(tau0, d), tau0, 0.5 * tau0**2),
                row(e, d + xp.times(tau0, e), 1.0, tau0),
                row(0.5 * u, e + xp.times(0.5 * tau0, u), 0.0, 0.5),
                row(z, 0.5 * u, 0.0, 0.0),
            ]
        ]
        zero_row = xp.zeros(m)
        if any(s.startswith("dvl") for s in self.sensors):
            for i in range(n):
                idx = [n + i]
                if self.current and "dvl-bottom" in self.sensors:
                    idx.append(2 * n + i)
                rows.append([xp.unit(m, idx), zero_row, zero_row, zero_row])
        if "depth" in self.sensors:
            ez = xp.unit(n, [n - 1])
            rows.append(
                [row(ez, xp.times(tau0, ez), 0.0, 0.0), row(z, ez, 0.0, 0.0), zero_row, zero_row]
            )
        return rows


@dataclass(frozen=True)
class _Backend:
    """How :meth:`AugmentedModel._row_coeffs` builds rows: concatenation, zeros, unit rows."""

    cat: Callable
    zeros: Callable
    unit: Callable
    scalar: Callable
    times: Callable


def _sx_unit(k: int, idx: list[int]) -> ca.SX:
    r = ca.SX.zeros(k)
    for i in idx:
        r[i] = 1.0
    return r


_CASADI = _Backend(
    cat=lambda parts: ca.vertcat(*parts),
    zeros=lambda k: ca.SX.zeros(k),
    unit=_sx_unit,
    scalar=lambda a: a,
    times=lambda a, b: a * b,
)


def _numpy_backend(K: int) -> _Backend:
    """Rows batched over ``K`` intervals: blocks of shape (K, k), scalars of shape (K,)."""

    def unit(k: int, idx: list[int]) -> np.ndarray:
        r = np.zeros((K, k))
        r[:, idx] = 1.0
        return r

    return _Backend(
        cat=lambda parts: np.concatenate(parts, axis=1),
        zeros=lambda k: np.zeros((K, k)),
        unit=unit,
        scalar=lambda a: np.broadcast_to(np.asarray(a, float).reshape(-1, 1), (K, 1)),
        times=lambda a, b: np.asarray(a)[..., None] * b if np.ndim(a) else a * b,
    )


def augmented_model(model: VehicleModel) -> AugmentedModel:
    """The augmented LTV model of a vehicle model (beacon and range form do not matter).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model: dimension, sensors and current.

    Returns
    -------
    AugmentedModel
        Its augmented model (eqs. 20–23).
    """
    return AugmentedModel(dim=model.dim, sensors=model.sensors, current=model.current)


def _interval_gramian_sx(aug: AugmentedModel, weighted: bool):
    n = aug.dim
    d, e, u = ca.SX.sym("d", n), ca.SX.sym("e", n), ca.SX.sym("u", n)
    tau0, h = ca.SX.sym("tau0"), ca.SX.sym("h")
    w = ca.SX.sym("w", aug.n_outputs)
    G = ca.SX.zeros(aug.state_dim, aug.state_dim)
    hp = [h ** (k + 1) / (k + 1) for k in range(7)]
    for r, coeffs in enumerate(aug._row_coeffs(d, e, u, tau0)):
        R = ca.horzcat(*coeffs)  # m × 4
        H = ca.SX.zeros(4, 4)
        for i in range(4):
            for j in range(4):
                H[i, j] = hp[i + j]
        G += (w[r] if weighted else 1.0) * (R @ H @ R.T)
    return [d, e, u, tau0, h, *([w] if weighted else [])], G


@cache
def interval_gramian_function(aug: AugmentedModel) -> ca.Function:
    """CasADi ``G_k = g(d_k, e_k, u_k, tau0, h)``: exact Gramian of one constant-input interval.

    Inputs are the displacement ``d_k`` (n), velocity change ``e_k = ν_k - ν_0`` (n), input ``u_k``
    (n), elapsed time ``tau0 = t_k - t_0`` and interval length ``h``, in consistent (normally
    nondimensional) units. Output: the ``m × m`` symmetric contribution ``∫ Φᵀ Cᵀ C Φ``.

    Parameters
    ----------
    aug : AugmentedModel
        The augmented model (sensors and current).

    Returns
    -------
    casadi.Function
        The interval's Gramian, built once per model (cached).
    """
    args, G = _interval_gramian_sx(aug, weighted=False)
    return ca.Function("interval_gramian", args, [G])


@cache
def weighted_interval_gramian_function(aug: AugmentedModel) -> ca.Function:
    """CasADi ``G_k = g(d_k, e_k, u_k, tau0, h, w)``: :func:`interval_gramian_function` with the
    output rows weighted, ``∫ Φᵀ Cᵀ diag(w) C Φ``.

    ``w`` has one weight per output row (``aug.n_outputs``: range, then DVL axes, then depth),
    constant on the interval (e.g. information per unit time,
    :mod:`obsplan.observability.windowed`).

    Parameters
    ----------
    aug : AugmentedModel
        The augmented model (sensors and current).

    Returns
    -------
    casadi.Function
        The weighted interval's Gramian, built once per model (cached).
    """
    args, G = _interval_gramian_sx(aug, weighted=True)
    return ca.Function("weighted_interval_gramian", args, [G])


#: Cholesky factor of the 4 × 4 Hilbert matrix ``1/(i+j+1)``: ``∫_0^h σ^{i+j} dσ = h^{i+j+1}/(i+j+1)
#: = (D L1 L1ᵀ D)_ij`` with ``D = diag(h^{i+½})``.
_HILBERT_L = np.linalg.cholesky(1.0 / (np.arange(4)[:, None] + np.arange(4)[None, :] + 1.0))


def _interval_factors(traj: Trajectory, aug: AugmentedModel, scales: Scales | None) -> np.ndarray:
    """``V`` (K, 4·rows, m) with ``G_k = V_kᵀ V_k`` exactly (eq. 25 on interval k)."""
    if aug.dim != traj.dim:
        raise ValueError(f"model is {aug.dim}D but the trajectory is {traj.dim}D")
    tr = traj if scales is None else traj.scaled(scales.length_m, scales.time_s)
    K, m = tr.n_samples - 1, aug.state_dim
    d = tr.displacement()[:-1]
    e = (tr.v - tr.v[0])[:-1]
    tau0 = (tr.t - tr.t[0])[:-1]
    R = np.stack(
        [np.stack(c, axis=1) for c in aug._row_coeffs(d, e, tr.u[:-1], tau0, _numpy_backend(K))],
        axis=1,
    )  # (K, rows, 4, m): coefficient of σ^i of every row
    # G_k = Σ_rows Σ_ij R_i R_jᵀ h^{i+j+1}/(i+j+1) = Σ_rows (Rᵀ D L1)(Rᵀ D L1)ᵀ
    M = (tr.dt[:, None] ** (np.arange(4) + 0.5))[:, :, None] * _HILBERT_L[None]  # (K, 4, 4)
    VT = np.swapaxes(R, 2, 3) @ M[:, None]  # (K, rows, m, 4)
    return np.swapaxes(VT, 2, 3).reshape(K, -1, m)


def _relative(
    traj: Trajectory, beacon_path: BeaconPath | None
) -> tuple[Trajectory, np.ndarray | None]:
    """The trajectory the Gramian is taken of and where the original samples sit in it: itself
    (None) for a fixed beacon; relative to a moving one (module docstring, "Moving beacon")."""
    if beacon_path is None:
        return traj, None
    return relative_trajectory(traj, beacon_path)


def interval_gramians(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    scales: Scales | None = DEFAULT_SCALES,
    row_weights: np.ndarray | None = None,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """Exact per-interval contributions ``G_k``, shape ``(N-1, m, m)``, referred to ``z(t_0)``.

    The closed form of :func:`interval_gramian_function` evaluated in numpy, vectorised over
    the intervals. ``scales=None`` computes in the trajectory's own units (used by tests of
    unit invariance). ``row_weights`` (shape ``(N-1, n_outputs)``, optional) weights each output
    row on each interval, as :func:`weighted_interval_gramian_function`.

    Parameters
    ----------
    traj : Trajectory
        The sampled path; only its inputs and velocities (through ``d`` and ``e``) matter.
    model : VehicleModel or AugmentedModel
        The sensor configuration.
    scales : Scales or None, optional
        Nondimensionalisation of the trajectory; None: its own (SI) units.
    row_weights : ndarray, shape (N-1, n_outputs), optional
        Weight of each output row on each interval (information per unit time); None: 1.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (module docstring, "Moving beacon"); None: a
        fixed beacon (where it is does not matter).

    Returns
    -------
    ndarray, shape (N-1, m, m)
        ``G_k`` of every interval, symmetric positive semi-definite, ``m`` the augmented state
        dimension.

    Raises
    ------
    ValueError
        If the model and the trajectory differ in dimension.
    InputError
        A beacon path of another dimension, or one that does not cover ``traj``.
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    rel, samples = _relative(traj, beacon_path)
    V = _interval_factors(rel, aug, scales)
    if row_weights is not None:
        K, rows = V.shape[0], aug.n_outputs
        w = np.asarray(row_weights, float).reshape(traj.n_samples - 1, rows)
        if samples is not None:  # each sub-interval carries the weights of its interval
            w = w[np.searchsorted(samples, np.arange(K), side="right") - 1]
        w = np.sqrt(w)
        V = (V.reshape(K, rows, 4, -1) * w[:, :, None, None]).reshape(V.shape)
    G = np.swapaxes(V, 1, 2) @ V
    if samples is not None:  # the sub-intervals of each interval of traj, summed
        G = np.add.reduceat(G, samples[:-1], axis=0)
    return G


def cumulative_gramians(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    scales: Scales | None = DEFAULT_SCALES,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """``G(t_k, t_0)`` at every sample, shape ``(N, m, m)`` (the first is zero).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    model : VehicleModel or AugmentedModel
        The sensor configuration.
    scales : Scales or None, optional
        Nondimensionalisation of the trajectory; None: its own (SI) units.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span; None: a fixed beacon.

    Returns
    -------
    ndarray, shape (N, m, m)
        The running sums of :func:`interval_gramians`.
    """
    Gk = interval_gramians(traj, model, scales, beacon_path=beacon_path)
    out = np.zeros((Gk.shape[0] + 1, *Gk.shape[1:]))
    np.cumsum(Gk, axis=0, out=out[1:])
    return out


def gramian(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    scales: Scales | None = DEFAULT_SCALES,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """The exact observability Gramian ``G(t_N, t_0)`` (eq. 25), shape ``(m, m)``, in ``scales``.

    ``Σ_k V_kᵀ V_k`` as one matrix product of the stacked interval factors.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    model : VehicleModel or AugmentedModel
        The sensor configuration.
    scales : Scales or None, optional
        Nondimensionalisation of the trajectory; None: its own (SI) units.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span; None: a fixed beacon.

    Returns
    -------
    ndarray, shape (m, m)
        The Gramian over the whole trajectory, symmetrised.
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    rel, _ = _relative(traj, beacon_path)
    V = _interval_factors(rel, aug, scales).reshape(-1, aug.state_dim)
    G = V.T @ V
    return 0.5 * (G + G.T)


@dataclass(frozen=True)
class GramianReport:
    """Global-observability verdict of the augmented model along a trajectory.

    ``rank`` and ``full_rank`` come from the unit-invariant test; ``min_eig``, ``log_det`` and
    ``condition`` are of the Gramian nondimensionalised by ``scales``.
    """

    full_rank: bool
    rank: int
    dim: int
    full_rank_from_t: float | None
    min_eig: float
    log_det: float
    condition: float
    scales: Scales = DEFAULT_SCALES

    def check_metrics(self) -> None:
        """Refuse metrics that the scales made meaningless.

        Raises
        ------
        ScaleError
            When the Gramian is full rank by the unit-invariant test yet singular in
            ``scales`` (``min_eig`` 0, ``log_det`` -inf, ``condition`` inf): the scales pushed
            its eigenvalues below round-off (``L = 1e300 m`` printed exactly that for a circle).
        """
        finite = math.isfinite(self.log_det) and math.isfinite(self.condition)
        if self.full_rank and not (self.min_eig > 0 and finite):
            reason = (
                "the Gramian is full rank, but in these scales its eigenvalues fall below "
                f"round-off (min_eig {self.min_eig:g}, log_det {self.log_det:g}); choose scales "
                "near the trajectory's size and duration (default 100 m, 100 s)"
            )
            where = f"scales (L = {self.scales.length_m:g} m, T = {self.scales.time_s:g} s)"
            raise ScaleError(f"{where}: {reason}", reason)

    def to_dict(self) -> dict:
        """The stable keys of the ``gramian`` dict of ``obsplan analyze --json``.

        Returns
        -------
        dict
            ``full_rank``, ``rank``, ``dim``, ``full_rank_from_t`` [s] and the metrics
            ``min_eig``, ``log_det``, ``condition`` (None where not finite).
        """

        def num(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "full_rank": bool(self.full_rank),
            "rank": int(self.rank),
            "dim": int(self.dim),
            "full_rank_from_t": self.full_rank_from_t,
            "min_eig": num(self.min_eig),
            "log_det": num(self.log_det),
            "condition": num(self.condition),
        }


def rank_scales(traj: Trajectory, beacon_path: BeaconPath | None = None) -> Scales:
    """Scales of the rank test, taken from the trajectory so that they change with its units.

    Length: the larger of the RMS displacement ``|d|`` (eq. 15) and the RMS spread of the
    positions about their mean, else the RMS speed times the duration, else 1; time: the duration.
    The Gramian sums sensors with different output units (ȳ in m², DVL in m/s, depth in m): in
    fixed scales a change of units re-weights them against each other, which the diagonal
    equilibration cannot undo (range + DVL in km and hours lost the range's information below the
    DVL's round-off). In these covariant scales the weights, hence the verdicts, are the same in
    any units; the exact rank never depends on them. The spread matters when ``d`` is round-off
    only (constant velocity): a length taken from ``d`` alone would blow that noise up to O(1).

    With ``beacon_path`` the length is the larger of the vehicle's and that of its motion
    relative to the beacon: a beacon trailing the vehicle leaves relative displacements of
    round-off size, which a length taken from them alone would blow up to O(1).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span; None: a fixed beacon.

    Returns
    -------
    Scales
        Length [m] and time [s] (the duration) of the rank test.
    """
    ell = _rank_length(traj)
    if beacon_path is not None:
        ell = max(ell, _rank_length(relative_trajectory(traj, beacon_path)[0]))
    return Scales(length_m=ell if ell > 0 else 1.0, time_s=traj.duration)


def _rank_length(traj: Trajectory) -> float:
    """The length of :func:`rank_scales` of one trajectory [m] (0 if it does not move)."""
    d = traj.displacement()
    rms_d = float(np.sqrt(np.mean(np.sum(d**2, axis=1))))
    spread = traj.p - traj.p.mean(axis=0)
    ell = max(rms_d, float(np.sqrt(np.mean(np.sum(spread**2, axis=1)))))
    if not ell > 0:
        ell = float(np.sqrt(np.mean(np.sum(traj.v**2, axis=1)))) * traj.duration
    return ell


def rank_over_time(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    tol: float = RANK_TOL,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """Unit-invariant rank of ``G(t_k, t_0)`` at every sample, shape ``(N,)``.

    Computed in :func:`rank_scales`, then equilibrated (see ``scaling.py``).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    model : VehicleModel or AugmentedModel
        The sensor configuration.
    tol : float, optional
        Tolerance on the equilibrated eigenvalues
        (:func:`~obsplan.observability.scaling.numerical_rank`).
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span; None: a fixed beacon.

    Returns
    -------
    ndarray of int, shape (N,)
        Rank of the Gramian from ``t_0`` to each sample (0 at the first).
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    G = cumulative_gramians(traj, aug, rank_scales(traj, beacon_path), beacon_path)
    ranks = np.zeros(G.shape[0], dtype=int)
    ranks[1:] = numerical_rank(G[1:], tol)
    return ranks


def gramian_report(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    scales: Scales = DEFAULT_SCALES,
    tol: float = RANK_TOL,
    beacon_path: BeaconPath | None = None,
) -> GramianReport:
    """Rank, first full-rank time and scaled metrics of the augmented Gramian along ``traj``.

    ``rank``, ``full_rank`` and ``full_rank_from_t`` come from the unit-invariant test
    (Gramian in :func:`rank_scales`, equilibrated); the metrics from the Gramian in ``scales``.

    A full-rank Gramian whose metrics come out singular in ``scales`` (``min_eig`` 0,
    ``log_det`` -inf: the scales, not the trajectory) keeps its verdicts;
    :meth:`GramianReport.check_metrics` refuses such metrics before they are shown.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    model : VehicleModel or AugmentedModel
        The sensor configuration.
    scales : Scales, optional
        Fixed nondimensionalisation of the metrics ``min_eig``, ``log_det``, ``condition``.
    tol : float, optional
        Tolerance of the rank test on the equilibrated eigenvalues.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (module docstring, "Moving beacon"); None: a
        fixed beacon.

    Returns
    -------
    GramianReport
        The verdicts and metrics; a rank-deficient Gramian gets ``min_eig`` 0, ``log_det``
        ``-inf`` and ``condition`` ``inf``.
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    Gcum = cumulative_gramians(traj, aug, rank_scales(traj, beacon_path), beacon_path)
    rank = numerical_rank(0.5 * (Gcum[-1] + Gcum[-1].T), tol)
    full = rank == aug.state_dim
    t_full: float | None = None
    if full:
        ranks = numerical_rank(Gcum[1:], tol)
        k = int(np.argmax(ranks == aug.state_dim)) + 1
        t_full = float(traj.t[k])
    if full:
        min_eig, log_det, cond = psd_metrics(gramian(traj, aug, scales, beacon_path))
    else:
        # The unit-invariant test found a null direction: the fixed-scale eigenvalue there is
        # round-off (e.g. 1e-16 beside a DVL block), not information, so report it as zero.
        min_eig, log_det, cond = 0.0, float("-inf"), float("inf")
    return GramianReport(
        full_rank=bool(full),
        rank=int(rank),
        dim=aug.state_dim,
        full_rank_from_t=t_full,
        min_eig=min_eig,
        log_det=log_det,
        condition=cond,
        scales=scales,
    )
