"""Solving a planning problem: the strategy (multi-start, coarse-to-fine, candidate selection).

What the returned plan guarantees (tested under several BLAS kernel sets, since IPOPT's path
depends on the machine):

* it satisfies every limit and the dynamics to the tolerances of
  :mod:`obsplan.planning.problem.feasibility` (``Tuning.limit_rtol``), checked by an independent
  numpy test on the continuous path. A start whose path violates a limit (e.g. by 0.02 % when IPOPT
  stops at its iteration limit) is first *projected*: the nearest path (least squares in the NLP's
  intrinsic units) satisfying every constraint, found by a second small IPOPT problem
  (:mod:`obsplan.planning.solver.ipopt`); its objective is then recomputed. Only if that fails is
  the start discarded;
* its objective, recomputed with numpy on the path (never read from lifting variables), is the
  best among every start's (projected) path, every feasible initial guess and every feasible
  baseline: the plan is never worse than the lawn-mower it starts from, and a start that ends
  worse than its own guess cannot beat that guess;
* ``success`` has one meaning: the returned path is a converged solution (IPOPT's
  ``Solve_Succeeded``) of the problem it was last solved for, and ``status`` is that solve's
  status. A start that stopped at ``Solved_To_Acceptable_Level`` or an iteration or time limit is
  reported as such and its path used only if feasible and best, with ``success`` False; an initial
  guess or baseline returned unchanged (every start ended worse) has ``status`` ``GUESS_STATUS``
  and ``success`` False. ``chosen`` names where the returned path came from, and the exit code of
  ``obsplan plan`` is 0 exactly when ``success`` is True.

A fine grid (``N > Tuning.coarse_steps``) is first solved on a coarse grid from the same guesses,
and each start's coarse plan becomes its fine guess (:mod:`obsplan.planning.transcription.guesses`).
The starts run in parallel worker processes with results identical to a serial run
(:mod:`obsplan.planning.solver.starts`); Ctrl-C stops every start at once and raises
``KeyboardInterrupt``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from obsplan.planning.baselines.vehicle import Baseline
from obsplan.planning.missions.check import completes_mission
from obsplan.planning.objectives.evaluate import better, objective_value
from obsplan.planning.problem.checks import check_structure
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.feasibility import check_limits
from obsplan.planning.solver.formulation import build_formulation
from obsplan.planning.solver.ipopt import SUCCESS_STATUS
from obsplan.planning.solver.starts import (
    Progress,
    StartOutcome,
    _num,
    run_starts,
    start_context,
)
from obsplan.planning.transcription.guesses import (
    coarse_problem,
    initial_guesses,
    refine,
)
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory

#: ``SolveResult.status`` when the returned path is an initial guess or baseline, unchanged
#: (every optimised start ended worse than it): no solve converged to this path
GUESS_STATUS = "Guess_Returned"


@dataclass(frozen=True)
class GuardOutcome:
    """What an estimator's default guard did (the augmented KF's or the EKF's:
    :mod:`obsplan.planning.objectives.guards`,
    :func:`~obsplan.planning.solver.margins.solve_with_keepout`).

    Attributes
    ----------
    engaged : bool
        The plan solved without the guard exceeded the bound, and the problem was re-solved
        with it.
    applied : bool
        The returned plan is the guarded re-solve's (False when not engaged, or when that
        re-solve found no path, did not converge or raised the other estimator's prediction:
        the note says which).
    bound : float
        The bound, a multiple of the lawn-mower's predicted std
        (:data:`~obsplan.planning.problem.schema.KF_GUARD`,
        :data:`~obsplan.planning.problem.schema.EKF_GUARD`).
    unguarded : tuple of float
        ``(mean, final)`` predicted std of the estimator (the augmented KF's Riccati recursion,
        the EKF's posterior CRB) on the plan solved without the guard, relative to the
        lawn-mower's.
    ratios : tuple of float
        The same for the returned plan (equal to ``unguarded`` when not engaged).
    """

    engaged: bool
    applied: bool
    bound: float
    unguarded: tuple[float, float]
    ratios: tuple[float, float]

    def to_dict(self) -> dict:
        """JSON-ready form (``solver.kf_guard``, ``solver.ekf_guard`` of report.json).

        Returns
        -------
        dict
            ``engaged``, ``applied``, ``bound``, ``unguarded_mean_ratio``,
            ``unguarded_final_ratio``, ``mean_ratio`` and ``final_ratio``.
        """
        return {
            "engaged": self.engaged,
            "applied": self.applied,
            "bound": self.bound,
            "unguarded_mean_ratio": _num(self.unguarded[0]),
            "unguarded_final_ratio": _num(self.unguarded[1]),
            "mean_ratio": _num(self.ratios[0]),
            "final_ratio": _num(self.ratios[1]),
        }


@dataclass(frozen=True, eq=False)
class SolveResult:
    """Outcome of :func:`solve`.

    ``status``/``iterations`` are those of the start whose path was chosen (for a chosen initial
    guess or baseline: :data:`GUESS_STATUS` and 0, with ``chosen`` saying so; after the keep-out
    re-solve of :func:`~obsplan.planning.solver.margins.solve_with_keepout`, the re-solve's);
    ``success`` is true exactly when that status is ``Solve_Succeeded`` and there is a path (the
    module's docstring; checked on construction); ``wall_s`` is the whole
    multi-start (the coarse-grid pass included, see ``Tuning.coarse_steps``); ``start_paths`` holds
    each start's returned path by label.
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
    # None: the default guard was not evaluated
    kf_guard: GuardOutcome | None = None
    ekf_guard: GuardOutcome | None = None

    def __post_init__(self) -> None:
        # the one meaning of success (module docstring): a result that says otherwise is a bug
        converged = self.trajectory is not None and self.status == SUCCESS_STATUS
        if bool(self.success) != converged:
            raise ValueError(
                f"SolveResult: success={self.success} disagrees with status {self.status!r} "
                f"(path {'present' if self.trajectory is not None else 'absent'})"
            )

    def to_dict(self) -> dict:
        """The ``solver`` keys of ``report.json`` (stable first, then extras).

        Returns
        -------
        dict
            JSON-ready: ``success``, ``status``, ``iterations``, ``wall_s`` [s],
            ``objective_kind``, ``objective_mode``, ``objective`` and ``lifted_objective`` (None
            when absent or not finite), ``best_start``, ``chosen``, ``note``,
            ``converged_starts`` (how many starts converged), ``build_s`` [s], ``starts``
            (each start's :meth:`~obsplan.planning.solver.starts.StartOutcome.to_dict`) and
            ``kf_guard`` and ``ekf_guard`` (:meth:`GuardOutcome.to_dict`, or None).
        """
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
            "kf_guard": None if self.kf_guard is None else self.kf_guard.to_dict(),
            "ekf_guard": None if self.ekf_guard is None else self.ekf_guard.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class _Candidate:
    """A feasible path that may be returned: a start's, an initial guess or a baseline."""

    label: str
    trajectory: Trajectory
    objective: float
    start: StartOutcome | None  # None for a guess or a baseline


def solve(
    pb: PlanningProblem,
    *,
    guesses: Sequence[tuple[str, Trajectory]] | None = None,
    baselines: dict[str, Baseline] | None = None,
    verbose: bool = False,
    progress: bool | Progress = False,
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
        Default: :func:`default_expand`.
    ipopt_options
        Extra IPOPT options (override the defaults).
    processes
        Worker processes for the starts; default :func:`default_processes`; 1 runs serially.

    Returns
    -------
    SolveResult
    """
    t_start = time.perf_counter()
    check_structure(pb)  # before any solver work (cached: a coarse pass does not repeat it)
    if expand is None:
        expand = default_expand(pb)
    coarse = coarse_problem(pb) if guesses is None else None
    refined: set[str] = set()
    if coarse is not None:
        guesses, refined = _coarse_guesses(pb, coarse, processes, ipopt_options, progress)
    guesses = list(initial_guesses(pb) if guesses is None else guesses)
    form = build_formulation(pb)
    ctx = start_context(
        form, verbose=verbose, expand=expand, ipopt_options=ipopt_options, warm=coarse is not None
    )
    build_s = time.perf_counter() - t_start
    results = run_starts(ctx, guesses, processes=processes, progress=progress, verbose=verbose)
    outcomes = [r[0] for r in results]
    trajs = [r[1] for r in results]
    labels = _guess_labels(guesses, refined, coarse.horizon.steps if coarse is not None else 0)
    extra = [(labels[i], tr) for i, (_, tr) in enumerate(guesses)]
    extra += [(f"{name} (baseline)", b.trajectory) for name, b in (baselines or {}).items()]
    cands = _candidates(pb, outcomes, trajs, extra)
    return _result(pb, outcomes, trajs, cands, wall=time.perf_counter() - t_start, build_s=build_s)


def default_expand(pb: PlanningProblem) -> bool:
    """Whether :func:`solve` expands the NLP to SX by default: for ``N <=``
    ``Tuning.coarse_steps`` and for every mission.

    A finer grid without a mission is warm-started from its coarse plan and needs few
    iterations, so construction dominates (measured at N = 1000, 2D min-eig: 9.6 s expanded
    against 4.6 s in all). A mission has no coarse pass
    (:func:`~obsplan.planning.transcription.guesses.coarse_problem`): its starts run hundreds of
    L-BFGS iterations from the lawn-mowers, each evaluating the covariance recursion's gradient,
    5-9x cheaper expanded (measured on the 3D DVL survey at N = 600: 15 ms against 75-130 ms
    per gradient, for about 8 s more construction).

    Parameters
    ----------
    pb
        The problem (its grid ``horizon.steps`` and whether it has a ``[mission]``).

    Returns
    -------
    bool
    """
    return pb.horizon.steps <= tuning().coarse_steps or pb.mission is not None


def _coarse_guesses(
    pb: PlanningProblem,
    coarse: PlanningProblem,
    processes: int | None,
    ipopt_options: dict | None,
    progress: bool | Progress,
) -> tuple[list[tuple[str, Trajectory]], set[str]]:
    """Each start first solved on the coarse grid (``Tuning.coarse_steps``): its coarse plan
    refined onto the fine grid, or its own guess where the coarse start returned no path.
    Returns the fine guesses and the labels that come from a coarse plan."""
    cres = solve(coarse, processes=processes, ipopt_options=ipopt_options, progress=progress)
    guesses: list[tuple[str, Trajectory]] = []
    refined: set[str] = set()
    for label, g in initial_guesses(pb):
        path = cres.start_paths.get(label)
        if path is None:
            guesses.append((label, g))
        else:
            guesses.append((label, refine(path, pb)))
            refined.add(label)
    return guesses, refined


def _guess_labels(
    guesses: Sequence[tuple[str, Trajectory]], refined: set[str], coarse_steps: int
) -> list[str]:
    """How the candidates list each guess: ``"<label> (initial guess)"`` or its coarse plan."""
    coarse = f"its coarse plan, N = {coarse_steps}"
    return [f"{label} ({coarse if label in refined else 'initial guess'})" for label, _ in guesses]


def _candidates(
    pb: PlanningProblem,
    outcomes: Sequence[StartOutcome],
    trajs: Sequence[Trajectory | None],
    extra: Sequence[tuple[str, Trajectory]],
) -> list[_Candidate]:
    """Every start's feasible path, then every feasible guess and baseline (module docstring)."""
    cands: list[_Candidate] = []
    for o, tr in zip(outcomes, trajs, strict=True):
        if tr is not None and o.feasible and o.objective is not None:
            cands.append(_Candidate(o.label, tr, o.objective, o))
    for label, tr in extra:
        if (
            tr.n_samples == pb.horizon.steps + 1
            and check_limits(tr, pb).ok()
            and completes_mission(tr, pb.mission_context)
        ):
            cands.append(_Candidate(label, tr, objective_value(tr, pb), None))
    return cands


def _best(cands: Sequence[_Candidate], pb: PlanningProblem) -> _Candidate:
    """The best candidate; among equals the first (starts come first, so a converged start wins
    over a guess it did not improve: strict improvement only)."""
    best = 0
    for i in range(1, len(cands)):
        if better(cands[i].objective, cands[best].objective, pb):
            best = i
    return cands[best]


def _result(
    pb: PlanningProblem,
    outcomes: list[StartOutcome],
    trajs: list[Trajectory | None],
    cands: list[_Candidate],
    *,
    wall: float,
    build_s: float,
) -> SolveResult:
    """The :class:`SolveResult` of the chosen candidate (or of none)."""
    if not cands:
        last = outcomes[-1] if outcomes else None
        return SolveResult(
            problem=pb,
            trajectory=None,
            success=False,
            status=last.status if last else "no starts",
            iterations=0,
            wall_s=wall,
            objective=None,
            lifted_objective=None,
            best_start=None,
            starts=tuple(outcomes),
            build_s=build_s,
            chosen=None,
            note="no start and no guess satisfies the limits",
        )
    best = _best(cands, pb)
    o = best.start
    note = ""
    if o is None:
        note = (
            f"every optimised start ended worse than the {best.label}; it is returned unchanged"
            if outcomes
            else ""
        )
    elif not o.success:
        note = f"the best path comes from a start that ended with {o.status}" + (
            f" ({o.note})" if o.note else ""
        )
    return SolveResult(
        problem=pb,
        trajectory=best.trajectory,
        success=o is not None and o.success,
        status=o.status if o is not None else GUESS_STATUS,
        iterations=o.iterations if o is not None else 0,
        wall_s=wall,
        objective=best.objective,
        lifted_objective=o.lifted if o is not None else None,
        best_start=o.label if o is not None else None,
        starts=tuple(outcomes),
        build_s=build_s,
        chosen=best.label,
        note=note,
        start_paths={o.label: t for o, t in zip(outcomes, trajs, strict=True) if t is not None},
    )
