"""Along which paths the range's scale and bias are observable
(:mod:`obsplan.observability.calibration`): the cases its docstring derives, a moving beacon,
unit invariance, the verdict's first time and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from obsplan import analyze
from obsplan.cli import main
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import make_model
from obsplan.observability.calibration import calibration_report
from obsplan.observability.scaling import Scales
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

LINE = gen.straight((-50.0, 20.0), (1.0, 0.0), 1.0, duration=100.0).sample(1.0)
CIRCLE_ABOUT = gen.circle(30.0, 1.5, 120.0).sample(1.0)
CIRCLE_OFF = gen.circle(30.0, 1.5, 120.0, center=(50.0, 0.0)).sample(1.0)
LAWNMOWER = gen.lawnmower((-40.0, -30.0), 80.0, 20.0, 4, 1.0).sample(1.0)


def _verdict(traj, sensors="range", current=False, **kw):
    return dict(
        calibration_report(traj, make_model(traj.dim, sensors, current=current), **kw).observable
    )


def test_straight_line_without_a_velocity_reference_has_no_scale():
    # k² rescales the quadratic under the range's square root: the start can do the same
    for sensors, current in (("range", False), ("range,dvl-water", True)):
        v = _verdict(LINE, sensors, current)
        assert v == {"scale": False, "bias": True, "scale_and_bias": False}, (sensors, current)


@pytest.mark.parametrize("sensors", ["range,dvl-bottom", "range,dvl-water"])
def test_straight_line_with_the_velocity_known_has_its_scale(sensors):
    # without a current either DVL gives |v|², and k² |v|² gives k
    assert _verdict(LINE, sensors) == {"scale": True, "bias": True, "scale_and_bias": True}


def test_circle_about_the_beacon_cannot_split_scale_and_bias():
    # a constant range: k R + β is one number (each alone: R from the known turn)
    for sensors in ("range", "range,dvl-bottom"):
        v = _verdict(CIRCLE_ABOUT, sensors)
        assert v == {"scale": True, "bias": True, "scale_and_bias": False}, sensors


@pytest.mark.parametrize("traj", [CIRCLE_OFF, LAWNMOWER], ids=["circle-off", "lawnmower"])
def test_turns_with_changing_range_separate_both(traj):
    assert _verdict(traj) == {"scale": True, "bias": True, "scale_and_bias": True}


def test_the_verdict_is_unit_invariant_and_its_first_time_is_monotone():
    a = calibration_report(LAWNMOWER, make_model(2, "range"))
    b = calibration_report(LAWNMOWER, make_model(2, "range"), scales=Scales(1000.0, 3600.0))
    assert a == b
    # both together need at least what each alone needs
    assert a.from_t["scale_and_bias"] >= max(a.from_t["scale"], a.from_t["bias"])
    assert a.state_rank == a.state_dim == 4
    # the first time is where it turns: on the path cut there it holds, one interval earlier not
    k = int(np.searchsorted(LAWNMOWER.t, a.from_t["scale"]))
    model = make_model(2, "range")
    assert calibration_report(LAWNMOWER.window(0, k + 1), model).observable["scale"]
    assert not calibration_report(LAWNMOWER.window(0, k), model).observable["scale"]


def test_a_circling_beacon_gives_a_straight_line_its_scale():
    # only the relative motion matters: a beacon circling ahead makes the line's ranges turn
    t = np.arange(0.0, 101.0, 1.0)
    th = 2 * np.pi * t / 50.0
    circling = BeaconPath(times=t, positions=np.c_[20.0 * np.cos(th), 20.0 * np.sin(th)])
    rep = analyze(LINE, "range", beacon_path=circling, calibration=True)
    assert rep.calibration is not None and rep.calibration.observable["scale"]
    assert not analyze(LINE, "range", calibration=True).calibration.observable["scale"]


def test_analyze_json_has_the_key_only_when_asked(tmp_path, capsys):
    f = tmp_path / "line.csv"
    write_csv(LINE, f)
    assert main(["analyze", str(f), "--json"]) == 0
    assert "range_calibration" not in json.loads(capsys.readouterr().out)
    assert main(["analyze", str(f), "--json", "--calibration", "--sensors", "range"]) == 0
    cal = json.loads(capsys.readouterr().out)["range_calibration"]
    assert cal["scale"] == {"observable": False, "from_t": None}
    assert cal["bias"]["observable"] and cal["bias"]["from_t"] > 0
    assert main(["analyze", str(f), "--calibration"]) == 0
    out = capsys.readouterr().out
    assert "range scale (sound speed): NOT observable" in out
    assert "range bias (clock offset): observable from t =" in out
