"""The results table: one row per task, built from the stored reports.

Columns, in order: ``task_id``, ``task`` (1-based number in the sweep), one column per axis
(named by its dotted path and unit, ``limits.accel [m/s^2]``: :func:`~obsplan.sweeps.spec.
axis_column`; list values as JSON text), ``status`` (``done``, ``failed`` or ``pending``),
``error``, ``attempts``, ``task_wall_s`` [s], ``worker``, then the report flattened
generically: nested keys joined by dots (``solver.success``, ``metrics.planned.min_eig``,
``validation.lawnmower.ekf.rmse_pos``, ``verdict...``), lists of tables by index
(``solver.starts.0.status``), other lists as JSON text. A key the report
gains later becomes a column without any change here.

Every column has one type whatever the tasks' outcomes: pandas' nullable ``boolean``, ``Int64``
and ``string`` dtypes, so that a failed or pending task's missing value is ``<NA>`` and never
turns a bool column into objects or an int column into floats; floats are ``float64`` with NaN.
:data:`FIXED_TYPES` holds for the bookkeeping and solver columns; the others take the type of
their values (:func:`column_type`). Parquet keeps these types; the CSV leaves a missing value
empty.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from obsplan.core.errors import InputError
from obsplan.core.textfiles import check_regular_file
from obsplan.sweeps.spec import Task, axis_column
from obsplan.sweeps.store import RESULTS_CSV, RESULTS_PARQUET, atomic_write

#: Report keys not flattened into the table: the task bookkeeping (its own columns) and the full
#: resolved problem (the axes say what varies; the rest is in sweep.json and report.json).
SKIP_KEYS = ("sweep",)
#: Columns that measure time or place and so differ between two runs of the same sweep.
RUN_DEPENDENT_SUFFIXES = ("wall_s", "build_s", "worker", "attempts")
#: Columns whose type is fixed (pandas nullable dtypes), present or not in a task's report.
FIXED_TYPES: dict[str, str] = {
    "task_id": "string",
    "task": "Int64",
    "status": "string",
    "error": "string",
    "attempts": "Int64",
    "task_wall_s": "float64",
    "worker": "string",
    "solver.success": "boolean",
    "solver.status": "string",
    "solver.iterations": "Int64",
    "solver.wall_s": "float64",
}
#: :func:`column_type` of a column mixing kinds of values: JSON text in a ``string`` column.
JSON_TEXT = "json"


def flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mapping -> ``{"a.b.c": value}``; lists become JSON text, non-finite floats None.

    Parameters
    ----------
    data : Mapping of str to Any
        A report (or part of one), as JSON values.
    prefix : str, optional
        Prepended to every key (``"solver."`` when recursing).

    Returns
    -------
    dict of str to Any
        Dotted key -> scalar; a list of mappings is flattened by index (``solver.starts.0.status``).
    """
    out: dict[str, Any] = {}
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, name + "."))
        elif (
            isinstance(value, list | tuple) and value and all(isinstance(v, Mapping) for v in value)
        ):
            # e.g. solver.starts: one group of columns per element (solver.starts.0.status)
            out.update(flatten({str(i): v for i, v in enumerate(value)}, name + "."))
        elif isinstance(value, list | tuple):
            out[name] = json.dumps(value)
        elif isinstance(value, float) and not math.isfinite(value):
            out[name] = None
        else:
            out[name] = value
    return out


def _tables(value: Any) -> bool:
    return (
        isinstance(value, list | tuple)
        and bool(value)
        and all(isinstance(v, Mapping) for v in value)
    )


def cell(value: Any) -> Any:
    """An axis value as a table cell: scalars as they are, lists and tables as JSON text.

    Parameters
    ----------
    value : Any
        The value a task takes on one axis.

    Returns
    -------
    Any
        ``value``, or its JSON text for a list, tuple or mapping.
    """
    if isinstance(value, list | tuple | Mapping):
        return json.dumps(value)
    return value


def row(task: Task, stored: Mapping[str, Any] | None) -> dict[str, Any]:
    """The table row of ``task`` from its stored report (None: not finished yet).

    Parameters
    ----------
    task : Task
        The task (its id, index and axis values).
    stored : Mapping of str to Any or None
        Its ``report.json``; None for a pending task.

    Returns
    -------
    dict of str to Any
        Column name -> cell: the bookkeeping and axis columns, then the flattened report.
    """
    out: dict[str, Any] = {"task_id": task.id, "task": task.index + 1}
    out.update({axis_column(path): cell(v) for path, v in task.axes.items()})
    if stored is None:
        out.update(status="pending", error=None, attempts=0, task_wall_s=None, worker=None)
        return out
    meta = stored.get("sweep", {})
    out.update(
        status=meta.get("status"),
        error=meta.get("error"),
        attempts=meta.get("attempts"),
        task_wall_s=meta.get("wall_s"),
        worker=meta.get("worker"),
    )
    report = {k: v for k, v in stored.items() if k not in SKIP_KEYS}
    for key, value in flatten(report).items():
        out.setdefault(key, value)  # an axis column wins over a same-named report key
    return out


def build_table(
    tasks: Sequence[Task], stored: Mapping[str, Mapping[str, Any] | None]
) -> pd.DataFrame:
    """One row per task (in sweep order); ``stored`` maps task id -> report (or None).

    Parameters
    ----------
    tasks : sequence of Task
        The sweep's tasks, in order.
    stored : Mapping of str to Mapping or None
        Task id -> its report (a missing id, or None: pending).

    Returns
    -------
    pandas.DataFrame
        The results table: columns in first-seen order, each of one nullable type (module
        docstring).
    """
    rows = [row(t, stored.get(t.id)) for t in tasks]
    columns: dict[str, None] = {}
    for r in rows:
        columns.update(dict.fromkeys(r))
    data = {c: typed_column([r.get(c) for r in rows], FIXED_TYPES.get(c)) for c in columns}
    return pd.DataFrame(data, index=pd.RangeIndex(len(rows)))


def column_type(values: Iterable[Any]) -> str:
    """The nullable pandas dtype of a column's values, missing ones (None, NaN) left aside:
    ``boolean``, ``Int64``, ``float64`` (ints and floats mixed too; missing is NaN, as numpy
    and string formatting expect), ``string``, or :data:`JSON_TEXT` for other mixtures (e.g. an
    axis of numbers and lists). A column with no value at all is ``float64`` (a metric that was
    never finite).

    Parameters
    ----------
    values : iterable
        The column's cells.

    Returns
    -------
    str
        A pandas dtype name, or :data:`JSON_TEXT`.
    """
    kinds = {_kind(v) for v in values if not _missing(v)}
    if not kinds:
        return "float64"
    if len(kinds) == 1:
        return {"bool": "boolean", "int": "Int64", "float": "float64", "str": "string"}.get(
            kinds.pop(), JSON_TEXT
        )
    return "float64" if kinds == {"int", "float"} else JSON_TEXT


def typed_column(values: Sequence[Any], dtype: str | None = None) -> pd.Series:
    """``values`` as a Series of ``dtype`` (default :func:`column_type`); missing -> ``<NA>``
    (NaN in a float column).

    Parameters
    ----------
    values : sequence
        The column's cells.
    dtype : str or None, optional
        A pandas dtype name or :data:`JSON_TEXT` (values that are not text then become JSON
        text in a ``string`` column); None: :func:`column_type` of ``values``.

    Returns
    -------
    pandas.Series
        The column, of that dtype.
    """
    dtype = dtype or column_type(values)
    cells: list[Any] = [None if _missing(v) else v for v in values]
    if dtype == JSON_TEXT:
        dtype = "string"
        cells = [v if v is None or isinstance(v, str) else json.dumps(v) for v in cells]
    return pd.Series(pd.array(cells, dtype=dtype))


def _kind(v: Any) -> str:
    if isinstance(v, bool):  # before int: a bool is an int to Python
        return "bool"
    if isinstance(v, int):
        return "int"
    if isinstance(v, float):
        return "float"
    return "str" if isinstance(v, str) else "other"


def _missing(v: Any) -> bool:
    return v is None or v is pd.NA or _isnan(v)


def _isnan(v: Any) -> bool:
    return isinstance(v, float) and math.isnan(v)


def write_table(df: pd.DataFrame, out: Path) -> tuple[Path, Path]:
    """``DIR/results.parquet`` and ``DIR/results.csv``, each written atomically.

    Parameters
    ----------
    df : pandas.DataFrame
        The results table (:func:`build_table`).
    out : Path
        The sweep's folder.

    Returns
    -------
    parquet : Path
        ``DIR/results.parquet``.
    csv : Path
        ``DIR/results.csv``.
    """
    pq = atomic_write(out / RESULTS_PARQUET, lambda tmp: df.to_parquet(tmp, index=False))
    csv = atomic_write(out / RESULTS_CSV, lambda tmp: df.to_csv(tmp, index=False))
    return pq, csv


def read_table(out: str | Path) -> pd.DataFrame:
    """``DIR/results.parquet`` as a DataFrame (the column types of :func:`build_table`).

    Parameters
    ----------
    out : str or Path
        The sweep's folder.

    Returns
    -------
    pandas.DataFrame
        The results table.

    Raises
    ------
    InputError
        If the file is missing or damaged (it is rewritten from the tasks' reports by running
        the sweep again).
    """
    path = Path(out) / RESULTS_PARQUET
    check_regular_file(path, "a sweep's results table (Parquet)")
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises its own error types for every damaged file
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"{path}: not a readable results table ({text[:200]}); run the sweep again to "
            "rewrite it from the tasks' reports"
        ) from None


def comparable(df: pd.DataFrame, drop: Iterable[str] = RUN_DEPENDENT_SUFFIXES) -> pd.DataFrame:
    """``df`` without the columns that measure time or place (two runs of a sweep agree on the
    rest exactly: every solver and Monte Carlo run is seeded).

    Parameters
    ----------
    df : pandas.DataFrame
        A results table.
    drop : iterable of str, optional
        Suffixes of the columns left out (default :data:`RUN_DEPENDENT_SUFFIXES`).

    Returns
    -------
    pandas.DataFrame
        The other columns, in order.
    """
    keep = [c for c in df.columns if not any(c.endswith(s) for s in drop)]
    return df[keep]
