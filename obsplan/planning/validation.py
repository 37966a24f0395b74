"""Validation of a plan against its baselines: EKF and KF Monte Carlo under identical conditions.

Every path is resampled to the filter step ``validation.dt`` (:func:`obsplan.trajectory.resample`,
exact: the inputs are piecewise constant on the planning grid, which the filter grid refines)
and run through :func:`obsplan.estimation.simulate.monte_carlo_paths` in one pass with the same
configuration (rates, noises, priors, process noise:
:func:`~obsplan.planning.validation_setup.estimation_config`), the same number of runs and the
same seed, so the truths' noise streams are identical across paths (and drawn once). Reported per
path and filter: position RMSE (time average), final error and standard deviation, NEES,
convergence time, the runs the divergence monitor flagged; and the posterior Cramér–Rao bound.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from obsplan.estimation.simulate import DEFAULT_FILTERS, MonteCarloResult, monte_carlo_paths
from obsplan.planning.problem import PlanningProblem
from obsplan.planning.validation_setup import estimation_config
from obsplan.trajectory import Trajectory, resample


@dataclass(frozen=True, eq=False)
class PathValidation:
    """Monte Carlo result of one path (:class:`~obsplan.estimation.simulate.MonteCarloResult`)."""

    name: str
    result: MonteCarloResult

    def to_dict(self) -> dict:
        """``{"ekf": {...}, "kf": {...}, "crlb_final_pos_std": ...}`` of report.json (and one
        entry per further filter that was run)."""
        r = self.result
        crlb = float(r.crlb_final_pos_std)
        out = {
            "ekf": None if r.ekf is None else r.ekf.to_dict(),
            "kf": None if r.kf is None else r.kf.to_dict(),
            "crlb_final_pos_std": crlb if np.isfinite(crlb) else None,
            "runs": int(r.runs),
            "seed": int(r.seed),
            "samples": int(r.t.size),
        }
        for name, s in (r.filters or {}).items():
            if name not in out:
                out[name] = s.to_dict()
        return out


def validate_paths(
    paths: Mapping[str, Trajectory],
    pb: PlanningProblem,
    *,
    runs: int | None = None,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    lines: Mapping[str, np.ndarray] | None = None,
) -> dict[str, PathValidation]:
    """Monte Carlo of the filters on each path under the problem's ``[validation]`` settings.

    Parameters
    ----------
    paths
        Name -> trajectory (on any grid whose intervals ``validation.dt`` divides).
    pb
        The problem (model, rates, noises, prior, seed).
    runs
        Override ``validation.runs`` (e.g. fewer runs in tests).
    progress
        Progress bar over runs.
    filters
        Estimators to run (names of :data:`obsplan.estimation.simulate.FILTERS`).
    lines
        Name -> boolean mask of the filter samples (``pb.filter_times``) flown on survey lines:
        the samples of that path's ``rmse_pos_lines``; default none.
    """
    val = pb.validation
    config = estimation_config(pb)
    n_runs = val.runs if runs is None else int(runs)
    if not paths:
        return {}
    fine = [resample(traj, val.dt) for traj in paths.values()]
    masks = [None if lines is None else lines.get(name) for name in paths]
    results = monte_carlo_paths(
        fine,
        config,
        runs=n_runs,
        seed=val.seed,
        progress=progress,
        filters=filters,
        lines=masks if any(m is not None for m in masks) else None,
    )
    return {name: PathValidation(name, res) for name, res in zip(paths, results, strict=True)}
