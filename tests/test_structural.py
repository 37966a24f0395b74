"""Exact (rational) rank of the held-input Gramian: structural profiles, exactness, the JSON keys.

Oracles: the numeric exact Gramian of ``gramian.py`` (float), sympy's rank over ℚ, mpmath
eigenvalues at 60 digits, and hand-derived structural facts (kernels, per-interval rank bounds).
"""

from __future__ import annotations

import json
import pickle
from fractions import Fraction

import numpy as np
import pytest
import sympy as sp

from obsplan.cli import main
from obsplan.model.vehicle import make_model
from obsplan.observability.analyze import analyze
from obsplan.observability.gramian import gramian, gramian_report
from obsplan.observability.scaling import RANK_TOL, Scales
from obsplan.observability.structural import (
    STRUCTURE_RTOL,
    ExactRankProfile,
    exact_gramian,
    exact_min_eigenvalue,
    exact_rank,
    exact_rank_profile,
    structural_inputs,
)
from obsplan.paper.tables import scenario
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory, write_csv

DT = 0.1  # exact ranks are per interval; 0.1 s keeps the conditioning times cheap


def circle2d() -> Trajectory:
    return gen.circle(50.0, 2.6, 120.0).sample(DT)  # Fig. 2


def circle_zsine() -> Trajectory:
    return gen.circle_z(
        50.0, 2.6, 180.0, z0=10.0, z_motion="sine", z_amp=5.0, z_period=90.0
    ).sample(DT)


#: The three configurations of the exact record: (trajectory, sensors, current, profile).
CONFIGS = {
    "2d-range": (circle2d, "range", False, (3, 5, 6)),
    "3d-range-depth": (circle_zsine, "range,depth", False, (5, 7, 8)),
    "3d-current-water": (circle_zsine, "range,dvl-water", True, (6, 8, 10, 11)),
}


def random_traj(seed: int, dim: int = 2, n: int = 12) -> Trajectory:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.2, 2.0, n)) - 0.3
    return Trajectory.from_inputs(
        t, rng.normal(0, 40, dim), rng.normal(0, 1, dim), rng.normal(0, 0.2, (n, dim))
    )


# ------------------------------------------------------------------ structural profiles
@pytest.mark.parametrize("key", list(CONFIGS))
def test_structural_profiles_of_the_three_configurations(key):
    make, sensors, current, want = CONFIGS[key]
    tr = make()
    prof = exact_rank_profile(tr, make_model(tr.dim, sensors, current=current))
    assert prof.ranks(len(want)) == want
    assert prof.rank == prof.dim == want[-1]
    assert prof.full_rank_interval == len(want) - 1
    assert prof.full_rank_from_t == tr.t[len(want)]  # end of that interval, exactly
    # the conditioning time is later, and moves with the tolerance
    model = make_model(tr.dim, sensors, current=current)
    times = [gramian_report(tr, model, tol=tol).full_rank_from_t for tol in (1e-12, 1e-10, 1e-8)]
    assert prof.full_rank_from_t < times[0] < times[1] < times[2]


def test_per_interval_rank_increments_are_bounded_by_the_row_structure():
    """An interval adds at most 4 directions per range output (cubic rows), 2 per depth gauge, and
    the n DVL rows once: the structural profile is the fastest possible."""
    for seed in range(4):
        for sensors, first, step in (("range", 3, 4), ("range,depth", 5, 6), ("range,dvl", 5, 4)):
            tr = random_traj(seed, dim=3)
            prof = exact_rank_profile(tr, make_model(3, sensors))
            r = prof.ranks(5)
            assert r[0] <= first and all(b - a <= step for a, b in zip(r, r[1:], strict=False))


def test_exact_rank_is_the_rank_of_the_exact_gramian_of_each_prefix():
    """The span argument (Hilbert middle matrix positive definite) against the Gramian itself."""
    tr = random_traj(3, dim=2, n=6)
    for sensors, current in (("range", False), ("range,dvl-bottom", True), ("range,dvl", False)):
        model = make_model(2, sensors, current=current)
        prof = exact_rank_profile(tr, model)
        ranks = prof.ranks(tr.n_samples - 1)
        for k in range(1, tr.n_samples):
            G = sp.Matrix(exact_gramian(tr.window(0, k + 1), model))
            assert G.rank() == ranks[k - 1], (sensors, k)


def test_exact_deficiencies_are_structural():
    # bottom-lock DVL with current: (w, -w) in (v, v_f) is in the kernel for every input
    tr = random_traj(1, dim=3, n=40)
    prof = exact_rank_profile(tr, make_model(3, "range,dvl-bottom", current=True))
    assert prof.rank == prof.dim - 3 and prof.full_rank_interval is None
    # lines along x carry exactly zero cross-track inputs: ranks 2 (u = 0), 3 (constant), 4
    e = (1.0, 0.0)
    for accel, rank in ((0.0, 2), (0.02, 3), (gen.sine_profile(0.02, 0.01, 10.0), 4)):
        line = gen.straight((-100.0, 60.0), e, 0.5, accel=accel, duration=40.0).sample(DT)
        assert exact_rank_profile(line, make_model(2, "range")).rank == rank
        dvl = exact_rank_profile(line, make_model(2, "range,dvl")).rank
        # DVL adds the n velocity directions; the range rows already hold (0, e, 0, 0) once
        # u != 0: 2 + n, 3 - 1 + n, 4 - 1 + n (bound n + 3)
        assert dvl == {2: 4, 3: 4, 4: 5}[rank]


def test_round_off_does_not_read_as_excitation():
    """Inputs a·(0.8, -0.6) rounded to doubles are not exactly parallel: as stored they are
    exactly full rank 6, while the path's structure (a line) is rank 4, as its conditioning."""
    line = gen.straight(
        (-80.0, 60.0), (0.8, -0.6), 0.5, accel=gen.sine_profile(0.02, 0.01, 20.0), duration=60.0
    ).sample()
    model = make_model(2, "range")
    u = line.u[:-1]
    assert np.any(u[:, 0] * 0.6 + u[:, 1] * 0.8 != 0)  # not exactly parallel to (0.8, -0.6)
    assert exact_rank_profile(line, model, structure_rtol=0).rank == 6  # the stored numbers
    assert exact_rank_profile(line, model).rank == 4  # the structure
    assert gramian_report(line, model).rank == 4


def _hidden_line_3d() -> Trajectory:
    e = np.array([0.48, -0.36, 0.8]) / np.linalg.norm([0.48, -0.36, 0.8])
    return gen.straight(
        (-80.0, 60.0, 5.0), e, 0.5, accel=gen.sine_profile(0.02, 0.01, 20.0), duration=60.0
    ).sample(0.25)


def test_hidden_straight_3d_line_is_rank_6_of_8_in_every_exact_key(tmp_path, capsys):
    line = _hidden_line_3d()
    u = line.u[:-1]
    e = u[0] / np.linalg.norm(u[0])
    off = np.linalg.norm(u - np.outer(u @ e, e), axis=1) / np.linalg.norm(u, axis=1)
    assert 0 < off.max() < 1e-14  # parallel to round-off only, as in the field report
    csv = write_csv(line, tmp_path / "line3d.csv")
    assert main(["analyze", str(csv), "--json", "--sensors", "range,dvl"]) == 0
    g = json.loads(capsys.readouterr().out)["gramian"]
    assert (g["rank_exact"], g["dim"]) == (6, 8)  # range + DVL on a line: 4 + n - 1
    assert g["full_rank_interval_exact"] is None and g["full_rank_from_t_exact"] is None
    assert g["rank"] == 6 and g["full_rank"] is False
    model = make_model(3, "range,dvl")
    assert exact_rank_profile(line, model, structure_rtol=0).rank == 8  # as stored: round-off


def test_a_round_off_cross_track_input_does_not_move_the_exact_time():
    """A leg along x whose last interval carries u_y = -1.2e-15, then a turn: the structure
    becomes full rank in the turn, not at the end of the leg."""
    h = 0.5
    leg = np.tile([0.02, 0.0], (120, 1))
    leg[60:, 0] = -0.01  # accelerate then brake along x: rank 3 on the leg (2D range)
    leg[-1, 1] = -1.22e-15
    turn = np.column_stack([np.zeros(20), np.full(20, 0.03)])
    u = np.vstack([leg, turn])
    t = np.arange(u.shape[0] + 1) * h
    tr = Trajectory.from_inputs(t, (-80.0, 60.0), (0.2, 0.0), u)
    model = make_model(2, "range")
    raw = exact_rank_profile(tr, model, structure_rtol=0)
    prof = exact_rank_profile(tr, model)
    assert raw.full_rank_interval == 119  # the round-off interval, as stored
    assert prof.full_rank_interval is not None and prof.full_rank_interval >= 120  # in the turn
    assert prof.ranks(120)[-1] == 4  # the leg's structure: a line with a varying input


def test_paper_lawnmower_first_leg_is_a_constant_acceleration():
    """Its chord inputs vary by ~1e-14 around 0.0125 m/s²: as stored they read as a 4th
    direction at interval 2; the structure is rank 3 until the turn (docs, exact record)."""
    tr = scenario("2d-lawnmower", True)
    model = make_model(2, "range")
    assert exact_rank_profile(tr, model, structure_rtol=0).increases[:2] == ((0, 3), (2, 4))
    prof = exact_rank_profile(tr, model)
    assert prof.increases == ((0, 3), (1600, 5), (1601, 6))
    assert tr.u[1599, 1] == 0 and tr.u[1600, 1] != 0  # 1600 is the turn's first interval


def test_structural_inputs_stay_within_the_tolerance_and_keep_generic_paths():
    rng = np.random.default_rng(3)
    u = rng.normal(0, 0.05, (200, 3))
    u[50:80] = np.outer(rng.uniform(-0.05, 0.05, 30), [0.6, 0.0, -0.8])  # a parallel run
    u[90:100] = 0.0
    u[120, 2] += 1e-17  # round-off on a generic input: no class changes
    U, s = structural_inputs(u)
    snapped = np.array([float(Fraction(int(x), 1 << s)) for x in U.ravel()]).reshape(u.shape)
    umax = np.linalg.norm(u, axis=1).max()
    # each input moves by at most the tolerance (direction and magnitude), relative to max |u|
    assert np.max(np.linalg.norm(snapped - u, axis=1)) <= 3 * STRUCTURE_RTOL * umax
    assert np.all(snapped[90:100] == 0)
    d = snapped[50:80] / np.linalg.norm(snapped[50:80], axis=1, keepdims=True)
    assert np.all(np.abs(np.abs(d @ d[0]) - 1) < 1e-15) and np.all(d[:, 1] == 0)
    tr = random_traj(4, dim=3, n=30)
    model = make_model(3, "range,depth")
    assert exact_rank_profile(tr, model) == exact_rank_profile(tr, model, structure_rtol=0)


def test_exact_interval_does_not_depend_on_units():
    """Generic data stay generic in km and h: the same structural interval."""
    tr = circle2d()
    km_h = tr.scaled(1000.0, 3600.0)
    model = make_model(2, "range")
    a, b = exact_rank_profile(tr, model), exact_rank_profile(km_h, model)
    assert a.increases == b.increases
    assert b.full_rank_from_t == pytest.approx(a.full_rank_from_t / 3600.0, rel=1e-15)


# ------------------------------------------------------------------ exact Gramian and eigenvalues
@pytest.mark.parametrize(
    ("dim", "sensors", "current"),
    [
        (2, "range", False),
        (2, "range,dvl-water", True),
        (2, "range,dvl-bottom", True),
        (3, "range,depth", False),
        (3, "range,depth,dvl-water", True),
    ],
)
@pytest.mark.parametrize("scales", [None, Scales(100.0, 100.0), Scales(7.0, 3.0)])
def test_exact_gramian_matches_the_float_gramian(dim, sensors, current, scales):
    tr = random_traj(11, dim=dim, n=30)
    model = make_model(dim, sensors, current=current)
    G = np.array(exact_gramian(tr, model, scales), dtype=float)
    Gf = gramian(tr, model, scales)
    # the float Gramian uses d, e from the integrated samples: agreement to round-off
    assert np.abs(G - Gf).max() <= 1e-12 * np.abs(Gf).max()
    assert all(isinstance(x, Fraction) for row in exact_gramian(tr, model) for x in row)


def test_exact_min_eigenvalue_encloses_the_60_digit_eigenvalue():
    import mpmath as mp

    mp.mp.dps = 60
    w = circle2d().window(0, 101)  # the 10 s window of the Fig. 2 circle
    G = exact_gramian(w, make_model(2, "range"), Scales())
    M = mp.matrix([[mp.mpf(x.numerator) / x.denominator for x in r] for r in G])
    D = mp.diag([1 / mp.sqrt(M[i, i]) for i in range(M.rows)])
    for equil, A in ((False, M), (True, D * M * D)):
        lo, hi = exact_min_eigenvalue(G, equilibrate=equil, rtol=1e-6)
        ev = min(mp.eigsy(A)[0])
        assert mp.mpf(lo.numerator) / lo.denominator <= ev <= mp.mpf(hi.numerator) / hi.denominator
        assert hi / lo <= 1 + Fraction(1, 10**6)
    assert exact_min_eigenvalue([[Fraction(1), Fraction(1)], [Fraction(1), Fraction(1)]]) == (0, 0)


def test_exact_rank_matches_sympy():
    rng = np.random.default_rng(5)
    for r in range(1, 5):
        M = (rng.integers(-3, 4, (6, r)) @ rng.integers(-3, 4, (r, 5))).astype(object)
        assert exact_rank(M) == sp.Matrix(M.tolist()).rank()


# ------------------------------------------------------------------ analyze and the JSON keys
NEW_KEYS = {"rank_exact", "full_rank_interval_exact", "full_rank_from_t_exact", "rank_tol"}


@pytest.mark.slow
@pytest.mark.parametrize("key", list(CONFIGS))
def test_analyze_json_reports_the_exact_interval_beside_full_rank_from_t(key, tmp_path, capsys):
    make, sensors, current, want = CONFIGS[key]
    tr = make()
    csv = write_csv(tr, tmp_path / f"{key}.csv")
    argv = ["analyze", str(csv), "--json", "--sensors", sensors] + (
        ["--current"] if current else []
    )
    assert main(argv) == 0
    g = json.loads(capsys.readouterr().out)["gramian"]
    assert NEW_KEYS <= set(g)
    # the CSV's doubles round-trip exactly, so the exact profile is that of the generator's data
    assert g["full_rank_interval_exact"] == len(want) - 1
    assert g["full_rank_from_t_exact"] == pytest.approx(tr.t[len(want)], abs=1e-12)
    assert g["rank_exact"] == g["dim"] == want[-1]
    assert g["rank_tol"] == RANK_TOL
    # stable keys keep their meaning: the conditioning verdict and time
    rep = gramian_report(tr, make_model(tr.dim, sensors, current=current))
    assert g["full_rank"] is True and g["rank"] == rep.rank
    assert g["full_rank_from_t"] == pytest.approx(rep.full_rank_from_t, abs=1e-9)
    assert g["full_rank_from_t"] > g["full_rank_from_t_exact"]


def test_analyze_without_exact_and_deficient_paths():
    line = gen.straight((-100.0, 60.0), (1.0, 0.0), 0.1, accel=0.02, duration=30.0).sample(DT)
    rep = analyze(line, "range")
    d = rep.to_dict()["gramian"]
    assert d["rank_exact"] == 3 and d["full_rank_interval_exact"] is None
    assert d["full_rank_from_t_exact"] is None and d["full_rank_from_t"] is None
    quick = analyze(line, "range", exact=False).to_dict()["gramian"]
    assert NEW_KEYS <= set(quick) and quick["rank_exact"] is None
    json.dumps(d, allow_nan=False)
    assert pickle.loads(pickle.dumps(rep)).exact == rep.exact
    assert isinstance(rep.exact, ExactRankProfile)


def test_dimension_mismatch_is_an_error():
    with pytest.raises(ValueError, match="3D"):
        exact_rank_profile(circle2d(), make_model(3, "range"))
    with pytest.raises(ValueError, match="3D"):
        exact_gramian(circle2d(), make_model(3, "range"))
