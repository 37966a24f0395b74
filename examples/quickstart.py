"""Quickstart: plan an observable path, check its observability, run the filters on it.

Plans a path for the default problem (``problems/default.toml``: 2D, one beacon at the origin,
range only, the paper's Fig. 3 start) on a short horizon, compares it with the lawn-mower flown
under the same limits, analyses it (both observability verdicts) and runs the EKF and the
augmented KF on it by Monte Carlo. Runs in well under a minute; ``--quick`` (or
``OBSPLAN_QUICK=1``) shrinks it further, for tests.

    python examples/quickstart.py [--quick]
"""

from __future__ import annotations

import os
import sys

from obsplan import analyze
from obsplan.estimation import monte_carlo
from obsplan.planning import estimation_config, load_problem, plan
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.sections import Horizon, ObjectiveSpec
from obsplan.trajectory.sampled import resample


def main(quick: bool = False) -> None:
    # 1. the problem: the default one, on a shorter horizon with fewer planning steps
    problem = load_problem(LOCALISE_PROBLEM).with_changes(
        horizon=Horizon(duration=300.0, steps=20 if quick else 50),
        objective=ObjectiveSpec(kind="pcrb-position", starts=1 if quick else 2),
    )
    # 2. plan: multi-start IPOPT minimising the posterior Cramer-Rao bound of the position
    #    (mission average and final value, each relative to the lawn-mower's)
    result = plan(problem, validate=False)
    path = result.trajectory
    if path is None:
        raise SystemExit(f"planning failed: {result.solve.status}")
    planned, mower = result.metrics["planned"], result.metrics["lawnmower"]
    print(f"solver: {result.solve.status}, {result.solve.iterations} iterations")
    print(
        f"mission-average bound: planned {planned.pcrb_mean_pos_std:.4g} m, "
        f"lawn-mower {mower.pcrb_mean_pos_std:.4g} m"
    )
    print(f"objective: planned {planned.objective:.4g}, lawn-mower {mower.objective:.4g}")
    # 3. analyse: local (LWO) and global (Gramian) observability of the planned path
    report = analyze(path, sensors=problem.vehicle.sensors).to_dict()
    print(f"LWO along the path: {report['lwo']['along_trajectory']}")
    print(f"Gramian full rank: {report['gramian']['full_rank']}")
    # 4. simulate: EKF and augmented KF, Monte Carlo with the problem's sensors and noises
    sim = monte_carlo(
        resample(path, problem.validation.dt),
        estimation_config(problem),
        runs=3 if quick else 10,
        seed=0,
    )
    print(f"EKF final position error: {sim.ekf.final_pos_err:.3g} m")
    print(f"KF final position error: {sim.kf.final_pos_err:.3g} m")
    print(f"CRB final position std: {sim.crlb_final_pos_std:.3g} m")


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:] or os.environ.get("OBSPLAN_QUICK") == "1")
