"""Real inputs in, flyable plans out: logged tracks, geodetic frames, waypoint missions.

* :mod:`obsplan.io.tracks` — logged tracks (CSV, ROS 1/2 bags, MAVLink telemetry logs) and the
  regularised least-squares fit of the piecewise-constant accelerations;
* :mod:`obsplan.io.geodetic` — latitude/longitude/depth to the local north-east-down frame of the
  package about a stated origin (extra ``geo``: pymap3d);
* :mod:`obsplan.io.waypoints` — waypoint lists and QGroundControl ``.plan`` missions with the
  exact tracking error of straight-line following;
* :mod:`obsplan.io.csvtable` — the one CSV table reader behind every CSV loader;
* :mod:`obsplan.io.atomic` — files and folders written atomically (temp + rename).

The package imports nothing at import time, so that :mod:`obsplan.trajectory` can use its
CSV and atomic-write helpers without a cycle.
"""
