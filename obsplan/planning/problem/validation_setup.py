"""The validation's filters as the estimation layer's objects: configuration, guidance, limits.

One place for what the validation Monte Carlo runs (:mod:`obsplan.planning.validation.validate`) and
what the estimator-aware objectives predict (:mod:`obsplan.planning.objectives.estimator`): the
filters' :class:`~obsplan.estimation.config.EstimationConfig` built from ``[validation]`` (its
process noise included), the measurement epochs on the horizon, the guidance law a closed-loop
validation flies every path with and the limits every true path is checked against. Both sides
read them here, so the planner's bound is the validation's own.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from scipy.stats import norm

from obsplan.core.errors import field_error
from obsplan.estimation.bounds.riccati import Epochs, make_epochs
from obsplan.estimation.config import EstimationConfig, paper_covariances
from obsplan.estimation.montecarlo.guidance import Guidance, TruthLimits
from obsplan.model.beacon import BeaconPath
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.trajectory.sampled import Trajectory


def estimation_config(
    pb: PlanningProblem, beacon_path: BeaconPath | None = None
) -> EstimationConfig:
    """The filters' configuration of the validation of ``pb``.

    The paper's prior (section 7) with the position and velocity blocks set by
    ``init_pos_error`` / ``init_vel_error``, the problem's rates and noises, the true current
    ``vehicle.current_velocity``, and the process noise of ``validation.process_noise_model``:
    ``"physical"``, the white acceleration noise ``accel_noise`` [m/s²/√Hz] (exact for any
    ``dt``), or ``"paper-per-step"``, the paper's ``Q`` per filter step of ``dt``; the EKF's
    range update ``validation.ekf_update``; the acoustic channel of the truth
    (``validation.channel`` and its ``channel_*`` fields), the filters' range gate
    (``validation.gate``) and range-calibration states (``validation.scale_state``,
    ``validation.bias_state``). Used by the validation and by the planning objectives (which
    read none of the last four).

    A moving beacon: ``beacon_path``, or the known path of ``beacon.motion = "path"``
    (:attr:`~obsplan.planning.problem.sections.ProblemData.beacon_path`), becomes the
    configuration's ``beacon_path`` (the model's fixed beacon then at the origin, as
    :class:`~obsplan.estimation.config.EstimationConfig` wants it); a planned beacon has no path
    of its own until one is given.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its vehicle model and ``[validation]`` section.
    beacon_path : BeaconPath or None, optional
        The beacon's path (a planned beacon's plan, or a beacon baseline's); None: the
        problem's own beacon.

    Returns
    -------
    EstimationConfig
        The EKF's and KF's priors, sensor rates [Hz] and noises, process noise and true current.
    """
    model, val, n = pb.model, pb.validation, pb.dim
    path = pb.beacon_path if beacon_path is None else beacon_path
    if path is None and pb.beacon_motion.motion == "planned":
        raise field_error(
            "beacon.motion",
            '"planned": the beacon has no path until it is planned (obsplan plan); give its '
            "path to validate with it",
        )
    if path is not None or pb.beacon_motion.moving:
        model = replace(model, beacon=(0.0,) * n)
    cov: dict[str, Any] = paper_covariances(model, val.dt)
    for key in ("p0_ekf", "p0_kf"):
        d = np.diag(cov[key]).copy()
        d[:n] = val.init_pos_error**2
        d[n : 2 * n] = val.init_vel_error**2
        cov[key] = np.diag(d)
    noise_model: dict[str, Any]
    if val.process_noise_model == "paper-per-step":
        noise_model = {"q_ekf": cov["q_ekf"], "q_kf": cov["q_kf"]}
    else:
        noise_model = {"accel_noise": val.accel_noise}
    rates = {"range": val.range_rate}
    noise = {"range": val.range_std}
    for s in model.sensors:
        if s.startswith("dvl"):
            rates[s], noise[s] = val.dvl_rate, val.dvl_std
        elif s == "depth":
            rates[s], noise[s] = val.depth_rate, val.depth_std
    return EstimationConfig(
        model=model,
        rates_hz=rates,
        noise=noise,
        true_current=pb.vehicle.current_velocity if pb.vehicle.current else None,
        init_error="sample",
        p0_ekf=cov["p0_ekf"],
        p0_kf=cov["p0_kf"],
        ekf_update=val.ekf_update,  # type: ignore[arg-type]
        beacon_path=path,
        range_times=pb.range_times,
        channel=val.channel_model(),
        gate=val.gate,
        scale_state=val.scale_state,
        bias_state=val.bias_state,
        **noise_model,
    )


def channel_dict(pb: PlanningProblem) -> dict:
    """``report.json``'s ``validation.channel``: the acoustic channel of the validation's truth
    (its ``name`` and fields, :meth:`Channel.to_dict
    <obsplan.estimation.channel.Channel.to_dict>`), the filters' range ``gate`` (its
    confidence; None: no gate) and whether they carry a range-scale state (``scale_state``) and a
    range-bias state (``bias_state``).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its ``[validation]`` section.

    Returns
    -------
    dict
        JSON-ready.
    """
    val = pb.validation
    channel = val.channel_model()
    cfg = EstimationConfig(
        model=pb.model,
        channel=channel,
        gate=val.gate,
        scale_state=val.scale_state,
        bias_state=val.bias_state,
    )
    return {
        **channel.to_dict(),
        "gate": cfg.gate_probability,
        "scale_state": cfg.scale_prior_std is not None,
        "bias_state": cfg.bias_prior_std is not None,
    }


def confidence_quantile(confidence: float) -> float:
    """``k = Φ⁻¹(confidence)`` (one-sided normal quantile); 0 when ``confidence`` is 0.

    Parameters
    ----------
    confidence : float
        A probability in ``[0, 1)`` (e.g. ``limits.keepout_confidence``).

    Returns
    -------
    float
        The quantile ``k`` (in standard deviations); 0 for ``confidence <= 0``.
    """
    c = float(confidence)
    return 0.0 if c <= 0 else float(norm.ppf(c))


def validation_guidance(pb: PlanningProblem, *, at_sea: bool = False) -> Guidance | None:
    """The guidance law of a closed-loop validation (``None`` for ``validation.mode =
    "open-loop"`` unless ``at_sea``): gains from the limits ``accel`` [m/s²] and ``speed`` [m/s],
    the feedback on a prior-sized position error (``init_pos_error`` [m]) using half the smallest
    acceleration bound (:meth:`~obsplan.estimation.montecarlo.guidance.Guidance.from_limits`), and
    the estimated speed kept ``k`` velocity stds of the EKF below the speed bound (``k`` the normal
    quantile of ``limits.keepout_confidence``, as the keep-out margins), so that the *true*
    speed holds it at that confidence.

    ``at_sea``: the law the vehicle at sea flies whatever the validation's mode (the keep-out
    margins are for that vehicle, which steers its estimate), never ``None``.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its limits, ``validation.mode``, ``validation.init_pos_error`` and
        ``validation.navigation``.
    at_sea : bool, optional
        Return the law even for an open-loop validation.

    Returns
    -------
    Guidance or None
        The guidance law; None for an open-loop validation (unless ``at_sea``).
    """
    if pb.validation.mode == "open-loop" and not at_sea:
        return None
    lim = pb.limits
    k = confidence_quantile(lim.keepout_confidence)
    val = pb.validation
    return Guidance.from_limits(
        lim.accel, lim.speed, val.init_pos_error, speed_k=k, navigation=val.navigation
    )


def truth_limits(pb: PlanningProblem) -> TruthLimits:
    """The problem's limits that every run's *true* path is checked against: acceleration,
    speed, area, depth band, ``min_range`` (0: none) and ``max_range``, strictly.

    With a planned beacon (``beacon.motion = "planned"``, where ``limits.min_range`` and
    ``limits.max_range`` are refused) the distances are those of its craft to the vehicle,
    measured to the beacon where it is at each sample: ``max_range`` is the craft's (a range);
    ``min_range`` is the craft's ``min_distance`` in 2D, where the horizontal distance is the
    range. In 3D it is not checked on the true paths (the kernels measure the range, and a
    range above ``min_distance`` says nothing of the horizontal distance): the nominal paths'
    check (:func:`~obsplan.planning.baselines.beacon.craft_limit_breaks`) stands alone.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its ``limits``.

    Returns
    -------
    TruthLimits
        The limits in the estimation layer's form ([m/s²], [m/s], [m]).
    """
    lim = pb.limits
    area = None if lim.area is None else (lim.area.x, lim.area.y)
    min_range = lim.min_range if lim.min_range > 0 else None
    max_range = lim.max_range
    craft = pb.beacon_vehicle
    if craft is not None:
        min_range = craft.min_distance if pb.dim == 2 and craft.min_distance > 0 else None
        max_range = craft.max_range
    return TruthLimits(
        accel=lim.accel,
        speed=lim.speed,
        area=area,
        depth=lim.depth,
        min_range=min_range,
        max_range=max_range,
    )


def filter_epochs(pb: PlanningProblem) -> Epochs:
    """Measurement epochs of the validation on the horizon (same schedule as the Monte Carlo).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its filter times (``validation.dt`` over the horizon), sensors and rates.

    Returns
    -------
    Epochs
        The epochs on the filter grid: every sample where a sensor reports (and the ends), with
        which sensors report there.
    """
    t = pb.filter_times
    z = np.zeros((t.size, pb.dim))
    sched = estimation_config(pb).schedule(Trajectory(t=t, p=z, v=z, u=z))
    return make_epochs(t, sched.mask)
