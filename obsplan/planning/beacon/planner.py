"""Plan the beacon: the craft's accelerations that minimise the vehicle's posterior CRB.

:func:`plan_beacon` builds the NLP once (the craft's path, :mod:`obsplan.planning.beacon.craft`;
the vehicle's covariance recursion along its fixed path,
:mod:`obsplan.planning.beacon.recursion`), then solves it with IPOPT from several starts and
keeps the best converged one:

* ``hold``: the craft holding its start;
* ``circle-<r>m-ccw`` / ``-cw``: circling the centre of the vehicle's path (the middle of its
  horizontal bounding box) at a third and at two thirds of the box's half-diagonal, spiralling
  out from the start at half the craft's speed, at 90 % of the angular rate its speed and
  acceleration allow;
* the caller's ``guesses`` (e.g. the beacon baselines, which include a circle at its best
  radius: with guesses the circle starts are left out unless ``circles=True``).

A start that fits onto the same path as an earlier one (within :data:`PATH_TOLERANCE_M` at every
node; e.g. the ``beacon-fixed`` baseline is holding station) is not solved again: IPOPT would end
where it did, and the start's entry says so.

Each start is first *fitted* onto the limits: the nearest path of the craft's dynamics (least
squares on the node positions, the limits as constraints, IPOPT with the exact Hessian), so every
solve begins feasible and each start's ``initial_objective`` is that of a path the craft can fly.
Each solve divides the objective by its value at the (fitted) start, 1 there, so IPOPT's
tolerance is relative to where the solve begins whatever the problem's units and sizes (relative to
holding station instead, a 3D range-only survey, whose optimum is 1.5 % of holding, stopped after
50 iterations at objectives 30 % apart). IPOPT runs L-BFGS (the exact Hessian of a recursion
over hundreds of epochs is dense and slow to build) with the monotone barrier (with one range
epoch per planning step, the reason of :func:`~obsplan.planning.solver.ipopt.lbfgs_options`).
A plan is ``success`` exactly when IPOPT's ``return_status`` is ``Solve_Succeeded``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from obsplan.core.errors import InputError
from obsplan.estimation.config import EstimationConfig
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.planning.beacon.craft import CHECK_DT, CraftGrid, craft_grid
from obsplan.planning.beacon.recursion import RangeRecursion, range_recursion
from obsplan.planning.solver.ipopt import SUCCESS_STATUS, _call, stop_reason
from obsplan.trajectory.sampled import Trajectory

#: Largest distance [m] between the planned path and the linear interpolation of its samples
#: (:attr:`BeaconPlan.path`; :meth:`~obsplan.planning.beacon.craft.CraftGrid.samples`).
PATH_TOLERANCE_M = 1e-3
#: Most planning intervals over the horizon: the default step is the ping interval, or longer
#: when that would give more intervals (a ping every second over an hour).
MAX_INTERVALS = 200
#: Planning step [s] when the configuration has no range rate (ranges at every sample).
DEFAULT_STEP = 10.0
#: IPOPT's tolerance on the normalised objective (1 at the start of each solve) and its
#: iteration limit per start. With L-BFGS, 1e-6 took 3-4x the iterations of 1e-4 for the last
#: 0.1 % of the objective (measured on a 2D range-only lawn-mower: > 1000 against 180-290).
SOLVER_TOL = 1e-4
MAX_ITER = 1000
#: L-BFGS pairs kept: 20 converged in 240-290 iterations where IPOPT's default 6 took 370-410,
#: for less time in all (the extra back-solves are cheaper than the extra iterations).
LBFGS_HISTORY = 20
#: Fractions of the half-diagonal of the vehicle's bounding box: the radii of the circle starts.
CIRCLE_FRACTIONS = (1.0 / 3.0, 2.0 / 3.0)


@dataclass(frozen=True)
class BeaconStart:
    """One IPOPT solve from one start.

    Attributes
    ----------
    label : str
        ``"hold"``, ``"circle-<r>m-ccw|cw"`` or the guess's label.
    success : bool
        ``status == "Solve_Succeeded"``.
    status : str
        IPOPT's ``return_status`` (or ``"exception: ..."``).
    iterations : int
        IPOPT iterations of the solve (the fit not counted).
    wall_s : float
        Fit and solve time [s].
    objective : float or None
        The objective [m²] of the solve's end point (:mod:`~obsplan.planning.beacon.recursion`).
    initial_objective : float or None
        The objective [m²] of the start once fitted onto the limits.
    reason : str
        Why it did not converge, in words ("" when it did).
    same_as : str
        The earlier start this one fitted onto, whose outcome it shares: not solved again (""
        when solved).
    """

    label: str
    success: bool
    status: str
    iterations: int
    wall_s: float
    objective: float | None
    initial_objective: float | None
    reason: str
    same_as: str = ""


@dataclass(frozen=True, eq=False)
class BeaconPlan:
    """The planned path of the craft carrying the beacon.

    Attributes
    ----------
    times : ndarray, shape (M,)
        Sample times [s] from the vehicle's first sample to its last.
    positions : ndarray, shape (M, n)
        Beacon positions [m]; in 3D ``z`` is the craft's start depth.
    velocities : ndarray, shape (M, n)
        Beacon velocities [m/s] (``v_z = 0`` in 3D).
    path : BeaconPath
        The samples as a path, linearly interpolated; within :data:`PATH_TOLERANCE_M` of the
        planned path everywhere.
    node_times : ndarray, shape (N + 1,)
        Planning nodes [s].
    accelerations : ndarray, shape (N, 2)
        Horizontal acceleration held on each planning interval [m/s²].
    success : bool
        The path is a converged IPOPT solution (``status == "Solve_Succeeded"``).
    status : str
        IPOPT's status of the returned start.
    iterations : int
        Its IPOPT iterations.
    wall_s : float
        Total planning time [s] (build and every start).
    objective : float
        The objective [m²] (:mod:`~obsplan.planning.beacon.recursion`): the weighted mean over
        the range epochs of the position variance plus the final one.
    hold_objective : float
        The same with the craft holding its start [m²].
    starts : tuple of BeaconStart
        Every start, in the order solved.
    label : str
        The start the plan came from.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    path: BeaconPath
    node_times: np.ndarray
    accelerations: np.ndarray
    success: bool
    status: str
    iterations: int
    wall_s: float
    objective: float
    hold_objective: float
    starts: tuple[BeaconStart, ...]
    label: str

    def summary(self) -> str:
        """A short text: status, objective against holding station, and every start.

        Returns
        -------
        str
            A few lines.
        """
        ratio = self.objective / self.hold_objective if self.hold_objective > 0 else math.nan
        head = (
            f"beacon plan: {'converged' if self.success else 'NOT converged'} ({self.status}), "
            f"{self.iterations} iterations, {self.wall_s:.1f} s; objective {self.objective:.4g} "
            f"m^2 ({ratio:.2f}x holding station), from start {self.label!r}"
        )
        lines = [head]
        for s in self.starts:
            obj = "-" if s.objective is None else f"{s.objective:.4g}"
            ini = "-" if s.initial_objective is None else f"{s.initial_objective:.4g}"
            why = f": {s.reason}" if s.reason else ""
            if s.same_as:
                why += f" (the same start as {s.same_as!r} once fitted: not solved again)"
            lines.append(f"  {s.label}: {s.status}, {obj} m^2 (start {ini}){why}")
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class _Nlp:
    """The built problem: solver, fit, objective function and the sizes."""

    grid: CraftGrid
    rec: RangeRecursion
    solver: ca.Function
    fit: ca.Function
    objective: ca.Function  # vec(W) -> J [m²]
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray


def _default_step(vehicle: Trajectory, config: EstimationConfig) -> float:
    rate = config.rates_hz.get("range")
    step = DEFAULT_STEP if rate is None else 1.0 / float(rate)
    return max(step, float(vehicle.t[-1] - vehicle.t[0]) / MAX_INTERVALS)


def _weights(weights: np.ndarray | None, count: int) -> np.ndarray:
    if weights is None:
        return np.ones(count)
    w = np.asarray(weights, float).reshape(-1)
    if w.shape != (count,) or not np.all(np.isfinite(w) & (w >= 0)) or w.sum() <= 0:
        raise InputError(
            f"weights must be {count} finite values >= 0 (one per range epoch, "
            "range_epoch_times) with a positive sum"
        )
    return w


def _ipopt_options(tol: float, max_iter: int, exact: bool) -> dict:
    ipopt = {
        "print_level": 0,
        "sb": "yes",
        "linear_solver": "mumps",
        "tol": tol,
        # the dynamics are equalities: keep the path on them, not IPOPT's default 1e-4
        "constr_viol_tol": 1e-8,
        "max_iter": max_iter,
    }
    if not exact:
        ipopt.update(
            {
                "hessian_approximation": "limited-memory",
                "limited_memory_max_history": LBFGS_HISTORY,
                "mu_strategy": "monotone",
            }
        )
    return {"ipopt": ipopt, "print_time": False}


def _fit_solver(grid: CraftGrid) -> ca.Function:
    """Least squares on the node positions to a target, within the limits (exact Hessian: the
    problem is quadratic with quadratic constraints); a tiny weight on the accelerations makes the
    minimiser unique."""
    N = grid.N
    x = ca.SX.sym("w", 6 * N)
    W = ca.reshape(x, 6, N)
    g, _, _ = grid.constraints(W)
    target = ca.SX.sym("target", 2 * N)
    f = ca.sumsqr(ca.vec(W[2:4, :]) - target) + 1e-6 * ca.sumsqr(W[0:2, :])
    nlp = {"x": x, "p": target, "f": f, "g": ca.vertcat(*g)}
    return ca.nlpsol("beacon_fit", "ipopt", nlp, _ipopt_options(1e-8, MAX_ITER, True))


def _build(grid: CraftGrid, rec: RangeRecursion, w: np.ndarray, tol: float, max_iter: int) -> _Nlp:
    N = grid.N
    x = ca.SX.sym("w", 6 * N)
    W = ca.reshape(x, 6, N)
    J = rec.objective(grid.epoch_beacons(W, rec.times, rec.positions), w)
    objective = ca.Function("beacon_objective", [x], [J])
    ref = ca.SX.sym("ref")  # the objective of the start: 1 there
    g, lo, hi = grid.constraints(W)
    nlp = {"x": x, "p": ref, "f": J / ref, "g": ca.vertcat(*g)}
    solver = ca.nlpsol("beacon", "ipopt", nlp, _ipopt_options(tol, max_iter, False))
    lbx, ubx = grid.bounds()
    return _Nlp(
        grid,
        rec,
        solver,
        _fit_solver(grid),
        objective,
        lbx.reshape(-1, order="F"),
        ubx.reshape(-1, order="F"),
        np.asarray(lo, float),
        np.asarray(hi, float),
    )


def circle_guesses(vehicle: Trajectory, craft: BeaconVehicle) -> list[tuple[str, BeaconPath]]:
    """The circle starts of the module docstring, as paths sampled every second.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path (its bounding box gives the centre and the radii).
    craft : BeaconVehicle
        The craft (start, speed, acceleration).

    Returns
    -------
    list of (str, BeaconPath)
        Label and path of each circle start (not necessarily within the craft's limits: the
        planner fits them onto the limits).
    """
    lo, hi = vehicle.p[:, :2].min(axis=0), vehicle.p[:, :2].max(axis=0)
    centre = 0.5 * (lo + hi)
    half_diag = max(0.5 * float(np.linalg.norm(hi - lo)), 1.0)
    t = np.linspace(vehicle.t[0], vehicle.t[-1], max(2, int(vehicle.duration) + 1))
    tau = t - t[0]
    d0 = craft.start[:2] - centre
    r0 = float(np.linalg.norm(d0))
    th0 = math.atan2(d0[1], d0[0]) if r0 > 1e-9 else 0.0
    out = []
    for frac in CIRCLE_FRACTIONS:
        r = frac * half_diag
        omega = 0.9 * min(craft.speed / r, math.sqrt(float(np.min(craft.accel)) / r))
        ramp = abs(r - r0) / (0.5 * craft.speed)
        radius = r0 + (r - r0) * np.clip(tau / max(ramp, 1e-9), 0.0, 1.0)
        for name, sign in (("ccw", 1.0), ("cw", -1.0)):
            th = th0 + sign * omega * tau
            xy = centre + radius[:, None] * np.column_stack([np.cos(th), np.sin(th)])
            if craft.dim == 3:
                xy = np.column_stack([xy, np.full(t.size, craft.start[2])])
            out.append((f"circle-{r:.0f}m-{name}", BeaconPath(t, xy)))
    return out


def _fit(
    grid: CraftGrid, fit: ca.Function, path: BeaconPath, bounds: tuple
) -> tuple[np.ndarray, bool]:
    """The ``W`` (flat) nearest ``path`` within the limits, and whether the fit converged
    (otherwise the path read off directly, clipped to the bounds)."""
    W = grid.from_path(path)
    lbx, ubx, lbg, ubg = bounds
    x0 = np.clip(W.reshape(-1, order="F"), lbx, ubx)
    target = W[2:4].reshape(-1, order="F")
    sol, stats, _ = _call(fit, x0=x0, p=target, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    if sol is None or stats.get("return_status") != SUCCESS_STATUS:
        return x0, False
    return np.asarray(sol["x"], float).reshape(-1), True


def _bounds(grid: CraftGrid) -> tuple:
    lbx, ubx = grid.bounds()
    _, lo, hi = grid.constraints(ca.SX.sym("w", 6, grid.N))
    return (
        lbx.reshape(-1, order="F"),
        ubx.reshape(-1, order="F"),
        np.asarray(lo, float),
        np.asarray(hi, float),
    )


def flyable_path(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    reference: BeaconPath,
    *,
    step: float = DEFAULT_STEP,
    check_dt: float = CHECK_DT,
) -> tuple[BeaconPath, bool]:
    """The path the craft can fly nearest ``reference``: its accelerations held over ``step``,
    within every limit (:mod:`~obsplan.planning.beacon.craft`), least squares on the positions
    at the nodes. How the planner fits its starts; a baseline that must respect the limits can
    use it.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path (the horizon and the distance limits).
    craft : BeaconVehicle
        The craft and its limits.
    reference : BeaconPath
        The path to follow, covering the horizon.
    step : float, optional
        Step [s] of the held accelerations.
    check_dt : float, optional
        Spacing of the distance limits' check points [s].

    Returns
    -------
    path : BeaconPath
        The flyable path, sampled within :data:`PATH_TOLERANCE_M` of it.
    converged : bool
        Whether the fit converged (``Solve_Succeeded``); if not, ``path`` is the reference read
        off at the nodes and may break a limit.
    """
    grid = craft_grid(vehicle, craft, step, check_dt)
    reference.check_covers(float(vehicle.t[0]), float(vehicle.t[-1]), "reference")
    x, ok = _fit(grid, _fit_solver(grid), reference, _bounds(grid))
    t, b, _ = grid.samples(x.reshape(6, grid.N, order="F"), PATH_TOLERANCE_M)
    return BeaconPath(t, b), ok


def beacon_objective(
    vehicle: Trajectory,
    config: EstimationConfig,
    path: BeaconPath,
    weights: np.ndarray | None = None,
) -> float:
    """The planner's objective [m²] (:mod:`~obsplan.planning.beacon.recursion`) for a given
    beacon path: the ranges taken to it at transmission, as the estimation takes them.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's fixed path.
    config : EstimationConfig
        Sensors, rates, noises, prior and process noise.
    path : BeaconPath
        The beacon's path, covering the vehicle's.
    weights : ndarray, shape (E,), or None, optional
        Per range epoch (:func:`range_epoch_times`); None: equal.

    Returns
    -------
    float
        The weighted mean of the position variance over the range epochs plus the final one
        [m²].
    """
    rec = range_recursion(vehicle, config)
    return float(rec.objective(rec.beacons_on_path(path), _weights(weights, rec.count)))


def _solve_start(
    nlp: _Nlp, label: str, x0: np.ndarray, fitted: bool
) -> tuple[BeaconStart, np.ndarray]:
    t0 = time.perf_counter()
    initial = float(nlp.objective(x0))
    ref = initial if math.isfinite(initial) and initial > 0 else 1.0
    sol, stats, err = _call(
        nlp.solver, x0=x0, p=ref, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg
    )
    status = err or str(stats.get("return_status", "unknown"))
    iters = int(stats.get("iter_count", 0))
    if sol is None:
        x, obj = x0, None
    else:
        x = np.asarray(sol["x"], float).reshape(-1)
        obj = float(nlp.objective(x))
        if not math.isfinite(obj):
            obj = None
    reason = "" if status == SUCCESS_STATUS else (err or stop_reason(stats, SOLVER_TOL, 1e-8))
    if not fitted:
        reason = (reason + "; " if reason else "") + (
            "the start could not be fitted onto the craft's limits, so IPOPT began from an "
            "infeasible path"
        )
    out = BeaconStart(
        label=label,
        success=status == SUCCESS_STATUS,
        status=status,
        iterations=iters,
        wall_s=time.perf_counter() - t0,
        objective=obj,
        initial_objective=initial if math.isfinite(initial) else None,
        reason=reason,
    )
    return out, x


def _violation(nlp: _Nlp, x: np.ndarray) -> float:
    """Largest violation of the bounds of ``x`` (the constraints are checked by IPOPT's
    status; a start that did not converge is kept only when nothing converged)."""
    return float(np.max(np.maximum(nlp.lbx - x, 0.0) + np.maximum(x - nlp.ubx, 0.0), initial=0.0))


def range_epoch_times(vehicle: Trajectory, config: EstimationConfig) -> np.ndarray:
    """The range epochs of ``vehicle`` under ``config`` [s]: one entry per ``weights`` entry of
    :func:`plan_beacon` (the samples where its range schedule reports).

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path.
    config : EstimationConfig
        Sensors and rates.

    Returns
    -------
    ndarray, shape (E,)
        Times [s].
    """
    return range_recursion(vehicle, config).times.copy()


def plan_beacon(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    config: EstimationConfig,
    *,
    step: float | None = None,
    weights: np.ndarray | None = None,
    guesses: Sequence[BeaconPath] = (),
    guess_labels: Sequence[str] | None = None,
    callback: Callable[[int, str, BeaconStart], None] | None = None,
    check_dt: float = CHECK_DT,
    tol: float = SOLVER_TOL,
    max_iter: int = MAX_ITER,
    circles: bool | None = None,
    truth_margins: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> BeaconPlan:
    """Plan the craft carrying the beacon for a vehicle flying ``vehicle`` (module docstring).

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's fixed path (the noise-free truth); the plan covers its first to last sample.
    craft : BeaconVehicle
        The craft: start, limits (speed, per-axis acceleration, area, distances).
    config : EstimationConfig
        The vehicle's sensors, rates, noises, prior and process noise
        (:mod:`~obsplan.planning.beacon.recursion`); its ``beacon_path`` is ignored.
    step : float or None, optional
        Planning step [s] of the craft's held accelerations; None: the ping interval
        ``1 / rates_hz["range"]`` (:data:`DEFAULT_STEP` without one), at least the horizon over
        :data:`MAX_INTERVALS`.
    weights : ndarray, shape (E,), or None, optional
        Weight of each range epoch (:func:`range_epoch_times`) in the mean, ``>= 0``; None: equal.
    guesses : sequence of BeaconPath, optional
        More starts (e.g. the beacon baselines), each covering the horizon.
    guess_labels : sequence of str or None, optional
        Their labels in :attr:`BeaconPlan.starts` (default ``guess-1``, ...).
    callback : callable or None, optional
        ``callback(index, label, start)`` after each start.
    check_dt : float, optional
        Spacing of the distance limits' check points [s] (:mod:`~obsplan.planning.beacon.craft`).
    tol : float, optional
        IPOPT's ``tol`` on the objective relative to holding station.
    max_iter : int, optional
        IPOPT's iteration limit per start.
    circles : bool or None, optional
        Include the circle starts; False: holding station and ``guesses`` only; None (default):
        the circles only when there are no ``guesses`` (a caller's guesses, the beacon baselines,
        include a circle at its best radius, which the circle starts would only repeat).
    truth_margins : tuple of three ndarray (M,), optional
        Times [s] and the margins [m] on ``min_distance`` and ``max_range`` that keep the limits
        against the vehicle's true path (:func:`~obsplan.planning.beacon.craft.craft_grid`);
        None: the limits are kept on its nominal path only.

    Returns
    -------
    BeaconPlan
        The best converged start (``success``), or, when none converged, the best of the rest
        with its status (``success`` False).

    Raises
    ------
    InputError
        A craft of another dimension, bad ``weights``, a ``step`` or ``check_dt`` that is not
        positive, or a guess that does not cover the horizon or has another dimension.
    ConfigError
        A configuration without a range sensor.
    """
    t_start = time.perf_counter()
    if config.model.dim != vehicle.dim:
        raise InputError(
            f"config.model is {config.model.dim}D but the vehicle's path is {vehicle.dim}D"
        )
    step = _default_step(vehicle, config) if step is None else float(step)
    grid = craft_grid(vehicle, craft, step, check_dt, truth_margins)
    rec = range_recursion(vehicle, config)
    w = _weights(weights, rec.count)
    if circles is None:
        circles = len(guesses) == 0
    starts = _start_paths(vehicle, craft, guesses, guess_labels, circles)
    nlp = _build(grid, rec, w, tol, max_iter)
    outcomes: list[BeaconStart] = []
    xs: list[np.ndarray] = []
    fits: list[np.ndarray] = []
    for i, (label, path) in enumerate(starts):
        t0 = time.perf_counter()
        x0, fitted = _fit(nlp.grid, nlp.fit, path, (nlp.lbx, nlp.ubx, nlp.lbg, nlp.ubg))
        same = _same_start(nlp.grid, x0, fits)
        fits.append(x0)
        if same is not None:  # IPOPT is deterministic: the same start ends where it did
            outcome = replace(
                outcomes[same],
                label=label,
                wall_s=time.perf_counter() - t0,
                same_as=outcomes[same].label,
            )
            x = xs[same]
        else:
            outcome, x = _solve_start(nlp, label, x0, fitted)
            outcome = replace(outcome, wall_s=time.perf_counter() - t0)
        outcomes.append(outcome)
        xs.append(x)
        if callback is not None:
            callback(i, label, outcome)
    best = _pick(nlp, outcomes, xs)
    return _beacon_plan(grid, nlp, craft, xs[best], outcomes[best], tuple(outcomes), t_start)


def _start_paths(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    guesses: Sequence[BeaconPath],
    labels: Sequence[str] | None,
    circles: bool,
) -> list[tuple[str, BeaconPath]]:
    t0, tf = float(vehicle.t[0]), float(vehicle.t[-1])
    out = [("hold", BeaconPath.fixed(craft.start.tolist(), t0, tf))]
    if circles:
        out += circle_guesses(vehicle, craft)
    labels = [f"guess-{i + 1}" for i in range(len(guesses))] if labels is None else list(labels)
    if len(labels) != len(guesses):
        raise InputError(f"guess_labels has {len(labels)} labels for {len(guesses)} guesses")
    for label, path in zip(labels, guesses, strict=True):
        if not isinstance(path, BeaconPath) or path.dim != vehicle.dim:
            raise InputError(f"guess {label!r} must be a {vehicle.dim}D BeaconPath")
        path.check_covers(t0, tf, f"guess {label!r}")
        out.append((str(label), path))
    return out


def _same_start(grid: CraftGrid, x0: np.ndarray, fits: list[np.ndarray]) -> int | None:
    """The first earlier fitted start whose node positions are all within
    :data:`PATH_TOLERANCE_M` of ``x0``'s (None if none is)."""
    pos = x0.reshape(6, grid.N, order="F")[2:4] * grid.L
    for i, other in enumerate(fits):
        if np.max(np.abs(other.reshape(6, grid.N, order="F")[2:4] * grid.L - pos)) <= (
            PATH_TOLERANCE_M
        ):
            return i
    return None


def _pick(nlp: _Nlp, outcomes: list[BeaconStart], xs: list[np.ndarray]) -> int:
    """The best converged start; when none converged, the best feasible-looking one."""

    def key(i: int) -> tuple:
        o = outcomes[i]
        obj = math.inf if o.objective is None else o.objective
        return (not o.success, _violation(nlp, xs[i]) > 1e-9, obj)

    return min(range(len(outcomes)), key=key)


def planning_step(vehicle: Trajectory, config: EstimationConfig) -> float:
    """The craft's default planning step [s] for ``vehicle`` (:func:`plan_beacon` with
    ``step=None``): the ping interval (:data:`DEFAULT_STEP` without a range rate), at least the
    horizon over :data:`MAX_INTERVALS`.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path (its duration).
    config : EstimationConfig
        Its rates (``rates_hz["range"]``).

    Returns
    -------
    float
        The step [s].
    """
    return _default_step(vehicle, config)


def resolve_beacon(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    config: EstimationConfig,
    in_force: BeaconPath,
    *,
    step: float,
    prior: np.ndarray | None = None,
    weights: np.ndarray | None = None,
    check_dt: float = CHECK_DT,
    tol: float = SOLVER_TOL,
    max_iter: int = MAX_ITER,
) -> tuple[BeaconPlan, float]:
    """One receding-horizon re-solve of the craft: from its state (``craft.start``,
    ``craft.velocity``) at the vehicle's first sample to its last, warm-started from the path in
    force (fitted onto the limits from that state), one IPOPT solve, no other start.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's (predicted) remaining path; its first sample is the replan time.
    craft : BeaconVehicle
        The craft with its state at the replan time as its start and velocity, and its limits.
    config : EstimationConfig
        The vehicle's sensors, rates, noises and process noise (its prior is replaced by
        ``prior`` when given).
    in_force : BeaconPath
        The path in force, covering the remaining horizon.
    step : float
        Planning step [s] (the one-shot plan's, so the nodes fall where they did).
    prior : ndarray, shape (m, m), or None, optional
        The vehicle's covariance at the replan time (``(p, v[, v_f])``); None: the
        configuration's prior.
    weights : ndarray, shape (E,), or None, optional
        Per remaining range epoch (:func:`range_epoch_times` of ``vehicle``); None: equal.
    check_dt, tol, max_iter : float, float, int, optional
        As :func:`plan_beacon`.

    Returns
    -------
    plan : BeaconPlan
        The re-solved path (``starts`` holds the one solve; ``hold_objective`` the craft holding
        its position from rest).
    in_force_objective : float
        The objective [m²] of the path in force over the same remaining horizon, with the same
        prior and weights (what flying on would give).
    """
    t_start = time.perf_counter()
    grid = craft_grid(vehicle, craft, float(step), check_dt)
    rec = range_recursion(vehicle, config)
    if prior is not None:
        rec = replace(rec, P0=np.asarray(prior, float))
    w = _weights(weights, rec.count)
    nlp = _build(grid, rec, w, tol, max_iter)
    x0, fitted = _fit(grid, nlp.fit, in_force, (nlp.lbx, nlp.ubx, nlp.lbg, nlp.ubg))
    outcome, x = _solve_start(nlp, "replan", x0, fitted)
    plan = _beacon_plan(grid, nlp, craft, x, outcome, (outcome,), t_start)
    return plan, float(rec.objective(rec.beacons_on_path(in_force), w))


def _beacon_plan(grid, nlp: _Nlp, craft: BeaconVehicle, x, chosen, starts, t_start: float):
    """The :class:`BeaconPlan` of the solved variables ``x`` (the solve ``chosen`` of
    ``starts``): the path sampled, the accelerations in m/s², the objective and holding's."""
    W = x.reshape(6, grid.N, order="F")
    times, positions, velocities = grid.samples(W, PATH_TOLERANCE_M)
    return BeaconPlan(
        times=times,
        positions=positions,
        velocities=velocities,
        path=BeaconPath(times, positions),
        node_times=grid.nodes.copy(),
        accelerations=(W[0:2].T * craft.accel).copy(),
        success=chosen.success,
        status=chosen.status,
        iterations=chosen.iterations,
        wall_s=time.perf_counter() - t_start,
        objective=float(nlp.objective(x)),
        hold_objective=float(nlp.objective(np.zeros(6 * grid.N))),
        starts=starts,
        label=chosen.label,
    )
