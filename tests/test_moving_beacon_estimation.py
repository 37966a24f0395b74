"""Estimation with a moving beacon (issue 46 item 3): the EKF, the augmented KF, the Gaussian sum,
the posterior CRB and the Monte Carlo (open and closed loop) ranging to a known ``BeaconPath``,
and ``obsplan simulate --beacon-path``."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.core.errors import ConfigError
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.epochs import SOUND_SPEED, epoch_beacons
from obsplan.estimation.montecarlo.guidance import Guidance
from obsplan.estimation.montecarlo.simulate import monte_carlo
from obsplan.estimation.montecarlo.stats import nees_bounds
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import make_model
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

T, DT, RUNS = 300.0, 0.5, 24
#: The vehicle: a straight line at constant speed (unobservable with a fixed beacon).
LINE = gen.straight((-150.0, 40.0), (1.0, 0.0), 1.0, duration=T).sample(DT)
KNOTS = np.arange(0.0, T + 1e-9, 2.0)  # a GPS log at 0.5 Hz


def _circling() -> BeaconPath:
    """A ship circling (radius 30 m, 1.5 m/s) about a point that keeps pace with the vehicle."""
    w = 1.5 / 30.0
    x = -150.0 + KNOTS + 30.0 * np.cos(w * KNOTS)
    return BeaconPath(KNOTS, np.column_stack([x, -20.0 + 30.0 * np.sin(w * KNOTS)]))


def _trailing() -> BeaconPath:
    """A ship trailing the vehicle at a constant offset: the relative position never changes."""
    p = LINE.p[:: int(2.0 / DT)]
    return BeaconPath(KNOTS, p + np.array([-40.0, -30.0]))


def _numbers(res) -> dict:
    d = res.to_dict()
    d.pop("wall_s")
    d.pop("config")
    return d


def _stats(res) -> dict:
    return {name: s for name, s in res.filter_stats().items()}


# ----------------------------------------------------------------------------- fixed = path
@pytest.mark.parametrize("dim,sensors", [(2, "range,dvl"), (3, "range,depth,dvl")])
def test_a_constant_path_is_the_fixed_beacon_bit_for_bit(dim, sensors):
    """A fixed beacon given as a constant BeaconPath: every filter, the truth's metrics and the
    PCRB are those of the model's fixed beacon, bit for bit (interpolating equal positions
    returns them exactly, and every relative displacement of the KF is an exact zero)."""
    b = (12.0, -9.0, 2.0)[:dim]
    traj = gen.circle(30.0, 1.5, 40.0, center=(0.0, 0.0, 10.0)[:dim]).sample(DT)
    fixed = EstimationConfig(model=make_model(dim, sensors, current=dim == 3, beacon=b))
    path = BeaconPath.fixed(b, 0.0, 40.0)
    moving = EstimationConfig(model=make_model(dim, sensors, current=dim == 3), beacon_path=path)
    kw = {"runs": 6, "seed": 3, "filters": ("ekf", "kf", "gsf")}
    assert _numbers(monte_carlo(traj, fixed, **kw)) == _numbers(monte_carlo(traj, moving, **kw))
    a, c = posterior_crlb(traj, fixed), posterior_crlb(traj, moving)
    assert np.array_equal(a.pos_std_t, c.pos_std_t) and np.array_equal(a.vel_std_t, c.vel_std_t)


def test_a_constant_path_is_the_fixed_beacon_in_closed_loop():
    traj = gen.circle(30.0, 1.5, 40.0).sample(DT)
    b = (12.0, -9.0)
    fixed = EstimationConfig(model=make_model(2, "range", beacon=b))
    moving = EstimationConfig(model=make_model(2, "range"), beacon_path=BeaconPath.fixed(b, 0, 40))
    kw = {"runs": 4, "seed": 5, "filters": ("ekf", "kf"), "guidance": Guidance.from_limits(0.05)}
    assert _numbers(monte_carlo(traj, fixed, **kw)) == _numbers(monte_carlo(traj, moving, **kw))


# ----------------------------------------------------------------------------- transmit time
def test_ranges_are_taken_to_the_beacon_at_transmission():
    """The beacon of a range received at ``t`` is the path's at ``t - r/c``."""
    t = np.array([0.0, 10.0, 20.0])
    path = BeaconPath(np.array([-5.0, 30.0]), np.array([[0.0, 0.0], [70.0, 0.0]]))  # 2 m/s
    p = np.array([[0.0, 1500.0], [20.0, 1500.0], [40.0, 1500.0]])
    model = make_model(2, "range")
    b = epoch_beacons(model, path, t, p)
    sent = t - np.linalg.norm(p - b, axis=1) / SOUND_SPEED
    assert np.allclose(b, path.position(sent), rtol=0, atol=1e-9)
    # about one second of travel at 1.5 km: the beacon is ~2 m behind its position at reception
    assert np.allclose(path.position(t)[:, 0] - b[:, 0], 2.0, atol=0.01)
    assert epoch_beacons(model, None, t, p).shape == (1, 2)


def test_a_path_that_does_not_cover_the_trajectory_is_refused():
    path = BeaconPath(np.array([0.0, 100.0]), np.zeros((2, 2)))
    cfg = EstimationConfig(model=make_model(2, "range"), beacon_path=path)
    with pytest.raises(ConfigError, match="beacon_path: covers t = 0..100 s"):
        monte_carlo(LINE, cfg, runs=1)
    back = pickle.loads(pickle.dumps(cfg))  # shipped to worker processes
    assert np.array_equal(back.beacon_path.positions, path.positions)
    with pytest.raises(ConfigError, match="replaces the model's fixed beacon"):
        EstimationConfig(model=make_model(2, "range", beacon=(1.0, 0.0)), beacon_path=path)
    with pytest.raises(ConfigError, match="3D but the model is 2D"):
        EstimationConfig(
            model=make_model(2, "range"), beacon_path=BeaconPath.fixed((0, 0, 0), 0, 1)
        )


def test_noise_free_filters_follow_the_truth_exactly():
    """No process noise, a 1 µm range noise, the exact start: the KF (relative coordinates, the
    beacon's motion as a known displacement) and the EKF stay on the truth within a millimetre
    (what the 1 µm noise leaves, as with a fixed beacon), ranges every 2 s and records in between
    (the KF's records add back the beacon of their epoch). Measured: KF 0.5 mm, EKF 0.06 mm RMS;
    without the KF's displacement of the table or of ``d``: 128 m and 89 m."""
    cfg = EstimationConfig(
        model=make_model(2, "range"),
        beacon_path=_circling(),
        rates_hz={"range": 0.5},
        noise={"range": 1e-6},
        init_error=np.zeros(4),
        process_noise=False,
    )
    res = monte_carlo(LINE, cfg, runs=2, seed=0, filters=("ekf", "kf"))
    for name, s in _stats(res).items():
        assert s.rmse_pos < 0.01 and s.final_vel_err < 1e-3, (name, s.rmse_pos)


# ----------------------------------------------------------------------------- observability
@pytest.fixture(scope="module")
def line_results():
    kw = {"runs": RUNS, "seed": 1, "filters": ("ekf", "kf", "gsf")}
    out = {}
    for name, path in (("circle", _circling()), ("trail", _trailing()), ("fixed", None)):
        model = make_model(2, "range", beacon=(0.0, -20.0) if path is None else None)
        cfg = EstimationConfig(model=model, beacon_path=path)
        out[name] = (monte_carlo(LINE, cfg, **kw), posterior_crlb(LINE, cfg))
    return out


def test_a_circling_beacon_makes_the_straight_line_observable(line_results):
    """The vehicle's straight constant-speed line, the beacon circling: the augmented KF and the
    Gaussian sum are consistent (run-averaged NEES inside its 95 % band at nearly every record)
    and accurate; the EKF (the paper's, from the wide prior) ends accurate; the PCRB is finite and
    decreases."""
    res, crb = line_results["circle"]
    st = _stats(res)
    for name in ("kf", "gsf"):
        assert st[name].nees_inside_fraction >= 0.95, (name, st[name].nees_inside_fraction)
        lo, hi = nees_bounds(RUNS, 4)
        assert lo < st[name].nees_mean < hi
        assert st[name].final_pos_err < 0.3 and st[name].converged_fraction == 1.0
    assert st["ekf"].final_pos_err < 0.5 and st["ekf"].diverged_runs == 0
    pcrb = crb.pos_std_t
    assert np.all(np.isfinite(pcrb))
    # down from the prior to the level the process noise keeps it at (it breathes with the
    # geometry within a lap of 126 s): bounded over the second half
    thirds = [float(np.mean(a)) for a in np.array_split(pcrb, 3)]
    assert thirds[0] > 3.0 * thirds[2], thirds
    assert pcrb[0] > pcrb[pcrb.size // 10] > 0.5 * np.max(pcrb[pcrb.size // 2 :])
    assert np.max(pcrb[pcrb.size // 2 :]) < 0.2
    assert pcrb[-1] < 0.1


def test_a_fixed_beacon_leaves_the_same_line_unobservable(line_results):
    """The same line with a fixed beacon: the KF cannot localise (its position std stays at
    tens of metres), the EKF is inconsistent, and the PCRB grows over the second half."""
    res, crb = line_results["fixed"]
    st = _stats(res)
    assert st["kf"].final_pos_std > 50.0
    assert st["ekf"].nees_inside_fraction < 0.5
    pcrb = crb.pos_std_t
    assert pcrb[-1] > 2.0 * pcrb[pcrb.size // 2]
    assert pcrb[-1] > 10.0 * line_results["circle"][1].pos_std_t[-1]


def test_a_trailing_beacon_never_fixes_the_position(line_results):
    """A beacon trailing at a constant offset: the range is constant, the position's PCRB does
    not converge (it grows with the process noise's random walk), and no filter converges."""
    res, crb = line_results["trail"]
    pcrb = crb.pos_std_t
    assert pcrb[-1] > 50.0 and pcrb[-1] > pcrb[pcrb.size // 2] > pcrb[pcrb.size // 10]
    st = _stats(res)
    assert st["kf"].final_pos_std > 50.0
    assert all(s.converged_fraction < 0.1 for s in st.values())


def test_closed_loop_with_a_moving_beacon():
    """Closed loop on the Gaussian sum: the vehicle keeps to its line and the filters converge."""
    cfg = EstimationConfig(model=make_model(2, "range"), beacon_path=_circling())
    res = monte_carlo(
        LINE, cfg, runs=8, seed=2, filters=("ekf", "kf", "gsf"), guidance=Guidance.from_limits(0.05)
    )
    st = _stats(res)
    assert st["gsf"].final_pos_err < 0.3 and st["kf"].final_pos_err < 0.3
    assert st["gsf"].nees_inside_fraction > 0.8
    assert res.truth.closest_range_m < 40.0  # measured against the moving beacon


def test_kf_refuses_a_beacon_changing_depth_with_a_depth_gauge():
    traj = gen.circle(30.0, 1.5, 20.0, center=(0.0, 0.0, 10.0)).sample(DT)
    knots = np.array([0.0, 20.0])
    path = BeaconPath(knots, np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 5.0]]))
    cfg = EstimationConfig(model=make_model(3, "range,depth"), beacon_path=path)
    with pytest.raises(ConfigError, match="constant depth"):
        monte_carlo(traj, cfg, runs=1, filters=("kf",))
    res = monte_carlo(traj, cfg, runs=2, filters=("ekf",))
    assert np.isfinite(_stats(res)["ekf"].final_pos_err)


# ----------------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("mb")
    traj = d / "line.csv"
    write_csv(gen.straight((-150.0, 40.0), (1.0, 0.0), 1.0, duration=60.0).sample(DT), traj)
    ship = d / "ship.csv"
    path = _circling()
    rows = [
        f"{float(t)!r},{float(x)!r},{float(y)!r}"
        for t, (x, y) in zip(path.times, path.positions, strict=True)
    ]
    ship.write_text("t,bx,by\n" + "\n".join(rows) + "\n")
    short = d / "short.csv"
    short.write_text("t,bx,by\n0,0,0\n30,10,0\n")
    problem = Path(__file__).resolve().parents[1] / "problems" / "default.toml"
    return {"traj": str(traj), "ship": str(ship), "short": str(short), "problem": str(problem)}


@pytest.mark.parametrize("loop", [["--open-loop"], ["--out", "{out}"]])
def test_cli_simulate_with_a_beacon_path(files, capsys, loop, tmp_path):
    """Open loop, and closed loop (the default) with its figures (the beacon's path drawn, the
    rank of the motion relative to it)."""
    argv = ["simulate", files["traj"], "--beacon-path", files["ship"], "--runs", "2", "--json"]
    assert main([*argv, *[a.format(out=tmp_path / "figs") for a in loop]]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["config"]["beacon_motion"] == "path"
    assert np.isfinite(d["crlb_final_pos_std"]) and d["ekf"]["final_pos_err"] >= 0.0
    if "--out" in loop:
        assert (tmp_path / "figs" / "estimation.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    "extra,needle",
    [
        (["--beacon-path", "{short}"], "--beacon-path"),
        (["--beacon-path", "{ship}", "--beacon", "1,2"], "not both"),
        (["--beacon-path", "{ship}", "--problem", "{problem}"], "the problem's [beacon]"),
    ],
)
def test_cli_simulate_refuses_a_bad_beacon_path(files, capsys, extra, needle):
    argv = ["simulate", files["traj"], "--runs", "2", "--open-loop"]
    argv += [a.format(**files) for a in extra]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "--beacon-path" in err and len(err.splitlines()) == 1, err
