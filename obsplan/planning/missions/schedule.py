"""The constant-speed schedule of a mission: the plain lawn-mower's timing, which fixes the
shortest horizon a mission needs, and the planner's (:func:`planner_schedule`: the same lines
flown faster after a lead-in at the start), which fixes the planner's line windows.

The schedule flies the whole mission at one horizontal speed ``v_c``: from the start it speeds
up (or slows down) along its heading at ``accel_use`` of the acceleration bound to ``v_c``, then
for each survey line it flies the shortest path of bounded curvature (a Dubins path, turns of
radius ``v_c² / a_turn`` with ``a_turn = accel_use * min(limits.accel)``: the tightest turns the
limits allow, less a margin for the discrete inputs) to a run-in point ``lead`` before the line's
start, then the line with a run-in and a run-out of ``lead = lead_steps * v_c * h`` (so that the
planning nodes just before the line's start and just after its end lie on the line's track).
Waypoints are passed the same way, each on a short straight of ``2 lead`` along the leg that
reaches it. After the mission (or at the end region, approached along the line from the last
point) it brakes to rest and holds. Depth (3D) changes smoothly (a half cosine) during each
transit; lines are level, or follow the seabed of an altitude band (the depth rate of the
line's slope is then reached on the transit's last planning step).

``v_c`` is the slowest speed of the band ``mission.speed`` at which the mission ends within the
horizon (a surveyor uses the time available): the lines then leave the planner a speed headroom
``1 - v_c / hi``. When no band speed fits, :func:`mission_fit_error` gives the shortest horizon
that would (at the band speed of the shortest mission).

The sinusoidally accelerated variant (the paper's remedy) flies each line at
``v_c + A sin(2 π k σ)`` (``σ`` the fraction of the line's time, ``k`` whole cycles), so that it
covers the line in the same time: both lawn-mowers share the windows.

The knobs (``accel_use``, ``lead_steps``, the sinusoid's, the speed search's and the lead-in's)
are :class:`~obsplan.planning.tuning.Tuning`'s, read at call time; the cached schedules are cached
per tuning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import field_error
from obsplan.planning.missions.spec import Mission, MissionContext
from obsplan.planning.tuning import cache_per_tuning, tuning


@dataclass(frozen=True, eq=False)
class Piece:
    """A piece of the schedule from time ``t0`` for ``dur`` [s].

    ``kind`` is ``"straight"`` (from ``p`` along unit ``e``, speed ``s0 + acc τ + amp sin(2 π
    cycles τ / dur)``), ``"arc"`` (horizontal circle of ``radius`` about ``center`` from angle
    ``phi0``, ``sign`` +1 anticlockwise, at speed ``s0``) or ``"hold"`` (at rest at ``p``). In 3D
    ``z`` follows ``z0 + dz (1 - cos(π (t - zt0) / zdur)) / 2`` on transits (``dz = 0``: level).
    """

    kind: str
    t0: float
    dur: float
    p: np.ndarray
    e: np.ndarray
    s0: float = 0.0
    acc: float = 0.0
    amp: float = 0.0
    cycles: int = 0
    center: np.ndarray | None = None
    radius: float = 0.0
    phi0: float = 0.0
    sign: float = 1.0
    z0: float = 0.0
    dz: float = 0.0
    zt0: float = 0.0
    zdur: float = 1.0

    @property
    def constant(self) -> bool:
        """Constant velocity over the piece (no input needed)."""
        return self.kind == "hold" or (
            self.kind == "straight" and self.acc == 0 and self.amp == 0 and self.dz == 0
        )

    def state(self, t: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities at times ``t`` (inside the piece), each (J, dim).

        Parameters
        ----------
        t : ndarray, shape (J,)
            Times [s] from the start of the horizon, inside ``[t0, t0 + dur]``.
        dim : int
            Spatial dimension ``n`` (2 or 3; in 3D ``z`` follows the transit's half cosine).

        Returns
        -------
        p : ndarray, shape (J, dim)
            Positions [m].
        v : ndarray, shape (J, dim)
            Inertial velocities [m/s].
        """
        tau = np.asarray(t, float) - self.t0
        J = tau.size
        p = np.zeros((J, dim))
        v = np.zeros((J, dim))
        if self.kind == "hold":
            p[:] = self.p
            return p, v
        if self.kind == "straight":
            w = 2 * math.pi * self.cycles / self.dur if self.cycles else 0.0
            s = self.s0 * tau + 0.5 * self.acc * tau**2
            sp = self.s0 + self.acc * tau
            if w:
                s = s + self.amp / w * (1 - np.cos(w * tau))
                sp = sp + self.amp * np.sin(w * tau)
            p[:] = self.p + s[:, None] * self.e[None, :dim]
            v[:] = sp[:, None] * self.e[None, :dim]
        else:
            assert self.center is not None
            ang = self.phi0 + self.sign * self.s0 * tau / self.radius
            p[:, 0] = self.center[0] + self.radius * np.cos(ang)
            p[:, 1] = self.center[1] + self.radius * np.sin(ang)
            v[:, 0] = -self.sign * self.s0 * np.sin(ang)
            v[:, 1] = self.sign * self.s0 * np.cos(ang)
            if dim == 3:
                p[:, 2] = self.p[2]
        if dim == 3 and self.dz != 0:
            x = np.clip((tau + self.t0 - self.zt0) / self.zdur, 0.0, 1.0)
            p[:, 2] = self.z0 + 0.5 * self.dz * (1 - np.cos(math.pi * x))
            v[:, 2] = 0.5 * self.dz * math.pi / self.zdur * np.sin(math.pi * x)
        return p, v


@dataclass(frozen=True, eq=False)
class MissionSchedule:
    """The constant-speed schedule of a mission (module docstring).

    Attributes
    ----------
    speed : float
        The horizontal speed ``v_c`` [m/s].
    pieces : tuple of Piece
        In time order, covering ``[0, end_s]``, then a hold (or straight) to the horizon.
    line_windows : tuple of (t0, t1)
        Times [s] the schedule is at each survey line's start and end.
    waypoint_times : tuple of float
        Times [s] the schedule passes each waypoint.
    end_s : float
        When the mission (braking included) ends [s].
    headroom : float
        ``1 - v_c / hi``: how much faster than the schedule the lines may be flown.
    lead : float
        Run-in and run-out of each line [m].
    """

    speed: float
    pieces: tuple[Piece, ...]
    line_windows: tuple[tuple[float, float], ...]
    waypoint_times: tuple[float, ...]
    end_s: float
    headroom: float
    lead: float
    #: The lead-in [s]: at rest at the start until then (:func:`planner_schedule`).
    lead_in: float = 0.0

    def state(self, t: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (J, dim) of the schedule at times ``t`` [s].

        Parameters
        ----------
        t : ndarray, shape (J,)
            Times [s] from the start of the horizon (outside the pieces: the first or the last
            piece extrapolated).
        dim : int
            Spatial dimension ``n`` (2 or 3).

        Returns
        -------
        p : ndarray, shape (J, dim)
            Positions [m].
        v : ndarray, shape (J, dim)
            Inertial velocities [m/s].
        """
        t = np.asarray(t, float)
        starts = np.array([pc.t0 for pc in self.pieces])
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.pieces) - 1)
        p = np.zeros((t.size, dim))
        v = np.zeros((t.size, dim))
        for i in np.unique(idx):
            sel = idx == i
            p[sel], v[sel] = self.pieces[i].state(t[sel], dim)
        return p, v

    def piece_at(self, t: float) -> Piece:
        """The piece flying at time ``t``.

        Parameters
        ----------
        t : float
            Time [s] from the start of the horizon.

        Returns
        -------
        Piece
            The last piece starting at or before ``t`` (the first before the schedule starts).
        """
        starts = [pc.t0 for pc in self.pieces]
        i = max(0, int(np.searchsorted(starts, t, side="right")) - 1)
        return self.pieces[min(i, len(self.pieces) - 1)]


# ------------------------------------------------------------------------------- Dubins paths
def _mod(x: float) -> float:
    return x % (2 * math.pi)


def _dubins_words(alpha: float, beta: float, d: float) -> list[tuple[str, tuple[float, ...]]]:
    """Candidate Dubins words (normalised: unit radius) and their three segment lengths."""
    sa, sb, ca_, cb = math.sin(alpha), math.sin(beta), math.cos(alpha), math.cos(beta)
    cab = math.cos(alpha - beta)
    out: list[tuple[str, tuple[float, ...]]] = []
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)
    if p2 >= 0:
        tmp = math.atan2(cb - ca_, d + sa - sb)
        out.append(("LSL", (_mod(-alpha + tmp), math.sqrt(p2), _mod(beta - tmp))))
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)
    if p2 >= 0:
        tmp = math.atan2(ca_ - cb, d - sa + sb)
        out.append(("RSR", (_mod(alpha - tmp), math.sqrt(p2), _mod(-beta + tmp))))
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(-ca_ - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append(("LSR", (_mod(-alpha + tmp), p, _mod(-beta + tmp))))
    p2 = d * d - 2 + 2 * cab - 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        tmp = math.atan2(ca_ + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append(("RSL", (_mod(alpha - tmp), p, _mod(beta - tmp))))
    tmp = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8
    if abs(tmp) <= 1:
        p = _mod(2 * math.pi - math.acos(tmp))
        t = _mod(alpha - math.atan2(ca_ - cb, d - sa + sb) + p / 2)
        out.append(("RLR", (t, p, _mod(alpha - beta - t + p))))
    tmp = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8
    if abs(tmp) <= 1:
        p = _mod(2 * math.pi - math.acos(tmp))
        t = _mod(-alpha - math.atan2(ca_ - cb, d + sa - sb) + p / 2)
        out.append(("LRL", (t, p, _mod(beta - alpha - t + p))))
    return out


def _advance(x: float, y: float, th: float, kind: str, length: float, r: float):
    """Pose after ``length`` [m] of a segment ``L``, ``R`` or ``S`` of radius ``r``."""
    if kind == "S":
        return x + length * math.cos(th), y + length * math.sin(th), th
    sgn = 1.0 if kind == "L" else -1.0
    dth = sgn * length / r
    cx, cy = x - sgn * r * math.sin(th), y + sgn * r * math.cos(th)
    th2 = th + dth
    return cx + sgn * r * math.sin(th2), cy - sgn * r * math.cos(th2), th2


def dubins(
    a: tuple[float, float, float], b: tuple[float, float, float], r: float
) -> list[tuple[str, float]]:
    """Shortest path of curvature at most ``1 / r`` from pose ``a`` to pose ``b``.

    Poses are ``(x, y, heading [rad])``; returns the segments ``[(kind, length [m]), ...]``
    (``kind`` in ``L``, ``R``, ``S``; zero lengths dropped). Every candidate word is checked by
    flying it; the shortest that ends at ``b`` is returned.

    Parameters
    ----------
    a : tuple of float
        Start pose ``(x [m], y [m], heading [rad])``, the heading anticlockwise from the x axis.
    b : tuple of float
        End pose, as ``a``.
    r : float
        Turn radius [m] (the schedule's ``v_c² / a_turn``).

    Returns
    -------
    list of (str, float)
        The segments in order: ``"L"`` (left turn), ``"R"`` (right turn) or ``"S"`` (straight),
        each with its length along the path [m].
    """
    dx, dy = b[0] - a[0], b[1] - a[1]
    d = math.hypot(dx, dy) / r
    th = math.atan2(dy, dx)
    alpha, beta = _mod(a[2] - th), _mod(b[2] - th)
    best: list[tuple[str, float]] | None = None
    best_len = math.inf
    for word, lens in _dubins_words(alpha, beta, d):
        segs = [(k, ln * r) for k, ln in zip(word, lens, strict=True)]
        x, y, h = a
        for k, ln in segs:
            x, y, h = _advance(x, y, h, k, ln, r)
        ok = (
            math.hypot(x - b[0], y - b[1]) <= 1e-6 * max(r, 1.0)
            and abs(math.remainder(h - b[2], 2 * math.pi)) <= 1e-6
        )
        total = sum(ln for _, ln in segs)
        if ok and total < best_len:
            best, best_len = segs, total
    assert best is not None, "a Dubins path always exists"
    return [(k, ln) for k, ln in best if ln > 1e-9]


# ---------------------------------------------------------------------------------- schedule
def _targets(
    ctx: MissionContext, m: Mission, lead: float
) -> list[tuple[str, np.ndarray, np.ndarray, float]]:
    """What the schedule flies in order: ``(kind, run-in point, unit direction, straight
    length)`` for every line (kind ``"line"``) or waypoint (``"waypoint"``) of ``m``."""
    n = ctx.dim
    out = []
    if m.kind == "survey":
        for a, b in m.segments(n):
            e = (b - a) / np.linalg.norm(b - a)
            out.append(("line", a - lead * e, e, float(np.linalg.norm(b - a)) + 2 * lead))
    else:
        prev = ctx.p0
        for wp in m.waypoints:
            w = np.asarray(wp, float)
            d = w - prev
            d[2:] = 0.0
            if np.linalg.norm(d) < 1e-9:
                d = np.zeros(n)
                d[0] = 1.0
            e = d / np.linalg.norm(d)
            out.append(("waypoint", w - lead * e, e, 2 * lead))
            prev = w
    return out


def _straight(t0, dur, p, e, s0, acc=0.0, amp=0.0, cycles=0) -> Piece:
    return Piece("straight", t0, dur, p.copy(), e.copy(), s0=s0, acc=acc, amp=amp, cycles=cycles)


def _transit(
    t: float, p: np.ndarray, th: float, goal: np.ndarray, th_goal: float, v: float, r: float
) -> tuple[list[Piece], float, np.ndarray]:
    """The Dubins pieces at speed ``v`` from pose ``(p, th)`` to ``(goal, th_goal)`` (depth
    changed smoothly over the transit); returns ``(pieces, end time, end position)``."""
    n = p.size
    segs = dubins((p[0], p[1], th), (goal[0], goal[1], th_goal), r)
    total = sum(ln for _, ln in segs) / v
    dz = float(goal[2] - p[2]) if n == 3 else 0.0
    if dz != 0 and total <= 0:
        total = 0.0
    pieces = []
    x, y, h = p[0], p[1], th
    z0 = float(p[2]) if n == 3 else 0.0
    zt0 = t
    for kind, ln in segs:
        start = np.array([x, y, z0][:n], float)
        dur = ln / v
        if kind == "S":
            e = np.zeros(n)
            e[:2] = (math.cos(h), math.sin(h))
            pc = Piece("straight", t, dur, start, e, s0=v)
        else:
            sgn = 1.0 if kind == "L" else -1.0
            c = np.array([x - sgn * r * math.sin(h), y + sgn * r * math.cos(h)])
            phi0 = math.atan2(y - c[1], x - c[0])
            pc = Piece("arc", t, dur, start, np.zeros(n), s0=v, center=c, radius=r, phi0=phi0)
            pc = _replace(pc, sign=sgn)
        if n == 3 and dz != 0:
            pc = _replace(pc, z0=z0, dz=dz, zt0=zt0, zdur=max(total, 1e-9))
        pieces.append(pc)
        x, y, h = _advance(x, y, h, kind, ln, r)
        t += dur
    return pieces, t, np.asarray(goal, float).copy()


def _replace(pc: Piece, **kw) -> Piece:
    fields = {k: getattr(pc, k) for k in pc.__dataclass_fields__}
    fields.update(kw)
    return Piece(**fields)


def _speed_change(t: float, p: np.ndarray, e: np.ndarray, s0: float, s1: float, a: float):
    """Straight speed change from ``s0`` to ``s1`` at ``a``: ``(piece or None, t, p)``."""
    if abs(s1 - s0) < 1e-12:
        return None, t, p
    dur = abs(s1 - s0) / a
    acc = math.copysign(a, s1 - s0)
    pc = _straight(t, dur, p, e, s0, acc=acc)
    return pc, t + dur, p + e * (s0 * dur + 0.5 * acc * dur**2)


def build_schedule(
    ctx: MissionContext,
    v: float,
    accelerated: bool = False,
    mission: Mission | None = None,
    delay: float | None = None,
) -> MissionSchedule:
    """The schedule of ``ctx``'s mission (or of ``mission``, same end region: a candidate line
    order) at horizontal speed ``v`` [m/s] (module docstring); ``accelerated``: sinusoidal speed
    on the lines (same windows); ``delay`` [s]: a lead-in, at rest at the start (braking first
    if moving) until then, the time the planner localises in (:func:`planner_schedule`); None:
    none (0 still brings a moving start to rest).

    Parameters
    ----------
    ctx : MissionContext
        The mission and the start, acceleration and speed limits, and horizon it is flown
        under.
    v : float
        The horizontal cruise speed ``v_c`` [m/s].
    accelerated : bool, optional
        Fly each line at ``v_c + A sin(2 π k σ)`` (the accelerated lawn-mower).
    mission : Mission or None, optional
        A mission to schedule instead of ``ctx.mission`` (a candidate line order of
        :mod:`obsplan.planning.missions.order`).
    delay : float or None, optional
        The lead-in [s], at rest at the start; None for none.

    Returns
    -------
    MissionSchedule
        Its pieces cover the horizon; ``end_s`` may lie beyond it (the caller checks the fit).
    """
    m = ctx.mission if mission is None else mission
    assert m is not None
    n = ctx.dim
    tun = tuning()
    a = tun.accel_use * float(np.min(ctx.accel))
    r = v * v / a
    lead = tun.lead_steps * v * ctx.dt
    lo, hi = m.speed_band(ctx.speed_limit)
    targets = _targets(ctx, m, lead)
    p = ctx.p0.astype(float).copy()
    s0 = float(np.linalg.norm(ctx.v0[:2]))
    if s0 > 0:
        th = math.atan2(ctx.v0[1], ctx.v0[0])
    else:
        d = targets[0][1][:2] - p[:2] if targets else np.array([1.0, 0.0])
        th = math.atan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else 0.0
    e0 = np.zeros(n)
    e0[:2] = (math.cos(th), math.sin(th))
    pieces: list[Piece] = []
    t = 0.0
    if delay is not None:
        pc, t, p = _speed_change(t, p, e0, s0, 0.0, a)
        if pc is not None:
            pieces.append(pc)
        pieces.append(Piece("hold", t, max(delay - t, 0.0), p.copy(), e0))
        t, s0 = max(t, delay), 0.0
    pc, t, p = _speed_change(t, p, e0, s0, v, a)
    if pc is not None:
        pieces.append(pc)
    windows, passes = [], []
    for kind, start, e, length in targets:
        trans, t, p = _transit(t, p, th, start, math.atan2(e[1], e[0]), v, r)
        pieces += trans
        th = math.atan2(e[1], e[0])
        if kind == "line":
            line_t = (length - 2 * lead) / v
            pieces.append(_straight(t, lead / v, p, e, v))
            amp, cycles = 0.0, 0
            if accelerated:
                amp, cycles = _sinusoid(v, lo, hi, a, line_t)
            pieces.append(
                _straight(t + lead / v, line_t, p + lead * e, e, v, amp=amp, cycles=cycles)
            )
            pieces.append(_straight(t + lead / v + line_t, lead / v, p + (length - lead) * e, e, v))
            windows.append((t + lead / v, t + lead / v + line_t))
        else:
            pieces.append(_straight(t, length / v, p, e, v))
            passes.append(t + 0.5 * length / v)
        t += length / v
        p = p + length * e
    pieces, t = _finish(ctx, pieces, t, p, th, v, a, r)
    headroom = 1.0 - v / hi
    return MissionSchedule(
        v, tuple(pieces), tuple(windows), tuple(passes), t, headroom, lead, delay or 0.0
    )


def _sinusoid(v: float, lo: float, hi: float, a: float, line_t: float) -> tuple[float, int]:
    """Amplitude [m/s] and cycles of the accelerated lawn-mower's speed on one line."""
    tun = tuning()
    room = tun.accel_amplitude * min(hi - v, v - lo)
    if room <= 0 or line_t <= 0:
        return 0.0, 0
    cycles = tun.accel_cycles
    amp = min(room, a * line_t / (2 * math.pi * cycles))
    return amp, cycles


def _finish(ctx, pieces, t, p, th, v, a, r):
    """The end region (approached straight, braking to rest at its centre) or a stop, then
    hold to the horizon; returns ``(pieces, end time)``."""
    m = ctx.mission
    n = ctx.dim
    e = np.zeros(n)
    e[:2] = (math.cos(th), math.sin(th))
    brake = v * v / (2 * a)
    if m.end is not None:
        goal = np.asarray(m.end.position, float)
        d = goal[:2] - p[:2]
        th_g = math.atan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else th
        eg = np.zeros(n)
        eg[:2] = (math.cos(th_g), math.sin(th_g))
        trans, t, p = _transit(t, p, th, goal - brake * eg, th_g, v, r)
        pieces += trans
        e = eg
    if ctx.min_speed > 0:
        # a vehicle that cannot hover keeps going straight at v_c
        pieces.append(_straight(t, max(ctx.duration - t, 0.0) + 1.0, p, e, v))
        return pieces, t
    pc, t, p = _speed_change(t, p, e, v, 0.0, a)
    if pc is not None:
        pieces.append(pc)
    pieces.append(Piece("hold", t, max(ctx.duration - t, 0.0) + 1.0, p.copy(), e))
    return pieces, t


def _slowest_fit(
    ctx: MissionContext, delay: float | None = None
) -> tuple[float | None, float, float]:
    """The slowest band speed whose schedule (with ``delay``) ends within the horizon: ``(speed
    or None, the fastest mission's speed, its end [s])`` (:func:`mission_schedule`)."""
    m = ctx.mission
    assert m is not None
    lo, hi = m.speed_band(ctx.speed_limit)
    T = ctx.duration
    speeds = [float(x) for x in np.linspace(lo, hi, tuning().speed_grid + 1)]
    ends = [build_schedule(ctx, s, delay=delay).end_s for s in speeds]
    best = int(np.argmin(ends))
    fits = [i for i, e in enumerate(ends) if e <= T]
    if not fits:
        return None, speeds[best], ends[best]
    i = fits[0]
    fit = speeds[i]
    if i > 0:
        unfit = speeds[i - 1]
        for _ in range(30):
            mid = 0.5 * (fit + unfit)
            if build_schedule(ctx, mid, delay=delay).end_s <= T:
                fit = mid
            else:
                unfit = mid
    return fit, speeds[best], ends[best]


@cache_per_tuning
def mission_schedule(ctx: MissionContext) -> MissionSchedule:
    """The schedule at the slowest band speed that ends within the horizon (module docstring).

    The mission time is not monotonic in the speed (faster lines, wider turns), so
    ``Tuning.speed_grid + 1`` speeds across the band are tried; the slowest that fits is refined
    by bisection towards the next slower one.

    Parameters
    ----------
    ctx : MissionContext
        The mission and the start, limits and horizon it is flown under.

    Returns
    -------
    MissionSchedule
        The plain lawn-mower's schedule, without a lead-in (cached per context and tuning).

    Raises
    ------
    ProblemError
        On ``horizon.duration`` (with the shortest duration that fits) when no band speed ends
        the mission within the horizon.
    """
    fit, fastest, end = _slowest_fit(ctx)
    if fit is None:
        T = ctx.duration
        raise field_error(
            "horizon.duration",
            f"{T:g} s is too short for the mission: at its fastest (a constant "
            f"{fastest:.3g} m/s within mission.speed, the tightest turns limits.accel "
            f"allows) it takes {end:.1f} s; use horizon.duration >= "
            f"{math.ceil(end)} s, a wider mission.speed, or fewer lines",
        )
    return build_schedule(ctx, fit)


def lead_in_seconds(ctx: MissionContext) -> float:
    """The lead-in [s] of ``ctx``'s survey (``mission.lead_in``, ``"auto"`` resolved; 0 for
    waypoints and transits, when the lines leave no speed headroom, and for a vehicle that
    cannot wait at the start, ``limits.min_speed > 0``).

    Parameters
    ----------
    ctx : MissionContext
        A context with a mission.

    Returns
    -------
    float
        The lead-in [s]; ``"auto"`` takes the horizon's slack at a cruise speed
        ``Tuning.lead_in_speed_share`` of the way up the headroom, in whole planning steps.

    Raises
    ------
    ProblemError
        On ``mission.lead_in`` when a lead-in is given for a mission without survey lines or
        for a vehicle with ``limits.min_speed``.
    """
    m = ctx.mission
    assert m is not None
    given = m.lead_in != "auto" and float(m.lead_in) > 0
    if m.kind != "survey" or not m.lines:
        if given:
            raise field_error(
                "mission.lead_in", f"is for survey lines; a {m.kind} mission has none: remove it"
            )
        return 0.0
    if ctx.min_speed > 0:
        if given:
            raise field_error(
                "mission.lead_in",
                f"{float(m.lead_in):g} s: a vehicle with limits.min_speed cannot wait at the "
                'start; use 0 or "auto" (no lead-in)',
            )
        return 0.0
    if m.lead_in != "auto":
        return float(m.lead_in)
    base = mission_schedule(ctx)
    if base.headroom <= 0:
        return 0.0
    _, hi = m.speed_band(ctx.speed_limit)
    v = base.speed + tuning().lead_in_speed_share * (hi - base.speed)
    slack = ctx.duration - build_schedule(ctx, v, delay=0.0).end_s
    # whole planning steps: the windows then fall on the nodes as the schedule's do
    h = ctx.dt
    return max(0.0, math.floor(slack / h) * h)


@cache_per_tuning
def planner_schedule(ctx: MissionContext) -> MissionSchedule:
    """The schedule whose line windows the planner flies: the lawn-mower's
    (:func:`mission_schedule`) delayed by the lead-in (``mission.lead_in``), the lines at the
    slowest band speed that still ends the mission within the horizon.

    The lead-in is time at the start, before the first line's run-in, in which the planner is
    free to localise: flown at the lawn-mower's speed, the first line starts while the filter
    still holds its prior, and those samples dominate the localisation error over the lines.
    A surveyor spends the speed headroom on a calibration manoeuvre first; the planner does the
    same, and chooses what to fly in it.

    Parameters
    ----------
    ctx : MissionContext
        The mission and the start, limits and horizon it is flown under.

    Returns
    -------
    MissionSchedule
        With ``lead_in`` [s] set; :func:`mission_schedule` itself when the lead-in is 0 (cached
        per context and tuning).

    Raises
    ------
    ProblemError
        On ``mission.lead_in`` when no band speed fits the lead-in and the mission in the
        horizon (with the longest lead-in that fits).
    """
    base = mission_schedule(ctx)
    delay = lead_in_seconds(ctx)
    if delay <= 0:
        return base
    fit, _, end = _slowest_fit(ctx, delay)
    if fit is None:
        # the shortest mission after the lead-in leaves this much of the horizon for it
        room = ctx.duration - (end - delay)
        raise field_error(
            "mission.lead_in",
            f"{delay:g} s does not fit: at its fastest the mission leaves "
            f"{max(math.floor(room), 0)} s of the horizon for it; use mission.lead_in <= that, "
            '"auto", or a longer horizon.duration',
        )
    return build_schedule(ctx, fit, delay=delay)


def mission_fit_error(ctx: MissionContext) -> None:
    """Refuse a mission that cannot fit the horizon (see :func:`mission_schedule`), or whose
    schedule passes a waypoint outside its time window (the planner passes it at that time).

    Parameters
    ----------
    ctx : MissionContext
        A context with a mission.

    Raises
    ------
    ProblemError
        On ``horizon.duration``, ``mission.lead_in`` or ``mission.windows[i]``.
    """
    sched = mission_schedule(ctx)
    planner_schedule(ctx)  # a lead-in that does not fit is refused here, before any solve
    m = ctx.mission
    assert m is not None
    for i, (t, (t0, t1)) in enumerate(zip(sched.waypoint_times, m.windows, strict=False)):
        if not t0 <= t <= t1:
            raise field_error(
                f"mission.windows[{i}]",
                f"[{t0:g}, {t1:g}] s does not contain t = {t:.1f} s, when the constant-speed "
                f"schedule ({sched.speed:.3g} m/s) passes waypoint {i}; widen the window or "
                "change horizon.duration",
            )


def line_sample_mask(ctx: MissionContext, t: np.ndarray) -> np.ndarray:
    """Boolean mask of the times ``t`` [s] inside the planner's line windows
    (:func:`planner_schedule`).

    Parameters
    ----------
    ctx : MissionContext
        The mission and the numbers it is flown under.
    t : ndarray, shape (J,)
        Times [s] from the start of the horizon.

    Returns
    -------
    ndarray of bool, shape (J,)
        True inside a line window (ends included, 1e-9 s slack); all False without a mission.
    """
    mask = np.zeros(np.asarray(t).size, bool)
    if ctx.mission is None:
        return mask
    for t0, t1 in planner_schedule(ctx).line_windows:
        mask |= (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    return mask


def check_mission_geometry(m: Mission, dim: int) -> None:
    """Lines of positive length, level in 3D (the schedule's turns are horizontal) unless they
    follow the seabed of an altitude band.

    Parameters
    ----------
    m : Mission
        The mission whose ``lines`` are checked.
    dim : int
        Spatial dimension ``n`` (2 or 3).

    Raises
    ------
    ProblemError
        On ``mission.lines[i]``: a line without horizontal length, or (3D, no altitude band) not
        level.
    """
    for i, (a, b) in enumerate(m.segments(dim)):
        if np.linalg.norm((b - a)[:2]) < 1e-6:
            raise field_error(
                f"mission.lines[{i}]", "has no horizontal length; give two distinct points"
            )
        if dim == 3 and m.altitude is None and abs(float(b[2] - a[2])) > 1e-9:
            raise field_error(
                f"mission.lines[{i}]",
                f"is not level (z from {a[2]:g} to {b[2]:g} m); survey lines are flown at one "
                "depth: give z0 = z1",
            )
