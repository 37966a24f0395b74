"""The one CSV table reader (and writer) behind the trajectory CSV and the logged-track CSV.

It finds the separator (comma, semicolon or tab, from the header line), insists on a header row
(a first line of numbers gets a hint naming the header to add), keeps each row's line number in
the file for error messages, and converts named columns to floats with one error naming the row
and column of the first bad cell. A column named twice is an error, never a silent choice.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from obsplan.atomic import atomic_file
from obsplan.errors import TrajectoryFormatError

#: Separators recognised in the header line, in order of preference.
SEPARATORS = (",", ";", "\t")
_SEP_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}
_SEP_DISPLAY = {",": ",", ";": ";", "\t": "<tab>"}


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass(frozen=True, eq=False)
class CsvTable:
    """A CSV file as text cells.

    Attributes
    ----------
    path : Path
    columns : tuple of str
        Header names, stripped and lower-cased.
    rows : tuple of tuple of str
        Data rows (blank lines skipped).
    lines : tuple of int
        Line number in the file of each data row (the header is on ``header_line``).
    header_line : int
    delimiter : str
    """

    path: Path
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    lines: tuple[int, ...]
    header_line: int
    delimiter: str

    def has(self, *names: str) -> bool:
        """True if every name is a column."""
        return all(n in self.columns for n in names)

    def index(self, name: str) -> int:
        """Position of column ``name``; an error if it is missing or appears twice."""
        where = [i for i, c in enumerate(self.columns) if c == name]
        if not where:
            raise TrajectoryFormatError(f"{self.path}: missing column {name!r}")
        if len(where) > 1:
            cols = " and ".join(str(i + 1) for i in where)
            raise TrajectoryFormatError(
                f"{self.path}: column {name!r} appears {len(where)} times (columns {cols} of the "
                f"header on line {self.header_line}); remove or rename the extra one"
            )
        return where[0]

    def numbers(self, names: Sequence[str]) -> np.ndarray:
        """The named columns as finite floats, shape ``(rows, len(names))``.

        Raises
        ------
        TrajectoryFormatError
            Naming the line and column of the first missing, non-numeric or non-finite cell.
        """
        idx = [self.index(c) for c in names]
        data = np.empty((len(self.rows), len(names)))
        for i, (r, line) in enumerate(zip(self.rows, self.lines, strict=True)):
            for j, (c, k) in enumerate(zip(names, idx, strict=True)):
                if k >= len(r):
                    raise TrajectoryFormatError(
                        f"{self.path}: row {line} has no value for column {c!r}"
                    )
                cell = r[k].strip()
                try:
                    val = float(cell)
                except ValueError:
                    hint = ""
                    if self.delimiter != "," and _is_number(cell.replace(",", ".", 1)):
                        hint = "; decimal commas are not supported: write 1.5, not 1,5"
                    raise TrajectoryFormatError(
                        f"{self.path}: row {line}, column {c!r}: {cell!r} is not a number{hint}"
                    ) from None
                if not math.isfinite(val):
                    raise TrajectoryFormatError(
                        f"{self.path}: row {line}, column {c!r}: {cell!r} is not finite (NaN/inf)"
                    )
                data[i, j] = val
        return data


def read_table(path: str | Path, example_header: str) -> CsvTable:
    """Read a CSV with a header row; ``example_header`` is shown in hints (e.g. ``t,px,py``).

    Raises
    ------
    TrajectoryFormatError
        For a missing, unreadable, binary or empty file, a file without a header row, or
        columns separated by spaces.
    """
    path = Path(path)
    if not path.exists():
        raise TrajectoryFormatError(f"file not found: {path}")
    if not path.is_file():
        raise TrajectoryFormatError(f"{path} is not a file; give the path of a CSV file")
    try:
        # utf-8-sig drops a byte-order mark before the header
        with path.open(newline="", encoding="utf-8-sig") as fh:
            text = fh.read()
    except UnicodeDecodeError as exc:
        raise TrajectoryFormatError(
            f"{path}: not a text CSV (undecodable byte at position {exc.start}); expected UTF-8 "
            f"text with a header row {example_header}"
        ) from None
    except OSError as exc:
        raise TrajectoryFormatError(f"{path}: cannot be read: {exc.strerror}") from None
    if "\x00" in text:
        raise TrajectoryFormatError(f"{path}: not a text CSV (it contains NUL bytes)")
    first = next((ln for ln in text.split("\n") if ln.strip()), None)
    if first is None:
        raise TrajectoryFormatError(
            f"{path}: the file is empty; expected a header row {example_header}"
        )
    delimiter = next((d for d in SEPARATORS if d in first), None)
    if delimiter is None and len(first.split()) > 1:
        raise TrajectoryFormatError(
            f"{path}: columns separated by spaces are not supported; separate them by commas "
            f"(or semicolons or tabs) under a header row {example_header}"
        )
    delimiter = delimiter or ","
    numbered: list[tuple[int, list[str]]] = []
    try:
        reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
        for r in reader:
            if any(c.strip() for c in r):
                numbered.append((reader.line_num, r))
    except csv.Error as exc:
        raise TrajectoryFormatError(f"{path}: not a readable CSV: {exc}") from None
    if not numbered:
        raise TrajectoryFormatError(
            f"{path}: the file is empty; expected a header row {example_header}"
        )
    header_line, header = numbered[0]
    if all(_is_number(c) for c in header if c.strip()):
        raise TrajectoryFormatError(
            f"{path}: line {header_line} looks like data, not a header; the first line must "
            f"name the columns, e.g. {example_header.replace(',', _SEP_DISPLAY[delimiter])}"
        )
    columns = tuple(h.strip().lower() for h in header)
    return CsvTable(
        path=path,
        columns=columns,
        rows=tuple(tuple(r) for _, r in numbered[1:]),
        lines=tuple(n for n, _ in numbered[1:]),
        header_line=header_line,
        delimiter=delimiter,
    )


def write_table(path: str | Path, header: Sequence[str], rows: np.ndarray) -> Path:
    """Write a header and numeric rows as a CSV, floats as ``repr`` (exact), atomically."""
    path = Path(path)
    with atomic_file(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(header))
        for row in np.asarray(rows, float):
            w.writerow([repr(float(x)) for x in row])
    return path


def separator_name(delimiter: str) -> str:
    """``","`` -> ``"comma"`` (for messages)."""
    return _SEP_NAMES.get(delimiter, repr(delimiter))
