"""Gramian objectives: E-optimal (``gramian-min-eig``) and D-optimal (``gramian-log-det``).

``G`` is the exact augmented Gramian ``G(t_N, t_0)`` (eq. 25) of the path in the problem's metric
scales (:func:`gramian_expr`), smooth in ``W``. CasADi has no symbolic eigenvalue, so both
objectives lift ``G`` with a lower-triangular variable ``L`` (constraints linear in ``G``, so the
Lagrangian Hessian keeps the stage-wise sparsity):

* ``gramian-min-eig``: ``max t`` s.t. ``G(W)/g - t I = L Lᵀ`` with ``g`` a fixed normaliser;
  ``G - tgI = LLᵀ`` forces ``t g <= λ_min(G)``, equal at the optimum;
* ``gramian-log-det``: ``max 2 Σ log L_ii`` s.t. ``D G(W) D = L Lᵀ`` with a fixed diagonal ``D``.

This is the paper's formulation (``objective.window = "mission"``, ``weights = "none"``); it
measures the initial state only and does not serve the filters (docs/results/suite.md, "Choosing the
objective"). Every other setting is the windowed, information-weighted form of
:mod:`obsplan.planning.objectives.windowed`.

The values on a path (:func:`gramian_metrics`) are computed numerically with the unit-invariant
rank test of :mod:`obsplan.observability.scaling`, never read from the lifting variables.
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from obsplan.observability.gramian import augmented_model, gramian, interval_gramian_function
from obsplan.observability.scaling import numerical_rank, psd_metrics
from obsplan.planning.objectives.windowed import paper_form, windowed_term, windowed_value
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import (
    ConstraintBlock,
    NLPContext,
    Objective,
    ObjectiveTerm,
    VariableBlock,
)
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.transcription.guesses import excited_path
from obsplan.trajectory.sampled import Trajectory

#: Lower bound of the diagonal of the log-det Cholesky variable: IPOPT may relax a bound by 1e-8
#: (bound_relax_factor), so a smaller floor would let log(L_ii) see a negative argument.
_CHOL_FLOOR = 1e-6


def vech_indices(m: int) -> list[tuple[int, int]]:
    """Lower-triangular index pairs ``(i, j)``, ``i >= j``, column by column.

    Parameters
    ----------
    m : int
        Size of the square matrix.

    Returns
    -------
    list of (int, int)
        ``m (m + 1) / 2`` pairs: the order of ``vech`` (the Cholesky variable's entries).
    """
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


def gramian_expr(grid: Grid, pb: PlanningProblem, W):
    """Exact Gramian ``G(t_N, t_0)`` (eq. 25) in the problem's metric scales, of ``W``.

    Parameters
    ----------
    grid : Grid
        The planning grid (intrinsic units of ``W``, the start state).
    pb : PlanningProblem
        The problem: its vehicle model and ``[scales]`` (length ``L`` [m], time ``T`` [s]).
    W : casadi.MX or ndarray, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    casadi expression, shape (m, m)
        The symmetric augmented Gramian (dimensionless, in the metric scales), ``m`` the
        augmented state's size.
    """
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


def gramian_metrics(traj: Trajectory, pb: PlanningProblem) -> tuple[float, float, float]:
    """``(min_eig, log_det, condition)`` of the scaled Gramian; ``(0, -inf, inf)`` when the
    unit-invariant rank test finds it rank deficient (round-off must not read as information:
    a 3D lawn-mower at constant depth has a 1e-17 "lambda_min" at N = 1000).

    Parameters
    ----------
    traj : Trajectory
        The path.
    pb : PlanningProblem
        The problem: its vehicle model and ``[scales]``.

    Returns
    -------
    min_eig : float
        Smallest eigenvalue of the scaled Gramian ``G(t_N, t_0)`` (dimensionless).
    log_det : float
        Its log-determinant.
    condition : float
        Its condition number.
    """
    path = pb.beacon_path
    if path is None:
        G = gramian(traj, pb.model, pb.scales)
    else:  # the known path's Gramian, the model's beacon at the origin as it wants
        model = replace(pb.model, beacon=(0.0,) * pb.dim)
        G = gramian(traj, model, pb.scales, beacon_path=path)
    if numerical_rank(G) < G.shape[0]:
        return 0.0, float("-inf"), float("inf")
    return psd_metrics(G)


class _Lifted:
    """The Gramian of ``ctx.W`` and the Cholesky variable ``L`` both objectives share."""

    def __init__(self, ctx: NLPContext):
        pb, grid, W = ctx.problem, ctx.grid, ctx.W
        self.G = gramian_expr(grid, pb, W)
        self.m = m = self.G.shape[0]
        self.Gfun = ca.Function("G", [W], [self.G])
        self.G_ref = np.asarray(self.Gfun(ctx.W_ref))
        self.nl = nl = m * (m + 1) // 2
        self.Lv = ca.MX.sym("L", nl)
        Lsx = ca.SX.sym("L", nl)
        Lm = _lower_from_vec(Lsx, m)
        self.llt = ca.Function("llt", [Lsx], [_vech(Lm @ Lm.T, m)])
        self.diag_idx = [k for k, (i, j) in enumerate(vech_indices(m)) if i == j]
        self.gnorm = max(float(np.trace(self.G_ref)) / m, 1e-300)

    def equality(self, Gn) -> ConstraintBlock:
        """``vech(Gn - L Lᵀ) = 0``."""
        z = np.zeros(self.nl)
        return ConstraintBlock("cholesky", _vech(Gn, self.m) - self.llt(self.Lv), z, z.copy())


def paper_min_eig_term(ctx: NLPContext) -> ObjectiveTerm:
    """E-optimal: ``max t`` s.t. ``G/g - t I = L Lᵀ`` (module docstring).

    E-optimality is not invariant to a diagonal congruence of ``G`` (it is a different objective
    in each metric), and the congruence of the log-det, ``G - tI ⪰ 0 <=> D G D - t D² ⪰ 0``, made
    IPOPT 5-10x slower in the default scales: it keeps ``G / g`` with a scalar ``g``.

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built: the problem, the grid, the path variables ``W`` and the reference
        path (``g`` is the mean diagonal of its Gramian).

    Returns
    -------
    ObjectiveTerm
        ``f = -t / t_ref`` (``t_ref`` the reference path's ``λ_min(G / g)``), the lifting
        variables ``(t, vech L)`` and the Cholesky equality.
    """
    lift = _Lifted(ctx)
    m, nl, gnorm, Gfun = lift.m, lift.nl, lift.gnorm, lift.Gfun
    Gn = lift.G / gnorm
    t = ca.MX.sym("t")
    ref = max(float(np.linalg.eigvalsh(lift.G_ref / gnorm)[0]), 1e-6)
    f_scale = ref * gnorm

    def init(W: np.ndarray) -> np.ndarray:
        # t at half of lambda_min: G - tI is well inside the PD cone, so L starts far from the
        # singular factors where the lifted problem has spurious stationary points (a
        # rank-deficient L breaks the constraint qualification)
        Gv = np.asarray(Gfun(W)) / gnorm
        ev = np.linalg.eigvalsh(Gv)
        floor = 1e-3 * max(ev[-1], 1e-12)
        t0 = 0.5 * ev[0] if ev[0] > floor else ev[0] - floor
        Lc = np.linalg.cholesky(Gv - t0 * np.eye(m))
        return np.concatenate([[t0], _vech_np(Lc)])

    lb = np.concatenate([np.array([-np.inf]), np.full(nl, -np.inf)])
    ub = np.concatenate([np.array([np.inf]), np.full(nl, np.inf)])
    return ObjectiveTerm(
        f=-t / ref,
        to_objective=lambda fv: float(-1.0 * f_scale * fv),
        variables=(VariableBlock("epigraph", ca.vertcat(t, lift.Lv), lb, ub, init),),
        constraints=(lift.equality(Gn - t * ca.MX.eye(m)),),
    )


def paper_log_det_term(ctx: NLPContext) -> ObjectiveTerm:
    """D-optimal: ``max 2 Σ log L_ii`` s.t. ``D G D = L Lᵀ`` (module docstring).

    The constraint acts on ``D G D`` with a fixed diagonal ``D`` (unit diagonal on typical paths:
    the reference and a random exciting path); ``log det G = log det(D G D) - 2 Σ log D_ii``, so
    the NLP, its iterates and its conditioning are the same whatever the metric scales make of
    G's t^0..t^4 columns (measured: identical iterations for L, T from (1 m, 1 s) to
    (10 km, 10 s)).

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built: the problem, the grid, the path variables ``W`` and the reference
        path (``D`` from the diagonal of its Gramian plus an excited path's).

    Returns
    -------
    ObjectiveTerm
        ``f = -log det G`` (through ``L`` and ``D``), the Cholesky variable ``vech L`` (its
        diagonal floored) and the Cholesky equality.
    """
    pb, grid = ctx.problem, ctx.grid
    lift = _Lifted(ctx)
    m, nl, Gfun = lift.m, lift.nl, lift.Gfun
    G_typ = lift.G_ref + np.asarray(Gfun(grid.from_trajectory(excited_path(pb))))
    diag = np.maximum(np.diag(G_typ), 1e-12 * np.max(np.diag(G_typ)))
    Dv = 1.0 / np.sqrt(diag)
    D = ca.DM(np.diag(Dv))

    def init(W: np.ndarray) -> np.ndarray:
        Gv = Dv[:, None] * np.asarray(Gfun(W)) * Dv[None, :]
        ev = np.linalg.eigvalsh(Gv)
        shift = max(1e-6 * ev[-1], 1e-9) - min(ev[0], 0.0)
        return _vech_np(np.linalg.cholesky(Gv + shift * np.eye(m)))

    lb = np.full(nl, -np.inf)
    lb[lift.diag_idx] = _CHOL_FLOOR
    # log det G = 2 Σ log L_ii - 2 Σ log D_ii: the constant does not change the optimum
    f = -2.0 * ca.sum1(ca.log(lift.Lv[lift.diag_idx])) + 2.0 * float(np.sum(np.log(Dv)))
    return ObjectiveTerm(
        f=f,
        to_objective=lambda fv: float(-1.0 * 1.0 * fv),
        variables=(VariableBlock("cholesky", lift.Lv, lb, np.full(nl, np.inf), init),),
        constraints=(lift.equality(D @ lift.G @ D),),
    )


def min_eig_term(ctx: NLPContext) -> ObjectiveTerm:
    """``gramian-min-eig``: the paper's lifted ``λ_min`` (:func:`paper_form`) or the windowed,
    information-weighted E-optimal surrogate (:mod:`obsplan.planning.objectives.windowed`).

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built.

    Returns
    -------
    ObjectiveTerm
        :func:`paper_min_eig_term`, or else
        :func:`~obsplan.planning.objectives.windowed.windowed_term`.
    """
    return paper_min_eig_term(ctx) if paper_form(ctx.problem) else windowed_term(ctx)


def log_det_term(ctx: NLPContext) -> ObjectiveTerm:
    """``gramian-log-det``: the paper's lifted ``log det`` or the windowed D-optimal form.

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built.

    Returns
    -------
    ObjectiveTerm
        :func:`paper_log_det_term`, or else
        :func:`~obsplan.planning.objectives.windowed.windowed_term`.
    """
    return paper_log_det_term(ctx) if paper_form(ctx.problem) else windowed_term(ctx)


def min_eig_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """``λ_min`` of ``G(t_N, t_0)`` (paper form) or the windowed E-optimal value on a path.

    Parameters
    ----------
    traj : Trajectory
        The path.
    pb : PlanningProblem
        The problem: its objective's settings, vehicle model and scales.

    Returns
    -------
    float
        The objective's value (maximised; 0 for a rank-deficient Gramian in the paper form).
    """
    return gramian_metrics(traj, pb)[0] if paper_form(pb) else windowed_value(traj, pb)


def log_det_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """``log det G(t_N, t_0)`` (paper form) or the windowed D-optimal value on a path.

    Parameters
    ----------
    traj : Trajectory
        The path.
    pb : PlanningProblem
        The problem: its objective's settings, vehicle model and scales.

    Returns
    -------
    float
        The objective's value (maximised; ``-inf`` for a rank-deficient Gramian in the paper
        form).
    """
    return gramian_metrics(traj, pb)[1] if paper_form(pb) else windowed_value(traj, pb)


GRAMIAN_MIN_EIG = Objective("gramian-min-eig", min_eig_term, min_eig_value)
GRAMIAN_LOG_DET = Objective("gramian-log-det", log_det_term, log_det_value)
