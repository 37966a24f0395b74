"""Scaling of observability matrices: one fixed nondimensionalisation, unit-invariant rank tests.

Two different jobs, two different tools:

* **Verdicts (rank).** A rank test on SI-unit numbers is meaningless here: the entries of the
  augmented Gramian grow as t⁰…t⁴ and a circle's Gramian has a condition number near 1e9 in (m, s)
  but 1e16 in (m, h). Changing units (or the time origin's scale) multiplies the state by a fixed
  *diagonal* matrix ``S``, which maps a Gramian ``G`` to ``c·S G S``. The equilibrated matrix
  ``D G D`` with ``D = diag(G)^-1/2`` is the same for ``G`` and ``c·S G S``, so the rank test below,
  done on it, is invariant to units by construction. ``D G D`` has a unit diagonal (a correlation
  matrix): its eigenvalues lie in ``[0, m]`` and sum to ``m``, so an *absolute* tolerance on them is
  meaningful. A zero eigenvalue of the exact matrix shows up as ≲1e-13 (the exact per-interval
  Gramians are accurate to a few ulps; summing 1e5 of them loses at most ~1e-12), while a direction
  that is 1e-9 "independent" of the others is already a real, if weak, observable direction. We take
  ``RANK_TOL = 1e-10``: three decades above round-off, below any excitation a vehicle can fly.
* **Objectives and metrics.** ``min_eig``, ``log_det`` and ``condition`` must grow with excitation,
  which equilibration would destroy. They are computed on the Gramian of the trajectory expressed
  in the *fixed* units of :class:`Scales` (length ``L`` and time ``T``): ``t/T``, ``p/L``,
  ``v T/L``, ``u T²/L``; every output is then dimensionless too (``ȳ/L²``, DVL ``v T/L``,
  depth ``p_z/L``).
  Defaults are ``L = 100 m`` and ``T = 100 s`` (the paper's scenarios: ranges of tens to a hundred
  metres, manoeuvres over minutes). A planning problem may set its own; comparisons are only made
  between numbers computed with the same scales.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from obsplan.errors import ConfigError

#: Absolute tolerance on the eigenvalues of an equilibrated (unit-diagonal) symmetric matrix.
RANK_TOL: float = 1e-10
#: A diagonal entry this small relative to the largest one *of the same unit group* (see
#: :func:`equilibrate`) marks a column with no information (round-off only).
ZERO_DIAG_TOL: float = 1e-14


@dataclass(frozen=True)
class Scales:
    """Fixed nondimensionalisation: a length [m] and a time [s]."""

    length_m: float = 100.0
    time_s: float = 100.0

    def __post_init__(self) -> None:
        for name in ("length_m", "time_s"):
            val = getattr(self, name)
            if not (np.isfinite(val) and val > 0):
                raise ConfigError(f"scales.{name} must be a positive number, got {val!r}")


DEFAULT_SCALES = Scales()


def equilibrate(
    G: np.ndarray, groups: Sequence[int] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric diagonal equilibration of PSD matrices.

    Parameters
    ----------
    G : ndarray, shape (..., m, m)
    groups : sequence of m ints, optional
        Unit group of each state (e.g. positions 0, velocities 1, ...; see
        ``AugmentedModel.unit_groups``). A diagonal entry is compared with ``ZERO_DIAG_TOL`` times
        the largest diagonal entry *of its group*, which has the same units, so the test is
        unit-invariant. Without groups the largest entry overall is used: then a change of
        units can move a column across the threshold (m -> km with s -> 1/3600 s turned a
        full-rank Gramian into rank 3 this way).

    Returns
    -------
    Gn : ndarray, shape (..., m, m)
        ``D G D`` with unit diagonal; rows/columns of (numerically) zero diagonal are set to zero.
    informative : ndarray of bool, shape (..., m)
        False where the diagonal was zero (a state the data says nothing about).
    """
    G = np.asarray(G, float)
    diag = np.diagonal(G, axis1=-2, axis2=-1)
    if groups is None:
        scale = np.max(np.abs(diag), axis=-1, keepdims=True)
    else:
        g = np.asarray(groups)
        if g.shape != diag.shape[-1:]:
            raise ValueError(f"groups needs {diag.shape[-1]} entries, got {g.shape}")
        scale = np.zeros_like(diag)
        for label in np.unique(g):
            cols = g == label
            scale[..., cols] = np.max(np.abs(diag[..., cols]), axis=-1, keepdims=True)
    informative = diag > ZERO_DIAG_TOL * np.where(scale > 0, scale, 1.0)
    informative &= diag > 0
    dinv = np.where(informative, 1.0 / np.sqrt(np.where(informative, diag, 1.0)), 0.0)
    Gn = G * dinv[..., :, None] * dinv[..., None, :]
    return 0.5 * (Gn + np.swapaxes(Gn, -1, -2)), informative


def equilibrated_eigvals(G: np.ndarray, groups: Sequence[int] | None = None) -> np.ndarray:
    """Eigenvalues (ascending) of ``D G D``; shape ``(..., m)``. ``groups``: see equilibrate."""
    Gn, _ = equilibrate(G, groups)
    return np.linalg.eigvalsh(Gn)


def numerical_rank(
    G: np.ndarray, tol: float = RANK_TOL, groups: Sequence[int] | None = None
) -> np.ndarray | int:
    """Unit-invariant rank of symmetric PSD matrices (batched over leading axes).

    The number of eigenvalues of the equilibrated matrix above ``tol`` (see module docstring).
    Pass ``groups`` (the unit group of each state, :func:`equilibrate`) for a test that is
    unit-invariant also for columns with almost no information.
    """
    ev = equilibrated_eigvals(G, groups)
    r = np.sum(ev > tol, axis=-1)
    return int(r) if np.ndim(r) == 0 else r


def psd_metrics(G: np.ndarray) -> tuple[float, float, float]:
    """``(min_eig, log_det, condition)`` of a symmetric PSD matrix in its given (fixed) units.

    ``log_det`` is ``-inf`` and ``condition`` is ``inf`` when the smallest eigenvalue is not
    positive; ``min_eig`` is clipped below at 0 (round-off can make it slightly negative).
    """
    ev = np.linalg.eigvalsh(0.5 * (G + G.T))
    lo, hi = float(ev[0]), float(ev[-1])
    if lo <= 0.0:
        return max(lo, 0.0), float("-inf"), float("inf")
    return lo, float(np.sum(np.log(ev))), hi / lo
