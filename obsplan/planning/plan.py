"""``plan(problem)``: solve, compare with the baselines, validate by Monte Carlo;
``validate(trajectory, problem)``: the same comparison and validation of a given path.

Both build their result (:mod:`obsplan.planning.results`) through one function, :func:`_assess`
(the baselines' metrics, the mission checks, the Monte Carlo in batches until decided, the
Gaussian-sum filter when the EKF is lost, the robustness row), so that a path validated by
:func:`validate` gets exactly the numbers :func:`plan` reported for it (same settings, runs and
seeds).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import Protocol

import numpy as np

from obsplan.core.errors import ConfigError, ProblemError, field_error
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.runs import DEFAULT_FILTERS
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.planning.baselines.beacon import beacon_baselines, craft_limit_breaks
from obsplan.planning.baselines.vehicle import Baseline, baselines, unfitted_baselines
from obsplan.planning.beacon import range_epoch_times
from obsplan.planning.beacon_replan import beacon_replan_monte_carlo, beacon_replan_times
from obsplan.planning.missions.check import mission_check
from obsplan.planning.objectives.evaluate import path_metrics
from obsplan.planning.objectives.robust import is_robust
from obsplan.planning.problem.checks import vehicle_path
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import load_problem
from obsplan.planning.problem.schema import LAWNMOWER_PATH
from obsplan.planning.problem.sections import BeaconMotion
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.planning.replan import replan_guidance, replan_monte_carlo, replan_nodes
from obsplan.planning.results import (
    ALONE,
    BeaconBound,
    BeaconPlanResult,
    BeaconSolve,
    JointPlan,
    PlanResult,
    ValidationResult,
)
from obsplan.planning.solver.margins import craft_distance_margins, solve_with_keepout
from obsplan.planning.solver.solve import GUESS_STATUS
from obsplan.planning.transcription.guesses import initial_guesses
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.stress import stress_active, stress_validate
from obsplan.planning.validation.validate import PathValidation
from obsplan.planning.validation.verdict import ekf_diverges, validate_until_decided
from obsplan.trajectory.sampled import Trajectory, resample


def plan(
    problem: PlanningProblem | str | Path | None = None,
    *,
    validate: bool = True,
    runs: int | None = None,
    max_runs: int | None = None,
    progress: bool = False,
    verbose: bool = False,
    processes: int | None = None,
    replan: float | None = None,
) -> PlanResult:
    """Solve a planning problem and compare the plan with the baselines.

    The beacon is fixed, or on a known path (``beacon.motion = "path"``, objective
    ``pcrb-position``, ``KNOWN_PATH_OBJECTIVES``): the vehicle is then planned knowing where
    the beacon will be (:class:`~obsplan.planning.transcription.grid.Grid`), and the plan and
    every baseline are validated with the beacon on its path.

    Parameters
    ----------
    problem : PlanningProblem or str or Path or None, default None
        A :class:`PlanningProblem`, a problem file or a shipped problem's name
        (:func:`~obsplan.planning.problem.parse.load_problem`), or None for the default problem.
    validate : bool, default True
        Run the EKF/KF Monte Carlo on the plan and every baseline (in closed loop unless
        ``validation.mode = "open-loop"``), adding batches of runs until every verdict is
        decided or ``validation.max_runs`` is reached
        (:func:`~obsplan.planning.validation.verdict.validate_until_decided`); :func:`validate`
        repeats it on any path.
    runs : int or None, default None
        Override ``validation.runs`` (the first batch).
    max_runs : int or None, default None
        Override ``validation.max_runs`` (the cap on the runs).
    progress : bool, default False
        Progress bars (tqdm, on stderr) for the starts and the validation.
    verbose : bool, default False
        IPOPT output.
    processes : int or None, default None
        Worker processes for the multi-start and the replanned Monte Carlo (None: one per core,
        at most one per start; 1: all in this process, e.g. inside a Dask worker).
    replan : float or None, default None
        Also validate with receding-horizon replanning every ``replan`` seconds (a multiple of
        the planning step; :func:`~obsplan.planning.replan.replan_monte_carlo`, ``obsplan plan
        --replan``); needs ``validate``. Default: no replanning.

    Returns
    -------
    PlanResult
        ``success`` is True exactly when the flown path is a converged solution (IPOPT's
        ``Solve_Succeeded``) of the problem it was last solved for, ``solve.status`` saying which;
        otherwise the best feasible path, if any, is still reported. ``summary()``, ``plot()``,
        ``save()`` and ``to_dict()`` give what ``obsplan plan`` prints, draws and writes.

    Raises
    ------
    ProblemError
        A problem file that does not load, or a ``replan`` period that does not fit the grid.

    Examples
    --------
    The free localisation problem on a coarse horizon, one start, without the Monte Carlo
    validation:

    >>> from obsplan import load_problem, plan
    >>> pb = load_problem("localise").with_changes(horizon={"steps": 20}, objective={"starts": 1})
    >>> result = plan(pb, validate=False)
    >>> result.trajectory.n_samples, len(result.baselines) > 0
    (21, True)
    >>> print(result.summary().splitlines()[-1])
    no validation was run: nothing says the plan localises better
    """
    t0 = time.perf_counter()
    pb = problem if isinstance(problem, PlanningProblem) else load_problem(problem)
    _fixed_only(pb, "plan")
    if replan is not None and pb.beacon_motion.moving:
        raise field_error(
            "beacon.motion", '"path": replanning with a moving beacon is not built yet; no replan'
        )
    if replan is not None:
        if not validate:
            raise ProblemError(
                "replan re-solves inside the validation: pass validate=True, or no replan"
            )
        replan_nodes(pb, replan)  # a bad period is refused before any work
    bls = baselines(pb)
    res, keepout = solve_with_keepout(
        pb, baselines=bls, progress=progress, verbose=verbose, processes=processes
    )
    checked = _assess(res.trajectory, pb, bls, validate, runs, max_runs, progress)
    rep = None
    if replan is not None and res.trajectory is not None:
        rep = replan_monte_carlo(
            res.problem,  # the guarded problem when the KF's guard engaged: re-solves keep it
            res.trajectory,
            replan,
            baselines={k: b.trajectory for k, b in bls.items()},
            runs=runs,
            processes=processes,
            progress=progress,
        )
    return PlanResult(
        **{f.name: getattr(checked, f.name) for f in fields(checked)},
        solve=res,
        wall_s=time.perf_counter() - t0,
        keepout=keepout,
        replan=rep,
    )


def validate(
    trajectory: Trajectory,
    problem: PlanningProblem | str | Path | None = None,
    *,
    runs: int | None = None,
    max_runs: int | None = None,
    progress: bool = False,
) -> ValidationResult:
    """Validate a path against the problem's baselines exactly as :func:`plan` validates its
    plan.

    The path is flown as ``"planned"`` beside every baseline of the problem, with the problem's
    ``[validation]`` (closed loop unless ``validation.mode = "open-loop"``, its filters, noises,
    prior and seed), in batches of runs until every verdict is decided or
    ``validation.max_runs`` is reached, with the Gaussian-sum filter beside the EKF and KF when
    the EKF is lost on the path; then the robustness row when ``validation.stress_*`` asks for
    it. ``obsplan.validate(obsplan.read_csv("plan.csv"), problem)`` reproduces the numbers of
    that plan's ``report.json`` (its ``validation``, ``verdict``, ``metrics``) to the last digit.
    Use it, not :func:`~obsplan.estimation.montecarlo.simulate.monte_carlo` (open loop and the
    EKF settings of its :class:`~obsplan.estimation.config.EstimationConfig` by default), to
    re-check a plan.

    Parameters
    ----------
    trajectory : Trajectory
        The path, on the problem's planning grid (``plan.csv``; any grid whose steps
        ``validation.dt`` divides runs, but the metrics and the baselines are the planning
        grid's).
    problem : PlanningProblem or str or Path or None, default None
        A :class:`PlanningProblem`, a problem file or a shipped problem's name, or None for the
        default problem.
    runs : int or None, default None
        Override ``validation.runs`` (the first batch), as :func:`plan`'s ``runs``.
    max_runs : int or None, default None
        Override ``validation.max_runs``, as :func:`plan`'s ``max_runs``.
    progress : bool, default False
        A progress bar (tqdm, on stderr) over the runs.

    Returns
    -------
    ValidationResult
        ``validation``, ``metrics``, ``verdict`` and the rest as :func:`plan` reports them for
        its plan; ``summary()``, ``plot()``, ``to_dict()`` and ``save()`` as for a plan.

    Examples
    --------
    A plan of a short horizon, validated again: the same numbers.

    >>> from obsplan import load_problem, plan, validate
    >>> pb = load_problem("localise").with_changes(
    ...     horizon={"duration": 120, "steps": 40},
    ...     objective={"starts": 1},
    ...     validation={"runs": 4, "max_runs": 4},
    ... )
    >>> result = plan(pb)
    >>> again = validate(result.trajectory, pb)
    >>> again.to_dict()["validation"] == result.to_dict()["validation"]
    True
    """
    pb = problem if isinstance(problem, PlanningProblem) else load_problem(problem)
    _fixed_only(pb, "validate")
    return _assess(trajectory, pb, baselines(pb), True, runs, max_runs, progress)


def _fixed_only(pb: PlanningProblem, verb: str) -> None:
    """Refuse a planned beacon in :func:`plan` / :func:`validate` (they plan and validate the
    vehicle, for a fixed beacon or one on a known path), pointing to what handles it."""
    if pb.beacon_motion.moving:
        check_beacon_plannable(pb)
        if pb.beacon_motion.motion == "path":
            return
        raise field_error(
            "beacon.motion",
            f'"{pb.beacon_motion.motion}": {verb}() is for a fixed beacon; a planned beacon (for '
            "a vehicle on a given path, or jointly with it) is planned and validated by "
            "plan_moving_beacon (obsplan plan does it)",
        )


class BeaconPlanner(Protocol):
    """A beacon planner: ``obsplan.planning.beacon.plan_beacon``'s signature."""

    def __call__(
        self,
        vehicle: Trajectory,
        craft: BeaconVehicle,
        config: EstimationConfig,
        *,
        weights: np.ndarray | None = None,
        guesses: Sequence[BeaconPath] = (),
        guess_labels: Sequence[str] | None = None,
        truth_margins: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> BeaconSolve: ...


#: Most rounds of joint planning (the vehicle for the beacon, then the beacon for the vehicle).
#: Each round costs a vehicle solve and a beacon solve; a second round is run only when the
#: first lowered the objective by more than JOINT_TOL.
JOINT_ROUNDS = 2
#: Least relative decrease of the beacon planner's objective for a round to be kept: the beacon
#: planner's own tolerance (SOLVER_TOL, 1e-4 relative) ten times over, so that a kept round is a
#: change of the paths, not of where IPOPT stopped.
JOINT_TOL = 1e-3

#: The objectives a vehicle is planned with for a beacon on a known path: those that see only
#: the positions relative to the beacon at the range epochs (the grid's sample operator takes
#: the beacon where it is then).
KNOWN_PATH_OBJECTIVES: tuple[str, ...] = ("pcrb-position",)


def check_beacon_plannable(pb: PlanningProblem) -> None:
    """Refuse a moving-beacon problem ``obsplan plan`` cannot plan, saying what it can.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Raises
    ------
    ProblemError
        A vehicle planned for a moving beacon (``beacon.motion = "path"``, or ``"planned"``
        without ``vehicle.path``: planned jointly with the beacon) with an objective other than
        ``pcrb-position`` (the others see the relative velocity or input, or a fixed beacon's
        KF, and are not built for a moving beacon), or robust.
    """
    bm = pb.beacon_motion
    if bm.motion == "path" or (bm.motion == "planned" and pb.vehicle.path is None):
        what = (
            'a beacon on a known path (beacon.motion = "path")'
            if bm.motion == "path"
            else 'the vehicle planned jointly with the beacon (beacon.motion = "planned" without '
            'vehicle.path; give vehicle.path = "lawnmower" to plan the beacon alone)'
        )
        if pb.objective.kind not in KNOWN_PATH_OBJECTIVES:
            raise field_error(
                "objective.kind",
                f'"{pb.objective.kind}" is not built for {what}; supported: '
                f"{', '.join(KNOWN_PATH_OBJECTIVES)}",
            )
        if is_robust(pb):
            raise field_error(
                "objective.robust_prior",
                f"robust planning is not built for {what}; remove objective.robust_prior and "
                "objective.robust_range_noise",
            )


def vehicle_trajectory(pb: PlanningProblem) -> Trajectory:
    """The path the vehicle flies while the beacon is planned (``vehicle.path``), or, planned
    jointly (no ``vehicle.path``), the path it flies with the beacon baselines.

    Parameters
    ----------
    pb : PlanningProblem
        A problem with a planned beacon.

    Returns
    -------
    Trajectory
        ``"lawnmower"`` or no ``vehicle.path``: the problem's lawn-mower baseline (its mission's
        plain lawn-mower); else the trajectory CSV
        (:func:`~obsplan.planning.problem.checks.vehicle_path`).

    Raises
    ------
    ProblemError
        On ``vehicle.path``: a lawn-mower that does not fit the problem.
    """
    name = pb.vehicle.path or LAWNMOWER_PATH
    if name != LAWNMOWER_PATH:
        return vehicle_path(pb)
    bls = baselines(pb)
    if "lawnmower" not in bls:
        why = unfitted_baselines(pb).get("lawnmower", "it does not fit")
        raise field_error("vehicle.path", f'"lawnmower": no lawn-mower fits the problem: {why}')
    return bls["lawnmower"].trajectory


def plan_moving_beacon(
    problem: PlanningProblem | str | Path | None,
    planner: BeaconPlanner,
    *,
    validate: bool = True,
    runs: int | None = None,
    max_runs: int | None = None,
    progress: bool = False,
    replan: float | None = None,
    processes: int | None = 1,
) -> BeaconPlanResult:
    """Plan the beacon's craft for a vehicle flying a given path, or both jointly, and validate
    the plan against the beacon baselines.

    The vehicle flies ``vehicle.path`` (:func:`vehicle_trajectory`); the beacon baselines
    (:func:`~obsplan.planning.baselines.beacon.beacon_baselines`) are built first and given to
    ``planner`` as its initial guesses, with weight 1 on the range epochs the vehicle flies on
    its survey lines (all epochs without lines). Then every beacon path is validated as a fixed
    beacon's plan is: the vehicle's filters in Monte Carlo (closed loop unless
    ``validation.mode = "open-loop"``) on the same path with that beacon, the same runs and seeds
    for every beacon (paired), in batches until each verdict is decided at 95 % or
    ``validation.max_runs`` is reached.

    Without ``vehicle.path`` the vehicle is planned too (``objective.kind = "pcrb-position"``,
    its mission and limits): from its lawn-mower and the beacon planned for it, rounds plan the
    vehicle for the beacon's path (:func:`vehicle_problem`), then the beacon for the vehicle's,
    while each lowers the beacon planner's objective (:data:`JOINT_ROUNDS`, :data:`JOINT_TOL`).
    The baselines' beacons then serve the vehicle on its lawn-mower (what it would fly without
    obsplan) and the plan is the pair: ``baseline_vehicle`` and ``joint`` of the result say so.

    Parameters
    ----------
    problem : PlanningProblem or str or Path or None
        A problem with ``beacon.motion = "planned"`` (or its file or shipped name).
    planner : callable
        The beacon planner (:class:`BeaconPlanner`).
    validate : bool, default True
        Run the Monte Carlo validation.
    runs, max_runs : int or None, default None
        Override ``validation.runs`` and ``validation.max_runs``.
    progress : bool, default False
        Progress bars.
    replan : float or None, default None
        Also validate with the craft re-planning every ``replan`` seconds from the vehicle's
        estimate (a multiple of the craft's planning step;
        :func:`~obsplan.planning.beacon_replan.beacon_replan_monte_carlo`, ``obsplan plan
        --replan``), for a vehicle on ``vehicle.path`` only; needs ``validate``.
    processes : int or None, default 1
        Worker processes of the replanned Monte Carlo (None: one per core).

    Returns
    -------
    BeaconPlanResult
        The planned beacon, the baselines, their bounds and validations, the verdict (and the
        replanned Monte Carlo with ``replan``).

    Raises
    ------
    ProblemError
        A problem whose beacon is not planned, or that cannot be planned
        (:func:`check_beacon_plannable`), or a ``replan`` that cannot be run
        (:func:`check_beacon_replan`).
    """
    t0 = time.perf_counter()
    pb = problem if isinstance(problem, PlanningProblem) else load_problem(problem)
    if pb.beacon_motion.motion != "planned":
        raise field_error(
            "beacon.motion",
            f'"{pb.beacon_motion.motion}": the beacon is not planned; plan the vehicle with '
            "obsplan.plan",
        )
    check_beacon_plannable(pb)
    if replan is not None:
        if not validate:
            raise ProblemError(
                "replan re-plans the craft inside the validation: pass validate=True, or no replan"
            )
        check_beacon_replan(pb, replan)  # before any work
    result = _plan_beacon_flow(pb, planner, validate, runs, max_runs, progress, t0)
    if replan is None:
        return result
    _, config = _craft_config(pb)
    fine_v, _, mask_v = _on_lines(pb, result.vehicle, config)
    rep = beacon_replan_monte_carlo(
        pb,
        fine_v,
        result.solve,
        replan,
        config,
        mask=mask_v,
        runs=runs,
        processes=processes,
        progress=progress,
    )
    return replace(result, replan=rep, wall_s=time.perf_counter() - t0)


def _plan_beacon_flow(
    pb: PlanningProblem,
    planner: BeaconPlanner,
    validate: bool,
    runs: int | None,
    max_runs: int | None,
    progress: bool,
    t0: float,
) -> BeaconPlanResult:
    """:func:`plan_moving_beacon` without the replanning: plan (alone or jointly), keep the
    craft out, validate against the baselines (``t0``: when the flow began, for its times)."""
    craft, config = _craft_config(pb)
    base = vehicle_trajectory(pb)
    fine, weights, mask = _on_lines(pb, base, config)
    bls = beacon_baselines(
        fine, craft, config, centre=_survey_centre(pb), weights=mask, step=pb.validation.dt
    )
    solve = planner(
        fine,
        craft,
        config,
        weights=weights,
        guesses=[b.path for b in bls.values()],
        guess_labels=list(bls),
    )
    vehicle, joint, first = base, None, solve
    if pb.vehicle.path is None:
        # the rounds start from the craft planned alone before the truth margins, as each
        # round's craft is (the margins come once, below); the alone plan is compared as obsplan
        # would fly it, kept out like the pair
        first, _ = _keep_craft_out(pb, planner, fine, craft, config, weights, solve)
        vehicle, solve, joint = _plan_jointly(pb, planner, craft, config, base, solve, progress)
    fine_v, weights_v, mask_v = _on_lines(pb, vehicle, config)
    alone = None if joint is None else first.path
    solve, margin = _keep_craft_out(pb, planner, fine_v, craft, config, weights_v, solve)
    others = {} if alone is None else {ALONE: alone}
    others.update({k: b.path for k, b in bls.items()})
    beacons = {"planned": solve.path, **others}
    bounds = {"planned": _bound(fine_v, replace(config, beacon_path=solve.path), mask_v)}
    bounds.update(
        {k: _bound(fine, replace(config, beacon_path=b), mask) for k, b in others.items()}
    )
    vehicles = {"planned": vehicle, **{k: base for k in others}}
    masks = None
    if mask is not None and mask_v is not None:
        masks = {"planned": mask_v, **{k: mask for k in others}}
    planning_s = time.perf_counter() - t0
    validation = {}
    if validate:
        validation = _validate_beacons(vehicles, pb, beacons, runs, max_runs, progress, masks)
        extra = measured_excess(validation["planned"], pb)
        if extra > 0:
            # the true paths strayed further than the linear loop predicts (the EKF above its
            # bound, the feedback saturated): once, the margin grows by what the runs measured
            # and the craft is re-planned and validated again (same runs and seeds)
            again, wider = _keep_craft_out(
                pb,
                planner,
                fine_v,
                craft,
                config,
                weights_v,
                solve,
                extra * (1.0 + tuning().inflate),
            )
            if again is not solve:
                solve, margin = again, wider
                beacons["planned"] = solve.path
                bounds["planned"] = _bound(fine_v, replace(config, beacon_path=solve.path), mask_v)
                validation = _validate_beacons(
                    vehicles, pb, beacons, runs, max_runs, progress, masks
                )
    return BeaconPlanResult(
        problem=pb,
        vehicle=vehicle,
        solve=solve,
        baselines=bls,
        bounds=bounds,
        validation=validation,
        lines=mask is not None,
        wall_s=time.perf_counter() - t0,
        planned_breaks=craft_limit_breaks(solve.path, solve.velocities, craft, fine_v),
        planning_s=planning_s,
        distance_margin_m=margin,
        baseline_vehicle=None if joint is None else base,
        joint=joint,
        beacon_alone=alone,
    )


def check_beacon_replan(pb: PlanningProblem, every: float) -> None:
    """Refuse a ``--replan`` of a planned beacon that cannot be run, before any work.

    Parameters
    ----------
    pb : PlanningProblem
        A problem with ``beacon.motion = "planned"``.
    every : float
        The replanning period [s].

    Raises
    ------
    ConfigError
        Joint planning (no ``vehicle.path``), open-loop validation, or a period that is not a
        positive multiple of the craft's planning step shorter than the horizon less one step
        (each message names ``--replan`` and the fix).
    """
    if pb.vehicle.path is None:
        raise ConfigError(
            "--replan re-plans the beacon's craft for a vehicle on a given path; the vehicle "
            'planned jointly with the beacon is not replanned: give vehicle.path (e.g. "lawnmower")'
            " to plan the beacon alone, or drop --replan"
        )
    replan_guidance(pb)  # closed loop only
    _, config = _craft_config(pb)
    fine = resample(vehicle_trajectory(pb), pb.validation.dt)
    if beacon_replan_times(fine, config, every).size == 0:
        raise ConfigError(
            f"--replan EVERY = {every!r} s leaves no replan time: it must be shorter than the "
            f"horizon ({float(fine.t[-1] - fine.t[0]):g} s) less one planning step of the craft"
        )


def _craft_config(pb: PlanningProblem) -> tuple[BeaconVehicle, EstimationConfig]:
    """A planned beacon's craft and the vehicle's estimation configuration (its beacon path
    the craft holding its start: the sensors, rates and noises; each flow sets its own path)."""
    craft = pb.beacon_vehicle
    if craft is None:  # a planned beacon always has its craft (sections.ProblemData)
        raise field_error("beacon.speed", "missing: the craft's limits of a planned beacon")
    hold = BeaconPath.fixed(craft.start.tolist(), 0.0, pb.horizon.duration)
    return craft, estimation_config(pb, hold)


def _on_lines(
    pb: PlanningProblem, vehicle: Trajectory, config: EstimationConfig
) -> tuple[Trajectory, np.ndarray | None, np.ndarray | None]:
    """The vehicle's path on the filter's step, the beacon planner's weights (1 on the range
    epochs the vehicle flies on its survey lines; None without lines: all equal) and the mask
    of the filter's samples on the lines (None without lines)."""
    fine = resample(vehicle, pb.validation.dt)
    chk = mission_check(vehicle, pb.mission_context)
    if chk is None or not chk.lines:
        return fine, None, None
    weights = chk.line_mask(range_epoch_times(fine, config)).astype(float)
    return fine, weights, chk.line_mask(fine.t)


def vehicle_problem(pb: PlanningProblem, beacon: BeaconPath) -> PlanningProblem:
    """The vehicle's planning problem for a planned beacon's path: ``pb`` with the beacon on that
    known path (``beacon.motion = "path"``, given in memory) and no distance to keep from it.

    The distances between the two are the craft's limits (``beacon.min_distance`` and
    ``beacon.max_range``), kept by the craft when it is planned for the vehicle's path: the
    craft is the faster of the two and the one that keeps clear, as a support vessel keeps clear
    of the vehicle it serves. Held on the vehicle's side too, the keep-out is a moving obstacle
    next to the path the vehicle must fly (the craft's best path passes close to it), and IPOPT
    ends locally infeasible from the feasible lawn-mower.

    Parameters
    ----------
    pb : PlanningProblem
        A problem with ``beacon.motion = "planned"``.
    beacon : BeaconPath
        The craft's path, covering the horizon.

    Returns
    -------
    PlanningProblem
        Checked; without ``vehicle.path``; ``limits.min_range = 0``.
    """
    return replace(
        pb,
        beacon_motion=BeaconMotion(motion="path", path=beacon),
        limits=replace(pb.limits, min_range=0.0),
        vehicle=replace(pb.vehicle, path=None),
    )


def _plan_jointly(
    pb: PlanningProblem,
    planner: BeaconPlanner,
    craft: BeaconVehicle,
    config: EstimationConfig,
    lawnmower: Trajectory,
    first: BeaconSolve,
    progress: bool,
) -> tuple[Trajectory, BeaconSolve, JointPlan]:
    """Block-coordinate descent from the lawn-mower and the beacon planned for it: each round
    plans the vehicle for the beacon's path (its mission, limits and objective,
    :func:`~obsplan.planning.solver.margins.solve_with_keepout`), then the beacon for that path
    (warm from the beacon before), and is kept when the beacon planner's objective falls by more
    than :data:`JOINT_TOL`; at most :data:`JOINT_ROUNDS` rounds."""
    vehicle, beacon, vsolve = lawnmower, first, None
    objectives = [float(first.objective) if first.objective is not None else math.inf]
    stop = f"{JOINT_ROUNDS} rounds"
    for _ in range(JOINT_ROUNDS):
        pbv = vehicle_problem(pb, beacon.path)
        guesses = [*initial_guesses(pbv), ("vehicle before", resample(vehicle, pbv.horizon.dt))]
        res, _ = solve_with_keepout(
            pbv, guesses=guesses, baselines=baselines(pbv), progress=progress
        )
        if res.trajectory is None or not res.success:
            stop = (
                "the vehicle's solve found no path better than the one before"
                if res.status == GUESS_STATUS
                else f"the vehicle's solve did not converge ({res.status})"
            )
            break
        fine, weights, _ = _on_lines(pb, res.trajectory, config)
        again = planner(
            fine, craft, config, weights=weights, guesses=[beacon.path], guess_labels=["before"]
        )
        new = math.inf if again.objective is None else float(again.objective)
        if not again.success or new > objectives[-1] * (1.0 - JOINT_TOL):
            stop = (
                f"the beacon's solve did not converge ({again.status})"
                if not again.success
                else f"a round lowered the objective by less than {JOINT_TOL:.1%}"
            )
            break
        vehicle, beacon, vsolve = res.trajectory, again, res
        objectives.append(new)
    return vehicle, beacon, JointPlan(vehicle_solve=vsolve, objectives=tuple(objectives), stop=stop)


def _keep_craft_out(
    pb: PlanningProblem,
    planner: BeaconPlanner,
    fine: Trajectory,
    craft: BeaconVehicle,
    config: EstimationConfig,
    weights: np.ndarray | None,
    nominal: BeaconSolve,
    extra: float = 0.0,
) -> tuple[BeaconSolve, float]:
    """The craft re-planned warm from ``nominal`` so that its distance limits hold against the
    vehicle's *true* path at ``limits.keepout_confidence``: the fixed beacon's rule (a margin from
    the closed loop's predicted deviation, then a re-solve), with the vehicle's CRB computed with
    the nominal craft's beacon (the re-planned craft moves the CRB little: it keeps the same
    objective); ``extra`` [m] is added to both margins (what a validation measured). Returns the
    plan kept (``nominal`` itself when the re-solve fails or no margin is needed) and the largest
    margin on ``min_distance`` [m] (0: none)."""
    if craft.min_distance <= 0 and craft.max_range is None:
        return nominal, 0.0
    with_craft = replace(config, beacon_path=nominal.path)
    m = craft_distance_margins(posterior_crlb(fine, with_craft), pb, with_craft)
    if m.k == 0:
        return nominal, 0.0
    again = planner(
        fine,
        craft,
        config,
        weights=weights,
        guesses=[nominal.path],
        guess_labels=["nominal + truth margins"],
        truth_margins=(m.t, m.horizontal + extra, m.range + extra),
    )
    if not again.success:
        return nominal, 0.0
    return again, float(np.max(m.horizontal, initial=0.0)) + extra


def measured_excess(validation: PathValidation, pb: PlanningProblem) -> float:
    """How far [m] the Monte Carlo's true vehicle paths broke the craft's distance limits beyond
    what ``limits.keepout_confidence`` allows: the largest excess over ``min_distance`` and
    ``max_range`` when more than ``(1 - confidence)`` of the runs broke one, else 0.

    Parameters
    ----------
    validation : PathValidation
        The planned beacon's validation (its ``truth`` statistics).
    pb : PlanningProblem
        The problem: ``limits.keepout_confidence``.

    Returns
    -------
    float
        The excess [m]; 0 without truth statistics, without a stated confidence, or within it.
    """
    tr = validation.result.truth
    conf = float(pb.limits.keepout_confidence)
    if tr is None or tr.limits is None or conf <= 0:
        return 0.0
    viol = tr.violations()
    out = 0.0
    for k in ("min_range", "max_range"):
        if k in viol and np.mean(viol[k]) > 1.0 - conf:
            out = max(out, float(tr.worst_excess.get(k, 0.0)))
    return out


def _validate_beacons(
    vehicles: dict[str, Trajectory],
    pb: PlanningProblem,
    beacons: dict[str, BeaconPath],
    runs: int | None,
    max_runs: int | None,
    progress: bool,
    masks: dict[str, np.ndarray] | None,
) -> dict[str, PathValidation]:
    """Each vehicle path with its beacon, paired, in batches until decided."""
    return validate_until_decided(
        vehicles,
        pb,
        runs=runs,
        max_runs=max_runs,
        progress=progress,
        lines=masks,
        beacons=beacons,
    )


def _survey_centre(pb: PlanningProblem) -> np.ndarray | None:
    """The horizontal centre of the mission's lines (None without lines)."""
    m = pb.mission
    if m is None or not m.lines:
        return None
    pts = np.array([q[:2] for a, b in m.segments(pb.dim) for q in (a, b)], float)
    return 0.5 * (pts.min(axis=0) + pts.max(axis=0))


def _bound(fine: Trajectory, config: EstimationConfig, mask: np.ndarray | None) -> BeaconBound:
    std = posterior_crlb(fine, config).pos_std_t
    lines = None if mask is None or not np.any(mask) else float(np.mean(std[mask]))
    return BeaconBound(float(np.mean(std)), lines, float(std[-1]))


def _assess(
    trajectory: Trajectory | None,
    pb: PlanningProblem,
    bls: dict[str, Baseline],
    validate: bool,
    runs: int | None,
    max_runs: int | None,
    progress: bool,
) -> ValidationResult:
    """The path (as ``planned``) beside the baselines: metrics, mission checks, validation and
    robustness, as :func:`plan` reports them."""
    paths: dict[str, Trajectory] = {}
    if trajectory is not None:
        paths["planned"] = trajectory
    paths.update({k: b.trajectory for k, b in bls.items()})
    metrics = {k: path_metrics(tr, pb) for k, tr in paths.items()}
    missions = {
        k: c for k, tr in paths.items() if (c := mission_check(tr, pb.mission_context)) is not None
    }
    lines = {k: c.line_mask(pb.filter_times) for k, c in missions.items() if c.lines}
    validation = _validate(paths, pb, runs, max_runs, progress, lines) if validate else {}
    robustness = None
    if validate and stress_active(pb):
        robustness = stress_validate(paths, pb, runs=runs, progress=progress)
    return ValidationResult(
        problem=pb,
        trajectory=trajectory,
        baselines=bls,
        metrics=metrics,
        validation=validation,
        not_fitted=unfitted_baselines(pb),
        robustness=robustness,
        missions=missions,
    )


def _validate(
    paths: dict[str, Trajectory],
    pb: PlanningProblem,
    runs: int | None,
    max_runs: int | None,
    progress: bool,
    lines: dict,
) -> dict[str, PathValidation]:
    """The validation of :func:`plan`: batches until decided, with the Gaussian-sum filter beside
    the EKF and KF on every path when the EKF is lost on the plan."""
    validation = validate_until_decided(
        paths, pb, runs=runs, max_runs=max_runs, progress=progress, lines=lines or None
    )
    planned = validation.get("planned")
    has_gsf = planned is not None and "gsf" in (planned.result.filters or {})
    if planned is not None and ekf_diverges(planned) and not has_gsf:
        # the EKF is lost on the plan while the KF is not: validate the Gaussian-sum filter
        # beside them on every path (same seeds and runs), so the report says what a robust
        # filter does there
        n = int(validation["planned"].result.runs)
        validation = validate_until_decided(
            paths,
            pb,
            runs=n,
            max_runs=n,
            progress=progress,
            filters=(*DEFAULT_FILTERS, "gsf"),
            lines=lines or None,
        )
    return validation
