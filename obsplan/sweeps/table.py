"""The results table: one row per task, built from the stored reports.

Columns, in order: ``task_id``, ``task`` (1-based number in the sweep), one column per axis
(named by its dotted path; list values as JSON text), ``status`` (``done``, ``failed`` or
``pending``), ``error``, ``attempts``, ``task_wall_s`` [s], ``worker``, then the report flattened
generically: nested keys joined by dots (``solver.success``, ``metrics.planned.min_eig``,
``validation.lawnmower.ekf.rmse_pos``, ``verdict...``), lists of tables by index
(``solver.starts.0.status``), other lists as JSON text. A key the report
gains later becomes a column without any change here.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from obsplan.sweeps.spec import Task
from obsplan.sweeps.store import RESULTS_CSV, RESULTS_PARQUET, atomic_write

#: Report keys not flattened into the table: the task bookkeeping (its own columns) and the full
#: resolved problem (the axes say what varies; the rest is in sweep.json and report.json).
SKIP_KEYS = ("sweep",)
#: Columns that measure time or place and so differ between two runs of the same sweep.
RUN_DEPENDENT_SUFFIXES = ("wall_s", "build_s", "worker", "attempts")


def flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mapping -> ``{"a.b.c": value}``; lists become JSON text, non-finite floats None."""
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
    """An axis value as a table cell: scalars as they are, lists and tables as JSON text."""
    if isinstance(value, list | tuple | Mapping):
        return json.dumps(value)
    return value


def row(task: Task, stored: Mapping[str, Any] | None) -> dict[str, Any]:
    """The table row of ``task`` from its stored report (None: not finished yet)."""
    out: dict[str, Any] = {"task_id": task.id, "task": task.index + 1}
    out.update({path: cell(v) for path, v in task.axes.items()})
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
    """One row per task (in sweep order); ``stored`` maps task id -> report (or None)."""
    rows = [row(t, stored.get(t.id)) for t in tasks]
    columns: dict[str, None] = {}
    for r in rows:
        columns.update(dict.fromkeys(r))
    return pd.DataFrame(rows, columns=list(columns))


def _arrow_safe(df: pd.DataFrame) -> pd.DataFrame:
    """Columns mixing Python types (e.g. an axis of numbers and lists) as JSON text, so that
    parquet, which needs one type per column, can store them."""
    df = df.copy()
    for col in df.columns:
        if df[col].dtype != object:
            continue
        kinds = {type(v) for v in df[col] if v is not None and not _isnan(v)}
        if len(kinds) > 1 and not kinds <= {int, float}:
            df[col] = [
                None if v is None or _isnan(v) else v if isinstance(v, str) else json.dumps(v)
                for v in df[col]
            ]
    return df


def _isnan(v: Any) -> bool:
    return isinstance(v, float) and math.isnan(v)


def write_table(df: pd.DataFrame, out: Path) -> tuple[Path, Path]:
    """``DIR/results.parquet`` and ``DIR/results.csv``, each written atomically."""
    safe = _arrow_safe(df)
    pq = atomic_write(out / RESULTS_PARQUET, lambda tmp: safe.to_parquet(tmp, index=False))
    csv = atomic_write(out / RESULTS_CSV, lambda tmp: safe.to_csv(tmp, index=False))
    return pq, csv


def read_table(out: str | Path) -> pd.DataFrame:
    """``DIR/results.parquet`` as a DataFrame."""
    return pd.read_parquet(Path(out) / RESULTS_PARQUET)


def comparable(df: pd.DataFrame, drop: Iterable[str] = RUN_DEPENDENT_SUFFIXES) -> pd.DataFrame:
    """``df`` without the columns that measure time or place (two runs of a sweep agree on the
    rest exactly: every solver and Monte Carlo run is seeded)."""
    keep = [c for c in df.columns if not any(c.endswith(s) for s in drop)]
    return df[keep]
