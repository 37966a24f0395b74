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
  Two caveats make the *input* of the test matter: a Gramian summing sensors of different output
  units (ȳ in m², DVL in m/s) is *not* mapped to ``c·S G S`` by a change of units (the sensors are
  re-weighted against each other), and ``ZERO_DIAG_TOL`` compares columns of different units. So
  rank tests run on the Gramian in scales taken from the trajectory itself
  (``gramian.rank_scales``), which change with the units; then every verdict is unit-invariant.
  Measured by ``benchmarks/bench_observability.py``: the true zeros of rank-deficient Gramians
  stay below ~1e-14 up to 6e4 samples.
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

from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.core.textfiles import check_magnitude

#: Absolute tolerance on the eigenvalues of an equilibrated (unit-diagonal) symmetric matrix.
RANK_TOL: float = 1e-10
#: A diagonal entry this small relative to the largest one marks a column with no information.
ZERO_DIAG_TOL: float = 1e-14
#: Largest scale accepted (length [m] and time [s]), and its inverse the smallest: the Gramian's
#: entries grow as (T/L)^4 and (1/L)^4, so a scale of 1e300 underflows them to 0 (a full-rank
#: Gramian reported with min_eig 0, log_det -inf) and 1e-300 overflows them; within 1e±7 they
#: stay far inside floating point.
MAX_SCALE: float = 1e7


class ScaleError(ConfigError):
    """Scales that make the fixed-scale metrics meaningless (out of range, or a full-rank
    Gramian whose eigenvalues they push below round-off).

    ``reason`` is the message without the scales it is about (a caller names them its way:
    ``--length-scale``, ``scales.length_m``).
    """

    def __init__(self, message: str, reason: str | None = None) -> None:
        super().__init__(message)
        self.reason = reason or message


def check_scale(value: float, name: str, unit: str) -> None:
    """Refuse a scale that is not a positive number within ``1/MAX_SCALE`` to
    :data:`MAX_SCALE` (the one rule of :func:`obsplan.core.textfiles.check_magnitude`);
    ``name`` is the field or option (``scales.length_m``, ``--length-scale``).

    Parameters
    ----------
    value : float
        The scale, a length [m] or a time [s].
    name : str
        The field or option that gave it, named in the message.
    unit : str
        Its unit, for the message.

    Raises
    ------
    ScaleError
        If ``value`` is not a positive finite number within ``1/MAX_SCALE`` to
        :data:`MAX_SCALE`.
    """
    if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
        raise ScaleError(f"{name} must be a positive number, got {value!r}")
    check_magnitude(value, name, MAX_SCALE, unit, smallest=1.0 / MAX_SCALE, error=ScaleError)


@dataclass(frozen=True)
class Scales:
    """Fixed nondimensionalisation: a length [m] and a time [s], each within 1e±7
    (:func:`check_scale`)."""

    length_m: float = 100.0
    time_s: float = 100.0

    def __post_init__(self) -> None:
        for name, unit in (("length_m", "m"), ("time_s", "s")):
            check_scale(getattr(self, name), f"scales.{name}", unit)


DEFAULT_SCALES = Scales()


def augmented_state_scale(state_dim: int, dim: int, length, time) -> list:
    """``z_nd / z`` for every state of the augmented model in the scales ``length`` [m] and
    ``time`` [s]: ``p/L``, ``v T/L`` (and ``v_f T/L``), ``α T/L²``, ``β T²/L²``; plain
    arithmetic, so floats give floats and ``Fraction`` s exact fractions.

    Parameters
    ----------
    state_dim : int
        Dimension ``m`` of the augmented state (``2n + 2``, or ``3n + 2`` with current).
    dim : int
        Spatial dimension ``n``.
    length : float or Fraction
        Length scale ``L`` [m].
    time : float or Fraction
        Time scale ``T`` [s].

    Returns
    -------
    list
        ``m`` factors, in the order of the augmented state (positions, velocities[, current],
        ``p0ᵀν0``, ``|ν0|²``), of the type of ``length`` and ``time``.
    """
    L, T = length, time
    return [1 / L] * dim + [T / L] * (state_dim - dim - 2) + [T / L**2, T**2 / L**2]


def equilibrate(G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric diagonal equilibration of PSD matrices.

    The zero-diagonal test compares columns with each other, so it is unit-invariant only for a
    matrix in scales that change with the units (as ``gramian.rank_scales`` provides).

    Parameters
    ----------
    G : ndarray, shape (..., m, m)
        Symmetric positive semi-definite matrices (Gramians).

    Returns
    -------
    Gn : ndarray, shape (..., m, m)
        ``D G D`` with unit diagonal; rows/columns of (numerically) zero diagonal are set to zero.
    informative : ndarray of bool, shape (..., m)
        False where the diagonal was zero (a state the data says nothing about).
    """
    G = np.asarray(G, float)
    diag = np.diagonal(G, axis1=-2, axis2=-1)
    scale = np.max(np.abs(diag), axis=-1, keepdims=True)
    informative = diag > ZERO_DIAG_TOL * np.where(scale > 0, scale, 1.0)
    informative &= diag > 0
    dinv = np.where(informative, 1.0 / np.sqrt(np.where(informative, diag, 1.0)), 0.0)
    Gn = G * dinv[..., :, None] * dinv[..., None, :]
    return 0.5 * (Gn + np.swapaxes(Gn, -1, -2)), informative


def equilibrated_eigvals(G: np.ndarray) -> np.ndarray:
    """Eigenvalues (ascending) of ``D G D``; shape ``(..., m)``.

    Parameters
    ----------
    G : ndarray, shape (..., m, m)
        Symmetric positive semi-definite matrices (Gramians).

    Returns
    -------
    ndarray, shape (..., m)
        Eigenvalues of the equilibrated matrices (:func:`equilibrate`), in ``[0, m]`` up to
        round-off.
    """
    Gn, _ = equilibrate(G)
    return np.linalg.eigvalsh(Gn)


def numerical_rank(G: np.ndarray, tol: float = RANK_TOL) -> np.ndarray | int:
    """Unit-invariant rank of symmetric PSD matrices (batched over leading axes).

    The number of eigenvalues of the equilibrated matrix above ``tol`` (see module docstring).

    Parameters
    ----------
    G : ndarray, shape (..., m, m)
        Symmetric positive semi-definite matrices (Gramians), in scales that change with the
        units (``gramian.rank_scales``).
    tol : float, optional
        Absolute tolerance on the equilibrated eigenvalues (dimensionless).

    Returns
    -------
    int or ndarray of int, shape (...)
        The rank of each matrix; an int for one matrix.
    """
    ev = equilibrated_eigvals(G)
    r = np.sum(ev > tol, axis=-1)
    return int(r) if np.ndim(r) == 0 else r


def psd_metrics(G: np.ndarray) -> tuple[float, float, float]:
    """``(min_eig, log_det, condition)`` of a symmetric PSD matrix in its given (fixed) units.

    ``log_det`` is ``-inf`` and ``condition`` is ``inf`` when the smallest eigenvalue is not
    positive; ``min_eig`` is clipped below at 0 (round-off can make it slightly negative).

    Parameters
    ----------
    G : ndarray, shape (m, m)
        Symmetric positive semi-definite matrix (a Gramian nondimensionalised by fixed scales).

    Returns
    -------
    min_eig : float
        Smallest eigenvalue, >= 0.
    log_det : float
        Natural log of the determinant (sum of the log-eigenvalues), or ``-inf``.
    condition : float
        Largest over smallest eigenvalue, or ``inf``.
    """
    ev = np.linalg.eigvalsh(0.5 * (G + G.T))
    lo, hi = float(ev[0]), float(ev[-1])
    if lo <= 0.0:
        return max(lo, 0.0), float("-inf"), float("inf")
    return lo, float(np.sum(np.log(ev))), hi / lo
