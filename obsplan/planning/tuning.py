"""The planner's tuning: every numeric knob of ``obsplan/planning`` in one typed, frozen object.

A knob is a value an engineer might tune: a margin, a share, a tolerance, a number of rounds,
a weight, a step count, a cap. Each field of :class:`Tuning` has its type, its default (the
value the planner uses), its unit and why it is there (what it trades); ``docs/tuning.md`` holds
the evidence behind each default (what was tried, on which problems, with which command).

Definitions are not knobs and stay where they are defined: kind names and vocabularies, the
problem-file limits and the defaults of problem fields (:mod:`obsplan.planning.problem.schema`),
IPOPT's status strings, round-off guards.

Every use reads the tuning in force at call time (:func:`tuning`), so that::

    with tuned(reserve_floor=0.2, max_rounds=5):
        result = plan(problem)

plans with the changed knobs, and the defaults are back after the block (also on an exception).
The tuning in force is process-global (one module attribute, :data:`TUNING`, not per thread):
worker processes started by ``fork`` (the multi-start's and the replanned Monte Carlo's) inherit
it; a process started otherwise begins with the defaults. Cached results that depend on a knob
are cached per tuning (:func:`cache_per_tuning`). The free line order of a mission
(:attr:`Tuning.exact_lines`, :attr:`Tuning.order_speeds`) is resolved when the problem is built
(:func:`~obsplan.planning.problem.parse.load_problem`): build it inside the block to change it.

This module is the planning stage's floor: it imports only :mod:`obsplan.core` and the standard
library, and every room of :mod:`obsplan.planning` may import it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields, replace
from functools import cache, wraps
from typing import Any, ParamSpec, TypeVar

from obsplan.core.errors import ConfigError

__all__ = ["TUNING", "Tuning", "cache_per_tuning", "tuned", "tuning"]


@dataclass(frozen=True)
class Tuning:
    """The planner's numeric tuning knobs (module docstring; ``docs/tuning.md`` has the evidence).

    Frozen and hashable: vary it with :func:`dataclasses.replace` or :func:`tuned`. Invalid
    values (a negative tolerance, a share above 1, a count below 1, ...) raise
    :class:`~obsplan.core.errors.ConfigError` naming the field.
    """

    # -- keep-out margins (obsplan.planning.solver.margins) -------------------------------------
    #: Re-solves with the limits tightened by the margins, at most: more rounds let the margins
    #: settle on a path that keeps them, each costs a warm solve.
    max_rounds: int = 3
    #: Times a re-solve stopped at IPOPT's iteration limit without keeping its margins is
    #: continued warm from its own iterate before it counts as failed (a failed round drops the
    #: reserves it needed); each continuation costs one more warm solve.
    continue_unconverged: int = 2
    #: [m] Growth of a margin between rounds below which it counts as unchanged (the rounds stop).
    margin_atol_m: float = 1e-2
    #: [-] Each round tightens by the recomputed margins times ``1 + inflate`` (never less than
    #: before): the next round's path moves a little and should stay inside them.
    inflate: float = 0.1
    #: [-] Relative tolerance of "the path keeps its margins" on the tightened constraints
    #: (intrinsic units, as IPOPT's constraint tolerance).
    held_tol: float = 1e-6
    #: [-] Largest fraction of the acceleration bound kept for the guidance's feedback: the rest
    #: stays the plan's to use.
    reserve_cap: float = 0.5
    #: [-] Change of an acceleration reserve (fraction of the bound) that counts as a change
    #: between rounds.
    reserve_atol: float = 0.01
    #: [-] Smallest fraction of the acceleration bound kept for the feedback, whatever the
    #: linearised loop predicts: room to recover from the EKF's transients beyond its
    #: linearisation, paid for by the plan's own manoeuvres.
    reserve_floor: float = 0.3
    #: [-] Largest fraction of the area's (or depth band's) width a margin may take from each
    #: side: the path keeps room to move inside the box.
    box_share: float = 0.45
    #: [-] Share of the distance the vehicle can put between itself and an area or depth limit by
    #: each node (from its start, at the acceleration the reserve leaves) that the margin there
    #: may claim beyond the start's own distance: margins grow in from a start near a limit and
    #: the NLP keeps room to do its job meanwhile.
    start_reach_share: float = 0.5
    #: [m/s] Change of a speed reserve that counts as a change between rounds.
    speed_atol: float = 1e-3

    # -- mission schedule (obsplan.planning.missions.schedule) ----------------------------------
    #: [-] Fraction of the acceleration bound the schedule's turns and speed changes use: the rest
    #: is the margin of the piecewise-constant inputs that fly it on the planning grid (more:
    #: tighter turns, a faster mission; less: more room for the inputs).
    accel_use: float = 0.85
    #: [planning steps] Run-in and run-out of each line at the line speed: the nodes just before
    #: a line's start and just after its end lie on its track.
    lead_steps: float = 1.5
    #: [-] Cycles of the accelerated lawn-mower's speed sinusoid per line (at most).
    accel_cycles: int = 2
    #: [-] Fraction of the speed headroom the accelerated lawn-mower's sinusoid uses.
    accel_amplitude: float = 0.9
    #: [-] Speeds tried across the band (plus one) before the bisection of the slowest that fits:
    #: finer finds the slowest fit more surely (the mission time is not monotonic in the speed),
    #: each costs one schedule.
    speed_grid: int = 24
    #: [-] ``mission.lead_in = "auto"``: the planner's lines are scheduled this share of the way
    #: from the lawn-mower's speed up to the top of the band, and the time saved is the lead-in
    #: (more: a longer lead-in to localise in, faster lines).
    lead_in_speed_share: float = 0.5

    # -- free line order (obsplan.planning.missions.order) --------------------------------------
    #: Lines up to which the order is exact (dynamic programming over subsets, exponential in the
    #: lines); beyond, greedy with 2-opt.
    exact_lines: int = 10
    #: Speeds across the band at which the order is searched (slowest first): finer finds a
    #: slower fitting speed more surely, each costs one transit table and schedule.
    order_speeds: int = 13

    # -- mission completion check (obsplan.planning.missions.check) -----------------------------
    #: Evaluation points per interval of the path: finer sees short excursions, costs time.
    check_subsamples: int = 16
    #: Stations along each line for its coverage (the coverage's resolution).
    coverage_bins: int = 1000
    #: [-] Relative slack of the mission's tolerances: the round-off of the solver's constraints.
    check_rtol: float = 1e-6

    # -- feasibility check (obsplan.planning.problem.feasibility) -------------------------------
    #: [-] Relative tolerance on every limit (acceleration, speed, box) for "within limits":
    #: above IPOPT's ~1e-8 relative bound satisfaction, so it flags only real violations.
    limit_rtol: float = 1e-6
    #: [m], [m/s] One-step mismatch of the dynamics accepted as consistent (exact integration
    #: gives ~1e-12).
    consistency_tol: float = 1e-6

    # -- baselines (obsplan.planning.baselines.vehicle) -----------------------------------------
    #: [-] Step of the cruise-speed factors the lawn-mower tries when a leg passes too close to
    #: the beacon (``1 - step * i``): each changes the leg spacing ``2 v² / a``.
    lawnmower_speed_step: float = 0.03
    #: Cruise-speed factors tried (``i = 0 .. tries - 1``, fastest first).
    lawnmower_speed_tries: int = 11
    #: [samples per planning sample] The paper's lawn-mower is a baseline only if its time-scaled
    #: version fits in this many: at tiny limits it would take ages to fly and to build.
    paper_max_oversampling: int = 50

    # -- transcription (obsplan.planning.transcription, obsplan.planning.solver.formulation) ----
    #: [steps] Largest N solved directly from the initial guesses; a finer grid is first solved
    #: on a coarse one that divides it: fewer IPOPT iterations on the fine grid, one more solve.
    coarse_steps: int = 250
    #: [-] Transition length of a flexible line zone's relaxation, as a fraction of one step at
    #: top speed: shorter holds the rows closer to the line's ends, sharper for IPOPT.
    flex_width: float = 0.1
    #: [-] Sharpness of the relaxation's softplus: how strictly a row is held at the zone's edge
    #: (``exp(-s) / s`` of one width) against the curvature IPOPT sees.
    flex_sharpness: float = 20.0
    #: [row units per width] Relaxation of the cross-track rows off a line's end: a funnel far
    #: wider than any turn.
    flex_relax_cross: float = 10.0
    #: [row units per width] Relaxation of the velocity rows (``v_max``) off a line's end
    #: (3 frees any velocity).
    flex_relax_vel: float = 3.0
    #: [-] Squared-speed floor inside the smooth ``|v|`` of the range-limit margins: smooth at
    #: rest, conservative by at most ``τ sqrt(eps) v_max``.
    speed_eps: float = 1e-8

    # -- objectives (obsplan.planning.objectives) -----------------------------------------------
    #: [-] Floor ``ε`` of every window Gramian, relative to the information of one window of unit
    #: excitation: finite criteria at rank-deficient windows, far below any window a vehicle can
    #: excite.
    window_floor_rel: float = 1e-8
    #: [range samples] Fewest range samples an ``"auto"`` window spans.
    min_window_samples: float = 10.0
    #: [-] ``"auto"`` stride as a fraction of the window: smaller scores the path more densely,
    #: more windows to evaluate.
    auto_stride_fraction: float = 1.0 / 8.0
    #: [-] Temperature of the soft minimum over the nodes of the LWO conditioning: within
    #: ``log(N + 1) / β`` of the true minimum, while the objective stays separable over the nodes.
    lwo_beta: float = 20.0
    #: [-] Ridge added to the normalised LWO Gram matrix before its pivots are logged: finite at
    #: rank-deficient nodes (their conditioning reads ``~ridge^(1/m)`` instead of 0).
    lwo_ridge: float = 1e-9
    #: [normalised objective] Cost of an excess of the whole linearisation bound at one range
    #: epoch: how hard the EKF's linearisation stress is held against the observability gained.
    linearisation_penalty: float = 1.0
    #: [normalised objective] Cost of an estimator's predicted std exceeding its guard's bound
    #: (``objective.kf_guard``, ``objective.ekf_guard``) by the whole bound, on its mission mean
    #: or its final value: how hard the estimator is held against the objective's gain
    #: (:mod:`obsplan.planning.objectives.guards`).
    guard_penalty: float = 100.0

    # -- IPOPT (obsplan.planning.solver.ipopt) ---------------------------------------------------
    #: [intrinsic units] Tolerance of the projection onto the limits (constraint violation and
    #: optimality): far below the feasibility check's :attr:`limit_rtol`.
    projection_tol: float = 1e-10
    #: [-] A warm start's ``bound_push`` and ``bound_frac``: begin at the guess (a coarse-grid
    #: optimum), not 1 % inside the bounds (exact Hessians only).
    warm_bound_push: float = 1e-9
    warm_bound_frac: float = 1e-9
    #: [-] A warm start's initial barrier ``mu_init`` (every Hessian): small, the guess is close.
    warm_mu_init: float = 1e-6
    #: Pairs of the L-BFGS Hessian approximation (``limited_memory_max_history``): each costs two
    #: extra back-solves per iteration; more model the objective's curvature better.
    lbfgs_history: int = 6
    #: [range epochs per planning interval] At most this many (sparse epochs), an L-BFGS solve
    #: uses IPOPT's monotone barrier instead of its adaptive one: the final std's curvature then
    #: sits on a few nodes' positions, which the adaptive barrier's step model cannot see.
    monotone_epochs_per_step: float = 1.6

    # -- validation verdict (obsplan.planning.validation.verdict) -------------------------------
    #: [-] The EKF "diverges" on a path when the divergence monitor flags at least this fraction
    #: of its runs (the KF "converges" below it).
    diverged_fraction: float = 0.1
    #: [-] ... or when its final error is this many times the KF's.
    diverged_ratio: float = 3.0
    #: [-] Confidence of the verdict's intervals and tests: surer verdicts, more ties.
    confidence: float = 0.95
    #: Bootstrap resamples of each interval: a steadier interval, more time.
    bootstrap: int = 2000
    #: [range stds] Peak EKF linearisation stress above which the verdict warns that the plan's
    #: EKF may lose track on runs too rare for its run count.
    stress_note_level: float = 0.3
    #: Runs from which the validation sees a loss of one run in a few hundred (the note is moot).
    stress_note_runs: int = 1000

    # -- replanning (obsplan.planning.replan) ---------------------------------------------------
    #: Runs per closed loop of the replanned Monte Carlo (a batch advances its runs together
    #: between replans): larger batches share more work, smaller ones spread over more workers.
    replan_batch: int = 5
    #: [-] IPOPT's tolerance of a re-solve relative to the objective's own (``objective.
    #: solver_tol``): a re-solve starts next to an optimum and has a vehicle's time budget.
    replan_tol_factor: float = 10.0
    #: IPOPT iterations of a re-solve: a deterministic budget (a wall-time limit would make
    #: results depend on the machine's load).
    replan_max_iter: int = 60

    def __post_init__(self) -> None:
        for f in fields(self):
            _check(f.name, getattr(self, f.name), f.type)
        if self.reserve_floor > self.reserve_cap:
            raise ConfigError(
                f"Tuning.reserve_floor: {self.reserve_floor!r} is above Tuning.reserve_cap "
                f"({self.reserve_cap!r})"
            )


#: ``field: (low, low allowed, high, high allowed)`` of every knob (``None``: no bound).
_RANGES: dict[str, tuple[float | None, bool, float | None, bool]] = {
    # counts that may be 0 (no re-solve, no continuation, never exact, no note)
    **dict.fromkeys(
        ("max_rounds", "continue_unconverged", "exact_lines", "stress_note_runs"),
        (0, True, None, False),
    ),
    # counts of at least one
    **dict.fromkeys(
        (
            "accel_cycles",
            "speed_grid",
            "order_speeds",
            "check_subsamples",
            "coverage_bins",
            "lawnmower_speed_tries",
            "paper_max_oversampling",
            "coarse_steps",
            "bootstrap",
            "replan_batch",
            "replan_max_iter",
            "lbfgs_history",
        ),
        (1, True, None, False),
    ),
    # tolerances and other non-negative amounts
    **dict.fromkeys(
        (
            "margin_atol_m",
            "inflate",
            "held_tol",
            "reserve_atol",
            "speed_atol",
            "lead_steps",
            "check_rtol",
            "limit_rtol",
            "consistency_tol",
            "linearisation_penalty",
            "guard_penalty",
            "stress_note_level",
        ),
        (0, True, None, False),
    ),
    # strictly positive amounts
    **dict.fromkeys(
        (
            "flex_width",
            "flex_sharpness",
            "flex_relax_cross",
            "flex_relax_vel",
            "speed_eps",
            "window_floor_rel",
            "min_window_samples",
            "lwo_beta",
            "lwo_ridge",
            "projection_tol",
            "warm_bound_push",
            "warm_bound_frac",
            "warm_mu_init",
            "diverged_ratio",
            "replan_tol_factor",
        ),
        (0, False, None, False),
    ),
    # amounts that may be 0 (0: never)
    **dict.fromkeys(
        ("monotone_epochs_per_step",),
        (0, True, None, False),
    ),
    # shares in [0, 1]
    **dict.fromkeys(
        (
            "reserve_cap",
            "reserve_floor",
            "start_reach_share",
            "accel_amplitude",
            "lead_in_speed_share",
            "diverged_fraction",
        ),
        (0, True, 1, True),
    ),
    # shares in (0, 1]
    **dict.fromkeys(("accel_use", "auto_stride_fraction"), (0, False, 1, True)),
    # a share of each side of a width: below one half
    "box_share": (0, True, 0.5, False),
    # a confidence level
    "confidence": (0, False, 1, False),
    # a step of the speed factors: the slowest stays above 0 (checked with the tries below)
    "lawnmower_speed_step": (0, True, None, False),
}


def _check(name: str, value: Any, kind: Any) -> None:
    """Raise :class:`ConfigError` naming ``name`` unless ``value`` is of the field's type and in
    its range (:data:`_RANGES`)."""
    integer = kind in (int, "int")
    if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
        want = "an integer" if integer else "a number"
        raise ConfigError(f"Tuning.{name}: must be {want}, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"Tuning.{name}: must be finite, got {value!r}")
    lo, lo_in, hi, hi_in = _RANGES[name]
    if lo is not None and (value < lo or (value == lo and not lo_in)):
        raise ConfigError(f"Tuning.{name}: must be {'>=' if lo_in else '>'} {lo}, got {value!r}")
    if hi is not None and (value > hi or (value == hi and not hi_in)):
        raise ConfigError(f"Tuning.{name}: must be {'<=' if hi_in else '<'} {hi}, got {value!r}")


#: The tuning in force (the defaults unless a :func:`tuned` block, or a test's monkeypatch, has
#: replaced it). Process-global; read it through :func:`tuning`.
TUNING: Tuning = Tuning()


def tuning() -> Tuning:
    """The tuning in force (:data:`TUNING`): what every knob's use reads, at call time.

    Returns
    -------
    Tuning
        The defaults, or the tuning of the innermost :func:`tuned` block.
    """
    return TUNING


@contextmanager
def tuned(base: Tuning | None = None, /, **changes: Any) -> Iterator[Tuning]:
    """Put ``base`` (default: the tuning in force) with ``changes`` in force for a ``with``
    block, and restore the previous one after it, also on an exception::

        with tuned(max_rounds=5) as t:
            ...  # tuning() is t

    Blocks nest (an inner one changes the outer one's tuning). Process-global, not per thread:
    every thread sees the block's tuning, and processes ``fork``-ed inside it inherit it.

    Parameters
    ----------
    base : Tuning or None, optional
        The tuning to change (positional only); None: the tuning in force.
    **changes
        Knob name -> its value in the block (the fields of :class:`Tuning`).

    Yields
    ------
    Tuning
        The tuning in force inside the block.

    Raises
    ------
    ConfigError
        Naming the field, for an unknown knob or an invalid value.
    """
    global TUNING
    known = {f.name for f in fields(Tuning)}
    for name in changes:
        if name not in known:
            raise ConfigError(f"Tuning.{name}: no such knob (docs/tuning.md lists them)")
    before = TUNING
    TUNING = replace(before if base is None else base, **changes)
    try:
        yield TUNING
    finally:
        TUNING = before


P = ParamSpec("P")
R = TypeVar("R")


def cache_per_tuning(fn: Callable[P, R]) -> Callable[P, R]:
    """:func:`functools.cache` of ``fn`` keyed on the tuning in force too: a result computed
    under one tuning is never returned under another (``fn`` reads :func:`tuning`, which is the
    key's while it runs). ``cache_clear`` of the wrapper empties it.

    Parameters
    ----------
    fn : callable
        A function of hashable arguments that reads :func:`tuning`.

    Returns
    -------
    callable
        The cached wrapper, with ``fn``'s name, docstring and signature.
    """

    def call(_tuning: Tuning, *args: Any, **kwargs: Any) -> R:
        return fn(*args, **kwargs)

    keyed = cache(call)
    keyed_call: Callable[..., R] = keyed

    @wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        return keyed_call(TUNING, *args, **kwargs)

    wrapper.cache_clear = keyed.cache_clear  # type: ignore[attr-defined]
    return wrapper
