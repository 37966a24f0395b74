"""The parts of a sweep that need no cluster: sharded Monte Carlo merged exactly, and the study's
figures drawn from a results table (the fast tier; the Dask runs are in test_sweep_dask.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from obsplan.core.errors import InputError
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.montecarlo.simulate import monte_carlo
from obsplan.model.vehicle import make_model
from obsplan.sweeps.figures import DEFAULT_METRICS, plot_metric, study_figures
from obsplan.sweeps.montecarlo import shard_bounds, sharded_monte_carlo
from obsplan.trajectory import generators as gen


class InlineClient:
    """The three calls of a Dask client that sharded_monte_carlo makes, run in this process."""

    def __init__(self):
        self.submitted = []

    def scatter(self, items, broadcast=False):
        return list(items)

    def submit(self, fn, *args, pure=True, **kwargs):
        self.submitted.append(kwargs)
        return fn(*args, **kwargs)

    def gather(self, futures):
        return list(futures)


@pytest.mark.parametrize("runs, shards", [(1, 1), (7, 3), (10, 10), (3, 5), (100, 7)])
def test_shards_cover_the_runs_once_in_order_with_sizes_within_one(runs, shards):
    bounds = shard_bounds(runs, shards)
    starts = [s for s, _ in bounds]
    sizes = [k for _, k in bounds]
    assert sum(sizes) == runs and min(sizes) >= 1 and max(sizes) - min(sizes) <= 1
    assert starts == list(np.cumsum([0, *sizes[:-1]]))
    assert len(bounds) == min(runs, shards)


@pytest.mark.parametrize("runs, shards", [(0, 2), (3, 0), (-1, 1)])
def test_shard_bounds_refuse_empty_requests(runs, shards):
    with pytest.raises(InputError, match="at least 1"):
        shard_bounds(runs, shards)


def test_a_sharded_monte_carlo_equals_the_unsharded_one():
    traj = gen.circle(radius=40.0, speed=1.5, duration=60.0).sample(dt=0.1)
    config = EstimationConfig.paper(make_model(2, "range"), 0.1)
    whole = monte_carlo(traj, config, runs=6, seed=3, progress=False)
    client = InlineClient()
    merged = sharded_monte_carlo(traj, config, runs=6, seed=3, shards=4, client=client)
    assert [(c["run_start"], c["runs"]) for c in client.submitted] == shard_bounds(6, 4)
    for name in ("ekf", "kf"):
        a, b = getattr(whole, name), getattr(merged, name)
        # the statistics are merged from sums: equal to round-off, not to Monte Carlo noise
        assert b.rmse_pos == pytest.approx(a.rmse_pos, rel=1e-12)
        assert b.final_pos_err == pytest.approx(a.final_pos_err, rel=1e-12)
        assert b.nees_mean == pytest.approx(a.nees_mean, rel=1e-12)


def _table() -> pd.DataFrame:
    accel = [0.02, 0.05, 0.1, 0.02, 0.05, 0.1]
    kind = ["gramian-min-eig"] * 3 + ["pcrb-position"] * 3
    rows = {
        "task_id": [f"t{i}" for i in range(6)],
        "limits.accel [m/s^2]": accel,
        "objective.kind": kind,
        "metrics.planned.min_eig": [1e-4, 1e-3, 1e-2, 2e-4, 2e-3, 0.0],
        "metrics.lawnmower.min_eig": [5e-5, 5e-4, 5e-3, 5e-5, 5e-4, 5e-3],
        "validation.planned.ekf.rmse_pos": [0.5, 0.4, 0.3, 0.45, 0.35, np.nan],
        "validation.lawnmower.ekf.rmse_pos": [0.8, 0.7, 0.6, 0.8, 0.7, 0.6],
    }
    return pd.DataFrame(rows)


def test_a_metric_is_drawn_per_path_with_a_line_per_other_axis_and_missing_points_counted():
    fig = plot_metric(_table(), "min_eig", "limits.accel", others=["objective.kind"])
    axes = fig.axes
    assert [a.get_title().split(" (")[0] for a in axes] == ["planned", "lawnmower"]
    assert [len(a.lines) for a in axes] == [2, 2]  # one line per objective.kind
    assert axes[0].get_yscale() == "log"  # over decades; the rank-deficient 0 is not drawn
    assert "(1 of 6 points not drawn)" in axes[0].get_title()
    assert axes[0].get_xlabel() == "limits.accel [m/s^2]"


def test_study_figures_write_one_file_per_metric_and_varying_axis(tmp_path):
    written = study_figures(_table(), tmp_path, axes=["limits.accel", "objective.kind"], name="s")
    names = sorted(p.name for p in written)
    drawn = [m for m in DEFAULT_METRICS if m in ("min_eig", "ekf.rmse_pos")]
    assert len(names) == 2 * len(drawn)  # each metric the table has, against each axis
    assert "min_eig_vs_limits.accel.png" in names and "ekf.rmse_pos_vs_objective.kind.png" in names
    assert all(p.stat().st_size > 1000 and p.read_bytes()[:4] == b"\x89PNG" for p in written)
