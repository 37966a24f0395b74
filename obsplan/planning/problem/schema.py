"""The problem file, declared: every field with its type, unit, default and meaning, and every
objective kind with its properties.

:data:`SCHEMA` is the one table of the problem file's fields: the loader
(:mod:`obsplan.planning.problem.parse`), its error messages and the field tables of
``docs/problem-files.md`` (:func:`schema_markdown`, :func:`update_field_tables`) all come from
it, so they cannot drift apart (``tests/test_problem.py`` checks the document).
:data:`OBJECTIVE_KINDS` declares each ``objective.kind``: whether it is maximised or minimised,
whether it has a time mode, its default solver tolerance and the structural rank it needs; the
implementations are registered by kind in :mod:`obsplan.planning.objectives.registry`.

A new section or field is one more entry here (then regenerate the document with
:func:`update_field_tables`), a frozen dataclass field in
:mod:`obsplan.planning.problem.sections`, and its conversion in
:mod:`obsplan.planning.problem.mapping`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

from obsplan.core import budget
from obsplan.estimation.config import DEFAULT_ACCEL_NOISE

#: Largest ``horizon.steps`` the planner accepts: the NLP grows linearly in N and IPOPT's time
#: faster; N = 1000 solves in seconds to a minute (docs/results/benchmarks.md), 5000 is already
#: hours.
MAX_STEPS = 5000
#: Longest horizon [s] and largest speed [m/s], acceleration [m/s²] and coordinate [m] accepted:
#: far beyond any vehicle (a bound keeps absurd inputs from overflowing the checks' arithmetic).
MAX_DURATION_S = 1e7
MAX_MAGNITUDE = 1e7


@dataclass(frozen=True)
class ObjectiveKind:
    """One ``objective.kind``: its declared properties (the implementation is registered by
    ``name`` in :data:`obsplan.planning.objectives.registry.REGISTRY`).

    Attributes
    ----------
    name : str
    sense : {"max", "min"}
        Whether a larger (Gramian, LWO) or a smaller (covariance) value is better.
    timed : bool
        Has a time mode (``objective.mode``: final, mission-average, average-and-final).
    auto_mode : str
        What ``objective.mode = "auto"`` resolves to (reports carry it for every kind).
    default_tol : float
        IPOPT ``tol`` when ``objective.tol`` is not given.
    structure : {"lwo", "gramian", None}
        The structural rank the kind needs (checked before solving by
        :mod:`obsplan.planning.problem.checks`): of the LWO matrix, of the augmented Gramian, or
        none.
    windowed_tol : float or None
        IPOPT ``tol`` of the kind's windowed form (``objective.window``/``weights`` other than
        the paper's ``"mission"``/``"none"``; for ``lwo-condition`` its information form);
        None: ``default_tol``.
    """

    name: str
    sense: Literal["max", "min"]
    timed: bool
    auto_mode: str
    default_tol: float
    structure: Literal["lwo", "gramian"] | None
    windowed_tol: float | None = None


#: Every objective kind, in the order the documents list them (the first is the default).
OBJECTIVE_KINDS: dict[str, ObjectiveKind] = {
    k.name: k
    for k in (
        # L-BFGS (the covariance objectives) converges slowly: at N = 1000, tol 1e-5 takes 5x the
        # iterations of 1e-4 for a 0.4 % better bound
        ObjectiveKind("pcrb-position", "min", True, "average-and-final", 1e-4, None),
        # the windowed min-eig at 1e-6 (its 22 problems of problems/, the suite and unseen
        # seeds 5, 36, 7, 101, 102; bench_planning_suite.py --set objective.tol=1e-6): the same
        # two lost, one of them now against the circle on two verdicts, a 3D range-only plan's
        # EKF RMSE 0.16x -> 0.51x the lawn-mower's, medians within 0.02, solves 2-5x longer
        ObjectiveKind("gramian-min-eig", "max", False, "average-and-final", 1e-8, "gramian", 1e-4),
        ObjectiveKind("gramian-log-det", "max", False, "average-and-final", 1e-8, "gramian", 1e-4),
        # lwo-condition's information form (exact Hessian): at N = 1000 (2D range-only), tol
        # 1e-8 took 580 iterations, 69 s CPU, 1e-6 231 and 30 s for a 5e-5 smaller objective
        ObjectiveKind("lwo-condition", "max", False, "average-and-final", 1e-8, "lwo", 1e-6),
        ObjectiveKind("kf-position-std", "min", True, "final", 1e-4, None),
    )
}
OBJECTIVES: tuple[str, ...] = tuple(OBJECTIVE_KINDS)
#: Default ``objective.pcrb_weight`` of ``kf-position-std``: the posterior CRB's weight beside
#: the KF's std, each relative to the reference path
#: (:func:`~obsplan.planning.objectives.estimator.covariance_expr` has the evidence).
KF_PCRB_WEIGHT = 1.0
#: The bound of ``objective.kf_guard`` when unset: the augmented KF's predicted position std
#: (mission mean and final) allowed, as a multiple of its value on the lawn-mower, applied by a
#: re-solve only to a plan that exceeds it (:mod:`obsplan.planning.objectives.guards`; the
#: evidence is in docs/problem-files.md).
KF_GUARD = 1.0
#: The bound of ``objective.ekf_guard`` when unset: the same for the EKF's bound (the posterior
#: CRB's position std) under an observability objective, applied to a plan whose bound exceeds
#: the lawn-mower's; below 1 because the EKF's error sits above its bound, so a plan held at
#: exactly the lawn-mower's bound ties its error at best (docs/problem-files.md, "The
#: estimators' guards", has the evidence).
EKF_GUARD = 0.95
#: Default ``objective.linearisation_bound`` [range stds] of the kinds in
#: :data:`LINEARISATION_KINDS` with ``weights = "information"`` (:mod:`obsplan.planning.
#: linearisation` has the evidence); 0 (off) for every other kind and form.
LINEARISATION_BOUND = 0.25
#: The objectives whose default bounds the EKF's linearisation stress: ``gramian-log-det``
#: (measured by ``benchmarks/bench_linearisation.py``, 1000 closed-loop runs: its plans lost the
#: EKF on 8 runs of 1000 on two suite geometries unbounded, 0-3 bounded). ``gramian-min-eig``
#: lost more with it (1 -> 5 and 2 -> 5 runs, EKF RMSE 0.34 -> 0.40 and 0.63 -> 0.74 m: its plans
#: close on the beacon along the line of sight however it is bounded, and the bound moved them to
#: worse local optima; those were its plans on the augmented system: on the linearised one, its
#: default, the bound changed nothing, 0.257 / 0.551 m unbounded, 0.250 / 0.552 bounded, none
#: lost), so it is off there. ``lwo-condition``'s two 2D suite plans are ahead of
#: the lawn-mower at 1000 runs unbounded (EKF RMSE 0.270 and 0.548 m against 0.488 and 0.718, no
#: run lost) since its node criterion holds the window's input; with each node's own input the
#: bound had moved them ahead (0.573 -> 0.474, 0.765 -> 0.642 m) but doubled the EKF final error
#: of ``suite/lwo-current-water-dvl.toml`` and took 1.4-11x the solve time, so it is off there.
LINEARISATION_KINDS: tuple[str, ...] = ("gramian-log-det",)
#: The Gramian kinds whose ``objective.system = "auto"`` (with information weights) is the
#: vehicle's model linearised about the path (:mod:`obsplan.observability.local_gramian`); the
#: others score the augmented model. Measured with ``benchmarks/bench_planning_suite.py`` (50
#: runs, batches to 400) on the 22 ``gramian-min-eig`` problems of ``problems/``,
#: ``problems/suite/`` and ``benchmarks/unseen_problems.py`` seeds 5, 36, 7, 101, 102: augmented,
#: 19 won every verdict and 3 lost (two 2D current problems, a 3D depth one); linearised with
#: its opening windows, 20 won, 2 lost (2D current with a water-profiling DVL: KF RMSE 1.10x
#: the lawn-mower's, where ``pcrb-position`` loses it too, 1.06x; KF final error 1.19x the
#: circle's), none with a diverging EKF. On the 22 ``gramian-log-det`` problems the augmented
#: model decided every verdict on 20 (2 ties), the linearised on 18 (4 ties, none lost, 8 solves
#: at the iteration limit): log-det stays augmented.
LINEARISED_KINDS: tuple[str, ...] = ("gramian-min-eig",)
#: Objectives that follow an estimator's covariance along the path and so have a time mode.
TIMED_OBJECTIVES: tuple[str, ...] = tuple(k for k, o in OBJECTIVE_KINDS.items() if o.timed)
#: Objectives for which a smaller value is better.
MINIMISED: tuple[str, ...] = tuple(k for k, o in OBJECTIVE_KINDS.items() if o.sense == "min")
#: ``beacon.motion`` values (the first is the default): a fixed beacon, a known path, a planned
#: surface craft (:mod:`obsplan.model.beacon`).
BEACON_MOTIONS: tuple[str, ...] = ("fixed", "path", "planned")
#: The ``[beacon]`` fields of a planned beacon's craft (refused for any other motion).
CRAFT_FIELDS: tuple[str, ...] = (
    "speed",
    "accel",
    "velocity",
    "area",
    "max_range",
    "min_distance",
)
#: ``vehicle.path``'s name for the mission's plain lawn-mower.
LAWNMOWER_PATH = "lawnmower"
#: ``validation.mode`` values (the first is the default).
VALIDATION_MODES: tuple[str, ...] = ("closed-loop", "open-loop")
#: ``validation.process_noise_model`` values (the first is the default).
PROCESS_NOISE_MODELS: tuple[str, ...] = ("physical", "paper-per-step")
#: ``objective.mode`` values; ``auto`` is ``final`` for kf-position-std (its historical meaning)
#: and ``average-and-final`` for pcrb-position (:attr:`ObjectiveKind.auto_mode`), which becomes
#: ``lines-and-final`` with survey lines
#: (:attr:`~obsplan.planning.problem.definition.PlanningProblem. objective_mode`).
MODES: tuple[str, ...] = (
    "auto",
    "final",
    "mission-average",
    "average-and-final",
    "lines",
    "lines-and-final",
)
#: The modes that average over survey lines (they need a [mission] with lines).
LINE_MODES: tuple[str, ...] = ("lines", "lines-and-final")


@dataclass(frozen=True)
class FieldSpec:
    """One documented field of the problem file."""

    name: str
    # "int", "float", "float-or-str", "bool", "str", "str-list", "float-list", "vec",
    # "vec-or-float", "hvec" (2 values), "hvec-or-float", "range", "area"; the mission's
    # "lines", "line-area", "points", "windows", "end"
    kind: str
    default: Any
    unit: str
    doc: str
    required: bool = False


_NONE = None
SCHEMA: dict[str, tuple[FieldSpec, ...]] = {
    "problem": (
        FieldSpec(
            "name",
            "str",
            "",
            "-",
            "Free-text name shown in reports and figure titles (default: file stem); at most "
            f"{budget.MAX_NAME_CHARS} characters.",
        ),
    ),
    "vehicle": (
        FieldSpec("dim", "int", 2, "-", "Spatial dimension n: 2 or 3."),
        FieldSpec(
            "sensors",
            "str-list",
            ["range"],
            "-",
            'Sensor names: "range" (required), "dvl-bottom" (alias "dvl"), "dvl-water", "depth".',
        ),
        FieldSpec(
            "current",
            "bool",
            False,
            "-",
            "Estimate an unknown constant ocean current v_f (state (p, v, v_f), eqs. 28-30).",
        ),
        FieldSpec(
            "current_velocity",
            "vec",
            _NONE,
            "m/s",
            "True current v_f of the validation's truth simulation; default zeros; non-zero "
            "only with current = true.",
        ),
        FieldSpec(
            "range_form",
            "str",
            "half-squared",
            "-",
            'Range output of the filters: "half-squared" (y = |p-b|^2/2, eq. 3) or "range".',
        ),
        FieldSpec(
            "path",
            "str",
            _NONE,
            "-",
            'With a moving beacon (beacon.motion other than "fixed"): the path the vehicle '
            "flies while the beacon is planned: a trajectory CSV (relative to the problem file; "
            't from 0 to horizon.duration) or "lawnmower" (the mission\'s plain lawn-mower '
            "baseline). Default none (the vehicle is planned).",
        ),
    ),
    "origin": (
        FieldSpec(
            "latitude",
            "float",
            _NONE,
            "deg",
            "WGS84 latitude of the origin of the local north-east-down frame (x north, y east, "
            "z down = depth; obsplan.model.frames). Needed by beacon.geodetic / start.geodetic; "
            "reports carry it and `obsplan export` writes geodetic waypoints with it.",
        ),
        FieldSpec("longitude", "float", _NONE, "deg", "WGS84 longitude of the origin."),
        FieldSpec(
            "altitude",
            "float",
            0.0,
            "m",
            "Ellipsoidal height of the depth-0 surface at the origin (depth = altitude - height).",
        ),
    ),
    "beacon": (
        FieldSpec("position", "vec", _NONE, "m", "Beacon position b (n values); default origin."),
        FieldSpec(
            "geodetic",
            "vec",
            _NONE,
            "deg, deg[, m]",
            "Instead of position: [latitude, longitude] (2D) or [latitude, longitude, depth] "
            "(3D) about [origin].",
        ),
        FieldSpec(
            "motion",
            "str",
            "fixed",
            "-",
            'How the beacon moves: "fixed" (at position), "path" (a known path: beacon.path), '
            'or "planned" (a surface craft obsplan plans: speed, accel, position its start, '
            "optional velocity, area, max_range, min_distance). Ranges are one-way travel "
            "times: the beacon is where it was when it transmitted.",
        ),
        FieldSpec(
            "path",
            "str",
            _NONE,
            "-",
            'motion = "path": the beacon path CSV t,bx,by[,bz] [s, m] in the problem\'s frame '
            "(relative to the problem file), linearly interpolated; it must cover the horizon.",
        ),
        FieldSpec(
            "speed",
            "float",
            _NONE,
            "m/s",
            'motion = "planned" (required): bound on the craft\'s horizontal speed.',
        ),
        FieldSpec(
            "accel",
            "hvec-or-float",
            _NONE,
            "m/s^2",
            'motion = "planned" (required): bound on the craft\'s horizontal acceleration per '
            "axis: one number or [ax, ay].",
        ),
        FieldSpec(
            "velocity",
            "hvec",
            _NONE,
            "m/s",
            'motion = "planned": the craft\'s start horizontal velocity [vx, vy]; default at rest.',
        ),
        FieldSpec(
            "area",
            "area",
            _NONE,
            "m",
            'motion = "planned": the area {x = [min, max], y = [min, max]} the craft must stay '
            "in; default anywhere.",
        ),
        FieldSpec(
            "max_range",
            "float",
            _NONE,
            "m",
            'motion = "planned": largest distance |p - b| from the craft to the vehicle (the '
            "acoustic link); default none.",
        ),
        FieldSpec(
            "min_distance",
            "float",
            0.0,
            "m",
            'motion = "planned": least horizontal distance from the craft to the vehicle '
            "(collision, surfacing); replaces limits.min_range for a planned beacon. 0 disables "
            "it.",
        ),
    ),
    "start": (
        FieldSpec("position", "vec", _NONE, "m", "Start position p(0) (n values).", True),
        FieldSpec("velocity", "vec", _NONE, "m/s", "Start inertial velocity p'(0); default zeros."),
        FieldSpec(
            "geodetic",
            "vec",
            _NONE,
            "deg, deg[, m]",
            "Instead of position (then not required): [latitude, longitude] (2D) or "
            "[latitude, longitude, depth] (3D) about [origin].",
        ),
    ),
    "limits": (
        FieldSpec(
            "accel",
            "vec-or-float",
            _NONE,
            "m/s^2",
            "Per-axis acceleration bound |u_i| <= a_i: one number for all axes or n values.",
            True,
        ),
        FieldSpec(
            "speed",
            "float",
            _NONE,
            "m/s",
            "Speed bound |p'| <= v_max (speed over ground; with a current choose it so that "
            "the speed through water stays feasible).",
            True,
        ),
        FieldSpec(
            "depth",
            "range",
            _NONE,
            "m",
            "3D only: [z_min, z_max] band for p_z on the whole continuous path; default none.",
        ),
        FieldSpec(
            "min_range",
            "float",
            5.0,
            "m",
            "Minimum distance |p-b| to the beacon on the whole continuous path (mooring, "
            "transducer blanking), to where it is at each time on a known beacon path; 0 "
            "disables it. The start must respect it.",
        ),
        FieldSpec(
            "max_range",
            "float",
            _NONE,
            "m",
            "Maximum distance |p-b| to the beacon (acoustic range) on the whole continuous "
            "path; default none.",
        ),
        FieldSpec(
            "min_speed",
            "float",
            0.0,
            "m/s",
            "Minimum speed through the water |p' - v_f| (v_f = vehicle.current_velocity) on the "
            "whole continuous path, for vehicles that cannot hover; the start velocity must "
            "respect it. 0 disables it.",
        ),
        FieldSpec(
            "keepout_confidence",
            "float",
            0.999,
            "-",
            "Confidence with which the true vehicle, steering its estimate onto the plan, keeps "
            "min_range, max_range, the area and the depth band: the plan keeps them with a "
            "margin k times a bound on the std of its true deviation from the plan (from the "
            "posterior CRB along the path and the guidance loop), k the normal quantile of the "
            "confidence (3.09 at 0.999). The same k sets the speed reserve: the guidance keeps "
            "the estimated speed k velocity stds of the EKF below limits.speed (at most 30 % of "
            "it) and the plan keeps the same reserve from the CRB. 0 disables the margins.",
        ),
        FieldSpec(
            "area",
            "area",
            _NONE,
            "m",
            "Operating area {x = [min, max], y = [min, max]} on the whole continuous path; "
            "the lawn-mower baseline covers it. Default none (the lawn-mower then covers a square "
            "of side speed*duration/4 centred on the start).",
        ),
    ),
    "horizon": (
        FieldSpec("duration", "float", _NONE, "s", "Planning horizon T_f.", True),
        FieldSpec(
            "steps",
            "int",
            _NONE,
            "-",
            "Number N of constant-acceleration intervals (N + 1 nodes), N >= 2.",
            True,
        ),
    ),
    "objective": (
        FieldSpec(
            "kind",
            "str",
            "pcrb-position",
            "-",
            "One of " + ", ".join(OBJECTIVES) + " (docs/problem-files.md has their formulations).",
        ),
        FieldSpec(
            "mode",
            "str",
            "auto",
            "-",
            'For pcrb-position and kf-position-std: "final" (position std at the end), '
            '"mission-average" (its time average over the mission), "average-and-final" (the '
            'sum of the two, each relative to its value on the lawn-mower), "lines" (its '
            "average over the planner's line windows: what the sonar data needs; needs a survey "
            '[mission]) or "lines-and-final" (the line average and the final value, each '
            "relative to its value on the planner's first start, the lawn-mower on its "
            'schedule); "auto" is average-and-final for '
            "pcrb-position (lines-and-final with survey lines) and final for kf-position-std.",
        ),
        FieldSpec(
            "starts",
            "int",
            4,
            "-",
            "Number of initial guesses: lawn-mower, circle, then seeded random ones.",
        ),
        FieldSpec("seed", "int", 0, "-", "Seed of the random initial guesses."),
        FieldSpec(
            "weights",
            "str",
            "information",
            "-",
            'For gramian-min-eig, gramian-log-det and lwo-condition: "information" (each output '
            "row scaled by its information rate, rate / variance; for the range of the "
            "linearised system 1/sigma_r^2, of the augmented one 1/(r^2 sigma_r^2 + sigma_r^4/2) "
            "with r from the path, for gramian-log-det 1/((r^2 + r_0^2) sigma_r^2 + sigma_r^4) "
            'with r_0 the start\'s: the augmented output subtracts the first range) or "none" '
            "(the paper's unit weights; for lwo-condition the scale-free conditioning of the LWO "
            "matrix, a diagnostic).",
        ),
        FieldSpec(
            "system",
            "str",
            "auto",
            "-",
            "For gramian-min-eig and gramian-log-det: the model whose Gramian is scored. "
            '"linearised": the vehicle\'s own model linearised about the path (the local '
            "observability Gramian, what an EKF on the path extracts: a range informs the "
            'position along its line of sight, 1/sigma_r^2 at any distance); "augmented": the '
            "paper's augmented LTV model (eqs. 14-27, the augmented KF's model); \"auto\" is "
            'linearised for gramian-min-eig with weights = "information", augmented otherwise '
            "(gramian-log-det won as often on the augmented model, with fewer ties: "
            "docs/problem-files.md).",
        ),
        FieldSpec(
            "window",
            "float-or-str",
            "auto",
            "s",
            "For gramian-min-eig and gramian-log-det: length of the sliding windows whose "
            "Gramians are scored (for lwo-condition: the past window each node's information "
            'is gathered over, clipped at the start); "auto" is 2 tau_f, '
            "tau_f = (3 sigma_r^2 / q_v)^(1/3) from the validation's velocity process noise "
            'q_v (at least 10 range samples, at most the horizon); "mission" is one window '
            'over the whole horizon (with weights = "none" the paper\'s G(t_N, t_0), eq. 25).',
        ),
        FieldSpec(
            "stride",
            "float-or-str",
            "auto",
            "s",
            'Spacing of the windows; "auto" is window / 8 (at least one planning step).',
        ),
        FieldSpec(
            "anchor",
            "str",
            "current",
            "-",
            'State each window\'s Gramian is about: "start" (observability of the state at the '
            'window\'s start) or "current" (constructibility of the state at its end; the final '
            "window then counts as much as the mean of all windows).",
        ),
        FieldSpec("max_iter", "int", 1000, "-", "IPOPT iteration limit per start."),
        FieldSpec(
            "tol",
            "float",
            _NONE,
            "-",
            "IPOPT convergence tolerance (tol) of the NLP, whose objective is normalised to 1 on "
            "the lawn-mower; default 1e-8, or 1e-4 for pcrb-position, kf-position-std and the "
            "windowed Gramian objectives (L-BFGS "
            "converges slowly: at N = 1000, 1e-5 takes 5x the iterations for a 0.4 % better "
            "bound), or 1e-6 for lwo-condition's information form (at N = 1000, 1e-8 took "
            "2.3x the CPU time for a 0.005 % better objective).",
        ),
        FieldSpec(
            "robust_prior",
            "float-list",
            (),
            "-",
            "Robust planning (pcrb-position, kf-position-std): multiples of the validation's "
            "prior std (init_pos_error, init_vel_error) to plan for, e.g. [1, 5]; every "
            "combination with robust_range_noise is a condition. Default none (plan for the "
            "stated prior only).",
        ),
        FieldSpec(
            "robust_range_noise",
            "float-list",
            (),
            "-",
            "Robust planning: multiples of validation.range_std to plan for, e.g. [1, 3]. "
            "Default none.",
        ),
        FieldSpec(
            "robust_aggregate",
            "str",
            "worst",
            "-",
            'How the conditions combine: "worst" (the largest of the objectives, each relative '
            'to its value on the lawn-mower; an epigraph) or "mean" (their mean).',
        ),
        FieldSpec(
            "pcrb_weight",
            "float",
            _NONE,
            "-",
            "For kf-position-std: weight of the posterior CRB of the position (the nonlinear "
            "model's bound, what an EKF can reach; as pcrb-position in its default mode) beside "
            "the KF's position std (in objective.mode), each relative to its value on the "
            "lawn-mower: the objective is K/K_lm + w B/B_lm (1 + w on the lawn-mower); default "
            "1; 0: the KF's std alone. The KF's augmented model alone plans paths the EKF "
            "cannot follow (docs/problem-files.md).",
        ),
        FieldSpec(
            "linearisation_bound",
            "float",
            _NONE,
            "sigma_r",
            "Bound on the EKF's linearisation stress b = tr((I - u u^T) P_pp) / (2 r), the mean "
            "of the range's curvature over the prior (u the line of sight, r the range, P_pp "
            "the predicted position covariance of the posterior CRB at every range epoch), in "
            "range standard deviations: the plan pays a quadratic penalty where b "
            'exceeds it. Default 0.25 for gramian-log-det with weights = "information" (its '
            "plans crept along the line of sight and lost the EKF on a few runs in 1000), 0 "
            "(off) otherwise (gramian-min-eig lost more with it, lwo-condition won and lost "
            "with it: docs/problem-files.md); set for an objective with an exact Hessian "
            "(lwo-condition, the paper's forms), IPOPT gets that Hessian without the "
            "penalty's curvature (the recursion's is dense).",
        ),
        FieldSpec(
            "kf_guard",
            "float",
            _NONE,
            "-",
            "Bound on the augmented KF's predicted position std along the plan (its mission "
            "mean and its final value, the exact Riccati recursion of the validation's KF), as "
            "a multiple of its value on the lawn-mower: the plan pays a quadratic penalty above "
            "it, so that an objective scoring the EKF's information does not trade the KF "
            "away. Unset (default): a plan whose predicted KF std exceeds the lawn-mower's is "
            "re-solved with the bound at 1 (report.json solver.kf_guard says so); a number g > 0: "
            "the penalty in every solve; 0: off. Not for kf-position-std (it plans for the KF) "
            "or a beacon that moves.",
        ),
        FieldSpec(
            "ekf_guard",
            "float",
            _NONE,
            "-",
            "Bound on the EKF's bound along the plan (the posterior CRB's position std, its "
            "mission mean and its final value), as a multiple of its value on the lawn-mower: "
            "the plan pays a quadratic penalty above it, so that an observability objective "
            "does not raise the Gramian or the LWO conditioning where the EKF's error gets "
            "worse than on the lawn-mower. Unset (default): a plan whose posterior CRB exceeds "
            "the lawn-mower's is re-solved with the bound at 0.95, the EKF's error sitting "
            "above its bound (report.json solver.ekf_guard says so); a number g > 0: the "
            "penalty in every solve; 0: off. Only for the "
            "observability objectives (pcrb-position and kf-position-std plan for the bound "
            "already) and a fixed beacon.",
        ),
    ),
    "scales": (
        FieldSpec(
            "length_m",
            "float",
            100.0,
            "m",
            "Length scale L of the Gramian metrics and objectives (obsplan.observability.scaling).",
        ),
        FieldSpec("time_s", "float", 100.0, "s", "Time scale T of the Gramian metrics."),
    ),
    "mission": (
        FieldSpec(
            "kind",
            "str",
            "survey",
            "-",
            'What the vehicle must do besides localising: "survey" (fly lines) or "waypoints" '
            "(pass points in order); any kind may add an end region. Without a [mission] the "
            "problem is free localisation.",
        ),
        FieldSpec(
            "lines",
            "lines",
            _NONE,
            "m",
            "Survey lines [[x0, y0, x1, y1], ...] (2D) or [[x0, y0, z0, x1, y1, z1], ...] (3D, "
            "level: z0 = z1), each flown from its first point to its second, in this order; at "
            f"most {budget.MAX_LINES} lines.",
        ),
        FieldSpec(
            "area",
            "line-area",
            _NONE,
            "m",
            "Instead of lines: generate them over {x = [min, max], y = [min, max]} or "
            "{polygon = [[x, y], ...]} with spacing and heading (rule in docs/problem-files.md); "
            f"a polygon of at most {budget.MAX_POLYGON_CORNERS} corners.",
        ),
        FieldSpec(
            "spacing",
            "float",
            _NONE,
            "m",
            "Distance between generated lines; at most "
            f"{budget.MAX_LINES} lines (the area's width across the heading / spacing, counted "
            "before any line is generated).",
        ),
        FieldSpec(
            "heading",
            "float",
            0.0,
            "deg",
            "Direction of generated lines, clockwise from north (x) to east (y): 90 flies east.",
        ),
        FieldSpec(
            "depth",
            "float",
            _NONE,
            "m",
            "3D only: depth z of generated lines; default the start depth.",
        ),
        FieldSpec(
            "altitude",
            "range",
            _NONE,
            "m",
            "3D surveys: [lo, hi] band of the altitude above mission.seabed held on the lines; "
            "the lines are then horizontal tracks [x0, y0, x1, y1] (or generated), flown at the "
            "band's middle with their depth following the seabed; cross_track is then the "
            "horizontal distance from the track. Excludes mission.depth.",
        ),
        FieldSpec(
            "seabed",
            "seabed",
            _NONE,
            "m",
            "With mission.altitude: a planar seabed {depth = d, slope = [sx, sy]}, its depth "
            "d + sx x + sy y [m] (z down; slope in m of depth per m, default [0, 0]).",
        ),
        FieldSpec(
            "cross_track",
            "float",
            2.0,
            "m",
            "Largest distance from a line while flying it, on the continuous path.",
        ),
        FieldSpec(
            "heading_tol",
            "float",
            10.0,
            "deg",
            "Largest angle between the velocity and the line's direction while flying it.",
        ),
        FieldSpec(
            "speed",
            "range",
            _NONE,
            "m/s",
            "[lo, hi] band of the speed on the lines (and of the lawn-mower's constant speed); "
            "default [0.3, 1] * limits.speed; hi <= limits.speed.",
        ),
        FieldSpec(
            "order",
            "str",
            "given",
            "-",
            '"given" (lines in the order given) or "free" (the planner reorders and reverses '
            "the lines for the shortest transits between them, which leaves the most time on "
            "the lines; the lawn-mowers fly the same order).",
        ),
        FieldSpec(
            "shift",
            "float",
            0.0,
            "-",
            "How far each survey line's window may shift: the line may start and end up to this "
            "fraction of its scheduled time earlier or later (within half the time to the "
            "neighbouring lines); 0 flies the schedule's fixed windows. In [0, 0.5).",
        ),
        FieldSpec(
            "lead_in",
            "float-or-str",
            "auto",
            "s",
            "Surveys: time at the start, before the first line, in which the planner localises "
            "(its lines are then flown faster than the lawn-mower's, in the same horizon). "
            '"auto": the time saved by scheduling the lines halfway from the lawn-mower\'s speed '
            "to the top of mission.speed (0 without speed headroom); 0: the lawn-mower's windows.",
        ),
        FieldSpec(
            "waypoints",
            "points",
            _NONE,
            "m",
            'kind = "waypoints": points [[x, y(, z)], ...] passed in order; at most '
            f"{budget.MAX_WAYPOINTS}.",
        ),
        FieldSpec("radius", "float", 5.0, "m", "Each waypoint is passed within this distance."),
        FieldSpec(
            "windows",
            "windows",
            _NONE,
            "s",
            "Optional time windows [[t0, t1], ...], one per waypoint.",
        ),
        FieldSpec(
            "end",
            "end",
            _NONE,
            "m, m/s",
            "End region {position = [x, y(, z)], radius = r, speed = s}: |p(T) - position| <= r "
            "at the horizon's end and, if speed is given, |v(T)| <= s.",
        ),
    ),
    "validation": (
        FieldSpec(
            "runs",
            "int",
            50,
            "-",
            f"Monte Carlo runs per trajectory (EKF and KF); at most {budget.MAX_RUNS:,}, within "
            "OBSPLAN_MAX_MEMORY and OBSPLAN_MAX_HOURS.",
        ),
        FieldSpec("seed", "int", 0, "-", "Seed of the Monte Carlo runs (same for every path)."),
        FieldSpec(
            "dt", "float", 0.1, "s", "Filter prediction step; must divide the planning step."
        ),
        FieldSpec("range_rate", "float", 1.0, "Hz", "Range measurement rate."),
        FieldSpec("range_std", "float", 0.1, "m", "Range noise standard deviation (on |p-b|)."),
        FieldSpec("dvl_rate", "float", 10.0, "Hz", "DVL rate (if a DVL is fitted)."),
        FieldSpec("dvl_std", "float", 1e-3, "m/s", "DVL noise standard deviation per axis."),
        FieldSpec("depth_rate", "float", 1.0, "Hz", "Depth gauge rate (if fitted)."),
        FieldSpec("depth_std", "float", 0.1, "m", "Depth noise standard deviation."),
        FieldSpec(
            "init_pos_error",
            "float",
            1.0,
            "m",
            "Initial position error standard deviation per axis (filters' prior and draws).",
        ),
        FieldSpec(
            "init_vel_error",
            "float",
            0.1,
            "m/s",
            "Initial velocity error standard deviation per axis.",
        ),
        FieldSpec(
            "accel_noise",
            "float",
            DEFAULT_ACCEL_NOISE,
            "m/s^2/sqrt(Hz)",
            "Intensity of the white acceleration noise on each axis (truth, filters, bound and "
            "the planner's objective alike), discretised exactly for any dt; the default adds "
            "the paper's velocity variance (1e-3 dt)^2 per step at dt = 0.1 s. 0: no process "
            "noise.",
        ),
        FieldSpec(
            "process_noise_model",
            "str",
            "physical",
            "-",
            'How process noise enters: "physical" (accel_noise, independent of dt) or '
            '"paper-per-step" (the paper\'s Q = diag(1e-3 dt)^2 per filter step, section 7, '
            "whose intensity changes with dt; accel_noise is then ignored).",
        ),
        FieldSpec(
            "mode",
            "str",
            "closed-loop",
            "-",
            'How the Monte Carlo flies every path: "closed-loop" (the vehicle steers its '
            "estimate (`navigation`) onto the path: feed-forward of the path's acceleration plus "
            'feedback saturated at the limits) or "open-loop" (the accelerations flown blind).',
        ),
        FieldSpec(
            "ekf_update",
            "str",
            "second-order",
            "-",
            "The range update of the EKF and of the Gaussian sum's components (the filters "
            'the vehicle steers on, `navigation`): "second-order" (the Gaussian second-order '
            "filter: the range's curvature over the prior adds its mean to the prediction and "
            "its variance to the reading's; steadier where the position std nears "
            "sqrt(2 r sigma_r): wide priors, long range-only legs, close passes) or "
            '"first-order" (the paper\'s EKF).',
        ),
        FieldSpec(
            "navigation",
            "str",
            "gsf",
            "-",
            'The filter the vehicle steers on in closed loop: "gsf" (the Gaussian-sum EKF\'s '
            'mixture mean: it keeps the branches of the range geometry) or "ekf" (a vehicle '
            "whose EKF locks onto a wrong branch flies off with it: its error enters the true "
            "path). The EKF and KF of the verdicts run on the same true path and readings.",
        ),
        FieldSpec(
            "max_runs",
            "int",
            400,
            "-",
            "Cap on the runs of the validation: starting from `runs`, batches doubling the "
            "runs are added until every verdict of the plan against a baseline (EKF and KF RMSE "
            "and final error) is decided at 95 % confidence (paired bootstrap interval of the "
            "ratio excluding 1) or the cap is reached (the undecided ones are ties). At most "
            f"`runs`: one batch. At most {budget.MAX_RUNS:,}, within OBSPLAN_MAX_MEMORY and "
            "OBSPLAN_MAX_HOURS (checked before any run).",
        ),
        FieldSpec(
            "stress_prior",
            "float",
            1.0,
            "-",
            "Robustness row of the report: every path re-validated, without replanning, with "
            "the prior std (init_pos_error, init_vel_error) times this. With stress_range_noise "
            "both 1 (the default), no robustness row.",
        ),
        FieldSpec(
            "stress_range_noise",
            "float",
            1.0,
            "-",
            "Robustness row: the range noise is range_std times this (the world the plan "
            "meets; the filters are configured for it, as for the stress prior).",
        ),
        FieldSpec(
            "stress_channel",
            "str",
            _NONE,
            "-",
            "Robustness row: every path re-validated, without replanning, with its ranges "
            'through this acoustic channel ("ideal" or "at-sea", with the channel_* fields as '
            "for `channel`; the gate and the scale state follow it as for `channel`). Default "
            "none (the row's channel is `channel`).",
        ),
        FieldSpec(
            "channel",
            "str",
            "ideal",
            "-",
            'The acoustic channel the truth\'s ranges go through, unknown to the filters: "ideal" '
            '(Gaussian ranges) or "at-sea" (10 % multipath outliers late by 2-30 m, 20 % of '
            "pings lost, a 1 % sound-speed scale error; the problem's own range_rate). The "
            'channel_* fields change one fault of the preset (docs/validation.md, "The '
            'acoustic channel").',
        ),
        FieldSpec(
            "channel_dropout",
            "float",
            _NONE,
            "-",
            "Probability that a ping is lost, in [0, 1); default the preset's.",
        ),
        FieldSpec(
            "channel_dropout_range",
            "float",
            _NONE,
            "m",
            "Range beyond which the loss probability grows linearly, to 1 at twice this range; "
            "default none (no growth).",
        ),
        FieldSpec(
            "channel_outlier_fraction",
            "float",
            _NONE,
            "-",
            "Probability that a range is a late multipath arrival, in [0, 1); default the "
            "preset's.",
        ),
        FieldSpec(
            "channel_outlier_excess",
            "range",
            _NONE,
            "m",
            "[min, max] of the excess path of a late arrival (uniform, >= 0); default [2, 30].",
        ),
        FieldSpec(
            "channel_sound_speed_scale",
            "float",
            _NONE,
            "-",
            "Relative sound-speed error s: every range is multiplied by 1 + s; default the "
            "preset's.",
        ),
        FieldSpec(
            "channel_clock_offset",
            "float",
            _NONE,
            "s",
            "Clock offset between beacon and vehicle: a range bias of 1500 m/s times it; "
            "default 0.",
        ),
        FieldSpec(
            "channel_ping_jitter",
            "float",
            _NONE,
            "s",
            "A ping leaves up to this much before or after its stamp (uniform), unknown to the "
            "filters: a range error of the range rate times it; default 0.",
        ),
        FieldSpec(
            "gate",
            "float-or-str",
            "auto",
            "-",
            "The filters' innovation gate on the ranges (chi-square, 1 dof; re-acquisition "
            'after 5 rejections in a row): a confidence in (0, 1), "off", or "auto" (0.999 '
            "when the channel has outliers, off otherwise).",
        ),
        FieldSpec(
            "scale_state",
            "str",
            "auto",
            "-",
            "A range-scale state (a sound-speed error, prior std 2 %) in the EKF, the "
            'Gaussian sum and the augmented KF: "on", "off", or "auto" (on when the channel is '
            "not ideal).",
        ),
        FieldSpec(
            "bias_state",
            "str",
            "auto",
            "-",
            "A range-bias state (a clock offset, prior std 3 m) in the EKF, the Gaussian sum "
            'and the augmented KF: "on", "off", or "auto" (on when the channel has a clock '
            "offset).",
        ),
        FieldSpec(
            "range_times",
            "str",
            _NONE,
            "-",
            "A ping schedule: a CSV with a column t [s from the mission's start] (relative to "
            "the problem file; e.g. the range times of a logged mission): the validation, the "
            "bounds and the planner's pcrb/kf objectives take the ranges there (the first filter "
            "step at or after each ping) instead of every 1/range_rate; range_rate must then be "
            "its mean rate over the horizon (within a factor 1.5: the Gramian and LWO objectives "
            "weigh ranges by it). Default none (the rate).",
        ),
    ),
}


def schema_markdown() -> str:
    """The field tables of ``docs/problem-files.md`` (one per section), from :data:`SCHEMA`.

    Returns
    -------
    str
        Markdown: per section a level-3 heading naming it and a table of its fields (name,
        unit, default, meaning).
    """
    out: list[str] = []
    for section, fields in SCHEMA.items():
        out.append(f"### `[{section}]`\n")
        out.append("| field | unit | default | meaning |")
        out.append("|---|---|---|---|")
        for f in fields:
            if f.required:
                default = "**required**"
            elif f.default is None:
                default = "see meaning"
            else:
                default = repr(f.default).replace("'", '"')
                default = default.replace("True", "true").replace("False", "false")
            doc = f.doc.replace("|", "\\|")
            out.append(f"| `{f.name}` | {f.unit} | {default} | {doc} |")
        out.append("")
    return "\n".join(out)


#: First line of the generated field tables in a document, per heading level.
_TABLES_START = re.compile(r"^(#+) `\[problem\]`$", re.M)


def update_field_tables(text: str) -> str:
    """``text`` (a Markdown document) with its field tables regenerated from :data:`SCHEMA`.

    The tables run from the heading of ``[problem]`` (any level: ``###`` in
    ``docs/problem-files.md``) to the end of the last section's table; everything else is kept.
    Regenerate the document after editing :data:`SCHEMA`::

        from pathlib import Path
        from obsplan.planning.problem.schema import update_field_tables
        doc = Path("docs/problem-files.md")
        doc.write_text(update_field_tables(doc.read_text()))

    Parameters
    ----------
    text : str
        The Markdown document.

    Returns
    -------
    str
        The document with the tables replaced by :func:`schema_markdown`'s, at the heading level
        found.

    Raises
    ------
    ValueError
        If the document has no ``[problem]`` field table.
    """
    m = _TABLES_START.search(text)
    if m is None:
        raise ValueError("no field tables (a heading `[problem]`) in the document")
    level = m.group(1)
    pos = text.index(f"{level} `[{list(SCHEMA)[-1]}]`", m.start())
    pos = text.index("\n|", pos) + 1  # the last section's table ...
    while text.startswith("|", pos):  # ... ends at its first line that is not a row
        nl = text.find("\n", pos)
        pos = len(text) if nl < 0 else nl + 1
    generated = schema_markdown().replace("### `", f"{level} `")
    return text[: m.start()] + generated + text[pos:]
