"""Lie-derivative observability matrix (eq. 9): structure, closed forms, rank test, invariances.

Oracles: the paper's printed matrices (eqs. 13, 35, 38, 43-45, 50) and an independent sympy
derivation of the (extended) Lie derivatives.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from obsplan.core.errors import InputError
from obsplan.model.vehicle import make_model
from obsplan.observability.lwo import (
    LWO_RANK_TOL,
    LWOReport,
    local_information_function,
    lwo_matrices,
    lwo_matrix_function,
    lwo_orders,
    lwo_ranks,
    lwo_report,
    lwo_structural_max_rank,
    ranks_of,
    taylor_moments,
)
from obsplan.planning import load_problem
from obsplan.planning.objectives.registry import REGISTRY
from obsplan.planning.transcription.guesses import random_guess, reference_path
from obsplan.trajectory.sampled import Trajectory

HSET = settings(max_examples=30, deadline=None, derandomize=True)
finite = st.floats(-3.0, 3.0, allow_nan=False)


# ----------------------------------------------------------------------------- sympy oracle
def sympy_O(dim, sensors, current, range_form="half-squared", m=0, orders=None):
    """O built from scratch with sympy (no CasADi, no obsplan code): symbols and the matrix."""
    n = dim
    p = sp.Matrix(sp.symbols(f"p0:{n}"))
    v = sp.Matrix(sp.symbols(f"v0:{n}"))
    vf = sp.Matrix(sp.symbols(f"w0:{n}"))
    us = [sp.Matrix(sp.symbols(f"u{i}_0:{n}")) for i in range(m + 1)]
    x = sp.Matrix.vstack(p, v, vf) if current else sp.Matrix.vstack(p, v)
    nu = v + vf if current else v
    f = sp.Matrix.vstack(nu, us[0], sp.zeros(n, 1)) if current else sp.Matrix.vstack(nu, us[0])
    outs = []
    for s in sensors:
        if s == "range":
            sq = (p.T * p)[0]
            outs.append(sq / 2 if range_form == "half-squared" else sp.sqrt(sq))
        elif s == "dvl-bottom":
            outs += list(nu)
        elif s == "dvl-water":
            outs += list(v)
        elif s == "depth":
            outs.append(p[2])
    K = 3 + m if orders is None else orders
    rows = []
    for h in outs:
        L = h
        for _ in range(K + 1):
            # polynomial outputs are kept expanded, so a zero gradient is literally 0; the
            # plain range's derivatives never vanish (and simplify on them is very slow)
            g = sp.Matrix([L]).jacobian(x).applyfunc(sp.expand if L.is_polynomial() else sp.S)
            if any(e != 0 for e in g):
                rows.append(g)
            dL = (sp.Matrix([L]).jacobian(x) * f)[0]
            for i in range(m):
                dL += (sp.Matrix([L]).jacobian(us[i]) * us[i + 1])[0]
            L = sp.expand(dL) if dL.is_polynomial() else dL
    return x, us, sp.Matrix.vstack(*rows)


SENSOR_CASES = [
    (2, ("range",), False),
    (2, ("range", "dvl-bottom"), True),
    (2, ("range", "dvl-water"), True),
    (3, ("range",), False),
    (3, ("range", "dvl-bottom", "depth"), False),
    (3, ("range", "dvl-water"), True),
]


ORACLE_CASES = [(*c, "half-squared", m) for c in SENSOR_CASES for m in (0, 1)] + [
    # plain range: sympy is slow on its nested square roots, so fewer cases
    (2, ("range",), False, "range", 0),
    (2, ("range",), False, "range", 1),
    (3, ("range", "dvl-water"), True, "range", 0),
    (3, ("range", "dvl-bottom", "depth"), False, "range", 0),
]


@pytest.mark.slow
@pytest.mark.parametrize("dim,sensors,current,range_form,m", ORACLE_CASES)
def test_matches_independent_sympy_derivation(dim, sensors, current, range_form, m):
    model = make_model(dim, sensors, current, range_form=range_form)
    x, us, O = sympy_O(dim, sensors, current, range_form, m)
    fn = lwo_matrix_function(model, m)
    num = sp.lambdify([x, *us], O, "numpy")
    rng = np.random.default_rng(7)
    for _ in range(3):
        xv = rng.standard_normal(model.state_dim)
        uv = [rng.standard_normal(dim) for _ in range(m + 1)]
        expected = np.asarray(num(xv, *uv), float)
        got = np.asarray(fn(xv, *uv))
        assert got.shape == expected.shape
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_range_only_matrix_is_eq_13():
    """2D (eq. 35) and 3D (eq. 38): rows (p,0), (v,p), (u,2v), (0,3u)."""
    rng = np.random.default_rng(0)
    for dim in (2, 3):
        p, v, u = rng.standard_normal((3, dim))
        z = np.zeros(dim)
        expected = np.array([np.r_[p, z], np.r_[v, p], np.r_[u, 2 * v], np.r_[z, 3 * u]])
        got = np.asarray(lwo_matrix_function(make_model(dim))(np.r_[p, v], u))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)


def test_dvl_and_current_matrices_are_eqs_40_and_50():
    rng = np.random.default_rng(1)
    n = 3
    p, v, vf, u = rng.standard_normal((4, n))
    nu = v + vf
    z, I, Z = np.zeros(n), np.eye(n), np.zeros((n, n))
    head = np.array(
        [np.r_[p, z, z], np.r_[nu, p, p], np.r_[u, 2 * nu, 2 * nu], np.r_[z, 3 * u, 3 * u]]
    )
    Ob = np.vstack([head, np.hstack([Z, I, I])])  # eq. 50, bottom lock
    Ow = np.vstack([head, np.hstack([Z, I, Z])])  # eq. 50, water profiling
    x = np.r_[p, v, vf]
    for sensors, expected in (("range,dvl-bottom", Ob), ("range,dvl-water", Ow)):
        got = np.asarray(lwo_matrix_function(make_model(n, sensors, True))(x, u))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)
    # eq. 40 (no current): range rows and the identity on v
    got = np.asarray(lwo_matrix_function(make_model(n, "range,dvl"))(np.r_[p, v], u))
    np.testing.assert_allclose(got[4:], np.hstack([Z, I]), atol=0)


def test_more_orders_never_raise_the_rank():
    """K = 3 + m (module docstring): two more orders add nothing, for every sensor set."""
    rng = np.random.default_rng(3)
    for dim, sensors, current in SENSOR_CASES:
        for rf in ("half-squared", "range"):
            model = make_model(dim, sensors, current, range_form=rf)
            for m in (0, 1):
                f = lwo_matrix_function(model, m)
                g = lwo_matrix_function(model, m, orders=lwo_orders(model, m) + 2)
                for _ in range(5):
                    args = [rng.standard_normal(model.state_dim)]
                    args += [rng.standard_normal(dim) for _ in range(m + 1)]
                    r1 = ranks_of(np.asarray(f(*args))[None])[0]
                    r2 = ranks_of(np.asarray(g(*args))[None])[0]
                    assert r1 == r2


# ----------------------------------------------------------------------------- closed forms
def test_closed_form_determinants_sympy():
    """det O exactly, from the sympy derivation.

    Straight line p_y = m p_x + q: det O = -3 u_x² q² (eq. 36, paper and truth agree).
    Centred circle (eq. 37), frozen input (eq. 35): det O = 6 ω⁴ ρ⁴ (the paper's value).
    Centred circle with the input's rotation (u' = -ω² v, input_derivatives=1): the first four
    rows have det = 4 ω⁴ ρ⁴ (the paper's 6 holds for the frozen matrix only).
    """
    x, us, O = sympy_O(2, ("range",), False, m=0)
    sl, q, px, s, a = sp.symbols("m q p_x s a", real=True)
    line = dict(zip(list(x) + list(us[0]), [px, sl * px + q, s, sl * s, a, sl * a], strict=True))
    assert sp.simplify(O.subs(line).det() + 3 * a**2 * q**2) == 0

    rho, w, t = sp.symbols("rho omega t", positive=True)
    pc = sp.Matrix([rho * sp.cos(w * t), rho * sp.sin(w * t)])
    vc, uc = pc.diff(t), pc.diff(t, 2)
    frozen = dict(zip(list(x) + list(us[0]), list(pc) + list(vc) + list(uc), strict=True))
    assert sp.simplify(O.subs(frozen).det() - 6 * w**4 * rho**4) == 0

    x1, us1, O1 = sympy_O(2, ("range",), False, m=1)
    vals = list(pc) + list(vc) + list(uc) + list(pc.diff(t, 3))
    rot = dict(zip(list(x1) + list(us1[0]) + list(us1[1]), vals, strict=True))
    assert sp.simplify(O1[:4, :].subs(rot).det() - 4 * w**4 * rho**4) == 0


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    rho=st.floats(0.1, 100),
    w=st.floats(0.01, 2),
    t=st.floats(0, 100),
)
def test_circle_determinants_casadi(rho, w, t):
    """The CasADi matrices give the same closed forms as sympy (6 frozen, 4 rotating)."""
    p = rho * np.array([np.cos(w * t), np.sin(w * t)])
    v = rho * w * np.array([-np.sin(w * t), np.cos(w * t)])
    u, u1 = -(w**2) * p, -(w**2) * v
    model = make_model(2)
    d0 = np.linalg.det(np.asarray(lwo_matrix_function(model)(np.r_[p, v], u)))
    d1 = np.linalg.det(np.asarray(lwo_matrix_function(model, 1)(np.r_[p, v], u, u1))[:4])
    assert d0 == pytest.approx(6 * w**4 * rho**4, rel=1e-9)
    assert d1 == pytest.approx(4 * w**4 * rho**4, rel=1e-9)


@HSET
@given(x=st.lists(finite, min_size=6, max_size=6), u=st.lists(finite, min_size=3, max_size=3))
def test_3d_range_only_rank_never_exceeds_4_with_constant_input(x, u):
    """The paper (section 5.2): eq. 38 has 4 non-zero rows, so LWO can never hold in 3D."""
    O = np.asarray(lwo_matrix_function(make_model(3))(np.array(x), np.array(u)))
    assert O.shape == (4, 6)
    assert ranks_of(O[None])[0] <= 4


def test_3d_range_only_rank_can_exceed_4_with_input_derivatives():
    """True for piecewise-constant inputs only: smooth time-varying inputs reach rank 5, 6."""
    model = make_model(3)
    assert lwo_structural_max_rank(model) == 4
    assert lwo_structural_max_rank(model, input_derivatives=1) == 5
    assert lwo_structural_max_rank(model, input_derivatives=2) == 6
    # 2D with current: bottom lock never full (the (w,-w) direction), water profiling can be
    assert lwo_structural_max_rank(make_model(2, "range,dvl-bottom", True)) == 4
    assert lwo_structural_max_rank(make_model(2, "range,dvl-water", True)) == 6
    # 3D with current (section 6.3): at most 7 non-zero rows, never 9 with constant input
    assert lwo_structural_max_rank(make_model(3, "range,dvl-water", True)) == 7


# ----------------------------------------------------------------------------- along trajectories
def straight_line(dim, q, accel=0.05, n=400, dt=0.5, seed=0, speed=1.0):
    """A straight line along a random direction, passing at distance ``q`` from the beacon."""
    rng = np.random.default_rng(seed)
    b = rng.standard_normal(dim)
    b /= np.linalg.norm(b)
    nrm = rng.standard_normal(dim)
    nrm -= (nrm @ b) * b
    nrm /= np.linalg.norm(nrm)
    t = np.arange(n) * dt
    return Trajectory.from_inputs(t, -60 * b + q * nrm, speed * b, np.tile(accel * b, (n, 1)))


def circle(rho=50.0, w=0.1, n=300, dt=0.2, z=None):
    """Centred circle (eq. 37); 3D at height ``z`` (eq. 46) when z is given."""
    t = np.arange(n) * dt
    c, s = np.cos(w * t), np.sin(w * t)
    p = np.c_[rho * c, rho * s]
    v = np.c_[-rho * w * s, rho * w * c]
    u = -(w**2) * p
    if z is not None:
        p, v, u = np.c_[p, np.full(n, z)], np.c_[v, np.zeros(n)], np.c_[u, np.zeros(n)]
    return Trajectory(t=t, p=p, v=v, u=u)


@pytest.mark.parametrize(
    "dim,sensors,q,expected",
    [
        (2, "range", 0.0, 2),  # radial: rank 2 (section 5.1)
        (2, "range", 10.0, 4),  # not radial, u != 0: full (eq. 36)
        (3, "range", 10.0, 4),  # 3D: 4 < 6 (eq. 38)
        (3, "range,dvl", 0.0, 4),  # eq. 45: 4 on radial lines
        (3, "range,dvl", 10.0, 5),  # eq. 45: 5 on non-radial lines
        (2, "range,dvl", 0.0, 3),  # section 6.1: 2 -> 3 with DVL on radial lines
    ],
)
def test_straight_line_ranks(dim, sensors, q, expected):
    ranks = lwo_ranks(straight_line(dim, q), make_model(dim, sensors))
    assert np.all(ranks == expected)


def test_constant_velocity_is_not_full_rank():
    """Null input: no LWO inference (section 5.1); 3 of 4 on a non-radial line."""
    assert np.all(lwo_ranks(straight_line(2, 10.0, accel=0.0), make_model(2)) == 3)


def test_circles_and_table_3_lwo():
    """2D circle: full (section 5.1). With current (Table 3, 2D): bottom lock NO, water YES.
    3D circle with DVL: full off the beacon's plane, not in it (section 6.2)."""
    tr = circle()
    assert lwo_report(tr, make_model(2)).along_trajectory
    assert not lwo_report(tr, make_model(2, "range,dvl-bottom", True)).along_trajectory
    assert lwo_report(tr, make_model(2, "range,dvl-water", True)).along_trajectory
    assert lwo_report(circle(z=20.0), make_model(3, "range,dvl")).along_trajectory
    rep = lwo_report(circle(z=0.0), make_model(3, "range,dvl"))
    assert not rep.along_trajectory and rep.min_rank == 5


def test_current_split_does_not_change_O():
    """Rows depend on v + v_f only: any split of the inertial velocity gives the same O."""
    tr = circle(n=40)
    model = make_model(2, "range,dvl-bottom", current=True)
    fn = lwo_matrix_function(model)
    rng = np.random.default_rng(5)
    O0 = lwo_matrices(tr, model)
    for _ in range(3):
        vf = rng.standard_normal(2)
        x = np.hstack([tr.p, tr.v - vf, np.tile(vf, (tr.n_samples, 1))])
        O1 = np.stack([np.asarray(fn(xk, uk)) for xk, uk in zip(x, tr.u, strict=True)])
        np.testing.assert_allclose(O1, O0, rtol=1e-13, atol=1e-12)
        assert np.array_equal(ranks_of(O1), ranks_of(O0))


def test_beacon_on_a_sample_gives_a_verdict_not_nan():
    """A radial line through the beacon: a sample sits on it. Half-squared O is finite there;
    the plain range O is NaN there (undefined), and both rank tests give a finite verdict."""
    n, dt = 41, 0.5
    t = np.arange(n) * dt
    p = np.c_[t - 10.0, 0.5 * (t - 10.0)]  # p = 0 at t = 10 (sample 20)
    v = np.tile([1.0, 0.5], (n, 1))
    tr = Trajectory(t=t, p=p, v=v, u=np.zeros((n, 2)))
    for rf in ("half-squared", "range"):
        model = make_model(2, range_form=rf)
        O = lwo_matrices(tr, model)
        assert np.isfinite(O).all() == (rf == "half-squared")
        ranks = lwo_ranks(tr, model)
        assert ranks.dtype.kind == "i" and ranks[20] < 4
        rep = lwo_report(tr, model)
        assert not rep.along_trajectory


@HSET
@given(
    seed=st.integers(0, 2**16),
    L=st.sampled_from([1e-3, 1.0, 1e3]),
    T=st.sampled_from([1 / 3600, 1.0, 3600.0]),
    angle=st.floats(0, 2 * np.pi),
)
def test_ranks_invariant_to_units_and_rotation_about_beacon(seed, L, T, angle):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.1, 1.0, 30))
    tr = Trajectory.from_inputs(
        t, rng.normal(0, 30, 2), rng.normal(0, 1, 2), rng.normal(0, 0.1, (30, 2))
    )
    c, s = np.cos(angle), np.sin(angle)
    beacon = rng.normal(0, 5, 2)
    for sensors, current in (("range", False), ("range,dvl-water", True)):
        model = make_model(2, sensors, current, beacon=beacon)
        r0 = lwo_ranks(tr, model)
        scaled = tr.translated(-beacon).scaled(L, T)
        assert np.array_equal(lwo_ranks(scaled, make_model(2, sensors, current)), r0)
        rot = tr.rotated(np.array([[c, -s], [s, c]]), about=beacon)
        assert np.array_equal(lwo_ranks(rot, model), r0)


def test_tolerance_margins_on_long_lines():
    """LWO_RANK_TOL sits between round-off and real directions on a 6000-sample line.

    Radial (rank 2): the 3rd singular value stays below 1e-12 σ_max (measured ~1e-13 at 6e4
    samples); a line passing 0.1 m from the beacon at ranges up to 80 m (σ_4 ≥ 1e-6 σ_max) is
    full rank at every sample.
    """
    from obsplan.observability.lwo import _dimensionless

    kw = dict(n=6000, dt=0.1, speed=0.2, accel=1e-4)
    radial = straight_line(2, 0.0, **kw)
    s = np.linalg.svd(_dimensionless(radial, make_model(2), 0), compute_uv=False)
    assert np.max(s[:, 2] / s[:, 0]) < 1e-3 * LWO_RANK_TOL
    near = straight_line(2, 0.1, **kw)
    s = np.linalg.svd(_dimensionless(near, make_model(2), 0), compute_uv=False)
    assert np.min(s[:, 3] / s[:, 0]) > 1e3 * LWO_RANK_TOL
    assert np.all(lwo_ranks(near, make_model(2)) == 4)


# ----------------------------------------------------------------------------- API
def test_symbolic_use_with_mx_and_sx():
    fn = lwo_matrix_function(make_model(2))
    for sym in (ca.MX, ca.SX):
        X, U = sym.sym("x", 4), sym.sym("u", 2)
        O = fn(X, U)
        assert O.shape == (4, 4)
        cond = ca.Function("c", [X, U], [ca.trace(O.T @ O)])
        assert float(cond(np.ones(4), np.ones(2))) == pytest.approx(
            2 + 4 + 10 + 18
        )  # rows (p,0),(v,p),(u,2v),(0,3u)


def test_report_fields_and_dict():
    rep = lwo_report(circle(n=20), make_model(2))
    assert rep.to_dict() == {
        "along_trajectory": True,
        "full_rank_fraction": 1.0,
        "min_rank": 4,
        "state_dim": 4,
    }
    assert "ranks" not in repr(rep)
    other = LWOReport(True, 1.0, 4, 4, ranks=np.zeros(3, int))
    assert rep == other  # ranks excluded from equality
    with pytest.raises(AttributeError):
        rep.min_rank = 0  # type: ignore[misc]


def test_bad_arguments():
    with pytest.raises(InputError, match="input_derivatives"):
        lwo_matrix_function(make_model(2), -1)
    with pytest.raises(InputError, match="3D"):
        lwo_ranks(circle(n=10), make_model(3))


def test_lwo_condition_ranks_paths_against_the_bound():
    # why the scale-free form is reported as a diagnostic and not flown: on the suite's LWO
    # problem (3D, range + water DVL) the path it scores best, among the lawn-mower and two
    # seeded random paths, has a worse final posterior CRB than the lawn-mower (measured 0.076 m
    # against 0.025 m, the best-scored path's bound 3.1x); the margin 1.5x is far from both.
    # The information form (the default) ranks the three as the bound does (measured: 151084,
    # 151039, 151015 against bounds 0.025, 0.043, 0.076 m; the values are close because the
    # first nodes, where only the prior counts, weigh most in the harmonic mean, but their
    # differences, 3e-4 and 2e-4 relative, are ten orders above the evaluation's round-off).
    pb = load_problem(Path(__file__).resolve().parents[1] / "problems/suite/lwo-dvl3d.toml")
    assert pb.objective.kind == "lwo-condition"
    scale_free = replace(pb, objective=replace(pb.objective, weights="none"))
    bound_pb = replace(pb, objective=replace(pb.objective, kind="pcrb-position", mode="final"))
    lwo, pcrb = REGISTRY["lwo-condition"], REGISTRY["pcrb-position"]
    paths = [reference_path(pb), random_guess(pb, 1), random_guess(pb, 2)]
    best = max(paths, key=lambda tr: lwo.value(tr, scale_free))
    assert best is not paths[0]
    assert pcrb.value(best, bound_pb) > 1.5 * pcrb.value(paths[0], bound_pb)
    by_info = sorted(paths, key=lambda tr: -lwo.value(tr, pb))
    by_bound = sorted(paths, key=lambda tr: pcrb.value(tr, bound_pb))
    assert [id(tr) for tr in by_info] == [id(tr) for tr in by_bound]


@pytest.mark.parametrize(
    ("dim", "sensors", "current"),
    [
        (2, ("range",), False),
        (3, ("range", "dvl-water"), True),
        (3, ("range", "dvl-bottom", "depth"), False),
    ],
)
def test_local_information_is_the_gramian_of_the_held_input_flow(dim, sensors, current):
    # independent route: the outputs along the explicit flow of the held input
    # (p(s) = p + (v + v_f) s + u s²/2, v(s) = v + u s), differentiated with respect to the state
    # now and integrated over [-τ, 0] by Gauss-Legendre (exact: the integrand is a polynomial)
    model = make_model(dim=dim, sensors=sensors, current=current)
    tau = 1.7
    rng = np.random.default_rng(dim + len(sensors))
    x0 = rng.normal(size=model.state_dim)
    u0 = rng.normal(size=dim)
    w = rng.uniform(0.5, 2.0, size=model.output_dim)
    I = np.asarray(local_information_function(model, tau)(x0, u0, w))
    x = ca.SX.sym("x", model.state_dim)
    s = ca.SX.sym("s")
    u = ca.DM(u0)
    p, v = x[:dim], x[dim : 2 * dim]
    nu = v + x[2 * dim :] if current else v
    xs = ca.vertcat(p + nu * s + 0.5 * u * s**2, v + u * s, *([x[2 * dim :]] if current else []))
    J = ca.Function("J", [x, s], [ca.jacobian(model.h_expr(xs), x)])
    nodes, weights = np.polynomial.legendre.leggauss(8)
    ref = np.zeros_like(I)
    for z, q in zip(nodes, weights, strict=True):
        Jz = np.asarray(J(x0, 0.5 * tau * (z - 1.0)))
        ref += 0.5 * tau * q * (Jz.T * w) @ Jz
    assert np.allclose(I, ref, rtol=0, atol=1e-10 * np.max(np.abs(ref)))
    assert np.allclose(I, I.T) and np.min(np.linalg.eigvalsh(I)) > -1e-9 * np.max(np.abs(I))
    # the window as an input (one per call): the same information
    H = taylor_moments(lwo_orders(model), tau).ravel(order="F")
    I_in = np.asarray(local_information_function(model, None)(x0, u0, w, H))
    assert np.allclose(I_in, I, rtol=1e-13, atol=1e-13 * np.max(np.abs(I)))


def test_taylor_moments():
    H = taylor_moments(3, 2.0)
    assert H[0, 0] == pytest.approx(2.0)  # ∫ ds
    assert H[0, 1] == pytest.approx(-2.0)  # ∫ s ds over [-2, 0]
    assert H[1, 1] == pytest.approx(8.0 / 3.0)
    assert H[3, 3] == pytest.approx(2.0**7 / 7 / 36)
    assert np.all(np.linalg.eigvalsh(H) > 0)
