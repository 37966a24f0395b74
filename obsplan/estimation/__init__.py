"""State estimation along a trajectory: EKF, augmented KF, multi-rate Monte Carlo and bounds."""

from __future__ import annotations

from obsplan.estimation.config import DEFAULT_NOISE, EstimationConfig, paper_covariances
from obsplan.estimation.crlb import CRLBResult, posterior_crlb, sampled_rank_over_time
from obsplan.estimation.ekf import EKFState, ExtendedKalmanFilter
from obsplan.estimation.kf import AugmentedKalmanFilter, KFState
from obsplan.estimation.schedule import Schedule, make_schedule
from obsplan.estimation.simulate import MonteCarloResult, RunHistory, monte_carlo
from obsplan.estimation.stats import FilterStats, nees_bounds

__all__ = [
    "DEFAULT_NOISE",
    "AugmentedKalmanFilter",
    "CRLBResult",
    "EKFState",
    "EstimationConfig",
    "ExtendedKalmanFilter",
    "FilterStats",
    "KFState",
    "MonteCarloResult",
    "RunHistory",
    "Schedule",
    "make_schedule",
    "monte_carlo",
    "nees_bounds",
    "paper_covariances",
    "posterior_crlb",
    "sampled_rank_over_time",
]
