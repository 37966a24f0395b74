"""``obsplan import LOG --out TRAJ.csv``: a logged track to the trajectory CSV, with fitted inputs.

The module is ``import_track`` because ``import`` is a Python keyword; the verb is ``import``.
"""

from __future__ import annotations

import argparse
import json
import sys

from obsplan.cli.common import Applies, OutputFile, check_applies, given_fact
from obsplan.io.tracks import (
    DEFAULT_VELOCITY_STD,
    FORMAT_NAMES,
    MAX_GAP_INTERVALS,
    fit_track,
    read_track,
    track_format,
)
from obsplan.trajectory.sampled import write_csv


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``import`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan import``: ``LOG``, ``--out``, ``--force``, ``--format``,
        ``--topic``, ``--ros-frame``, ``--message``, ``--origin``, ``--grid``, ``--position-std``,
        ``--velocity-std``, ``--max-gap`` and ``--json``.
    """
    p = subparsers.add_parser(
        "import",
        help="a logged track (CSV, ROS bag, MAVLink log) to a trajectory CSV with fitted inputs",
        description=(
            "Read a logged track (positions, optional velocities; irregular times and gaps are "
            "fine) from a CSV (t,px,py[,pz][,vx,vy[,vz]]), a ROS 1/2 bag (nav_msgs/Odometry or "
            "geometry_msgs/PoseStamped; extra 'ros') or a MAVLink telemetry log (.tlog: "
            "LOCAL_POSITION_NED or GLOBAL_POSITION_INT; extra 'mavlink'), fit the "
            "piecewise-constant accelerations of the double integrator by regularised least "
            "squares (a Kalman/RTS smoother; the noise and smoothness are chosen by maximum "
            "marginal likelihood; docs/import.md), and write the trajectory CSV. Positions are "
            "north-east-down (z = depth)."
        ),
    )
    p.add_argument("log", metavar="LOG", help="track CSV, ROS bag (file or folder) or .tlog")
    p.add_argument("--out", metavar="TRAJ.csv", required=True, help="trajectory CSV to write")
    p.add_argument("--force", action="store_true", help="replace an existing TRAJ.csv")
    p.add_argument(
        "--format",
        choices=("auto", "csv", "rosbag", "mavlink"),
        default="auto",
        help="log format (default: from the extension: .bag/.mcap/.db3/folder, .tlog, else CSV)",
    )
    p.add_argument("--topic", default=None, help="ROS topic (default: the only position topic)")
    p.add_argument(
        "--ros-frame",
        choices=("enu", "ned"),
        default=None,
        help="frame of the bag's positions: enu (ROS REP-103, converted to north-east-down; "
        "default) or ned (kept)",
    )
    p.add_argument(
        "--message",
        choices=("LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"),
        default=None,
        help="MAVLink message (default: LOCAL_POSITION_NED if present)",
    )
    p.add_argument(
        "--origin",
        metavar="LAT,LON[,ALT]",
        default=None,
        help="origin of the local frame for GLOBAL_POSITION_INT or a geodetic waypoint CSV "
        "(default: the first fix)",
    )
    p.add_argument(
        "--grid",
        metavar="S",
        type=float,
        default=None,
        help="hold the accelerations on a uniform grid of S seconds (default: they may change "
        "at every sample); e.g. a multiple of the filter step of `simulate --dt`",
    )
    p.add_argument(
        "--position-std",
        metavar="M",
        type=float,
        default=None,
        help="known position noise [m] (default: estimated per axis)",
    )
    p.add_argument(
        "--velocity-std",
        metavar="M/S",
        type=float,
        default=None,
        help=f"noise of logged velocities [m/s] (default {DEFAULT_VELOCITY_STD:g}; for logs "
        "with velocities)",
    )
    p.add_argument(
        "--max-gap",
        metavar="S",
        type=float,
        default=None,
        help=f"longest gap to bridge [s] (default {MAX_GAP_INTERVALS:g} median intervals)",
    )
    p.add_argument("--json", action="store_true", help="print the fit summary as JSON")
    return p


#: Options that apply only to some logs (:func:`obsplan.cli.common.check_applies`): the
#: format's are judged before the log is read, the content's after.
APPLIES = (
    Applies("--topic", "ROS bags", "rosbag"),
    Applies("--ros-frame", "ROS bags", "rosbag"),
    Applies("--message", "MAVLink logs", "mavlink"),
    Applies(
        "--origin",
        "geodetic logs (MAVLink GLOBAL_POSITION_INT, a waypoint CSV of latitude, longitude)",
        "geodetic",
    ),
    Applies("--velocity-std", "logs with velocities (vx, vy[, vz]; MAVLink)", "velocities"),
)


def run(args: argparse.Namespace) -> int:
    """Run ``obsplan import``; 0 on success.

    Reads the log, fits the accelerations, writes ``--out`` and prints the fit's summary (JSON
    with ``--json``); the log's notes are warnings on stderr.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 (the trajectory CSV written).

    Raises
    ------
    InputError
        An option that does not apply to the log (:data:`APPLIES`, judged by its format before
        it is read and by its content after), an output that exists without ``--force``, or a
        log that cannot be read or fitted (exit 2).
    """
    # checked before reading the log
    fmt = track_format(args.log, args.format)
    where = f"{args.log} is {FORMAT_NAMES.get(fmt, fmt)}"
    facts = {"rosbag": given_fact(fmt == "rosbag", where)}
    facts["mavlink"] = given_fact(fmt == "mavlink", where)
    if fmt == "rosbag":  # a bag has local positions and no velocities the fit reads
        facts["geodetic"] = facts["velocities"] = where
    check_applies(args, APPLIES, facts)
    out = OutputFile(args.out, args.force, "--out", inputs=[args.log])
    origin = None
    if args.origin is not None:
        from obsplan.io.geodetic import parse_origin

        origin = parse_origin(args.origin)
    track = read_track(
        args.log,
        fmt,
        topic=args.topic,
        message=args.message,
        origin=origin,
        ros_frame=args.ros_frame or "enu",
    )
    read = f"{track.source} has"
    check_applies(
        args,
        APPLIES,
        {
            "geodetic": given_fact(track.origin is not None, f"{read} local positions"),
            "velocities": given_fact(track.v is not None, f"{read} no velocities"),
        },
    )
    for note in track.notes:
        print(f"obsplan import: warning: {note}", file=sys.stderr)
    fit = fit_track(
        track,
        position_std=args.position_std,
        velocity_std=DEFAULT_VELOCITY_STD if args.velocity_std is None else args.velocity_std,
        grid=args.grid,
        max_gap=args.max_gap,
    )
    with out.writing() as tmp:
        write_csv(fit.trajectory, tmp)
    if args.json:
        print(json.dumps({**fit.to_dict(), "out": str(out.path)}, indent=2))
    else:
        print(fit.summary())
        print(f"wrote {out.path} ({fit.trajectory.n_samples} rows)")
    return 0
