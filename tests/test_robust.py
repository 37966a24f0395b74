"""Robust planning over a family of conditions, and the robustness (stress) row."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from obsplan.core.errors import ProblemError
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.objectives.estimator import covariance_value
from obsplan.planning.objectives.evaluate import objective_value
from obsplan.planning.objectives.registry import objective_of
from obsplan.planning.objectives.robust import (
    ROBUST,
    condition_problems,
    condition_values,
    conditions,
    is_robust,
    robust_value,
    scaled_problem,
)
from obsplan.planning.problem.parse import LOCALISE_PROBLEM, problem_from_dict, problem_to_dict
from obsplan.planning.problem.validation_setup import validation_guidance
from obsplan.planning.solver.formulation import build_formulation
from obsplan.planning.solver.margins import condition_margins, keepout_margins
from obsplan.planning.validation.stress import stress_active, stress_validate
from obsplan.planning.validation.validate import validate_paths


def _robust(pb, aggregate="worst"):
    obj = replace(
        pb.objective,
        robust_prior=(1.0, 5.0),
        robust_range_noise=(1.0, 3.0),
        robust_aggregate=aggregate,
    )
    return replace(pb, objective=obj)


def test_conditions_are_every_combination_and_scale_the_validation(short_problem):
    pb = _robust(short_problem)
    assert is_robust(pb) and not is_robust(short_problem)
    assert conditions(pb) == ((1.0, 1.0), (1.0, 3.0), (5.0, 1.0), (5.0, 3.0))
    s = scaled_problem(pb, 5.0, 3.0)
    v, v0 = s.validation, short_problem.validation
    assert v.init_pos_error == 5 * v0.init_pos_error and v.init_vel_error == 5 * v0.init_vel_error
    assert v.range_std == 3 * v0.range_std
    assert not is_robust(s)
    assert objective_of(pb) is ROBUST


def test_robust_value_is_the_worst_or_mean_of_the_conditions(short_problem):
    pb = _robust(short_problem)
    tr = baselines(pb)["circle"].trajectory
    vals = condition_values(tr, pb)
    assert vals.shape == (4,)
    ref = baselines(pb)["lawnmower"].trajectory
    # each condition relative to its own value on the reference (the lawn-mower): 1 there
    np.testing.assert_allclose(condition_values(ref, pb), 1.0, rtol=1e-9)
    assert robust_value(tr, pb) == pytest.approx(vals.max())
    assert robust_value(tr, _robust(short_problem, "mean")) == pytest.approx(vals.mean())
    # the nominal condition is the nominal objective
    nominal = covariance_value(tr, short_problem) / covariance_value(ref, short_problem)
    assert vals[0] == pytest.approx(nominal, rel=1e-9)
    assert objective_value(tr, pb) == pytest.approx(vals.max())


@pytest.mark.parametrize("aggregate", ["worst", "mean"])
def test_the_nlp_evaluates_the_same_aggregate(short_problem, aggregate):
    pb = _robust(short_problem, aggregate)
    form = build_formulation(pb)
    tr = baselines(pb)["circle"].trajectory
    x = form.pack(tr)
    f = ca.Function("f", [form.w], [form.f, form.g])
    fv, gv = (np.asarray(v).reshape(-1) for v in f(x))
    vals = condition_values(tr, pb)
    if aggregate == "mean":
        assert form.lifted_value(float(fv[0])) == pytest.approx(vals.mean(), rel=1e-8)
    else:
        # the epigraph starts at the worst condition: its constraints hold, the tightest is 0
        assert form.lifted_value(float(fv[0])) == pytest.approx(vals.max(), rel=1e-8)
        epi = gv[-4:]
        assert np.all(epi >= -1e-9) and np.min(epi) == pytest.approx(0.0, abs=1e-9)


def test_robust_fields_are_read_written_and_checked():
    data = problem_to_dict(load_problem(LOCALISE_PROBLEM))
    assert data["objective"]["robust_prior"] == [] and data["objective"]["robust_aggregate"]
    data["objective"]["robust_prior"] = [1, 5]
    assert problem_from_dict(data).objective.robust_prior == (1.0, 5.0)
    bad = {**data, "objective": {**data["objective"], "robust_prior": [1, -5]}}
    with pytest.raises(ProblemError, match="objective.robust_prior"):
        problem_from_dict(bad)
    bad = {**data, "objective": {**data["objective"], "robust_aggregate": "max"}}
    with pytest.raises(ProblemError, match="objective.robust_aggregate"):
        problem_from_dict(bad)
    bad = {**data, "objective": {**data["objective"], "kind": "gramian-min-eig"}}
    with pytest.raises(ProblemError, match="robust planning needs an estimator objective"):
        problem_from_dict(bad)
    bad = {**data, "validation": {**data["validation"], "stress_prior": 0}}
    with pytest.raises(ProblemError, match="validation.stress_prior"):
        problem_from_dict(bad)


def test_stress_validation_is_the_validation_of_the_scaled_problem(short_problem):
    assert not stress_active(short_problem)
    val = replace(short_problem.validation, stress_prior=5.0, stress_range_noise=3.0)
    pb = replace(short_problem, validation=val)
    assert stress_active(pb)
    paths = {k: b.trajectory for k, b in baselines(pb).items() if k in ("lawnmower", "circle")}
    rob = stress_validate(paths, pb, runs=3)
    direct = validate_paths(paths, scaled_problem(pb, 5.0, 3.0), runs=3)
    for k in paths:
        a, b = rob.validation[k].result.ekf, direct[k].result.ekf
        assert a.rmse_pos == b.rmse_pos and a.final_pos_err == b.final_pos_err
    d = rob.to_dict()
    assert d["prior"] == 5.0 and d["range_noise"] == 3.0 and set(d["validation"]) == set(paths)
    # a wider prior and noisier ranges: a larger error than under the nominal condition
    nominal = validate_paths(paths, pb, runs=3)
    assert rob.validation["circle"].result.ekf.rmse_pos > nominal["circle"].result.ekf.rmse_pos


def test_stress_channel_row_is_the_validation_in_that_channel(short_problem):
    """``validation.stress_channel`` re-validates every path with its ranges through the channel:
    the same numbers as validating the problem whose channel it is, pings lost and ranges
    rejected counted, the channel named in the report and the summary."""
    val = replace(short_problem.validation, stress_channel="at-sea")
    pb = replace(short_problem, validation=val)
    assert stress_active(pb)
    paths = {k: b.trajectory for k, b in baselines(pb).items() if k in ("lawnmower", "circle")}
    rob = stress_validate(paths, pb, runs=3)
    at_sea = replace(short_problem, validation=replace(short_problem.validation, channel="at-sea"))
    direct = validate_paths(paths, at_sea, runs=3)
    nominal = validate_paths(paths, pb, runs=3)
    for k in paths:
        a, b = rob.validation[k].result, direct[k].result
        assert a.ekf.rmse_pos == b.ekf.rmse_pos and a.ekf.final_pos_err == b.ekf.final_pos_err
        used = a.filter_dict("ekf")["ranges_used"]
        assert used < nominal[k].result.filter_dict("ekf")["ranges_used"]  # 20 % of pings lost
    d = rob.to_dict()
    assert d["channel"]["name"] == "at-sea" and d["channel"]["dropout"] == 0.2
    assert "channel at-sea" in rob.condition
    # the nominal problem is left as it was: no channel in its validation
    assert pb.validation.channel_model().is_ideal


def test_stress_channel_must_be_a_preset():
    data = problem_to_dict(load_problem(LOCALISE_PROBLEM))
    bad = {**data, "validation": {**data["validation"], "stress_channel": "stormy"}}
    with pytest.raises(ProblemError, match="validation.stress_channel"):
        problem_from_dict(bad)
    good = {**data, "validation": {**data["validation"], "stress_channel": "at-sea"}}
    pb = problem_from_dict(good)
    assert pb.validation.stress_channel == "at-sea"
    assert problem_from_dict(problem_to_dict(pb)).validation.stress_channel == "at-sea"
    assert "stress_channel" not in problem_to_dict(load_problem(LOCALISE_PROBLEM))["validation"]


def test_a_robust_plan_keeps_its_limits_in_every_condition(short_problem, lawnmower):
    """The keep-out margins of a robust problem are the largest over its conditions, each with
    that condition's prior and range noise and the vehicle's own (nominal) guidance: wider
    than the nominal ones where the wide prior is not yet forgotten."""
    pb = _robust(short_problem)
    g = validation_guidance(short_problem, at_sea=True)
    both = keepout_margins(lawnmower, pb)
    each = [condition_margins(lawnmower, c, g) for c in condition_problems(pb)]
    for name in ("range_points", "box", "accel_reserve", "speed"):
        want = np.max([getattr(m, name) for m in each], axis=0)
        np.testing.assert_allclose(getattr(both, name), want, rtol=1e-12)
    nominal = keepout_margins(lawnmower, short_problem)
    np.testing.assert_allclose(each[0].range_points, nominal.range_points, rtol=1e-12)
    assert np.max(both.range_points) > 2 * np.max(nominal.range_points)  # 5x the prior
