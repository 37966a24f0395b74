"""``obsplan export PLAN.csv --waypoints WP.csv [--qgc MISSION.plan]``: flyable waypoints.

``PLAN.csv`` is the vehicle's ``plan.csv`` or the planned beacon's ``beacon.csv`` (its craft's
path: an ASV or a ship flies the waypoints too)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from obsplan.cli.common import Applies, OutputFile, check_applies, given_fact, read_trajectory
from obsplan.core.errors import InputError
from obsplan.core.textfiles import read_json
from obsplan.model.frames import check_local_points

DEFAULT_EVERY_S = 30.0
DEFAULT_ACCEPTANCE_M = 1.0
#: Options that apply only to some outputs (:func:`obsplan.cli.common.check_applies`).
APPLIES = (
    Applies("--origin", "geodetic output (--geodetic, --qgc)", "geodetic"),
    Applies("--geodetic", "the waypoint CSV (--waypoints)", "waypoints"),
    Applies("--depth", "the QGroundControl mission of a 2D plan (--qgc)", "qgc"),
    Applies("--acceptance-radius", "the QGroundControl mission (--qgc)", "qgc"),
)


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``export`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan export``: ``PLAN.csv``, ``--waypoints``, ``--qgc``, ``--every`` or
        ``--spacing``, ``--geodetic``, ``--origin``, ``--depth``, ``--acceptance-radius``,
        ``--force`` and ``--json``.
    """
    p = subparsers.add_parser(
        "export",
        help="waypoints (metric or geodetic) and a QGroundControl mission from a plan",
        description=(
            "Turn a planned trajectory CSV (or the beacon.csv of a planned beacon: its craft's "
            "path) into waypoints for an autopilot that flies straight "
            "legs: a waypoint CSV (time, position, speed, and the exact tracking error of each "
            "leg) and/or a QGroundControl .plan mission for MAVLink (ArduSub) vehicles. "
            "Geodetic output needs the origin of the plan's north-east-down frame: --origin, or "
            "the 'origin' of report.json beside PLAN.csv (written by `obsplan plan` for a "
            "geodetic problem). See docs/export.md."
        ),
    )
    p.add_argument(
        "plan",
        metavar="PLAN.csv",
        help="trajectory CSV (e.g. DIR/plan.csv), or a planned beacon's DIR/beacon.csv",
    )
    p.add_argument("--waypoints", metavar="WP.csv", default=None, help="waypoint CSV to write")
    p.add_argument("--qgc", metavar="MISSION.plan", default=None, help="QGroundControl plan")
    space = p.add_mutually_exclusive_group()
    space.add_argument(
        "--every",
        metavar="S",
        type=float,
        default=None,
        help=f"a waypoint every S seconds of the plan (default {DEFAULT_EVERY_S:g})",
    )
    space.add_argument(
        "--spacing", metavar="M", type=float, default=None, help="a waypoint every M metres"
    )
    p.add_argument(
        "--geodetic",
        action="store_true",
        help="write latitude, longitude[, depth] in the waypoint CSV (needs an origin)",
    )
    p.add_argument("--origin", metavar="LAT,LON[,ALT]", default=None, help="origin of the frame")
    p.add_argument(
        "--depth",
        metavar="M",
        type=float,
        default=None,
        help="depth [m] >= 0 of a 2D plan in the mission (default 0: at the surface; a 3D plan "
        "has its own depths)",
    )
    p.add_argument(
        "--acceptance-radius",
        metavar="M",
        type=float,
        default=None,
        help=f"waypoint acceptance radius of the --qgc mission [m] (default "
        f"{DEFAULT_ACCEPTANCE_M:g})",
    )
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    return p


def _origin(args: argparse.Namespace):
    """The origin of the plan's frame and where it came from: ``--origin``, or the report.json
    beside the plan (read only when geodetic output is asked for)."""
    from obsplan.io.geodetic import parse_origin
    from obsplan.model.frames import GeodeticOrigin

    if args.origin is not None:
        return parse_origin(args.origin), "--origin"
    report = Path(args.plan).with_name("report.json")
    if not (args.geodetic or args.qgc) or not report.exists():
        return None, None
    doc = read_json(report, "the report.json of `obsplan plan` (or give --origin)")
    o = doc.get("origin") if isinstance(doc, dict) else None
    if isinstance(o, dict):
        try:
            origin = GeodeticOrigin(o["latitude"], o["longitude"], o.get("altitude", 0.0))
        except (KeyError, TypeError, InputError):
            raise InputError(f"{report}: its 'origin' is malformed; give --origin") from None
        return origin, str(report)
    return None, None


def run(args: argparse.Namespace) -> int:
    """Run ``obsplan export``; 0 on success.

    Writes the waypoint CSV and/or the QGroundControl mission and prints a summary (JSON with
    ``--json``).

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 (the files written).

    Raises
    ------
    InputError
        Nothing to write, ``--waypoints`` and ``--qgc`` naming the same file, an output that
        exists without ``--force``, geodetic output without an origin, a ``--depth`` below 0 or
        with a 3D plan, an ``--acceptance-radius`` that is not positive, an option that does not
        apply (:data:`APPLIES`), a bad plan or a plan beyond the frame's reach about its origin
        (exit 2).
    """
    from obsplan.io.waypoints import waypoints_from_trajectory, write_qgc_plan, write_waypoints_csv

    if args.waypoints is None and args.qgc is None:
        raise InputError("nothing to write: give --waypoints WP.csv and/or --qgc MISSION.plan")
    outs = []
    if args.waypoints is not None:
        outs.append(OutputFile(args.waypoints, args.force, "--waypoints", inputs=[args.plan]))
    if args.qgc is not None:
        outs.append(OutputFile(args.qgc, args.force, "--qgc", inputs=[args.plan]))
    if len(outs) == 2 and outs[0].path.resolve() == outs[1].path.resolve():
        raise InputError("--waypoints and --qgc name the same file; give two names")
    geodetic = args.geodetic or args.qgc is not None
    check_applies(
        args,
        APPLIES,
        {
            "geodetic": given_fact(geodetic, "no --geodetic or --qgc is given"),
            "waypoints": given_fact(args.waypoints is not None, "no --waypoints is given"),
            "qgc": given_fact(args.qgc is not None, "no --qgc is given"),
        },
    )
    origin, origin_from = _origin(args)
    if geodetic and origin is None:
        raise InputError(
            ("--qgc" if args.qgc else "--geodetic")
            + " needs geodetic coordinates: give --origin LAT,LON[,ALT] (the origin of the "
            "plan's north-east-down frame), or export a plan whose report.json has an origin"
        )
    if args.depth is not None:
        if not (math.isfinite(args.depth) and args.depth >= 0):
            raise InputError(
                f"--depth {args.depth:g}: a depth must be a finite number of metres >= 0 "
                "(0: at the surface)"
            )
    radius = DEFAULT_ACCEPTANCE_M if args.acceptance_radius is None else args.acceptance_radius
    if not (math.isfinite(radius) and radius > 0):
        raise InputError(f"--acceptance-radius {radius:g}: must be a positive number of metres")
    traj = read_trajectory(args.plan, "export", beacon=True)
    if args.depth is not None and traj.dim == 3:
        raise InputError(
            f"--depth: {args.plan} is a 3D plan, whose mission flies its own depths (pz); "
            "drop --depth"
        )
    if origin is not None:  # the frame serves 50 km about its origin (docs/geodetic.md)
        by = "" if origin_from == "--origin" else f" (origin from {origin_from})"
        check_local_points(traj.p, origin, f"{args.plan}{by}")
    every = args.every if (args.every is not None or args.spacing is not None) else DEFAULT_EVERY_S
    wp = waypoints_from_trajectory(traj, every=every, spacing=args.spacing, origin=origin)
    written = []
    if args.waypoints is not None:
        with outs[0].writing() as tmp:
            write_waypoints_csv(wp, tmp, geodetic=args.geodetic)
        written.append(str(outs[0].path))
    if args.qgc is not None:
        with outs[-1].writing() as tmp:
            write_qgc_plan(wp, tmp, depth_2d=args.depth or 0.0, acceptance_radius=radius)
        written.append(str(outs[-1].path))
    summary = {
        "waypoints": len(wp),
        "every_s": args.every if args.spacing is None else None,
        "spacing_m": args.spacing,
        "max_cross_track_m": wp.max_cross_track,
        "max_schedule_error_m": wp.max_schedule_error,
        "origin": origin.to_dict() if origin is not None else None,
        "written": written,
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        step = f"every {every:g} s" if args.spacing is None else f"every {args.spacing:g} m"
        print(
            f"{args.plan}: {len(wp)} waypoints ({step}); straight-line following leaves the "
            f"planned path by at most {wp.max_cross_track:.3g} m (cross-track) and "
            f"{wp.max_schedule_error:.3g} m from the planned position at the same time "
            "(exact, from the piecewise-quadratic plan)"
        )
        if origin_from is not None:
            print(f"origin {origin.latitude:.8g}, {origin.longitude:.8g} (from {origin_from})")
        print("wrote " + ", ".join(written))
    if origin_from is not None and origin_from != "--origin" and not args.json:
        print(f"obsplan export: using the origin of {origin_from}", file=sys.stderr)
    return 0
