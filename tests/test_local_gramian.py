"""The local observability Gramian (the vehicle's model linearised about the path) and the
Gramian objectives that score it (``objective.system``)."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from test_windowed_gramian import SENSOR_CASES, _with  # every sensor set; objective fields

from obsplan.core.errors import ProblemError
from obsplan.observability import windowed as wd
from obsplan.observability.gramian import augmented_model, interval_gramians
from obsplan.observability.local_gramian import (
    LOS_FLOOR_M,
    linearised_model,
    local_interval_gramian_function,
    local_interval_gramians,
)
from obsplan.planning import load_problem
from obsplan.planning.objectives.windowed import (
    gramian_model,
    paper_form,
    sensor_information,
    start_information,
    window_floor,
    window_settings,
    windowed_value,
)
from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict
from obsplan.planning.transcription.guesses import random_guess
from obsplan.trajectory.sampled import Trajectory

ROOT = Path(__file__).resolve().parents[1]


def _weights(pb):
    return wd.local_row_weights(linearised_model(pb.model), sensor_information(pb), pb.scales)


def _fisher_by_finite_differences(traj: Trajectory, pb, k: int, per_interval: int) -> np.ndarray:
    """An independent route to interval ``k``'s contribution: the Fisher information about
    ``x(t_0)`` of samples on a fine grid of the interval (midpoint rule), each sample's
    Jacobian by central differences of the true outputs (range, DVL, depth) of the vehicle's
    model propagated from a perturbed ``x(t_0)`` with the path's inputs, in the metric scales."""
    L, T = pb.scales.length_m, pb.scales.time_s
    n, lm = pb.dim, linearised_model(pb.model)
    b = np.asarray(pb.beacon, float)
    w = _weights(pb)
    cur = np.zeros(n)  # the linearisation point's current: zero, as the planner's nominal path
    x0 = np.concatenate([traj.p[0], traj.v[0], *([cur] if lm.current else [])])
    h = traj.dt[k]

    def outputs(x, t):
        # exact double integrator from t_0 with the path's piecewise-constant input
        p, v = x[:n].copy(), x[n : 2 * n].copy()
        vf = x[2 * n :] if lm.current else np.zeros(n)
        dp = traj.p[k] - traj.p[0] - traj.v[0] * (traj.t[k] - traj.t[0])  # input part
        dv = traj.v[k] - traj.v[0]
        s = t - traj.t[k]
        tk = traj.t[k] - traj.t[0]
        pos = p + (v + vf) * (tk + s) + dp + dv * s + 0.5 * traj.u[k] * s**2
        vel = v + dv + traj.u[k] * s
        y = [np.linalg.norm(pos - b) / L]
        if any(x.startswith("dvl") for x in lm.sensors):
            bottom = lm.current and "dvl-bottom" in lm.sensors
            y += list((vel + (vf if bottom else 0.0)) * T / L)
        if "depth" in lm.sensors:
            y.append(pos[-1] / L)
        return np.asarray(y)

    scale = np.concatenate([np.full(n, L), np.full(lm.state_dim - n, L / T)])
    G = np.zeros((lm.state_dim, lm.state_dim))
    for j in range(per_interval):
        t = traj.t[k] + (j + 0.5) * h / per_interval
        J = np.zeros((lm.n_outputs, lm.state_dim))
        for i in range(lm.state_dim):
            e = np.zeros(lm.state_dim)
            e[i] = 1e-4 * scale[i]
            J[:, i] = (outputs(x0 + e, t) - outputs(x0 - e, t)) / (2e-4)
        G += (h / T / per_interval) * (J.T * w) @ J
    return G


@pytest.mark.parametrize("path", SENSOR_CASES)
def test_local_gramian_is_the_fisher_information_of_the_true_outputs(path):
    # Simpson on the exact path against a 400-point midpoint sum of finite-difference
    # Jacobians of the vehicle's own outputs: agreement to 1e-5 relative (the midpoint rule's
    # O(1/400²) and the differences' O(1e-8)); the trajectory is a random feasible guess
    pb = load_problem(ROOT / path)
    traj = random_guess(pb, 3)
    lm = linearised_model(pb.model)
    G = local_interval_gramians(traj, lm, np.asarray(pb.beacon), _weights(pb), pb.scales)
    for k in (0, traj.n_samples // 2, traj.n_samples - 2):
        expect = _fisher_by_finite_differences(traj, pb, k, 400)
        assert np.allclose(G[k], expect, rtol=0, atol=1e-5 * np.max(np.abs(expect))), k
        assert np.allclose(G[k], G[k].T) and np.linalg.eigvalsh(G[k]).min() > -1e-12 * np.max(
            np.abs(G[k])
        )


@pytest.mark.parametrize("path", SENSOR_CASES)
def test_symbolic_interval_equals_numpy(path):
    pb = load_problem(ROOT / path)
    traj = random_guess(pb, 1)
    lm = linearised_model(pb.model)
    w = _weights(pb)
    G = local_interval_gramians(traj, lm, np.asarray(pb.beacon), w, pb.scales)
    L, T = pb.scales.length_m, pb.scales.time_s
    f = local_interval_gramian_function(lm)
    b = np.asarray(pb.beacon)
    for k in (0, 7, traj.n_samples - 2):
        h = traj.dt[k]
        pa = traj.p[k] - b
        pm = pa + 0.5 * h * traj.v[k] + 0.125 * h**2 * traj.u[k]
        tk = (traj.t[k] - traj.t[0]) / T
        g = f(pa / L, pm / L, (traj.p[k + 1] - b) / L, tk, h / T, w, (LOS_FLOOR_M / L) ** 2)
        Gs = np.reshape(np.asarray(g), (lm.state_dim, lm.state_dim), order="F")
        assert np.allclose(Gs, G[k], rtol=0, atol=1e-12 * np.max(np.abs(G[k])))


def test_a_straight_leg_informs_the_linearised_model_and_not_the_augmented_one():
    # 2D range + DVL at constant velocity, not through the beacon: the DVL gives v, the
    # ranges |p - b|² and (p - b)·v, so an EKF learns the position (full rank), while the
    # augmented model's range row (d = 0) leaves p unseen. Range alone would not do: the whole
    # line turned about the beacon gives the same ranges.
    from obsplan.observability.gramian import AugmentedModel
    from obsplan.observability.local_gramian import LinearisedModel
    from obsplan.observability.scaling import Scales

    sensors = ("range", "dvl-water")
    lm = LinearisedModel(dim=2, sensors=sensors, current=False)
    t = np.linspace(0.0, 200.0, 101)
    p0, v0 = np.array([-60.0, 40.0]), np.array([0.5, 0.0])
    traj = Trajectory(t=t, p=p0 + np.outer(t, v0), v=np.tile(v0, (101, 1)), u=np.zeros((101, 2)))
    sc = Scales(100.0, 100.0)
    G = local_interval_gramians(traj, lm, np.zeros(2), np.ones(3), sc).sum(0)
    ev = np.linalg.eigvalsh(G)
    assert ev[0] > 1e-4 * ev[-1]
    Ga = interval_gramians(traj, AugmentedModel(dim=2, sensors=sensors, current=False), sc)
    Ga = Ga.sum(0)
    assert np.allclose(Ga[:2, :2], 0.0, atol=1e-12 * np.max(np.abs(Ga)))
    # and range alone: the turn about the beacon is in the kernel
    lr = LinearisedModel(dim=2, sensors=("range",), current=False)
    Gr = local_interval_gramians(traj, lr, np.zeros(2), np.ones(1), sc).sum(0)
    ev = np.linalg.eigvalsh(Gr)
    assert ev[0] < 1e-12 * ev[-1]
    turn = np.concatenate([[-p0[1], p0[0]], [-v0[1], v0[0]]]) / np.r_[[100.0] * 2, [1.0] * 2]
    assert np.linalg.norm(Gr @ turn) < 1e-9 * np.linalg.norm(Gr) * np.linalg.norm(turn)


def test_system_resolves_from_the_weights_and_the_paper_form_is_augmented():
    pb = load_problem(ROOT / "problems/suite/gramian-offset-beacon.toml")
    assert pb.objective.system == "auto" and pb.objective.resolved_system == "linearised"
    assert window_settings(pb).system == "linearised"
    assert gramian_model(pb).state_dim == 2 * pb.dim
    paper = _with(pb, window="mission", weights="none")
    assert paper.objective.resolved_system == "augmented" and paper_form(paper)
    # the paper's weights and window with the linearised system is not the paper's form
    assert not paper_form(_with(paper, system="linearised"))
    lwo = _with(pb, kind="lwo-condition")
    assert lwo.objective.resolved_system == "augmented"
    # gramian-log-det stays on the augmented model unless asked (LINEARISED_KINDS)
    ld = _with(pb, kind="gramian-log-det")
    assert ld.objective.resolved_system == "augmented" and window_settings(ld).opening
    assert _with(ld, system="linearised").objective.resolved_system == "linearised"


def test_augmented_system_keeps_the_augmented_windowed_objective():
    # system = "augmented" with information weights: the windows of the augmented Gramian
    # recomputed here from its interval contributions (no planner code)
    pb = _with(load_problem(ROOT / "problems/suite/gramian-depth3d.toml"), system="augmented")
    traj = random_guess(pb, 2)
    ws = window_settings(pb)
    assert ws.system == "augmented" and not ws.opening
    aug = augmented_model(pb.model)
    Gk = wd.weighted_interval_gramians(
        traj, aug, np.asarray(pb.beacon), sensor_information(pb), pb.scales
    )
    tau = (traj.t - traj.t[0]) / pb.scales.time_s
    a, b = np.asarray(ws.starts), np.asarray(ws.ends)
    G = wd.windowed_gramians(Gk, tau, aug, a, b, ws.anchor)
    tr, _ = wd.window_criteria(G, window_floor(pb, ws))
    agg = 0.5 * (np.mean(tr) + tr[-1])  # anchor "current"
    assert windowed_value(traj, pb) == pytest.approx(aug.state_dim / agg, rel=1e-12)
    # and the linearised default scores another model
    assert windowed_value(traj, _with(pb, system="auto")) != pytest.approx(
        windowed_value(traj, pb), rel=1e-3
    )


def test_linearised_windows_hold_the_ekf_prior_from_the_start():
    # both criteria score the opening windows of the linearised model, each holding the EKF's
    # prior (p, v[, v_f]) in the metric scales
    pb = _with(
        load_problem(ROOT / "problems/suite/gramian-current-water-dvl.toml"), system="linearised"
    )
    for kind in ("gramian-min-eig", "gramian-log-det"):
        ws = window_settings(_with(pb, kind=kind))
        assert ws.opening and ws.starts[0] == 0 and ws.ends[0] < ws.ends[-1]
    L, T, n, val = pb.scales.length_m, pb.scales.time_s, pb.dim, pb.validation
    P = np.linalg.inv(start_information(pb))
    assert P.shape == (3 * n, 3 * n)
    assert np.allclose(np.sqrt(np.diag(P)[:n]) * L, val.init_pos_error, rtol=1e-12)
    assert np.allclose(np.sqrt(np.diag(P)[n : 2 * n]) * L / T, val.init_vel_error, rtol=1e-12)
    # the augmented min-eig keeps full windows and no prior
    assert not window_settings(_with(pb, kind="gramian-min-eig", system="augmented")).opening


def test_a_range_informs_the_same_at_any_distance():
    # the linearised range row is the unit line of sight: moving the whole path away from the
    # beacon along the line of sight of a radial leg changes nothing
    pb = load_problem(ROOT / "problems/suite/gramian-offset-beacon.toml")
    lm = linearised_model(pb.model)
    t = np.linspace(0.0, 60.0, 31)
    b = np.asarray(pb.beacon, float)
    e = np.array([0.6, 0.8])
    paths = []
    for r in (10.0, 200.0):
        p = b + np.outer(r + 0.5 * t, e)
        paths.append(Trajectory(t=t, p=p, v=np.tile(0.5 * e, (31, 1)), u=np.zeros((31, 2))))
    G = [local_interval_gramians(tr, lm, b, _weights(pb), pb.scales).sum(0) for tr in paths]
    assert np.allclose(G[0], G[1], rtol=1e-12, atol=1e-12 * np.max(np.abs(G[0])))
    # per unit time, a range carries rate / σ_r² along its line of sight (metric scales)
    info = sensor_information(pb)
    L = pb.scales.length_m
    assert G[1][0, 0] + G[1][1, 1] == pytest.approx(
        info.range_rate * 60.0 * L**2 / info.range_std**2, rel=1e-12
    )


def test_a_path_through_the_beacon_stays_finite():
    # limits.min_range = 0 lets a path cross the beacon, where the line of sight is undefined:
    # the floor keeps the rows finite there (and the NLP's derivatives with them)
    pb = load_problem(ROOT / "problems/suite/gramian-offset-beacon.toml")
    lm = linearised_model(pb.model)
    b = np.asarray(pb.beacon, float)
    t = np.linspace(0.0, 20.0, 11)
    p = b + np.outer(t - 10.0, [0.5, 0.0])  # node 5 exactly at the beacon
    traj = Trajectory(t=t, p=p, v=np.tile([0.5, 0.0], (11, 1)), u=np.zeros((11, 2)))
    G = local_interval_gramians(traj, lm, b, _weights(pb), pb.scales)
    assert np.all(np.isfinite(G))
    L = pb.scales.length_m
    q = ca.SX.sym("q", 2)
    d2 = (LOS_FLOOR_M / L) ** 2
    g = local_interval_gramian_function(lm)(q, q, q, 0.1, 0.02, _weights(pb), d2)
    J = ca.Function("J", [q], [g, ca.jacobian(g, q)])
    for val in J(np.zeros(2)):
        assert np.all(np.isfinite(np.asarray(val)))


def test_bad_system_names_the_field():
    d = problem_to_dict(load_problem(ROOT / "problems/suite/gramian-offset-beacon.toml"))
    d["objective"]["system"] = "fisher"
    with pytest.raises(ProblemError, match='objective.system: must be "auto", "linearised"'):
        problem_from_dict(d)
    d["objective"]["system"] = "augmented"
    assert problem_from_dict(d).objective.resolved_system == "augmented"


def test_nlp_value_matches_for_every_sensor_set():
    # the planner's expression of the linearised objective (both kinds; gramian-log-det only
    # when asked) equals the value on a path
    from obsplan.planning.objectives.registry import objective_of
    from obsplan.planning.transcription.blocks import NLPContext
    from obsplan.planning.transcription.grid import Grid
    from obsplan.planning.transcription.guesses import reference_path

    for path in SENSOR_CASES:
        pb = load_problem(ROOT / path)
        for kind in ("gramian-min-eig", "gramian-log-det"):
            q = _with(pb, kind=kind, system="linearised")
            grid = Grid.from_problem(q)
            W = ca.MX.sym("W", 3 * q.dim, grid.N)
            ref = reference_path(q)
            term = objective_of(q).nlp(NLPContext(q, grid, W, ref, grid.from_trajectory(ref)))
            F = ca.Function("f", [W], [term.f])
            Wn = grid.from_trajectory(random_guess(q, 4))
            v = windowed_value(grid.to_trajectory(Wn), q)
            assert term.to_objective(float(F(Wn))) == pytest.approx(v, rel=1e-6), (path, kind)
