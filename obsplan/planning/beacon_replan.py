"""Receding horizon for a planned beacon: the craft re-plans its remaining path inside the
closed-loop Monte Carlo, from the vehicle's estimate, as a ship does that hears the AUV's
estimate over the acoustic modem.

The vehicle flies its given path (``vehicle.path``) in closed loop, steering its estimate onto
it. Every ``every`` seconds (a multiple of the craft's planning step,
:func:`beacon_replan_times`) each run stops and the craft re-plans
(:func:`~obsplan.planning.beacon.planner.resolve_beacon`):

* from its own state on the path in force, exactly (the craft has GPS);
* for the vehicle's *predicted* remaining path: the run's navigation estimate of position and
  velocity at that time joined back onto the vehicle's path over the recovery window (the
  least-energy correction of :func:`~obsplan.planning.replan.return_inputs`, over the time
  :func:`~obsplan.planning.replan.recovery_steps` gives), then the path (the vehicle steers its
  estimate onto its path, so from its estimate on its path is what it will fly);
* with the information at that time taken from the run's EKF covariance (the recursion's prior,
  :class:`~obsplan.planning.beacon.recursion.RangeRecursion`). The recursion's first epoch is the
  replan time itself: when that is a range epoch, the range the EKF already used there is counted
  once more in the craft's prediction (not in the runs);
* with the same craft limits, objective and weights (1 on the remaining range epochs on the
  survey lines; equal weights when none is left) over the remaining horizon, on the one-shot
  plan's nodes. The truth margins the one-shot plan may carry on ``min_distance`` and
  ``max_range`` (``limits.keepout_confidence``) are not re-derived: a re-solve keeps the limits
  against the predicted path with the check spacing's margin;
* warm-started from the path in force (fitted onto the limits from the craft's state).

A re-solve whose IPOPT status is not one of :data:`~obsplan.planning.replan.FLOWN_STATUSES`, or
whose path breaks a craft limit against the predicted vehicle path
(:func:`~obsplan.planning.baselines.beacon.craft_limit_breaks`), keeps the path in force
(``failures``); one that is not strictly better than the path in force on the same objective
keeps it too (``kept_warm_start``). The run's ranges after the replan are taken to the new path
(:meth:`~obsplan.estimation.montecarlo.closedloop.ClosedLoop.set_beacon`): each run is a loop of
its own, since each has its own beacon; every filter reported (navigation and passive) and the
truth's closest approach see that run's beacon. The bound reported with ``"replanned"`` is the
one along the one-shot plan (each run flies its own beacon), left out of the verdict.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
from tqdm import tqdm

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.estimation.montecarlo.results import MonteCarloResult, merge_monte_carlo
from obsplan.estimation.montecarlo.runs import DEFAULT_FILTERS
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.planning.baselines.beacon import craft_limit_breaks
from obsplan.planning.beacon.planner import (
    BeaconPlan,
    planning_step,
    range_epoch_times,
    resolve_beacon,
)
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.validation_setup import truth_limits
from obsplan.planning.replan import (
    FLOWN_STATUSES,
    ReplanResult,
    ReplanSolve,
    recovery_steps,
    replan_guidance,
    return_inputs,
    state_for_planner,
    steps_of,
)
from obsplan.planning.solver.starts import default_processes, run_forked
from obsplan.planning.validation.validate import PathValidation, validate_paths
from obsplan.planning.validation.verdict import Verdict, metric_value, verdict
from obsplan.trajectory.sampled import Trajectory


class BeaconSamples(Protocol):
    """The samples of a planned beacon path the replanning reads (a ``BeaconPlan``)."""

    @property
    def times(self) -> np.ndarray: ...  # (M,) [s]

    @property
    def positions(self) -> np.ndarray: ...  # (M, n) [m]

    @property
    def velocities(self) -> np.ndarray: ...  # (M, n) [m/s]

    @property
    def path(self) -> BeaconPath: ...


#: Relative tolerance for ``every`` to be a multiple of the craft's planning step, and for a
#: time to fall on a sample.
_STEP_RTOL = 1e-9


def beacon_replan_times(vehicle: Trajectory, config: EstimationConfig, every: float) -> np.ndarray:
    """Times [s] at which the craft re-plans: every ``every`` s from the vehicle's first sample,
    while at least one planning step of the horizon is left.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path on the filter grid.
    config : EstimationConfig
        Its rates (the craft's planning step, :func:`~obsplan.planning.beacon.planning_step`).
    every : float
        Replanning period [s] (``--replan EVERY``).

    Returns
    -------
    ndarray, shape (R,)
        The replan times [s]; empty when ``every`` is as long as the horizon less a step.

    Raises
    ------
    ConfigError
        When ``every`` is not a positive multiple of the craft's planning step (the message
        names ``--replan``).
    """
    h = planning_step(vehicle, config)
    _, k = steps_of(every, h, "the beacon craft's planning step (the ping interval),")
    t0, tf = float(vehicle.t[0]), float(vehicle.t[-1])
    count = max(0, math.ceil((tf - h - t0) / (k * h) - _STEP_RTOL))
    times = t0 + k * h * np.arange(1, count + 1)
    return times[times < tf - h * (1 - _STEP_RTOL)]


def predicted_vehicle(pb: PlanningProblem, vehicle: Trajectory, k: int, state: np.ndarray):
    """The vehicle's predicted path from sample ``k`` on: from ``state`` back onto ``vehicle``
    within the recovery window (:func:`~obsplan.planning.replan.recovery_steps` planning steps),
    the least-energy correction (:func:`~obsplan.planning.replan.return_inputs`), then the path.

    Parameters
    ----------
    pb : PlanningProblem
        The problem (model, limits, planning step).
    vehicle : Trajectory
        The vehicle's path on a uniform filter grid.
    k : int
        The sample of the replan time.
    state : ndarray, shape (2n,)
        The estimate of position [m] and inertial velocity [m/s] there.

    Returns
    -------
    Trajectory
        Samples ``k ..`` of ``vehicle``'s grid, shape ``(N - k, n)`` per field.
    """
    n = pb.dim
    rest = vehicle.window(int(k))
    h = float(rest.t[1] - rest.t[0])
    F, G = pb.model.transition(h)
    F, G = F[: 2 * n, : 2 * n], G[: 2 * n]
    steps = math.ceil(recovery_steps(pb) * pb.horizon.dt / h - 1e-9)
    H = rest.n_samples - 1
    e = np.asarray(state, float)[: 2 * n] - np.concatenate([rest.p[0], rest.v[0]])
    c = return_inputs(F, G, e, steps, H)
    err = np.empty((H + 1, 2 * n))
    err[0] = e
    for j in range(H):
        err[j + 1] = F @ err[j] + G @ c[j]
    u = rest.u + np.vstack([c, np.zeros((1, n))])
    return Trajectory(t=rest.t, p=rest.p + err[:, :n], v=rest.v + err[:, n:], u=u)


def craft_at(craft: BeaconVehicle, plan: tuple[np.ndarray, ...], t: float) -> BeaconVehicle:
    """The craft with its state at time ``t`` on the path in force as its start.

    Parameters
    ----------
    craft : BeaconVehicle
        The craft and its limits.
    plan : tuple of ndarray
        The path in force: times (M,) [s], positions (M, n) [m], velocities (M, n) [m/s].
    t : float
        The time [s] (a knot of the path when it is a planning node: the state is exact there).

    Returns
    -------
    BeaconVehicle
        ``craft`` with ``start`` and ``velocity`` at ``t``.
    """
    times, pos, vel = plan
    i = int(np.argmin(np.abs(times - t)))
    if abs(times[i] - t) <= _STEP_RTOL * max(1.0, abs(t)):
        b, v = pos[i], vel[i]
    else:
        b = np.array([np.interp(t, times, pos[:, j]) for j in range(pos.shape[1])])
        v = np.array([np.interp(t, times, vel[:, j]) for j in range(vel.shape[1])])
    return replace(craft, start=np.asarray(b, float).copy(), velocity=np.asarray(v[:2]).copy())


def splice(old: tuple[np.ndarray, ...], new: BeaconPlan, t: float) -> tuple[np.ndarray, ...]:
    """The path in force before ``t`` [s], then ``new`` (which starts at ``t``).

    Parameters
    ----------
    old : tuple of ndarray
        Times (M,) [s], positions (M, n) [m], velocities (M, n) [m/s].
    new : BeaconPlan
        The re-solved path from ``t`` on.
    t : float
        The replan time [s].

    Returns
    -------
    tuple of ndarray
        The joined times, positions and velocities.
    """
    keep = old[0] < new.times[0] - _STEP_RTOL * max(1.0, abs(t))
    return (
        np.concatenate([old[0][keep], new.times]),
        np.vstack([old[1][keep], new.positions]),
        np.vstack([old[2][keep], new.velocities]),
    )


def _weights(job: dict, rest: Trajectory) -> np.ndarray | None:
    """The remaining range epochs' weights: 1 on the lines (None without lines or none left)."""
    mask = job["mask"]
    if mask is None:
        return None
    idx = np.searchsorted(job["fine"].t, range_epoch_times(rest, job["config"]) - 1e-9)
    w = np.asarray(mask, float)[idx]
    return w if w.sum() > 0 else None


def _resolve(job: dict, in_force: tuple, t: float, k: int, est, cov, run: int):
    """One re-solve of one run: the solve's record and the new path (None: keep the one in
    force)."""
    pb, craft = job["problem"], job["craft"]
    rest = predicted_vehicle(pb, job["fine"], k, state_for_planner(pb, est))
    here = craft_at(craft, in_force, t)
    c0, w0 = time.process_time(), time.perf_counter()
    try:
        new, flying_on = resolve_beacon(
            rest,
            here,
            job["config"],
            BeaconPath(in_force[0], in_force[1]),
            step=job["step"],
            prior=cov,
            weights=_weights(job, rest),
        )
    except Exception as exc:  # noqa: BLE001 - a failed re-solve keeps the path in force
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        return ReplanSolve(t, run, f"exception: {exc}", False, 0, wall, cpu, None), None
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    rec = ReplanSolve(t, run, new.status, False, new.iterations, wall, cpu, None)
    if new.status not in FLOWN_STATUSES or not math.isfinite(new.objective):
        return rec, None
    if craft_limit_breaks(new.path, new.velocities, craft, rest):
        return replace(rec, status="limits"), None
    if not new.objective < flying_on:  # flying on is no worse: the path in force is kept
        return replace(rec, success=True, objective=flying_on, kept_warm_start=True), None
    return replace(rec, success=True, objective=new.objective), new


def _fly_run(job: dict, run: int) -> tuple[MonteCarloResult, list[ReplanSolve]]:
    """Run ``run`` in closed loop (a loop of its own: its own beacon), re-planning the craft at
    every replan time."""
    loop = ClosedLoop(
        job["fine"],
        job["config"],
        1,
        job["seed"],
        run,
        guidance=job["guidance"],
        limits=job["limits"],
        lines=job["mask"],
        filters=job["filters"],
    )
    in_force = job["plan"]
    solves: list[ReplanSolve] = []
    for t in job["times"]:
        loop.advance(float(t))
        snap = loop.snapshot()
        out, new = _resolve(
            job, in_force, float(snap.t), snap.k, snap.estimate[0], snap.covariance[0], run
        )
        solves.append(out)
        if new is not None:
            in_force = splice(in_force, new, float(snap.t))
            loop.set_beacon(BeaconPath(in_force[0], in_force[1]))
    return loop.result(job["crlb"]), solves


@dataclass(frozen=True, eq=False)
class BeaconReplanResult(ReplanResult):
    """The craft's replanned closed-loop Monte Carlo beside the one-shot planned beacon
    (:class:`~obsplan.planning.replan.ReplanResult`, whose fields it has).

    Attributes
    ----------
    lines : bool
        The vehicle has survey lines: the EKF's RMSE over them is compared and printed.
    """

    lines: bool = False

    @property
    def verdict(self) -> Verdict:
        """The replanned beacon (as ``planned``) against the one-shot planned beacon, on the
        filters' errors (the EKF's over the lines too, with lines), paired runs, at 95 %; the
        bound rows are left out (computed along the one-shot plan only)."""
        v = dict(self.validation)
        full = verdict({"planned": v.pop("replanned"), **v}, {}, lines=self.lines)
        comps = {
            name: {k: c for k, c in cs.items() if not k.startswith("crlb.")}
            for name, cs in full.comparisons.items()
        }
        return Verdict(comps, {}, full.runs, full.notes)

    @property
    def kept(self) -> int:
        """Re-solves that converged within the limits but not better than the path in force,
        which was kept."""
        return sum(s.kept_warm_start for s in self.solves)

    @property
    def done(self) -> int:
        """Re-solves whose new path was flown."""
        return sum(s.success and not s.kept_warm_start for s in self.solves)

    def to_dict(self) -> dict:
        """The ``replan`` entry of the beacon's report.json: :meth:`ReplanResult.to_dict` with
        ``what = "beacon"`` and the counts ``done`` (new path flown), ``failures`` and ``kept``.

        Returns
        -------
        dict
            JSON values.
        """
        return {"what": "beacon", "done": self.done, "kept": self.kept, **super().to_dict()}

    def summary(self) -> list[str]:
        """Lines for the terminal: the re-solves (done, failed, kept), solve times, each path's
        EKF errors [m] and the verdict's words.

        Returns
        -------
        list of str
            A head line, one line each for ``"replanned"`` and ``"one-shot"``, the verdict.
        """
        w = self.solve_times()
        med = f"{np.median(w):.2f}" if w.size else "-"
        mx = f"{np.max(w):.2f}" if w.size else "-"
        lines = [
            f"beacon replanning every {self.every:g} s: {len(self.solves)} re-solves, "
            f"{self.done} flown, {self.failures} failed and {self.kept} no better (path in force "
            f"kept), solve time median {med} s, max {mx} s, {self.wall_s:.1f} s in all"
        ]
        for name in ("replanned", "one-shot"):
            v = self.validation[name]
            ekf = v.result.ekf
            on_lines = metric_value(v, "ekf.rmse_pos_lines") if self.lines else None
            lines.append(
                f"  {name:<10} EKF rmse {_f(ekf.rmse_pos if ekf else None)} m"
                + (f", EKF rmse on lines {_f(on_lines)} m" if self.lines else "")
                + f", EKF final {_f(ekf.final_pos_err if ekf else None)} m"
            )
        lines += [f"  replanned beacon: {line}" for line in self.verdict.summary()]
        return lines


def _f(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.4g}"


def beacon_replan_monte_carlo(
    pb: PlanningProblem,
    vehicle: Trajectory,
    plan: BeaconSamples,
    every: float,
    config: EstimationConfig,
    *,
    mask: np.ndarray | None = None,
    runs: int | None = None,
    processes: int | None = 1,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
) -> BeaconReplanResult:
    """Closed-loop Monte Carlo of the vehicle on its path with the craft re-planning every
    ``every`` s (module docstring), beside the one-shot planned beacon (same runs and seed:
    paired).

    Parameters
    ----------
    pb : PlanningProblem
        The problem (``[validation]``: runs, seed, filter step; the craft's limits).
    vehicle : Trajectory
        The vehicle's path on the filter grid (``validation.dt``).
    plan : BeaconSamples
        The one-shot planned beacon (a ``BeaconPlan``; its planning step is
        :func:`~obsplan.planning.beacon.planning_step`'s).
    every : float
        Replanning period [s] (:func:`beacon_replan_times`).
    config : EstimationConfig
        The vehicle's estimation configuration (its ``beacon_path`` is replaced by the plan's).
    mask : ndarray of bool, shape (N,), or None, optional
        The vehicle's samples on its survey lines (the weights and ``rmse_pos_lines``).
    runs : int or None, optional
        Override ``validation.runs``.
    processes : int or None, optional
        Worker processes over runs (``fork``; 1: serial; None: one per core).
    progress : bool, optional
        A tqdm bar over runs (stderr).
    filters : sequence of str, optional
        Filters reported (the navigation filter in any case).

    Returns
    -------
    BeaconReplanResult
        ``"replanned"`` and ``"one-shot"`` validations, every re-solve, the verdict.

    Raises
    ------
    ConfigError
        A bad period, open-loop validation or fewer than one run.
    """
    t0 = time.perf_counter()
    times = beacon_replan_times(vehicle, config, every)
    n_runs = pb.validation.runs if runs is None else int(runs)
    if n_runs < 1:
        raise ConfigError(f"runs must be at least 1, got {n_runs}")
    if pb.beacon_vehicle is None:
        raise ConfigError("beacon replanning needs a planned beacon (beacon.motion = 'planned')")
    cfg = replace(config, beacon_path=plan.path)
    job: dict[str, Any] = {
        "problem": pb,
        "craft": pb.beacon_vehicle,
        "fine": vehicle,
        "config": cfg,
        "seed": pb.validation.seed,
        "guidance": replan_guidance(pb),
        "limits": truth_limits(pb),
        "mask": mask,
        "filters": tuple(filters),
        "times": times,
        "step": planning_step(vehicle, config),
        "plan": (plan.times, plan.positions, plan.velocities),
        "crlb": posterior_crlb(vehicle, cfg),
    }
    nproc = default_processes(n_runs) if processes is None else max(1, int(processes))
    with tqdm(total=n_runs, disable=not progress, unit="run", desc="replanned beacon") as bar:
        done = (lambda i, _: bar.update(1)) if progress else None
        parts = run_forked(_fly_run, job, list(range(n_runs)), nproc, done)
    replanned = merge_monte_carlo([p for p, _ in parts])
    lines = None if mask is None else {"one-shot": mask}
    validation = {"replanned": PathValidation("replanned", replanned)}
    validation.update(
        validate_paths(
            {"one-shot": vehicle},
            pb,
            runs=n_runs,
            filters=filters,
            lines=lines,
            beacons={"one-shot": plan.path},
        )
    )
    return BeaconReplanResult(
        every=float(every),
        times=tuple(float(t) for t in times),
        solves=tuple(s for _, ss in parts for s in ss),
        validation=validation,
        build_s=0.0,
        wall_s=time.perf_counter() - t0,
        lines=mask is not None and bool(np.any(mask)),
    )
