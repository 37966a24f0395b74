"""The filters of the Monte Carlo, behind one interface (:mod:`~obsplan.estimation.filters.base`):
the EKF (:mod:`~obsplan.estimation.filters.ekf`), the augmented KF
(:mod:`~obsplan.estimation.filters.kf`) and the Gaussian sum
(:mod:`~obsplan.estimation.filters.gsf`), their shared Kalman structure and kernel arguments, and
numpy linear filtering and smoothing (:mod:`~obsplan.estimation.filters.linear`).

Imports the estimation floor (configuration, schedules, epochs, kernels) and the model.
"""
