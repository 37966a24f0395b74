"""The vehicle model (a double integrator ranging to one beacon, section 2) and the frames it lives
in (the local north-east-down frame and geodetic coordinates).

Imports :mod:`obsplan.core` only.
"""

from obsplan.model.frames import GeodeticOrigin, geodetic_to_local, local_to_geodetic
from obsplan.model.vehicle import SENSORS, VehicleModel, make_model, parse_sensors

__all__ = [
    "SENSORS",
    "GeodeticOrigin",
    "VehicleModel",
    "geodetic_to_local",
    "local_to_geodetic",
    "make_model",
    "parse_sensors",
]
