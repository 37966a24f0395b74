"""Geodetic coordinates: latitude, longitude and depth to the package's local frame and back.

The conversion core, below every module that reads positions (problem files, logged tracks,
waypoints); :mod:`obsplan.io.geodetic` parses the command line's geodetic options with it.

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from obsplan.core.errors import InputError


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

    def to_dict(self) -> dict[str, float | str]:
        """``{"latitude": ..., "longitude": ..., "altitude": ..., "frame": "NED"}``.

        Returns
        -------
        dict
            The origin's latitude and longitude [deg], altitude [m] and the frame's name, as
            written in JSON outputs.
        """
        return {
            "latitude": self.latitude,
            "longitude": self.longitude,
            "altitude": self.altitude,
            "frame": "NED",
        }


def check_lat_lon(lat: Any, lon: Any, where: str) -> None:
    """Refuse a latitude outside [-90, 90] or a longitude outside [-180, 360) degrees.

    Parameters
    ----------
    lat : float
        Latitude [deg], WGS84.
    lon : float
        Longitude [deg], WGS84.
    where : str
        What the point is, for the message (e.g. ``"origin"``).

    Raises
    ------
    InputError
        If either is not a finite number in its range (a bool is not a number here).
    """
    for name, val, lo, hi in (("latitude", lat, -90.0, 90.0), ("longitude", lon, -180.0, 360.0)):
        ok = isinstance(val, int | float) and not isinstance(val, bool) and math.isfinite(val)
        if not ok or not lo <= val <= hi or (name == "longitude" and val == hi):
            raise InputError(
                f"{where}: {name} {val!r} is not in [{lo:g}, {hi:g}] degrees (WGS84 decimal "
                "degrees, e.g. 43.7167, 10.4)"
            )


def check_lat_lons(lat: Any, lon: Any, where: str) -> None:
    """Refuse the first of an array of points (or one point) whose latitude is not in [-90, 90]
    degrees or whose longitude is not finite, naming it ``where (sample k)`` (``where`` for a
    scalar point). Longitudes of points wrap (370 is 10); an origin's must be in [-180, 360).

    Parameters
    ----------
    lat : float or array_like, shape (N,)
        Latitudes [deg], WGS84.
    lon : float or array_like, shape (N,)
        Longitudes [deg], WGS84.
    where : str
        What the points are, for the message (e.g. a file name).

    Raises
    ------
    InputError
        For the first point out of range.
    """
    la, lo = np.atleast_1d(np.asarray(lat, float)), np.atleast_1d(np.asarray(lon, float))
    bad = np.flatnonzero(~((np.abs(la) <= 90.0) & np.isfinite(lo)))  # False for NaN
    if bad.size:
        k = int(bad[0])
        at = "" if np.ndim(lat) == 0 else f" (sample {k})"
        name, val, rng = (
            ("latitude", la[k], "in [-90, 90] degrees")
            if not abs(la[k]) <= 90.0
            else ("longitude", lo[k], "a finite number of degrees")
        )
        raise InputError(
            f"{where}{at}: {name} {float(val)!r} is not {rng} (WGS84 decimal degrees, e.g. "
            "43.7167, 10.4)"
        )


def first_point_origin(lat: Any, lon: Any, where: str) -> GeodeticOrigin:
    """The origin at the first of the points ``lat``, ``lon`` [deg], at the surface: the default
    frame of a geodetic log or waypoint CSV. Every point is checked first, so a bad latitude is
    named as the file's own (``where (sample k)``), not as an origin the user never gave; the
    first longitude is wrapped into [-180, 180) if it is outside an origin's range.

    Parameters
    ----------
    lat : float or array_like, shape (N,)
        Latitudes [deg], WGS84.
    lon : float or array_like, shape (N,)
        Longitudes [deg], WGS84.
    where : str
        What the points are, for the message (e.g. a file name).

    Returns
    -------
    GeodeticOrigin
        The first point, at altitude 0 (the surface).

    Raises
    ------
    InputError
        For the first point out of range (:func:`check_lat_lons`).
    """
    check_lat_lons(lat, lon, where)
    lat0, lon0 = float(np.atleast_1d(lat)[0]), float(np.atleast_1d(lon)[0])
    if not -180.0 <= lon0 < 360.0:
        lon0 = (lon0 + 180.0) % 360.0 - 180.0
    return GeodeticOrigin(latitude=lat0, longitude=lon0)


#: Farthest a point may be from the origin of a local frame [m]: at 50 km the tangent plane is
#: ~200 m below the surface and the flat-frame distances are off by ~1 part in 10^5.
MAX_LOCAL_DISTANCE_M = 50_000.0
#: Largest depth (or height above the surface, negative) of a geodetic point [m].
MAX_DEPTH_M = 20_000.0


def _pymap3d():
    try:
        import pymap3d
    except ImportError:
        raise InputError(
            "geodetic coordinates need the optional package pymap3d: pip install 'obsplan[geo]'"
        ) from None
    return pymap3d


def geodetic_to_local(
    lat: Any,
    lon: Any,
    depth: Any,
    origin: GeodeticOrigin,
    dim: int = 3,
    where: str = "geodetic point",
) -> np.ndarray:
    """Latitude [deg], longitude [deg], depth [m] -> local NED positions [m].

    Returns shape ``(N, dim)`` for array inputs and ``(dim,)`` for scalars; in 2D the depth is
    ignored (pass 0) and the result is ``(north, east)``.

    Parameters
    ----------
    lat : float or array_like, shape (N,)
        Latitudes [deg], WGS84.
    lon : float or array_like, shape (N,)
        Longitudes [deg], WGS84.
    depth : float or array_like, shape (N,)
        Depths below the reference surface [m], positive down.
    origin : GeodeticOrigin
        Origin of the local frame.
    dim : int, optional
        Spatial dimension of the result (2 or 3).
    where : str, optional
        What the points are, for messages.

    Returns
    -------
    ndarray, shape (N, dim) or (dim,)
        Local NED positions [m] relative to ``origin``.

    Raises
    ------
    InputError
        Naming ``where``, for a point farther than :data:`MAX_LOCAL_DISTANCE_M` from the origin
        or deeper than :data:`MAX_DEPTH_M` (a local frame does not serve it). Also when
        ``pymap3d`` is not installed, or for a latitude out of range.
    """
    pm = _pymap3d()
    scalar = np.ndim(lat) == 0
    check_lat_lons(lat, lon, where)
    la, lo, de = (np.atleast_1d(np.asarray(a, float)) for a in (lat, lon, depth))
    n, e, d = pm.geodetic2ned(
        la, lo, origin.altitude - de, origin.latitude, origin.longitude, origin.altitude
    )
    p = np.column_stack([n, e, d])
    check_local_range(p, de, origin, where, scalar)
    p = p[:, :dim]
    return p[0] if scalar else p


def check_local_range(
    ned: np.ndarray, depth: np.ndarray, origin: GeodeticOrigin, where: str, scalar: bool = False
) -> None:
    """Refuse NED points ``(N, 3)`` [m] farther than :data:`MAX_LOCAL_DISTANCE_M` from the
    origin (distance of the surface point: the depth ``(N,)`` [m] taken out) or deeper than
    :data:`MAX_DEPTH_M`.

    Parameters
    ----------
    ned : ndarray, shape (N, 3)
        Local NED positions [m].
    depth : ndarray, shape (N,)
        Depth of each point [m], positive down.
    origin : GeodeticOrigin
        Origin of the frame (named in the message).
    where : str
        What the points are, for the message.
    scalar : bool, optional
        The points are one point given as scalars (the message then names no sample).

    Raises
    ------
    InputError
        For the first point too far or too deep.
    """
    surface = ned.copy()
    surface[:, 2] -= depth
    dist = np.linalg.norm(surface, axis=1)
    bad = np.flatnonzero(~(dist <= MAX_LOCAL_DISTANCE_M))
    at = "" if scalar else " (sample {k})"
    if bad.size:
        k = int(bad[0])
        raise InputError(
            f"{where}{at.format(k=k)}: {dist[k] / 1e3:,.1f} km from the origin "
            f"({origin.latitude:g}, {origin.longitude:g}); a local north-east-down frame serves "
            f"points within {MAX_LOCAL_DISTANCE_M / 1e3:g} km of its origin (the tangent plane "
            "is 200 m below the sea there): give an origin near the points"
        )
    deep = np.flatnonzero(~(np.abs(depth) <= MAX_DEPTH_M))
    if deep.size:
        k = int(deep[0])
        raise InputError(
            f"{where}{at.format(k=k)}: depth {depth[k]:g} m is beyond ±{MAX_DEPTH_M:g} m "
            "(the deepest ocean is 11 km); depths are in metres, positive down"
        )


def check_local_points(p: Any, origin: GeodeticOrigin, where: str) -> None:
    """:func:`check_local_range` of local NED positions ``(N, 2)`` or ``(N, 3)`` [m] (2D: at
    depth 0), naming the first bad one ``where (sample k)``.

    Parameters
    ----------
    p : array_like, shape (N, 2) or (N, 3)
        Local NED positions [m].
    origin : GeodeticOrigin
        Origin of the frame.
    where : str
        What the points are, for the message.

    Raises
    ------
    InputError
        For the first point too far or too deep.
    """
    p = np.atleast_2d(np.asarray(p, float))
    z = p[:, 2] if p.shape[1] == 3 else np.zeros(p.shape[0])
    check_local_range(np.column_stack([p[:, :2], z]), z, origin, where)


def local_to_geodetic(
    p: Any, origin: GeodeticOrigin, where: str = "local point"
) -> tuple[np.ndarray, ...]:
    """Local NED positions ``(N, n)`` [m] -> ``(latitude, longitude, depth)`` arrays.

    In 2D the points are taken at ``z = 0`` and the depth returned is that of the tangent plane.

    Parameters
    ----------
    p : array_like, shape (N, n) or (n,)
        Local NED positions [m] relative to ``origin``, ``n`` = 2 or 3.
    origin : GeodeticOrigin
        Origin of the local frame.
    where : str, optional
        What the points are, for messages.

    Returns
    -------
    latitude, longitude : ndarray, shape (N,)
        WGS84 degrees.
    depth : ndarray, shape (N,)
        Depth below the reference surface [m], positive down.

    Raises
    ------
    InputError
        Naming ``where``, for a point farther than :data:`MAX_LOCAL_DISTANCE_M` from the origin
        or deeper than :data:`MAX_DEPTH_M` (:func:`check_local_range`, as the other way).
    """
    pm = _pymap3d()
    p = np.atleast_2d(np.asarray(p, float))
    z = p[:, 2] if p.shape[1] == 3 else np.zeros(p.shape[0])
    check_local_points(p, origin, where)
    lat, lon, h = pm.ned2geodetic(
        p[:, 0], p[:, 1], z, origin.latitude, origin.longitude, origin.altitude
    )
    return np.asarray(lat, float), np.asarray(lon, float), origin.altitude - np.asarray(h, float)
