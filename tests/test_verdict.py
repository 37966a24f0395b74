"""Verdicts with confidence: paired bootstrap intervals of the ratio, decided or tie, runs added
in batches until decided (merged exactly)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.objectives.evaluate import path_metrics
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.transcription.guesses import reference_path
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.validate import validate_paths
from obsplan.planning.validation.verdict import (
    RUN_METRICS,
    Comparison,
    Verdict,
    limit_notes,
    ratio_interval,
    stress_notes,
    validate_until_decided,
    verdict,
)


def test_interval_of_a_clear_win_excludes_one_and_is_seeded():
    rng = np.random.default_rng(3)
    b = rng.lognormal(0.0, 0.5, 200)
    a = 0.5 * b * rng.lognormal(0.0, 0.1, 200)  # paired: the plan halves every run's error
    lo, hi = ratio_interval(a, b, seed=1)
    assert lo < a.mean() / b.mean() < hi < 1.0
    assert ratio_interval(a, b, seed=1) == (lo, hi)
    assert ratio_interval(a, b, seed=2) != (lo, hi)


def test_noise_alone_is_a_tie():
    """Two independent draws of the same distribution: the interval contains 1."""
    rng = np.random.default_rng(0)
    a, b = rng.exponential(1.0, 50), rng.exponential(1.0, 50)
    lo, hi = ratio_interval(a, b, seed=0)
    assert lo < 1.0 < hi
    c = Comparison("ekf.final_pos_err", float(a.mean()), float(b.mean()), ci=(lo, hi))
    assert not c.decided and c.outcome == "tie"


@pytest.mark.parametrize(
    "planned,baseline,ci,decided,outcome",
    [
        (1.0, 2.0, (0.4, 0.6), True, "better"),
        (1.0, 2.0, (0.4, 1.1), False, "tie"),
        (2.0, 1.0, (1.5, 2.5), True, "worse"),
        # the interval of the per-run means disagrees with the reported values: not decided
        (1.0, 2.0, (1.1, 1.3), False, "tie"),
        (None, 1.0, None, True, "worse"),  # the plan's filter diverged
        (1.0, None, None, True, "better"),
        (1.0, 2.0, None, False, "tie"),  # no interval (e.g. a non-finite run)
    ],
)
def test_decided_means_the_interval_excludes_one_on_the_side_of_better(
    planned, baseline, ci, decided, outcome
):
    c = Comparison("ekf.rmse_pos", planned, baseline, ci=ci)
    assert c.decided is decided and c.outcome == outcome
    d = c.to_dict()
    assert d["decided"] is decided and d["ci"] == (None if ci is None else list(ci))


def test_missing_or_unpaired_runs_have_no_interval():
    a = np.ones(5)
    assert ratio_interval(None, a) is None
    assert ratio_interval(a, np.ones(4)) is None
    assert ratio_interval(a, np.array([1, 1, np.nan, 1, 1.0])) is None
    assert ratio_interval(a[:1], a[:1]) is None


def test_the_summary_says_beats_only_when_every_lead_is_decided():
    """Ahead on every metric with an undecided lead is not "beats": the words say ahead, and
    name the tie."""
    won = Comparison("ekf.final_pos_err", 1.0, 2.0, ci=(0.4, 0.6))
    lead = Comparison("ekf.rmse_pos", 1.0, 1.1, ci=(0.8, 1.2))
    decided = Verdict({"lawnmower": {"ekf.final_pos_err": won}}, {}, runs=50).summary()
    assert decided[0] == "the plan beats every validated baseline on every metric"
    tied = Verdict(
        {"lawnmower": {"ekf.final_pos_err": won, "ekf.rmse_pos": lead}}, {}, runs=50
    ).summary()
    assert "beats" not in tied[0] and "not decidedly on the ties below" in tied[0]
    assert any("EKF position RMSE" in line and "[0.80, 1.20]" in line for line in tied[1:])


def test_the_summary_calls_a_metric_not_won_a_loss_only_when_decided():
    """Behind on the mean inside the interval is a tie, not a loss: the words say which."""
    won = Comparison("ekf.final_pos_err", 1.0, 2.0, ci=(0.4, 0.6))
    lost = Comparison("ekf.rmse_pos", 1.2, 1.0, ci=(1.1, 1.3))
    behind = Comparison("kf.rmse_pos", 1.05, 1.0, ci=(0.9, 1.2))
    lines = Verdict(
        {"lawnmower": {"ekf.final_pos_err": won, "ekf.rmse_pos": lost, "kf.rmse_pos": behind}},
        {},
        runs=50,
    ).summary()
    assert "does NOT beat" in lines[0] and lines[0].endswith("it does not win here:")
    loss = [x for x in lines if "EKF position RMSE" in x][0]
    assert loss.startswith("  - ") and loss.endswith(", a loss")
    tie = [x for x in lines if "KF position RMSE" in x and "EKF" not in x][0]
    assert tie.endswith(", a tie")
    assert not any("EKF final" in x for x in lines[1:])  # a decided win is not listed


def test_a_decided_loss_is_not_also_called_within_the_noise():
    """Two standard errors of the mean difference and the bootstrap interval of the ratio can
    disagree at the margin; the words follow the interval (what ``decided`` reports) alone."""
    lost = Comparison("ekf.final_pos_err", 1.0001, 1.0, noise=0.001, ci=(1.00001, 1.0002))
    tied = Comparison("kf.final_pos_err", 1.0001, 1.0, noise=0.001, ci=(0.999, 1.001))
    assert lost.within_noise and tied.within_noise  # the premise: 2 SE call both noise
    lines = Verdict(
        {"one-shot": {"ekf.final_pos_err": lost, "kf.final_pos_err": tied}}, {}, runs=200
    ).losses()
    loss = [x for x in lines if "EKF final" in x][0]
    tie = [x for x in lines if "KF final" in x and "EKF" not in x][0]
    assert loss.endswith(", a loss") and "Monte Carlo noise" not in loss
    assert tie.endswith("within the Monte Carlo noise (+-0.001 m), a tie")


@pytest.fixture(scope="module")
def short(short_problem):
    pb = short_problem
    bls = baselines(pb)
    return pb, {"planned": bls["circle"].trajectory, "lawnmower": bls["lawnmower"].trajectory}


def test_batches_until_decided_merge_exactly(short):
    """Runs 2, 4, 8 (doubling) stop when every run-estimated verdict is decided or at the cap;
    the merged batches are exactly one validation of as many runs."""
    pb, paths = short
    val = validate_until_decided(paths, pb, runs=2, max_runs=8)
    n = val["planned"].result.runs
    assert n in (2, 4, 8)
    v = verdict(val, {})
    assert v.runs == n
    if n < 8:
        assert v.all_decided
    one = validate_paths(paths, pb, runs=n)
    for name in paths:
        for f in ("ekf", "kf"):
            np.testing.assert_array_equal(
                getattr(val[name].result, f).final_pos_err_runs,
                getattr(one[name].result, f).final_pos_err_runs,
            )
        np.testing.assert_array_equal(
            val[name].result.truth.closest_range_runs, one[name].result.truth.closest_range_runs
        )
    for comps in v.comparisons.values():
        for key in RUN_METRICS:
            assert comps[key].ci is not None
    d = v.to_dict()
    assert d["confidence"] == 0.95 and d["runs"] == n
    assert len(d["ties"]) == sum(
        not c.decided for cs in v.comparisons.values() for c in cs.values()
    )


def test_one_batch_when_the_cap_is_the_first_batch(short):
    pb, paths = short
    val = validate_until_decided(paths, pb, runs=3, max_runs=1)
    assert val["planned"].result.runs == 3


def test_rmse_interval_is_about_the_reported_ratio(short):
    """Every interval contains its verdict's reported ratio (the RMSE's is carried from the ratio
    of the runs' RMS to the reported time-averaged one)."""
    pb, paths = short
    v = verdict(validate_paths(paths, pb, runs=6), {})
    for comps in v.comparisons.values():
        for key in RUN_METRICS:
            c = comps[key]
            assert c.ci[0] <= c.ratio <= c.ci[1], (key, c)


def test_rms_interval_of_squares():
    rng = np.random.default_rng(5)
    b = rng.lognormal(0.0, 0.3, 100)
    a = 0.7 * b
    lo, hi = ratio_interval(a, b, seed=0, rms=True)
    assert lo == pytest.approx(0.7) and hi == pytest.approx(0.7)


def test_a_stressed_plan_is_warned_of_losses_too_rare_for_its_runs():
    pb = load_problem(LOCALISE_PROBLEM)
    pb = replace(pb, horizon=Horizon(pb.horizon.duration, 40))
    m = path_metrics(reference_path(pb), pb)

    def paths(plan: float, *others: float):
        out = {"planned": replace(m, ekf_linearisation_stress=plan)}
        out.update({f"b{i}": replace(m, ekf_linearisation_stress=x) for i, x in enumerate(others)})
        return out

    (note,) = stress_notes(paths(0.45, 0.24, 0.2, 0.8, float("nan")), 50)
    assert "0.45" in note and "b1's at 0.20" in note and "50 runs" in note
    # enough runs to see a loss in a few hundred; below the level; every baseline as stressed;
    # no stress at all (no range epoch after the first); nothing to compare with
    assert stress_notes(paths(0.45, 0.2), tuning().stress_note_runs) == ()
    assert stress_notes(paths(tuning().stress_note_level, 0.2), 50) == ()
    assert stress_notes(paths(0.45, 0.5, 0.45), 50) == ()
    assert stress_notes(paths(float("nan"), 0.2), 50) == ()
    assert stress_notes(paths(0.45), 50) == ()
    assert stress_notes({}, 50) == ()


def test_a_baseline_that_wins_by_breaking_the_limits_the_plan_keeps_is_named(short):
    """The note names a baseline the plan does not beat whose true paths broke a limit more often
    than the keep-out allows (one-sided binomial test at 95 %) and more often than the plan's;
    never one the plan beats on every run metric, nor without margins (confidence 0); and the
    plan itself when its own true paths break a limit that often."""
    pb, paths = short
    val = validate_paths(paths, pb, runs=6)

    def breaking(name: str, runs: int):
        r = val[name].result
        t = r.truth
        speed = np.full(t.runs, 0.5 * t.limits.speed)
        speed[:runs] = 1.01 * t.limits.speed  # 1 % over the bound on the first runs
        return replace(val[name], result=replace(r, truth=replace(t, max_speed_runs=speed)))

    def comps(plan_wins: bool) -> dict:
        win = Comparison("ekf.rmse_pos", 1.0, 2.0, None, (0.4, 0.6))
        loss = Comparison("ekf.rmse_pos", 2.0, 1.0, None, (1.8, 2.2))
        return {"lawnmower": {"ekf.rmse_pos": win if plan_wins else loss}}

    def notes(val, conf: float, plan_wins: bool = False) -> tuple[str, ...]:
        clean = {"planned": breaking("planned", 0), "lawnmower": val["lawnmower"]}
        return limit_notes({**clean, **val}, comps(plan_wins), conf)

    three = {"lawnmower": breaking("lawnmower", 3)}
    (note,) = notes(three, 0.9)  # 3 of 6 at an allowed share of 0.1: P = 0.016
    assert note.startswith("the lawnmower's true path broke a limit on 50.0 % of the runs")
    assert "speed in 50.0 % (by up to 0.01 m/s)" in note and "the plan's on 0.0 %" in note
    assert "limits.keepout_confidence = 0.9, the lawnmower is flown" in note
    assert notes({"lawnmower": breaking("lawnmower", 1)}, 0.9) == ()  # 1 of 6: P = 0.47
    assert notes({"lawnmower": breaking("lawnmower", 1)}, 0.999) != ()  # P = 0.006
    assert notes(three, 0.9, plan_wins=True) == ()
    assert notes(three, 0.0) == ()
    as_often = {**three, "planned": breaking("planned", 3)}
    (mine,) = notes(as_often, 0.9)  # the plan's own breaks, not the baseline's
    assert mine.startswith("the plan's true path broke a limit on 50.0 % of the runs (speed")
    assert "more often than limits.keepout_confidence = 0.9 allows" in mine
    one = {"planned": breaking("planned", 1), "lawnmower": breaking("lawnmower", 0)}
    assert notes(one, 0.9) == ()  # 1 of 6: P = 0.47
    # through verdict(): said after the other notes, and only with the plan's confidence
    val3 = {"planned": breaking("planned", 0), "lawnmower": breaking("lawnmower", 3)}
    loses = any(not c.better for c in verdict(val3, {}).comparisons["lawnmower"].values())
    said = verdict(val3, {}, keepout_confidence=0.9).notes
    assert (len(said) == 1) == loses
    assert verdict(val3, {}).notes == ()
