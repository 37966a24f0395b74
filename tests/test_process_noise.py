"""The physical process noise: a continuous white acceleration, exact for any filter step.

The truth, the filters and the bound integrate one intensity, so their results do not depend on
the filter step beyond the discretisation of the path itself; the paper's per-step setting,
kept as a preset, does.
"""

from __future__ import annotations

import numpy as np
import pytest

from obsplan.core.errors import ConfigError
from obsplan.estimation import EstimationConfig, monte_carlo
from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import DEFAULT_ACCEL_NOISE
from obsplan.estimation.montecarlo.truth import truth_factor
from obsplan.model.vehicle import make_model
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory

STEPS = (0.05, 0.1, 0.5)


def resampled(traj: Trajectory, dt: float) -> Trajectory:
    """The same path (piecewise-constant inputs) on a grid of step ``dt`` dividing its own."""
    k = int(round(traj.dt[0] / dt))
    u = np.repeat(traj.u[:-1], k, axis=0)
    t = traj.t[0] + dt * np.arange(u.shape[0] + 1)
    return Trajectory.from_inputs(t, traj.p[0], traj.v[0], u)


@pytest.fixture(scope="module")
def path():
    """A 600 s circle flown with 1 s inputs, range at 1 Hz (its epochs are on every grid)."""
    return gen.circle(51.0, 1.0, 600.0, center=(0.0, 2.0)).sample(1.0)


def test_default_intensity_matches_the_paper_at_the_default_step():
    """accel_noise = sqrt(1e-7): velocity variance per 0.1 s step (1e-3 · 0.1)²."""
    model = make_model(2, "range")
    cfg = EstimationConfig(model=model)
    assert DEFAULT_ACCEL_NOISE == pytest.approx(3.1623e-4, rel=1e-4)
    q = cfg.covariances(0.1)["q_ekf"]
    paper = EstimationConfig.paper(model, 0.1).covariances(0.1)["q_ekf"]
    np.testing.assert_allclose(np.diag(q)[2:], np.diag(paper)[2:], rtol=1e-12)
    # per axis q [[h³/3, h²/2], [h²/2, h]] on (p, v)
    h, qa = 0.37, 1e-7
    Q = cfg.covariances(h)["q_ekf"]
    np.testing.assert_allclose(Q[0, [0, 2]], qa * np.array([h**3 / 3, h**2 / 2]), rtol=1e-12)
    np.testing.assert_allclose(Q[2, [0, 2]], qa * np.array([h**2 / 2, h]), rtol=1e-12)
    assert Q[0, 1] == Q[0, 3] == 0.0
    assert cfg.to_dict()["process_noise_model"] == "continuous"
    assert EstimationConfig.paper(model, 0.1).to_dict()["process_noise_model"] == "per-step"


def test_current_random_walk_enters_position_and_current():
    cfg = EstimationConfig(
        model=make_model(2, "range,dvl-water", current=True), accel_noise=2e-3, current_noise=1e-3
    )
    h = 0.5
    Q = cfg.covariances(h)["q_ekf"]
    qa, qf = 4e-6, 1e-6
    assert Q[0, 0] == pytest.approx((qa + qf) * h**3 / 3, rel=1e-12)
    assert Q[0, 2] == pytest.approx(qa * h**2 / 2, rel=1e-12)
    assert Q[0, 4] == pytest.approx(qf * h**2 / 2, rel=1e-12)
    assert Q[4, 4] == pytest.approx(qf * h, rel=1e-12) and Q[2, 4] == 0.0
    # the truth's factor of a step reproduces Q(h) (two normals per white source)
    pn = cfg.process_noise_model()
    L, e = truth_factor(True, pn.q_ekf, 2, True)
    Lh = (h**e)[:, None] * L
    np.testing.assert_allclose(Lh @ Lh.T, Q, rtol=1e-12, atol=1e-20)
    assert L.shape == (6, 8)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"accel_noise": 1e-3, "q_ekf": np.ones(4)}, "not both"),
        ({"accel_noise": -1.0}, "accel_noise must be an intensity"),
        ({"current_noise": 1e-3}, "no current"),
        ({"current_noise": float("nan")}, "current_noise must be an intensity"),
    ],
)
def test_bad_process_noise_gets_one_clear_error(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        EstimationConfig(model=make_model(2, "range"), **kwargs)


def test_posterior_crlb_does_not_depend_on_the_filter_step(path):
    """On one path resampled exactly to 0.05, 0.1 and 0.5 s (range at 1 Hz: the same epochs on
    every grid) the physical noise gives the same final bound to round-off (1e-9: measured
    1e-12, the gap integrals are exact); the paper's per-step noise changes it by 2.5x."""
    model = make_model(2, "range")
    cfg = EstimationConfig(model=model, rates_hz={"range": 1.0})
    bounds = [posterior_crlb(resampled(path, dt), cfg).final_pos_std for dt in STEPS]
    np.testing.assert_allclose(bounds, bounds[1], rtol=1e-9)
    paper = [
        posterior_crlb(
            resampled(path, dt), EstimationConfig.paper(model, dt, rates_hz={"range": 1.0})
        ).final_pos_std
        for dt in STEPS
    ]
    assert paper[2] > 2.0 * paper[0]


def test_posterior_crlb_of_a_path_generated_at_each_step():
    """The circle generated at each step (chord inputs of that step: the path itself changes,
    its radius by up to 9e-4 m at 0.5 s) with a DVL at 2 Hz: the bound agrees within 2 %. The
    tolerance is the path's discretisation, O((ω dt)²) in position and in the information of
    each range (measured 5e-8 relative), far below the factor 2.5 of the per-step noise."""
    model = make_model(2, "range,dvl-water")
    cfg = EstimationConfig(model=model, rates_hz={"range": 1.0, "dvl-water": 2.0})
    b = [
        posterior_crlb(
            gen.circle(51.0, 1.0, 600.0, center=(0.0, 2.0)).sample(dt), cfg
        ).final_pos_std
        for dt in STEPS
    ]
    np.testing.assert_allclose(b, b[1], rtol=0.02)


def test_filter_statistics_do_not_depend_on_the_filter_step(path):
    """100 runs on the resampled path at each step. The runs share their initial errors and
    reading noises (same streams) and differ by the process noise's draws only. The filters'
    reported final std is a function of the estimate only: equal within 2 % (measured 0.07 %);
    the mean squared final error is compared by a paired test over the runs (|z| < 4: a 4-sigma
    bound on the difference of two estimates of one expectation); the KF's NEES is in the 95 %
    band of 100 runs at every step (measured |z| <= 1.2)."""
    cfg = EstimationConfig(model=make_model(2, "range"), rates_hz={"range": 1.0})
    res = {
        dt: monte_carlo(resampled(path, dt), cfg, runs=100, seed=0, filters=("ekf", "kf"))
        for dt in STEPS
    }
    ref = res[0.1]
    for dt in STEPS:
        r = res[dt]
        for name in ("ekf", "kf"):
            a, b = r.stats(name), ref.stats(name)
            assert a.final_pos_std == pytest.approx(b.final_pos_std, rel=0.02)
            d = a.final_pos_err_runs**2 - b.final_pos_err_runs**2
            if dt != 0.1:
                z = d.mean() / (d.std(ddof=1) / np.sqrt(d.size))
                assert abs(z) < 4.0, (dt, name, z)
        lo, hi = r.kf.nees_bounds
        assert lo <= r.kf.nees_mean <= hi
