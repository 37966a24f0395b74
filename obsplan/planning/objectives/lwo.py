"""The ``lwo-condition`` objective: the LWO matrix (eq. 9) along the path, node by node.

Two forms (``objective.weights``), both separable over the nodes (no lifting variables, a banded
exact Hessian, so they scale to N = 1000; an epigraph with a Cholesky factor per node did not):

* ``"information"`` (default): at every node the LWO matrix with its rows weighted by what they
  carry for a filter, ``I_k = Σ_j w_j O_jᵀ H(τ) O_j``
  (:func:`~obsplan.observability.lwo.local_information_function`): the Fisher information about
  the state at the node from each output over the past window ``τ`` (``objective.window``,
  ``"auto"``: the Gramian objectives' ``2 τ_f``), the input held, ``w_j`` its rate / variance
  (the range's ``1/(r²σ_r² + ½σ_r⁴)`` at the node's distance). Two things a filter has at the
  node complete it (:func:`node_windows`): the window is clipped at the start, ``τ_k = min(τ,
  t_k)`` (no reading precedes the mission: a full window at the first nodes credited them with
  readings never taken, and the plan spent its first minute rushing at the beacon while both
  filters' errors doubled), and the validation's prior, propagated to ``t_k``, adds its
  information ``(Φ(t_k) P0 Φ(t_k)ᵀ)⁻¹`` (process noise left out). The input held over the
  window is the one that carries the node's velocity from the window's start to the node,
  ``(ν_k - ν(t_k - τ_k)) / τ_k`` (:func:`window_mean_inputs`), not the node's own: held for
  ``2 τ_f`` (about two minutes), the instantaneous input of a path that weaves every few seconds
  reads as a turn sustained over the whole window, whose fictitious geometry the information
  credits. With the node's own input the plans wove toward the beacon, the filters' errors in
  the first two minutes twice the lawn-mower's (``benchmarks/unseen_problems.py --seed 102
  --edge-start``, 2D, 0.2 Hz: EKF RMSE 1.07x the lawn-mower's, with the window's input 0.87x),
  and over 1000 runs the EKF lost track on 1 and 3 runs of the suite's 2D plans (none with the
  window's input; ``benchmarks/bench_linearisation.py``). The node criterion is the
  geometric mean of its eigenvalues, ``q_k = det(I_k + εI)^(1/m)``, and the objective
  ``max K / Σ_k 1/q_k``, their harmonic mean over the ``K`` nodes (dominated by the worst
  nodes: the paper's rule that the matrix be well conditioned at all times).
* ``"none"``: the scale-free form, ``max`` the soft minimum ``-log(mean_k exp(-β g_k))/β`` of the
  conditioning ``g_k`` (:func:`lwo_node_function`: geometric over arithmetic mean of the
  eigenvalues of ``OᵀO``, in [0, 1]). It ignores the range's distance, the rates and the
  process noise, keeps away from the beacon and does not serve the filters
  (docs/results/suite.md, "Choosing the objective"): a diagnostic, kept for research and
  comparison.
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from obsplan.model.vehicle import RangeForm, VehicleModel
from obsplan.observability.lwo import (
    local_information_function,
    lwo_matrices,
    lwo_matrix_function,
    lwo_orders,
    taylor_moments,
)
from obsplan.observability.windowed import (
    range_information,
    row_weight_factors,
    window_criteria_function,
)
from obsplan.planning.objectives.windowed import sensor_information, window_floor, window_settings
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.planning.transcription.blocks import NLPContext, Objective, ObjectiveTerm
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory


def _at_beacon(pb: PlanningProblem, range_form: RangeForm | None = None) -> VehicleModel:
    """``pb``'s model with the beacon at the origin (the nodes are passed relative to it), in
    ``range_form`` (default: the model's)."""
    m = pb.model
    form = m.range_form if range_form is None else range_form
    return VehicleModel(dim=m.dim, sensors=m.sensors, current=m.current, range_form=form)


def lwo_node_function(pb: PlanningProblem) -> ca.Function:
    """``g(x, u)``: conditioning of the LWO matrix at one node, in the metric scales.

    ``g = det(M̃)^(1/m)`` with ``M̃ = OᵀO / (tr(OᵀO)/m) + ridge I`` (``Tuning.lwo_ridge``): the
    ratio of the geometric to the arithmetic mean of the eigenvalues of ``OᵀO`` (``O`` of eq. 9 with
    the input held), 1 for a perfectly conditioned node and 0 for a rank-deficient one. The
    determinant comes from an unpivoted Cholesky factor (``M̃`` is positive definite), so ``g`` is
    smooth.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its vehicle model (sensors, current, range form).

    Returns
    -------
    casadi.Function
        ``g(x, u)``: ``x`` the state relative to the beacon and ``u`` the input, both in the
        metric scales; ``g`` in ``[0, 1]``.
    """
    nd = _at_beacon(pb)
    O = lwo_matrix_function(nd, 0)
    x = ca.SX.sym("x", nd.state_dim)
    u = ca.SX.sym("u", nd.dim)
    Ox = O(x, u)
    M = Ox.T @ Ox
    m = nd.state_dim
    _, logdet = window_criteria_function(m)(M / (ca.trace(M) / m), tuning().lwo_ridge)
    return ca.Function("lwo_condition", [x, u], [ca.exp(logdet / m)])


def scale_free(pb: PlanningProblem) -> bool:
    """True for the scale-free, diagnostic form (``objective.weights = "none"``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its ``objective.weights``.

    Returns
    -------
    bool
        The scale-free form; False for the information form.
    """
    return pb.objective.paper_form


def lwo_information_node_function(pb: PlanningProblem) -> ca.Function:
    """``q(x, u, h, ip)``: geometric mean of the eigenvalues of the weighted LWO information at
    one node (module docstring), in the metric scales; ``x`` relative to the beacon, ``h`` the
    node's Taylor moments and ``ip`` its prior information (:func:`node_windows`, one column).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its vehicle model, objective window, ``[validation]`` sensors and
        ``[scales]``.

    Returns
    -------
    casadi.Function
        ``q(x, u, h, ip)``, all in the metric scales: ``x`` the state, ``u`` the held input,
        ``h`` the ``K²`` Taylor moments, ``ip`` the ``m²`` prior information (column-major).
    """
    nd = _at_beacon(pb, "half-squared")  # the weights are those of y = |p - b|²/2
    ws = window_settings(pb)
    L = pb.scales.length_m
    info = sensor_information(pb)
    c_range, other = row_weight_factors(nd, replace(info, start_range=None), pb.scales)
    x = ca.SX.sym("x", nd.state_dim)
    u = ca.SX.sym("u", nd.dim)
    m = nd.state_dim
    K = lwo_orders(nd) + 1
    h = ca.SX.sym("h", K * K)
    ip = ca.SX.sym("ip", m * m)
    r2 = ca.sumsqr(x[: nd.dim]) * L**2
    w = ca.vertcat(c_range * range_information(r2, info.range_std), ca.DM(other))
    I = local_information_function(nd, None)(x, u, w, h) + ca.reshape(ip, m, m)
    _, logdet = window_criteria_function(m)(I, window_floor(pb, ws))
    return ca.Function("lwo_information_mean", [x, u, h, ip], [ca.exp(logdet / m)])


def clipped_windows(grid: Grid, pb: PlanningProblem) -> tuple[np.ndarray, np.ndarray]:
    """Each node's past window clipped at the start (module docstring), the one rule
    :func:`node_windows` and :func:`window_mean_inputs` share: its length ``τ_k = min(τ, t_k)``
    [s], shape (N+1,), and the node where it starts, the one nearest ``t_k - τ_k`` and at least
    one step before ``k`` (0 at the first nodes), int, shape (N+1,). The Taylor moments take the
    exact length; the held input needs a node to difference the velocity against.

    Parameters
    ----------
    grid : Grid
        The planning grid (node times, step ``h`` [s]).
    pb : PlanningProblem
        The problem: its objective's window
        (:func:`~obsplan.planning.objectives.windowed.window_settings`).

    Returns
    -------
    tau : ndarray, shape (N + 1,)
        Each node's window length ``τ_k`` [s].
    start : ndarray of int, shape (N + 1,)
        The node where each window starts.
    """
    tau = window_settings(pb).window_s
    w = max(1, int(round(tau / grid.h)))
    k = np.arange(grid.N + 1)
    return np.minimum(tau, np.asarray(grid.times, float)), np.maximum(0, k - w)


def node_windows(grid: Grid, pb: PlanningProblem) -> tuple[np.ndarray, np.ndarray]:
    """Per node ``k``: the Taylor moments of its window clipped at the start,
    ``τ_k = min(τ, t_k)`` (no reading precedes the mission), flattened ``(K², N+1)``, and the
    prior's information about the state at ``t_k`` (the validation's prior propagated without
    process noise), flattened ``(m², N+1)``; both in the metric scales.

    Parameters
    ----------
    grid : Grid
        The planning grid.
    pb : PlanningProblem
        The problem: its vehicle model, objective window, validation's prior (the EKF's
        ``P0``) and ``[scales]``.

    Returns
    -------
    moments : ndarray, shape (K², N + 1)
        Each node's Taylor moments, column-major (dimensionless).
    prior : ndarray, shape (m², N + 1)
        Each node's prior information, column-major (dimensionless).
    """
    nd = _at_beacon(pb, "half-squared")
    T, L = pb.scales.time_s, pb.scales.length_m
    tau_k, _ = clipped_windows(grid, pb)
    K = lwo_orders(nd) + 1
    m, n = nd.state_dim, nd.dim
    P0 = np.asarray(estimation_config(pb).p0_ekf, float)[:m, :m]
    S = np.diag([1.0 / L] * n + [T / L] * (m - n))
    Hk, Ik = [], []
    for t, tau in zip(grid.times, tau_k, strict=True):
        Hk.append(taylor_moments(K - 1, float(tau) / T).ravel(order="F"))
        F, _ = nd.transition(float(t))
        Pt = S @ F @ P0 @ F.T @ S.T
        Ik.append(np.linalg.inv(0.5 * (Pt + Pt.T)).ravel(order="F"))
    return np.array(Hk).T, np.array(Ik).T


def window_mean_inputs(grid: Grid, pb: PlanningProblem, u, v):
    """The input held over each node's window (information form): ``(ν_k - ν_a) / (t_k - t_a)``
    with ``a`` the node where the window clipped at the start begins (:func:`node_windows`), the
    constant acceleration that carries the velocity across the window; ``u_0`` at the first node
    (an empty window). ``u`` (n, N) and ``v`` (n, N+1) [SI], numpy or CasADi; shape (n, N+1)
    [m/s²].

    Parameters
    ----------
    grid : Grid
        The planning grid.
    pb : PlanningProblem
        The problem: its objective's window.
    u : ndarray or casadi.MX, shape (n, N)
        Inputs [m/s²].
    v : ndarray or casadi.MX, shape (n, N + 1)
        Node velocities [m/s].

    Returns
    -------
    ndarray or casadi.MX, shape (n, N + 1)
        The held input of each node's window [m/s²].
    """
    _, start = clipped_windows(grid, pb)
    cols = [u[:, 0]]
    for k in range(1, grid.N + 1):
        a = int(start[k])
        cols.append((v[:, k] - v[:, a]) / ((k - a) * grid.h))
    return np.column_stack(cols) if isinstance(u, np.ndarray) else ca.horzcat(*cols)


def lwo_conditions(grid: Grid, pb: PlanningProblem, W):
    """Row ``(1, N+1)`` of the node criteria of ``W``: ``q_k`` of the information form
    (:func:`lwo_information_node_function`, the input of :func:`window_mean_inputs`), or the
    conditioning ``g_k`` of the scale-free one (:func:`lwo_node_function`, the node's own input:
    the paper's matrix).

    Parameters
    ----------
    grid : Grid
        The planning grid.
    pb : PlanningProblem
        The problem: its objective's form, model and ``[scales]``.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    ndarray or casadi.MX, shape (1, N + 1)
        The node criteria ``q_k`` or ``g_k`` (numeric for a numeric ``W``).
    """
    L, T = pb.scales.length_m, pb.scales.time_s
    uu, p, v = grid.si_nodes(W)
    numeric = isinstance(W, np.ndarray)
    parts = [p / L, v * (T / L)]
    if pb.model.current:  # O depends on v + v_f only (lwo.py): v_f = 0 nominally
        parts.append(np.zeros((grid.n, grid.N + 1)) if numeric else ca.DM.zeros(grid.n, grid.N + 1))
    X = np.vstack(parts) if numeric else ca.vertcat(*parts)
    if scale_free(pb):
        Uext = (np.hstack([uu, uu[:, -1:]]) if numeric else ca.horzcat(uu, uu[:, -1])) * (T**2 / L)
        g = lwo_node_function(pb).map(grid.N + 1)(X, Uext)
    else:
        Uext = window_mean_inputs(grid, pb, uu, v) * (T**2 / L)
        Hk, Ik = node_windows(grid, pb)
        g = lwo_information_node_function(pb).map(grid.N + 1)(X, Uext, Hk, Ik)
    return np.asarray(g) if numeric else g


def lwo_softmin(g) -> float:
    """``-log(mean exp(-β g)) / β``, the soft minimum the scale-free form maximises (``β``:
    ``Tuning.lwo_beta``, within ``log(N + 1) / β`` of the true minimum).

    Parameters
    ----------
    g : array_like
        The node conditionings ``g_k`` (any shape, flattened).

    Returns
    -------
    float
        The soft minimum.
    """
    beta = tuning().lwo_beta
    g = np.asarray(g, float).ravel()
    lo = float(g.min())  # shifted for a stable log-sum-exp
    return lo - float(np.log(np.mean(np.exp(-beta * (g - lo))))) / beta


def lwo_harmonic_mean(q) -> float:
    """``K / Σ_k 1/q_k``, what the information form maximises.

    Parameters
    ----------
    q : array_like
        The node criteria ``q_k``, positive (any shape, flattened).

    Returns
    -------
    float
        Their harmonic mean.
    """
    q = np.asarray(q, float).ravel()
    return float(q.size / np.sum(1.0 / q))


def lwo_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The ``lwo-condition`` objective on ``traj`` (on the planning grid).

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid of ``pb``.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    float
        :func:`lwo_softmin` (scale-free form) or :func:`lwo_harmonic_mean` (information form)
        of the node criteria; larger is better.
    """
    grid = Grid.from_problem(pb)
    g = lwo_conditions(grid, pb, grid.from_trajectory(traj))
    return lwo_softmin(g) if scale_free(pb) else lwo_harmonic_mean(g)


def lwo_condition(traj: Trajectory, pb: PlanningProblem) -> float:
    """``min_k λ_min(O_kᵀO_k) / (tr(O_kᵀO_k)/m)`` in the problem's scales (a hard-minimum
    diagnostic of the LWO conditioning, independent of :func:`lwo_node_function`).

    Parameters
    ----------
    traj : Trajectory
        The path (any sampling).
    pb : PlanningProblem
        The problem: its vehicle model, beacon and ``[scales]``.

    Returns
    -------
    float
        The worst node's ratio of the smallest to the mean eigenvalue, in ``[0, 1]``.
    """
    L, T = pb.scales.length_m, pb.scales.time_s
    b = np.asarray(pb.beacon, float)
    tr = Trajectory(t=traj.t / T, p=(traj.p - b) / L, v=traj.v * T / L, u=traj.u * T**2 / L)
    O = lwo_matrices(tr, _at_beacon(pb), 0)
    M = np.swapaxes(O, 1, 2) @ O
    ev = np.linalg.eigvalsh(M)
    return float(np.min(ev[:, 0] / (np.trace(M, axis1=1, axis2=2) / M.shape[-1])))


def lwo_term(ctx: NLPContext) -> ObjectiveTerm:
    """The node sum of the form in force over its value on the reference ``s_ref``: ``min Σ_k
    1/q_k / s_ref`` (information) or ``min Σ_k exp(-β g_k) / s_ref`` (scale-free).

    Separable over the nodes, so the exact Hessian keeps the stage-wise sparsity (no lifting).

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built: the problem, the grid, ``W`` and the reference path ``W_ref``.

    Returns
    -------
    ObjectiveTerm
        The normalised node sum and the map back to :func:`lwo_value`'s units (exact Hessian).
    """
    pb, grid = ctx.problem, ctx.grid
    g_nodes = lwo_conditions(grid, pb, ctx.W)
    g_ref = lwo_conditions(grid, pb, ctx.W_ref)
    K = grid.N + 1
    if not scale_free(pb):
        s_ref = float(np.sum(1.0 / g_ref))
        return ObjectiveTerm(
            f=ca.sum2(1.0 / g_nodes) / s_ref, to_objective=lambda fv: float(K / (fv * s_ref))
        )
    beta = tuning().lwo_beta
    s_ref = float(np.sum(np.exp(-beta * g_ref)))
    return ObjectiveTerm(
        f=ca.sum2(ca.exp(-beta * g_nodes)) / s_ref,
        to_objective=lambda fv: float(-np.log(fv * s_ref / K) / beta),
    )


LWO_CONDITION = Objective("lwo-condition", lwo_term, lwo_value)
