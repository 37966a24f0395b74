"""Atomic outputs: a file or a folder appears whole under its final name, or not at all.

Everything obsplan writes for a user goes through these helpers, so that an error, a full disk or
Ctrl-C never leaves a half-written file or a folder that mixes old and new results:

* :func:`atomic_file` yields a temporary path beside the target (same folder, hence the same file
  system) and renames it over the target only when the block finishes without an exception;
* :func:`replace_dir` swaps a finished staging folder in place of a results folder (the old one, if
  any, is renamed aside first and removed after the swap), with SIGINT deferred during the two
  renames so that Ctrl-C cannot fall between them;
* :func:`staging_dir` creates a fresh, empty folder beside a target (hidden name, permissions from
  the umask, unlike :func:`tempfile.mkdtemp`'s 0700).

Temporary names start with ``.<name>.tmp-`` so that a leftover after a power cut is recognisable.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import threading
from collections.abc import Iterator
from pathlib import Path


def _tmp_name(target: Path, tag: str = "tmp") -> Path:
    # keep the suffix: matplotlib and json writers choose the format from the extension
    return target.with_name(f".{target.stem}.{tag}-{secrets.token_hex(4)}{target.suffix}")


@contextlib.contextmanager
def deferred_sigint() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) until the block ends, then raise :class:`KeyboardInterrupt`.

    Only effective in the main thread (elsewhere Python cannot install handlers; the block then
    runs unprotected).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


@contextlib.contextmanager
def atomic_file(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; it replaces ``path`` if the block succeeds.

    On any exception (including :class:`KeyboardInterrupt`) the temporary file is removed and
    ``path`` is untouched. The parent folder must exist.
    """
    target = Path(path)
    tmp = _tmp_name(target)
    try:
        yield tmp
        with deferred_sigint():
            os.replace(tmp, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def staging_dir(target: str | Path) -> Path:
    """Create and return an empty hidden folder beside ``target`` (its parent must exist)."""
    target = Path(target)
    while True:
        tmp = _tmp_name(target)
        try:
            os.mkdir(tmp)  # mode 0o777 & ~umask, like any folder the user creates
            return tmp
        except FileExistsError:  # pragma: no cover - 32 random bits collided
            continue


def replace_dir(staging: str | Path, target: str | Path) -> Path:
    """Move the finished folder ``staging`` to ``target``, replacing ``target`` whole.

    Both must be in the same parent folder. If ``target`` exists it is renamed aside, the staging
    folder takes its name, and the old folder is then deleted: at no time does ``target`` hold a
    mix of old and new files. If the second rename fails the old folder is put back.
    """
    staging, target = Path(staging), Path(target)
    with deferred_sigint():
        old = None
        if target.exists():
            old = _tmp_name(target, "old")
            os.rename(target, old)
        try:
            os.rename(staging, target)
        except BaseException:
            if old is not None:
                os.rename(old, target)
            raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


def remove_tree(path: str | Path) -> None:
    """Delete a staging folder (no error if it is already gone)."""
    shutil.rmtree(path, ignore_errors=True)
