"""Trajectories: sampled paths of the double integrator, their CSV form and exact integration.

A :class:`Trajectory` holds times ``t`` (N,), positions ``p`` (N, n), inertial velocities ``v``
(N, n) and accelerations ``u`` (N, n), where ``u[k]`` is held constant on ``[t_k, t_{k+1})`` (the
CSV convention of the README). Generators of the motion classes of Tables 1–3 are in
:mod:`obsplan.trajectory.generators`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from obsplan.core.csvtable import CsvTable, read_table, write_table
from obsplan.core.errors import InputError, TrajectoryFormatError
from obsplan.model.frames import GeodeticOrigin, local_to_geodetic

_AXES = "xyz"
#: Default tolerance of the consistency check: positions within 1 mm, velocities within 1 mm/s.
CONSISTENCY_TOL_POS_M = 1e-3
CONSISTENCY_TOL_VEL_MS = 1e-3


def check_samples(t: np.ndarray, arrays: dict[str, np.ndarray], what: str) -> None:
    """Refuse non-finite values and times that do not strictly increase (trajectories, tracks).

    ``t`` has shape (N,), each array (N, ...); ``what`` starts the messages (``"trajectory"``).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s].
    arrays : dict of str to ndarray, shape (N, ...)
        The other fields by name (positions, velocities...), one row per sample.
    what : str
        What is checked, first word of the messages.

    Raises
    ------
    TrajectoryFormatError
        For the first non-finite value (field and sample named) or a time that does not
        increase.
    """
    for name, a in (("t", t), *arrays.items()):
        bad = np.argwhere(~np.isfinite(a.reshape(a.shape[0], -1) if a.size else a[:, None]))
        if bad.size:
            raise TrajectoryFormatError(
                f"{what} field {name!r} has a non-finite value at sample {bad[0][0]}"
            )
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise TrajectoryFormatError(
            f"{what}: time must be strictly increasing: t[{k + 1}] = {t[k + 1]} <= t[{k}] = {t[k]}"
        )


class InconsistentTrajectoryWarning(UserWarning):
    """The inputs of a trajectory do not reproduce its positions and velocities."""


def csv_columns(dim: int) -> list[str]:
    """Column names of the trajectory CSV for dimension ``dim``.

    Parameters
    ----------
    dim : int
        Spatial dimension (2 or 3).

    Returns
    -------
    list of str
        ``t``, then ``px, py[, pz]``, ``vx, vy[, vz]``, ``ux, uy[, uz]``.
    """
    axes = _AXES[:dim]
    return ["t"] + [f"p{a}" for a in axes] + [f"v{a}" for a in axes] + [f"u{a}" for a in axes]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A sampled trajectory of the double integrator.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Strictly increasing sample times [s].
    p : ndarray, shape (N, n)
        Positions [m] in the inertial frame.
    v : ndarray, shape (N, n)
        Inertial velocities ``p'`` [m/s].
    u : ndarray, shape (N, n)
        Accelerations [m/s²]; ``u[k]`` acts on ``[t_k, t_{k+1})``.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    u: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float).reshape(-1)
        arrays = {}
        for name in ("p", "v", "u"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.ndim != 2 or a.shape[0] != t.size:
                raise TrajectoryFormatError(
                    f"trajectory field {name!r} must have shape (N, n) with N = {t.size} samples, "
                    f"got {a.shape}"
                )
            arrays[name] = a
        n = arrays["p"].shape[1]
        if n not in (2, 3) or arrays["v"].shape[1] != n or arrays["u"].shape[1] != n:
            raise TrajectoryFormatError(
                "trajectory p, v and u must all have 2 columns (2D) or all 3 (3D), got "
                f"{arrays['p'].shape[1]}, {arrays['v'].shape[1]}, {arrays['u'].shape[1]}"
            )
        if t.size < 2:
            raise TrajectoryFormatError("a trajectory needs at least 2 samples")
        check_samples(t, arrays, "trajectory")
        for name, a in (("t", t), *arrays.items()):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    # ---------------------------------------------------------------- basic properties
    @property
    def dim(self) -> int:
        return int(self.p.shape[1])

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    def __len__(self) -> int:
        return self.n_samples

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> np.ndarray:
        """Interval lengths, shape ``(N-1,)`` [s]."""
        return np.diff(self.t)

    def displacement(self) -> np.ndarray:
        """Displacement ``d(t_k, t_0) = p_k - p_0 - v_0 (t_k - t_0)`` (eq. 15), shape (N, n) [m].

        Returns
        -------
        ndarray, shape (N, n)
            The displacement due to the inputs alone at each sample [m].
        """
        return self.p - self.p[0] - np.outer(self.t - self.t[0], self.v[0])

    # ---------------------------------------------------------------- construction
    @classmethod
    def from_inputs(
        cls, t: np.ndarray, p0: np.ndarray, v0: np.ndarray, u: np.ndarray
    ) -> Trajectory:
        """Integrate piecewise-constant inputs exactly.

        Parameters
        ----------
        t : ndarray, shape (N,)
            Sample times [s].
        p0, v0 : ndarray, shape (n,)
            Initial position [m] and velocity [m/s].
        u : ndarray, shape (N, n) or (N-1, n)
            Accelerations [m/s²], ``u[k]`` held on ``[t_k, t_{k+1})``. With ``N-1`` rows the last
            input is repeated so that the CSV has one per sample.

        Returns
        -------
        Trajectory
            The samples of the integrated path.

        Raises
        ------
        TrajectoryFormatError
            If ``u`` has neither ``N`` nor ``N-1`` rows, or the samples are invalid.
        """
        t = np.asarray(t, float).reshape(-1)
        u = np.atleast_2d(np.asarray(u, float))
        p0 = np.asarray(p0, float).reshape(-1)
        v0 = np.asarray(v0, float).reshape(-1)
        if u.shape[0] == t.size - 1:
            u = np.vstack([u, u[-1:]])
        if u.shape[0] != t.size:
            raise TrajectoryFormatError(f"u needs {t.size} or {t.size - 1} rows, got {u.shape[0]}")
        dt = np.diff(t)[:, None]
        dv = u[:-1] * dt
        v = np.vstack([v0, v0 + np.cumsum(dv, axis=0)])
        dp = v[:-1] * dt + 0.5 * u[:-1] * dt**2
        p = np.vstack([p0, p0 + np.cumsum(dp, axis=0)])
        return cls(t=t, p=p, v=v, u=u)

    def consistency_error(self) -> tuple[float, float]:
        """Largest one-step mismatch when the inputs are integrated from each sample to the next.

        Returns
        -------
        (pos_err_m, vel_err_ms)
            Max over samples of ``|p_{k+1} - (p_k + v_k dt + ½ u_k dt²)|`` [m] and
            ``|v_{k+1} - (v_k + u_k dt)|`` [m/s].
        """
        dt = self.dt[:, None]
        p_pred = self.p[:-1] + self.v[:-1] * dt + 0.5 * self.u[:-1] * dt**2
        v_pred = self.v[:-1] + self.u[:-1] * dt
        pe = float(np.max(np.linalg.norm(self.p[1:] - p_pred, axis=1)))
        ve = float(np.max(np.linalg.norm(self.v[1:] - v_pred, axis=1)))
        return pe, ve

    def check_consistency(
        self,
        tol_pos: float = CONSISTENCY_TOL_POS_M,
        tol_vel: float = CONSISTENCY_TOL_VEL_MS,
        source: str = "trajectory",
    ) -> bool:
        """Warn (``InconsistentTrajectoryWarning``) if the inputs do not reproduce the samples.

        The augmented Gramian is, in exact terms, a function of the inputs only, while it is
        computed from the sampled ``p`` and ``v``; the LWO test uses ``p``, ``v`` and ``u``. Both
        assume that the samples and the inputs agree. Returns True when consistent.

        Parameters
        ----------
        tol_pos : float, optional
            Largest one-step position mismatch accepted [m] (:meth:`consistency_error`).
        tol_vel : float, optional
            Largest one-step velocity mismatch accepted [m/s].
        source : str, optional
            What the trajectory is (a file name), first word of the warning.

        Returns
        -------
        bool
            True if both mismatches are within their tolerances; False after the warning.

        Warns
        -----
        InconsistentTrajectoryWarning
            If a mismatch is beyond its tolerance.
        """
        pe, ve = self.consistency_error()
        if pe > tol_pos or ve > tol_vel:
            warnings.warn(
                f"{source}: the inputs u do not reproduce the samples: one-step mismatch up to "
                f"{pe:.3g} m in position and {ve:.3g} m/s in velocity (tolerance {tol_pos:g} m, "
                f"{tol_vel:g} m/s); observability verdicts assume that they agree",
                InconsistentTrajectoryWarning,
                stacklevel=2,
            )
            return False
        return True

    # ---------------------------------------------------------------- transformations
    def scaled(self, length_m: float, time_s: float) -> Trajectory:
        """The same trajectory in units of ``length_m`` and ``time_s`` (nondimensionalised).

        Parameters
        ----------
        length_m : float
            Unit of length [m].
        time_s : float
            Unit of time [s].

        Returns
        -------
        Trajectory
            Times, positions, velocities and inputs divided by ``T``, ``L``, ``L/T`` and
            ``L/T²``.
        """
        L, T = float(length_m), float(time_s)
        return Trajectory(t=self.t / T, p=self.p / L, v=self.v * T / L, u=self.u * T**2 / L)

    def translated(self, offset: np.ndarray) -> Trajectory:
        """Positions shifted by ``offset`` [m] (velocities and inputs unchanged).

        Parameters
        ----------
        offset : ndarray, shape (n,)
            Shift added to every position [m].

        Returns
        -------
        Trajectory
            The shifted trajectory.
        """
        return Trajectory(t=self.t, p=self.p + np.asarray(offset, float), v=self.v, u=self.u)

    def rotated(self, R: np.ndarray, about: np.ndarray | None = None) -> Trajectory:
        """Rotate positions about ``about`` (default origin), velocities and inputs by ``R``.

        Parameters
        ----------
        R : ndarray, shape (n, n)
            Rotation matrix.
        about : ndarray, shape (n,), optional
            Centre of the rotation [m]; None: the origin.

        Returns
        -------
        Trajectory
            The rotated trajectory (same times).
        """
        R = np.asarray(R, float)
        c = np.zeros(self.dim) if about is None else np.asarray(about, float)
        return Trajectory(t=self.t, p=(self.p - c) @ R.T + c, v=self.v @ R.T, u=self.u @ R.T)

    def window(self, start: int, stop: int | None = None) -> Trajectory:
        """Samples ``start:stop`` as a new trajectory (times keep their values).

        Parameters
        ----------
        start : int
            First sample index.
        stop : int or None, optional
            Index after the last sample; None: to the end.

        Returns
        -------
        Trajectory
            The window (at least 2 samples, else :class:`TrajectoryFormatError`).
        """
        s = slice(start, stop)
        return Trajectory(t=self.t[s], p=self.p[s], v=self.v[s], u=self.u[s])

    def then(self, other: Trajectory) -> Trajectory:
        """Concatenate ``other`` after this one; ``other``'s first sample replaces our last.

        ``other`` is shifted in time (and must start where this one ends, within 1e-6 m) so that
        the result is one continuous trajectory.

        Parameters
        ----------
        other : Trajectory
            The trajectory that follows, of the same dimension.

        Returns
        -------
        Trajectory
            The two joined, with this one's times.

        Raises
        ------
        TrajectoryFormatError
            If the dimensions differ or ``other`` does not start where this one ends.
        """
        if other.dim != self.dim:
            raise TrajectoryFormatError("cannot concatenate a 2D and a 3D trajectory")
        gap = float(np.linalg.norm(other.p[0] - self.p[-1]))
        if gap > 1e-6 * max(1.0, float(np.abs(self.p).max())):
            raise TrajectoryFormatError(f"trajectories do not join: gap of {gap:.3g} m")
        t2 = other.t - other.t[0] + self.t[-1]
        u = np.vstack([self.u[:-1], other.u])
        return Trajectory(
            t=np.concatenate([self.t[:-1], t2]),
            p=np.vstack([self.p[:-1], other.p]),
            v=np.vstack([self.v[:-1], other.v]),
            u=u,
        )

    def to_array(self) -> np.ndarray:
        """Rows ``t, p, v, u`` as one array, shape (N, 1 + 3n).

        Returns
        -------
        ndarray, shape (N, 1 + 3n)
            Columns in the order of :func:`csv_columns`, SI units.
        """
        return np.column_stack([self.t, self.p, self.v, self.u])


# -------------------------------------------------------------------- CSV
#: Header of the 2D trajectory CSV, shown in hints.
_EXAMPLE_HEADER = ",".join(csv_columns(2))
#: Relative distance (in grid steps) within which every time must lie of a decimal grid
#: ``t0 + k h`` for the times to be written on that grid.
_GRID_TOL = 1e-6


def grid_times(t: np.ndarray) -> np.ndarray:
    """Times with the floating-point noise of grid arithmetic removed (used by ``write_csv``).

    If every time lies within ``1e-6`` steps of a decimal grid ``t0 + k h`` (``h`` the shortest
    interval to 10 significant digits, ``t0`` the first time to 12), the times are that grid,
    computed in exact decimal arithmetic: ``56.99999999999999`` becomes ``57.0``, and a grid
    with longer holds (multiples of ``h``) is kept. Times on no such grid are returned unchanged.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times [s].

    Returns
    -------
    ndarray, shape (N,)
        The times on their decimal grid, or ``t`` itself [s].
    """
    from decimal import Decimal

    t = np.asarray(t, float)
    if t.size < 2 or not np.all(np.isfinite(t)):
        return t
    h_dec = Decimal(f"{float(np.min(np.diff(t))):.10g}")
    t0_dec = Decimal(f"{float(t[0]):.12g}")
    h, t0 = float(h_dec), float(t0_dec)
    if not h > 0:
        return t
    k = np.rint((t - t0) / h)
    if np.max(np.abs(t - (t0 + k * h))) > _GRID_TOL * h or np.any(np.diff(k) < 1):
        return t
    return np.array([float(t0_dec + int(ki) * h_dec) for ki in k])


def write_csv(traj: Trajectory, path: str | Path, overwrite: bool = True) -> Path:
    """Write the trajectory CSV (one header row, SI units), atomically.

    Positions, velocities and inputs are written with ``repr`` (exact round trip); times are
    written on their grid (:func:`grid_times`: ``57.0``, not ``56.99999999999999``), other
    times exactly. The file is
    written to a temporary name and renamed, so an interruption never leaves half a file.

    Parameters
    ----------
    traj : Trajectory
        The trajectory to write.
    path : str or Path
        The CSV file.
    overwrite : bool, optional
        Replace an existing file; if False an existing file is an error.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is False.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from obsplan import write_csv
    >>> from obsplan.trajectory import generators
    >>> line = generators.straight((0.0, 0.0), (1.0, 0.0), 10.0, duration=5.0).sample(1.0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = write_csv(line, Path(tmp) / "line.csv")
    ...     path.read_text().splitlines()[0]
    't,px,py,vx,vy,ux,uy'
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    data = traj.to_array().copy()
    data[:, 0] = grid_times(traj.t)
    return write_table(path, csv_columns(traj.dim), data)


def write_geodetic_samples(traj: Trajectory, origin: GeodeticOrigin, path: str | Path) -> Path:
    """Write the samples as ``t,latitude,longitude[,depth],speed`` about ``origin``, atomically.

    Parameters
    ----------
    traj
        Positions in the local north-east-down frame about ``origin`` [m].
    origin
        The frame's origin (:class:`~obsplan.model.frames.GeodeticOrigin`).
    path
        The CSV file written (``plan-geodetic.csv`` of ``obsplan plan``).

    Returns
    -------
    Path
        ``path``: times [s] on their grid, latitude and longitude [deg], depth [m] (3D),
        speed ``|v|`` [m/s].
    """
    lat, lon, depth = local_to_geodetic(traj.p, origin, "plan")
    cols = ["t", "latitude", "longitude", "depth"][: 1 + traj.dim] + ["speed"]
    rows = np.column_stack(
        [grid_times(traj.t), *[lat, lon, depth][: traj.dim], np.linalg.norm(traj.v, axis=1)]
    )
    return write_table(path, cols, rows)


def read_csv(path: str | Path, check: bool = True) -> Trajectory:
    """Read a trajectory CSV; extra columns are ignored.

    The separator may be a comma, a semicolon or a tab (found from the header line).

    Parameters
    ----------
    path : str or Path
        The CSV file: columns ``t, px, py[, pz], vx, vy[, vz], ux, uy[, uz]`` in SI units.
    check : bool, optional
        Warn (:class:`InconsistentTrajectoryWarning`) if the inputs do not reproduce the samples
        (:meth:`Trajectory.check_consistency`).

    Returns
    -------
    Trajectory
        The trajectory.

    Raises
    ------
    TrajectoryFormatError
        Naming the row (the line number in the file, header is row 1 when it is the first line)
        or column at fault, a column that appears twice, or a missing header row.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from obsplan import read_csv, write_csv
    >>> from obsplan.trajectory import generators
    >>> traj = generators.circle(50.0, 1.0, 60.0).sample(1.0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     back = read_csv(write_csv(traj, Path(tmp) / "circle.csv"))
    >>> back.n_samples, bool(np.allclose(back.p, traj.p))
    (61, True)
    """
    return trajectory_from_table(read_table(path, _EXAMPLE_HEADER), check=check)


def trajectory_dim(columns: tuple[str, ...], path: object) -> int:
    """2 or 3 from the header (``pz`` present); mixed 2D/3D columns are an error.

    Parameters
    ----------
    columns : tuple of str
        Header names, lower-case.
    path : object
        The file, named in the message.

    Returns
    -------
    int
        3 if ``pz``, ``vz`` and ``uz`` are all there, else 2.

    Raises
    ------
    TrajectoryFormatError
        If some but not all of ``pz``, ``vz``, ``uz`` are there.
    """
    has_z = [c in columns for c in ("pz", "vz", "uz")]
    if any(has_z) and not all(has_z):
        missing = [c for c, h in zip(("pz", "vz", "uz"), has_z, strict=True) if not h]
        raise TrajectoryFormatError(
            f"{path}: mixed 2D/3D columns: has some of pz,vz,uz but not {', '.join(missing)}; "
            "a 3D file needs all of t,px,py,pz,vx,vy,vz,ux,uy,uz"
        )
    return 3 if all(has_z) else 2


def trajectory_from_table(table: CsvTable, check: bool = True) -> Trajectory:
    """A :class:`Trajectory` from a :class:`~obsplan.core.csvtable.CsvTable` (like read_csv).

    Parameters
    ----------
    table : CsvTable
        The CSV read as text cells.
    check : bool, optional
        Warn if the inputs do not reproduce the samples
        (:meth:`Trajectory.check_consistency`).

    Returns
    -------
    Trajectory
        The trajectory.

    Raises
    ------
    TrajectoryFormatError
        For missing columns, fewer than 2 rows, a bad cell or times that do not increase
        (naming the row).
    """
    path = table.path
    dim = trajectory_dim(table.columns, path)
    cols = csv_columns(dim)
    data = table.samples(cols, str(path), f"the header must contain {','.join(cols)}")
    t = data[:, 0]
    n = dim
    traj = Trajectory(
        t=t, p=data[:, 1 : 1 + n], v=data[:, 1 + n : 1 + 2 * n], u=data[:, 1 + 2 * n :]
    )
    if check:
        traj.check_consistency(source=str(path))
    return traj


def resample(traj: Trajectory, dt: float, name: str = "validation.dt") -> Trajectory:
    """The same path sampled every ``dt`` [s] (exact for piecewise-constant inputs).

    Each interval of ``traj`` must be an integer multiple of ``dt``; ``name`` is how the error
    message calls ``dt`` (the problem field or the command-line option).

    Parameters
    ----------
    traj : Trajectory
        The path, with piecewise-constant inputs.
    dt : float
        New sampling interval [s].
    name : str, optional
        How the message calls ``dt``.

    Returns
    -------
    Trajectory
        The path integrated exactly from the first sample on the finer grid.

    Raises
    ------
    InputError
        If an interval is not a multiple of ``dt``.
    """
    steps = traj.dt / dt
    k = np.rint(steps).astype(int)
    if np.any(np.abs(steps - k) > 1e-6 * np.maximum(steps, 1.0)) or np.any(k < 1):
        raise InputError(
            f"{name} = {dt:g} s must divide every interval of the path "
            f"(intervals from {traj.dt.min():g} to {traj.dt.max():g} s)"
        )
    u = np.repeat(traj.u[:-1], k, axis=0)
    t = traj.t[0] + np.concatenate([[0.0], np.cumsum(np.repeat(traj.dt / k, k))])
    t[-1] = traj.t[-1]
    return Trajectory.from_inputs(t, traj.p[0], traj.v[0], u)


def position_at(traj: Trajectory, times: np.ndarray) -> np.ndarray:
    """Exact positions of the piecewise-quadratic path at ``times`` [s], shape (len, n).

    Parameters
    ----------
    traj : Trajectory
        The path; ``u[k]`` is held on ``[t_k, t_{k+1})`` and the last hold extends beyond the end.
    times : ndarray, shape (M,)
        Times [s].

    Returns
    -------
    ndarray, shape (M, n)
        Positions [m].
    """
    times = np.asarray(times, float)
    k = np.clip(np.searchsorted(traj.t, times, side="right") - 1, 0, traj.t.size - 1)
    tau = (times - traj.t[k])[:, None]
    return traj.p[k] + traj.v[k] * tau + 0.5 * traj.u[k] * tau**2
