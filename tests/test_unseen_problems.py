"""benchmarks/unseen_problems.py: seeded problems of the suite's kinds, every one loadable."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from obsplan.planning import load_problem

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "unseen_problems.py"


def _script():
    spec = importlib.util.spec_from_file_location("unseen_problems", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_geometry_and_kind_is_written_but_the_ones_the_loader_rejects(tmp_path, capsys):
    mod = _script()
    assert mod.main(["--seed", "1", "--out", str(tmp_path / "a"), "--keep", "1.0"]) == 0
    files = sorted((tmp_path / "a").glob("*.toml"))
    # 6 geometries x 3 kinds, less lwo-condition on 3D range-only (its LWO matrix is rank
    # deficient: the loader refuses it)
    assert len(files) == len(mod.GEOMETRIES) * len(mod.KINDS) - 1
    assert not any("3d-range-lwo" in f.name for f in files)
    err = capsys.readouterr().err
    assert "skipped 3d-range, lwo-condition:" in err and "objective.kind" in err
    kinds = set()
    for f in files:
        pb = load_problem(f)
        kinds.add(pb.objective.kind)
        assert pb.dim == (3 if "-3d-" in f.name else 2)
        assert ("dvl-water" in pb.model.sensors) == ("2d-current" in f.name)
    assert kinds == set(mod.KINDS)


def test_the_seed_fixes_the_problems_and_nothing_is_replaced(tmp_path):
    mod = _script()
    mod.main(["--seed", "7", "--out", str(tmp_path / "a")])
    mod.main(["--seed", "7", "--out", str(tmp_path / "b")])
    mod.main(["--seed", "8", "--out", str(tmp_path / "c")])
    read = {d: {f.name: f.read_text() for f in (tmp_path / d).glob("*.toml")} for d in "abc"}
    assert read["a"] and read["a"] == read["b"]
    assert read["a"] != read["c"]
    mine = tmp_path / "a" / sorted(read["a"])[0]
    mine.write_text("# the user's file\n")
    mod.main(["--seed", "7", "--out", str(tmp_path / "a")])
    assert mine.read_text() == "# the user's file\n"


def test_edge_starts_are_near_the_area_and_the_surface_and_leave_the_default_alone(tmp_path):
    mod = _script()
    mod.main(["--seed", "3", "--out", str(tmp_path / "a")])
    mod.main(["--seed", "3", "--out", str(tmp_path / "e"), "--edge-start", "--keep", "1.0"])
    mod.main(["--seed", "3", "--out", str(tmp_path / "b")])
    a = {f.name: f.read_text() for f in (tmp_path / "a").glob("*.toml")}
    assert a == {f.name: f.read_text() for f in (tmp_path / "b").glob("*.toml")}
    files = sorted((tmp_path / "e").glob("*.toml"))
    assert len(files) == 17
    for f in files:
        pb = load_problem(f)
        p, area = pb.p0, pb.limits.area
        slack = min(p[0] - area.x[0], area.x[1] - p[0], p[1] - area.y[0], area.y[1] - p[1])
        assert 1.0 - 0.1 <= slack <= 5.0 + 0.1, f  # written to 0.1 m
        if pb.dim == 3:
            assert 0.5 - 0.1 <= p[2] - pb.limits.depth[0] <= 3.0 + 0.1, f


def test_the_wide_family_varies_the_vehicle_the_start_and_the_area(tmp_path):
    """``--wide`` problems all load, and over a seed they span other vehicles, far and moving
    starts and rectangular areas (what the default family never draws)."""
    mod = _script()
    kinds = [*mod.KINDS, "kf-position-std"]
    mod.main(["--seed", "4", "--out", str(tmp_path / "w"), "--wide", "--keep", "1.0", "--kinds"]
             + kinds)  # fmt: skip
    files = sorted((tmp_path / "w").glob("*.toml"))
    assert len(files) == len(mod.GEOMETRIES) * len(kinds) - 1  # no 3D range-only lwo
    pbs = [load_problem(f) for f in files]
    speeds = {pb.limits.speed for pb in pbs}
    assert len(speeds) > 10 and min(speeds) >= 0.5 and max(speeds) <= 2.0
    far = [np.linalg.norm((pb.p0 - np.asarray(pb.beacon, float))[:2]) for pb in pbs]
    assert min(far) >= 30.0 - 1e-6 and max(far) > 150.0
    assert any(np.linalg.norm(pb.v0) > 0 for pb in pbs)
    assert any(np.linalg.norm(pb.v0) == 0 for pb in pbs)
    assert any(pb.limits.area.x != pb.limits.area.y for pb in pbs)
    for pb in pbs:  # the start inside its area, moving slower than the bound
        a = pb.limits.area
        assert a.x[0] < pb.p0[0] < a.x[1] and a.y[0] < pb.p0[1] < a.y[1]
        assert np.linalg.norm(pb.v0) < pb.limits.speed
