"""The starts of a multi-start solve: one IPOPT run per initial guess, serially or in processes.

Each start is an independent call of the same solver, so a parallel run gives the results of a
serial one. Starts run in worker processes (``fork``; the solver is built once in the parent and
inherited); Ctrl-C stops every start at once and raises ``KeyboardInterrupt``. A start whose
path violates a limit is first projected onto the limits (:func:`~obsplan.planning.solver.ipopt
.project`); its objective is recomputed numerically on the returned path
(:func:`~obsplan.planning.objectives.evaluate.objective_value`), never read from lifting variables.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from tqdm import tqdm

from obsplan.core import interrupts
from obsplan.planning.missions.check import completes_mission
from obsplan.planning.objectives.evaluate import objective_value
from obsplan.planning.problem.feasibility import LimitCheck, check_limits
from obsplan.planning.solver.formulation import Formulation
from obsplan.planning.solver.ipopt import (
    SUCCESS_STATUS,
    _call,
    ipopt_settings,
    make_projection,
    make_solver,
    project,
    stop_reason,
)
from obsplan.trajectory.sampled import Trajectory

#: A progress callback: ``(index, label, outcome)`` after each start.
Progress = Callable[[int, str, "StartOutcome"], None]


_INF_CHECK = LimitCheck(*(math.inf,) * 8)


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class StartOutcome:
    """One IPOPT run from one initial guess.

    Attributes
    ----------
    label : str
        ``"lawnmower"``, ``"circle"`` or ``"random-<i>"``.
    success : bool
        ``return_status == "Solve_Succeeded"``.
    status : str
        IPOPT's ``return_status`` (or ``"exception: ..."``).
    iterations : int
    wall_s : float
        Solve time [s] (projection included).
    objective : float or None
        The objective recomputed numerically on the returned (projected) path.
    lifted : float or None
        The solver's own objective (e.g. the epigraph variable ``t``).
    initial_objective : float or None
        The objective of the initial guess.
    limits : LimitCheck
        Independent check of the returned path (after projection, if any).
    projected : bool
        Whether the path was projected onto the limits.
    """

    label: str
    success: bool
    status: str
    iterations: int
    wall_s: float
    objective: float | None
    lifted: float | None
    initial_objective: float | None
    limits: LimitCheck
    projected: bool = False
    #: The path completes the problem's mission (True without one):
    #: :func:`~obsplan.planning.missions.check.mission_check`.
    mission_complete: bool = True
    #: Why a start that did not converge stopped, in words (""  when it converged):
    #: :func:`~obsplan.planning.solver.ipopt.stop_reason`.
    note: str = ""

    @property
    def feasible(self) -> bool:
        return self.limits.ok() and self.mission_complete

    def to_dict(self) -> dict:
        return {
            "label": self.label,
            "success": bool(self.success),
            "status": self.status,
            "iterations": int(self.iterations),
            "wall_s": float(self.wall_s),
            "objective": _num(self.objective),
            "lifted_objective": _num(self.lifted),
            "initial_objective": _num(self.initial_objective),
            "feasible": bool(self.feasible),
            "projected": bool(self.projected),
            "mission_complete": bool(self.mission_complete),
            "note": self.note,
        }


@dataclass
class StartContext:
    """What every start needs: the formulation, its solver and the (lazily built) projection."""

    form: Formulation
    solver: ca.Function
    projection: Callable[[], ca.Function]
    #: The solver's ``tol`` and ``constr_viol_tol`` (what a stopped start is measured against).
    tol: float = 0.0
    constr_viol_tol: float = 0.0


def start_context(
    form: Formulation,
    *,
    verbose: bool = False,
    expand: bool = True,
    ipopt_options: dict | None = None,
    warm: bool = False,
) -> StartContext:
    """The solver of ``form`` (:func:`~obsplan.planning.solver.ipopt.make_solver`) and a projection
    built on first use (most starts end within the limits and never need it)."""
    solver = make_solver(
        form, verbose=verbose, expand=expand, ipopt_options=ipopt_options, warm=warm
    )
    cache: list[ca.Function] = []

    def projection() -> ca.Function:
        if not cache:
            cache.append(make_projection(form.problem, form))
        return cache[0]

    settings = ipopt_settings(form, ipopt_options=ipopt_options, warm=warm)
    return StartContext(
        form,
        solver,
        projection,
        float(settings["tol"]),
        float(settings["constr_viol_tol"]),
    )


def run_start(
    ctx: StartContext, label: str, guess: Trajectory
) -> tuple[StartOutcome, Trajectory | None]:
    """IPOPT from one guess; its path (projected onto the limits if needed) or None."""
    form = ctx.form
    pb = form.problem
    x0 = form.pack(guess)
    init_obj = objective_value(guess, pb)
    t0 = time.perf_counter()
    sol, stats, err = _call(
        ctx.solver,
        x0=x0,
        p=form.parameter_values,
        lbx=form.lbx,
        ubx=form.ubx,
        lbg=form.lbg,
        ubg=form.ubg,
    )
    status = err or str(stats.get("return_status", "unknown"))
    iters = int(stats.get("iter_count", 0))
    note = err or stop_reason(stats, ctx.tol, ctx.constr_viol_tol)
    if sol is None or not np.all(np.isfinite(np.asarray(sol["x"]))):
        wall = time.perf_counter() - t0
        return StartOutcome(
            label,
            False,
            status,
            iters,
            wall,
            None,
            None,
            _num(init_obj),
            _INF_CHECK,
            note=note or "the solver returned no finite point",
        ), None
    x = np.asarray(sol["x"]).reshape(-1)
    traj, _ = form.unpack(x)
    lifted = form.lifted_value(float(sol["f"]), x)
    limits = check_limits(traj, pb)
    projected = False
    if not (limits.ok() and completes_mission(traj, pb.mission_context)):
        proj, _ = project(form, ctx.projection(), traj)
        projected = True
        if proj is not None:
            traj = proj
            limits = check_limits(traj, pb)
    wall = time.perf_counter() - t0
    outcome = StartOutcome(
        label=label,
        success=status == SUCCESS_STATUS,
        status=status,
        iterations=iters,
        wall_s=wall,
        objective=objective_value(traj, pb),
        lifted=lifted,
        initial_objective=_num(init_obj),
        limits=limits,
        projected=projected,
        mission_complete=completes_mission(traj, pb.mission_context),
        note=note,
    )
    return outcome, traj


# ----------------------------------------------------------------------------- processes
#: ``(fn, state)`` of :func:`run_forked`: set in the parent before fork, read by the children
#: (inherited, never pickled: a built solver does not pickle).
_WORKER: tuple[Callable[[Any, Any], Any], Any] | None = None


def _worker_init() -> None:
    interrupts.child_init()  # the parent stops everyone on Ctrl-C; a child dies with its parent
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def _worker_call(item: Any) -> Any:
    assert _WORKER is not None
    fn, state = _WORKER
    return fn(state, item)


def default_processes(n_starts: int) -> int:
    """Worker processes for ``n_starts`` starts: one per available core, at most one per start."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_starts))


def run_forked(
    fn: Callable[[Any, Any], Any],
    state: Any,
    items: Sequence[Any],
    processes: int,
    on_result: Callable[[int, Any], None] | None = None,
) -> list:
    """``[fn(state, item) for item in items]``, in up to ``processes`` ``fork``-ed workers.

    ``state`` (e.g. a built solver) reaches the workers by the fork, not by pickling; the items
    and the results are pickled. Serial when ``processes <= 1``, with one item, or where
    ``fork`` is not available. ``on_result(i, result)`` is called in item order as the results
    arrive. Ctrl-C in the parent terminates the workers.
    """
    global _WORKER
    items = list(items)
    nproc = min(int(processes), len(items))
    if nproc <= 1 or "fork" not in mp.get_all_start_methods():
        out = []
        for i, item in enumerate(items):
            out.append(fn(state, item))
            if on_result is not None:
                on_result(i, out[-1])
        return out
    _WORKER = (fn, state)
    pool = mp.get_context("fork").Pool(nproc, initializer=_worker_init)
    try:
        pending = [pool.apply_async(_worker_call, (item,)) for item in items]
        out = []
        for i, res in enumerate(pending):
            while True:
                try:
                    item = res.get(timeout=0.2)  # short waits keep Ctrl-C responsive
                    break
                except mp.TimeoutError:
                    continue
            out.append(item)
            if on_result is not None:
                on_result(i, item)
        pool.close()
        return out
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
        _WORKER = None


def _start(ctx: StartContext, guess: tuple[str, Trajectory]):
    return run_start(ctx, *guess)


def run_starts(
    ctx: StartContext,
    guesses: Sequence[tuple[str, Trajectory]],
    *,
    processes: int | None = None,
    progress: bool | Progress = False,
    verbose: bool = False,
) -> list[tuple[StartOutcome, Trajectory | None]]:
    """Every start, in the order of ``guesses``: ``(outcome, path or None)`` each.

    ``processes``: default :func:`default_processes`; 1 (or ``verbose``, whose IPOPT output
    would interleave) runs serially. ``progress``: a callback after each start, or True for a
    tqdm bar (on stderr, closed at the end).
    """
    guesses = list(guesses)
    bar = None
    callback: Progress | None = progress or None  # type: ignore[assignment]
    if progress is True:
        desc = f"starts (N = {ctx.form.problem.horizon.steps})"
        bar = tqdm(total=len(guesses), desc=desc, unit="start", leave=False)

        def tick(i: int, label: str, outcome: StartOutcome) -> None:
            bar.set_postfix_str(f"{label}: {outcome.status}")
            bar.update(1)

        callback = tick

    nproc = default_processes(len(guesses)) if processes is None else max(1, int(processes))
    nproc = min(nproc, len(guesses))

    def done(i: int, item: tuple[StartOutcome, Trajectory | None]) -> None:
        if callback is not None:
            callback(i, guesses[i][0], item[0])

    try:
        return run_forked(_start, ctx, guesses, 1 if verbose else nproc, done)
    finally:
        if bar is not None:
            bar.close()
