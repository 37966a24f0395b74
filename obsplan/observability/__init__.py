"""Observability of the single-beacon double integrator: LWO rank test and augmented Gramian.

The LWO matrix (:mod:`~.lwo`), the augmented Gramian and its windows (:mod:`~.gramian`,
:mod:`~.windowed`, :mod:`~.local_gramian`), exact structural ranks (:mod:`~.structural`), the
fixed nondimensionalisation (:mod:`~.scaling`) and both verdicts on one path (:mod:`~.analyze`).
Imports the model, the trajectory stage and the core only.
"""

from __future__ import annotations

from obsplan.observability.analyze import ObservabilityReport, analyze
from obsplan.observability.gramian import GramianReport, gramian, gramian_report
from obsplan.observability.lwo import (
    LWOReport,
    lwo_matrices,
    lwo_matrix_function,
    lwo_ranks,
    lwo_report,
    lwo_structural_max_rank,
)
from obsplan.observability.scaling import DEFAULT_SCALES, Scales

__all__ = [
    "DEFAULT_SCALES",
    "GramianReport",
    "LWOReport",
    "ObservabilityReport",
    "Scales",
    "analyze",
    "gramian",
    "gramian_report",
    "lwo_matrices",
    "lwo_matrix_function",
    "lwo_ranks",
    "lwo_report",
    "lwo_structural_max_rank",
]
