"""Bounds along a path: covariance (Riccati) recursions at measurement epochs, the posterior
Cramér–Rao bound, and the linearised covariance of the closed loop.

Imports the estimation floor (configuration, schedules, epochs, sensors), the model and the
observability stage; no filter and no Monte Carlo.
"""
