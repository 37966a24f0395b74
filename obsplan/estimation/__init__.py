"""State estimation along a trajectory: EKF, augmented KF, multi-rate Monte Carlo and bounds."""

from __future__ import annotations

from obsplan.estimation.config import DEFAULT_NOISE, EstimationConfig, paper_covariances
from obsplan.estimation.crlb import CRLBResult, posterior_crlb, sampled_rank_over_time
from obsplan.estimation.ekf import ExtendedKalmanFilter
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
from obsplan.estimation.stats import FilterStats, GroupStats, nees_bounds

__all__ = [
    "DEFAULT_FILTERS",
    "DEFAULT_NOISE",
    "FILTERS",
    "AugmentedKalmanFilter",
    "CRLBResult",
    "EstimationConfig",
    "ExtendedKalmanFilter",
    "FilterStats",
    "GroupStats",
    "MonteCarloResult",
    "RunHistory",
    "Schedule",
    "make_schedule",
    "merge_monte_carlo",
    "monte_carlo",
    "monte_carlo_paths",
    "nees_bounds",
    "paper_covariances",
    "posterior_crlb",
    "sampled_rank_over_time",
]
