"""The ``obsplan`` command. Each verb lives in its own module exposing ``add_parser`` and ``run``.

Exit codes: 0 success, 1 solver or validation failure, 2 bad input (file, option, problem),
130 / 143 interrupted by SIGINT / SIGTERM (:mod:`obsplan.core.interrupts`; nothing is left written).
Errors raised on purpose (:mod:`obsplan.core.errors`) are printed as one line, without a traceback.
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import signal
import sys
from collections.abc import Sequence
from typing import NoReturn

from obsplan.cli.common import join_negative_values
from obsplan.core import interrupts, outputs
from obsplan.core.errors import InputError, ObsplanError
from obsplan.version import __version__

VERBS = ("plan", "analyze", "simulate", "paper", "sweep", "import", "export", "problems")
#: Module of each verb whose name is not a valid module name.
_MODULES = {"import": "import_track"}


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
            mod = importlib.import_module(f"obsplan.cli.{_MODULES.get(verb, verb)}")
        except ModuleNotFoundError as exc:  # a verb not built yet must not break the others
            if exc.name != f"obsplan.cli.{_MODULES.get(verb, verb)}":
                raise
            continue
        p = mod.add_parser(sub)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``obsplan`` console script; returns the exit code.

    0 success, 1 solver/validation failure (or an output that could not be written), 2 bad
    input (one line naming the field and the fix), 130 / 143 interrupted by SIGINT / SIGTERM at
    any moment (outputs are swapped in atomically and undone if the signal came after the swap,
    so nothing is left written).
    """
    previous = interrupts.install()
    interrupts.reset()
    os.environ.setdefault("MPLBACKEND", "Agg")
    code = 1
    try:
        code = _run(argv)
    except BaseException as exc:  # a signal turned into another error (e.g. inside CasADi)
        if interrupts.pending() is None:
            raise
        with interrupts.ignored():
            print(_interrupted_message("", exc), file=sys.stderr)
    finally:
        signalled = interrupts.exit_code()
        outputs.finish(undo=signalled is not None)
        if argv is None:
            # the console script: the work is done and whole; a signal while the interpreter
            # shuts down (seconds on a loaded machine) must not turn it into a kill
            interrupts.ignore_all()
            if signalled is not None:
                _exit_now(signalled)
        else:
            interrupts.uninstall(previous)
    return code if signalled is None else signalled


def _exit_now(code: int) -> NoReturn:
    """End the interrupted console script with ``code``, skipping the interpreter's
    finalisation.

    The outputs are already undone and the exit handlers (temporary folders, worker pools) run
    here; what is skipped is the teardown of threads a signal left inside native code (a numba
    or BLAS pool stopped mid-loop), which once aborted the process (SIGABRT, "PyThreadState_Get
    ... finalizing") after it had printed that nothing was written.
    """
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe: nothing more can be said
                pass
        os._exit(code)


def _interrupted_message(verb: str, exc: BaseException) -> str:
    signum = interrupts.pending()
    by = f" by {signal.Signals(signum).name}" if signum not in (None, signal.SIGINT) else ""
    kept = getattr(exc, "kept", None) or "nothing was written"
    return f"{_who(verb)}: interrupted{by}; {kept}"


def _who(verb: str) -> str:
    return f"obsplan {verb}" if verb else "obsplan"


def _run(argv: Sequence[str] | None) -> int:
    verb = ""
    try:
        parser = build_parser()
        args = parser.parse_args(
            join_negative_values(parser, sys.argv[1:] if argv is None else argv)
        )
        verb = args.verb
        code = int(args._run(args) or 0)
        interrupts.check()  # a swallowed signal: the exit code says so (outputs are undone)
        return code
    except InputError as exc:
        print(f"{_who(verb)}: error: {exc}", file=sys.stderr)
        return 2
    except FileExistsError as exc:
        print(f"{_who(verb)}: error: {exc}", file=sys.stderr)
        return 2
    except ObsplanError as exc:
        print(f"{_who(verb)}: failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        with interrupts.ignored():
            print(_interrupted_message(verb, exc), file=sys.stderr)
        return exc.exit_code if isinstance(exc, interrupts.Interrupted) else 130
    except OSError as exc:  # e.g. the disk filled up while writing results
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"{_who(verb)}: failed: {exc.strerror or exc}{where}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
