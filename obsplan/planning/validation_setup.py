"""The validation's filters as the estimation layer's objects: their configuration and epochs.

One place for what the validation Monte Carlo runs (:mod:`obsplan.planning.validation`) and what
the estimator-aware objectives predict (:mod:`obsplan.planning.estimator_objectives`): the
filters' :class:`~obsplan.estimation.config.EstimationConfig` built from ``[validation]`` and the
measurement epochs on the horizon. Both sides read them here, so the planner's bound is the
validation's own.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from obsplan.estimation.config import EstimationConfig, paper_covariances
from obsplan.estimation.riccati import Epochs, make_epochs
from obsplan.estimation.schedule import make_schedule
from obsplan.planning.problem import PlanningProblem
from obsplan.trajectory import Trajectory


def estimation_config(pb: PlanningProblem) -> EstimationConfig:
    """The filters' configuration of the validation of ``pb``.

    The paper's covariances at step ``validation.dt`` with the prior of ``p`` and ``v`` set by
    ``init_pos_error`` / ``init_vel_error``, the problem's rates and noises, and the true
    current ``vehicle.current_velocity``. Used by the validation and by the planning objectives.
    """
    model, val, n = pb.model, pb.validation, pb.dim
    cov: dict[str, Any] = paper_covariances(model, val.dt)
    for key in ("p0_ekf", "p0_kf"):
        d = np.diag(cov[key]).copy()
        d[:n] = val.init_pos_error**2
        d[n : 2 * n] = val.init_vel_error**2
        cov[key] = np.diag(d)
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
        **cov,
    )


def filter_epochs(pb: PlanningProblem) -> Epochs:
    """Measurement epochs of the validation on the horizon (same schedule as the Monte Carlo)."""
    t = pb.filter_times
    z = np.zeros((t.size, pb.dim))
    rates = dict(estimation_config(pb).rates_hz)
    sched = make_schedule(Trajectory(t=t, p=z, v=z, u=z), pb.model.sensors, rates)
    return make_epochs(t, sched.mask)
