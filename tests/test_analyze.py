"""obsplan.analyze: both verdicts, PRODUCT keys, lawn-mower first full-rank time, edge cases."""

from __future__ import annotations

import json

import numpy as np
import pytest

import obsplan
from obsplan import ObservabilityReport, analyze
from obsplan.core.errors import ConfigError, InputError
from obsplan.model.vehicle import make_model
from obsplan.observability.gramian import rank_over_time
from obsplan.observability.scaling import Scales
from obsplan.trajectory.sampled import Trajectory

PRODUCT_KEYS = {
    "lwo": {"along_trajectory", "full_rank_fraction", "min_rank", "state_dim"},
    "gramian": {
        "full_rank",
        "rank",
        "dim",
        "full_rank_from_t",
        "min_eig",
        "log_det",
        "condition",
    },
}


def lawnmower(legs=3, leg=40.0, speed=1.0, radius=5.0, dt=0.25, p0=(-20.0, -30.0)):
    """Straight legs at constant speed (u = 0) joined by half-turns; returns (traj, turn starts)."""
    n_leg = round(leg / speed / dt)
    n_turn = round(np.pi * radius / speed / dt)
    w = speed / radius
    us, turns, heading = [], [], 0.0
    for i in range(legs):
        us += [np.zeros(2)] * n_leg
        if i == legs - 1:
            break
        turns.append(len(us) * dt)
        s = 1.0 if np.cos(heading) > 0 else -1.0  # always turn towards +y
        for k in range(n_turn):
            th = heading + s * w * (k + 0.5) * dt
            us.append(speed * s * w * np.array([-np.sin(th), np.cos(th)]))
        heading += s * np.pi
    u = np.array(us)
    t = np.arange(len(u) + 1) * dt
    return Trajectory.from_inputs(t, np.array(p0), np.array([speed, 0.0]), u), turns


def test_lawnmower_shape():
    tr, _ = lawnmower()
    assert tr.p[-1, 1] == pytest.approx(-10.0, abs=2.0)  # three legs ~10 m apart (ZOH turns)
    assert tr.p[:, 0].max() < 27 and tr.p[:, 0].min() > -27


def test_keys_are_exactly_the_product_keys():
    tr, _ = lawnmower()
    d = analyze(tr).to_dict()
    assert set(d) == {"dim", "sensors", "current", "lwo", "gramian"}
    assert set(d["lwo"]) == PRODUCT_KEYS["lwo"]
    # the stable keys, plus the exact structural keys beside them (observability/structural.py)
    exact = {"rank_tol", "rank_exact", "full_rank_interval_exact", "full_rank_from_t_exact"}
    assert set(d["gramian"]) == PRODUCT_KEYS["gramian"] | exact
    assert d["dim"] == 2 and d["sensors"] == ["range"] and d["current"] is False
    json.dumps(d, allow_nan=False)  # strict JSON: no NaN/inf anywhere


def test_lawnmower_verdicts_and_first_full_rank_time():
    """Constant-velocity legs: Gramian rank 2 (d = 0) until the first turn starts; the change of
    acceleration there makes it full within 0.5 s (measured: t = 40.5 s, turn at 40 s).
    LWO: O loses rank on the legs (null input, section 5.1), so not along the whole path."""
    tr, turns = lawnmower()
    rep = analyze(tr, sensors="range")
    g = rep.gramian
    assert g.full_rank and g.rank == g.dim == 6
    assert turns[0] < g.full_rank_from_t <= turns[0] + 1.0
    ranks = rank_over_time(tr, make_model(2))
    k = int(np.flatnonzero(tr.t == g.full_rank_from_t)[0])
    assert ranks[k] == 6 and np.all(ranks[:k] < 6)
    assert np.all(ranks[1 : int(turns[0] / 0.25)] == 2)
    assert not rep.lwo.along_trajectory and rep.lwo.min_rank == 3
    assert 0.2 < rep.lwo.full_rank_fraction < 0.5  # the turns' share of the samples
    dvl = analyze(tr, sensors=["range", "dvl"])
    assert dvl.lwo.along_trajectory and dvl.sensors == ("range", "dvl-bottom")


def test_sensors_as_string_current_and_beacon():
    tr, _ = lawnmower()
    rep = analyze(tr, "range,dvl-water", current=True, beacon=(1.0, 2.0))
    assert isinstance(rep, ObservabilityReport)
    assert rep.gramian.dim == 8 and rep.lwo.state_dim == 6
    bottom = analyze(tr, "range,dvl-bottom", current=True)
    assert not bottom.gramian.full_rank and bottom.gramian.rank <= 6
    assert not bottom.lwo.along_trajectory


def test_scales_change_metrics_not_verdicts():
    tr, _ = lawnmower()
    a = analyze(tr)
    b = analyze(tr, scales=Scales(length_m=10.0, time_s=5.0))
    assert (a.gramian.rank, a.gramian.full_rank_from_t) == (
        b.gramian.rank,
        b.gramian.full_rank_from_t,
    )
    assert a.lwo == b.lwo
    assert a.gramian.min_eig != b.gramian.min_eig


@pytest.mark.parametrize("range_form", ["half-squared", "range"])
def test_beacon_on_the_path_gives_a_verdict(range_form):
    """The lawn-mower passes exactly over a beacon placed on one of its samples."""
    tr, _ = lawnmower()
    rep = analyze(tr, beacon=tuple(tr.p[10]), range_form=range_form)
    d = rep.to_dict()
    json.dumps(d, allow_nan=False)
    assert rep.lwo.ranks[10] < 4 and not d["lwo"]["along_trajectory"]
    assert d["gramian"] == analyze(tr).to_dict()["gramian"]  # the Gramian ignores the beacon


def test_bad_inputs():
    tr, _ = lawnmower()
    with pytest.raises(ConfigError, match="unknown sensor 'sonar'"):
        analyze(tr, "range,sonar")
    with pytest.raises(ConfigError, match="beacon must be 2 finite"):
        analyze(tr, beacon=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="needs dim = 3"):
        analyze(tr, "range,depth")
    with pytest.raises(InputError, match="must be an obsplan Trajectory"):
        analyze(np.zeros((3, 7)))  # type: ignore[arg-type]


def test_package_exports():
    assert obsplan.analyze is analyze and "analyze" in obsplan.__all__
