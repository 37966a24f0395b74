"""Options and checks shared by the verbs: vehicle options, beacon, inputs and safe outputs.

Outputs, for every verb (and reusable by ``sweep`` and ``paper``):

* :class:`OutputDir` — a results folder. Construct it **before any work**: it refuses a file, a
  non-empty folder without ``--force``, a read-only folder, and a place where nothing can be
  written (it probes the nearest existing parent by creating and removing a folder). Then::

      out = OutputDir(args.out, args.force)       # checks now, writes nothing
      with out:                                   # any exception or Ctrl-C: nothing is left
          result = work()
          staging = out.stage()                   # hidden empty folder beside DIR
          write_files(staging)
          out.commit()                            # DIR replaced whole, atomically

  ``commit`` renames the staging folder over ``DIR`` (an old ``DIR`` is renamed aside first and
  deleted after), so ``--force`` never leaves old files beside new ones and an interruption never
  leaves a half-written folder.
* :class:`OutputFile` — the same for one file (``import --out``, ``export --waypoints``):
  checked at construction, written through :meth:`OutputFile.writing` (temp file + rename).

KeyboardInterrupt is mapped to exit 130 by :func:`obsplan.cli.main`; these helpers only make
sure that nothing half-written remains when it propagates.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import stat
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

from obsplan.atomic import atomic_file, remove_tree, replace_dir, staging_dir
from obsplan.csvtable import COLUMN_LIMITS
from obsplan.errors import InputError
from obsplan.textfiles import check_magnitude
from obsplan.trajectory import InconsistentTrajectoryWarning, Trajectory


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
        "--force", action="store_true", help="replace a non-empty DIR whole (old files removed)"
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
    from obsplan.io.tracks import load_trajectory

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


# ------------------------------------------------------------------------------ outputs
def _read_only(path: Path) -> bool:
    """No write permission for us, or no write bit at all (root ignores permissions, but a
    folder or file its owner made read-only is meant to stay as it is)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not os.access(path, os.W_OK) or not (mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _existing_ancestor(path: Path, option: str) -> Path:
    anc = path.parent if path.parent != path else path
    anc = Path(os.path.abspath(anc))
    while not anc.exists():
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"{option} {path}: {anc} is a file, so nothing can be written under it")
    return anc


def _probe(folder: Path, option: str, path: Path) -> None:
    """Create and remove a folder in ``folder``: the only test that also works as root and on
    read-only or special file systems."""
    try:
        probe = staging_dir(folder / ".obsplan-write-test")
        os.rmdir(probe)
    except OSError as exc:
        raise InputError(
            f"{option} {path}: cannot write in {folder} ({exc.strerror}); choose a writable place"
        ) from None


class OutputDir:
    """A results folder checked before work and replaced whole at the end (see module doc).

    Parameters
    ----------
    path
        The folder (``--out DIR``); missing parents are created at :meth:`stage`.
    force
        Allow replacing a non-empty folder (its old content is removed at :meth:`commit`).
    option
        How messages name the folder (``"--out"``).
    inputs
        Files the verb reads: replacing a folder that holds one of them is refused (``--force``
        must not delete the user's input).
    """

    def __init__(
        self,
        path: str | Path,
        force: bool,
        option: str = "--out",
        inputs: Sequence[str | Path | None] = (),
    ) -> None:
        self.path = Path(path)
        self.option = option
        out = self.path
        if out.exists() and not out.is_dir():
            raise InputError(f"{option} {out} is a file; give a folder")
        if out.is_dir():
            if any(out.iterdir()) and not force:
                raise InputError(
                    f"{option} {out} is not empty; choose another folder or pass --force to "
                    "replace it whole (its files are removed)"
                )
            here = out.resolve()
            for f in inputs:
                if f is not None and here in Path(f).resolve().parents:
                    raise InputError(
                        f"{option} {out} holds the input {f}, which replacing the folder would "
                        "delete; choose another output folder"
                    )
            if _read_only(out):
                raise InputError(
                    f"{option} {out} is read-only; make it writable or choose another folder"
                )
        _probe(_existing_ancestor(out, option), option, out)
        self._staging: Path | None = None
        self._created: list[Path] = []
        self.committed = False

    def stage(self) -> Path:
        """Create (once) and return the empty staging folder to write the results into."""
        if self._staging is None:
            parent = Path(os.path.abspath(self.path.parent))
            missing = []
            while not parent.exists():
                missing.append(parent)
                parent = parent.parent
            for folder in reversed(missing):
                folder.mkdir()
                self._created.append(folder)
            self._staging = staging_dir(self.path.parent / self.path.name)
        return self._staging

    def final(self, staged: Path) -> Path:
        """Where a file written in the staging folder ends up after :meth:`commit`."""
        return self.path / Path(staged).relative_to(self.stage())

    def commit(self) -> Path:
        """Replace ``path`` by the staging folder (atomic rename; old content removed)."""
        replace_dir(self.stage(), self.path)
        self.committed = True
        self._staging = None
        return self.path

    def discard(self) -> None:
        """Remove the staging folder and any parent folder created for it."""
        if self._staging is not None:
            remove_tree(self._staging)
            self._staging = None
        if not self.committed:
            for folder in reversed(self._created):
                with contextlib.suppress(OSError):
                    folder.rmdir()
            self._created = []

    def __enter__(self) -> OutputDir:
        return self

    def __exit__(self, *exc: object) -> None:
        self.discard()


class OutputFile:
    """One output file, checked before work and written atomically.

    Refuses a folder, an existing file without ``force``, one of the verb's ``inputs``, a
    read-only file and a place where nothing can be written.
    """

    def __init__(
        self,
        path: str | Path,
        force: bool,
        option: str,
        inputs: Sequence[str | Path | None] = (),
    ) -> None:
        self.path = Path(path)
        self.option = option
        p = self.path
        if p.is_dir():
            raise InputError(f"{option} {p} is a folder; give a file name")
        if p.exists() and any(f is not None and Path(f).resolve() == p.resolve() for f in inputs):
            raise InputError(f"{option} {p} is the input file; give another name for the output")
        if p.exists():
            if not force:
                raise InputError(
                    f"{option} {p} exists; choose another name or pass --force to replace it"
                )
            if _read_only(p):
                raise InputError(f"{option} {p} is read-only; make it writable or choose another")
        _probe(_existing_ancestor(p, option), option, p)

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """Yield a temporary path; it becomes ``path`` when the block succeeds."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(self.path) as tmp:
            yield tmp


def output_dir(path: str | Path, force: bool) -> Path:
    """Deprecated simple form: check and create ``path`` (not atomic; prefer :class:`OutputDir`).

    Kept for verbs that write their files one by one.
    """
    OutputDir(path, force)
    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    return out
