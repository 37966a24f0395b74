"""The craft's distance limits to the vehicle are checked on the Monte Carlo's true vehicle paths
(2D: min_distance and max_range; 3D: max_range only), and the verdict says when runs break them."""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.model.beacon import BeaconPath
from obsplan.planning.beacon import plan_beacon
from obsplan.planning.beacon.craft import CHECK_DT
from obsplan.planning.beacon.planner import PATH_TOLERANCE_M
from obsplan.planning.plan import measured_excess, vehicle_trajectory
from obsplan.planning.problem.parse import load_problem
from obsplan.planning.problem.validation_setup import (
    confidence_quantile,
    estimation_config,
    truth_limits,
)
from obsplan.planning.results import truth_distance_notes
from obsplan.planning.solver.margins import craft_distance_margins
from obsplan.planning.validation.validate import validate_paths
from obsplan.trajectory.sampled import position_at, resample


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
    # the flow's second round widens the margin by what the runs measured: the worst excess of
    # the near beacon's runs, nothing for the far one or without a stated confidence
    near_tr = val["near"].result.truth
    assert measured_excess(val["near"], pb) == pytest.approx(near_tr.worst_excess["min_range"])
    # 6 m in on the nominal path; the runs stray less than 2 m from it
    assert measured_excess(val["near"], pb) > 4.0
    assert measured_excess(val["far"], pb) == 0.0
    off = pb.with_changes(limits={"keepout_confidence": 0.0})
    assert measured_excess(val["near"], off) == 0.0


def _margins(pb):
    """The vehicle's path (at the validation's step), the configuration with the craft holding
    its start, and the craft's distance margins there."""
    fine = resample(vehicle_trajectory(pb), pb.validation.dt)
    craft = pb.beacon_vehicle
    config = estimation_config(pb, BeaconPath.fixed(craft.start.tolist(), 0.0, fine.t[-1]))
    return fine, config, craft_distance_margins(posterior_crlb(fine, config), pb, config)


def test_craft_margins_follow_the_stated_confidence():
    pb = load_problem("asv-survey")
    _, _, m = _margins(pb)
    assert m.k == pytest.approx(confidence_quantile(pb.limits.keepout_confidence))
    assert np.all(m.horizontal > 0) and np.all(m.range >= m.horizontal - 1e-12)
    # a lower confidence: the same bound times a smaller quantile
    _, _, low = _margins(pb.with_changes(limits={"keepout_confidence": 0.9}))
    np.testing.assert_allclose(low.horizontal * m.k, m.horizontal * low.k, rtol=1e-9)
    # no stated confidence: no margin, and the flow keeps the nominal plan
    _, _, off = _margins(pb.with_changes(limits={"keepout_confidence": 0.0}))
    assert off.k == 0 and not np.any(off.horizontal) and not np.any(off.range)


@pytest.mark.slow
def test_the_planned_craft_keeps_min_distance_plus_the_margin():
    pb = load_problem("asv-survey")
    fine, config, m = _margins(pb)
    craft = pb.beacon_vehicle
    plan = plan_beacon(
        fine, craft, config, circles=False, truth_margins=(m.t, m.horizontal, m.range)
    )
    assert plan.success
    # at the check points (the first is after the start, which is given): the nominal distance
    # keeps min_distance plus the margin, to the sampled path's tolerance plus IPOPT's (1 mm)
    t = np.arange(fine.t[0] + CHECK_DT, fine.t[-1], CHECK_DT)
    d = np.linalg.norm(plan.path.position(t)[:, :2] - position_at(fine, t)[:, :2], axis=1)
    need = craft.min_distance + np.interp(t, m.t, m.horizontal)
    assert np.all(d >= need - PATH_TOLERANCE_M - 1e-3)
    # and the margin binds somewhere: without it the planner goes closer
    free = plan_beacon(fine, craft, config, circles=False)
    d0 = np.linalg.norm(free.path.position(t)[:, :2] - position_at(fine, t)[:, :2], axis=1)
    assert np.any(d0 < need - PATH_TOLERANCE_M - 1e-3)
