"""The ``obsplan`` command. Each verb lives in its own module exposing ``add_parser`` and ``run``.

Exit codes: 0 success, 1 solver or validation failure, 2 bad input (file, option, problem).
Errors raised on purpose (:mod:`obsplan.errors`) are printed as one line, without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from obsplan import __version__
from obsplan.errors import InputError, ObsplanError

VERBS = ("plan", "analyze", "simulate", "paper")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="obsplan",
        description=(
            "Observability-aware trajectory planning for single-beacon range localisation "
            "(De Palma et al., Ocean Engineering 142, 2017). SI units throughout."
        ),
    )
    parser.add_argument("--version", action="version", version=f"obsplan {__version__}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    sub.required = True
    for verb in VERBS:
        try:
            mod = importlib.import_module(f"obsplan.cli.{verb}")
        except ModuleNotFoundError as exc:  # a verb not built yet must not break the others
            if exc.name != f"obsplan.cli.{verb}":
                raise
            continue
        p = mod.add_parser(sub)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``obsplan`` console script."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except InputError as exc:
        print(f"obsplan {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except FileExistsError as exc:
        print(f"obsplan {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except ObsplanError as exc:
        print(f"obsplan {args.verb}: failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"obsplan {args.verb}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
