"""A beacon that moves along a known path: a ship's or a surface vehicle's logged track.

Only the motion of the vehicle *relative* to the beacon enters the range: with ``r = p - b``,
``r'' = u - b''`` (the paper's eqs. 1-3 with the beacon moving). A :class:`BeaconPath` gives
``b(t)`` from samples ``(t_j, b_j)``, ``j = 0..M-1``, and the derivatives of ``b`` the two
observability tests need, in two deliberate forms:

* **The path itself is piecewise linear** (:meth:`BeaconPath.position`): a log's samples
  interpolated linearly, nothing assumed between them. Its velocity (:meth:`BeaconPath.velocity`) is
  constant on each segment ``[t_j, t_{j+1})`` (right-continuous at the knots, as held inputs are)
  and its acceleration is zero between knots and impulsive at them. The augmented Gramian uses
  exactly this path: on the union of the trajectory's samples and the beacon's knots the relative
  motion is that of a held input, so the Gramian's closed form stays exact, and the impulses appear
  as jumps of the relative velocity (:mod:`obsplan.trajectory.relative`); no ``b''`` is needed. *
  **The LWO rank test is local**: it reads ``b'`` and ``b''`` at an instant. The impulses of a
  piecewise-linear path are invisible there (between knots ``b'' = 0``), so a log sampling a
  circling ship would look, to the LWO test, like a beacon that never accelerates. The test uses
  instead the derivatives of the smooth path that the samples are taken from, estimated by the
  three-point divided differences of :meth:`BeaconPath.derivative_estimates` (exact on constant-
  velocity and constant-acceleration legs; second order in the knot spacing elsewhere).

A fixed beacon is the constant path (:meth:`BeaconPath.fixed`): velocity and acceleration are
then exactly zero. A path must cover the interval it is used on (:meth:`BeaconPath.check_covers`):
nothing is extrapolated.

The CSV form (:func:`read_beacon_path`): a header row, then ``t,bx,by`` (2D) or ``t,bx,by,bz``
(3D), seconds and metres in the trajectory's frame, times strictly increasing, extra columns
ignored.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from obsplan.core.budget import check_file_rows
from obsplan.core.csvtable import read_table, write_table
from obsplan.core.errors import InputError, TrajectoryFormatError

_AXES = "xyz"
#: A change of segment velocity at a knot within this many times the round-off bound of the two
#: divided differences (:meth:`BeaconPath.derivative_estimates`) is taken as no change. The bound
#: counts one rounding of each stored time and position; a log written by a script carries a few
#: (``b0 + v t`` then printed), hence 16. A constant-velocity beacon then has exactly ``b'' = 0``,
#: which the LWO test needs: an acceleration of round-off size ``eps |b| / h²`` is 1e-9 of the
#: trajectory's own scale (``LWO_RANK_TOL``) for a log at 0.01 s some kilometres away, and would
#: read as excitation. A real change is many orders larger (1 mm/s at 1 km is 1e11 ulps).
VELOCITY_SNAP: float = 16.0


def beacon_columns(dim: int) -> list[str]:
    """Column names of the beacon path CSV for dimension ``dim``.

    Parameters
    ----------
    dim : int
        Spatial dimension (2 or 3).

    Returns
    -------
    list of str
        ``t, bx, by`` or ``t, bx, by, bz``.
    """
    return ["t"] + [f"b{a}" for a in _AXES[:dim]]


@dataclass(frozen=True, eq=False)
class BeaconPath:
    """A known beacon path, linearly interpolated between its samples.

    Attributes
    ----------
    times : ndarray, shape (M,)
        Strictly increasing sample times [s], ``M >= 2``, on the trajectory's clock.
    positions : ndarray, shape (M, n)
        Beacon positions [m] at ``times``, in the trajectory's frame; ``n`` is 2 or 3.

    Raises
    ------
    TrajectoryFormatError
        For fewer than 2 samples, a shape other than ``(M,)`` and ``(M, 2|3)``, a non-finite
        value or times that do not strictly increase (the sample is named).
    """

    times: np.ndarray
    positions: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float).reshape(-1)
        b = np.asarray(self.positions, dtype=float)
        if b.ndim != 2 or b.shape[0] != t.size or b.shape[1] not in (2, 3):
            raise TrajectoryFormatError(
                f"beacon path positions must have shape (M, 2) or (M, 3) with M = {t.size} "
                f"samples, got {b.shape}"
            )
        if t.size < 2:
            raise TrajectoryFormatError(
                "a beacon path needs at least 2 samples (a fixed beacon: BeaconPath.fixed)"
            )
        for name, a in (("t", t), ("positions", b)):
            bad = np.argwhere(~np.isfinite(a.reshape(t.size, -1)))
            if bad.size:
                raise TrajectoryFormatError(
                    f"beacon path field {name!r} has a non-finite value at sample {bad[0][0]}"
                )
        dt = np.diff(t)
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0))
            raise TrajectoryFormatError(
                f"beacon path: time must be strictly increasing: t[{k + 1}] = {t[k + 1]} <= "
                f"t[{k}] = {t[k]}"
            )
        for name, a in (("times", t), ("positions", b)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @classmethod
    def fixed(cls, position: Sequence[float], t0: float, t1: float) -> BeaconPath:
        """The constant path of a fixed beacon over ``[t0, t1]``.

        Parameters
        ----------
        position : sequence of float, shape (n,)
            Beacon position [m].
        t0, t1 : float
            First and last time covered [s], ``t0 < t1``.

        Returns
        -------
        BeaconPath
            Two samples at ``t0`` and ``t1``, both at ``position``.
        """
        b = np.asarray(position, float).reshape(1, -1)
        return cls(times=np.array([t0, t1], float), positions=np.repeat(b, 2, axis=0))

    # ------------------------------------------------------------------ sizes
    @property
    def dim(self) -> int:
        """Spatial dimension ``n`` (2 or 3)."""
        return int(self.positions.shape[1])

    @property
    def start(self) -> float:
        """First time covered [s]."""
        return float(self.times[0])

    @property
    def end(self) -> float:
        """Last time covered [s]."""
        return float(self.times[-1])

    @property
    def segment_velocities(self) -> np.ndarray:
        """Constant velocity of each segment ``[t_j, t_{j+1})``, shape ``(M-1, n)`` [m/s]."""
        return np.diff(self.positions, axis=0) / np.diff(self.times)[:, None]

    # ------------------------------------------------------------------ coverage
    def check_covers(
        self, t0: float, t1: float, where: str = "beacon path", error: type[InputError] = InputError
    ) -> None:
        """Refuse an interval ``[t0, t1]`` the path does not cover (nothing is extrapolated).

        Parameters
        ----------
        t0, t1 : float
            First and last time that must be covered [s].
        where : str, optional
            The option or field that gave the path, first in the message
            (``"--beacon-path ship.csv"``, ``"beacon.path"``).
        error : type of InputError, optional
            The error raised (a problem file passes ``ProblemError``).

        Raises
        ------
        InputError
            (or ``error``) ``"<where>: covers t = a..b s but ... needs t = c..d s; ..."``.
        """
        if self.start <= t0 and t1 <= self.end:
            return
        raise error(
            f"{where}: covers t = {self.start:g}..{self.end:g} s but t = {t0:g}..{t1:g} s is "
            "needed; log the beacon over the whole trajectory (nothing is extrapolated) or cut "
            "the trajectory to the logged span"
        )

    def _check_times(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, float)
        if t.size and (np.min(t) < self.start or np.max(t) > self.end):
            self.check_covers(float(np.min(t)), float(np.max(t)))
        return t

    # ------------------------------------------------------------------ the path
    def position(self, t: np.ndarray | float) -> np.ndarray:
        """Linearly interpolated position at times ``t``.

        Parameters
        ----------
        t : float or ndarray, shape (N,)
            Times [s] within ``[start, end]``.

        Returns
        -------
        ndarray, shape (N, n)
            Beacon positions [m] (one row for a scalar ``t``).

        Raises
        ------
        InputError
            A time outside the path.
        """
        t = np.atleast_1d(self._check_times(t))
        return np.column_stack([np.interp(t, self.times, c) for c in self.positions.T])

    def _segment(self, t: np.ndarray) -> np.ndarray:
        """Index of the segment ``[t_j, t_{j+1})`` holding each time (the last one at ``end``)."""
        return np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, self.times.size - 2)

    def velocity(self, t: np.ndarray | float) -> np.ndarray:
        """Velocity of the piecewise-linear path: constant on each segment, right-continuous.

        Parameters
        ----------
        t : float or ndarray, shape (N,)
            Times [s] within ``[start, end]``; at a knot the segment that starts there counts
            (at ``end``, the last segment).

        Returns
        -------
        ndarray, shape (N, n)
            Beacon velocities [m/s].

        Raises
        ------
        InputError
            A time outside the path.
        """
        t = np.atleast_1d(self._check_times(t))
        return self.segment_velocities[self._segment(t)]

    def knot_derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration at the knots of the smooth path the samples are taken from.

        Three-point divided differences on the (possibly uneven) knots: with ``V_j`` the segment
        velocities and ``ΔV_j = V_j - V_{j-1}``, ``b''_j = 2 ΔV_j / (h_{j-1} + h_j)`` and
        ``b'_j = V_{j-1} + h_{j-1} ΔV_j / (h_{j-1} + h_j)`` at the inner knots; at the two ends
        the neighbour's acceleration is carried over (``b'_0 = V_0 - b''_0 h_0 / 2``). Exact
        for a path that is quadratic over each three knots (fixed, constant velocity, constant
        acceleration). A ``ΔV_j`` within :data:`VELOCITY_SNAP` times the round-off bound of its
        two differences is set to zero. Two samples: the segment velocity, no acceleration.

        Returns
        -------
        velocity : ndarray, shape (M, n)
            ``b'`` at the knots [m/s].
        acceleration : ndarray, shape (M, n)
            ``b''`` at the knots [m/s²].
        """
        t, b = self.times, self.positions
        h = np.diff(t)
        V = self.segment_velocities
        M = t.size
        acc = np.zeros_like(b)
        vel = np.empty_like(b)
        if M == 2:
            vel[:] = V[0]
            return vel, acc
        eps = np.finfo(float).eps
        bn = np.linalg.norm(b, axis=1)
        tn = np.abs(t)
        # one rounding of each stored position and time, through the divided difference
        err = eps * (bn[:-1] + bn[1:] + np.linalg.norm(V, axis=1) * (tn[:-1] + tn[1:])) / h
        dV = np.diff(V, axis=0)
        dV[np.linalg.norm(dV, axis=1) <= VELOCITY_SNAP * (err[:-1] + err[1:])] = 0.0
        span = (h[:-1] + h[1:])[:, None]
        acc[1:-1] = 2.0 * dV / span
        acc[0], acc[-1] = acc[1], acc[-2]
        vel[1:-1] = V[:-1] + h[:-1, None] * dV / span
        vel[0] = V[0] - 0.5 * acc[0] * h[0]
        vel[-1] = V[-1] + 0.5 * acc[-1] * h[-1]
        return vel, acc

    def derivative_estimates(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """``b'`` and ``b''`` at times ``t`` of the smooth path the samples are taken from.

        The knot values of :meth:`knot_derivatives`, interpolated linearly (exact on a
        constant-acceleration leg). The LWO rank test reads these (module docstring).

        Parameters
        ----------
        t : float or ndarray, shape (N,)
            Times [s] within ``[start, end]``.

        Returns
        -------
        velocity : ndarray, shape (N, n)
            ``b'`` [m/s].
        acceleration : ndarray, shape (N, n)
            ``b''`` [m/s²].

        Raises
        ------
        InputError
            A time outside the path.
        """
        t = np.atleast_1d(self._check_times(t))
        vel, acc = self.knot_derivatives()

        def interp(a: np.ndarray) -> np.ndarray:
            return np.column_stack([np.interp(t, self.times, c) for c in a.T])

        return interp(vel), interp(acc)

    def knots_within(self, t0: float, t1: float) -> np.ndarray:
        """The knot times strictly inside ``(t0, t1)``, shape ``(K,)`` [s]: where the
        piecewise-linear path turns.

        Parameters
        ----------
        t0, t1 : float
            The open interval [s].

        Returns
        -------
        ndarray, shape (K,)
            Knot times, increasing.
        """
        return self.times[(self.times > t0) & (self.times < t1)].copy()


def read_beacon_path(
    path: str | Path, dim: int | None = None, where: str | None = None
) -> BeaconPath:
    """Read a beacon path CSV: ``t,bx,by`` (2D) or ``t,bx,by,bz`` (3D); extra columns ignored.

    The file is read by the one CSV reader (:func:`obsplan.core.csvtable.read_table`: separator,
    header, comments, the row and column of a bad cell) after its size is checked
    (:func:`obsplan.core.budget.check_file_rows`).

    Parameters
    ----------
    path : str or Path
        The CSV file: times [s] and positions [m] in the trajectory's frame.
    dim : int or None, optional
        The dimension the path must have (the trajectory's); None: 3 if ``bz`` is a column,
        else 2.
    where : str or None, optional
        The option or field that gave the file, first in the messages; default the path.

    Returns
    -------
    BeaconPath
        The path.

    Raises
    ------
    TrajectoryFormatError
        A missing, too large or malformed file (row and column named), a missing column, a
        ``bz`` column for a 2D trajectory or none for a 3D one, fewer than 2 rows, or a time that
        does not strictly increase (its row named).
    """
    where = where or str(path)
    check_file_rows(path, where, error=TrajectoryFormatError)
    table = read_table(path, ",".join(beacon_columns(dim or 2)))
    has_z = "bz" in table.columns
    if dim is None:
        dim = 3 if has_z else 2
    if dim == 2 and has_z:
        raise TrajectoryFormatError(
            f"{where}: column 'bz' makes it a 3D beacon path but the trajectory is 2D; remove "
            "the bz column (2D columns: t,bx,by)"
        )
    cols = beacon_columns(dim)
    hint = " (the trajectory is 3D)" if dim == 3 else ""
    data = table.samples(cols, where, f"the header must contain {','.join(cols)}", hint)
    t = data[:, 0]
    return BeaconPath(times=t, positions=data[:, 1:])


def write_beacon_csv(
    path: str | Path, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray
) -> Path:
    """Write a beacon's path with its velocities: ``t,bx,by[,bz],vbx,vby[,vbz]``, atomically.

    :func:`read_beacon_path` reads it back (the velocity columns are extra columns to it).

    Parameters
    ----------
    path : str or Path
        The CSV file (replaced whole).
    times : ndarray, shape (M,)
        Times [s].
    positions : ndarray, shape (M, n)
        Beacon positions [m].
    velocities : ndarray, shape (M, n)
        Beacon velocities [m/s].

    Returns
    -------
    Path
        ``path``.
    """
    b = np.asarray(positions, float)
    dim = b.shape[1]
    header = beacon_columns(dim) + [f"vb{a}" for a in _AXES[:dim]]
    rows = np.column_stack([np.asarray(times, float), b, np.asarray(velocities, float)])
    return write_table(path, header, rows)


@dataclass(frozen=True, eq=False)
class BeaconVehicle:
    """The vehicle that carries a planned beacon: a surface craft (ASV, ship) with GPS.

    It is a horizontal double integrator ``b'' = a`` at a constant depth: in 3D its ``z`` stays at
    ``start[2]`` (the depth of the transducer it carries). Limits are those a planner must keep
    on the whole path.

    Attributes
    ----------
    start : ndarray, shape (n,)
        Start position [m] in the problem's frame, ``n`` = 2 or 3.
    speed : float
        Bound on the horizontal speed ``|b'|`` [m/s], > 0.
    accel : ndarray, shape (2,)
        Per-axis bound on the horizontal acceleration ``|b''_i|`` [m/s²], each > 0.
    velocity : ndarray, shape (2,)
        Start horizontal velocity [m/s]; zeros for a craft that starts holding station.
    area : ndarray, shape (2, 2) or None
        ``[[x_min, x_max], [y_min, y_max]]`` [m] the craft must stay in, or None (anywhere).
    max_range : float or None
        Maximum distance ``|p - b|`` [m] to the vehicle (the acoustic link), or None.
    min_distance : float
        Minimum *horizontal* distance ``|p_xy - b_xy|`` [m] to the vehicle (collision, the
        vehicle surfacing under the craft); 0 disables it.

    Raises
    ------
    InputError
        For a limit that is not positive and finite, a start velocity above ``speed``, a start
        outside ``area`` or arrays of the wrong shape (the field is named).
    """

    start: np.ndarray
    speed: float
    accel: np.ndarray
    velocity: np.ndarray
    area: np.ndarray | None = None
    max_range: float | None = None
    min_distance: float = 0.0

    def __post_init__(self) -> None:
        start = np.asarray(self.start, float).reshape(-1)
        accel = np.broadcast_to(np.asarray(self.accel, float), (2,)).copy()
        vel = np.asarray(self.velocity, float).reshape(-1)
        if start.size not in (2, 3) or not np.all(np.isfinite(start)):
            raise InputError(f"beacon vehicle start must be 2 or 3 finite values, got {start}")
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"beacon vehicle speed must be > 0 m/s, got {self.speed}")
        if not np.all(np.isfinite(accel) & (accel > 0)):
            raise InputError(f"beacon vehicle accel must be > 0 m/s^2 per axis, got {accel}")
        if vel.shape != (2,) or not np.all(np.isfinite(vel)):
            raise InputError(f"beacon vehicle velocity must be 2 finite values, got {vel}")
        if np.linalg.norm(vel) > self.speed * (1 + 1e-9):
            raise InputError(
                f"beacon vehicle start velocity |{vel.tolist()}| exceeds its speed bound "
                f"{self.speed} m/s"
            )
        area = None
        if self.area is not None:
            area = np.asarray(self.area, float)
            if area.shape != (2, 2) or not np.all(area[:, 0] < area[:, 1]):
                raise InputError(
                    "beacon vehicle area must be [[x_min, x_max], [y_min, y_max]] with min < max"
                )
            if np.any(start[:2] < area[:, 0]) or np.any(start[:2] > area[:, 1]):
                raise InputError(f"beacon vehicle start {start[:2].tolist()} is outside its area")
            area.setflags(write=False)
        if self.max_range is not None and not (self.max_range > 0):
            raise InputError(f"beacon vehicle max_range must be > 0 m, got {self.max_range}")
        if not (np.isfinite(self.min_distance) and self.min_distance >= 0):
            raise InputError(f"beacon vehicle min_distance must be >= 0 m, got {self.min_distance}")
        for name, a in (("start", start), ("accel", accel), ("velocity", vel)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "area", area)

    @property
    def dim(self) -> int:
        """Spatial dimension of the problem the craft serves (2 or 3)."""
        return int(self.start.size)
