"""Options and checks shared by the verbs: vehicle options, beacon, inputs, and the outputs.

Output folders and files (:class:`OutputDir`, :class:`OutputFile`) are those of
:mod:`obsplan.core.outputs`, one implementation for every verb: checked before any work, written
into a staging folder and swapped in place, ``--force`` replacing only an earlier output of the
same verb that holds nothing but what it wrote.
Signals are mapped to exit 130 / 143 by :func:`obsplan.cli.main` (:mod:`obsplan.core.interrupts`).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

from obsplan.core.budget import check_file_rows
from obsplan.core.csvtable import COLUMN_LIMITS
from obsplan.core.errors import InputError
from obsplan.core.outputs import OutputDir, OutputFile
from obsplan.core.textfiles import check_magnitude

if TYPE_CHECKING:
    from obsplan.trajectory.sampled import Trajectory


# ------------------------------------------------------------------------------ arguments
def add_vehicle_arguments(p: argparse.ArgumentParser) -> None:
    """``--sensors``, ``--current``, ``--beacon``, ``--beacon-geodetic``, ``--origin``."""
    p.add_argument(
        "--sensors",
        default=None,
        help="comma-separated: range, dvl-bottom|dvl-water (dvl = dvl-bottom), depth "
        "(default: range)",
    )
    p.add_argument(
        "--current", action="store_true", default=None, help="include an unknown constant current"
    )
    p.add_argument(
        "--beacon", metavar="X,Y[,Z]", default=None, help="beacon position [m] (default: origin)"
    )
    p.add_argument(
        "--beacon-geodetic",
        metavar="LAT,LON[,DEPTH]",
        default=None,
        help="beacon as latitude, longitude [deg] (and depth [m] in 3D), converted to the local "
        "north-east-down frame about --origin",
    )
    p.add_argument(
        "--origin",
        metavar="LAT,LON[,ALT]",
        default=None,
        help="geodetic origin of the trajectory's local north-east-down frame [deg, deg, m]",
    )


def add_output_arguments(p: argparse.ArgumentParser, what: str, default: str | None) -> None:
    """``--out DIR`` and ``--force`` (plan, simulate, paper)."""
    shown = f" (default: {default})" if default else ""
    p.add_argument("--out", metavar="DIR", default=default, help=f"write {what} to DIR{shown}")
    p.add_argument(
        "--force",
        action="store_true",
        help="replace DIR whole if it is an earlier obsplan output (old files removed)",
    )


_NEGATIVE = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)


def join_negative_values(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """``--beacon -50,10`` -> ``--beacon=-50,10`` for every option that takes a value.

    argparse reads a value starting with ``-`` as an option unless it is a plain negative
    number, so negative coordinates, seeds and latitudes would otherwise need ``--opt=-1``.
    """
    takes_value: set[str] = set()
    parsers = [parser]
    while parsers:
        ps = parsers.pop()
        for action in ps._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
            elif action.option_strings and action.nargs is None:
                takes_value.update(action.option_strings)
    out: list[str] = []
    i = 0
    argv = list(argv)
    while i < len(argv):
        tok = argv[i]
        if tok == "--":
            out.extend(argv[i:])
            break
        if tok in takes_value and i + 1 < len(argv) and _NEGATIVE.match(argv[i + 1]):
            out.append(f"{tok}={argv[i + 1]}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


def check_seed(seed: int | None, option: str = "--seed") -> int | None:
    """A seed must be a non-negative integer (numpy's generators refuse negative ones)."""
    if seed is not None and seed < 0:
        raise InputError(f"{option} {seed}: a seed must be a non-negative integer, e.g. 0")
    return seed


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
    limit, unit = COLUMN_LIMITS["px"]  # the same bound as a position in a trajectory CSV
    check_magnitude(values, f"--beacon {text!r}", limit, unit)
    return values


def resolve_beacon(args: argparse.Namespace, dim: int):
    """Beacon position (metric, or geodetic about ``--origin``) and the origin, from ``args``.

    Returns ``(beacon or None, GeodeticOrigin or None)``.
    """
    from obsplan.io.geodetic import parse_geodetic_point, parse_origin

    origin = parse_origin(args.origin) if getattr(args, "origin", None) else None
    geo = getattr(args, "beacon_geodetic", None)
    if geo is not None and args.beacon is not None:
        raise InputError("give either --beacon X,Y[,Z] [m] or --beacon-geodetic, not both")
    if geo is not None:
        return parse_geodetic_point(geo, dim, origin, "--beacon-geodetic"), origin
    return parse_beacon(args.beacon, dim), origin


# ------------------------------------------------------------------------------ inputs
def read_trajectory(path: str, verb: str) -> Trajectory:
    """Read a trajectory CSV, or fit a position-only track on the fly (said on stderr).

    A consistency warning is printed as one line, not a traceback.
    """
    # imported here: `obsplan` installs its signal handlers before numpy and the rest load
    from obsplan.io.tracks import load_trajectory
    from obsplan.trajectory.sampled import InconsistentTrajectoryWarning

    check_file_rows(path, "the trajectory")  # a huge file is refused before it is read
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InconsistentTrajectoryWarning)
        traj, fit = load_trajectory(path, check=True)
    for w in caught:
        if issubclass(w.category, InconsistentTrajectoryWarning):
            print(f"obsplan {verb}: warning: {w.message}", file=sys.stderr)
        else:  # pragma: no cover - pass other warnings on untouched
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if fit is not None:
        rms = max(fit.residual_rms)
        print(
            f"obsplan {verb}: {path} has positions only: fitted piecewise-constant "
            f"accelerations on {fit.nodes} nodes (position residual RMS {rms:.3g} m, "
            f"acceleration std {max(fit.accel_std):.3g} m/s²; `obsplan import` writes them "
            "and has the fit's options)",
            file=sys.stderr,
        )
    return traj


__all__ = [
    "OutputDir",
    "OutputFile",
    "add_output_arguments",
    "add_vehicle_arguments",
    "check_seed",
    "join_negative_values",
    "parse_beacon",
    "read_trajectory",
    "resolve_beacon",
]
