"""Geodetic frames: conversions, problem files with [origin], the CLI's --beacon-geodetic."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymap3d")

from obsplan.cli import main  # noqa: E402
from obsplan.core.errors import InputError, ProblemError  # noqa: E402
from obsplan.io.geodetic import parse_origin  # noqa: E402
from obsplan.model.frames import GeodeticOrigin, geodetic_to_local, local_to_geodetic  # noqa: E402
from obsplan.planning.problem.parse import problem_from_dict, resolve_problem_geodetic  # noqa: E402
from obsplan.trajectory.sampled import read_csv  # noqa: E402

ORIGIN = GeodeticOrigin(43.7, 10.3)  # off Livorno
DEFAULT = Path(__file__).resolve().parents[1] / "problems" / "localise.toml"


def test_round_trip_and_the_ned_convention():
    rng = np.random.default_rng(0)
    p = rng.uniform(-5000, 5000, (50, 3))
    p[:, 2] = rng.uniform(0, 200, 50)  # depths
    lat, lon, depth = local_to_geodetic(p, ORIGIN)
    back = geodetic_to_local(lat, lon, depth, ORIGIN)
    # pymap3d's iterative inverse is good to ~1e-8 m; 1e-6 m is far below any survey error
    np.testing.assert_allclose(back, p, atol=1e-6)
    # x is north, y is east, z is down (depth): 1e-4 deg of latitude is ~11.1 m north
    n, e, d = geodetic_to_local(43.7001, 10.3, 0.0, ORIGIN)
    assert 11.0 < n < 11.2 and abs(e) < 1e-6 and abs(d) < 1e-4
    n, e, d = geodetic_to_local(43.7, 10.3001, 30.0, ORIGIN)
    assert abs(n) < 1e-3 and 7.9 < e < 8.1 and abs(d - 30.0) < 1e-3
    # 2D: (north, east); the tangent-plane drop is not a coordinate
    assert geodetic_to_local(43.7001, 10.3, 0.0, ORIGIN, dim=2).shape == (2,)


@pytest.mark.parametrize(
    "text,match",
    [
        ("91,0", "latitude 91.0 is not in"),
        ("0,400", "longitude"),
        ("1", "LAT,LON"),
        ("a,b", "expected LAT,LON"),
    ],
)
def test_origin_option_errors(text, match):
    with pytest.raises(InputError, match=match):
        parse_origin(text)


def _default_data() -> dict:
    with DEFAULT.open("rb") as fh:
        return tomllib.load(fh)


def _geodetic_twin(data: dict) -> dict:
    """The default problem with the beacon and start given geodetically about ORIGIN (their
    positions then differ from the metric file's by the ~1e-8 m of the inverse conversion)."""
    lat, lon, _ = local_to_geodetic([data["start"]["position"], data["beacon"]["position"]], ORIGIN)
    geo = json.loads(json.dumps(data))
    geo["origin"] = {"latitude": ORIGIN.latitude, "longitude": ORIGIN.longitude}
    geo["start"] = {"geodetic": [float(lat[0]), float(lon[0])], "velocity": [0.0, 0.0]}
    geo["beacon"] = {"geodetic": [float(lat[1]), float(lon[1])]}
    return geo


def test_problem_file_resolver():
    data = _default_data()
    pb = problem_from_dict(_geodetic_twin(data))
    assert pb.origin == ORIGIN
    np.testing.assert_allclose(pb.start_position, data["start"]["position"], atol=1e-6)
    np.testing.assert_allclose(pb.beacon, data["beacon"]["position"], atol=1e-6)
    # nothing geodetic: the mapping is returned as it is, no origin
    same, origin = resolve_problem_geodetic(data)
    assert same is data and origin is None


@pytest.mark.parametrize(
    "edit,match",
    [
        (lambda d: d.pop("origin"), r"beacon\.geodetic: needs an \[origin\] section"),
        (lambda d: d["start"].update(position=[0.0, 0.0]), r"either start\.position .* not both"),
        (lambda d: d["beacon"].update(geodetic=[43.7, 10.3, 5.0]), r"\[latitude, longitude\]"),
        (lambda d: d["beacon"].update(geodetic=[95.0, 10.3]), r"beacon\.geodetic: latitude 95"),
        (lambda d: d["origin"].update(lat=1.0), r"origin\.lat: unknown key"),
        (lambda d: d["origin"].pop("longitude"), r"origin\.longitude: missing"),
        (lambda d: d["origin"].update(altitude="x"), r"origin\.altitude: expected a finite"),
    ],
)
def test_problem_file_errors_name_the_field(edit, match):
    geo = _geodetic_twin(_default_data())
    edit(geo)
    with pytest.raises(ProblemError, match=match):
        problem_from_dict(geo)


def _toml(data: dict) -> str:
    """A tiny TOML writer for the problem mappings used here (tables of scalars/lists/tables)."""

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        return repr(v)

    return "\n".join(
        f"[{sec}]\n" + "\n".join(f"{k} = {val(v)}" for k, v in body.items()) + "\n"
        for sec, body in data.items()
    )


@pytest.mark.slow
def test_geodetic_problem_plans_the_same_path_as_its_metric_twin(tmp_path, capsys):
    """Acceptance: the same path to 1 mm; the report carries the origin; geodetic plan.

    The geodetic file is what a user writes (surveyed latitudes and longitudes); its metric
    twin has the positions converted once (written with repr, so both problems hold the same
    floats). The conversion's accuracy is checked by ``test_round_trip_and_the_ned_convention``.
    """
    geo = _default_data()
    geo["origin"] = {"latitude": ORIGIN.latitude, "longitude": ORIGIN.longitude}
    geo["start"] = {"geodetic": [43.70054, 10.29901], "velocity": [0.0, 0.0]}
    geo["beacon"] = {"geodetic": [43.7, 10.3]}
    metric = json.loads(json.dumps(geo))
    del metric["origin"]
    for sec in ("start", "beacon"):
        lat, lon = metric[sec].pop("geodetic")
        metric[sec]["position"] = [float(x) for x in geodetic_to_local(lat, lon, 0.0, ORIGIN, 2)]
    area = geo["limits"]["area"]  # keep the start inside the operating area
    assert area["x"][0] < metric["start"]["position"][0] < area["x"][1]
    (tmp_path / "metric.toml").write_text(_toml(metric))
    (tmp_path / "geo.toml").write_text(_toml(geo))
    small = ["--steps", "20", "--starts", "1", "--no-validate", "--quiet"]
    for name in ("metric", "geo"):
        code = main(["plan", str(tmp_path / f"{name}.toml"), "--out", str(tmp_path / name), *small])
        assert code == 0
    capsys.readouterr()
    a, b = read_csv(tmp_path / "metric" / "plan.csv"), read_csv(tmp_path / "geo" / "plan.csv")
    assert np.max(np.abs(a.p - b.p)) < 1e-3  # the acceptance: the same path to 1 mm
    rep = json.loads((tmp_path / "geo" / "report.json").read_text())
    assert rep["origin"] == ORIGIN.to_dict()
    assert "origin" not in json.loads((tmp_path / "metric" / "report.json").read_text())
    # the plan written back in geodetic form converts back to the plan
    text = (tmp_path / "geo" / "plan-geodetic.csv").read_text()
    assert text.splitlines()[0] == "t,latitude,longitude,speed"
    rows = np.loadtxt(tmp_path / "geo" / "plan-geodetic.csv", delimiter=",", skiprows=1)
    back = geodetic_to_local(rows[:, 1], rows[:, 2], np.zeros(len(rows)), ORIGIN, dim=2)
    np.testing.assert_allclose(back, b.p, atol=1e-6)


def test_beacon_geodetic_option(tmp_path, capsys):
    from obsplan.trajectory import generators as gen
    from obsplan.trajectory.sampled import write_csv

    path = write_csv(gen.circle(30.0, 1.5, 60.0).sample(0.5), tmp_path / "c.csv")
    lat, lon, _ = local_to_geodetic([[-50.0, 10.0]], ORIGIN)
    geo = f"{float(lat[0])!r},{float(lon[0])!r}"
    assert main(["analyze", str(path), "--json", "--beacon", "-50,10"]) == 0
    metric = json.loads(capsys.readouterr().out)
    args = ["analyze", str(path), "--json", "--beacon-geodetic", geo, "--origin", "43.7,10.3"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["origin"]["latitude"] == 43.7 and out["origin"]["frame"] == "NED"
    np.testing.assert_allclose(out["beacon"], [-50.0, 10.0], atol=1e-6)
    assert out["gramian"]["rank"] == metric["gramian"]["rank"]
    assert out["gramian"]["min_eig"] == pytest.approx(metric["gramian"]["min_eig"], rel=1e-6)
    assert main(["analyze", str(path), "--beacon-geodetic", geo]) == 2
    assert "needs --origin" in capsys.readouterr().err
    both = ["--beacon", "1,2", "--beacon-geodetic", geo, "--origin", "43.7,10.3"]
    assert main(["analyze", str(path), *both]) == 2
    assert "not both" in capsys.readouterr().err
    # a southern/western origin: negative values after the option need no '='
    assert main(["analyze", str(path), "--beacon-geodetic", "-33.8,-70.1", "--origin",
                 "-33.8,-70.1", "--json"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out)["origin"]["longitude"] == -70.1


def test_geodetic_problem_path_figure_is_a_map():
    from obsplan.planning.figures import plot_paths
    from obsplan.trajectory import generators as gen

    pb = problem_from_dict(_geodetic_twin(_default_data()))
    path = gen.circle(30.0, 1.0, 120.0, center=(-80.0, 30.0)).sample(1.0)
    ax = plot_paths({"planned": path}, pb).axes[0]
    assert ax.get_xlabel() == "y = east [m]" and ax.get_ylabel() == "x = north [m]"
    np.testing.assert_allclose(ax.lines[0].get_xdata(), path.p[:, 1])  # east across
