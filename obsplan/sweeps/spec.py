"""Sweep files: a base problem, axes of dotted problem-file fields, and their expansion into tasks.

A sweep file (TOML, reference in ``docs/sweep-files.md``) names a base problem (``sweep.base``, a
problem file relative to the sweep file, and/or an inline ``[base]`` table with the problem
file's sections, merged over it section by section) and ``[axes]``: dotted field paths of the
problem file (``limits.accel``, ``beacon.position``, ``limits.accel.2`` for one component) with a
list of values or a generator table (``{range = 5}``, ``{linspace = [a, b, n]}``,
``{geomspace = [a, b, n]}``). The axes are combined as a product (default) or zipped.

Every task is the base mapping with its axis values written in (on the raw TOML mapping, so
fields the base leaves to their defaults keep adapting, e.g. a default beacon to a changed
``vehicle.dim``) and validated by :func:`obsplan.planning.problem.definition.problem_from_dict`
before anything runs: a typo in the 50th task is an error naming the task and the field. A task's
identity is a hash of its resolved problem
(:func:`~obsplan.planning.problem.definition.problem_to_dict`, defaults filled in), its mode, the
package version and a fingerprint of the package's code (:func:`code_fingerprint`): the same problem
in another sweep, or in an edited version of the same sweep, is the same task; the same problem
computed by changed code is another one.
"""

from __future__ import annotations

import copy
import difflib
import functools
import hashlib
import itertools
import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, cast

import numpy as np

from obsplan.core import budget
from obsplan.core.errors import InputError, ProblemError
from obsplan.core.textfiles import read_toml
from obsplan.estimation.montecarlo.runs import FILTERS
from obsplan.estimation.montecarlo.stats import FilterStats
from obsplan.planning.objectives.evaluate import PathMetrics
from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict
from obsplan.planning.problem.schema import SCHEMA
from obsplan.version import __version__

#: What each task computes: ``plan`` (plan + validation against the baselines) or ``baselines``
#: (only the metrics and Monte Carlo validation of the baselines; no solver, cheap).
MODES: tuple[str, ...] = ("plan", "baselines")
COMBINE: tuple[str, ...] = ("product", "zip")
#: Keys of ``[sweep]``.
SWEEP_KEYS: tuple[str, ...] = ("name", "base", "mode", "combine")
#: Generator tables accepted as axis values.
GENERATORS: tuple[str, ...] = ("range", "linspace", "geomspace")
#: Problem-file fields whose missing value defaults to zeros of length ``vehicle.dim`` (so that a
#: component axis such as ``beacon.position.0`` can be applied on a base that omits them).
_ZERO_DEFAULTS = {("beacon", "position"), ("start", "velocity"), ("vehicle", "current_velocity")}
_INDEXABLE = {"vec", "vec-or-float", "range", "str-list"}


class SweepFileError(InputError):
    """A sweep file (or mapping) that is malformed, or one of whose tasks is not a valid problem."""


@dataclass(frozen=True)
class Axis:
    """One axis: a dotted field path of the problem file and its values (plain TOML data)."""

    path: str
    keys: tuple[str | int, ...]
    values: tuple[Any, ...]


@dataclass(frozen=True, eq=False)
class SweepSpec:
    """A parsed sweep file.

    Attributes
    ----------
    name : str
        Shown in reports and figure titles (default: the sweep file's stem).
    base : dict
        The raw problem-file mapping every task starts from.
    base_name : str
        Name given to the task problems when ``[problem].name`` is not set.
    axes : tuple[Axis, ...]
        In file order.
    combine : str
        ``"product"`` or ``"zip"``.
    mode : str
        ``"plan"`` or ``"baselines"``.
    figure_metrics : tuple[str, ...] or None
        ``[figures] metrics`` (None: the default list of :mod:`obsplan.sweeps.figures`).
    source : Path or None
        The sweep file, if read from one.
    """

    name: str
    base: dict[str, Any]
    base_name: str
    axes: tuple[Axis, ...]
    combine: str = "product"
    mode: str = "plan"
    figure_metrics: tuple[str, ...] | None = None
    source: Path | None = field(default=None, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (stored as ``DIR/sweep.json``).

        Returns
        -------
        dict of str to Any
            The name, mode, combine, axes (path -> list of values), raw base mapping, base name,
            figure metrics and source path (as text, or None).
        """
        return {
            "name": self.name,
            "mode": self.mode,
            "combine": self.combine,
            "axes": {a.path: list(a.values) for a in self.axes},
            "base": self.base,
            "base_name": self.base_name,
            "figure_metrics": None if self.figure_metrics is None else list(self.figure_metrics),
            "source": None if self.source is None else str(self.source),
        }


@dataclass(frozen=True, eq=False)
class Task:
    """One problem of a sweep, validated.

    Attributes
    ----------
    id : str
        16 hex digits of SHA-256 of the resolved problem, the mode, the package version and
        the code fingerprint (:func:`code_fingerprint`).
    index : int
        Position in the sweep's expansion (0-based).
    axes : dict[str, Any]
        Axis path -> the value this task takes.
    mode : str
    problem : dict
        The resolved problem (:func:`~obsplan.planning.problem.definition.problem_to_dict`): every
        field present, rebuilt on the worker with
        :func:`~obsplan.planning.problem.definition.problem_from_dict`.
    """

    id: str
    index: int
    axes: dict[str, Any]
    mode: str
    problem: dict[str, Any]


# ------------------------------------------------------------------------------ reading
def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep file (the tasks are validated by :func:`expand`).

    Parameters
    ----------
    path : str or Path
        The sweep file (TOML); ``sweep.base`` is relative to its folder.

    Returns
    -------
    SweepSpec
        Named by ``sweep.name``, or else the file's stem.

    Raises
    ------
    SweepFileError
        Missing file, invalid TOML, unknown key, bad axis path or values, missing base.
    """
    path = Path(path)
    if not path.exists():
        raise SweepFileError(f"sweep file not found: {path}")
    data = _read_toml(path)  # a folder, a device or a named pipe is refused by its kind
    try:
        return sweep_from_dict(data, base_dir=path.parent, name=path.stem, source=path)
    except SweepFileError as exc:
        raise SweepFileError(f"{path}: {exc}") from None


def sweep_from_dict(
    data: Mapping[str, Any],
    *,
    base_dir: str | Path = ".",
    name: str = "sweep",
    source: Path | None = None,
) -> SweepSpec:
    """Build a :class:`SweepSpec` from a parsed sweep file; ``sweep.base`` is relative to
    ``base_dir``.

    Parameters
    ----------
    data : Mapping of str to Any
        The sweep file's tables (``[sweep]``, ``[base]``, ``[axes]``, ``[figures]``).
    base_dir : str or Path, optional
        The folder ``sweep.base`` is relative to.
    name : str, optional
        The sweep's name when ``sweep.name`` is not given.
    source : Path or None, optional
        The sweep file it was read from (recorded in the manifest).

    Returns
    -------
    SweepSpec
        The checked sweep (its tasks are validated by :func:`expand`).

    Raises
    ------
    SweepFileError
        Naming the table or key at fault: an unknown table or key, a bad mode, combine, base,
        axis path or values, axes of unequal length for ``zip``, too many tasks, or an unknown
        figure metric.
    """
    unknown = sorted(set(data) - {"sweep", "base", "axes", "figures"})
    if unknown:
        raise SweepFileError(
            f"{unknown[0]}: unknown table; a sweep file has [sweep], [base], [axes], [figures]"
        )
    head = _table(data, "sweep")
    bad = sorted(set(head) - set(SWEEP_KEYS))
    if bad:
        raise SweepFileError(
            f"sweep.{bad[0]}: unknown key (a typo?); [sweep] accepts {', '.join(SWEEP_KEYS)}"
        )
    sweep_name = _string(head, "name", name)
    budget.check_name_length(sweep_name, "sweep.name", SweepFileError)
    mode = _string(head, "mode", "plan")
    if mode not in MODES:
        raise SweepFileError(f"sweep.mode: must be one of {', '.join(MODES)}, got {mode!r}")
    combine = _string(head, "combine", "product")
    if combine not in COMBINE:
        raise SweepFileError(f"sweep.combine: must be one of {', '.join(COMBINE)}, got {combine!r}")
    base, base_name = _base(head, data, Path(base_dir), sweep_name)
    axes_raw = _table(data, "axes")
    if not axes_raw:
        raise SweepFileError('[axes] is empty; give at least one axis, e.g. "limits.accel" = [...]')
    flat = _flatten_axes(axes_raw)
    axes = tuple(_axis(p, v) for p, v, _ in flat)
    _check_distinct(axes, [w for _, _, w in flat])
    if combine == "zip":
        lengths = {a.path: len(a.values) for a in axes}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"{p} has {n}" for p, n in lengths.items())
            raise SweepFileError(
                f"sweep.combine = zip needs axes of equal length; {shown} values "
                '(use combine = "product", or give each axis the same number of values)'
            )
    n_tasks = len(axes[0].values) if combine == "zip" else math.prod(len(a.values) for a in axes)
    budget.check_tasks(n_tasks, f"[axes] ({combine} of {len(axes)} axes)", SweepFileError)
    figs = _table(data, "figures")
    bad = sorted(set(figs) - {"metrics"})
    if bad:
        raise SweepFileError(f"figures.{bad[0]}: unknown key; [figures] accepts metrics")
    metrics = figs.get("metrics")
    if metrics is not None and (
        not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics)
    ):
        raise SweepFileError(
            f'figures.metrics: expected a list of metric names such as ["min_eig", '
            f'"ekf.rmse_pos"], got {metrics!r}'
        )
    known = figure_metric_names()
    for m in metrics or ():
        if m not in known:
            near = difflib.get_close_matches(m, sorted(known), n=1)
            hint = f"did you mean {near[0]!r}? " if near else ""
            raise SweepFileError(
                f"figures.metrics: unknown metric {m!r}; {hint}a metric of a path's report: "
                "min_eig, log_det, condition, pcrb_final_pos_std, ..., or FILTER.STAT such as "
                "ekf.rmse_pos, kf.final_pos_err"
            )
    return SweepSpec(
        name=sweep_name,
        base=base,
        base_name=base_name,
        axes=axes,
        combine=combine,
        mode=mode,
        figure_metrics=None if metrics is None else tuple(metrics),
        source=source,
    )


def figure_metric_names() -> frozenset[str]:
    """The names ``[figures] metrics`` accepts: the scalar fields of a path's metrics
    (``metrics.<path>.<name>``), the bound, and ``FILTER.STAT`` of every filter's statistics.

    Returns
    -------
    frozenset of str
        Names such as ``"min_eig"``, ``"within_limits"``, ``"crlb_final_pos_std"`` and
        ``"ekf.rmse_pos"``.
    """
    scalar = ("float", "int", "float | None", "int | None")
    names = {f.name for f in fields(PathMetrics) if f.type in scalar}
    names |= {"within_limits", "crlb_final_pos_std"}
    stats = [f.name for f in fields(FilterStats) if f.type in scalar]
    names |= {f"{filt}.{stat}" for filt in FILTERS for stat in stats}
    return frozenset(names)


def _read_toml(path: Path, field: str | None = None) -> dict[str, Any]:
    """The TOML of ``path``; errors start with ``field`` (e.g. ``sweep.base``) when given."""
    what = "a problem file (TOML)" if field else "a sweep file (TOML)"
    try:
        return read_toml(path, what, error=SweepFileError)
    except SweepFileError as exc:
        raise SweepFileError(f"{field}: {exc}" if field else str(exc)) from None


def _table(data: Mapping[str, Any], key: str) -> dict[str, Any]:
    raw = data.get(key, {})
    if not isinstance(raw, dict):
        raise SweepFileError(f"{key}: expected a table [{key}], got {raw!r}")
    return raw


def _string(table: Mapping[str, Any], key: str, default: str) -> str:
    raw = table.get(key, default)
    if not isinstance(raw, str):
        raise SweepFileError(f"sweep.{key}: expected a string, got {raw!r}")
    return raw


def _base(
    head: Mapping[str, Any], data: Mapping[str, Any], base_dir: Path, sweep_name: str
) -> tuple[dict[str, Any], str]:
    base: dict[str, Any] = {}
    base_name = sweep_name
    if "base" in head:
        rel = head["base"]
        if not isinstance(rel, str):
            raise SweepFileError(f"sweep.base: expected a problem file path, got {rel!r}")
        path = base_dir / rel
        if not path.exists():
            raise SweepFileError(
                f"sweep.base: problem file {rel!r} not found (looked for {path}; the path is "
                "relative to the sweep file)"
            )
        base = _read_toml(path, "sweep.base")  # a folder, a device, a FIFO: said by its kind
        base_name = path.stem
    inline = _table(data, "base")
    for section, values in inline.items():
        if section not in SCHEMA:
            raise SweepFileError(
                f"base.{section}: unknown section; a problem has {', '.join(SCHEMA)}"
            )
        if not isinstance(values, dict):
            raise SweepFileError(f"base.{section}: expected a table, got {values!r}")
        base.setdefault(section, {})
        if not isinstance(base[section], dict):
            raise SweepFileError(f"sweep.base: [{section}] of the base file is not a table")
        base[section].update(copy.deepcopy(values))
    if "base" not in head and not inline:
        raise SweepFileError(
            'no base problem: give sweep.base = "PROBLEM.toml" (relative to the sweep file) '
            "or an inline [base] table with the problem file's sections"
        )
    return base, base_name


def _flatten_axes(raw: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any, str]]:
    """``[axes]`` with TOML dotted keys (nested tables) back to dotted paths, in file order.

    Returns ``(path, value, written)`` per axis, ``written`` the key as the file spells it (a
    key holding dots quoted: ``"limits.speed"`` is one TOML key, ``limits.speed`` two), for the
    message that names two axes setting the same field.
    """
    out: list[tuple[str, Any, str]] = []
    for key, value in raw.items():
        path = f"{prefix}{key}"
        if (
            isinstance(value, dict)
            and not (set(value) & set(GENERATORS))
            and _table_path(path, value)
        ):
            out.extend(_flatten_axes(value, path + "."))
        else:
            written = prefix + (f'"{key}"' if "." in key or not key else key)
            out.append((path, value, written))
    return out


def _table_path(path: str, value: Mapping[str, Any]) -> bool:
    """Whether a table at ``path`` of [axes] holds more axes (a section, an area's sides, or
    bare component keys: ``limits.accel.0 = [...]`` is the table ``{"0": [...]}`` at
    ``limits.accel``) rather than being a (mistyped) generator table."""
    parts = path.split(".")
    if len(parts) == 1:
        return True
    specs = {s.name: s for s in SCHEMA.get(parts[0], ())}
    spec = specs.get(parts[1])
    if spec is None or len(parts) > 3:
        return False
    digits = bool(value) and all(k.isdigit() for k in value)
    if len(parts) == 2:
        return spec.kind == "area" or (spec.kind in _INDEXABLE and digits)
    return spec.kind == "area" and parts[2] in ("x", "y") and digits


def _check_distinct(axes: Sequence[Axis], written: Sequence[str]) -> None:
    """Refuse two axes that set the same field, or a field and a part of it (the same path
    spelt twice, quoted and as dotted keys, ``limits.accel.0`` and ``limits.accel[0]``, or
    ``limits.accel`` and ``limits.accel.2``): one would silently overwrite the other."""
    for j, b in enumerate(axes):
        for i, a in enumerate(axes[:j]):
            n = min(len(a.keys), len(b.keys))
            if a.keys[:n] != b.keys[:n]:
                continue
            both = f"axes: {written[i]} and {written[j]}"
            if len(a.keys) == len(b.keys):
                field = ".".join(map(str, a.keys))
                raise SweepFileError(
                    f"{both} both set {field}, so one would be dropped; give the axis once "
                    "(one key, one list of values)"
                )
            whole, part = (a, b) if len(a.keys) < len(b.keys) else (b, a)
            raise SweepFileError(
                f"{both} overlap: {'.'.join(map(str, part.keys))} is a part of "
                f"{'.'.join(map(str, whole.keys))}, which the other sets whole, so one would "
                "overwrite the other; sweep either the whole field or its parts"
            )


_INDEX = re.compile(r"^(.*)\[(\d+)\]$")


def parse_path(path: str) -> tuple[str | int, ...]:
    """``"limits.accel.2"`` / ``"limits.accel[2]"`` -> ``("limits", "accel", 2)``, checked
    against the problem file's schema.

    Parameters
    ----------
    path : str
        A dotted field path of the problem file, optionally with a component index (``.2`` or
        ``[2]``) or an area side (``limits.area.x``).

    Returns
    -------
    tuple of str or int
        The keys: section, field, then an index or side (and index).

    Raises
    ------
    SweepFileError
        Naming the part of the path that is not a problem-file field.
    """
    keys: list[str | int] = []
    for part in path.split("."):
        m = _INDEX.match(part)
        if m:
            keys.extend([m.group(1), int(m.group(2))])
        else:
            keys.append(int(part) if part.isdigit() else part)
    where = f"axes.{path}"
    if len(keys) < 2 or not isinstance(keys[0], str) or not isinstance(keys[1], str):
        raise SweepFileError(
            f"{where}: an axis is a field path section.field of the problem file, e.g. "
            '"limits.accel"'
        )
    section, name = keys[0], keys[1]
    if section not in SCHEMA:
        raise SweepFileError(
            f"{where}: unknown section {section!r}; sections are {', '.join(SCHEMA)}"
        )
    specs = {s.name: s for s in SCHEMA[section]}
    if name not in specs:
        raise SweepFileError(
            f"{where}: unknown field {name!r} of [{section}] (a typo?); fields are "
            f"{', '.join(specs)}"
        )
    rest = keys[2:]
    kind = specs[name].kind
    ok = (
        not rest
        or (kind in _INDEXABLE and len(rest) == 1 and isinstance(rest[0], int))
        or (
            kind == "area"
            and rest[0] in ("x", "y")
            and (len(rest) == 1 or (len(rest) == 2 and isinstance(rest[1], int)))
        )
    )
    if not ok:
        raise SweepFileError(
            f"{where}: {section}.{name} has no part {'.'.join(map(str, rest))!r}; give the whole "
            "field, a component index (limits.accel.2) or an area side (limits.area.x)"
        )
    return tuple(keys)


def _axis(path: str, raw: Any) -> Axis:
    keys = parse_path(path)
    where = f"axes.{path}"
    if isinstance(raw, dict):
        values = _generate(where, raw)
    elif isinstance(raw, list):
        values = list(raw)
    else:
        raise SweepFileError(
            f"{where}: expected a list of values or a generator table ({{range = 5}}, "
            f"{{linspace = [a, b, n]}}, {{geomspace = [a, b, n]}}), got {raw!r}"
        )
    if not values:
        raise SweepFileError(f"{where}: no values; give at least one")
    return Axis(path=path, keys=keys, values=tuple(values))


def _generate(where: str, raw: Mapping[str, Any]) -> list[Any]:
    if len(raw) != 1 or next(iter(raw)) not in GENERATORS:
        raise SweepFileError(
            f"{where}: a generator table has exactly one of {', '.join(GENERATORS)}, got {raw!r}"
        )
    kind, arg = next(iter(raw.items()))
    if kind == "range":
        args = [arg] if isinstance(arg, int) and not isinstance(arg, bool) else arg
        if (
            not isinstance(args, list)
            or not 1 <= len(args) <= 3
            or not all(isinstance(a, int) and not isinstance(a, bool) for a in args)
        ):
            raise SweepFileError(
                f"{where}: range takes an integer N or [start, stop] or [start, stop, step] "
                f"(integers, stop excluded), got {arg!r}"
            )
        if len(args) == 3 and args[2] == 0:
            raise SweepFileError(f"{where}: range step must not be 0")
        budget.check_tasks(len(range(*args)), where, SweepFileError)  # before the list exists
        return list(range(*args))
    if (
        not isinstance(arg, list)
        or len(arg) != 3
        or not all(isinstance(a, int | float) and not isinstance(a, bool) for a in arg[:2])
        or not isinstance(arg[2], int)
        or isinstance(arg[2], bool)
        or arg[2] < 1
        or not all(math.isfinite(a) for a in arg[:2])
    ):
        raise SweepFileError(
            f"{where}: {kind} takes [start, stop, count] (finite numbers, count >= 1 an "
            f"integer), got {arg!r}"
        )
    a, b, n = float(arg[0]), float(arg[1]), int(arg[2])
    budget.check_tasks(n, where, SweepFileError)
    if kind == "geomspace":
        if not (a > 0 and b > 0):
            raise SweepFileError(f"{where}: geomspace needs start and stop > 0, got {arg!r}")
        vals = np.geomspace(a, b, n)
    else:
        vals = np.linspace(a, b, n)
    # plain floats, rounded to 12 significant digits so that a value written in another sweep
    # (or typed by hand) as 0.3 is the same task as linspace's 0.30000000000000004
    return [float(f"{v:.12g}") for v in vals]


# ------------------------------------------------------------------------------ expansion
def combinations(spec: SweepSpec) -> list[dict[str, Any]]:
    """Axis path -> value for every task, in order (last axis varies fastest for a product).

    Parameters
    ----------
    spec : SweepSpec
        The sweep: its axes and ``combine``.

    Returns
    -------
    list of dict of str to Any
        One mapping per task, in the sweep's order.
    """
    paths = [a.path for a in spec.axes]
    rows: Iterable[tuple[Any, ...]]
    if spec.combine == "zip":
        rows = zip(*(a.values for a in spec.axes), strict=True)
    else:
        rows = itertools.product(*(a.values for a in spec.axes))
    return [dict(zip(paths, r, strict=True)) for r in rows]


def apply_axes(base: Mapping[str, Any], spec: SweepSpec, values: Mapping[str, Any]) -> dict:
    """The raw problem mapping of one task: ``base`` with each axis value written in.

    ``vehicle.dim`` is applied first, so that a component axis (``limits.accel.2``) on a scalar
    or omitted field expands it to the task's dimension.

    Parameters
    ----------
    base : Mapping of str to Any
        The raw problem-file mapping (not modified).
    spec : SweepSpec
        The sweep whose axes are written.
    values : Mapping of str to Any
        Axis path -> the task's value (one row of :func:`combinations`).

    Returns
    -------
    dict
        A new raw problem mapping, not yet checked.

    Raises
    ------
    SweepFileError
        When the base has no list or area for a component axis to index, or the index is out
        of range.
    """
    return _write(base, spec.axes, values)


def set_fields(base: Mapping[str, Any], values: Mapping[str, Any]) -> dict:
    """``base`` (a raw problem mapping) with each dotted field path of ``values``
    (:func:`parse_path`: ``"objective.mode"``, ``"limits.accel.2"``) set to its value, as a
    sweep's axes are; check the result with ``problem_from_dict``.

    Parameters
    ----------
    base : Mapping of str to Any
        The raw problem-file mapping (not modified).
    values : Mapping of str to Any
        Dotted field path -> its value.

    Returns
    -------
    dict
        A new raw problem mapping, not yet checked.

    Raises
    ------
    SweepFileError
        For a path that is not a problem-file field, or a component the base cannot index.
    """
    axes = [Axis(path=p, keys=parse_path(p), values=(v,)) for p, v in values.items()]
    return _write(base, axes, values)


def _write(base: Mapping[str, Any], axes: Sequence[Axis], values: Mapping[str, Any]) -> dict:
    data = copy.deepcopy(dict(base))
    for axis in sorted(axes, key=lambda a: a.keys[:2] != ("vehicle", "dim")):
        _set(data, axis, copy.deepcopy(values[axis.path]))
    return data


def _set(data: dict[str, Any], axis: Axis, value: Any) -> None:
    section, name, *rest = axis.keys
    sec = data.setdefault(cast(str, section), {})
    if not isinstance(sec, dict):
        raise SweepFileError(f"axes.{axis.path}: [{section}] of the base problem is not a table")
    if not rest:
        sec[name] = value
        return
    dim = data.get("vehicle", {}).get("dim", 2) if isinstance(data.get("vehicle"), dict) else 2
    if isinstance(rest[0], int):
        current = sec.get(name)
        if current is None and (section, name) in _ZERO_DEFAULTS:
            current = [0.0] * dim
        elif isinstance(current, int | float) and not isinstance(current, bool):
            current = [current] * dim  # one number for every axis (limits.accel)
        if not isinstance(current, list):
            raise SweepFileError(
                f"axes.{axis.path}: the base problem has no list {section}.{name} to index; "
                "give the whole field in the base"
            )
        current = list(current)
        if not rest[0] < len(current):
            raise SweepFileError(
                f"axes.{axis.path}: index {rest[0]} is out of range; {section}.{name} has "
                f"{len(current)} values"
            )
        current[rest[0]] = value
        sec[name] = current
        return
    area = sec.get(name)
    if not isinstance(area, dict):
        raise SweepFileError(
            f"axes.{axis.path}: the base problem has no {section}.{name} table; give the whole "
            "area in the base or sweep the whole field"
        )
    area = copy.deepcopy(area)
    if len(rest) == 1:
        area[rest[0]] = value
    else:
        side = area.get(rest[0])
        index = cast(int, rest[1])
        if not isinstance(side, list) or not index < len(side):
            raise SweepFileError(f"axes.{axis.path}: the base has no {section}.{name}.{rest[0]}")
        side = list(side)
        side[index] = value
        area[rest[0]] = side
    sec[name] = area


#: The package's source folder, whose files :func:`code_fingerprint` hashes.
PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: Sub-folders of the package left out of the fingerprint: they present results but compute no
#: part of a task (the command line's wording may change without invalidating a study).
UNFINGERPRINTED = ("cli",)


@functools.cache
def code_fingerprint(root: Path = PACKAGE_DIR) -> str:
    """16 hex digits of SHA-256 over the package's Python sources, ``cli/`` excluded.

    Part of every task's identity: :func:`obsplan.__version__` stays the same through many
    commits, while any edit of the code that computes a task (planner, filters, model, ...)
    changes this. Every ``.py`` file counts, even one a task does not import: a needless rerun
    is better than results of two codes mixed in one table. Computed once per process (about a
    hundred small files).

    Parameters
    ----------
    root
        The package folder (default: this installation's).

    Returns
    -------
    str
        16 lowercase hex digits.
    """
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] in UNFINGERPRINTED or "__pycache__" in rel.parts:
            continue
        digest.update(rel.as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()[:16]


def task_id(problem: Mapping[str, Any], mode: str) -> str:
    """16 hex digits identifying a resolved problem (its name excluded: a label), a mode, the
    package version and the code that computes it (:func:`code_fingerprint`).

    Parameters
    ----------
    problem : Mapping of str to Any
        The resolved problem mapping
        (:func:`~obsplan.planning.problem.parse.problem_to_dict`).
    mode : str
        ``"plan"`` or ``"baselines"``.

    Returns
    -------
    str
        16 lowercase hex digits of SHA-256.
    """
    ident = {k: v for k, v in problem.items() if k != "problem"}
    text = json.dumps(
        {"problem": ident, "mode": mode, "obsplan": __version__, "code": code_fingerprint()},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def axis_unit(path: str) -> str:
    """The unit of the problem-file field an axis path sets (``"m/s^2"`` for
    ``limits.accel.2``), ``"-"`` for a unitless field
    (:data:`obsplan.planning.problem.schema.SCHEMA`).

    Parameters
    ----------
    path : str
        An axis path (:func:`parse_path`).

    Returns
    -------
    str
        The field's unit.

    Raises
    ------
    SweepFileError
        For a path that is not a problem-file field.
    """
    keys = parse_path(path)
    specs = {s.name: s for s in SCHEMA[cast(str, keys[0])]}
    return specs[cast(str, keys[1])].unit


def axis_column(path: str) -> str:
    """The results table's column of an axis: its path and unit, ``"limits.accel [m/s^2]"``
    (the path alone for a unitless field: ``"objective.kind"``).

    Parameters
    ----------
    path : str
        An axis path.

    Returns
    -------
    str
        The column's name.
    """
    unit = axis_unit(path)
    return path if unit == "-" else f"{path} [{unit}]"


def describe(values: Mapping[str, Any]) -> str:
    """``"limits.accel = 0.05, beacon.position = [50, 0]"`` (for messages and legends).

    Parameters
    ----------
    values : Mapping of str to Any
        Axis path -> value.

    Returns
    -------
    str
        ``path = value`` pairs, values as JSON, separated by commas.
    """
    return ", ".join(f"{k} = {json.dumps(v)}" for k, v in values.items())


def expand(spec: SweepSpec) -> list[Task]:
    """Every task of the sweep, each validated as a problem.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.

    Returns
    -------
    list of Task
        In the sweep's order, each with its resolved problem and id (two tasks may share an
        id: :func:`unique_tasks`).

    Raises
    ------
    SweepFileError
        For the first task that is not a valid problem, naming the task (number and axis values)
        and the problem field at fault; how many other tasks fail is said too.
    """
    tasks: list[Task] = []
    errors: list[str] = []
    for i, values in enumerate(combinations(spec)):
        raw = apply_axes(spec.base, spec, values)
        try:
            pb = problem_from_dict(raw, name=spec.base_name)
        except ProblemError as exc:
            errors.append(f"task {i + 1} of the sweep ({describe(values)}): {exc}")
            continue
        resolved = problem_to_dict(pb)
        tasks.append(
            Task(
                id=task_id(resolved, spec.mode),
                index=i,
                axes=values,
                mode=spec.mode,
                problem=resolved,
            )
        )
    if errors:
        more = f" (and {len(errors) - 1} more invalid tasks)" if len(errors) > 1 else ""
        raise SweepFileError(errors[0] + more)
    return tasks


def as_spec(spec: SweepSpec | str | Path | Mapping[str, Any]) -> SweepSpec:
    """A :class:`SweepSpec` from a spec, a sweep-file path or a parsed mapping.

    Parameters
    ----------
    spec : SweepSpec or str or Path or Mapping of str to Any
        The sweep: returned as is, read (:func:`load_sweep`) or built
        (:func:`sweep_from_dict`).

    Returns
    -------
    SweepSpec
        The sweep.

    Raises
    ------
    SweepFileError
        When the file or mapping is not a valid sweep.
    TypeError
        For any other type of ``spec``.
    """
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, str | Path):
        return load_sweep(spec)
    if isinstance(spec, Mapping):
        return sweep_from_dict(spec)
    raise TypeError(f"expected a SweepSpec, a sweep file path or a mapping, got {spec!r}")


def unique_tasks(tasks: Sequence[Task]) -> list[Task]:
    """First task of each id (two axis combinations may resolve to the same problem).

    Parameters
    ----------
    tasks : sequence of Task
        The sweep's tasks.

    Returns
    -------
    list of Task
        In the order of their first occurrence.
    """
    seen: dict[str, Task] = {}
    for t in tasks:
        seen.setdefault(t.id, t)
    return list(seen.values())
