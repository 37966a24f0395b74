"""SIGINT and SIGTERM at any moment: one exception, one exit code, nothing half-written.

The command line calls :func:`install` first. From then on both signals raise
:class:`Interrupted` (a :class:`KeyboardInterrupt`, so every ``except KeyboardInterrupt`` and
``finally`` that cleans up after Ctrl-C also runs on a batch scheduler's SIGTERM), and the
signal is remembered:

* Python cannot raise it inside a ``__del__`` or a weakref callback: an unraisable-exception
  hook delivers the signal again instead of printing "Exception ignored", so it is raised in the
  code that was running;
* a native library may swallow the exception (CasADi turns it into a solver status);
  :func:`check` raises it again at the next checkpoint
  (after each solve, before an output is committed) and :func:`exit_code` gives 130 / 143 even
  if the verb then returned normally or failed with another exception;
* a second signal while the first unwinds is ignored, so that cleanup (removing a staging
  folder, stopping worker processes) is not cut short.

Worker processes call :func:`child_init`: Ctrl-C in a terminal and a batch scheduler's SIGTERM
reach the whole process group, and only the parent decides (it stops its workers); a child
ignores both and dies with its parent even if the parent is killed hard.
"""

from __future__ import annotations

import _thread
import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

#: The signals handled, in the order a terminal and a batch scheduler send them.
SIGNALS = (signal.SIGINT, signal.SIGTERM)

_PR_SET_PDEATHSIG = 1  # linux/prctl.h

_pending: int | None = None
_installed = False
_redeliver = False
_redeliver_pid = -1  # the process that armed the re-delivery (not a forked child)
_in_hook = False
_previous_unraisablehook: Any = None


class Interrupted(KeyboardInterrupt):
    """Raised by SIGINT or SIGTERM once :func:`install` ran.

    Attributes
    ----------
    signum : int
        The signal received.
    """

    def __init__(self, signum: int = signal.SIGINT) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """128 + the signal number, as a shell reports a process the signal stopped."""
        return 128 + self.signum


def _handler(signum: int, frame: object) -> None:
    global _pending, _redeliver
    # our re-delivery of an Interrupted that Python could not raise; a forked child inherits
    # the flag but must not raise (its parent decides)
    if _redeliver and _redeliver_pid == os.getpid():
        if _in_hook:  # still inside the hook, where it would be lost again: once more, later
            _redeliver_later()
            return
        _redeliver = False
        raise Interrupted(_pending if _pending is not None else signum)
    if _pending is not None:  # already unwinding: let the cleanup finish
        return
    _pending = signum
    raise Interrupted(signum)


def _redeliver_later() -> None:
    # from another thread, so that the handler runs in the main thread's own code, after the
    # ``__del__`` or callback that swallowed it has returned (``signal.raise_signal`` would run
    # it at once, inside that callback again)
    main = threading.main_thread().ident
    signum = _pending if _pending is not None else signal.SIGINT

    def send() -> None:
        time.sleep(0.001)  # long enough for the callback to return (a few bytecodes)
        signal.pthread_kill(main, signum)  # type: ignore[arg-type]

    if main is not None:
        _thread.start_new_thread(send, ())  # does not wait for the thread, unlike Thread.start


def _unraisablehook(unraisable: Any) -> None:
    """Keep an :class:`Interrupted` that Python could not raise (it came inside a ``__del__`` or a
    weakref callback) from printing "Exception ignored" and from being lost: deliver the signal
    again, so that it is raised in the code that was running."""
    global _redeliver, _redeliver_pid, _in_hook
    exc = getattr(unraisable, "exc_value", None)
    if isinstance(exc, Interrupted) and _installed:
        _in_hook = True
        try:
            _redeliver, _redeliver_pid = True, os.getpid()
            _redeliver_later()
        finally:
            _in_hook = False
        return
    hook = _previous_unraisablehook or sys.__unraisablehook__
    hook(unraisable)


def install() -> dict[Any, Any] | None:
    """Route SIGINT and SIGTERM to :class:`Interrupted` (main thread only; else no-op).

    Returns the previous handlers, for :func:`uninstall`.

    Returns
    -------
    dict or None
        The previous handler of each signal, keyed by signal; None outside the main thread
        (nothing was installed).
    """
    global _installed, _previous_unraisablehook
    if threading.current_thread() is not threading.main_thread():
        return None
    previous = {s: signal.signal(s, _handler) for s in SIGNALS}
    if sys.unraisablehook is not _unraisablehook:
        _previous_unraisablehook = sys.unraisablehook
        sys.unraisablehook = _unraisablehook
    _installed = True
    return previous


def uninstall(previous: dict[Any, Any] | None) -> None:
    """Put back the handlers :func:`install` replaced (a library caller's own, e.g. pytest's),
    and forget a received signal: the caller that installed them has reported it (its exit
    code), and a signal left pending would interrupt the library caller's later work at its
    next :func:`check`.

    Parameters
    ----------
    previous : dict or None
        What :func:`install` returned; None: nothing to put back.
    """
    global _installed
    if previous is None or threading.current_thread() is not threading.main_thread():
        return
    reset()
    for s, h in previous.items():
        signal.signal(s, h)  # type: ignore[arg-type]
    if sys.unraisablehook is _unraisablehook:
        sys.unraisablehook = _previous_unraisablehook or sys.__unraisablehook__
    _installed = False


def ignore_all() -> None:
    """Ignore SIGINT and SIGTERM from now on (a finished command about to exit)."""
    if threading.current_thread() is threading.main_thread():
        for s in SIGNALS:
            signal.signal(s, signal.SIG_IGN)


def installed() -> bool:
    """Whether :func:`install` ran in this process.

    Returns
    -------
    bool
        True once :func:`install` ran (and :func:`uninstall` did not).
    """
    return _installed


def pending() -> int | None:
    """The signal received since :func:`install` (or :func:`reset`), or None.

    Returns
    -------
    int or None
        The signal number, or None if none arrived.
    """
    return _pending


def check() -> None:
    """Raise :class:`Interrupted` if a signal arrived (even one whose exception was swallowed).

    Raises
    ------
    Interrupted
        If a signal arrived since :func:`install` (or :func:`reset`).
    """
    if _pending is not None:
        raise Interrupted(_pending)


def exit_code() -> int | None:
    """130 (SIGINT) or 143 (SIGTERM) once a signal arrived, else None.

    Returns
    -------
    int or None
        128 + the signal number, or None if no signal arrived.
    """
    return None if _pending is None else 128 + _pending


def reset() -> None:
    """Forget a received signal (the command line starts each call of ``main`` afresh)."""
    global _pending, _redeliver
    _pending, _redeliver = None, False


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends, then raise as they would have.

    For the few renames that must not be separated (an output swapped in place). Only effective
    in the main thread.

    Yields
    ------
    None
        Control, for the block.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous: dict[Any, Any] = {
        s: signal.signal(s, lambda signum, frame: caught.append(signum)) for s in SIGNALS
    }
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        # delivered even if the block failed: the signal is then the cause (e.g. a child that
        # the terminal's Ctrl-C reached), and its exception replaces the block's
        if caught:
            signum = caught[0]
            handler = previous[signum]
            if callable(handler):
                handler(signum, None)  # ours raises Interrupted, Python's KeyboardInterrupt
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)  # the default action, as if never held


@contextlib.contextmanager
def spawning() -> Iterator[None]:
    """Start worker processes and threads that a terminal's Ctrl-C does not reach.

    SIGINT is blocked (``pthread_sigmask``) in the block: threads and processes started in it
    inherit the blocked signal, even across ``exec`` (Dask's spawned workers), so a Ctrl-C sent
    to the whole process group reaches the parent alone, which stops its children. The parent
    gets the held SIGINT (and a SIGTERM, :func:`deferred`) when the block ends.

    Yields
    ------
    None
        Control, for the block.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    with deferred():
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@contextlib.contextmanager
def ignored() -> Iterator[None]:
    """Ignore SIGINT and SIGTERM in the block (the last steps of a finished or undone run).

    Yields
    ------
    None
        Control, for the block.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, signal.SIG_IGN) for s in SIGNALS}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def child_init() -> None:
    """For a worker process: ignore SIGINT and SIGTERM, and be killed (SIGKILL) when the parent
    dies (Linux), even by SIGKILL.

    A terminal's Ctrl-C and a batch scheduler's SIGTERM reach the whole process group: the
    parent alone decides, and stops its workers itself. A worker that died of the signal on
    its own could do so holding a lock its parent then waits for (``multiprocessing.Pool``'s
    queue: the parent hung for ever). Block :data:`SIGNALS` across the fork
    (``signal.pthread_sigmask``) and unblock them after this call, so that none is raised in the
    child before it ignores them.
    """
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    global _pending, _installed
    _pending, _installed = None, False
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
