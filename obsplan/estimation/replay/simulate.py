"""Simulated logged missions, for tests and documentation: a trajectory flown with process noise,
logged as a vehicle would log it (seeded).

The truth starts at the trajectory's first state and is driven by its inputs plus white
acceleration noise of density ``accel_std``, sampled exactly over every interval
(:func:`obsplan.estimation.kalman.integrated_noise`), so that the replay's process model is
exactly right; with ``current`` the vehicle also drifts with a constant current. The log holds
a row per trajectory sample (the inputs, or DVL velocities, and depth) and a row per range, at
irregular times (intervals uniform in ``range_interval``). A range is the true distance to the
beacon at its time plus Gaussian noise; with probability ``outlier_fraction`` it arrives late by
multipath, a positive excess uniform in ``outlier_excess``; with probability ``dropout`` it is
lost (its row stays, without a range).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import InputError
from obsplan.estimation import kalman
from obsplan.estimation.replay.log import MissionLog
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True, eq=False)
class SimulatedLog:
    """A simulated log and what only the simulation knows.

    Attributes
    ----------
    log : MissionLog
        The log, with the true positions in ``log.truth``.
    outliers : ndarray of bool, shape (N,)
        Rows whose range is a multipath outlier.
    velocity : ndarray, shape (N, n)
        True velocities ``v`` [m/s] (through the water).
    """

    log: MissionLog
    outliers: np.ndarray
    velocity: np.ndarray


def _range_times(t0: float, t1: float, interval: tuple[float, float], rng) -> np.ndarray:
    lo, hi = interval
    if not 0 < lo <= hi:
        raise InputError(f"range_interval {interval!r}: need 0 < low <= high [s]")
    out, t = [], t0 + rng.uniform(0.0, lo)
    while t <= t1:
        out.append(t)
        t += rng.uniform(lo, hi)
    return np.array(out)


def _truth(traj: Trajectory, t: np.ndarray, accel_std: float, current, rng) -> np.ndarray:
    """True states ``(p, v, v_f)`` at the rows ``t`` (shape (N, 3n))."""
    n = traj.dim
    model = VehicleModel(dim=n, current=True)
    W = np.zeros((3 * n, 3 * n))
    W[n : 2 * n, n : 2 * n] = accel_std**2 * np.eye(n)
    x = np.concatenate([traj.p[0], traj.v[0], current])
    X = np.empty((t.size, 3 * n))
    X[0] = x
    seg = np.clip(np.searchsorted(traj.t, t, side="right") - 1, 0, traj.n_samples - 1)
    for k in range(1, t.size):
        dt = float(t[k] - t[k - 1])
        F, G = model.transition(dt)
        x = F @ x + G @ traj.u[seg[k - 1]]
        if dt > 0:
            Q = kalman.integrated_noise(W, n, True, dt)[: 2 * n, : 2 * n]
            x[: 2 * n] += np.linalg.cholesky(Q) @ rng.standard_normal(2 * n)
        X[k] = x
    return X


def simulate_log(
    traj: Trajectory,
    *,
    inputs: bool = True,
    dvl: str | None = None,
    depth: bool = False,
    beacon: tuple[float, ...] | BeaconPath | None = None,
    beacon_columns: bool = False,
    range_interval: tuple[float, float] = (10.0, 30.0),
    range_std: float = 1.0,
    dvl_std: float = 0.02,
    depth_std: float = 0.1,
    accel_std: float = 0.01,
    current: tuple[float, ...] | None = None,
    outlier_fraction: float = 0.0,
    outlier_excess: tuple[float, float] = (2.0, 30.0),
    dropout: float = 0.0,
    range_scale: float = 0.0,
    range_bias: float = 0.0,
    seed: int = 0,
) -> SimulatedLog:
    """Fly ``traj`` with process noise and log it (module docstring).

    Parameters
    ----------
    traj : Trajectory
        The planned path: its start state and held inputs; its samples are the log's rows.
    inputs : bool, optional
        Log the inputs ``u`` [m/s²] at the trajectory's samples.
    dvl : {"bottom", "water"} or None, optional
        Log DVL velocities at the samples: ``v + v_f`` (bottom) or ``v`` (water); None: none.
    depth : bool, optional
        Log the depth ``p_z`` (3D trajectories).
    beacon : tuple of float or BeaconPath or None, optional
        The beacon [m]: fixed (None: the origin) or moving.
    beacon_columns : bool, optional
        Log a moving beacon's position in the range rows (``bx,by[,bz]``); otherwise the
        path is given apart to the replay.
    range_interval : (float, float), optional
        Bounds of the interval between ranges [s].
    range_std, dvl_std, depth_std : float, optional
        Reading noises [m, m/s, m].
    accel_std : float, optional
        White-acceleration density of the truth's process noise [m/s²/√Hz].
    current : tuple of float or None, optional
        Constant current [m/s], shape ``(n,)``; None: still water.
    outlier_fraction : float, optional
        Probability that a range is a multipath outlier, in [0, 1].
    outlier_excess : (float, float), optional
        Bounds of an outlier's excess range [m].
    dropout : float, optional
        Probability that a range is lost, in [0, 1].
    range_scale : float, optional
        Relative error ``s`` of the sound speed: every range scaled by ``1 + s``, in (-0.5, 0.5).
    range_bias : float, optional
        Bias of every range [m] (a clock offset's ``c Δt``).
    seed : int, optional
        Seed of the generator (every random draw comes from it).

    Returns
    -------
    SimulatedLog
        The log (with truth), its outlier rows and the true velocities.

    Raises
    ------
    InputError
        A bad interval, a probability outside [0, 1], depth in 2D, or a log with neither
        inputs nor DVL.
    """
    rng = np.random.default_rng(seed)
    n = traj.dim
    for name, pr in (("outlier_fraction", outlier_fraction), ("dropout", dropout)):
        if not 0.0 <= pr <= 1.0:
            raise InputError(f"{name} {pr!r} must be in [0, 1]")
    vf = np.zeros(n) if current is None else np.asarray(current, float)
    tr = _range_times(float(traj.t[0]), float(traj.t[-1]), range_interval, rng)
    t = np.union1d(traj.t, tr)
    is_sample, is_range = np.isin(t, traj.t), np.isin(t, tr)
    X = _truth(traj, t, accel_std, vf, rng)
    p, v = X[:, :n], X[:, n : 2 * n]
    N = t.size
    b = _beacon(beacon, t, is_range, n)
    ranges = np.full(N, np.nan)
    r_true = np.linalg.norm(p[is_range] - b[is_range], axis=1)
    if not -0.5 < range_scale < 0.5:
        raise InputError(f"range_scale {range_scale!r} must be in (-0.5, 0.5)")
    noise = range_std * rng.standard_normal(r_true.size)
    ranges[is_range] = (1.0 + range_scale) * r_true + range_bias + noise
    outliers = np.zeros(N, bool)
    outliers[is_range] = rng.random(r_true.size) < outlier_fraction
    ranges[outliers] += rng.uniform(*outlier_excess, size=int(outliers.sum()))
    lost = np.zeros(N, bool)
    lost[is_range] = rng.random(r_true.size) < dropout
    ranges[lost], outliers[lost] = np.nan, False
    u = dvl_v = dep = None
    if inputs:
        u = np.full((N, n), np.nan)
        u[is_sample] = traj.u
    if dvl is not None:
        dvl_v = np.full((N, n), np.nan)
        base = v + vf if dvl == "bottom" else v
        dvl_v[is_sample] = base[is_sample] + dvl_std * rng.standard_normal((traj.n_samples, n))
    if depth:
        dep = np.full(N, np.nan)
        dep[is_sample] = p[is_sample, -1] + depth_std * rng.standard_normal(traj.n_samples)
    log = MissionLog(
        t=t,
        ranges=ranges,
        u=u,
        dvl=dvl_v,
        dvl_mode=dvl or "bottom",
        depth=dep,
        beacon=np.where(is_range[:, None], b, np.nan) if beacon_columns else None,
        truth=p,
        dim=n,
        source="simulated log",
    )
    return SimulatedLog(log=log, outliers=outliers, velocity=v)


def _beacon(beacon, t: np.ndarray, is_range: np.ndarray, n: int) -> np.ndarray:
    """The beacon at every row (a path: at the ranges' rows, NaN elsewhere)."""
    if isinstance(beacon, BeaconPath):
        out = np.full((t.size, n), np.nan)
        out[is_range] = beacon.position(t[is_range])
        return out
    b = np.zeros(n) if beacon is None else np.asarray(beacon, float)
    return np.repeat(b[None], t.size, axis=0)
