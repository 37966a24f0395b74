"""Paths of the double integrator: sampled trajectories with their CSV form and exact integration
(:mod:`~obsplan.trajectory.sampled`), analytic paths in continuous time and their sampling
(:mod:`~obsplan.trajectory.analytic`), and the generators of the paper's motion classes and of the
baselines, which return analytic paths (:mod:`~obsplan.trajectory.generators`).

Imports :mod:`obsplan.core` and :mod:`obsplan.model` only.
"""

from obsplan.trajectory.analytic import AnalyticPath
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
    "resample",
    "write_csv",
]
