"""The vehicle model (a double integrator ranging to one beacon, section 2), the frames it lives
in (the local north-east-down frame and geodetic coordinates) and a beacon that moves along a
known path (:mod:`~obsplan.model.beacon`: the path, its CSV form, the derivatives the
observability tests read).

Imports :mod:`obsplan.core` only.
"""

from obsplan.model.beacon import BeaconPath, BeaconVehicle, read_beacon_path
from obsplan.model.frames import GeodeticOrigin, geodetic_to_local, local_to_geodetic
from obsplan.model.vehicle import SENSORS, VehicleModel, make_model, parse_sensors

__all__ = [
    "BeaconPath",
    "BeaconVehicle",
    "SENSORS",
    "GeodeticOrigin",
    "VehicleModel",
    "geodetic_to_local",
    "local_to_geodetic",
    "make_model",
    "parse_sensors",
    "read_beacon_path",
]
