"""Geodetic coordinates: latitude, longitude and depth to the package's local frame and back.

**Frame.** The local frame of obsplan is **north-east-down (NED)** about a stated origin: ``x``
north, ``y` east, ``z`` down, in metres, on the plane tangent to the WGS84 ellipsoid at the origin.
``z`` down makes ``p_z`` the depth, which is how the problem files already use it
(``limits.depth = [z_min, z_max]`` is a band of depths, the depth gauge measures ``p_z``) and how
MAVLink's ``LOCAL_POSITION_NED`` reports it; NED is right-handed. The paper states no geographic
frame (its ``z`` is only a coordinate), and observability is invariant to the choice.

**Depth.** A point given as ``(latitude, longitude, depth)`` is at ellipsoidal height
``origin.altitude - depth``: ``origin.altitude`` [m] is the height of the reference surface
(depth 0: the sea surface, or the datum of the depth gauge) at the origin, 0 by default. The
conversion is exact (``pymap3d.geodetic2ned``), so far from the origin ``z`` also contains the
drop of the tangent plane below the curved surface (about ``r² / 2R``: 8 cm at 1 km).
In 2D a point is ``(latitude, longitude)`` and its local position is ``(north, east)`` at depth 0.

Conversions need the optional package ``pymap3d`` (``pip install 'obsplan[geo]'``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from obsplan.errors import InputError, ProblemError


@dataclass(frozen=True)
class GeodeticOrigin:
    """Origin of the local north-east-down frame.

    Attributes
    ----------
    latitude, longitude : float
        WGS84 degrees (latitude in [-90, 90], longitude in [-180, 360)).
    altitude : float
        Ellipsoidal height of the reference surface (depth 0) at the origin [m].
    """

    latitude: float
    longitude: float
    altitude: float = 0.0

    def __post_init__(self) -> None:
        check_lat_lon(self.latitude, self.longitude, "origin")
        if not math.isfinite(self.altitude) or abs(self.altitude) > 1e5:
            raise InputError(
                f"origin altitude {self.altitude!r} m: expected a finite height within 100 km"
            )

    def to_dict(self) -> dict[str, float]:
        """``{"latitude": ..., "longitude": ..., "altitude": ..., "frame": "NED"}``."""
        return {
            "latitude": self.latitude,
            "longitude": self.longitude,
            "altitude": self.altitude,
            "frame": "NED",
        }


def check_lat_lon(lat: Any, lon: Any, where: str) -> None:
    """Refuse a latitude outside [-90, 90] or a longitude outside [-180, 360) degrees."""
    for name, val, lo, hi in (("latitude", lat, -90.0, 90.0), ("longitude", lon, -180.0, 360.0)):
        ok = isinstance(val, int | float) and not isinstance(val, bool) and math.isfinite(val)
        if not ok or not lo <= val <= hi or (name == "longitude" and val == hi):
            raise InputError(
                f"{where}: {name} {val!r} is not in [{lo:g}, {hi:g}] degrees (WGS84 decimal "
                "degrees, e.g. 43.7167, 10.4)"
            )


def _pymap3d():
    try:
        import pymap3d
    except ImportError:
        raise InputError(
            "geodetic coordinates need the optional package pymap3d: pip install 'obsplan[geo]'"
        ) from None
    return pymap3d


def geodetic_to_local(
    lat: Any, lon: Any, depth: Any, origin: GeodeticOrigin, dim: int = 3
) -> np.ndarray:
    """Latitude [deg], longitude [deg], depth [m] -> local NED positions [m].

    Returns shape ``(N, dim)`` for array inputs and ``(dim,)`` for scalars; in 2D the depth is
    ignored (pass 0) and the result is ``(north, east)``.
    """
    pm = _pymap3d()
    scalar = np.ndim(lat) == 0
    la, lo, de = (np.atleast_1d(np.asarray(a, float)) for a in (lat, lon, depth))
    n, e, d = pm.geodetic2ned(
        la, lo, origin.altitude - de, origin.latitude, origin.longitude, origin.altitude
    )
    p = np.column_stack([n, e, d])[:, :dim]
    return p[0] if scalar else p


def local_to_geodetic(p: Any, origin: GeodeticOrigin) -> tuple[np.ndarray, ...]:
    """Local NED positions ``(N, n)`` [m] -> ``(latitude, longitude, depth)`` arrays.

    In 2D the points are taken at ``z = 0`` and the depth returned is that of the tangent plane.
    """
    pm = _pymap3d()
    p = np.atleast_2d(np.asarray(p, float))
    z = p[:, 2] if p.shape[1] == 3 else np.zeros(p.shape[0])
    lat, lon, h = pm.ned2geodetic(
        p[:, 0], p[:, 1], z, origin.latitude, origin.longitude, origin.altitude
    )
    return np.asarray(lat, float), np.asarray(lon, float), origin.altitude - np.asarray(h, float)


def parse_origin(text: str, option: str = "--origin") -> GeodeticOrigin:
    """``"lat,lon[,alt]"`` -> :class:`GeodeticOrigin`."""
    vals = _numbers(text, option, "LAT,LON[,ALT]", (2, 3))
    try:
        return GeodeticOrigin(*vals)
    except InputError as exc:
        raise InputError(f"{option} {text!r}: {exc}") from None


def parse_geodetic_point(
    text: str, dim: int, origin: GeodeticOrigin | None, option: str
) -> tuple[float, ...]:
    """``"lat,lon[,depth]"`` -> local position (``dim`` values, depth only in 3D)."""
    if origin is None:
        raise InputError(
            f"{option} needs --origin LAT,LON[,ALT]: the origin of the trajectory's local "
            "north-east-down frame"
        )
    counts = (2,) if dim == 2 else (2, 3)
    form = "LAT,LON" if dim == 2 else "LAT,LON[,DEPTH]"
    vals = _numbers(text, option, form, counts, dim_note=dim)
    try:
        check_lat_lon(vals[0], vals[1], option)
    except InputError as exc:
        raise InputError(f"{option} {text!r}: {exc}") from None
    depth = vals[2] if len(vals) == 3 else 0.0
    return tuple(float(x) for x in geodetic_to_local(vals[0], vals[1], depth, origin, dim))


def _numbers(
    text: str, option: str, form: str, counts: tuple[int, ...], dim_note: int | None = None
) -> list[float]:
    try:
        vals = [float(s) for s in str(text).split(",")]
    except ValueError:
        vals = []
    if len(vals) not in counts or not all(math.isfinite(v) for v in vals):
        extra = f" (the trajectory is {dim_note}D)" if dim_note else ""
        raise InputError(
            f"{option} {text!r}: expected {form}{extra} in decimal degrees [and m], separated by "
            f"commas, e.g. {option} 43.7,10.4" + (",20" if "DEPTH" in form else "")
        )
    return vals


# -------------------------------------------------------------------------- problem files
def origin_of(data: Mapping[str, Any]) -> GeodeticOrigin | None:
    """The ``[origin]`` section of a problem mapping as a :class:`GeodeticOrigin` (or None)."""
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
        p = geodetic_to_local(float(raw[0]), float(raw[1]), depth, origin, dim)
        section = {k: v for k, v in data[sec].items() if k != "geodetic"}
        section["position"] = [float(x) for x in p]
        out[sec] = section
    return out, origin
