"""Fuzzing the loaders: random and mutated CSVs, tracks, waypoint files, missions and problems.

Every input must end in a valid result or an :class:`~obsplan.core.errors.InputError` (exit 2 in the
CLI), never another exception. 500 examples per loader (seeded by hypothesis' database-free
derandomised mode so CI is reproducible); each example is milliseconds.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from obsplan.core.csvtable import COLUMN_LIMITS
from obsplan.core.errors import InputError
from obsplan.io.tracks import Track, TrackFit, load_trajectory, read_track_csv
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import load_problem, problem_from_dict
from obsplan.trajectory.sampled import Trajectory, read_csv

EXAMPLES = 500
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
DEFAULT = Path(__file__).resolve().parents[1] / "problems" / "localise.toml"
_TMP = Path()  # set per module by the fixture below: pytest's tmp_path, cleaned up by pytest


@pytest.fixture(scope="module", autouse=True)
def _fuzz_folder(tmp_path_factory):
    global _TMP
    _TMP = tmp_path_factory.mktemp("fuzz-loaders")
    yield
    _TMP = Path()


VALID_2D = (
    "t,px,py,vx,vy,ux,uy\n0,0,0,1,0,0,0\n1,1,0,1,0,0,0\n2,2,0,1,0,0.1,0\n3,3.05,0,1.1,0,0,0\n"
)
VALID_3D = (
    "t,px,py,pz,vx,vy,vz,ux,uy,uz\n0,0,0,5,1,0,0,0,0,0\n1,1,0,5,1,0,0,0,0,0\n"
    "2,2,0,5,1,0,0,0,0,0\n3,3,0,5,1,0,0,0,0,0\n"
)
VALID_TRACK = "t,px,py\n0,0,0\n1,1,0.1\n2,2,0\n3,3,-0.1\n4,4,0\n5,5,0.05\n"
TOKENS = [
    "", " ", "0", "-1", "1e308", "-1e308", "1e-320", "nan", "NaN", "inf", "-inf", "1,5", "abc",
    "0x10", "1_000", "٣", "\u2028", '"', '"1"', "1.", ".5", "1e", "--1", "t", "px", "ux", "pz",
    "1e300", "-1e300", "1e12", "-1e9", "1e7", "9999999", "1e10", "# c", "#",
]  # fmt: skip
ALPHABET = ",;\t\n\r -.0123456789eEinfatxpyzvuINF#\"'\x00é"


def _file(text: str | bytes, suffix: str = ".csv") -> Path:
    fd, name = tempfile.mkstemp(dir=_TMP, suffix=suffix)
    os.close(fd)
    path = Path(name)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return path


@st.composite
def mutated(draw, base: str) -> str:
    """A valid CSV with a few random edits: cells, rows, columns, separators, truncation."""
    rows = [r.split(",") for r in base.strip().split("\n")]
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["cell", "drop-row", "dup-row", "swap", "drop-col", "dup-col",
                                   "sep", "blank", "truncate", "header"]))  # fmt: skip
        i = draw(st.integers(0, len(rows) - 1))
        j = draw(st.integers(0, max(len(rows[i]) - 1, 0)))
        if op == "cell" and rows[i]:
            rows[i][j] = draw(st.sampled_from(TOKENS) | st.text(ALPHABET, max_size=6))
        elif op == "drop-row" and len(rows) > 1:
            rows.pop(i)
        elif op == "dup-row":
            rows.insert(i, list(rows[i]))
        elif op == "swap" and len(rows) > 2:
            k = draw(st.integers(1, len(rows) - 1))
            rows[i], rows[k] = rows[k], rows[i]
        elif op == "drop-col":
            rows = [r[:j] + r[j + 1 :] for r in rows]
        elif op == "dup-col":
            rows = [r + r[j : j + 1] for r in rows]
        elif op == "header":
            rows[0][j % max(len(rows[0]), 1) if rows[0] else 0 : 1] = [
                draw(st.sampled_from(["t", "px", "PX", " py ", "vz", "uz", "pz", ""]))
            ]
        elif op == "blank":
            rows.insert(i, [""])
    sep = draw(st.sampled_from([",", ",", ";", "\t"]))
    text = "\n".join(sep.join(r) for r in rows) + "\n"
    if draw(st.booleans()) and draw(st.booleans()):
        text = text[: draw(st.integers(0, len(text)))]
    return text


def _expect_trajectory(fn, path: Path) -> None:
    try:
        out = fn(path)
    except InputError:
        return
    traj = out[0] if isinstance(out, tuple) else out
    assert isinstance(traj, Trajectory | Track)
    assert np.all(np.isfinite(traj.p)) and np.all(np.diff(traj.t) > 0)
    # magnitudes beyond any vehicle are refused, never passed on
    assert np.all(np.abs(traj.t) <= COLUMN_LIMITS["t"][0])
    if not (isinstance(out, tuple) and out[1] is not None):  # a fit may overshoot a little
        assert np.all(np.abs(traj.p) <= COLUMN_LIMITS["px"][0])
    if isinstance(out, tuple) and out[1] is not None:
        assert isinstance(out[1], TrackFit)


CSV_INPUTS = (
    st.text(ALPHABET, max_size=300)
    | st.binary(max_size=200)
    | mutated(VALID_2D)
    | mutated(VALID_3D)
    | mutated(VALID_TRACK)
)


@FUZZ
@given(CSV_INPUTS)
def test_fuzz_trajectory_csv(text):
    _expect_trajectory(lambda p: read_csv(p, check=False), _file(text))


@FUZZ
@given(CSV_INPUTS)
def test_fuzz_track_csv(text):
    _expect_trajectory(read_track_csv, _file(text))


@pytest.mark.slow
@FUZZ
@given(CSV_INPUTS)
def test_fuzz_trajectory_or_track_with_fit(text):
    """What analyze and simulate read: a trajectory, or a track fitted on the fly."""
    _expect_trajectory(lambda p: load_trajectory(p, check=False), _file(text))


#: The encodings files arrive in; only UTF-8 (with or without a byte-order mark) is text to us.
ENCODINGS = ["utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-32", "latin-1", "cp1252"]
NON_ASCII = ["", "# logged at Livorno, 20 °C, café\n", "# Ünterwasser ✓\n"]


@st.composite
def encoded(draw, docs: list[str]) -> tuple[bytes, str]:
    """A document (with a non-ASCII comment line or not) in one of ENCODINGS: (bytes, text)."""
    text = draw(st.sampled_from(NON_ASCII)) + draw(st.sampled_from(docs))
    enc = draw(st.sampled_from(ENCODINGS))
    raw = text.encode(enc, errors="replace")
    return raw, text


def _decodes_as_utf8(raw: bytes) -> bool:
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw:
        return False  # a byte-order mark of UTF-16/32, or NUL bytes: not text to a reader
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@FUZZ
@given(encoded([VALID_2D, VALID_3D, VALID_TRACK]))
def test_fuzz_csv_encodings(doc):
    """UTF-8 text (a byte-order mark or not) reads as the same table; anything else is one
    InputError, never a wrong table."""
    raw, text = doc
    ref = load_trajectory(_file(text), check=False)[0]
    try:
        got = load_trajectory(_file(raw), check=False)[0]
    except InputError as exc:
        assert not _decodes_as_utf8(raw), exc
        assert "UTF" in str(exc) or "text" in str(exc)
        return
    assert _decodes_as_utf8(raw)
    np.testing.assert_array_equal(got.p, ref.p)
    np.testing.assert_array_equal(got.t, ref.t)


@FUZZ
@given(encoded([DEFAULT.read_text(encoding="utf-8")]))
def test_fuzz_problem_file_encodings(doc):
    raw, text = doc
    try:
        pb = load_problem(_file(raw, ".toml"))
    except InputError as exc:
        assert not _decodes_as_utf8(raw), exc
        return
    assert pb == load_problem(_file(text, ".toml"))


@FUZZ
@given(CSV_INPUTS | mutated("t,x,y,speed,leg_cross_track,leg_schedule_error\n0,0,0,1,0,0\n"))
def test_fuzz_waypoint_csv(text):
    from obsplan.io.waypoints import read_waypoints_csv

    try:
        cols = read_waypoints_csv(_file(text))
    except InputError:
        return
    assert all(np.all(np.isfinite(v)) for v in cols.values())


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=7) | st.dictionaries(st.text(max_size=8), inner),
    max_leaves=6,
)


@st.composite
def plan_docs(draw):
    items = draw(st.lists(st.fixed_dictionaries(
        {"command": st.sampled_from([16, 178, 22]) | JSON_VALUES, "params": JSON_VALUES}
    ), max_size=4))  # fmt: skip
    doc = {"fileType": draw(st.sampled_from(["Plan", "Plan", "x"])), "mission": {"items": items}}
    if draw(st.booleans()):
        doc = draw(JSON_VALUES)
    return json.dumps(doc)


@pytest.mark.slow
@FUZZ
@given(plan_docs() | st.text(max_size=80))
def test_fuzz_qgc_plan(text):
    from obsplan.io.waypoints import read_qgc_plan

    try:
        out = read_qgc_plan(_file(text, ".plan"))
    except InputError:
        return
    assert set(out) == {"latitude", "longitude", "altitude", "speed"}


# ------------------------------------------------------------------------------ problems
with DEFAULT.open("rb") as _fh:
    BASE = tomllib.load(_fh)

VALUES = (
    st.integers(-(10**12), 10**12)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from([0, 1, 2, 3, -1, 0.0, 1e-12, 1e12, 100000, True, False, "", "range"])
    | st.text(max_size=8)
    | st.lists(st.floats(-1e3, 1e3) | st.integers(-5, 5) | st.text(max_size=3), max_size=4)
    | st.dictionaries(st.sampled_from(["x", "y", "z", "latitude"]), st.floats(-200, 200))
)
KEYS = {sec: list(body) for sec, body in BASE.items()} | {
    "origin": ["latitude", "longitude", "altitude"],
    "beacon": ["position", "geodetic"],
    "start": ["position", "velocity", "geodetic"],
    "limits": ["accel", "speed", "depth", "area", "min_range", "max_range", "min_speed"],
    "objective": ["kind", "mode", "starts", "seed", "max_iter", "tol"],
}


@st.composite
def problems(draw):
    data = json.loads(json.dumps(BASE))  # a deep copy
    for _ in range(draw(st.integers(1, 4))):
        sec = draw(st.sampled_from([*KEYS, "bogus"]))
        op = draw(st.sampled_from(["set", "set", "set", "delete", "section"]))
        if op == "section":
            data[sec] = draw(VALUES | st.just({}))
            continue
        body = data.setdefault(sec, {})
        if not isinstance(body, dict):
            continue
        key = draw(st.sampled_from([*KEYS.get(sec, []), "typo"]))
        if op == "delete":
            body.pop(key, None)
        elif key == "geodetic" and draw(st.booleans()):
            body[key] = [draw(st.floats(-100, 100)), draw(st.floats(-200, 400))]
            data.setdefault("origin", {"latitude": 43.7, "longitude": 10.3})
        elif key == "geodetic":  # near the origin: either side of the local frame's range
            body[key] = [43.7 + draw(st.floats(-0.6, 0.6)), 10.3 + draw(st.floats(-0.8, 0.8))]
            data["origin"] = {"latitude": 43.7, "longitude": 10.3}
        else:
            body[key] = draw(VALUES)
    return data


@pytest.mark.slow
@FUZZ
@given(problems())
def test_fuzz_problem_mapping(data):
    try:
        pb = problem_from_dict(data)
    except InputError:
        return
    assert isinstance(pb, PlanningProblem)
    assert all(math.isfinite(x) for x in (*pb.start_position, *pb.beacon))
    for sec, pos in (("beacon", pb.beacon), ("start", pb.start_position)):
        if isinstance(data.get(sec), dict) and "geodetic" in data[sec]:
            assert math.hypot(pos[0], pos[1]) <= 50_000.0 * (1 + 1e-6), (sec, pos)


@FUZZ
@given(st.text(max_size=200) | st.binary(max_size=100).map(lambda b: b.decode("latin-1")))
def test_fuzz_problem_file_text(text):
    base = DEFAULT.read_text()
    for doc in (text, base[: len(text)] + text):  # random text, and a truncated-then-mangled file
        try:
            load_problem(_file(doc, ".toml"))
        except InputError:
            pass


# ------------------------------------------------------------------------------ geodetic ranges
@FUZZ
@given(
    st.floats(-89.9, 89.9),
    st.floats(-180.0, 359.9),
    st.floats(-1.0, 1.0) | st.floats(-180.0, 180.0),
    st.floats(-1.0, 1.0) | st.floats(-360.0, 360.0),
    st.floats(-100.0, 100.0) | st.floats(-1e5, 1e5),
)
def test_fuzz_geodetic_points_near_or_far_from_the_origin(lat0, lon0, dlat, dlon, depth):
    """A point within the local frame's range converts and round-trips; one beyond it is refused
    with the distance, never turned into positions of thousands of kilometres."""
    pytest.importorskip("pymap3d")
    from obsplan.model.frames import (
        MAX_DEPTH_M,
        MAX_LOCAL_DISTANCE_M,
        GeodeticOrigin,
        geodetic_to_local,
        local_to_geodetic,
    )

    origin = GeodeticOrigin(lat0, lon0)
    lat, lon = lat0 + dlat, lon0 + dlon
    if not -90.0 <= lat <= 90.0:
        return
    try:
        p = geodetic_to_local(lat, lon, depth, origin, dim=3, where="point")
    except InputError as exc:
        assert "km from the origin" in str(exc) or "depth" in str(exc)
        return
    assert abs(depth) <= MAX_DEPTH_M
    horizontal = math.hypot(p[0], p[1])
    assert horizontal <= MAX_LOCAL_DISTANCE_M * (1 + 1e-6)
    la, lo, de = local_to_geodetic(p, origin)
    assert abs(la[0] - lat) < 1e-7 and abs(de[0] - depth) < 1e-3
    assert abs((lo[0] - lon + 180.0) % 360.0 - 180.0) < 1e-7 or abs(abs(lat) - 90.0) < 1e-3
