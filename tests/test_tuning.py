"""The planner's tuning (obsplan.planning.tuning): its defaults are the values the planner used,
``tuned`` swaps it in for a block and restores it, invalid knobs are refused by name, and the
knobs are read at call time (cached results included)."""

from __future__ import annotations

import ast
from dataclasses import FrozenInstanceError, fields, replace
from pathlib import Path

import pytest

import obsplan.planning.tuning as tuning_module
from obsplan.core.errors import ConfigError, ProblemError
from obsplan.planning.missions.lawnmower import mission_lawnmower
from obsplan.planning.missions.schedule import mission_schedule, planner_schedule
from obsplan.planning.problem.parse import load_problem
from obsplan.planning.tuning import TUNING, Tuning, cache_per_tuning, tuned, tuning

#: Every knob and the value of the module constant it replaced (``margins.MAX_ROUNDS`` ...).
PLANNER_VALUES = {
    # solver/margins.py
    "max_rounds": 3,
    "continue_unconverged": 2,
    "margin_atol_m": 1e-2,
    "inflate": 0.1,
    "held_tol": 1e-6,
    "reserve_cap": 0.5,
    "reserve_atol": 0.01,
    "reserve_floor": 0.3,
    "box_share": 0.45,
    "start_reach_share": 0.5,
    "speed_atol": 1e-3,
    # missions/schedule.py, order.py, check.py
    "accel_use": 0.85,
    "lead_steps": 1.5,
    "accel_cycles": 2,
    "accel_amplitude": 0.9,
    "speed_grid": 24,
    "lead_in_speed_share": 0.5,
    "exact_lines": 10,
    "order_speeds": 13,
    "check_subsamples": 16,
    "coverage_bins": 1000,
    "check_rtol": 1e-6,
    # problem/feasibility.py, baselines/vehicle.py
    "limit_rtol": 1e-6,
    "consistency_tol": 1e-6,
    "lawnmower_speed_step": 0.03,
    "lawnmower_speed_tries": 11,
    "paper_max_oversampling": 50,
    # transcription/guesses.py, mission.py, solver/formulation.py
    "coarse_steps": 250,
    "flex_width": 0.1,
    "flex_sharpness": 20.0,
    "flex_relax_cross": 10.0,
    "flex_relax_vel": 3.0,
    "speed_eps": 1e-8,
    # objectives/windowed.py, lwo.py, linearisation.py, kf_guard.py
    "window_floor_rel": 1e-8,
    "min_window_samples": 10.0,
    "auto_stride_fraction": 1.0 / 8.0,
    "lwo_beta": 20.0,
    "lwo_ridge": 1e-9,
    "linearisation_penalty": 1.0,
    "guard_penalty": 100.0,
    # solver/ipopt.py (PROJECTION_TOL, WARM_START)
    "projection_tol": 1e-10,
    "warm_bound_push": 1e-9,
    "warm_bound_frac": 1e-9,
    "warm_mu_init": 1e-6,
    "lbfgs_history": 6,
    "monotone_epochs_per_step": 1.6,
    # validation/verdict.py
    "diverged_fraction": 0.1,
    "diverged_ratio": 3.0,
    "confidence": 0.95,
    "bootstrap": 2000,
    "stress_note_level": 0.3,
    "stress_note_runs": 1000,
    # replan.py
    "replan_batch": 5,
    "replan_tol_factor": 10.0,
    "replan_max_iter": 60,
}


def test_the_defaults_are_the_values_the_planner_used():
    t = Tuning()
    assert tuning() == t and TUNING == t
    assert {f.name for f in fields(Tuning)} == set(PLANNER_VALUES)
    for name, value in PLANNER_VALUES.items():
        # the same number of the same type (an int counts; a float's arithmetic stays float)
        assert getattr(t, name) == value and type(getattr(t, name)) is type(value), name
    # the lawn-mower's cruise-speed factors, float for float
    factors = tuple(1.0 - t.lawnmower_speed_step * i for i in range(t.lawnmower_speed_tries))
    assert factors == tuple(1.0 - 0.03 * i for i in range(11))
    # the warm start's IPOPT options, key for key
    from obsplan.planning.solver.ipopt import warm_start_options

    assert warm_start_options(False) == {"bound_push": 1e-9, "bound_frac": 1e-9, "mu_init": 1e-6}
    assert warm_start_options(True) == {"mu_init": 1e-6}


def test_tuned_swaps_the_tuning_in_for_a_block_and_restores_it():
    before = tuning()
    with tuned(max_rounds=5, reserve_floor=0.2) as t:
        assert tuning() is t and tuning_module.TUNING is t
        assert (t.max_rounds, t.reserve_floor) == (5, 0.2)
        assert t.reserve_cap == before.reserve_cap  # the others as they were
        with tuned(max_rounds=1):  # blocks nest: the inner one changes the outer one's tuning
            assert (tuning().max_rounds, tuning().reserve_floor) == (1, 0.2)
        assert tuning() is t
    assert tuning() is before
    # a whole Tuning, changed further
    base = replace(Tuning(), inflate=0.2)
    with tuned(base, box_share=0.3):
        assert (tuning().inflate, tuning().box_share) == (0.2, 0.3)
    assert tuning() is before


def test_tuned_restores_the_tuning_on_an_exception():
    before = tuning()
    with pytest.raises(RuntimeError, match="inside"), tuned(bootstrap=10):
        assert tuning().bootstrap == 10
        raise RuntimeError("inside")
    assert tuning() is before


def test_a_monkeypatched_tuning_is_the_one_in_force(monkeypatch):
    monkeypatch.setattr(tuning_module, "TUNING", replace(Tuning(), coarse_steps=100))
    assert tuning().coarse_steps == 100


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"held_tol": -1e-6}, "held_tol"),
        ({"margin_atol_m": float("nan")}, "margin_atol_m"),
        ({"reserve_floor": 1.5}, "reserve_floor"),
        ({"reserve_floor": 0.6}, "reserve_floor"),  # above the cap
        ({"box_share": 0.5}, "box_share"),
        ({"confidence": 1.0}, "confidence"),
        ({"max_rounds": -1}, "max_rounds"),
        ({"max_rounds": 2.5}, "max_rounds"),
        ({"bootstrap": 0}, "bootstrap"),
        ({"lwo_beta": 0.0}, "lwo_beta"),
        ({"accel_use": "0.85"}, "accel_use"),
        ({"speed_grid": True}, "speed_grid"),
    ],
)
def test_an_invalid_knob_raises_a_config_error_naming_it(changes, field):
    with pytest.raises(ConfigError, match=rf"Tuning\.{field}\b"):
        Tuning(**changes)
    before = tuning()
    with pytest.raises(ConfigError, match=rf"Tuning\.{field}\b"), tuned(**changes):
        pass  # never reached
    assert tuning() is before


def test_an_unknown_knob_is_refused_and_the_tuning_is_frozen():
    with pytest.raises(ConfigError, match=r"Tuning\.max_round\b"), tuned(max_round=5):
        pass  # never reached
    with pytest.raises(FrozenInstanceError):
        tuning().max_rounds = 5  # type: ignore[misc]


def test_a_cache_per_tuning_never_returns_a_result_of_another_tuning():
    calls = []

    @cache_per_tuning
    def share(x: float) -> float:
        calls.append(x)
        return x * tuning().box_share

    assert share(2.0) == 0.9 and share(2.0) == 0.9 and len(calls) == 1
    with tuned(box_share=0.25):
        assert share(2.0) == 0.5
    assert share(2.0) == 0.9 and len(calls) == 2  # the default's result, still cached


def test_the_schedule_reads_its_knobs_when_it_is_computed_cached_or_not():
    """``mission_schedule`` and ``planner_schedule`` are cached on their MissionContext: a
    schedule computed before a ``tuned`` block is not what the block sees, and is back after."""
    ctx = load_problem().mission_context
    base = mission_schedule(ctx)
    with tuned(lead_steps=3.0):
        longer = mission_schedule(ctx)
        # the run-in in planning steps at the line speed: twice as many steps
        assert longer.lead / longer.speed == pytest.approx(2 * base.lead / base.speed)
    with tuned(accel_use=1.0):  # tighter turns, a shorter mission: a slower line speed fits
        tighter = mission_schedule(ctx)
        assert tighter.end_s <= ctx.duration and tighter.speed < base.speed
    assert mission_schedule(ctx) is base  # the default's schedule, from the cache
    # the planner's lead-in: the share of the headroom its lines are scheduled at
    lead_in = planner_schedule(ctx).lead_in
    assert lead_in > 0
    with tuned(lead_in_speed_share=0.25):
        assert 0 < planner_schedule(ctx).lead_in < lead_in
    assert planner_schedule(ctx).lead_in == lead_in
    # the accelerated lawn-mower's sinusoid: with none of the headroom, there is none to fly
    accelerated = mission_lawnmower(ctx, accelerated=True)[0]
    with tuned(accel_amplitude=0.0), pytest.raises(ProblemError, match="no speed headroom"):
        mission_lawnmower(ctx, accelerated=True)
    assert (mission_lawnmower(ctx, accelerated=True)[0].p == accelerated.p).all()


def test_the_tuning_is_the_planning_stages_floor():
    """obsplan/planning/tuning.py imports the standard library and obsplan.core only (every room
    of planning may import it)."""
    tree = ast.parse(Path(tuning_module.__file__).read_text())
    imported = {
        name
        for node in ast.walk(tree)
        if isinstance(node, ast.Import | ast.ImportFrom)
        for name in (
            [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
        )
    }
    ours = {m for m in imported if m.split(".")[0] == "obsplan"}
    assert ours and all(m == "obsplan.core" or m.startswith("obsplan.core.") for m in ours)
