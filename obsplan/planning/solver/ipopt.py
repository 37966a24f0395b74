"""IPOPT: the solvers of a formulation, calling them, and Ctrl-C.

* :func:`make_solver`: the ``nlpsol`` of a :class:`~obsplan.planning.solver.formulation.Formulation`
  (MUMPS; the exact Hessian or L-BFGS as the objective asks; warm-start options);
* :func:`make_projection` / :func:`project`: the nearest flyable path to one that violates a limit
  by a little (e.g. by 0.02 % when IPOPT stops at its iteration limit): least squares in the NLP's
  intrinsic units on the inputs, subject to every path constraint and the mission's, by a second
  small IPOPT problem;
* :func:`_call`: one call of an ``nlpsol`` returning ``(solution or None, stats, error)``, with
  Ctrl-C (:func:`_interrupt_guard`) surfacing as ``KeyboardInterrupt``.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any

import casadi as ca
import numpy as np

from obsplan.core import interrupts
from obsplan.planning.objectives.linearisation import penalty_bound
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.solver.formulation import Formulation, path_constraints
from obsplan.planning.transcription.mission import mission_part
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory

#: IPOPT's status of a converged solve (``Solved_To_Acceptable_Level`` is not).
SUCCESS_STATUS = "Solve_Succeeded"

#: What IPOPT's statuses of a stopped solve mean, in words (:func:`stop_reason`).
_STOP_WORDS = {
    "Maximum_Iterations_Exceeded": "stopped at IPOPT's iteration limit",
    "Maximum_WallTime_Exceeded": "stopped at IPOPT's wall-time limit",
    "Maximum_CpuTime_Exceeded": "stopped at IPOPT's CPU-time limit",
    "Solved_To_Acceptable_Level": "stopped at IPOPT's acceptable level (acceptable_tol), not tol",
    "Restoration_Failed": "IPOPT's restoration phase failed to find a less infeasible point",
    "Infeasible_Problem_Detected": "IPOPT found the constraints locally infeasible",
    "Search_Direction_Becomes_Too_Small": "IPOPT's search direction became too small",
    "Error_In_Step_Computation": "IPOPT could not compute a step (singular KKT system)",
    "Invalid_Number_Detected": "a function returned NaN or Inf",
}


def warm_start_options(limited: bool) -> dict[str, float]:
    """IPOPT options of a warm start (guesses that are coarse-grid optima): begin at the guess,
    not 1 % inside the bounds (``bound_push`` / ``bound_frac``), with a small barrier
    (``mu_init``).

    Parameters
    ----------
    limited : bool
        Whether the Hessian is L-BFGS: then only the small barrier, since starting on the bounds
        its first steps wander off.

    Returns
    -------
    dict of str to float
        ``mu_init`` (``Tuning.warm_mu_init``), and without ``limited`` also ``bound_push`` and
        ``bound_frac`` (``Tuning.warm_bound_push``, ``warm_bound_frac``).
    """
    tun = tuning()
    if limited:
        return {"mu_init": tun.warm_mu_init}
    return {
        "bound_push": tun.warm_bound_push,
        "bound_frac": tun.warm_bound_frac,
        "mu_init": tun.warm_mu_init,
    }


def ipopt_settings(
    form: Formulation,
    verbose: bool = False,
    ipopt_options: dict | None = None,
    warm: bool = False,
) -> dict[str, Any]:
    """The IPOPT options :func:`make_solver` gives the solver of ``form``: MUMPS, the
    objective's tolerance and iteration limit, the exact Hessian or L-BFGS as the objective
    asks (:func:`lbfgs_options`), :func:`warm_start_options` when ``warm``, and
    ``ipopt_options`` last.

    Parameters
    ----------
    form : Formulation
        The NLP: its problem's ``objective`` (``solver_tol``, ``max_iter``) and its ``hessian``.
    verbose : bool, optional
        Print IPOPT's iterations (``print_level`` 5 instead of 0).
    ipopt_options : dict, optional
        IPOPT options applied last, overriding the others (e.g. ``{"max_wall_time": 120.0}``
        in the benchmark).
    warm : bool, optional
        The guesses are coarse-grid optima: add :func:`warm_start_options`.

    Returns
    -------
    dict of str to Any
        The ``ipopt`` options of ``nlpsol``; ``constr_viol_tol`` is at most 1e-8, not IPOPT's
        default 1e-4, since the equality residuals bound how far an epigraph variable exceeds
        what it bounds and how far the path is from the dynamics.
    """
    obj = form.problem.objective
    ipopt: dict[str, Any] = {
        "linear_solver": "mumps",
        "print_level": 5 if verbose else 0,
        "sb": "yes",
        "tol": obj.solver_tol,
        # equality residuals bound how far the epigraph variable can exceed lambda_min and how
        # far the path is from the dynamics: keep them tight, not IPOPT's default 1e-4
        "constr_viol_tol": min(obj.solver_tol, 1e-8),
        "max_iter": obj.max_iter,
    }
    limited = form.hessian.startswith("limited-memory")
    if limited:
        ipopt.update(lbfgs_options(form.problem, form.hessian == "limited-memory-sr1"))
    if warm:
        ipopt.update(warm_start_options(limited))
    ipopt.update(ipopt_options or {})
    return ipopt


def range_epochs_per_step(pb: PlanningProblem) -> float:
    """Range epochs per planning interval: the validation's range rate times the step [-].

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``validation.range_rate`` [Hz] and its ``horizon``.

    Returns
    -------
    float
        The expected number of range epochs in one step ``h`` [-].
    """
    return pb.validation.range_rate * pb.horizon.duration / pb.horizon.steps


def lbfgs_options(pb: PlanningProblem, sr1: bool = False) -> dict[str, Any]:
    """IPOPT options of the quasi-Newton (L-BFGS, or SR1) Hessian approximation of ``pb``.

    * ``limited_memory_max_history`` (``Tuning.lbfgs_history``): each stored pair costs two
      extra back-solves per iteration;
    * ``mu_strategy = "monotone"`` when the range epochs are sparse, at most
      ``Tuning.monotone_epochs_per_step`` per planning interval
      (:func:`range_epochs_per_step`), or the NLP has the EKF linearisation penalty
      (:func:`~obsplan.planning.objectives.linearisation.penalty_bound`); IPOPT's default, the
      adaptive barrier, otherwise.

    Why (docs/tuning.md, "The barrier with L-BFGS"): the final std of the estimator objectives
    turns with the bearings of the last range epochs, steeply where the plan ends near the
    beacon. With sparse epochs each of those epochs sits on one node, so a handful of position
    variables carry curvature 1e2-1e3 against 1e-3 for the rest of the path, which a short
    L-BFGS history cannot model. IPOPT's adaptive barrier (its default with a quasi-Newton
    Hessian) predicts each step with that model: ``mu`` bounced between 1e-3 and 1e-5, steps
    overshot on those positions and every start stopped at the iteration limit with the dual
    infeasibility at 1e-2..1 there. The monotone barrier solves each barrier problem before
    lowering ``mu``, and the same starts converge. With denser epochs the curvature is spread
    over many epochs and nodes, and the monotone barrier was the slower one (a 3-minute
    ``kf-position-std`` problem at 2 epochs per step crept at 5e-4 per iteration to the limit
    on every start, where the adaptive one converges in about 100 iterations). The linearisation
    penalty does the same with dense epochs: it is active at a few epochs whose stress sits on
    the bound (early in the mission, where the prior is still wide), curvature on a few nodes
    again; under the adaptive barrier ``mu`` fell to 1e-11 with the dual infeasibility at 5e-2
    and the objective still moving, on every start of a 3D depth-gauge ``gramian-log-det``
    problem, where the monotone barrier converges in 65-238 iterations (docs/tuning.md).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its range rate and horizon decide the barrier strategy.
    sr1 : bool, optional
        Use the SR1 update instead of BFGS (``limited_memory_update_type = "sr1"``).

    Returns
    -------
    dict of str to Any
        ``hessian_approximation = "limited-memory"``, ``limited_memory_max_history``, and
        ``mu_strategy`` and ``limited_memory_update_type`` when they apply.
    """
    out: dict[str, Any] = {
        "hessian_approximation": "limited-memory",
        "limited_memory_max_history": tuning().lbfgs_history,
    }
    sparse = range_epochs_per_step(pb) <= tuning().monotone_epochs_per_step
    if sparse or penalty_bound(pb) > 0:
        out["mu_strategy"] = "monotone"
    if sr1:
        out["limited_memory_update_type"] = "sr1"
    return out


def make_solver(
    form: Formulation,
    verbose: bool = False,
    expand: bool = True,
    ipopt_options: dict | None = None,
    warm: bool = False,
) -> ca.Function:
    """The IPOPT ``nlpsol`` of a formulation with the options of :func:`ipopt_settings`
    (MUMPS; exact Hessian or L-BFGS per objective; ``warm``: :func:`warm_start_options`;
    ``ipopt_options`` passed last).

    Parameters
    ----------
    form : Formulation
        The NLP.
    verbose : bool, optional
        Print IPOPT's iterations and CasADi's timings.
    expand : bool, optional
        Expand the MX graph to SX before solving (CasADi's ``expand``): faster evaluations, at
        the cost of building the expanded graph.
    ipopt_options : dict, optional
        IPOPT options applied last (:func:`ipopt_settings`).
    warm : bool, optional
        The guesses are coarse-grid optima (:func:`warm_start_options`).

    Returns
    -------
    casadi.Function
        The solver, called with ``x0``, ``p``, ``lbx``, ``ubx``, ``lbg``, ``ubg``. With the
        ``exact-without-penalty`` Hessian it is given a ``hess_lag`` that leaves the parts'
        penalty out of the objective's curvature.
    """
    ipopt = ipopt_settings(form, verbose=verbose, ipopt_options=ipopt_options, warm=warm)
    opts: dict[str, Any] = {"expand": expand, "print_time": verbose, "ipopt": ipopt}
    if form.hessian == "exact-without-penalty":
        opts["hess_lag"] = _hessian_without_penalty(form, expand)
    nlp = {"x": form.w, "p": form.parameters, "f": form.f, "g": form.g}
    return ca.nlpsol("obsplan_planner", "ipopt", nlp, opts)  # type: ignore[arg-type]


def _hessian_without_penalty(form: Formulation, expand: bool) -> ca.Function:
    """IPOPT's ``hess_lag``: the upper triangle of the exact Hessian of the Lagrangian with
    the penalty (``form.penalty``) left out of the objective.

    The penalty is a covariance recursion's, whose exact Hessian is dense (building it for a 3D
    DVL problem ran out of 24 GB); IPOPT still has its exact gradient, so a step that raises it
    is cut back by the line search. Against L-BFGS on the whole (``lwo-condition`` bounded,
    ``benchmarks/bench_gramian_objectives.py``): Solve_Succeeded at N = 200, 1000 and 3D
    N = 600 where L-BFGS ended at an acceptable level and at its iteration limit.
    """
    x, p = form.w, form.parameters
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", form.g.numel())
    f = form.f if form.objective_f is None else form.objective_f
    lagrangian = lam_f * f + ca.dot(lam_g, form.g)
    hess = ca.triu(ca.hessian(lagrangian, x)[0])
    fn = ca.Function(
        "nlp_hess_l",
        [x, p, lam_f, lam_g],
        [hess],
        ["x", "p", "lam_f", "lam_g"],
        ["triu_hess_gamma_x_x"],
    )
    return fn.expand() if expand else fn


def make_projection(pb: PlanningProblem, form: Formulation) -> ca.Function:
    """IPOPT for the nearest inputs ``min ½ |U - Ū|²`` (intrinsic units, ``|U_i| <= 1``) such
    that the path satisfies every path constraint (``W̄`` the parameter ``p``).

    The inputs determine the path, so nearest inputs mean the nearest flyable path; positions
    and velocities follow through the dynamics constraints.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its limits and mission give the constraints.
    form : Formulation
        The planning NLP: its grid.

    Returns
    -------
    casadi.Function
        The projection's ``nlpsol`` on ``vec(W)`` with parameter ``vec(W̄)``; its constraints are
        the path constraints then the mission's, whose bounds :func:`project` passes at the call.
        It starts at the given path with a small barrier (``bound_push`` 1e-9, ``mu_init``
        1e-8): IPOPT's default push of 1 % off the bounds would move a long path by tens of
        metres.
    """
    grid = form.grid
    n = grid.n
    W = ca.MX.sym("W", 3 * n, grid.N)
    Wbar = ca.MX.sym("Wbar", 3 * n, grid.N)
    g = [c.g for c in _projected_constraints(grid, pb, W)]
    f = 0.5 * ca.sumsqr(W[:n, :] - Wbar[:n, :])
    nlp: dict[str, Any] = {"x": ca.vec(W), "p": ca.vec(Wbar), "f": f, "g": ca.vertcat(*g)}
    ipopt: dict[str, Any] = {
        "linear_solver": "mumps",
        "print_level": 0,
        "sb": "yes",
        "tol": tuning().projection_tol,
        "constr_viol_tol": tuning().projection_tol,
        "max_iter": 200,
        # start at the given path, not 1 % inside the bounds (IPOPT's default bound_push
        # moves inputs at their limit by 1 %, which over a long horizon moves the path by
        # tens of metres), with a small barrier: the point is already nearly optimal
        "bound_push": 1e-9,
        "bound_frac": 1e-9,
        "mu_init": 1e-8,
    }
    return ca.nlpsol(
        "obsplan_projection", "ipopt", nlp, {"expand": True, "print_time": False, "ipopt": ipopt}
    )


def _projected_constraints(grid, pb: PlanningProblem, W) -> list:
    """The constraints a projected path satisfies: the path's, then the mission's (they are on
    ``W`` only)."""
    part = mission_part(pb, grid, W)
    return [*path_constraints(grid, pb, W), *(part.constraints if part is not None else ())]


@contextmanager
def _interrupt_guard():
    """Make Ctrl-C stop a CasADi solve and surface as ``KeyboardInterrupt``.

    CasADi catches the ``KeyboardInterrupt`` raised inside IPOPT's iteration check and returns
    ``NonIpopt_Exception_Thrown``; the handler below records the signal so that the caller can
    raise it once the solver has returned (at the next iteration, i.e. at once).
    """
    hit: list[bool] = []
    if interrupts.installed() or threading.current_thread() is not threading.main_thread():
        # the command line's handler (obsplan.core.interrupts) records the signal: check() raises it
        yield hit
        return
    prev = signal.getsignal(signal.SIGINT)
    if prev is signal.SIG_IGN:  # a worker process: the parent handles Ctrl-C
        yield hit
        return

    def handler(signum, frame):
        hit.append(True)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield hit
    finally:
        signal.signal(signal.SIGINT, prev)


def _call(solver: ca.Function, **kwargs) -> tuple[dict | None, dict, str | None]:
    """Call an nlpsol; ``(solution or None, stats, error message or None)``; Ctrl-C re-raised."""
    with _interrupt_guard() as hit:
        try:
            sol = solver(**kwargs)
            err = None
        except RuntimeError as exc:  # IPOPT/CasADi errors (e.g. evaluation failures)
            sol, err = None, f"exception: {exc}".splitlines()[0][:200]
        if hit:
            raise KeyboardInterrupt
    interrupts.check()  # SIGTERM (or a SIGINT CasADi swallowed) stops the solve the same way
    return sol, solver.stats(), err


def stop_reason(stats: dict, tol: float, constr_viol_tol: float) -> str:
    """Why a solve that did not converge stopped, in words ("" for ``Solve_Succeeded``):
    IPOPT's status, the dual infeasibility and constraint violation of the last iterate against
    the tolerances the solve needed (``tol``, ``constr_viol_tol``), the barrier parameter, and
    how much the objective still moved over the last iterations (from ``stats["iterations"]``).

    E.g. "stopped at IPOPT's iteration limit (1000 iterations) with the dual infeasibility at
    2.5e-01 (tol 1e-04) and the constraint violation at 6.6e-15 (tol 1e-08), the barrier at
    5.3e-05: the objective still moved by 1.4 % over the last 100 iterations (0.6580 -> 0.6578,
    between 0.6520 and 0.6612)".

    Parameters
    ----------
    stats : dict
        The solver's ``stats()``: ``return_status``, ``iter_count`` and the per-iteration
        ``iterations`` (``inf_du``, ``inf_pr``, ``mu``, ``obj``).
    tol : float
        IPOPT's ``tol`` of the solve, against which the dual infeasibility is reported.
    constr_viol_tol : float
        IPOPT's ``constr_viol_tol`` of the solve, against which the constraint violation is
        reported.

    Returns
    -------
    str
        The reason; "" for ``Solve_Succeeded``; only the status's words and the iteration count
        when ``stats`` has no per-iteration trace. The objective's movement is over the last
        ``min(100, len(obj) // 2)`` iterations.
    """
    status = str(stats.get("return_status", "unknown"))
    if status == SUCCESS_STATUS:
        return ""
    words = _STOP_WORDS.get(status, f"IPOPT ended with {status}")
    iters = int(stats.get("iter_count", 0))
    trace = stats.get("iterations") or {}
    du, pr, mu, obj = (list(trace.get(k) or []) for k in ("inf_du", "inf_pr", "mu", "obj"))
    if not (du and pr and obj):
        return f"{words} ({iters} iterations)"
    text = (
        f"{words} ({iters} iterations) with the dual infeasibility at {du[-1]:.1e} (tol "
        f"{tol:.0e}) and the constraint violation at {pr[-1]:.1e} (tol {constr_viol_tol:.0e})"
    )
    if mu:
        text += f", the barrier at {mu[-1]:.1e}"
    k = min(100, max(len(obj) // 2, 1))
    last = np.asarray(obj[-k - 1 :], float)
    scale = max(abs(float(last[0])), 1e-12)
    if last.size > 1 and np.all(np.isfinite(last)):
        moved = float(last.max() - last.min()) / scale
        text += (
            f": the objective still moved by {100 * moved:.2g} % over the last {k} iterations "
            f"({last[0]:.4g} -> {last[-1]:.4g}, between {last.min():.4g} and {last.max():.4g})"
        )
    return text


def project(
    form: Formulation, projection: ca.Function, traj: Trajectory
) -> tuple[Trajectory | None, str]:
    """Nearest path to ``traj`` satisfying the path constraints, by the IPOPT ``projection`` of
    :func:`make_projection` (module docstring).

    Parameters
    ----------
    form : Formulation
        The planning NLP: its grid, and the bounds of ``W`` and of the path constraints.
    projection : casadi.Function
        The projection solver of :func:`make_projection` for the same problem.
    traj : Trajectory
        The path to project, on the planning grid (``N + 1`` samples); it is both the start and
        the target ``W̄``.

    Returns
    -------
    path : Trajectory or None
        The projected inputs re-integrated exactly from the start, so the samples are
        consistent; None when the call raised. Returned whatever IPOPT's status: the caller
        checks the path itself.
    status : str
        IPOPT's ``return_status``, or the error message of a call that raised.
    """
    grid = form.grid
    wbar = grid.from_trajectory(traj).reshape(-1, order="F")
    k, nw = form.n_path_constraints, form.n_w  # path constraints come first in g and x
    lbg, ubg = [form.lbg[:k]], [form.ubg[:k]]
    part = mission_part(form.problem, grid, ca.MX.sym("W", 3 * grid.n, grid.N))
    for c in part.constraints if part is not None else ():
        lbg.append(c.lb)
        ubg.append(c.ub)
    sol, stats, err = _call(
        projection,
        x0=wbar,
        p=wbar,
        lbx=form.lbx[:nw],
        ubx=form.ubx[:nw],
        lbg=np.concatenate(lbg),
        ubg=np.concatenate(ubg),
    )
    status = err or str(stats.get("return_status", "unknown"))
    if sol is None:
        return None, status
    w = np.asarray(sol["x"]).reshape(-1)
    W = w.reshape(3 * grid.n, grid.N, order="F")
    # exact re-integration of the projected inputs: the returned samples are consistent
    raw = grid.to_trajectory(W)
    return Trajectory.from_inputs(raw.t, raw.p[0], raw.v[0], raw.u[:-1]), status
