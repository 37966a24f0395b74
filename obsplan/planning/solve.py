"""Solving a planning problem: IPOPT from several initial guesses, honest reporting.

Each start is judged by IPOPT's ``return_status`` (``Solve_Succeeded`` is a success;
``Solved_To_Acceptable_Level`` and every failure are not) *and* by an independent numpy check of
the returned path (:func:`~obsplan.planning.feasibility.check_limits`). The returned plan is the
best objective (recomputed numerically on the path, not read from the lifting variables) among the
successful feasible starts; if no start succeeded, the best feasible iterate is returned with
``success = False``; if none is feasible, no path is returned.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from obsplan.planning.baselines import circle_baseline, lawnmower_baseline
from obsplan.planning.feasibility import LimitCheck, check_limits
from obsplan.planning.metrics import better, objective_value
from obsplan.planning.objectives import Formulation, build_formulation
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory

SUCCESS_STATUS = "Solve_Succeeded"


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
        Solve time [s].
    objective : float or None
        The objective recomputed numerically on the returned path.
    lifted : float or None
        The solver's own objective (e.g. the epigraph variable ``t``).
    initial_objective : float or None
        The objective of the initial guess.
    limits : LimitCheck
        Independent check of the returned path.
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
        }


@dataclass(frozen=True, eq=False)
class SolveResult:
    """Outcome of :func:`solve`.

    ``success``/``status``/``iterations`` are those of the returned start; ``wall_s`` is the whole
    multi-start (formulation, solver construction and every start).
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

    def to_dict(self) -> dict:
        """The ``solver`` keys of ``report.json`` (stable first, then extras)."""
        return {
            "success": bool(self.success),
            "status": self.status,
            "iterations": int(self.iterations),
            "wall_s": float(self.wall_s),
            "objective_kind": self.problem.objective.kind,
            "objective": _num(self.objective),
            "lifted_objective": _num(self.lifted_objective),
            "best_start": self.best_start,
            "build_s": float(self.build_s),
            "starts": [s.to_dict() for s in self.starts],
        }


def random_guess(pb: PlanningProblem, seed: int | Sequence[int]) -> Trajectory:
    """A smooth random input sequence within the acceleration bounds, integrated exactly.

    Per axis, a sum of three sinusoids with random periods (1/8 to 1/2 of the horizon) and
    phases, scaled to 80 % of the bound. Speed and area limits are left to the solver.
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
    """``objective.starts`` guesses: lawn-mower, circle (if defined), then seeded random ones."""
    out: list[tuple[str, Trajectory]] = [("lawnmower", lawnmower_baseline(pb).trajectory)]
    circ = circle_baseline(pb)
    if circ is not None:
        out.append(("circle", circ.trajectory))
    i = 0
    while len(out) < pb.objective.starts:
        out.append((f"random-{i}", random_guess(pb, (pb.objective.seed, i))))
        i += 1
    return out[: pb.objective.starts]


def make_solver(
    form: Formulation,
    verbose: bool = False,
    expand: bool = True,
    ipopt_options: dict | None = None,
) -> ca.Function:
    """The IPOPT ``nlpsol`` of a formulation (MUMPS; exact Hessian except for the KF objective).

    ``ipopt_options`` are passed last (e.g. ``{"max_wall_time": 120.0}`` in the benchmark).
    """
    obj = form.problem.objective
    ipopt = {
        "linear_solver": "mumps",
        "print_level": 5 if verbose else 0,
        "sb": "yes",
        "tol": obj.tol,
        # equality residuals bound how far the epigraph variable can exceed lambda_min: keep
        # them at the optimality tolerance, not IPOPT's default 1e-4
        "constr_viol_tol": obj.tol,
        "max_iter": obj.max_iter,
    }
    if obj.kind == "kf-position-std":
        # the exact Hessian of a 600-step Riccati recursion is dense and slow to build
        # (measured: 166 s to construct at N = 50); L-BFGS needs only gradients
        ipopt["hessian_approximation"] = "limited-memory"
    ipopt.update(ipopt_options or {})
    opts = {"expand": expand, "print_time": verbose, "ipopt": ipopt}
    nlp = {"x": form.w, "f": form.f, "g": form.g}
    return ca.nlpsol("obsplan_planner", "ipopt", nlp, opts)  # type: ignore[arg-type]


def _run_start(
    form: Formulation, solver: ca.Function, label: str, guess: Trajectory
) -> tuple[StartOutcome, Trajectory | None]:
    pb = form.problem
    x0 = form.pack(guess)
    init_obj = objective_value(guess, pb)
    t0 = time.perf_counter()
    try:
        sol = solver(x0=x0, lbx=form.lbx, ubx=form.ubx, lbg=form.lbg, ubg=form.ubg)
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        iters = int(stats.get("iter_count", 0))
        x = np.asarray(sol["x"]).reshape(-1)
    except RuntimeError as exc:  # IPOPT/CasADi errors (e.g. evaluation failures)
        wall = time.perf_counter() - t0
        outcome = StartOutcome(
            label,
            False,
            f"exception: {exc}".splitlines()[0][:200],
            0,
            wall,
            None,
            None,
            _num(init_obj),
            LimitCheck(math.inf, math.inf, math.inf, math.inf, math.inf, math.inf),
        )
        return outcome, None
    wall = time.perf_counter() - t0
    if not np.all(np.isfinite(x)):
        bad = LimitCheck(math.inf, math.inf, math.inf, math.inf, math.inf, math.inf)
        return StartOutcome(
            label, False, status, iters, wall, None, None, _num(init_obj), bad
        ), None
    traj, _ = form.unpack(x)
    lifted = float(form.objective_sign * float(sol["f"]))
    outcome = StartOutcome(
        label=label,
        success=status == SUCCESS_STATUS,
        status=status,
        iterations=iters,
        wall_s=wall,
        objective=objective_value(traj, pb),
        lifted=lifted,
        initial_objective=_num(init_obj),
        limits=check_limits(traj, pb),
    )
    return outcome, traj


def solve(
    pb: PlanningProblem,
    *,
    guesses: Sequence[tuple[str, Trajectory]] | None = None,
    verbose: bool = False,
    progress: bool = False,
    expand: bool = True,
    ipopt_options: dict | None = None,
) -> SolveResult:
    """Plan a path for ``pb`` by multi-start IPOPT.

    Parameters
    ----------
    pb
        The problem.
    guesses
        ``(label, trajectory)`` initial guesses on the planning grid; default
        :func:`initial_guesses`.
    verbose
        IPOPT output (print_level 5) and timing.
    progress
        One line per start on stderr.
    expand
        Expand the MX graph to SX before solving (faster evaluation; measured in the benchmark).
    ipopt_options
        Extra IPOPT options (override the defaults).

    Returns
    -------
    SolveResult
    """
    t_start = time.perf_counter()
    form = build_formulation(pb)
    solver = make_solver(form, verbose=verbose, expand=expand, ipopt_options=ipopt_options)
    build_s = time.perf_counter() - t_start
    guesses = list(initial_guesses(pb) if guesses is None else guesses)
    outcomes: list[StartOutcome] = []
    trajs: list[Trajectory | None] = []
    for i, (label, guess) in enumerate(guesses):
        outcome, traj = _run_start(form, solver, label, guess)
        outcomes.append(outcome)
        trajs.append(traj)
        if progress:
            print(
                f"  start {i + 1}/{len(guesses)} ({label}): {outcome.status}, "
                f"{outcome.iterations} it, {outcome.wall_s:.1f} s, objective "
                f"{outcome.objective if outcome.objective is not None else float('nan'):.6g}",
                file=sys.stderr,
                flush=True,
            )
    best = _select(outcomes, pb)
    wall = time.perf_counter() - t_start
    if best is None:
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
        )
    o = outcomes[best]
    return SolveResult(
        problem=pb,
        trajectory=trajs[best],
        success=o.success,
        status=o.status,
        iterations=o.iterations,
        wall_s=wall,
        objective=o.objective,
        lifted_objective=o.lifted,
        best_start=o.label,
        starts=tuple(outcomes),
        build_s=build_s,
    )


def _select(outcomes: Sequence[StartOutcome], pb: PlanningProblem) -> int | None:
    """Index of the best feasible start, preferring successful ones (module docstring)."""
    for want_success in (True, False):
        best: int | None = None
        for i, o in enumerate(outcomes):
            if o.objective is None or not o.feasible or (want_success and not o.success):
                continue
            if best is None or better(o.objective, outcomes[best].objective, pb):  # type: ignore[arg-type]
                best = i
        if best is not None:
            return best
    return None
