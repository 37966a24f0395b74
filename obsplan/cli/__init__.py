"""The ``obsplan`` command. Each verb lives in its own module exposing ``add_parser`` and ``run``.

Exit codes: 0 success, 1 solver or validation failure, 2 bad input (file, option, problem),
130 / 143 interrupted by SIGINT / SIGTERM (:mod:`obsplan.core.interrupts`; nothing is left written),
141 the reader of the output went away (``obsplan paper --json | head -c 10``).
Errors raised on purpose (:mod:`obsplan.core.errors`) are printed as one line, without a traceback.

**A closed output.** When the reader of stdout (or stderr) closes it before the verb has said
everything, the verb stops quietly, as a Unix tool killed by SIGPIPE does: nothing is printed,
the exit code is 141 (128 + SIGPIPE, what a shell reports for ``yes | head``; never 1, which
says the computation failed), and stdout is pointed at ``/dev/null`` so that the interpreter's
last flush cannot complain either (Python's recommended handling of ``BrokenPipeError``, with
the shell's code). stdout is flushed when the verb ends, so a pipe closed early is found there,
not in the interpreter's last flush; output files already committed stay. A
``BrokenPipeError`` of anything else (a worker's pipe, with stdout and stderr open) is a failure
like any ``OSError`` (exit 1).
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import select
import signal
import sys
from collections.abc import Sequence
from typing import NoReturn

from obsplan.cli.common import check_option_numbers, join_negative_values
from obsplan.core import interrupts, outputs
from obsplan.core.errors import InputError, ObsplanError
from obsplan.version import __version__

VERBS = (
    "plan",
    "analyze",
    "simulate",
    "paper",
    "sweep",
    "import",
    "export",
    "estimate",
    "problems",
)
#: Exit code of a verb whose output's reader went away: 128 + SIGPIPE, as a shell reports a tool
#: killed by the signal (module docstring).
EXIT_CLOSED_OUTPUT = 128 + 13
#: Module of each verb whose name is not a valid module name.
_MODULES = {"import": "import_track"}


def build_parser() -> argparse.ArgumentParser:
    """The ``obsplan`` argument parser: ``--version`` and one sub-parser per verb of ``VERBS``.

    Each verb's module (``obsplan.cli.<verb>``; ``import_track`` for ``import``) adds its
    sub-parser with ``add_parser`` and sets its ``run`` as the ``_run`` of the parsed
    arguments; a verb whose module is not there is left out.

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan``; a verb is required.
    """
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

    Parameters
    ----------
    argv : sequence of str or None, default None
        The arguments after ``obsplan`` (``["plan", "--out", "DIR"]``); None: ``sys.argv[1:]``,
        as the console script calls it; then an interrupted run ends the process at once
        (outputs undone, exit handlers run) instead of returning, and signals are ignored while
        the interpreter shuts down. With ``argv`` given, the signal handlers in place before
        the call are restored.

    Returns
    -------
    int
        The exit code: 0 success, 1 failure, 2 bad input, 130 / 143 interrupted by SIGINT /
        SIGTERM, 141 the reader of the output went away (the module's docstring).
    """
    previous = interrupts.install()
    interrupts.reset()
    os.environ.setdefault("MPLBACKEND", "Agg")
    code = 1
    try:
        code = _run(argv)
    except BrokenPipeError:  # the reader of stderr went away while an error was said
        code = _closed_output()
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
        check_option_numbers(parser, args)
        code = int(args._run(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's last flush
        interrupts.check()  # a swallowed signal: the exit code says so (outputs are undone)
        return code
    except BrokenPipeError as exc:
        if _output_is_closed():
            return _closed_output()
        print(f"{_who(verb)}: failed: {exc.strerror or exc}", file=sys.stderr)
        return 1
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


def _is_closed(stream) -> bool | None:
    """Whether ``stream`` is a pipe (or socket) whose reader went away; None when it cannot be
    asked (no file descriptor, as under a test's capture)."""
    try:
        poll = select.poll()
        poll.register(stream.fileno(), select.POLLOUT)
        return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poll.poll(0))
    except (OSError, ValueError, AttributeError):
        return None


def _output_is_closed() -> bool:
    """Whether the ``BrokenPipeError`` came from stdout or stderr: one of them is closed, or
    cannot be asked (then the error came from writing to it)."""
    return any(_is_closed(stream) is not False for stream in (sys.stdout, sys.stderr))


def _closed_output() -> int:
    """End a verb whose output's reader went away: stdout (and stderr, if closed too) pointed at
    ``/dev/null``, so that no later write and not the interpreter's last flush fails; returns
    :data:`EXIT_CLOSED_OUTPUT`."""
    for stream in (sys.stdout, sys.stderr):
        if stream is sys.stderr and not _is_closed(stream):
            continue
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, stream.fileno())
            finally:
                os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass  # not a real file (a test's capture): nothing will flush into a pipe
    return EXIT_CLOSED_OUTPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
