"""``plan(problem)``: solve, compare with the baselines, validate by Monte Carlo."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from obsplan.estimation.runs import DEFAULT_FILTERS
from obsplan.planning.baselines import Baseline, baselines, unfitted_baselines
from obsplan.planning.evaluate import PathMetrics, path_metrics
from obsplan.planning.margins import KeepoutReport, solve_with_keepout
from obsplan.planning.parse import load_problem, problem_to_dict
from obsplan.planning.problem import PlanningProblem
from obsplan.planning.solve import SolveResult
from obsplan.planning.stress import Robustness, stress_active, stress_validate
from obsplan.planning.validation import PathValidation
from obsplan.planning.verdict import Verdict, ekf_diverges, validate_until_decided, verdict
from obsplan.trajectory import Trajectory


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
        (:mod:`obsplan.planning.margins`).
    robustness : Robustness or None
        Every path re-validated at ``validation.stress_*`` (:mod:`obsplan.planning.stress`).
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

    @property
    def verdict(self) -> Verdict:
        """The plan against every validated baseline (:mod:`obsplan.planning.verdict`)."""
        return verdict(self.validation, self.not_fitted, self.problem.objective.kind)

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
            },
            "baselines": {k: b.description for k, b in self.baselines.items()},
            "baselines_not_fitted": dict(self.not_fitted),
            "problem_file": problem_to_dict(pb),
            "keepout": None if self.keepout is None else self.keepout.to_dict(),
            "robustness": None if self.robustness is None else self.robustness.to_dict(),
            "wall_s": float(self.wall_s),
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
        (:func:`~obsplan.planning.verdict.validate_until_decided`).
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
    validation: dict[str, PathValidation] = {}
    if validate:
        validation = validate_until_decided(
            paths, pb, runs=runs, max_runs=max_runs, progress=progress
        )
        if "planned" in validation and ekf_diverges(validation["planned"]):
            # the EKF is lost on the plan while the KF is not: validate the Gaussian-sum filter
            # beside them on every path (same seeds and runs), so the report says what a robust
            # filter does there
            n = int(validation["planned"].result.runs)
            filters = (*DEFAULT_FILTERS, "gsf")
            validation = validate_until_decided(
                paths, pb, runs=n, max_runs=n, progress=progress, filters=filters
            )
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
    )
