"""``obsplan problems [NAME | copy NAME FILE]``: the shipped problems, suite and sweeps.

Without arguments the list (name, kind, title); with a NAME that file's text; ``copy NAME FILE``
writes a copy to edit.

The files are package data (:data:`~obsplan.planning.problem.parse.PROBLEMS_DIR`), so every
install has them; ``obsplan plan NAME`` plans one by name. A copied sweep's relative ``base``
(``"../localise.toml"``) and a problem's relative ``path = "..."`` naming a shipped file (a known
beacon path's CSV) are rewritten to the shipped file they name, so the copy runs anywhere.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from obsplan.cli.common import OutputFile
from obsplan.core.errors import InputError
from obsplan.core.textfiles import read_text, read_toml
from obsplan.planning.problem.parse import PROBLEMS_DIR, shipped_file, shipped_files

#: A sweep file's ``base = "..."`` line, or a problem's ``path = "..."`` (relative to the file).
_BASE = re.compile(r'^((?:base|path)\s*=\s*)"([^"]+)"', re.M)


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``problems`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan problems``: ``NAME | copy NAME FILE`` (optional words) and
        ``--force``.
    """
    p = subparsers.add_parser(
        "problems",
        help="list the shipped problems, suite and sweeps; copy one out to edit",
        description=(
            "Without arguments: the shipped problem and sweep files, by name (plan one with "
            "`obsplan plan NAME`). `obsplan problems NAME` prints one; `obsplan problems copy "
            "NAME FILE` writes a copy to edit."
        ),
    )
    p.add_argument(
        "words",
        nargs="*",
        metavar="NAME | copy NAME FILE",
        help='a shipped name (e.g. "default", "suite/far-start"), or copy NAME FILE',
    )
    p.add_argument("--force", action="store_true", help="replace FILE if it exists")
    return p


def describe(path: Path) -> tuple[str, str]:
    """``(kind, title)`` of a shipped file: ``"problem"`` and its ``[problem] name``, or
    ``"sweep"`` and its ``[sweep] name``.

    Parameters
    ----------
    path : Path
        A shipped problem or sweep file (:func:`~obsplan.planning.problem.parse.shipped_files`).

    Returns
    -------
    kind : str
        ``"sweep"`` when the file has a ``[sweep]`` table, else ``"problem"``.
    title : str
        That table's ``name`` (``""`` when it has none).
    """
    data = read_toml(path, "a shipped problem file")
    kind = "sweep" if "sweep" in data else "problem"
    return kind, str(data.get(kind, {}).get("name", ""))


def copied_text(path: Path) -> str:
    """The text of shipped ``path`` as a copy elsewhere needs it: a sweep's relative ``base``
    and a problem's relative ``path`` made absolute (the shipped file they name).

    Parameters
    ----------
    path : Path
        A shipped problem or sweep file.

    Returns
    -------
    str
        Its text, every relative ``base = "..."`` or ``path = "..."`` line naming a shipped file
        replaced by that file's absolute path (``path = "lawnmower"`` names none: kept); the
        rest unchanged.
    """
    text = read_text(path, "a shipped problem file")

    def absolute(m: re.Match[str]) -> str:
        base = Path(m.group(2))
        if base.is_absolute() or not (path.parent / base).is_file():
            return m.group(0)
        return f'{m.group(1)}"{(path.parent / base).resolve().as_posix()}"'

    return _BASE.sub(absolute, text)


def _shipped(name: str) -> Path:
    src = shipped_file(name)
    if src is None:
        raise InputError(f"no shipped file {name!r}; `obsplan problems` lists them")
    return src


def run(args: argparse.Namespace) -> int:
    """Run the verb: the list, one file's text, or one copy; 0 on success.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 (the list or the text printed, or the copy written).

    Raises
    ------
    InputError
        An unknown name, words that are neither ``NAME`` nor ``copy NAME FILE``, or a ``FILE``
        that exists without ``--force`` (exit 2).
    """
    words = list(args.words)
    if not words:
        files = shipped_files()
        width = max(len(n) for n in files)
        print(f"{'NAME':<{width}}  {'KIND':<7}  TITLE")
        for name, path in files.items():
            kind, text = describe(path)
            print(f"{name:<{width}}  {kind:<7}  {text}")
        print(f"{len(files)} files in {PROBLEMS_DIR}")
        print("show one: obsplan problems NAME; edit one: obsplan problems copy NAME FILE")
        return 0
    if words[0] != "copy":
        if len(words) > 1:
            raise InputError("give one NAME to show, or copy NAME FILE to copy one")
        print(read_text(_shipped(words[0]), "a shipped problem file"), end="")
        return 0
    if len(words) != 3:
        raise InputError("copy needs NAME and FILE: obsplan problems copy NAME FILE")
    _, name, file = words
    src = _shipped(name)
    out = OutputFile(file, args.force, "FILE")
    text = copied_text(src)
    with out.writing() as tmp:
        tmp.write_text(text, encoding="utf-8")
    sweep = describe(src)[0] == "sweep"
    then = f"obsplan sweep {out.path} --out DIR" if sweep else f"obsplan plan {out.path}"
    print(f"wrote {out.path} (a copy of {name}); run it with `{then}`")
    return 0
