"""Trajectories: exact integration, consistency, transformations, CSV round trip and errors."""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.core.errors import TrajectoryFormatError
from obsplan.model.vehicle import make_model
from obsplan.trajectory.sampled import (
    InconsistentTrajectoryWarning,
    Trajectory,
    csv_columns,
    read_csv,
    write_csv,
)


def random_traj(seed=0, dim=2, n=50):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.05, 1.0, n))
    return Trajectory.from_inputs(
        t, rng.normal(0, 10, dim), rng.normal(0, 1, dim), rng.normal(0, 0.3, (n, dim))
    )


@pytest.mark.parametrize("dim", [2, 3])
def test_from_inputs_matches_exact_discretisation(dim):
    """Integrating with model.transition step by step gives the same samples (eq. 4, ZOH)."""
    tr = random_traj(1, dim)
    model = make_model(dim)
    x = np.r_[tr.p[0], tr.v[0]]
    for k in range(tr.n_samples - 1):
        F, G = model.transition(tr.dt[k])
        x = F @ x + G @ tr.u[k]
        np.testing.assert_allclose(x, np.r_[tr.p[k + 1], tr.v[k + 1]], rtol=1e-12, atol=1e-10)
    pe, ve = tr.consistency_error()
    assert pe < 1e-9 and ve < 1e-12
    assert tr.check_consistency()


def test_displacement_is_eq_15():
    """Constant input: d(t, t0) = ½ u (t - t0)²."""
    t = np.linspace(0, 10, 21)
    u = np.array([0.3, -0.2])
    tr = Trajectory.from_inputs(t, [5.0, 1.0], [1.0, 2.0], np.tile(u, (21, 1)))
    np.testing.assert_allclose(tr.displacement(), 0.5 * np.outer(t**2, u), atol=1e-12)


def test_inconsistent_inputs_warn_with_the_mismatch():
    tr = random_traj(2)
    bad = Trajectory(
        t=tr.t, p=tr.p + np.r_[0, 0.5][None, :] * (np.arange(50) == 10)[:, None], v=tr.v, u=tr.u
    )
    with pytest.warns(InconsistentTrajectoryWarning, match=r"up to 0\.5 m in position"):
        assert not bad.check_consistency()


def test_transformations():
    tr = random_traj(3)
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    c = np.array([2.0, 3.0])
    rot = tr.rotated(R, about=c)
    np.testing.assert_allclose(np.linalg.norm(rot.p - c, axis=1), np.linalg.norm(tr.p - c, axis=1))
    assert rot.check_consistency()
    sc = tr.scaled(1000.0, 3600.0)
    np.testing.assert_allclose(sc.p * 1000.0, tr.p)
    np.testing.assert_allclose(sc.u * 1000.0 / 3600.0**2, tr.u)
    assert sc.check_consistency(tol_pos=1e-9, tol_vel=1e-9)
    a, b = tr.window(0, 20), tr.window(19)
    joined = a.then(b)
    np.testing.assert_allclose(joined.p, tr.p)
    np.testing.assert_allclose(joined.t, tr.t)
    with pytest.raises(TrajectoryFormatError, match="do not join"):
        a.then(tr.window(30))


@pytest.mark.parametrize("dim", [2, 3])
def test_csv_round_trip_is_exact(tmp_path, dim):
    tr = random_traj(4, dim)
    path = write_csv(tr, tmp_path / "t.csv")
    back = read_csv(path)
    for name in ("t", "p", "v", "u"):
        assert np.array_equal(getattr(back, name), getattr(tr, name))
    assert path.read_text().splitlines()[0] == ",".join(csv_columns(dim))


def test_csv_extra_columns_and_order_are_ignored(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("note,uy,ux,vy,vx,py,px,t\na,0,0,1,1,0,0,0\nb,0,0,1,1,1,1,1\n")
    tr = read_csv(path)
    np.testing.assert_array_equal(tr.p, [[0, 0], [1, 1]])


BAD_CSVS = [
    ("t,px,py,vx,vy,ux\n0,0,0,0,0,0\n1,0,0,0,0,0\n", r"missing column\(s\) uy"),
    ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n1,0,abc,0,0,0,0\n", r"row 3, column 'py': 'abc' is not"),
    ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n1,0,0,0,nan,0,0\n", r"row 3, column 'vy'.*not finite"),
    (
        "t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n2,0,0,0,0,0,0\n2,0,0,0,0,0,0\n",
        r"row 4, column 't': time 2\.0 does not increase",
    ),
    ("t,px,py,pz,vx,vy,ux,uy\n0,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0\n", r"mixed 2D/3D.*vz, uz"),
    ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n\n1,0,0,0\n", r"row 4 has no value for column 'vy'"),
    ("t,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n", r"at least 2 data rows"),
    ("", r"empty"),
]


@pytest.mark.parametrize("content,match", BAD_CSVS)
def test_bad_csv_names_row_or_column(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(TrajectoryFormatError, match=match):
        read_csv(path)


def test_unreadable_files(tmp_path):
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"\x89PNG\x00garbage")
    with pytest.raises(TrajectoryFormatError, match="not a text file"):
        read_csv(binary)
    binary.write_bytes(b"\xff\xfe\x00garbage")  # a UTF-16 byte-order mark
    with pytest.raises(TrajectoryFormatError, match="saved as UTF-16 text; save it as UTF-8"):
        read_csv(binary)
    with pytest.raises(TrajectoryFormatError, match="not found"):
        read_csv(tmp_path / "missing.csv")
    with pytest.raises(TrajectoryFormatError, match="not a file"):
        read_csv(tmp_path)
    bom = tmp_path / "bom.csv"
    bom.write_bytes("\ufefft,px,py,vx,vy,ux,uy\n0,0,0,0,0,0,0\n1,0,0,0,0,0,0\n".encode())
    assert read_csv(bom).n_samples == 2


def test_array_validation():
    with pytest.raises(TrajectoryFormatError, match="strictly increasing"):
        Trajectory(t=[0, 1, 1], p=np.zeros((3, 2)), v=np.zeros((3, 2)), u=np.zeros((3, 2)))
    with pytest.raises(TrajectoryFormatError, match="'p' must have shape"):
        Trajectory(t=[0, 1], p=np.zeros((3, 2)), v=np.zeros((2, 2)), u=np.zeros((2, 2)))
    with pytest.raises(TrajectoryFormatError, match="non-finite value at sample 1"):
        Trajectory(t=[0, 1], p=[[0, 0], [np.inf, 0]], v=np.zeros((2, 2)), u=np.zeros((2, 2)))


# ---------------------------------------------------------------- CSV dialects and grid times
CANONICAL = "t,px,py,vx,vy,ux,uy\n0,0,0,1,0,0,0\n1,1,0,1,0,0,0\n"


@pytest.mark.parametrize("sep", [";", "\t"])
def test_semicolon_and_tab_separators_are_detected(tmp_path, sep):
    path = tmp_path / "x.csv"
    path.write_text(CANONICAL.replace(",", sep))
    tr = read_csv(path)
    np.testing.assert_array_equal(tr.p, [[0, 0], [1, 0]])


@pytest.mark.parametrize(
    "content,match",
    [
        # no header: one hint naming the header to add
        ("0,0,0,1,0,0,0\n1,1,0,1,0,0,0\n", r"line 1 looks like data, not a header.*t,px,py"),
        ("0;0;0;1;0;0;0\n1;1;0;1;0;0;0\n", r"looks like data.*t;px;py"),
        # a duplicated column is an error, not a silent choice of the first
        ("t,px,py,px,vx,vy,ux,uy\n0,0,0,9,1,0,0,0\n1,1,0,9,1,0,0,0\n", r"'px' appears 2 times"),
        # decimal commas with semicolon separators get a hint
        ("t;px;py;vx;vy;ux;uy\n0;0,5;0;1;0;0;0\n1;1;0;1;0;0;0\n", r"decimal commas"),
        ("t px py vx vy ux uy\n0 0 0 1 0 0 0\n", r"separated by spaces are not supported"),
    ],
)
def test_csv_dialect_errors_give_the_fix(tmp_path, content, match):
    path = tmp_path / "x.csv"
    path.write_text(content)
    with pytest.raises(TrajectoryFormatError, match=match):
        read_csv(path)


def test_times_are_written_on_their_grid(tmp_path):
    """``k * dt`` accumulated in floating point is written as the grid time (57.0, not
    56.99999999999999), while times that are not grid noise keep their exact value."""
    t = np.cumsum(np.full(600, 0.1))  # 0.1, 0.2, ... with accumulated rounding error
    t = np.r_[0.0, t]
    assert t[570] != 57.0  # the noise the file must not show
    tr = Trajectory.from_inputs(t, [0.0, 0.0], [1.0, 0.0], np.zeros((t.size, 2)))
    path = write_csv(tr, tmp_path / "grid.csv")
    times = [line.split(",")[0] for line in path.read_text().splitlines()[1:]]
    assert times[570] == "57.0" and times[1] == "0.1" and times[3] == "0.3"
    assert all(len(s) <= 6 for s in times)
    back = read_csv(path)
    np.testing.assert_allclose(back.t, t, rtol=0, atol=1e-12)  # moved by ulps only
    # arbitrary times are written exactly (round trip of test_csv_round_trip_is_exact)
    rnd = random_traj(9)
    np.testing.assert_array_equal(read_csv(write_csv(rnd, tmp_path / "r.csv")).t, rnd.t)


def test_write_csv_is_atomic(tmp_path, monkeypatch):
    """An interruption while writing leaves the old file and no temporary file."""
    path = write_csv(random_traj(1), tmp_path / "t.csv")
    before = path.read_bytes()
    real_writer = __import__("csv").writer

    class Boom:
        def __init__(self, fh):
            self.w, self.n = real_writer(fh), 0

        def writerow(self, row):
            self.n += 1
            if self.n > 5:
                raise KeyboardInterrupt
            self.w.writerow(row)

    monkeypatch.setattr("obsplan.core.csvtable.csv.writer", Boom)
    with pytest.raises(KeyboardInterrupt):
        write_csv(random_traj(2), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]
