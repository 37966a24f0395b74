"""``plan(problem)``: solve, compare with the baselines, validate by Monte Carlo."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from obsplan.estimation.montecarlo.runs import DEFAULT_FILTERS
from obsplan.planning.baselines.vehicle import Baseline, baselines, unfitted_baselines
from obsplan.planning.missions.check import MissionCheck, mission_check
from obsplan.planning.missions.schedule import mission_schedule, planner_schedule
from obsplan.planning.objectives.evaluate import PathMetrics, path_metrics
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import load_problem, problem_to_dict
from obsplan.planning.solver.margins import KeepoutReport, solve_with_keepout
from obsplan.planning.solver.solve import SolveResult
from obsplan.planning.validation.stress import Robustness, stress_active, stress_validate
from obsplan.planning.validation.validate import PathValidation
from obsplan.planning.validation.verdict import (
    Verdict,
    ekf_diverges,
    objective_notes,
    stress_notes,
    validate_until_decided,
    verdict,
)
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True, eq=False)
class PlanResult:
    """Everything ``obsplan plan`` reports.

    Attributes
    ----------
    problem : PlanningProblem
    solve : SolveResult
        Multi-start outcome (status, iterations, wall time, every start).
    baselines : dict[str, Baseline]
    metrics : dict[str, PathMetrics]
        ``"planned"`` (if a path was found) and every baseline, computed the same way.
    validation : dict[str, PathValidation]
        Monte Carlo per path (empty when not run).
    wall_s : float
        Total time [s].
    not_fitted : dict[str, str]
        Baselines the problem cannot fit, with the reason.
    keepout : KeepoutReport or None
        How the plan keeps its limits with the keep-out margins
        (:mod:`obsplan.planning.solver.margins`).
    robustness : Robustness or None
        Every path re-validated at ``validation.stress_*``
        (:mod:`obsplan.planning.validation.stress`).
    """

    problem: PlanningProblem
    solve: SolveResult
    baselines: dict[str, Baseline]
    metrics: dict[str, PathMetrics]
    validation: dict[str, PathValidation]
    wall_s: float
    not_fitted: dict[str, str] = field(default_factory=dict)
    keepout: KeepoutReport | None = None
    robustness: Robustness | None = None
    #: Per path, the independent mission check (empty without a ``[mission]``).
    missions: dict[str, MissionCheck] = field(default_factory=dict)

    @property
    def verdict(self) -> Verdict:
        """The plan against every validated baseline (:mod:`obsplan.planning.validation.verdict`);
        with a mission, only against the paths that complete it."""
        val = dict(self.validation)
        not_fitted = dict(self.not_fitted)
        for name, chk in self.missions.items():
            if not chk.complete and name in val and name != "planned":
                del val[name]
                not_fitted[name] = "does not complete the mission (not compared)"
        survey = self.problem.mission is not None and bool(self.problem.mission.lines)
        runs = int(val["planned"].result.runs) if "planned" in val else 0
        notes = (*objective_notes(self.problem), *stress_notes(self.metrics, runs))
        return verdict(
            val,
            not_fitted,
            notes,
            lines=survey,
            keepout_confidence=self.problem.limits.keepout_confidence,
        )

    @property
    def success(self) -> bool:
        return self.solve.success and self.trajectory is not None

    @property
    def trajectory(self) -> Trajectory | None:
        """The planned path on the planning grid (None if no feasible path was found)."""
        return self.solve.trajectory

    def validation_dict(self) -> dict:
        """``report.json``'s ``validation``: ``mode`` (``"closed-loop"`` or ``"open-loop"``)
        and one entry per validated path (empty when no validation was run)."""
        if not self.validation:
            return {}
        return {
            "mode": self.problem.validation.mode,
            **{k: v.to_dict() for k, v in self.validation.items()},
        }

    def paths(self) -> dict[str, Trajectory]:
        """``planned`` (when found) then every baseline."""
        out: dict[str, Trajectory] = {}
        if self.trajectory is not None:
            out["planned"] = self.trajectory
        out.update({k: b.trajectory for k, b in self.baselines.items()})
        return out

    def to_dict(self) -> dict:
        """``report.json`` (stable keys ``solver``, ``metrics``, ``validation``)."""
        pb = self.problem
        return {
            "solver": self.solve.to_dict(),
            "metrics": {k: m.to_dict() for k, m in self.metrics.items()},
            "validation": self.validation_dict(),
            "verdict": self.verdict.to_dict(),
            "problem": {
                "name": pb.name,
                "dim": pb.dim,
                "sensors": list(pb.vehicle.sensors),
                "current": pb.vehicle.current,
                "objective": pb.objective.kind,
                "objective_mode": pb.objective_mode,
                "steps": pb.horizon.steps,
                "duration_s": pb.horizon.duration,
                "scales": {"length_m": pb.scales.length_m, "time_s": pb.scales.time_s},
                "schedule": _schedule_dict(pb),
            },
            "baselines": {k: b.description for k, b in self.baselines.items()},
            "baselines_not_fitted": dict(self.not_fitted),
            "mission": {k: c.to_dict() for k, c in self.missions.items()},
            "problem_file": problem_to_dict(pb),
            "keepout": None if self.keepout is None else self.keepout.to_dict(),
            "robustness": None if self.robustness is None else self.robustness.to_dict(),
            "wall_s": float(self.wall_s),
        }


def _schedule_dict(pb: PlanningProblem) -> dict | None:
    """The mission's schedules: the lawn-mower's speed, the planner's line speed and lead-in."""
    if pb.mission is None:
        return None
    base, lead = mission_schedule(pb.mission_context), planner_schedule(pb.mission_context)
    return {
        "lawnmower_speed_mps": float(base.speed),
        "planner_speed_mps": float(lead.speed),
        "lead_in_s": float(lead.lead_in),
        "headroom": float(base.headroom),
    }


def plan(
    problem: PlanningProblem | str | Path | None = None,
    *,
    validate: bool = True,
    runs: int | None = None,
    max_runs: int | None = None,
    progress: bool = False,
    verbose: bool = False,
    processes: int | None = None,
) -> PlanResult:
    """Solve a planning problem and compare the plan with the baselines.

    Parameters
    ----------
    problem
        A :class:`PlanningProblem`, a path to a problem TOML, or None for ``problems/default.toml``.
    validate
        Run the EKF/KF Monte Carlo on the plan and every baseline (in closed loop unless
        ``validation.mode = "open-loop"``), adding batches of runs until every verdict is
        decided or ``validation.max_runs`` is reached
        (:func:`~obsplan.planning.validation.verdict.validate_until_decided`).
    runs
        Override ``validation.runs`` (the first batch).
    max_runs
        Override ``validation.max_runs`` (the cap on the runs).
    progress
        Progress bars (tqdm, on stderr) for the starts and the validation.
    verbose
        IPOPT output.
    processes
        Worker processes for the multi-start (None: one per core, at most one per start; 1: all
        starts in this process, e.g. inside a Dask worker).

    Returns
    -------
    PlanResult
        ``success`` is False when no start converged (the best feasible iterate, if any, is still
        reported, flagged by ``solve.status``).

    Examples
    --------
    The free localisation problem on a coarse horizon, one start, without the Monte Carlo
    validation:

    >>> from dataclasses import replace
    >>> from obsplan import load_problem, plan
    >>> from obsplan.planning.problem.parse import LOCALISE_PROBLEM
    >>> from obsplan.planning.problem.sections import Horizon
    >>> pb = load_problem(LOCALISE_PROBLEM)
    >>> pb = replace(pb, horizon=Horizon(duration=pb.horizon.duration, steps=20),
    ...              objective=replace(pb.objective, starts=1))
    >>> result = plan(pb, validate=False)
    >>> result.solve.trajectory.n_samples, len(result.baselines) > 0
    (21, True)
    """
    t0 = time.perf_counter()
    pb = problem if isinstance(problem, PlanningProblem) else load_problem(problem)
    bls = baselines(pb)
    res, keepout = solve_with_keepout(
        pb, baselines=bls, progress=progress, verbose=verbose, processes=processes
    )
    paths: dict[str, Trajectory] = {}
    if res.trajectory is not None:
        paths["planned"] = res.trajectory
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
    return PlanResult(
        problem=pb,
        solve=res,
        baselines=bls,
        metrics=metrics,
        validation=validation,
        wall_s=time.perf_counter() - t0,
        not_fitted=unfitted_baselines(pb),
        keepout=keepout,
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
