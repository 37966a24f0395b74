"""Structure shared by the filters: sparse transitions, composed noise terms, measurement rows.

Both filters order their states ``(p, v[, v_f], ...)`` and predict with ``F = I + N`` where ``N``
is nilpotent and sparse (``p_i ← v_i [+ v_f,i]`` with coefficient ``T``; the augmented KF adds its
chain, :mod:`obsplan.estimation.filters.kf`). The kernels (:mod:`obsplan.estimation.kernels`) take
``N`` as a list of ``(row, col, mult, power)`` entries, ``N[row, col] = mult · T^power``, and the
composed process noise of a segment as ``Q = S0 q0 + S1 q1 + S2 q2`` with ``q0 = q``,
``q1 = A q + q Aᵀ``, ``q2 = A q Aᵀ`` (:mod:`obsplan.estimation.epochs`).

Every measurement is a scalar update in the Joseph form, ``P⁺ = (I - k hᵀ) P (I - k hᵀ)ᵀ + r k
kᵀ``, evaluated as ``P - (k wᵀ + w kᵀ)`` with ``b = P h``, ``s = hᵀ b + r``, ``k = b/s``,
``w = b - s k/2`` (valid for any gain, so an error in ``k`` changes ``P⁺`` only to second order),
which is exactly symmetric. Rows of one epoch are processed in the model's output order; every row
after the range is linear, so for the EKF this equals the joint update linearised once at the
prior.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.model.vehicle import VehicleModel


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + Pᵀ)/2`` over the last two axes.

    Parameters
    ----------
    P : ndarray, shape (..., m, m)
        Covariances.

    Returns
    -------
    ndarray, shape (..., m, m)
        Their symmetric parts.
    """
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def nav_matrix(n: int, current: bool, m: int) -> np.ndarray:
    """``T`` with ``T x = (p, p')``: position and inertial velocity ``v (+ v_f)``, shape (2n, m).

    Both filters order their states ``(p, v[, v_f], ...)``, so the same map gives the navigation
    state of either; errors, standard deviations and NEES are reported on ``(p, p')``.

    Parameters
    ----------
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.
    m : int
        Number of states of the filter.

    Returns
    -------
    ndarray, shape (2n, m)
        The map to position [m] and inertial velocity [m/s].
    """
    T = np.zeros((2 * n, m))
    T[:, : 2 * n] = np.eye(2 * n)
    if current:
        T[n:, 2 * n : 3 * n] = np.eye(n)
    return T


def kinematic_A(n: int, current: bool, m: int) -> np.ndarray:
    """``A`` of ``p' = v [+ v_f]`` on the first ``2n [+ n]`` of ``m`` states.

    Parameters
    ----------
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.
    m : int
        Number of states.

    Returns
    -------
    ndarray, shape (m, m)
        The dynamics matrix (nilpotent, ``A² = 0``).
    """
    A = np.zeros((m, m))
    A[:n, n : 2 * n] = np.eye(n)
    if current:
        A[:n, 2 * n : 3 * n] = np.eye(n)
    return A


@dataclass(frozen=True, eq=False)
class Transition:
    """Sparse ``N`` of ``F = I + N``: ``N[row, col] = mult · T^power`` (kernel arrays)."""

    row: np.ndarray
    col: np.ndarray
    mult: np.ndarray
    power: np.ndarray

    @classmethod
    def build(cls, entries: list[tuple[int, int, float, int]]) -> Transition:
        """From ``(row, col, mult, power)`` entries; ``N`` must be strictly upper triangular
        (``row < col``: the kernels predict in place, row by row).

        Parameters
        ----------
        entries : list of (int, int, float, int)
            ``(row, col, mult, power)``: ``N[row, col] = mult · T^power``.

        Returns
        -------
        Transition
            The entries sorted, as kernel arrays.

        Raises
        ------
        ValueError
            If an entry is not strictly above the diagonal.
        """
        if any(r >= c for r, c, _, _ in entries):
            raise ValueError("N must be strictly upper triangular (row < col)")
        r, c, mu, pw = zip(*sorted(entries), strict=True)
        return cls(
            np.array(r, dtype=np.int64),
            np.array(c, dtype=np.int64),
            np.array(mu, dtype=float),
            np.array(pw, dtype=np.int64),
        )

    def packed(self) -> np.ndarray:
        """Rows ``(row, col, mult, power)`` as floats (the kernels' layout), shape (K, 4).

        Returns
        -------
        ndarray, shape (K, 4)
            One row per non-zero entry of ``N``, C-contiguous.
        """
        return np.ascontiguousarray(
            np.column_stack([self.row, self.col, self.mult, self.power]).astype(float)
        )

    def matrix(self, m: int, T: float) -> np.ndarray:
        """Dense ``F`` for a segment of length ``T`` (tests, documentation).

        Parameters
        ----------
        m : int
            Number of states.
        T : float
            Length of the segment [s].

        Returns
        -------
        ndarray, shape (m, m)
            ``F = I + N``.
        """
        F = np.eye(m)
        for r, c, mu, pw in zip(self.row, self.col, self.mult, self.power, strict=True):
            F[r, c] += mu * T**pw
        return F


def kinematic_entries(n: int, current: bool) -> list[tuple[int, int, float, int]]:
    """Entries of ``N = T A`` for ``p' = v [+ v_f]``.

    Parameters
    ----------
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.

    Returns
    -------
    list of (int, int, float, int)
        ``(row, col, 1.0, 1)`` entries for :meth:`Transition.build`.
    """
    out = [(i, n + i, 1.0, 1) for i in range(n)]
    if current:
        out += [(i, 2 * n + i, 1.0, 1) for i in range(n)]
    return out


def composed_noise_terms(q: np.ndarray, n: int, current: bool) -> np.ndarray:
    """``(q, A q + q Aᵀ, A q Aᵀ)`` for the kinematic block, so ``Q = S0 q0 + S1 q1 + S2 q2``.

    Shape (3, m, m).

    Parameters
    ----------
    q : ndarray, shape (m, m)
        Process-noise intensity or covariance on the filter's state.
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.

    Returns
    -------
    ndarray, shape (3, m, m)
        ``q0, q1, q2``, C-contiguous.
    """
    m = q.shape[0]
    A = kinematic_A(n, current, m)
    return np.ascontiguousarray(np.stack([q, A @ q + q @ A.T, A @ q @ A.T]).astype(float))


def nav_noise(q: np.ndarray, n: int, current: bool) -> np.ndarray:
    """Per-step noise of the navigation state ``(p, p')``: ``T q Tᵀ``, shape (2n, 2n).

    Parameters
    ----------
    q : ndarray, shape (m, m)
        Per-step process-noise covariance on the filter's state.
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.

    Returns
    -------
    ndarray, shape (2n, 2n)
        The covariance on position [m²] and inertial velocity [m²/s²].
    """
    T = nav_matrix(n, current, q.shape[0])
    return np.ascontiguousarray(T @ q @ T.T)


@dataclass(frozen=True, eq=False)
class LinearRows:
    """The linear output rows (DVL, depth) as kernel arrays; row 0 (the range) is unused.

    ``h_o(x) = off[o] + Σ_t x[idx[o, t]]`` for ``t < nnz[o]``, noise variance ``var[o]``.
    """

    idx: np.ndarray
    nnz: np.ndarray
    var: np.ndarray
    off: np.ndarray

    def packed(self) -> np.ndarray:
        """Rows ``(nnz, idx0, idx1, var, off)`` as floats (the kernels' layout), (p, 5).

        Returns
        -------
        ndarray, shape (p, 5)
            One row per output, C-contiguous.
        """
        return np.ascontiguousarray(
            np.column_stack([self.nnz, self.idx, self.var, self.off]).astype(float)
        )


def linear_rows(model: VehicleModel, noise: dict[str, float], depth_offset: float) -> LinearRows:
    """Rows of the DVL (``v``, or ``v + v_f`` in bottom-lock with current) and depth (``p_z``).

    ``depth_offset`` is added to the depth state's prediction (the beacon's ``z`` for the KF,
    whose positions are relative to the beacon).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (its sensors and output order).
    noise : dict of str to float
        Standard deviation per sensor (DVL [m/s], depth [m]).
    depth_offset : float
        Added to the predicted depth [m].

    Returns
    -------
    LinearRows
        The rows as kernel arrays.
    """
    n, p = model.dim, model.output_dim
    idx = np.zeros((p, 2), dtype=np.int64)
    nnz = np.zeros(p, dtype=np.int64)
    var = np.ones(p)
    off = np.zeros(p)
    for s, sl in model.output_slices.items():
        if s.startswith("dvl"):
            for i, o in enumerate(range(sl.start, sl.stop)):
                idx[o, 0] = n + i
                nnz[o] = 1
                if s == "dvl-bottom" and model.current:
                    idx[o, 1] = 2 * n + i
                    nnz[o] = 2
                var[o] = noise[s] ** 2
        elif s == "depth":
            idx[sl.start, 0] = 2
            nnz[sl.start] = 1
            var[sl.start] = noise[s] ** 2
            off[sl.start] = depth_offset
    return LinearRows(idx=idx, nnz=nnz, var=var, off=off)


def integrated_noise(w: np.ndarray, n: int, current: bool, h: float) -> np.ndarray:
    """``∫_0^h e^{As} W e^{Aᵀs} ds = h W + h²/2 (A W + W Aᵀ) + h³/3 A W Aᵀ`` (``A² = 0``).

    The exact covariance that white noise of intensity ``W`` (m × m, on ``(p, v[, v_f], ...)``)
    adds over ``h`` [s] to the kinematic states ``p' = v [+ v_f]``; further states (the KF's
    ``α, β``) have no dynamics.

    Parameters
    ----------
    w : ndarray, shape (m, m)
        Noise intensity ``W`` [m²/s³ on ``v``, ``v_f``].
    n : int
        Spatial dimension.
    current : bool
        Whether the state has the current block ``v_f``.
    h : float
        Span [s].

    Returns
    -------
    ndarray, shape (m, m)
        The covariance added over ``h``.
    """
    w = np.asarray(w, float)
    A = kinematic_A(n, current, w.shape[0])
    return h * w + 0.5 * h**2 * (A @ w + w @ A.T) + h**3 / 3.0 * (A @ w @ A.T)
