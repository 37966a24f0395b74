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

Temporary names are ``.<name>.tmp-<pid>-<random><suffix>`` (and ``.old-`` for a folder renamed
aside): :func:`dead_leftovers` recognises those of a process that no longer runs (``kill -9``, a
power cut), and the next run removes them.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path

from obsplan.core.interrupts import deferred

#: Hold SIGINT and SIGTERM during a few renames (:func:`obsplan.core.interrupts.deferred`).
deferred_sigint = deferred


def _tmp_name(target: Path, tag: str = "tmp") -> Path:
    # keep the suffix: matplotlib and json writers choose the format from the extension; the
    # pid tells a later run whether the writer is still alive
    token = f"{os.getpid()}-{secrets.token_hex(4)}"
    return target.with_name(f".{target.stem}.{tag}-{token}{target.suffix}")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def dead_leftovers(target: str | Path) -> list[Path]:
    """Temporary siblings of ``target`` (:func:`_tmp_name`) whose writing process is gone.

    Only names of exactly our form are returned (``.<stem>.tmp-<pid>-<8 hex><suffix>`` or
    ``.old-``), never a file of the user's.
    """
    target = Path(target)
    pattern = re.compile(
        rf"^\.{re.escape(target.stem)}\.(?:tmp|old)-(\d+)-[0-9a-f]{{8}}{re.escape(target.suffix)}$"
    )
    out: list[Path] = []
    try:
        entries = list(target.parent.iterdir())
    except OSError:
        return out
    for p in entries:
        m = pattern.match(p.name)
        if m and not _alive(int(m.group(1))):
            out.append(p)
    return sorted(out)


def remove_dead_leftovers(target: str | Path) -> list[Path]:
    """Delete :func:`dead_leftovers` of ``target``; returns what was removed."""
    removed = []
    for p in dead_leftovers(target):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                p.unlink()
        if not p.exists():
            removed.append(p)
    return removed


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
        with deferred():
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


def swap_dir(staging: str | Path, target: str | Path) -> Path | None:
    """Move the finished folder ``staging`` to ``target``; an old ``target`` is renamed aside
    (returned, for the caller to delete or to put back), else None.

    Both must be in the same parent folder; SIGINT and SIGTERM are held during the renames. If
    the second rename fails the old folder is put back.
    """
    staging, target = Path(staging), Path(target)
    with deferred():
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
    return old


def replace_dir(staging: str | Path, target: str | Path) -> Path:
    """Move the finished folder ``staging`` to ``target``, replacing ``target`` whole.

    Both must be in the same parent folder. If ``target`` exists it is renamed aside, the staging
    folder takes its name, and the old folder is then deleted: at no time does ``target`` hold a
    mix of old and new files (:func:`swap_dir`).
    """
    old = swap_dir(staging, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return Path(target)


def remove_tree(path: str | Path) -> None:
    """Delete a staging folder (no error if it is already gone)."""
    shutil.rmtree(path, ignore_errors=True)
