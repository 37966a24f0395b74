"""The beacon paths an operator flies with a surface craft (ASV, ship) serving a vehicle.

Every baseline is a :class:`~obsplan.model.beacon.BeaconPath` flown by the craft of
:class:`~obsplan.model.beacon.BeaconVehicle` (a horizontal double integrator at its start depth),
from its start state, sampled every ``step`` seconds. Each is produced the same way: a reference
point ``r(t)`` (with its velocity ``r'(t)``) that the craft chases with a speed-and-acceleration
limited tracker (:func:`fly_reference`): the commanded velocity is the reference's plus a closing
speed towards it that can still be braked to zero within the acceleration bound, and the
acceleration that reaches it within one step is clipped per axis and then to the speed bound. So
every baseline keeps the craft's speed and per-axis acceleration bounds by construction; the
area, the craft's ``max_range`` and its horizontal ``min_distance`` to the vehicle are checked
afterwards (:func:`craft_limit_breaks`) and said in words when broken (an operator flies these
paths as they are; the planner keeps the limits).

The baselines, by their names in ``report.json`` (:data:`BEACON_BASELINES`):

``beacon-fixed``
    Holding its start (a craft started moving brakes and returns to it).
``beacon-circle``
    Circling the survey's centre (the mission lines' centre, else the middle of the vehicle's
    path) at constant speed, counter-clockwise (steered onto the circle at its own angle); the
    radius is the best of a grid (:data:`CIRCLE_RADII` times the survey's half-diagonal, and
    no closer than ``min_distance``) by the same posterior Cramér–Rao bound the planner uses
    (:func:`~obsplan.estimation.bounds.crlb.posterior_crlb`: its mean over the weighted samples
    plus its final value), among the radii whose circle keeps the craft's limits when any does
    (the circle may cross the survey lines within ``min_distance`` of the vehicle). The speed
    is the craft's, lowered to ``sqrt(a r)`` so that the centripetal acceleration fits. The
    craft transits from its start straight out to the circle.
``beacon-trail``
    Following the vehicle :data:`TRAIL_OFFSET_M` behind it along its horizontal velocity
    (the last heading when it hovers), speed-limited.
``beacon-greedy``
    At each ping, of the 9 piecewise-constant accelerations ``{-a, 0, a}`` per axis held to the
    next ping, the one that puts the craft where the next range removes the most of the trace
    of the vehicle's position covariance (an EKF covariance recursion of the vehicle's state
    with the configuration's prior, process noise, range noise and its DVL and depth readings,
    one update per ping interval at their averaged information).
``beacon-orbit``
    Orbiting the vehicle's position (which the craft knows: the vehicle's path is given) at a
    radius of :data:`ORBIT_VERTICAL_FACTOR` times their vertical separation in 3D, or
    :data:`ORBIT_RADIUS_2D_M` in 2D (at least ``min_distance``); the orbit's speed relative to
    the vehicle is what the craft has left beyond the vehicle's speed, lowered for the
    centripetal acceleration.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from obsplan.estimation.bounds.crlb import posterior_crlb
from obsplan.estimation.config import EstimationConfig
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.trajectory.sampled import Trajectory

#: The beacon baselines, in report order (module docstring).
BEACON_BASELINES: tuple[str, ...] = (
    "beacon-fixed",
    "beacon-circle",
    "beacon-trail",
    "beacon-greedy",
    "beacon-orbit",
)
#: ``beacon-trail``'s distance behind the vehicle [m]: far enough for a support craft to keep
#: clear of the vehicle's track, close enough to keep the acoustic link short.
TRAIL_OFFSET_M = 50.0
#: ``beacon-orbit``'s radius in 3D: this times the vertical separation (the rule of thumb).
ORBIT_VERTICAL_FACTOR = 1.5
#: ``beacon-orbit``'s radius in 2D [m].
ORBIT_RADIUS_2D_M = 50.0
#: ``beacon-circle``'s radii tried, as fractions of the survey's horizontal half-diagonal.
CIRCLE_RADII: tuple[float, ...] = (0.15, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.2)
#: Fraction of the speed (and of ``sqrt(a r)``) a circling reference moves at: the rest is the
#: tracker's room to correct.
CRUISE = 0.9
#: Fraction of the acceleration bound the closing speed assumes for braking.
BRAKE = 0.5


@dataclass(frozen=True, eq=False)
class BeaconBaseline:
    """One beacon baseline.

    Attributes
    ----------
    name : str
        Its name in ``report.json`` (:data:`BEACON_BASELINES`).
    path : BeaconPath
        The craft's path, knots every ``step`` seconds.
    velocities : ndarray, shape (M, n)
        The craft's velocity at the knots [m/s] (``z`` zero in 3D).
    description : str
        What it does, in words.
    breaks : str
        The craft's limits it breaks, in words (empty when it keeps them all).
    """

    name: str
    path: BeaconPath
    velocities: np.ndarray
    description: str
    breaks: str = ""

    @property
    def within_limits(self) -> bool:
        """The path keeps every limit of the craft."""
        return not self.breaks


#: ``(t, b) -> (r, r')``: the reference point and its velocity at time ``t`` for the craft at ``b``
#: (horizontal, [m], [m/s]); a circling reference is the point of the circle at the craft's own
#: angle (a vector field: a point chased around the circle is never caught at nearly the craft's
#: speed).
Reference = Callable[[float, np.ndarray], tuple[np.ndarray, np.ndarray]]


def _step_velocity(v: np.ndarray, target: np.ndarray, craft: BeaconVehicle, h: float):
    """The velocity after one step of ``h`` towards ``target``: the change clipped per axis to
    ``accel h`` and the result to the speed bound (the box of changes holds ``v``, so moving
    back along the change keeps both bounds)."""
    dv = np.clip(target - v, -craft.accel * h, craft.accel * h)
    w = v + dv
    s = float(np.linalg.norm(w))
    if s > craft.speed:
        # the largest fraction of the change that keeps |v + lam dv| <= speed
        a, b, c = dv @ dv, 2.0 * (v @ dv), v @ v - craft.speed**2
        lam = 0.0 if a == 0 else max(0.0, (-b + math.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a))
        w = v + min(lam, 1.0) * dv
    return w


def fly_reference(
    craft: BeaconVehicle, times: np.ndarray, reference: Reference
) -> tuple[np.ndarray, np.ndarray]:
    """Fly the craft after a moving reference point within its speed and acceleration bounds.

    Parameters
    ----------
    craft : BeaconVehicle
        The craft: start, start velocity, speed [m/s] and per-axis acceleration [m/s²] bounds.
    times : ndarray, shape (M,)
        Knot times [s], increasing.
    reference : callable
        ``(t, b) -> (r, r')``: the horizontal reference position [m] and velocity [m/s], each
        (2,), at time ``t`` for the craft at ``b``.

    Returns
    -------
    positions : ndarray, shape (M, n)
        The craft's positions [m] (``z`` at its start depth in 3D); constant acceleration on
        each interval, so the positions are exact for the velocities.
    velocities : ndarray, shape (M, n)
        Its velocities [m/s].
    """
    n = craft.dim
    pos = np.zeros((times.size, 2))
    vel = np.zeros((times.size, 2))
    pos[0], vel[0] = craft.start[:2], craft.velocity
    brake = BRAKE * float(np.min(craft.accel))
    # the closing speed's time constant: the craft's own (speed / accel); a shorter one makes the
    # saturated loop ring around a moving reference
    tau = craft.speed / float(np.min(craft.accel))
    for k in range(times.size - 1):
        h = float(times[k + 1] - times[k])
        r, rv = reference(float(times[k + 1]), pos[k] + vel[k] * h)
        e = r - (pos[k] + vel[k] * h)
        d = float(np.linalg.norm(e))
        close = min(craft.speed, math.sqrt(2.0 * brake * d), d / max(h, tau))
        target = rv + (e / d * close if d > 0 else 0.0)
        vel[k + 1] = _step_velocity(vel[k], target, craft, h)
        pos[k + 1] = pos[k] + 0.5 * (vel[k] + vel[k + 1]) * h
    if n == 3:
        z = np.full((times.size, 1), craft.start[2])
        return np.hstack([pos, z]), np.hstack([vel, np.zeros_like(z)])
    return pos, vel


def _vehicle_at(vehicle: Trajectory, t: float) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle's exact position and velocity at ``t`` (held input within an interval)."""
    k = int(np.clip(np.searchsorted(vehicle.t, t, side="right") - 1, 0, vehicle.t.size - 2))
    s = t - vehicle.t[k]
    u = vehicle.u[k]
    return vehicle.p[k] + vehicle.v[k] * s + 0.5 * u * s * s, vehicle.v[k] + u * s


def craft_limit_breaks(
    path: BeaconPath, velocities: np.ndarray, craft: BeaconVehicle, vehicle: Trajectory
) -> str:
    """The craft's limits a beacon path breaks, in words.

    Speed and per-axis acceleration from the knot velocities (1e-9 relative slack: round-off),
    the area at the knots, ``max_range`` and the horizontal ``min_distance`` to the vehicle at
    the vehicle's samples and the knots.

    Parameters
    ----------
    path : BeaconPath
        The craft's path.
    velocities : ndarray, shape (M, n)
        Its velocities at the knots [m/s].
    craft : BeaconVehicle
        The craft and its limits.
    vehicle : Trajectory
        The vehicle's path.

    Returns
    -------
    str
        ``"speed 2.3 m/s > 2 m/s; ..."``, or ``""`` when every limit holds.
    """
    out = []
    tol = 1 + 1e-9
    speed = float(np.max(np.linalg.norm(velocities[:, :2], axis=1)))
    if speed > craft.speed * tol:
        out.append(f"speed {speed:.3g} m/s > {craft.speed:g} m/s")
    acc = np.abs(np.diff(velocities[:, :2], axis=0)) / np.diff(path.times)[:, None]
    if np.any(acc > craft.accel * tol):
        out.append(f"acceleration {float(np.max(acc)):.3g} m/s^2 > {list(craft.accel)}")
    if craft.area is not None:
        xy = path.positions[:, :2]
        if np.any(xy < craft.area[:, 0] - 1e-9) or np.any(xy > craft.area[:, 1] + 1e-9):
            out.append("leaves its area")
    t = np.union1d(vehicle.t[(vehicle.t >= path.start) & (vehicle.t <= path.end)], path.times)
    p = np.array([_vehicle_at(vehicle, float(s))[0] for s in t])
    rel = p - path.position(t)
    horiz = float(np.min(np.linalg.norm(rel[:, :2], axis=1)))
    if horiz < craft.min_distance:
        out.append(f"passes {horiz:.3g} m (horizontal) from the vehicle < min_distance")
    far = float(np.max(np.linalg.norm(rel, axis=1)))
    if craft.max_range is not None and far > craft.max_range:
        out.append(f"{far:.4g} m from the vehicle > max_range {craft.max_range:g} m")
    return "; ".join(out)


def _baseline(
    name: str, craft: BeaconVehicle, vehicle: Trajectory, times: np.ndarray, ref: Reference, words
) -> BeaconBaseline:
    pos, vel = fly_reference(craft, times, ref)
    path = BeaconPath(times=times, positions=pos)
    return BeaconBaseline(name, path, vel, words, craft_limit_breaks(path, vel, craft, vehicle))


def _around(
    centre: np.ndarray, velocity: np.ndarray, radius: float, speed: float, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The point of a circle about a centre moving at ``velocity`` at the craft's angle, moving
    counter-clockwise at ``speed`` relative to the centre (at the centre: angle 0)."""
    d = b - centre
    a = math.atan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else 0.0
    c, s = math.cos(a), math.sin(a)
    return centre + radius * np.array([c, s]), velocity + speed * np.array([-s, c])


def _circle_ref(centre: np.ndarray, radius: float, craft: BeaconVehicle) -> Reference:
    speed = CRUISE * min(craft.speed, math.sqrt(float(np.min(craft.accel)) * radius))
    return lambda t, b: _around(centre, np.zeros(2), radius, speed, b)


def _circle(craft, vehicle, times, config, centre, weights, span) -> BeaconBaseline:
    best: tuple[tuple[bool, float], BeaconBaseline] | None = None
    for f in CIRCLE_RADII:
        radius = max(f * span, craft.min_distance, 1.0)
        words = f"circling the survey centre {np.round(centre, 1).tolist()} at {radius:.3g} m"
        bl = _baseline(
            "beacon-circle", craft, vehicle, times, _circle_ref(centre, radius, craft), words
        )
        # a radius whose circle keeps the craft's limits beats any that breaks them
        score = (bool(bl.breaks), bound_score(vehicle, bl.path, config, weights))
        if best is None or score < best[0]:
            best = (score, bl)
    assert best is not None
    bl = best[1]
    desc = bl.description + f" (the best of {len(CIRCLE_RADII)} radii by the posterior CRB"
    desc += ", none of which keeps the craft's limits)" if bl.breaks else ")"
    return BeaconBaseline(bl.name, bl.path, bl.velocities, desc, bl.breaks)


def bound_score(
    vehicle: Trajectory,
    path: BeaconPath,
    config: EstimationConfig,
    weights: np.ndarray | None = None,
) -> float:
    """The posterior CRB of the vehicle's position with the beacon on ``path``: its weighted mean
    over the vehicle's samples plus its final value (what ``pcrb-position`` scores).

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path, on a grid of the configuration's readings (the validation's).
    path : BeaconPath
        The beacon's path, covering the vehicle's.
    config : EstimationConfig
        Sensors, rates, noises, prior and process noise (its ``beacon_path`` is replaced).
    weights : ndarray, shape (N,), or None
        Weight of each vehicle sample in the mean (e.g. 1 on the survey lines); None: all 1.

    Returns
    -------
    float
        Mean plus final position bound [m].
    """
    cfg = replace(config, beacon_path=path)
    std = posterior_crlb(vehicle, cfg).pos_std_t
    w = np.ones(std.size) if weights is None or not np.any(weights) else np.asarray(weights, float)
    return float(w @ std / w.sum() + std[-1])


def _trail_ref(vehicle: Trajectory, offset: float) -> Reference:
    last = np.array([1.0, 0.0])

    def ref(t: float, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nonlocal last
        p, v = _vehicle_at(vehicle, min(t, float(vehicle.t[-1])))
        s = float(np.linalg.norm(v[:2]))
        if s > 1e-6:
            last = v[:2] / s
        return p[:2] - offset * last, v[:2]

    return ref


def _orbit_ref(vehicle: Trajectory, craft: BeaconVehicle, radius: float) -> Reference:
    vmax = float(np.max(np.linalg.norm(vehicle.v[:, :2], axis=1)))
    room = max(craft.speed - vmax, 0.1 * craft.speed)
    speed = CRUISE * min(room, math.sqrt(float(np.min(craft.accel)) * radius))

    def ref(t: float, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, v = _vehicle_at(vehicle, min(t, float(vehicle.t[-1])))
        return _around(p[:2], v[:2], radius, speed, b)

    return ref


def orbit_radius(vehicle: Trajectory, craft: BeaconVehicle) -> float:
    """``beacon-orbit``'s radius [m]: :data:`ORBIT_VERTICAL_FACTOR` times the mean vertical
    separation in 3D (:data:`ORBIT_RADIUS_2D_M` when it is under a metre, and in 2D), at least
    ``min_distance``.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path.
    craft : BeaconVehicle
        The craft (its depth and ``min_distance``).

    Returns
    -------
    float
        The radius [m].
    """
    radius = ORBIT_RADIUS_2D_M
    if craft.dim == 3:
        sep = float(np.mean(np.abs(vehicle.p[:, 2] - craft.start[2])))
        if sep >= 1.0:
            radius = ORBIT_VERTICAL_FACTOR * sep
    return max(radius, craft.min_distance)


def _greedy(craft: BeaconVehicle, vehicle: Trajectory, config: EstimationConfig, step: float):
    """``beacon-greedy`` (module docstring): one-ping look-ahead on the EKF's covariance."""
    model = config.model
    n, m = model.dim, model.state_dim
    ping = 1.0 / float(config.rates_hz["range"])
    t_end = float(vehicle.t[-1])
    pings = np.arange(0.0, t_end + 1e-9, ping)
    P = np.array(config.covariances(ping)["p0_ekf"], float)
    q = np.array(config.covariances(ping)["q_ekf"], float)
    F = np.eye(m)
    F[:n, n : 2 * n] = ping * np.eye(n)
    rows = _linear_rows(config, ping)
    sig2 = float(config.noise["range"]) ** 2
    choices = [np.array([i, j], float) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    sub = max(1, int(round(ping / step)))
    times = [0.0]
    b, v = craft.start[:2].copy(), craft.velocity.copy()
    pos, vel = [b.copy()], [v.copy()]
    for k in range(pings.size - 1):
        P = F @ P @ F.T + q
        for H, R in rows:
            P = _update(P, H, R)
        p_next = _vehicle_at(vehicle, float(pings[k + 1]))[0]
        best = None
        for c in choices:
            bs, vs = _hold(b, v, c * craft.accel, craft, ping / sub, sub)
            H = _range_row(p_next, _at_depth(bs[-1], craft), m, n)
            gain = float(np.sum((P @ H.T)[:n] ** 2) / (H @ P @ H.T + sig2))
            if best is None or gain > best[0] + 1e-12:
                best = (gain, bs, vs, H)
        assert best is not None
        _, bs, vs, H = best
        P = _update(P, H[None, :], sig2)
        for j in range(sub):
            times.append(float(pings[k] + (j + 1) * ping / sub))
        pos += list(bs[1:])
        vel += list(vs[1:])
        b, v = bs[-1], vs[-1]
    return _extend(np.array(times), np.array(pos), np.array(vel), craft, t_end)


def _hold(b, v, a, craft: BeaconVehicle, h: float, steps: int):
    """Hold acceleration ``a`` for ``steps`` steps of ``h`` within the speed bound."""
    bs, vs = [b], [v]
    for _ in range(steps):
        w = _step_velocity(vs[-1], vs[-1] + a * h, craft, h)
        bs.append(bs[-1] + 0.5 * (vs[-1] + w) * h)
        vs.append(w)
    return bs, vs


def _at_depth(b: np.ndarray, craft: BeaconVehicle) -> np.ndarray:
    return np.append(b, craft.start[2]) if craft.dim == 3 else b


def _range_row(p: np.ndarray, b: np.ndarray, m: int, n: int) -> np.ndarray:
    d = p - b
    H = np.zeros(m)
    H[:n] = d / max(float(np.linalg.norm(d)), 1e-9)
    return H


def _update(P: np.ndarray, H: np.ndarray, R) -> np.ndarray:
    H = np.atleast_2d(H)
    S = H @ P @ H.T + np.atleast_2d(R)
    K = P @ H.T @ np.linalg.inv(S)
    P = P - K @ H @ P
    return 0.5 * (P + P.T)


def _linear_rows(config: EstimationConfig, ping: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The DVL and depth readings of one ping interval, as one update of averaged information."""
    model = config.model
    n, m = model.dim, model.state_dim
    out = []
    for s in model.sensors:
        if s == "range":
            continue
        count = max(1.0, float(config.rates_hz[s]) * ping)
        var = float(config.noise[s]) ** 2 / count
        if s == "depth":
            H = np.zeros((1, m))
            H[0, 2] = 1.0
        else:
            H = np.zeros((n, m))
            H[:, n : 2 * n] = np.eye(n)
        out.append((H, var * np.eye(H.shape[0])))
    return out


def _extend(times, pos, vel, craft: BeaconVehicle, t_end: float):
    """Knots up to ``t_end``: the last ping interval, if short, is flown at the last velocity
    (within the bounds: no acceleration)."""
    if times[-1] < t_end - 1e-9:
        h = t_end - times[-1]
        times = np.append(times, t_end)
        pos = np.vstack([pos, pos[-1] + vel[-1] * h])
        vel = np.vstack([vel, vel[-1]])
    if craft.dim == 3:
        z = np.full((times.size, 1), craft.start[2])
        pos, vel = np.hstack([pos, z]), np.hstack([vel, np.zeros_like(z)])
    return times, pos, vel


def beacon_baselines(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    config: EstimationConfig,
    *,
    step: float = 1.0,
    centre: np.ndarray | None = None,
    weights: np.ndarray | None = None,
) -> dict[str, BeaconBaseline]:
    """Every beacon baseline (module docstring) for a vehicle flying ``vehicle``.

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's path from t = 0, on a grid of the configuration's readings (the
        validation's filter grid).
    craft : BeaconVehicle
        The craft carrying the beacon, of the vehicle's dimension.
    config : EstimationConfig
        The vehicle's filters' configuration (sensors, rates, noises, prior, process noise): the
        circle's radius is chosen and the greedy path steered by it.
    step : float, optional
        Knot spacing of the baselines' paths [s].
    centre : ndarray, shape (2,), or None
        The survey's horizontal centre [m]; None: the middle of the vehicle path's extent.
    weights : ndarray, shape (N,), or None
        Weight of each vehicle sample in the circle's score (1 on the survey lines); None: all.

    Returns
    -------
    dict of str to BeaconBaseline
        By the names of :data:`BEACON_BASELINES`, in that order.
    """
    t_end = float(vehicle.t[-1])
    times = np.linspace(0.0, t_end, max(2, int(math.ceil(t_end / step - 1e-9)) + 1))
    xy = vehicle.p[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    c = 0.5 * (lo + hi) if centre is None else np.asarray(centre, float)
    span = max(float(np.max(np.linalg.norm(xy - c, axis=1))), 1.0)
    start = craft.start[:2].copy()
    out = {
        "beacon-fixed": _baseline(
            "beacon-fixed",
            craft,
            vehicle,
            times,
            lambda t, b: (start, np.zeros(2)),
            f"holding its start {np.round(start, 1).tolist()}",
        )
    }
    out["beacon-circle"] = _circle(craft, vehicle, times, config, c, weights, span)
    offset = max(TRAIL_OFFSET_M, craft.min_distance)
    out["beacon-trail"] = _baseline(
        "beacon-trail",
        craft,
        vehicle,
        times,
        _trail_ref(vehicle, offset),
        f"following the vehicle {offset:g} m behind along its velocity",
    )
    gt, gp, gv = _greedy(craft, vehicle, config, step)
    gpath = BeaconPath(times=gt, positions=gp)
    out["beacon-greedy"] = BeaconBaseline(
        "beacon-greedy",
        gpath,
        gv,
        "moving each ping interval to where the next range removes the most position variance",
        craft_limit_breaks(gpath, gv, craft, vehicle),
    )
    radius = orbit_radius(vehicle, craft)
    out["beacon-orbit"] = _baseline(
        "beacon-orbit",
        craft,
        vehicle,
        times,
        _orbit_ref(vehicle, craft, radius),
        f"orbiting the vehicle at {radius:.3g} m",
    )
    return out
