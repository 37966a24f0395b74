"""A problem's file mapping and its sections, both ways, by the problem file's rules.

:func:`sections_from_dict` reads a parsed problem mapping (a TOML file's, or one built in Python)
field by field by :data:`~obsplan.planning.problem.schema.SCHEMA` (types, units, defaults: an
unknown key is an error naming it) into the frozen sections of
:mod:`~obsplan.planning.problem.sections`; ``beacon.geodetic`` / ``start.geodetic`` become metric
positions about ``[origin]`` (:func:`resolve_problem_geodetic`, with the conversions of
:mod:`obsplan.model.frames`). :func:`problem_to_dict` writes the canonical mapping of a problem and
:func:`problem_to_toml` its text.

It needs only the schema and the sections, so it sits below
:mod:`~obsplan.planning.problem.definition`: the problem's own methods
(``PlanningProblem.from_dict``, ``with_changes``, ``to_toml``) and the loader
(:mod:`~obsplan.planning.problem.parse`) share it, one way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from obsplan.core import budget
from obsplan.core.errors import ConfigError, InputError, ProblemError, field_error
from obsplan.core.textfiles import check_magnitude, toml_text
from obsplan.model.frames import GeodeticOrigin, check_lat_lon, geodetic_to_local
from obsplan.model.vehicle import parse_sensors
from obsplan.observability.scaling import Scales
from obsplan.planning.missions.spec import (
    EndRegion,
    LineArea,
    Mission,
    Seabed,
    generate_lines,
    lines_at_altitude,
)
from obsplan.planning.problem.schema import (
    BEACON_MOTIONS,
    CRAFT_FIELDS,
    LAWNMOWER_PATH,
    MAX_MAGNITUDE,
    SCHEMA,
    FieldSpec,
)
from obsplan.planning.problem.sections import (
    CHANNEL_KEYS,
    Area,
    BeaconMotion,
    Horizon,
    Limits,
    ObjectiveSpec,
    ProblemData,
    ValidationSpec,
    VehicleSpec,
)


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _magnitude(where: str, values: Any, unit: str) -> None:
    """The one rule of a number no vehicle problem has
    (:func:`~obsplan.core.textfiles.check_magnitude`, :data:`MAX_MAGNITUDE`), applied to every
    number of the file before any arithmetic (a range_std of 1e300 would overflow its square)."""
    check_magnitude(values, where, MAX_MAGNITUDE, unit, error=ProblemError)


def _parse_value(section: str, spec: FieldSpec, raw: Any, dim: int) -> Any:
    where = f"{section}.{spec.name}"
    value = _parse_raw(where, spec, raw, dim)
    k = spec.kind
    if k in ("float", "float-or-str") and not isinstance(value, str):
        _magnitude(where, value, spec.unit)
    elif k in ("float-list", "vec", "vec-or-float", "hvec", "hvec-or-float", "range"):
        _magnitude(where, value, spec.unit)
    elif k in ("lines", "tracks", "points", "windows"):
        _magnitude(where, [x for row in value for x in row], spec.unit)
    return value


def _parse_raw(where: str, spec: FieldSpec, raw: Any, dim: int) -> Any:
    k = spec.kind
    if k == "int":
        if not isinstance(raw, int) or isinstance(raw, bool):
            raise field_error(where, f"expected an integer, got {raw!r}")
        return int(raw)
    if k == "float":
        if not _is_number(raw) or not math.isfinite(raw):
            raise field_error(where, f"expected a finite number [{spec.unit}], got {raw!r}")
        return float(raw)
    if k == "float-or-str":
        if isinstance(raw, str):
            return raw
        if not _is_number(raw) or not math.isfinite(raw):
            raise field_error(where, f"expected a number [{spec.unit}] or a name, got {raw!r}")
        return float(raw)
    if k == "bool":
        if not isinstance(raw, bool):
            raise field_error(where, f"expected true or false, got {raw!r}")
        return raw
    if k == "str":
        if not isinstance(raw, str):
            raise field_error(where, f"expected a string, got {raw!r}")
        return raw
    if k == "str-list":
        if isinstance(raw, str):
            raw = [s for s in raw.split(",")]
        if not isinstance(raw, list) or not all(isinstance(s, str) for s in raw):
            raise field_error(where, f'expected a list of names such as ["range"], got {raw!r}')
        return raw
    if k == "float-list":
        if not isinstance(raw, list) or not all(
            _is_number(x) and math.isfinite(x) and x > 0 for x in raw
        ):
            raise field_error(
                where, f"expected a list of positive numbers such as [1, 5], got {raw!r}"
            )
        return tuple(float(x) for x in raw)
    if k in ("hvec", "hvec-or-float"):  # the horizontal axes of a surface craft
        if k == "hvec-or-float" and _is_number(raw):
            raw = [raw, raw]
        if not (
            isinstance(raw, list)
            and len(raw) == 2
            and all(_is_number(x) and math.isfinite(x) for x in raw)
        ):
            raise field_error(
                where, f"expected 2 finite numbers [{spec.unit}] (horizontal x, y), got {raw!r}"
            )
        return tuple(float(x) for x in raw)
    if k in ("vec", "vec-or-float"):
        if k == "vec-or-float" and _is_number(raw):
            raw = [raw] * dim
        if (
            not isinstance(raw, list)
            or len(raw) != dim
            or not all(_is_number(x) and math.isfinite(x) for x in raw)
        ):
            raise field_error(
                where,
                f"expected {dim} finite numbers [{spec.unit}] (vehicle.dim = {dim}), got {raw!r}",
            )
        return tuple(float(x) for x in raw)
    if k == "range":
        if (
            not isinstance(raw, list)
            or len(raw) != 2
            or not all(_is_number(x) and math.isfinite(x) for x in raw)
        ):
            raise field_error(where, f"expected [min, max] in {spec.unit}, got {raw!r}")
        lo, hi = float(raw[0]), float(raw[1])
        if not lo < hi:
            raise field_error(where, f"min must be below max, got [{lo:g}, {hi:g}]")
        return (lo, hi)
    if k == "area":
        if not isinstance(raw, dict):
            raise field_error(
                where, f"expected a table {{x = [min, max], y = [min, max]}}, got {raw!r}"
            )
        unknown = sorted(set(raw) - {"x", "y"})
        if unknown:
            raise field_error(f"{where}.{unknown[0]}", "unknown key; an area has only x and y")
        axes = {}
        for ax in ("x", "y"):
            if ax not in raw:
                raise field_error(f"{where}.{ax}", "missing; give [min, max] in m")
            axes[ax] = _parse_value(where, FieldSpec(ax, "range", None, "m", ""), raw[ax], dim)
        return Area(x=axes["x"], y=axes["y"])
    if k in ("lines", "tracks", "points", "windows", "line-area", "end", "seabed"):
        return _parse_mission_value(where, spec, raw, dim)
    raise AssertionError(k)  # pragma: no cover


def _parse_mission_value(where: str, spec: FieldSpec, raw: Any, dim: int) -> Any:
    """The mission's kinds of :func:`_parse_value`: lines, points, windows, an area, an end."""
    k = spec.kind
    if k in ("lines", "tracks", "points", "windows"):
        if isinstance(raw, list):  # counted before a single row is converted
            _check_rows(where, k, len(raw))
        width = {"lines": 2 * dim, "tracks": 4, "points": dim, "windows": 2}[k]
        form = {
            "lines": "[[x0, y0, x1, y1], ...]" if dim == 2 else "[[x0, y0, z0, x1, y1, z1], ...]",
            "tracks": "horizontal tracks [[x0, y0, x1, y1], ...] (with mission.altitude)",
            "points": "[[x, y], ...]" if dim == 2 else "[[x, y, z], ...]",
            "windows": "[[t0, t1], ...]",
        }[k]
        ok = (
            isinstance(raw, list)
            and len(raw) > 0
            and all(
                isinstance(r, list)
                and len(r) == width
                and all(_is_number(x) and math.isfinite(x) for x in r)
                for r in raw
            )
        )
        if not ok:
            raise field_error(
                where, f"expected {form} in {spec.unit} (vehicle.dim = {dim}), got {raw!r}"
            )
        return tuple(tuple(float(x) for x in r) for r in raw)
    if k == "line-area":
        return _line_area(where, raw, dim)
    if k == "seabed":
        return _seabed(where, raw)
    return _end_region(where, raw, dim)


def _check_rows(where: str, kind: str, n: int) -> None:
    """The count of a mission's list (lines, waypoints and their windows, polygon corners)
    within :mod:`obsplan.core.budget`'s limits."""
    if kind in ("lines", "tracks"):
        budget.check_lines(n, where, error=ProblemError)
    elif where.endswith(".polygon"):
        budget.check_corners(n, where, ProblemError)
    else:
        budget.check_waypoints(n, where, ProblemError)


def _seabed(where: str, raw: Any) -> Seabed:
    if not isinstance(raw, dict):
        raise field_error(where, f"expected {{depth = d, slope = [sx, sy]}}, got {raw!r}")
    unknown = sorted(set(raw) - {"depth", "slope"})
    if unknown:
        raise field_error(f"{where}.{unknown[0]}", "unknown key; a seabed has depth and slope")
    if "depth" not in raw:
        raise field_error(f"{where}.depth", "missing; the seabed's depth [m] at x = y = 0")
    depth = _parse_value(where, FieldSpec("depth", "float", None, "m", ""), raw["depth"], 2)
    slope = (0.0, 0.0)
    if "slope" in raw:
        slope = _parse_value(where, FieldSpec("slope", "vec", None, "m/m", ""), raw["slope"], 2)
    return Seabed(depth=depth, slope=slope)


def _line_area(where: str, raw: Any, dim: int) -> LineArea:
    if not isinstance(raw, dict) or not raw:
        raise field_error(
            where,
            f"expected {{x = [min, max], y = [min, max]}} or {{polygon = [[x, y], ...]}}, "
            f"got {raw!r}",
        )
    if "polygon" in raw:
        if set(raw) != {"polygon"}:
            raise field_error(where, "give either polygon or x and y, not both")
        pts = _parse_value(where, FieldSpec("polygon", "points", None, "m", ""), raw["polygon"], 2)
        if len(pts) < 3:
            raise field_error(f"{where}.polygon", f"needs at least 3 corners, got {len(pts)}")
        return LineArea(polygon=tuple((p[0], p[1]) for p in pts))
    box = _parse_value(where.rpartition(".")[0], FieldSpec("area", "area", None, "m", ""), raw, dim)
    return LineArea(x=box.x, y=box.y)


def _end_region(where: str, raw: Any, dim: int) -> EndRegion:
    if not isinstance(raw, dict):
        raise field_error(where, f"expected {{position = [...], radius = r}}, got {raw!r}")
    unknown = sorted(set(raw) - {"position", "radius", "speed"})
    if unknown:
        raise field_error(
            f"{where}.{unknown[0]}", "unknown key; an end has position, radius, speed"
        )
    for key in ("position", "radius"):
        if key not in raw:
            raise field_error(f"{where}.{key}", "missing")
    pos = _parse_value(where, FieldSpec("position", "vec", None, "m", ""), raw["position"], dim)
    radius = _parse_value(where, FieldSpec("radius", "float", None, "m", ""), raw["radius"], dim)
    speed = None
    if "speed" in raw:
        speed = _parse_value(where, FieldSpec("speed", "float", None, "m/s", ""), raw["speed"], dim)
    return EndRegion(position=pos, radius=radius, speed=speed)


def _mission(data: Mapping[str, Any], vals: dict[str, Any], dim: int, start) -> Mission | None:
    """The ``[mission]`` (None without one): lines given or generated from an area."""
    if "mission" not in data:
        return None
    given = set(data["mission"])
    lines = vals["lines"]
    area = vals["area"]
    if area is not None:
        if lines is not None:
            raise field_error("mission.area", "give either mission.lines or mission.area, not both")
        if vals["spacing"] is None:
            raise field_error(
                "mission.spacing", "missing; the distance between generated lines [m]"
            )
        if not vals["spacing"] > 0:
            raise field_error("mission.spacing", f"must be > 0 m, got {vals['spacing']}")
        depth = None
        if dim == 3 and vals["altitude"] is None:
            depth = float(start[2]) if vals["depth"] is None else vals["depth"]
        lines = generate_lines(area, vals["spacing"], vals["heading"], np.asarray(start[:2]), depth)
    else:
        for key in ("spacing", "heading", "depth"):
            if key in given:
                raise field_error(f"mission.{key}", "is for generated lines; give mission.area")
    altitude, seabed = vals["altitude"], vals["seabed"]
    if altitude is not None:
        if dim != 3:
            raise field_error("mission.altitude", "an altitude band needs vehicle.dim = 3")
        if seabed is None:
            raise field_error(
                "mission.seabed", "missing; the altitude band is above it: {depth = d}"
            )
        if "depth" in given:
            raise field_error(
                "mission.depth", "excludes mission.altitude (the lines follow the seabed)"
            )
        if lines:
            lines = lines_at_altitude(lines, altitude, seabed)
    elif seabed is not None:
        raise field_error("mission.seabed", "is for an altitude band; give mission.altitude")
    return Mission(
        kind=vals["kind"],
        lines=lines or (),
        cross_track=vals["cross_track"],
        heading_tol=vals["heading_tol"],
        speed=vals["speed"],
        order=vals["order"],
        shift=vals["shift"],
        lead_in=vals["lead_in"],
        waypoints=vals["waypoints"] or (),
        radius=vals["radius"],
        windows=vals["windows"] or (),
        end=vals["end"],
        area=area,
        spacing=vals["spacing"] if area is not None else None,
        heading=vals["heading"] if area is not None else None,
        depth=vals["depth"] if area is not None else None,
        altitude=altitude,
        seabed=seabed,
    )


def _section_values(data: Mapping[str, Any], section: str, dim: int) -> dict[str, Any]:
    raw = data.get(section, {})
    if not isinstance(raw, dict):
        raise field_error(section, f"expected a table [{section}], got {raw!r}")
    specs = {s.name: s for s in SCHEMA[section]}
    unknown = sorted(set(raw) - set(specs))
    if unknown:
        raise field_error(
            f"{section}.{unknown[0]}",
            f"unknown key (a typo?); [{section}] accepts {', '.join(specs)}",
        )
    out: dict[str, Any] = {}
    for name, spec in specs.items():
        if name in raw:
            # with an altitude band the lines are horizontal tracks (their depth follows the
            # seabed): [x0, y0, x1, y1] in 3D too
            if section == "mission" and name == "lines" and "altitude" in raw:
                spec = replace(spec, kind="tracks")
            out[name] = _parse_value(section, spec, raw[name], dim)
        elif spec.required:
            raise field_error(f"{section}.{name}", f"missing; {spec.doc} [{spec.unit}]")
        else:
            out[name] = spec.default
    return out


def sections_from_dict(data: Mapping[str, Any], name: str = "") -> dict[str, Any]:
    """The sections of a problem from its file mapping, by the file's rules.

    Parameters
    ----------
    data : Mapping of str to Any
        A parsed problem file (``tomllib``), or a mapping of the same form built in Python.
    name : str, default ""
        The problem's name when ``[problem] name`` is not given (a file's stem).

    Returns
    -------
    dict
        The keyword arguments of :class:`~obsplan.planning.problem.definition.PlanningProblem`
        (``vehicle``, ``limits``, ``horizon``, ... as the frozen sections of
        :mod:`~obsplan.planning.problem.sections`; ``origin`` from ``[origin]``, the geodetic
        fields turned into metric positions).

    Raises
    ------
    ProblemError
        Naming the ``section.field`` at fault (an unknown section or key, a wrong type, a
        missing field) and what it should be.
    """
    data, origin = resolve_problem_geodetic(data)  # [origin] + *.geodetic -> metric positions
    unknown = sorted(set(data) - set(SCHEMA))
    if unknown:
        raise field_error(unknown[0], f"unknown section; sections are {', '.join(SCHEMA)}")
    dim_raw = data.get("vehicle", {}).get("dim", 2) if isinstance(data.get("vehicle"), dict) else 2
    if dim_raw not in (2, 3) or isinstance(dim_raw, bool):
        raise field_error("vehicle.dim", f"must be 2 or 3, got {dim_raw!r}")
    dim = int(dim_raw)
    s = {sec: _section_values(data, sec, dim) for sec in SCHEMA}
    veh = s["vehicle"]
    try:
        sensors = parse_sensors(veh["sensors"])
    except ConfigError as exc:
        raise field_error("vehicle.sensors", str(exc)) from None
    vehicle = VehicleSpec(
        dim=dim,
        sensors=sensors,
        current=veh["current"],
        current_velocity=veh["current_velocity"] or (0.0,) * dim,
        range_form=veh["range_form"],
        path=veh["path"],
    )
    lim = s["limits"]
    motion = _beacon_motion(data, s["beacon"])
    if veh["path"] is not None and not motion.moving:
        raise field_error(
            "vehicle.path",
            "is the path the vehicle flies while a moving beacon is planned; with a fixed "
            "beacon the vehicle is planned: remove it (or set beacon.motion)",
        )
    if motion.motion == "planned":
        lim = _moving_beacon_limits(data, lim)
    return dict(
        name=s["problem"]["name"] or name,
        vehicle=vehicle,
        beacon=s["beacon"]["position"] or (0.0,) * dim,
        start_position=s["start"]["position"],
        start_velocity=s["start"]["velocity"] or (0.0,) * dim,
        limits=Limits(
            accel=lim["accel"],
            speed=lim["speed"],
            depth=lim["depth"],
            area=lim["area"],
            min_range=lim["min_range"],
            max_range=lim["max_range"],
            min_speed=lim["min_speed"],
            keepout_confidence=lim["keepout_confidence"],
        ),
        horizon=Horizon(**s["horizon"]),
        objective=ObjectiveSpec(**s["objective"]),
        scales=_scales(s["scales"]),
        validation=ValidationSpec(**s["validation"]),
        origin=origin,
        mission=_mission(data, s["mission"], dim, s["start"]["position"]),
        beacon_motion=motion,
    )


def _beacon_motion(data: Mapping[str, Any], vals: dict[str, Any]) -> BeaconMotion:
    """``[beacon] motion`` and its fields; a field meaningless for the motion is refused."""
    motion = vals["motion"]
    if motion not in BEACON_MOTIONS:
        raise field_error(
            "beacon.motion", f"must be one of {', '.join(BEACON_MOTIONS)}, got {motion!r}"
        )
    given = set(data.get("beacon", {}))
    craft = [f for f in CRAFT_FIELDS if f in given]
    if motion != "planned" and craft:
        raise field_error(
            f"beacon.{craft[0]}",
            f'is a limit of a planned beacon\'s craft; set beacon.motion = "planned" or remove '
            f"it (motion is {motion!r})",
        )
    if motion != "path" and "path" in given:
        raise field_error(
            "beacon.path",
            f'is the file of a known beacon path: set beacon.motion = "path" '
            f"or remove it (motion is {motion!r})",
        )
    if motion == "path":
        if vals["path"] is None:
            raise field_error("beacon.path", 'missing; motion = "path" needs the CSV t,bx,by[,bz]')
        if "position" in given or "geodetic" in given:
            raise field_error(
                "beacon.position",
                'a beacon on a known path has no fixed position (motion = "path"); remove it',
            )
    if motion == "planned":
        for key in ("speed", "accel"):
            if vals[key] is None:
                raise field_error(
                    f"beacon.{key}", f'missing; motion = "planned" needs the craft\'s {key} limit'
                )
        if "position" not in given and "geodetic" not in given:
            raise field_error(
                "beacon.position", 'missing; motion = "planned" needs the craft\'s start'
            )
    return BeaconMotion(
        motion=motion,
        path=vals["path"],
        speed=vals["speed"],
        accel=vals["accel"],
        velocity=vals["velocity"],
        area=vals["area"],
        max_range=vals["max_range"],
        min_distance=vals["min_distance"],
    )


def _moving_beacon_limits(data: Mapping[str, Any], lim: dict[str, Any]) -> dict[str, Any]:
    """The limits of a problem with a planned beacon (on a known path, ``limits.min_range`` and
    ``max_range`` are to where the beacon is at each time): the distance limits are the
    craft's (``beacon.min_distance``, ``beacon.max_range``), ``limits.min_range`` is 0."""
    given = data.get("limits", {})
    for key, instead in (("min_range", "min_distance"), ("max_range", "max_range")):
        if isinstance(given, Mapping) and key in given:
            raise field_error(
                f"limits.{key}",
                f"is a distance to a fixed beacon; with a moving beacon give "
                f'beacon.{instead} (motion = "planned") or remove it',
            )
    return {**lim, "min_range": 0.0, "max_range": None}


def problem_to_dict(pb: ProblemData) -> dict[str, Any]:
    """The canonical problem-file mapping of ``pb``.

    ``problem_from_dict(problem_to_dict(pb))`` rebuilds an equal problem. Every field of
    :data:`~obsplan.planning.problem.schema.SCHEMA` is present (defaults resolved), so the
    mapping identifies the problem (sweeps hash it); a geodetic problem keeps its ``[origin]``
    and gives its beacon and start in metres about it.

    Parameters
    ----------
    pb : ProblemData
        The problem (its sections).

    Returns
    -------
    dict
        ``{section: {field: value}}``: TOML's types only (bool, int, float, str, lists, tables).
    """
    veh, lim, hor, obj, val = pb.vehicle, pb.limits, pb.horizon, pb.objective, pb.validation
    planned = pb.beacon_motion.motion == "planned"
    limits: dict[str, Any] = {
        "accel": list(lim.accel),
        "speed": lim.speed,
        "min_range": lim.min_range,
        "min_speed": lim.min_speed,
        "keepout_confidence": lim.keepout_confidence,
    }
    if planned:  # the craft's limits replace them (beacon.min_distance, beacon.max_range)
        del limits["min_range"]
    if lim.depth is not None:
        limits["depth"] = list(lim.depth)
    if lim.area is not None:
        limits["area"] = {"x": list(lim.area.x), "y": list(lim.area.y)}
    if lim.max_range is not None:
        limits["max_range"] = lim.max_range
    out: dict[str, Any] = {
        "problem": {"name": pb.name},
        "vehicle": {
            "dim": veh.dim,
            "sensors": list(veh.sensors),
            "current": veh.current,
            "current_velocity": list(veh.current_velocity),
            "range_form": veh.range_form,
        },
        "beacon": _beacon_to_dict(pb),
        "start": {"position": list(pb.start_position), "velocity": list(pb.start_velocity)},
        "limits": limits,
        "horizon": {"duration": hor.duration, "steps": hor.steps},
        "objective": {
            f: list(v) if isinstance(v, tuple) else v
            for f in obj.__dataclass_fields__
            if (v := getattr(obj, f)) is not None
        },
        "scales": {"length_m": pb.scales.length_m, "time_s": pb.scales.time_s},
        "validation": _validation_to_dict(val),
    }
    if veh.path is not None:
        out["vehicle"]["path"] = veh.path
    if pb.mission is not None:
        out["mission"] = _mission_to_dict(pb.mission)
    if pb.origin is not None:
        o = pb.origin
        out["origin"] = {"latitude": o.latitude, "longitude": o.longitude, "altitude": o.altitude}
    return out


def _beacon_to_dict(pb: ProblemData) -> dict[str, Any]:
    """``[beacon]``: its position alone for a fixed beacon (as before beacon.motion), else the
    motion and its fields."""
    bm = pb.beacon_motion
    if bm.motion == "fixed":
        return {"position": list(pb.beacon)}
    if bm.motion == "path":
        if not isinstance(bm.path, str):
            raise field_error(
                "beacon.path",
                "a path given in memory has no file to name; write it with "
                "obsplan.model.beacon.write_beacon_csv and give that file",
            )
        return {"motion": "path", "path": bm.path}
    out: dict[str, Any] = {
        "motion": "planned",
        "position": list(pb.beacon),
        "speed": bm.speed,
        "accel": list(bm.accel or ()),
        "min_distance": bm.min_distance,
    }
    if bm.velocity is not None:
        out["velocity"] = list(bm.velocity)
    if bm.area is not None:
        out["area"] = {"x": list(bm.area.x), "y": list(bm.area.y)}
    if bm.max_range is not None:
        out["max_range"] = bm.max_range
    return out


def _validation_to_dict(val: ValidationSpec) -> dict[str, Any]:
    """The ``[validation]`` table; the channel's fields only where they differ from their
    defaults, so that a problem written before the channel existed keeps its mapping (and a
    sweep its task ids)."""
    out: dict[str, Any] = {}
    for f in val.__dataclass_fields__:
        v = getattr(val, f)
        new_field = (
            f in ("channel", "gate", "scale_state", "bias_state", "stress_channel", "range_times")
            or f in CHANNEL_KEYS
        )
        if new_field and v == getattr(ValidationSpec, f):
            continue
        out[f] = list(v) if isinstance(v, tuple) else v
    return out


def _mission_to_dict(m: Mission) -> dict[str, Any]:
    out: dict[str, Any] = {
        "kind": m.kind,
        "cross_track": m.cross_track,
        "heading_tol": m.heading_tol,
        "order": m.order,
        "shift": m.shift,
        "lead_in": m.lead_in,
        "radius": m.radius,
    }
    if m.area is not None:
        if m.area.polygon:
            out["area"] = {"polygon": [list(p) for p in m.area.polygon]}
        else:
            out["area"] = {"x": list(m.area.x or ()), "y": list(m.area.y or ())}
        out["spacing"] = m.spacing
        out["heading"] = m.heading
        if m.depth is not None:
            out["depth"] = m.depth
    elif m.lines:
        given = m.given_lines()
        if m.altitude is not None:  # horizontal tracks: their depth follows the seabed
            given = tuple(ln[:2] + ln[3:5] for ln in given)
        out["lines"] = [list(ln) for ln in given]
    if m.altitude is not None and m.seabed is not None:
        out["altitude"] = list(m.altitude)
        out["seabed"] = {"depth": m.seabed.depth, "slope": list(m.seabed.slope)}
    if m.speed is not None:
        out["speed"] = list(m.speed)
    if m.waypoints:
        out["waypoints"] = [list(w) for w in m.waypoints]
    if m.windows:
        out["windows"] = [list(w) for w in m.windows]
    if m.end is not None:
        end: dict[str, Any] = {"position": list(m.end.position), "radius": m.end.radius}
        if m.end.speed is not None:
            end["speed"] = m.end.speed
        out["end"] = end
    return out


def _scales(vals: dict[str, float]) -> Scales:
    try:
        return Scales(**vals)
    except ConfigError as exc:
        raise ProblemError(str(exc)) from None


def problem_to_toml(pb: ProblemData) -> str:
    """The text of a problem file of ``pb`` (:func:`problem_to_dict` as TOML).

    Parameters
    ----------
    pb : ProblemData
        The problem (its sections).

    Returns
    -------
    str
        TOML that loads back to an equal problem:
        ``problem_from_dict(tomllib.loads(problem_to_toml(pb))) == pb``.
    """
    header = f"{pb.name or 'problem'}: every field, unit and default: docs/problem-files.md"
    return toml_text(problem_to_dict(pb), header=header)


def resolve_problem_files(data: Mapping[str, Any], base: str | Path) -> Mapping[str, Any]:
    """``beacon.path``, ``vehicle.path`` (a CSV, not ``"lawnmower"``) and
    ``validation.range_times`` resolved against the folder of the problem file that names them,
    as the loader reads them.

    Parameters
    ----------
    data : Mapping of str to Any
        The problem file's sections as parsed from TOML.
    base : str or Path
        The folder of the problem file.

    Returns
    -------
    Mapping of str to Any
        ``data`` with those relative paths made absolute (unchanged when there are none; a
        malformed value is left for the parser to name).
    """
    out = dict(data)
    for section, key in (("beacon", "path"), ("vehicle", "path"), ("validation", "range_times")):
        sec = out.get(section)
        if not isinstance(sec, Mapping) or not isinstance(sec.get(key), str):
            continue
        name = sec[key]
        if (section == "vehicle" and name == LAWNMOWER_PATH) or Path(name).is_absolute():
            continue
        out[section] = {**sec, key: str(Path(base) / name)}
    return out


# ---------------------------------------------------------------------- geodetic problem fields
def origin_of(data: Mapping[str, Any]) -> GeodeticOrigin | None:
    """The ``[origin]`` section of a problem mapping as a :class:`GeodeticOrigin` (or None).

    Parameters
    ----------
    data : Mapping of str to Any
        The problem file's sections as parsed from TOML.

    Returns
    -------
    GeodeticOrigin or None
        The origin of the local north-east-down frame (latitude and longitude [deg], altitude
        [m], 0 by default); None without ``[origin]``.

    Raises
    ------
    ProblemError
        On ``origin`` or ``origin.<key>``: not a table, an unknown or missing key, a value that
        is not a finite number or out of range.
    """
    raw = data.get("origin")
    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise ProblemError(f"origin: expected a table [origin], got {raw!r}")
    unknown = sorted(set(raw) - {"latitude", "longitude", "altitude"})
    if unknown:
        raise ProblemError(
            f"origin.{unknown[0]}: unknown key (a typo?); [origin] accepts latitude, longitude, "
            "altitude"
        )
    for key in ("latitude", "longitude"):
        if key not in raw:
            raise ProblemError(f"origin.{key}: missing; WGS84 decimal degrees [deg]")
    alt = raw.get("altitude", 0.0)
    if not isinstance(alt, int | float) or isinstance(alt, bool) or not math.isfinite(alt):
        raise ProblemError(f"origin.altitude: expected a finite number [m], got {alt!r}")
    try:
        return GeodeticOrigin(raw["latitude"], raw["longitude"], float(alt))
    except InputError as exc:
        raise ProblemError(str(exc)) from None


def resolve_problem_geodetic(
    data: Mapping[str, Any],
) -> tuple[Mapping[str, Any], GeodeticOrigin | None]:
    """Turn ``beacon.geodetic`` / ``start.geodetic`` into ``position`` about ``[origin]``.

    Returns the mapping with the geodetic fields replaced by metric ones and the ``[origin]``
    section removed, and the origin (None without one). A mapping with neither is returned
    unchanged (no pymap3d needed). Malformed sections that are not about geodetic fields are left
    for the problem parser to report.

    Parameters
    ----------
    data : Mapping of str to Any
        The problem file's sections as parsed from TOML.

    Returns
    -------
    data : Mapping of str to Any
        The sections with ``<section>.geodetic`` replaced by ``<section>.position`` [m] (local
        north-east-down about the origin) and without ``[origin]``.
    origin : GeodeticOrigin or None
        The ``[origin]`` section (None without one).

    Raises
    ------
    ProblemError
        A geodetic field without ``[origin]``, both ``position`` and ``geodetic`` in a section,
        a value of the wrong length or outside the latitude/longitude ranges.
    """
    if not isinstance(data, Mapping):
        return data, None
    sections = [
        s for s in ("beacon", "start") if isinstance(data.get(s), Mapping) and "geodetic" in data[s]
    ]
    if "origin" not in data and not sections:
        return data, None
    origin = origin_of(data)
    out = {k: v for k, v in data.items() if k != "origin"}
    if not sections:
        return out, origin
    veh = data.get("vehicle", {})
    dim = veh.get("dim", 2) if isinstance(veh, Mapping) else 2
    if dim not in (2, 3) or isinstance(dim, bool):
        return out, origin  # the problem parser names vehicle.dim
    for sec in sections:
        where = f"{sec}.geodetic"
        if origin is None:
            raise ProblemError(
                f"{where}: needs an [origin] section (latitude, longitude [deg], altitude [m]) "
                "for the local north-east-down frame"
            )
        if "position" in data[sec]:
            raise ProblemError(
                f"{where}: give either {sec}.position [m] or {sec}.geodetic, not both"
            )
        raw = data[sec]["geodetic"]
        form = "[latitude, longitude]" if dim == 2 else "[latitude, longitude, depth]"
        ok = (
            isinstance(raw, list)
            and len(raw) == dim
            and all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                for x in raw
            )
        )
        if not ok:
            raise ProblemError(
                f"{where}: expected {form} in deg, deg"
                + (", m" if dim == 3 else "")
                + f" (vehicle.dim = {dim}), got {raw!r}"
            )
        try:
            check_lat_lon(raw[0], raw[1], where)
        except InputError as exc:
            raise ProblemError(str(exc)) from None
        depth = float(raw[2]) if dim == 3 else 0.0
        try:
            p = geodetic_to_local(float(raw[0]), float(raw[1]), depth, origin, dim, where)
        except InputError as exc:
            raise ProblemError(str(exc)) from None
        section = {k: v for k, v in data[sec].items() if k != "geodetic"}
        section["position"] = [float(x) for x in p]
        out[sec] = section
    return out, origin
