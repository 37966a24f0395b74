"""The order of a survey's lines when ``mission.order = "free"``: which line next, and which way.

A surveyor's freedom is the order and the direction of the lines; what the planner gains from
it is time. The horizon is fixed, so every second the transits between lines do not need is
speed headroom left to the planner on the lines (:mod:`obsplan.planning.missions.schedule`: the
lawn-mower's constant speed ``v_c`` is the slowest that ends within the horizon). The free
order is the one that lets the schedule fly slowest, found on a grid of ``order_speeds`` speeds
across the band ``mission.speed``, slowest first: at each speed ``s`` the order of the shortest
transit path (from the start pose, along the schedule's bounded-curvature Dubins transits at ``s``,
turn radius ``s² / a_turn`` and run-in and run-out ``lead`` as the schedule's, to every line's
run-in point in turn, each line flown whole in the direction chosen, then straight to the end region
if any); the first of these orders whose schedule at ``s`` ends within the horizon is kept
(``mission_schedule`` then refines ``v_c`` for it). The speed matters: with turns wider than the
line spacing the shortest path skips a line and comes back, with tight turns it takes the next. When
no speed fits, the order of the shortest mission is kept (and the fit check refuses it with the
shortest horizon).

* Up to ``exact_lines`` lines the order is exact: dynamic programming over the subsets of lines
  flown (Held–Karp) on precomputed transit lengths.
* Beyond, the greedy nearest next line and direction, improved by reversing runs of the order
  (2-opt, each run's lines reversed too) while that shortens the path.

Ties are broken by a canonical order of the lines (sorted by their endpoints), so the result
depends only on the set of lines, not on how they were listed: a problem file written back with
its lines in the flown order resolves to the same order. The lawn-mower baselines fly the same
order, so the comparison stays like for like. The observability objective does not choose the
order: it chooses the speed, the turns and the manoeuvres between lines in the windows the
order leaves.

``order_speeds`` and ``exact_lines`` are :class:`~obsplan.planning.tuning.Tuning`'s, read at call
time (the order is resolved when the problem is built).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from obsplan.planning.missions.schedule import build_schedule, dubins
from obsplan.planning.missions.spec import Mission, MissionContext
from obsplan.planning.tuning import tuning

#: Most lines a free order is searched for (its transit table grows as the square of the lines,
#: on every speed of the search); more are refused before any work.
MAX_FREE_LINES = 60
#: Relative tolerance under which two path lengths are a tie (round-off of the Dubins lengths).
_TIE = 1e-9


def _poses(
    segs: list[tuple[np.ndarray, np.ndarray]], lead: float
) -> tuple[list[tuple[float, float, float]], list[np.ndarray]]:
    """Run-in pose and exit point of every line ``j`` flown forward (index ``2j``) and reversed
    (``2j + 1``)."""
    runin, exit_ = [], []
    for a, b in segs:
        for s, f in ((a, b), (b, a)):
            e = (f - s)[:2] / np.linalg.norm((f - s)[:2])
            p = s[:2] - lead * e
            runin.append((float(p[0]), float(p[1]), math.atan2(e[1], e[0])))
            exit_.append(np.array([*(f[:2] + lead * e), math.atan2(e[1], e[0])]))
    return runin, exit_


def _costs(ctx: MissionContext, segs: list[tuple[np.ndarray, np.ndarray]], speed: float):
    """Transit lengths [m] at ``speed`` [m/s]: from the start to each oriented line, between
    oriented lines, and from each oriented line to the end region (0 without one)."""
    m = ctx.mission
    assert m is not None
    tun = tuning()
    r = speed * speed / (tun.accel_use * float(np.min(ctx.accel)))
    lead = tun.lead_steps * speed * ctx.dt
    runin, exit_ = _poses(segs, lead)
    k = len(runin)
    p0 = ctx.p0[:2].astype(float)
    moving = float(np.linalg.norm(ctx.v0[:2])) > 0
    heading = math.atan2(ctx.v0[1], ctx.v0[0]) if moving else 0.0
    first = np.empty(k)
    for j, pose in enumerate(runin):
        th0 = heading
        if not moving:  # from rest the vehicle sets off towards its first target (as the schedule)
            d = np.array(pose[:2]) - p0
            th0 = math.atan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else pose[2]
        first[j] = sum(ln for _, ln in dubins((p0[0], p0[1], th0), pose, r))
    between = np.empty((k, k))
    for i, ex in enumerate(exit_):
        for j, pose in enumerate(runin):
            between[i, j] = sum(ln for _, ln in dubins(tuple(ex), pose, r))
    last = np.zeros(k)
    if m.end is not None:
        goal = np.asarray(m.end.position, float)[:2]
        last = np.array([float(np.linalg.norm(goal - ex[:2])) for ex in exit_])
    return first, between, last


def _exact(first: np.ndarray, between: np.ndarray, last: np.ndarray, n: int) -> list[int]:
    """Held–Karp over subsets: the oriented-line sequence (indices ``2j + d``) of least length."""
    full = (1 << n) - 1
    inf = math.inf
    cost = np.full((1 << n, 2 * n), inf)
    back = np.full((1 << n, 2 * n), -1, dtype=np.int64)
    line_of = np.arange(2 * n) >> 1
    for o in range(2 * n):
        cost[1 << (o >> 1), o] = first[o]
    for mask in range(1, full + 1):
        ends = np.flatnonzero(np.isfinite(cost[mask]))
        if ends.size == 0:
            continue
        # every way to extend the paths ending at ``ends`` by one oriented line not yet flown
        ext = cost[mask, ends][:, None] + between[ends]
        src = ends[np.argmin(ext, axis=0)]  # argmin: the first (canonical) of equal lengths
        best = ext.min(axis=0)
        for o2 in np.flatnonzero(((mask >> line_of) & 1) == 0):
            nxt = mask | (1 << int(line_of[o2]))
            if best[o2] < cost[nxt, o2] * (1 - _TIE):
                cost[nxt, o2] = best[o2]
                back[nxt, o2] = src[o2]
    tot = cost[full] + last
    o = int(np.argmin(tot))  # argmin: the first (canonical) of equal lengths
    seq, mask = [], full
    while o >= 0:
        seq.append(o)
        prev = int(back[mask, o])
        mask &= ~(1 << (o >> 1))
        o = prev
    return seq[::-1]


def _length(seq: list[int], first, between, last) -> float:
    return float(
        first[seq[0]]
        + sum(between[a, b] for a, b in zip(seq, seq[1:], strict=False))
        + last[seq[-1]]
    )


def _greedy(first: np.ndarray, between: np.ndarray, last: np.ndarray, n: int) -> list[int]:
    """Nearest next line, then 2-opt (a run reversed, its lines flown the other way)."""
    seq = [int(np.argmin(first))]
    left = set(range(n)) - {seq[0] >> 1}
    while left:
        o = seq[-1]
        cand = [o2 for j in sorted(left) for o2 in (2 * j, 2 * j + 1)]
        nxt = min(cand, key=lambda o2: between[o, o2])
        seq.append(nxt)
        left.discard(nxt >> 1)
    return _two_opt(seq, first, between, last)


def _two_opt(seq: list[int], first, between, last) -> list[int]:
    """Reverse runs ``seq[i..j]`` (each line flown the other way) while that shortens the path.

    A pass costs ``O(n²)``: the run's own transits, forward and reversed, come from prefix sums
    (the costs are asymmetric, so the reversed run's transits are not the forward ones)."""
    n = len(seq)
    best = _length(seq, first, between, last)
    improved = True
    while improved:
        improved = False
        s = np.asarray(seq)
        fwd = np.concatenate([[0.0], np.cumsum(between[s[:-1], s[1:]])])
        rev = np.concatenate([[0.0], np.cumsum(between[s[1:] ^ 1, s[:-1] ^ 1])])
        for i in range(n - 1):
            before = first[s[i]] if i == 0 else between[s[i - 1], s[i]]
            for j in range(i + 1, n):
                after = last[s[j]] if j == n - 1 else between[s[j], s[j + 1]]
                new_before = first[s[j] ^ 1] if i == 0 else between[s[i - 1], s[j] ^ 1]
                new_after = last[s[i] ^ 1] if j == n - 1 else between[s[i] ^ 1, s[j + 1]]
                delta = (new_before + new_after + rev[j] - rev[i]) - (
                    before + after + fwd[j] - fwd[i]
                )
                if delta < -_TIE * best:
                    seq = seq[:i] + [o ^ 1 for o in reversed(seq[i : j + 1])] + seq[j + 1 :]
                    best = _length(seq, first, between, last)
                    improved = True
                    break
            if improved:
                break
    return seq


def free_order(ctx: MissionContext) -> Mission:
    """``ctx``'s mission with its lines in the free order (module docstring).

    Parameters
    ----------
    ctx : MissionContext
        The mission (``mission.order = "free"``) and the start, limits and horizon it is flown
        under (the transits and the schedule's end depend on them).

    Returns
    -------
    Mission
        ``lines`` in the order and direction flown, ``flown_as`` the given index of each and
        whether it is reversed. Missions without survey lines, or not ``order = "free"``, are
        returned unchanged.
    """
    m = ctx.mission
    if m is None or m.order != "free" or not m.lines or m.flown_as:
        return m  # type: ignore[return-value]
    n = ctx.dim
    given = m.segments(n)
    canon = sorted(range(len(given)), key=lambda i: tuple(sorted(map(tuple, given[i]))))
    segs: list[tuple[np.ndarray, np.ndarray]] = []
    swapped: list[bool] = []  # the canonical endpoints are the given ones swapped
    for i in canon:  # each line's endpoints in a canonical order too
        a, b = given[i]
        swapped.append(tuple(b) < tuple(a))
        segs.append((b, a) if swapped[-1] else (a, b))
    k = len(segs)
    lo, hi = m.speed_band(ctx.speed_limit)
    fallback: tuple[float, Mission] | None = None
    tun = tuning()
    for s in np.linspace(lo, hi, tun.order_speeds):
        first, between, last = _costs(ctx, segs, float(s))
        seq = (_exact if k <= tun.exact_lines else _greedy)(first, between, last, k)
        cand = _flown(m, canon, swapped, segs, seq)
        end = build_schedule(ctx, float(s), mission=cand).end_s
        if end <= ctx.duration:
            return cand
        if fallback is None or end < fallback[0]:
            fallback = (end, cand)
    assert fallback is not None
    return fallback[1]


def _flown(m: Mission, canon: list[int], swapped: list[bool], segs, seq: list[int]) -> Mission:
    """``m`` with its lines in the oriented order ``seq`` (indices ``2c + reversed`` into the
    canonical ``segs``; ``canon[c]`` the given index, ``swapped[c]`` its endpoints' order)."""
    lines, flown = [], []
    for o in seq:
        c, rev = o >> 1, bool(o & 1)
        a, b = segs[c][::-1] if rev else segs[c]
        flown.append((canon[c], rev != swapped[c]))
        lines.append(tuple(float(x) for x in (*a, *b)))
    return replace(m, lines=tuple(lines), flown_as=tuple(flown))
