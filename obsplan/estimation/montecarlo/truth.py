"""Truth simulation: the vehicle along a trajectory, perturbed by process noise, and its readings.

The truth of run ``r`` at sample ``k`` is ``x_k = x̄_k + δ_k`` where ``x̄`` is the trajectory's state
(``p``, ``v = p' - v_f``, ``v_f``) and ``δ_{k+1} = F_k δ_k + w_k``, ``w_k = L_k z_k ~ N(0, Q_k)``
(exact ZOH ``F_k``, ``L_k L_kᵀ = Q_k``): with no process noise the truth is the trajectory itself.
In closed loop (:mod:`obsplan.estimation.montecarlo.closedloop`) the truth adds the response to the
input corrections, ``x = x̄ + c + δ``, with the same ``δ``.

Process noise per step (:func:`truth_factor`): with the physical noise (white acceleration of
intensity ``q``, optionally a current random walk ``q_f``) ``Q_k`` is the exact integral over the
step ``h_k``, and ``L_k = diag(h_k^e) L_1`` with exponents ``e = 3/2`` on ``p`` and ``1/2`` on
``v``, ``v_f``: each white source of intensity ``q_s`` on state ``j`` (``v_i`` or ``v_f,i``) feeding
``p_i`` gets two columns, ``sqrt(q_s) (1/√3, √3/2)`` on ``(p_i, j)`` and ``sqrt(q_s) (0, 1/2)``,
whose outer products sum to ``q_s [[h³/3, h²/2], [h²/2, h]]``; sources in state order (the
accelerations, then the current). In the paper's per-step setting ``L_k = L``
(:func:`noise_factor` of the per-step ``Q``).
Readings are the device quantities (range ``r`` [m], DVL [m/s], depth [m]) plus Gaussian noise,
drawn only where the schedule says the sensor reports.

Random streams
--------------
Every draw of run ``r`` comes from a stream that depends only on ``(seed, r)`` and its purpose, so
run ``r`` is the same whatever the number of runs, the batch it is computed in (sharding by runs)
or the other sensors fitted; each is ``numpy.random.default_rng(SeedSequence(seed,
spawn_key=key))`` with

==========================  ===================================================================
key                         draws, in order
==========================  ===================================================================
``(r, 0)``                  initial error: ``state_dim`` normals (``x̂0 - x0 = chol(P0) z``),
                            then 2 normals for the KF's ``(p0ᵀν0, |ν0|²)`` (``init_error="sample"``)
``(r, 1)``                  process noise: ``(N - 1, columns of L)`` normals, row ``k`` drives
                            step ``k`` (drawn in one call, or in consecutive blocks of rows: the
                            same numbers)
``(r, 2, i)``               noise of sensor ``SENSORS[i]``: ``(reports, width)`` normals
``(r, 3, i)``               dropout of sensor ``SENSORS[i]``: ``reports`` uniforms (if it drops;
                            the range's also when the channel loses pings)
``(r, 4)``                  the acoustic channel (:mod:`obsplan.estimation.channel`, not ideal):
                            ``reports`` uniforms of multipath, then ``reports`` of the excess,
                            then ``reports`` of the ping's time
==========================  ===================================================================

The channel's draws do not depend on the path, so every path compared sees the same lost and
late pings (a loss that grows with range compares the same uniforms with each path's own
probability).

where ``reports`` counts the samples at which the sensor reports (in time order) and ``width`` is
its number of outputs. The steps are drawn for all samples at once and summed by a compiled
recursion; only the states at the epochs and records are kept.
"""

from __future__ import annotations

import numpy as np

from obsplan.estimation.channel import Channel, channel_errors
from obsplan.estimation.montecarlo.stats import empty_metrics
from obsplan.model.vehicle import SENSORS, VehicleModel
from obsplan.trajectory.sampled import Trajectory

STREAM_INIT, STREAM_PROCESS, STREAM_NOISE, STREAM_DROPOUT, STREAM_CHANNEL = 0, 1, 2, 3, 4


def run_rng(seed: int, run: int, purpose: int, sensor: str | None = None) -> np.random.Generator:
    """The generator of run ``run`` for one purpose (module docstring), from ``seed`` alone.

    Parameters
    ----------
    seed : int
        The Monte Carlo's seed.
    run : int
        Run index.
    purpose : int
        ``STREAM_INIT``, ``STREAM_PROCESS``, ``STREAM_NOISE`` or ``STREAM_DROPOUT``.
    sensor : str or None, optional
        The sensor of a noise or dropout stream.

    Returns
    -------
    numpy.random.Generator
        The stream (module docstring, "Random streams").
    """
    key = (
        (int(run), int(purpose))
        if sensor is None
        else (int(run), int(purpose), SENSORS.index(sensor))
    )
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=key))


def noise_factor(Q: np.ndarray) -> np.ndarray:
    """``L`` (m × rank) with ``L Lᵀ = Q`` for a PSD (possibly singular) ``Q``.

    A diagonal ``Q`` gives the columns ``sqrt(Q_ii) e_i`` of its non-zero entries in state order,
    otherwise the scaled eigenvectors of the non-zero eigenvalues (ascending).

    Parameters
    ----------
    Q : ndarray, shape (m, m)
        Symmetric positive semi-definite covariance.

    Returns
    -------
    ndarray, shape (m, rank)
        The factor ``L``.
    """
    Q = 0.5 * (Q + Q.T)
    if np.count_nonzero(Q - np.diag(np.diag(Q))) == 0:
        idx = np.flatnonzero(np.diag(Q) > 0)
        L = np.zeros((Q.shape[0], idx.size))
        L[idx, np.arange(idx.size)] = np.sqrt(np.diag(Q)[idx])
        return L
    lam, V = np.linalg.eigh(Q)
    keep = lam > 1e-14 * max(float(lam.max()), 0.0)
    return V[:, keep] * np.sqrt(lam[keep])


def truth_factor(
    continuous: bool, q: np.ndarray, n: int, current: bool
) -> tuple[np.ndarray, np.ndarray]:
    """``(L_1, e)`` with ``L_k = diag(h_k^e) L_1`` the noise factor of a step ``h_k`` (module
    docstring); ``q`` is the intensity ``W`` (continuous) or the per-step ``Q``, (m, m).

    Parameters
    ----------
    continuous : bool
        ``q`` is an intensity of the physical noise (diagonal, on ``v`` and ``v_f`` only).
    q : ndarray, shape (m, m)
        Intensity [m²/s³] or per-step covariance of the process noise.
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.

    Returns
    -------
    L_1 : ndarray, shape (m, c)
        The factor of a unit step.
    e : ndarray, shape (m,)
        The exponents of the step length per state (zeros in the per-step setting).

    Raises
    ------
    ValueError
        If a continuous intensity is not diagonal on ``v`` (and ``v_f``).
    """
    q = np.asarray(q, float)
    m = q.shape[0]
    if not continuous:
        return noise_factor(q), np.zeros(m)
    if np.count_nonzero(q - np.diag(np.diag(q))) or np.any(np.diag(q)[:n] != 0):
        raise ValueError("the physical noise intensity is diagonal, on v (and v_f) only")
    cols = []
    for j in range(n, m):
        qs = float(q[j, j])
        if qs > 0:
            a, b = np.zeros(m), np.zeros(m)
            i = j % n  # the position p_i that v_i (or v_f,i) drives
            a[i], a[j] = np.sqrt(qs / 3.0), np.sqrt(qs) * np.sqrt(3.0) / 2.0
            b[j] = 0.5 * np.sqrt(qs)
            cols += [a, b]
    L = np.column_stack(cols) if cols else np.zeros((m, 0))
    expo = np.full(m, 0.5)
    expo[:n] = 1.5
    return L, expo


def truth_deviation(
    traj: Trajectory,
    model: VehicleModel,
    L: np.ndarray,
    z: np.ndarray,
    points: np.ndarray,
    expo: np.ndarray | None = None,
) -> np.ndarray:
    """``δ`` at the samples ``points`` (sorted), shape (P, state_dim), from the normals ``z``.

    ``z`` has shape ``(N - 1, L.shape[1])``; ``δ_0 = 0``; the factor of step ``k`` is
    ``diag(h_k^expo) L`` (``expo`` zero by default: the per-step setting).

    Parameters
    ----------
    traj : Trajectory
        The nominal path (its times fix the steps).
    model : VehicleModel
        The vehicle model (dimension, current, beacon).
    L : ndarray, shape (m, c)
        Noise factor of a step (:func:`truth_factor`).
    z : ndarray, shape (N - 1, c)
        Standard normals, row ``k`` driving step ``k``.
    points : ndarray of int, shape (P,)
        Samples where ``δ`` is kept, sorted.
    expo : ndarray, shape (m,), optional
        Exponents of the step length in the factor (:func:`truth_factor`); None: zeros.

    Returns
    -------
    ndarray, shape (P, state_dim)
        The deviation from the nominal state at ``points``.
    """
    return open_loop_truth(traj, model, L, z, points, expo)[0]


def open_loop_truth(
    traj: Trajectory,
    model: VehicleModel,
    L: np.ndarray,
    z: np.ndarray | None,
    points: np.ndarray,
    expo: np.ndarray | None = None,
    navs: np.ndarray | None = None,
    box: np.ndarray | None = None,
    beacons: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`truth_deviation` and the metrics of the true paths ``nav + δ`` of paths on the
    same grid.

    ``navs`` (J, N, 2n) are the paths' nominal ``(p, p')`` (none by default), ``box`` (3, 2)
    the area and depth bounds (``TruthLimits.box``). Returns ``δ`` at ``points`` and the
    metrics (J, N_TM) of :func:`obsplan.estimation.kernels.span_metrics`.

    Parameters
    ----------
    traj : Trajectory
        The nominal path (its times fix the steps).
    model : VehicleModel
        The vehicle model (dimension, current, beacon).
    L : ndarray, shape (m, c)
        Noise factor of a step (:func:`truth_factor`).
    z : ndarray, shape (N - 1, c), or None
        Standard normals, row ``k`` driving step ``k``.
    points : ndarray of int, shape (P,)
        Samples where ``δ`` is kept, sorted.
    expo : ndarray, shape (m,), optional
        Exponents of the step length in the factor (:func:`truth_factor`); None: zeros.
    navs : ndarray, shape (J, N, 2n), optional
        Nominal position [m] and inertial velocity [m/s] of each path.
    box : ndarray, shape (3, 2), optional
        Bounds of the area (x, y) and of the depth [m]; None: unbounded.
    beacons : ndarray, shape (N, n) or (1, n), optional
        The beacon at every sample [m] (a moving beacon,
        :func:`~obsplan.estimation.epochs.sample_beacons`); None: the model's.

    Returns
    -------
    delta : ndarray, shape (P, state_dim)
        The deviation at ``points``.
    metrics : ndarray, shape (J, N_TM)
        The metrics of each true path (layout: :mod:`obsplan.estimation.columns`).
    """
    from obsplan.estimation import kernels

    n, m = model.dim, model.state_dim
    out = np.zeros((points.size, m))
    navs = np.zeros((0, traj.n_samples, 2 * n)) if navs is None else np.asarray(navs, float)
    tm = empty_metrics(navs.shape[0])
    if L.shape[1] == 0 and navs.shape[0] == 0:
        return out, tm
    if L.shape[1] == 0:
        z = np.zeros((traj.n_samples - 1, 0))
    kernels.truth_deviation(
        np.ascontiguousarray(z),
        np.ascontiguousarray(L),
        traj.dt,
        np.zeros(m) if expo is None else np.asarray(expo, float),
        n,
        model.current,
        points,
        out,
        np.ascontiguousarray(navs),
        np.ascontiguousarray(model.beacon_array[None, :] if beacons is None else beacons),
        np.tile([-np.inf, np.inf], (3, 1)) if box is None else np.asarray(box, float),
        tm,
    )
    return out, tm


def clean_readings(
    model: VehicleModel, x: np.ndarray, beacons: np.ndarray | None = None
) -> np.ndarray:
    """Noise-free stacked readings at true states ``x`` (K, state_dim): (K, output_dim).

    Columns in the model's output order: range ``r`` [m] (whatever the filter's range form),
    DVL [m/s], depth [m].

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (sensors, beacon).
    x : ndarray, shape (K, state_dim)
        True states.
    beacons : ndarray, shape (K, n) or (1, n), optional
        The beacon of each state's range [m] (a moving beacon); None: the model's.

    Returns
    -------
    ndarray, shape (K, output_dim)
        The readings without noise.
    """
    n = model.dim
    b = model.beacon_array if beacons is None else beacons
    out = np.empty((x.shape[0], model.output_dim))
    for s, sl in model.output_slices.items():
        if s == "range":
            rel = x[:, :n] - b
            out[:, sl] = np.sqrt(np.einsum("ki,ki->k", rel, rel))[:, None]
        elif s == "dvl-bottom":
            out[:, sl] = x[:, n : 2 * n] + (x[:, 2 * n : 3 * n] if model.current else 0.0)
        elif s == "dvl-water":
            out[:, sl] = x[:, n : 2 * n]
        elif s == "depth":
            out[:, sl] = x[:, 2:3]
    return out


def true_readings(model: VehicleModel, x: np.ndarray) -> dict[str, np.ndarray]:
    """Noise-free device readings at true states ``x`` (R, m), per sensor (R, width).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.
    x : ndarray, shape (R, m)
        True states.

    Returns
    -------
    dict of str to ndarray, shape (R, width)
        Range [m], DVL [m/s], depth [m] by sensor.
    """
    y = clean_readings(model, x)
    return {s: y[:, sl].copy() for s, sl in model.output_slices.items()}


def reading_draws(
    model: VehicleModel, reports: np.ndarray, dropout: dict[str, float], seed: int, run: int
) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Run ``run``'s reading noise (normals) and dropout mask per sensor, from its streams.

    ``reports`` (E, sensors) says which sensor reports at each epoch. The range at the first
    epoch (sample 0, the KF's anchor) is never dropped.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (its sensors).
    reports : ndarray of bool, shape (E, sensors)
        Which sensor reports at each epoch.
    dropout : dict of str to float
        Probability per sensor that a report is missing.
    seed : int
        The Monte Carlo's seed.
    run : int
        Run index.

    Returns
    -------
    list of (ndarray, ndarray or None)
        Per sensor, the normals ``(reports, width)`` and the dropout mask ``(reports,)`` (None
        if the sensor does not drop).
    """
    out = []
    for i, (s, sl) in enumerate(model.output_slices.items()):
        rows = np.flatnonzero(reports[:, i])
        e = run_rng(seed, run, STREAM_NOISE, s).standard_normal((rows.size, sl.stop - sl.start))
        drop = None
        p = dropout.get(s, 0.0)
        if p > 0:
            drop = run_rng(seed, run, STREAM_DROPOUT, s).random(rows.size) < p
            if s == "range":
                drop &= rows != 0
        out.append((e, drop))
    return out


def channel_draws(
    model: VehicleModel, reports: np.ndarray, channel: Channel, seed: int, run: int
) -> tuple[np.ndarray, ...] | None:
    """Run ``run``'s uniforms of the acoustic channel at its range reports (module docstring).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (the range is its first sensor).
    reports : ndarray of bool, shape (E, sensors)
        Which sensor reports at each epoch.
    channel : Channel
        The channel; an ideal one draws nothing.
    seed : int
        The Monte Carlo's seed.
    run : int
        Run index.

    Returns
    -------
    tuple of ndarray, shape (K,) each, or None
        The uniforms of loss, multipath, excess and the ping's time at the ``K`` range reports;
        None for an ideal channel.
    """
    if channel.is_ideal:
        return None
    k = int(np.count_nonzero(reports[:, list(model.output_slices).index("range")]))
    u_drop = run_rng(seed, run, STREAM_DROPOUT, "range").random(k)
    g = run_rng(seed, run, STREAM_CHANNEL)
    return u_drop, g.random(k), g.random(k), g.random(k)


def corrupt_ranges(
    model: VehicleModel,
    y: np.ndarray,
    reports: np.ndarray,
    channel: Channel,
    cdraws: tuple[np.ndarray, ...] | None,
    rho: np.ndarray | None,
    rho_dot: np.ndarray | None = None,
) -> None:
    """Add the channel's bias and late arrivals to the range column of ``y`` and lose its pings
    (NaN), in place; the scale ``1 + s`` multiplies the clean range where it is computed.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.
    y : ndarray, shape (E, output_dim)
        Reading noise (or readings) at the epochs, changed in place.
    reports : ndarray of bool, shape (E, sensors)
        Which sensor reports at each epoch.
    channel : Channel
        The channel.
    cdraws : tuple of ndarray or None
        From :func:`channel_draws` (None: ideal, nothing changes).
    rho : ndarray, shape (E,) or None
        The path's nominal range at the epochs [m] (for a loss growing with range).
    rho_dot : ndarray, shape (E,) or None, optional
        The path's nominal range rate at the epochs [m/s] (for the ping jitter).
    """
    if cdraws is None:
        return
    i = list(model.output_slices).index("range")
    col = model.output_slices["range"].start
    rows = np.flatnonzero(reports[:, i])
    u_drop, u_out, u_excess, u_jitter = cdraws
    add, lost = channel_errors(
        channel,
        rows,
        u_drop,
        u_out,
        u_excess,
        u_jitter,
        None if rho is None else rho[rows],
        None if rho_dot is None else rho_dot[rows],
    )
    y[rows, col] += add
    y[rows[lost], col] = np.nan


def noisy_readings(
    model: VehicleModel,
    x_epochs: np.ndarray,
    reports: np.ndarray,
    noise: dict[str, float],
    draws: list[tuple[np.ndarray, np.ndarray | None]],
    beacons: np.ndarray | None = None,
    channel: Channel | None = None,
    cdraws: tuple[np.ndarray, ...] | None = None,
    rho: np.ndarray | None = None,
    rho_dot: np.ndarray | None = None,
) -> np.ndarray:
    """Readings at the epochs: (E, output_dim), NaN where a sensor does not report (or drops).

    ``x_epochs`` are the true states at the epochs (E, state_dim), ``draws`` from
    :func:`reading_draws` (shared by every path on the same time grid).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.
    x_epochs : ndarray, shape (E, state_dim)
        True states at the epochs.
    reports : ndarray of bool, shape (E, sensors)
        Which sensor reports at each epoch.
    noise : dict of str to float
        Standard deviation per sensor (range [m], DVL [m/s], depth [m]).
    draws : list of (ndarray, ndarray or None)
        From :func:`reading_draws`.
    beacons : ndarray, shape (E, n) or (1, n), optional
        The beacon of each epoch's range [m] (a moving beacon,
        :func:`~obsplan.estimation.epochs.epoch_beacons`); None: the model's.
    channel : Channel, optional
        The acoustic channel (None: ideal): its scale ``1 + s`` multiplies the clean range, its
        bias, late arrivals and lost pings are applied (:func:`corrupt_ranges`).
    cdraws : tuple of ndarray, optional
        The run's channel uniforms (:func:`channel_draws`).
    rho : ndarray, shape (E,), optional
        The path's nominal range at the epochs [m].
    rho_dot : ndarray, shape (E,), optional
        The path's nominal range rate at the epochs [m/s].

    Returns
    -------
    ndarray, shape (E, output_dim)
        The device readings (range [m], DVL [m/s], depth [m]); NaN where none.
    """
    clean = clean_readings(model, x_epochs, beacons)
    y = reading_noise(model, reports, noise, draws)
    if channel is not None and cdraws is not None:
        clean[:, model.output_slices["range"]] *= 1.0 + channel.sound_speed_scale
        corrupt_ranges(model, y, reports, channel, cdraws, rho, rho_dot)
    return clean + y


def reading_noise(
    model: VehicleModel,
    reports: np.ndarray,
    noise: dict[str, float],
    draws: list[tuple[np.ndarray, np.ndarray | None]],
) -> np.ndarray:
    """The noise of the readings at the epochs, (E, output_dim): ``σ`` times the drawn normals
    where a sensor reports, NaN where it does not (or drops). A reading is the clean value at
    the true state plus this (in closed loop computed inside the simulation loop).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model.
    reports : ndarray of bool, shape (E, sensors)
        Which sensor reports at each epoch.
    noise : dict of str to float
        Standard deviation per sensor (range [m], DVL [m/s], depth [m]).
    draws : list of (ndarray, ndarray or None)
        From :func:`reading_draws`.

    Returns
    -------
    ndarray, shape (E, output_dim)
        The noise of each reading; NaN where none.
    """
    y = np.full((reports.shape[0], model.output_dim), np.nan)
    for i, (s, sl) in enumerate(model.output_slices.items()):
        rows = np.flatnonzero(reports[:, i])
        e, drop = draws[i]
        val = noise[s] * e
        if drop is not None:
            val[drop] = np.nan
        y[rows, sl] = val
    return y
