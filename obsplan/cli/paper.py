"""``obsplan paper``: the paper's Tables 1–3 with our verdict beside each of the paper's.

Prints the tables (or JSON with ``--json``); with ``--out DIR`` also writes ``DIR/tables.txt`` and
``DIR/tables.json`` and, unless ``--no-figures``, the figure scenarios (Figs. 1–9) when
:mod:`obsplan.paper.figures` is available. Disagreements with the paper are results, not errors:
the exit code is 0.
"""

from __future__ import annotations

import argparse
import json
import sys

from obsplan.cli.common import Applies, OutputDir, check_applies, given_fact
from obsplan.paper.tables import all_rows, claims, paper_report, render_tables, structural


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``paper`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan paper``: ``--out``, ``--json``, ``--quick``, ``--force``,
        ``--no-figures`` and ``--quiet``.
    """
    p = subparsers.add_parser(
        "paper",
        help="regenerate the paper's Tables 1-3 (and figure scenarios) beside our verdicts",
        description=(
            "Recompute every row of the paper's Tables 1-3 (LWO along the trajectory and "
            "augmented-Gramian rank) on representative trajectories, print the paper's verdicts "
            "beside ours and explain each disagreement; then the checked claims of sections 4-7 "
            "and the exact (rational) first full-rank intervals of the held-input Gramian."
        ),
    )
    p.add_argument("--out", metavar="DIR", help="also write tables.txt, tables.json (and figures)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the text tables")
    p.add_argument(
        "--quick", action="store_true", help="sample at 0.1 s instead of 0.01 s (same verdicts)"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace --out DIR whole if it is an earlier obsplan output (old files removed)",
    )
    p.add_argument("--no-figures", action="store_true", help="with --out: skip the figures")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    return p


#: Options that apply only with an output folder (:func:`obsplan.cli.common.check_applies`).
APPLIES = (
    Applies("--force", "an output folder (--out)", "out"),
    Applies("--no-figures", "an output folder (--out)", "out"),
)


def run(args: argparse.Namespace) -> int:
    """Compute, print and optionally write the tables; returns the exit code.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0, whatever the verdicts (a disagreement with the paper is a result).

    Raises
    ------
    InputError
        ``--force`` or ``--no-figures`` without ``--out``, or an ``--out`` folder that cannot
        be written or replaced (exit 2).
    """
    check_applies(args, APPLIES, {"out": given_fact(args.out is not None, "no --out is given")})
    out = OutputDir(args.out, args.force, verb="paper") if args.out is not None else None
    if not args.quiet:
        dt = "0.1 s" if args.quick else "0.01 s"
        print(f"obsplan paper: computing Tables 1-3 (dt = {dt})...", file=sys.stderr)
    rows, cl = all_rows(args.quick), claims(args.quick)
    text = render_tables(rows, cl, structural(args.quick))
    report = paper_report(args.quick)
    if out is None:
        print(json.dumps(report, indent=2) if args.json else text)
        return 0
    with out:  # the folder appears whole (tables and figures) or not at all
        staging = out.stage()
        (staging / "tables.txt").write_text(text + "\n", encoding="utf-8")
        (staging / "tables.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        figures = [] if args.no_figures else _figures(staging, args)
        out.commit()
    print(json.dumps(report, indent=2) if args.json else text)
    if not args.quiet:
        extra = f" and {len(figures)} figures" if figures else ""
        print(
            f"obsplan paper: wrote {out.path / 'tables.txt'}, {out.path / 'tables.json'}{extra}",
            file=sys.stderr,
        )
    return 0


def _figures(folder, args: argparse.Namespace) -> list:
    try:
        from obsplan.paper.figures import write_figures
    except ModuleNotFoundError as exc:
        if exc.name != "obsplan.paper.figures":
            raise
        if not args.quiet:
            print("obsplan paper: figure scenarios not available yet; skipped", file=sys.stderr)
        return []
    return write_figures(folder, quick=args.quick, progress=not args.quiet)
