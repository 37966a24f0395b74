"""The one place where user text files are opened and user numbers are judged by their size.

Every reader of a user's text file (the trajectory and track CSVs, the problem and sweep TOML
files: :func:`read_toml`; the JSON a verb reads back: :func:`read_json`) goes through
:func:`read_text`, so that a missing file, a folder, a device or a named pipe (``/dev/zero``, a
FIFO: :func:`check_regular_file`, which never opens them), a binary file, a byte-order mark, a
file saved in another encoding than UTF-8, a file far too large, arrays nested thousands of levels
deep or an integer of thousands of digits get the same one-line error everywhere, naming the file
and the fix. :func:`check_magnitude` is the one test of "a number no vehicle problem can have"
(``1e300`` m, ``1e200`` m of noise, a scale of ``1e-300`` m), so that such values are refused by
name before any arithmetic overflows or underflows. :func:`toml_text` writes the
TOML that :func:`read_toml` reads back (a problem file written from Python).
"""

from __future__ import annotations

import codecs
import json
import math
import numbers
import re
import stat
import tomllib
from collections.abc import Iterable, Mapping
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


_KINDS = (
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISSOCK, "a socket"),
)


def check_regular_file(
    path: str | Path, what: str, *, error: type[InputError] = InputError
) -> Path:
    """``path`` if it is a regular file (a link to one counts), else one clear error.

    Nothing is opened: a named pipe would block the reader forever and a device such as
    ``/dev/zero`` never ends.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file should be, for messages (``"a problem file (TOML)"``).
    error : type of InputError, optional
        The :class:`~obsplan.core.errors.InputError` subclass to raise.

    Returns
    -------
    Path
        ``path``, a regular file.

    Raises
    ------
    InputError
        (as ``error``) for a missing path, a folder, a device, a named pipe or a socket.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise error(f"file not found: {path}") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read: {exc.strerror or exc}") from None
    if stat.S_ISREG(mode):
        return path
    if stat.S_ISDIR(mode):
        raise error(f"{path} is a folder, not a file; give the path of {what}")
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    raise error(f"{path} is not a regular file ({kind}); give the path of {what}")


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
    path : str or Path
        The file.
    what : str
        What the file should be, for messages (``"a problem file (TOML)"``).
    error : type of InputError, optional
        The :class:`~obsplan.core.errors.InputError` subclass to raise.
    max_bytes : int, optional
        Largest size read [bytes].

    Returns
    -------
    str
        The text, decoded from UTF-8.

    Raises
    ------
    InputError
        (as ``error``) for a missing file, a folder, a device or a named pipe
        (:func:`check_regular_file`), an unreadable, too large or binary file, or text that is
        not UTF-8 (with the line and column of the first bad byte).
    """
    path = check_regular_file(path, what, error=error)
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


#: Deepest nesting of arrays and tables (objects) read from a TOML or JSON file: the files
#: obsplan reads nest a few levels (a mission's lines: section, field, list of lists), while
#: thousands exhaust the stack of the parser or of whatever walks the result (a deep copy).
MAX_NESTING = 64
#: The refusal of a file nested too deeply (by the parser's stack, or by :data:`MAX_NESTING`).
_NESTING_WORDS = (
    "arrays or tables nested {depth} levels deep ({what} nests a few, and at most {limit} are "
    "read); is it the right file?"
)


def _check_nesting(data: Any, path: str | Path, what: str, error: type[InputError]) -> Any:
    """``data`` if no array or table in it is nested deeper than :data:`MAX_NESTING` (walked
    without recursion), else one error naming the file."""
    stack = [(data, 0)]
    while stack:
        obj, depth = stack.pop()
        if isinstance(obj, dict | list):
            if depth >= MAX_NESTING:
                words = _NESTING_WORDS.format(
                    depth=f"more than {MAX_NESTING}", limit=MAX_NESTING, what=what
                )
                raise error(f"{path}: {words}")
            stack.extend((v, depth + 1) for v in (obj.values() if isinstance(obj, dict) else obj))
    return data


def read_toml(
    path: str | Path, what: str, *, error: type[InputError] = InputError
) -> dict[str, Any]:
    """A TOML file (through :func:`read_text`, at most
    :data:`~obsplan.core.budget.MAX_TOML_BYTES`) as a mapping, or one error naming the line.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    what : str
        What the file should be, for messages (``"a problem file (TOML)"``).
    error : type of InputError, optional
        The :class:`~obsplan.core.errors.InputError` subclass to raise.

    Returns
    -------
    dict
        The parsed tables and values.

    Raises
    ------
    InputError
        (as ``error``) for everything :func:`read_text` refuses, text that is not TOML, arrays
        or tables nested deeper than :data:`MAX_NESTING` levels, or an integer of more digits
        than Python converts.
    """
    text = read_text(path, what, error=error, max_bytes=MAX_TOML_BYTES)
    try:
        data = tomllib.loads(text)
    except RecursionError:
        words = _NESTING_WORDS.format(depth="hundreds of", limit=MAX_NESTING, what=what)
        raise error(f"{path}: {words}") from None
    except ValueError as exc:  # TOMLDecodeError, or an integer of more than 4300 digits
        raise error(f"{path}: not valid TOML: {_first_line(exc)}") from None
    return _check_nesting(data, path, what, error)


def read_json(path: str | Path, what: str, *, error: type[InputError] = InputError) -> Any:
    """A JSON file (through :func:`read_text`) as plain data, or one error naming the file.

    Parameters
    ----------
    path : str or Path
        The JSON file.
    what : str
        What the file should be, for messages.
    error : type of InputError, optional
        The :class:`~obsplan.core.errors.InputError` subclass to raise.

    Returns
    -------
    object
        The parsed data (dicts, lists, strings, numbers, booleans, None).

    Raises
    ------
    InputError
        (as ``error``) for everything :func:`read_text` refuses, text that is not JSON, arrays
        or objects nested deeper than :data:`MAX_NESTING` levels, or an integer of more digits
        than Python converts.
    """
    text = read_text(path, what, error=error)
    try:
        data = json.loads(text)
    except RecursionError:
        words = _NESTING_WORDS.format(depth="hundreds of", limit=MAX_NESTING, what=what)
        raise error(f"{path}: {words}") from None
    except ValueError as exc:
        raise error(f"{path}: not valid JSON: {_first_line(exc)}") from None
    return _check_nesting(data, path, what, error)


def _first_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def toml_text(data: Mapping[str, Any], header: str = "") -> str:
    """A mapping as TOML text that :func:`read_toml` (``tomllib``) reads back equal.

    Parameters
    ----------
    data
        Top-level keys: scalars first, then one ``[table]`` per mapping value. Values: bool,
        int, float (written by ``repr``: exact; ``inf``/``nan`` as TOML's), str, lists of
        values, and mappings inside a table as inline tables.
    header
        Text written first as ``#`` comment lines.

    Returns
    -------
    str
        The TOML document, ending with a newline.

    Raises
    ------
    TypeError
        A value (named by its dotted key) that TOML cannot hold, such as None.

    Examples
    --------
    >>> print(toml_text({"horizon": {"duration": 600.0, "steps": 200}}, header="a problem"), end="")
    # a problem
    <BLANKLINE>
    [horizon]
    duration = 600.0
    steps = 200
    """
    lines = [f"# {ln}".rstrip() for ln in header.splitlines()]
    if lines:
        lines.append("")
    tables = {k: v for k, v in data.items() if isinstance(v, Mapping)}
    for key, value in data.items():
        if key not in tables:
            lines.append(f"{_toml_key(key)} = {_toml_value(value, key)}")
    if len(tables) < len(data):
        lines.append("")
    for name, table in tables.items():
        lines.append(f"[{_toml_key(name)}]")
        for key, value in table.items():
            lines.append(f"{_toml_key(key)} = {_toml_value(value, f'{name}.{key}')}")
        lines.append("")
    return "\n".join(lines[:-1] if lines and lines[-1] == "" else lines) + "\n"


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_string(key)


def _toml_string(s: str) -> str:
    # JSON's escapes (\", \\, \n, \uXXXX) are TOML's; DEL must be escaped in TOML too
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def _toml_value(value: Any, where: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        x = float(value)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v, f"{where}[]") for v in value) + "]"
    if isinstance(value, Mapping):
        items = (f"{_toml_key(k)} = {_toml_value(v, f'{where}.{k}')}" for k, v in value.items())
        return "{" + ", ".join(items) + "}"
    raise TypeError(f"{where}: {value!r} has no TOML form (TOML has no null)")


def check_magnitude(
    values: float | Iterable[float],
    name: str,
    limit: float,
    unit: str,
    *,
    smallest: float = 0.0,
    error: type[InputError] = InputError,
) -> None:
    """Refuse a value that is not finite, larger in size than ``limit`` or, when ``smallest``
    is given, non-zero and smaller in size than ``smallest`` (all in ``unit``).

    Parameters
    ----------
    values : float or iterable of float
        One number or several (each is judged; the first bad one is named).
    name : str
        How the message calls the value: an option, a field, a row and column.
    limit : float
        Largest size accepted.
    unit : str
        Unit of the values and limits, for the message (``""`` or ``"-"``: none).
    smallest : float, optional
        Smallest non-zero size accepted (a scale or a step of ``1e-300`` underflows what it
        divides); 0: no lower bound.
    error : type of InputError, optional
        The :class:`~obsplan.core.errors.InputError` subclass to raise.

    Raises
    ------
    InputError
        (as ``error``) For the first value that is not finite or out of bounds.
    """
    vals = [values] if isinstance(values, int | float) else list(values)
    u = "" if unit in ("", "-") else f" {unit}"
    for v in vals:
        if not math.isfinite(v):
            raise error(f"{name}: {v!r} is not a finite number")
        if abs(v) > limit:
            raise error(
                f"{name}: {v:g}{u} is beyond ±{limit:g}{u}, more than any vehicle problem has; "
                "check the units (SI: m, s, m/s, m/s²)"
            )
        if 0 < abs(v) < smallest:
            raise error(
                f"{name}: {v:g}{u} is below {smallest:g}{u} in size, less than any vehicle "
                "problem has; check the units (SI: m, s, m/s, m/s²)"
            )
