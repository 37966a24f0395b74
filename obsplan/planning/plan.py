"""``plan(problem)``: solve, compare with the baselines, validate by Monte Carlo."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from obsplan.planning.baselines import Baseline, baselines
from obsplan.planning.metrics import PathMetrics, path_metrics
from obsplan.planning.problem import PlanningProblem, load_problem
from obsplan.planning.solve import SolveResult, solve
from obsplan.trajectory import Trajectory
from obsplan.validation import PathValidation, validate_paths


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
    """

    problem: PlanningProblem
    solve: SolveResult
    baselines: dict[str, Baseline]
    metrics: dict[str, PathMetrics]
    validation: dict[str, PathValidation]
    wall_s: float

    @property
    def success(self) -> bool:
        return self.solve.success and self.trajectory is not None

    @property
    def trajectory(self) -> Trajectory | None:
        """The planned path on the planning grid (None if no feasible path was found)."""
        return self.solve.trajectory

    def paths(self) -> dict[str, Trajectory]:
        """``planned`` (when found) then every baseline."""
        out: dict[str, Trajectory] = {}
        if self.trajectory is not None:
            out["planned"] = self.trajectory
        out.update({k: b.trajectory for k, b in self.baselines.items()})
        return out

    def to_dict(self) -> dict:
        """``report.json`` (PRODUCT.md stable keys ``solver``, ``metrics``, ``validation``)."""
        pb = self.problem
        return {
            "solver": self.solve.to_dict(),
            "metrics": {k: m.to_dict() for k, m in self.metrics.items()},
            "validation": {k: v.to_dict() for k, v in self.validation.items()},
            "problem": {
                "name": pb.name,
                "dim": pb.dim,
                "sensors": list(pb.vehicle.sensors),
                "current": pb.vehicle.current,
                "objective": pb.objective.kind,
                "steps": pb.horizon.steps,
                "duration_s": pb.horizon.duration,
                "scales": {"length_m": pb.scales.length_m, "time_s": pb.scales.time_s},
            },
            "baselines": {k: b.description for k, b in self.baselines.items()},
            "wall_s": float(self.wall_s),
        }


def plan(
    problem: PlanningProblem | str | Path | None = None,
    *,
    validate: bool = True,
    runs: int | None = None,
    progress: bool = False,
    verbose: bool = False,
) -> PlanResult:
    """Solve a planning problem and compare the plan with the baselines.

    Parameters
    ----------
    problem
        A :class:`PlanningProblem`, a path to a problem TOML, or None for ``problems/default.toml``.
    validate
        Run the EKF/KF Monte Carlo on the plan and every baseline.
    runs
        Override ``validation.runs``.
    progress
        Progress lines on stderr.
    verbose
        IPOPT output.

    Returns
    -------
    PlanResult
        ``success`` is False when no start converged (the best feasible iterate, if any, is still
        reported, flagged by ``solve.status``).
    """
    import sys

    t0 = time.perf_counter()
    pb = problem if isinstance(problem, PlanningProblem) else load_problem(problem)
    if progress:
        print(
            f"obsplan plan: {pb.name or 'problem'}: {pb.objective.kind}, N = {pb.horizon.steps}, "
            f"{pb.objective.starts} starts",
            file=sys.stderr,
        )
    res = solve(pb, progress=progress, verbose=verbose)
    bls = baselines(pb)
    paths: dict[str, Trajectory] = {}
    if res.trajectory is not None:
        paths["planned"] = res.trajectory
    paths.update({k: b.trajectory for k, b in bls.items()})
    metrics = {k: path_metrics(tr, pb) for k, tr in paths.items()}
    validation: dict[str, PathValidation] = {}
    if validate:
        for name, tr in paths.items():
            if progress:
                print(f"  validating {name} ...", file=sys.stderr, flush=True)
            validation.update(validate_paths({name: tr}, pb, runs=runs))
    return PlanResult(
        problem=pb,
        solve=res,
        baselines=bls,
        metrics=metrics,
        validation=validation,
        wall_s=time.perf_counter() - t0,
    )
