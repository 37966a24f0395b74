"""Windowed, information-weighted Gramians of the augmented model (eqs. 20-27 with two changes).

The Gramian ``G(t_N, t_0)`` of :mod:`obsplan.observability.gramian` measures what the whole
horizon says about the *initial* augmented state, with every output row weighted alike. A
filter with process noise forgets: what it knows at ``t`` comes from the last few ``τ_f``
seconds of measurements, and a range carries less information the farther the beacon is. So:

* **Information weights.** Each output row is scaled by its information per unit time, rate /
  variance. For the range pseudo-output ``y = |p - b|²/2`` with range noise ``σ_r`` the variance
  is ``r² σ_r² + σ_r⁴/2``. The augmented output is ``ȳ = y - y_0 + |d|²/2`` (eq. 21): it also
  carries the noise of the *first* sample ``y_0``, and with it the variance is
  ``(r² + r_0²) σ_r² + σ_r⁴`` (``r_0`` the start's range; ``SensorInformation.start_range``).
  Without ``y_0``'s share the weight grows as ``1/r²`` at the beacon while the row ``dᵀ`` keeps
  the size of the displacement from the start, so a sample's position block reads ``|d|²/r²``
  times the ``1/σ_r²`` a range carries; with it ``|d| <= r + r_0`` bounds that ratio by 2 (start
  at rest). Whether to use it is the caller's choice (``start_range = None``: not). ``r²`` is
  held at its mean
  over each interval (Simpson's rule on the exact quadratic path). DVL rows get
  ``rate / σ_dvl²``, the depth row ``rate / σ_z²``. Weights are expressed in the metric scales
  (outputs ``ȳ/L²``, ``v T/L``, ``p_z/L``; time ``t/T``).
* **Windows.** The Gramian of a window ``[t_a, t_b]`` is the sum of its intervals' exact
  contributions (eq. 25), built once for the whole path: a window is a difference of prefix
  sums. The contributions are referred to ``z(t_0)``; since ``z(t) = Φ(t - t_0) z(t_0)`` +
  input terms with ``Φ(τ) = I + Aτ`` (eq. 26, ``A² = 0``), the information the window carries
  about ``z(t_s)`` is ``Φ(-τ_s)ᵀ G_ab Φ(-τ_s)`` with ``τ_s = t_s - t_0``: ``anchor = "start"``
  takes ``t_s = t_a`` (observability of the window's initial state), ``anchor = "current"``
  ``t_s = t_b`` (constructibility of the state at the window's end, Salaris et al.).
  ``det Φ = 1``, so the anchor changes eigenvalues and ``tr G⁻¹`` but not ``log det``.

Criteria of one window (:func:`window_criteria`) are computed on ``G + εI`` with a small floor
``ε`` (finite at rank-deficient windows) through an unpivoted Cholesky factor, the same formula in
numpy and in CasADi so that the planner's objective and the value on a path agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from obsplan.model.vehicle import VehicleModel
from obsplan.observability.gramian import AugmentedModel, interval_gramians
from obsplan.observability.local_gramian import LinearisedModel
from obsplan.observability.scaling import Scales
from obsplan.trajectory.sampled import Trajectory

ANCHORS: tuple[str, ...] = ("start", "current")


@dataclass(frozen=True)
class SensorInformation:
    """Rates [Hz] and noise standard deviations of the sensors (range std on ``|p - b|`` [m],
    DVL [m/s] per axis, depth [m]); a sensor the model lacks is ignored. ``start_range`` [m]
    is ``r_0``, the range of the first sample, whose noise every augmented output carries
    (module docstring; None: ``y_0`` taken as exact)."""

    range_rate: float
    range_std: float
    dvl_rate: float = 0.0
    dvl_std: float = 1.0
    depth_rate: float = 0.0
    depth_std: float = 1.0
    start_range: float | None = None


def range_information(r2, sigma: float, start_range=None):
    """Information per sample of ``ȳ = y - y_0 + |d|²/2`` with range noise ``sigma`` [m]:
    ``1/((r² + r_0²) σ² + σ⁴)`` [1/m⁴], for ``r2 = r²`` [m²] and ``start_range = r_0`` [m]
    (numpy or CasADi); ``start_range = None``: ``y``'s alone, ``1/(r²σ² + σ⁴/2)``.

    Parameters
    ----------
    r2 : float, ndarray or casadi.SX
        Squared range to the beacon ``r²`` [m²] (e.g. :func:`mean_square_range`).
    sigma : float
        Standard deviation of the range noise [m].
    start_range : float or None, optional
        Range of the first sample ``r_0`` [m]; None: ``y_0`` taken as exact.

    Returns
    -------
    float, ndarray or casadi.SX
        Information per sample [1/m⁴], of the type and shape of ``r2``.
    """
    if start_range is None:
        return 1.0 / (r2 * sigma**2 + 0.5 * sigma**4)
    return 1.0 / ((r2 + start_range**2) * sigma**2 + sigma**4)


def simpson_mean(f_start, f_mid, f_end):
    """Simpson's rule mean of a function over an interval from its start, midpoint and end.

    Parameters
    ----------
    f_start, f_mid, f_end : float, ndarray or casadi.SX
        The function's values at the start, midpoint and end of the interval(s).

    Returns
    -------
    float, ndarray or casadi.SX
        ``(f_start + 4 f_mid + f_end) / 6``, in the unit of the values.
    """
    return (f_start + 4.0 * f_mid + f_end) / 6.0


def mean_square_range(traj: Trajectory, beacon: np.ndarray) -> np.ndarray:
    """Mean of ``|p - b|²`` over each interval of ``traj`` (Simpson's rule on the exact quadratic
    between samples), shape ``(N-1,)`` [m²].

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    beacon : ndarray, shape (n,)
        Beacon position [m].

    Returns
    -------
    ndarray, shape (N-1,)
        Mean squared range over each interval [m²].
    """
    p, v, u, h = traj.p - beacon, traj.v, traj.u[:-1], traj.dt[:, None]
    mid = p[:-1] + 0.5 * h * v[:-1] + 0.125 * h**2 * u
    sq = np.sum(p**2, axis=1)
    return simpson_mean(sq[:-1], np.sum(mid**2, axis=1), sq[1:])


def row_weight_factors(
    aug: AugmentedModel | LinearisedModel | VehicleModel, info: SensorInformation, scales: Scales
) -> tuple[float, np.ndarray]:
    """``(c_range, w_other)``: the range row's weight is ``c_range * range_information(r²)``, the
    other rows' (DVL axes, then depth) are the constants ``w_other``; all in the metric scales
    (information per unit of ``t/T`` about outputs ``ȳ/L²``, ``v T/L``, ``p_z/L``).

    Parameters
    ----------
    aug : AugmentedModel or LinearisedModel or VehicleModel
        The model (its sensors and dimension).
    info : SensorInformation
        Sensor rates [Hz] and noise standard deviations.
    scales : Scales
        Metric scales, length [m] and time [s].

    Returns
    -------
    c_range : float
        Factor of the range row's weight.
    w_other : ndarray, shape (n_outputs - 1,)
        Weights of the DVL rows (one per axis) and of the depth row, where the model has them.
    """
    L, T = scales.length_m, scales.time_s
    c_range = info.range_rate * T * L**4
    other: list[float] = []
    if any(s.startswith("dvl") for s in aug.sensors):
        other += [info.dvl_rate * T * (L / T) ** 2 / info.dvl_std**2] * aug.dim
    if "depth" in aug.sensors:
        other.append(info.depth_rate * T * L**2 / info.depth_std**2)
    return c_range, np.asarray(other, float)


def local_row_weights(lm: LinearisedModel, info: SensorInformation, scales: Scales) -> np.ndarray:
    """Row weights ``(n_outputs,)`` of the local Gramian (:mod:`obsplan.observability.
    local_gramian`) in the metric scales: ``rate T L² / σ_r²`` for the range (output ``r/L``;
    a range carries ``1/σ_r²`` at any distance), the augmented model's for the other rows.

    Parameters
    ----------
    lm : LinearisedModel
        The linearised model (its sensors).
    info : SensorInformation
        Sensor rates [Hz] and noise standard deviations.
    scales : Scales
        Metric scales, length [m] and time [s].

    Returns
    -------
    ndarray, shape (n_outputs,)
        Information rate of the range row, then the DVL axes and depth rows.
    """
    _, other = row_weight_factors(lm, info, scales)
    L, T = scales.length_m, scales.time_s
    return np.concatenate([[info.range_rate * T * L**2 / info.range_std**2], other])


def information_weights(
    traj: Trajectory,
    aug: AugmentedModel,
    beacon: np.ndarray,
    info: SensorInformation,
    scales: Scales,
) -> np.ndarray:
    """Row weights of every interval, shape ``(N-1, n_outputs)``, in the metric scales.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    aug : AugmentedModel
        The augmented model (its sensors).
    beacon : ndarray, shape (n,)
        Beacon position [m].
    info : SensorInformation
        Sensor rates [Hz] and noise standard deviations.
    scales : Scales
        Metric scales, length [m] and time [s].

    Returns
    -------
    ndarray, shape (N-1, n_outputs)
        Information per unit time of every output row on every interval: the range row's from
        the interval's mean squared range, the others constant.
    """
    c_range, other = row_weight_factors(aug, info, scales)
    r2 = mean_square_range(traj, beacon)
    wr = c_range * range_information(r2, info.range_std, info.start_range)
    return np.column_stack([wr, np.broadcast_to(other, (wr.size, other.size))])


def window_layout(n_intervals: int, window: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows of ``window`` intervals every ``stride`` intervals, the last one ending at the end.

    Returns ``(starts, ends)`` as interval indices (window ``j`` is intervals
    ``starts[j] <= k < ends[j]``); one window ``[0, n_intervals)`` when ``window >= n_intervals``.

    Parameters
    ----------
    n_intervals : int
        Number of intervals of the path, ``N - 1``.
    window : int
        Length of a window, in intervals.
    stride : int
        Intervals between the starts of consecutive windows.

    Returns
    -------
    starts, ends : ndarray of int, shape (n_windows,)
        First interval of each window and the one after its last.

    Raises
    ------
    ValueError
        If ``window`` or ``stride`` is below 1.
    """
    if window < 1 or stride < 1:
        raise ValueError(f"window and stride must be >= 1 interval, got {window}, {stride}")
    if window >= n_intervals:
        return np.array([0]), np.array([n_intervals])
    starts = list(range(0, n_intervals - window + 1, stride))
    if starts[-1] + window < n_intervals:
        starts.append(n_intervals - window)
    a = np.asarray(starts)
    return a, a + window


def anchor_times(tau: np.ndarray, starts: np.ndarray, ends: np.ndarray, anchor: str) -> np.ndarray:
    """The times ``τ_s`` (same units as ``tau``, the node times from ``t_0``) the windows are
    referred to: their start or their end.

    Parameters
    ----------
    tau : ndarray, shape (N,)
        Node times from ``t_0``.
    starts, ends : ndarray of int, shape (n_windows,)
        :func:`window_layout`.
    anchor : {"start", "current"}
        Refer each window to its start or to its end.

    Returns
    -------
    ndarray, shape (n_windows,)
        ``τ_s`` of every window.

    Raises
    ------
    ValueError
        For an unknown ``anchor``.
    """
    if anchor not in ANCHORS:
        raise ValueError(f"anchor must be one of {ANCHORS}, got {anchor!r}")
    return tau[starts] if anchor == "start" else tau[ends]


def reanchor_matrix(aug: AugmentedModel | LinearisedModel, tau_s):
    """``Φ(-τ_s) = I - A τ_s`` (eq. 26): ``z(t_0) = Φ(-τ_s) z(t_s)`` up to input terms (either
    model: both have ``A² = 0``).

    Parameters
    ----------
    aug : AugmentedModel or LinearisedModel
        The model (its dynamics matrix ``A``).
    tau_s : float
        Time of the anchor from ``t_0``, in the units of ``A``'s model (normally scaled).

    Returns
    -------
    ndarray, shape (m, m)
        The transition matrix back from the anchor.
    """
    return np.eye(aug.state_dim) - aug.A * tau_s


def windowed_gramians(
    Gk: np.ndarray,
    tau: np.ndarray,
    aug: AugmentedModel | LinearisedModel,
    starts: np.ndarray,
    ends: np.ndarray,
    anchor: str,
    prior: np.ndarray | None = None,
) -> np.ndarray:
    """Window Gramians about the anchor state from interval contributions, by prefix sums.

    Parameters
    ----------
    Gk : ndarray, shape (K, m, m)
        Interval contributions referred to ``z(t_0)`` (:func:`interval_gramians`).
    tau : ndarray, shape (K + 1,)
        Node times from ``t_0``, in the units of ``Gk`` (scaled).
    aug : AugmentedModel or LinearisedModel
        The model whose state the Gramians are about (its ``A``).
    starts, ends : ndarray of int
        :func:`window_layout`.
    anchor : {"start", "current"}
        Refer each window to the state at its start or at its end.
    prior : ndarray, shape (m, m), optional
        Information about ``z(t_0)`` (a prior) added to every window before it is re-anchored:
        the prior propagated to the anchor without process noise.

    Returns
    -------
    ndarray, shape (n_windows, m, m)
        The Gramian of every window about its anchor state, symmetrised.
    """
    C = np.zeros((Gk.shape[0] + 1, *Gk.shape[1:]))
    np.cumsum(Gk, axis=0, out=C[1:])
    G = C[ends] - C[starts]
    if prior is not None:
        G = G + prior
    P = np.stack([reanchor_matrix(aug, s) for s in anchor_times(tau, starts, ends, anchor)])
    G = np.swapaxes(P, 1, 2) @ G @ P
    return 0.5 * (G + np.swapaxes(G, 1, 2))


def windowed_gramians_quadrature(
    traj: Trajectory,
    aug: AugmentedModel,
    row_weights: np.ndarray,
    scales: Scales,
    starts: np.ndarray,
    ends: np.ndarray,
    anchor: str,
) -> np.ndarray:
    """The same window Gramians by Gauss-Legendre quadrature of ``Φ(t - t_s)ᵀ Cᵀ W C Φ(t - t_s)``.

    An independent route (``C(t)`` of :meth:`AugmentedModel.output_matrix` at each quadrature
    node, no interval closed form, no prefix sums) to check :func:`windowed_gramians`; 5 nodes
    per interval integrate the degree-6 integrand exactly. Slow: for tests and small paths.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    aug : AugmentedModel
        The augmented model.
    row_weights : ndarray, shape (N-1, n_outputs)
        Information per unit time of every output row on every interval, in ``scales``.
    scales : Scales
        Metric scales, length [m] and time [s].
    starts, ends : ndarray of int, shape (n_windows,)
        :func:`window_layout`.
    anchor : {"start", "current"}
        Refer each window to the state at its start or at its end.

    Returns
    -------
    ndarray, shape (n_windows, m, m)
        The Gramian of every window about its anchor state.
    """
    tr = traj.scaled(scales.length_m, scales.time_s)
    x, wq = np.polynomial.legendre.leggauss(5)
    tau = tr.t - tr.t[0]
    ts = anchor_times(tau, starts, ends, anchor)
    out = np.zeros((starts.size, aug.state_dim, aug.state_dim))
    for j, (a, b) in enumerate(zip(starts, ends, strict=True)):
        for k in range(a, b):
            h = tr.dt[k]
            for xi, wi in zip(x, wq, strict=True):
                s = 0.5 * h * (xi + 1.0)
                p = tr.p[k] + tr.v[k] * s + 0.5 * tr.u[k] * s**2
                t = tau[k] + s
                d = p - tr.p[0] - tr.v[0] * t
                C = aug.output_matrix(d, t) @ (np.eye(aug.state_dim) + aug.A * (t - ts[j]))
                out[j] += 0.5 * h * wi * (C.T * row_weights[k]) @ C
    return out


def _cholesky_criteria(G, m: int, eps, log, zeros):
    """``(tr (G + εI)⁻¹, log det(G + εI))`` by an unpivoted Cholesky factor (numpy or SX)."""
    L = [[zeros() for _ in range(m)] for _ in range(m)]
    logdet = 0.0
    for j in range(m):
        s = G[j, j] + eps - sum(L[j][k] * L[j][k] for k in range(j))
        L[j][j] = s**0.5
        logdet = logdet + log(s)
        for i in range(j + 1, m):
            L[i][j] = (G[i, j] - sum(L[i][k] * L[j][k] for k in range(j))) / L[j][j]
    # tr G⁻¹ = ||L⁻¹||_F²: forward substitution for every column of L⁻¹
    tr = 0.0
    for c in range(m):
        y = [zeros() for _ in range(m)]
        for i in range(c, m):
            rhs = (1.0 if i == c else 0.0) - sum(L[i][k] * y[k] for k in range(c, i))
            y[i] = rhs / L[i][i]
            tr = tr + y[i] * y[i]
    return tr, logdet


def window_criteria(G: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """``tr (G + εI)⁻¹`` and ``log det(G + εI)`` of every window, each shape ``(n_windows,)``.

    ``G`` has shape ``(n_windows, m, m)``; a window that is not positive definite even with the
    floor (round-off only) reads ``(inf, -inf)``.

    Parameters
    ----------
    G : ndarray, shape (n_windows, m, m)
        Window Gramians (:func:`windowed_gramians`), nondimensional.
    eps : float
        Floor added to the diagonal, nondimensional.

    Returns
    -------
    trace_inv : ndarray, shape (n_windows,)
        ``tr (G + εI)⁻¹`` (an A-optimality criterion; smaller is better).
    log_det : ndarray, shape (n_windows,)
        ``log det(G + εI)`` (a D-optimality criterion; larger is better).
    """
    m = G.shape[1]
    tr = np.full(G.shape[0], np.inf)
    ld = np.full(G.shape[0], -np.inf)
    for j in range(G.shape[0]):
        try:
            Lc = np.linalg.cholesky(G[j] + eps * np.eye(m))
        except np.linalg.LinAlgError:
            continue
        Li = np.linalg.inv(Lc)
        tr[j] = float(np.sum(Li**2))
        ld[j] = 2.0 * float(np.sum(np.log(np.diag(Lc))))
    return tr, ld


@cache
def window_criteria_function(m: int) -> ca.Function:
    """CasADi ``(tr, logdet) = f(G, eps)`` of one window: :func:`window_criteria` as a smooth
    expression (``G`` m × m symmetric, ``eps`` the floor).

    Parameters
    ----------
    m : int
        Dimension of the window Gramian.

    Returns
    -------
    casadi.Function
        ``(tr (G + εI)⁻¹, log det(G + εI))`` of ``(G, eps)`` (cached per ``m``).
    """
    G = ca.SX.sym("G", m, m)
    eps = ca.SX.sym("eps")
    Gs = 0.5 * (G + G.T)
    tr, ld = _cholesky_criteria(Gs, m, eps, ca.log, lambda: ca.SX(0))
    return ca.Function("window_criteria", [G, eps], [tr, ld])


def weighted_interval_gramians(
    traj: Trajectory,
    aug: AugmentedModel,
    beacon: np.ndarray,
    info: SensorInformation | None,
    scales: Scales,
) -> np.ndarray:
    """Interval contributions in ``scales`` with information weights (``info = None``: the
    paper's unit weights), shape ``(N-1, m, m)``.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    aug : AugmentedModel
        The augmented model.
    beacon : ndarray, shape (n,)
        Beacon position [m].
    info : SensorInformation or None
        Sensor rates and noises; None: unit weights.
    scales : Scales
        Metric scales, length [m] and time [s].

    Returns
    -------
    ndarray, shape (N-1, m, m)
        The weighted contribution of every interval, referred to ``z(t_0)``.
    """
    w = None if info is None else information_weights(traj, aug, beacon, info, scales)
    return interval_gramians(traj, aug, scales, row_weights=w)
