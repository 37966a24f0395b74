"""Symbolic pieces of the planning NLP: exact discretised double integrator, limits, objectives.

Decision variables
------------------
``W`` of shape ``(3n, N)``, column ``k`` = ``(U_k, P_{k+1}, V_{k+1})`` (stage ordering, so the KKT
matrix is banded), followed by objective-specific lifting variables; the start node is fixed.
The variables are in *intrinsic* units of the problem, not the user's: ``U = u / a`` (per-axis
bound, so ``|U_i| <= 1``), ``V = v / v_max`` (``|V| <= 1``) and ``P = (p - b) / L_p`` with
``L_p = max(|p_0 - b|, v_max T_f / 4)``. Every constraint is written in those units, so the
conditioning IPOPT sees does not depend on the problem's size, its units or its metric
``[scales]``; the objective is divided by its value on a reference path (:class:`Formulation`).

Limits on the continuous path
-----------------------------
* Inputs: box bounds. Speed: ``|V_k|² <= 1`` at the nodes, exact because ``|v(t)|²`` is convex on
  an interval of constant acceleration. Area and depth band: node bounds tightened by
  ``a h² / 8``, the largest overshoot of a parabola with ``|p''| <= a`` over an interval ``h``.
* Distance to the beacon and speed through the water are enforced at the nodes and the midpoints
  of the intervals; each point covers ``±τ = h/4`` of the path, over which the distance moves by at
  most ``|v| τ + |a| τ²/2`` and the speed through the water by at most ``|a| τ`` (``|a|`` the norm
  of the per-axis bounds). So ``|p - b| - |v| τ >= r_min + |a| τ²/2`` at those points guarantees
  ``|p(t) - b| >= r_min`` everywhere (similarly for ``r_max`` and ``v_min``); the start is checked
  by the problem loader.

Objectives
----------
* ``pcrb-position``: the posterior Cramér–Rao bound of the nonlinear model's position,
  ``sqrt(tr P_pp)`` [m], at the end (``final``), averaged over the validation's filter samples
  (``mission-average``) or the sum of the two, each relative to its value on the lawn-mower
  (``average-and-final``, :func:`timed_value`). The bound is the
  validation's own (:func:`obsplan.estimation.crlb.posterior_crlb`): the same recursion
  (:mod:`obsplan.estimation.riccati`), prior, process noise, sensor rates and noises, evaluated
  on the positions of the planned path at the measurement epochs.
* ``kf-position-std``: the augmented KF's predicted position std (eqs. 20-24), with the same two
  modes. The model is linear, so its Riccati recursion depends only on the inputs; it is the
  recursion of :mod:`obsplan.estimation.riccati` on the augmented state with the anchor state of
  ``y0_mode="augment"`` (range rows ``C(t)`` of eq. 21, ``R = r² σ_r² + ½ σ_r⁴``; no range update at
  the anchor sample), in the metric scales.
* ``gramian-min-eig`` (E-optimal): ``max t`` s.t. ``G(W)/g - t I = L Lᵀ`` with ``L`` a lower-
  triangular variable and ``g`` a fixed normaliser; ``G`` is the exact Gramian (eq. 25) in the
  metric scales. ``G - tgI = LLᵀ`` forces ``t g <= λ_min(G)``, equal at the optimum; the constraints
  are smooth and linear in ``G``, so the Lagrangian Hessian keeps the stage-wise sparsity.
* ``gramian-log-det`` (D-optimal): ``max 2 Σ log L_ii`` s.t. ``G(W)/g = L Lᵀ``.
* ``lwo-condition``: ``max`` the soft minimum over the nodes, ``-log(mean_k exp(-β g_k))/β``, of
  the conditioning ``g_k`` of the LWO matrix (eq. 9) at node ``k`` (:func:`lwo_node_function`:
  geometric over arithmetic mean of the eigenvalues of ``OᵀO``, in [0, 1]). Written as
  ``min Σ_k exp(-β g_k)``, it is separable over the nodes: no lifting variables, a banded exact
  Hessian, and so it scales to N = 1000 (an epigraph with a Cholesky factor per node did not).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp

from obsplan.estimation.crlb import pcrb_model, range_information
from obsplan.estimation.riccati import (
    Epochs,
    RecursionModel,
    make_epochs,
    position_std,
    run_recursion,
)
from obsplan.estimation.schedule import make_schedule
from obsplan.model import VehicleModel
from obsplan.observability.gramian import augmented_model, interval_gramian_function
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

#: Lower bound of the diagonal of the log-det Cholesky variable: IPOPT may relax a bound by 1e-8
#: (bound_relax_factor), so a smaller floor would let log(L_ii) see a negative argument.
_CHOL_FLOOR = 1e-6
#: Squared-speed floor [-] inside the smooth ``|v|`` of the range-limit margins (the margin is
#: conservative by at most ``τ sqrt(eps)`` = 1e-4 τ v_max).
_SPEED_EPS = 1e-8


def vech_indices(m: int) -> list[tuple[int, int]]:
    """Lower-triangular index pairs ``(i, j)``, ``i >= j``, column by column."""
    return [(i, j) for j in range(m) for i in range(j, m)]


def _lower_from_vec(vec, m: int):
    L = ca.SX.zeros(m, m)
    for k, (i, j) in enumerate(vech_indices(m)):
        L[i, j] = vec[k]
    return L


def _vech(M, m: int):
    return ca.vertcat(*[M[i, j] for i, j in vech_indices(m)])


def _vech_np(M: np.ndarray) -> np.ndarray:
    return np.array([M[i, j] for i, j in vech_indices(M.shape[0])])


# ----------------------------------------------------------------------------- the grid
@dataclass(frozen=True)
class Grid:
    """The planning grid and the intrinsic units of the decision variables (module docstring)."""

    n: int
    N: int
    h: float  # planning step [s]
    p0: np.ndarray  # start position relative to the beacon [m]
    v0: np.ndarray  # start velocity [m/s]
    a: np.ndarray  # per-axis input bound [m/s^2] = unit of U
    v_max: float  # speed bound [m/s] = unit of V
    Lp: float  # unit of P [m]
    beacon: np.ndarray  # [m]

    @classmethod
    def from_problem(cls, pb: PlanningProblem) -> Grid:
        b = np.asarray(pb.beacon, float)
        p0 = pb.p0 - b
        T = pb.horizon.duration
        v_max = pb.limits.speed
        return cls(
            n=pb.dim,
            N=pb.horizon.steps,
            h=pb.horizon.dt,
            p0=p0,
            v0=pb.v0.copy(),
            a=pb.accel.copy(),
            v_max=v_max,
            Lp=max(float(np.linalg.norm(p0)), v_max * T / 4.0, 1e-3),
            beacon=b,
        )

    @property
    def times(self) -> np.ndarray:
        """Node times ``t_k``, k = 0..N [s]."""
        return np.arange(self.N + 1) * self.h

    def to_trajectory(self, W: np.ndarray) -> Trajectory:
        """Scaled ``W`` ``(3n, N)`` to an SI :class:`Trajectory` on the planning grid."""
        n = self.n
        U, P, V = W[:n], W[n : 2 * n], W[2 * n :]
        p = np.vstack([self.p0, (P * self.Lp).T]) + self.beacon
        v = np.vstack([self.v0, (V * self.v_max).T])
        u = (U * self.a[:, None]).T
        u = np.vstack([u, u[-1:]])
        return Trajectory(t=self.times, p=p, v=v, u=u)

    def from_trajectory(self, traj: Trajectory) -> np.ndarray:
        """SI trajectory on this grid to scaled ``W`` ``(3n, N)``."""
        if traj.n_samples != self.N + 1:
            raise ValueError(f"trajectory has {traj.n_samples} samples, grid has {self.N + 1}")
        U = (traj.u[:-1] / self.a).T
        P = ((traj.p[1:] - self.beacon) / self.Lp).T
        V = (traj.v[1:] / self.v_max).T
        return np.vstack([U, P, V])

    def si_nodes(self, W):
        """SI ``(u (n, N), p - b (n, N+1), v (n, N+1))`` of symbolic or numeric ``W``."""
        n = self.n
        U, P, V = W[:n, :], W[n : 2 * n, :], W[2 * n :, :]
        if isinstance(W, np.ndarray):
            u = U * self.a[:, None]
            p = np.hstack([self.p0[:, None], P * self.Lp])
            v = np.hstack([self.v0[:, None], V * self.v_max])
            return u, p, v
        u = ca.diag(ca.DM(self.a)) @ U
        p = ca.horzcat(ca.DM(self.p0), P * self.Lp)
        v = ca.horzcat(ca.DM(self.v0), V * self.v_max)
        return u, p, v

    def sample_operator(
        self, s: np.ndarray
    ) -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix, np.ndarray]:
        """Affine maps from ``vec(W)`` (column-major) to positions and velocities at times ``s``.

        Returns ``(Mp, cp, Mv, cv)`` with ``p(s) - b = reshape(Mp w + cp, (n, J))`` [m] and
        ``v(s) = reshape(Mv w + cv, (n, J))`` [m/s] (the exact quadratic between nodes).
        """
        n, N, h = self.n, self.N, self.h
        s = np.asarray(s, float)
        J = s.size
        k = np.clip(np.floor(s / h + 1e-9).astype(int), 0, N - 1)
        sig = s - k * h
        rows_p, cols_p, vals_p = [], [], []
        rows_v, cols_v, vals_v = [], [], []
        cp = np.zeros((n, J))
        cv = np.zeros((n, J))
        for i in range(n):
            r = np.arange(J) * n + i  # row of (i, j) in vec of an (n, J) array
            # input u_k = a_i U[i, k]: column k*3n + i
            cu = k * 3 * n + i
            rows_p.append(r)
            cols_p.append(cu)
            vals_p.append(0.5 * self.a[i] * sig**2)
            rows_v.append(r)
            cols_v.append(cu)
            vals_v.append(self.a[i] * sig)
            # node k: fixed start for k = 0, else P, V of column k-1
            first = k == 0
            cp[i, first] = self.p0[i] + self.v0[i] * sig[first]
            cv[i, first] = self.v0[i]
            later = ~first
            colp = (k[later] - 1) * 3 * n + n + i
            colv = (k[later] - 1) * 3 * n + 2 * n + i
            rows_p += [r[later], r[later]]
            cols_p += [colp, colv]
            vals_p += [np.full(later.sum(), self.Lp), self.v_max * sig[later]]
            rows_v.append(r[later])
            cols_v.append(colv)
            vals_v.append(np.full(later.sum(), self.v_max))
        shape = (n * J, 3 * n * N)
        Mp = sp.csc_matrix(
            (np.concatenate(vals_p), (np.concatenate(rows_p), np.concatenate(cols_p))), shape
        )
        Mv = sp.csc_matrix(
            (np.concatenate(vals_v), (np.concatenate(rows_v), np.concatenate(cols_v))), shape
        )
        return Mp, cp, Mv, cv


def _apply(M: sp.csc_matrix, c: np.ndarray, w, n: int):
    """``reshape(M w + c, (n, J))`` for CasADi ``w`` (vec of W) or a numpy vector."""
    J = c.shape[1]
    if isinstance(w, np.ndarray):
        return (M @ w).reshape(J, n).T + c
    return ca.reshape(ca.DM(M) @ w, n, J) + ca.DM(c)


def dynamics_residual(grid: Grid, W):
    """Exact ZOH double integrator residuals in intrinsic units, shape ``(2n, N)``."""
    u, p, v = grid.si_nodes(W)
    h = grid.h
    rp = (p[:, 1:] - p[:, :-1] - v[:, :-1] * h - 0.5 * h**2 * u) / grid.Lp
    rv = (v[:, 1:] - v[:, :-1] - h * u) / grid.v_max
    return ca.vertcat(rp, rv)


def midpoints(grid: Grid, W):
    """SI ``(p - b, v)`` at the interval midpoints, each ``(n, N)``."""
    u, p, v = grid.si_nodes(W)
    t = 0.5 * grid.h
    return p[:, :-1] + v[:, :-1] * t + 0.5 * u * t**2, v[:, :-1] + u * t


def gramian_expr(grid: Grid, pb: PlanningProblem, W):
    """Exact Gramian ``G(t_N, t_0)`` (eq. 25) in the problem's metric scales, of ``W``."""
    L, T = pb.scales.length_m, pb.scales.time_s
    aug = augmented_model(pb.model)
    g = interval_gramian_function(aug)
    N = grid.N
    u, p, v = grid.si_nodes(W)
    tau = ca.DM(np.arange(N) * grid.h).T
    D = (p[:, :N] - ca.repmat(ca.DM(grid.p0), 1, N) - ca.DM(grid.v0) @ tau) / L  # eq. 15
    E = (v[:, :N] - ca.repmat(ca.DM(grid.v0), 1, N)) * (T / L)
    gsum = g.map("gramian_sum", "serial", N, [], [0])
    G = gsum(D, E, u * (T**2 / L), tau / T, ca.DM.ones(1, N) * (grid.h / T))
    return 0.5 * (G + G.T)


# ----------------------------------------------------------------------------- covariances
@dataclass(frozen=True, eq=False)
class CovarianceObjective:
    """A covariance recursion along the planned path (``pcrb-position`` / ``kf-position-std``).

    Attributes
    ----------
    model : RecursionModel
    epochs : Epochs
        On the validation's filter grid (``PlanningProblem.filter_times``).
    P0 : ndarray
    mask : ndarray
        Report mask per epoch (the KF skips the range at the anchor sample).
    scale : float
        Multiplies the recursion's std to metres.
    """

    model: RecursionModel
    epochs: Epochs
    P0: np.ndarray
    mask: np.ndarray
    scale: float
    rows: Callable  # (grid, W) -> (h, rho): range rows and variances at the epochs

    def evaluate(self, grid: Grid, W):
        """``(mission-average std, final std)`` [m] as CasADi expressions or numbers."""
        h, rho = self.rows(grid, W)
        numeric = isinstance(W, np.ndarray)
        _, D = run_recursion(self.model, self.epochs, self.P0, h, rho, self.mask)
        n = self.model.n
        if numeric:
            std = position_std(np.asarray(D), n, self.epochs)
            return float(np.mean(std)) * self.scale, float(std[-1]) * self.scale
        total, final = position_std(D, n, self.epochs)
        count = int(self.epochs.gap.sum())
        return total * (self.scale / count), final * self.scale


def timed_value(mode: str, average, final, reference: tuple[float, float]):
    """The objective of a time ``mode`` from the mission-average and final std [m].

    ``average-and-final`` is ``average / a_ref + final / f_ref`` with ``(a_ref, f_ref) =
    reference``, the two values on the reference path (:func:`reference_path`): the survey and
    its end weigh alike whatever their sizes (with a DVL the final std is often 10x smaller than
    the average, and a plain sum would ignore it). It is dimensionless: 2 on the reference.
    """
    if mode == "mission-average":
        return average
    if mode == "final":
        return final
    return average / reference[0] + final / reference[1]


def _excited_path(pb: PlanningProblem) -> Trajectory:
    """A seeded random path that excites every axis (the equilibration's second reference)."""
    from obsplan.planning.solve import random_guess

    return random_guess(pb, (pb.objective.seed, 7919))


def reference_path(pb: PlanningProblem) -> Trajectory:
    """The path objectives are normalised by: the lawn-mower, or the first guess if it is unfit."""
    from obsplan.planning.solve import initial_guesses

    return initial_guesses(pb)[0][1]


def filter_epochs(pb: PlanningProblem) -> Epochs:
    """Measurement epochs of the validation on the horizon (same schedule as the Monte Carlo)."""
    t = pb.filter_times
    z = np.zeros((t.size, pb.dim))
    sched = make_schedule(Trajectory(t=t, p=z, v=z, u=z), pb.model.sensors, _rates(pb))
    return make_epochs(t, sched.mask)


def _rates(pb: PlanningProblem) -> dict[str, float]:
    return dict(pb.estimation_config().rates_hz)


def pcrb_objective(pb: PlanningProblem) -> CovarianceObjective:
    """The posterior CRB of the validation (:func:`obsplan.estimation.crlb.posterior_crlb`)."""
    cfg = pb.estimation_config()
    cov = cfg.covariances(pb.validation.dt)
    model = pb.model
    rec = pcrb_model(model, cov["q_ekf"], dict(cfg.noise))
    epochs = filter_epochs(pb)
    s = pb.filter_times[epochs.index]
    grid = Grid.from_problem(pb)
    Mp, cp, _, _ = grid.sample_operator(s)
    sigma = cfg.noise["range"]
    n = model.dim

    def rows(grid: Grid, W):
        w = W.reshape(-1, order="F") if isinstance(W, np.ndarray) else ca.vec(W)
        rel = _apply(Mp, cp, w, n)
        return range_information(rel, sigma)

    return CovarianceObjective(rec, epochs, cov["p0_ekf"], epochs.mask, 1.0, rows)


def kf_objective(pb: PlanningProblem) -> CovarianceObjective:
    """The augmented KF's covariance (:mod:`obsplan.estimation.kf`) in the metric scales.

    The filter's own coordinates ``z = (p - b, v[, v_f], κ, φ, γ)`` (chain ``κ' = φ``,
    ``φ' = 2γ``; the anchor's error in ``κ`` for ``y0_mode="augment"``), its prior, per-step
    process noise and range variance, and its process-noise coupling with the gains taken on the
    nominal path, where ``p - d = p0 - b + ν0 τ`` and ``ν - ḋ = ν0`` whatever the inputs: so the
    per-step noise is ``q(τ) = Γ(τ) q Γ(τ)ᵀ`` with ``Γ`` linear in ``τ`` (a quadratic ``q(τ)``,
    exact in :mod:`obsplan.estimation.riccati`). The filter takes the gains at its estimate, so
    the prediction matches its covariance up to the estimation error of ``p0`` and ``ν0``.
    """
    from obsplan.errors import ConfigError

    L, T = pb.scales.length_m, pb.scales.time_s
    val = pb.validation
    model = pb.model
    aug = augmented_model(model)
    n, mx = model.dim, model.state_dim
    m = mx + 3
    kc = mx  # κ, φ, γ follow the kinematic states
    cfg = pb.estimation_config()
    cov = cfg.covariances(val.dt)
    q_kf = np.asarray(cov["q_kf"], float)
    if np.any(q_kf[mx:, :] != 0) or np.any(q_kf[:, mx:] != 0):
        raise ConfigError(
            "the planning KF models process noise on (p, v[, v_f]) only; the configured noise on "
            "(p0·v0, |v0|²) is not supported by kf-position-std"
        )
    qx = q_kf[:mx, :mx]
    # state scaling: p/L, v T/L, v_f T/L, κ/L², φ T/L², γ T²/L²
    scale = np.concatenate([np.full(n, 1 / L), np.full(mx - n, T / L), [1 / L**2, T / L**2]])
    scale = np.append(scale, T**2 / L**2)
    S = np.diag(scale)
    # prior: φ = α, γ = ½β, κ = the anchor's error (variance of ½(r0 + ε)², as the filter's)
    Mc = np.zeros((m, mx + 2))
    Mc[:mx, :mx] = np.eye(mx)
    Mc[kc + 1, mx] = 1.0
    Mc[kc + 2, mx + 1] = 0.5
    P0 = Mc @ np.asarray(cov["p0_kf"], float) @ Mc.T
    sigma = cfg.noise["range"]
    r0 = float(np.linalg.norm(pb.p0 - np.asarray(pb.beacon)))
    var0 = (r0 * sigma) ** 2 + 0.5 * sigma**4
    inflate = cfg.y0_mode == "inflate"
    if not inflate:
        P0[kc, kc] += var0
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    if model.current:
        A[:n, 2 * n : 3 * n] = np.eye(n)
    A[kc, kc + 1], A[kc + 1, kc + 2] = 1.0, 2.0
    # noise gains Γ(τ) = Γ0 + τ Γ1 of w = (w_p, w_v[, w_f]) on z, at the nominal path
    nu0 = pb.v0  # inertial start velocity: ν0 = v0 + v_f
    cp0 = pb.p0 - np.asarray(pb.beacon, float)
    G0 = np.zeros((m, mx))
    G1 = np.zeros((m, mx))
    G0[:mx] = np.eye(mx)
    if cfg.kf_coupling:
        nu_cols = [np.arange(n, 2 * n)] + ([np.arange(2 * n, 3 * n)] if model.current else [])
        G0[kc, :n] = cp0  # κ: c_p · w_p
        G1[kc, :n] = nu0
        G0[kc + 1, :n] = nu0  # φ: c_v · w_p + c_p · w_ν
        for cols in nu_cols:
            G0[kc + 1, cols] = cp0
            G1[kc + 1, cols] = nu0
            G0[kc + 2, cols] = nu0  # γ: c_v · w_ν
    q0 = G0 @ qx @ G0.T
    q1 = G0 @ qx @ G1.T + G1 @ qx @ G0.T
    q2 = G1 @ qx @ G1.T
    # constant rows in the scaled state and outputs: C_s = c_out C S^-1, σ_s = c_out σ, with
    # c_out = T/L for a DVL (a velocity) and 1/L for the depth gauge (a position)
    full = aug.output_matrix(np.zeros(n), 0.0)
    rows_c, var_c, which = [], [], []
    i = 1
    for j, sensor in enumerate(model.sensors):
        if sensor == "range":
            continue
        width = n if sensor.startswith("dvl") else 1
        c_out = T / L if sensor.startswith("dvl") else 1 / L
        for r in range(width):
            row = np.zeros(m)
            row[:mx] = c_out * full[i + r][:mx] / scale[:mx]
            rows_c.append(row)
            var_c.append((c_out * cfg.noise[sensor]) ** 2)
            which.append(j)
        i += width
    nav = np.zeros((2 * n, m))
    nav[:n, :n] = np.eye(n)
    nav[n:, n : 2 * n] = np.eye(n)
    if model.current:
        nav[n:, 2 * n : 3 * n] = np.eye(n)
    rec = RecursionModel(
        A=A,  # S A S^-1 T = A: the scaling is consistent with the dynamics
        q=S @ q0 @ S,
        q1=T * (S @ q1 @ S),
        q2=T**2 * (S @ q2 @ S),
        nav=nav,
        rows=np.array(rows_c).reshape(len(rows_c), m),
        row_var=np.array(var_c),
        row_sensor=tuple(which),
        range_sensor=model.sensors.index("range"),
        n_sensors=len(model.sensors),
        range_support=(*range(n), kc),  # ȳ = dᵀ(p - b) + κ
    )
    epochs = filter_epochs(pb).scaled(T)
    mask = epochs.mask.copy()
    mask[0, model.sensors.index("range")] = 0.0  # ȳ_0 ≡ 0: the anchor carries no information
    s = pb.filter_times[epochs.index]
    grid = Grid.from_problem(pb)
    Mp, cp, _, _ = grid.sample_operator(s)
    d_off = (grid.p0[:, None] + grid.v0[:, None] * s[None, :]) / L  # d = p - p0 - ν0 τ (eq. 15)
    sig_s = sigma / L
    extra = (var0 / L**4) if inflate else 0.0
    ones = np.ones((1, s.size))

    def rows(grid: Grid, W):
        w = W.reshape(-1, order="F") if isinstance(W, np.ndarray) else ca.vec(W)
        rel = _apply(Mp, cp, w, n) / L
        d = rel - d_off
        if isinstance(W, np.ndarray):
            hh = np.vstack([d, ones])
            rho = np.sum(rel**2, axis=0, keepdims=True) * sig_s**2 + 0.5 * sig_s**4 + extra
        else:
            hh = ca.vertcat(d, ca.DM(ones))
            rho = ca.sum1(rel**2) * sig_s**2 + 0.5 * sig_s**4 + extra
        return hh, rho

    return CovarianceObjective(rec, epochs, S @ P0 @ S, mask, L, rows)


def covariance_objective(pb: PlanningProblem, kind: str | None = None) -> CovarianceObjective:
    """The :class:`CovarianceObjective` of ``kind`` (default: the problem's objective)."""
    kind = pb.objective.kind if kind is None else kind
    return kf_objective(pb) if kind == "kf-position-std" else pcrb_objective(pb)


# ----------------------------------------------------------------------------- LWO
#: Temperature of the soft minimum over nodes of the LWO conditioning: within log(N + 1) / β of
#: the true minimum (0.35 at N = 1000), while the objective stays separable over the nodes.
LWO_BETA = 20.0
#: Ridge added to the normalised LWO Gram matrix before its pivots are logged: keeps log finite
#: at rank-deficient nodes (their conditioning reads ~1e-9^(1/m) instead of 0).
LWO_RIDGE = 1e-9


def lwo_node_function(pb: PlanningProblem) -> ca.Function:
    """``g(x, u)``: conditioning of the LWO matrix at one node, in the metric scales.

    ``g = det(M̃)^(1/m)`` with ``M̃ = OᵀO / (tr(OᵀO)/m) + LWO_RIDGE I``: the ratio of the geometric
    to the arithmetic mean of the eigenvalues of ``OᵀO`` (``O`` of eq. 9 with the input held),
    1 for a perfectly conditioned node and 0 for a rank-deficient one. The determinant comes
    from the pivots of an unpivoted LDLᵀ (``M̃`` is positive definite), so ``g`` is smooth.
    """
    from obsplan.observability.lwo import lwo_matrix_function

    model = pb.model
    nd = VehicleModel(
        dim=model.dim, sensors=model.sensors, current=model.current, range_form=model.range_form
    )
    O = lwo_matrix_function(nd, 0)
    x = ca.SX.sym("x", nd.state_dim)
    u = ca.SX.sym("u", nd.dim)
    Ox = O(x, u)
    M = Ox.T @ Ox
    m = nd.state_dim
    M = M / (ca.trace(M) / m) + LWO_RIDGE * ca.SX.eye(m)
    logdet = ca.SX(0)
    A = [[M[i, j] for j in range(m)] for i in range(m)]
    for k in range(m):  # LDLᵀ without pivoting: A[k][k] is the k-th pivot
        piv = A[k][k]
        logdet = logdet + ca.log(piv)
        for i in range(k + 1, m):
            f = A[i][k] / piv
            for j in range(k + 1, i + 1):
                A[i][j] = A[i][j] - f * A[j][k]
                A[j][i] = A[i][j]
    return ca.Function("lwo_condition", [x, u], [ca.exp(logdet / m)])


def lwo_conditions(grid: Grid, pb: PlanningProblem, W):
    """Row ``(1, N+1)`` of the node conditionings ``g_k`` (:func:`lwo_node_function`) of ``W``."""
    L, T = pb.scales.length_m, pb.scales.time_s
    uu, p, v = grid.si_nodes(W)
    numeric = isinstance(W, np.ndarray)
    parts = [p / L, v * (T / L)]
    if pb.model.current:  # O depends on v + v_f only (lwo.py): v_f = 0 nominally
        parts.append(np.zeros((grid.n, grid.N + 1)) if numeric else ca.DM.zeros(grid.n, grid.N + 1))
    X = np.vstack(parts) if numeric else ca.vertcat(*parts)
    Uext = (np.hstack([uu, uu[:, -1:]]) if numeric else ca.horzcat(uu, uu[:, -1])) * (T**2 / L)
    g = lwo_node_function(pb).map(grid.N + 1)(X, Uext)
    return np.asarray(g) if numeric else g


def lwo_softmin(g) -> float:
    """``-log(mean exp(-β g)) / β``, the soft minimum the ``lwo-condition`` objective maximises."""
    g = np.asarray(g, float).ravel()
    lo = float(g.min())  # shifted for a stable log-sum-exp
    return lo - float(np.log(np.mean(np.exp(-LWO_BETA * (g - lo))))) / LWO_BETA


# ----------------------------------------------------------------------------- assembly
@dataclass
class Formulation:
    """The NLP of a problem: symbols, bounds and helpers to pack/unpack and evaluate.

    ``f`` is the objective divided by its magnitude on the reference path and signed so that
    IPOPT minimises it; ``to_objective`` maps the solver's ``f`` back to the objective.
    """

    problem: PlanningProblem
    grid: Grid
    w: ca.MX
    f: ca.MX
    g: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    extra_init: Callable[[np.ndarray], np.ndarray]  # W -> initial lifting variables
    to_objective: Callable[[float], float]  # solver's f -> the objective in the user's units
    hessian: str  # "exact" or "limited-memory"
    n_path_constraints: int  # the first rows of g: dynamics and limits (no lifting)

    @property
    def n_w(self) -> int:
        return 3 * self.grid.n * self.grid.N

    def pack(self, traj: Trajectory) -> np.ndarray:
        """Initial guess vector from a trajectory on the planning grid."""
        W = self.grid.from_trajectory(traj)
        extra = np.asarray(self.extra_init(W)).reshape(-1)
        return np.concatenate([W.reshape(-1, order="F"), extra])

    def unpack(self, x: np.ndarray) -> tuple[Trajectory, np.ndarray]:
        """Solution vector to ``(trajectory [SI], lifting variables)``."""
        x = np.asarray(x, float).reshape(-1)
        n, N = self.grid.n, self.grid.N
        W = x[: self.n_w].reshape(3 * n, N, order="F")
        return self.grid.to_trajectory(W), x[self.n_w :]

    def lifted_value(self, f: float) -> float:
        """The solver's objective ``f`` in the user's sign and units."""
        return float(self.to_objective(float(f)))


def path_constraints(grid: Grid, pb: PlanningProblem, Wsym):
    """Dynamics and limit constraints ``(g, lbg, ubg)`` and box bounds ``(lbW, ubW)`` of ``W``."""
    n, N = grid.n, grid.N
    lim = pb.limits
    lbW = np.full((3 * n, N), -np.inf)
    ubW = np.full((3 * n, N), np.inf)
    lbW[:n] = -1.0
    ubW[:n] = 1.0
    # area / depth: node bounds tightened by the parabola's overshoot a h^2 / 8
    margin = grid.a * grid.h**2 / 8.0
    boxes: list[tuple[int, tuple[float, float]]] = []
    if lim.area is not None:
        boxes += [(0, lim.area.x), (1, lim.area.y)]
    if lim.depth is not None:
        boxes.append((2, lim.depth))
    for axis, (lo, hi) in boxes:
        b = grid.beacon[axis]
        lbW[n + axis] = (lo - b + margin[axis]) / grid.Lp
        ubW[n + axis] = (hi - b - margin[axis]) / grid.Lp

    g = [ca.vec(dynamics_residual(grid, Wsym))]
    lbg = [np.zeros(2 * n * N)]
    ubg = [np.zeros(2 * n * N)]
    V = Wsym[2 * n :, :]
    g.append(ca.sum1(V**2).T)  # exact: |v(t)|^2 is convex between nodes
    lbg.append(np.full(N, -np.inf))
    ubg.append(np.ones(N))

    _, p, v = grid.si_nodes(Wsym)
    pm, vm = midpoints(grid, Wsym)
    pts_p = ca.horzcat(p[:, 1:], pm)
    pts_v = ca.horzcat(v[:, 1:], vm)
    tau = grid.h / 4.0
    a_norm = float(np.linalg.norm(grid.a))
    K = 2 * N
    if lim.min_range > 0 or lim.max_range is not None:
        dist = ca.sqrt(ca.sum1(pts_p**2))
        spd = ca.sqrt(ca.sum1(pts_v**2) + _SPEED_EPS * grid.v_max**2)
        slack = 0.5 * a_norm * tau**2
        L = grid.Lp
        if lim.min_range > 0:
            g.append(((dist - spd * tau) / L).T)
            lbg.append(np.full(K, (lim.min_range + slack) / L))
            ubg.append(np.full(K, np.inf))
        if lim.max_range is not None:
            g.append(((dist + spd * tau) / L).T)
            lbg.append(np.full(K, -np.inf))
            ubg.append(np.full(K, (lim.max_range - slack) / L))
    if lim.min_speed > 0:
        w = pts_v - ca.repmat(ca.DM(pb.current_array), 1, K)
        g.append((ca.sum1(w**2) / grid.v_max**2).T)
        lbg.append(np.full(K, ((lim.min_speed + a_norm * tau) / grid.v_max) ** 2))
        ubg.append(np.full(K, np.inf))
    return g, lbg, ubg, lbW, ubW


def build_formulation(pb: PlanningProblem) -> Formulation:
    """Assemble the NLP (variables, objective, constraints, bounds) of ``pb``.

    The objective is normalised by its value on :func:`reference_path` (the lawn-mower).
    """
    from obsplan.planning.metrics import objective_value

    grid = Grid.from_problem(pb)
    n, N = grid.n, grid.N
    kind = pb.objective.kind
    Wsym = ca.MX.sym("W", 3 * n, N)
    g_parts, lbg, ubg, lbW, ubW = path_constraints(grid, pb, Wsym)
    n_path = int(sum(x.size for x in lbg))
    reference = reference_path(pb)
    W_ref = grid.from_trajectory(reference)

    extra_lb: list[np.ndarray] = []
    extra_ub: list[np.ndarray] = []
    hessian = "exact"
    if kind in ("gramian-min-eig", "gramian-log-det"):
        # log-det: the constraint acts on D G D with a fixed diagonal D (unit diagonal on typical
        # paths); log det G = log det(D G D) - 2 Σ log D_ii, so the NLP, its iterates and its
        # conditioning are the same whatever the metric scales make of G's t^0..t^4 columns
        # (measured: identical iterations for L, T from (1 m, 1 s) to (10 km, 10 s)).
        # min-eig: E-optimality is not invariant to such a scaling (it is a different objective
        # in each metric), and the same congruence, G - tI ⪰ 0 <=> D G D - t D² ⪰ 0, made IPOPT
        # 5-10x slower in the default scales; it keeps G / g with a scalar g.
        G = gramian_expr(grid, pb, Wsym)
        m = G.shape[0]
        Gfun = ca.Function("G", [Wsym], [G])
        G_ref = np.asarray(Gfun(W_ref))
        G_typ = G_ref + np.asarray(Gfun(grid.from_trajectory(_excited_path(pb))))
        diag = np.maximum(np.diag(G_typ), 1e-12 * np.max(np.diag(G_typ)))
        Dv = 1.0 / np.sqrt(diag)
        D = ca.DM(np.diag(Dv))
        nl = m * (m + 1) // 2
        Lv = ca.MX.sym("L", nl)
        Lsx = ca.SX.sym("L", nl)
        Lm = _lower_from_vec(Lsx, m)
        llt = ca.Function("llt", [Lsx], [_vech(Lm @ Lm.T, m)])
        diag_idx = [k for k, (i, j) in enumerate(vech_indices(m)) if i == j]
        gnorm = max(float(np.trace(G_ref)) / m, 1e-300)

        def equilibrated(W):
            return Dv[:, None] * np.asarray(Gfun(W)) * Dv[None, :]

        if kind == "gramian-min-eig":
            Gn = G / gnorm
            t = ca.MX.sym("t")
            extra = ca.vertcat(t, Lv)
            g_parts.append(_vech(Gn - t * ca.MX.eye(m), m) - llt(Lv))
            sign = -1.0
            ref = max(float(np.linalg.eigvalsh(G_ref / gnorm)[0]), 1e-6)
            f = -t / ref
            f_scale = ref * gnorm
            extra_lb += [np.array([-np.inf]), np.full(nl, -np.inf)]
            extra_ub += [np.array([np.inf]), np.full(nl, np.inf)]

            def extra_init_np(W):
                # t at half of lambda_min: G - tI is well inside the PD cone, so L starts far
                # from the singular factors where the lifted problem has spurious stationary
                # points (a rank-deficient L breaks the constraint qualification)
                Gv = np.asarray(Gfun(W)) / gnorm
                ev = np.linalg.eigvalsh(Gv)
                floor = 1e-3 * max(ev[-1], 1e-12)
                t0 = 0.5 * ev[0] if ev[0] > floor else ev[0] - floor
                Lc = np.linalg.cholesky(Gv - t0 * np.eye(m))
                return np.concatenate([[t0], _vech_np(Lc)])

        else:
            Gn = D @ G @ D
            extra = Lv
            g_parts.append(_vech(Gn, m) - llt(Lv))
            sign = -1.0
            # log det G = 2 Σ log L_ii - 2 Σ log D_ii: the constant does not change the optimum
            f = -2.0 * ca.sum1(ca.log(Lv[diag_idx])) + 2.0 * float(np.sum(np.log(Dv)))
            f_scale = 1.0
            lb = np.full(nl, -np.inf)
            lb[diag_idx] = _CHOL_FLOOR
            extra_lb.append(lb)
            extra_ub.append(np.full(nl, np.inf))

            def extra_init_np(W):
                Gv = equilibrated(W)
                ev = np.linalg.eigvalsh(Gv)
                shift = max(1e-6 * ev[-1], 1e-9) - min(ev[0], 0.0)
                return _vech_np(np.linalg.cholesky(Gv + shift * np.eye(m)))

        lbg.append(np.zeros(nl))
        ubg.append(np.zeros(nl))
    elif kind == "lwo-condition":
        # maximise the soft minimum over nodes, i.e. minimise Σ_k exp(-β g_k): separable over
        # the nodes, so the exact Hessian keeps the stage-wise sparsity (no lifting variables)
        g_nodes = lwo_conditions(grid, pb, Wsym)
        s_ref = float(np.sum(np.exp(-LWO_BETA * lwo_conditions(grid, pb, W_ref))))
        f = ca.sum2(ca.exp(-LWO_BETA * g_nodes)) / s_ref
        f_scale = s_ref
        sign = -1.0
        K = grid.N + 1
        to_objective = lambda fv: float(-np.log(fv * s_ref / K) / LWO_BETA)  # noqa: E731
        extra = ca.MX.zeros(0, 1)

        def extra_init_np(W):
            return np.zeros(0)

    elif kind in ("pcrb-position", "kf-position-std"):
        cobj = covariance_objective(pb)
        avg, final = cobj.evaluate(grid, Wsym)
        value = timed_value(pb.objective_mode, avg, final, cobj.evaluate(grid, W_ref))
        ref = max(objective_value(reference, pb), 1e-12)
        f = value / ref
        f_scale = ref
        sign = 1.0
        extra = ca.MX.zeros(0, 1)
        # the exact Hessian of a recursion over hundreds of epochs is dense and slow to build
        # (measured: 166 s to construct at N = 50): L-BFGS needs only gradients
        hessian = "limited-memory"

        def extra_init_np(W):
            return np.zeros(0)

    else:  # pragma: no cover - validated by the problem
        raise ValueError(kind)

    if kind != "lwo-condition":

        def to_objective(fv: float) -> float:
            return float(sign * f_scale * fv)

    w = ca.vertcat(ca.vec(Wsym), extra)
    lbx = np.concatenate([lbW.reshape(-1, order="F"), *extra_lb])
    ubx = np.concatenate([ubW.reshape(-1, order="F"), *extra_ub])
    return Formulation(
        problem=pb,
        grid=grid,
        w=w,
        f=f,
        g=ca.vertcat(*g_parts),
        lbx=lbx,
        ubx=ubx,
        lbg=np.concatenate(lbg),
        ubg=np.concatenate(ubg),
        extra_init=extra_init_np,
        to_objective=to_objective,
        hessian=hessian,
        n_path_constraints=n_path,
    )
