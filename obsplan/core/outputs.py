"""Output folders and files that cannot destroy a user's data, shared by every verb.

Rules (checked when the output object is constructed, i.e. before any work, and again at the
commit):

* every folder obsplan writes holds the marker file :data:`MARKER`: the verb that wrote it and,
  for a folder written whole (``plan``, ``simulate``, ``paper``), the files it wrote (size and
  SHA-256: a manifest). A folder without it is the user's: never written into, even with
  ``--force`` (an empty folder excepted);
* ``--force`` replaces an earlier output of the *same* verb, whole, and only if it holds nothing
  but what that verb wrote: a file the user added or changed there, or a sub-folder of theirs,
  refuses it, with the list of those files. An output of another verb is never replaced (a
  ``plan`` never replaces a resumable ``sweep`` folder, a ``sweep`` never writes into a plan's);
  nor is a folder holding an input of the run, the working folder or a parent of it, the home
  folder or a parent of it, or ``/``; nor an output of an older obsplan that did not record its
  files;
* a symbolic link as the output is refused (renaming over it would replace the link by a
  folder and leave the old target behind): the message names the real path to give instead;
* a read-only place is judged by its mode bits as well as by :func:`os.access`, so that root
  (who may write anywhere) is refused the same folders as anyone: the output folder, the folder
  it is created in, and the first existing folder above new sub-folders;
* results are written into a hidden staging folder beside the target and moved in place at the
  commit only if the target is still what the check saw (:func:`obsplan.core.atomic.put_in_place`):
  a folder that appeared at ``--out`` during the run, or was replaced, or got files of the user's,
  is left as it is and the run exits 2 (of two runs writing to the same place, exactly one
  wins); what a killed run left (temporary siblings whose process is gone) is removed by the
  next run that writes there;
* a resumable folder (a sweep's, :class:`ResumableDir`) is created whole with its marker, never
  created over a newcomer, and locked while a run writes into it: a second run into it exits 2
  at once instead of mixing its files in.

Use::

    out = OutputDir(args.out, args.force, inputs=[args.problem], verb="plan")  # checks only
    with out:                                 # an exception or a signal: nothing is left
        staging = out.stage()                 # hidden folder with the marker
        write_files(staging)
        out.commit()                          # checked again, swapped in place

When :mod:`obsplan.core.interrupts` is installed (the command line), :meth:`OutputDir.commit` keeps
the old folder aside until :func:`finish` runs at the very end of the command: a signal that
arrives after the swap still undoes it, so an interrupted command leaves the folder as it was.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import stat
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from obsplan.core import interrupts
from obsplan.core.atomic import (
    Identity,
    TargetChanged,
    _tmp_name,
    atomic_file,
    exchange,
    identity,
    put_in_place,
    remove_dead_leftovers,
    remove_tree,
    rename_noreplace,
    staging_dir,
)
from obsplan.core.errors import InputError
from obsplan.version import __version__

#: The file that marks a folder as obsplan's own output (``--force`` may replace it).
MARKER = ".obsplan-output"

#: Names shown when a message lists a folder's files.
SHOW_FILES = 4

#: Swaps of this command not yet final: ``(target, old or None, parents created, our identity)``.
_SWAPPED: list[tuple[Path, Path | None, list[Path], Identity | None]] = []


# ------------------------------------------------------------------------------ the marker
@dataclass(frozen=True)
class Marker:
    """What a folder's :data:`MARKER` says.

    Attributes
    ----------
    verb : str or None
        The verb that wrote the folder (``""`` for a library call); None if the marker is not
        one obsplan wrote (unreadable).
    files : dict or None
        Relative path -> ``{"size", "sha256"}`` of every file the verb wrote; None when not
        recorded (a resumable folder, or an older obsplan).
    folders : frozenset of str
        Sub-folders the verb created.
    links : dict
        Symbolic links the verb created, and their targets.
    """

    verb: str | None
    files: dict[str, dict[str, Any]] | None = None
    folders: frozenset[str] = field(default_factory=frozenset)
    links: dict[str, str] = field(default_factory=dict)


def _sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _walk(folder: Path, prefix: str = "") -> Iterator[tuple[str, os.DirEntry[str]]]:
    """``(relative path, entry)`` of everything in ``folder``, in name order, not following
    links; the caller decides whether to descend (:func:`_below`)."""
    with os.scandir(folder) as it:
        entries = sorted(it, key=lambda e: e.name)
    for e in entries:
        yield prefix + e.name, e


def _record(folder: Path) -> dict[str, Any]:
    files: dict[str, dict[str, Any]] = {}
    folders: list[str] = []
    links: dict[str, str] = {}
    stack = [(folder, "")]
    while stack:
        here, prefix = stack.pop()
        for rel, e in _walk(here, prefix):
            if rel == MARKER:
                continue
            if e.is_symlink():
                links[rel] = os.readlink(e.path)
            elif e.is_dir():
                folders.append(rel)
                stack.append((Path(e.path), rel + "/"))
            elif e.is_file():
                files[rel] = {"size": e.stat().st_size, "sha256": _sha256(e.path)}
    return {"files": files, "folders": sorted(folders), "links": links}


def write_marker(folder: str | Path, verb: str, *, record: bool = True) -> Path:
    """Mark ``folder`` as the output of ``obsplan verb``; returns the marker's path.

    With ``record`` (a folder written whole) the marker lists every file ``folder`` holds now,
    with its size and SHA-256: the files a later ``--force`` may replace. Without it (a resumable
    folder) it records the verb only. Written atomically.

    Parameters
    ----------
    folder : str or Path
        The output folder (or its staging folder).
    verb : str
        The verb that writes it (``"plan"``, ``"sweep"``...; ``""`` for a library call).
    record : bool, optional
        List every file the folder holds now (a folder written whole); False for a resumable
        folder.

    Returns
    -------
    Path
        The marker file, ``folder / MARKER``.
    """
    folder = Path(folder)
    doc: dict[str, Any] = {
        "written_by": f"obsplan {verb}".strip(),
        "verb": verb,
        "version": __version__,
    }
    if record:
        doc.update(_record(folder))
    else:
        doc["resumable"] = True
    path = folder / MARKER
    with atomic_file(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return path


def has_marker(folder: str | Path) -> bool:
    """Whether ``folder`` is an obsplan output (holds :data:`MARKER`).

    Parameters
    ----------
    folder : str or Path
        The folder to look at.

    Returns
    -------
    bool
        True if ``folder / MARKER`` is a file.
    """
    return (Path(folder) / MARKER).is_file()


def read_marker(folder: str | Path) -> Marker | None:
    """``folder``'s :class:`Marker`, or None if it has none.

    Parameters
    ----------
    folder : str or Path
        The folder to look at.

    Returns
    -------
    Marker or None
        What the marker says (``verb`` None if obsplan did not write it or it cannot be read),
        or None if there is no marker.
    """
    path = Path(folder) / MARKER
    if not os.path.lexists(path):
        return None
    try:
        if path.is_symlink():
            raise ValueError("a link")
        doc = json.loads(path.read_text(encoding="utf-8"))
        by = doc["written_by"]
        if not isinstance(by, str) or by.split(" ")[0] != "obsplan":
            raise ValueError(by)
        verb = doc.get("verb", by.partition(" ")[2])
        files = doc.get("files")
        if files is not None:
            files = {
                str(k): {"size": int(v["size"]), "sha256": str(v["sha256"])}
                for k, v in files.items()
            }
        folders = frozenset(str(f) for f in doc.get("folders", ()))
        links = {str(k): str(v) for k, v in doc.get("links", {}).items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return Marker(verb=None)
    return Marker(verb=str(verb), files=files, folders=folders, links=links)


def foreign_files(folder: str | Path, marker: Marker) -> list[str]:
    """What ``folder`` holds that its marker does not list as written by obsplan: files and
    links of the user's, their sub-folders (``name/``, not entered), and files obsplan wrote
    that were changed since (``name (changed since obsplan wrote it)``).

    Parameters
    ----------
    folder : str or Path
        An obsplan output folder.
    marker : Marker
        Its marker (:func:`read_marker`).

    Returns
    -------
    list of str
        The relative paths, sorted; empty if the folder holds only what obsplan wrote.
    """
    files = marker.files or {}
    owned = set(marker.folders)
    for rel in [*files, *marker.links]:
        parts = rel.split("/")
        owned.update("/".join(parts[:k]) for k in range(1, len(parts)))
    out: list[str] = []
    stack = [(Path(folder), "")]
    while stack:
        here, prefix = stack.pop()
        for rel, e in _walk(here, prefix):
            if rel == MARKER:
                continue
            if e.is_symlink():
                if marker.links.get(rel) != os.readlink(e.path):
                    out.append(rel)
            elif e.is_dir():
                if rel in owned:
                    stack.append((Path(e.path), rel + "/"))
                else:
                    out.append(rel + "/")
            elif e.is_file() and rel in files:
                want = files[rel]
                if e.stat().st_size != want["size"] or _sha256(e.path) != want["sha256"]:
                    out.append(f"{rel} (changed since obsplan wrote it)")
            else:
                out.append(rel)
    return sorted(out)


def _listing(names: Sequence[str]) -> str:
    shown = ", ".join(names[:SHOW_FILES])
    more = len(names) - SHOW_FILES
    return shown + (f" and {more} more" if more > 0 else "")


def _kind(verb: str) -> str:
    if verb == "sweep":
        return "resumable `obsplan sweep` folder"
    return f"`obsplan {verb}` output" if verb else "obsplan output"


def _holds(verb: str) -> str:
    """``"is a resumable ... folder"`` or ``"holds an ... output"``."""
    if verb == "sweep":
        return f"is a {_kind(verb)}"
    return f"holds an {_kind(verb)}"


def _contents(folder: Path) -> list[str]:
    return [rel + ("/" if e.is_dir() and not e.is_symlink() else "") for rel, e in _walk(folder)]


def _not_obsplans(
    head: str, folder: Path, marker: Marker | None, verb: str, force_option: str = "--force"
) -> str | None:
    """The refusal of a non-empty folder no ``verb`` run wrote, or None."""
    if marker is None:
        return (
            f"{head} is not empty and is not an obsplan output folder (it has no {MARKER} file; "
            f"it holds {_listing(_contents(folder))}), so `obsplan {verb}` will not write there, "
            f"even with {force_option}; choose a new or empty folder"
        )
    if marker.verb is None:
        return (
            f"{head} has a {MARKER} file that obsplan did not write, so it is not known to be an "
            f"obsplan output folder and is never written into, even with {force_option}; choose "
            "a new or empty folder"
        )
    if marker.verb != verb:
        return (
            f"{head} {_holds(marker.verb)}, which `obsplan {verb}` never writes over, even with "
            f"{force_option}; choose another folder"
        )
    return None


def replace_refusal(
    folder: str | Path,
    verb: str,
    force: bool,
    option: str = "--out",
    shown: Path | None = None,
    force_option: str = "--force",
) -> str | None:
    """Why ``obsplan verb`` may not replace the existing ``folder`` (the rules of the module
    doc), in one line naming ``option``, ``force_option`` and the fix; None if it may (an empty
    folder, or with ``force`` an earlier output of ``verb`` holding only what it wrote).

    Parameters
    ----------
    folder : str or Path
        The existing output folder.
    verb : str
        The verb that would replace it.
    force : bool
        Whether ``--force`` was given.
    option : str, optional
        How the message names the folder (``"--out"``).
    shown : Path or None, optional
        The path the message shows instead of ``folder`` (the target when ``folder`` is its old
        copy moved aside).
    force_option : str, optional
        How the message names ``force`` (``"--force"``; ``"force=True"`` for a Python call).

    Returns
    -------
    str or None
        The refusal, one line; None if the folder may be replaced.
    """
    folder = Path(folder)
    if not any(folder.iterdir()):
        return None
    head = f"{option} {shown or folder}"
    marker = read_marker(folder)
    why = _not_obsplans(head, folder, marker, verb, force_option)
    if why is not None:
        return why
    assert marker is not None
    if marker.files is None:
        return (
            f"{head} {_holds(verb)} of an older obsplan that did not record the files it wrote, "
            f"so {force_option} cannot tell them from yours; move what you want to keep and "
            "remove the folder yourself, or choose another folder"
        )
    foreign = foreign_files(folder, marker)
    if foreign:
        n = len(foreign)
        return (
            f"{head} holds {n} file{'s' if n != 1 else ''} that obsplan did not write (or that "
            f"changed since): {_listing(foreign)}; {force_option} replaces only what obsplan "
            f"wrote, so move {'them' if n != 1 else 'it'} out of {shown or folder} or choose "
            "another folder"
        )
    if not force:
        return (
            f"{head} is not empty: it holds an earlier {_kind(verb)}; pass {force_option} to "
            "replace it, or choose another folder"
        )
    return None


# ------------------------------------------------------------------------------ checks
def protected_reason(path: str | Path) -> str | None:
    """Why ``path`` must never be replaced or written into as a whole, or None.

    The root, the home folder, the working folder and every parent of the last two.

    Parameters
    ----------
    path : str or Path
        The output path (resolved through links).

    Returns
    -------
    str or None
        What the path is (``"your home folder"``, ``"a parent of the working folder (...)"``),
        or None if it is not protected.
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
    """The common first checks: a non-empty name, not a symbolic link, not a protected folder.

    Parameters
    ----------
    path : str or Path or None
        The output path given.
    option : str
        How messages name it (``"--out"``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        For an empty name, a symbolic link or a protected folder (:func:`protected_reason`).
    """
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
    """No write permission for us, or no write bit at all: root ignores permissions, but a
    folder or file its owner made read-only is meant to stay as it is, for root too."""
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


def _writable_place(folder: Path, option: str, path: Path) -> None:
    """Refuse ``folder`` (where ``path`` or its first new parent is created) if it is read-only
    by its mode bits or its permissions, or if a folder cannot be created there: the same answer
    for root as for anyone."""
    if _read_only(folder):
        mode = stat.S_IMODE(folder.stat().st_mode)
        raise InputError(
            f"{option} {path}: cannot write in {folder}: it is read-only (mode {mode:o}); make "
            f"it writable (chmod u+w {folder}) or choose another place"
        )
    try:  # the only test that also works on read-only or special file systems
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


def _changed(option: str, path: Path, appeared: bool, what: str = "results") -> str:
    how = (
        "appeared while this run was working (another run or program created it)"
        if appeared
        else "was replaced, removed or changed while this run was working (by another run or "
        "program)"
    )
    return (
        f"{option} {path} {how}; it was left as it is and this run's {what} were not written; "
        f"choose another {option} and run again"
    )


def _make_parents(path: Path) -> list[Path]:
    """Create the missing parents of ``path``; returns those this call created, top first."""
    parent = Path(os.path.abspath(path.parent))
    missing = []
    while not parent.exists():
        missing.append(parent)
        parent = parent.parent
    created = []
    for folder in reversed(missing):
        try:
            folder.mkdir()
        except FileExistsError:  # another run made it meanwhile: not ours to remove
            continue
        created.append(folder)
    return created


# ------------------------------------------------------------------------------ folders
class OutputDir:
    """A results folder checked before work and replaced whole at the end (module doc).

    Parameters
    ----------
    path : str or Path or None
        The folder (``--out DIR``); missing parents are created at :meth:`stage`.
    force : bool
        Allow replacing an earlier output of ``verb`` that holds only what it wrote.
    option : str, optional
        How messages name the folder (``"--out"``).
    inputs : sequence of str or Path or None, optional
        Files the verb reads: a folder holding one of them is never replaced.
    verb : str, optional
        Recorded in the marker; an existing output of another verb is never replaced.
    force_option
        How messages name ``force`` (``"--force"``; ``"force=True"`` for a Python call).

    Raises
    ------
    InputError
        If the folder may not be written (the rules of the module doc).
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
        self.path, self.option, self.verb, self.force = out, option, verb, force
        if out.exists() and not out.is_dir():
            raise InputError(f"{option} {out} is a file; give a folder")
        if out.is_dir():
            held = _holds_input(out, inputs)
            if held is not None:
                raise InputError(
                    f"{option} {out} holds the input {held}, which replacing the folder would "
                    "delete; choose another output folder"
                )
            why = replace_refusal(out, verb, force, option, force_option=force_option)
            if why is not None:
                raise InputError(why)
            if _read_only(out):
                raise InputError(
                    f"{option} {out} is read-only; make it writable or choose another folder"
                )
        _writable_place(_existing_ancestor(out, option), option, out)
        remove_dead_leftovers(out)
        #: What the commit expects at ``path`` (None: nothing).
        self._seen = identity(out)
        self._staging: Path | None = None
        self._created: list[Path] = []
        self.committed = False

    def stage(self) -> Path:
        """Create (once) and return the staging folder (holding only the marker).

        Returns
        -------
        Path
            The hidden staging folder beside :attr:`path`.
        """
        if self._staging is None:
            self._created += _make_parents(self.path)
            self._staging = staging_dir(self.path.parent / self.path.name)
            write_marker(self._staging, self.verb)
        return self._staging

    def final(self, staged: str | Path) -> Path:
        """Where a file written in the staging folder ends up after :meth:`commit`.

        Parameters
        ----------
        staged : str or Path
            A path inside the staging folder (:meth:`stage`).

        Returns
        -------
        Path
            The same relative path under :attr:`path`.
        """
        return self.path / Path(staged).relative_to(self.stage())

    def _verify(self, old: Path) -> None:
        """The folder about to be replaced (at ``path`` or just moved aside) is still one the
        check accepted: it holds nothing new of the user's."""
        why = replace_refusal(old, self.verb, self.force, self.option, shown=self.path)
        if why is not None:
            raise InputError(
                f"{why} (found when this run's results were ready: nothing was replaced and "
                "they were not written)"
            )

    def commit(self) -> Path:
        """Swap the staging folder in place of ``path`` if ``path`` is still what the check saw.

        The marker records every file written. Refused if a signal arrived.

        Returns
        -------
        Path
            :attr:`path`, now holding the results.

        Raises
        ------
        InputError
            ``path`` appeared, was replaced, or got files of the user's since the check; it is
            left as it is (the staging folder is removed by :meth:`discard`).
        """
        interrupts.check()  # a signal whose exception was swallowed still stops the commit
        staging = self.stage()
        write_marker(staging, self.verb)  # the manifest: what --force may replace later
        if self._seen is not None and identity(self.path) == self._seen:
            self._verify(self.path)
        try:
            old = put_in_place(staging, self.path, self._seen, verify=self._verify)
        except TargetChanged as exc:
            raise InputError(_changed(self.option, self.path, exc.appeared)) from None
        self.committed = True
        self._staging = None
        if interrupts.installed():
            _SWAPPED.append((self.path, old, self._created, identity(self.path)))
        elif old is not None:
            _remove(old)
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


class ResumableDir:
    """A folder a verb creates or adds to over several runs (a sweep's), checked before work.

    Accepted: a new folder, an empty one, or one whose marker names ``verb`` (what it holds then
    is the caller's to judge, e.g. which sweep); refused: a file, a link, a protected folder,
    any other non-empty folder (even with ``--force``), a read-only one, one another run is
    writing into (it is locked, :func:`fcntl.flock`, until :meth:`release`: an existing folder
    from this check on, a new one from :meth:`claim` on).
    :meth:`claim` creates the folder whole with its marker (never over a newcomer), or checks
    that it is still the folder the check saw. Nothing is written before :meth:`claim`.

    Parameters
    ----------
    path : str or Path or None
        The folder (``--out DIR``).
    verb : str
        The verb whose folders are resumed; recorded in the marker.
    option : str, optional
        How messages name the folder.

    Raises
    ------
    InputError
        If the folder may not be written, or another run holds its lock.
    """

    def __init__(self, path: str | Path | None, verb: str, option: str = "--out") -> None:
        out = check_name(path, option)
        self.path, self.verb, self.option = out, verb, option
        self._fd: int | None = None
        if out.exists() and not out.is_dir():
            raise InputError(f"{option} {out} is a file; give a folder")
        if out.is_dir():
            if any(out.iterdir()):
                why = _not_obsplans(f"{option} {out}", out, read_marker(out), verb)
                if why is not None:
                    raise InputError(why)
            if _read_only(out):
                raise InputError(f"{option} {out} is read-only; make it writable or choose another")
            self._lock()
        else:
            _writable_place(_existing_ancestor(out, option), option, out)
        remove_dead_leftovers(out)
        self._seen = identity(out)

    def _lock(self) -> None:
        fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise InputError(
                f"{self.option} {self.path}: another obsplan run is writing into it now; wait "
                "for it to end and run again, or choose another folder"
            ) from None
        self._fd = fd

    def claim(self) -> Path:
        """Make ``path`` this verb's folder before the first write: created whole with the
        marker if it was absent, else checked to be the folder the check saw (and marked if it
        was empty). Returns ``path``.

        Returns
        -------
        Path
            :attr:`path`, this verb's folder.

        Raises
        ------
        InputError
            ``path`` appeared, was replaced, or got someone else's files since the check.
        """
        out = self.path
        if self._seen is None:
            created = _make_parents(out)
            staging = staging_dir(out)
            try:
                write_marker(staging, self.verb, record=False)
                put_in_place(staging, out, None)
            except BaseException as exc:
                remove_tree(staging)
                _remove_created(created)
                if isinstance(exc, TargetChanged):
                    raise InputError(_changed(self.option, out, True, "files")) from None
                raise
            self._seen = identity(out)
            self._lock()
        if identity(out) != self._seen or (
            self._fd is not None and _fd_identity(self._fd) != self._seen
        ):
            raise InputError(_changed(self.option, out, False, "files"))
        if not has_marker(out):
            if any(out.iterdir()):  # an empty folder at the check, someone's files now
                why = _not_obsplans(f"{self.option} {out}", out, read_marker(out), self.verb)
                raise InputError(why or _changed(self.option, out, False, "files"))
            write_marker(out, self.verb, record=False)
        return out

    def release(self) -> None:
        """Unlock the folder (at the end of the run; exiting the process does it too)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> ResumableDir:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _fd_identity(fd: int) -> Identity:
    st = os.fstat(fd)
    return (st.st_dev, st.st_ino, stat.S_IFMT(st.st_mode))


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


def _undo(target: Path, old: Path | None, created: list[Path], ours: Identity | None) -> None:
    if identity(target) != ours:
        # replaced by someone else since this run wrote it: theirs stays; the earlier one is
        # kept beside it under a visible name rather than deleted
        if old is not None:
            keep = target.with_name(f"{target.name}.before-{os.getpid()}")
            with contextlib.suppress(OSError):
                rename_noreplace(old, keep)
                print(
                    f"obsplan: {target} changed after this run wrote it; the earlier {target.name} "
                    f"is kept as {keep}",
                    file=sys.stderr,
                )
        return
    if old is not None and exchange(old, target):
        _remove(old)  # now this run's output
    else:
        trash = _tmp_name(target, "old")
        with contextlib.suppress(OSError):
            os.rename(target, trash)
            if old is not None:
                rename_noreplace(old, target)
        _remove(trash)
    _remove_created(created)


def finish(undo: bool) -> None:
    """End this command's swaps: delete the old folders and files, or (``undo``) put them back.

    Called by the command line last, with signals ignored; ``undo`` when a signal arrived.

    Parameters
    ----------
    undo : bool
        Put the old folders and files back (a signal arrived) instead of deleting them.
    """
    with interrupts.ignored():
        while _SWAPPED:
            target, old, created, ours = _SWAPPED.pop()
            if not undo:
                if old is not None:
                    _remove(old)
                continue
            _undo(target, old, created, ours)


# ------------------------------------------------------------------------------ files
class OutputFile:
    """One output file, checked before work and written atomically.

    Refuses an empty name, a link, a folder, an existing file without ``force``, one of the
    verb's ``inputs``, a read-only file and a place where nothing can be written. The write is
    refused (exit 2) if the file appeared, or was changed or replaced, after the check.
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
        _writable_place(_existing_ancestor(p, option), option, p)
        remove_dead_leftovers(p)
        self._seen = identity(p)

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """Yield a temporary path; it becomes ``path`` when the block succeeds and ``path`` is
        still what the check saw.

        With :mod:`obsplan.core.interrupts` installed, an old file is kept aside until
        :func:`finish`, so that a signal after the rename still undoes it.

        Yields
        ------
        Path
            A hidden temporary path beside :attr:`path`, with the same suffix, to write to.

        Raises
        ------
        InputError
            If the file appeared, or was replaced or changed, since the check (nothing is
            written then).
        """
        created = _make_parents(self.path)
        tmp = _tmp_name(self.path)
        try:
            yield tmp
            interrupts.check()
            try:
                old = put_in_place(tmp, self.path, self._seen)
            except TargetChanged as exc:
                raise InputError(_changed(self.option, self.path, exc.appeared, "output")) from None
            if interrupts.installed():
                _SWAPPED.append((self.path, old, created, identity(self.path)))
            elif old is not None:
                _remove(old)
        finally:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            if not self.path.exists():
                _remove_created(created)
