"""Waypoints: exact tracking errors, spacing, CSV and QGroundControl round trips, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.core.errors import InputError
from obsplan.io.waypoints import (
    leg_errors,
    read_qgc_plan,
    read_waypoints_csv,
    waypoints_from_trajectory,
    write_waypoints_csv,
)
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory, position_at, write_csv


def random_plan(seed: int = 0, dim: int = 2) -> Trajectory:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 120.0, 41)
    return Trajectory.from_inputs(t, rng.normal(0, 20, dim), rng.normal(0, 1, dim),
                                  rng.uniform(-0.05, 0.05, (41, dim)))  # fmt: skip


def sampled_errors(traj: Trajectory, ta: float, tb: float, n: int = 200_001):
    """Brute force: dense samples of the distance to the segment and to the scheduled point."""
    t = np.linspace(ta, tb, n)
    p = position_at(traj, t)
    a, b = position_at(traj, np.array([ta, tb]))
    d = b - a
    s = np.clip((p - a) @ d / (d @ d), 0.0, 1.0)
    cross = np.linalg.norm(p - (a + s[:, None] * d), axis=1).max()
    sched = np.linalg.norm(p - (a + ((t - ta) / (tb - ta))[:, None] * d), axis=1).max()
    return cross, sched


@pytest.mark.parametrize("dim", [2, 3])
def test_tracking_errors_are_exact(dim):
    traj = random_plan(1, dim)
    for ta, tb in [(0.0, 30.0), (12.5, 47.1), (60.0, 120.0), (3.0, 4.5)]:
        exact = leg_errors(traj, ta, tb)
        brute = sampled_errors(traj, ta, tb)
        # the exact maximum is never below the sampled one, and the sampled one converges to
        # it (grid of 2e5 points: error O(h²) of a smooth maximum, < 1e-6 m here)
        for e, s in zip(exact, brute, strict=True):
            assert e >= s - 1e-12 and e - s < 1e-6, (ta, tb, exact, brute)


def test_a_straight_plan_flown_straight_has_no_error():
    line = gen.straight([0.0, 0.0], [1.0, 0.5], float(np.hypot(1.0, 0.5)), duration=100.0)
    line = line.sample(1.0)
    wp = waypoints_from_trajectory(line, every=10.0)
    assert wp.max_cross_track < 1e-9 and wp.max_schedule_error < 1e-9
    np.testing.assert_allclose(wp.speed, np.hypot(1.0, 0.5))


def test_spacing_in_time_and_in_distance():
    circle = gen.circle(50.0, 2.0, 2 * np.pi * 50.0 / 2.0).sample(0.5)  # one lap, 157 s at 2 m/s
    wp = waypoints_from_trajectory(circle, every=10.0)
    np.testing.assert_allclose(np.diff(wp.t)[:-1], 10.0)
    assert wp.t[0] == circle.t[0] and wp.t[-1] == circle.t[-1]
    wp_m = waypoints_from_trajectory(circle, spacing=25.0)
    arcs = np.diff(wp_m.t)[:-1] * 2.0  # constant speed: arc length = speed x time
    np.testing.assert_allclose(arcs, 25.0, rtol=1e-4)
    # chord of a 25 m arc on a 50 m circle: sagitta r (1 - cos(θ/2)), θ = 0.5 rad
    assert wp_m.max_cross_track == pytest.approx(50.0 * (1 - np.cos(0.25)), rel=1e-3)
    with pytest.raises(InputError, match="exactly one of"):
        waypoints_from_trajectory(circle)
    with pytest.raises(InputError, match="more than"):
        waypoints_from_trajectory(circle, every=1e-6)


def test_waypoint_csv_round_trip(tmp_path):
    wp = waypoints_from_trajectory(random_plan(2, 3), every=7.0)
    path = write_waypoints_csv(wp, tmp_path / "wp.csv")
    back = read_waypoints_csv(path)
    np.testing.assert_array_equal(back["t"], wp.t)
    np.testing.assert_array_equal(np.c_[back["x"], back["y"], back["z"]], wp.p)
    np.testing.assert_array_equal(back["speed"], wp.speed)
    np.testing.assert_array_equal(back["leg_cross_track"][:-1], wp.cross_track)
    np.testing.assert_array_equal(back["leg_schedule_error"][:-1], wp.schedule_error)


def test_geodetic_waypoints_and_qgc_mission_round_trip(tmp_path):
    pytest.importorskip("pymap3d")
    from obsplan.model.frames import GeodeticOrigin, geodetic_to_local, local_to_geodetic

    origin = GeodeticOrigin(43.7, 10.3, 2.0)
    traj = random_plan(3, 3).translated([0.0, 0.0, 30.0])  # below the surface
    wp = waypoints_from_trajectory(traj, every=10.0, origin=origin)
    back = read_waypoints_csv(write_waypoints_csv(wp, tmp_path / "g.csv", geodetic=True))
    lat, lon, depth = local_to_geodetic(wp.p, origin)
    for col, ref in (("latitude", lat), ("longitude", lon), ("depth", depth)):
        np.testing.assert_array_equal(back[col], ref)
    np.testing.assert_allclose(
        geodetic_to_local(back["latitude"], back["longitude"], back["depth"], origin), wp.p,
        atol=1e-6,
    )  # fmt: skip

    from obsplan.io.waypoints import write_qgc_plan

    path = write_qgc_plan(wp, tmp_path / "m.plan", acceptance_radius=2.0)
    doc = json.loads(path.read_text())  # strict JSON: no NaN anywhere (yaw is null)
    assert doc["fileType"] == "Plan" and doc["version"] == 1
    mission = doc["mission"]
    assert mission["version"] == 2 and mission["firmwareType"] == 3
    assert mission["vehicleType"] == 12  # MAV_TYPE_SUBMARINE
    assert mission["plannedHomePosition"] == [43.7, 10.3, 2.0]
    nav = [it for it in mission["items"] if it["command"] == 16]
    assert len(nav) == len(wp)
    for it in mission["items"]:
        assert it["type"] == "SimpleItem" and len(it["params"]) == 7 and it["autoContinue"]
    assert [it["doJumpId"] for it in mission["items"]] == list(range(1, len(mission["items"]) + 1))
    first = nav[0]
    assert first["frame"] == 3 and first["params"][:4] == [0, 2.0, 0, None]
    assert first["Altitude"] == first["params"][6] == -depth[0]  # ArduSub: altitude = -depth
    q = read_qgc_plan(path)
    np.testing.assert_array_equal(q["latitude"], lat)
    np.testing.assert_array_equal(q["longitude"], lon)
    np.testing.assert_array_equal(q["altitude"], -depth)
    # each leg is flown at its speed (set by DO_CHANGE_SPEED before it)
    np.testing.assert_allclose(q["speed"][1:], wp.speed[:-1], atol=0.01)


def test_export_cli(tmp_path, capsys):
    pytest.importorskip("pymap3d")
    plan = write_csv(random_plan(4), tmp_path / "plan.csv")
    wp_csv, mission = tmp_path / "wp.csv", tmp_path / "m.plan"
    assert main(["export", str(plan), "--waypoints", str(wp_csv), "--every", "15"]) == 0
    out = capsys.readouterr().out
    assert "straight-line following leaves the planned path by at most" in out
    assert read_waypoints_csv(wp_csv)["t"][1] == 15.0
    # a mission needs an origin: refused before anything is written
    assert main(["export", str(plan), "--qgc", str(mission)]) == 2
    assert "--origin" in capsys.readouterr().err and not mission.exists()
    # --force never overwrites the plan itself
    assert main(["export", str(plan), "--waypoints", str(plan), "--force"]) == 2
    assert "is the input file" in capsys.readouterr().err
    # existing output: refused without --force, the user's file untouched
    assert main(["export", str(plan), "--waypoints", str(wp_csv)]) == 2
    assert "--force" in capsys.readouterr().err
    # the origin of report.json beside the plan (as `obsplan plan` writes it for a geodetic
    # problem) is used
    (tmp_path / "report.json").write_text(
        json.dumps({"origin": {"latitude": -33.9, "longitude": 151.2, "altitude": 0.0}})
    )
    args = ["export", str(plan), "--qgc", str(mission), "--spacing", "20", "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["origin"]["latitude"] == -33.9 and summary["spacing_m"] == 20.0
    assert read_qgc_plan(mission)["latitude"][0] == pytest.approx(-33.9, abs=1e-3)
    # --origin overrides it; negative values need no '='
    args = ["export", str(plan), "--waypoints", str(wp_csv), "--geodetic", "--force",
            "--origin", "-10.5,-20.25"]  # fmt: skip
    assert main(args) == 0
    assert read_waypoints_csv(wp_csv)["latitude"][0] == pytest.approx(-10.5, abs=1e-3)


def test_ctrl_c_while_exporting_leaves_no_partial_file(tmp_path, capsys, monkeypatch):
    plan = write_csv(random_plan(5), tmp_path / "plan.csv")
    import obsplan.core.csvtable as table

    real = table.csv.writer

    class Cut:
        def __init__(self, fh):
            self.w, self.n = real(fh), 0

        def writerow(self, row):
            self.n += 1
            if self.n == 3:
                raise KeyboardInterrupt
            self.w.writerow(row)

    monkeypatch.setattr(table.csv, "writer", Cut)
    assert main(["export", str(plan), "--waypoints", str(tmp_path / "wp.csv")]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.csv"]


@pytest.mark.parametrize("dim", [2, 3])
def test_export_a_planned_beacons_csv(tmp_path, capsys, dim):
    # a craft's path of piecewise-constant accelerations, written as obsplan plan writes
    # beacon.csv (samples at every change of acceleration and between): export reads the
    # accelerations back from the velocities and its waypoints lie on the path
    from obsplan.model.beacon import write_beacon_csv

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 200.0, 81)
    a = np.zeros((t.size, dim))
    a[:, :2] = rng.uniform(-0.1, 0.1, (t.size, 2))
    craft = Trajectory.from_inputs(t, np.array([10.0, -5.0, 0.0][:dim]), np.zeros(dim), a)
    beacon = write_beacon_csv(tmp_path / "beacon.csv", craft.t, craft.p, craft.v)
    wp_csv = tmp_path / "wp.csv"
    # every 7 s: most waypoints fall between samples, where the accelerations read back matter
    args = ["export", str(beacon), "--waypoints", str(wp_csv), "--every", "7"]
    assert main(args) == 0
    assert "warning" not in capsys.readouterr().err  # the accelerations reproduce the samples
    wp = read_waypoints_csv(wp_csv)
    axes = ("x", "y", "z")[:dim]
    # waypoints are samples of the exact path: to round-off of the CSV's 17 digits
    np.testing.assert_allclose(
        np.column_stack([wp[c] for c in axes]), position_at(craft, wp["t"]), atol=1e-9
    )
    # and the QGC mission of the craft (at the surface in 2D: --depth defaults to 0)
    mission = tmp_path / "craft.plan"
    assert main(["export", str(beacon), "--qgc", str(mission), "--origin", "43.0,5.0"]) == 0
    assert read_qgc_plan(mission)["latitude"].size > 0


def test_export_refuses_a_beacon_csv_without_velocities(tmp_path, capsys):
    path = tmp_path / "beacon.csv"
    path.write_text("t,bx,by\n0,0,0\n10,1,1\n")
    assert main(["export", str(path), "--waypoints", str(tmp_path / "wp.csv")]) == 2
    assert "vbx" in capsys.readouterr().err
