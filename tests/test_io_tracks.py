"""Logged tracks: readers (CSV, ROS bags, MAVLink logs), the fit of the inputs, refusals, CLI."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

from obsplan.cli import main
from obsplan.core.errors import InputError, TrajectoryFormatError
from obsplan.io.tracks import Track, TrackFitError, fit_track, read_track_csv
from obsplan.trajectory.sampled import Trajectory, read_csv, resample, write_csv

NOISE_M = 0.05  # the acceptance case: 5 cm position noise at 1 Hz


def known_plan() -> Trajectory:
    """A plan-like path from known inputs: 3 s holds over 600 s within |u| <= 0.05 m/s², from
    the default problem's start (-80, 60) m at rest."""
    tc = np.linspace(0.0, 600.0, 201)
    u = 0.05 * np.c_[np.sin(2 * np.pi * tc / 150), np.cos(2 * np.pi * tc / 220)]
    return Trajectory.from_inputs(tc, [-80.0, 60.0], [0.0, 0.0], u)


def noisy_positions(traj: Trajectory, seed: int, drop: float = 0.0, jitter: float = 0.0):
    """1 Hz positions of ``traj`` with 5 cm noise; optionally dropped samples and jittered
    (irregular) times, the exact positions at the jittered times."""
    from obsplan.trajectory.sampled import position_at

    rng = np.random.default_rng(seed)
    t = np.arange(traj.t[0], traj.t[-1] + 1e-9, 1.0)
    if jitter:
        t[1:-1] += rng.uniform(-jitter, jitter, t.size - 2)
    keep = np.r_[True, rng.random(t.size - 2) >= drop, True]
    t = t[keep]
    return t, position_at(traj, t) + rng.normal(0.0, NOISE_M, (t.size, traj.dim))


def true_inputs_at(traj: Trajectory, t: np.ndarray) -> np.ndarray:
    k = np.searchsorted(traj.t, t, side="right") - 1
    return traj.u[np.clip(k, 0, traj.n_samples - 1)]


def write_track(path: Path, t, p, v=None, sep=",") -> Path:
    cols = ["t", "px", "py", "pz"][: 1 + p.shape[1]]
    if v is not None:
        cols += ["vx", "vy", "vz"][: p.shape[1]]
    rows = [sep.join(cols)]
    data = np.column_stack([t, p] + ([v] if v is not None else []))
    rows += [sep.join(repr(float(x)) for x in r) for r in data]
    path.write_text("\n".join(rows) + "\n")
    return path


# ------------------------------------------------------------------------- the acceptance case
def test_known_inputs_import_within_the_stated_error_and_keep_the_verdicts(tmp_path, capsys):
    """Positions only, 5 cm noise, 1 Hz: the accelerations come back within the stated error
    (the posterior std, per axis) and analyze gives the original's verdicts."""
    plan = known_plan()
    write_csv(plan, tmp_path / "original.csv")
    t, y = noisy_positions(plan, seed=0)
    write_track(tmp_path / "log.csv", t, y)
    assert main(["import", str(tmp_path / "log.csv"), "--out", str(tmp_path / "fit.csv")]) == 0
    assert "position residual RMS" in capsys.readouterr().out
    fit = fit_track(read_track_csv(tmp_path / "log.csv"))
    fitted = read_csv(tmp_path / "fit.csv")
    np.testing.assert_array_equal(fitted.u, fit.trajectory.u)  # the file is the fit
    err = fitted.u[:-1] - true_inputs_at(plan, fitted.t[:-1])
    rms = np.sqrt(np.mean(err**2, axis=0))
    # stated error = the median posterior std of u; measured RMS/std 0.5-0.7 on seeds 0-7
    assert np.all(rms <= np.array(fit.accel_std)), (rms, fit.accel_std)
    assert np.all(np.array(fit.accel_std) < 0.01)  # and it is small against |u| <= 0.05
    # the noise is estimated, and the residual is the noise (not over- or under-fitted)
    np.testing.assert_allclose(fit.position_std, NOISE_M, rtol=0.3)
    np.testing.assert_allclose(fit.residual_rms, NOISE_M, rtol=0.2)

    reports = []
    for name in ("original.csv", "fit.csv"):
        assert main(["analyze", str(tmp_path / name), "--json"]) == 0
        reports.append(json.loads(capsys.readouterr().out))
    a, b = reports
    assert a["lwo"]["along_trajectory"] == b["lwo"]["along_trajectory"] is True
    assert a["lwo"]["min_rank"] == b["lwo"]["min_rank"]
    assert a["gramian"]["full_rank"] == b["gramian"]["full_rank"] is True
    assert a["gramian"]["rank"] == b["gramian"]["rank"]
    # the excitation metric itself is close (within 25 %: the fit smooths the input steps)
    assert abs(b["gramian"]["min_eig"] / a["gramian"]["min_eig"] - 1) < 0.25


@pytest.mark.parametrize("drop,jitter", [(0.2, 0.0), (0.0, 0.3), (0.2, 0.3)])
def test_dropped_samples_and_irregular_times(drop, jitter):
    plan = known_plan()
    t, y = noisy_positions(plan, seed=1, drop=drop, jitter=jitter)
    fit = fit_track(Track(t=t, p=y))
    err = fit.trajectory.u[:-1] - true_inputs_at(plan, fit.trajectory.t[:-1])
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) <= np.array(fit.accel_std))
    assert np.all(np.isin(t, fit.trajectory.t))  # a node at every sample (+ some in gaps)
    # the output is an exact double-integrator path
    pe, ve = fit.trajectory.consistency_error()
    assert pe < 1e-6 and ve < 1e-9


def test_gaps_are_bridged_with_extra_nodes_or_refused():
    plan = known_plan()
    t, y = noisy_positions(plan, seed=2)
    keep = (t <= 200) | (t >= 216)  # a 16 s gap in a 1 Hz log
    fit = fit_track(Track(t=t[keep], p=y[keep]))
    assert fit.inserted == 15  # nodes every second inside the gap, so u may change there
    err = fit.trajectory.u[:-1] - true_inputs_at(plan, fit.trajectory.t[:-1])
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) <= np.array(fit.accel_std))
    with pytest.raises(TrackFitError, match=r"gap of 16 s .* --max-gap"):
        fit_track(Track(t=t[keep], p=y[keep]), max_gap=10.0)
    keep = (t <= 200) | (t >= 261)  # 61 s: more than 30 median intervals
    with pytest.raises(TrackFitError, match=r"gap of 61 s between samples 200 and 201.*split"):
        fit_track(Track(t=t[keep], p=y[keep]))


def test_grid_holds_the_inputs_on_the_plan_grid():
    plan = known_plan()
    t, y = noisy_positions(plan, seed=3, jitter=0.3)
    fit = fit_track(Track(t=t, p=y), grid=3.0)
    np.testing.assert_allclose(fit.trajectory.t, plan.t, atol=1e-9)  # rows on the 3 s grid
    err = fit.trajectory.u[:-1] - plan.u[:-1]
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) <= np.array(fit.accel_std))
    # so `simulate --dt 0.1` can resample it (0.1 s divides 3 s)
    assert resample(fit.trajectory, 0.1).n_samples == 6001


def test_velocities_and_depth_are_used_in_3d():
    tc = np.linspace(0.0, 300.0, 101)
    u = np.c_[0.04 * np.sin(tc / 30), 0.04 * np.cos(tc / 40), 0.01 * np.sin(tc / 25)]
    truth = Trajectory.from_inputs(tc, [10.0, -20.0, 5.0], [0.5, 0.0, 0.0], u)
    fine = resample(truth, 0.5)
    rng = np.random.default_rng(4)
    y = fine.p + rng.normal(0, NOISE_M, fine.p.shape)
    w = fine.v + rng.normal(0, 0.01, fine.v.shape)
    without = fit_track(Track(t=fine.t, p=y))
    with_v = fit_track(Track(t=fine.t, p=y, v=w), velocity_std=0.01)
    # logged velocities (1 cm/s) pin the accelerations down better (measured ratio 0.66)
    assert max(with_v.accel_std) < 0.8 * max(without.accel_std)
    err = with_v.trajectory.u[:-1] - fine.u[:-1]
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) <= np.array(with_v.accel_std))
    assert with_v.trajectory.dim == 3


def test_known_noise_is_kept_and_reported():
    plan = known_plan()
    t, y = noisy_positions(plan, seed=5)
    fit = fit_track(Track(t=t, p=y), position_std=NOISE_M)
    assert fit.position_std == (NOISE_M, NOISE_M) and not fit.estimated
    d = fit.to_dict()
    assert d["position_std_estimated"] is False and d["samples"] == t.size
    assert "(given)" in fit.summary()


# ------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    "content,match",
    [
        ("t,px,py\n0,0,0\n1,1,0\n2,2,0\n", r"3 samples; fitting accelerations needs at least 4"),
        ("t,px,py\n0,0,0\n1,1,0\n1,2,0\n3,3,0\n", r"row 4, column 't': time 1\.0 does not incr"),
        ("t,px,py\n0,0,0\n2,1,0\n1,2,0\n3,3,0\n", r"row 4.*does not increase.*sort the log"),
        ("t,px,py\n0,0,0\n1,nan,0\n2,2,0\n3,3,0\n", r"row 3, column 'px'.*not finite"),
        ("t,px\n0,0\n1,1\n", r"missing column\(s\) py"),
        ("t,px,py,vx\n0,0,0,0\n1,1,0,0\n", r"some of vx,vy but not all"),
        ("t,px,py\n0,0,0\n1,1e12,0\n2,2,0\n3,3,0\n", r"check the units"),
    ],
)
def test_unfittable_tracks_are_refused_with_the_reason(tmp_path, content, match):
    path = tmp_path / "log.csv"
    path.write_text(content)
    with pytest.raises(InputError, match=match):
        fit_track(read_track_csv(path))


def test_track_arrays_are_checked():
    with pytest.raises(TrajectoryFormatError, match="non-finite value at sample 1"):
        Track(t=[0, 1, 2, 3], p=[[0, 0], [np.nan, 0], [0, 0], [0, 0]])
    with pytest.raises(TrajectoryFormatError, match=r"strictly increasing: t\[2\] = 1.0"):
        Track(t=[0, 1, 1, 3], p=np.zeros((4, 2)))
    with pytest.raises(TrajectoryFormatError, match=r"shape \(N, 2\) or \(N, 3\)"):
        Track(t=[0, 1], p=np.zeros((2, 4)))
    with pytest.raises(InputError, match="grid must be a positive"):
        fit_track(Track(t=np.arange(5.0), p=np.zeros((5, 2))), grid=-1.0)
    with pytest.raises(InputError, match="more than the limit"):
        fit_track(Track(t=np.arange(5.0), p=np.zeros((5, 2))), grid=1e-9)


# ------------------------------------------------------------------------- readers
def test_csv_separators_and_extra_columns(tmp_path):
    plan = known_plan()
    t, y = noisy_positions(plan, seed=6)
    a = read_track_csv(write_track(tmp_path / "a.csv", t, y))
    b = read_track_csv(write_track(tmp_path / "b.csv", t, y, sep=";"))
    c = read_track_csv(write_track(tmp_path / "c.tsv", t, y, sep="\t"))
    for other in (b, c):
        np.testing.assert_array_equal(other.p, a.p)
    full = read_track_csv(write_csv(plan, tmp_path / "plan.csv"))  # a trajectory is a track
    np.testing.assert_array_equal(full.v, plan.v)


def _write_tlog(path: Path, t, p, v, kind: str) -> Path:
    mav2 = pytest.importorskip("pymavlink.dialects.v20.ardupilotmega")
    m = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    with open(path, "wb") as fh:
        for k, tk in enumerate(t):
            ms = int(round(tk * 1000))
            if kind == "LOCAL_POSITION_NED":
                msg = mav2.MAVLink_local_position_ned_message(ms, *p[k], *v[k])
            else:
                lat, lon, depth = p[k]
                msg = mav2.MAVLink_global_position_int_message(
                    ms,
                    int(round(lat * 1e7)),
                    int(round(lon * 1e7)),
                    int(round(-depth * 1000)),
                    int(round(-depth * 1000)),
                    *[int(round(x * 100)) for x in v[k]],
                    0,
                )
            # a .tlog record: 8-byte big-endian microseconds, then the MAVLink packet
            fh.write(struct.pack(">Q", 1_700_000_000_000_000 + ms * 1000))
            fh.write(msg.pack(m))
            if k == 2:  # a telemetry link repeats messages: same time_boot_ms again
                fh.write(struct.pack(">Q", 1_700_000_000_000_000 + ms * 1000))
                fh.write(msg.pack(m))
    return path


def test_mavlink_local_position_ned(tmp_path, capsys):
    pytest.importorskip("pymavlink")
    from obsplan.io.tracks import read_track_mavlink

    truth = resample(known_plan(), 1.0).window(0, 121)
    p3 = np.c_[truth.p, np.full(truth.n_samples, 4.0)]
    v3 = np.c_[truth.v, np.zeros(truth.n_samples)]
    log = _write_tlog(tmp_path / "dive.tlog", truth.t, p3, v3, "LOCAL_POSITION_NED")
    tr = read_track_mavlink(log)
    assert tr.n_samples == truth.n_samples  # the repeated message is dropped
    # float32 fields: positions to ~1e-5 m
    np.testing.assert_allclose(tr.p, p3, atol=1e-4)
    np.testing.assert_allclose(tr.v, v3, atol=1e-5)
    out = tmp_path / "dive.csv"
    assert main(["import", str(log), "--out", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["samples"] == truth.n_samples and d["dim"] == 3
    assert read_csv(out).dim == 3


def test_mavlink_global_position_int_goes_through_the_origin(tmp_path):
    pytest.importorskip("pymavlink")
    pytest.importorskip("pymap3d")
    from obsplan.io.tracks import read_track_mavlink
    from obsplan.model.frames import GeodeticOrigin, local_to_geodetic

    origin = GeodeticOrigin(43.7, 10.3)
    truth = resample(known_plan(), 1.0).window(0, 61)
    p3 = np.c_[truth.p, np.full(truth.n_samples, 12.0)]
    lat, lon, depth = local_to_geodetic(p3, origin)
    v3 = np.c_[truth.v, np.zeros(truth.n_samples)]
    log = _write_tlog(tmp_path / "g.tlog", truth.t, np.c_[lat, lon, depth], v3, "GLOBAL")
    tr = read_track_mavlink(log, origin=origin)
    assert tr.origin == origin
    # 1e-7 deg is 1.1 cm in latitude; depth in mm
    np.testing.assert_allclose(tr.p, p3, atol=0.02)


@pytest.mark.parametrize("ros1", [False, True])
def test_rosbag_odometry_enu_to_ned(tmp_path, ros1):
    pytest.importorskip("rosbags")
    from obsplan.io.tracks import read_track_rosbag

    truth = resample(known_plan(), 1.0).window(0, 61)
    enu = np.c_[truth.p[:, 1], truth.p[:, 0], np.full(truth.n_samples, -7.0)]  # east, north, up
    path = tmp_path / ("track.bag" if ros1 else "track")
    _write_bag(path, 1000.0 + truth.t, enu, ros1=ros1)
    tr = read_track_rosbag(path)
    np.testing.assert_allclose(tr.t, 1000.0 + truth.t, atol=1e-9)
    np.testing.assert_allclose(tr.p, np.c_[truth.p, np.full(truth.n_samples, 7.0)], atol=1e-9)
    kept = read_track_rosbag(path, frame="ned")
    np.testing.assert_allclose(kept.p, enu, atol=1e-12)


def test_rosbag_topic_choice_and_errors(tmp_path):
    pytest.importorskip("rosbags")
    from obsplan.io.tracks import read_track_rosbag

    t = np.arange(5.0)
    path = _write_bag(tmp_path / "b", t, np.zeros((5, 3)), pose_stamped=True)
    assert read_track_rosbag(path).n_samples == 5
    with pytest.raises(TrajectoryFormatError, match="no topic '/nav'"):
        read_track_rosbag(path, topic="/nav")
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"not a bag")
    with pytest.raises(TrajectoryFormatError, match="not a readable ROS bag"):
        read_track_rosbag(bad)


def _write_bag(path, t, p, ros1=False, pose_stamped=False, topic="/odom"):
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    msgtype = "geometry_msgs/msg/PoseStamped" if pose_stamped else "nav_msgs/msg/Odometry"

    def header(tk):
        sec = int(tk)
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((tk - sec) * 1e9)))
        return T["std_msgs/msg/Header"](
            stamp=stamp, frame_id="odom", **({"seq": 0} if ros1 else {})
        )

    def msg(tk, xyz):
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        if pose_stamped:
            return T[msgtype](header=header(tk), pose=pose)
        v3 = T["geometry_msgs/msg/Vector3"]
        zero = v3(x=0.0, y=0.0, z=0.0)
        return T[msgtype](
            header=header(tk),
            child_frame_id="base",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                covariance=np.zeros(36),
            ),
        )

    if ros1:
        from rosbags.rosbag1 import Writer

        kw, ser = {}, ts.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer

        kw, ser = {"version": 8}, ts.serialize_cdr
    with Writer(Path(path), **kw) as w:
        c = w.add_connection(topic, msgtype, typestore=ts)
        for tk, xyz in zip(t, p, strict=True):
            w.write(c, int(tk * 1e9), ser(msg(float(tk), [float(v) for v in xyz]), msgtype))
    return Path(path)


# ------------------------------------------------------------------------- CLI
def test_import_refuses_to_overwrite_and_checks_the_output_first(tmp_path, capsys):
    plan = known_plan()
    t, y = noisy_positions(plan, seed=7)
    log = write_track(tmp_path / "log.csv", t, y)
    out = tmp_path / "fit.csv"
    out.write_text("the user's file\n")
    assert main(["import", str(log), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert out.read_text() == "the user's file\n"
    assert main(["import", str(log), "--out", str(out), "--force"]) == 0
    assert read_csv(out).n_samples == t.size
    # --force never overwrites the log itself
    assert main(["import", str(log), "--out", str(log), "--force"]) == 2
    assert "is the input file" in capsys.readouterr().err and log.is_file()
    # an output under a file is refused before the log is even read
    assert main(["import", str(tmp_path / "missing.csv"), "--out", str(log / "x.csv")]) == 2
    assert "is a file" in capsys.readouterr().err


def test_analyze_and_simulate_fit_position_only_tracks_on_the_fly(tmp_path, capsys):
    plan = known_plan()
    t, y = noisy_positions(plan, seed=8)
    log = write_track(tmp_path / "log.csv", t[:121], y[:121])
    assert main(["analyze", str(log), "--json"]) == 0
    cap = capsys.readouterr()
    assert "has positions only: fitted piecewise-constant accelerations" in cap.err
    assert json.loads(cap.out)["dim"] == 2
    assert main(["simulate", str(log), "--runs", "2", "--json"]) == 0
    cap = capsys.readouterr()
    assert "has positions only" in cap.err and json.loads(cap.out)["runs"] == 2


def test_ctrl_c_during_import_exits_130_and_writes_nothing(tmp_path, capsys, monkeypatch):
    plan = known_plan()
    t, y = noisy_positions(plan, seed=9)
    log = write_track(tmp_path / "log.csv", t, y)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr("obsplan.cli.import_track.fit_track", interrupted)
    assert main(["import", str(log), "--out", str(tmp_path / "fit.csv")]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv"]
