"""Logged tracks (positions, optional velocities) and the fit of the double integrator's inputs.

A log never has the accelerations ``u`` of the trajectory CSV. :func:`fit_track` finds the
piecewise-constant accelerations (held between consecutive nodes: the sample times, plus nodes
inserted in gaps, or a uniform grid with ``grid``) by **regularised least squares**, per axis:

    minimise   Σ_i (p(t_i) − y_i)² / σ_p²  [+ Σ_i (p'(t_i) − w_i)² / σ_v²]
             + Σ_c (u_c − u_{c−1})² / (q Δ_c)

over the start position and velocity and the inputs ``u_c``, where ``p`` is the exact
double-integrator path of those inputs (eqs. 1–2), ``y``/``w`` the logged positions/velocities,
``Δ_c`` the time between the centres of the holds before and after node ``c``, and the
regulariser penalises changes of acceleration (a discrete jerk penalty: smooth manoeuvres are not
biased towards zero acceleration, unlike a penalty on ``u`` itself). Its weight is the ratio
``σ_p² / q`` of the position noise variance to the intensity ``q`` [m²/s⁵] of a random-walk
acceleration.

**How the weight is chosen.** The least-squares problem is the maximum a posteriori estimate of
the linear Gaussian state-space model with state ``(p, v, u)``, ``u`` a random walk of intensity
``q``, and white position noise ``σ_p``; the fit is computed exactly by a Kalman filter and a
Rauch–Tung–Striebel smoother (O(N), stable, irregular times and gaps for free; the smoothed means
obey the dynamics exactly because the model's noise enters ``u`` only). ``q`` and ``σ_p`` are
chosen per axis by **maximising the marginal likelihood** of the data (empirical Bayes, the
prediction-error decomposition of the filter; the first three scalar innovations, which only fix
the diffuse initial state, are left out), on a log grid of 21 × 13 values (``q`` 1e-16 to 1e4
m²/s⁵, ``σ_p`` 1e-4 to 1e2 m) refined once around the best (steps of 1/4 decade in ``q`` and 1/16
of a decade in ``σ_p``). Give ``position_std`` when the noise is known; it then stays fixed.

The result reports the position residual (RMS and max per axis), the chosen ``σ_p`` and ``q``,
and the posterior standard deviation of the fitted accelerations: the error to expect of ``u``.

Readers: :func:`read_track_csv` (``t,px,py[,pz]`` and optional ``vx,vy[,vz]``), and as optional
extras :func:`read_track_rosbag` (``rosbags``: ``nav_msgs/Odometry`` or
``geometry_msgs/PoseStamped``, ROS 1 ``.bag`` or ROS 2 folders) and :func:`read_track_mavlink`
(``pymavlink``: ``LOCAL_POSITION_NED`` or ``GLOBAL_POSITION_INT`` from a ``.tlog``).
Frames: positions are in the package's local frame, north-east-down (``z`` is depth, as in the
problem files' ``limits.depth``); see :mod:`obsplan.model.frames`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from obsplan.core.csvtable import COLUMN_LIMITS, CsvTable, read_table
from obsplan.core.errors import InputError, TrajectoryFormatError
from obsplan.core.textfiles import check_magnitude, check_regular_file
from obsplan.estimation.filters import linear
from obsplan.model.frames import first_point_origin, geodetic_to_local
from obsplan.trajectory.sampled import Trajectory, check_samples, csv_columns, trajectory_from_table

#: Fewest samples a fit accepts (three fix the quadratic of one hold; one more leaves a residual).
MIN_SAMPLES = 4
#: Default largest gap, in median sample intervals, that the fit bridges.
MAX_GAP_INTERVALS = 30.0
#: Gaps longer than this many median intervals get extra nodes (the input may change inside).
FILL_GAP_INTERVALS = 3.0
#: Largest number of nodes (samples + inserted nodes) a fit accepts: about 10 min of work.
MAX_NODES = 2_000_000
#: Least fraction of a MAVLink log's bytes (and of its expected samples) that must decode.
MIN_READABLE_FRACTION = 0.9
#: Default standard deviation of logged velocities [m/s] when a log has them.
DEFAULT_VELOCITY_STD = 0.05

_Q_GRID = 10.0 ** np.arange(-16.0, 4.5, 1.0)  # m²/s⁵
_S_GRID = 10.0 ** np.arange(-4.0, 2.25, 0.5)  # m
_DIFFUSE = 3  # scalar innovations that only fix the diffuse initial state (p, v, u)


class TrackFitError(InputError):
    """A track that cannot be fitted (too few samples, a huge gap, unusable values)."""


@dataclass(frozen=True, eq=False)
class Track:
    """A logged track in the local frame.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Strictly increasing times [s].
    p : ndarray, shape (N, n)
        Positions [m], n = 2 or 3 (x north, y east, z down).
    v : ndarray, shape (N, n) or None
        Inertial velocities [m/s] when the log has them.
    source : str
        Where the track came from (file, topic or message), for messages.
    origin : GeodeticOrigin or None
        The geodetic origin of the local frame when positions were converted from latitude and
        longitude.
    notes : tuple of str
        What the reader had to drop or assume (e.g. the bytes of a damaged log), for the user.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray | None = None
    source: str = "track"
    origin: Any = None
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        t = np.asarray(self.t, float).reshape(-1)
        p = np.asarray(self.p, float)
        if t.size == 0:
            raise TrajectoryFormatError(f"{self.source}: the track has no samples")
        if p.ndim != 2 or p.shape[0] != t.size or p.shape[1] not in (2, 3):
            raise TrajectoryFormatError(
                f"{self.source}: positions must have shape (N, 2) or (N, 3) with N = {t.size} "
                f"samples, got {p.shape}"
            )
        arrays = {"t": t, "p": p}
        if self.v is not None:
            v = np.asarray(self.v, float)
            if v.shape != p.shape:
                raise TrajectoryFormatError(
                    f"{self.source}: velocities must have the shape of the positions {p.shape}, "
                    f"got {v.shape}"
                )
            arrays["v"] = v
        check_samples(t, {k: a for k, a in arrays.items() if k != "t"}, f"{self.source}: track")
        for name, a in arrays.items():
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def dim(self) -> int:
        return int(self.p.shape[1])

    @property
    def n_samples(self) -> int:
        return int(self.t.size)


@dataclass(frozen=True, eq=False)
class TrackFit:
    """The fitted trajectory and how well it fits.

    Attributes
    ----------
    trajectory : Trajectory
        Exact double-integrator trajectory (``from_inputs``) on the output nodes.
    residual_rms, residual_max : tuple of float
        Per axis RMS and largest ``|p(t_i) - y_i|`` over the samples [m].
    position_std : tuple of float
        Per axis position noise σ_p used (estimated unless given) [m].
    accel_intensity : tuple of float
        Per axis random-walk intensity q of the acceleration [m²/s⁵]; the regulariser weight
        is ``σ_p² / q``.
    accel_std : tuple of float
        Per axis median posterior standard deviation of the fitted accelerations [m/s²].
    samples, nodes, inserted : int
        Samples fitted, nodes of the fit, nodes inserted in gaps.
    estimated : bool
        True when σ_p was estimated (not given).
    at_search_edge : tuple of bool
        Per axis: the chosen q or σ_p is at the end of its search range (the data may not fit
        the model: check units and gaps).
    source : str
    """

    trajectory: Trajectory
    residual_rms: tuple[float, ...]
    residual_max: tuple[float, ...]
    position_std: tuple[float, ...]
    accel_intensity: tuple[float, ...]
    accel_std: tuple[float, ...]
    samples: int
    nodes: int
    inserted: int
    estimated: bool
    at_search_edge: tuple[bool, ...]
    source: str = "track"
    origin: Any = field(default=None)

    def to_dict(self) -> dict:
        """JSON-friendly summary (SI units).

        Returns
        -------
        dict
            Counts, per-axis residuals [m], noise σ_p [m], intensities q [m²/s⁵], acceleration
            standard deviations [m/s²], search-edge flags and, if any, the geodetic origin.
        """
        out = {
            "source": self.source,
            "samples": self.samples,
            "nodes": self.nodes,
            "inserted_gap_nodes": self.inserted,
            "dim": self.trajectory.dim,
            "residual_rms_m": list(self.residual_rms),
            "residual_max_m": list(self.residual_max),
            "position_std_m": list(self.position_std),
            "position_std_estimated": self.estimated,
            "accel_intensity_m2_s5": list(self.accel_intensity),
            "accel_std_ms2": list(self.accel_std),
            "at_search_edge": list(self.at_search_edge),
        }
        if self.origin is not None:
            out["origin"] = self.origin.to_dict()
        return out

    def summary(self) -> str:
        """One paragraph for a terminal.

        Returns
        -------
        str
            Several lines: samples and nodes, residuals, noise, accelerations' uncertainty, and a
            warning if an estimate is at the edge of its search range.
        """
        f = ", ".join
        lines = [
            f"{self.source}: {self.samples} samples, {self.trajectory.dim}D, fitted on "
            f"{self.nodes} nodes"
            + (f" ({self.inserted} inserted in gaps)" if self.inserted else ""),
            "  position residual RMS "
            + f(f"{r:.3g}" for r in self.residual_rms)
            + " m (max "
            + f(f"{r:.3g}" for r in self.residual_max)
            + " m)",
            "  position noise σ_p "
            + f(f"{s:.3g}" for s in self.position_std)
            + (" m (estimated)" if self.estimated else " m (given)"),
            "  fitted accelerations: posterior std "
            + f(f"{s:.3g}" for s in self.accel_std)
            + " m/s² (random-walk intensity q "
            + f(f"{q:.3g}" for q in self.accel_intensity)
            + " m²/s⁵)",
        ]
        if any(self.at_search_edge):
            axes = f("xyz"[i] for i, e in enumerate(self.at_search_edge) if e)
            lines.append(
                f"  warning: axis {axes}: the noise or smoothness estimate is at the end of its "
                "search range; check the units of the log, its gaps, or give --position-std"
            )
        return "\n".join(lines)


# ---------------------------------------------------------------------------------- readers
def _track_columns(columns: tuple[str, ...], path: object) -> tuple[list[str], list[str] | None]:
    has_pz = "pz" in columns
    pos = ["px", "py", "pz"] if has_pz else ["px", "py"]
    missing = [c for c in ["t", *pos] if c not in columns]
    if missing:
        raise TrajectoryFormatError(
            f"{path}: missing column(s) {', '.join(missing)}; a track needs the header "
            "t,px,py[,pz] (optional vx,vy[,vz]; positions in m, north-east-down)"
        )
    vel = ["vx", "vy", "vz"][: len(pos)]
    present = [c in columns for c in vel]
    if any(present) and not all(present):
        raise TrajectoryFormatError(
            f"{path}: has some of {','.join(vel)} but not all; give every velocity column or none"
        )
    return pos, (vel if all(present) else None)


def _waypoint_track(table: CsvTable, origin: Any) -> Track | None:
    """obsplan's own waypoint CSV (``t,x,y[,z],speed,...`` or ``t,latitude,longitude[,depth],
    ...``, written by ``obsplan export``) as a track; None for other tables."""
    cols = table.columns
    if "px" in cols or "t" not in cols:
        return None
    if table.has("x", "y"):
        pos = ["x", "y", "z"] if "z" in cols else ["x", "y"]
        data = table.numbers(["t", *pos])
        return Track(t=data[:, 0], p=data[:, 1:], source=str(table.path))
    if table.has("latitude", "longitude"):
        names = ["t", "latitude", "longitude", *(["depth"] if "depth" in cols else [])]
        data = table.numbers(names)
        first = origin is None
        where = f"{table.path}" + (" (origin: the first waypoint)" if first else "")
        if first:  # the file's own latitudes are checked first: a bad one is the file's
            origin = first_point_origin(data[:, 1], data[:, 2], f"{table.path}")
        depth = data[:, 3] if data.shape[1] == 4 else np.zeros(data.shape[0])
        p = geodetic_to_local(
            data[:, 1], data[:, 2], depth, origin, dim=data.shape[1] - 1, where=where
        )
        return Track(t=data[:, 0], p=p, source=str(table.path), origin=origin)
    return None


def track_from_table(table: CsvTable, origin: Any = None) -> Track:
    """A :class:`Track` from a :class:`~obsplan.core.csvtable.CsvTable` with ``t,px,py[,pz]`` (or a
    waypoint CSV of ``obsplan export``: ``t,x,y[,z]`` or ``t,latitude,longitude[,depth]``, the
    latter about ``origin``, default the first waypoint).

    Parameters
    ----------
    table : CsvTable
        The CSV read as text cells.
    origin : GeodeticOrigin or None, optional
        Origin of the local frame for geodetic waypoints; None: the first waypoint.

    Returns
    -------
    Track
        Times [s] and local NED positions [m] (and velocities [m/s] if the table has them).

    Raises
    ------
    TrajectoryFormatError
        For missing columns, a partial set of velocity columns, a bad cell or times that do not
        increase (naming the row).
    """
    path = table.path
    wp = _waypoint_track(table, origin)
    if wp is not None:
        _check_increasing(wp.t, table)
        return wp
    pos, vel = _track_columns(table.columns, path)
    data = table.numbers(["t", *pos, *(vel or [])])
    t = data[:, 0]
    _check_increasing(t, table)
    n = len(pos)
    v = data[:, 1 + n :] if vel else None
    return Track(t=t, p=data[:, 1 : 1 + n], v=v, source=str(path))


def _check_increasing(t: np.ndarray, table: CsvTable) -> None:
    table.check_increasing(t, str(table.path), "sort the log or drop duplicated samples")


def read_track_csv(path: str | Path, origin: Any = None) -> Track:
    """Read a track CSV: ``t,px,py[,pz]`` [s, m] and optional ``vx,vy[,vz]`` [m/s].

    Separators: comma, semicolon or tab; extra columns are ignored. A full trajectory CSV (with
    ``ux..``) is also a track (its inputs are ignored), and so is a waypoint CSV written by
    ``obsplan export`` (``t,x,y[,z],...``, or ``t,latitude,longitude[,depth],...`` converted about
    ``origin``, a :class:`~obsplan.model.frames.GeodeticOrigin`; default: the first waypoint).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    origin : GeodeticOrigin or None, optional
        Origin of the local frame for a geodetic waypoint CSV; None: the first waypoint.

    Returns
    -------
    Track
        The logged track in the local NED frame.

    Raises
    ------
    TrajectoryFormatError
        For a file that is not such a CSV (:func:`track_from_table`).
    """
    return track_from_table(read_table(path, "t,px,py[,pz]"), origin)


def _one_line(exc: BaseException, limit: int = 240) -> str:
    """A library's exception as one line (YAML and bag readers write several)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _missing_extra(package: str, extra: str) -> InputError:
    return InputError(
        f"reading this log needs the optional package {package}: pip install 'obsplan[{extra}]'"
    )


def _enu_to_ned(p: np.ndarray) -> np.ndarray:
    # ENU (x east, y north, z up; ROS REP-103) -> NED (x north, y east, z down)
    out = p[:, [1, 0, 2]].copy()
    out[:, 2] *= -1.0
    return out


ROS_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped")


def read_track_rosbag(path: str | Path, topic: str | None = None, frame: str = "enu") -> Track:
    """Positions of a ``nav_msgs/Odometry`` or ``geometry_msgs/PoseStamped`` topic of a bag.

    Times are the messages' header stamps (the log time when a stamp is zero). The twist of an
    Odometry message is in the body frame and is not used.

    Parameters
    ----------
    path : str or Path
        ROS 1 ``.bag`` file or ROS 2 bag folder (sqlite3 or mcap), read with ``rosbags``.
    topic : str or None, optional
        Topic name; default: the only topic of a supported type.
    frame : {"enu", "ned"}, optional
        ``"enu"`` (ROS convention, REP-103: converted to north-east-down) or ``"ned"`` (kept).

    Returns
    -------
    Track
        Times [s] and positions [m] in the local NED frame; no velocities.

    Raises
    ------
    InputError
        If ``rosbags`` is not installed or ``frame`` is unknown.
    TrajectoryFormatError
        For a bag that cannot be read, no (or several) position topics, or no messages.
    """
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise _missing_extra("rosbags", "ros") from None
    if frame not in ("enu", "ned"):
        raise InputError(f"frame must be 'enu' or 'ned', got {frame!r}")
    path = Path(path)
    if not path.is_dir():  # a ROS 2 bag is a folder; a ROS 1 bag or an .mcap a regular file
        check_regular_file(path, "a ROS bag (file or folder)", error=TrajectoryFormatError)
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:  # rosbags raises its own error types for every malformed bag
        raise TrajectoryFormatError(f"{path}: not a readable ROS bag: {_one_line(exc)}") from None
    try:
        conns = [c for c in reader.connections if _ros_type(c.msgtype) in ROS_TYPES]
        if topic is not None:
            conns = [c for c in conns if c.topic == topic]
        topics = sorted({c.topic for c in conns})
        if not topics:
            have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise TrajectoryFormatError(
                f"{path}: no {'topic ' + repr(topic) + ' of ' if topic else ''}type "
                f"{' or '.join(ROS_TYPES)}; the bag has: {', '.join(have) or 'no topics'}"
            )
        if len(topics) > 1:
            raise TrajectoryFormatError(
                f"{path}: several position topics ({', '.join(topics)}); choose one with --topic"
            )
        t, p = [], []
        for conn, stamp_ns, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            pose = msg.pose.pose if _ros_type(conn.msgtype) == ROS_TYPES[0] else msg.pose
            st = msg.header.stamp
            ts = st.sec + 1e-9 * st.nanosec
            t.append(ts if ts > 0 else 1e-9 * stamp_ns)
            pos = pose.position
            p.append((pos.x, pos.y, pos.z))
    except TrajectoryFormatError:
        raise
    except Exception as exc:
        raise TrajectoryFormatError(
            f"{path}: cannot read the bag's messages: {_one_line(exc)}"
        ) from None
    finally:
        reader.close()
    if not t:
        raise TrajectoryFormatError(f"{path}: topic {topics[0]} has no messages")
    pa = np.asarray(p, float)
    if frame == "enu":
        pa = _enu_to_ned(pa)
    return Track(t=np.asarray(t), p=pa, source=f"{path}:{topics[0]}")


def _ros_type(msgtype: str) -> str:
    # ROS 1 bags name types "nav_msgs/Odometry"; rosbags normalises most to ".../msg/..."
    return msgtype if "/msg/" in msgtype else msgtype.replace("/", "/msg/", 1)


MAVLINK_MESSAGES = ("LOCAL_POSITION_NED", "GLOBAL_POSITION_INT")


def read_track_mavlink(path: str | Path, message: str | None = None, origin: Any = None) -> Track:
    """Positions (and velocities) of a MAVLink telemetry log (``.tlog``), with ``pymavlink``.

    Times are ``time_boot_ms`` [s]; repeated messages with the same time are dropped (a
    telemetry link sends some twice).

    Parameters
    ----------
    path : str or Path
        The telemetry log.
    message : {"LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"} or None, optional
        ``"LOCAL_POSITION_NED"`` (x, y, z [m] and vx, vy, vz [m/s], north-east-down) or
        ``"GLOBAL_POSITION_INT"`` (lat, lon [1e-7 deg], relative_alt [mm]: depth =
        −relative_alt, as ArduSub reports it; vx, vy, vz [cm/s]); default: the first present,
        in that order.
    origin : GeodeticOrigin or None, optional
        :class:`~obsplan.model.frames.GeodeticOrigin` of the local frame for
        ``GLOBAL_POSITION_INT``; default: the first fix, at the surface.

    Returns
    -------
    Track
        Times [s], positions [m] and velocities [m/s] in the local NED frame; ``notes`` says
        what a damaged log lost.

    Raises
    ------
    InputError
        If ``pymavlink`` is not installed or ``message`` is unknown.
    TrajectoryFormatError
        For a log that cannot be read, has no such messages, whose clock goes back (a reboot),
        or of which less than :data:`MIN_READABLE_FRACTION` decodes.
    """
    try:
        from pymavlink import mavutil
    except ImportError:
        raise _missing_extra("pymavlink", "mavlink") from None
    path = check_regular_file(path, "a MAVLink telemetry log (.tlog)", error=TrajectoryFormatError)
    if message is not None and message not in MAVLINK_MESSAGES:
        raise InputError(f"message must be one of {', '.join(MAVLINK_MESSAGES)}, got {message!r}")
    rows: dict[str, list[tuple[float, ...]]] = {m: [] for m in MAVLINK_MESSAGES}
    mlog = None
    readable = 0  # bytes of the log in messages that decoded (with their time stamps)
    try:
        mlog = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
        stamp = 0 if getattr(mlog, "notimestamps", False) else 8
        while True:
            m = mlog.recv_msg()
            if m is None:
                break
            name = m.get_type()
            if name != "BAD_DATA" and not name.startswith("UNKNOWN"):
                readable += len(m.get_msgbuf()) + stamp
            if name not in rows:
                continue
            if name == "LOCAL_POSITION_NED":
                rows[name].append((m.time_boot_ms * 1e-3, m.x, m.y, m.z, m.vx, m.vy, m.vz))
            else:
                rows[name].append(
                    (
                        m.time_boot_ms * 1e-3,
                        m.lat * 1e-7,
                        m.lon * 1e-7,
                        -m.relative_alt * 1e-3,
                        m.vx * 1e-2,
                        m.vy * 1e-2,
                        m.vz * 1e-2,
                    )
                )
    except Exception as exc:  # pymavlink raises bare Exceptions on damaged logs
        raise TrajectoryFormatError(
            f"{path}: not a readable MAVLink log: {_one_line(exc)}"
        ) from None
    finally:
        if mlog is not None:
            mlog.close()
    name = message or next((m for m in MAVLINK_MESSAGES if rows[m]), None)
    if name is None or not rows[name]:
        raise TrajectoryFormatError(
            f"{path}: no {message or ' or '.join(MAVLINK_MESSAGES)} messages in the log"
        )
    a = np.asarray(rows[name], float)
    notes = _damage(path, readable, name, a[:, 0])
    keep = np.r_[True, np.diff(a[:, 0]) > 0]  # drop repeats; a clock reset stays an error
    if np.any(np.diff(a[:, 0]) < 0):
        k = int(np.flatnonzero(np.diff(a[:, 0]) < 0)[0])
        raise TrajectoryFormatError(
            f"{path}: {name} time_boot_ms goes back at message {k + 1} ({a[k + 1, 0]:g} s after "
            f"{a[k, 0]:g} s): the autopilot rebooted; split the log"
        )
    a = a[keep]
    if name == "GLOBAL_POSITION_INT":
        first_fix = origin is None
        if origin is None:  # the log's own fixes are checked first: a bad one is the log's
            origin = first_point_origin(a[:, 1], a[:, 2], f"{path}: {name}")
        where = f"{path}: {name}" + (" (origin: the first fix)" if first_fix else "")
        p = geodetic_to_local(a[:, 1], a[:, 2], a[:, 3], origin, dim=3, where=where)
        return Track(
            t=a[:, 0], p=p, v=a[:, 4:7], source=f"{path}:{name}", origin=origin, notes=notes
        )
    return Track(t=a[:, 0], p=a[:, 1:4], v=a[:, 4:7], source=f"{path}:{name}", notes=notes)


def _damage(path: Path, readable: int, name: str, t: np.ndarray) -> tuple[str, ...]:
    """What a damaged log lost: a note, or an error below :data:`MIN_READABLE_FRACTION`."""
    size = path.stat().st_size
    lost = max(0, size - readable)
    if lost == 0:
        return ()
    h = np.diff(np.unique(t))
    # the sample interval: a low quantile of the intervals, as lost samples only lengthen some
    step = float(np.quantile(h, 0.25)) if h.size else 0.0
    expected = int(round((t.max() - t.min()) / step)) + 1 if step > 0 else t.size
    text = (
        f"{path}: {lost:,} of {size:,} bytes ({100 * lost / size:.1f} %) could not be decoded "
        f"(damaged or unknown messages); {t.size} {name} samples read of about "
        f"{max(expected, t.size)} over the log's time span"
    )
    if readable < MIN_READABLE_FRACTION * size or t.size < MIN_READABLE_FRACTION * expected:
        raise TrajectoryFormatError(
            f"{text}: below the {100 * MIN_READABLE_FRACTION:.0f} % a fit is trusted with; "
            "repair the log or export its track to CSV"
        )
    return (text,)


#: The log formats, in words (for messages).
FORMAT_NAMES = {"csv": "a CSV", "rosbag": "a ROS bag", "mavlink": "a MAVLink log"}


def track_format(path: str | Path, fmt: str = "auto") -> str:
    """``fmt``, or with ``"auto"`` the format of ``path`` by its extension: ``.bag``/``.mcap``/
    ``.db3`` or a folder -> ``"rosbag"``, ``.tlog``/``.mavlink`` -> ``"mavlink"``, else
    ``"csv"``.

    Parameters
    ----------
    path : str or Path
        The log file or folder.
    fmt : {"auto", "csv", "rosbag", "mavlink"}, optional
        The format, or ``"auto"`` to guess it.

    Returns
    -------
    str
        ``fmt`` unless it is ``"auto"``; else ``"csv"``, ``"rosbag"`` or ``"mavlink"``.
    """
    if fmt != "auto":
        return fmt
    path = Path(path)
    ext = path.suffix.lower()
    if ext in (".bag", ".mcap", ".db3") or path.is_dir():
        return "rosbag"
    if ext in (".tlog", ".mavlink"):
        return "mavlink"
    return "csv"


def read_track(
    path: str | Path,
    fmt: str = "auto",
    *,
    topic: str | None = None,
    message: str | None = None,
    origin: Any = None,
    ros_frame: str = "enu",
) -> Track:
    """Read a track from a CSV, a ROS bag or a MAVLink log (``fmt``: :func:`track_format`).

    Parameters
    ----------
    path : str or Path
        The log file (or ROS 2 bag folder).
    fmt : {"auto", "csv", "rosbag", "mavlink"}, optional
        Its format; ``"auto"``: by its extension.
    topic : str or None, optional
        ROS topic to read (:func:`read_track_rosbag`).
    message : str or None, optional
        MAVLink message to read (:func:`read_track_mavlink`).
    origin : GeodeticOrigin or None, optional
        Origin of the local frame for geodetic positions; None: the first point.
    ros_frame : {"enu", "ned"}, optional
        Frame of a ROS bag's positions.

    Returns
    -------
    Track
        The logged track in the local NED frame.

    Raises
    ------
    InputError
        For an unknown format, or what the reader of the format raises.
    """
    path = Path(path)
    fmt = track_format(path, fmt)
    if fmt == "csv":
        return read_track_csv(path, origin)
    if fmt == "rosbag":
        return read_track_rosbag(path, topic=topic, frame=ros_frame)
    if fmt == "mavlink":
        return read_track_mavlink(path, message=message, origin=origin)
    raise InputError(f"unknown log format {fmt!r}; choose auto, csv, rosbag or mavlink")


# ---------------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class _Nodes:
    t: np.ndarray  # node times (M,)
    sample: np.ndarray  # (M,) index of the sample at the node, -1 if none
    change: np.ndarray  # (M,) bool: the input may change at this node
    jump_dt: np.ndarray  # (M,) Δ_c of the jump into node c (0 where no change)
    out: np.ndarray  # (M,) bool: node is a row of the output trajectory
    inserted: int


def _nodes(t: np.ndarray, grid: float | None, max_gap: float | None) -> _Nodes:
    h = np.diff(t)
    med = float(np.median(h))
    limit = MAX_GAP_INTERVALS * med if max_gap is None else float(max_gap)
    if not (math.isfinite(limit) and limit > 0):
        raise InputError(f"max_gap must be a positive time in seconds, got {max_gap!r}")
    big = np.flatnonzero(h > limit)
    if big.size:
        k = int(big[0])
        raise TrackFitError(
            f"gap of {h[k]:.6g} s between samples {k} and {k + 1} (t = {t[k]:.6g} s to "
            f"{t[k + 1]:.6g} s) is longer than the largest gap bridged, {limit:.6g} s"
            + (f" ({MAX_GAP_INTERVALS:g} median intervals)" if max_gap is None else "")
            + ": no fit can say what the vehicle did there; split the log at the gap or "
            "raise --max-gap"
        )
    span = float(t[-1] - t[0])
    if grid is not None:
        grid = float(grid)
        if not (math.isfinite(grid) and grid > 0):
            raise InputError(f"grid must be a positive time step in seconds, got {grid!r}")
        n_grid = math.ceil(span / grid - 1e-9) + 1
        if n_grid + t.size > MAX_NODES:
            raise InputError(
                f"grid {grid:g} s over {span:g} s gives {n_grid} nodes, more than the limit "
                f"{MAX_NODES}; choose a grid of at least {span / (MAX_NODES - t.size):.3g} s"
            )
        g = t[0] + grid * np.arange(n_grid)
        # a sample within 1e-9 grid steps of a grid node is at that node
        j = np.clip(np.rint((t - t[0]) / grid).astype(np.int64), 0, n_grid - 1)
        on = np.abs(t - g[j]) <= 1e-9 * grid
        extra = t[~on]
        nt = np.concatenate([g, extra])
        order = np.argsort(nt, kind="stable")
        nt = nt[order]
        is_grid = np.concatenate([np.ones(n_grid, bool), np.zeros(extra.size, bool)])[order]
        sample_at = np.full(nt.size, -1)
        pos_grid = np.flatnonzero(is_grid)
        pos_extra = np.flatnonzero(~is_grid)
        sample_at[pos_grid[j[on]]] = np.flatnonzero(on)
        sample_at[pos_extra] = np.flatnonzero(~on)
        change, out, inserted = is_grid, is_grid, 0
    else:
        fill = np.where(h > FILL_GAP_INTERVALS * med, np.ceil(h / med).astype(np.int64) - 1, 0)
        if t.size + int(fill.sum()) > MAX_NODES:
            raise InputError(
                f"the track has {t.size} samples and needs {int(fill.sum())} gap nodes, more than "
                f"the limit of {MAX_NODES} nodes; split or subsample the log"
            )
        pieces, samples = [], []
        for k in range(h.size):
            m = int(fill[k])
            pieces.append(t[k] + h[k] * np.arange(m + 1) / (m + 1))
            samples.append(np.r_[k, np.full(m, -1)])
        nt = np.concatenate([*pieces, t[-1:]])
        sample_at = np.concatenate([*samples, [t.size - 1]]).astype(np.int64)
        change = np.ones(nt.size, bool)
        out = change
        inserted = int(fill.sum())
    # Δ_c: time between the centres of the holds before and after change node c
    cidx = np.flatnonzero(change)
    holds = np.diff(nt[cidx])
    jump = np.zeros(nt.size)
    if holds.size:
        after = np.r_[holds[1:], holds[-1]]
        jump[cidx[1:]] = 0.5 * (holds + after)
    return _Nodes(t=nt, sample=sample_at, change=change, jump_dt=jump, out=out, inserted=inserted)


def _kalman(
    nodes: _Nodes,
    y: np.ndarray,
    w: np.ndarray | None,
    q: np.ndarray,
    sp: np.ndarray,
    sv: float,
    axis: np.ndarray,
    store: bool,
):
    """Batched forward filter over B = len(q) independent 1D models (one axis each).

    Returns the log-likelihood per batch and, with ``store``, the filtered/predicted moments.
    """
    B, M = q.size, nodes.t.size
    h_all = np.diff(nodes.t)
    y0 = y[0, axis]
    span = np.ptp(y[: min(10, y.shape[0])], axis=0)[axis]
    h0 = float(np.median(h_all))
    s0 = 10.0 * np.maximum(span, 1.0) + 10.0 * sp  # diffuse but not numerically huge
    x = np.zeros((B, 3))
    x[:, 0] = y0
    P = np.zeros((B, 3, 3))
    P[:, 0, 0] = s0**2
    P[:, 1, 1] = (s0 / h0) ** 2
    P[:, 2, 2] = (s0 / h0**2) ** 2
    loglik = np.zeros(B)
    count = 0
    r_p = sp**2
    if store:
        xf = np.empty((M, B, 3))
        Pf = np.empty((M, B, 3, 3))
        xp = np.empty((M, B, 3))
        Pp = np.empty((M, B, 3, 3))
    for k in range(M):
        if k > 0:
            hk = h_all[k - 1]
            x, P = linear.predict(x, P, _transition(hk))
            if nodes.jump_dt[k] > 0:
                P[:, 2, 2] += q * nodes.jump_dt[k]
        if store:
            xp[k], Pp[k] = x, P
        i = nodes.sample[k]
        if i >= 0:
            meas: list[tuple[int, Any, Any]] = [(0, y[i, axis], r_p)]
            if w is not None:
                meas.append((1, w[i, axis], sv**2))
            for comp, val, r in meas:
                x, P, S, e = linear.update_component(x, P, comp, val, r)
                if count >= _DIFFUSE:
                    loglik += linear.log_likelihood(S, e)
                count += 1
        if store:
            xf[k], Pf[k] = x, P
    if store:
        return loglik, (xf, Pf, xp, Pp)
    return loglik, None


def _transition(h: float) -> np.ndarray:
    """``F`` of the constant-acceleration model ``(p, v, u)`` over a step ``h``."""
    return np.array([[1.0, h, 0.5 * h * h], [0.0, 1.0, h], [0.0, 0.0, 1.0]])


def _rts(nodes: _Nodes, moments) -> tuple[np.ndarray, np.ndarray]:
    """Rauch–Tung–Striebel smoother (:func:`obsplan.estimation.filters.linear.rts_smooth`): smoothed
    means (M, B, 3) and u variances (M, B)."""
    xf, Pf, xp, Pp = moments
    F = np.array([_transition(h) for h in np.diff(nodes.t)]).reshape(-1, 3, 3)
    xs, Ps = linear.rts_smooth(xf, Pf, xp, Pp, F)
    return xs, Ps[:, :, 2, 2]


def fit_track(
    track: Track,
    *,
    position_std: float | None = None,
    velocity_std: float = DEFAULT_VELOCITY_STD,
    grid: float | None = None,
    max_gap: float | None = None,
) -> TrackFit:
    """Fit the piecewise-constant accelerations of a logged track (see the module docstring).

    Parameters
    ----------
    track : Track
        Times, positions and optional velocities.
    position_std : float or None, optional
        Known position noise σ_p [m] (all axes); default: estimated per axis.
    velocity_std : float, optional
        Noise of the logged velocities [m/s] (used only when the track has velocities).
    grid : float or None, optional
        Hold the inputs on a uniform grid of this step [s] from the first sample (the output
        rows are the grid nodes; the last is at or after the last sample). Default: the input
        may change at every sample (and at nodes inserted in long gaps).
    max_gap : float or None, optional
        Longest gap between samples the fit bridges [s]; default 30 median intervals.

    Returns
    -------
    TrackFit
        The exact double-integrator trajectory of the fitted inputs and the fit's statistics.

    Raises
    ------
    TrackFitError
        Too few samples, a gap longer than ``max_gap``, or values the fit cannot use.
    """
    t, y = track.t, track.p
    if t.size < MIN_SAMPLES:
        raise TrackFitError(
            f"{track.source}: {t.size} samples; fitting accelerations needs at least "
            f"{MIN_SAMPLES} (three fix one parabola, one more checks it)"
        )
    for name, val, col in (
        ("position_std", position_std, "px"),
        ("velocity_std", velocity_std, "vx"),
    ):
        if val is not None and not (math.isfinite(val) and val > 0):
            raise InputError(f"{name} must be a positive number, got {val!r}")
        if val is not None:
            check_magnitude(val, name, *COLUMN_LIMITS[col])
    scale = float(np.max(np.abs(y - y[0]))) if y.size else 0.0
    if not math.isfinite(scale) or scale > 1e8 or float(np.ptp(t)) > 1e9:
        raise TrackFitError(
            f"{track.source}: positions span {scale:.3g} m over {float(np.ptp(t)):.3g} s, beyond "
            "what a vehicle track can be (check the units: metres and seconds)"
        )
    try:
        nodes = _nodes(t, grid, max_gap)
    except TrackFitError as exc:
        raise TrackFitError(f"{track.source}: {exc}") from None
    n = track.dim
    w = track.v
    with np.errstate(all="ignore"):
        sp_grid = _S_GRID if position_std is None else np.array([float(position_std)])
        try:
            qs, ss, edge = _search(nodes, y, w, velocity_std, n, _Q_GRID, sp_grid)
            q_ref = qs[:, None] * 10.0 ** np.linspace(-1, 1, 9)[None, :]
            s_ref = ss[:, None] * (
                10.0 ** np.linspace(-0.25, 0.25, 9)[None, :] if position_std is None else 1.0
            )
            qs, ss = _refine(nodes, y, w, velocity_std, n, q_ref, s_ref)
            _, moments = _kalman(nodes, y, w, qs, ss, velocity_std, np.arange(n), store=True)
            xs, u_var = _rts(nodes, moments)
        except np.linalg.LinAlgError:
            xs = u_var = np.full(1, np.nan)  # refused just below, in words
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(u_var))):
        raise TrackFitError(
            f"{track.source}: the fit did not give finite values (positions {scale:.3g} m over "
            f"{float(np.ptp(t)):.3g} s); check the units and the samples"
            + (f", and --position-std {position_std:g} m" if position_std is not None else "")
        )
    _check_fitted(xs, nodes, t, track.source)
    out = nodes.out
    t_out = nodes.t[out]
    u = xs[out, :, 2]
    traj = Trajectory.from_inputs(t_out, xs[0, :, 0], xs[0, :, 1], u)
    # residual of the exact path at the samples: integrate on all nodes (same inputs)
    u_all = xs[:, :, 2]
    if grid is not None:
        idx = np.maximum.accumulate(np.where(nodes.change, np.arange(nodes.t.size), 0))
        u_all = u_all[idx]  # hold the grid node's input until the next grid node
    full = Trajectory.from_inputs(nodes.t, xs[0, :, 0], xs[0, :, 1], u_all)
    at = nodes.sample >= 0
    res = full.p[at] - y[nodes.sample[at]]
    return TrackFit(
        trajectory=traj,
        residual_rms=tuple(float(r) for r in np.sqrt(np.mean(res**2, axis=0))),
        residual_max=tuple(float(r) for r in np.max(np.abs(res), axis=0)),
        position_std=tuple(float(s) for s in ss),
        accel_intensity=tuple(float(q) for q in qs),
        accel_std=tuple(float(s) for s in np.sqrt(np.median(u_var[nodes.change], axis=0))),
        samples=int(t.size),
        nodes=int(nodes.t.size),
        inserted=nodes.inserted,
        estimated=position_std is None,
        at_search_edge=tuple(bool(e) for e in edge),
        source=track.source,
        origin=track.origin,
    )


def _check_fitted(xs: np.ndarray, nodes: _Nodes, t: np.ndarray, source: str) -> None:
    """Refuse a fit whose velocities or accelerations no vehicle has (the limits of the
    trajectory CSV's columns, :data:`~obsplan.core.csvtable.COLUMN_LIMITS`): samples 1e-12 s
    apart, or times in another unit, fit "exactly" with absurd inputs, which no warning may
    pass on as a trajectory."""
    h = float(np.median(np.diff(t)))
    for what, col, j in (("velocity", "vx", 1), ("acceleration", "ux", 2)):
        limit, unit = COLUMN_LIMITS[col]
        big = np.argwhere(np.abs(xs[:, :, j]) > limit)
        if big.size:
            k, axis = (int(i) for i in big[0])
            check_magnitude(
                float(xs[k, axis, j]),
                f"{source}: the fit needs a {what} along {'xyz'[axis]} at t = "
                f"{nodes.t[k]:.6g} s (the samples are {h:.3g} s apart, median)",
                limit,
                unit,
                error=TrackFitError,
            )


def _search(nodes, y, w, sv, n, q_grid, s_grid):
    """Coarse grid: best (q, σ_p) per axis and whether it is at the edge of the grid."""
    Q, S = np.meshgrid(q_grid, s_grid, indexing="ij")
    nq, ns = Q.shape
    q = np.tile(Q.ravel(), n)
    s = np.tile(S.ravel(), n)
    axis = np.repeat(np.arange(n), nq * ns)
    ll, _ = _kalman(nodes, y, w, q, s, sv, axis, store=False)
    ll = np.where(np.isfinite(ll), ll, -np.inf).reshape(n, nq, ns)
    best = ll.reshape(n, -1).argmax(axis=1)
    iq, is_ = np.unravel_index(best, (nq, ns))
    edge = (iq == 0) | (iq == nq - 1) | (((is_ == 0) | (is_ == ns - 1)) & (ns > 1))
    return q_grid[iq], s_grid[is_], edge


def _refine(nodes, y, w, sv, n, q_ref, s_ref):
    """Fine grid around the coarse optimum, per axis (q_ref, s_ref: (n, k) candidates)."""
    nq, ns = q_ref.shape[1], s_ref.shape[1]
    q = np.repeat(q_ref, ns, axis=1).ravel()
    s = np.tile(s_ref, (1, nq)).ravel()
    axis = np.repeat(np.arange(n), nq * ns)
    ll, _ = _kalman(nodes, y, w, q, s, sv, axis, store=False)
    ll = np.where(np.isfinite(ll), ll, -np.inf).reshape(n, nq * ns)
    best = ll.argmax(axis=1)
    return q.reshape(n, -1)[np.arange(n), best], s.reshape(n, -1)[np.arange(n), best]


def beacon_trajectory_from_table(table: CsvTable, check: bool = True) -> Trajectory:
    """The path of the craft carrying a planned beacon, from its ``beacon.csv`` (``t,bx,by[,bz],
    vbx,vby[,vbz]``, :func:`~obsplan.model.beacon.write_beacon_csv`), as a trajectory.

    The craft holds a constant acceleration between samples (the planner samples its path at
    every node where the acceleration changes), so the acceleration on ``[t_k, t_{k+1})`` is
    ``(v_{k+1} - v_k) / (t_{k+1} - t_k)`` exactly; the last sample repeats the one before.

    Parameters
    ----------
    table : CsvTable
        The CSV read as text cells.
    check : bool, optional
        Warn if those accelerations do not reproduce the positions
        (:meth:`~obsplan.trajectory.sampled.Trajectory.check_consistency`): a file that is not
        a path of piecewise-constant accelerations sampled at their changes.

    Returns
    -------
    Trajectory
        Positions ``b``, velocities ``vb`` and the accelerations between samples.

    Raises
    ------
    TrajectoryFormatError
        A missing column (the velocities too), a bad cell, fewer than 2 rows or times that do not
        increase.
    """
    dim = 3 if "bz" in table.columns else 2
    cols = ["t"] + [f"b{a}" for a in "xyz"[:dim]] + [f"vb{a}" for a in "xyz"[:dim]]
    needs = f"a beacon path to export needs {','.join(cols)} (the beacon.csv of `obsplan plan`)"
    data = table.samples(cols, str(table.path), needs)
    t, b, v = data[:, 0], data[:, 1 : 1 + dim], data[:, 1 + dim :]
    u = np.diff(v, axis=0) / np.diff(t)[:, None]
    traj = Trajectory(t, b, v, np.vstack([u, u[-1:]]))
    if check:
        traj.check_consistency(source=str(table.path))
    return traj


def load_trajectory(
    path: str | Path, *, check: bool = True, beacon: bool = False, **fit_options: Any
) -> tuple[Trajectory, TrackFit | None]:
    """A trajectory CSV as it is, or a position-only track CSV fitted on the fly.

    A file with any ``u`` column is read as a trajectory CSV
    (:func:`obsplan.trajectory.sampled.read_csv`); one with ``t,px,py[,pz]`` and no ``u`` is a
    track, fitted by :func:`fit_track` with ``fit_options``. Returns the trajectory and the fit
    (None for a trajectory CSV).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    check : bool, optional
        Warn if a trajectory CSV's inputs do not reproduce its samples
        (:meth:`~obsplan.trajectory.sampled.Trajectory.check_consistency`).
    beacon : bool, optional
        Also read a planned beacon's ``beacon.csv`` (a ``bx`` column;
        :func:`beacon_trajectory_from_table`), for tools that fly the craft's path.
    **fit_options
        Keyword arguments of :func:`fit_track` (``position_std``, ``grid``...), for a track.

    Returns
    -------
    trajectory : Trajectory
        The trajectory read or fitted.
    fit : TrackFit or None
        The fit of a track; None for a trajectory CSV.

    Raises
    ------
    TrajectoryFormatError
        For a file that is neither a trajectory CSV nor a track CSV.
    TrackFitError
        For a track that cannot be fitted.
    """
    table = read_table(path, "t,px,py,vx,vy,ux,uy (or a track: t,px,py)")
    if beacon and "bx" in table.columns:
        return beacon_trajectory_from_table(table, check=check), None
    if any(c in table.columns for c in ("ux", "uy", "uz")):
        return trajectory_from_table(table, check=check), None
    if not table.has("t", "px", "py"):
        dim = 3 if "pz" in table.columns else 2
        missing = [c for c in csv_columns(dim) if c not in table.columns]
        raise TrajectoryFormatError(
            f"{table.path}: missing column(s) {', '.join(missing)}; the header must contain "
            f"{','.join(csv_columns(dim))}, or t,px,py[,pz] for a position-only track"
        )
    fit = fit_track(track_from_table(table), **fit_options)
    return fit.trajectory, fit
