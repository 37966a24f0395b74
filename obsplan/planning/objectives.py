"""Symbolic pieces of the planning NLP: the exact discretised double integrator and the objectives.

Everything is in the problem's fixed nondimensional units
(:class:`~obsplan.observability.scaling.Scales` ``L``, ``T``): time ``t/T``, position relative
to the beacon ``(p - b)/L``, velocity ``v T/L``, input ``u T²/L``.

Decision variables: ``W`` of shape ``(3n, N)``, column ``k`` = ``(u_k, p_{k+1}, v_{k+1})`` (stage
ordering, so the KKT matrix is banded), followed by objective-specific lifting variables.
The start node ``(p_0, v_0)`` is fixed.

Objectives (all built from the same CasADi functions that evaluate the metrics):

* ``gramian-min-eig`` (E-optimal): ``max t`` s.t. ``G(W) - t I = L Lᵀ`` with ``L`` a lower-
  triangular variable. ``G`` is the exact Gramian (eq. 25) summed from
  :func:`~obsplan.observability.gramian.interval_gramian_function`. ``G - tI = LLᵀ`` forces
  ``G ⪰ tI``, i.e. ``t ≤ λ_min(G)``, and maximising ``t`` makes it equal at the optimum. Unlike
  ``λ_min`` itself, the constraints are smooth, and linear in ``G`` so that the Lagrangian Hessian
  keeps the stage-wise sparsity of ``G = Σ_k G_k``.
* ``gramian-log-det`` (D-optimal): ``max 2 Σ log L_ii`` s.t. ``G(W) = L Lᵀ`` (a Cholesky factor as a
  variable, same sparsity argument; ``log det`` of a symbolic ``G`` would make the Hessian dense).
* ``lwo-condition``: ``max c`` s.t. ``O_kᵀO_k - c (tr(O_kᵀO_k)/m) I = L_k L_kᵀ`` at every node:
  ``c = min_k λ_min(O_kᵀO_k) / mean eigenvalue`` ∈ [0, 1] is the worst normalised conditioning of
  the LWO matrix (eq. 9 via :func:`~obsplan.observability.lwo.lwo_matrix_function`, constant input)
  along the path from the nominal start; 1 means perfectly conditioned, 0 rank deficient.
* ``kf-position-std``: ``min`` the final position standard deviation ``sqrt(tr P_pp)`` [m] of the
  augmented KF (eqs. 20-24). The model is linear, so the Riccati recursion depends only on the
  inputs: it runs (a CasADi ``fold``) at the range epochs with ``H = C(t)`` (eq. 21) and
  ``R = r² σ_r² + ½ σ_r⁴`` (the variance of ``½ (r + ε)²``, as the filter uses); DVL and depth
  updates, whose rows do not depend on the path, are applied at the range epochs with their
  information aggregated over the epoch (variance × range_rate / sensor_rate).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from obsplan.model import VehicleModel
from obsplan.observability.gramian import augmented_model, interval_gramian_function
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

#: Lower bound of the diagonal of the log-det Cholesky variable: IPOPT may relax a bound by 1e-8
#: (bound_relax_factor), so a smaller floor would let log(L_ii) see a negative argument.
_CHOL_FLOOR = 1e-6


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


@dataclass(frozen=True)
class Grid:
    """The planning grid and the limits, in scaled units."""

    n: int
    N: int
    h: float  # step, scaled
    p0: np.ndarray  # start position rel. beacon, scaled
    v0: np.ndarray  # start velocity, scaled
    u_max: np.ndarray  # per-axis input bound, scaled
    v_max: float  # speed bound, scaled
    L: float
    T: float
    beacon: np.ndarray  # [m]

    @classmethod
    def from_problem(cls, pb: PlanningProblem) -> Grid:
        L, T = pb.scales.length_m, pb.scales.time_s
        b = np.asarray(pb.beacon, float)
        return cls(
            n=pb.dim,
            N=pb.horizon.steps,
            h=pb.horizon.dt / T,
            p0=(pb.p0 - b) / L,
            v0=pb.v0 * T / L,
            u_max=pb.accel * T**2 / L,
            v_max=pb.limits.speed * T / L,
            L=L,
            T=T,
            beacon=b,
        )

    @property
    def tau(self) -> np.ndarray:
        """Node times ``t_k - t_0`` for k = 0..N-1, scaled."""
        return np.arange(self.N) * self.h

    def to_trajectory(self, U: np.ndarray, P: np.ndarray, V: np.ndarray) -> Trajectory:
        """Scaled stage arrays ``(n, N)`` (nodes 1..N for P, V) to an SI :class:`Trajectory`."""
        L, T = self.L, self.T
        p = np.vstack([self.p0, P.T]) * L + self.beacon
        v = np.vstack([self.v0, V.T]) * L / T
        u = np.vstack([U.T, U.T[-1:]]) * L / T**2
        t = np.arange(self.N + 1) * self.h * T
        return Trajectory(t=t, p=p, v=v, u=u)

    def from_trajectory(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """SI trajectory on this grid to scaled ``(U, P, V)`` with shapes ``(n, N)``."""
        L, T = self.L, self.T
        if traj.n_samples != self.N + 1:
            raise ValueError(f"trajectory has {traj.n_samples} samples, grid has {self.N + 1}")
        U = (traj.u[:-1] * T**2 / L).T
        P = ((traj.p[1:] - self.beacon) / L).T
        V = (traj.v[1:] * T / L).T
        return U, P, V


def split_W(W, n: int):
    """Rows of ``W`` as ``(U, P, V)`` (inputs, then nodes 1..N)."""
    return W[:n, :], W[n : 2 * n, :], W[2 * n :, :]


def node_arrays(grid: Grid, P, V):
    """Positions and velocities at nodes 0..N as ``(n, N+1)`` (CasADi or numpy)."""
    if isinstance(P, np.ndarray):
        return np.hstack([grid.p0[:, None], P]), np.hstack([grid.v0[:, None], V])
    return ca.horzcat(ca.DM(grid.p0), P), ca.horzcat(ca.DM(grid.v0), V)


def dynamics_residual(grid: Grid, W):
    """Exact ZOH double integrator residuals, shape ``(2n, N)`` (zero on a consistent path)."""
    n, h = grid.n, grid.h
    U, P, V = split_W(W, n)
    Pn, Vn = node_arrays(grid, P, V)
    rp = P - (Pn[:, :-1] + Vn[:, :-1] * h + 0.5 * h**2 * U)
    rv = V - (Vn[:, :-1] + h * U)
    return ca.vertcat(rp, rv)


def gramian_expr(grid: Grid, model: VehicleModel, W):
    """Exact scaled Gramian ``G(t_N, t_0)`` of the path (eq. 25) as a CasADi expression of ``W``."""
    aug = augmented_model(model)
    g = interval_gramian_function(aug)
    N = grid.N
    U, P, V = split_W(W, grid.n)
    Pn, Vn = node_arrays(grid, P, V)
    tau = ca.DM(grid.tau).T
    D = Pn[:, :N] - ca.repmat(ca.DM(grid.p0), 1, N) - ca.DM(grid.v0) @ tau  # eq. 15
    E = Vn[:, :N] - ca.repmat(ca.DM(grid.v0), 1, N)
    gsum = g.map("gramian_sum", "serial", N, [], [0])
    G = gsum(D, E, U, tau, ca.DM.ones(1, N) * grid.h)
    return 0.5 * (G + G.T)


# ----------------------------------------------------------------------------- KF Riccati
@dataclass(frozen=True)
class KFNoise:
    """Noise model of the planning KF, scaled units.

    Attributes
    ----------
    epoch : float
        Range period (scaled).
    n_epochs : int
        Number of range updates in the horizon (at ``epoch, 2 epoch, ...``).
    sigma_r : float
        Range noise std (scaled): ``R = r² σ_r² + ½ σ_r⁴`` on ``ȳ``.
    P0 : ndarray (m, m)
        Prior covariance of ``z(t_0)``.
    Qd : ndarray (m, m)
        Process noise added per epoch.
    const_rows : ndarray (k, m)
        Path-independent output rows (DVL, depth).
    const_var : ndarray (k,)
        Their variances per epoch (aggregated).
    """

    epoch: float
    n_epochs: int
    sigma_r: float
    P0: np.ndarray
    Qd: np.ndarray
    const_rows: np.ndarray
    const_var: np.ndarray


def kf_noise(pb: PlanningProblem) -> KFNoise:
    """The planning KF's noise model: the validation KF's (``PlanningProblem.estimation_config``).

    Same prior ``p0_kf`` and per-step ``q_kf`` (accumulated over a range epoch), same range noise,
    and the anchor state ``β = -ε_0`` of ``y0_mode="augment"`` appended last (prior variance
    ``(r_0 σ_r)²``, a 1 in the range row), so the predicted covariance is the filter's.
    """
    L, T = pb.scales.length_m, pb.scales.time_s
    val = pb.validation
    model = pb.model
    aug = augmented_model(model)
    n, m = model.dim, aug.state_dim
    cfg = pb.estimation_config()
    cov = cfg.covariances(val.dt)
    epoch_s = 1.0 / val.range_rate
    n_epochs = int(np.floor(pb.horizon.duration / epoch_s + 1e-9))
    # state scaling of z = (p, v, [v_f], alpha, beta) and of the anchor (y units, m^2)
    scale = np.ones(m + 1)
    scale[:n] = 1 / L
    scale[n : m - 2] = T / L
    scale[m - 2] = T / L**2
    scale[m - 1] = T**2 / L**2
    scale[m] = 1 / L**2
    sigma_r = cfg.noise["range"]
    r0 = float(np.linalg.norm(pb.p0 - np.asarray(pb.beacon)))
    P0 = np.zeros((m + 1, m + 1))
    P0[:m, :m] = cov["p0_kf"]
    P0[m, m] = (r0 * sigma_r) ** 2 + 0.5 * sigma_r**4  # var of ½(r + ε)², as the filter's
    Qd = np.zeros((m + 1, m + 1))
    Qd[:m, :m] = cov["q_kf"] * (epoch_s / val.dt)
    S = np.diag(scale)
    rows: list[np.ndarray] = []
    var: list[float] = []
    full = aug.output_matrix(np.zeros(n), 0.0)
    i = 1
    for s in model.sensors:
        if s.startswith("dvl"):
            rows.extend(full[i : i + n])
            var.extend([(cfg.noise[s] * T / L) ** 2 * val.range_rate / val.dvl_rate] * n)
            i += n
        elif s == "depth":
            rows.append(full[i])
            var.append((cfg.noise[s] / L) ** 2 * val.range_rate / val.depth_rate)
            i += 1
    const_rows = np.zeros((len(rows), m + 1))
    if rows:
        const_rows[:, :m] = np.array(rows)
    return KFNoise(
        epoch=epoch_s / T,
        n_epochs=n_epochs,
        sigma_r=sigma_r / L,
        P0=S @ P0 @ S,
        Qd=S @ Qd @ S,
        const_rows=const_rows,
        const_var=np.array(var),
    )


def _riccati_step(aug, noise: KFNoise, dt_scaled: float) -> ca.Function:
    """One epoch: predict over ``dt`` then update with the range row and the constant rows."""
    m = aug.state_dim + 1  # with the anchor state
    P = ca.SX.sym("P", m, m)
    hcol = ca.SX.sym("h", m)
    r2 = ca.SX.sym("R")
    Phi = np.eye(m)
    Phi[:-1, :-1] += aug.A * dt_scaled  # eq. 26
    Pp = Phi @ P @ Phi.T + noise.Qd
    for row, var in [(hcol.T, r2)] + [
        (ca.DM(r).T, float(v)) for r, v in zip(noise.const_rows, noise.const_var, strict=True)
    ]:
        Ph = Pp @ row.T
        Pp = Pp - (Ph @ Ph.T) / (row @ Ph + var)
    Pp = 0.5 * (Pp + Pp.T)
    return ca.Function("riccati_step", [P, hcol, r2], [Pp])


def _epoch_rows(grid: Grid, noise: KFNoise, model: VehicleModel, Pn, Vn, U):
    """Range rows ``C(s_j)`` (eq. 21) and ``R_j`` at the range epochs, as CasADi matrices."""
    aug = augmented_model(model)
    m, n = aug.state_dim, grid.n
    rows, r2s = [], []
    for j in range(1, noise.n_epochs + 1):
        s = j * noise.epoch
        k = min(int(np.floor(s / grid.h + 1e-9)), grid.N - 1)
        sig = s - k * grid.h
        p = Pn[:, k] + Vn[:, k] * sig + 0.5 * U[:, k] * sig**2
        d = p - grid.p0 - grid.v0 * s  # eq. 15
        rows.append(ca.horzcat(d.T, ca.DM.zeros(1, m - n - 2), s, 0.5 * s**2, 1.0))
        # exact variance of ½(r + ε)² - ½r² for Gaussian ε (obsplan.estimation.sensors)
        r2s.append(ca.sumsqr(p) * noise.sigma_r**2 + 0.5 * noise.sigma_r**4)
    return ca.vertcat(*rows), ca.horzcat(*r2s)


def kf_final_cov_expr(grid: Grid, pb: PlanningProblem, W):
    """Final covariance of ``z`` of the planning KF (scaled) as a CasADi expression of ``W``."""
    model = pb.model
    aug = augmented_model(model)
    noise = kf_noise(pb)
    U, P, V = split_W(W, grid.n)
    Pn, Vn = node_arrays(grid, P, V)
    H, R = _epoch_rows(grid, noise, model, Pn, Vn, U)
    step = _riccati_step(aug, noise, noise.epoch)
    Pk = step.fold(noise.n_epochs)(ca.DM(noise.P0), H.T, R)
    rest = grid.N * grid.h - noise.n_epochs * noise.epoch
    if rest > 1e-12:
        Phi = np.eye(aug.state_dim + 1)
        Phi[:-1, :-1] += aug.A * rest
        Pk = Phi @ Pk @ Phi.T + noise.Qd * (rest / noise.epoch)
    return Pk


def kf_position_std_expr(grid: Grid, pb: PlanningProblem, W):
    """``sqrt(tr P_pp)`` at the final time [m]."""
    Pf = kf_final_cov_expr(grid, pb, W)
    n = grid.n
    return ca.sqrt(ca.trace(Pf[:n, :n])) * grid.L


# ----------------------------------------------------------------------------- LWO
def lwo_gram_terms(grid: Grid, model: VehicleModel, W):
    """``(OᵀO, trace)`` at every node 0..N with its held input, for the scaled nominal path.

    Returns a CasADi matrix ``(m, m (N+1))`` of the ``OᵀO`` blocks and a row of traces.
    """
    from obsplan.observability.lwo import lwo_matrix_function

    # the same model in the scaled frame, beacon at the origin (positions are relative to it)
    nd = VehicleModel(
        dim=model.dim, sensors=model.sensors, current=model.current, range_form=model.range_form
    )
    O = lwo_matrix_function(nd, 0)
    x = ca.SX.sym("x", nd.state_dim)
    u = ca.SX.sym("u", nd.dim)
    Ox = O(x, u)
    OtO = Ox.T @ Ox
    m = nd.state_dim
    gram = ca.Function("lwo_gram", [x, u], [OtO, ca.trace(OtO) / m])
    U, P, V = split_W(W, grid.n)
    Pn, Vn = node_arrays(grid, P, V)
    parts = [Pn, Vn]
    if model.current:
        parts.append(ca.DM.zeros(grid.n, grid.N + 1))  # O depends on v + v_f only (lwo.py)
    X = ca.vertcat(*parts)
    Uext = ca.horzcat(U, U[:, -1])
    return gram.map(grid.N + 1)(X, Uext)


# ----------------------------------------------------------------------------- assembly
@dataclass
class Formulation:
    """The NLP of a problem: symbols, bounds and helpers to pack/unpack and evaluate."""

    problem: PlanningProblem
    grid: Grid
    w: ca.MX
    f: ca.MX
    g: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    n_extra: int
    extra_init: Callable[[np.ndarray], np.ndarray]  # W -> initial lifting variables
    objective_sign: float  # +1: objective = f; -1: objective = -f (maximised)

    @property
    def n_w(self) -> int:
        return 3 * self.grid.n * self.grid.N

    def pack(self, traj: Trajectory) -> np.ndarray:
        """Initial guess vector from a trajectory on the planning grid."""
        U, P, V = self.grid.from_trajectory(traj)
        W = np.vstack([U, P, V])
        extra = np.asarray(self.extra_init(W)).reshape(-1)
        return np.concatenate([W.reshape(-1, order="F"), extra])

    def unpack(self, x: np.ndarray) -> tuple[Trajectory, np.ndarray]:
        """Solution vector to ``(trajectory [SI], lifting variables)``."""
        x = np.asarray(x, float).reshape(-1)
        n, N = self.grid.n, self.grid.N
        W = x[: self.n_w].reshape(3 * n, N, order="F")
        return self.grid.to_trajectory(W[:n], W[n : 2 * n], W[2 * n :]), x[self.n_w :]

    def objective_value(self, x: np.ndarray) -> float:
        """The objective in its user sign/units at ``x`` (e.g. ``t`` for min-eig)."""
        return float(self.objective_sign * float(ca.Function("f", [self.w], [self.f])(x)))

    @cached_property
    def constraint_fn(self) -> ca.Function:
        return ca.Function("g", [self.w], [self.g])


def build_formulation(pb: PlanningProblem) -> Formulation:
    """Assemble the NLP (variables, objective, constraints, bounds) of ``pb``."""
    grid = Grid.from_problem(pb)
    model = pb.model
    n, N = grid.n, grid.N
    kind = pb.objective.kind
    Wsym = ca.MX.sym("W", 3 * n, N)
    U, P, V = split_W(Wsym, n)

    # box bounds on W: input bounds; depth band / area on nodes, tightened so that the quadratic
    # position between nodes stays inside: a parabola with |p''| <= a overshoots the larger of its
    # end values by at most a h^2 / 8 on an interval of length h
    lbW = np.full((3 * n, N), -np.inf)
    ubW = np.full((3 * n, N), np.inf)
    lbW[:n] = -grid.u_max[:, None]
    ubW[:n] = grid.u_max[:, None]
    margin = grid.u_max * grid.h**2 / 8.0
    lim = pb.limits
    boxes: list[tuple[int, tuple[float, float]]] = []
    if lim.area is not None:
        boxes += [(0, lim.area.x), (1, lim.area.y)]
    if lim.depth is not None:
        boxes.append((2, lim.depth))
    for axis, (lo, hi) in boxes:
        b = grid.beacon[axis]
        lbW[n + axis] = (lo - b) / grid.L + margin[axis]
        ubW[n + axis] = (hi - b) / grid.L - margin[axis]

    # constraints: dynamics (equalities), speed at the nodes (exact: |v(t)|^2 is convex on an
    # interval of constant acceleration, so its maximum is at a node)
    g_parts = [ca.vec(dynamics_residual(grid, Wsym))]
    lbg = [np.zeros(2 * n * N)]
    ubg = [np.zeros(2 * n * N)]
    g_parts.append(ca.sum1(V**2).T)
    lbg.append(np.full(N, -np.inf))
    ubg.append(np.full(N, grid.v_max**2))

    extra_lb: list[np.ndarray] = []
    extra_ub: list[np.ndarray] = []
    if kind in ("gramian-min-eig", "gramian-log-det"):
        G = gramian_expr(grid, model, Wsym)
        m = G.shape[0]
        nl = m * (m + 1) // 2
        Lv = ca.MX.sym("L", nl)
        Lsx = ca.SX.sym("L", nl)
        Lm = _lower_from_vec(Lsx, m)
        llt = ca.Function("llt", [Lsx], [_vech(Lm @ Lm.T, m)])
        diag_idx = [k for k, (i, j) in enumerate(vech_indices(m)) if i == j]
        Gfun = ca.Function("G", [Wsym], [G])
        if kind == "gramian-min-eig":
            t = ca.MX.sym("t")
            extra = ca.vertcat(t, Lv)
            g_parts.append(_vech(G - t * ca.MX.eye(m), m) - llt(Lv))
            f = -t
            sign = -1.0
            extra_lb += [np.array([-np.inf]), np.full(nl, -np.inf)]
            extra_ub += [np.array([np.inf]), np.full(nl, np.inf)]

            def extra_init_np(W):
                # t at half of lambda_min: G - tI is well inside the PD cone, so L starts far
                # from the singular factors where the lifted problem has spurious stationary
                # points (a rank-deficient L breaks the constraint qualification)
                Gv = np.asarray(Gfun(W))
                ev = np.linalg.eigvalsh(Gv)
                floor = 1e-3 * max(ev[-1], 1e-12)
                t0 = 0.5 * ev[0] if ev[0] > floor else ev[0] - floor
                Lc = np.linalg.cholesky(Gv - t0 * np.eye(m))
                return np.concatenate([[t0], _vech_np(Lc)])

        else:
            extra = Lv
            g_parts.append(_vech(G, m) - llt(Lv))
            f = -2.0 * ca.sum1(ca.log(Lv[diag_idx]))
            sign = -1.0
            lb = np.full(nl, -np.inf)
            lb[diag_idx] = _CHOL_FLOOR
            extra_lb.append(lb)
            extra_ub.append(np.full(nl, np.inf))

            def extra_init_np(W):
                Gv = np.asarray(Gfun(W))
                ev = np.linalg.eigvalsh(Gv)
                shift = max(1e-6 * ev[-1], 1e-9) - min(ev[0], 0.0)
                return _vech_np(np.linalg.cholesky(Gv + shift * np.eye(m)))

        lbg.append(np.zeros(nl))
        ubg.append(np.zeros(nl))
    elif kind == "lwo-condition":
        OtO, tr = lwo_gram_terms(grid, model, Wsym)
        m = OtO.shape[0]
        nl = m * (m + 1) // 2
        K = N + 1
        c = ca.MX.sym("c")
        Lv = ca.MX.sym("L", nl, K)
        Lsx = ca.SX.sym("L", nl)
        Lm = _lower_from_vec(Lsx, m)
        As = ca.SX.sym("A", m, m)
        trs, cs = ca.SX.sym("tr"), ca.SX.sym("c")
        res = ca.Function(
            "lwo_res",
            [As, trs, cs, Lsx],
            [_vech(As - cs * trs * ca.SX.eye(m), m) - _vech(Lm @ Lm.T, m)],
        )
        g_parts.append(ca.vec(res.map(K)(OtO, tr, c, Lv)))
        lbg.append(np.zeros(nl * K))
        ubg.append(np.zeros(nl * K))
        extra = ca.vertcat(c, ca.vec(Lv))
        f = -c
        sign = -1.0
        extra_lb += [np.array([-np.inf]), np.full(nl * K, -np.inf)]
        extra_ub += [np.array([np.inf]), np.full(nl * K, np.inf)]
        terms = ca.Function("terms", [Wsym], [OtO, tr])

        def extra_init_np(W):
            A_all, tr_all = (np.asarray(a) for a in terms(W))
            blocks = A_all.reshape(m, K, m).transpose(1, 0, 2)
            trs_np = tr_all.ravel()
            rho = np.linalg.eigvalsh(blocks)[:, 0] / trs_np
            c0 = float(rho.min()) - 1e-3
            Ls = [
                _vech_np(np.linalg.cholesky(B - c0 * t * np.eye(m)))
                for B, t in zip(blocks, trs_np, strict=True)
            ]
            return np.concatenate([[c0], np.concatenate(Ls)])

    elif kind == "kf-position-std":
        extra = ca.MX.zeros(0, 1)
        f = kf_position_std_expr(grid, pb, Wsym)
        sign = 1.0

        def extra_init_np(W):
            return np.zeros(0)

    else:  # pragma: no cover - validated by the problem
        raise ValueError(kind)

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
        n_extra=int(extra.shape[0]),
        extra_init=extra_init_np,
        objective_sign=sign,
    )
