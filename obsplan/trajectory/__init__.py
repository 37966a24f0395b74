"""Paths of the double integrator: sampled trajectories with their CSV form and exact integration
(:mod:`~obsplan.trajectory.sampled`), and the analytic paths of the paper's motion classes and of
the baselines (:mod:`~obsplan.trajectory.generators`).

Imports :mod:`obsplan.core` and :mod:`obsplan.model` only.
"""

from obsplan.trajectory.sampled import (
    InconsistentTrajectoryWarning,
    Trajectory,
    read_csv,
    resample,
    write_csv,
)

__all__ = ["InconsistentTrajectoryWarning", "Trajectory", "read_csv", "resample", "write_csv"]
