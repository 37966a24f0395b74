"""Tables 1–3: every row, every sensor configuration, paper's verdict and ours; exact arguments.

``EXPECTED`` holds the mathematically correct verdicts (derived in docs/paper-discrepancies.md),
written here independently of ``obsplan.paper.tables``; ``PAPER`` is a second transcription of the
paper's tables. Rank verdicts do not depend on dt, so the tables run in quick mode (dt = 0.1 s).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from obsplan.cli import main
from obsplan.model.vehicle import make_model
from obsplan.observability.gramian import gramian, gramian_report
from obsplan.observability.lwo import lwo_structural_max_rank
from obsplan.paper import tables as paper
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory

Y, N = True, False
# ours, per row key: ((LWO, O) per column)
EXPECTED: dict[str, tuple[tuple[bool, bool], ...]] = {
    "t1-2d-straight-radial": ((N, N),),
    "t1-2d-parabola-beacon": ((N, N),),  # rank 3 on the whole segment (tests/test_paper_record.py)
    "t1-2d-straight-const-accel": ((Y, N),),
    "t1-2d-straight-varying": ((Y, N),),
    "t1-2d-straight-const-speed": ((N, N),),
    "t1-2d-circle": ((Y, Y),),
    "t1-2d-circle-radial": ((N, Y),),
    "t1-2d-circle-straight-accel": ((Y, Y),),
    "t1-2d-circle-straight-const": ((N, Y),),
    "t1-3d-straight-radial": ((N, N),),
    "t1-3d-straight-not-radial": ((N, N),),
    "t1-3d-circle-plane": ((N, N),),
    "t1-3d-circle-out": ((N, N),),
    "t1-3d-circle-zsine": ((N, Y),),
    "t1-3d-circle-zsine-lap": ((N, N),),
    "t1-3d-circle-zstraight": ((N, N),),
    "t1-3d-circle-zsine-straight": ((N, Y),),
    "t1-current-2d-circle": ((N, N),),
    "t1-current-3d-zsine": ((N, N),),
    # Table 2: range | range + DVL
    "t2-2d-straight-radial": ((N, N), (N, N)),
    "t2-2d-straight-const-accel": ((Y, N), (Y, N)),
    "t2-2d-straight-const-speed": ((N, N), (Y, N)),
    "t2-2d-circle": ((Y, Y), (Y, Y)),
    "t2-2d-circle-radial": ((N, Y), (N, Y)),
    "t2-2d-circle-straight-accel": ((Y, Y), (Y, Y)),
    "t2-2d-circle-straight-const": ((N, Y), (Y, Y)),
    "t2-3d-straight-radial": ((N, N), (N, N)),
    "t2-3d-straight-not-radial": ((N, N), (N, N)),
    "t2-3d-circle-plane": ((N, N), (N, N)),
    "t2-3d-circle-out": ((N, N), (Y, N)),
    "t2-3d-circle-zsine": ((N, Y), (Y, Y)),
    "t2-3d-circle-zsine-straight": ((N, Y), (N, Y)),
    # Table 3: bottom lock | water profiling, with current
    "t3-2d-circle": ((N, N), (Y, Y)),
    "t3-2d-straight-const-accel": ((N, N), (Y, N)),
    "t3-2d-straight-const-speed": ((N, N), (N, N)),
    "t3-2d-straight-radial": ((N, N), (N, N)),
    "t3-3d-circle-out": ((N, N), (N, N)),
    "t3-3d-straight-not-radial": ((N, N), (N, N)),
    "t3-3d-circle-zsine": ((N, N), (N, Y)),
}

# The paper's tables, transcribed again: (table, dim, motion) -> (LWO, O) per column.
PAPER: dict[tuple[int, int, str], tuple[tuple[bool, bool], ...]] = {
    (1, 2, "Straight (radial)"): ((N, N),),
    (1, 2, "Straight (not radial)"): ((Y, N),),
    (1, 2, "Circular"): ((Y, Y),),
    (1, 2, "Circular + Straight (radial)"): ((Y, Y),),
    (1, 2, "Circular + Straight (not radial)"): ((Y, Y),),
    (1, 3, "Straight (radial and not radial)"): ((N, N),),
    (1, 3, "Circular"): ((N, N),),
    (1, 3, "Circular in (x, y) and suff. exciting along z axis"): ((N, Y),),
    (1, 3, "Circular in (x, y) and suff. exciting along z axis + Straight"): ((N, Y),),
    (1, 2, "2D/3D with ocean currents"): ((N, N),),
    (1, 3, "2D/3D with ocean currents"): ((N, N),),
    (2, 2, "Straight (radial)"): ((N, N), (N, N)),
    (2, 2, "Straight (not radial)"): ((Y, N), (Y, N)),
    (2, 2, "Circular"): ((Y, Y), (Y, Y)),
    (2, 2, "Circular + Straight (radial)"): ((N, Y), (N, Y)),
    (2, 2, "Circular + Straight (not radial)"): ((Y, Y), (Y, Y)),
    (2, 3, "Straight (radial and not radial)"): ((N, N), (N, N)),
    (2, 3, "Circular (in the plane of the beacon)"): ((N, N), (N, N)),
    (2, 3, "Circular (out of the plane of the beacon)"): ((N, N), (Y, N)),
    (2, 3, "Circular in (x, y) and suff. excit. along z axis"): ((N, Y), (Y, Y)),
    (2, 3, "Circular in (x, y) and suff. excit. along z axis + Straight"): ((N, Y), (N, Y)),
    (3, 2, "Straight and circular"): ((N, N), (Y, N)),
    (3, 3, "Straight and circular"): ((N, N), (N, N)),
}


@pytest.fixture(scope="module")
def rows() -> tuple[paper.TableRow, ...]:
    return paper.all_rows(quick=True)


def test_every_row_is_checked(rows):
    assert [r.key for r in rows] == list(EXPECTED)
    assert len({r.key for r in rows}) == len(rows)


def test_our_verdicts_every_row_every_column(rows):
    for r in rows:
        got = tuple((c.ours.lwo, c.ours.o) for c in r.cells)
        assert got == EXPECTED[r.key], r.key


def test_paper_transcription_and_coverage(rows):
    covered = set()
    for r in rows:
        key = (r.table, r.dim, r.motion)
        if all(c.paper is None for c in r.cells):
            # ours only: rows that show a condition the paper leaves implicit
            assert r.key in (
                "t1-2d-parabola-beacon",
                "t1-3d-circle-zsine-lap",
                "t3-3d-circle-zsine",
            )
            continue
        assert key in PAPER, key
        assert tuple((c.paper.lwo, c.paper.o) for c in r.cells) == PAPER[key], r.key
        covered.add(key)
    assert covered == set(PAPER)  # every row of the three tables is recomputed


def test_disagreements_are_explained(rows):
    disagree = [(r.key, c.column) for r in rows for c in r.cells if c.agrees is False]
    for r in rows:
        for c in r.cells:
            if c.agrees is False or c.paper is None:
                assert c.notes and all(n in paper.NOTES for n in c.notes), (r.key, c.column)
            if c.agrees is False:
                assert c.paper != c.ours and c.differing
    # the disagreements, exactly: the ones docs/paper-discrepancies.md lists
    assert sorted(disagree) == sorted(
        [
            ("t1-2d-straight-const-speed", "range"),
            ("t1-2d-circle-radial", "range"),
            ("t1-2d-circle-straight-const", "range"),
            ("t1-3d-circle-zstraight", "range"),
            ("t2-2d-straight-const-speed", "range"),
            ("t2-2d-circle-straight-const", "range"),
            ("t3-2d-circle", "range + DVL (water profiling)"),
            ("t3-2d-straight-const-speed", "range + DVL (water profiling)"),
            ("t3-2d-straight-radial", "range + DVL (water profiling)"),
        ]
    )


def test_table1_contradicts_table2_on_circle_plus_radial(rows):
    by_key = {r.key: r for r in rows}
    t1, t2 = by_key["t1-2d-circle-radial"].cells[0], by_key["t2-2d-circle-radial"].cells[0]
    assert t1.paper.lwo != t2.paper.lwo  # the paper disagrees with itself...
    assert t1.ours == t2.ours  # ...we compute the same thing twice
    assert t1.evidence.lwo_min_rank == 2  # the radial leg: p, v, u collinear


def test_rank_evidence_of_straight_lines(rows):
    ev = {r.key: r.cells[0].evidence for r in rows if r.table == 1}
    # range-only Gramian rank: 2 if u = 0, 3 if u constant, 4 if varying (2D and 3D)
    assert ev["t1-2d-straight-const-speed"].gramian_rank == 2
    assert ev["t1-2d-straight-const-accel"].gramian_rank == 3
    assert ev["t1-2d-straight-varying"].gramian_rank == 4
    assert ev["t1-3d-straight-not-radial"].gramian_rank == 4
    assert ev["t1-2d-straight-const-speed"].lwo_min_rank == 3  # row (0, 3u) vanishes


def test_claims_of_sections_6_and_7():
    got = {c.key: c.agrees for c in paper.claims(quick=True)}
    assert got == {
        "6.1-gramian-2d-straight": True,
        "6.2-lwo-3d-straight": True,
        "6.2-gramian-3d-straight": False,
        "7.1-fig3-lwo": False,
        "7.1-fig3-smooth-turns": False,
        "7.2-fig5-gramian": False,
        "7.2-fig6-gramian": False,
        "4.2-windows": False,
        "6.3-water-circle": False,
    }
    assert all(c.notes or c.agrees for c in paper.claims(quick=True))


# ------------------------------------------------------------------ exact arguments
def _O(p, v, u):
    """Frozen-input observability matrix of eq. 13 (range only)."""
    z = sp.zeros(1, len(p))
    return sp.Matrix.vstack(
        sp.Matrix.hstack(p.T, z),
        sp.Matrix.hstack(v.T, p.T),
        sp.Matrix.hstack(u.T, 2 * v.T),
        sp.Matrix.hstack(z, 3 * u.T),
    )


def test_symbolic_determinants_of_section_5_1():
    x, m, q, vx, ux, t, w, rho = sp.symbols("x m q v_x u_x t omega rho", real=True)
    line = _O(sp.Matrix([x, m * x + q]), sp.Matrix([vx, m * vx]), sp.Matrix([ux, m * ux]))
    assert sp.expand(line.det() - (-3 * ux**2 * q**2)) == 0  # eq. 36
    p = sp.Matrix([rho * sp.cos(w * t), rho * sp.sin(w * t)])
    circ = _O(p, p.diff(t), p.diff(t, 2))
    assert sp.simplify(circ.det() - 6 * w**4 * rho**4) == 0  # section 5.1, circle


def test_symbolic_dvl_condition_for_circle_with_sine_z():
    """Note 'dvl-zsine-condition': with DVL, O is full rank iff det[p; v; u] != 0."""
    t, w, rho, A, W, z0 = sp.symbols("t omega rho A Omega z0", real=True)
    p = sp.Matrix([rho * sp.cos(w * t), rho * sp.sin(w * t), z0 + A * sp.sin(W * t)])
    det = sp.Matrix.hstack(p, p.diff(t), p.diff(t, 2)).det()
    want = w * rho**2 * (w**2 * z0 + A * (w**2 - W**2) * sp.sin(W * t))
    assert sp.simplify(det - want) == 0
    # with DVL rows [0, I], O reduces to blocks [p; v; u] and I: rank = rank[p; v; u] + 3
    pv, vv, uv = (sp.Matrix(sp.symbols(f"{s}x {s}y {s}z")) for s in "pvu")
    O = _O(pv, vv, uv).col_join(sp.Matrix.hstack(sp.zeros(3), sp.eye(3)))
    minor = O.extract([0, 1, 2, 4, 5, 6], list(range(6)))
    assert sp.expand(minor.det() - sp.Matrix.hstack(pv, vv, uv).det()) == 0


def test_range_only_3d_lwo_is_structurally_impossible():
    assert lwo_structural_max_rank(make_model(3, "range")) == 4  # < 6 (section 5.2)
    assert lwo_structural_max_rank(make_model(3, "range,dvl-water", current=True)) == 7  # < 9


def _lines(dim: int, accel) -> tuple[Trajectory, Trajectory]:
    e = np.eye(dim)[0]
    radial_p0 = -100 * e
    off_p0 = radial_p0 + 60 * np.eye(dim)[1]

    def line(p0: np.ndarray) -> Trajectory:
        return gen.straight(p0, e, 1.0, accel=accel, duration=40).sample(0.1)

    return line(radial_p0), line(off_p0)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(
    ("accel", "rank"), [(0.0, 2), (0.02, 3), (gen.sine_profile(0.02, 0.01, 10), 4)]
)
def test_straight_gramian_rank_bound_and_beacon_independence(dim, accel, rank):
    radial, off = _lines(dim, accel)
    model = make_model(dim, "range")
    G = gramian(radial, model)
    # (a) the Gramian depends on the inputs only: not on p0 (radial or not) nor on the beacon
    np.testing.assert_allclose(gramian(off, model), G, rtol=1e-12, atol=1e-12 * np.abs(G).max())
    moved = make_model(dim, "range", beacon=np.full(dim, 7.0))
    np.testing.assert_allclose(gramian(off, moved), G, rtol=1e-12, atol=1e-12 * np.abs(G).max())
    # (b) every row of C Phi lies in span{(e,0,0,0), (0,e,0,0), (0,0,1,0), (0,0,0,1)}
    m = 2 * dim + 2
    W = np.zeros((m, 4))
    W[0, 0] = W[dim, 1] = W[m - 2, 2] = W[m - 1, 3] = 1.0
    P = W @ W.T
    assert np.abs(G - P @ G @ P).max() <= 1e-14 * np.abs(G).max()
    assert gramian_report(off, model).rank == rank


def test_current_bottom_lock_kernel_and_water_profiling_circle():
    circ = gen.circle(50, 2.6, 120).sample(0.1)
    bottom = make_model(2, "range,dvl-bottom", current=True)
    G = gramian(circ, bottom)
    w = np.array([0.3, -1.1])
    k = np.concatenate([np.zeros(2), w, -w, np.zeros(2)])  # (w, -w) in (v, v_f)
    assert np.linalg.norm(G @ k) <= 1e-13 * np.linalg.norm(G) * np.linalg.norm(k)
    water = make_model(2, "range,dvl-water", current=True)
    assert gramian_report(circ, water).full_rank  # fact (c): Table 3 says NO


def test_constant_vertical_acceleration_is_not_enough():
    """Note 'straight-z': constant u_z != 0 gives d_z ∝ t², collinear with the |ν0|² column."""
    c = gen.circle(50, 2.6, 180, z=4.0).sample(0.1)
    u = c.u.copy()
    u[:, 2] = 0.001
    tr = Trajectory.from_inputs(c.t, c.p[0], c.v[0], u)
    assert gramian_report(tr, make_model(3, "range")).rank == 7


# ------------------------------------------------------------------ rendering and CLI
def test_render_marks_every_disagreement_and_numbers_notes(rows):
    cl = paper.claims(quick=True)
    text = paper.render_tables(rows, cl, paper.structural(quick=True))
    n_dis = sum(c.agrees is False for r in rows for c in r.cells)
    assert text.count("≠ (") == n_dis
    keys = dict.fromkeys([n for r in rows for n in r.notes] + [n for c in cl for n in c.notes])
    for i in range(1, len(keys) + 1):
        assert f"\n[{i}] " in text
    for r in rows:
        assert r.motion in text and r.trajectory in text
    # the exact structural section: per-interval ranks beside the conditioning times
    section = text[text.index("Exact structural ranks") :]
    for r in paper.structural(quick=True):
        assert r.configuration in section and ", ".join(map(str, r.ranks)) in section
    assert "full_rank_from_t, tol 1e-10" in section


def test_structural_rows_are_the_exact_and_conditioning_times():
    for r, (_, _, name, sensors, current) in zip(
        paper.structural(quick=True), paper.STRUCTURAL_CONFIGS, strict=True
    ):
        tr = paper.scenario(name, True)
        model = make_model(tr.dim, sensors, current=current)
        assert r.full_rank_from_t_exact == tr.t[r.full_rank_interval_exact + 1]
        assert r.ranks[-1] == model.state_dim + 2 and r.ranks == tuple(sorted(r.ranks))
        for tol, t in r.conditioning:  # the stable full_rank_from_t at each tolerance
            assert t == gramian_report(tr, model, tol=tol).full_rank_from_t
            assert t > r.full_rank_from_t_exact


def test_paper_report_is_json(rows):
    rep = paper.paper_report(quick=True)
    json.dumps(rep)
    s = rep["summary"]
    assert s["rows"] == len(rows) == sum(len(v) for v in rep["tables"].values())
    assert s["cells_disagreeing"] == 9 and s["cells_not_in_paper"] == 4
    assert s["claims_disagreeing"] == 7
    assert [r["key"] for r in rep["structural"]] == [k for k, *_ in paper.STRUCTURAL_CONFIGS]
    assert set(rep["record"]) == {"smooth_turns", "windows", "expanded_water_circle"}
    first = rep["tables"]["1"][0]["cells"][0]
    assert set(first) >= {"paper", "ours", "agrees", "evidence", "notes"}


def test_cli_paper_writes_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "paper"
    argv = ["paper", "--quick", "--out", str(out), "--no-figures", "--quiet"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "Table 1" in printed and "Exact structural ranks" in printed
    assert (out / "tables.txt").read_text().startswith("Table 1")
    assert json.loads((out / "tables.json").read_text())["summary"]["rows"] == len(EXPECTED)
    assert main(argv) == 2
    assert "--force" in capsys.readouterr().err
    assert main([*argv, "--force", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["dt"] == 0.1
