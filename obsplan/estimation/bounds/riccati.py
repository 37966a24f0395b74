"""Covariance (Riccati) recursions at measurement epochs: one implementation for bound and planner.

Both the posterior Cramér–Rao bound of the nonlinear model (the validation's bound) and the
planner's estimator-aware objectives (``pcrb-position``, ``kf-position-std``) propagate a
covariance along a path of the double integrator:

* between measurements, exact prediction on the filter grid. The dynamics ``z' = A z`` have a
  nilpotent ``A`` (``A² = 0`` for ``p' = v (+ v_f)``; ``A³ = 0`` for the augmented KF's chain
  ``κ' = φ, φ' = 2γ``), so ``F(t) = I + A t + ½ A² t²`` and

      F(t) X F(t)ᵀ = Σ_{p=0..4} t^p M_p(X),   M_0 = X,  M_1 = A X + X Aᵀ,
      M_2 = A X Aᵀ + ½ (A² X + X A²ᵀ),  M_3 = ½ (A² X Aᵀ + A X A²ᵀ),  M_4 = ¼ A² X A²ᵀ.

  The process noise added at the end of a filter step may depend on its time ``τ`` (the KF's
  state-dependent noise gain, evaluated on the nominal path): ``q(τ) = q0 + τ q1 + τ² q2``.
  Over the ``k`` steps of length ``Δ`` from an epoch at ``τ_a``, with ``c = τ_a + k Δ``,

      Σ_{i<k} F(iΔ) q(c - iΔ) F(iΔ)ᵀ = Σ_{p,r} Δ^p S_{p+r}(k) M_p(Q_r),
      Q_0 = q0 + c q1 + c² q2,  Q_1 = -Δ (q1 + 2c q2),  Q_2 = Δ² q2,

  with the Faulhaber sums ``S_n(k) = Σ_{i<k} iⁿ`` (:func:`faulhaber`). With the physical
  process noise (``continuous``: ``q(τ)`` an intensity, :mod:`obsplan.estimation.config`) the sum
  is the integral ``∫_0^t F(u) q(c - u) F(u)ᵀ du`` over the gap ``t = k Δ``: the same formula with
  ``Δ^n S_n(k)`` replaced by ``t^{n+1}/(n+1)``, whatever the steps. So the work is proportional
  to the number of measurement epochs, not of filter steps;
* at an epoch, a sequential scalar update per reporting row: the path-dependent range row ``h``
  with variance ``ρ`` (given per epoch) and the constant rows of the DVL and depth gauge.

:func:`recursion_step` builds that epoch step once as a CasADi function of ``(P, h, ρ, mask, k,
dt, τ)``. The validation evaluates its ``mapaccum`` numerically; the planner calls the same
function on symbolic ``h`` and ``ρ`` built from the decision variables, so the objective it
optimises and the bound it is judged by are the same arithmetic. Besides the prior of the next
epoch the step returns the diagonal of the navigation covariance ``T P Tᵀ`` at each of the ``k``
samples of the gap (posterior at the epoch, then the predictions), from which every per-sample
statistic (final value, mission average) is read.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from obsplan.core.errors import ConfigError

#: Relative tolerance when deciding that two filter steps are the same length [-]: grids built by
#: ``linspace``/``arange`` differ by rounding only (~1e-15 relative).
STEP_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class Epochs:
    """Measurement epochs on a filter grid of samples ``0 .. N-1``.

    Attributes
    ----------
    index : ndarray of int, shape (J,)
        Sample index of each epoch: every sample where a sensor reports, the first and the last
        sample, and every sample where the step length changes (so each gap has one step).
    gap : ndarray of int, shape (J,)
        Samples from the epoch to the next one (the last epoch: 1); ``gap.sum() == N``.
    dt : ndarray, shape (J,)
        The filter step inside each gap (0 for the last epoch).
    mask : ndarray, shape (J, S)
        1.0 where sensor ``s`` reports at the epoch, else 0.0.
    time : ndarray, shape (J,)
        Time of each epoch since the first sample (same unit as ``dt``).
    """

    index: np.ndarray
    gap: np.ndarray
    dt: np.ndarray
    mask: np.ndarray
    time: np.ndarray

    @property
    def count(self) -> int:
        return int(self.index.size)

    @property
    def max_gap(self) -> int:
        return int(self.gap.max())

    def scaled(self, time_unit: float) -> Epochs:
        """The same epochs with times and steps divided by ``time_unit``.

        Parameters
        ----------
        time_unit : float
            The new unit of time, in the current one (e.g. the planner's time scale [s]).

        Returns
        -------
        Epochs
            The epochs with ``dt`` and ``time`` in that unit.
        """
        return Epochs(self.index, self.gap, self.dt / time_unit, self.mask, self.time / time_unit)

    def sample_values(self, per_epoch: np.ndarray) -> np.ndarray:
        """Per-sample values from an ``(..., K J)`` output of the recursion, shape ``(..., N)``.

        Column ``j K + i`` holds sample ``index[j] + i`` for ``i < gap[j]``.

        Parameters
        ----------
        per_epoch : ndarray, shape (..., K J)
            Values per epoch and sample of its gap (``K`` = :attr:`max_gap`, zero padded).

        Returns
        -------
        ndarray, shape (..., N)
            The values at every sample.
        """
        K, J = self.max_gap, self.count
        blocks = per_epoch.reshape(*per_epoch.shape[:-1], J, K)
        keep = np.arange(K)[None, :] < self.gap[:, None]
        return blocks[..., keep]


def make_epochs(t: np.ndarray, mask: np.ndarray) -> Epochs:
    """Epochs of a sample grid ``t`` (N,) [s] with report mask ``mask`` (N, S) bool.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times of the filter grid [s].
    mask : ndarray of bool, shape (N, S)
        Which sensor reports at which sample (:attr:`~obsplan.estimation.schedule.Schedule.mask`).

    Returns
    -------
    Epochs
        The epochs: reports, first and last sample, and step changes.

    Raises
    ------
    ConfigError
        If ``mask`` does not have one row per sample.
    """
    t = np.asarray(t, float)
    mask = np.asarray(mask, bool)
    N = t.size
    if N < 1 or mask.shape[0] != N:
        raise ConfigError(f"make_epochs: mask has {mask.shape[0]} rows for {N} samples")
    start = np.zeros(N, dtype=bool)
    start[0] = True
    start[-1] = True
    start |= mask.any(axis=1)
    if N > 2:
        h = np.diff(t)
        changed = np.abs(h[1:] - h[:-1]) > STEP_RTOL * np.maximum(h[1:], h[:-1])
        start[1:-1] |= changed
    index = np.flatnonzero(start)
    gap = np.diff(np.append(index, N))
    dt = np.zeros(index.size)
    inner = index < N - 1
    dt[inner] = t[index[inner] + 1] - t[index[inner]]
    return Epochs(index=index, gap=gap, dt=dt, mask=mask[index].astype(float), time=t[index] - t[0])


@dataclass(frozen=True, eq=False)
class RecursionModel:
    """The linear structure a covariance recursion needs (module docstring).

    Attributes
    ----------
    A : ndarray (m, m)
        Continuous dynamics, nilpotent (``A³ = 0``).
    q : ndarray (m, m)
        Process noise added per filter step (``q0``).
    nav : ndarray (2n, m)
        Rows of the navigation quantities ``(p, p')`` whose variances are reported.
    rows : ndarray (c, m)
        Constant (path-independent) output rows: DVL, depth.
    row_var : ndarray (c,)
        Their noise variances.
    row_sensor : tuple of int
        The sensor index (column of ``Epochs.mask``) of each constant row.
    range_sensor : int
        Sensor index of the range row (its row and variance are inputs of the step).
    n_sensors : int
    range_support : tuple of int
        State indices where the range row can be non-zero (the step takes only those entries).
    q1, q2 : ndarray (m, m), optional
        Time-varying parts of the per-step noise, ``q(τ) = q + τ q1 + τ² q2`` (zero by default).
    continuous : bool
        ``q`` (and ``q1``, ``q2``) are intensities of white noise, integrated exactly over each
        gap (the physical process noise), instead of covariances added per filter step.
    """

    A: np.ndarray
    q: np.ndarray
    nav: np.ndarray
    rows: np.ndarray
    row_var: np.ndarray
    row_sensor: tuple[int, ...]
    range_sensor: int
    n_sensors: int
    range_support: tuple[int, ...] = ()
    q1: np.ndarray | None = field(default=None, repr=False)
    q2: np.ndarray | None = field(default=None, repr=False)
    continuous: bool = False

    def __post_init__(self) -> None:
        A = np.asarray(self.A, float)
        if np.any(np.abs(A @ A @ A) > 0):
            raise ConfigError("RecursionModel: A must be nilpotent, A^3 = 0 (double integrator)")
        if not self.range_support:
            object.__setattr__(self, "range_support", tuple(range(A.shape[0])))
        for name in ("q1", "q2"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros_like(A))

    @property
    def m(self) -> int:
        return int(self.A.shape[0])

    @property
    def n(self) -> int:
        return int(self.nav.shape[0]) // 2

    def key(self) -> tuple:
        """Hashable identity (the CasADi step is cached on it).

        Returns
        -------
        tuple
            The arrays' bytes and the structure's sizes and flags.
        """
        arrays = (self.A, self.q, self.q1, self.q2, self.nav, self.rows, self.row_var)
        return tuple(np.asarray(a, float).tobytes() for a in arrays) + (
            self.row_sensor,
            self.range_sensor,
            self.n_sensors,
            self.range_support,
            self.A.shape,
            self.rows.shape,
            bool(self.continuous),
        )


def faulhaber(k, top: int = 6) -> list:
    """``[S_0(k), ..., S_top(k)]`` with ``S_n(k) = Σ_{i=0}^{k-1} iⁿ`` (``top <= 6``).

    Closed forms (Faulhaber), valid for numbers and CasADi symbols alike.

    Parameters
    ----------
    k : int, float or casadi.MX
        Number of terms.
    top : int, optional
        Highest power, at most 6.

    Returns
    -------
    list
        ``top + 1`` sums, of the type of ``k``.
    """
    m = k - 1  # S_n(k) = Σ_{i=1}^{m} iⁿ
    sums = [
        k,
        m * (m + 1) / 2,
        m * (m + 1) * (2 * m + 1) / 6,
        (m * (m + 1) / 2) ** 2,
        m * (m + 1) * (2 * m + 1) * (3 * m**2 + 3 * m - 1) / 30,
        m**2 * (m + 1) ** 2 * (2 * m**2 + 2 * m - 1) / 12,
        m * (m + 1) * (2 * m + 1) * (3 * m**4 + 6 * m**3 - 3 * m + 1) / 42,
    ]
    return sums[: top + 1]


_STEPS: dict[tuple, ca.Function] = {}


def recursion_step(model: RecursionModel, K: int) -> ca.Function:
    """The epoch step of the module docstring, cached per model structure and ``K``.

    Inputs ``P`` (m, m) prior at the epoch, ``h`` (len(range_support), 1) range row, ``rho``
    range variance, ``mask`` (S, 1), ``k`` samples to the next epoch (``1 <= k <= K``), ``dt``
    step, ``tau`` the epoch's time. Outputs ``P_next`` (m, m), the prior at the next epoch, and
    ``D`` (2n, K): the diagonal of ``nav P navᵀ`` at the samples ``0 .. k-1`` of the gap (zeros
    beyond ``k``).

    Parameters
    ----------
    model : RecursionModel
        The recursion's structure.
    K : int
        Largest gap, in samples (:attr:`Epochs.max_gap`).

    Returns
    -------
    casadi.Function
        The epoch step.
    """
    key = (*model.key(), int(K))
    fn = _STEPS.get(key)
    if fn is None:
        fn = _STEPS.setdefault(key, _recursion_step_impl(model, int(K)))
    return fn


def _nonzeros(M: np.ndarray) -> list[list[tuple[int, float]]]:
    """Per row, the ``(column, value)`` pairs of the non-zero entries of ``M``."""
    return [[(int(j), float(M[i, j])) for j in np.flatnonzero(M[i])] for i in range(M.shape[0])]


def _moments(X: np.ndarray, A: np.ndarray) -> list[np.ndarray]:
    """``M_0 .. M_4`` of a numeric symmetric ``X`` (module docstring)."""
    A2 = A @ A
    return [
        X,
        A @ X + X @ A.T,
        A @ X @ A.T + 0.5 * (A2 @ X + X @ A2.T),
        0.5 * (A2 @ X @ A.T + A @ X @ A2.T),
        0.25 * A2 @ X @ A2.T,
    ]


def _recursion_step_impl(model: RecursionModel, K: int) -> ca.Function:
    # Written entry by entry on the lower triangle, exploiting the symmetry of P and the sparsity
    # of A, of the constant rows and of the range row: the planner expands this function at
    # every epoch, so each flop saved here is saved thousands of times.
    m = model.m
    P = ca.SX.sym("P", m, m)
    h = ca.SX.sym("h", len(model.range_support))
    rho = ca.SX.sym("rho")
    mask = ca.SX.sym("mask", model.n_sensors)
    k = ca.SX.sym("k")
    dt = ca.SX.sym("dt")
    tau = ca.SX.sym("tau")
    Pl = [[P[max(i, j), min(i, j)] for j in range(m)] for i in range(m)]  # symmetric view
    Pu = _updates(model, Pl, h, rho, mask)
    propagate = _propagator(model, Pu, dt)

    P_next = ca.SX(m, m)
    for i in range(m):
        for j in range(i + 1):
            P_next[i, j] = propagate(i, j, k, tau + k * dt)
            P_next[j, i] = P_next[i, j]

    # per-sample diagonals of nav P navᵀ, polynomial in the sample index i of the gap
    nav = _nonzeros(np.asarray(model.nav, float))
    zero = ca.SX(0)
    cols = []
    for i in range(K):
        col = []
        for row in nav:
            v = zero
            for a, wa in row:
                for b, wb in row:
                    v = v + wa * wb * propagate(a, b, float(i), tau + i * dt)
            col.append(v)
        cols.append(ca.if_else(i < k, ca.vertcat(*col), ca.SX.zeros(len(col))))
    D = ca.horzcat(*cols)
    return ca.Function(
        "riccati_epoch",
        [P, h, rho, mask, k, dt, tau],
        [P_next, D],
        ["P", "h", "rho", "mask", "k", "dt", "tau"],
        ["P_next", "D"],
    )


def _updates(model: RecursionModel, Pl: list, h, rho, mask) -> list:
    """The epoch's scalar updates of the symmetric view ``Pl``: the range row ``h`` on its
    support (variance ``rho``), then the constant rows, each weighted by its sensor's mask."""
    m, zero = model.m, ca.SX(0)

    def update(Pl, row: list[tuple[int, Any]], var, w):
        ph = [sum((Pl[i][j] * r for j, r in row), zero) for i in range(m)]
        c = w / (sum((r * ph[j] for j, r in row), zero) + var)
        cph = [c * x for x in ph]
        out = [[None] * m for _ in range(m)]
        for i in range(m):
            for j in range(i + 1):
                out[i][j] = out[j][i] = Pl[i][j] - cph[i] * ph[j]
        return out

    support = model.range_support
    Pu = update(Pl, [(j, h[i]) for i, j in enumerate(support)], rho, mask[model.range_sensor])
    for r, v, sen in zip(model.rows, model.row_var, model.row_sensor, strict=True):
        Pu = update(Pu, [(int(j), float(r[j])) for j in np.flatnonzero(r)], float(v), mask[sen])
    return Pu


def _propagator(model: RecursionModel, Pu: list, dt):
    """``propagate(i, j, kk, c)``: entry ``(i, j)`` of ``F(kkΔ) Pu F(kkΔ)ᵀ`` plus the noise of
    ``kk`` steps ending at time ``c`` (module docstring), on the moments of ``Pu``."""
    m, zero = model.m, ca.SX(0)
    A = np.asarray(model.A, float)
    A2 = A @ A
    Arows, A2rows = _nonzeros(A), _nonzeros(A2)

    def left(rows, X):  # (rows X)[i][j] for a sparse numeric left factor
        return [[sum((a * X[l][j] for l, a in rows[i]), zero) for j in range(m)] for i in range(m)]

    AP, A2P = left(Arows, Pu), left(A2rows, Pu)
    APA = [[sum((a * AP[j][l] for l, a in Arows[i]), zero) for j in range(m)] for i in range(m)]
    A2PA = [[sum((a * AP[j][l] for l, a in A2rows[i]), zero) for j in range(m)] for i in range(m)]
    A2PA2 = [[sum((a * A2P[j][l] for l, a in A2rows[i]), zero) for j in range(m)] for i in range(m)]

    def moment(p, i, j):  # M_p(Pu)[i][j]
        if p == 0:
            return Pu[i][j]
        if p == 1:
            return AP[i][j] + AP[j][i]
        if p == 2:
            return APA[i][j] + 0.5 * (A2P[i][j] + A2P[j][i])
        if p == 3:
            return 0.5 * (A2PA[i][j] + A2PA[j][i])
        return 0.25 * A2PA2[i][j]

    qs = [np.asarray(x, float) for x in (model.q, model.q1, model.q2)]
    Mq = [_moments(x, A) for x in qs]  # Mq[a][p] = M_p(q_a)
    top_p = 2 if not A2.any() else 4
    top_r = 2 if qs[2].any() else (1 if qs[1].any() else 0)

    def moment_sums(kk):
        """``I_j = Δ^j S_j(kk)`` per step, or ``∫_0^t u^j du = t^{j+1}/(j+1)`` (continuous)."""
        if model.continuous:
            t = kk * dt
            return [t ** (j + 1) / (j + 1) for j in range(top_p + top_r + 1)]
        Sn = faulhaber(kk, top_p + top_r)
        return [dt**j * Sn[j] for j in range(top_p + top_r + 1)]

    def noise(i, j, kk, c):
        """Entry (i, j) of Σ_{l<kk} F(lΔ) q(c - lΔ) F(lΔ)ᵀ (its integral if continuous)."""
        In = moment_sums(kk)
        e = zero
        for p in range(top_p + 1):
            m0, m1, m2 = Mq[0][p][i, j], Mq[1][p][i, j], Mq[2][p][i, j]
            if m0 != 0 or m1 != 0 or m2 != 0:
                # Q_0 = q0 + c q1 + c² q2
                e = e + In[p] * (m0 + c * m1 + c**2 * m2)
            if top_r >= 1 and (m1 != 0 or m2 != 0):
                # Q_1 = -(q1 + 2 c q2) per unit lag (-Δ (q1 + 2 c q2) per step)
                e = e - In[p + 1] * (m1 + 2 * c * m2)
            if top_r >= 2 and m2 != 0:
                # Q_2 = q2 per squared lag (Δ² q2 per step)
                e = e + In[p + 2] * m2
        return e

    def propagate(i, j, kk, c):
        t = kk * dt
        e = zero
        for p in range(top_p + 1):
            e = e + t**p * moment(p, i, j)
        return e + noise(i, j, kk, c)

    return propagate


def run_recursion(
    model: RecursionModel,
    epochs: Epochs,
    P0,
    h,
    rho,
    mask: np.ndarray | None = None,
):
    """Run the recursion over every epoch (numerically or on CasADi symbols).

    Parameters
    ----------
    model : RecursionModel
        Structure.
    epochs : Epochs
        Epochs.
    P0 : ndarray or casadi.MX, shape (m, m)
        Prior covariance at the first sample.
    h : ndarray or casadi.MX, shape (len(model.range_support), J)
        Range row at each epoch, its entries on ``model.range_support`` (ndarray or CasADi).
    rho : ndarray or casadi.MX, shape (1, J)
        Range variance at each epoch.
    mask : ndarray, shape (J, S), optional
        Override of ``epochs.mask`` (e.g. no range update at the anchor sample of the KF).

    Returns
    -------
    P_prior : (m, m J)
        Prior covariance at each epoch's successor, concatenated.
    D : (2n, K J)
        Per-sample navigation variances (:meth:`Epochs.sample_values` turns it per sample).
    """
    J, K = epochs.count, epochs.max_gap
    step = recursion_step(model, K)
    acc = step.mapaccum("riccati", J)
    M = epochs.mask if mask is None else np.asarray(mask, float)
    args = (
        P0,
        h,
        rho,
        ca.DM(M.T),
        ca.DM(epochs.gap.astype(float)).T,
        ca.DM(epochs.dt).T,
        ca.DM(epochs.time).T,
    )
    return acc(*args)


def position_std(D, n: int, epochs: Epochs):
    """Per-sample ``sqrt(tr P_pp)`` from the recursion's ``D`` (numpy: shape (N,)).

    With CasADi input, returns ``(sum over samples, final value)`` of the same quantity: the
    mission-average and final objectives of the planner.

    Parameters
    ----------
    D : ndarray or casadi.MX, shape (2n, K J)
        Per-sample navigation variances from :func:`run_recursion`.
    n : int
        Spatial dimension.
    epochs : Epochs
        The recursion's epochs.

    Returns
    -------
    ndarray, shape (N,), or tuple of casadi.MX
        The position standard deviation at every sample [m]; with CasADi input, its sum over
        the samples and its final value.
    """
    if isinstance(D, np.ndarray):
        return np.sqrt(np.maximum(epochs.sample_values(D[:n].sum(axis=0)), 0.0))
    K, J = epochs.max_gap, epochs.count
    keep = (np.arange(K)[None, :] < epochs.gap[:, None]).reshape(-1).astype(float)
    var = ca.sum1(D[:n, :])
    std = ca.sqrt(var + 1e-30)  # the tiny floor keeps the derivative finite at 0 (never reached)
    total = ca.dot(std.T, ca.DM(keep))
    return total, std[(J - 1) * K]


def constant_rows(
    sensors: Sequence[str], H: np.ndarray, noise: dict[str, float], slices: dict[str, slice]
) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """The DVL / depth rows of an output matrix ``H`` with their variances and sensor indices.

    Parameters
    ----------
    sensors : sequence of str
        The model's sensors, in order.
    H : ndarray, shape (p, m)
        Output matrix (constant for the DVL and depth rows).
    noise : dict of str to float
        Standard deviation per sensor (DVL [m/s], depth [m]).
    slices : dict of str to slice
        Rows of each sensor in ``H`` (:attr:`VehicleModel.output_slices
        <obsplan.model.vehicle.VehicleModel.output_slices>`).

    Returns
    -------
    rows : ndarray, shape (c, m)
        The constant rows.
    var : ndarray, shape (c,)
        Their noise variances.
    which : tuple of int
        The sensor index of each row.
    """
    rows, var, which = [], [], []
    for j, s in enumerate(sensors):
        if s == "range":
            continue
        for r in range(slices[s].start, slices[s].stop):
            rows.append(H[r])
            var.append(noise[s] ** 2)
            which.append(j)
    m = H.shape[1]
    return (
        np.array(rows, float).reshape(len(rows), m),
        np.array(var, float),
        tuple(which),
    )
