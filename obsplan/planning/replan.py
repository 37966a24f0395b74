"""Receding-horizon replanning inside the closed-loop Monte Carlo.

Every ``every`` seconds each run of the closed loop stops, and the planner re-solves from that
run's estimate (of its navigation filter, ``validation.navigation``) over the remaining horizon;
the vehicle then steers its estimate onto the new plan (the guidance law of
:mod:`obsplan.estimation.montecarlo.guidance`) until the next replan.

Shrinking horizon on the planning grid
--------------------------------------
The NLP is built once (:func:`~obsplan.planning.solver.formulation.build_formulation`, the one-shot
plan's own formulation and objective) and its IPOPT solver once; a re-solve at node ``k`` only
changes bounds and the initial point:

* the columns of ``W`` before ``k`` (inputs ``U_0..U_{k-1}``, nodes ``1..k``) are fixed by
  ``lbx = ubx``: the past of the plan in force, with node ``k`` set to the run's estimate of
  position and velocity. IPOPT removes fixed variables, so only the remaining horizon is solved;
* the path constraints that involve only fixed variables (the dynamics steps before ``k``, the
  speed and range limits at nodes ``1..k`` and midpoints before ``k``) are relaxed to
  ``(-inf, inf)``: the estimate need not be where the plan was, and the past is not re-decided;
* the initial point is *flying on*: from the estimate back onto the plan in force over the
  recovery window below (the plan's inputs plus the least-energy correction that joins it,
  :func:`return_inputs`), the plan in force after it (IPOPT's warm-start options,
  :func:`~obsplan.planning.solver.ipopt.warm_start_options`). Re-integrating the plan's inputs from
  the estimate instead carries the estimate's velocity offset to the end of the mission (a 1 cm/s
  offset is 5 m after 500 s): on the median suite problem those drifted paths, kept or refined, lost
  to the one-shot plan (EKF final error 1.13x, 200 runs); joined back, replanning ties it (1.00x;
  ``benchmarks/bench_replan.py``, docs/replanning.md);
* a run whose estimate is already too close to the beacon (or too fast) cannot meet the limits
  at once: over a *recovery window* of :func:`recovery_steps` steps after ``k`` (the time to
  shed the full speed at the smallest acceleration bound) the inequality limits are loosened to
  what the initial point reaches, so each is no worse than flying on; after the window every
  limit holds as planned, and the returned path is checked there (independently, on the
  continuous path, from the node after the window).

The objective is the one-shot plan's, over the whole horizon: for the covariance objectives the
information gathered before ``k`` is the planner's prediction along the past of the plan in force
(from the problem's prior), not the EKF's covariance, which the NLP does not take as an input.
A re-solve that fails (no path, or a path that breaks a limit on the remaining horizon) leaves
the plan in force unchanged; failures are counted.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np
from tqdm import tqdm

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.estimation.montecarlo.guidance import Guidance
from obsplan.estimation.montecarlo.results import MonteCarloResult, merge_monte_carlo
from obsplan.estimation.montecarlo.simulate import DEFAULT_FILTERS
from obsplan.planning.objectives.evaluate import better, objective_value
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.feasibility import check_limits
from obsplan.planning.problem.validation_setup import (
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.planning.solver.formulation import Formulation, build_formulation
from obsplan.planning.solver.ipopt import SUCCESS_STATUS, _call, make_solver
from obsplan.planning.solver.margins import keepout_margins, tighten
from obsplan.planning.solver.starts import default_processes, run_forked
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.validate import PathValidation, validate_paths
from obsplan.planning.validation.verdict import Verdict, verdict
from obsplan.trajectory.sampled import Trajectory, resample

#: IPOPT statuses whose path is flown when it is within the limits: a converged solve, or one
#: stopped by the iteration budget (its iterate is checked like any path, and never flown when
#: flying on is better).
FLOWN_STATUSES = (SUCCESS_STATUS, "Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded")
#: What a re-solve starts from: the navigation filter's estimate, or (a research bound, no
#: vehicle has it) the true state.
REPLAN_FROM = ("estimate", "truth")
#: Relative tolerance for ``every`` to be a multiple of the planning step.
_STEP_RTOL = 1e-9
#: Path-constraint blocks whose rows belong to nodes (and midpoints) of the grid.
_PER_NODE = {"dynamics", "speed", "min_range", "max_range", "min_speed"}


def replan_guidance(pb: PlanningProblem) -> Guidance:
    """The closed-loop validation's guidance law (replanning runs only in closed loop).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its limits and ``[validation]`` (mode, navigation filter, prior).

    Returns
    -------
    Guidance
        :func:`~obsplan.planning.problem.validation_setup.validation_guidance` of ``pb``.

    Raises
    ------
    ConfigError
        For ``validation.mode = "open-loop"``.
    """
    g = validation_guidance(pb)
    if g is None:
        raise ConfigError(
            "--replan re-solves from the estimate the vehicle steers on: it needs "
            'validation.mode = "closed-loop" (the default), not "open-loop"'
        )
    return g


def steps_of(every: Any, h: float, step_name: str) -> tuple[float, int]:
    """A replanning period as a whole number of planning steps, or one error naming ``--replan``.

    Parameters
    ----------
    every : Any
        The period [s] as given.
    h : float
        The planning step [s].
    step_name : str
        The step's name in the message (``"... step ="``).

    Returns
    -------
    every : float
        The period [s].
    k : int
        Planning steps per period (>= 1).

    Raises
    ------
    ConfigError
        When ``every`` is not a positive multiple of ``h`` (to :data:`_STEP_RTOL`).
    """
    try:
        e = float(every)
    except (TypeError, ValueError):
        e = math.nan
    steps = e / h
    k = round(steps) if math.isfinite(steps) else 0
    if not (math.isfinite(e) and e > 0 and k >= 1 and abs(steps - k) <= _STEP_RTOL * max(1, k)):
        raise ConfigError(
            f"--replan EVERY = {every!r} s must be a positive multiple of {step_name} {h:g} s "
            f"(e.g. {h * max(1, round(60 / h)):g})"
        )
    return e, k


def replan_nodes(pb: PlanningProblem, every: float) -> np.ndarray:
    """Planning nodes ``k`` at which the runs re-solve: every ``every`` s, before the end.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its planning step ``horizon.dt`` [s] and ``horizon.steps``.
    every : float
        Replanning period [s] (``--replan EVERY``).

    Returns
    -------
    ndarray of int, shape (R,)
        ``k, 2k, ...`` below ``horizon.steps``, with ``k = every / horizon.dt``.

    Raises
    ------
    ConfigError
        When ``every`` is not a positive multiple of the planning step ``horizon.dt`` shorter
        than the horizon (the message names ``--replan`` and the fix).
    """
    h, T = pb.horizon.dt, pb.horizon.duration
    e, k = steps_of(every, h, "the planning step horizon.duration / horizon.steps =")
    if e >= T:
        raise ConfigError(
            f"--replan EVERY = {e:g} s must be shorter than the horizon ({T:g} s) to replan at all"
        )
    return np.arange(k, pb.horizon.steps, k, dtype=int)


@dataclass(frozen=True)
class ReplanSolve:
    """One re-solve of one run.

    Attributes
    ----------
    t : float
        Time of the replan [s].
    run : int
        Run index.
    status : str
        IPOPT's ``return_status`` (or ``"exception: ..."``, or ``"limits"`` when the returned
        path breaks a limit on the remaining horizon).
    success : bool
        A new plan is flown: IPOPT ended with one of :data:`FLOWN_STATUSES` and the remaining
        path is within the limits (``status`` says whether it converged).
    iterations : int
    wall_s : float
        Time of the IPOPT call [s].
    cpu_s : float
        CPU time of this process during the call [s] (what the solve costs on an idle core).
    objective : float or None
        The objective of the new plan over the whole horizon (past included), numpy-evaluated.
    kept_warm_start : bool
        The warm start (flying on: from the estimate back onto the plan in force,
        :meth:`Replanner.warm_guess`) was strictly better than IPOPT's path and is flown
        instead.
    """

    t: float
    run: int
    status: str
    success: bool
    iterations: int
    wall_s: float
    cpu_s: float
    objective: float | None
    kept_warm_start: bool = False

    def to_dict(self) -> dict:
        """The re-solve's entry in the ``replan`` of ``report.json``.

        Returns
        -------
        dict
            Every field as JSON values (``objective`` None when missing or not finite).
        """
        obj = self.objective
        return {
            "t": float(self.t),
            "run": int(self.run),
            "status": self.status,
            "success": bool(self.success),
            "iterations": int(self.iterations),
            "wall_s": float(self.wall_s),
            "cpu_s": float(self.cpu_s),
            "objective": None if obj is None or not math.isfinite(obj) else float(obj),
            "kept_warm_start": bool(self.kept_warm_start),
        }


def recovery_steps(pb: PlanningProblem) -> int:
    """Steps after a replan node over which violated inequality limits are loosened (module
    docstring): ``ceil(v_max / min(a) / h)``, at least 1.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``limits.speed`` [m/s], the acceleration bounds [m/s²] and the planning
        step ``h`` [s].

    Returns
    -------
    int
        Number of planning steps of the recovery window.
    """
    shed = float(pb.limits.speed) / float(np.min(pb.accel))
    return max(1, math.ceil(shed / pb.horizon.dt - 1e-9))


def return_inputs(
    F: np.ndarray, G: np.ndarray, error: np.ndarray, steps: int, horizon: int
) -> np.ndarray:
    """Input corrections [m/s²] that bring the vehicle ``error`` = ``(dp, dv)`` [m, m/s] off its
    plan back onto it in ``steps`` steps (at least 2, at most ``horizon``) of the exact
    zero-order hold ``e' = F e + G c`` (:meth:`~obsplan.model.vehicle.VehicleModel.transition`, its
    ``(p, v)`` block): the least-energy sequence, zero after; shape ``(horizon, n)``.

    Parameters
    ----------
    F : ndarray, shape (2n, 2n)
        State transition of one planning step on ``(p, v)``.
    G : ndarray, shape (2n, n)
        Input matrix of one planning step (zero-order hold).
    error : ndarray, shape (2n,)
        The state minus the plan's at the replan node, ``(dp [m], dv [m/s])``.
    steps : int
        Steps to join the plan in (clipped to ``2 .. horizon``).
    horizon : int
        Steps left to the end of the horizon.

    Returns
    -------
    ndarray, shape (horizon, n)
        The corrections [m/s²], added to the plan's inputs; zero after ``steps``.
    """
    n = G.shape[1]
    m = max(1, min(max(2, int(steps)), int(horizon)))
    # e_m = F^m e_0 + sum_i F^(m-1-i) G c_i
    C = np.hstack([np.linalg.matrix_power(F, m - 1 - i) @ G for i in range(m)])
    c = -np.linalg.pinv(C) @ (np.linalg.matrix_power(F, m) @ np.asarray(error, float))
    out = np.zeros((int(horizon), n))
    out[:m] = c.reshape(m, n)
    return out


class Replanner:
    """The shrinking-horizon NLP of a problem, built once, re-solved from any node and state
    (module docstring).

    Parameters
    ----------
    pb
        The problem (its formulation and objective are the one-shot plan's).
    plan
        The one-shot plan: with ``limits.keepout_confidence > 0`` the re-solves keep the
        keep-out margins computed along it (:mod:`obsplan.planning.solver.margins`).
    expand
        Expand the NLP to SX (faster iterations, slower construction).
    ipopt_options
        Extra IPOPT options (after the warm-start ones, the tolerance
        ``Tuning.replan_tol_factor`` ``* objective.solver_tol`` and
        ``Tuning.replan_max_iter``).
    """

    def __init__(
        self,
        pb: PlanningProblem,
        *,
        plan: Trajectory | None = None,
        expand: bool = True,
        ipopt_options: dict | None = None,
    ) -> None:
        t0 = time.perf_counter()
        self.problem = pb
        self.form: Formulation = build_formulation(pb)
        if plan is not None and pb.limits.keepout_confidence > 0:
            # the one-shot plan's keep-out margins (bounds only: the same compiled NLP)
            self.form = tighten(self.form, keepout_margins(plan, pb, replan_guidance(pb)))
        opts = {
            "tol": tuning().replan_tol_factor * pb.objective.solver_tol,
            "max_iter": tuning().replan_max_iter,
            **(ipopt_options or {}),
        }
        self.solver: ca.Function = make_solver(
            self.form, expand=expand, ipopt_options=opts, warm=True
        )
        self._rows = _node_rows(self.form)
        self._equal = np.concatenate(
            [np.full(c.size, c.name == "dynamics") for c in self.form.constraints]
        )
        self._g = ca.Function("obsplan_replan_g", [self.form.w], [self.form.g])
        self.recovery = recovery_steps(pb)
        F, G = pb.model.transition(self.form.grid.h)  # the (p, v) block: the plan's state
        self._zoh = (F[: 2 * pb.dim, : 2 * pb.dim], G[: 2 * pb.dim])
        self.build_s = time.perf_counter() - t0

    def warm_guess(self, plan: Trajectory, k: int, state: np.ndarray) -> Trajectory:
        """Flying on from ``state`` = ``(p, v)`` [m, m/s] at node ``k``: the plan in force's
        inputs plus :func:`return_inputs`, which join it within the recovery window
        (:func:`recovery_steps`, at least 2 steps), then the plan in force to the end (the
        initial point of a re-solve, and what is flown when no re-solve beats it).

        Parameters
        ----------
        plan : Trajectory
            The plan in force, on the planning grid (``N + 1`` samples).
        k : int
            The replan node.
        state : ndarray, shape (2n,)
            Position [m] and inertial velocity [m/s] at node ``k`` (:func:`state_for_planner`).

        Returns
        -------
        Trajectory
            On the planning grid: ``plan`` before node ``k``, then flown on from ``state``.

        Raises
        ------
        ConfigError
            When ``state`` has fewer than ``2n`` values or ``plan`` is not on the planning grid.
        """
        n = self.problem.dim
        x = np.asarray(state, float).reshape(-1)
        if x.size < 2 * n or plan.n_samples != self.form.grid.N + 1:
            raise ConfigError(
                f"replan: the state must hold (p, v) ({2 * n} values) and the plan "
                f"{self.form.grid.N + 1} samples on the planning grid"
            )
        error = x[: 2 * n] - np.concatenate([plan.p[k], plan.v[k]])
        u = plan.u[k:-1] + return_inputs(*self._zoh, error, self.recovery, len(plan.t) - 1 - k)
        future = Trajectory.from_inputs(plan.t[k:], x[:n], x[n : 2 * n], u)
        return Trajectory(
            t=plan.t.copy(),
            p=np.vstack([plan.p[:k], future.p]),
            v=np.vstack([plan.v[:k], future.v]),
            u=np.vstack([plan.u[:k], future.u]),
        )

    def bounds(self, guess: Trajectory, k: int) -> tuple[np.ndarray, ...]:
        """``(x0, lbx, ubx, lbg, ubg)`` of the re-solve at node ``k`` from the warm ``guess``
        (module docstring).

        Parameters
        ----------
        guess : Trajectory
            The warm start on the planning grid (:meth:`warm_guess`).
        k : int
            The replan node: the columns of ``W`` before it are fixed.

        Returns
        -------
        tuple of ndarray
            ``x0`` (the initial point, clipped to the bounds), ``lbx``, ``ubx`` (the past fixed)
            and ``lbg``, ``ubg`` (past rows free, rows in the recovery window loosened to what
            ``x0`` reaches), in the NLP's variable and constraint order.
        """
        form = self.form
        grid = form.grid
        lbx, ubx = form.lbx.copy(), form.ubx.copy()
        fixed = grid.from_trajectory(guess)[:, :k].reshape(-1, order="F")
        lbx[: fixed.size] = fixed
        ubx[: fixed.size] = fixed
        x0 = np.clip(form.pack(guess), lbx, ubx)
        lbg, ubg = form.lbg.copy(), form.ubg.copy()
        past = self._rows <= k
        lbg[past] = -np.inf
        ubg[past] = np.inf
        window = (self._rows > k) & (self._rows <= k + self.recovery) & ~self._equal
        g0 = np.asarray(self._g(x0)).reshape(-1)[window]
        lbg[window] = np.minimum(lbg[window], g0)
        ubg[window] = np.maximum(ubg[window], g0)
        return x0, lbx, ubx, lbg, ubg

    def resolve(
        self, plan: Trajectory, k: int, state: np.ndarray, run: int = 0
    ) -> tuple[ReplanSolve, Trajectory | None]:
        """Re-solve from node ``k`` (``1 <= k < N``) at ``state`` = ``(p, v)``, warm-started
        from ``plan`` (on the planning grid).

        Parameters
        ----------
        plan : Trajectory
            The plan in force, on the planning grid.
        k : int
            The replan node, ``1 <= k < N``.
        state : ndarray, shape (2n,)
            Position [m] and inertial velocity [m/s] at node ``k``.
        run : int, optional
            The Monte Carlo run's index (recorded in the outcome).

        Returns
        -------
        (ReplanSolve, Trajectory or None)
            The outcome and the new plan on the whole planning grid (its samples before ``k``
            are the old plan's, node ``k`` is ``state``), or None when the re-solve failed.

        Raises
        ------
        ConfigError
            When ``k`` is outside ``1 .. N - 1`` (or ``state``, ``plan`` are malformed).
        """
        pb, form = self.problem, self.form
        if not 1 <= int(k) < form.grid.N:
            raise ConfigError(f"replan node k = {k} must be in 1 .. {form.grid.N - 1}")
        k = int(k)
        guess = self.warm_guess(plan, k, state)
        x0, lbx, ubx, lbg, ubg = self.bounds(guess, k)
        t0, c0 = time.perf_counter(), time.process_time()
        sol, stats, err = _call(
            self.solver, x0=x0, p=form.parameter_values, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg
        )
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        status = err or str(stats.get("return_status", "unknown"))
        iters = int(stats.get("iter_count", 0))
        t_k = float(plan.t[k])
        if sol is None or not np.all(np.isfinite(np.asarray(sol["x"]))):
            return ReplanSolve(t_k, run, status, False, iters, wall, cpu, None), None
        traj, _ = form.unpack(np.asarray(sol["x"]).reshape(-1))
        if not self._flyable(traj, k):
            return ReplanSolve(t_k, run, "limits", False, iters, wall, cpu, None), None
        if status not in FLOWN_STATUSES:
            return ReplanSolve(t_k, run, status, False, iters, wall, cpu, None), None
        obj = objective_value(traj, pb)
        # never worse than flying on: the warm start, when flyable and strictly better, is kept
        if self._flyable(guess, k) and better(g_obj := objective_value(guess, pb), obj, pb):
            return ReplanSolve(t_k, run, status, True, iters, wall, cpu, g_obj, True), guess
        return ReplanSolve(t_k, run, status, True, iters, wall, cpu, obj), traj

    def _flyable(self, traj: Trajectory, k: int) -> bool:
        """Every limit holds after the recovery window: from node ``k + recovery + 1`` on (the
        NLP enforces them from the window's last step on)."""
        after = min(k + self.recovery + 1, self.form.grid.N - 1)
        return replace(check_limits(traj.window(after), self.problem), start=0.0).ok()


def _node_rows(form: Formulation) -> np.ndarray:
    """For every row of ``g``: how many leading columns of ``W`` it involves among the path
    constraints (``j + 1`` for the dynamics step ``j``, node ``j + 1`` and the midpoint of step
    ``j``), so that ``rows <= k`` are the rows on fixed variables only at node ``k``; objective
    and part rows get ``N + 1`` (never relaxed)."""
    N = form.grid.N
    nodes = np.arange(1, N + 1)  # node k+1 is column k of W
    out: list[np.ndarray] = []
    for block in form.constraints:
        size = block.size
        if block.name == "dynamics":  # step k: nodes k, k+1 -> free once k + 1 > k_fixed
            out.append(np.repeat(nodes, size // N))
        elif block.name in _PER_NODE:
            if size == N:
                out.append(nodes.copy())
            else:  # nodes 1..N, then midpoints of the steps 0..N-1 (they need U_k: step k+1)
                out.append(np.concatenate([nodes, nodes]))
        else:
            out.append(np.full(size, N + 1))
    rows = np.concatenate(out) if out else np.zeros(0, int)
    if rows.size != form.lbg.size:
        raise ConfigError("replan: the constraint blocks do not cover g (unknown layout)")
    return rows


def state_for_planner(pb: PlanningProblem, estimate: np.ndarray) -> np.ndarray:
    """``(p, p')`` [m, m/s] from the EKF's ``(p, v[, v_f])``: the planner's velocity is the
    inertial one, ``p' = v + v_f`` with a current.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its dimension ``n`` and whether the state holds a current.
    estimate : ndarray, shape (2n,) or (3n,)
        The filter's state: position [m], velocity through the water [m/s] and, with a current,
        the current ``v_f`` [m/s].

    Returns
    -------
    ndarray, shape (2n,)
        Position [m] and inertial velocity [m/s].
    """
    n = pb.dim
    x = np.asarray(estimate, float).reshape(-1)
    v = x[n : 2 * n] + (x[2 * n : 3 * n] if pb.vehicle.current else 0.0)
    return np.concatenate([x[:n], v])


@dataclass(frozen=True, eq=False)
class ReplanResult:
    """The replanned closed-loop Monte Carlo beside the one-shot plan and the baselines.

    Attributes
    ----------
    every : float
        Replanning period [s].
    times : tuple of float
        Replan times [s].
    solves : tuple of ReplanSolve
        Every re-solve of every run, in run then time order.
    validation : dict[str, PathValidation]
        ``"replanned"``, ``"one-shot"`` and every baseline, all in closed loop with the same
        guidance, runs and seed (paired). The bound reported with ``"replanned"`` is the one
        along the one-shot plan (each run flies its own replanned path).
    build_s : float
        Construction of the NLP and its solver [s] (once).
    wall_s : float
        The whole replanned Monte Carlo [s].
    """

    every: float
    times: tuple[float, ...]
    solves: tuple[ReplanSolve, ...]
    validation: dict[str, PathValidation]
    build_s: float
    wall_s: float

    @property
    def verdict(self) -> Verdict:
        """The replanned plan (as ``planned``) against the one-shot plan and every baseline, on
        the filters' errors: the bound rows are left out, since each replanned run flies its
        own path and the bound is computed along the one-shot plan only."""
        v = dict(self.validation)
        full = verdict({"planned": v.pop("replanned"), **v}, {})
        comps = {
            name: {k: c for k, c in cs.items() if not k.startswith("crlb.")}
            for name, cs in full.comparisons.items()
        }
        return Verdict(comps, {}, full.runs, full.notes)

    @property
    def unconverged_flown(self) -> int:
        """Re-solves stopped short of convergence (e.g. by ``replan_max_iter``) whose
        checked path was flown."""
        return sum(s.success and s.status != SUCCESS_STATUS for s in self.solves)

    @property
    def failures(self) -> int:
        """Re-solves whose new plan was not flown (the plan in force was kept)."""
        return sum(not s.success for s in self.solves)

    def solve_times(self, cpu: bool = False) -> np.ndarray:
        """Wall (or CPU) time of every re-solve [s].

        Parameters
        ----------
        cpu : bool, optional
            CPU time of the solving process instead of wall time.

        Returns
        -------
        ndarray, shape (S,)
            One time [s] per re-solve, in :attr:`solves` order.
        """
        return np.array([s.cpu_s if cpu else s.wall_s for s in self.solves], float)

    def to_dict(self) -> dict:
        """The ``replan`` entry of report.json.

        Returns
        -------
        dict
            The period and times [s], counts of solves, failures and statuses, solve times
            (median and max, wall and CPU [s]), build and total times [s], every path's
            validation and the verdict.
        """
        w, c = self.solve_times(), self.solve_times(cpu=True)
        statuses: dict[str, int] = {}
        for s in self.solves:
            statuses[s.status] = statuses.get(s.status, 0) + 1
        return {
            "every_s": float(self.every),
            "times_s": [float(t) for t in self.times],
            "solves": len(self.solves),
            "failures": int(self.failures),
            "kept_warm_start": sum(s.kept_warm_start for s in self.solves),
            "unconverged_flown": int(self.unconverged_flown),
            "statuses": statuses,
            "solve_s": {
                "median": float(np.median(w)) if w.size else None,
                "max": float(np.max(w)) if w.size else None,
            },
            "solve_cpu_s": {
                "median": float(np.median(c)) if c.size else None,
                "max": float(np.max(c)) if c.size else None,
            },
            "build_s": float(self.build_s),
            "wall_s": float(self.wall_s),
            "validation": {k: v.to_dict() for k, v in self.validation.items()},
            "verdict": self.verdict.to_dict(),
        }

    def summary(self) -> list[str]:
        """Lines for the terminal: the solve times, failures and the verdict's words.

        Returns
        -------
        list of str
            A head line, one line each for ``"replanned"`` and ``"one-shot"`` (EKF and KF
            errors [m]), then the verdict's lines.
        """
        w = self.solve_times()
        med = f"{np.median(w):.2f}" if w.size else "-"
        mx = f"{np.max(w):.2f}" if w.size else "-"
        head = (
            f"replanning every {self.every:g} s: {len(self.solves)} re-solves, "
            f"{self.failures} failed (plan in force kept), {self.unconverged_flown} flown "
            f"unconverged, solve time median {med} s, max {mx} s"
        )
        lines = [head]
        for name in ("replanned", "one-shot"):
            r = self.validation[name].result
            ekf, kf = r.ekf, r.kf
            lines.append(
                f"  {name:<10} EKF rmse {_f(ekf.rmse_pos if ekf else None)} m, "
                f"EKF final {_f(ekf.final_pos_err if ekf else None)} m, "
                f"KF rmse {_f(kf.rmse_pos if kf else None)} m"
            )
        lines += [f"  replanned: {line}" for line in self.verdict.summary()]
        return lines


def _f(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.4g}"


# ----------------------------------------------------------------------------- Monte Carlo


def _fly_batch(
    rp: Replanner, job: dict, run_start: int, runs: int
) -> tuple[MonteCarloResult, list[ReplanSolve]]:
    """Runs ``run_start .. run_start + runs - 1`` in closed loop, re-solving at every node."""
    pb = rp.problem
    dt = pb.validation.dt
    loop = ClosedLoop(
        job["fine"],
        job["config"],
        runs,
        job["seed"],
        run_start,
        guidance=job["guidance"],
        limits=job["limits"],
        filters=job["filters"],
    )
    plans = [job["plan"]] * runs
    refs = None
    solves: list[ReplanSolve] = []
    h = pb.horizon.dt
    for k in job["nodes"]:
        loop.advance(float(k) * h, references=refs)
        snap = loop.snapshot()
        refs = []
        known = snap.truth if job["replan_from"] == "truth" else snap.estimate
        for j in range(runs):
            state = state_for_planner(pb, known[j])
            out, new = rp.resolve(plans[j], int(k), state, run=int(snap.runs[j]))
            solves.append(out)
            if new is not None:
                plans[j] = new
            refs.append(resample(plans[j].window(int(k)), dt))
    loop.advance(float(pb.horizon.duration), references=refs)
    return loop.result(job["crlb"]), solves


def _batch(state: tuple[Replanner, dict], batch: tuple[int, int]):
    return _fly_batch(*state, *batch)


def _fly_all(rp: Replanner, job: dict, batches: list[tuple[int, int]], processes: int, bar):
    """Every batch, serially or in ``fork``-ed processes (same results: runs are independent
    and the solver is deterministic on one machine)."""

    def done(i: int, _) -> None:
        if bar is not None:
            bar(batches[i][1])

    return run_forked(_batch, (rp, job), batches, processes, done)


def replan_monte_carlo(
    pb: PlanningProblem,
    plan: Trajectory,
    every: float,
    *,
    baselines: Mapping[str, Trajectory] | None = None,
    runs: int | None = None,
    processes: int | None = 1,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    replanner: Replanner | None = None,
    replan_from: str = "estimate",
) -> ReplanResult:
    """Closed-loop Monte Carlo with receding-horizon replanning every ``every`` s.

    Every run flies ``plan`` in closed loop (:func:`replan_guidance`); at each replan time it
    re-solves from its estimate over the remaining horizon (:class:`Replanner`) and flies
    the new plan from there. The one-shot plan and every baseline are flown in closed loop with
    the same guidance, runs and seed, so all comparisons are paired.

    Parameters
    ----------
    pb
        The problem (``validation`` settings: runs, seed, filter step, noises).
    plan
        The one-shot plan on the planning grid, ``(N + 1)`` samples.
    every
        Replanning period [s], a multiple of the planning step (:func:`replan_nodes`).
    baselines
        Name -> baseline path, validated alongside (default none).
    runs
        Override ``validation.runs``.
    processes
        Worker processes over batches of ``Tuning.replan_batch`` runs (``fork``; 1:
        serial; None: one per core).
    progress
        A tqdm bar over runs (stderr).
    filters
        Filters reported (the EKF navigates in any case).
    replanner
        A :class:`Replanner` of ``pb`` already built (e.g. by a benchmark).
    replan_from
        ``"estimate"`` (what a vehicle can do: its navigation filter's estimate) or
        ``"truth"``: a clairvoyant replanner that re-solves from the true state, which no
        vehicle has. A research bound: what re-solving could buy at best from knowing where the
        vehicle is (the vehicle still steers its estimate onto the new plan).

    Returns
    -------
    ReplanResult
    """
    t0 = time.perf_counter()
    if replan_from not in REPLAN_FROM:
        raise ConfigError(
            f"replan_from must be one of {', '.join(map(repr, REPLAN_FROM))}, got {replan_from!r}"
        )
    nodes = replan_nodes(pb, every)
    val = pb.validation
    n_runs = val.runs if runs is None else int(runs)
    if n_runs < 1:
        raise ConfigError(f"runs must be at least 1, got {n_runs}")
    if plan.n_samples != pb.horizon.steps + 1:
        raise ConfigError(
            f"plan has {plan.n_samples} samples; the planning grid has {pb.horizon.steps + 1}"
        )
    replan_guidance(pb)  # closed loop only, before any work
    rp = replanner if replanner is not None else Replanner(pb, plan=plan)
    config = estimation_config(pb)
    fine = resample(plan, val.dt)
    job: dict[str, Any] = {
        "plan": plan,
        "fine": fine,
        "config": config,
        "seed": val.seed,
        "guidance": replan_guidance(pb),
        "limits": truth_limits(pb),
        "filters": tuple(filters),
        "nodes": nodes,
        "crlb": posterior_crlb(fine, config),
        "replan_from": replan_from,
    }
    batch = tuning().replan_batch
    batches = [(c, min(batch, n_runs - c)) for c in range(0, n_runs, batch)]
    nproc = default_processes(len(batches)) if processes is None else max(1, int(processes))
    with tqdm(total=n_runs, disable=not progress, unit="run", desc="replanned runs") as bar:
        parts = _fly_all(rp, job, batches, nproc, bar.update if progress else None)
    solves = tuple(s for _, ss in parts for s in ss)
    replanned = merge_monte_carlo([p for p, _ in parts])
    others = {"one-shot": plan, **dict(baselines or {})}
    validation = {"replanned": PathValidation("replanned", replanned)}
    validation.update(validate_paths(others, pb, runs=n_runs, filters=filters))
    return ReplanResult(
        every=float(every),
        times=tuple(float(k) * pb.horizon.dt for k in nodes),
        solves=solves,
        validation=validation,
        build_s=rp.build_s,
        wall_s=time.perf_counter() - t0,
    )
