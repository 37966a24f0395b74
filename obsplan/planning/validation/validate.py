"""Validation of a plan against its baselines: EKF and KF Monte Carlo under identical conditions.

By default (``validation.mode = "closed-loop"``) every path, plan and baselines alike, is flown as
a vehicle at sea flies it: steering its estimate onto the path with the guidance law of
:func:`~obsplan.planning.problem.validation_setup.validation_guidance` (gains and saturation from
the limits), so the true path is the path minus the estimation and tracking errors; ``"open-loop"``
flies the accelerations blind. Either way each run's true path is checked against the problem's
limits (:func:`~obsplan.planning.problem.validation_setup.truth_limits`): closest approach to the
beacon, runs inside ``min_range``, tracking error, runs breaking any limit.

Every path is resampled to the filter step ``validation.dt``
(:func:`obsplan.trajectory.sampled.resample`, exact: the inputs are piecewise constant on the
planning grid, which the filter grid refines) and run through
:func:`obsplan.estimation.montecarlo.simulate.monte_carlo_paths` in one pass with the same
configuration (rates, noises, priors, process noise:
:func:`~obsplan.planning.problem.validation_setup.estimation_config`), the same number of runs and
the same seed, so the truths' noise streams are identical across paths (and drawn once). Reported
per path and filter: position RMSE (time average), final error and standard deviation, NEES,
convergence time, the runs the divergence monitor flagged; and the posterior Cramér–Rao bound. Runs
``run_start ..`` of the seed can be added later and merged exactly (:func:`merge_validations`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from obsplan.estimation.montecarlo.simulate import (
    DEFAULT_FILTERS,
    MonteCarloResult,
    merge_monte_carlo,
    monte_carlo_paths,
)
from obsplan.model.beacon import BeaconPath
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.validation_setup import (
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.trajectory.sampled import Trajectory, resample


@dataclass(frozen=True, eq=False)
class PathValidation:
    """Monte Carlo result of one path
    (:class:`~obsplan.estimation.montecarlo.simulate.MonteCarloResult`)."""

    name: str
    result: MonteCarloResult

    def to_dict(self) -> dict:
        """``{"ekf": {...}, "kf": {...}, "crlb_final_pos_std": ..., "truth": {...}}`` of
        report.json (and one entry per further filter that was run).

        ``truth`` holds the true paths' ``closest_range_m`` (over all runs), the
        ``runs_inside_min_range``, the ``tracking_rmse_m`` (RMS of ``|p - p_ref|``), the final
        drift, and the fraction of runs breaking each limit and any limit.

        Returns
        -------
        dict
            Also ``mode``, ``runs``, ``seed`` and ``samples``; None for a filter (or truth) that
            was not run, and for a non-finite bound.
        """
        r = self.result
        crlb = float(r.crlb_final_pos_std)
        out = {
            "mode": r.mode,
            "truth": None if r.truth is None else r.truth.to_dict(),
            "ekf": r.filter_dict("ekf"),
            "kf": r.filter_dict("kf"),
            "crlb_final_pos_std": crlb if np.isfinite(crlb) else None,
            "runs": int(r.runs),
            "seed": int(r.seed),
            "samples": int(r.t.size),
        }
        for name in r.filters or {}:
            if name not in out:
                out[name] = r.filter_dict(name)
        return out


def validate_paths(
    paths: Mapping[str, Trajectory],
    pb: PlanningProblem,
    *,
    runs: int | None = None,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    run_start: int = 0,
    lines: Mapping[str, np.ndarray] | None = None,
    beacons: Mapping[str, BeaconPath] | None = None,
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
        Estimators to run (names of :data:`obsplan.estimation.montecarlo.simulate.FILTERS`); in
        closed loop the filter the vehicle steers on (``validation.navigation``) is always reported
        (:class:`~obsplan.estimation.montecarlo.closedloop.ClosedLoop`).
    run_start
        First run of the seed's streams (runs ``run_start .. run_start + runs - 1``; the same
        runs on every path, so that results of several calls merge exactly).
    lines
        Name -> boolean mask of the filter samples (``pb.filter_times``) flown on survey lines:
        the samples of that path's ``rmse_pos_lines``; default none.
    beacons
        Name -> the moving beacon's path that path is flown with (a planned beacon and its
        baselines, the vehicle's path the same): each path is then run with its own beacon, on
        the same seed's runs (paired); default none: the problem's beacon for every path.

    Returns
    -------
    dict of str to PathValidation
        Name -> its Monte Carlo result, in the order of ``paths`` (empty without paths).
    """
    val = pb.validation
    n_runs = val.runs if runs is None else int(runs)
    if not paths:
        return {}
    fine = [resample(traj, val.dt) for traj in paths.values()]
    masks = [None if lines is None else lines.get(name) for name in paths]
    kwargs: dict[str, Any] = dict(
        runs=n_runs,
        seed=val.seed,
        progress=progress,
        filters=filters,
        run_start=run_start,
        guidance=validation_guidance(pb),
        limits=truth_limits(pb),
    )
    if beacons is None:
        config = estimation_config(pb)
        results = monte_carlo_paths(
            fine, config, lines=masks if any(m is not None for m in masks) else None, **kwargs
        )
    else:
        results = [
            monte_carlo_paths(
                [tr],
                estimation_config(pb, beacons[name]),
                lines=None if mask is None else [mask],
                **kwargs,
            )[0]
            for name, tr, mask in zip(paths, fine, masks, strict=True)
        ]
    return {name: PathValidation(name, res) for name, res in zip(paths, results, strict=True)}


def merge_validations(
    parts: Sequence[Mapping[str, PathValidation]],
) -> dict[str, PathValidation]:
    """Validations of the same paths over consecutive runs (in run order) merged into one, exactly
    (:func:`~obsplan.estimation.montecarlo.simulate.merge_monte_carlo`).

    Parameters
    ----------
    parts : sequence of Mapping of str to PathValidation
        Validations of the same paths, each over the runs following the previous one's (the
        names of the first part are merged).

    Returns
    -------
    dict of str to PathValidation
        Name -> the validation over all the runs.
    """
    names = list(parts[0])
    return {
        name: PathValidation(name, merge_monte_carlo([p[name].result for p in parts]))
        for name in names
    }
