"""The augmented KF's guard (``objective.kf_guard``, :mod:`obsplan.planning.objectives.kf_guard`)
and the verdict's words on which estimator a plan serves."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import obsplan.planning.objectives.kf_guard as kf_guard_module
import obsplan.planning.solver.margins as margins_module
from obsplan.core.errors import ProblemError
from obsplan.planning import load_problem
from obsplan.planning.objectives.estimator import covariance_stds, reference_stds
from obsplan.planning.objectives.kf_guard import (
    applies,
    guard_ratios_of,
    kf_guard_part,
    penalty_expr,
)
from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict
from obsplan.planning.problem.sections import ObjectiveSpec
from obsplan.planning.solver.formulation import build_formulation
from obsplan.planning.solver.margins import solve_with_keepout
from obsplan.planning.solver.solve import solve
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.transcription.guesses import initial_guesses, reference_path
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.verdict import Comparison, estimator_notes

ROOT = Path(__file__).resolve().parents[1]
OFFSET = ROOT / "problems/suite/gramian-offset-beacon.toml"

#: A 2D range-only min-eig problem that solves in seconds; the tests set the guard relative to
#: the KF's predicted std on its plan solved without it.
TRADING = {
    "problem": {"name": "min-eig, beacon off the start"},
    "vehicle": {"dim": 2, "sensors": ["range"]},
    "beacon": {"position": [6.0, -10.0]},
    "start": {"position": [-20.0, 15.0], "velocity": [0.2, 0.5]},
    "limits": {"accel": 0.1, "speed": 0.95, "area": {"x": [-65.0, 65.0], "y": [-37.0, 37.0]}},
    "horizon": {"duration": 600.0, "steps": 60},
    "objective": {"kind": "gramian-min-eig", "starts": 3},
    "validation": {"runs": 8, "dt": 0.1, "range_rate": 1.0, "range_std": 0.05},
}


def _objective(pb, **fields):
    return replace(pb, objective=replace(pb.objective, **fields))


def test_the_ratios_are_one_on_the_lawnmower_and_the_penalty_is_their_hinge():
    pb = load_problem(OFFSET).with_changes(horizon={"steps": 40})
    np.testing.assert_allclose(guard_ratios_of(reference_path(pb), pb), (1.0, 1.0), rtol=1e-12)
    grid = Grid.from_problem(pb)
    circle = dict(initial_guesses(pb))["circle"]
    W = grid.from_trajectory(circle)
    a, f = guard_ratios_of(circle, pb)
    assert a != pytest.approx(f, rel=0.05)  # a bound between them tests both sides of the hinge
    c = tuning().kf_guard_penalty
    Wsym = ca.MX.sym("W", *W.shape)
    for bound in (0.5 * min(a, f), 0.5 * (a + f), 2.0 * max(a, f)):
        by_hand = c * sum(max(0.0, r / bound - 1.0) ** 2 for r in (a, f))
        assert penalty_expr(pb, grid, W, bound) == pytest.approx(by_hand, rel=1e-12)
        fn = ca.Function("p", [Wsym], [penalty_expr(pb, grid, Wsym, bound)])
        # the same recursion through CasADi's graph: round-off only
        assert float(fn(W)) == pytest.approx(by_hand, rel=1e-9, abs=1e-15)
    assert penalty_expr(pb, grid, W, 2.0 * max(a, f)) == 0.0


def test_the_guard_applies_where_the_planner_has_the_kfs_recursion():
    pb = load_problem(OFFSET)
    assert pb.objective.kf_guard is None and applies(pb)
    grid, W = Grid.from_problem(pb), ca.MX.sym("W", 6, pb.horizon.steps)
    assert kf_guard_part(pb, grid, W) is None  # unset: engaged by a re-solve, not in the NLP
    assert kf_guard_part(_objective(pb, kf_guard=1.0), grid, W).name == "kf_guard"
    assert not applies(_objective(pb, kf_guard=0.0))
    assert not applies(_objective(pb, kind="kf-position-std"))
    assert not applies(load_problem(ROOT / "problems/ship-track.toml"))  # a moving beacon


def test_a_guarded_exact_hessian_objective_solves_with_a_limited_memory_hessian():
    # the guard's penalty is a whole-path functional: no exact Hessian without its curvature
    pb = _objective(load_problem(OFFSET), kind="lwo-condition").with_changes(horizon={"steps": 20})
    assert build_formulation(pb).hessian == "exact"
    assert build_formulation(_objective(pb, kf_guard=1.0)).hessian == "limited-memory"
    # the linearisation penalty keeps the objective's exact Hessian, without its own curvature
    bounded = _objective(pb, linearisation_bound=0.25)
    assert build_formulation(bounded).hessian == "exact-without-penalty"
    assert build_formulation(_objective(bounded, kf_guard=1.0)).hessian == "limited-memory"


@pytest.mark.parametrize("value", [-0.1, float("nan"), float("inf")])
def test_a_bad_guard_names_its_field(value):
    d = problem_to_dict(load_problem(OFFSET))
    d["objective"]["kf_guard"] = value
    with pytest.raises(ProblemError, match="objective.kf_guard"):
        problem_from_dict(d)


def test_the_guard_round_trips():
    pb = _objective(load_problem(OFFSET), kf_guard=0.9)
    assert problem_from_dict(problem_to_dict(pb)) == pb


@pytest.mark.slow
def test_a_set_guard_holds_the_kf_below_what_the_plan_reaches_without_it():
    pb = problem_from_dict(TRADING)
    free = solve(_objective(pb, kf_guard=0.0), processes=1)
    assert free.success
    unguarded = guard_ratios_of(free.trajectory, pb)
    bound = 0.85 * max(unguarded)  # the guard must move the plan
    held = solve(_objective(pb, kf_guard=bound), processes=1)
    assert held.success
    ratios = guard_ratios_of(held.trajectory, pb)
    # a quadratic penalty leaves an excess where its slope 2 c x meets the objective's own
    # (c = 100 per unit ratio): 3 % of the bound would take a marginal gain of 6 normalised
    # objectives per unit of the KF's ratio, far above what the information objectives show
    assert max(ratios) <= 1.03 * bound


@pytest.mark.slow
def test_the_default_guard_changes_nothing_unless_it_engages_and_then_re_solves(monkeypatch):
    pb = problem_from_dict(TRADING).with_changes(limits={"keepout_confidence": 0.0})
    free, _ = solve_with_keepout(_objective(pb, kf_guard=0.0), processes=1)
    assert free.kf_guard is None  # off: not evaluated
    unguarded = guard_ratios_of(free.trajectory, pb)

    # a bound every plan keeps: the default returns exactly the plan solved without the guard
    monkeypatch.setattr(kf_guard_module, "KF_GUARD", 2.0 * max(unguarded))
    monkeypatch.setattr(margins_module, "KF_GUARD", 2.0 * max(unguarded))
    kept, _ = solve_with_keepout(pb, processes=1)
    assert not kept.kf_guard.engaged and not kept.kf_guard.applied
    np.testing.assert_array_equal(kept.trajectory.u, free.trajectory.u)
    assert kept.problem.objective.kf_guard is None

    # a bound the plan breaks: re-solved with it, and said so
    bound = 0.85 * max(unguarded)
    monkeypatch.setattr(kf_guard_module, "KF_GUARD", bound)
    monkeypatch.setattr(margins_module, "KF_GUARD", bound)
    res, _ = solve_with_keepout(pb, processes=1)
    out = res.kf_guard
    assert out.engaged and out.applied and out.unguarded == pytest.approx(unguarded, rel=1e-12)
    assert res.problem.objective.kf_guard == bound
    assert out.ratios == pytest.approx(guard_ratios_of(res.trajectory, pb), rel=1e-12)
    assert max(out.ratios) <= 1.03 * bound  # the tolerance of the test above
    assert "re-solved with objective.kf_guard" in res.note
    assert res.to_dict()["kf_guard"]["engaged"] is True
    # and the EKF's bound held: not above both the lawn-mower's and the plan's without the guard
    ref = reference_stds(pb, "pcrb-position")
    before = covariance_stds(free.trajectory, pb, "pcrb-position")
    after = covariance_stds(res.trajectory, pb, "pcrb-position")
    assert all(a <= max(r, b) for r, b, a in zip(ref[:2], before, after, strict=True))


def test_the_ekfs_bound_decides_whether_a_guarded_plan_is_kept():
    pb = load_problem(OFFSET).with_changes(horizon={"steps": 40})
    ref = reference_stds(pb, "pcrb-position")
    paths = {label: tr for label, tr in initial_guesses(pb)}
    # a path whose bound is below the lawn-mower's at the end: a plan of that bound
    paths["plan"] = solve(_objective(pb, kind="pcrb-position", starts=1), processes=1).trajectory
    stds = {k: covariance_stds(tr, pb, "pcrb-position") for k, tr in paths.items()}
    worse = next(k for k, s in stds.items() if s[1] > 1.01 * ref[1])  # and one above it
    better = "plan"
    assert stds[better][1] < ref[1]
    words = margins_module._ekf_cost(pb, paths[better], paths[worse])
    assert f"final to {stds[worse][1] / ref[1]:.2f}x" in words
    assert margins_module._ekf_cost(pb, paths[worse], paths[better]) == ""
    assert margins_module._ekf_cost(pb, paths[worse], paths[worse]) == ""  # no worse than itself


@pytest.mark.slow
def test_a_guarded_plan_that_costs_the_ekf_is_not_kept(monkeypatch):
    pb = problem_from_dict(TRADING).with_changes(limits={"keepout_confidence": 0.0})
    free, _ = solve_with_keepout(_objective(pb, kf_guard=0.0), processes=1)
    bound = 0.85 * max(guard_ratios_of(free.trajectory, pb))
    monkeypatch.setattr(kf_guard_module, "KF_GUARD", bound)
    monkeypatch.setattr(margins_module, "KF_GUARD", bound)
    monkeypatch.setattr(margins_module, "_ekf_cost", lambda pb, a, b: "final to 1.50x")
    res, _ = solve_with_keepout(pb, processes=1)
    out = res.kf_guard
    assert out.engaged and not out.applied and out.ratios == out.unguarded
    np.testing.assert_array_equal(res.trajectory.u, free.trajectory.u)
    assert "raised the EKF's bound (posterior CRB) final to 1.50x the lawn-mower's" in res.note
    assert res.note.endswith("the plan without the guard is kept")


def _comp(key: str, ratio: float, lo: float, hi: float) -> Comparison:
    return Comparison(key, ratio, 1.0, None, (lo, hi))


def test_the_verdict_says_which_estimator_a_plan_serves():
    comps = {
        "lawnmower": {
            "ekf.rmse_pos": _comp("ekf.rmse_pos", 0.7, 0.68, 0.72),
            "kf.rmse_pos": _comp("kf.rmse_pos", 1.05, 1.01, 1.08),
        },
        "circle": {  # a KF loss that is a tie: nothing to say
            "ekf.rmse_pos": _comp("ekf.rmse_pos", 0.7, 0.68, 0.72),
            "kf.rmse_pos": _comp("kf.rmse_pos", 1.02, 0.99, 1.05),
        },
    }
    gramian = ObjectiveSpec(kind="gramian-min-eig")
    (note,) = estimator_notes(comps, gramian)
    assert note.startswith("the plan serves the EKF (its objective, gramian-min-eig, scores")
    assert "loses the augmented KF's verdict against the lawnmower on KF position RMSE" in note
    assert "objective.kf_guard holds" in note
    assert "= 0 turned off" in estimator_notes(comps, replace(gramian, kf_guard=0.0))[0]
    assert estimator_notes(comps, None) == ()

    swapped = {
        "lawnmower": {
            "ekf.final_pos_err": _comp("ekf.final_pos_err", 1.2, 1.1, 1.3),
            "kf.final_pos_err": _comp("kf.final_pos_err", 0.5, 0.4, 0.6),
        }
    }
    (note,) = estimator_notes(swapped, gramian)
    assert note.startswith("the plan serves the EKF (its objective, gramian-min-eig, scores")
    assert "yet loses the EKF's verdict against the lawnmower on EKF final" in note
    assert "where the augmented KF wins" in note
    (note,) = estimator_notes(swapped, ObjectiveSpec(kind="kf-position-std"))
    assert note.startswith("the plan serves the augmented KF (objective kf-position-std")
    assert "objective.pcrb_weight = 1" in note and "loses the EKF's verdict" in note
