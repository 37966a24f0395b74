"""Paths of the double integrator: sampled trajectories with their CSV form and exact integration
(:mod:`~obsplan.trajectory.sampled`), the vehicle's motion relative to a moving beacon
(:mod:`~obsplan.trajectory.relative`), analytic paths in continuous time and their sampling
(:mod:`~obsplan.trajectory.analytic`), and the generators of the paper's motion classes and of the
baselines, which return analytic paths (:mod:`~obsplan.trajectory.generators`).

Imports :mod:`obsplan.core` and :mod:`obsplan.model` only.
"""

from obsplan.trajectory.analytic import AnalyticPath
from obsplan.trajectory.relative import relative_samples, relative_trajectory
from obsplan.trajectory.sampled import (
    InconsistentTrajectoryWarning,
    Trajectory,
    read_csv,
    resample,
    write_csv,
)

__all__ = [
    "AnalyticPath",
    "InconsistentTrajectoryWarning",
    "Trajectory",
    "read_csv",
    "relative_samples",
    "relative_trajectory",
    "resample",
    "write_csv",
]
