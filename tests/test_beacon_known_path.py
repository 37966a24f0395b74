"""Planning the vehicle for a beacon on a known path (``[beacon] motion = "path"``).

The grid keeps the decision variables relative to the beacon's start ``b(0)``; every position the
objective and the distance limits see is relative to where the beacon is at that time. The tests
check that identity at arbitrary times, that a beacon path standing still plans exactly as the
fixed beacon, that the keep-out holds to the moving beacon on the continuous path, the refusal of
the objectives not built for it, and the command line end to end.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from obsplan import load_problem, plan
from obsplan.cli import main
from obsplan.core.errors import ProblemError
from obsplan.model.beacon import read_beacon_path
from obsplan.planning.beacon import plan_beacon
from obsplan.planning.plan import plan_moving_beacon
from obsplan.planning.problem.feasibility import range_extremes
from obsplan.planning.problem.parse import shipped_file
from obsplan.planning.problem.schema import OBJECTIVE_KINDS
from obsplan.planning.transcription.grid import Grid, apply_operator
from obsplan.trajectory.sampled import read_csv


def _localise(tmp_path: Path, rows: list[tuple[float, float, float]], **changes) -> Path:
    """The shipped free localisation problem with its beacon on the path ``rows`` (t, bx, by),
    written beside it; ``changes``: sections to update."""
    csv = tmp_path / "ship.csv"
    csv.write_text("t,bx,by\n" + "".join(f"{t:g},{x!r},{y!r}\n" for t, x, y in rows))
    data = tomllib.loads(shipped_file("localise").read_text())
    data["beacon"] = {"motion": "path", "path": "ship.csv"}
    for section, values in changes.items():
        data.setdefault(section, {}).update(values)
    toml = tmp_path / "p.toml"
    toml.write_text(_dump(data))
    return toml


def _dump(data: dict) -> str:
    """A minimal TOML writer for the problem mappings of these tests (tables of scalars,
    lists and inline tables)."""

    def val(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(v)

    return "".join(
        f"[{s}]\n" + "".join(f"{k} = {val(v)}\n" for k, v in tab.items()) for s, tab in data.items()
    )


#: small settings for the solves: coarse grid, one start, no Monte Carlo unless asked
SMALL = {"horizon": {"duration": 300.0, "steps": 60}, "objective": {"starts": 1}}


def test_the_grid_gives_positions_relative_to_the_beacon_where_it_is(tmp_path):
    rows = [(0.0, 30.0, -40.0), (70.0, 50.0, -10.0), (200.0, -20.0, 25.0), (700.0, 10.0, 90.0)]
    pb = load_problem(_localise(tmp_path, rows))
    grid = Grid.from_problem(pb)
    assert np.array_equal(grid.beacon, [30.0, -40.0])  # the start of the path
    rng = np.random.default_rng(3)
    W = rng.uniform(-1.0, 1.0, (3 * grid.n, grid.N))
    traj = grid.to_trajectory(W)  # absolute positions
    s = np.sort(rng.uniform(0.0, grid.N * grid.h, 40))
    Mp, cp, _, _ = grid.sample_operator(s)
    rel = apply_operator(Mp, cp, W.reshape(-1, order="F"), grid.n)
    k = np.clip(np.floor(s / grid.h).astype(int), 0, grid.N - 1)
    sig = (s - traj.t[k])[:, None]
    p = traj.p[k] + traj.v[k] * sig + 0.5 * traj.u[k] * sig**2  # the exact quadratic
    ship = read_beacon_path(tmp_path / "ship.csv", 2)
    # round-off only: positions of O(100 m) from sums of a few terms
    assert np.allclose(rel.T, p - ship.position(s), rtol=0, atol=1e-9)


def test_a_beacon_path_standing_still_plans_exactly_as_the_fixed_beacon(tmp_path):
    b0 = (12.5, -7.25)
    toml = _localise(tmp_path, [(0.0, *b0), (400.0, *b0), (900.0, *b0)])
    still = load_problem(toml).with_changes(**SMALL)
    fixed = load_problem("localise").with_changes(beacon={"position": list(b0)}, **SMALL)
    a, b = plan(still, validate=False), plan(fixed, validate=False)
    assert a.success and b.success
    for name in ("t", "p", "v", "u"):
        assert np.array_equal(getattr(a.trajectory, name), getattr(b.trajectory, name)), name
    assert a.solve.status == b.solve.status and a.solve.iterations == b.solve.iterations


@pytest.mark.slow
def test_the_keepout_holds_to_the_moving_beacon_on_the_continuous_path(tmp_path):
    # the ship crosses the area; the plan's information pulls the vehicle towards it
    rows = [(0.0, -60.0, -30.0), (150.0, 0.0, 10.0), (300.0, 60.0, -30.0)]
    toml = _localise(tmp_path, rows, limits={"min_range": 30.0}, **SMALL)
    pb = load_problem(toml)
    res = plan(pb, validate=False)
    assert res.trajectory is not None  # converged or not, the path flown keeps the limit
    ship = pb.beacon_path
    near, _ = range_extremes(res.trajectory, ship)
    # sampled independently of the exact extremes: every 0.05 s, the path's own quadratic
    t = np.arange(0.0, 300.0, 0.05)
    k = np.clip(
        np.searchsorted(res.trajectory.t, t, side="right") - 1, 0, res.trajectory.t.size - 2
    )
    tr = res.trajectory
    sig = (t - tr.t[k])[:, None]
    p = tr.p[k] + tr.v[k] * sig + 0.5 * tr.u[k] * sig**2
    sampled = float(np.min(np.linalg.norm(p - ship.position(t), axis=1)))
    # the keep-out's margins make the plan keep at least min_range; 1e-6 m is IPOPT's
    # constraint tolerance scaled by Lp, the sampling can only find a larger minimum
    assert sampled >= 30.0 - 1e-6 and near >= 30.0 - 1e-6 and sampled >= near - 1e-9
    assert res.metrics["planned"].closest_approach_m == pytest.approx(near, abs=1e-9)
    # and the limit matters: without it the plan passes closer to the ship
    free = plan(pb.with_changes(limits={"min_range": 0.0}), validate=False)
    assert free.trajectory is not None
    assert range_extremes(free.trajectory, ship)[0] < 30.0


@pytest.mark.parametrize("kind", sorted(set(OBJECTIVE_KINDS) - {"pcrb-position"}))
def test_objectives_not_built_for_a_known_path_are_refused_naming_objective_kind(tmp_path, kind):
    toml = _localise(tmp_path, [(0.0, 0.0, 0.0), (900.0, 50.0, 0.0)], objective={"kind": kind})
    pb = load_problem(toml)
    with pytest.raises(
        ProblemError, match=rf'^objective\.kind: "{kind}" .*supported: pcrb-position'
    ):
        plan(pb, validate=False)


@pytest.mark.slow
def test_plan_on_the_command_line_writes_the_plan_the_beacon_and_the_report(tmp_path, capsys):
    rows = [(0.0, 40.0, -60.0), (100.0, 70.0, -30.0), (200.0, 40.0, 0.0), (300.0, 70.0, 30.0)]
    toml = _localise(
        tmp_path,
        rows,
        horizon=SMALL["horizon"],
        objective={"starts": 1},
        validation={"runs": 4, "max_runs": 4, "dt": 1.0},
    )
    out = tmp_path / "out"
    code = main(["plan", str(toml), "--out", str(out), "--quiet"])
    report = json.loads((out / "report.json").read_text())
    assert code == (0 if report["solver"]["success"] else 1)
    assert {"plan.csv", "beacon.csv", "report.json", "path.png"} <= {p.name for p in out.iterdir()}
    assert {"planned", "lawnmower"} <= set(report["validation"])
    plan_csv = read_csv(out / "plan.csv")
    beacon = np.genfromtxt(out / "beacon.csv", delimiter=",", names=True)
    assert list(beacon.dtype.names) == ["t", "bx", "by", "vbx", "vby"]
    assert np.array_equal(beacon["t"], plan_csv.t)
    ship = read_beacon_path(tmp_path / "ship.csv", 2)
    assert np.allclose(np.column_stack([beacon["bx"], beacon["by"]]), ship.position(plan_csv.t))
    assert np.allclose(np.column_stack([beacon["vbx"], beacon["vby"]]), ship.velocity(plan_csv.t))


def test_the_shipped_ship_track_reads_its_csv_beside_it_and_a_copy_runs_anywhere(tmp_path):
    pb = load_problem("ship-track")
    assert pb.beacon_motion.motion == "path" and pb.objective.kind == "pcrb-position"
    csv = shipped_file("ship-track").parent / "ship-track.csv"
    assert np.array_equal(pb.beacon_path.positions, read_beacon_path(csv, 2).positions)
    copy = tmp_path / "elsewhere" / "mine.toml"
    copy.parent.mkdir()
    assert main(["problems", "copy", "ship-track", str(copy)]) == 0
    assert np.array_equal(load_problem(copy).beacon_path.positions, pb.beacon_path.positions)


def test_the_planned_beacon_flow_refuses_a_known_path_naming_the_motion():
    pb = load_problem(shipped_file("ship-track.toml"))
    with pytest.raises(ProblemError, match=r'beacon\.motion.*"path".*obsplan\.plan'):
        plan_moving_beacon(pb, plan_beacon)
