"""The ``[mission]`` of a problem: what the vehicle must do besides localising.

A mission is a frozen :class:`Mission`:

* ``survey``: straight lines, each flown from its first point to its second within a cross-track
  tolerance ``cross_track`` [m], a heading tolerance ``heading_tol`` [deg] (the velocity's
  direction against the line's) and a speed band ``speed = (lo, hi)`` [m/s] (``lo <= |v| <= hi``
  and way on along the line, ``v·e >= lo``). The lines are given (``lines``, 2D ``[x0, y0, x1,
  y1]``, 3D ``[x0, y0, z0, x1, y1, z1]``) or generated from an area (:func:`generate_lines`);
* ``waypoints``: points passed in order, each within ``radius`` [m], optionally inside a time
  window ``[t0, t1]`` [s];
* ``end`` (any kind): a region ``|p(T) - position| <= radius`` reached at the end of the horizon,
  optionally with a final speed ``|v(T)| <= speed``.

Generated lines (:func:`generate_lines`): the lines are parallel to ``heading`` (degrees clockwise
from north, the x axis of the local north-east-down frame: 90 flies east, along +y), ``spacing``
[m] apart across the heading: ``floor(width / spacing)`` lines (``width`` the area's extent
across the heading), centred across the area, so that each line is the centre of a swath of
width ``spacing`` inside the area; each line is the chord of the
area (rectangle or polygon; of a non-convex polygon the longest chord piece) along its offset.
They are flown boustrophedon: the line nearest the start first, along ``heading``; then every
next line in the opposite direction of the previous one.

**Altitude band** (3D surveys): with ``altitude = (lo, hi)`` [m] above a planar ``seabed``
(:class:`Seabed`, depth ``d + sx x + sy y``, ``z`` positive down), the lines are given (or
generated) as horizontal tracks ``[x0, y0, x1, y1]`` and flown at the band's middle
(:func:`lines_at_altitude`): over a plane that is a straight line whose depth follows the seabed.
The line's horizontal distance from its track is held within ``cross_track`` and its altitude
``seabed(x, y) - z`` within the band (a linear row in the position, :meth:`Mission.altitude_row`).

``order = "free"`` lets the planner reorder and reverse the lines
(:mod:`obsplan.planning.missions.order`: the order of the shortest transits); ``lines`` then holds
them as flown and ``flown_as`` how they were given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsplan.core import budget
from obsplan.core.errors import ProblemError, field_error

#: Mission kinds.
MISSION_KINDS: tuple[str, ...] = ("survey", "waypoints")
#: Line orders: as given, or free for the planner (reordering and reversing lines).
MISSION_ORDERS: tuple[str, ...] = ("given", "free")


@dataclass(frozen=True)
class EndRegion:
    """A region reached at the end of the horizon: ``|p(T) - position| <= radius`` [m], and
    ``|v(T)| <= speed`` [m/s] when ``speed`` is given."""

    position: tuple[float, ...]
    radius: float
    speed: float | None = None


@dataclass(frozen=True)
class LineArea:
    """The area lines are generated from: a rectangle (``x``, ``y`` as ``(min, max)``) or a
    polygon (``polygon``: its corners ``(x, y)`` in order) [m]."""

    x: tuple[float, float] | None = None
    y: tuple[float, float] | None = None
    polygon: tuple[tuple[float, float], ...] = ()

    def corners(self) -> np.ndarray:
        """The polygon's corners, shape (k, 2) [m] (a rectangle's four).

        Returns
        -------
        ndarray, shape (k, 2)
            ``(x, y)`` of each corner [m], in order (a rectangle's anticlockwise from
            ``(x_min, y_min)``).
        """
        if self.polygon:
            return np.asarray(self.polygon, float)
        assert self.x is not None and self.y is not None
        (x0, x1), (y0, y1) = self.x, self.y
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


@dataclass(frozen=True)
class Seabed:
    """A planar seabed: its depth [m] (``z`` down) is ``depth + slope[0] x + slope[1] y``."""

    depth: float
    slope: tuple[float, float] = (0.0, 0.0)

    def depth_at(self, xy: np.ndarray) -> np.ndarray:
        """The seabed's depth [m] under the points ``xy`` (..., 2) [m].

        Parameters
        ----------
        xy : ndarray, shape (..., 2)
            Horizontal positions ``(x, y)`` [m].

        Returns
        -------
        ndarray, shape (...)
            Depth ``z`` of the seabed [m], positive down.
        """
        xy = np.asarray(xy, float)
        return self.depth + xy[..., 0] * self.slope[0] + xy[..., 1] * self.slope[1]


def lines_at_altitude(
    tracks: tuple[tuple[float, ...], ...], altitude: tuple[float, float], seabed: Seabed
) -> tuple[tuple[float, ...], ...]:
    """Horizontal tracks ``(x0, y0, x1, y1)`` [m] as 3D lines at the middle of the ``altitude``
    band [m] above ``seabed``: ``(x0, y0, z0, x1, y1, z1)``.

    Parameters
    ----------
    tracks : tuple of tuple of float
        The horizontal tracks, each ``(x0, y0, x1, y1)`` [m] (of a longer tuple, its first two
        and last two numbers).
    altitude : tuple of float
        The band ``(lo, hi)`` [m] above the seabed.
    seabed : Seabed
        The planar seabed under the tracks.

    Returns
    -------
    tuple of tuple of float
        One 3D line per track, ``(x0, y0, z0, x1, y1, z1)`` [m], ``z`` positive down.
    """
    mid = 0.5 * (altitude[0] + altitude[1])
    out = []
    for x0, y0, x1, y1 in (tr[:2] + tr[-2:] for tr in tracks):
        z0 = float(seabed.depth_at(np.array([x0, y0]))) - mid
        z1 = float(seabed.depth_at(np.array([x1, y1]))) - mid
        out.append((x0, y0, z0, x1, y1, z1))
    return tuple(out)


@dataclass(frozen=True)
class Mission:
    """A mission (module docstring). ``lines`` are the resolved lines (given or generated),
    each ``2 n`` numbers [m]; the generator's fields (``area``, ``spacing``, ``heading``,
    ``depth``) are kept so that the problem file round-trips."""

    kind: str = "survey"
    lines: tuple[tuple[float, ...], ...] = ()
    cross_track: float = 2.0
    heading_tol: float = 10.0
    speed: tuple[float, float] | None = None
    order: str = "given"
    shift: float = 0.0
    #: Seconds at the start before the planner's first line, or ``"auto"``
    #: (:func:`~obsplan.planning.missions.schedule.planner_schedule`).
    lead_in: float | str = "auto"
    waypoints: tuple[tuple[float, ...], ...] = ()
    radius: float = 5.0
    windows: tuple[tuple[float, float], ...] = ()
    end: EndRegion | None = None
    area: LineArea | None = None
    spacing: float | None = None
    heading: float | None = None
    depth: float | None = None
    #: 3D surveys: the band ``(lo, hi)`` [m] of the altitude above ``seabed`` (module docstring).
    altitude: tuple[float, float] | None = None
    seabed: Seabed | None = None
    #: With ``order = "free"``: for each line of ``lines`` (the order flown), its index in the
    #: lines as given and whether it is flown reversed (:mod:`obsplan.planning.missions.order`).
    flown_as: tuple[tuple[int, bool], ...] = ()

    def given_lines(self) -> tuple[tuple[float, ...], ...]:
        """The lines as given (``lines`` undone from the free order), each ``2 n`` numbers [m].

        Returns
        -------
        tuple of tuple of float
            ``lines`` in the given order and direction (``lines`` itself without ``flown_as``).
        """
        if not self.flown_as:
            return self.lines
        out: list[tuple[float, ...]] = [()] * len(self.lines)
        for ln, (i, rev) in zip(self.lines, self.flown_as, strict=True):
            h = len(ln) // 2
            out[i] = (*ln[h:], *ln[:h]) if rev else ln
        return tuple(out)

    def altitude_row(self) -> tuple[np.ndarray, float] | None:
        """``(w, half)``: a point ``p`` at ``r = p - a`` from a line's start ``a`` is inside the
        altitude band when ``|w·r| <= half`` (``w = (sx, sy, -1)``, the altitude's gradient;
        ``half`` the band's half width [m]); None without a band.

        Returns
        -------
        tuple of (ndarray, float) or None
            ``w``, shape (3,) (dimensionless), and ``half`` [m]; None without an altitude band
            and seabed.
        """
        if self.altitude is None or self.seabed is None:
            return None
        sx, sy = self.seabed.slope
        return np.array([sx, sy, -1.0]), 0.5 * (self.altitude[1] - self.altitude[0])

    def speed_band(self, speed_limit: float) -> tuple[float, float]:
        """``speed`` or its default ``(0.3, 1) * limits.speed`` [m/s].

        Parameters
        ----------
        speed_limit : float
            ``limits.speed`` [m/s].

        Returns
        -------
        tuple of float
            The band ``(lo, hi)`` [m/s].
        """
        if self.speed is not None:
            return self.speed
        return (0.3 * speed_limit, speed_limit)

    def segments(self, dim: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """The survey lines as ``(start, end)`` points, each shape (dim,) [m].

        Parameters
        ----------
        dim : int
            Spatial dimension ``n`` (2 or 3): each line holds ``2 n`` numbers.

        Returns
        -------
        list of (ndarray, ndarray)
            ``(start, end)`` of each line in ``lines`` (the order flown), each shape (dim,) [m].
        """
        return [(np.asarray(ln[:dim], float), np.asarray(ln[dim:], float)) for ln in self.lines]


def _chord(corners: np.ndarray, point: np.ndarray, e: np.ndarray) -> tuple[float, float] | None:
    """Longest piece ``[s0, s1]`` of the line ``point + s e`` inside the polygon (None: none)."""
    ss = []
    k = corners.shape[0]
    for i in range(k):
        a, b = corners[i], corners[(i + 1) % k]
        d = b - a
        den = e[0] * (-d[1]) + e[1] * d[0]  # solve point + s e = a + r d
        if abs(den) < 1e-12:
            continue
        w = a - point
        s = (w[0] * (-d[1]) + w[1] * d[0]) / den
        r = (e[0] * w[1] - e[1] * w[0]) / den
        if -1e-12 <= r <= 1 + 1e-12:
            ss.append(s)
    ss = sorted(ss)
    best = None
    for s0, s1 in zip(ss[::2], ss[1::2], strict=False):
        if s1 - s0 > 1e-9 and (best is None or s1 - s0 > best[1] - best[0]):
            best = (s0, s1)
    return best


def generate_lines(
    area: LineArea,
    spacing: float,
    heading_deg: float,
    start_xy: np.ndarray,
    depth: float | None = None,
) -> tuple[tuple[float, ...], ...]:
    """Survey lines covering ``area`` (the rule of the module docstring).

    Parameters
    ----------
    area : LineArea
    spacing : float
        Distance between lines [m].
    heading_deg : float
        Direction of the lines [deg clockwise from north (x) towards east (y)].
    start_xy : ndarray, shape (2,)
        The start (the nearest line is flown first).
    depth : float or None
        In 3D, the lines' depth ``z`` [m] (None in 2D).

    Returns
    -------
    tuple of lines, each ``(x0, y0, x1, y1)`` or ``(x0, y0, z, x1, y1, z)`` [m].

    Raises
    ------
    ProblemError
        When the area is narrower than ``spacing`` across the heading, or so wide that it
        would hold more than :data:`~obsplan.core.budget.MAX_LINES` lines (counted first).
    """
    h = math.radians(heading_deg)
    e = np.array([math.cos(h), math.sin(h)])
    n = np.array([-e[1], e[0]])
    corners = area.corners()
    off = corners @ n
    lo, hi = float(off.min()), float(off.max())
    # counted before a line is made: a tiny spacing would build billions of them
    budget.check_lines(
        (hi - lo) / spacing,
        "mission.spacing",
        f"over the area's {hi - lo:.4g} m across the heading, use a spacing of at least "
        f"{(hi - lo) / budget.MAX_LINES:.3g} m ({budget.MAX_LINES} lines at most)",
        ProblemError,
    )
    budget.check_corners(len(corners), "mission.area.polygon", ProblemError)
    count = int(math.floor((hi - lo) / spacing + 1e-9))
    if count < 1:
        raise field_error(
            "mission.spacing",
            f"{spacing:g} m is wider than the area across the heading ({hi - lo:.4g} m); use a "
            "smaller spacing",
        )
    first = lo + 0.5 * (hi - lo - (count - 1) * spacing)
    offsets = [first + j * spacing for j in range(count)]
    if abs(float(start_xy @ n) - offsets[-1]) < abs(float(start_xy @ n) - offsets[0]):
        offsets.reverse()
    lines: list[tuple[float, ...]] = []
    sign = 1.0
    for o in offsets:
        chord = _chord(corners, o * n, e)
        if chord is None:
            continue
        a, b = o * n + chord[0] * e, o * n + chord[1] * e
        if sign < 0:
            a, b = b, a
        sign = -sign
        if depth is None:
            lines.append((float(a[0]), float(a[1]), float(b[0]), float(b[1])))
        else:
            lines.append((float(a[0]), float(a[1]), depth, float(b[0]), float(b[1]), depth))
    return tuple(lines)


@dataclass(frozen=True)
class MissionContext:
    """What a mission's timing needs of its problem: the mission, the start, the limits and the
    horizon (a :class:`~obsplan.planning.problem.definition.PlanningProblem` gives its own as
    :attr:`~obsplan.planning.problem.definition.PlanningProblem.mission_context`).

    Every function of :mod:`obsplan.planning.missions` takes one: the missions room knows the
    mission and the numbers it is flown under, never the whole problem.
    """

    #: The mission (None: free localisation).
    mission: Mission | None
    #: Start position and inertial velocity [m], [m/s], shape (n,).
    start_position: tuple[float, ...]
    start_velocity: tuple[float, ...]
    #: Per-axis acceleration bound [m/s²], shape (n,).
    accel_limit: tuple[float, ...]
    #: Speed bound and minimum speed through the water [m/s] (``limits.speed``, ``min_speed``).
    speed_limit: float
    min_speed: float
    #: Horizon [s] and its number of planning steps.
    duration: float
    steps: int

    @property
    def dim(self) -> int:
        return len(self.start_position)

    @property
    def p0(self) -> np.ndarray:
        """Start position, shape (n,) [m]."""
        return np.asarray(self.start_position, float)

    @property
    def v0(self) -> np.ndarray:
        """Start inertial velocity, shape (n,) [m/s]."""
        return np.asarray(self.start_velocity, float)

    @property
    def accel(self) -> np.ndarray:
        """Per-axis acceleration bounds, shape (n,) [m/s²]."""
        return np.asarray(self.accel_limit, float)

    @property
    def dt(self) -> float:
        """Planning step ``duration / steps`` [s]."""
        return self.duration / self.steps

    @property
    def times(self) -> np.ndarray:
        """Planning grid ``t_k = k dt``, shape (N + 1,) [s]."""
        return np.linspace(0.0, self.duration, self.steps + 1)
