"""The one place where user text files are opened and user numbers are judged by their size.

Every reader of a user's text file (the trajectory and track CSVs, the problem and sweep TOML
files: :func:`read_toml`) goes through :func:`read_text`, so that a missing file, a folder, a
binary file, a byte-order mark, a file saved in another encoding than UTF-8 or a file far too
large get the same one-line error everywhere, naming the file and the fix. :func:`check_magnitude`
is the one test of "a number no vehicle problem can have" (``1e300`` m, ``1e200`` m of noise), so
that such values are refused by name before any arithmetic overflows.
"""

from __future__ import annotations

import codecs
import math
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from obsplan.core.budget import MAX_TOML_BYTES
from obsplan.core.errors import InputError

#: Largest text file read whole [bytes]; a CSV of 2,000,000 rows of a 3D trajectory is ~400 MB.
MAX_TEXT_BYTES = 1_000_000_000

_BOMS = (
    (codecs.BOM_UTF32_LE, "UTF-32"),
    (codecs.BOM_UTF32_BE, "UTF-32"),
    (codecs.BOM_UTF16_LE, "UTF-16"),
    (codecs.BOM_UTF16_BE, "UTF-16"),
)


def read_text(
    path: str | Path,
    what: str,
    *,
    error: type[InputError] = InputError,
    max_bytes: int = MAX_TEXT_BYTES,
) -> str:
    """The text of a UTF-8 file (a leading byte-order mark dropped), or one clear error.

    Parameters
    ----------
    path
        The file.
    what
        What the file should be, for messages (``"a problem file (TOML)"``).
    error
        The :class:`~obsplan.core.errors.InputError` subclass to raise.
    max_bytes
        Largest size read [bytes].

    Raises
    ------
    InputError
        (as ``error``) for a missing file, a folder, an unreadable, too large or binary file, or
        text that is not UTF-8 (with the line and column of the first bad byte).
    """
    path = Path(path)
    if not path.exists():
        raise error(f"file not found: {path}")
    if not path.is_file():
        raise error(f"{path} is not a file; give the path of {what}")
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise error(
                f"{path}: {size / 1e6:,.0f} MB, more than the {max_bytes / 1e6:,.0f} MB read for "
                f"{what}; split or subsample the file"
            )
        raw = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot be read: {exc.strerror or exc}") from None
    for bom, name in _BOMS:
        if raw.startswith(bom):
            raise error(
                f"{path}: the file is saved as {name} text; save it as UTF-8 (expected {what})"
            )
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8) :]  # Windows editors write one; it is not content
    if b"\x00" in raw:
        if len(raw) >= 4 and (raw[1::2].count(0) > 0.9 * (len(raw) // 2)):
            raise error(
                f"{path}: the file is saved as UTF-16 text (no byte-order mark); save it as "
                f"UTF-8 (expected {what})"
            )
        raise error(f"{path}: not a text file (it contains NUL bytes); expected {what}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error(
            f"{path}: line {line}, column {col}: byte 0x{raw[exc.start]:02x} is not UTF-8 text "
            f"(a Latin-1 or Windows-1252 file, or not text at all); save it as UTF-8 (expected "
            f"{what})"
        ) from None
    return text


def read_toml(
    path: str | Path, what: str, *, error: type[InputError] = InputError
) -> dict[str, Any]:
    """A TOML file (through :func:`read_text`, at most
    :data:`~obsplan.core.budget.MAX_TOML_BYTES`) as a mapping, or one error naming the line."""
    text = read_text(path, what, error=error, max_bytes=MAX_TOML_BYTES)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None


def check_magnitude(
    values: float | Iterable[float],
    name: str,
    limit: float,
    unit: str,
    *,
    error: type[InputError] = InputError,
) -> None:
    """Refuse a value that is not finite or larger in size than ``limit`` (same unit).

    ``name`` is how the message calls the value (an option, a field, a row and column).
    """
    vals = [values] if isinstance(values, int | float) else list(values)
    for v in vals:
        if not math.isfinite(v):
            raise error(f"{name}: {v!r} is not a finite number")
        if abs(v) > limit:
            raise error(
                f"{name}: {v:g} {unit} is beyond ±{limit:g} {unit}, more than any vehicle "
                "problem has; check the units (SI: m, s, m/s, m/s²)"
            )
