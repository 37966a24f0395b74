"""A ping schedule from a log (``validation.range_times``, ``EstimationConfig.range_times``):
where the ranges report, that the Monte Carlo, the bound and the planner's epochs follow it, and
the problem file's errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from obsplan import EstimationConfig, make_model, monte_carlo
from obsplan.core.errors import ConfigError, ProblemError
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.schedule import make_schedule
from obsplan.planning.problem.parse import load_problem
from obsplan.planning.problem.validation_setup import estimation_config, filter_epochs
from obsplan.trajectory import generators as gen

TRAJ = gen.circle(30.0, 1.5, 60.0).sample(0.1)
MODEL = make_model(2, "range")


def test_pings_report_at_the_first_sample_at_or_after_them():
    times = np.array([0.0, 0.1, 0.15, 0.17, 2.0, 7.04, 59.95, 75.0])
    col = make_schedule(TRAJ, ("range",), {}, times).reports("range")
    # 0 and 0.1 on their samples; 0.15 and 0.17 both on 0.2 (one report); 7.04 on 7.1;
    # 59.95 on 60.0; 75 s is after the path: not flown
    assert np.flatnonzero(col).tolist() == [0, 1, 2, 20, 71, 600]


def test_a_periodic_schedule_is_the_rate_and_the_monte_carlo_is_the_same():
    """Pings every second given as times schedule exactly as ``range_rate = 1``: the Monte
    Carlo's numbers are identical (same seeds, same epochs)."""
    rate = EstimationConfig(MODEL, rates_hz={"range": 1.0})
    times = EstimationConfig(MODEL, rates_hz={"range": 1.0}, range_times=np.arange(1.0, 61.0))
    np.testing.assert_array_equal(rate.schedule(TRAJ).mask, times.schedule(TRAJ).mask)
    a = monte_carlo(TRAJ, rate, runs=8, seed=3).to_dict()
    b = monte_carlo(TRAJ, times, runs=8, seed=3).to_dict()
    assert a["ekf"] == b["ekf"] and a["kf"] == b["kf"]


def test_the_bound_follows_the_schedule():
    # the same number of pings, all in the first half: the bound at the end is larger (the
    # second half is dead reckoning) than with them spread over the path
    spread = EstimationConfig(MODEL, range_times=np.arange(1.0, 61.0, 2.0))
    early = EstimationConfig(MODEL, range_times=np.arange(1.0, 31.0, 1.0))
    assert spread.schedule(TRAJ).reports("range").sum() == 31
    assert early.schedule(TRAJ).reports("range").sum() == 31
    b_spread, b_early = posterior_crlb(TRAJ, spread), posterior_crlb(TRAJ, early)
    assert b_early.final_pos_std > b_spread.final_pos_std
    i = int(np.searchsorted(TRAJ.t, 30.0))  # while the early pings come, they bound it better
    assert b_early.pos_std_t[i] < b_spread.pos_std_t[i]


@pytest.mark.parametrize("bad", [[], [1.0, 1.0], [2.0, 1.0], [0.0, np.nan]])
def test_config_refuses_a_bad_schedule(bad):
    with pytest.raises(ConfigError, match="range_times"):
        EstimationConfig(MODEL, range_times=np.array(bad, float))


def _problem(tmp_path, rows: str, rate: float):
    """The default problem with a ping schedule of ``rows`` beside it and ``range_rate``."""
    (tmp_path / "pings.csv").write_text(rows)
    src = load_problem("default").to_toml()
    src = src.replace("[validation]\n", '[validation]\nrange_times = "pings.csv"\n', 1)
    src = src.replace("range_rate = 1.0", f"range_rate = {rate}")
    f = tmp_path / "p.toml"
    f.write_text(src)
    return f


def test_problem_file_schedule_reaches_the_planner_and_the_validation(tmp_path):
    pb0 = load_problem("default")
    T = pb0.horizon.duration
    times = np.arange(0.0, T, 10.0) + 3.0  # every 10 s, 3 s after the periods' starts
    f = _problem(tmp_path, "t\n" + "\n".join(f"{t:g}" for t in times) + "\n", 0.1)
    pb = load_problem(f)
    assert pb.validation.range_times == str(tmp_path / "pings.csv")  # resolved beside the file
    np.testing.assert_array_equal(pb.range_times, times)
    cfg = estimation_config(pb)
    np.testing.assert_array_equal(cfg.range_times, times)
    ep = filter_epochs(pb)  # the planner's epochs: the filter steps at the pings (and the ends)
    t_ep = pb.filter_times[ep.index]
    for t in times[times <= T]:
        assert np.any(np.isclose(t_ep, t)), t
    # the problem written back keeps the field (relative names become absolute ones)
    assert "range_times" in pb.to_toml()


def test_problem_file_errors_name_the_field(tmp_path):
    pb0 = load_problem("default")
    T = pb0.horizon.duration
    with pytest.raises(ProblemError, match="validation.range_times.*header must contain t"):
        load_problem(_problem(tmp_path, "time\n1\n2\n", 1.0))
    with pytest.raises(ProblemError, match="validation.range_times.*first ping is at t = -1"):
        load_problem(_problem(tmp_path, "t\n-1\n2\n", 1.0))
    with pytest.raises(ProblemError, match="validation.range_times.*1 ping"):
        load_problem(_problem(tmp_path, f"t\n1\n{T + 5}\n", 1.0))
    rows = "t\n" + "\n".join(f"{t:g}" for t in np.arange(1.0, T, 10.0)) + "\n"
    with pytest.raises(ProblemError, match="validation.range_rate.*set range_rate = 0.1"):
        load_problem(_problem(tmp_path, rows, 1.0))


def test_cli_simulate_range_times(tmp_path, capsys):
    from obsplan.cli import main
    from obsplan.trajectory.sampled import write_csv

    traj = tmp_path / "c.csv"
    write_csv(TRAJ, traj)
    pings = tmp_path / "pings.csv"
    pings.write_text("t\n" + "\n".join(str(t) for t in range(3, 60, 7)) + "\n")
    args = ["simulate", str(traj), "--runs", "4", "--quiet", "--json"]
    assert main([*args, "--range-times", str(pings)]) == 0
    sched = json.loads(capsys.readouterr().out)
    assert main(args) == 0  # every sample: another schedule, other numbers
    every = json.loads(capsys.readouterr().out)
    assert sched["ekf"]["final_pos_std"] > every["ekf"]["final_pos_std"]
    assert main([*args, "--range-times", str(pings), "--problem", "default"]) == 2
    assert "--range-times cannot be combined with --problem" in capsys.readouterr().err
