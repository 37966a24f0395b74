"""Options and checks shared by the verbs: vehicle options, beacon, trajectory input, outputs."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

from obsplan.errors import InputError
from obsplan.trajectory import InconsistentTrajectoryWarning, Trajectory, read_csv


def add_vehicle_arguments(p: argparse.ArgumentParser) -> None:
    """``--sensors``, ``--current`` and ``--beacon`` (analyze, simulate)."""
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


def add_output_arguments(p: argparse.ArgumentParser, what: str, default: str | None) -> None:
    """``--out DIR`` and ``--force`` (plan, simulate, paper)."""
    shown = f" (default: {default})" if default else ""
    p.add_argument("--out", metavar="DIR", default=default, help=f"write {what} to DIR{shown}")
    p.add_argument("--force", action="store_true", help="write into a non-empty DIR")


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


def read_trajectory(path: str, verb: str) -> Trajectory:
    """Read a trajectory CSV; a consistency warning is printed as one line, not a traceback."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InconsistentTrajectoryWarning)
        traj = read_csv(path, check=True)
    for w in caught:
        if issubclass(w.category, InconsistentTrajectoryWarning):
            print(f"obsplan {verb}: warning: {w.message}", file=sys.stderr)
        else:  # pragma: no cover - pass other warnings on untouched
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return traj


def output_dir(path: str | Path, force: bool) -> Path:
    """Create ``path``; refuse a file, or a non-empty folder unless ``force`` (user results)."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} is a file; give a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise InputError(
            f"--out {out} is not empty; choose another folder or pass --force to overwrite "
            "its files"
        )
    out.mkdir(parents=True, exist_ok=True)
    return out
