"""Baselines: same start, grid and limits as the plan; the properties each one claims."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from obsplan.observability.gramian import gramian
from obsplan.observability.scaling import numerical_rank, psd_metrics
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.objectives.estimator import covariance_stds
from obsplan.planning.objectives.evaluate import objective_value, path_metrics
from obsplan.planning.objectives.linearisation import linearisation_stress
from obsplan.planning.problem.feasibility import check_limits
from obsplan.planning.problem.parse import LOCALISE_PROBLEM, PROBLEMS_DIR
from obsplan.planning.problem.sections import Horizon
from obsplan.trajectory.generators import paper_lawnmower


@pytest.fixture(scope="module", params=["localise", "range3d", "range-dvl-water-current2d"])
def problem(request):
    return load_problem(PROBLEMS_DIR / f"{request.param}.toml")


def test_every_baseline_shares_start_grid_and_limits(problem):
    bls = baselines(problem)
    assert "lawnmower" in bls and "straight" in bls
    for name, b in bls.items():
        tr = b.trajectory
        assert np.array_equal(tr.t, problem.times), name
        np.testing.assert_allclose(tr.p[0], problem.p0, atol=1e-9)
        np.testing.assert_allclose(tr.v[0], problem.v0, atol=1e-9)
        chk = check_limits(tr, problem)
        assert chk.ok(), (name, chk)


def test_lawnmower_flies_at_the_limits(problem):
    tr = baselines(problem)["lawnmower"].trajectory
    speed = np.linalg.norm(tr.v, axis=1)
    assert speed.max() == pytest.approx(problem.limits.speed, rel=1e-6)
    # turns at the (horizontal) acceleration limit: chord inputs reach it to O((w h)^2)
    a = float(np.min(problem.accel[:2]))
    assert np.linalg.norm(tr.u[:-1], axis=1).max() == pytest.approx(a, rel=0.01)
    assert np.all(tr.u[:, 2] == 0) if problem.dim == 3 else True


def test_3d_flat_baselines_are_not_observable_with_range_only():
    pb = load_problem(PROBLEMS_DIR / "range3d.toml")
    for name in ("lawnmower", "circle", "straight"):
        G = gramian(baselines(pb)[name].trajectory, pb.model, pb.scales)
        assert numerical_rank(G) < G.shape[0], name  # Table 1: planar paths, u_z = 0


def test_straight_baseline_is_rank_deficient_and_not_radial():
    pb = load_problem(LOCALISE_PROBLEM)
    tr = baselines(pb)["straight"].trajectory
    G = gramian(tr, pb.model, pb.scales)
    assert numerical_rank(G) < G.shape[0]  # Table 1: straight lines are never observable
    direction = tr.p[-1] - tr.p[0]
    radial = pb.p0 - np.asarray(pb.beacon)
    cos = abs(direction @ radial) / np.linalg.norm(direction) / np.linalg.norm(radial)
    assert cos < 0.99


def test_paper_lawnmower_rescaled_to_a_limit():
    pb = load_problem(LOCALISE_PROBLEM)
    tr = baselines(pb)["paper-lawnmower"].trajectory
    ref = paper_lawnmower(2).sample(0.5)
    speed_ratio = np.linalg.norm(tr.v, axis=1).max() / pb.limits.speed
    accel_ratio = np.max(np.abs(tr.u[:-1]) / pb.accel)
    # the whole scaled path touches the binding limit exactly (fixed point of the time scale);
    # the horizon's window of it samples its turns at other phases: within 1 %
    assert max(speed_ratio, accel_ratio) <= 1.0 + 1e-9
    assert max(speed_ratio, accel_ratio) >= 0.99
    # same shape: the first leg is along +x like Fig. 3
    assert tr.p[10, 1] == pytest.approx(pb.p0[1]) and tr.p[10, 0] > pb.p0[0]
    assert ref.p[0] == pytest.approx([-80.0, 60.0])


def test_circle_is_about_the_beacon():
    pb = load_problem(LOCALISE_PROBLEM)
    tr = baselines(pb)["circle"].trajectory
    r = pb.model.range_to_beacon(tr.p)
    assert np.ptp(r) < 1e-3 * r.mean()


def test_metrics_are_computed_the_same_way_for_every_path():
    pb = load_problem(LOCALISE_PROBLEM)
    pb = replace(pb, horizon=Horizon(duration=pb.horizon.duration, steps=60))
    for name, b in baselines(pb).items():
        m = path_metrics(b.trajectory, pb)
        G = gramian(b.trajectory, pb.model, pb.scales)
        # round-off in a rank-deficient Gramian is not information: the rank test decides
        full = numerical_rank(G) == G.shape[0]
        expect = psd_metrics(G) if full else (0.0, float("-inf"), float("inf"))
        assert (m.min_eig, m.log_det, m.condition) == expect, name
        assert full != (name == "straight")  # Table 1: a straight line is never observable
        assert m.objective == objective_value(b.trajectory, pb)
        mean, final = covariance_stds(b.trajectory, pb, "pcrb-position")
        assert (m.pcrb_mean_pos_std, m.pcrb_final_pos_std) == (mean, final)
        assert 0 < m.pcrb_final_pos_std and m.closest_approach_m >= pb.limits.min_range
        assert m.ekf_linearisation_stress == linearisation_stress(b.trajectory, pb).max() > 0
        d = m.to_dict()
        assert set(d) >= {
            "min_eig",
            "log_det",
            "condition",
            "kf_final_pos_std",
            "pcrb_final_pos_std",
            "pcrb_mean_pos_std",
            "closest_approach_m",
            "ekf_linearisation_stress",
        }


def test_unfitted_baselines_are_reported_with_a_reason():
    from obsplan.planning.baselines.vehicle import unfitted_baselines

    pb = load_problem(PROBLEMS_DIR / "suite/moving-start.toml")
    assert "lawnmower" in baselines(pb)
    why = unfitted_baselines(pb)
    assert "not tangent" in why["circle"]
    assert set(why) | set(baselines(pb)) == {"lawnmower", "circle", "straight", "paper-lawnmower"}


def test_a_moving_start_whose_legs_do_not_fit_along_its_velocity_turns_onto_an_axis():
    """A diagonal start velocity: legs along it leave the box by its corners, so the lawn-mower
    turns onto an axis first (at the start's speed and the acceleration bound); a start velocity
    along which the legs fit keeps its heading (the suite's moving start: no turn)."""
    pb = load_problem(PROBLEMS_DIR / "suite/moving-start.toml")
    kept = baselines(pb)["lawnmower"]
    assert "after a turn" not in kept.description
    v = kept.trajectory.v
    heading = np.arctan2(v[:, 1], v[:, 0])
    assert abs(heading[1] - np.arctan2(pb.v0[1], pb.v0[0])) < 1e-6  # straight on at first
    a = float(np.min(pb.accel[:2]))
    diag = 0.6 * pb.limits.speed * np.array([np.cos(0.7), np.sin(0.7), 0.0][: pb.dim])
    moved = replace(pb, start_velocity=tuple(diag))
    bl = baselines(moved)["lawnmower"]
    tr = bl.trajectory
    assert "after a turn from the moving start" in bl.description
    np.testing.assert_allclose(tr.p[0], moved.p0, atol=1e-9)
    np.testing.assert_allclose(tr.v[0], moved.v0, atol=1e-9)
    assert check_limits(tr, moved).ok()
    assert np.linalg.norm(tr.u[:, :2], axis=1).max() <= a * (1 + 1e-9)
    legs = np.abs(np.linalg.norm(tr.u[:, :2], axis=1)) < 1e-12  # straight, unaccelerated
    lane = np.arctan2(tr.v[legs, 1], tr.v[legs, 0]) % (np.pi / 2)
    assert np.all(np.minimum(lane, np.pi / 2 - lane) < 1e-6)  # every leg along an axis


def test_lawnmower_keeps_clear_of_the_beacon():
    # a lawn-mower whose legs would pass over the beacon shifts its legs (slower cruise)
    pb = load_problem(LOCALISE_PROBLEM)
    pb = replace(pb, limits=replace(pb.limits, min_range=25.0))
    tr = baselines(pb)["lawnmower"].trajectory
    assert check_limits(tr, pb).ok()
    assert pb.model.range_to_beacon(tr.p).min() >= 25.0 - 1e-6


def test_a_coarse_grid_still_gets_a_lawnmower_with_gentler_turns():
    # at 150 s per step a turn at the acceleration limit would last under one step; the
    # lawn-mower turns more gently (each turn at least 4 steps) and still keeps every limit
    pb = replace(load_problem(LOCALISE_PROBLEM), horizon=Horizon(duration=600.0, steps=4))
    bl = baselines(pb)["lawnmower"]
    assert check_limits(bl.trajectory, pb).ok()
    assert "turns of radius" in bl.description
