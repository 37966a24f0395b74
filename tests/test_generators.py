"""Generators of the Tables 1–3 motion classes: dynamic consistency, geometry, argument errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from obsplan.core.errors import ConfigError
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory

RHO, SPEED = 50.0, 2.6  # the paper's circle (Fig. 2)
OMEGA = SPEED / RHO
LAP = 2 * math.pi / OMEGA
# exact integration of N steps accumulates ~N ulps: 1e-9 m is far above that, far below any path
CONSISTENT = 1e-9


def assert_consistent(tr: Trajectory) -> None:
    pe, ve = tr.consistency_error()
    assert pe < CONSISTENT and ve < CONSISTENT


def _all_generated() -> list[Trajectory]:
    dt = 0.1
    return [
        gen.straight((-100, 60), (1, 0), 0.1, accel=0.02, duration=50).sample(dt),
        gen.straight(
            (1, 2, 3), (0, 1, 1), 1.0, accel=gen.sine_profile(0.1, 0.05, 7), duration=30
        ).sample(dt),
        gen.circle(RHO, SPEED, LAP).sample(dt),
        gen.circle(RHO, SPEED, 60, center=(10, -5), phase=1.0, z=5.0, ccw=False).sample(dt),
        gen.circle_z(RHO, SPEED, 90, z0=10, z_amp=5, z_period=90).sample(dt),
        gen.circle_z(RHO, SPEED, 90, z0=4, z_motion="straight", z_speed=-0.01).sample(dt),
        gen.circle_then_straight(
            RHO,
            SPEED,
            circle_duration=60,
            straight_duration=20,
            radial=True,
            straight_accel=0.02,
            dt=dt,
        ),
        gen.lawnmower((0, 0), 100, 20, 4, 2.0, start_with_circle=True).sample(dt),
        gen.lawnmower_within_limits((0, 0), 200, 100, 2.0, 0.2, 500, z=-5, z_speed=0.01).sample(dt),
        gen.paper_lawnmower(2).sample(dt),
        gen.paper_lawnmower(3).sample(dt),
    ]


def test_every_generator_is_dynamically_consistent():
    for tr in _all_generated():
        assert_consistent(tr)
        assert np.all(np.diff(tr.t) > 0)


@pytest.mark.parametrize("dt", [0.01, 0.1])
def test_circle_radius_and_velocity(dt):
    tr = gen.circle(RHO, SPEED, LAP).sample(dt)
    radius_err = np.abs(np.linalg.norm(tr.p, axis=1) - RHO).max()
    bound = RHO * (OMEGA * dt) ** 2 / 6  # trapezoidal step shortening (analytic.py docstring)
    assert radius_err <= bound * 1.01
    assert radius_err > bound * 0.5  # the error is the predicted one, not a lucky zero
    th = OMEGA * tr.t
    v_true = SPEED * np.column_stack([-np.sin(th), np.cos(th)])
    assert np.abs(tr.v - v_true).max() < 1e-9
    # chord inputs never exceed the centripetal acceleration
    assert np.linalg.norm(tr.u, axis=1).max() <= SPEED**2 / RHO


def test_circle_3d_plane_center_and_direction():
    tr = gen.circle(10.0, 1.0, 30, center=(3, 4), phase=math.pi / 2, z=-2.0, ccw=False).sample(0.05)
    assert tr.dim == 3
    np.testing.assert_allclose(tr.p[0], (3, 14, -2), atol=1e-12)
    np.testing.assert_allclose(tr.v[0], (1, 0, 0), atol=1e-12)  # clockwise from the top
    assert np.all(tr.p[:, 2] == -2.0) and np.all(tr.u[:, 2] == 0.0)
    assert np.abs(np.linalg.norm(tr.p[:, :2] - (3, 4), axis=1) - 10).max() < 1e-4


def test_straight_is_exactly_straight_and_speed_profile_is_accurate():
    prof = gen.sine_profile(0.02, 0.01, 20.0)
    T, dt = 100.0, 0.01
    tr = gen.straight((-100, 60), (1, 0), 0.1, accel=prof, duration=T).sample(dt)
    assert np.all(tr.p[:, 1] == 60.0) and np.all(tr.u[:, 1] == 0.0)
    assert np.all(tr.u[:-1, 0] >= 0.01 - 1e-15)  # never zero: LWO needs it (eq. 36)
    exact = 0.1 + 0.02 * T + 0.01 * 20 / (2 * math.pi) * (1 - math.cos(2 * math.pi * T / 20))
    assert abs(tr.v[-1, 0] - exact) < 1e-8  # midpoint rule: O(dt²)
    radial = gen.straight((-80, 60, 20), (80, -60, -20), 0.5, accel=prof, duration=60).sample(0.1)
    cross = np.cross(radial.p, radial.v)
    assert np.abs(cross).max() < 1e-9 * 100 * 2  # exactly radial up to round-off


def test_straight_accel_array_and_constant():
    tr = gen.straight((0, 0), (0, 2), 1.0, accel=0.5, duration=10).sample(0.5)
    np.testing.assert_allclose(tr.p[-1], (0, 1.0 * 10 + 0.25 * 100), atol=1e-12)
    arr = np.linspace(0, 1, 20)
    path = gen.straight((0, 0), (1, 0), 1.0, accel=arr, duration=10)
    tr2 = path.sample(0.5)  # one value per interval of 10 s / 20
    np.testing.assert_array_equal(tr2.u[:-1, 0], arr)
    assert path.duration == 10.0 and len(path.breakpoints) == 21
    p, v, a = path.evaluate(tr2.t)
    np.testing.assert_allclose(tr2.p, p, atol=1e-12)  # constant-acceleration pieces: exact
    np.testing.assert_allclose(tr2.v, v, atol=1e-12)
    fine = path.sample(0.1)  # five samples per held value
    np.testing.assert_array_equal(fine.u[:-1, 0], np.repeat(arr, 5))
    np.testing.assert_allclose(fine.p[-1], tr2.p[-1], atol=1e-12)


def test_a_line_with_a_callable_profile_is_the_integral_of_it():
    """Any callable: positions and velocities by quadrature agree with a sine profile's closed
    form; sampling holds the profile at interval midpoints."""
    prof = gen.sine_profile(0.02, 0.01, 20.0, phase=0.3)
    closed = gen.straight((1, 2), (3, 4), 0.5, accel=prof, duration=50)
    numeric = gen.straight((1, 2), (3, 4), 0.5, accel=lambda t: prof(t), duration=50)
    t = np.linspace(0, 50, 41)
    for a, b in zip(closed.evaluate(t), numeric.evaluate(t), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10)
    h = 1e-4
    p1, v1, _ = closed.evaluate(t[1:-1] - h)
    p2, v2, _ = closed.evaluate(t[1:-1] + h)
    _, v, a = closed.evaluate(t[1:-1])
    np.testing.assert_allclose((p2 - p1) / (2 * h), v, atol=1e-8)
    np.testing.assert_allclose((v2 - v1) / (2 * h), a, atol=1e-8)
    tr = numeric.sample(0.5)
    mid = tr.t[:-1] + 0.25
    np.testing.assert_array_equal(tr.u[:-1], np.outer(prof(mid), (0.6, 0.8)))
    scalar_only = gen.straight((0, 0), (1, 0), 0.5, accel=lambda t: 0.01 * math.cos(t), duration=9)
    assert scalar_only.sample(1.0).u[0, 0] == pytest.approx(0.01 * math.cos(0.5))


def test_generators_return_analytic_paths():
    from obsplan.trajectory import AnalyticPath

    paths = [
        gen.straight((0, 0), (1, 0), 1.0, duration=5),
        gen.parabola((0, 0), (1, 0), (0, 0.1), duration=5),
        gen.circle(RHO, SPEED, 5),
        gen.circle_z(RHO, SPEED, 5, z0=1, z_amp=1, z_period=10),
        gen.lawnmower((0, 0), 100, 20, 2, 2.0),
        gen.lawnmower_within_limits((0, 0), 200, 100, 2.0, 0.2, 5),
        gen.paper_lawnmower(3),
    ]
    for path in paths:
        assert isinstance(path, AnalyticPath)
        tr = path.sample()  # the paper's 0.01 s by default
        assert tr.t[1] == gen.DT and tr.t[-1] == path.duration


def test_time_grid_ends_exactly_at_duration():
    tr = gen.circle(RHO, SPEED, 10.05).sample(0.1)
    assert tr.t[-1] == 10.05 and np.all(np.diff(tr.t) > 0)
    assert abs(tr.t[-1] - tr.t[-2] - 0.05) < 1e-9


def test_circle_z_sine_and_straight():
    tr = gen.circle_z(RHO, SPEED, 180, z0=10, z_amp=5, z_period=90).sample(0.01)
    z_true = 10 + 5 * np.sin(2 * np.pi * tr.t / 90)
    assert np.abs(tr.p[:, 2] - z_true).max() < 1e-6
    assert np.abs(np.linalg.norm(tr.p[:, :2], axis=1) - RHO).max() < 1e-5
    st = gen.circle_z(RHO, SPEED, 60, z0=4, z_motion="straight", z_speed=-0.01).sample(0.1)
    assert np.all(st.u[:, 2] == 0.0)  # u_z = 0: the reason Fig. 5 is not observable
    np.testing.assert_allclose(st.p[:, 2], 4 - 0.01 * st.t, atol=1e-12)


@pytest.mark.parametrize("radial", [True, False])
def test_circle_then_straight_geometry(radial):
    tr = gen.circle_then_straight(
        RHO,
        SPEED,
        circle_duration=100,
        straight_duration=30,
        radial=radial,
        straight_accel=0.02,
        dt=0.05,
    )
    leg = tr.t >= 100 - 1e-9
    p, v = tr.p[leg], tr.v[leg]
    e = v / np.linalg.norm(v, axis=1)[:, None]
    dist_to_line = np.abs(p[:, 0] * e[:, 1] - p[:, 1] * e[:, 0])  # beacon's distance to the leg
    if radial:
        assert dist_to_line.max() < 1e-9
    else:
        np.testing.assert_allclose(dist_to_line, RHO, atol=1e-4)
    assert np.all(np.abs(tr.u[leg][:-1, 0] - 0.02) < 1e-12)


def test_lawnmower_turns_legs_and_area():
    speed, spacing, L, n = 2.0, 30.0, 160.0, 5
    tr = gen.lawnmower((-80, 60), L, spacing, n, speed, first_turn="right").sample(0.05)
    acc = np.linalg.norm(tr.u, axis=1)
    assert acc.max() <= 2 * speed**2 / spacing
    np.testing.assert_allclose(tr.duration, (n * L + (n - 1) * math.pi * spacing / 2) / speed)
    lo, hi = tr.p.min(axis=0), tr.p.max(axis=0)
    np.testing.assert_allclose(lo, (-80 - spacing / 2, 60 - (n - 1) * spacing), atol=1e-3)
    np.testing.assert_allclose(hi, (80 + spacing / 2, 60), atol=1e-3)
    on_legs = acc == 0.0
    lanes = 60.0 - spacing * np.arange(n)
    lane_err = np.abs(tr.p[on_legs, 1][:, None] - lanes[None, :]).min(axis=1)
    r, w = spacing / 2, speed / (spacing / 2)
    assert lane_err.max() <= (n - 1) * r * (w * 0.05) ** 2 / 3  # O(dt²) per turn (analytic.py)


def test_lawnmower_within_limits_respects_accel_and_fills_duration():
    speed, amax = 2.0, 0.2
    lay = gen.lawnmower_layout(200, 100, speed, amax)
    assert lay.spacing == pytest.approx(2 * speed**2 / amax) and lay.n_legs == 3
    assert lay.turn_accel == pytest.approx(amax) and lay.covered_height == 80.0
    path = gen.lawnmower_within_limits((0, 0), 200, 100, speed, amax, 2000.0)
    assert path.duration == 2000.0 and path.breakpoints[-1] == 2000.0
    assert np.all(np.diff(path.breakpoints) > 0)  # pieces after the end are not listed
    tr = path.sample(0.1)
    assert tr.t[-1] == 2000.0
    assert np.linalg.norm(tr.u, axis=1).max() <= amax * (1 + 1e-12)
    assert np.linalg.norm(tr.v, axis=1).max() <= speed * (1 + 1e-12)
    lo, hi = tr.p.min(axis=0), tr.p.max(axis=0)
    r = lay.turn_radius
    assert lo[0] >= -r - 1e-3 and hi[0] <= 200 - r + 1e-3  # within the stated width
    assert lo[1] >= -1e-3 and hi[1] <= lay.covered_height + 1e-3
    assert hi[1] > lay.covered_height - 1e-3  # it reaches the far side and sweeps back
    back = tr.p[tr.t > 0.8 * 2000, 1]
    assert back.min() < lay.covered_height  # still sweeping after the first pass
    from_rest = gen.lawnmower_within_limits(
        (0, 0), 200, 100, speed, amax, 300, initial_speed=0.0
    ).sample(0.1)
    assert np.all(from_rest.v[0] == 0)
    assert np.linalg.norm(from_rest.u, axis=1).max() <= amax * (1 + 1e-12)  # to round-off


def test_a_moving_start_turns_onto_the_first_leg_at_its_speed():
    """From a start moving north at 1 m/s, a lawn-mower heading east first turns right on a
    quarter circle of radius v²/a = 10 m (ending 10 m east and 10 m north of the start), then
    flies its legs from there; the velocity is continuous and the acceleration within its bound."""
    s, a = 1.0, 0.1
    end = gen.turn_onto_end((5.0, -3.0), (0.0, s), 0.0, a)
    np.testing.assert_allclose(end, (15.0, 7.0), atol=1e-12)
    np.testing.assert_allclose(gen.turn_onto_end((5.0, -3.0), (s, 0.0), 0.0, a), (5.0, -3.0))
    np.testing.assert_allclose(gen.turn_onto_end((5.0, -3.0), (0.0, 0.0), 1.0, a), (5.0, -3.0))
    # opposite: a left half circle (two radii to the left of the velocity)
    np.testing.assert_allclose(gen.turn_onto_end((0, 0), (s, 0), np.pi, a), (0.0, 20.0), atol=1e-9)
    tr = gen.lawnmower_within_limits(
        (5.0, -3.0), 200, 100, 2.0, a, 600.0, initial_velocity=(0.0, s)
    ).sample(0.1)
    np.testing.assert_allclose(tr.p[0], (5.0, -3.0), atol=1e-12)
    np.testing.assert_allclose(tr.v[0], (0.0, s), atol=1e-12)
    assert np.linalg.norm(tr.u, axis=1).max() <= a * (1 + 1e-12)
    quarter = np.pi / 2 * 10.0 / s  # the turn's duration [s]
    k = int(np.ceil(quarter / 0.1)) + 1
    np.testing.assert_allclose(tr.v[k] / np.linalg.norm(tr.v[k]), (1.0, 0.0), atol=1e-9)
    # on the first leg, 10 m north, to the chord inputs' offset r (w h)² / 6 (analytic.py docstring)
    assert tr.p[k, 1] == pytest.approx(7.0, abs=10.0 * (s / 10.0 * 0.1) ** 2 / 6)


def test_paper_lawnmower_start_states():
    tr2 = gen.paper_lawnmower(2).sample(0.1)
    np.testing.assert_allclose(tr2.p[0], (-80, 60))
    np.testing.assert_allclose(tr2.v[0], (0, 0))  # Fig. 3 starts from rest
    assert tr2.u[0, 0] > 0
    tr3 = gen.paper_lawnmower(3).sample(0.1)
    np.testing.assert_allclose(tr3.p[0], (-80, 60, 5))
    np.testing.assert_allclose(tr3.v[0], (2, 0, -0.01))


def test_concat_and_then_straight():
    c = gen.circle(RHO, SPEED, 30).sample(0.1)
    leg = gen.straight(c.p[-1], c.v[-1], SPEED, duration=10).sample(0.1)
    both = gen.concat(c, leg)
    assert both.n_samples == c.n_samples + leg.n_samples - 1
    assert_consistent(both)
    via = gen.then_straight(c, duration=10, dt=0.1)
    np.testing.assert_allclose(via.p, both.p, atol=1e-12)
    bad = gen.straight(c.p[-1], (1, 0), SPEED, duration=10).sample(0.1)
    with pytest.raises(ConfigError, match="velocity"):
        gen.concat(c, bad)
    far = gen.straight(c.p[-1] + 1.0, c.v[-1], SPEED, duration=10).sample(0.1)
    with pytest.raises(ConfigError, match="starts"):
        gen.concat(c, far)
    with pytest.raises(ConfigError, match="parallel"):
        gen.then_straight(c, duration=5, direction=(1, 1))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: gen.circle(0, SPEED, 10), "radius"),
        (lambda: gen.circle(-5, SPEED, 10), "radius"),
        (lambda: gen.circle(RHO, float("nan"), 10), "speed"),
        (lambda: gen.circle(RHO, SPEED, 0.01).sample(0.01), "duration"),
        (lambda: gen.circle(RHO, SPEED, 10).sample(0), "dt"),
        (lambda: gen.circle(RHO, SPEED, 10, center=(0, 0, 1), z=2), "height"),
        (lambda: gen.circle(RHO, SPEED, 10, center=(0,)), "center"),
        (lambda: gen.straight((0, 0), (0, 0), 1, duration=5), "direction"),
        (lambda: gen.straight((0, 0), (1, 0, 0), 1, duration=5), "direction"),
        (lambda: gen.straight((0, 0), (1, 0), -1, duration=5), "speed0"),
        (lambda: gen.straight((0, 0), (1, 0), 0, duration=5), "not move"),
        (lambda: gen.straight((0, 0), (1, 0), 1, accel=[], duration=5), "accel"),
        (lambda: gen.straight((0, 0), (1, 0), 1, accel=[1, np.nan], duration=5), "accel"),
        (lambda: gen.straight((0, 0), (1, 0), 0, accel=lambda t: 0 * t, duration=5), "move"),
        (lambda: gen.parabola((0, 0), (1, 0), (0, 1), duration=5).sample(10), "duration"),
        (lambda: gen.paper_lawnmower(2).sample(-0.1), "dt"),
        (lambda: gen.circle_z(RHO, SPEED, 10, z0=1), "z_amp"),
        (lambda: gen.circle_z(RHO, SPEED, 10, z0=1, z_amp=0, z_period=5), "z_amp"),
        (lambda: gen.circle_z(RHO, SPEED, 10, z0=1, z_motion="straight", z_speed=0), "z_speed"),
        (lambda: gen.circle_z(RHO, SPEED, 10, z0=1, z_motion="zigzag"), "z_motion"),
        (lambda: gen.lawnmower((0, 0), 100, 20, 0, 2.0), "n_legs"),
        (lambda: gen.lawnmower((0, 0), 100, 20, 3, 2.0, turn="bulb"), "turn"),
        (lambda: gen.lawnmower((0, 0), 100, -20, 3, 2.0), "spacing"),
        (lambda: gen.lawnmower((0, 0), 100, 20, 3, 2.0, initial_speed=-1), "initial_speed"),
        (
            lambda: gen.lawnmower((0, 0), 10, 20, 3, 2.0, initial_speed=0, initial_accel=0.01),
            "within the first leg",
        ),
        (lambda: gen.lawnmower_layout(200, 10, 2.0, 0.2), "too small"),
        (lambda: gen.lawnmower_within_limits((0, 0), 200, 100, 2.0, 0.0, 100), "accel_max"),
        (lambda: gen.sine_profile(0.1, 0.05, 0), "period"),
        (lambda: gen.straight((0, 0), (1, 0), 1, accel=lambda t: "x", duration=5), "accel"),
        (lambda: gen.paper_lawnmower(4), "dim"),
    ],
)
def test_argument_errors_name_the_parameter(call, match):
    with pytest.raises(ConfigError, match=match):
        call()
