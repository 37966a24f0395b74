"""Vehicle model: exact discretisation, outputs and Jacobians, configuration errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from obsplan.core.errors import ConfigError
from obsplan.model.vehicle import make_model, parse_sensors


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("current", [False, True])
@pytest.mark.parametrize("dt", [1e-3, 0.1, 7.5])
def test_transition_is_exact_zoh(dim, current, dt):
    """F, G equal the blocks of expm([[A, B], [0, 0]] dt) (eqs. 4, 47), to 1e-14 relative."""
    model = make_model(dim, current=current)
    x, u = np.zeros(model.state_dim), np.zeros(dim)
    A = np.asarray(model.f.jacobian()(x, u, 0)[0])  # ∂f/∂x, then ∂f/∂u
    B = np.asarray(model.f.jacobian()(x, u, 0)[1])
    m = model.state_dim
    M = np.zeros((m + dim, m + dim))
    M[:m, :m], M[:m, m:] = A, B
    E = expm(M * dt)
    F, G = model.transition(dt)
    np.testing.assert_allclose(F, E[:m, :m], rtol=1e-14, atol=1e-14 * max(1, dt))
    np.testing.assert_allclose(G, E[:m, m:], rtol=1e-14, atol=1e-14 * max(1, dt**2))


def test_outputs_and_jacobian():
    rng = np.random.default_rng(0)
    b = np.array([3.0, -1.0, 2.0])
    p, v, vf = rng.standard_normal((3, 3))
    x = np.r_[p, v, vf]
    cases = {
        "half-squared": (0.5 * np.sum((p - b) ** 2), np.r_[p - b, np.zeros(6)]),
        "range": (np.linalg.norm(p - b), np.r_[(p - b) / np.linalg.norm(p - b), np.zeros(6)]),
    }
    for form, (y_exp, row_exp) in cases.items():
        model = make_model(3, "range,dvl-bottom,depth", current=True, beacon=b, range_form=form)
        y = np.asarray(model.h(x)).ravel()
        H = np.asarray(model.H(x))
        assert y[0] == pytest.approx(y_exp)
        np.testing.assert_allclose(y[1:4], v + vf)  # eq. 48
        assert y[4] == p[2]
        np.testing.assert_allclose(H[0], row_exp, rtol=1e-14)
        np.testing.assert_array_equal(H[1:4, 3:], np.hstack([np.eye(3), np.eye(3)]))
        assert model.output_names == (
            ("y" if form == "half-squared" else "r"),
            "dvl_x",
            "dvl_y",
            "dvl_z",
            "depth",
        )
    water = make_model(3, "range,dvl-water", current=True)
    np.testing.assert_allclose(np.asarray(water.h(x)).ravel()[1:], v)  # eq. 49


def test_sensor_parsing():
    assert parse_sensors("range, DVL") == ("range", "dvl-bottom")
    assert parse_sensors(["depth", "range"]) == ("range", "depth")
    assert make_model(2, "range,dvl-water").sensors == ("range", "dvl-water")


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(sensors="range,sonar"), "unknown sensor 'sonar'"),
        (dict(sensors="range,range"), "listed twice"),
        (dict(sensors="range,dvl-bottom,dvl-water"), "one DVL mode"),
        (dict(sensors="dvl"), "must include 'range'"),
        (dict(sensors="range,depth"), "needs dim = 3"),
        (dict(beacon=(1.0, 2.0, 3.0)), "beacon must be 2 finite"),
        (dict(beacon=(1.0, float("nan"))), "beacon must be 2 finite"),
        (dict(range_form="squared"), "range_form"),
        (dict(dim=4), "dim must be 2 or 3"),
    ],
)
def test_configuration_errors(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        make_model(**{"dim": 2, **kwargs})
