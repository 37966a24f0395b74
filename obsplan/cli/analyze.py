"""``obsplan analyze TRAJ.csv``: both observability verdicts for a trajectory CSV."""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings

from obsplan.errors import InputError
from obsplan.observability.analyze import ObservabilityReport, analyze
from obsplan.observability.scaling import DEFAULT_SCALES, Scales
from obsplan.trajectory import InconsistentTrajectoryWarning, read_csv


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``analyze`` verb."""
    p = subparsers.add_parser(
        "analyze",
        help="local (LWO) and global (Gramian) observability of a trajectory CSV",
        description=(
            "Both observability verdicts for a trajectory CSV (t,px,py[,pz],vx,vy[,vz],ux,uy[,uz], "
            "SI units): the Lie-derivative rank condition at every sample and the rank and "
            "metrics of the augmented observability Gramian."
        ),
    )
    p.add_argument("trajectory", metavar="TRAJ.csv", help="trajectory CSV file")
    p.add_argument(
        "--sensors",
        default="range",
        help="comma-separated: range, dvl-bottom|dvl-water (dvl = dvl-bottom), depth "
        "(default: range)",
    )
    p.add_argument("--current", action="store_true", help="include an unknown constant current")
    p.add_argument(
        "--beacon", metavar="X,Y[,Z]", default=None, help="beacon position [m] (default: origin)"
    )
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
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def parse_beacon(text: str | None, dim: int) -> tuple[float, ...] | None:
    """``"x,y[,z]"`` -> floats, checked against the trajectory dimension."""
    if text is None:
        return None
    parts = [s.strip() for s in text.split(",")]
    try:
        values = tuple(float(s) for s in parts)
    except ValueError:
        raise InputError(
            f"--beacon {text!r}: expected {dim} numbers separated by commas, e.g. "
            f"--beacon {','.join(['0'] * dim)}"
        ) from None
    if len(values) != dim or not all(math.isfinite(v) for v in values):
        raise InputError(
            f"--beacon {text!r}: the trajectory is {dim}D, so the beacon needs {dim} finite "
            f"coordinates [m], e.g. --beacon {','.join(['0'] * dim)}"
        )
    return values


def format_report(rep: ObservabilityReport, path: str) -> str:
    """Human-readable summary of a report."""
    lwo, g = rep.lwo, rep.gramian
    verdict = "YES" if lwo.along_trajectory else "NO"
    lines = [
        f"{path}: {rep.dim}D, sensors {','.join(rep.sensors)}"
        + (", unknown current" if rep.current else ""),
        f"  LWO along trajectory (rank condition, eq. 9): {verdict}  "
        f"(full rank {lwo.state_dim} at {100 * lwo.full_rank_fraction:.1f}% of samples, "
        f"min rank {lwo.min_rank})",
        f"  Gramian full rank (augmented LTV, eq. 25):    {'YES' if g.full_rank else 'NO'}  "
        f"(rank {g.rank} of {g.dim}"
        + (f", full from t = {g.full_rank_from_t:g} s)" if g.full_rank_from_t is not None else ")"),
        f"  scaled Gramian (L = {g.scales.length_m:g} m, T = {g.scales.time_s:g} s): "
        f"min_eig {g.min_eig:.4g}, log_det {g.log_det:.4g}, condition {g.condition:.4g}",
    ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``obsplan analyze``; exit code 0 (errors raise, mapped by the dispatcher)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InconsistentTrajectoryWarning)
        traj = read_csv(args.trajectory, check=True)
    for w in caught:
        if issubclass(w.category, InconsistentTrajectoryWarning):
            print(f"obsplan analyze: warning: {w.message}", file=sys.stderr)
        else:  # pragma: no cover - pass other warnings on untouched
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    beacon = parse_beacon(args.beacon, traj.dim)
    scales = Scales(length_m=args.length_scale, time_s=args.time_scale)
    rep = analyze(traj, sensors=args.sensors, current=args.current, beacon=beacon, scales=scales)
    if args.json:
        print(json.dumps(rep.to_dict(), indent=2))
    else:
        print(format_report(rep, args.trajectory))
    return 0
