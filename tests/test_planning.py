"""The planner: exactness of the lifted objectives, limits and dynamics (checked without CasADi),
multi-start honesty, and the default problem's acceptance against the lawn-mower."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from obsplan.observability.gramian import gramian
from obsplan.planning import load_problem, solve
from obsplan.planning.baselines import lawnmower_baseline
from obsplan.planning.metrics import kf_final_pos_std, lwo_condition, objective_value
from obsplan.planning.problem import Horizon, problem_from_dict
from obsplan.planning.solve import initial_guesses, random_guess
from obsplan.validation import validate_paths


def small(kind: str = "gramian-min-eig", steps: int = 30, starts: int = 2, **obj):
    pb = load_problem()
    return replace(
        pb,
        horizon=Horizon(duration=pb.horizon.duration, steps=steps),
        objective=replace(pb.objective, kind=kind, starts=starts, **obj),
    )


def assert_limits_and_dynamics(traj, pb, rtol=1e-6):
    """Independent numpy check: exact ZOH integration, bounds, and the continuous area."""
    h = np.diff(traj.t)[:, None]
    u = traj.u[:-1]
    # dynamics: re-integrate the inputs from the start state
    v = np.vstack([pb.v0, pb.v0 + np.cumsum(u * h, axis=0)])
    p = np.vstack([pb.p0, pb.p0 + np.cumsum(v[:-1] * h + 0.5 * u * h**2, axis=0)])
    assert np.max(np.abs(p - traj.p)) < 1e-6
    assert np.max(np.abs(v - traj.v)) < 1e-8
    assert np.all(np.abs(u) <= pb.accel * (1 + rtol))
    # speed: dense sampling inside the intervals as well as the nodes
    s = np.linspace(0.0, 1.0, 11)[None, :, None] * h[:, :, None]
    vv = traj.v[:-1, None, :] + u[:, None, :] * s
    pp = traj.p[:-1, None, :] + traj.v[:-1, None, :] * s + 0.5 * u[:, None, :] * s**2
    assert np.max(np.linalg.norm(vv, axis=2)) <= pb.limits.speed * (1 + rtol)
    a = pb.limits.area
    if a is not None:
        tol = 1e-6 * max(a.width, a.height)
        assert pp[..., 0].min() >= a.x[0] - tol and pp[..., 0].max() <= a.x[1] + tol
        assert pp[..., 1].min() >= a.y[0] - tol and pp[..., 1].max() <= a.y[1] + tol


@pytest.fixture(scope="module")
def min_eig_result():
    return solve(small("gramian-min-eig", steps=30, starts=3))


def test_min_eig_reaches_true_lambda_min(min_eig_result):
    res = min_eig_result
    assert res.success and res.status == "Solve_Succeeded"
    pb = res.problem
    G = gramian(res.trajectory, pb.model, pb.scales)
    lam = np.linalg.eigvalsh(G)[0]
    assert lam > 0
    assert abs(res.lifted_objective - lam) <= 1e-6 * lam
    assert res.objective == pytest.approx(lam, rel=1e-12)


def test_min_eig_path_within_limits_and_consistent(min_eig_result):
    assert_limits_and_dynamics(min_eig_result.trajectory, min_eig_result.problem)


def test_min_eig_plan_beats_every_initial_guess(min_eig_result):
    # Not every start must improve on its own guess: the lifted problem has spurious stationary
    # points with a singular factor L (observed here: the circle start at N = 30 "succeeds" at
    # lambda_min = 0). The returned plan must still beat every guess, baselines included.
    res = min_eig_result
    assert all(s.success for s in res.starts)
    assert res.objective > max(s.initial_objective for s in res.starts)


def test_multistart_never_worse_than_its_best_start():
    pb = small("gramian-min-eig", steps=24, starts=4)
    guesses = initial_guesses(pb)
    multi = solve(pb, guesses=guesses)
    singles = [solve(pb, guesses=[g]) for g in guesses]
    best_single = max(s.objective for s in singles if s.success)
    assert multi.objective >= best_single - 1e-9 * abs(best_single)
    assert multi.objective == pytest.approx(max(s.objective for s in multi.starts if s.success))
    # the same start gives the same answer alone and inside the multi-start
    for single, inner in zip(singles, multi.starts, strict=True):
        assert single.starts[0].objective == pytest.approx(inner.objective, rel=1e-9)


def test_log_det_matches_numpy_slogdet():
    res = solve(small("gramian-log-det", steps=24, starts=1))
    assert res.success
    pb = res.problem
    sign, logdet = np.linalg.slogdet(gramian(res.trajectory, pb.model, pb.scales))
    assert sign > 0
    assert res.lifted_objective == pytest.approx(logdet, rel=1e-6)
    assert res.objective == pytest.approx(logdet, rel=1e-9)
    assert_limits_and_dynamics(res.trajectory, pb)


def test_kf_objective_lowers_predicted_std_and_matches_the_filter():
    # range at 0.1 Hz keeps the recursion short (60 epochs): L-BFGS converges in ~300 iterations
    pb = load_problem("problems/lowrate-range.toml")
    pb = replace(
        pb,
        horizon=Horizon(duration=600.0, steps=20),
        objective=replace(pb.objective, starts=1, tol=1e-5),
    )
    res = solve(pb)
    assert res.success, res.status
    lm = lawnmower_baseline(pb).trajectory
    assert res.objective < kf_final_pos_std(lm, pb)
    assert res.objective == pytest.approx(res.lifted_objective, rel=1e-9)
    assert_limits_and_dynamics(res.trajectory, pb)
    # the Riccati recursion inside the NLP predicts the validation KF's own covariance
    mc = validate_paths({"planned": res.trajectory}, pb, runs=3)["planned"].result
    assert mc.kf.final_pos_std == pytest.approx(res.objective, rel=0.02)


def test_lwo_condition_objective_is_the_numpy_value():
    pb = small("lwo-condition", steps=12, starts=2, tol=1e-6, max_iter=2000)
    res = solve(pb)
    assert res.success, [s.status for s in res.starts]
    assert res.objective == pytest.approx(lwo_condition(res.trajectory, pb), rel=1e-12)
    assert res.lifted_objective == pytest.approx(res.objective, rel=1e-6)
    assert res.objective > max(s.initial_objective for s in res.starts)
    assert_limits_and_dynamics(res.trajectory, pb)


def test_3d_depth_band_respected_on_the_continuous_path():
    pb = load_problem("problems/range3d.toml")
    pb = replace(
        pb,
        horizon=Horizon(duration=pb.horizon.duration, steps=24),
        objective=replace(pb.objective, starts=1),
    )
    res = solve(pb)
    assert res.success
    tr = res.trajectory
    assert_limits_and_dynamics(tr, pb)
    lo, hi = pb.limits.depth
    h = np.diff(tr.t)[:, None]
    s = np.linspace(0, 1, 51)[None, :] * h
    z = tr.p[:-1, 2:3] + tr.v[:-1, 2:3] * s + 0.5 * tr.u[:-1, 2:3] * s**2
    assert z.min() >= lo - 1e-6 and z.max() <= hi + 1e-6
    assert np.ptp(tr.p[:, 2]) > 1.0  # the planner excites the vertical axis (Table 1)


def test_failed_solve_is_reported_as_failed():
    pb = small("gramian-min-eig", steps=20, starts=1, max_iter=2)
    res = solve(pb)
    assert not res.success
    assert res.status == "Maximum_Iterations_Exceeded"
    assert not res.starts[0].success
    if res.trajectory is not None:  # only a feasible iterate may be returned
        assert res.starts[0].feasible


def test_random_guesses_are_seeded():
    pb = small()
    a, b = random_guess(pb, (0, 1)), random_guess(pb, (0, 1))
    c = random_guess(pb, (1, 1))
    assert np.array_equal(a.u, b.u) and not np.array_equal(a.u, c.u)
    assert np.all(np.abs(a.u) <= pb.accel)


def test_objective_value_on_any_path():
    pb = small()
    lm = lawnmower_baseline(pb).trajectory
    lam = np.linalg.eigvalsh(gramian(lm, pb.model, pb.scales))[0]
    assert objective_value(lm, pb) == pytest.approx(max(lam, 0.0), rel=1e-9, abs=1e-15)


# ------------------------------------------------------------------ acceptance (default problem)
#: Measured on the default problem (N = 200, 4 starts, 50 runs, seed 0): planned/lawn-mower
#: min_eig 0.1824 / 0.003372 (54x); KF RMSE 1.426 / 4.315 m (0.33); EKF RMSE 0.4050 / 0.4279 m
#: (0.946). The asserted margins sit below these ratios, not at arbitrary values.
ACCEPT_MIN_EIG_RATIO = 20.0
ACCEPT_KF_RMSE_RATIO = 0.5
ACCEPT_EKF_RMSE_RATIO = 0.97


@pytest.mark.slow
def test_default_problem_beats_the_lawnmower():
    pb = load_problem()
    res = solve(pb)
    assert res.success
    assert_limits_and_dynamics(res.trajectory, pb)
    lm = lawnmower_baseline(pb).trajectory
    assert res.objective >= ACCEPT_MIN_EIG_RATIO * objective_value(lm, pb)
    val = validate_paths({"planned": res.trajectory, "lawnmower": lm}, pb)  # full 50 runs
    p, m = val["planned"].result, val["lawnmower"].result
    assert p.kf.rmse_pos <= ACCEPT_KF_RMSE_RATIO * m.kf.rmse_pos
    assert p.ekf.rmse_pos <= ACCEPT_EKF_RMSE_RATIO * m.ekf.rmse_pos


def test_problem_from_dict_3d_plans_without_area():
    pb = problem_from_dict(
        {
            "vehicle": {"dim": 3, "sensors": ["range", "depth"]},
            "start": {"position": [30.0, 0.0, 5.0]},
            "limits": {"accel": 0.05, "speed": 1.0, "depth": [0.0, 20.0]},
            "horizon": {"duration": 200.0, "steps": 16},
            "objective": {"starts": 1},
        }
    )
    res = solve(pb)
    assert res.success
    assert_limits_and_dynamics(res.trajectory, pb)


@pytest.mark.parametrize(
    "name", ["default", "range3d", "range-dvl3d", "range-dvl-water-current2d", "lowrate-range"]
)
def test_every_shipped_problem_solves_at_reduced_size(name):
    pb = load_problem(f"problems/{name}.toml")
    obj = pb.objective
    pb = replace(
        pb,
        horizon=Horizon(duration=pb.horizon.duration, steps=16),
        objective=replace(obj, starts=2, tol=max(obj.tol, 1e-5 if "kf" in obj.kind else 1e-8)),
    )
    res = solve(pb)
    assert res.success, res.status
    assert_limits_and_dynamics(res.trajectory, pb)
    lm = lawnmower_baseline(pb).trajectory
    own, base = res.objective, objective_value(lm, pb)
    assert own < base if obj.kind == "kf-position-std" else own > base
