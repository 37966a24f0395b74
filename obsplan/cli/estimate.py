"""``obsplan estimate LOG.csv --out DIR``: a logged mission replayed, filtered and smoothed.

Reads the logged-mission CSV (:mod:`obsplan.io.missionlog`), runs the gated EKF and the RTS
smoother (:mod:`obsplan.estimation.replay.smoother`) and writes ``DIR/track.csv``,
``DIR/ranges.csv``, ``DIR/estimate.json`` and the figures ``track.png`` and ``ranges.png``
through the safe output folder (:class:`~obsplan.core.outputs.OutputDir`).
"""

from __future__ import annotations

import argparse
import json

from obsplan.cli.common import OutputDir, add_output_arguments, parse_beacon
from obsplan.core.csvtable import write_table
from obsplan.core.errors import InputError
from obsplan.estimation.replay.smoother import (
    DEFAULT_ACCEL_STD,
    DEFAULT_DEPTH_STD,
    DEFAULT_DVL_STD,
    DEFAULT_INIT_VELOCITY_STD,
    DEFAULT_RANGE_STD,
    GATE_PROBABILITY,
    REACQUIRE_AFTER,
    ReplayConfig,
    replay,
)
from obsplan.io.missionlog import read_mission_log
from obsplan.model.beacon import read_beacon_path

#: The files ``obsplan estimate`` writes in ``--out``.
OUTPUTS = ("track.csv", "ranges.csv", "estimate.json", "track.png", "ranges.png")


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``estimate`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan estimate``: ``LOG.csv``, ``--out``, ``--force``, ``--beacon``,
        ``--beacon-path``, ``--dvl``, ``--current``, the noises, ``--init``, ``--init-std``,
        ``--init-velocity``, ``--init-velocity-std``, ``--gate``, ``--reacquire-after`` and
        ``--json``.
    """
    p = subparsers.add_parser(
        "estimate",
        help="a logged mission replayed: filtered and RTS-smoothed track, outliers marked",
        description=(
            "Replay a logged mission (t, inputs ux,uy[,uz] or DVL velocities dvx,dvy[,dvz], "
            "range with empty cells where none, optional depth, optional moving beacon "
            "bx,by[,bz], optional truth px,py[,pz]; docs/guides/real-inputs.md): an EKF whose "
            "NIS gate rejects multipath outliers and re-acquires after a run of rejections, "
            "then a Rauch-Tung-Striebel smoother. Writes track.csv, ranges.csv, estimate.json "
            "and figures to --out."
        ),
    )
    p.add_argument("log", metavar="LOG.csv", help="logged-mission CSV")
    add_output_arguments(p, "track.csv, ranges.csv, estimate.json and figures", None)
    p.add_argument(
        "--beacon", metavar="X,Y[,Z]", default=None, help="fixed beacon [m] (default: origin)"
    )
    p.add_argument(
        "--beacon-path",
        metavar="B.csv",
        default=None,
        help="moving beacon t,bx,by[,bz], read at each range's time (not with bx,by columns)",
    )
    p.add_argument(
        "--dvl",
        choices=("bottom", "water"),
        default="bottom",
        help="what the dv* columns measure: bottom-track v + current (default) or water-track v",
    )
    p.add_argument("--current", action="store_true", help="estimate an unknown constant current")
    p.add_argument(
        "--scale-state",
        action="store_true",
        help="estimate the ranges' scale (a sound-speed error; prior std 2 %%)",
    )
    p.add_argument(
        "--bias-state",
        action="store_true",
        help="estimate a range bias (a clock offset; prior std 3 m)",
    )
    for opt, unit, default in (
        ("--range-std", "m", DEFAULT_RANGE_STD),
        ("--dvl-std", "m/s", DEFAULT_DVL_STD),
        ("--depth-std", "m", DEFAULT_DEPTH_STD),
        ("--accel-std", "m/s²/√Hz", DEFAULT_ACCEL_STD),
    ):
        what = "white-acceleration density (process noise)" if opt == "--accel-std" else "noise std"
        p.add_argument(
            opt, type=float, default=default, help=f"{what} [{unit}] (default {default:g})"
        )
    p.add_argument(
        "--init",
        metavar="X,Y[,Z]",
        default=None,
        help="initial position guess [m] (default: the first range north of the beacon)",
    )
    p.add_argument(
        "--init-std",
        type=float,
        default=None,
        help="its std per axis [m] (default: the first range)",
    )
    p.add_argument(
        "--init-velocity",
        metavar="VX,VY[,VZ]",
        default=None,
        help="initial velocity guess [m/s] (default: the first DVL reading, else at rest)",
    )
    p.add_argument(
        "--init-velocity-std",
        type=float,
        default=DEFAULT_INIT_VELOCITY_STD,
        help=f"its std per axis [m/s] (default {DEFAULT_INIT_VELOCITY_STD:g})",
    )
    p.add_argument(
        "--gate",
        type=float,
        default=GATE_PROBABILITY,
        help="confidence of the range NIS gate, in (0, 1]; 1: no gate "
        f"(default {GATE_PROBABILITY:g})",
    )
    p.add_argument(
        "--reacquire-after",
        metavar="K",
        type=int,
        default=REACQUIRE_AFTER,
        help="re-acquire after K consecutive rejected ranges; 0: never "
        f"(default {REACQUIRE_AFTER})",
    )
    p.add_argument("--json", action="store_true", help="print estimate.json instead of the summary")
    return p


def _vector(text: str | None, dim: int, option: str) -> tuple[float, ...] | None:
    """``"x,y[,z]"`` of ``option`` as ``dim`` floats (the --beacon rule, renamed)."""
    if text is None:
        return None
    try:
        return parse_beacon(text, dim)
    except InputError as exc:
        raise InputError(str(exc).replace("--beacon", option, 1)) from None


def _config(args: argparse.Namespace, dim: int) -> ReplayConfig:
    if not 0.0 < args.gate <= 1.0:
        raise InputError(f"--gate {args.gate:g}: a confidence in (0, 1], e.g. --gate 0.999")
    if args.reacquire_after < 0:
        raise InputError(f"--reacquire-after {args.reacquire_after}: 0 (never) or a count, e.g. 5")
    path = None
    if args.beacon_path is not None:
        if args.beacon is not None:
            raise InputError(
                "give either --beacon (a fixed beacon) or --beacon-path (a moving one), not both"
            )
        path = read_beacon_path(args.beacon_path, dim, f"--beacon-path {args.beacon_path}")
    return ReplayConfig(
        range_std=args.range_std,
        dvl_std=args.dvl_std,
        depth_std=args.depth_std,
        accel_std=args.accel_std,
        init=_vector(args.init, dim, "--init"),
        init_std=args.init_std,
        init_velocity=_vector(args.init_velocity, dim, "--init-velocity"),
        init_velocity_std=args.init_velocity_std,
        current=args.current,
        scale_state=args.scale_state,
        bias_state=args.bias_state,
        gate_probability=args.gate,
        reacquire_after=args.reacquire_after or None,
        beacon=parse_beacon(args.beacon, dim),
        beacon_path=path,
    )


def run(args: argparse.Namespace) -> int:
    """Run ``obsplan estimate``; 0 on success.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 (the outputs written).

    Raises
    ------
    InputError
        A log that cannot be read (no ranges, neither inputs nor DVL, unknown dimension, times
        going back, ...), a bad option or beacon, or an ``--out`` that cannot be written
        (exit 2).
    """
    if args.out is None:
        raise InputError("--out DIR is needed: the folder for track.csv, ranges.csv and figures")
    out = OutputDir(args.out, args.force, inputs=[args.log, args.beacon_path], verb="estimate")
    log = read_mission_log(args.log, args.dvl, where=args.log)
    res = replay(log, _config(args, log.dim))
    report = res.to_dict()
    staging = out.stage()
    write_table(staging / "track.csv", *res.track_table())
    write_table(staging / "ranges.csv", *res.range_table())
    (staging / "estimate.json").write_text(json.dumps(report, indent=2) + "\n")
    for kind in ("track", "ranges"):
        res.plot(kind).savefig(staging / f"{kind}.png", dpi=110)
    out.commit()
    if args.json:
        print(json.dumps({**report, "out": str(out.path)}, indent=2))
    else:
        print(res.summary())
        print(f"wrote {out.path}/ ({', '.join(OUTPUTS)})")
    return 0
