"""Output folders and files that cannot destroy a user's data, shared by every verb.

Rules (checked when the output object is constructed, i.e. before any work):

* every folder obsplan creates holds the marker file :data:`MARKER`; ``--force`` replaces only a
  folder that has it — never a folder of the user's, one holding an input of the run, the
  working folder or a parent of it, the home folder or a parent of it, or ``/``;
* a symbolic link as the output is refused (renaming over it would replace the link by a
  folder and leave the old target behind): the message names the real path to give instead;
* results are written into a hidden staging folder beside the target and renamed in place
  (:mod:`obsplan.core.atomic`); what a killed run left (temporary siblings whose process is gone)
  is removed by the next run that writes there.

Use::

    out = OutputDir(args.out, args.force, inputs=[args.problem])   # checks, writes nothing
    with out:                                 # an exception or a signal: nothing is left
        staging = out.stage()                 # hidden folder with the marker
        write_files(staging)
        out.commit()                          # swapped in place

When :mod:`obsplan.core.interrupts` is installed (the command line), :meth:`OutputDir.commit` keeps
the old folder aside until :func:`finish` runs at the very end of the command: a signal that
arrives after the swap still undoes it, so an interrupted command leaves the folder as it was.
A resumable folder (a sweep's) is checked by :func:`check_resumable_dir`.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import stat
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from obsplan.core import interrupts
from obsplan.core.atomic import (
    _tmp_name,
    atomic_file,
    remove_dead_leftovers,
    remove_tree,
    staging_dir,
    swap_dir,
)
from obsplan.core.errors import InputError
from obsplan.version import __version__

#: The file that marks a folder as obsplan's own output (``--force`` may replace it).
MARKER = ".obsplan-output"

#: Swaps of this command not yet final: ``(target, old folder or None, parents created)``.
_SWAPPED: list[tuple[Path, Path | None, list[Path]]] = []


# ------------------------------------------------------------------------------ the marker
def write_marker(folder: str | Path, verb: str) -> Path:
    """Write :data:`MARKER` (verb and version, JSON) into ``folder``; returns its path."""
    path = Path(folder) / MARKER
    doc = {"written_by": f"obsplan {verb}".strip(), "version": __version__}
    path.write_text(json.dumps(doc) + "\n", encoding="utf-8")
    return path


def has_marker(folder: str | Path) -> bool:
    """Whether ``folder`` is an obsplan output (holds :data:`MARKER`)."""
    return (Path(folder) / MARKER).is_file()


# ------------------------------------------------------------------------------ checks
def protected_reason(path: str | Path) -> str | None:
    """Why ``path`` must never be replaced or written into as a whole, or None.

    The root, the home folder, the working folder and every parent of the last two.
    """
    here = Path(os.path.abspath(path))
    try:
        here = here.resolve()
    except OSError:
        pass
    if here == Path(here.anchor):
        return "the root folder"
    places = [("your home folder", Path.home()), ("the working folder", Path.cwd())]
    for what, place in places:
        with contextlib.suppress(OSError):
            place = place.resolve()
        if here == place:
            return what
        if here in place.parents:
            return f"a parent of {what} ({place})"
    return None


def check_name(path: str | Path | None, option: str) -> Path:
    """The common first checks: a non-empty name, not a symbolic link, not a protected folder."""
    if path is None or str(path).strip() == "":
        raise InputError(f"{option} is empty; give a folder or file name, e.g. {option} results")
    p = Path(path)
    if p.is_symlink():
        real = os.path.realpath(p)
        raise InputError(
            f"{option} {p} is a symbolic link (to {real}); give the real path instead, e.g. "
            f"{option} {real}"
        )
    why = protected_reason(p)
    if why is not None:
        raise InputError(
            f"{option} {p} is {why}, which obsplan never writes over; give a new folder, e.g. "
            f"{option} {Path(p) / 'obsplan-results'}"
        )
    return p


def _read_only(path: Path) -> bool:
    """No write permission for us, or no write bit at all (root ignores permissions, but a
    folder or file its owner made read-only is meant to stay as it is)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not os.access(path, os.W_OK) or not (mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _existing_ancestor(path: Path, option: str) -> Path:
    anc = path.parent if path.parent != path else path
    anc = Path(os.path.abspath(anc))
    while not anc.exists():
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"{option} {path}: {anc} is a file, so nothing can be written under it")
    return anc


def _probe(folder: Path, option: str, path: Path) -> None:
    """Create and remove a folder in ``folder``: the only test that also works as root and on
    read-only or special file systems."""
    try:
        probe = staging_dir(folder / ".obsplan-write-test")
        os.rmdir(probe)
    except OSError as exc:
        raise InputError(
            f"{option} {path}: cannot write in {folder} ({exc.strerror}); choose a writable place"
        ) from None


def _holds_input(folder: Path, inputs: Sequence[str | Path | None]) -> str | None:
    here = folder.resolve()
    for f in inputs:
        if f is not None and (here == Path(f).resolve() or here in Path(f).resolve().parents):
            return str(f)
    return None


def _not_ours(option: str, out: Path, force: bool, force_option: str = "--force") -> InputError:
    if not force:
        return InputError(
            f"{option} {out} is not empty; choose another folder, or pass {force_option} to "
            "replace an earlier obsplan output whole"
        )
    return InputError(
        f"{option} {out} is not an obsplan output folder (it has no {MARKER} file), so "
        f"{force_option} will not replace it; choose a new folder name, or remove the folder "
        "yourself"
    )


def check_resumable_dir(
    path: str | Path | None,
    option: str = "--out",
    ours: Callable[[Path], bool] = has_marker,
) -> Path:
    """Check a folder that a verb creates or adds to (a sweep's): refused if it is a file, a
    link, a protected folder, a non-empty folder that ``ours`` does not recognise, or not
    writable. Nothing is written; dead runs' leftovers beside it are removed."""
    out = check_name(path, option)
    if out.exists() and not out.is_dir():
        raise InputError(f"{option} {out} is a file; give a folder")
    if out.is_dir():
        if any(out.iterdir()) and not (has_marker(out) or ours(out)):
            raise InputError(
                f"{option} {out} is not empty and is not an obsplan output folder (no "
                f"{MARKER}); choose a new or empty folder"
            )
        if _read_only(out):
            raise InputError(f"{option} {out} is read-only; make it writable or choose another")
    _probe(_existing_ancestor(out, option), option, out)
    remove_dead_leftovers(out)
    return out


# ------------------------------------------------------------------------------ folders
class OutputDir:
    """A results folder checked before work and replaced whole at the end (module doc).

    Parameters
    ----------
    path
        The folder (``--out DIR``); missing parents are created at :meth:`stage`.
    force
        Allow replacing a non-empty folder that is an obsplan output (has :data:`MARKER`).
    option
        How messages name the folder (``"--out"``).
    inputs
        Files the verb reads: a folder holding one of them is never replaced.
    verb
        Recorded in the marker.
    force_option
        How messages name ``force`` (``"--force"``; ``"force=True"`` for a Python call).
    """

    def __init__(
        self,
        path: str | Path | None,
        force: bool,
        option: str = "--out",
        inputs: Sequence[str | Path | None] = (),
        verb: str = "",
        force_option: str = "--force",
    ) -> None:
        out = check_name(path, option)
        self.path, self.option, self.verb = out, option, verb
        if out.exists() and not out.is_dir():
            raise InputError(f"{option} {out} is a file; give a folder")
        if out.is_dir():
            held = _holds_input(out, inputs)
            if held is not None:
                raise InputError(
                    f"{option} {out} holds the input {held}, which replacing the folder would "
                    "delete; choose another output folder"
                )
            if any(out.iterdir()) and not (force and has_marker(out)):
                raise _not_ours(option, out, force, force_option)
            if _read_only(out):
                raise InputError(
                    f"{option} {out} is read-only; make it writable or choose another folder"
                )
        _probe(_existing_ancestor(out, option), option, out)
        remove_dead_leftovers(out)
        self._staging: Path | None = None
        self._created: list[Path] = []
        self.committed = False

    def stage(self) -> Path:
        """Create (once) and return the staging folder (holding only the marker)."""
        if self._staging is None:
            parent = Path(os.path.abspath(self.path.parent))
            missing = []
            while not parent.exists():
                missing.append(parent)
                parent = parent.parent
            for folder in reversed(missing):
                folder.mkdir()
                self._created.append(folder)
            self._staging = staging_dir(self.path.parent / self.path.name)
            write_marker(self._staging, self.verb)
        return self._staging

    def final(self, staged: str | Path) -> Path:
        """Where a file written in the staging folder ends up after :meth:`commit`."""
        return self.path / Path(staged).relative_to(self.stage())

    def commit(self) -> Path:
        """Swap the staging folder in place of ``path`` (refused if a signal arrived)."""
        interrupts.check()  # a signal whose exception was swallowed still stops the commit
        old = swap_dir(self.stage(), self.path)
        self.committed = True
        self._staging = None
        if interrupts.installed():
            _SWAPPED.append((self.path, old, self._created))
        elif old is not None:
            shutil.rmtree(old, ignore_errors=True)
        self._created = []
        return self.path

    def discard(self) -> None:
        """Remove the staging folder and any parent folder created for it."""
        if self._staging is not None:
            remove_tree(self._staging)
            self._staging = None
        if not self.committed:
            _remove_created(self._created)
            self._created = []

    def __enter__(self) -> OutputDir:
        return self

    def __exit__(self, *exc: object) -> None:
        self.discard()


def _remove_created(created: list[Path]) -> None:
    for folder in reversed(created):
        with contextlib.suppress(OSError):
            folder.rmdir()


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def finish(undo: bool) -> None:
    """End this command's swaps: delete the old folders and files, or (``undo``) put them back.

    Called by the command line last, with signals ignored; ``undo`` when a signal arrived.
    """
    with interrupts.ignored():
        while _SWAPPED:
            target, old, created = _SWAPPED.pop()
            if not undo:
                if old is not None:
                    _remove(old)
                continue
            trash = _tmp_name(target, "old")
            with contextlib.suppress(OSError):
                os.rename(target, trash)
                if old is not None:
                    os.rename(old, target)
            _remove(trash)
            _remove_created(created)


# ------------------------------------------------------------------------------ files
class OutputFile:
    """One output file, checked before work and written atomically.

    Refuses an empty name, a link, a folder, an existing file without ``force``, one of the
    verb's ``inputs``, a read-only file and a place where nothing can be written.
    """

    def __init__(
        self,
        path: str | Path | None,
        force: bool,
        option: str,
        inputs: Sequence[str | Path | None] = (),
    ) -> None:
        p = check_name(path, option)
        self.path, self.option = p, option
        if p.is_dir():
            raise InputError(f"{option} {p} is a folder; give a file name")
        if p.exists() and any(f is not None and Path(f).resolve() == p.resolve() for f in inputs):
            raise InputError(f"{option} {p} is the input file; give another name for the output")
        if p.exists():
            if not force:
                raise InputError(
                    f"{option} {p} exists; choose another name or pass --force to replace it"
                )
            if _read_only(p):
                raise InputError(f"{option} {p} is read-only; make it writable or choose another")
        _probe(_existing_ancestor(p, option), option, p)
        remove_dead_leftovers(p)

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """Yield a temporary path; it becomes ``path`` when the block succeeds.

        With :mod:`obsplan.core.interrupts` installed, an old file is kept aside until
        :func:`finish`, so that a signal after the rename still undoes it.
        """
        parent = Path(os.path.abspath(self.path.parent))
        created = []
        while not parent.exists():
            created.append(parent)
            parent = parent.parent
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if not interrupts.installed():
            with atomic_file(self.path) as tmp:
                yield tmp
            return
        tmp = _tmp_name(self.path)
        try:
            yield tmp
            interrupts.check()
            with interrupts.deferred():
                old = None
                if self.path.exists():
                    old = _tmp_name(self.path, "old")
                    try:  # the old file stays whole under a second name
                        os.link(self.path, old)
                    except OSError:  # no hard links here
                        shutil.copy2(self.path, old)
                os.replace(tmp, self.path)
                _SWAPPED.append((self.path, old, list(reversed(created))))
        finally:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            if not self.path.exists():
                _remove_created(list(reversed(created)))
