"""``obsplan analyze TRAJ.csv``: both observability verdicts for a trajectory CSV."""

from __future__ import annotations

import argparse
import json

import numpy as np

from obsplan.cli.common import (
    add_beacon_path_argument,
    add_vehicle_arguments,
    read_trajectory,
    resolve_beacon,
    resolve_beacon_path,
)
from obsplan.core.errors import InputError
from obsplan.observability.analyze import ObservabilityReport, analyze
from obsplan.observability.scaling import DEFAULT_SCALES, ScaleError, Scales, check_scale


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``analyze`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan analyze``: ``TRAJ.csv``, the vehicle options
        (:func:`~obsplan.cli.common.add_vehicle_arguments`), ``--beacon-path``,
        ``--length-scale``, ``--time-scale``, ``--calibration`` and ``--json``.
    """
    p = subparsers.add_parser(
        "analyze",
        help="local (LWO) and global (Gramian) observability of a trajectory CSV",
        description=(
            "Both observability verdicts for a trajectory CSV (t,px,py[,pz],vx,vy[,vz],ux,uy[,uz], "
            "SI units): the Lie-derivative rank condition at every sample and the rank and "
            "metrics of the augmented observability Gramian. A position-only track "
            "(t,px,py[,pz]) is fitted on the fly (see obsplan import)."
        ),
    )
    p.add_argument("trajectory", metavar="TRAJ.csv", help="trajectory CSV file")
    add_vehicle_arguments(p)
    add_beacon_path_argument(p)
    p.add_argument(
        "--length-scale",
        metavar="M",
        type=float,
        default=DEFAULT_SCALES.length_m,
        help=f"length scale of min_eig/log_det/condition [m] (default {DEFAULT_SCALES.length_m:g})",
    )
    p.add_argument(
        "--time-scale",
        metavar="S",
        type=float,
        default=DEFAULT_SCALES.time_s,
        help=f"time scale of min_eig/log_det/condition [s] (default {DEFAULT_SCALES.time_s:g})",
    )
    p.add_argument(
        "--calibration",
        action="store_true",
        help=(
            "also say whether the range's scale (a sound-speed error) and bias (a clock "
            "offset) are observable along the trajectory (JSON key range_calibration)"
        ),
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def format_report(rep: ObservabilityReport, path: str) -> str:
    """Human-readable summary of a report.

    Parameters
    ----------
    rep : ObservabilityReport
        The report of :func:`obsplan.observability.analyze.analyze`.
    path : str
        The trajectory file, named on the first line.

    Returns
    -------
    str
        Four lines: the dimension and sensors, the LWO verdict along the trajectory, the
        augmented Gramian's rank, and the scaled Gramian's ``min_eig``, ``log_det`` and
        ``condition``; then, when the report has it, the range's calibration (three lines).
    """
    lwo, g = rep.lwo, rep.gramian
    verdict = "YES" if lwo.along_trajectory else "NO"
    lines = [
        f"{path}: {rep.dim}D, sensors {','.join(rep.sensors)}"
        + (", unknown current" if rep.current else "")
        + (", moving beacon (known path)" if rep.beacon_motion == "path" else ""),
        f"  LWO along trajectory (rank condition, eq. 9): {verdict}  "
        f"(full rank {lwo.state_dim} at {100 * lwo.full_rank_fraction:.1f}% of samples, "
        f"min rank {lwo.min_rank})",
        f"  Gramian full rank (augmented LTV, eq. 25):    {'YES' if g.full_rank else 'NO'}  "
        f"(rank {g.rank} of {g.dim}"
        + (f", full from t = {g.full_rank_from_t:g} s)" if g.full_rank_from_t is not None else ")"),
        f"  scaled Gramian (L = {g.scales.length_m:g} m, T = {g.scales.time_s:g} s): "
        f"min_eig {g.min_eig:.4g}, log_det {g.log_det:.4g}, condition {g.condition:.4g}",
    ]
    if rep.calibration is not None:
        lines += ["  " + line for line in rep.calibration.summary().splitlines()]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``obsplan analyze``; exit code 0 (errors raise, mapped by the dispatcher).

    Prints the report (:func:`format_report`, or JSON with ``--json``, with the origin and the
    beacon for a geodetic beacon). A trajectory that is not observable is a result, not a
    failure.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0.

    Raises
    ------
    InputError
        A bad scale, trajectory, beacon or beacon path (malformed, of another dimension, not
        covering the trajectory, or given with ``--beacon``), or scales under which the
        full-rank Gramian's metrics fall below round-off (exit 2).
    """
    check_scale(args.length_scale, "--length-scale", "m")
    check_scale(args.time_scale, "--time-scale", "s")
    scales = Scales(length_m=args.length_scale, time_s=args.time_scale)
    traj = read_trajectory(args.trajectory, "analyze")
    beacon, origin = resolve_beacon(args, traj.dim)
    path = resolve_beacon_path(args, traj.dim, beacon, float(traj.t[0]), float(traj.t[-1]))
    rep = analyze(
        traj,
        sensors=args.sensors or "range",
        current=bool(args.current),
        beacon=beacon,
        scales=scales,
        beacon_path=path,
        calibration=bool(args.calibration),
    )
    try:
        rep.gramian.check_metrics()  # never print min_eig 0, log_det -inf for a full rank
    except ScaleError as exc:
        size = float(np.max(np.ptp(traj.p, axis=0)))
        raise InputError(
            f"--length-scale {args.length_scale:g}, --time-scale {args.time_scale:g}: "
            f"{exc.reason}; {args.trajectory} spans {size:.3g} m over {traj.duration:.3g} s"
        ) from None
    if args.json:
        out = rep.to_dict()
        if origin is not None:
            out["origin"] = origin.to_dict()
            out["beacon"] = list(beacon) if beacon is not None else [0.0] * traj.dim
        if path is not None:
            out["beacon_path"] = args.beacon_path
        print(json.dumps(out, indent=2))
    else:
        print(format_report(rep, args.trajectory))
    return 0
