"""State estimation along a trajectory: EKF, augmented KF, multi-rate Monte Carlo (open or closed
loop) and bounds.

The floor (modules directly here) holds what every room shares: the filters' configuration and
process noise (:mod:`~.config`), the double integrator's Kalman structure (:mod:`~.kalman`),
measurement schedules and epochs (:mod:`~.schedule`, :mod:`~.epochs`), a batch of runs as a
filter sees it (:mod:`~.batch`), the batched output model (:mod:`~.sensors`) and the compiled
kernels with their column layout (:mod:`~.kernels`, :mod:`~.columns`, :mod:`~.jitcache`). On
it stand :mod:`~.filters`, :mod:`~.bounds` and, on both, :mod:`~.montecarlo`. Imports the model,
trajectory and observability stages and the core.
"""

from __future__ import annotations

from obsplan.estimation.bounds.crlb import CRLBResult, posterior_crlb, sampled_rank_over_time
from obsplan.estimation.config import (
    DEFAULT_ACCEL_NOISE,
    DEFAULT_NOISE,
    EstimationConfig,
    ProcessNoise,
    paper_covariances,
)
from obsplan.estimation.filters.ekf import ExtendedKalmanFilter
from obsplan.estimation.filters.kf import AugmentedKalmanFilter
from obsplan.estimation.montecarlo.closedloop import ClosedLoop, ClosedLoopState
from obsplan.estimation.montecarlo.guidance import Guidance, TruthLimits
from obsplan.estimation.montecarlo.simulate import (
    DEFAULT_FILTERS,
    FILTERS,
    MonteCarloResult,
    RunHistory,
    merge_monte_carlo,
    monte_carlo,
    monte_carlo_paths,
)
from obsplan.estimation.montecarlo.stats import FilterStats, GroupStats, TruthStats, nees_bounds
from obsplan.estimation.schedule import Schedule, make_schedule

__all__ = [
    "DEFAULT_ACCEL_NOISE",
    "DEFAULT_FILTERS",
    "DEFAULT_NOISE",
    "FILTERS",
    "AugmentedKalmanFilter",
    "CRLBResult",
    "ClosedLoop",
    "ClosedLoopState",
    "EstimationConfig",
    "ExtendedKalmanFilter",
    "FilterStats",
    "GroupStats",
    "Guidance",
    "MonteCarloResult",
    "ProcessNoise",
    "RunHistory",
    "Schedule",
    "TruthLimits",
    "TruthStats",
    "make_schedule",
    "merge_monte_carlo",
    "monte_carlo",
    "monte_carlo_paths",
    "nees_bounds",
    "paper_covariances",
    "posterior_crlb",
    "sampled_rank_over_time",
]
