"""The paper's record, exact: the seven statements of docs/paper-discrepancies.md ("Exact record"),
each proved symbolically (sympy) or computed exactly (rationals), and the smooth paths behind them.

1. smooth lawn-mower turns: det O = 3ω⁴r²(2r² + 2cr cos φ − c² sin²φ), two zeros per turn;
2. held input: O(φ_τ(x)) Dφ_τ = T(τ) O(x), so d/dt det O = 0 and sampling is exact for CSVs;
3. DVL on straight lines: Gramian rank <= n + 3;
4. Table 3 water-profiling circle: the expanded augmentation has rank 8 of 11;
5. short windows of eq. 27 are nearly singular (exact λ_min 3.3e-15, equilibrated);
6. (tests/test_structural.py) exact structural interval vs conditioning time;
7. a constant-acceleration parabola through the beacon is rank deficient on the whole segment.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from test_paper_tables import _O

from obsplan.core.errors import ConfigError, InputError
from obsplan.model.vehicle import make_model
from obsplan.observability.lwo import lwo_matrix_function, lwo_path_report, lwo_report
from obsplan.observability.scaling import RANK_TOL
from obsplan.observability.structural import exact_gramian, exact_rank, exact_rank_profile
from obsplan.paper import tables as paper
from obsplan.trajectory import generators as gen

DOC = Path(__file__).resolve().parents[1] / "docs" / "paper-discrepancies.md"
O_range = _O  # the frozen-input matrix of eq. 13 (range only), rows of orders 0..3


# ------------------------------------------------------------------ 1. smooth lawn-mower turns
def turn_factor(c: float, r: float, psi: float) -> float:
    return 2 * r**2 + 2 * c * r * math.cos(psi) - c**2 * math.sin(psi) ** 2


def test_turn_determinant_closed_form_and_its_zeros():
    c, r, w, phi = sp.symbols("c r omega phi", positive=True)
    p = sp.Matrix([c + r * sp.cos(phi), r * sp.sin(phi)])  # centre (c, 0), beacon at the origin
    v = r * w * sp.Matrix([-sp.sin(phi), sp.cos(phi)])
    u = -r * w**2 * sp.Matrix([sp.cos(phi), sp.sin(phi)])  # the input frozen at p''
    det = O_range(p, v, u).det()
    factor = 2 * r**2 + 2 * c * r * sp.cos(phi) - c**2 * sp.sin(phi) ** 2
    assert sp.simplify(det - 3 * w**4 * r**2 * factor) == 0
    assert sp.simplify(det.subs(c, 0) - 6 * w**4 * r**4) == 0  # eq. 37 on the centred circle
    # as a quadratic in x = cos(phi): c² x² + 2 c r x + 2 r² - c² = 0
    x = sp.symbols("x")
    quad = sp.expand(factor.subs(sp.sin(phi) ** 2, 1 - x**2).subs(sp.cos(phi), x))
    assert sp.expand(quad - (c**2 * x**2 + 2 * c * r * x + 2 * r**2 - c**2)) == 0
    for root in ((-r + sp.sqrt(c**2 - r**2)) / c, (-r - sp.sqrt(c**2 - r**2)) / c):
        assert sp.simplify(quad.subs(x, root)) == 0
    # c > r: one root in (-1, 1), so two zeros on the circle; c < r: no real root, no zero
    for cc, rr in ((91.79, 15.0), (2.0, 1.0)):
        x0 = (math.sqrt(cc**2 - rr**2) - rr) / cc
        assert -1 < x0 < 1 and (-rr - math.sqrt(cc**2 - rr**2)) / cc < -1
        assert abs(turn_factor(cc, rr, math.acos(x0))) < 1e-9 * cc**2
    assert all(turn_factor(0.5, 1.0, s) > 0 for s in np.linspace(0, 2 * np.pi, 721))


def test_every_smooth_turn_of_the_paper_lawnmower_has_two_isolated_zeros():
    path = gen.paper_lawnmower(2)
    rep = lwo_path_report(path, make_model(2, "range"))
    zeros = [d for d in rep.drops if d.isolated]
    turns = [1, 3, 5, 7]  # pieces: accelerating leg, then (turn, leg) x 4
    assert sorted({d.piece for d in zeros}) == turns
    assert all(sum(d.piece == i for d in zeros) == 2 for i in turns)
    assert all(d.rank == 3 for d in zeros)
    for d in zeros:
        p, v, a = (x[0] for x in path.evaluate(d.t_start, piece=d.piece))
        centre = p + a * (v @ v) / (a @ a)
        r, c = float(np.linalg.norm(p - centre)), float(np.linalg.norm(centre))
        q = p - centre
        psi = math.atan2(
            centre[0] * q[1] - centre[1] * q[0], centre @ q
        )  # from the centre's direction
        assert r == pytest.approx(15.0, rel=1e-12)
        # the zero is a root of the closed form (relative to its scale 2r² + 2cr + c²)
        assert abs(turn_factor(c, r, psi)) <= 1e-9 * (c + r) ** 2
    # first turn, centre (80, 45), r = 15 m: phi = -5.24 and 63.96 deg from the x axis
    c, r = math.hypot(80.0, 45.0), 15.0
    psi0 = math.degrees(math.acos((math.sqrt(c**2 - r**2) - r) / c))
    want = sorted(math.degrees(math.atan2(45.0, 80.0)) + s * psi0 for s in (-1, 1))
    st = paper.smooth_turns(quick=True)
    assert st.first_turn_deg == pytest.approx(want, abs=1e-6)
    assert [round(x, 2) for x in want] == [-5.24, 63.96]
    assert st.n_turns == 4 and st.zeros_per_turn == 2 and len(st.zeros) == 8
    assert st.leg_ranks == (3, 2, 3, 3)  # constant-speed legs; the third runs through the beacon


@pytest.mark.parametrize("dt", [0.1, 0.01])
def test_held_input_turns_jump_across_zero_without_vanishing(dt):
    """The generators' (held-input) lawn-mower: full rank at every sample of every turn; det O
    changes sign between two samples (at an input switch) near each zero of the smooth turn."""
    path = gen.paper_lawnmower(2)
    tr = path.sample(dt)
    model = make_model(2, "range")
    ranks = lwo_report(tr, model).ranks
    bp = path.breakpoints
    fn = lwo_matrix_function(model)
    for i in (1, 3, 5, 7):
        sel = np.flatnonzero((tr.t[:-1] >= bp[i]) & (tr.t[1:] <= bp[i + 1]))
        assert np.all(ranks[sel] == 4)
        det = [np.linalg.det(np.asarray(fn(np.r_[tr.p[k], tr.v[k]], tr.u[k]))) for k in sel]
        assert np.sum(np.diff(np.sign(det)) != 0) == 2


# ------------------------------------------------------------------ 2. held input: exact sampling
def _symbolic_O(dim: int, sensors: tuple[str, ...], current: bool):
    """All rows (orders 0..K) of eq. 9 for the half-squared range and the other sensors."""
    p = sp.Matrix(sp.symbols(f"p0:{dim}"))
    v = sp.Matrix(sp.symbols(f"v0:{dim}"))
    vf = sp.Matrix(sp.symbols(f"f0:{dim}")) if current else sp.zeros(dim, 1)
    u = sp.Matrix(sp.symbols(f"u0:{dim}"))
    x = sp.Matrix.vstack(p, v, vf) if current else sp.Matrix.vstack(p, v)
    f = sp.Matrix.vstack(v + vf, u, sp.zeros(dim, 1)) if current else sp.Matrix.vstack(v, u)
    outs = [(p.T * p)[0] / 2]
    if "dvl-bottom" in sensors:
        outs += list(v + vf)
    if "dvl-water" in sensors:
        outs += list(v)
    if "depth" in sensors:
        outs.append(p[dim - 1])
    K = 4  # ∇L^4 y = ∇(3|u|²) = 0; DVL and depth rows vanish sooner
    blocks = []
    for h in outs:
        L, rows = h, []
        for _ in range(K):
            rows.append(sp.Matrix([L]).jacobian(x))
            L = (sp.Matrix([L]).jacobian(x) * f)[0]
        assert sp.Matrix([L]).jacobian(x) == sp.zeros(1, len(x))  # the Taylor sum is finite
        blocks.append(rows)
    return x, u, f, blocks


@pytest.mark.parametrize(
    ("dim", "sensors", "current"),
    [
        (2, ("range",), False),
        (3, ("range",), False),
        (2, ("range", "dvl-bottom"), False),
        (2, ("range", "dvl-water"), True),
        (3, ("range", "depth", "dvl-bottom"), True),
    ],
)
def test_held_input_O_later_is_an_invertible_transform_of_O_at_the_start(dim, sensors, current):
    """O(φ_τ(x)) Dφ_τ = T(τ) O(x), T unit upper triangular per output (Taylor shift), det Dφ = 1."""
    x, u, f, blocks = _symbolic_O(dim, sensors, current)
    tau = sp.symbols("tau")
    n = dim
    phi = sp.Matrix(x)
    vel = x[n : 2 * n, :] + (x[2 * n : 3 * n, :] if current else sp.zeros(n, 1))
    phi[:n, 0] = x[:n, 0] + vel * tau + u * tau**2 / 2  # exact flow of the double integrator
    phi[n : 2 * n, 0] = x[n : 2 * n, 0] + u * tau
    D = phi.jacobian(x)
    assert sp.simplify(D.det()) == 1
    sub = dict(zip(list(x), list(phi), strict=True))
    for rows in blocks:
        K = len(rows)
        later = sp.Matrix.vstack(*(r.subs(sub, simultaneous=True) for r in rows)) * D
        T = sp.Matrix(K, K, lambda i, j: tau ** (j - i) / sp.factorial(j - i) if j >= i else 0)
        assert sp.expand(later - T * sp.Matrix.vstack(*rows)) == sp.zeros(K, len(x))


def test_det_O_is_constant_on_a_hold_interval_2d_range():
    p0 = sp.Matrix(sp.symbols("px py"))
    v0 = sp.Matrix(sp.symbols("vx vy"))
    u = sp.Matrix(sp.symbols("ux uy"))
    t = sp.symbols("t")
    det = O_range(p0 + v0 * t + u * t**2 / 2, v0 + u * t, u).det()
    assert sp.expand(sp.diff(det, t)) == 0  # d/dt det O = 0 with the input held


def test_held_input_csv_rank_is_the_same_inside_every_hold_interval():
    """Numeric counterpart: O at interior points of each interval, from the exact ZOH motion,
    has the determinant of O at the interval's start (to round-off)."""
    rng = np.random.default_rng(7)
    tr = gen.circle(50.0, 2.6, 20.0, center=(30.0, 10.0)).sample(0.5)
    fn = lwo_matrix_function(make_model(2, "range"))
    for k in rng.integers(0, tr.n_samples - 1, 10):
        h = tr.t[k + 1] - tr.t[k]
        d0 = np.linalg.det(np.asarray(fn(np.r_[tr.p[k], tr.v[k]], tr.u[k])))
        for s in rng.uniform(0, h, 3):
            x = np.r_[tr.p[k] + tr.v[k] * s + 0.5 * tr.u[k] * s**2, tr.v[k] + tr.u[k] * s]
            # entries are products of O(100 m) positions: relative agreement to ~1e-12
            assert np.linalg.det(np.asarray(fn(x, tr.u[k]))) == pytest.approx(d0, rel=1e-9)


def test_path_check_finds_the_zeros_a_sampled_test_misses():
    """Note 'dvl-zsine-condition': a z oscillation about the beacon's plane, with DVL, loses rank
    where sin(Ωt) = 0; the held-input samples do not."""
    path = gen.circle_z(50.0, 2.6, 180.0, z0=0.0, z_motion="sine", z_amp=5.0, z_period=90.0)
    model = make_model(3, "range,dvl")
    rep = lwo_path_report(path, model)
    assert not rep.along_trajectory
    assert rep.zeros == pytest.approx([0.0, 45.0, 90.0, 135.0, 180.0], abs=1e-6)
    assert lwo_report(path.sample(0.1), model).along_trajectory
    lifted = gen.circle_z(50.0, 2.6, 180.0, z0=10.0, z_motion="sine", z_amp=5.0, z_period=90.0)
    assert lwo_path_report(lifted, model).along_trajectory  # ω²|z0| > A|ω² - Ω²|
    centred = lwo_path_report(gen.circle(50.0, 2.6, 120.0), make_model(2, "range"))
    assert centred.along_trajectory and centred.min_rank == 4  # det O = 6ω⁴ρ⁴ (eq. 37)
    flat3d = lwo_path_report(gen.circle(50.0, 2.6, 60.0, z=5.0), make_model(3, "range"))
    assert [(d.t_start, d.t_end, d.rank) for d in flat3d.drops] == [(0.0, 60.0, 4)]  # eq. 38
    legs = lwo_path_report(gen.lawnmower((0.0, 30.0), 40.0, 10.0, 2, 1.0), make_model(2))
    assert [(d.piece, d.rank, d.isolated) for d in legs.drops if not d.isolated] == [
        (0, 3, False),
        (2, 3, False),
    ]  # constant-speed legs: deficient on the whole piece


def test_paths_sample_to_held_input_trajectories():
    """Chord inputs: the samples have the path's velocities; midpoint inputs on a
    constant-acceleration piece: the samples lie on the path, the inputs are its acceleration."""
    chord = [
        gen.circle(50, 2.6, 30, center=(3, 4), phase=0.3),
        gen.circle(50, 2.6, 30, z=5.0),
        gen.circle_z(50, 2.6, 30, z0=1.0, z_amp=5.0, z_period=90.0, z_phase=0.2),
        gen.circle_z(50, 2.6, 30, z0=4.0, z_motion="straight", z_speed=-0.01),
        gen.paper_lawnmower(2),
        gen.paper_lawnmower(3),
    ]
    for path in chord:
        tr = path.sample(0.1)
        assert tr.t[-1] == path.duration and tr.dim == path.dim
        np.testing.assert_allclose(tr.v, path.evaluate(tr.t)[1], rtol=0, atol=1e-9)
    midpoint = [
        gen.parabola((0.0, 1.0), (1.0, 0.0), (0.0, 0.5), duration=4.0),
        gen.straight((-100.0, 60.0, 5.0), (1.0, 1.0, 0.0), 0.1, accel=0.02, duration=30.0),
        gen.straight((0.0, 0.0), (1.0, 0.0), 1.0, accel=[0.1, -0.2, 0.0, 0.3], duration=8.0),
    ]
    for path in midpoint:
        tr = path.sample(0.5)
        p, v, a = path.evaluate(tr.t)
        np.testing.assert_allclose(tr.p, p, rtol=0, atol=1e-9)
        np.testing.assert_allclose(tr.v, v, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(tr.u[:-1], path.evaluate(tr.t[:-1] + 0.25)[2])


def test_path_derivatives_and_pieces():
    path = gen.paper_lawnmower(3)
    assert path.dim == 3 and path.duration == pytest.approx(path.breakpoints[-1])
    t = np.linspace(1.0, path.duration - 1.0, 400)
    h = 1e-5
    p1, v1, a1 = path.evaluate(t - h)
    p2, v2, a2 = path.evaluate(t + h)
    _, v, a = path.evaluate(t)
    inside = np.all(np.abs(path.breakpoints[:, None] - t[None]) > 2 * h, axis=0)
    # central differences: O(h²) truncation, O(eps/h) round-off on 100 m positions
    np.testing.assert_allclose(((p2 - p1) / (2 * h))[inside], v[inside], atol=1e-6)
    np.testing.assert_allclose(((v2 - v1) / (2 * h))[inside], a[inside], atol=1e-6)
    # a piece's own formulas at its end: the turn's acceleration, not the next leg's zero
    _, _, a_end = path.evaluate(path.breakpoints[2], piece=1)
    assert np.linalg.norm(a_end) == pytest.approx(2.0**2 / 15.0)
    back = pickle.loads(pickle.dumps(path))
    np.testing.assert_array_equal(back.evaluate(t)[0], path.evaluate(t)[0])
    with pytest.raises(ConfigError, match="piece"):
        path.evaluate(1.0, piece=99)
    with pytest.raises(InputError, match="3D"):
        lwo_path_report(path, make_model(2))
    with pytest.raises(InputError, match="points_per_piece"):
        lwo_path_report(gen.circle(50, 2.6, 10), make_model(2), points_per_piece=2)


# ------------------------------------------------------------------ 3. DVL on straight lines
@pytest.mark.parametrize("n", [2, 3])
def test_dvl_adds_at_most_n_minus_1_to_a_straight_line(n):
    """Range rows span W (4-dim), DVL rows V = (0, I, 0, 0): dim(W + V) = n + 3 (note 1)."""
    e = sp.Matrix(sp.symbols(f"e0:{n}"))
    m = 2 * n + 2
    W = sp.zeros(4, m)
    W[0, :n] = e.T
    W[1, n : 2 * n] = e.T
    W[2, m - 2] = W[3, m - 1] = 1
    V = sp.zeros(n, m)
    V[:, n : 2 * n] = sp.eye(n)
    span = sp.Matrix.vstack(W, V).subs({s: k + 1 for k, s in enumerate(e)})  # any e != 0
    assert span.rank() == n + 3 != 4 + n
    # exact ranks of a line along x with varying acceleration: 4 -> n + 3
    line = gen.straight(
        np.eye(n)[0] * -100 + np.eye(n)[1] * 60,
        np.eye(n)[0],
        0.1,
        accel=gen.sine_profile(0.02, 0.01, 20.0),
        duration=100.0,
    ).sample(0.1)
    assert exact_rank_profile(line, make_model(n, "range")).rank == 4
    assert exact_rank_profile(line, make_model(n, "range,dvl")).rank == n + 3
    assert "n + 3" in paper.NOTES["gramian-straight-rank"]
    assert "+ n with DVL" not in paper.NOTES["gramian-straight-rank"]


# ------------------------------------------------------------------ 4. Table 3 water circle
def test_expanded_augmentation_duplicates_three_columns():
    n = 2
    d = sp.Matrix(sp.symbols("d0:2"))
    tau = sp.symbols("tau")
    p0, v0, vf = (sp.Matrix(sp.symbols(f"{s}0:2")) for s in ("q", "w", "f"))
    # ȳ = dᵀ p(t) + τ p0·ν0 + τ²/2 |ν0|²  (eq. 18 with ν0 = v0 + v_f), expanded products as states
    ze = [p0.dot(v0), p0.dot(vf), v0.dot(v0), v0.dot(vf), vf.dot(vf)]
    row_e = sp.Matrix([[*d, *(tau * d), *(tau * d), tau, tau, tau**2 / 2, tau**2, tau**2 / 2]])
    row_c = sp.Matrix([[*d, *(tau * d), *(tau * d), tau, tau**2 / 2]])
    E = sp.Matrix(paper.expansion_matrix(n))
    assert row_e == row_c * E  # so G_e = Eᵀ G E: rank G_e = rank G <= 8 < 11
    nu0 = v0 + vf
    zc = [p0.dot(nu0), nu0.dot(nu0)]
    assert sp.expand(E[6:, 6:] * sp.Matrix(ze) - sp.Matrix(zc)) == sp.zeros(2, 1)
    assert E.rank() == 8 and E.shape == (8, 11)
    e = paper.expanded_water_circle(quick=True)
    assert (e.rank_compact, e.dim_compact, e.rank_expanded, e.dim_expanded) == (8, 8, 8, 11)
    # the expanded Gramian of the whole circle, exactly: still 8
    circ = paper.scenario("2d-circle", True).window(0, 40)
    G = np.array(exact_gramian(circ, make_model(2, "range,dvl-water", current=True)), dtype=object)
    Eo = paper.expansion_matrix(n).astype(object)
    assert exact_rank(Eo.T @ G @ Eo) == 8


# ------------------------------------------------------------------ 5. short windows
def test_short_windows_are_nearly_singular():
    w = paper.windows(quick=True)
    w10 = w[0]
    assert w10.window_s == 10.0
    lo, hi = w10.min_eig_equilibrated
    assert 3.25e-15 < lo <= hi < 3.35e-15  # "3.3e-15" (exact enclosure)
    assert 3.1e-21 < w10.min_eig_fixed[0] <= w10.min_eig_fixed[1] < 3.3e-21
    assert w10.min_eig_equilibrated[0] > 1e5 * w10.min_eig_fixed[1]  # equilibration gains 6 dec.
    assert w10.rank == 5  # at RANK_TOL, although exactly full rank:
    circ = paper.scenario("2d-circle", True)
    assert exact_rank_profile(circ.window(0, 101), make_model(2)).rank == 6
    # the condition number diverges as the window shrinks
    assert [x.window_s for x in w] == [10.0, 20.0, 40.0]
    assert w[0].min_eig_equilibrated[1] < w[1].min_eig_equilibrated[0]
    assert w[1].min_eig_equilibrated[1] < w[2].min_eig_equilibrated[0]


# ------------------------------------------------------------------ 7. parabola through the beacon
def test_parabola_through_the_beacon_is_deficient_on_the_whole_segment():
    t, ts = sp.symbols("t t_star", real=True)
    v0 = sp.Matrix(sp.symbols("a b", real=True))
    u = sp.Matrix(sp.symbols("c e", real=True))
    p0 = -(v0 * ts + u * ts**2 / 2)  # p(t*) = 0: through the beacon at t*
    p = p0 + v0 * t + u * t**2 / 2
    O = O_range(p, v0 + u * t, u)
    assert sp.expand(O.det()) == 0  # for all t, not only at t*
    num = {v0[0]: 1, v0[1]: 0, u[0]: 0, u[1]: sp.Rational(1, 25), ts: 30, t: 7}
    assert O.subs(num).rank() == 3  # u not parallel to v0: rank 3, not the radial line's 2
    row = {r.key: r for r in paper.table1(quick=True)}["t1-2d-parabola-beacon"]
    ev = row.cells[0].evidence
    assert ev.lwo_min_rank == 3 and ev.lwo_fraction == 0.0 and ev.gramian_rank == 3
    tr = paper.scenario("2d-parabola-beacon", True)
    assert np.abs(tr.p).min(axis=0).max() < 1e-9  # the path really reaches the beacon
    assert np.all(lwo_report(tr, make_model(2)).ranks == 3)


def test_parabola_generator():
    tr = gen.parabola((0.0, 1.0), (1.0, 0.0), (0.0, 0.5), duration=4.0).sample(0.5)
    np.testing.assert_allclose(tr.p[-1], [4.0, 1.0 + 0.25 * 16])
    assert np.all(tr.u == [0.0, 0.5])
    with pytest.raises(ConfigError, match="both zero"):
        gen.parabola((0.0, 1.0), (0.0, 0.0), (0.0, 0.0), duration=4.0)
    with pytest.raises(ConfigError, match="accel"):
        gen.parabola((0.0, 1.0), (1.0, 0.0), (0.0, 0.0, 1.0), duration=4.0)


# ------------------------------------------------------------------ the record as written
def test_docs_state_the_computed_numbers():
    """docs/paper-discrepancies.md quotes the numbers these tests compute."""
    text = DOC.read_text(encoding="utf-8")
    st = paper.smooth_turns(quick=True)
    for x in st.first_turn_deg:
        assert f"{x:.2f}" in text.replace("−", "-")
    w10 = paper.windows(quick=True)[0]
    assert f"{w10.min_eig_equilibrated[0]:.1e}" in text
    assert "rank 8 of 11" in text and "n + 3" in text
    assert "3, 5, 6" in text and "5, 7, 8" in text and "6, 8, 10, 11" in text
    assert "full_rank_interval_exact" in text and "full_rank_from_t_exact" in text
    assert f"{RANK_TOL:g}" in text  # the conditioning tolerance the verdicts use
