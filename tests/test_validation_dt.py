"""The validation's bounds do not depend on its filter step (physical process noise), and the
paper's per-step preset does (its intensity grows with the step)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.objectives.evaluate import path_metrics
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.validation_setup import estimation_config
from obsplan.trajectory.sampled import resample

STEPS = (0.05, 0.1, 0.5)


def _bounds(pb, paths, model: str) -> dict[float, dict[str, tuple[float, float]]]:
    """Per filter step: per path, the validation's final bound and the planner's [m]."""
    out = {}
    for dt in STEPS:
        p = replace(pb, validation=replace(pb.validation, dt=dt, process_noise_model=model))
        cfg = estimation_config(p)
        out[dt] = {
            name: (
                posterior_crlb(resample(tr, dt), cfg).final_pos_std,
                path_metrics(tr, p).pcrb_final_pos_std,
            )
            for name, tr in paths.items()
        }
    return out


@pytest.fixture(scope="module")
def default_paths():
    pb = load_problem(LOCALISE_PROBLEM)
    bls = baselines(pb)
    return pb, {
        k: bls[k].trajectory for k in ("lawnmower", "circle", "paper-lawnmower") if k in bls
    }


def test_final_bounds_within_2_percent_for_dt_005_01_05(default_paths):
    pb, paths = default_paths
    b = _bounds(pb, paths, "physical")
    for name in paths:
        for i in (0, 1):  # the validation's posterior CRB, the planner's objective bound
            vals = [b[dt][name][i] for dt in STEPS]
            assert max(vals) / min(vals) - 1 < 0.02, (name, i, vals)
        # the planner's bound is the validation's
        assert b[0.1][name][1] == pytest.approx(b[0.1][name][0], rel=1e-6)


def test_the_paper_preset_changes_with_the_step(default_paths):
    """The paper's Q = (1e-3 dt)^2 per step: at dt 0.5 s its intensity is 5x that at 0.1 s, and
    the lawn-mower's final bound grows by more than the 2 % the physical noise keeps."""
    pb, paths = default_paths
    b = _bounds(pb, {"lawnmower": paths["lawnmower"]}, "paper-per-step")
    assert b[0.5]["lawnmower"][0] > 1.02 * b[0.1]["lawnmower"][0]
