"""Geodetic command-line options: ``--origin LAT,LON[,ALT]`` and ``LAT,LON[,DEPTH]`` points.

The frame and the conversions are in :mod:`obsplan.model.frames` (the one place for the math).
"""

from __future__ import annotations

import math

from obsplan.core.errors import InputError
from obsplan.model.frames import GeodeticOrigin, check_lat_lon, geodetic_to_local


def parse_origin(text: str, option: str = "--origin") -> GeodeticOrigin:
    """``"lat,lon[,alt]"`` -> :class:`GeodeticOrigin`.

    Parameters
    ----------
    text : str
        Latitude and longitude [deg, WGS84] and optionally the altitude of the reference
        surface [m], separated by commas.
    option : str, optional
        The option that gave ``text``, named in messages.

    Returns
    -------
    GeodeticOrigin
        The origin of the local north-east-down frame.

    Raises
    ------
    InputError
        If ``text`` is not 2 or 3 finite numbers, or the latitude or longitude is out of range.
    """
    vals = _numbers(text, option, "LAT,LON[,ALT]", (2, 3))
    try:
        return GeodeticOrigin(*vals)
    except InputError as exc:
        raise InputError(f"{option} {text!r}: {exc}") from None


def parse_geodetic_point(
    text: str, dim: int, origin: GeodeticOrigin | None, option: str
) -> tuple[float, ...]:
    """``"lat,lon[,depth]"`` -> local position (``dim`` values, depth only in 3D).

    Parameters
    ----------
    text : str
        Latitude and longitude [deg, WGS84] and, in 3D, optionally the depth [m, positive
        down], separated by commas.
    dim : int
        Spatial dimension of the trajectory (2 or 3).
    origin : GeodeticOrigin or None
        Origin of the local frame (``--origin``); None is an error.
    option : str
        The option that gave ``text``, named in messages.

    Returns
    -------
    tuple of float
        The local NED position [m], ``dim`` values.

    Raises
    ------
    InputError
        Without an origin, for a malformed point, a latitude or longitude out of range, or a
        point too far from the origin (:func:`obsplan.model.frames.geodetic_to_local`).
    """
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
    return tuple(float(x) for x in geodetic_to_local(vals[0], vals[1], depth, origin, dim, option))


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
