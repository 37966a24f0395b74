"""The linearised closed loop's covariance against Monte Carlo runs of the same loop.

Two oracles: a plain numpy simulation of the linear loop (a Kalman filter with the posterior
CRB's rows, the guidance's feedback on its estimate, process noise drawn step by step), which
checks the algebra of :mod:`obsplan.estimation.bounds.loop_covariance` exactly up to Monte Carlo
noise; and the validation's own closed-loop kernel (the second-order EKF the vehicle steers on),
which checks that the linearisation describes it once the filter has converged.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

from obsplan.estimation.bounds.loop_covariance import loop_covariance, loop_gain_matrix
from obsplan.estimation.montecarlo.closedloop import ClosedLoop
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.objectives.estimator import covariance_objective
from obsplan.planning.problem.validation_setup import (
    estimation_config,
    truth_limits,
    validation_guidance,
)
from obsplan.planning.solver.margins import path_loop_covariance
from obsplan.planning.transcription.grid import Grid
from obsplan.trajectory.sampled import resample


def _van_loan(A: np.ndarray, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(F, Q)`` of one step ``dt`` of ``x' = A x + w`` with white noise of intensity ``q``."""
    m = A.shape[0]
    M = np.zeros((2 * m, 2 * m))
    M[:m, :m], M[:m, m:], M[m:, m:] = -A, q, A.T
    E = scipy.linalg.expm(M * dt)
    F = E[m:, m:].T
    return F, F @ E[:m, m:]


def _simulate_linear_loop(cobj, h, rho, kp, kd, runs, seed):
    """Per epoch, the sample covariances of ``ε`` and ``δ`` and the filter's ``T P Tᵀ`` (numpy,
    step by step on the filter grid)."""
    model, ep = cobj.model, cobj.epochs
    m, n = model.m, model.n
    T = np.asarray(model.nav, float)
    rng = np.random.default_rng(seed)
    P = np.asarray(cobj.P0, float).copy()
    e = rng.multivariate_normal(np.zeros(m), P, size=runs)  # e = x̂ - x
    eps = np.zeros((runs, 2 * n))
    out = []
    for j in range(ep.count):
        rows = [(np.zeros(m), float(rho[0, j]), model.range_sensor)]
        rows[0][0][list(model.range_support)] = h[:, j]
        rows += list(zip(model.rows, model.row_var, model.row_sensor, strict=True))
        for r, var, sensor in rows:
            if ep.mask[j, sensor] == 0:
                continue
            r = np.asarray(r, float)
            K = P @ r / (r @ P @ r + var)
            nu = rng.normal(0.0, np.sqrt(var), size=runs)
            corr = np.outer(-(e @ r) + nu, K)  # x̂⁺ - x̂ = K (y - r x̂)
            e = e + corr
            eps = eps + corr @ T.T
            P = P - np.outer(K, r @ P)
        delta = eps - e @ T.T
        out.append((np.cov(eps.T), np.cov(delta.T), T @ P @ T.T))
        if j == ep.count - 1:
            break
        dt, k = float(ep.dt[j]), int(ep.gap[j])
        A, q = np.asarray(model.A, float), np.asarray(model.q, float)
        if model.continuous:  # an intensity
            F, Q = _van_loan(A, q, dt)
        else:  # the covariance added per filter step (the physical noise's exact Q(dt))
            F, Q = np.eye(A.shape[0]) + A * dt + 0.5 * A @ A * dt**2, q
        phi = loop_gain_matrix(kp, kd, dt, n)
        L = np.linalg.cholesky(Q + 1e-30 * np.eye(m))
        for _ in range(k):
            e = e @ F.T + rng.standard_normal((runs, m)) @ L.T
            eps = eps @ phi.T
            P = F @ P @ F.T + Q
    return out


def test_the_linear_loop_covariance_matches_a_simulation_of_the_linear_loop(
    short_problem, lawnmower
):
    """The joint recursion is the second moment of the linear loop: the filter block equals a
    plain Kalman recursion to round-off (1e-9 relative), the deviations match 3000 simulated runs
    within 8 % in std (about 6 standard errors of a std estimated from 3000 samples)."""
    g = validation_guidance(short_problem, at_sea=True)
    cobj = covariance_objective(short_problem, "pcrb-position")
    grid = Grid.from_problem(short_problem)
    h, rho = (np.asarray(x, float) for x in cobj.rows(grid, grid.from_trajectory(lawnmower)))
    lc = loop_covariance(cobj.model, cobj.epochs, cobj.P0, h, rho, g.kp, g.kd, cobj.mask)
    sim = _simulate_linear_loop(cobj, h, rho, g.kp, g.kd, runs=3000, seed=3)
    n = short_problem.dim
    checked = 0
    for j in range(5, cobj.epochs.count, 10):
        eps, delta, filt = sim[j]
        np.testing.assert_allclose(lc.filter[j], filt, rtol=1e-9, atol=1e-12)
        for lin, mc in ((lc.estimated[j], eps), (lc.true[j], delta)):
            s_lin, s_mc = np.sqrt(np.diag(lin)), np.sqrt(np.diag(mc))
            np.testing.assert_allclose(s_mc, s_lin, rtol=0.08)
        # the feedback command's std, per axis
        c = lc.command_std(g.kp, g.kd)[j]
        cmd = [
            g.kp**2 * eps[i, i] + 2 * g.kp * g.kd * eps[i, n + i] + g.kd**2 * eps[n + i, n + i]
            for i in range(n)
        ]
        np.testing.assert_allclose(np.sqrt(cmd), c, rtol=0.08)
        checked += 1
    assert checked >= 10


def test_the_estimated_deviation_is_much_smaller_than_the_true_one_once_converged(
    short_problem, lawnmower
):
    """A slowly varying estimation error moves the vehicle, not the command: once the filter has
    converged the estimated deviation (what the feedback sees) is a fraction of the true one."""
    g = validation_guidance(short_problem, at_sea=True)
    lc = path_loop_covariance(lawnmower, short_problem, g)
    late = lc.time >= 100.0  # the last 20 s of the 120 s lawn-mower
    est = lc.std("estimated", "pos")[late]
    true = lc.std("true", "pos")[late]
    assert np.all(est < 0.5 * true)


@pytest.mark.slow
def test_the_validations_closed_loop_matches_the_linearisation_once_converged(short_problem):
    """The validation's kernel (second-order EKF, saturations, the real range) against the
    linearisation over the last minute of the circle about the beacon, 400 runs, robust stds
    (half the 16-84 % range, so a run the EKF loses does not count; about 6 % standard error):

    * the feedback command (what the acceleration reserve is kept for) within 15 % or 1 % of the
      acceleration bound (the EKF's covariance is a few % above the CRB the linearisation uses, and
      its corrections with it; the second-order filter's bias and the hold between filter steps are
      left out);
    * the true deviation (what the vehicle does) within 15 % or 10 % of the filter's own largest
      position or velocity std.

    The circle flies at the speed bound, which the guidance would hold back (a saturation the
    linearisation leaves out), so it is flown under a bound 50 % higher."""
    circle = baselines(short_problem)["circle"].trajectory
    pb = replace(
        short_problem, limits=replace(short_problem.limits, speed=1.5 * short_problem.limits.speed)
    )
    g = validation_guidance(pb, at_sea=True)
    lc = path_loop_covariance(circle, pb, g)
    fine = resample(circle, pb.validation.dt)
    loop = ClosedLoop(
        fine,
        estimation_config(pb),
        runs=400,
        seed=1,
        guidance=g,
        limits=truth_limits(pb),
        filters=("ekf",),
    )
    n = pb.dim
    accel = np.asarray(g.bounds(n))

    def robust_std(x):
        q16, q84 = np.quantile(x, [0.16, 0.84], axis=0)
        return (q84 - q16) / 2

    for t in (60.0, 90.0, 119.0):
        j = int(np.argmin(np.abs(lc.time - t)))
        loop.advance(float(lc.time[j]))
        s = loop.snapshot()
        xref = np.concatenate([fine.p[s.k], fine.v[s.k]])
        eps = s.estimate[:, : 2 * n] - xref
        delta = s.truth[:, : 2 * n] - xref
        cmd_mc = robust_std(-(g.kp * eps[:, :n] + g.kd * eps[:, n:]))
        cmd = lc.command_std(g.kp, g.kd)[j]
        assert np.all(np.abs(cmd_mc - cmd) <= 0.15 * cmd + 0.01 * accel), (t, cmd_mc, cmd)
        floor = np.repeat([lc.std("filter", b)[j].max() for b in ("pos", "vel")], n)
        dev_mc, dev = robust_std(delta), np.sqrt(np.diag(lc.true[j]))
        assert np.all(np.abs(dev_mc - dev) <= 0.15 * dev + 0.1 * floor), (t, dev_mc, dev)
