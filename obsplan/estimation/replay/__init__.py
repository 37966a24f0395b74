"""A logged mission replayed: one log's extended Kalman filter with an innovation gate and
re-acquisition, its Rauch–Tung–Striebel smoother, the result (summary, figures), and a simulated
log generator for tests and documentation.

The log (:mod:`~.log`) is what a vehicle records: inputs or DVL velocities, ranges at their own
times, depth, the beacon; the smoother (:mod:`~.smoother`) is numpy, one log at a time, built on
the estimation floor's measurement model (:mod:`obsplan.estimation.sensors`) and exact
discretisation (:mod:`obsplan.estimation.kalman`) and on the linear RTS smoother of
:mod:`obsplan.estimation.filters.linear`. Imports the estimation floor,
:mod:`~obsplan.estimation.filters`, the model, the trajectory stage and the core; the CSV form of
a log is in :mod:`obsplan.io.missionlog`.
"""
