"""State estimation along a trajectory: EKF, augmented KF, multi-rate Monte Carlo (open or closed
loop) and bounds."""

from __future__ import annotations

from obsplan.estimation.closedloop import ClosedLoop, ClosedLoopState
from obsplan.estimation.config import (
    DEFAULT_ACCEL_NOISE,
    DEFAULT_NOISE,
    EstimationConfig,
    ProcessNoise,
    paper_covariances,
)
from obsplan.estimation.crlb import CRLBResult, posterior_crlb, sampled_rank_over_time
from obsplan.estimation.ekf import ExtendedKalmanFilter
from obsplan.estimation.guidance import Guidance, TruthLimits
from obsplan.estimation.kf import AugmentedKalmanFilter
from obsplan.estimation.schedule import Schedule, make_schedule
from obsplan.estimation.simulate import (
    DEFAULT_FILTERS,
    FILTERS,
    MonteCarloResult,
    RunHistory,
    merge_monte_carlo,
    monte_carlo,
    monte_carlo_paths,
)
from obsplan.estimation.stats import FilterStats, GroupStats, TruthStats, nees_bounds

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
