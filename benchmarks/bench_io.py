"""Track import and waypoint export: accuracy and speed tables.

    python benchmarks/bench_io.py [--quick]

Accuracy: a plan-like path from known inputs (3 s holds, |u| <= 0.05 m/s², 600 s), sampled at
1 Hz with 5 cm position noise, as logged (dropped samples, irregular times, velocities): the RMS
error of the fitted accelerations against the stated posterior std, and the estimated noise.
Speed: the fit against a baseline doing the same smoothing with a known regulariser (one
Kalman/RTS pass, no search), for growing logs; the exact tracking errors of a waypoint export.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from obsplan.io.tracks import Track, _kalman, _nodes, _rts, fit_track
from obsplan.io.waypoints import waypoints_from_trajectory
from obsplan.trajectory.sampled import Trajectory, position_at


def plan_like(duration: float = 600.0) -> Trajectory:
    tc = np.arange(0.0, duration + 1e-9, 3.0)
    u = 0.05 * np.c_[np.sin(2 * np.pi * tc / 150), np.cos(2 * np.pi * tc / 220)]
    return Trajectory.from_inputs(tc, [-80.0, 60.0], [0.0, 0.0], u)


def logged(traj, rate_hz, seed, drop=0.0, jitter=0.0, vel_std=None):
    rng = np.random.default_rng(seed)
    t = np.arange(traj.t[0], traj.t[-1] + 1e-9, 1.0 / rate_hz)
    if jitter:
        t[1:-1] += rng.uniform(-jitter, jitter, t.size - 2) / rate_hz
    keep = np.r_[True, rng.random(t.size - 2) >= drop, True]
    t = t[keep]
    p = position_at(traj, t) + rng.normal(0, 0.05, (t.size, 2))
    v = None
    if vel_std is not None:
        k = np.clip(np.searchsorted(traj.t, t, side="right") - 1, 0, traj.n_samples - 1)
        v = traj.v[k] + traj.u[k] * (t - traj.t[k])[:, None] + rng.normal(0, vel_std, p.shape)
    return Track(t=t, p=p, v=v)


def accuracy(seeds: int) -> None:
    traj = plan_like()
    cases = [
        ("1 Hz", {}),
        ("1 Hz, 20 % dropped", {"drop": 0.2}),
        ("1 Hz, jitter ±0.3 s", {"jitter": 0.3}),
        ("1 Hz + velocities 1 cm/s", {"vel_std": 0.01}),
        ("0.2 Hz", {"rate": 0.2}),
    ]
    print("accuracy (5 cm noise; RMS of u error / stated posterior std, over seeds)")
    print(
        f"{'case':28s} {'u RMS err [m/s²]':>17s} {'stated std':>11s} {'ratio':>6s} {'σ_p est':>8s}"
    )
    for name, kw in cases:
        rate = kw.pop("rate", 1.0)
        errs, stds, sig = [], [], []
        for seed in range(seeds):
            track = logged(traj, rate, seed, **kw)
            fit = fit_track(track, velocity_std=kw.get("vel_std") or 0.05)
            tr = fit.trajectory
            k = np.searchsorted(traj.t, tr.t[:-1], side="right") - 1
            errs.append(np.sqrt(np.mean((tr.u[:-1] - traj.u[k]) ** 2)))
            stds.append(np.mean(fit.accel_std))
            sig.append(np.mean(fit.position_std))
        e, s = float(np.mean(errs)), float(np.mean(stds))
        print(f"{name:28s} {e:17.4f} {s:11.4f} {e / s:6.2f} {np.mean(sig):8.4f}")


def speed(sizes) -> None:
    print("\nspeed of the fit (2D, 1 Hz): full fit (noise + smoothness search, 2 grid passes, "
          "smoother) vs one smoother pass at known settings")  # fmt: skip
    print(f"{'samples':>8s} {'fit [s]':>9s} {'one pass [s]':>13s} {'ratio':>6s}")
    for n in sizes:
        traj = plan_like(duration=3.0 * np.ceil(n / 3.0))
        track = logged(traj, 1.0, 0)
        t0 = time.perf_counter()
        fit = fit_track(track)
        t_fit = time.perf_counter() - t0
        nodes = _nodes(track.t, None, None)
        t0 = time.perf_counter()
        q, s = np.asarray(fit.accel_intensity), np.asarray(fit.position_std)
        _, moments = _kalman(nodes, track.p, None, q, s, 0.05, np.arange(2), store=True)
        _rts(nodes, moments)
        t_one = time.perf_counter() - t0
        print(f"{track.n_samples:8d} {t_fit:9.3f} {t_one:13.3f} {t_fit / t_one:6.1f}")


def export_speed() -> None:
    traj = plan_like()
    print("\nwaypoint export of the 600 s plan (exact leg errors)")
    print(f"{'every [s]':>10s} {'waypoints':>10s} {'time [s]':>9s} {'max cross-track [m]':>20s}")
    for every in (3.0, 15.0, 30.0, 60.0):
        t0 = time.perf_counter()
        wp = waypoints_from_trajectory(traj, every=every)
        dt = time.perf_counter() - t0
        print(f"{every:10g} {len(wp):10d} {dt:9.4f} {wp.max_cross_track:20.3f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    accuracy(2 if args.quick else 8)
    speed([600, 3600] if args.quick else [600, 3600, 36000])
    export_speed()
