"""The paths a user would otherwise fly, under the same limits, horizon, start and mission as the
plan: lawn-mowers, circles, straight legs and the paper's lawn-mower (:mod:`~.vehicle`).

Imports :mod:`obsplan.planning.problem`, :mod:`obsplan.planning.missions` and the trajectory
generators.
"""
