"""Options and checks shared by the verbs: vehicle options, beacon, inputs, and the outputs.

Two rules of the argument layer hold for every verb, so that no option is silently accepted:

* **numbers**: every option that takes a number (``type=float``) is judged by the one rule of
  :func:`~obsplan.core.textfiles.check_magnitude` against its unit's limit in
  :func:`option_limits` (:func:`check_option_numbers`, run by :func:`obsplan.cli.main` before
  the verb; ``tests/test_cli_input_classes.py`` holds every float option to the table);
* **what applies**: an option that only means something for some inputs (``--topic`` for ROS
  bags, ``--origin`` with a geodetic beacon, ``--acceptance-radius`` with ``--qgc``) is declared
  as an :class:`Applies` rule by its verb and refused by :func:`check_applies` when given where
  it does not apply: ``"--topic applies to ROS bags; LOG is a CSV: remove it"``.

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
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

from obsplan.core.budget import check_file_rows
from obsplan.core.csvtable import COLUMN_LIMITS
from obsplan.core.errors import InputError
from obsplan.core.outputs import OutputDir, OutputFile
from obsplan.core.textfiles import check_magnitude
from obsplan.model.beacon import BeaconPath, read_beacon_path

if TYPE_CHECKING:
    from obsplan.trajectory.sampled import Trajectory


# ------------------------------------------------------------------------------ numbers
@cache
def option_limits() -> dict[str, tuple[float, str]]:
    """Largest size and unit of every number option (``type=float``) of every verb; the
    smallest non-zero size accepted is the inverse of the largest (a step of 1e-320 s overflows
    what it divides).

    The limits are the trajectory CSV's (:data:`~obsplan.core.csvtable.COLUMN_LIMITS`), the
    scales' (:data:`~obsplan.observability.scaling.MAX_SCALE`) and the geodetic frame's
    (:data:`~obsplan.model.frames.MAX_DEPTH_M`); a function, so that the command line loads
    the model only once its signal handlers are installed.

    Returns
    -------
    dict of str to (float, str)
        Option (``"--dt"``) -> its largest size and its unit (``(1e10, "s")``).
    """
    from obsplan.model.frames import MAX_DEPTH_M
    from obsplan.observability.scaling import MAX_SCALE

    seconds, metres = COLUMN_LIMITS["t"], COLUMN_LIMITS["px"]
    speed, accel = COLUMN_LIMITS["vx"], COLUMN_LIMITS["ux"]
    return {
        "--length-scale": (MAX_SCALE, "m"),
        "--time-scale": (MAX_SCALE, "s"),
        "--dt": seconds,
        "--accel-noise": (accel[0], "m/s²/√Hz"),
        "--accel": accel,
        "--speed": speed,
        "--grid": seconds,
        "--position-std": metres,
        "--velocity-std": speed,
        "--max-gap": seconds,
        "--every": seconds,
        "--spacing": metres,
        "--depth": (MAX_DEPTH_M, "m"),
        "--acceptance-radius": metres,
        "--replan": seconds,
        "--range-std": metres,
        "--dvl-std": speed,
        "--depth-std": (MAX_DEPTH_M, "m"),
        "--accel-std": (accel[0], "m/s²/√Hz"),
        "--init-std": metres,
        "--init-velocity-std": speed,
        "--gate": (1e6, ""),  # a probability; (0, 1] is checked by the verb
    }


def verb_parser(parser: argparse.ArgumentParser, verb: str) -> argparse.ArgumentParser:
    """The sub-parser of ``verb`` in the ``obsplan`` parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``obsplan`` parser (:func:`obsplan.cli.build_parser`).
    verb : str
        One of its verbs, ``"plan"``.

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan <verb>``.

    Raises
    ------
    KeyError
        ``verb`` is not a verb of ``parser`` (or ``parser`` has no verbs).
    """
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices[verb]
    raise KeyError(verb)  # pragma: no cover - the parser always has its verbs


def check_option_numbers(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse a number option of ``args.verb`` beyond its limit in :func:`option_limits`, or
    non-zero below its inverse, or not finite: one line naming the option and its unit.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``obsplan`` parser (:func:`obsplan.cli.build_parser`).
    args : argparse.Namespace
        The parsed arguments; ``args.verb`` names the verb whose number options are judged
        (those not given, None, are not).

    Raises
    ------
    InputError
        ``"<option>: <value> <unit> is beyond ±<limit> <unit>, ..."`` (or below the inverse, or
        not a finite number).
    """
    for action in verb_parser(parser, args.verb)._actions:
        value = getattr(args, action.dest, None)
        if action.type is float and value is not None:
            option = action.option_strings[-1]
            limit, unit = option_limits()[option]
            check_magnitude(value, option, limit, unit, smallest=1.0 / limit)


# ------------------------------------------------------------------------------ what applies
@dataclass(frozen=True)
class Applies:
    """An option that means something only for some inputs.

    Attributes
    ----------
    option : str
        The option, ``"--topic"``.
    to : str
        Where it applies, in words: ``"ROS bags"``.
    when : str
        The name of the fact (a key of :func:`check_applies`'s ``facts``) that holds where it
        applies: ``"rosbag"``.
    """

    option: str
    to: str
    when: str


def option_given(args: argparse.Namespace, option: str) -> bool:
    """Whether ``option`` was given (options that a rule judges default to None or False).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed arguments.
    option : str
        The option as typed, ``"--beacon-geodetic"`` (read from ``args.beacon_geodetic``).

    Returns
    -------
    bool
        True when its value is neither None nor False.
    """
    value = getattr(args, option.lstrip("-").replace("-", "_"), None)
    return value is not None and value is not False


def check_applies(
    args: argparse.Namespace, rules: Iterable[Applies], facts: Mapping[str, str | None]
) -> None:
    """Refuse the first option given whose rule's fact does not hold.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed arguments.
    rules : iterable of Applies
        The verb's rules.
    facts : Mapping of str to str or None
        Fact name -> None when it holds, else what holds instead, in words (``"LOG is a
        CSV"``). Rules whose fact is not in ``facts`` are not judged (yet: an input's content
        is known once it is read).

    Raises
    ------
    InputError
        ``"<option> applies to <to>; <what holds instead>: remove it"``.
    """
    for rule in rules:
        instead = facts.get(rule.when)
        if instead is not None and option_given(args, rule.option):
            raise InputError(f"{rule.option} applies to {rule.to}; {instead}: remove it")


def given_fact(holds: bool, instead: str) -> str | None:
    """A fact for :func:`check_applies`: None when it ``holds``, else ``instead``.

    Parameters
    ----------
    holds : bool
        Whether the fact holds (the option applies).
    instead : str
        What holds instead, in words (``"no --out is given"``), for the refusal's message.

    Returns
    -------
    str or None
        None when ``holds``, else ``instead``.
    """
    return None if holds else instead


# ------------------------------------------------------------------------------ arguments
def add_vehicle_arguments(p: argparse.ArgumentParser) -> None:
    """``--sensors``, ``--current``, ``--beacon``, ``--beacon-geodetic``, ``--origin``.

    Each defaults to None (read by :func:`resolve_beacon` and the verb).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The verb's parser, to which the options are added.
    """
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
    """``--out DIR`` and ``--force`` (plan, simulate, paper).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The verb's parser, to which the options are added.
    what : str
        What the verb writes to DIR, in words, for the help (``"figures"``).
    default : str or None
        The default folder, shown in the help; None: no default (nothing is written without
        ``--out``).
    """
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

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``obsplan`` parser; the options of it and of every verb's sub-parser that take one
        value are joined.
    argv : sequence of str
        The arguments after ``obsplan``; those after ``--`` are left as they are.

    Returns
    -------
    list of str
        ``argv`` with every such option and its negative value (``-50,10``, ``-.5``, ``-inf``,
        ``-nan``) joined by ``=``.
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
    """A seed must be a non-negative integer (numpy's generators refuse negative ones).

    Parameters
    ----------
    seed : int or None
        The seed given; None: none given.
    option : str, default "--seed"
        The option, for the message.

    Returns
    -------
    int or None
        ``seed``, unchanged.

    Raises
    ------
    InputError
        A negative seed.
    """
    if seed is not None and seed < 0:
        raise InputError(f"{option} {seed}: a seed must be a non-negative integer, e.g. 0")
    return seed


def parse_beacon(text: str | None, dim: int) -> tuple[float, ...] | None:
    """``"x,y[,z]"`` -> floats, checked against the trajectory dimension.

    Parameters
    ----------
    text : str or None
        The ``--beacon`` value, coordinates [m] separated by commas; None: not given.
    dim : int
        The trajectory's dimension, 2 or 3: the number of coordinates expected.

    Returns
    -------
    tuple of float or None
        The beacon position [m], shape ``(dim,)``; None when ``text`` is None.

    Raises
    ------
    InputError
        Not ``dim`` finite numbers, or a coordinate beyond the limit of a trajectory CSV's
        positions.
    """
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


def add_channel_argument(p: argparse.ArgumentParser) -> None:
    """``--channel NAME``: the acoustic channel of the truth's ranges, a preset of
    :data:`~obsplan.estimation.channel.CHANNEL_PRESETS` (checked by the verb, which reads it with
    :func:`channel_error`); it overrides ``validation.channel``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The verb's parser.
    """
    p.add_argument(
        "--channel",
        metavar="NAME",
        default=None,
        help="the acoustic channel the truth's ranges go through, unknown to the filters: "
        '"ideal" (Gaussian ranges) or "at-sea" (multipath outliers, lost pings, a sound-speed '
        "error); overrides validation.channel (default ideal)",
    )


def channel_error(exc: Exception) -> InputError:
    """The error of a bad ``--channel``: the message of ``exc`` after its field name, on the
    option.

    Parameters
    ----------
    exc : Exception
        The error of the channel's check (``validation.channel: ...`` or ``channel: ...``).

    Returns
    -------
    InputError
        ``--channel: <message>``.
    """
    return InputError(f"--channel: {str(exc).split(': ', 1)[-1]}")


def add_beacon_path_argument(p: argparse.ArgumentParser) -> None:
    """``--beacon-path B.csv``: a moving beacon along a trajectory (read by
    :func:`resolve_beacon_path`).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The verb's parser (one with :func:`add_vehicle_arguments` and a ``trajectory``).
    """
    p.add_argument(
        "--beacon-path",
        metavar="B.csv",
        default=None,
        help="a moving beacon: CSV t,bx,by (2D) or t,bx,by,bz (3D) [s, m] in the trajectory's "
        "frame, linearly interpolated, covering the trajectory's time span (instead of --beacon)",
    )


def resolve_beacon_path(
    args: argparse.Namespace, dim: int, beacon: tuple[float, ...] | None, t0: float, t1: float
) -> BeaconPath | None:
    """The ``--beacon-path``, read and checked against the trajectory; None when not given.

    Parameters
    ----------
    args : argparse.Namespace
        Arguments with :func:`add_beacon_path_argument`, :func:`add_vehicle_arguments` and
        ``trajectory``.
    dim : int
        The trajectory's dimension, 2 or 3.
    beacon : tuple of float or None
        The fixed beacon :func:`resolve_beacon` returned (None: none given).
    t0, t1 : float
        The trajectory's time span [s], which the path must cover.

    Returns
    -------
    BeaconPath or None
        The path; None without ``--beacon-path``.

    Raises
    ------
    InputError
        A fixed beacon given as well, or a path that does not read, is of another dimension or
        does not cover ``[t0, t1]``.
    """
    if args.beacon_path is None:
        return None
    if beacon is not None:
        given = "--beacon" if args.beacon is not None else "--beacon-geodetic"
        raise InputError(
            f"give either {given} (a fixed beacon) or --beacon-path (a moving one), not both"
        )
    where = f"--beacon-path {args.beacon_path}"
    path = read_beacon_path(args.beacon_path, dim, where)
    path.check_covers(t0, t1, f"{where} (the trajectory {args.trajectory})")
    return path


#: The vehicle options that apply only to some inputs (:func:`resolve_beacon`).
VEHICLE_APPLIES = (
    Applies("--origin", "a geodetic beacon (--beacon-geodetic, whose frame it fixes)", "geodetic"),
)
NO_GEODETIC = "no --beacon-geodetic is given"


def resolve_beacon(args: argparse.Namespace, dim: int):
    """Beacon position (metric, or geodetic about ``--origin``) and the origin, from ``args``.

    Returns ``(beacon or None, GeodeticOrigin or None)``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed arguments of a verb with :func:`add_vehicle_arguments` (``--beacon``,
        ``--beacon-geodetic``, ``--origin``).
    dim : int
        The trajectory's dimension, 2 or 3.

    Returns
    -------
    beacon : tuple of float or None
        The beacon position [m] in the trajectory's frame, shape ``(dim,)`` (a geodetic beacon
        converted to north-east-down about the origin); None when neither option is given (the
        beacon is at the origin).
    origin : GeodeticOrigin or None
        The ``--origin``; None when not given.

    Raises
    ------
    InputError
        Both ``--beacon`` and ``--beacon-geodetic``, ``--origin`` without
        ``--beacon-geodetic``, ``--beacon-geodetic`` without ``--origin``, or a malformed
        value.
    """
    from obsplan.io.geodetic import parse_geodetic_point, parse_origin

    geo = getattr(args, "beacon_geodetic", None)
    check_applies(args, VEHICLE_APPLIES, {"geodetic": given_fact(geo is not None, NO_GEODETIC)})
    origin = parse_origin(args.origin) if getattr(args, "origin", None) else None
    if geo is not None and args.beacon is not None:
        raise InputError("give either --beacon X,Y[,Z] [m] or --beacon-geodetic, not both")
    if geo is not None:
        return parse_geodetic_point(geo, dim, origin, "--beacon-geodetic"), origin
    return parse_beacon(args.beacon, dim), origin


# ------------------------------------------------------------------------------ inputs
def read_trajectory(path: str, verb: str, beacon: bool = False) -> Trajectory:
    """Read a trajectory CSV, or fit a position-only track on the fly (said on stderr).

    A consistency warning is printed as one line, not a traceback.

    Parameters
    ----------
    path : str
        The CSV: a trajectory (``t,px,py[,pz],vx,vy[,vz],ux,uy[,uz]``) or a position-only
        track (``t,px,py[,pz]``).
    verb : str
        The verb reading it, for the messages on stderr (``"analyze"``).
    beacon : bool, optional
        Also read a planned beacon's ``beacon.csv`` (``t,bx,by[,bz],vbx,vby[,vbz]``) as the
        craft's trajectory (:func:`obsplan.io.tracks.beacon_trajectory_from_table`).

    Returns
    -------
    Trajectory
        The trajectory, read or fitted (:func:`obsplan.io.tracks.load_trajectory`).

    Raises
    ------
    InputError
        A file that is missing, too large (:func:`obsplan.core.budget.check_file_rows`) or
        malformed.
    """
    # imported here: `obsplan` installs its signal handlers before numpy and the rest load
    from obsplan.io.tracks import load_trajectory
    from obsplan.trajectory.sampled import InconsistentTrajectoryWarning

    check_file_rows(path, "the trajectory")  # a huge file is refused before it is read
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InconsistentTrajectoryWarning)
        traj, fit = load_trajectory(path, check=True, beacon=beacon)
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
    "Applies",
    "OutputDir",
    "OutputFile",
    "add_output_arguments",
    "add_vehicle_arguments",
    "check_applies",
    "check_option_numbers",
    "check_seed",
    "given_fact",
    "join_negative_values",
    "option_given",
    "option_limits",
    "parse_beacon",
    "read_trajectory",
    "resolve_beacon",
    "verb_parser",
]
