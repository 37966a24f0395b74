"""The estimators' guards (``objective.kf_guard``, ``objective.ekf_guard``,
:mod:`obsplan.planning.objectives.guards`) and the verdict's words on which estimator a plan
serves."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import obsplan.planning.objectives.guards as guards_module
import obsplan.planning.solver.margins as margins_module
from obsplan.core.errors import ProblemError
from obsplan.planning import load_problem
from obsplan.planning.objectives.estimator import covariance_stds, reference_stds
from obsplan.planning.objectives.guards import (
    applies,
    ekf_guard_part,
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


#: A 2D problem with a current and a water-track DVL whose log-det plan, solved without the
#: EKF's guard, has a mission-mean posterior CRB above the lawn-mower's (an unseen problem's
#: setup at 40 nodes and one start).
EKF_TRADING = {
    "problem": {"name": "log-det with a current, trading the EKF's bound"},
    "vehicle": {
        "dim": 2,
        "sensors": ["range", "dvl-water"],
        "current": True,
        "current_velocity": [0.088, 0.133],
    },
    "beacon": {"position": [12.0, 56.2]},
    "start": {"position": [-90.4, -193.6], "velocity": [0.0, 0.0]},
    "limits": {
        "accel": 0.146,
        "speed": 1.71,
        "area": {"x": [-142.7, 142.7], "y": [-267.6, 267.6]},
        "keepout_confidence": 0.0,
    },
    "horizon": {"duration": 600.0, "steps": 40},
    "objective": {"kind": "gramian-log-det", "starts": 1},
    "validation": {
        "runs": 8,
        "dt": 0.1,
        "range_rate": 0.5,
        "range_std": 0.2,
        "dvl_rate": 5.0,
        "dvl_std": 0.001,
    },
}


def _objective(pb, **fields):
    return replace(pb, objective=replace(pb.objective, **fields))


@pytest.mark.parametrize("est", ["kf", "ekf"])
def test_the_ratios_are_one_on_the_lawnmower_and_the_penalty_is_their_hinge(est):
    pb = load_problem(OFFSET).with_changes(horizon={"steps": 40})
    lawnmower = guard_ratios_of(reference_path(pb), pb, est)
    np.testing.assert_allclose(lawnmower, (1.0, 1.0), rtol=1e-12)
    grid = Grid.from_problem(pb)
    circle = dict(initial_guesses(pb))["circle"]
    W = grid.from_trajectory(circle)
    a, f = guard_ratios_of(circle, pb, est)
    assert a != pytest.approx(f, rel=0.05)  # a bound between them tests both sides of the hinge
    # the EKF's ratios are the posterior CRB's stds, relative to the lawn-mower's
    kind = {"kf": "kf-position-std", "ekf": "pcrb-position"}[est]
    ref = reference_stds(pb, kind)
    by_stds = np.array(covariance_stds(circle, pb, kind)) / np.array(ref[:2])
    np.testing.assert_allclose((a, f), by_stds, rtol=1e-9)
    c = tuning().guard_penalty
    Wsym = ca.MX.sym("W", *W.shape)
    for bound in (0.5 * min(a, f), 0.5 * (a + f), 2.0 * max(a, f)):
        by_hand = c * sum(max(0.0, r / bound - 1.0) ** 2 for r in (a, f))
        assert penalty_expr(pb, grid, W, bound, est) == pytest.approx(by_hand, rel=1e-12)
        fn = ca.Function("p", [Wsym], [penalty_expr(pb, grid, Wsym, bound, est)])
        # the same recursion through CasADi's graph: round-off only
        assert float(fn(W)) == pytest.approx(by_hand, rel=1e-9, abs=1e-15)
    assert penalty_expr(pb, grid, W, 2.0 * max(a, f), est) == 0.0


def test_the_guard_applies_where_the_planner_has_the_kfs_recursion():
    pb = load_problem(OFFSET)
    assert pb.objective.kf_guard is None and applies(pb)
    grid, W = Grid.from_problem(pb), ca.MX.sym("W", 6, pb.horizon.steps)
    assert kf_guard_part(pb, grid, W) is None  # unset: engaged by a re-solve, not in the NLP
    assert kf_guard_part(_objective(pb, kf_guard=1.0), grid, W).name == "kf_guard"
    assert not applies(_objective(pb, kf_guard=0.0))
    assert not applies(_objective(pb, kind="kf-position-std"))
    assert not applies(load_problem(ROOT / "problems/ship-track.toml"))  # a moving beacon


def test_the_ekfs_guard_applies_to_the_observability_objectives():
    pb = load_problem(OFFSET)
    assert pb.objective.ekf_guard is None and applies(pb, "ekf")
    grid, W = Grid.from_problem(pb), ca.MX.sym("W", 6, pb.horizon.steps)
    assert ekf_guard_part(pb, grid, W) is None  # unset: engaged by a re-solve, not in the NLP
    assert ekf_guard_part(_objective(pb, ekf_guard=1.0), grid, W).name == "ekf_guard"
    assert kf_guard_part(_objective(pb, ekf_guard=1.0), grid, W) is None  # one guard each
    assert not applies(_objective(pb, ekf_guard=0.0), "ekf")
    for kind in ("lwo-condition", "gramian-log-det"):
        assert applies(_objective(pb, kind=kind), "ekf")
    # the estimator objectives plan for the bound already
    for kind in ("pcrb-position", "kf-position-std"):
        assert not applies(_objective(pb, kind=kind, ekf_guard=1.0), "ekf")
        assert ekf_guard_part(_objective(pb, kind=kind, ekf_guard=1.0), grid, W) is None
    assert not applies(load_problem(ROOT / "problems/ship-track.toml"), "ekf")


def test_a_guarded_exact_hessian_objective_solves_with_a_limited_memory_hessian():
    # the guard's penalty is a whole-path functional: no exact Hessian without its curvature
    pb = _objective(load_problem(OFFSET), kind="lwo-condition").with_changes(horizon={"steps": 20})
    assert build_formulation(pb).hessian == "exact"
    assert build_formulation(_objective(pb, kf_guard=1.0)).hessian == "limited-memory"
    # the linearisation penalty keeps the objective's exact Hessian, without its own curvature
    bounded = _objective(pb, linearisation_bound=0.25)
    assert build_formulation(bounded).hessian == "exact-without-penalty"
    assert build_formulation(_objective(bounded, kf_guard=1.0)).hessian == "limited-memory"
    assert build_formulation(_objective(pb, ekf_guard=1.0)).hessian == "limited-memory"


@pytest.mark.parametrize("field", ["kf_guard", "ekf_guard"])
@pytest.mark.parametrize("value", [-0.1, float("nan"), float("inf")])
def test_a_bad_guard_names_its_field(field, value):
    d = problem_to_dict(load_problem(OFFSET))
    d["objective"][field] = value
    with pytest.raises(ProblemError, match=f"objective.{field}"):
        problem_from_dict(d)


def test_the_guards_round_trip():
    pb = _objective(load_problem(OFFSET), kf_guard=0.9, ekf_guard=1.1)
    assert problem_from_dict(problem_to_dict(pb)) == pb


def _only(pb, est, bound=None):
    """``pb`` with the guard of ``est`` at ``bound`` (None: its default) and the other off."""
    other = "kf" if est == "ekf" else "ekf"
    return _objective(pb, **{f"{est}_guard": bound, f"{other}_guard": 0.0})


@pytest.mark.slow
@pytest.mark.parametrize("est", ["kf"])  # the EKF's: on EKF_TRADING below
def test_a_set_guard_holds_the_estimator_below_what_the_plan_reaches_without_it(est):
    pb = problem_from_dict(TRADING)
    free = solve(_only(pb, est, 0.0), processes=1)
    assert free.success
    unguarded = guard_ratios_of(free.trajectory, pb, est)
    bound = 0.85 * max(unguarded)  # the guard must move the plan
    held = solve(_only(pb, est, bound), processes=1)
    assert held.success
    ratios = guard_ratios_of(held.trajectory, pb, est)
    # a quadratic penalty leaves an excess where its slope 2 c x meets the objective's own
    # (c = 100 per unit ratio): 3 % of the bound would take a marginal gain of 6 normalised
    # objectives per unit of the estimator's ratio, far above what the information objectives
    # show
    assert max(ratios) <= 1.03 * bound


@pytest.mark.slow
@pytest.mark.parametrize("est", ["kf"])  # the EKF's: on EKF_TRADING below
def test_the_default_guard_changes_nothing_unless_it_engages_and_then_re_solves(monkeypatch, est):
    pb = problem_from_dict(TRADING).with_changes(limits={"keepout_confidence": 0.0})
    free, _ = solve_with_keepout(_only(pb, est, 0.0), processes=1)
    assert getattr(free, f"{est}_guard") is None  # off: not evaluated
    unguarded = guard_ratios_of(free.trajectory, pb, est)

    # a bound every plan keeps: the default returns exactly the plan solved without the guard
    monkeypatch.setitem(guards_module.DEFAULT_BOUNDS, est, 2.0 * max(unguarded))
    monkeypatch.setitem(guards_module.ENGAGE_ABOVE, est, 2.0 * max(unguarded))
    kept, _ = solve_with_keepout(_only(pb, est), processes=1)
    out = getattr(kept, f"{est}_guard")
    assert not out.engaged and not out.applied
    np.testing.assert_array_equal(kept.trajectory.u, free.trajectory.u)
    assert getattr(kept.problem.objective, f"{est}_guard") is None

    # a bound the plan breaks: re-solved with it, and said so
    bound = 0.85 * max(unguarded)
    monkeypatch.setitem(guards_module.DEFAULT_BOUNDS, est, bound)
    monkeypatch.setitem(guards_module.ENGAGE_ABOVE, est, bound)
    res, _ = solve_with_keepout(_only(pb, est), processes=1)
    out = getattr(res, f"{est}_guard")
    assert out.engaged and out.applied and out.unguarded == pytest.approx(unguarded, rel=1e-12)
    assert getattr(res.problem.objective, f"{est}_guard") == bound
    assert out.ratios == pytest.approx(guard_ratios_of(res.trajectory, pb, est), rel=1e-12)
    assert max(out.ratios) <= 1.03 * bound  # the tolerance of the test above
    assert f"re-solved with objective.{est}_guard" in res.note
    assert res.to_dict()[f"{est}_guard"]["engaged"] is True
    # and the other estimator's prediction held: not above both the lawn-mower's and the plan's
    # without the guard
    other = "kf" if est == "ekf" else "ekf"
    before = guard_ratios_of(free.trajectory, pb, other)
    after = guard_ratios_of(res.trajectory, pb, other)
    assert all(a <= max(1.0, b) for b, a in zip(before, after, strict=True))


@pytest.mark.slow
def test_the_ekfs_default_guard_holds_a_plan_that_trades_the_ekf(monkeypatch):
    pb = problem_from_dict(EKF_TRADING)
    free, _ = solve_with_keepout(_only(pb, "ekf", 0.0), processes=1)
    assert free.success
    unguarded = guard_ratios_of(free.trajectory, pb, "ekf")
    assert max(unguarded) > 1.0  # the plan without the guard trades the EKF's bound
    costs = []
    real_cost = margins_module._cost

    def cost(pb, est, a, b):
        costs.append(est)
        return real_cost(pb, est, a, b)

    monkeypatch.setattr(margins_module, "_cost", cost)
    res, _ = solve_with_keepout(_only(pb, "ekf"), processes=1)
    out = res.ekf_guard
    assert out.engaged and out.applied and res.success
    assert out.unguarded == pytest.approx(unguarded, rel=1e-12)  # the same first solve
    bound = guards_module.DEFAULT_BOUNDS["ekf"]
    assert res.problem.objective.ekf_guard == bound == 0.95  # engaged above 1, held below it
    assert out.ratios == pytest.approx(guard_ratios_of(res.trajectory, pb, "ekf"), rel=1e-12)
    assert max(out.ratios) <= 1.03 * bound  # the tolerance of the KF's test above
    assert "re-solved with objective.ekf_guard = 0.95, EKF" in res.note
    assert res.to_dict()["ekf_guard"]["applied"] is True and res.kf_guard is None  # KF's off
    # the KF's prediction was checked, and not raised above both the lawn-mower's and the plan's
    # without the guard
    assert costs == ["kf"]
    before = guard_ratios_of(free.trajectory, pb, "kf")
    after = guard_ratios_of(res.trajectory, pb, "kf")
    assert all(a <= max(1.0, b) for b, a in zip(before, after, strict=True))


def test_the_other_estimators_prediction_decides_whether_a_guarded_plan_is_kept():
    pb = load_problem(OFFSET).with_changes(horizon={"steps": 40})
    ref = reference_stds(pb, "pcrb-position")
    paths = {label: tr for label, tr in initial_guesses(pb)}
    # a path whose bound is below the lawn-mower's at the end: a plan of that bound
    paths["plan"] = solve(_objective(pb, kind="pcrb-position", starts=1), processes=1).trajectory
    stds = {k: covariance_stds(tr, pb, "pcrb-position") for k, tr in paths.items()}
    worse = next(k for k, s in stds.items() if s[1] > 1.01 * ref[1])  # and one above it
    better = "plan"
    assert stds[better][1] < ref[1]
    words = margins_module._cost(pb, "ekf", paths[better], paths[worse])
    assert f"final to {stds[worse][1] / ref[1]:.2f}x" in words
    assert margins_module._cost(pb, "ekf", paths[worse], paths[better]) == ""
    assert margins_module._cost(pb, "ekf", paths[worse], paths[worse]) == ""  # no worse than itself


@pytest.mark.slow
@pytest.mark.parametrize("est", ["kf"])  # the EKF's: on EKF_TRADING below
def test_a_guarded_plan_that_costs_the_other_estimator_is_not_kept(monkeypatch, est):
    pb = problem_from_dict(TRADING).with_changes(limits={"keepout_confidence": 0.0})
    free, _ = solve_with_keepout(_only(pb, est, 0.0), processes=1)
    bound = 0.85 * max(guard_ratios_of(free.trajectory, pb, est))
    monkeypatch.setitem(guards_module.DEFAULT_BOUNDS, est, bound)
    monkeypatch.setitem(guards_module.ENGAGE_ABOVE, est, bound)
    monkeypatch.setattr(margins_module, "_cost", lambda pb, e, a, b: "final to 1.50x")
    res, _ = solve_with_keepout(_only(pb, est), processes=1)
    out = getattr(res, f"{est}_guard")
    assert out.engaged and not out.applied and out.ratios == out.unguarded
    np.testing.assert_array_equal(res.trajectory.u, free.trajectory.u)
    other = "kf" if est == "ekf" else "ekf"
    assert f"raised {guards_module.HELD[other]} final to 1.50x the lawn-mower's" in res.note
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
    assert "objective.ekf_guard holds the EKF's bound" in note  # an observability objective
    off = estimator_notes(swapped, replace(gramian, ekf_guard=0.0))[0]
    assert off.endswith("objective.ekf_guard = 0 turned off the guard on the EKF's bound")
    (pcrb,) = estimator_notes(swapped, ObjectiveSpec(kind="pcrb-position"))
    assert "ekf_guard" not in pcrb  # the bound is that objective itself
    (note,) = estimator_notes(swapped, ObjectiveSpec(kind="kf-position-std"))
    assert note.startswith("the plan serves the augmented KF (objective kf-position-std")
    assert "objective.pcrb_weight = 1" in note and "loses the EKF's verdict" in note
