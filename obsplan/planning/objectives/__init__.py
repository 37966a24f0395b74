"""Every ``objective.kind``: windowed and information-weighted Gramians (:mod:`~.windowed`,
:mod:`~.gramian`), the LWO matrix (:mod:`~.lwo`), the estimators' predicted covariance
(:mod:`~.estimator`), robust families (:mod:`~.robust`), the registry (:mod:`~.registry`), the
EKF's linearisation penalty (:mod:`~.linearisation`), and their values and metrics on any path
(:mod:`~.evaluate`).

Imports the transcription, problem and missions rooms, observability and estimation bounds.
"""
