"""Estimator-aware objectives: the position std an estimator predicts along the planned path.

Both follow a covariance recursion of :mod:`obsplan.estimation.bounds.riccati` (the one the
validation's bound uses) on the validation's filter grid
(:func:`~obsplan.planning.problem.validation_setup .filter_epochs`), with the validation's prior,
process noise, sensor rates and noises
(:func:`~obsplan.planning.problem.validation_setup.estimation_config`):

* ``pcrb-position``: the posterior Cramér–Rao bound of the nonlinear model's position,
  ``sqrt(tr P_pp)`` [m] (:func:`obsplan.estimation.bounds.crlb.posterior_crlb`), evaluated on the
  positions of the planned path at the measurement epochs;
* ``kf-position-std``: the augmented KF's predicted position std (eqs. 20-24). The model is
  linear, so its Riccati recursion depends only on the inputs; it runs on the augmented state
  with the anchor state of ``y0_mode="augment"`` (range rows ``C(t)`` of eq. 21,
  ``R = r² σ_r² + ½ σ_r⁴``; no range update at the anchor sample), in the metric scales. By
  default the posterior CRB joins it (``objective.pcrb_weight``, :func:`covariance_expr`).

Each has a time mode (:func:`timed_value`): at the end (``final``), averaged over the filter
samples (``mission-average``), the sum of the two, each relative to its value on the reference
path (``average-and-final``), averaged over the filter samples inside the survey lines'
windows (``lines``: the schedule's, :mod:`obsplan.planning.missions.schedule`), or that line
average and the final value, each relative to the reference path's (``lines-and-final``: what the
sonar data and the recovery need; the default of a survey). The exact
Hessian of a recursion over hundreds of epochs is dense and slow to build, so IPOPT runs L-BFGS
on them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import pcrb_model, range_information
from obsplan.estimation.bounds.riccati import Epochs, RecursionModel, position_std, run_recursion
from obsplan.observability.gramian import augmented_model
from obsplan.planning.missions.schedule import line_sample_mask
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.validation_setup import estimation_config, filter_epochs
from obsplan.planning.transcription.blocks import NLPContext, Objective, ObjectiveTerm
from obsplan.planning.transcription.grid import Grid, apply_operator
from obsplan.planning.transcription.guesses import reference_path
from obsplan.planning.tuning import cache_per_tuning
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True, eq=False)
class CovarianceObjective:
    """A covariance recursion along the planned path (``pcrb-position`` / ``kf-position-std``).

    Attributes
    ----------
    model : RecursionModel
    epochs : Epochs
        On the validation's filter grid (``PlanningProblem.filter_times``).
    P0 : ndarray
    mask : ndarray
        Report mask per epoch (the KF skips the range at the anchor sample).
    scale : float
        Multiplies the recursion's std to metres.
    """

    model: RecursionModel
    epochs: Epochs
    P0: np.ndarray
    mask: np.ndarray
    scale: float
    rows: Callable  # (grid, W) -> (h, rho): range rows and variances at the epochs
    #: Boolean mask of the filter samples on the survey lines (None: no lines).
    lines: np.ndarray | None = None

    def evaluate(self, grid: Grid, W):
        """``(mission-average std, final std)`` [m] as CasADi expressions or numbers.

        Parameters
        ----------
        grid : Grid
            The planning grid of the problem.
        W : ndarray or casadi.MX, shape (3n, N)
            The path's decision variables (intrinsic units).

        Returns
        -------
        average : float or casadi.MX
            Mean over the filter samples of the predicted position std [m].
        final : float or casadi.MX
            The std at the last filter sample [m].
        """
        return self.evaluate_all(grid, W)[:2]

    def std_series(self, grid: Grid, W: np.ndarray) -> np.ndarray:
        """The predicted position std ``sqrt(tr P_pp)`` [m] at every filter sample
        (``PlanningProblem.filter_times``) of the path ``W`` (numbers, intrinsic units), shape
        ``(samples,)``: what the time modes average and end on.

        Parameters
        ----------
        grid : Grid
            The planning grid of the problem.
        W : ndarray, shape (3n, N)
            The path's decision variables (intrinsic units).

        Returns
        -------
        ndarray, shape (samples,)
            The predicted position std [m] at every filter sample.
        """
        h, rho = self.rows(grid, W)
        _, D = run_recursion(self.model, self.epochs, self.P0, h, rho, self.mask)
        return position_std(np.asarray(D), self.model.n, self.epochs) * self.scale

    def evaluate_all(self, grid: Grid, W):
        """``(mission-average, final, average over the lines)`` std [m] (the last None without
        lines), as CasADi expressions or numbers.

        Parameters
        ----------
        grid : Grid
            The planning grid of the problem.
        W : ndarray or casadi.MX, shape (3n, N)
            The path's decision variables (intrinsic units).

        Returns
        -------
        average : float or casadi.MX
            Mean over the filter samples of the predicted position std [m].
        final : float or casadi.MX
            The std at the last filter sample [m].
        lines : float or casadi.MX or None
            Mean over the filter samples on the survey lines [m]; None without lines.
        """
        if isinstance(W, np.ndarray):
            std = self.std_series(grid, W)
            on = None if self.lines is None else float(np.mean(std[self.lines]))
            return float(np.mean(std)), float(std[-1]), on
        h, rho = self.rows(grid, W)
        _, D = run_recursion(self.model, self.epochs, self.P0, h, rho, self.mask)
        n = self.model.n
        total, final = position_std(D, n, self.epochs)
        count = int(self.epochs.gap.sum())
        on = None
        if self.lines is not None:
            on = _lines_average(D, n, self.epochs, self.lines) * self.scale
        return total * (self.scale / count), final * self.scale, on


def _lines_average(D, n: int, epochs: Epochs, lines: np.ndarray):
    """The mean of ``sqrt(tr P_pp)`` over the samples ``lines`` (CasADi), in the column layout
    of :func:`~obsplan.estimation.bounds.riccati.position_std` (epoch ``j``, step ``kk < gap_j``).

    The mean of the std, as the mission average (``rmse_pos`` averages the RMSE over time). The
    RMS over the samples (the bound of ``rmse_pos_lines`` exactly) was tried: the same verdicts
    within the Monte Carlo noise (median over the surveys 0.63 against 0.64 of the lawn-mower's
    EKF RMSE on the lines), but the 3D DVL and depth surveys no longer converged
    (``Maximum_Iterations_Exceeded`` where the mean converges in 921 iterations at N = 600)."""
    K = epochs.max_gap
    sample = epochs.index[:, None] + np.arange(K)[None, :]
    keep = np.arange(K)[None, :] < epochs.gap[:, None]
    on = keep & lines[np.minimum(sample, lines.size - 1)]
    w = on.reshape(-1).astype(float)
    std = ca.sqrt(ca.sum1(D[:n, :]) + 1e-30)
    return ca.dot(std.T, ca.DM(w)) / max(float(w.sum()), 1.0)


def timed_value(mode: str, average, final, reference: tuple, lines=None):
    """The objective of a time ``mode`` from the mission-average and final std [m].

    ``average-and-final`` is ``average / a_ref + final / f_ref`` with ``(a_ref, f_ref, l_ref) =
    reference``, the values on the reference path
    (:func:`~obsplan.planning.transcription.guesses.reference_path`): the survey and its end weigh
    alike whatever their sizes (with a DVL the final std is often 10x smaller than the average, and
    a plain sum would ignore it). It is dimensionless: 2 on the reference. ``lines`` is the
    average over the survey lines' windows (mode ``lines``); ``lines-and-final`` is
    ``lines / l_ref + final / f_ref``.

    Parameters
    ----------
    mode : str
        The time mode: ``"final"``, ``"mission-average"``, ``"average-and-final"``,
        ``"lines"`` or ``"lines-and-final"``.
    average : float or casadi.MX
        Mission-average std [m].
    final : float or casadi.MX
        Final std [m].
    reference : tuple
        ``(a_ref, f_ref, l_ref)``: the same on the reference path [m] (``l_ref`` None without
        lines).
    lines : float or casadi.MX or None, optional
        Average std over the survey lines' windows [m].

    Returns
    -------
    float or casadi.MX
        [m] for ``final``, ``mission-average`` and ``lines``; dimensionless for the two sums.
    """
    if mode == "lines":
        return lines
    if mode == "mission-average":
        return average
    if mode == "final":
        return final
    if mode == "lines-and-final":
        return lines / reference[2] + final / reference[1]
    return average / reference[0] + final / reference[1]


def pcrb_objective(pb: PlanningProblem) -> CovarianceObjective:
    """The posterior CRB of the validation
    (:func:`obsplan.estimation.bounds.crlb.posterior_crlb`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its vehicle model, ``[validation]`` (prior, process noise, sensors, filter
        grid) and mission lines.

    Returns
    -------
    CovarianceObjective
        The recursion on the nonlinear model, range rows taken at the path's positions at the
        measurement epochs; stds in metres (scale 1).
    """
    cfg = estimation_config(pb)
    cov = cfg.covariances(pb.validation.dt)
    model = pb.model
    rec = pcrb_model(model, cov["q_ekf"], dict(cfg.noise))
    epochs = filter_epochs(pb)
    s = pb.filter_times[epochs.index]
    grid = Grid.from_problem(pb)
    Mp, cp, _, _ = grid.sample_operator(s)
    sigma = cfg.noise["range"]
    n = model.dim
    channel = pb.validation.channel_model()

    def rows(grid: Grid, W):
        w = W.reshape(-1, order="F") if isinstance(W, np.ndarray) else ca.vec(W)
        rel = apply_operator(Mp, cp, w, n)
        h, rho = range_information(rel, sigma)
        return h, channel.expected_variance(rho, rel)

    return CovarianceObjective(rec, epochs, cov["p0_ekf"], epochs.mask, 1.0, rows, _lines(pb))


def _lines(pb: PlanningProblem) -> np.ndarray | None:
    """The filter samples inside the mission's line windows (None without survey lines)."""
    if pb.mission is None or not pb.mission.lines:
        return None
    return line_sample_mask(pb.mission_context, pb.filter_times)


def kf_objective(pb: PlanningProblem) -> CovarianceObjective:
    """The augmented KF's covariance (:mod:`obsplan.estimation.filters.kf`) in the metric scales.

    The filter's own coordinates ``z = (p - b, v[, v_f], κ, φ, γ)`` (chain ``κ' = φ``,
    ``φ' = 2γ``; the anchor's error in ``κ`` for ``y0_mode="augment"``), its prior, per-step
    process noise and range variance, and its process-noise coupling with the gains taken on the
    nominal path, where ``p - d = p0 - b + ν0 τ`` and ``ν - ḋ = ν0`` whatever the inputs: so the
    per-step noise is ``q(τ) = Γ(τ) q Γ(τ)ᵀ`` with ``Γ`` linear in ``τ`` (a quadratic ``q(τ)``,
    exact in :mod:`obsplan.estimation.bounds.riccati`). The filter takes the gains at its estimate,
    so the prediction matches its covariance up to the estimation error of ``p0`` and ``ν0``.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its vehicle model, start, beacon, ``[validation]`` and ``[scales]``.

    Returns
    -------
    CovarianceObjective
        The recursion on the scaled augmented state (``scale`` = ``L`` [m] back to metres), the
        range update left out at the anchor sample.

    Raises
    ------
    ConfigError
        When the configured KF process noise acts on the augmented entries ``(p0·v0, |v0|²)``.
    """
    L, T = pb.scales.length_m, pb.scales.time_s
    model = pb.model
    n, mx = model.dim, model.state_dim
    m = mx + 3
    kc = mx  # κ, φ, γ follow the kinematic states
    cfg = estimation_config(pb)
    cov = cfg.covariances(pb.validation.dt)
    # state scaling: p/L, v T/L, v_f T/L, κ/L², φ T/L², γ T²/L²
    scale = np.concatenate([np.full(n, 1 / L), np.full(mx - n, T / L), [1 / L**2, T / L**2]])
    scale = np.append(scale, T**2 / L**2)
    S = np.diag(scale)
    P0, var0 = _kf_prior(pb, cfg, cov, m, kc)
    q0, q1, q2 = _kf_process_noise(pb, cfg, cov, m, kc)
    rows_c, var_c, which = _kf_sensor_rows(pb, cfg, scale, m)
    rec = RecursionModel(
        A=_kf_dynamics(n, m, kc, model.current),  # S A S^-1 T = A: consistent with the scaling
        q=S @ q0 @ S,
        q1=T * (S @ q1 @ S),
        q2=T**2 * (S @ q2 @ S),
        nav=_kf_navigation(n, m, model.current),
        rows=np.array(rows_c).reshape(len(rows_c), m),
        row_var=np.array(var_c),
        row_sensor=tuple(which),
        range_sensor=model.sensors.index("range"),
        n_sensors=len(model.sensors),
        range_support=(*range(n), kc),  # ȳ = dᵀ(p - b) + κ
    )
    epochs = filter_epochs(pb).scaled(T)
    mask = epochs.mask.copy()
    mask[0, model.sensors.index("range")] = 0.0  # ȳ_0 ≡ 0: the anchor carries no information
    extra = (var0 / L**4) if cfg.y0_mode == "inflate" else 0.0
    rows = _kf_range_rows(pb, pb.filter_times[epochs.index], cfg.noise["range"], extra)
    return CovarianceObjective(rec, epochs, S @ P0 @ S, mask, L, rows, _lines(pb))


def _kf_prior(pb: PlanningProblem, cfg, cov: dict, m: int, kc: int) -> tuple[np.ndarray, float]:
    """The KF's prior on ``z`` and the variance of the anchor ``ȳ_0`` (unscaled)."""
    mx = kc
    # prior: φ = α, γ = ½β, κ = the anchor's error (variance of ½(r0 + ε)², as the filter's)
    Mc = np.zeros((m, mx + 2))
    Mc[:mx, :mx] = np.eye(mx)
    Mc[kc + 1, mx] = 1.0
    Mc[kc + 2, mx + 1] = 0.5
    P0 = Mc @ np.asarray(cov["p0_kf"], float) @ Mc.T
    sigma = cfg.noise["range"]
    r0 = float(np.linalg.norm(pb.p0 - np.asarray(pb.beacon)))
    var0 = (r0 * sigma) ** 2 + 0.5 * sigma**4
    if cfg.y0_mode != "inflate":
        P0[kc, kc] += var0
    return P0, var0


def _kf_dynamics(n: int, m: int, kc: int, current: bool) -> np.ndarray:
    """``A`` of ``z' = A z``: ``p' = v (+ v_f)``, ``κ' = φ``, ``φ' = 2γ``."""
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    if current:
        A[:n, 2 * n : 3 * n] = np.eye(n)
    A[kc, kc + 1], A[kc + 1, kc + 2] = 1.0, 2.0
    return A


def _kf_navigation(n: int, m: int, current: bool) -> np.ndarray:
    """Rows of ``z`` giving the navigation state ``(p - b, ν)``."""
    nav = np.zeros((2 * n, m))
    nav[:n, :n] = np.eye(n)
    nav[n:, n : 2 * n] = np.eye(n)
    if current:
        nav[n:, 2 * n : 3 * n] = np.eye(n)
    return nav


def _kf_process_noise(
    pb: PlanningProblem, cfg, cov: dict, m: int, kc: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q0, q1, q2)`` of the per-step noise ``q(τ) = q0 + τ q1 + τ² q2`` on ``z`` (unscaled)."""
    model = pb.model
    n, mx = model.dim, kc
    q_kf = np.asarray(cov["q_kf"], float)
    if np.any(q_kf[mx:, :] != 0) or np.any(q_kf[:, mx:] != 0):
        raise ConfigError(
            "the planning KF models process noise on (p, v[, v_f]) only; the configured noise on "
            "(p0·v0, |v0|²) is not supported by kf-position-std"
        )
    qx = q_kf[:mx, :mx]
    # noise gains Γ(τ) = Γ0 + τ Γ1 of w = (w_p, w_v[, w_f]) on z, at the nominal path
    nu0 = pb.v0  # inertial start velocity: ν0 = v0 + v_f
    cp0 = pb.p0 - np.asarray(pb.beacon, float)
    G0 = np.zeros((m, mx))
    G1 = np.zeros((m, mx))
    G0[:mx] = np.eye(mx)
    if cfg.kf_coupling:
        nu_cols = [np.arange(n, 2 * n)] + ([np.arange(2 * n, 3 * n)] if model.current else [])
        G0[kc, :n] = cp0  # κ: c_p · w_p
        G1[kc, :n] = nu0
        G0[kc + 1, :n] = nu0  # φ: c_v · w_p + c_p · w_ν
        for cols in nu_cols:
            G0[kc + 1, cols] = cp0
            G1[kc + 1, cols] = nu0
            G0[kc + 2, cols] = nu0  # γ: c_v · w_ν
    q0 = G0 @ qx @ G0.T
    q1 = G0 @ qx @ G1.T + G1 @ qx @ G0.T
    q2 = G1 @ qx @ G1.T
    return q0, q1, q2


def _kf_sensor_rows(
    pb: PlanningProblem, cfg, scale: np.ndarray, m: int
) -> tuple[list[np.ndarray], list[float], list[int]]:
    """Constant output rows (DVL, depth) in the scaled state, their variances and sensors.

    ``C_s = c_out C S^-1``, ``σ_s = c_out σ``, with ``c_out = T/L`` for a DVL (a velocity) and
    ``1/L`` for the depth gauge (a position).
    """
    L, T = pb.scales.length_m, pb.scales.time_s
    model = pb.model
    n, mx = model.dim, model.state_dim
    full = augmented_model(model).output_matrix(np.zeros(n), 0.0)
    rows_c, var_c, which = [], [], []
    i = 1
    for j, sensor in enumerate(model.sensors):
        if sensor == "range":
            continue
        width = n if sensor.startswith("dvl") else 1
        c_out = T / L if sensor.startswith("dvl") else 1 / L
        for r in range(width):
            row = np.zeros(m)
            row[:mx] = c_out * full[i + r][:mx] / scale[:mx]
            rows_c.append(row)
            var_c.append((c_out * cfg.noise[sensor]) ** 2)
            which.append(j)
        i += width
    return rows_c, var_c, which


def _kf_range_rows(pb: PlanningProblem, s: np.ndarray, sigma: float, extra: float) -> Callable:
    """``(grid, W) -> (h, rho)``: the KF's range rows ``(d, 1)`` (eq. 21) and variances at the
    epoch times ``s`` [s], in the metric scales (``extra``: the inflated anchor's variance)."""
    L = pb.scales.length_m
    n = pb.dim
    grid = Grid.from_problem(pb)
    Mp, cp, _, _ = grid.sample_operator(s)
    d_off = (grid.p0[:, None] + grid.v0[:, None] * s[None, :]) / L  # d = p - p0 - ν0 τ (eq. 15)
    sig_s = sigma / L
    ones = np.ones((1, s.size))
    channel = pb.validation.channel_model()

    def rows(grid: Grid, W):
        w = W.reshape(-1, order="F") if isinstance(W, np.ndarray) else ca.vec(W)
        rel_m = apply_operator(Mp, cp, w, n)
        rel = rel_m / L
        d = rel - d_off
        if isinstance(W, np.ndarray):
            hh = np.vstack([d, ones])
            rho = np.sum(rel**2, axis=0, keepdims=True) * sig_s**2 + 0.5 * sig_s**4 + extra
        else:
            hh = ca.vertcat(d, ca.DM(ones))
            rho = ca.sum1(rel**2) * sig_s**2 + 0.5 * sig_s**4 + extra
        return hh, channel.expected_variance(rho, rel_m)

    return rows


@cache_per_tuning
def covariance_objective(pb: PlanningProblem, kind: str | None = None) -> CovarianceObjective:
    """The :class:`CovarianceObjective` of ``kind`` (default: the problem's objective), built
    once per problem (its CasADi functions are shared by the planner, the metrics and the
    margins).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    kind : str or None, optional
        ``"kf-position-std"`` (the augmented KF), or any other kind for the posterior CRB; None:
        ``pb.objective.kind``.

    Returns
    -------
    CovarianceObjective
        :func:`kf_objective` or :func:`pcrb_objective` of ``pb`` (cached per problem, kind and
        tuning).
    """
    kind = pb.objective.kind if kind is None else kind
    return kf_objective(pb) if kind == "kf-position-std" else pcrb_objective(pb)


def covariance_stds(traj: Trajectory, pb: PlanningProblem, kind: str) -> tuple[float, float]:
    """``(mission-average, final)`` position std [m] of the ``kind`` recursion along ``traj``.

    ``kind`` is ``"pcrb-position"`` or ``"kf-position-std"``; ``traj`` must be on the problem's
    planning grid (N + 1 samples).

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid.
    pb : PlanningProblem
        The problem.
    kind : str
        Which recursion.

    Returns
    -------
    average : float
        Mean over the filter samples of the predicted position std [m].
    final : float
        The std at the end of the horizon [m].
    """
    grid = Grid.from_problem(pb)
    return covariance_objective(pb, kind).evaluate(grid, grid.from_trajectory(traj))


@cache_per_tuning
def reference_stds(pb: PlanningProblem, kind: str) -> tuple:
    """``(mission-average, final, lines)`` std [m] of the ``kind`` recursion on the reference
    path (:func:`~obsplan.planning.transcription.guesses.reference_path`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    kind : str
        ``"pcrb-position"`` or ``"kf-position-std"`` (:func:`covariance_objective`).

    Returns
    -------
    tuple
        ``(average, final, lines)`` [m]; ``lines`` None without survey lines.
    """
    grid = Grid.from_problem(pb)
    return covariance_objective(pb, kind).evaluate_all(
        grid, grid.from_trajectory(reference_path(pb))
    )


def _timed(pb: PlanningProblem, kind: str, grid: Grid, W):
    """The ``kind`` recursion on ``W`` in the problem's time mode (CasADi or number)."""
    avg, final, on = covariance_objective(pb, kind).evaluate_all(grid, W)
    return timed_value(pb.objective_mode, avg, final, reference_stds(pb, kind), on)


def covariance_expr(pb: PlanningProblem, grid: Grid, W):
    """The problem's covariance objective on the path ``W`` (CasADi or number).

    ``pcrb-position``, and ``kf-position-std`` with ``objective.pcrb_weight = 0``: the
    recursion in the time mode [m or -]. ``kf-position-std`` with a weight ``w > 0`` (default
    :data:`~obsplan.planning.problem.schema.KF_PCRB_WEIGHT`): ``K/K_ref + w B/B_ref``, the KF's
    value ``K`` in its time mode and ``B`` the ``pcrb-position`` objective in its default mode
    (:func:`pcrb_problem`: the posterior CRB, the nonlinear model's bound, what an EKF can
    reach, over the mission and at its end), each relative to the reference path's (``1 + w``
    there) [-]. The KF's model is linear in an augmented state whose range rows grow near the
    beacon (``R = r² σ_r² + ½σ_r⁴``) and which has no absolute range: alone, its plans closed
    radially on the beacon first, where the EKF beside the vehicle's filter cannot see the
    tangential position (``suite/short-horizon.toml``: EKF RMSE 1.38× the lawn-mower's; with
    ``w = 1`` 0.46×, the KF's own 0.22× against 0.19×), or with ``mode = "final"`` left the
    path between start and end free (docs/problem-files.md has six more problems).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its objective's kind, time mode and ``pcrb_weight``.
    grid : Grid
        The planning grid of the problem.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables (intrinsic units).

    Returns
    -------
    float or casadi.MX
        The objective (minimised): [m] or dimensionless, as above.
    """
    kind = pb.objective.kind
    value = _timed(pb, kind, grid, W)
    w = pb.objective.resolved_pcrb_weight
    if w == 0:
        return value
    bound = pcrb_problem(pb)
    return value / _reference_timed(pb, kind) + w * _timed(
        bound, "pcrb-position", grid, W
    ) / _reference_timed(bound, "pcrb-position")


def pcrb_problem(pb: PlanningProblem) -> PlanningProblem:
    """``pb`` with the ``pcrb-position`` objective in its default time mode (the bound term of
    ``kf-position-std``, :func:`covariance_expr`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    PlanningProblem
        A copy with ``objective.kind = "pcrb-position"``, ``mode = "auto"`` and no
        ``pcrb_weight``.
    """
    obj = replace(pb.objective, kind="pcrb-position", mode="auto", pcrb_weight=None)
    return replace(pb, objective=obj)


@cache_per_tuning
def _reference_timed(pb: PlanningProblem, kind: str) -> float:
    """The ``kind`` recursion on the reference path in the problem's time mode (> 0)."""
    ref = reference_stds(pb, kind)
    return max(float(timed_value(pb.objective_mode, ref[0], ref[1], ref, ref[2])), 1e-12)


def covariance_value(traj: Trajectory, pb: PlanningProblem) -> float:
    """The problem's covariance objective (:func:`covariance_expr`) on ``traj`` [m or -].

    Parameters
    ----------
    traj : Trajectory
        The path, on the planning grid.
    pb : PlanningProblem
        The problem.

    Returns
    -------
    float
        The objective's value (smaller is better).
    """
    grid = Grid.from_problem(pb)
    return float(covariance_expr(pb, grid, grid.from_trajectory(traj)))


def covariance_term(ctx: NLPContext) -> ObjectiveTerm:
    """The problem's covariance objective on ``ctx.W``, divided by its value on the reference.

    Parameters
    ----------
    ctx : NLPContext
        The NLP being built: the problem, the grid, ``W`` and the reference path.

    Returns
    -------
    ObjectiveTerm
        The normalised expression (1 on the reference), its map back to
        :func:`covariance_value`'s units and the limited-memory Hessian.
    """
    pb, grid = ctx.problem, ctx.grid
    value = covariance_expr(pb, grid, ctx.W)
    ref = max(covariance_value(ctx.reference, pb), 1e-12)
    return ObjectiveTerm(
        f=value / ref,
        to_objective=lambda fv: float(1.0 * ref * fv),
        # the exact Hessian of a recursion over hundreds of epochs is dense and slow to build
        # (measured: 166 s to construct at N = 50): L-BFGS needs only gradients
        hessian="limited-memory",
    )


PCRB_POSITION = Objective("pcrb-position", covariance_term, covariance_value)
KF_POSITION_STD = Objective("kf-position-std", covariance_term, covariance_value)
