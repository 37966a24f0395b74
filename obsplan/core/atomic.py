"""Atomic outputs: a file or a folder appears whole under its final name, or not at all.

Everything obsplan writes for a user goes through these helpers, so that an error, a full disk or
Ctrl-C never leaves a half-written file or a folder that mixes old and new results:

* :func:`atomic_file` yields a temporary path beside the target (same folder, hence the same file
  system) and renames it over the target only when the block finishes without an exception;
* :func:`replace_dir` swaps a finished staging folder in place of a results folder (the old one, if
  any, is renamed aside first and removed after the swap), with SIGINT deferred during the two
  renames so that Ctrl-C cannot fall between them;
* :func:`staging_dir` creates a fresh, empty folder beside a target (hidden name, permissions from
  the umask, unlike :func:`tempfile.mkdtemp`'s 0700);
* :func:`put_in_place` moves a finished file or folder to its target only if the target is still
  what was checked before the work (:func:`identity`): absent (then a newcomer is never replaced:
  ``renameat2(RENAME_NOREPLACE)``), or the same file or folder (then the two are exchanged in one
  step, ``RENAME_EXCHANGE``, and checked again; a mismatch exchanges them back). Exactly one of
  two runs that commit to the same target wins; the other gets :class:`TargetChanged`.

Temporary names are ``.<name>.tmp-<pid>-<random><suffix>`` (and ``.old-`` for a folder renamed
aside): :func:`dead_leftovers` recognises those of a process that no longer runs (``kill -9``, a
power cut), and the next run removes them.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import os
import re
import secrets
import shutil
import stat
from collections.abc import Callable, Iterator
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

    Parameters
    ----------
    target : str or Path
        The output file or folder whose hidden siblings are looked at.

    Returns
    -------
    list of Path
        The leftovers, sorted; empty if there are none or the parent folder cannot be read.
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
    """Delete :func:`dead_leftovers` of ``target``; returns what was removed.

    Parameters
    ----------
    target : str or Path
        The output file or folder whose dead temporary siblings are deleted.

    Returns
    -------
    list of Path
        The leftovers that are gone now (one that could not be deleted is not listed).
    """
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

    Parameters
    ----------
    path : str or Path
        The file to write.

    Yields
    ------
    Path
        A hidden temporary path beside ``path``, with the same suffix, to write to.
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
    """Create and return an empty hidden folder beside ``target`` (its parent must exist).

    Parameters
    ----------
    target : str or Path
        The results folder the staging folder will later replace (:func:`replace_dir`).

    Returns
    -------
    Path
        The new, empty staging folder (``.<name>.tmp-<pid>-<random>``).
    """
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

    Parameters
    ----------
    staging : str or Path
        The finished staging folder (:func:`staging_dir`).
    target : str or Path
        The results folder it becomes.

    Returns
    -------
    Path or None
        Where the old ``target`` was renamed to (a hidden ``.old-`` sibling), or None if there
        was no ``target``.
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

    Parameters
    ----------
    staging : str or Path
        The finished staging folder (:func:`staging_dir`).
    target : str or Path
        The results folder it replaces.

    Returns
    -------
    Path
        ``target``, now holding the new results.
    """
    old = swap_dir(staging, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return Path(target)


def remove_tree(path: str | Path) -> None:
    """Delete a staging folder (no error if it is already gone).

    Parameters
    ----------
    path : str or Path
        The folder to delete, with everything in it.
    """
    shutil.rmtree(path, ignore_errors=True)


# ------------------------------------------------------------------------------ commit checked
_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2
_UNSUPPORTED = {errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP}


class TargetChanged(Exception):
    """The target of a commit is no longer what was checked before the work.

    Attributes
    ----------
    appeared : bool
        True if it did not exist at the check and exists now; False if it was replaced, removed
        or (a file) modified since.
    """

    def __init__(self, target: Path, appeared: bool) -> None:
        super().__init__(str(target))
        self.target, self.appeared = target, appeared


Identity = tuple[int, ...]


def identity(path: str | Path) -> Identity | None:
    """What a later commit compares: device, inode and type (and for a file its size and
    modification time); None if nothing is at ``path``. A link is not followed.

    Parameters
    ----------
    path : str or Path
        The file or folder to identify.

    Returns
    -------
    tuple of int or None
        ``(device, inode, type)`` for a folder, ``(device, inode, type, size [bytes],
        modification time [ns])`` otherwise; None if nothing is at ``path``.
    """
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    kind = stat.S_IFMT(st.st_mode)
    if stat.S_ISDIR(st.st_mode):
        return (st.st_dev, st.st_ino, kind)
    return (st.st_dev, st.st_ino, kind, st.st_size, st.st_mtime_ns)


@functools.cache
def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def _renameat2(src: Path, dst: Path, flags: int) -> bool:
    """``renameat2(2)``; False where the C library or the file system lacks it."""
    fn = getattr(_libc(), "renameat2", None)
    if fn is None:  # pragma: no cover - glibc < 2.28
        return False
    if fn(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) == 0:
        return True
    err = ctypes.get_errno()
    if err in _UNSUPPORTED:  # pragma: no cover - e.g. some network file systems
        return False
    raise OSError(err, os.strerror(err), str(src), None, str(dst))


def rename_noreplace(src: str | Path, dst: str | Path) -> None:
    """Rename ``src`` to ``dst`` unless something is at ``dst`` (:class:`FileExistsError`).

    Atomic with ``renameat2``; elsewhere checked just before the rename (a folder then never
    replaces a non-empty one, a file is linked, which fails on an existing name).

    Parameters
    ----------
    src : str or Path
        The file or folder to rename.
    dst : str or Path
        Its new name, which must not exist.

    Raises
    ------
    FileExistsError
        If something is at ``dst``.
    """
    src, dst = Path(src), Path(dst)
    if _renameat2(src, dst, _RENAME_NOREPLACE):
        return
    if os.path.lexists(dst):  # pragma: no cover - fallback
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    if src.is_dir():  # pragma: no cover - fallback
        os.rename(src, dst)
    else:  # pragma: no cover - fallback
        os.link(src, dst)
        os.unlink(src)


def exchange(a: str | Path, b: str | Path) -> bool:
    """Swap two paths in one step (``renameat2(RENAME_EXCHANGE)``); False if unsupported.

    Parameters
    ----------
    a, b : str or Path
        The two paths to swap; both must exist.

    Returns
    -------
    bool
        True if they were swapped, False if the C library or the file system cannot do it (the
        paths are then untouched).
    """
    return _renameat2(Path(a), Path(b), _RENAME_EXCHANGE)


def put_in_place(
    staged: str | Path,
    target: str | Path,
    expected: Identity | None,
    verify: Callable[[Path], None] | None = None,
) -> Path | None:
    """Move the finished ``staged`` file or folder to ``target`` if ``target`` is still what was
    checked; returns where the old target now is (a hidden sibling, for the caller to delete or to
    put back), or None if there was none.

    Parameters
    ----------
    staged : str or Path
        The finished file or folder, beside ``target``.
    target : str or Path
        Where it goes.
    expected : tuple of int or None
        :func:`identity` of ``target`` at the check (None: it did not exist).
    verify : callable or None, optional
        Called with the old target once it is out of the way; an exception puts it back (and is
        raised): e.g. a check that the old folder holds nothing new.

    Returns
    -------
    Path or None
        The hidden sibling the old ``target`` was renamed to, or None if there was no old target.

    Raises
    ------
    TargetChanged
        If ``target`` appeared, was replaced or removed, or (a file) was modified since the
        check. Nothing is moved then: the newcomer stays, ``staged`` stays for its owner to remove.
    """
    staged, target = Path(staged), Path(target)
    with deferred():
        if expected is None:
            try:
                rename_noreplace(staged, target)
            except FileExistsError:
                raise TargetChanged(target, appeared=True) from None
            except OSError as exc:  # pragma: no cover - fallback: a non-empty folder appeared
                if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                    raise TargetChanged(target, appeared=True) from None
                raise
            return None
        if identity(target) != expected:
            raise TargetChanged(target, appeared=False)
        if exchange(staged, target):
            try:  # the old target is now under the staged name
                if identity(staged) != expected:  # replaced between the look and the exchange
                    raise TargetChanged(target, appeared=False)
                if verify is not None:
                    verify(staged)
            except BaseException:
                exchange(staged, target)  # the newcomer (or the old folder) back in place
                raise
            old = _tmp_name(target, "old")
            os.rename(staged, old)
            return old
        old = _tmp_name(target, "old")  # pragma: no cover - fallback: two renames
        os.rename(target, old)  # pragma: no cover
        try:  # pragma: no cover
            if identity(old) != expected:
                raise TargetChanged(target, appeared=False)
            if verify is not None:
                verify(old)
            rename_noreplace(staged, target)
        except BaseException:  # pragma: no cover
            with contextlib.suppress(OSError):
                rename_noreplace(old, target)
            raise
        return old  # pragma: no cover
