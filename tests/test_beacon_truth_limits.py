"""The craft's distance limits to the vehicle are checked on the Monte Carlo's true vehicle paths
(2D: min_distance and max_range; 3D: max_range only), and the verdict says when runs break them."""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.model.beacon import BeaconPath
from obsplan.planning.plan import vehicle_trajectory
from obsplan.planning.problem.parse import load_problem
from obsplan.planning.problem.validation_setup import truth_limits
from obsplan.planning.results import truth_distance_notes
from obsplan.planning.validation.validate import validate_paths


def test_a_planned_beacons_truth_limits_are_its_crafts():
    pb = load_problem("asv-survey").with_changes(beacon={"max_range": 300.0})
    lim = truth_limits(pb)
    assert lim.min_range == pb.beacon_vehicle.min_distance == 10.0
    assert lim.max_range == 300.0
    assert truth_limits(load_problem("asv-survey")).max_range is None  # the file sets none
    # 3D: the range the kernels measure says nothing of the horizontal distance
    lim3 = truth_limits(load_problem("asv-survey3d").with_changes(beacon={"max_range": 300.0}))
    assert lim3.min_range is None and lim3.max_range == 300.0
    # a fixed beacon keeps limits.min_range
    fixed = load_problem("localise")
    assert truth_limits(fixed).min_range == fixed.limits.min_range


@pytest.mark.slow
def test_true_paths_that_come_too_close_to_the_craft_are_said():
    # the craft rides 4 m beside the vehicle's nominal path (min_distance 10 m): every run's
    # true path breaks it; a craft 40 m away (farther than any run strays) breaks nothing
    pb = load_problem("asv-survey").with_changes(validation={"dt": 1.0})
    traj = vehicle_trajectory(pb)
    t = traj.t
    near = BeaconPath(t, traj.p[:, :2] + np.array([0.0, 4.0]))
    far = BeaconPath(t, traj.p[:, :2] + np.array([0.0, 40.0]))
    val = validate_paths(
        {"near": traj, "far": traj},
        pb,
        runs=2,
        filters=("ekf",),
        beacons={"near": near, "far": far},
    )
    notes = truth_distance_notes(val)
    assert len(notes) == 1 and notes[0].startswith("with the near beacon")
    assert "min_distance (10 m) on 2 of 2 runs" in notes[0]
