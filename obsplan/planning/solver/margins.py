"""Keep-out margins: limits kept by the *true* vehicle, not only by the plan.

A vehicle steers its estimate onto the plan (:mod:`obsplan.estimation.montecarlo.guidance`), so its
true path is the plan minus what its navigation filter gets wrong. The limits that protect it
(``min_range``, ``max_range``, the area box and the depth band) are therefore planned with a
margin that grows with the predicted uncertainty along the path:

    margin(t) = k · (B(t) + σ_w),    k = Φ⁻¹(limits.keepout_confidence)

**Deviation of the true path.** With the guidance ``u = u_ref + Kp (p_ref - p̂) + Kd (v_ref - v̂)``
and estimation errors ``e_p = p̂ - p``, ``e_v = v̂ - v``, the deviation ``δ = p - p_ref`` obeys
``δ'' + Kd δ' + Kp δ = -Kp e_p - Kd e_v + w`` (``w`` the process noise), so along a unit direction
``d`` it is the loop's impulse response ``g`` (``G(s) = 1/(s² + Kd s + Kp)``, ``δ(0) = 0``)
applied to the errors. The triangle inequality in L² bounds its standard deviation whatever the
errors' correlation in time:

    std(dᵀδ(t)) <= B(t) + σ_w,
    B(t) = ∫₀ᵗ |g(τ)| (Kp σ_p(t - τ) + Kd σ_v(t - τ)) dτ,    σ_w² = q ∫₀^∞ g² = q / (2 Kp Kd)

with ``σ_p(s)² = dᵀ P_pp(s) d`` and ``σ_v(s)² = dᵀ P_vv(s) d`` from the posterior Cramér–Rao
bound along the path: the same recursion the planner's ``pcrb-position`` objective evaluates
(:func:`obsplan.planning.objectives.estimator.pcrb_objective`, the validation's prior, process
noise, sensor rates and noises), run numerically once per round. Between two epochs the
predicted variance in a fixed direction is convex in time (a quadratic plus the cubic of the
process noise), so the larger of the priors at the gap's two ends bounds it on the whole gap.
The tracking error is in the bound (the loop's lag and its response to estimate corrections);
``q`` is the white-acceleration intensity of the validation's process noise. For ``min_range``
and ``max_range`` ``d`` is the radial direction at the constraint point, for the area and the
depth band the axis. ``B`` is evaluated at each constraint point and at the ends of the stretch of
path it covers (:mod:`obsplan.planning.solver.formulation`), and the largest value is kept.

**Reserves.** The acceleration the plan leaves free for the feedback and the speed it keeps
below the bound come from the linearised loop's second moments
(:mod:`obsplan.estimation.bounds.loop_covariance`, the CRB's gains along the path): per interval,
``k`` times the largest std of the feedback command ``-(Kp ε_p + Kd ε_v)`` over the epochs acting on
it (at most ``Tuning.reserve_cap`` of the bound, at least ``Tuning.reserve_floor``: the EKF's
transients beyond the linearisation need room to be recovered from), and ``k`` times the filter's
velocity std plus the std of the estimated velocity's deviation (the guidance keeps the estimated
speed ``k σ_v`` below the bound, and the plan must leave room for the estimate's deviation above
that). Between epochs the estimate moves with the known input, so the command moves only with the
filter's corrections, which are white: this is the command's std, not a bound, and much smaller than
the bound above applied to it (a slowly varying estimation error moves the vehicle, not the
command).

**Robust planning.** A plan made for a family of conditions (``objective.robust_prior``,
``robust_range_noise``, :mod:`obsplan.planning.objectives.robust`) keeps its limits in every one of
them: the margins are the largest over the conditions, each from that condition's prior and range
noise, with the guidance the vehicle flies (its gains from the nominal prior).

**Fixed point.** The margin depends on the path, the path on the margin. The plan is solved
without margins (the full multi-start strategy), the margins are computed on it, and the NLP is
re-solved warm from it with every limit tightened by its margin (only the bounds ``lbg``, ``ubg``,
``lbx``, ``ubx`` change: the compiled NLP is the same). The margins are then recomputed on the new
path; where they grew, the tightening takes the larger value and the NLP is solved again, at most
``Tuning.max_rounds`` times. The margins only grow, so the rounds stop; ``held`` says whether the
returned path keeps the margins computed on itself. Symbolic margins (the recursion inside every
constraint) would make every limit row dense in the whole path; this costs one or two warm
re-solves.

The bound uses the Cramér–Rao bound, which the EKF attains only asymptotically, and the normal
quantile per point, not over the whole path; how often the true path breaks the limit is measured
by the closed-loop Monte Carlo (``TruthStats`` of :mod:`obsplan.estimation.montecarlo.stats`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
import scipy.linalg

from obsplan.estimation.bounds.crlb import CRLBResult
from obsplan.estimation.bounds.loop_covariance import LoopCovariance, loop_covariance
from obsplan.estimation.bounds.riccati import run_recursion
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.guidance import SPEED_RESERVE_CAP, Guidance
from obsplan.planning.objectives.estimator import CovarianceObjective, covariance_objective
from obsplan.planning.objectives.evaluate import objective_value
from obsplan.planning.objectives.guards import (
    DEFAULT_BOUNDS,
    ESTIMATORS,
    HELD,
    SHORT,
    engages,
    guard_ratios_of,
)
from obsplan.planning.objectives.robust import condition_problems, is_robust
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.feasibility import beacon_of, check_limits, range_extremes
from obsplan.planning.problem.validation_setup import (
    confidence_quantile,
    estimation_config,
    validation_guidance,
)
from obsplan.planning.solver.formulation import Formulation, build_formulation
from obsplan.planning.solver.solve import GuardOutcome, SolveResult, solve
from obsplan.planning.solver.starts import StartOutcome, run_start, start_context
from obsplan.planning.transcription.grid import Grid, distance_times
from obsplan.planning.tuning import cache_per_tuning, tuning
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True)
class LoopResponse:
    """The guidance loop's impulse response on a grid: ``∫₀ˣ |g|`` and ``∫ g²``.

    Attributes
    ----------
    tau : ndarray (M,)
        Lags [s] from 0 to ``30 /`` (the loop's slowest decay rate).
    cum_abs : ndarray (M,)
        ``∫₀^tau |g|`` [s²] (the position's response).
    l2 : float
        ``∫₀^∞ g²`` [s³].
    kp, kd : float
        The gains [1/s²], [1/s].
    """

    tau: np.ndarray
    cum_abs: np.ndarray
    l2: float
    kp: float
    kd: float

    @classmethod
    def of(cls, guidance: Guidance, samples: int = 4000) -> LoopResponse:
        """The response of ``δ'' + Kd δ' + Kp δ = input``: ``(g, g') = e^{Aτ} [0 1]ᵀ``.

        Parameters
        ----------
        guidance : Guidance
            The guidance law: its gains ``kp`` [1/s²] and ``kd`` [1/s].
        samples : int, optional
            Number of lags ``M`` from 0 to 30 times the loop's slowest time constant (beyond
            it the response has decayed by ``e⁻³⁰``); the integrals use the trapezoidal rule.

        Returns
        -------
        LoopResponse
            The lags, ``∫₀^tau |g|`` on them, ``∫ g²`` and the gains.

        Raises
        ------
        ValueError
            If ``kp <= 0`` or ``kd <= 0`` (the loop does not settle).
        """
        kp, kd = guidance.kp, guidance.kd
        if kp <= 0 or kd <= 0:
            raise ValueError("keep-out margins need a guidance with kp > 0 and kd > 0")
        A = np.array([[0.0, 1.0], [-kp, -kd]])
        # slowest decay rate of the loop: the real part of its slower pole
        rate = kd / 2.0 - math.sqrt(max(kd**2 / 4.0 - kp, 0.0))
        tau = np.linspace(0.0, 30.0 / rate, samples)  # e^-30: the tail beyond is negligible
        dt = tau[1] - tau[0]
        step = scipy.linalg.expm(A * dt)
        resp = np.empty((samples, 2))
        x = np.array([0.0, 1.0])
        for i in range(samples):
            resp[i] = x
            x = step @ x

        def cumulative(y: np.ndarray) -> np.ndarray:
            return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * dt)])

        g = resp[:, 0]
        return cls(
            tau=tau,
            cum_abs=cumulative(np.abs(g)),
            l2=float(cumulative(g**2)[-1]),
            kp=kp,
            kd=kd,
        )

    def weight(self, x: np.ndarray) -> np.ndarray:
        """``∫₀ˣ |g|`` at lags ``x`` [s] (0 for ``x <= 0``).

        Parameters
        ----------
        x : ndarray
            Lags [s], any shape.

        Returns
        -------
        ndarray
            ``∫₀ˣ |g|`` [s²], shape of ``x``, interpolated linearly on :attr:`tau` (the full
            integral beyond its last lag).
        """
        return np.interp(np.maximum(x, 0.0), self.tau, self.cum_abs)


@dataclass(frozen=True, eq=False)
class PathCovariance:
    """The PCRB's position and velocity covariances at the epochs along a path.

    Attributes
    ----------
    time : ndarray (J,)
        Epoch times [s] from the start.
    pos, vel : ndarray (J, n, n)
        Prior covariance (before the update) at each epoch [m²], [m²/s²]; at the first epoch
        the prior of the validation.
    """

    time: np.ndarray
    pos: np.ndarray
    vel: np.ndarray

    def gap_std(self, d: np.ndarray, block: str) -> np.ndarray:
        """Per gap ``j`` (epoch ``j`` to ``j + 1``) the largest ``sqrt(dᵀPd)`` at its ends, for
        each of the ``C`` unit directions ``d``.

        The variance in a fixed direction is convex in time between two epochs, so the larger of
        the two ends bounds it on the whole gap.

        Parameters
        ----------
        d : ndarray, shape (C, n)
            Unit directions.
        block : {"pos", "vel"}
            The covariance: :attr:`pos`, or :attr:`vel` (any other value).

        Returns
        -------
        ndarray, shape (C, J - 1)
            The std along each direction per gap [m] or [m/s].
        """
        P = self.pos if block == "pos" else self.vel
        var = np.einsum("ci,jik,ck->cj", d, P, d)
        return np.sqrt(np.maximum(np.maximum(var[:, :-1], var[:, 1:]), 0.0))


@cache_per_tuning
def _pcrb(pb: PlanningProblem) -> CovarianceObjective:
    return covariance_objective(pb, "pcrb-position")


def path_covariance(traj: Trajectory, pb: PlanningProblem) -> PathCovariance:
    """The posterior CRB along ``traj`` (on the planning grid), numerically.

    The recursion of the ``pcrb-position`` objective (its model, epochs, prior and range rows),
    so the margins and that objective predict the same covariance.

    Parameters
    ----------
    traj : Trajectory
        A path on the planning grid of ``pb`` (``N + 1`` samples).
    pb : PlanningProblem
        The problem: the validation's prior, process noise, sensor rates and noises.

    Returns
    -------
    PathCovariance
        The prior covariances of position [m²] and velocity [m²/s²] at every epoch, the first
        the validation's prior.
    """
    cobj = _pcrb(pb)
    grid = Grid.from_problem(pb)
    h, rho = cobj.rows(grid, grid.from_trajectory(traj))
    P_prior, _ = run_recursion(cobj.model, cobj.epochs, cobj.P0, h, rho, cobj.mask)
    m, J = cobj.model.m, cobj.epochs.count
    blocks = np.asarray(P_prior).reshape(m, J, m).transpose(1, 0, 2)  # (J, m, m)
    # block j is the prior at epoch j + 1; epoch 0 starts from the validation's prior
    P = np.concatenate([np.asarray(cobj.P0, float)[None], blocks[:-1]])
    nav = cobj.model.nav
    Pn = np.einsum("ai,jik,bk->jab", nav, P, nav)
    n = pb.dim
    s = cobj.scale
    return PathCovariance(
        time=np.asarray(cobj.epochs.time, float),
        pos=Pn[:, :n, :n] * s**2,
        vel=Pn[:, n:, n:] * s**2,
    )


def path_loop_covariance(
    traj: Trajectory, pb: PlanningProblem, guidance: Guidance
) -> LoopCovariance:
    """The linearised closed loop along ``traj`` (planning grid) flown with ``guidance``
    (:func:`~obsplan.estimation.bounds.loop_covariance.loop_covariance`), with the posterior CRB of
    the ``pcrb-position`` recursion as the filter's covariance.

    Parameters
    ----------
    traj : Trajectory
        A path on the planning grid of ``pb`` (``N + 1`` samples).
    pb : PlanningProblem
        The problem: the validation's prior, process noise, sensor rates and noises.
    guidance : Guidance
        The guidance law flown: its gains ``kp`` [1/s²] and ``kd`` [1/s].

    Returns
    -------
    LoopCovariance
        The second moments of the filter's covariance, the estimated and the true deviations
        from the plan after each epoch's update.
    """
    cobj = _pcrb(pb)
    assert cobj.scale == 1.0  # the CRB's recursion is in metres and seconds, as the gains
    grid = Grid.from_problem(pb)
    h, rho = cobj.rows(grid, grid.from_trajectory(traj))
    return loop_covariance(
        cobj.model, cobj.epochs, cobj.P0, h, rho, guidance.kp, guidance.kd, cobj.mask
    )


def _interval_epochs(epoch_time: np.ndarray, node_time: np.ndarray) -> np.ndarray:
    """Per interval ``[t_i, t_{i+1}]`` the first and last epoch whose update acts on it: the last
    epoch at or before ``t_i`` through the last one before ``t_{i+1}``, shape (N, 2)."""
    lo = np.searchsorted(epoch_time, node_time[:-1], side="right") - 1
    hi = np.searchsorted(epoch_time, node_time[1:], side="left") - 1
    lo = np.clip(lo, 0, epoch_time.size - 1)
    return np.stack([lo, np.maximum(hi, lo)], axis=1)


def _window_max(values: np.ndarray, window: np.ndarray) -> np.ndarray:
    """The largest of ``values`` (J, c) over each epoch window (N, 2) (inclusive), (N, c)."""
    out = np.empty((window.shape[0], values.shape[1]))
    for i, (a, b) in enumerate(window):
        out[i] = values[a : b + 1].max(axis=0)
    return out


def deviation_bound(
    cov: PathCovariance,
    loop: LoopResponse,
    q: float,
    times: np.ndarray,
    dirs: np.ndarray,
) -> np.ndarray:
    """``B(t) + σ_w`` (module docstring) [m] along unit directions ``dirs``, the largest over
    the times ``times`` of each direction.

    Parameters
    ----------
    cov : PathCovariance
        The CRB's position and velocity covariances at the epochs along the path.
    loop : LoopResponse
        The guidance loop's impulse response.
    q : float
        White-acceleration intensity of the process noise [m²/s³], per axis.
    times : ndarray, shape (C, T)
        Times [s] from the start at which to bound each direction's deviation.
    dirs : ndarray, shape (C, n)
        Unit directions.

    Returns
    -------
    ndarray, shape (C,)
        Per direction, the largest ``B(t)`` over its ``T`` times plus ``σ_w = sqrt(q ∫ g²)``
        [m]: a bound on the std of the true path's deviation along it (not yet times ``k``).
    """
    sp = cov.gap_std(dirs, "pos")  # (C, J-1)
    sv = cov.gap_std(dirs, "vel")
    a, b = cov.time[:-1], cov.time[1:]
    drive = loop.kp * sp + loop.kd * sv
    out = np.zeros(dirs.shape[0])
    for col in range(times.shape[1]):
        t = times[:, col][:, None]
        # ∫ over gap [a, b] ∩ [0, t] of |g(t - s)| ds
        w = loop.weight(t - a[None, :]) - loop.weight(t - np.minimum(b[None, :], t))
        out = np.maximum(out, np.sum(w * drive, axis=1))
    return out + math.sqrt(max(q * loop.l2, 0.0))


@dataclass(frozen=True)
class KeepoutMargins:
    """The margins of one path, in metres.

    Attributes
    ----------
    confidence : float
        ``limits.keepout_confidence``.
    k : float
        ``Φ⁻¹(confidence)``.
    range_points : ndarray (2N,)
        At the distance constraints' points: nodes 1..N, then the N interval midpoints
        (:func:`obsplan.planning.solver.formulation.path_constraints`); zeros without a distance
        limit.
    box : ndarray (n, N)
        Per axis at nodes 1..N (the area's x, y and the depth band's z); zeros where unbounded.
    accel_reserve : ndarray (n, N)
        Per axis and interval, the fraction of the acceleration bound kept for the guidance's
        feedback (at most ``Tuning.reserve_cap``).
    speed : ndarray (N,)
        At nodes 1..N, the speed reserve [m/s]: the guidance bounds the *estimated* speed by
        ``speed - k σ_v`` (:class:`~obsplan.estimation.montecarlo.guidance.Guidance`, ``speed_k``),
        so the plan keeps ``k`` times the velocity std and the velocity deviation's bound below it
        (at most :data:`~obsplan.estimation.montecarlo.guidance.SPEED_RESERVE_CAP` of the bound);
        zeros without a speed limit.
    """

    confidence: float
    k: float
    range_points: np.ndarray
    box: np.ndarray
    accel_reserve: np.ndarray
    speed: np.ndarray
    #: Largest speed reserve [m/s]: the guidance's own cap,
    #: :data:`~obsplan.estimation.montecarlo.guidance.SPEED_RESERVE_CAP` of the speed bound (a plan
    #: slower than the guidance's floor gains nothing).
    speed_cap: float = math.inf

    def maximum(self, other: KeepoutMargins, scale: float = 1.0) -> KeepoutMargins:
        """The larger of these margins and ``scale`` times ``other``'s at every point (the
        reserves capped at ``Tuning.reserve_cap`` and :attr:`speed_cap`).

        Parameters
        ----------
        other : KeepoutMargins
            Margins on the same grid (e.g. of another condition, or of the new path).
        scale : float, optional
            Factor on ``other``'s margins before the comparison (``1 + Tuning.inflate`` in
            :func:`keep_out`, so that the rounds do not creep up in tiny steps).

        Returns
        -------
        KeepoutMargins
            These margins with every array the pointwise maximum; ``confidence``, ``k`` and
            ``speed_cap`` are these margins', the speed reserve capped at the smaller of the two
            caps.
        """
        reserve = np.minimum(scale * other.accel_reserve, tuning().reserve_cap)
        speed = np.minimum(scale * other.speed, min(self.speed_cap, other.speed_cap))
        return replace(
            self,
            range_points=np.maximum(self.range_points, scale * other.range_points),
            box=np.maximum(self.box, scale * other.box),
            accel_reserve=np.maximum(self.accel_reserve, reserve),
            speed=np.maximum(self.speed, speed),
        )

    def without_speed_reserve(self) -> KeepoutMargins:
        """These margins with no speed reserve (every other margin kept).

        Returns
        -------
        KeepoutMargins
            With ``speed`` zero and ``speed_cap`` 0, so that a later :meth:`maximum` adds no
            speed reserve back.
        """
        return replace(self, speed=np.zeros_like(self.speed), speed_cap=0.0)

    def grew(self, other: KeepoutMargins, atol: float | None = None) -> bool:
        """True when ``other`` exceeds these margins anywhere by more than ``atol`` [m], its
        reserves by more than ``Tuning.reserve_atol`` and ``Tuning.speed_atol``.

        Parameters
        ----------
        other : KeepoutMargins
            Margins on the same grid, typically recomputed on the re-solved path.
        atol : float, optional
            Tolerance on the distance and box margins [m] (default ``Tuning.margin_atol_m``).

        Returns
        -------
        bool
            Whether any margin grew beyond its tolerance (``other``'s speed reserve counted up to
            :attr:`speed_cap`): if not, the path keeps the margins computed on itself.
        """
        tun = tuning()
        if atol is None:
            atol = tun.margin_atol_m
        return bool(
            np.any(other.range_points > self.range_points + atol)
            or np.any(other.box > self.box + atol)
            or np.any(other.accel_reserve > self.accel_reserve + tun.reserve_atol)
            or np.any(np.minimum(other.speed, self.speed_cap) > self.speed + tun.speed_atol)
        )

    def to_dict(self) -> dict:
        """JSON-ready summary of these margins.

        Returns
        -------
        dict
            ``confidence``, ``k``, and the largest margins ``max_range_margin_m`` [m],
            ``max_box_margin_m`` [m], ``max_accel_reserve`` (fraction of the bound) and
            ``max_speed_margin_mps`` [m/s] (0 when empty): the margin keys of ``keepout`` in
            report.json (:meth:`KeepoutReport.to_dict`).
        """
        return {
            "confidence": self.confidence,
            "k": self.k,
            "max_range_margin_m": float(np.max(self.range_points, initial=0.0)),
            "max_box_margin_m": float(np.max(self.box, initial=0.0)),
            "max_accel_reserve": float(np.max(self.accel_reserve, initial=0.0)),
            "max_speed_margin_mps": float(np.max(self.speed, initial=0.0)),
        }


def _range_points(grid: Grid, traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Times (2N,) and positions relative to the beacon (2N, n) of the distance constraints."""
    h = grid.h
    rel = traj.p - grid.beacon
    mid = rel[:-1] + traj.v[:-1] * (h / 2) + 0.5 * traj.u[:-1] * (h / 2) ** 2
    s = distance_times(grid)
    pts = np.vstack([rel[1:], mid])
    if grid.beacon_path is not None:  # relative to the beacon where it is at each point
        pts = pts - grid.beacon_offset(s).T
    return s, pts


def _process_intensity(pb: PlanningProblem, config: EstimationConfig | None = None) -> float:
    """White-acceleration PSD ``q`` [m²/s³] of the validation's process noise, per axis: the
    velocity variance it adds per filter step over the step (exact for the physical noise);
    ``config`` the validation's configuration when ``pb``'s beacon needs a path to give one."""
    dt = pb.validation.dt
    cfg = estimation_config(pb) if config is None else config
    q_step = np.asarray(cfg.covariances(dt)["q_ekf"], float)
    n = pb.dim
    return float(np.max(np.diag(q_step)[n : 2 * n]) / dt)


#: Times at which :func:`craft_distance_margins` evaluates the bound (interpolated between).
MARGIN_TIMES = 400


@dataclass(frozen=True)
class CraftMargins:
    """Margins on a beacon craft's distance limits to the vehicle, kept by the vehicle's *true*
    path (a planned beacon, :func:`craft_distance_margins`).

    Attributes
    ----------
    t : ndarray (M,)
        Times [s] of the vehicle's samples.
    horizontal : ndarray (M,)
        Margin on ``min_distance`` (horizontal) at each time [m].
    range : ndarray (M,)
        Margin on ``max_range`` at each time [m].
    confidence, k : float
        ``limits.keepout_confidence`` and its normal quantile (0: no margins).
    """

    t: np.ndarray
    horizontal: np.ndarray
    range: np.ndarray
    confidence: float
    k: float


def craft_distance_margins(
    crb: CRLBResult, pb: PlanningProblem, config: EstimationConfig
) -> CraftMargins:
    """Margins ``k (B(t) + σ_w)`` (module docstring) on a beacon craft's distance limits, from the
    vehicle's posterior CRB along its path with that craft's beacon.

    The rule of the fixed beacon's ``min_range`` and ``max_range``, with the same guidance (the
    law flown at sea), ``k`` and process noise; two differences. The direction from the vehicle to
    the craft is not known before the craft is planned, so the std in every direction is bounded
    by ``sqrt(tr P)`` (of the horizontal block for ``min_distance``, of the whole position block
    for ``max_range``): at most ``sqrt(2)`` (``sqrt(3)``) times the std along the radial
    direction. And the CRB is the one at the vehicle's samples (``crb``), not at the planning
    epochs.

    Parameters
    ----------
    crb : CRLBResult
        The vehicle's posterior CRB along its path with the craft's beacon.
    pb : PlanningProblem
        The problem: ``limits.keepout_confidence``, the limits (the guidance's gains) and the
        validation's process noise.
    config : EstimationConfig
        The validation's configuration with the craft's beacon (its process noise).

    Returns
    -------
    CraftMargins
        The margins [m] at the CRB's times; zeros when ``limits.keepout_confidence`` is 0.
    """
    conf = float(pb.limits.keepout_confidence)
    k = confidence_quantile(conf)
    t = np.asarray(crb.t, float)
    if k == 0:
        zero = np.zeros(t.size)
        return CraftMargins(t, zero, zero.copy(), conf, 0.0)
    guidance = validation_guidance(pb, at_sea=True)
    assert guidance is not None  # at_sea: never None
    loop = LoopResponse.of(guidance)
    q = _process_intensity(pb, config)
    var_p = np.asarray(crb.pos_std_axes_t, float) ** 2
    # the velocity's per-axis split is not in the CRB's result: its trace on every axis bounds it
    var_v = np.asarray(crb.vel_std_t, float) ** 2
    eye = np.eye(var_p.shape[1])
    # the bound at a few hundred times, each the larger of its own and its neighbours' (B is
    # smooth on the loop's time constant, which is longer than these gaps on a survey)
    at = np.unique(np.linspace(0, t.size - 1, min(t.size, MARGIN_TIMES)).round().astype(int))
    out = []
    for var in (var_p[:, :2].sum(axis=1), var_p.sum(axis=1)):
        cov = PathCovariance(time=t, pos=var[:, None, None] * eye, vel=var_v[:, None, None] * eye)
        m = k * deviation_bound(cov, loop, q, t[at][:, None], np.repeat(eye[:1], at.size, 0))
        m = np.maximum(m, np.maximum(np.r_[m[1:], m[-1]], np.r_[m[0], m[:-1]]))
        out.append(np.interp(t, t[at], m))
    return CraftMargins(t, out[0], out[1], conf, k)


def _box_axes(pb: PlanningProblem) -> list[tuple[int, tuple[float, float]]]:
    lim = pb.limits
    out: list[tuple[int, tuple[float, float]]] = []
    if lim.area is not None:
        out += [(0, lim.area.x), (1, lim.area.y)]
    if lim.depth is not None:
        out.append((2, lim.depth))
    return out


def keepout_margins(
    traj: Trajectory, pb: PlanningProblem, guidance: Guidance | None = None
) -> KeepoutMargins:
    """The margins (module docstring) of the limits of ``pb`` along ``traj`` (planning grid):
    with robust planning (``objective.robust_prior`` / ``robust_range_noise``), the largest over
    every condition of the family, each with that condition's prior and range noise and the
    guidance the vehicle flies (designed for the nominal prior): the limits are kept for every
    world the plan is made for, not only the nominal one.

    Parameters
    ----------
    traj : Trajectory
        A path on the planning grid (``N + 1`` samples).
    pb : PlanningProblem
        The problem: limits, ``limits.keepout_confidence``, the validation's filter settings.
    guidance : Guidance, optional
        The guidance law the vehicle flies with (default: the validation's,
        :func:`~obsplan.planning.problem.validation_setup.validation_guidance` with ``at_sea``).

    Returns
    -------
    KeepoutMargins
        The margins [m] and reserves along ``traj`` (:func:`condition_margins`; all zero when
        ``limits.keepout_confidence`` is 0).
    """
    flown = guidance or validation_guidance(pb, at_sea=True)
    assert flown is not None  # at_sea: never None
    family = condition_problems(pb) if is_robust(pb) else (pb,)
    out = condition_margins(traj, family[0], flown)
    for cpb in family[1:]:
        out = out.maximum(condition_margins(traj, cpb, flown))
    return out


def condition_margins(traj: Trajectory, pb: PlanningProblem, guidance: Guidance) -> KeepoutMargins:
    """:func:`keepout_margins` of one condition: ``pb``'s own prior and noises, flown with
    ``guidance``.

    Parameters
    ----------
    traj : Trajectory
        A path on the planning grid (``N + 1`` samples).
    pb : PlanningProblem
        The condition's problem: its limits, confidence, prior, noises and sensor rates.
    guidance : Guidance
        Required: the vehicle's guidance, whatever the condition (its gains from the nominal
        prior).

    Returns
    -------
    KeepoutMargins
        ``k`` times the deviation bound at the distance constraints' points (each the largest
        over ``±h/4``) and at the nodes of each bounded axis (over ``±h/2``), zero where there
        is no such limit; the acceleration reserve between ``Tuning.reserve_floor`` and
        ``Tuning.reserve_cap``; the speed reserve at most ``SPEED_RESERVE_CAP`` of the speed
        bound (0 without one). All zero when ``k`` is 0.
    """
    grid = Grid.from_problem(pb)
    n, N = grid.n, grid.N
    conf = float(pb.limits.keepout_confidence)
    k = confidence_quantile(conf)
    rng = np.zeros(2 * N)
    box = np.zeros((n, N))
    reserve = np.zeros((n, N))
    speed = np.zeros(N)
    if k == 0:
        return KeepoutMargins(conf, k, rng, box, reserve, speed)
    lim = pb.limits
    cov = path_covariance(traj, pb)
    loop = LoopResponse.of(guidance)
    q = _process_intensity(pb)
    T = float(grid.times[-1])
    if lim.min_range > 0 or lim.max_range is not None:
        t, rel = _range_points(grid, traj)
        dirs = rel / np.maximum(np.linalg.norm(rel, axis=1, keepdims=True), 1e-12)
        tau = grid.h / 4.0
        times = np.clip(np.stack([t - tau, t, t + tau], axis=1), 0.0, T)
        rng = k * deviation_bound(cov, loop, q, times, dirs)
    t_nodes = grid.times[1:]
    at_nodes = np.clip(np.stack([t_nodes - grid.h / 2, t_nodes, t_nodes + grid.h / 2], 1), 0, T)
    for axis, _ in _box_axes(pb):
        box[axis] = k * deviation_bound(cov, loop, q, at_nodes, _axis_dirs(N, n, axis))
    # the reserves: the feedback command and the estimated velocity move only with the filter's
    # corrections (obsplan.estimation.bounds.loop_covariance), at the epochs of each interval
    loop_cov = path_loop_covariance(traj, pb, guidance)
    window = _interval_epochs(loop_cov.time, grid.times)
    command = _window_max(loop_cov.command_std(guidance.kp, guidance.kd), window)  # (N, n)
    tun = tuning()
    reserve = np.clip(
        k * command.T / np.asarray(grid.a, float)[:, None], tun.reserve_floor, tun.reserve_cap
    )
    vel = loop_cov.std("filter", "vel").max(axis=1) + loop_cov.std("estimated", "vel").max(axis=1)
    speed = k * _window_max(vel[:, None], window)[:, 0]
    cap = SPEED_RESERVE_CAP * float(lim.speed) if lim.speed is not None else 0.0
    speed = np.minimum(speed, cap)
    return KeepoutMargins(conf, k, rng, box, reserve, speed, cap)


def _axis_dirs(count: int, n: int, axis: int) -> np.ndarray:
    d = np.zeros((count, n))
    d[:, axis] = 1.0
    return d


def start_reach(grid: Grid, axis: int, sign: float, accel: float) -> np.ndarray:
    """Farthest displacement [m] along ``sign`` times ``axis`` from the start by each node
    ``1..N``: the start velocity, then ``accel`` [m/s²] up to the speed bound.

    Parameters
    ----------
    grid : Grid
        The planning grid: node times, start velocity ``v0`` [m/s] and speed bound ``v_max``
        [m/s].
    axis : int
        The axis (0, 1 or 2 for the depth).
    sign : float
        +1 or -1: the direction along the axis.
    accel : float
        The acceleration available along it [m/s²]; ``<= 0``: the start velocity only.

    Returns
    -------
    ndarray, shape (N,)
        The displacement [m] at nodes ``1..N`` (negative where the start velocity points the
        other way and ``accel`` has not yet turned it).
    """
    t = grid.times[1:]
    v = sign * float(grid.v0[axis])
    v_max = float(grid.v_max)
    if accel <= 0.0:
        return v * t
    t1 = max((v_max - v) / accel, 0.0)
    return np.where(
        t <= t1, v * t + 0.5 * accel * t**2, v * t1 + 0.5 * accel * t1**2 + v_max * (t - t1)
    )


def _box_margin_limits(
    form: Formulation, margins: KeepoutMargins
) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per area/depth axis: the margin [m] at most ``Tuning.box_share`` of the width, and the room
    the start leaves below and above (:func:`box_margins`), each ``(N,)``."""
    grid = form.grid
    n, N = grid.n, grid.N
    lbW = form.lbx[: form.n_w].reshape(3 * n, N, order="F")
    ubW = form.ubx[: form.n_w].reshape(3 * n, N, order="F")
    out = {}
    tun = tuning()
    for axis, (lo, hi) in _box_axes(form.problem):
        full = np.minimum(margins.box[axis], tun.box_share * (hi - lo))
        reserve = float(np.max(margins.accel_reserve[axis], initial=0.0))
        accel = float(grid.a[axis]) * (1.0 - reserve)
        p0 = float(grid.p0[axis])
        up = tun.start_reach_share * start_reach(grid, axis, 1.0, accel)
        down = tun.start_reach_share * start_reach(grid, axis, -1.0, accel)
        out[axis] = (full, p0 - lbW[n + axis] * grid.Lp + up, ubW[n + axis] * grid.Lp - p0 + down)
    return out


def box_margins(
    form: Formulation, margins: KeepoutMargins
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per area/depth axis, the margins [m] the NLP's lower and upper node bounds get, each
    ``(N,)``: ``margins.box`` at most ``Tuning.box_share`` of the width, and at most the
    start's distance to the limit plus ``Tuning.start_reach_share`` of what the vehicle can add
    to it by each node (:func:`start_reach`, at the acceleration the reserve leaves).

    Why the second cap: a start closer to a limit than its margin cannot be ``k σ`` from it at
    once, so the margin grows in with what the vehicle can reach (:func:`start_limited_s`).

    Parameters
    ----------
    form : Formulation
        The planning NLP (untightened): its node bounds and grid.
    margins : KeepoutMargins
        The margins: ``box`` and the acceleration reserve.

    Returns
    -------
    dict of int to tuple of ndarray
        Per bounded axis (0, 1: the area's x, y; 2: the depth band), ``(lower, upper)``
        margins [m], each shape ``(N,)`` at nodes ``1..N``, never negative.
    """
    return {
        axis: (np.minimum(full, np.maximum(lo, 0.0)), np.minimum(full, np.maximum(hi, 0.0)))
        for axis, (full, lo, hi) in _box_margin_limits(form, margins).items()
    }


def start_limited_s(form: Formulation, margins: KeepoutMargins) -> float:
    """Time [s] of the last node whose area or depth margin the start limits
    (:func:`box_margins`; 0 when none).

    Parameters
    ----------
    form : Formulation
        The planning NLP (untightened).
    margins : KeepoutMargins
        The margins.

    Returns
    -------
    float
        The time [s] from the start; a margin counts as limited when it is more than
        ``Tuning.margin_atol_m`` below ``margins.box`` capped at ``Tuning.box_share`` of the
        width.
    """
    last = 0.0
    atol = tuning().margin_atol_m
    for full, lo, hi in _box_margin_limits(form, margins).values():
        short = np.flatnonzero((lo < full - atol) | (hi < full - atol))
        if short.size:
            last = max(last, float(form.grid.times[1 + short[-1]]))
    return last


def tighten(form: Formulation, margins: KeepoutMargins) -> Formulation:
    """``form`` with its distance and box limits tightened by ``margins`` (bounds only: the
    symbols, and so a compiled solver, are unchanged); the area and depth margins as
    :func:`box_margins` gives them.

    Parameters
    ----------
    form : Formulation
        The planning NLP (untightened).
    margins : KeepoutMargins
        The margins and reserves.

    Returns
    -------
    Formulation
        A copy with new ``lbg``, ``ubg``, ``lbx``, ``ubx``: ``min_range`` raised and
        ``max_range`` lowered by the range margins, the speed constraint
        ``|V|² <= (1 - speed / v_max)²``, the area/depth node bounds narrowed, and the inputs
        bounded by ``|U| <= 1 - accel_reserve``.
    """
    grid = form.grid
    lbg, ubg = form.lbg.copy(), form.ubg.copy()
    row = 0
    for block in form.constraints:
        sl = slice(row, row + block.size)
        if block.name == "min_range":
            lbg[sl] += margins.range_points / grid.Lp
        elif block.name == "max_range":
            ubg[sl] -= margins.range_points / grid.Lp
        elif block.name == "speed":  # |V|² <= (1 - reserve / v_max)²
            ubg[sl] = np.minimum(ubg[sl], (1.0 - margins.speed / grid.v_max) ** 2)
        row += block.size
    lbx, ubx = form.lbx.copy(), form.ubx.copy()
    n, N = grid.n, grid.N
    lbW = lbx[: form.n_w].reshape(3 * n, N, order="F")  # views into lbx, ubx
    ubW = ubx[: form.n_w].reshape(3 * n, N, order="F")
    for axis, (m_lo, m_hi) in box_margins(form, margins).items():
        lbW[n + axis] += m_lo / grid.Lp
        ubW[n + axis] -= m_hi / grid.Lp
    # inputs: |U| <= 1 - reserve (U is the input over the per-axis bound)
    lbW[:n] = np.maximum(lbW[:n], -(1.0 - margins.accel_reserve))
    ubW[:n] = np.minimum(ubW[:n], 1.0 - margins.accel_reserve)
    return replace(form, lbg=lbg, ubg=ubg, lbx=lbx, ubx=ubx)


def keeps_margins(form: Formulation, traj: Trajectory, tol: float | None = None) -> bool:
    """True when ``traj`` satisfies the (tightened) path constraints and bounds of ``form``.

    Parameters
    ----------
    form : Formulation
        The NLP, typically :func:`tighten`'s.
    traj : Trajectory
        A path on the planning grid (``N + 1`` samples).
    tol : float, optional
        Tolerance in intrinsic units (default ``Tuning.held_tol``): on the bounds of ``W``
        absolute, on the path constraints relative (``tol (1 + |g|)``).

    Returns
    -------
    bool
        Whether every bound of ``W`` and every path constraint holds to ``tol`` (the
        objective's and the parts' constraints are not checked).
    """
    if tol is None:
        tol = tuning().held_tol
    W = form.grid.from_trajectory(traj)
    w = W.reshape(-1, order="F")
    k, nw = form.n_path_constraints, form.n_w
    g_path = ca.Function("g_path", [form.w], [form.g[:k]])
    x = np.concatenate([w, np.zeros(form.w.numel() - nw)])
    g = np.asarray(g_path(x)).reshape(-1)
    scale = 1.0 + np.abs(g)
    ok_g = np.all(g >= form.lbg[:k] - tol * scale) and np.all(g <= form.ubg[:k] + tol * scale)
    ok_x = np.all(w >= form.lbx[:nw] - tol) and np.all(w <= form.ubx[:nw] + tol)
    return bool(ok_g and ok_x)


@dataclass(frozen=True)
class KeepoutReport:
    """How the keep-out margins were kept (``keepout`` of report.json).

    Attributes
    ----------
    confidence, k : float
        The stated confidence and its normal quantile.
    rounds : int
        Re-solves with tightened limits (0: margins disabled or nothing to keep).
    held : bool
        The returned path keeps the margins computed on itself.
    statuses : tuple of str
        IPOPT status of each re-solve.
    max_range_margin_m, max_box_margin_m : float
        Largest margin on the distance limits and on the area/depth band [m].
    max_accel_reserve : float
        Largest fraction of an acceleration bound kept for the guidance.
    max_speed_margin_mps : float
        Largest speed reserve [m/s] below the speed bound.
    planned_closest_range_m : float
        The returned path's closest distance to the beacon [m].
    wall_s : float
        Time of the margins and the re-solves [s].
    note : str
    """

    confidence: float
    k: float
    rounds: int
    held: bool
    statuses: tuple[str, ...]
    max_range_margin_m: float
    max_box_margin_m: float
    max_accel_reserve: float
    planned_closest_range_m: float
    wall_s: float
    note: str = ""
    max_speed_margin_mps: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready form of the report (``keepout`` of report.json).

        Returns
        -------
        dict
            Every attribute by name: ``confidence``, ``k``, ``rounds``, ``held``, ``statuses``
            (a list), ``max_range_margin_m``, ``max_box_margin_m``, ``max_accel_reserve``,
            ``max_speed_margin_mps``, ``planned_closest_range_m``, ``wall_s`` and ``note``.
        """
        return {
            "confidence": self.confidence,
            "k": self.k,
            "rounds": self.rounds,
            "held": self.held,
            "statuses": list(self.statuses),
            "max_range_margin_m": self.max_range_margin_m,
            "max_box_margin_m": self.max_box_margin_m,
            "max_accel_reserve": self.max_accel_reserve,
            "max_speed_margin_mps": self.max_speed_margin_mps,
            "planned_closest_range_m": self.planned_closest_range_m,
            "wall_s": self.wall_s,
            "note": self.note,
        }


def _resolve(
    form: Formulation, margins: KeepoutMargins, guess: Trajectory, label: str
) -> tuple[StartOutcome, Trajectory | None, bool]:
    """One warm IPOPT run of the tightened NLP from ``guess`` (continued from its own iterate,
    at most ``Tuning.continue_unconverged`` times, while it stops at the iteration limit without
    keeping its margins); ``(outcome, path, keeps)``."""
    tight = tighten(form, margins)
    ctx = start_context(tight, warm=True)
    for more in range(tuning().continue_unconverged + 1):
        outcome, traj = run_start(ctx, label + (f" (continued {more})" if more else ""), guess)
        # a re-solve that IPOPT did not finish may keep the limits and margins yet break the
        # mission (a heading off a survey line): it is kept only if it still does the job
        keeps = (
            traj is not None
            and outcome.limits.ok()
            and outcome.mission_complete
            and keeps_margins(tight, traj)
        )
        if keeps or traj is None or outcome.status != "Maximum_Iterations_Exceeded":
            break
        guess = traj
    return outcome, traj, keeps


def keep_out(
    pb: PlanningProblem, nominal: Trajectory, guidance: Guidance | None = None
) -> tuple[Trajectory, KeepoutReport, StartOutcome | None]:
    """Re-solve from the ``nominal`` plan until it keeps its margins (module docstring).

    Each round is a warm re-solve of the tightened NLP. When a re-solve fails to keep its
    margins before any round has, and the margins include a speed reserve, it is tried again
    without the speed reserve (a mission's timing may leave no room for it, and the margins off
    the beacon and inside the box matter more); the report's note says so.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    nominal : Trajectory
        The plan solved without margins, on the planning grid.
    guidance : Guidance, optional
        The guidance the vehicle flies (default: the validation's, :func:`keepout_margins`).

    Returns
    -------
    path : Trajectory
        The path of the last re-solve that kept its limits, mission and margins; ``nominal``
        when none did (``held`` False) or when no re-solve was needed (margins disabled, or
        ``nominal`` already keeps them: 0 rounds, ``held`` True).
    report : KeepoutReport
        The margins, rounds and statuses, and a note in words of what was not achieved or
        narrows the margins.
    outcome : StartOutcome or None
        The last kept re-solve's outcome (None if none).
    """
    t0 = time.perf_counter()
    first = keepout_margins(nominal, pb, guidance)
    conf, k = first.confidence, first.k
    margins = first.maximum(first, 1.0 + tuning().inflate)
    if k == 0:
        return nominal, _report(pb, margins, nominal, 0, True, (), t0), None
    form = build_formulation(pb)
    if keeps_margins(tighten(form, margins), nominal):
        return nominal, _report(pb, margins, nominal, 0, True, (), t0), None
    path, best, statuses = nominal, None, []
    held = unreserved = False
    guess = nominal
    why = ""  # why the last re-solve stopped, in words ("" when it converged)
    for rnd in range(tuning().max_rounds):
        outcome, traj, keeps = _resolve(form, margins, guess, f"keep-out round {rnd + 1}")
        statuses.append(outcome.status)
        if (not keeps or traj is None) and best is None and np.any(margins.speed > 0):
            # a mission's timing (or the limits) may leave no room for the speed reserve: the
            # margins that keep the vehicle off the beacon and inside its box matter more, so
            # they are kept without it (the guidance still slows the vehicle: it lags the plan
            # there), and the report says so
            margins = margins.without_speed_reserve()
            unreserved = True
            outcome, traj, keeps = _resolve(form, margins, guess, f"keep-out round {rnd + 1}")
            statuses.append(outcome.status)
        why = outcome.note
        if not keeps or traj is None:
            break
        path, best, guess = traj, outcome, traj
        again = keepout_margins(traj, pb, guidance)
        if not margins.grew(again):
            held = True
            break
        margins = margins.maximum(again, 1.0 + tuning().inflate)
    if best is None:
        failed = statuses[-1] + (f": {why}" if why else "")
        notes = [f"the tightened re-solve failed ({failed}); the nominal plan is returned"]
    else:
        notes = []
        if unreserved:
            notes.append(
                "the speed reserve did not fit the plan (the guidance still keeps it, so the "
                "vehicle lags the plan where the plan flies above it); planned with every other "
                "margin"
            )
        if not held:
            notes.append("no re-solve kept the margins computed on its own path")
        limited = start_limited_s(form, margins)
        if limited > 0:
            notes.append(
                f"the area/depth margins are narrower than k sigma for the first {limited:.0f} s: "
                "the start is closer to the limit than its margin (they grow in at half what "
                "the vehicle can reach)"
            )
    note = "; ".join([*notes, *narrow_limits(pb, margins)])
    rep = _report(pb, margins, path, len(statuses), held, tuple(statuses), t0, note)
    return path, replace(rep, confidence=conf, k=k), best


def narrow_limits(pb: PlanningProblem, margins: KeepoutMargins) -> list[str]:
    """A sentence per area axis or depth band narrower than twice the largest margin the plan
    must keep from it: no path keeps such a limit at ``limits.keepout_confidence`` (the vehicle
    knows its position along that axis too poorly), whatever the objective.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its area and depth band.
    margins : KeepoutMargins
        The margins: ``box``, ``confidence`` and ``k``.

    Returns
    -------
    list of str
        One sentence per such limit, with what to change; empty otherwise.
    """
    out = []
    names = {0: "the area's x range", 1: "the area's y range", 2: "the depth band"}
    for axis, (lo, hi) in _box_axes(pb):
        m = float(np.max(margins.box[axis], initial=0.0))
        if m <= 0 or hi - lo > 2.0 * m:
            continue
        fix = "add a depth gauge (vehicle.sensors), " if axis == 2 else ""
        out.append(
            f"{names[axis]} ({hi - lo:.3g} m) is narrower than twice the margin the plan must keep "
            f"from its edges at limits.keepout_confidence = {margins.confidence:g} ({m:.3g} m, "
            f"{margins.k:.2f} sigma of the position along it): no path holds it at that "
            f"confidence; {fix}widen the limit or lower limits.keepout_confidence"
        )
    return out


def _report(
    pb: PlanningProblem,
    margins: KeepoutMargins,
    path: Trajectory,
    rounds: int,
    held: bool,
    statuses: Sequence[str],
    t0: float,
    note: str = "",
) -> KeepoutReport:
    return KeepoutReport(
        confidence=margins.confidence,
        k=margins.k,
        rounds=rounds,
        held=held,
        statuses=tuple(statuses),
        max_range_margin_m=float(np.max(margins.range_points, initial=0.0)),
        max_box_margin_m=float(np.max(margins.box, initial=0.0)),
        max_accel_reserve=float(np.max(margins.accel_reserve, initial=0.0)),
        max_speed_margin_mps=float(np.max(margins.speed, initial=0.0)),
        planned_closest_range_m=range_extremes(path, beacon_of(pb))[0],
        wall_s=time.perf_counter() - t0,
        note=note,
    )


def solve_with_keepout(pb: PlanningProblem, **kwargs) -> tuple[SolveResult, KeepoutReport]:
    """:func:`~obsplan.planning.solver.solve.solve`, then :func:`keep_out` on its plan, and the
    same again with the estimators' guards where a default guard engages on the kept plan
    (:mod:`obsplan.planning.objectives.guards`).

    With ``objective.kf_guard`` and ``objective.ekf_guard`` unset, the kept plan is returned when
    the predicted std of every guarded estimator (the augmented KF's Riccati recursion, the
    EKF's posterior CRB; mission mean and final) is at most the lawn-mower's
    (:data:`~obsplan.planning.objectives.guards.ENGAGE_ABOVE`; the keep-out re-solve moves the
    plan, so it is judged after it); otherwise the problem is solved and kept out again, every
    start, with the guard of each estimator that exceeded it at its default bound
    (:data:`~obsplan.planning.objectives.guards.DEFAULT_BOUNDS`), and that result is returned
    (its ``problem`` the guarded one; ``wall_s`` both passes'; ``note`` says so). A guarded
    pass that finds no path, does not converge where the first did, or raises an unguarded
    estimator's prediction (mean or final) above both the lawn-mower's and the first plan's
    returns the first, with the reason: a guard holds one estimator where that costs the other
    little, not by losing the other's verdicts.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    **kwargs
        Passed on to :func:`~obsplan.planning.solver.solve.solve`.

    Returns
    -------
    result : SolveResult
        The kept path (its objective recomputed, its status, success and iterations those of
        the re-solve that returned it, a note of that re-solve's status) when a re-solve kept
        the margins, else the nominal result unchanged; ``kf_guard`` / ``ekf_guard`` set when
        that default guard was evaluated.
    report : KeepoutReport
        :func:`keep_out`'s report of the returned pass; "no plan to keep out" (0 rounds) when
        ``solve`` returned no path.
    """
    first, rep = _solve_kept(pb, **kwargs)
    if first.trajectory is None:
        return first, rep
    checks = engages(first.trajectory, pb)
    engaged = [est for est, (on, _) in checks.items() if on]
    if not engaged:
        idle = {
            e: GuardOutcome(False, False, DEFAULT_BOUNDS[e], r, r) for e, (_, r) in checks.items()
        }
        return _with_outcomes(first, idle), rep
    obj = pb.objective
    guarded = replace(
        pb,
        objective=replace(
            obj,
            kf_guard=DEFAULT_BOUNDS["kf"] if "kf" in engaged else obj.kf_guard,
            ekf_guard=DEFAULT_BOUNDS["ekf"] if "ekf" in engaged else obj.ekf_guard,
        ),
    )
    second, rep2 = _solve_kept(guarded, **kwargs)
    without = "the plan without the guard" + ("s" if len(engaged) > 1 else "")
    words = f"{without} had " + " and ".join(
        f"{HELD[e]} at {checks[e][1][0]:.3f}x / {checks[e][1][1]:.3f}x the lawn-mower's "
        "(mean / final)"
        for e in engaged
    )
    setting = " and ".join(f"objective.{e}_guard = {DEFAULT_BOUNDS[e]:g}" for e in engaged)
    after = None
    if second.trajectory is not None:
        after = {e: guard_ratios_of(second.trajectory, guarded, e) for e in ESTIMATORS}
    why = _not_kept(pb, first, second, engaged, after)
    if after is None or why:
        note = f"{words}; the re-solve with {setting} {why}: {without} is kept"
        kept = {
            e: GuardOutcome(e in engaged, False, DEFAULT_BOUNDS[e], r, r)
            for e, (_, r) in checks.items()
        }
        return _with_outcomes(first, kept, note=_join(first.note, note)), rep
    held = _held(after, engaged)
    applied = {
        e: GuardOutcome(e in engaged, e in engaged, DEFAULT_BOUNDS[e], r, after[e])
        for e, (_, r) in checks.items()
    }
    res = _with_outcomes(
        second,
        applied,
        wall_s=first.wall_s + second.wall_s,
        note=_join(second.note, f"{words}: re-solved with {setting}, {held}"),
    )
    return res, rep2


def _with_outcomes(res: SolveResult, outcomes: dict[str, GuardOutcome], **fields) -> SolveResult:
    """``res`` with the guards' outcomes (``kf_guard``, ``ekf_guard``; None: not evaluated) and
    ``fields`` replaced."""
    return replace(res, kf_guard=outcomes.get("kf"), ekf_guard=outcomes.get("ekf"), **fields)


def _held(after: dict[str, tuple[float, float]], engaged: list[str]) -> str:
    """The guarded estimators' ratios in words (``"EKF 0.998x / 0.870x"``)."""
    return " and ".join(f"{SHORT[e]} {after[e][0]:.3f}x / {after[e][1]:.3f}x" for e in engaged)


def _not_kept(
    pb: PlanningProblem,
    first: SolveResult,
    second: SolveResult,
    engaged: list[str],
    after: dict[str, tuple[float, float]] | None,
) -> str:
    """Why the guarded result ``second`` (its ratios ``after`` per estimator, None without a
    path) is not returned instead of the result ``first`` solved without the guards of
    ``engaged``, in words; ``""`` when it is. A converged plan is not traded for one that did
    not converge, nor an unguarded estimator's prediction for a guarded one's (:func:`_cost`)."""
    if second.trajectory is None or after is None:
        return "found no path"
    if first.success and not second.success:
        return f"ended {second.status}"
    assert first.trajectory is not None  # solve_with_keepout returns earlier without a path
    for est in ESTIMATORS:
        if est in engaged:
            continue
        costly = _cost(pb, est, first.trajectory, second.trajectory)
        if costly:
            held = _held(after, engaged)
            return f"held it at {held} but raised {HELD[est]} {costly} the lawn-mower's"
    return ""


def _cost(pb: PlanningProblem, estimator: str, unguarded: Trajectory, guarded: Trajectory) -> str:
    """Where the guarded plan's predicted std of ``estimator`` (mission mean, final) is above
    both the lawn-mower's and the unguarded plan's, in words relative to the lawn-mower's
    (``"mean to 1.17x and final to 1.36x"``); ``""`` where it is not: a guard may not make
    another estimator lose to the lawn-mower where the plan without it did not."""
    before = guard_ratios_of(unguarded, pb, estimator)
    after = guard_ratios_of(guarded, pb, estimator)
    words = [
        f"{name} to {a:.2f}x"
        for name, b, a in zip(("mean", "final"), before, after, strict=True)
        if a > max(1.0, b)
    ]
    return " and ".join(words)


def _join(*notes: str) -> str:
    return "; ".join(n for n in notes if n)


def _solve_kept(pb: PlanningProblem, **kwargs) -> tuple[SolveResult, KeepoutReport]:
    """:func:`~obsplan.planning.solver.solve.solve`, then :func:`keep_out` on its plan (the
    result of :func:`solve_with_keepout` without the KF guard)."""
    res = solve(pb, **kwargs)
    if res.trajectory is None:
        return res, KeepoutReport(
            float(pb.limits.keepout_confidence),
            0.0,
            0,
            False,
            (),
            0.0,
            0.0,
            0.0,
            math.nan,
            0.0,
            "no plan to keep out",
        )
    path, rep, outcome = keep_out(pb, res.trajectory)
    if outcome is None or path is res.trajectory:
        return res, rep
    # the headline status and iterations are the flown path's, the last kept re-solve's: a
    # best start that stopped at IPOPT's iteration limit but whose tightened re-solve converged
    # is a converged plan (the start's own status stays in the note and in ``starts``)
    kept = replace(
        res,
        trajectory=path,
        objective=objective_value(path, pb),
        success=outcome.success,
        status=outcome.status,
        iterations=outcome.iterations,
        chosen=f"{res.chosen} + keep-out margins",
        wall_s=res.wall_s + rep.wall_s,
        note=(res.note + "; " if res.note else "")
        + f"keep-out re-solve: {outcome.status}"
        + (f" ({outcome.note})" if outcome.note else ""),
    )
    if not check_limits(path, pb).ok():  # never reached: run_start keeps only feasible paths
        return res, rep
    return kept, rep
