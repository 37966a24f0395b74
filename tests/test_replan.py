"""Receding-horizon replanning: the shrinking-horizon re-solve, the replanned Monte Carlo, CLI."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.core.errors import ConfigError
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.estimation.montecarlo.simulate import DEFAULT_FILTERS
from obsplan.planning.objectives.evaluate import better
from obsplan.planning.problem.feasibility import check_limits
from obsplan.planning.problem.parse import LOCALISE_PROBLEM, PROBLEMS_DIR, load_problem
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.problem.validation_setup import estimation_config, truth_limits
from obsplan.planning.replan import (
    Replanner,
    recovery_steps,
    replan_guidance,
    replan_monte_carlo,
    replan_nodes,
    return_inputs,
    state_for_planner,
)
from obsplan.planning.solver.solve import solve
from obsplan.trajectory.sampled import Trajectory, resample

SMALL = ["--steps", "20", "--starts", "1", "--runs", "2", "--quiet"]


@pytest.fixture(scope="module")
def small():
    """The free localisation problem on a coarse grid (N = 40, 15 s steps), its one-shot plan,
    and the replanner built once."""
    pb = load_problem(LOCALISE_PROBLEM)
    pb = replace(pb, horizon=Horizon(duration=600.0, steps=40))
    pb = replace(pb, objective=replace(pb.objective, starts=1))
    res = solve(pb, processes=1)
    assert res.trajectory is not None and res.success
    return pb, res, Replanner(pb)


@pytest.mark.parametrize("every", [7.0, 0.0, -60.0, math.nan, math.inf, 600.0, 900.0])
def test_bad_every_is_an_input_error_naming_the_option(small, every):
    pb, _, _ = small
    with pytest.raises(ConfigError, match="--replan"):
        replan_nodes(pb, every)


def test_replan_nodes_are_multiples_of_every_before_the_end(small):
    pb, _, _ = small
    k = replan_nodes(pb, 120.0)  # 15 s steps: every 8 nodes
    assert list(k) == [8, 16, 24, 32]


def test_resolve_from_the_exact_plan_state_reproduces_the_plan(small):
    pb, res, rp = small
    plan = res.trajectory
    for k in (8, 20, 32):
        state = np.concatenate([plan.p[k], plan.v[k]])
        out, new = rp.resolve(plan, k, state)
        assert out.success, out.status
        np.testing.assert_allclose(new.p[: k + 1], plan.p[: k + 1], atol=1e-9)
        # never worse than the plan in force; the one-shot plan's remaining part is kept
        # unless the re-solve found a strictly better one (then within its tolerance of it)
        assert not better(res.objective, out.objective, pb)
        if out.kept_warm_start:
            np.testing.assert_allclose(new.p, plan.p, atol=1e-9)
        else:
            assert out.objective == pytest.approx(res.objective, rel=1e-3)


def test_resolve_from_a_perturbed_estimate_keeps_the_past_and_the_limits(small):
    pb, res, rp = small
    plan = res.trajectory
    rng = np.random.default_rng(3)
    n = pb.dim
    for k in (4, 12, 24, 36):
        state = np.concatenate([plan.p[k], plan.v[k]])
        state[:n] += rng.normal(0.0, 1.0, n)
        state[n:] += rng.normal(0.0, 0.02, n)
        out, new = rp.resolve(plan, k, state)
        assert out.success, out.status
        np.testing.assert_allclose(new.u[:k], plan.u[:k], atol=1e-12)  # the past is not redone
        np.testing.assert_allclose(new.p[k], state[:n], atol=1e-9)  # it starts at the estimate
        np.testing.assert_allclose(new.v[k], state[n:], atol=1e-9)
        assert np.all(np.abs(new.u[k:-1]) <= pb.accel * (1 + 1e-6))
        after = min(k + recovery_steps(pb) + 1, pb.horizon.steps - 1)
        assert replace(check_limits(new.window(after), pb), start=0.0).ok()
        # the remaining path is dynamically consistent (exact double integrator)
        assert max(new.window(k).consistency_error()) < 1e-6


@pytest.mark.parametrize("dim", [2, 3])
def test_return_inputs_join_the_plan_in_the_window_with_least_energy(dim):
    pb = load_problem(PROBLEMS_DIR / "suite/gramian-depth3d.toml" if dim == 3 else LOCALISE_PROBLEM)
    n, h = pb.dim, 3.0
    F, G = pb.model.transition(h)
    F, G = F[: 2 * n, : 2 * n], G[: 2 * n]
    rng = np.random.default_rng(5)
    error = np.concatenate([rng.normal(0.0, 1.0, n), rng.normal(0.0, 0.02, n)])
    c = return_inputs(F, G, error, 7, 20)
    assert c.shape == (20, n)
    np.testing.assert_array_equal(c[7:], 0.0)
    # integrated exactly from the error, the corrections land on the plan at step 7 and stay
    off = Trajectory.from_inputs(np.arange(21) * h, error[:n], error[n:], c)
    np.testing.assert_allclose(off.p[7:], 0.0, atol=1e-9)
    np.testing.assert_allclose(off.v[7:], 0.0, atol=1e-12)
    # least energy: any other sequence that joins in 7 steps (plus a null-space move) costs more
    C = np.hstack([np.linalg.matrix_power(F, 6 - i) @ G for i in range(7)])
    null = np.linalg.svd(C)[2][-1]
    other = c[:7].reshape(-1) + 0.01 * null
    np.testing.assert_allclose(C @ other, C @ c[:7].reshape(-1), atol=1e-12)
    assert np.sum(other**2) > np.sum(c[:7] ** 2)
    # on the plan there is nothing to correct; one step left: the closest it can get
    np.testing.assert_array_equal(return_inputs(F, G, np.zeros(2 * n), 7, 20), 0.0)
    assert return_inputs(F, G, error, 7, 1).shape == (1, n)


def test_warm_guess_flies_on_from_the_estimate_back_onto_the_plan_in_force(small):
    pb, res, rp = small
    plan = res.trajectory
    n, k = pb.dim, 12
    state = np.concatenate([plan.p[k] + 0.8, plan.v[k] - 0.03])
    guess = rp.warm_guess(plan, k, state)
    np.testing.assert_array_equal(guess.p[:k], plan.p[:k])
    np.testing.assert_allclose(guess.p[k], state[:n], atol=1e-12)
    np.testing.assert_allclose(guess.v[k], state[n:], atol=1e-12)
    # joined within the recovery window (at least 2 steps): the plan in force after it, where
    # re-integrating the plan's inputs would carry the velocity offset to the end
    j = k + max(2, recovery_steps(pb))
    np.testing.assert_allclose(guess.p[j:], plan.p[j:], atol=1e-9)
    np.testing.assert_allclose(guess.v[j:], plan.v[j:], atol=1e-12)
    assert max(guess.window(k).consistency_error()) < 1e-6


def test_state_for_planner_adds_the_current_to_the_water_velocity():
    pb = load_problem(PROBLEMS_DIR / "range-dvl-water-current2d.toml")
    est = np.array([1.0, 2.0, 0.3, -0.1, 0.05, 0.02])
    np.testing.assert_allclose(state_for_planner(pb, est), [1.0, 2.0, 0.35, -0.08])


def test_replanned_monte_carlo_is_paired_and_reported(small):
    pb, res, rp = small
    out = replan_monte_carlo(pb, res.trajectory, 150.0, runs=2, replanner=rp, processes=1)
    assert len(out.solves) == 2 * 3  # runs x replans at 150, 300, 450 s
    assert out.times == (150.0, 300.0, 450.0)
    assert set(out.validation) == {"replanned", "one-shot"}
    for v in out.validation.values():
        assert v.result.runs == 2 and v.result.seed == pb.validation.seed
        # the guidance saturates the applied inputs at the acceleration limit
        assert np.all(v.result.truth.accel_ratio_runs <= 1 + 1e-9)
    doc = json.loads(json.dumps(out.to_dict(), allow_nan=False))
    assert doc["solves"] == 6 and doc["failures"] == out.failures
    assert doc["solve_s"]["max"] >= doc["solve_s"]["median"] > 0
    assert "one-shot" in doc["verdict"]["baselines"]
    assert set(doc["verdict"]["baselines"]["one-shot"]) == {
        "ekf.rmse_pos",
        "ekf.final_pos_err",
        "kf.rmse_pos",
        "kf.final_pos_err",
    }
    assert out.summary()[0].startswith("replanning every 150 s: 6 re-solves")


def test_clairvoyant_replanner_starts_from_the_truth_not_the_estimate(small, monkeypatch):
    """``replan_from="truth"`` (the research bound) re-solves from the true state; the default
    from the navigation filter's estimate. Both are checked against a closed loop flown
    independently to the first replan (nothing differs before it: same runs, seed, plan)."""
    pb, res, rp = small
    seen: dict[str, list] = {}
    resolve = rp.resolve

    def recording(source):
        def call(plan, k, state, run=0):
            seen.setdefault(source, []).append((k, run, np.array(state)))
            return resolve(plan, k, state, run=run)

        return call

    for source in ("estimate", "truth"):
        monkeypatch.setattr(rp, "resolve", recording(source))
        replan_monte_carlo(
            pb, res.trajectory, 300.0, runs=2, replanner=rp, processes=1, replan_from=source
        )
    loop = ClosedLoop(
        resample(res.trajectory, pb.validation.dt),
        estimation_config(pb),
        2,
        pb.validation.seed,
        0,
        guidance=replan_guidance(pb),
        limits=truth_limits(pb),
        filters=DEFAULT_FILTERS,
    )
    loop.advance(300.0)
    snap = loop.snapshot()
    for source, known in (("estimate", snap.estimate), ("truth", snap.truth)):
        first = [(run, x) for k, run, x in seen[source] if k == replan_nodes(pb, 300.0)[0]]
        assert [run for run, _ in first] == [0, 1]
        for run, x in first:
            np.testing.assert_allclose(x, state_for_planner(pb, known[run]), rtol=0, atol=1e-12)
    # the two differ by the filter's error (a run with an exact estimate would make this vacuous)
    assert np.min(np.abs(snap.estimate[:, : pb.dim] - snap.truth[:, : pb.dim])) > 1e-6
    with pytest.raises(ConfigError, match="replan_from"):
        replan_monte_carlo(pb, res.trajectory, 300.0, runs=1, replanner=rp, replan_from="plan")


@pytest.mark.slow
def test_cli_replan_flag_writes_the_replan_report(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["plan", str(LOCALISE_PROBLEM), "--out", str(out), *SMALL, "--replan", "120"]) == 0
    rep = json.loads((out / "report.json").read_text())
    r = rep["replan"]
    assert r["every_s"] == 120.0 and r["solves"] == 2 * 4
    assert {"replanned", "one-shot", "lawnmower", "circle"} <= set(r["validation"])
    assert "replanning every 120 s" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra",
    [
        ["--replan", "7"],
        ["--replan", "-30"],
        ["--replan", "600"],
        ["--replan", "60", "--no-validate"],
    ],
)
def test_cli_bad_replan_exits_2(tmp_path, capsys, extra):
    code = main(["plan", str(LOCALISE_PROBLEM), "--out", str(tmp_path / "o"), *SMALL, *extra])
    assert code == 2
    assert "--replan" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_replan_not_a_number_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:  # argparse's own usage error
        main(["plan", str(LOCALISE_PROBLEM), "--out", str(tmp_path / "o"), *SMALL, "--replan", "x"])
    assert exc.value.code == 2
    assert "--replan" in capsys.readouterr().err
