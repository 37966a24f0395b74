"""The EKF's linearisation stress and the planner's penalty on it (linearisation_bound)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from obsplan.core.errors import ProblemError
from obsplan.planning import load_problem
from obsplan.planning.objectives.linearisation import linearisation_stress
from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict
from obsplan.planning.problem.schema import LINEARISATION_BOUND
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.planning.solver.formulation import build_formulation
from obsplan.planning.solver.ipopt import _hessian_without_penalty
from obsplan.planning.solver.solve import solve
from obsplan.planning.transcription.guesses import reference_path
from obsplan.trajectory.sampled import Trajectory

ROOT = Path(__file__).resolve().parents[1]
OFFSET = ROOT / "problems/suite/gramian-offset-beacon.toml"


def _objective(pb, **fields):
    return replace(pb, objective=replace(pb.objective, **fields))


def test_stress_of_a_vehicle_at_rest_is_the_closed_form():
    # At rest the range row is the line of sight, always the same: with an isotropic prior and
    # process noise the covariance across it never sees an update and grows as
    # P_tt(t) = σ_p² + σ_v² t² + q t³ / 3 (white acceleration of intensity q), so
    # b / σ_r = P_tt / (2 r σ_r) at every range epoch.
    pb = load_problem(OFFSET)
    cfg = estimation_config(pb)
    P0 = np.asarray(cfg.covariances(pb.validation.dt)["p0_ekf"])
    sp2, sv2 = P0[0, 0], P0[2, 2]
    assert (
        np.allclose(np.diag(P0), [sp2, sp2, sv2, sv2])
        and np.count_nonzero(P0 - np.diag(np.diag(P0))) == 0
    )
    q = pb.validation.accel_noise**2
    assert np.allclose(pb.v0, 0.0)
    t = np.linspace(0.0, pb.horizon.duration, pb.horizon.steps + 1)
    z = np.zeros((t.size, 2))
    rest = Trajectory(t=t, p=np.tile(pb.p0, (t.size, 1)), v=z, u=z)
    b = linearisation_stress(rest, pb)
    tr = np.arange(1, b.size + 1) / pb.validation.range_rate  # range epochs after the first
    assert tr[-1] == pytest.approx(pb.horizon.duration)
    r = float(np.linalg.norm(pb.p0 - np.asarray(pb.beacon)))
    expected = (sp2 + sv2 * tr**2 + q * tr**3 / 3.0) / (2.0 * r * pb.validation.range_std)
    # the recursion's exact discretisation against the closed form: round-off only
    np.testing.assert_allclose(b, expected, rtol=1e-9)


def test_default_bound_applies_to_log_det_weighted_by_information():
    me = load_problem(OFFSET)  # gramian-min-eig: off (its plans lost more with it)
    assert me.objective.resolved_linearisation_bound == 0.0
    pb = _objective(me, kind="gramian-log-det")
    assert pb.objective.resolved_linearisation_bound == LINEARISATION_BOUND
    # the paper's forms and the estimator objectives are left as they were
    assert _objective(pb, weights="none").objective.resolved_linearisation_bound == 0.0
    pcrb = _objective(pb, kind="pcrb-position", weights="information")
    assert pcrb.objective.resolved_linearisation_bound == 0.0
    assert _objective(pcrb, linearisation_bound=0.3).objective.resolved_linearisation_bound == 0.3
    # off: no penalty in the NLP; on: a penalty, not an objective term
    small = replace(pb, horizon=Horizon(600.0, 12))
    off = build_formulation(_objective(small, linearisation_bound=0.0))
    on = build_formulation(small)
    assert off.penalty.is_constant() and not on.penalty.is_constant()
    assert on.w.numel() == off.w.numel() and on.g.numel() == off.g.numel()
    # lwo-condition (exact Hessian) only when asked, and then with its exact Hessian without the
    # penalty's (the recursion's is dense)
    lwo = _objective(small, kind="lwo-condition")
    assert lwo.objective.resolved_linearisation_bound == 0.0
    assert build_formulation(lwo).hessian == "exact"
    asked = build_formulation(_objective(lwo, linearisation_bound=0.25))
    assert asked.hessian == "exact-without-penalty" and not asked.penalty.is_constant()


@pytest.mark.slow
def test_the_solver_hessian_is_the_unbounded_problems():
    # IPOPT gets the exact Hessian of the Lagrangian without the penalty's curvature: the same
    # matrix, to round-off, as the unbounded formulation's (same variables and constraints).
    # A bound of 0.01 σ_r is active on the lawn-mower, so the penalty's curvature is not zero there.
    lwo = load_problem(ROOT / "problems/suite/lwo-offset-beacon.toml")
    pb = _objective(replace(lwo, horizon=Horizon(600.0, 12)), linearisation_bound=0.01)
    on = build_formulation(pb)
    off = build_formulation(_objective(pb, linearisation_bound=0.0))
    assert on.hessian == "exact-without-penalty" and off.hessian == "exact"
    rng = np.random.default_rng(0)
    x = on.pack(reference_path(pb)) + 1e-3 * rng.standard_normal(on.w.numel())
    assert on.penalty_value(x) > 0
    lam_g = rng.standard_normal(on.g.numel())
    lam_f, lam = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", on.g.numel())

    def triu_hessian(form, f):
        lag = lam_f * f + ca.dot(lam, form.g)
        fn = ca.Function("h", [form.w, lam_f, lam], [ca.triu(ca.hessian(lag, form.w)[0])])
        return np.asarray(ca.DM(fn(x, 0.7, lam_g)))

    ours = _hessian_without_penalty(on, expand=True)
    H_ours = np.asarray(ca.DM(ours(x, on.parameter_values, 0.7, lam_g)))
    H_off, H_full = triu_hessian(off, off.f), triu_hessian(on, on.f)
    scale = np.abs(H_off).max()
    # double round-off on entries of order max |H|
    np.testing.assert_allclose(H_ours, H_off, rtol=0, atol=1e-12 * scale)
    assert np.abs(H_full - H_off).max() > 1e-6 * scale


@pytest.mark.parametrize("value", [-0.1, float("nan"), float("inf")])
def test_a_bad_bound_names_its_field(value):
    d = problem_to_dict(load_problem(OFFSET))
    d["objective"]["linearisation_bound"] = value
    with pytest.raises(ProblemError, match="objective.linearisation_bound"):
        problem_from_dict(d)


def test_the_bound_round_trips():
    pb = _objective(load_problem(OFFSET), linearisation_bound=0.4)
    assert problem_from_dict(problem_to_dict(pb)) == pb


@pytest.mark.slow
def test_the_penalty_keeps_a_log_det_plan_off_the_line_of_sight():
    # 0.2 Hz ranges, the start 100 m from the beacon: unbounded, the log-det plan closes on the
    # beacon along the line of sight (b about 0.5 σ_r at N = 200; at N = 200 such plans lost the
    # EKF on 8 of 1000 closed-loop runs); bounded, it turns across the line of sight sooner.
    pb = load_problem(ROOT / "problems/suite/gramian-slow-range.toml")
    pb = _objective(pb, kind="gramian-log-det", starts=2)
    free = solve(_objective(pb, linearisation_bound=0.0), processes=1)
    bounded = solve(pb, processes=1)
    kappa = LINEARISATION_BOUND
    b_free = linearisation_stress(free.trajectory, pb).max()
    b_bounded = linearisation_stress(bounded.trajectory, pb).max()
    assert b_free > 1.5 * kappa, "the unbounded plan no longer stresses the EKF: pick another"
    # a quadratic penalty leaves a residual; 20 % of the bound is far below the unbounded excess
    assert b_bounded <= 1.2 * kappa
    # the solver's value is the objective's, the penalty taken out
    if bounded.best_start is not None:
        assert bounded.lifted_objective == pytest.approx(bounded.objective, rel=1e-9)
