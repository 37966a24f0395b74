"""The starts of a multi-start solve: one IPOPT run per initial guess, serially or in processes.

Each start is an independent call of the same solver, so a parallel run gives the results of a
serial one. Starts run in worker processes (``fork``; the solver is built once in the parent and
inherited); Ctrl-C stops every start at once and raises ``KeyboardInterrupt``. A start whose
path violates a limit is first projected onto the limits (:func:`~obsplan.planning.solver.ipopt
.project`); its objective is recomputed numerically on the returned path
(:func:`~obsplan.planning.objectives.evaluate.objective_value`), never read from lifting variables.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing as mp
import multiprocessing.connection as mp_connection
import os
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any

import casadi as ca
import numpy as np
from tqdm import tqdm

from obsplan.core import interrupts
from obsplan.core.errors import SolverError
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
        """JSON-ready form of the outcome (an item of ``solver.starts`` in report.json).

        Returns
        -------
        dict
            ``label``, ``success``, ``status``, ``iterations``, ``wall_s`` [s], ``objective``,
            ``lifted_objective`` and ``initial_objective`` (None when absent or not finite),
            ``feasible`` (within the limits and completing the mission), ``projected``,
            ``mission_complete`` and ``note``.
        """
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
    built on first use (most starts end within the limits and never need it).

    Parameters
    ----------
    form : Formulation
        The NLP (possibly with tightened bounds: the starts use its bounds).
    verbose : bool, optional
        Print IPOPT's iterations and timings.
    expand : bool, optional
        Expand the MX graph to SX before solving.
    ipopt_options : dict, optional
        IPOPT options applied last (:func:`~obsplan.planning.solver.ipopt.ipopt_settings`).
    warm : bool, optional
        The guesses are coarse-grid optima (warm-start options).

    Returns
    -------
    StartContext
        The formulation, its solver, the lazy projection, and the solver's ``tol`` and
        ``constr_viol_tol`` (what a stopped start is measured against).
    """
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
    """IPOPT from one guess; its path (projected onto the limits if needed) or None.

    Parameters
    ----------
    ctx : StartContext
        The formulation and its solver (:func:`start_context`).
    label : str
        The start's name, e.g. ``"lawnmower"`` or ``"random-3"``.
    guess : Trajectory
        The initial guess, on the planning grid.

    Returns
    -------
    outcome : StartOutcome
        Status, iterations, the objective recomputed numerically on the returned path, the
        limit and mission checks of that path, and why a start that did not converge stopped.
    path : Trajectory or None
        The solver's path, projected onto the limits when it breaks a limit or the mission (the
        unprojected path, with ``projected`` True and its failed checks, when the projection
        fails); None when the solver returned no finite point.
    """
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
#: Seconds a worker gets to leave after its last item before it is killed (it only returns).
JOIN_TIMEOUT_S = 5.0
#: Seconds between two looks at the workers while the parent waits for a result.
POLL_S = 0.2


class WorkerDied(SolverError):
    """A worker process of :func:`run_forked` ended without returning its item's result (killed
    from outside, out of memory, or crashed in native code)."""


def _worker_main(conn: Connection, fn: Callable[[Any, Any], Any], state: Any) -> None:
    """A forked worker: ``fn(state, item)`` for each ``(index, item)`` received, until ``None``.

    SIGINT and SIGTERM are ignored (:func:`~obsplan.core.interrupts.child_init`; they were
    blocked across the fork, so none sent meanwhile can reach Python's handler here): the
    parent alone decides, and stops its workers with SIGKILL. The worker dies with its parent.
    """
    interrupts.child_init()
    signal.pthread_sigmask(signal.SIG_UNBLOCK, interrupts.SIGNALS)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):  # the parent closed the pipe: nothing more to do
            return
        if msg is None:
            return
        i, item = msg
        try:
            reply: tuple[int, bool, Any] = (i, True, fn(state, item))
        except BaseException as exc:  # noqa: BLE001 - re-raised in the parent
            reply = (i, False, exc)
        try:
            conn.send(reply)  # pickled whole before a byte is written
        except Exception as exc:  # noqa: BLE001 - an unpicklable result or exception
            what = "result" if reply[1] else f"exception {reply[2]!r}"
            conn.send((i, False, SolverError(f"item {i}: cannot send its {what} back: {exc}")))


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Block SIGINT and SIGTERM in this thread for the block (the forks): a child inherits the
    mask, so a signal sent to the process group while it starts is never raised in it; the
    parent gets its own when the block ends."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, interrupts.SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _stop_workers(workers: list[tuple[BaseProcess, Connection]], kill: bool) -> None:
    """End every worker: ask them to leave (``kill=False``, after the last result) or SIGKILL them
    (an interruption or an error), then reap them and close the pipes.

    Nothing here waits on a lock or a queue a worker could hold, and no worker outlives the
    call, whatever interrupts it (the workers ignore SIGTERM: ``multiprocessing``'s exit handler
    would wait for ever on a worker left running).
    """
    try:
        if not kill:
            for _, conn in workers:
                with contextlib.suppress(OSError, ValueError):
                    conn.send(None)
            deadline = time.monotonic() + JOIN_TIMEOUT_S
            for proc, _ in workers:
                proc.join(max(0.0, deadline - time.monotonic()))  # they leave at once
    finally:
        # what is left (an interruption, an error, a signal meanwhile, a worker that did not
        # leave in time): SIGKILL, reaped in milliseconds
        for proc, _ in workers:
            if proc.exitcode is None:
                with contextlib.suppress(OSError, ValueError, AttributeError):
                    proc.kill()
        for proc, conn in workers:
            proc.join(JOIN_TIMEOUT_S)
            conn.close()
            with contextlib.suppress(ValueError):
                proc.close()


def default_processes(n_starts: int) -> int:
    """Worker processes for ``n_starts`` starts: one per available core, at most one per start.

    Parameters
    ----------
    n_starts : int
        Number of starts.

    Returns
    -------
    int
        ``min(cores available to this process, n_starts)``, at least 1.
    """
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

    The one process pool of the package (the multi-start and the replanned Monte Carlo).
    ``state`` (e.g. a built solver) reaches the workers by the fork, not by pickling; the items
    and the results are pickled, through one pipe per worker (no queue or lock shared between
    workers, so a worker killed at any moment cannot block the others or the parent). Serial
    when ``processes <= 1``, with one item, or where ``fork`` is not available. An exception of
    ``fn`` is raised here.

    The workers ignore SIGINT and SIGTERM (a terminal's Ctrl-C and a batch scheduler's SIGTERM
    reach the whole process group): the parent raises
    :class:`~obsplan.core.interrupts.Interrupted` (or ``KeyboardInterrupt``) and kills its
    workers at once, without waiting for their solves. A worker dies with its parent.

    Parameters
    ----------
    fn : callable
        ``fn(state, item)``: the work on one item; its result must be picklable.
    state : Any
        Shared by every call; inherited by the forked workers, never pickled.
    items : sequence
        The items (picklable), one call each.
    processes : int
        At most this many worker processes (never more than items); ``<= 1`` runs serially.
    on_result : callable, optional
        ``on_result(i, result)`` for each item index ``i``, in item order as the results arrive.

    Returns
    -------
    list
        ``fn(state, item)`` for each item, in the order of ``items``.

    Raises
    ------
    WorkerDied
        When a worker ended without returning a result (killed from outside, out of memory).
    """
    items = list(items)
    nproc = min(int(processes), len(items))
    if nproc <= 1 or "fork" not in mp.get_all_start_methods():
        out = []
        for i, item in enumerate(items):
            out.append(fn(state, item))
            if on_result is not None:
                on_result(i, out[-1])
        return out
    ctx = mp.get_context("fork")
    workers: list[tuple[BaseProcess, Connection]] = []
    busy: dict[Connection, tuple[BaseProcess, int]] = {}
    done: dict[int, Any] = {}
    reported = 0
    queue = iter(enumerate(items))
    finished = False
    try:
        with _signals_held():
            for _ in range(nproc):
                parent_end, child_end = ctx.Pipe(duplex=True)
                child = ctx.Process(target=_worker_main, args=(child_end, fn, state), daemon=True)
                try:
                    child.start()
                finally:
                    child_end.close()
                workers.append((child, parent_end))
        idle = list(workers)

        def feed() -> None:
            while idle:
                nxt = next(queue, None)
                if nxt is None:
                    return
                proc, conn = idle.pop()
                conn.send(nxt)
                busy[conn] = (proc, nxt[0])

        feed()
        while reported < len(items):
            ready = mp_connection.wait(list(busy), timeout=POLL_S)
            interrupts.check()  # a signal whose exception a library swallowed
            for conn in ready:
                assert isinstance(conn, Connection)
                proc, i = busy.pop(conn)
                try:
                    j, ok, value = conn.recv()
                except (EOFError, OSError):
                    proc.join(JOIN_TIMEOUT_S)
                    raise WorkerDied(
                        f"a worker process ended (exit code {proc.exitcode}) while computing "
                        f"item {i + 1} of {len(items)} (killed from outside, or out of "
                        "memory?); run again, or with one process"
                    ) from None
                if not ok:
                    raise value
                done[j] = value
                idle.append((proc, conn))
            feed()
            while reported in done:
                if on_result is not None:
                    on_result(reported, done[reported])
                reported += 1
        finished = True
        return [done[i] for i in range(len(items))]
    finally:
        _stop_workers(workers, kill=not finished)


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

    Parameters
    ----------
    ctx : StartContext
        The formulation and its solver, shared by every start (inherited by the workers).
    guesses : sequence of (str, Trajectory)
        ``(label, initial guess)`` per start, on the planning grid.
    processes : int, optional
        Worker processes; default :func:`default_processes`; 1 runs serially.
    progress : bool or Progress, optional
        A callback ``(index, label, outcome)`` after each start, in order, or True for a tqdm
        bar (on stderr, closed at the end).
    verbose : bool, optional
        Runs serially, since the starts' IPOPT output would interleave.

    Returns
    -------
    list of (StartOutcome, Trajectory or None)
        :func:`run_start`'s ``(outcome, path or None)`` per guess, in the order of ``guesses``.
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
