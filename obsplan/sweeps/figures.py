"""Pictures of a study: each metric against each axis, the plan and the lawn-mower side by side.

One figure per (metric, axis): one panel per path (``planned`` and ``lawnmower`` for a plan
sweep; the lawn-mower and the other baselines for a ``baselines`` sweep), the metric against the
axis with one line per combination of the other axes' values (product sweeps; a zipped sweep has
one line). Panels share the y axis so the plan and the lawn-mower compare at a glance. A metric
spanning two decades or more gets a log axis. Points without a value (a failed task, a
rank-deficient Gramian's ``log_det``, a zero ``min_eig`` on a log axis) are not drawn and are
counted in the panel title.

Figures are built on :class:`matplotlib.figure.Figure` directly (no pyplot state, no GUI
backend) and written atomically.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from functools import partial
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from obsplan.core.errors import InputError
from obsplan.core.outputs import ResumableDir
from obsplan.sweeps.spec import axis_column
from obsplan.sweeps.store import FIGURES, RESULTS_PARQUET, atomic_write, read_manifest
from obsplan.sweeps.table import read_table

#: Metrics drawn by default, by their name inside a path's report (``metrics.<path>.<name>``
#: or ``validation.<path>.<name>``).
DEFAULT_METRICS: tuple[str, ...] = (
    "min_eig",
    "log_det",
    "kf_final_pos_std",
    "ekf.rmse_pos",
    "ekf.final_pos_err",
    "kf.rmse_pos",
    "kf.final_pos_err",
)
_UNITS = {
    "min_eig": "scaled",
    "log_det": "scaled",
    "condition": "-",
    "kf_final_pos_std": "m",
    "crlb_final_pos_std": "m",
}
_BASELINE_ORDER = ("lawnmower", "circle", "straight", "paper-lawnmower")


def paths_in(df: pd.DataFrame) -> list[str]:
    """The paths a table has metrics for: planned and lawn-mower, or the baselines (no plan).

    Parameters
    ----------
    df : pandas.DataFrame
        The results table (:mod:`obsplan.sweeps.table`).

    Returns
    -------
    list of str
        ``"planned"`` and ``"lawnmower"`` (those present) for a plan sweep; otherwise every
        baseline with metrics, the known ones in report order first.
    """
    present = {c.split(".")[1] for c in df.columns if c.startswith("metrics.")}
    if "planned" in present:
        return [p for p in ("planned", "lawnmower") if p in present]
    ordered = [p for p in _BASELINE_ORDER if p in present]
    return ordered + sorted(present - set(ordered))


def metric_column(df: pd.DataFrame, path: str, metric: str) -> str | None:
    """``metrics.<path>.<metric>`` or ``validation.<path>.<metric>``, whichever exists.

    Parameters
    ----------
    df : pandas.DataFrame
        The results table.
    path : str
        A path's name (``"planned"``, ``"lawnmower"``, ...).
    metric : str
        A metric name inside its report, e.g. ``"min_eig"`` or ``"ekf.rmse_pos"``.

    Returns
    -------
    str or None
        The column's name; None when the table has neither.
    """
    for group in ("metrics", "validation"):
        col = f"{group}.{path}.{metric}"
        if col in df.columns:
            return col
    return None


def table_column(df: pd.DataFrame, name: str) -> str:
    """The column of ``df`` called ``name``, or of the axis whose path is ``name``
    (``"limits.accel"`` -> ``"limits.accel [m/s^2]"``: :func:`~obsplan.sweeps.spec.axis_column`).

    Parameters
    ----------
    df : pandas.DataFrame
        The results table.
    name : str
        A column name, or an axis path.

    Returns
    -------
    str
        The column's name (``name`` itself when neither is in the table: pandas then names the
        missing column).
    """
    if name in df.columns:
        return name
    try:
        col = axis_column(name)
    except InputError:  # not a problem-file path: let pandas name the missing column
        return name
    return col if col in df.columns else name


def _numeric(series: pd.Series) -> bool:
    return pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series)


def _as_float(series: pd.Series) -> np.ndarray:
    return pd.to_numeric(series, errors="coerce").to_numpy(dtype=float, na_value=np.nan)


def _label(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str) and v[:1] in "[{":
        try:
            return json.dumps(json.loads(v), separators=(",", ":"))
        except ValueError:
            return v
    return str(v)


def plot_metric(
    df: pd.DataFrame,
    metric: str,
    axis: str,
    *,
    others: Sequence[str] = (),
    paths: Sequence[str] | None = None,
    title: str = "",
    ax=None,
) -> Figure:
    """``metric`` against the axis column ``axis``, one panel per path.

    Parameters
    ----------
    df
        The results table (:mod:`obsplan.sweeps.table`).
    metric
        A metric name inside a path's report, e.g. ``"min_eig"`` or ``"ekf.rmse_pos"``.
    axis
        The axis drawn along x: its column or its path (``"limits.accel"``).
    others
        Axes (columns or paths) whose value combinations each get a line.
    paths
        Panels (default :func:`paths_in`).
    title
        The figure's title (default: ``"<metric> against <axis>"``).
    ax
        A sequence of Axes, one per path (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
    """
    paths = list(paths or paths_in(df))
    axis = table_column(df, axis)
    others = [table_column(df, o) for o in others]
    if ax is None:
        fig = Figure(figsize=(5.0 * len(paths) + 1.0, 4.0), layout="constrained")
        axs = fig.subplots(1, len(paths), sharey=True, squeeze=False)[0]
    else:
        axs = list(ax)
        fig = axs[0].figure
    numeric_x = _numeric(df[axis])
    if numeric_x:
        x_all = _as_float(df[axis])
        categories: list[Any] = []
    else:
        xs_raw = list(df[axis])
        categories = list(dict.fromkeys(xs_raw))
        x_all = np.array([categories.index(v) for v in xs_raw], float)
    groups = df.groupby(list(others), sort=False, dropna=False) if others else [((), df)]
    columns = {p: metric_column(df, p, metric) for p in paths}
    y_all = np.concatenate(
        [_as_float(df[c]) for c in columns.values() if c is not None] or [np.empty(0)]
    )
    finite = y_all[np.isfinite(y_all)]
    pos = finite[finite > 0]
    # a log axis for quantities over decades (lambda_min); zeros (rank deficient) then are not
    # drawn, and are counted as missing in the panel title
    log_y = pos.size >= 2 and pos.size >= finite.size / 2 and pos.max() / pos.min() >= 100
    for path, a in zip(paths, axs, strict=True):
        col = columns[path]
        if col is None:
            a.set_title(f"{path}: no {metric}", fontsize=9)
            continue
        missing = 0
        for key, sub in groups:
            key = key if isinstance(key, tuple) else (key,)
            x = x_all[sub.index.to_numpy()]
            y = _as_float(sub[col])
            order = np.argsort(x, kind="stable")
            label = ", ".join(f"{o} = {_label(v)}" for o, v in zip(others, key, strict=True))
            a.plot(x[order], y[order], "o-", ms=4, label=label or None)
            drawn = np.isfinite(y) & (y > 0) if log_y else np.isfinite(y)
            missing += int(np.sum(~drawn))
        shown = f" ({missing} of {len(df)} points not drawn)" if missing else ""
        a.set_title(f"{path}{shown}", fontsize=9)
        a.set_xlabel(axis)
        a.grid(True, which="both", alpha=0.3)
        if categories:
            a.set_xticks(range(len(categories)), [_label(c) for c in categories], fontsize=8)
        elif np.all(x_all > 0) and x_all.max() / x_all.min() >= 20:
            a.set_xscale("log")
        if log_y:
            a.set_yscale("log")
    unit = _UNITS.get(metric.split(".")[-1], "m")
    axs[0].set_ylabel(f"{metric} [{unit}]")
    if others and len(groups) <= 12:
        axs[-1].legend(fontsize=7)
    fig.suptitle(title or f"{metric} against {axis}", fontsize=10)
    return fig


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-")


def study_figures(
    df: pd.DataFrame,
    folder: str | Path,
    *,
    axes: Sequence[str],
    combine: str = "product",
    name: str = "",
    metrics: Sequence[str] | None = None,
) -> list[Path]:
    """Write ``<metric>_vs_<axis>.png`` into ``folder`` for every metric and axis.

    Parameters
    ----------
    df
        The results table.
    folder
        Where the figures are written (created if missing).
    axes
        The sweep's axis columns.
    combine
        ``"product"``: one line per combination of the other axes; ``"zip"``: one line.
    name
        The study's name (figure titles).
    metrics
        Metric names (default :data:`DEFAULT_METRICS`); those the table lacks are skipped.

    Returns
    -------
    list[Path]
        The files written.
    """
    folder = Path(folder)
    paths = paths_in(df)
    written: list[Path] = []
    if not paths:
        return written
    columns = {a: axis_column(a) for a in axes}
    for metric in metrics or DEFAULT_METRICS:
        if all(metric_column(df, p, metric) is None for p in paths):
            continue
        for axis, col in columns.items():
            if df[col].nunique(dropna=False) < 2:
                continue  # a one-value axis has nothing to show along x
            others = [c for a, c in columns.items() if a != axis] if combine == "product" else []
            others = [o for o in others if df[o].nunique(dropna=False) > 1]
            title = f"{name}: {metric} against {col}" if name else ""
            fig = plot_metric(df, metric, col, others=others, paths=paths, title=title)
            target = folder / f"{_slug(metric)}_vs_{_slug(axis)}.png"
            buf = BytesIO()
            fig.savefig(buf, format="png", dpi=100)
            data = buf.getvalue()
            written.append(atomic_write(target, partial(Path.write_bytes, data=data)))
    return written


def figures_from_manifest(df: pd.DataFrame, out: str | Path, sweep: dict[str, Any]) -> list[Path]:
    """:func:`study_figures` into ``out/figures`` with the axes, combination, name and metrics
    of ``sweep`` (the ``"sweep"`` entry of ``DIR/sweep.json``).

    Parameters
    ----------
    df : pandas.DataFrame
        The results table.
    out : str or Path
        The sweep's folder.
    sweep : dict of str to Any
        The manifest's ``"sweep"`` object: ``axes``, and optionally ``combine``, ``name`` and
        ``figure_metrics``.

    Returns
    -------
    list of Path
        The figure files written.
    """
    return study_figures(
        df,
        Path(out) / FIGURES,
        axes=list(sweep["axes"]),
        combine=sweep.get("combine", "product"),
        name=sweep.get("name", ""),
        metrics=sweep.get("figure_metrics"),
    )


def redraw_figures(out: str | Path) -> list[Path]:
    """Redraw ``DIR/figures/`` from ``DIR/results.parquet`` and ``DIR/sweep.json``.

    Parameters
    ----------
    out : str or Path
        The sweep's folder (``obsplan sweep --report``).

    Returns
    -------
    list of Path
        The figure files written.

    Raises
    ------
    InputError
        If ``out`` holds no sweep or no results table.
    """
    manifest = read_manifest(Path(out), axes=True)
    if not (Path(out) / RESULTS_PARQUET).exists():
        raise InputError(f"{out} has no {RESULTS_PARQUET}; run the sweep first")
    # only a folder an obsplan sweep made, and no sweep is writing into it now
    with ResumableDir(out, "sweep", "--report"):
        return figures_from_manifest(read_table(out), out, manifest["sweep"])
