"""The one CSV table reader (and writer) behind the trajectory CSV and the logged-track CSV.

It finds the separator (comma, semicolon or tab, from the header line), insists on a header row
(a first line of numbers gets a hint naming the header to add), skips comment lines (first
character ``#``), keeps each row's line number in the file for error messages, and converts named
columns to floats with one error naming the row and column of the first bad cell, or of a value
no vehicle can have (a magnitude check per column: :data:`COLUMN_LIMITS`). A column named twice is
an error, never a silent choice. Files are opened by :func:`obsplan.core.textfiles.read_text`
(encodings, binary files); a file of more than :data:`MAX_ROWS` rows is refused before it is
parsed.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from obsplan.core.atomic import atomic_file
from obsplan.core.errors import TrajectoryFormatError
from obsplan.core.textfiles import check_magnitude, read_text

#: Separators recognised in the header line, in order of preference.
SEPARATORS = (",", ";", "\t")
_SEP_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}
_SEP_DISPLAY = {",": ",", ";": ";", "\t": "<tab>"}
#: Most data rows a table is read with (the track fit's node limit; a trajectory of 2,000,000
#: samples is 55 h at 0.1 s). Larger files are refused before parsing, with their size.
MAX_ROWS = 2_000_000
#: Memory the parsed cells of a table take, about [bytes per cell] (for the refusal's figure).
_BYTES_PER_CELL = 80
#: Largest magnitude and unit of each standard column: beyond any vehicle (positions 10,000 km (as
#: problem files), 10 km/s, 1000 m/s²; times up to 1e10 s so that Unix time stamps are accepted).
COLUMN_LIMITS: dict[str, tuple[float, str]] = {
    "t": (1e10, "s"),
    **{f"p{a}": (1e7, "m") for a in "xyz"},
    **{f"b{a}": (1e7, "m") for a in "xyz"},  # a beacon path's positions (model/beacon.py)
    **{f"v{a}": (1e4, "m/s") for a in "xyz"},
    **{f"u{a}": (1e3, "m/s²") for a in "xyz"},
    # a logged mission's readings (obsplan.io.missionlog): DVL velocities, range, depth
    **{f"dv{a}": (1e4, "m/s") for a in "xyz"},
    "range": (1e7, "m"),
    "depth": (1e7, "m"),
}
#: Magnitude limit of any other numeric column.
OTHER_LIMIT = (1e10, "")


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
        """True if every name is a column.

        Parameters
        ----------
        *names : str
            Column names, lower-case.

        Returns
        -------
        bool
            True if each of ``names`` is in :attr:`columns`.
        """
        return all(n in self.columns for n in names)

    def index(self, name: str) -> int:
        """Position of column ``name``; an error if it is missing or appears twice.

        Parameters
        ----------
        name : str
            Column name, lower-case.

        Returns
        -------
        int
            Its 0-based position in the header.

        Raises
        ------
        TrajectoryFormatError
            If the column is missing or appears more than once.
        """
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

    def numbers(self, names: Sequence[str], blank: bool = False) -> np.ndarray:
        """The named columns as finite floats, shape ``(rows, len(names))``.

        Parameters
        ----------
        names : sequence of str
            Column names, lower-case; each is checked against its magnitude limit
            (:data:`COLUMN_LIMITS`, :data:`OTHER_LIMIT`).
        blank : bool, optional
            Read an empty cell, a cell missing at the end of a short row, or ``nan`` as NaN
            ("no reading in this row", a logged mission's sparse columns); infinities and text
            are still refused. Default False: every cell must be a finite number.

        Returns
        -------
        ndarray, shape (rows, len(names))
            The cells as floats, in the columns' units.

        Raises
        ------
        TrajectoryFormatError
            Naming the line and column of the first missing, non-numeric or non-finite cell.
        """
        idx = [self.index(c) for c in names]
        data = np.empty((len(self.rows), len(names)))
        for i, (r, line) in enumerate(zip(self.rows, self.lines, strict=True)):
            for j, (c, k) in enumerate(zip(names, idx, strict=True)):
                if blank and (k >= len(r) or r[k].strip().lower() in ("", "nan")):
                    data[i, j] = math.nan
                    continue
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
                limit, unit = COLUMN_LIMITS.get(c, OTHER_LIMIT)
                check_magnitude(
                    val,
                    f"{self.path}: row {line}, column {c!r}",
                    limit,
                    unit or "(column unit)",
                    error=TrajectoryFormatError,
                )
                data[i, j] = val
        return data

    def samples(self, names: Sequence[str], where: str, needs: str, hint: str = "") -> np.ndarray:
        """The named columns of a path sampled in time (the first, ``t``, strictly increasing):
        the one check of trajectory, beacon-path and beacon.csv files.

        Parameters
        ----------
        names : sequence of str
            Column names, lower-case, ``t`` first.
        where : str
            What the messages start with (the file, or the field naming it).
        needs : str
            The end of the missing-column message: what the header must contain.
        hint : str, optional
            Said right after the missing columns (e.g. ``" (the trajectory is 3D)"``).

        Returns
        -------
        ndarray, shape (rows, len(names))
            The cells as floats (:meth:`numbers`).

        Raises
        ------
        TrajectoryFormatError
            A missing column, a bad cell, fewer than 2 rows or a time that does not strictly
            increase (its row named).
        """
        missing = [c for c in names if c not in self.columns]
        if missing:
            raise TrajectoryFormatError(
                f"{where}: missing column(s) {', '.join(missing)}{hint}; {needs}"
            )
        data = self.numbers(names)
        if data.shape[0] < 2:
            raise TrajectoryFormatError(
                f"{where}: needs at least 2 data rows, found {data.shape[0]}"
            )
        self.check_increasing(data[:, 0], where, "times must be strictly increasing")
        return data

    def check_increasing(self, t: np.ndarray, where: str, fix: str) -> None:
        """Refuse times ``t`` (one per data row) that do not strictly increase, naming the
        first offending row and its predecessor.

        Parameters
        ----------
        t : ndarray, shape (rows,)
            The table's times [s], in row order.
        where : str
            What the message starts with (the file, or the field naming it).
        fix : str
            The message's last clause: what the user should do.

        Raises
        ------
        TrajectoryFormatError
            At the first time that is not larger than the one before it.
        """
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            k = int(bad[0])
            raise TrajectoryFormatError(
                f"{where}: row {self.lines[k + 1]}, column 't': time {float(t[k + 1])!r} does "
                f"not increase (row {self.lines[k]} has {float(t[k])!r}); {fix}"
            )


def read_table(path: str | Path, example_header: str) -> CsvTable:
    """Read a CSV with a header row; ``example_header`` is shown in hints (e.g. ``t,px,py``).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    example_header : str
        A header the caller expects, comma-separated, shown in the messages' hints.

    Returns
    -------
    CsvTable
        The header, the data rows as text cells and their line numbers.

    Raises
    ------
    TrajectoryFormatError
        For a missing, unreadable, binary or empty file, a file without a header row, or
        columns separated by spaces.
    """
    path = Path(path)
    _check_rows(path)
    text = read_text(
        path, f"a CSV file with a header row {example_header}", error=TrajectoryFormatError
    )
    # comment lines become blank lines: skipped, and the line numbers stay those of the file
    lines = text.split("\n")
    comments = {k: ln.lstrip()[1:] for k, ln in enumerate(lines) if ln.lstrip().startswith("#")}
    for k in comments:
        lines[k] = ""
    text = "\n".join(lines)
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
        before = [k for k in comments if k + 1 < header_line]
        named = before and not all(
            _is_number(c) for c in comments[before[-1]].split(delimiter) if c.strip()
        )
        if named and delimiter in comments[before[-1]]:
            raise TrajectoryFormatError(
                f"{path}: the header is commented out (line {before[-1] + 1} starts with '#'); "
                "remove the '#' so that the first line names the columns"
            )
        raise TrajectoryFormatError(
            f"{path}: line {header_line} looks like data, not a header; the first line must "
            f"name the columns, e.g. {example_header.replace(',', _SEP_DISPLAY[delimiter])}"
        )
    columns = tuple(h.strip().lower() for h in header)
    _check_unique(columns, path, header_line)
    return CsvTable(
        path=path,
        columns=columns,
        rows=tuple(tuple(r) for _, r in numbered[1:]),
        lines=tuple(n for n, _ in numbered[1:]),
        header_line=header_line,
        delimiter=delimiter,
    )


def _check_unique(columns: tuple[str, ...], path: Path, header_line: int) -> None:
    seen: dict[str, list[int]] = {}
    for i, c in enumerate(columns):
        if c:
            seen.setdefault(c, []).append(i + 1)
    for c, where in seen.items():
        if len(where) > 1:
            cols = " and ".join(str(i) for i in where)
            raise TrajectoryFormatError(
                f"{path}: column {c!r} appears {len(where)} times (columns {cols} of the header on "
                f"line {header_line}); remove or rename the extra one"
            )


def _check_rows(path: Path) -> None:
    """Refuse, before parsing, a file of more than :data:`MAX_ROWS` lines (counted in chunks)."""
    if not path.is_file():
        return  # read_text names the problem, without opening a device or a named pipe
    try:
        size = path.stat().st_size
    except OSError:
        return  # read_text names the problem
    if size < 16 * MAX_ROWS:  # fewer bytes than MAX_ROWS of the shortest rows: no count needed
        return
    lines = 0
    cells = 0
    with path.open("rb") as fh:
        first = fh.readline()
        cells = max(1, max(first.count(d.encode()) for d in SEPARATORS) + 1)
        lines = 1
        while chunk := fh.read(1 << 22):
            lines += chunk.count(b"\n")
    rows = lines - 1
    if rows > MAX_ROWS:
        need = rows * cells * _BYTES_PER_CELL / 1e9
        raise TrajectoryFormatError(
            f"{path}: {rows:,} rows ({size / 1e6:,.0f} MB), more than the {MAX_ROWS:,} rows read "
            f"(parsing it would take about {need:.1f} GB of memory); subsample or split the file"
        )


def write_table(path: str | Path, header: Sequence[str], rows: np.ndarray) -> Path:
    """Write a header and numeric rows as a CSV, floats as ``repr`` (exact), atomically.

    Parameters
    ----------
    path : str or Path
        The file to write (replaced whole: :func:`obsplan.core.atomic.atomic_file`).
    header : sequence of str
        Column names.
    rows : ndarray, shape (rows, len(header))
        The numbers, one row per line.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    with atomic_file(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(header))
        for row in np.asarray(rows, float):
            w.writerow([repr(float(x)) for x in row])
    return path


def separator_name(delimiter: str) -> str:
    """``","`` -> ``"comma"`` (for messages).

    Parameters
    ----------
    delimiter : str
        A separator character.

    Returns
    -------
    str
        ``"comma"``, ``"semicolon"`` or ``"tab"``; the ``repr`` of any other character.
    """
    return _SEP_NAMES.get(delimiter, repr(delimiter))
