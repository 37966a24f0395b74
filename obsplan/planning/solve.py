"""Solving a planning problem: IPOPT from several initial guesses, a projection, honest reporting.

What the returned plan guarantees (tested under several BLAS kernel sets, since IPOPT's path
depends on the machine):

* it satisfies every limit and the dynamics to the tolerances of
  :mod:`obsplan.planning.feasibility` (``LIMIT_RTOL``), checked by an independent numpy test on the
  continuous path. A start whose path violates a limit (e.g. by 0.02 % when IPOPT stops at its
  iteration limit) is first *projected*: the nearest path (least squares in the NLP's intrinsic
  units) satisfying every constraint, found by a second small IPOPT problem; its objective is then
  recomputed. Only if that fails is the start discarded;
* its objective, recomputed with numpy on the path (never read from lifting variables), is the
  best among every start's (projected) path, every feasible initial guess and every feasible
  baseline: the plan is never worse than the lawn-mower it starts from, and a start that ends
  worse than its own guess cannot beat that guess;
* ``success`` means at least one start ended with IPOPT's ``Solve_Succeeded``;
  ``Solved_To_Acceptable_Level`` and iteration or time limits are reported as such, and their paths
  are used only if feasible and best. ``chosen`` names where the returned path came from.

Starts run in parallel worker processes (``fork``; the solver is built once in the parent and
inherited) with results identical to a serial run: each start is an independent call of the same
solver. Ctrl-C stops every start at once and raises ``KeyboardInterrupt``.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np

from obsplan.planning.baselines import Baseline
from obsplan.planning.baselines import baselines as all_baselines
from obsplan.planning.feasibility import LimitCheck, check_limits
from obsplan.planning.metrics import better, objective_value
from obsplan.planning.objectives import Formulation, build_formulation, path_constraints
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

SUCCESS_STATUS = "Solve_Succeeded"
#: Largest N solved directly from the initial guesses: a finer grid is first solved at
#: N / k <= COARSE_STEPS (k the smallest divisor of N that gets there), and each start's coarse
#: plan, which is a path of the fine grid too, becomes that start's fine guess. From a good guess
#: IPOPT needs a fraction of the iterations (3D min-eig at N = 1000 did not converge in 1000
#: iterations from the lawn-mower).
COARSE_STEPS = 250
#: IPOPT tolerance of the projection onto the limits (constraint violation and optimality, in
#: intrinsic units): far below the feasibility check's ``LIMIT_RTOL = 1e-6``.
PROJECTION_TOL = 1e-10

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

    @property
    def feasible(self) -> bool:
        return self.limits.ok()

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
        }


@dataclass(frozen=True, eq=False)
class SolveResult:
    """Outcome of :func:`solve`.

    ``status``/``iterations`` are those of the start whose path was chosen (for a chosen initial
    guess or baseline: the best start's, with ``chosen`` saying so); ``success`` is true when at
    least one start converged (``Solve_Succeeded``); ``wall_s`` is the whole multi-start (the
    coarse-grid pass included, see :data:`COARSE_STEPS`); ``start_paths`` holds each start's
    returned path by label.
    """

    problem: PlanningProblem
    trajectory: Trajectory | None
    success: bool
    status: str
    iterations: int
    wall_s: float
    objective: float | None
    lifted_objective: float | None
    best_start: str | None
    starts: tuple[StartOutcome, ...]
    build_s: float
    chosen: str | None = None
    note: str = ""
    start_paths: dict[str, Trajectory] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """The ``solver`` keys of ``report.json`` (stable first, then extras)."""
        return {
            "success": bool(self.success),
            "status": self.status,
            "iterations": int(self.iterations),
            "wall_s": float(self.wall_s),
            "objective_kind": self.problem.objective.kind,
            "objective_mode": self.problem.objective_mode,
            "objective": _num(self.objective),
            "lifted_objective": _num(self.lifted_objective),
            "best_start": self.best_start,
            "chosen": self.chosen,
            "note": self.note,
            "converged_starts": sum(s.success for s in self.starts),
            "build_s": float(self.build_s),
            "starts": [s.to_dict() for s in self.starts],
        }


def random_guess(pb: PlanningProblem, seed: int | Sequence[int]) -> Trajectory:
    """A smooth random input sequence within the acceleration bounds, integrated exactly.

    Per axis, a sum of three sinusoids with random periods (1/8 to 1/2 of the horizon) and
    phases, scaled to 80 % of the bound. Limits other than the inputs are left to the solver.
    """
    rng = np.random.default_rng(seed)
    t = pb.times
    T = pb.horizon.duration
    tm = 0.5 * (t[:-1] + t[1:])
    u = np.zeros((t.size - 1, pb.dim))
    for i in range(pb.dim):
        periods = rng.uniform(T / 8, T / 2, 3)
        phases = rng.uniform(0, 2 * np.pi, 3)
        w = sum(np.sin(2 * np.pi * tm / P + ph) for P, ph in zip(periods, phases, strict=True))
        u[:, i] = 0.8 * pb.accel[i] * w / max(np.max(np.abs(w)), 1e-12)
    return Trajectory.from_inputs(t, pb.p0, pb.v0, u)


def initial_guesses(pb: PlanningProblem) -> list[tuple[str, Trajectory]]:
    """``objective.starts`` guesses: lawn-mower and circle (if they fit), then seeded random."""
    fitted = all_baselines(pb)
    out: list[tuple[str, Trajectory]] = [
        (name, fitted[name].trajectory) for name in ("lawnmower", "circle") if name in fitted
    ]
    i = 0
    while len(out) < pb.objective.starts:
        out.append((f"random-{i}", random_guess(pb, (pb.objective.seed, i))))
        i += 1
    return out[: pb.objective.starts]


def coarse_problem(pb: PlanningProblem) -> PlanningProblem | None:
    """The problem on the coarse grid of :data:`COARSE_STEPS` (None if N is small or prime)."""
    from obsplan.errors import ProblemError
    from obsplan.planning.problem import Horizon

    N = pb.horizon.steps
    if N <= COARSE_STEPS:
        return None
    for k in range(2, N // 50 + 1):
        if N % k == 0 and N // k <= COARSE_STEPS:
            try:
                return replace(pb, horizon=Horizon(pb.horizon.duration, N // k))
            except ProblemError:  # e.g. the coarse step cannot keep a limit from the start
                return None
    return None


def refine(traj: Trajectory, pb: PlanningProblem) -> Trajectory:
    """A coarse path on the planning grid of ``pb`` (the same path when the grids nest)."""
    t = pb.times
    mid = 0.5 * (t[:-1] + t[1:])
    k = np.clip(np.searchsorted(traj.t, mid, side="right") - 1, 0, traj.n_samples - 2)
    return Trajectory.from_inputs(t, pb.p0, pb.v0, traj.u[k])


#: IPOPT options of a warm start (guesses that are coarse-grid optima): begin at the guess, not
#: 1 % inside the bounds (bound_push / bound_frac), with a small barrier. Measured on 3D min-eig
#: at N = 1000: 194 iterations to Solve_Succeeded, against no progress in 400 with the defaults.
#: With the L-BFGS Hessian only the small barrier: starting on the bounds its first steps
#: wandered off (3D kf-position-std at N = 1000 ended at 0.41 m from a 0.118 m warm start; with
#: the default push it improved it, in 4 iterations).
WARM_START = {"bound_push": 1e-9, "bound_frac": 1e-9, "mu_init": 1e-6}
WARM_START_LBFGS = {"mu_init": 1e-6}


def make_solver(
    form: Formulation,
    verbose: bool = False,
    expand: bool = True,
    ipopt_options: dict | None = None,
    warm: bool = False,
) -> ca.Function:
    """The IPOPT ``nlpsol`` of a formulation (MUMPS; exact Hessian or L-BFGS per objective).

    ``warm`` adds :data:`WARM_START` (or :data:`WARM_START_LBFGS`); ``ipopt_options`` are
    passed last (e.g.
    ``{"max_wall_time": 120.0}`` in the benchmark).
    """
    obj = form.problem.objective
    ipopt = {
        "linear_solver": "mumps",
        "print_level": 5 if verbose else 0,
        "sb": "yes",
        "tol": obj.solver_tol,
        # equality residuals bound how far the epigraph variable can exceed lambda_min and how
        # far the path is from the dynamics: keep them tight, not IPOPT's default 1e-4
        "constr_viol_tol": min(obj.solver_tol, 1e-8),
        "max_iter": obj.max_iter,
    }
    if form.hessian == "limited-memory":
        ipopt["hessian_approximation"] = "limited-memory"
        # a short history: each stored pair costs two extra back-solves per iteration, and six
        # reach the same objective as twenty in fewer seconds (measured at N = 200 and 1000)
        ipopt["limited_memory_max_history"] = 6
    if warm:
        ipopt.update(WARM_START_LBFGS if form.hessian == "limited-memory" else WARM_START)
    ipopt.update(ipopt_options or {})
    opts = {"expand": expand, "print_time": verbose, "ipopt": ipopt}
    nlp = {"x": form.w, "f": form.f, "g": form.g}
    return ca.nlpsol("obsplan_planner", "ipopt", nlp, opts)  # type: ignore[arg-type]


def make_projection(pb: PlanningProblem, form: Formulation) -> ca.Function:
    """IPOPT for the nearest inputs ``min ½ |U - Ū|²`` (intrinsic units, ``|U_i| <= 1``) such
    that the path satisfies every path constraint (``W̄`` the parameter ``p``).

    The inputs determine the path, so nearest inputs mean the nearest flyable path; positions
    and velocities follow through the dynamics constraints.
    """
    grid = form.grid
    n = grid.n
    W = ca.MX.sym("W", 3 * n, grid.N)
    Wbar = ca.MX.sym("Wbar", 3 * n, grid.N)
    g, _, _, _, _ = path_constraints(grid, pb, W)
    f = 0.5 * ca.sumsqr(W[:n, :] - Wbar[:n, :])
    nlp = {"x": ca.vec(W), "p": ca.vec(Wbar), "f": f, "g": ca.vertcat(*g)}
    ipopt = {
        "linear_solver": "mumps",
        "print_level": 0,
        "sb": "yes",
        "tol": PROJECTION_TOL,
        "constr_viol_tol": PROJECTION_TOL,
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


@contextmanager
def _interrupt_guard():
    """Make Ctrl-C stop a CasADi solve and surface as ``KeyboardInterrupt``.

    CasADi catches the ``KeyboardInterrupt`` raised inside IPOPT's iteration check and returns
    ``NonIpopt_Exception_Thrown``; the handler below records the signal so that the caller can
    raise it once the solver has returned (at the next iteration, i.e. at once).
    """
    hit: list[bool] = []
    if threading.current_thread() is not threading.main_thread():
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
    return sol, solver.stats(), err


def _project(
    form: Formulation, projection: ca.Function, traj: Trajectory
) -> tuple[Trajectory | None, str]:
    """Nearest path satisfying the path constraints (module docstring), or None."""
    grid = form.grid
    wbar = grid.from_trajectory(traj).reshape(-1, order="F")
    k, nw = form.n_path_constraints, form.n_w  # path constraints come first in g and x
    sol, stats, err = _call(
        projection,
        x0=wbar,
        p=wbar,
        lbx=form.lbx[:nw],
        ubx=form.ubx[:nw],
        lbg=form.lbg[:k],
        ubg=form.ubg[:k],
    )
    status = err or str(stats.get("return_status", "unknown"))
    if sol is None:
        return None, status
    w = np.asarray(sol["x"]).reshape(-1)
    W = w.reshape(3 * grid.n, grid.N, order="F")
    # exact re-integration of the projected inputs: the returned samples are consistent
    raw = grid.to_trajectory(W)
    return Trajectory.from_inputs(raw.t, raw.p[0], raw.v[0], raw.u[:-1]), status


@dataclass
class _Context:
    form: Formulation
    solver: ca.Function
    projection: Callable[[], ca.Function]


def _run_start(
    ctx: _Context, label: str, guess: Trajectory
) -> tuple[StartOutcome, Trajectory | None]:
    form = ctx.form
    pb = form.problem
    x0 = form.pack(guess)
    init_obj = objective_value(guess, pb)
    t0 = time.perf_counter()
    sol, stats, err = _call(
        ctx.solver, x0=x0, lbx=form.lbx, ubx=form.ubx, lbg=form.lbg, ubg=form.ubg
    )
    status = err or str(stats.get("return_status", "unknown"))
    iters = int(stats.get("iter_count", 0))
    if sol is None or not np.all(np.isfinite(np.asarray(sol["x"]))):
        wall = time.perf_counter() - t0
        return StartOutcome(
            label, False, status, iters, wall, None, None, _num(init_obj), _INF_CHECK
        ), None
    x = np.asarray(sol["x"]).reshape(-1)
    traj, _ = form.unpack(x)
    lifted = form.lifted_value(float(sol["f"]))
    limits = check_limits(traj, pb)
    projected = False
    if not limits.ok():
        proj, _ = _project(form, ctx.projection(), traj)
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
    )
    return outcome, traj


# ----------------------------------------------------------------------------- processes
_WORKER: _Context | None = None  # set in the parent before fork; read by the children


def _worker_init() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops everyone on Ctrl-C
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def _worker_start(args: tuple[str, Trajectory]) -> tuple[StartOutcome, Trajectory | None]:
    assert _WORKER is not None
    return _run_start(_WORKER, *args)


def default_processes(n_starts: int) -> int:
    """Worker processes for ``n_starts`` starts: one per available core, at most one per start."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_starts))


def _run_parallel(ctx: _Context, guesses, processes: int, progress: Callable | None):
    global _WORKER
    _WORKER = ctx
    pool = mp.get_context("fork").Pool(processes, initializer=_worker_init)
    try:
        pending = [pool.apply_async(_worker_start, (g,)) for g in guesses]
        out = []
        for i, res in enumerate(pending):
            while True:
                try:
                    item = res.get(timeout=0.2)  # short waits keep Ctrl-C responsive
                    break
                except mp.TimeoutError:
                    continue
            out.append(item)
            if progress is not None:
                progress(i, guesses[i][0], item[0])
        pool.close()
        return out
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
        _WORKER = None


def solve(
    pb: PlanningProblem,
    *,
    guesses: Sequence[tuple[str, Trajectory]] | None = None,
    baselines: dict[str, Baseline] | None = None,
    verbose: bool = False,
    progress: bool | Callable[[int, str, StartOutcome], None] = False,
    expand: bool | None = None,
    ipopt_options: dict | None = None,
    processes: int | None = None,
) -> SolveResult:
    """Plan a path for ``pb`` by multi-start IPOPT (module docstring for the guarantees).

    Parameters
    ----------
    pb
        The problem.
    guesses
        ``(label, trajectory)`` initial guesses on the planning grid; default
        :func:`initial_guesses`.
    baselines
        Baselines whose paths are candidates too (default: none besides the guesses).
    verbose
        IPOPT output (print_level 5) and timing; forces a serial run.
    progress
        A callback ``(index, label, outcome)`` after each start (or True for a tqdm bar).
    expand
        Expand the MX graph to SX before solving: faster iterations, slower construction.
        Default: for ``N <= COARSE_STEPS`` only; a finer grid is warm-started from the coarse
        plan and needs few iterations, so construction dominates (measured at N = 1000, 2D
        min-eig: 9.6 s expanded against 4.6 s in all).
    ipopt_options
        Extra IPOPT options (override the defaults).
    processes
        Worker processes for the starts; default :func:`default_processes`; 1 runs serially.

    Returns
    -------
    SolveResult
    """
    t_start = time.perf_counter()
    if expand is None:
        expand = pb.horizon.steps <= COARSE_STEPS
    coarse = coarse_problem(pb) if guesses is None else None
    refined: set[str] = set()
    if coarse is not None:
        # each start first solved on the coarse grid (module constant COARSE_STEPS)
        cres = solve(
            coarse,
            processes=processes,
            ipopt_options=ipopt_options,
            progress=progress,
        )
        guesses = []
        for label, g in initial_guesses(pb):
            path = cres.start_paths.get(label)
            if path is None:
                guesses.append((label, g))
            else:
                guesses.append((label, refine(path, pb)))
                refined.add(label)
    guesses = list(initial_guesses(pb) if guesses is None else guesses)
    form = build_formulation(pb)
    solver = make_solver(
        form,
        verbose=verbose,
        expand=expand,
        ipopt_options=ipopt_options,
        warm=coarse is not None,
    )
    proj_cache: list[ca.Function] = []

    def projection() -> ca.Function:
        if not proj_cache:
            proj_cache.append(make_projection(pb, form))
        return proj_cache[0]

    ctx = _Context(form, solver, projection)
    build_s = time.perf_counter() - t_start

    bar = None
    callback: Callable[[int, str, StartOutcome], None] | None = progress or None  # type: ignore[assignment]
    if progress is True:
        from tqdm import tqdm

        desc = f"starts (N = {pb.horizon.steps})"
        bar = tqdm(total=len(guesses), desc=desc, unit="start", leave=False)

        def tick(i: int, label: str, outcome: StartOutcome) -> None:
            bar.set_postfix_str(f"{label}: {outcome.status}")
            bar.update(1)

        callback = tick

    nproc = default_processes(len(guesses)) if processes is None else max(1, int(processes))
    nproc = min(nproc, len(guesses))
    try:
        if nproc > 1 and not verbose and "fork" in mp.get_all_start_methods():
            results = _run_parallel(ctx, guesses, nproc, callback)
        else:
            results = []
            for i, (label, guess) in enumerate(guesses):
                results.append(_run_start(ctx, label, guess))
                if callback is not None:
                    callback(i, label, results[-1][0])
    finally:
        if bar is not None:
            bar.close()
    outcomes = [r[0] for r in results]
    trajs = [r[1] for r in results]

    # candidates: every start's path, then every initial guess and baseline (module docstring)
    cands: list[tuple[str, Trajectory, float, StartOutcome | None]] = []
    for o, tr in zip(outcomes, trajs, strict=True):
        if tr is not None and o.feasible and o.objective is not None:
            cands.append((o.label, tr, o.objective, o))
    nc = coarse.horizon.steps if coarse is not None else 0
    extra = [
        (f"{label} ({f'its coarse plan, N = {nc}' if label in refined else 'initial guess'})", tr)
        for label, tr in guesses
    ]
    extra += [(f"{name} (baseline)", b.trajectory) for name, b in (baselines or {}).items()]
    for label, tr in extra:
        if tr.n_samples == pb.horizon.steps + 1 and check_limits(tr, pb).ok():
            cands.append((label, tr, objective_value(tr, pb), None))
    wall = time.perf_counter() - t_start
    success = any(o.success for o in outcomes)
    if not cands:
        last = outcomes[-1] if outcomes else None
        return SolveResult(
            pb,
            None,
            False,
            last.status if last else "no starts",
            0,
            wall,
            None,
            None,
            None,
            tuple(outcomes),
            build_s,
            None,
            "no start and no guess satisfies the limits",
        )
    # prefer a converged start among equals: stable order (starts first) and strict improvement
    best = 0
    for i in range(1, len(cands)):
        if better(cands[i][2], cands[best][2], pb):
            best = i
    label, traj, value, o = cands[best]
    converged = [x for x in outcomes if x.success]
    ref = o if o is not None else (converged[0] if converged else outcomes[0])
    note = ""
    if o is None:
        note = (
            f"every optimised start ended worse than the {label}; it is returned unchanged"
            if outcomes
            else ""
        )
    elif not o.success:
        note = f"the best path comes from a start that ended with {o.status}"
    return SolveResult(
        problem=pb,
        trajectory=traj,
        success=success,
        status=ref.status,
        iterations=ref.iterations,
        wall_s=wall,
        objective=value,
        lifted_objective=o.lifted if o is not None else None,
        best_start=o.label if o is not None else None,
        starts=tuple(outcomes),
        build_s=build_s,
        chosen=label,
        note=note,
        start_paths={o.label: t for o, t in zip(outcomes, trajs, strict=True) if t is not None},
    )


__all__ = [
    "SUCCESS_STATUS",
    "SolveResult",
    "StartOutcome",
    "default_processes",
    "initial_guesses",
    "make_solver",
    "random_guess",
    "solve",
]
