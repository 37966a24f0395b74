"""The ``lwo-condition`` objective: the conditioning of the LWO matrix (eq. 9) along the path.

``max`` the soft minimum over the nodes, ``-log(mean_k exp(-β g_k))/β``, of the conditioning
``g_k`` of the LWO matrix at node ``k`` (:func:`lwo_node_function`: geometric over arithmetic mean
of the eigenvalues of ``OᵀO``, in [0, 1]). Written as ``min Σ_k exp(-β g_k)``, it is separable over
the nodes: no lifting variables, a banded exact Hessian, and so it scales to N = 1000 (an epigraph
with a Cholesky factor per node did not).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from obsplan.model import VehicleModel
from obsplan.observability.lwo import lwo_matrices, lwo_matrix_function
from obsplan.planning.blocks import NLPContext, Objective, ObjectiveTerm
from obsplan.planning.grid import Grid
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

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


def lwo_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The ``lwo-condition`` objective on ``traj`` (on the planning grid): the soft minimum."""
    grid = Grid.from_problem(pb)
    return lwo_softmin(lwo_conditions(grid, pb, grid.from_trajectory(traj)))


def lwo_condition(traj: Trajectory, pb: PlanningProblem) -> float:
    """``min_k λ_min(O_kᵀO_k) / (tr(O_kᵀO_k)/m)`` in the problem's scales (a hard-minimum
    diagnostic of the LWO conditioning, independent of :func:`lwo_node_function`)."""
    L, T = pb.scales.length_m, pb.scales.time_s
    b = np.asarray(pb.beacon, float)
    tr = Trajectory(t=traj.t / T, p=(traj.p - b) / L, v=traj.v * T / L, u=traj.u * T**2 / L)
    m = pb.model
    nd = VehicleModel(dim=m.dim, sensors=m.sensors, current=m.current, range_form=m.range_form)
    O = lwo_matrices(tr, nd, 0)
    M = np.swapaxes(O, 1, 2) @ O
    ev = np.linalg.eigvalsh(M)
    return float(np.min(ev[:, 0] / (np.trace(M, axis1=1, axis2=2) / M.shape[-1])))


def lwo_term(ctx: NLPContext) -> ObjectiveTerm:
    """``min Σ_k exp(-β g_k) / s_ref`` (module docstring), ``s_ref`` its value on the reference.

    Separable over the nodes, so the exact Hessian keeps the stage-wise sparsity (no lifting).
    """
    pb, grid = ctx.problem, ctx.grid
    g_nodes = lwo_conditions(grid, pb, ctx.W)
    s_ref = float(np.sum(np.exp(-LWO_BETA * lwo_conditions(grid, pb, ctx.W_ref))))
    K = grid.N + 1
    return ObjectiveTerm(
        f=ca.sum2(ca.exp(-LWO_BETA * g_nodes)) / s_ref,
        to_objective=lambda fv: float(-np.log(fv * s_ref / K) / LWO_BETA),
    )


LWO_CONDITION = Objective("lwo-condition", lwo_term, lwo_value)
