"""Real inputs in, flyable plans out: logged tracks, geodetic options, waypoint missions.

* :mod:`obsplan.io.tracks` — logged tracks (CSV, ROS 1/2 bags, MAVLink telemetry logs) and the
  regularised least-squares fit of the piecewise-constant accelerations;
* :mod:`obsplan.io.geodetic` — the command line's ``--origin`` and geodetic points (the frame
  and the conversions are in :mod:`obsplan.model.frames`; extra ``geo``: pymap3d);
* :mod:`obsplan.io.waypoints` — waypoint lists and QGroundControl ``.plan`` missions with the
  exact tracking error of straight-line following.

The CSV table reader and the atomic writes they share with :mod:`obsplan.trajectory.sampled`
are below them, in :mod:`obsplan.core.csvtable` and :mod:`obsplan.core.atomic`. Imports every
stage up to planning; nothing of :mod:`obsplan.sweeps` or the command line.
"""
