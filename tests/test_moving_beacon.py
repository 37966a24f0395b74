"""A beacon on a known path: the path, its CSV, and both observability tests with it (issue 46).

Facts (docs/theory.md, "A moving beacon"): only the motion relative to the beacon matters
(``r = p - b``, input ``u - b''``), so a beacon at constant velocity is no better than a fixed
one, a circling beacon makes a straight constant-speed line observable, and a beacon trailing
the vehicle at a constant offset leaves it unobservable. Each is checked with the LWO rank test
and the augmented Gramian, in 2D and 3D, with depth and DVL; the verdicts use the package's
stated tolerances (``LWO_RANK_TOL`` 1e-9, ``RANK_TOL`` 1e-10), nothing looser.
"""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.core.errors import InputError, TrajectoryFormatError
from obsplan.model.beacon import BeaconPath, read_beacon_path
from obsplan.model.vehicle import make_model
from obsplan.observability.analyze import analyze
from obsplan.observability.gramian import gramian, gramian_report, interval_gramians
from obsplan.observability.lwo import lwo_matrices, lwo_ranks, lwo_report
from obsplan.trajectory.relative import relative_trajectory
from obsplan.trajectory.sampled import Trajectory

T = np.arange(0.0, 200.0 + 1e-9, 1.0)
#: Beacon logs sampled at other times than the trajectory (0.7 s, offset), covering it.
TB = np.arange(-5.0, 210.0, 0.7)
P0 = np.array([-100.0, 30.0, 10.0])
V0 = np.array([1.0, 0.2, 0.05])


def line(dim: int) -> Trajectory:
    """A straight constant-velocity line: unobservable with a fixed beacon (eq. 13: no input)."""
    return Trajectory.from_inputs(T, P0[:dim], V0[:dim], np.zeros((T.size, dim)))


def const_velocity_beacon(dim: int) -> BeaconPath:
    b0, vb = np.array([20.0, -40.0, 0.0])[:dim], np.array([-0.3, 0.8, 0.0])[:dim]
    return BeaconPath(TB, b0 + np.outer(TB, vb))


def circling_beacon(dim: int, radius: float = 40.0, w: float = 0.05) -> BeaconPath:
    b = np.zeros((TB.size, dim))
    b[:, 0], b[:, 1] = radius * np.cos(w * TB), radius * np.sin(w * TB)
    return BeaconPath(TB, b)


def trailing_beacon(dim: int) -> BeaconPath:
    """The line of :func:`line` plus a constant offset, logged at the other times."""
    off = np.array([10.0, -20.0, -5.0])[:dim]
    return BeaconPath(TB, P0[:dim] + np.outer(TB - T[0], V0[:dim]) + off)


CASES = [
    (2, "range"),
    (3, "range,depth"),
    (2, "range,dvl-water"),
    (3, "range,depth,dvl-water"),
    (3, "range,depth,dvl-bottom"),
]


def verdicts(traj, sensors, **kw):
    d = analyze(traj, sensors, **kw).to_dict()
    return d["lwo"]["along_trajectory"], d["gramian"]["full_rank"], d["gramian"]["rank"]


# ------------------------------------------------------------------ the three facts
@pytest.mark.parametrize("dim,sensors", CASES)
def test_constant_velocity_beacon_is_no_better_than_a_fixed_one(dim, sensors):
    traj = line(dim)
    fixed = verdicts(traj, sensors)
    moving = verdicts(traj, sensors, beacon_path=const_velocity_beacon(dim))
    assert fixed[1] is False  # the line is unobservable with a fixed beacon
    assert moving == fixed


@pytest.mark.parametrize("dim,sensors", CASES)
def test_circling_beacon_makes_a_straight_line_observable(dim, sensors):
    lwo, full, rank = verdicts(line(dim), sensors, beacon_path=circling_beacon(dim))
    assert lwo is True and full is True
    assert rank == make_model(dim, sensors).state_dim + 2


@pytest.mark.parametrize("dim,sensors", CASES)
def test_trailing_beacon_leaves_the_vehicle_unobservable(dim, sensors):
    traj = line(dim)
    path = trailing_beacon(dim)
    lwo, full, rank = verdicts(traj, sensors, beacon_path=path)
    assert lwo is False and full is False
    # r is constant: the range rows see only the (τ, τ²/2) columns and the depth/DVL rows
    model = make_model(dim, sensors)
    assert max(lwo_ranks(traj, model, beacon_path=path)) < model.state_dim
    rep = gramian_report(traj, model, beacon_path=path)
    assert rep.rank < rep.dim and rep.min_eig == 0.0


def test_circling_beacon_in_3d_range_only_stays_planar_deficient():
    """A horizontal circle gives no vertical excitation: 3D range only stays rank deficient."""
    _lwo, full, rank = verdicts(line(3), "range", beacon_path=circling_beacon(3))
    assert full is False and rank < 8


def test_the_trailing_gramian_is_exactly_singular_not_nearly():
    """Scaled by the vehicle's own length, the trailing Gramian's position block is round-off:
    below 1e-20 of its largest entry (stated tolerance: round-off of |b| ~ 100 m values)."""
    traj, path = line(2), trailing_beacon(2)
    G = gramian(traj, make_model(2), beacon_path=path)
    assert np.max(np.abs(G[:2, :2])) <= 1e-20 * np.max(np.abs(G))


# ------------------------------------------------------------------ fixed beacon: unchanged
def test_no_path_is_bit_identical_to_today():
    t = np.arange(0.0, 60.0, 0.5)
    u = np.c_[0.05 * np.cos(0.1 * t), 0.05 * np.sin(0.1 * t)]
    traj = Trajectory.from_inputs(t, [30.0, 0.0], [0.0, 1.0], u)
    model = make_model(2, "range,dvl-water", beacon=(3.0, -4.0))
    assert np.array_equal(lwo_matrices(traj, model), lwo_matrices(traj, model, beacon_path=None))
    G = interval_gramians(traj, model, beacon_path=None)
    assert np.array_equal(interval_gramians(traj, model), G)
    assert gramian_report(traj, model) == gramian_report(traj, model, beacon_path=None)


def test_a_constant_path_is_the_fixed_beacon():
    """The constant path (knots inside the span) gives the fixed beacon's LWO matrices bit for
    bit and its Gramian to 1e-12 relative (sub-intervals summed: round-off only)."""
    t = np.arange(0.0, 60.0, 0.5)
    u = np.c_[0.05 * np.cos(0.1 * t), 0.05 * np.sin(0.1 * t)]
    traj = Trajectory.from_inputs(t, [30.0, 0.0], [0.0, 1.0], u)
    b = (3.0, -4.0)
    path = BeaconPath(TB, np.tile(b, (TB.size, 1)))
    fixed, moving = make_model(2, beacon=b), make_model(2)
    assert np.array_equal(lwo_matrices(traj, fixed), lwo_matrices(traj, moving, beacon_path=path))
    G0, G1 = gramian(traj, fixed), gramian(traj, moving, beacon_path=path)
    assert np.allclose(G1, G0, rtol=1e-12, atol=1e-12 * np.max(np.abs(G0)))


# ------------------------------------------------------------------ the relative trajectory
def test_relative_trajectory_is_exact_on_the_union_of_samples_and_knots():
    traj = Trajectory.from_inputs(T[:11], [0.0, 0.0], [1.0, 0.0], np.full((11, 2), 0.1))
    path = BeaconPath([0.0, 2.5, 10.0], [[0.0, 5.0], [5.0, 5.0], [5.0, 0.0]])
    rel, idx = relative_trajectory(traj, path)
    assert np.array_equal(rel.t[idx], traj.t) and 2.5 in rel.t and rel.n_samples == 12
    k = int(np.flatnonzero(rel.t == 2.5)[0])
    # the vehicle at 2.5 s exactly (held input), the beacon at its knot
    p = np.array([2.5 + 0.05 * 2.5**2, 0.05 * 2.5**2])
    assert np.allclose(rel.p[k], p - [5.0, 5.0], rtol=0, atol=1e-14)
    # the relative velocity jumps by minus the beacon's change of velocity: (2, 0) -> (0, -2/3)
    assert np.allclose(rel.v[k] - (rel.v[k - 1] + 0.1 * 0.5), [2.0, 2.0 / 3.0], atol=1e-14)


def test_interval_gramians_are_given_on_the_trajectorys_own_intervals():
    traj, path = line(2), circling_beacon(2)
    Gk = interval_gramians(traj, make_model(2), beacon_path=path)
    assert Gk.shape == (T.size - 1, 6, 6)
    assert np.allclose(Gk.sum(axis=0), gramian(traj, make_model(2), beacon_path=path))


def test_beacon_log_sampled_elsewhere_agrees_with_one_on_the_trajectorys_times():
    """The same circle logged at the trajectory's times and at 0.7 s offsets: same verdicts,
    and close metrics (linear interpolation of a 40 m circle at ≤ 1 s: chord error ≤ 5 mm)."""
    traj = line(2)
    b = np.c_[40 * np.cos(0.05 * T), 40 * np.sin(0.05 * T)]
    same = analyze(traj, "range", beacon_path=BeaconPath(T, b)).to_dict()
    other = analyze(traj, "range", beacon_path=circling_beacon(2)).to_dict()
    assert same["lwo"]["along_trajectory"] and other["lwo"]["along_trajectory"]
    assert same["gramian"]["rank"] == other["gramian"]["rank"] == 6
    assert other["gramian"]["log_det"] == pytest.approx(same["gramian"]["log_det"], abs=0.05)


def test_lwo_reads_the_smooth_paths_acceleration():
    """A log of a circle: b'' estimated at the knots is the circle's (-ω² b) to O((ωh)²)."""
    path = circling_beacon(2)
    _v, a = path.derivative_estimates(T)
    expect = -(0.05**2) * path.position(T)
    assert np.max(np.abs(a - expect)) <= 1e-3 * 40 * 0.05**2


def test_constant_velocity_log_has_exactly_zero_acceleration():
    """Round-off of the divided differences (a log at 0.01 s, km away) is snapped to zero."""
    t = 1000.0 + np.arange(0.0, 50.0, 0.01)
    path = BeaconPath(t, np.c_[3000.0 + 0.37 * t, -2500.0 - 1.3 * t])
    _v, a = path.derivative_estimates(t)
    assert not np.any(a)


# ------------------------------------------------------------------ the path and its CSV
def test_path_interpolates_and_holds_segment_velocities():
    path = BeaconPath([0.0, 2.0, 4.0], [[0.0, 0.0], [2.0, 0.0], [2.0, 4.0]])
    assert np.allclose(path.position([1.0, 3.0]), [[1.0, 0.0], [2.0, 2.0]])
    assert np.allclose(path.velocity([0.0, 2.0, 4.0]), [[1.0, 0.0], [0.0, 2.0], [0.0, 2.0]])
    assert path.dim == 2 and path.knots_within(0.0, 4.0).tolist() == [2.0]
    fixed = BeaconPath.fixed((1.0, 2.0, 3.0), 0.0, 10.0)
    v, a = fixed.derivative_estimates([0.0, 5.0])
    assert fixed.dim == 3 and not v.any() and not a.any()


@pytest.mark.parametrize(
    "t,b,match",
    [
        ([0.0], [[0.0, 0.0]], "at least 2 samples"),
        ([0.0, 0.0], [[0.0, 0.0], [1.0, 1.0]], "strictly increasing"),
        ([0.0, 1.0], [[0.0, np.nan], [1.0, 1.0]], "non-finite"),
        ([0.0, 1.0], [[0.0], [1.0]], "shape"),
    ],
)
def test_bad_paths_are_refused(t, b, match):
    with pytest.raises(TrajectoryFormatError, match=match):
        BeaconPath(t, b)


def test_a_path_that_does_not_cover_the_trajectory_is_refused():
    path = BeaconPath([10.0, 100.0], [[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(InputError, match=r"ship: covers t = 10\.\.100 s but t = 0\.\.200 s"):
        path.check_covers(0.0, 200.0, "ship")
    with pytest.raises(InputError, match="covers"):
        analyze(line(2), beacon_path=path)
    with pytest.raises(InputError, match="covers"):
        path.position(5.0)


def test_path_of_another_dimension_or_with_a_fixed_beacon_is_refused():
    with pytest.raises(InputError, match="3D but the trajectory is 2D"):
        analyze(line(2), beacon_path=circling_beacon(3))
    with pytest.raises(InputError, match="not both"):
        analyze(line(2), beacon=(1.0, 2.0), beacon_path=circling_beacon(2))


def test_read_csv_2d_3d_extra_columns(tmp_path):
    f = tmp_path / "ship.csv"
    f.write_text("t,bx,by,heading\n0,1,2,90\n1.5,3,4,91\n")
    path = read_beacon_path(f)
    assert path.dim == 2 and path.times.tolist() == [0.0, 1.5]
    assert path.positions.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    f3 = tmp_path / "ship3.csv"
    f3.write_text("# a ship\nt;bx;by;bz\n0;1;2;0\n1;1;2;0\n")
    assert read_beacon_path(f3).dim == 3 and read_beacon_path(f3, 3).dim == 3


@pytest.mark.parametrize(
    "content,dim,match",
    [
        ("t,bx\n0,1\n1,2\n", 2, "missing column(s) by"),
        ("t,bx,by\n0,1,2\n1,2,3\n", 3, "missing column(s) bz (the trajectory is 3D)"),
        ("t,bx,by,bz\n0,1,2,3\n1,2,3,4\n", 2, "column 'bz' makes it a 3D"),
        ("t,bx,by\n0,1,2\n", 2, "at least 2 data rows"),
        ("t,bx,by\n0,1,2\n0,2,3\n", 2, "row 3, column 't'"),
        ("t,bx,by\n0,1,2\n1,x,3\n", 2, "row 3, column 'bx'"),
        ("t,bx,by\n0,1,2\n1,1e9,3\n", 2, "column 'bx'"),
    ],
)
def test_bad_csv_names_row_or_column(tmp_path, content, dim, match):
    f = tmp_path / "b.csv"
    f.write_text(content)
    with pytest.raises(TrajectoryFormatError, match=None) as exc:
        read_beacon_path(f, dim)
    assert match in str(exc.value)


def test_lwo_report_with_a_path_counts_the_trajectorys_samples():
    traj = line(2)
    rep = lwo_report(traj, make_model(2), beacon_path=circling_beacon(2))
    assert rep.ranks.shape == (T.size,) and rep.along_trajectory
