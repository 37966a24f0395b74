"""Exact (structural) rank of the held-input augmented Gramian, in rational arithmetic.

Why exact
---------
The verdicts of :mod:`obsplan.observability.gramian` are *conditioning* tests: the Gramian is
equilibrated and its eigenvalues compared with ``RANK_TOL`` (``scaling.py``). That answers "is
every direction excited enough to stand out of round-off", and its first full-rank time
``full_rank_from_t`` moves with the tolerance (Fig. 2 circle at 100 Hz: 20.1 s at 1e-12,
34.5 s at 1e-10, 58.0 s at 1e-8). The mathematical question "from when is G(t, t0) non-singular"
has a different, exact answer, computed here.

Definitions
-----------
*Held-input trajectory.* The inputs ``u[k]`` act on ``[t_k, t_{k+1})`` (the CSV convention). Its
Gramian (eq. 25) depends on the times and inputs only (``gramian.py``), and every float is a
dyadic rational, so ``G(t_k, t_0)`` has rational entries: no rounding anywhere below. (The float
Gramian of ``gramian.py`` takes ``d`` and ``e`` from the sampled positions and velocities; on a
consistent trajectory they are the inputs' to round-off, and the CSV reader warns when not.)

*Exact rank.* On the interval ``k`` every output row of ``C Φ`` (eqs. 21, 26, 41; depth) is a
polynomial ``r(σ) = Σ_i R_i σ^i`` of degree ≤ 3 in ``σ = t - t_k`` (``gramian.py``), and
``∫_0^h r rᵀ dσ = Σ_ij R_i R_jᵀ h^{i+j+1}/(i+j+1)`` whose middle matrix (a scaled Hilbert
matrix) is positive definite. Hence ``rank G(t_{k+1}, t_0)`` is the dimension of the span of all
coefficient vectors ``R_i`` of the intervals ``0..k``: computed over ℚ on integer vectors (each
float is ``m · 2^-s``), never with a tolerance.

*Exact structural interval* ``full_rank_interval_exact = k``: the first interval whose end makes
``G(t_{k+1}, t_0)`` non-singular; ``full_rank_from_t_exact = t_{k+1}`` [s]. An interval adds at most
4 directions per range output (2 per depth gauge, and DVL rows n at once), so exciting paths reach
full rank 3-4 intervals after excitation starts: ranks 3, 5, 6 (2D range), 5, 7, 8 (3D
range + depth), 6, 8, 10, 11 (3D current, water-profiling DVL). This is the *structural* profile,
attained for generic inputs; a lower exact rank means an exact relation between the inputs
(``u_y ≡ 0``, all ``u`` parallel, bottom-lock DVL with current, ...).

*Structure, not round-off.* An exact rank of the doubles as stored would answer a question
about round-off: a "straight" line along (0.8, -0.6) stores inputs that are parallel only to
1e-16, and a leg's last interval may carry ``u_y = -1.2e-15``; exact arithmetic on those numbers
counts the round-off as excitation (full rank 8 of 8 on a straight 3D line whose true rank is 6).
So the exact rank is that of the path's *structure*: before any exact arithmetic the held inputs
are classified with the stated relative tolerance :data:`STRUCTURE_RTOL` and replaced by exact
representatives of their class (:func:`structural_inputs`):

* *zero input*: ``|u_k| <= rtol · max_k |u_k|`` becomes exactly 0;
* *the input subspace*: when the inputs span fewer than ``n`` directions to ``rtol`` (a planar
  path in 3D, every input parallel to one line), each input is written exactly in an orthonormal
  basis of that subspace (basis vectors whose components below ``rtol`` are exact zeros, so an
  axis-aligned subspace stays exactly axis-aligned);
* *parallel inputs*: inputs whose directions agree to ``rtol`` (up to sign) share one exact
  direction, and magnitudes that agree to ``rtol · max |u|`` share one exact value (a constant
  acceleration stays exactly constant).

Every representative is a product of doubles, hence a dyadic rational: the exact arithmetic
below is unchanged. The tolerance is far above the round-off of stored or integrated inputs
(~1e-16 relative per number, ~1e-13 after a CSV round trip of integrated samples) and far below
any excitation that moves a vehicle: a 1e-9 relative component of a 0.05 m/s² input moves it
by 3e-4 m in an hour. ``structure_rtol=0`` gives the exact rank of the numbers as stored.

*Conditioning time* ``full_rank_from_t``: the first sample whose equilibrated Gramian has every
eigenvalue above ``RANK_TOL``. It is never earlier than the exact time, and it is the one the
verdicts use: the exact rank says whether the path's structure can make the Gramian
non-singular, the conditioning time when the excitation stands out of the noise floor. Both are
reported by ``obsplan analyze --json``.

Cost: integer (big-int) arithmetic on numpy object arrays, one pass over the intervals with an
early exit at full rank; a rank-deficient trajectory is certified by checking every coefficient
vector against integer kernel vectors of the current span (measured in
``benchmarks/bench_structural.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from math import gcd

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from obsplan.model.vehicle import VehicleModel
from obsplan.observability.gramian import AugmentedModel, augmented_model
from obsplan.observability.scaling import Scales, augmented_state_scale
from obsplan.trajectory.sampled import Trajectory

#: Intervals whose coefficient vectors are built at once (doubling from the first block).
_FIRST_BLOCK, _MAX_BLOCK = 16, 4096
#: Relative tolerance of the input classes (module docstring, *Structure, not round-off*).
STRUCTURE_RTOL = 1e-9


# ------------------------------------------------------------------ exact data
def _dyadic(x: np.ndarray) -> tuple[np.ndarray, int]:
    """Integers ``X`` (object array, shape of ``x``) and one ``s >= 0`` with ``x = X / 2**s``."""
    flat = np.asarray(x, float).ravel()
    ratios = [v.as_integer_ratio() for v in flat.tolist()]
    s = max((den.bit_length() - 1 for _, den in ratios), default=0)
    out = np.empty(flat.size, dtype=object)
    out[:] = [num << (s - den.bit_length() + 1) for num, den in ratios]
    return out.reshape(np.shape(x)), s


def _zeros(shape: tuple[int, ...]) -> np.ndarray:
    out = np.empty(shape, dtype=object)
    out.fill(0)
    return out


def _snap(x: np.ndarray, rtol: float) -> np.ndarray:
    """``x`` with the entries below ``rtol`` times its largest entry set to exactly 0."""
    x = np.array(x, float)
    x[np.abs(x) <= rtol * max(float(np.max(np.abs(x), initial=0.0)), 1e-300)] = 0.0
    return x


def _subspace(d: np.ndarray, rtol: float) -> np.ndarray:
    """Orthonormal basis ``(n, r)`` of the smallest subspace holding every unit row of ``d`` to
    ``rtol`` (its components below ``rtol`` exact zeros); the identity when ``r = n``."""
    n = d.shape[1]
    _, _, Vt = np.linalg.svd(d, full_matrices=False)
    for r in range(1, n):
        V = Vt[:r].T
        if np.max(np.linalg.norm(d - (d @ V) @ V.T, axis=1)) <= rtol:
            return np.column_stack([_snap(V[:, j], rtol) for j in range(r)])
    return np.eye(n)


def _directions(c: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster the rows of ``c`` (K, r), none zero, by direction up to sign.

    Returns ``(reps, label)``: unit representatives (J, r), components below ``rtol`` exact zeros,
    and the cluster of each row. Directions within ``rtol`` (Euclidean, either sign) of each other
    are linked and each connected group shares the direction of its first member (a k-d tree
    finds the links, so a generic path of 10⁵ distinct inputs costs milliseconds).
    """
    w = c / np.linalg.norm(c, axis=1, keepdims=True)
    uniq, first, inverse = np.unique(w, axis=0, return_index=True, return_inverse=True)
    J = len(uniq)
    pairs = cKDTree(np.vstack([uniq, -uniq])).query_pairs(rtol, output_type="ndarray") % J
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(J, J))
    _, comp = connected_components(graph, directed=False)
    # the representative of a group: its member that comes first along the path
    lead = np.full(comp.max() + 1, -1)
    for j in np.argsort(first, kind="stable"):
        if lead[comp[j]] < 0:
            lead[comp[j]] = j
    reps = uniq[lead]  # unit rows: their components below rtol are exact zeros
    reps[np.abs(reps) <= rtol] = 0.0
    return reps, comp[inverse.ravel()]


def _magnitudes(a: np.ndarray, label: np.ndarray, atol: float) -> np.ndarray:
    """``a`` with the values of one label that chain within ``atol`` of each other replaced by
    the smallest of their chain."""
    order = np.lexsort((a, label))
    s, lab = a[order], label[order]
    start = np.concatenate([[True], (np.diff(s) > atol) | (np.diff(lab) != 0)])
    group_first = s[np.flatnonzero(start)][np.cumsum(start) - 1]
    out = np.empty_like(a)
    out[order] = group_first
    return out


def structural_inputs(u: np.ndarray, rtol: float = STRUCTURE_RTOL) -> tuple[np.ndarray, int]:
    """The held inputs as exact representatives of their structure (module docstring).

    Parameters
    ----------
    u : ndarray, shape (K, n)
        Inputs [m/s²] (any unit: the classes are relative).
    rtol : float, optional
        Relative tolerance of the classes; 0 keeps the numbers as stored.

    Returns
    -------
    U : ndarray of object, shape (K, n)
        Python integers with ``u_structural = U / 2**s``.
    s : int
        The common binary exponent, ``>= 0``.
    """
    u = np.asarray(u, float)
    norms = np.linalg.norm(u, axis=1) if u.size else np.zeros(len(u))
    umax = float(norms.max(initial=0.0))
    if rtol <= 0 or umax == 0.0:
        return _dyadic(u)
    active = norms > rtol * umax
    B = _subspace(u[active] / norms[active, None], rtol)
    c = u[active] @ np.linalg.pinv(B).T  # coordinates in the subspace (floats)
    reps, label = _directions(c, rtol)
    a = np.einsum("kr,kr->k", c, reps[label])  # signed magnitudes along the representatives
    if np.max(np.linalg.norm(c - a[:, None] * reps[label], axis=1) / norms[active]) > 4 * rtol:
        # a chain of links drifted beyond the tolerance (inputs turning by < rtol per interval
        # over a wide angle): such inputs are not parallel, keep them as stored
        return _dyadic(u)
    a = _magnitudes(a, label, rtol * umax)
    Ri, sR = _dyadic(reps)
    Ai, sA = _dyadic(a)
    if B.shape[1] < B.shape[0]:  # exact: products and sums of integers
        Bi, sB = _dyadic(B)
        Ri, sR = np.dot(Ri, Bi.T), sR + sB
    U = _zeros(u.shape)
    U[active] = Ai[:, None] * Ri[label]
    return U, sR + sA


@dataclass(frozen=True)
class _Exact:
    """Times, inputs and the integration quantities of a held-input trajectory, as integers.

    ``tau = Tau / 2^A`` (``t_k - t_0``), ``h = H / 2^A``, ``u = U / 2^B``,
    ``e = E / 2^(A+B)`` (``ν_k - ν_0``), ``d = D / 2^(2A+B+1)`` (eq. 15): all per interval.
    """

    Tau: np.ndarray  # (K,)
    H: np.ndarray  # (K,)
    U: np.ndarray  # (K, n)
    E: np.ndarray  # (K, n)
    D: np.ndarray  # (K, n)
    A: int
    B: int

    @classmethod
    def of(cls, traj: Trajectory, rtol: float = 0.0) -> _Exact:
        """Exact data of ``traj``; ``rtol > 0`` replaces the inputs by their structure."""
        T, A = _dyadic(traj.t)
        U, B = structural_inputs(traj.u[:-1], rtol)  # the last row drives nothing (CSV convention)
        H = T[1:] - T[:-1]
        UH = U * H[:, None]
        E = _zeros(U.shape)
        D = _zeros(U.shape)
        if len(H) > 1:
            E[1:] = np.cumsum(UH[:-1], axis=0)
            D[1:] = np.cumsum(2 * E[:-1] * H[:-1, None] + UH[:-1] * H[:-1, None], axis=0)
        return cls(Tau=T[:-1] - T[0], H=H, U=U, E=E, D=D, A=A, B=B)


# ------------------------------------------------------------------ coefficient vectors
def _coefficients(aug: AugmentedModel, ex: _Exact, k0: int, k1: int) -> list[list]:
    """Integer coefficient vectors of the rows of ``C Φ`` on intervals ``k0..k1-1``.

    Returns one list per output row type: ``[(R̂_i, M_i), ...]`` with ``R̂_i`` of shape
    ``(k1 - k0, m)`` and ``R_i = R̂_i / 2^M_i`` the coefficient of ``σ^i`` (see ``gramian.py``,
    ``AugmentedModel._row_coeffs``, whose rows these are, in exact arithmetic).
    """
    n, m, A, B = aug.dim, aug.state_dim, ex.A, ex.B
    nv = 2 if aug.current else 1  # velocity-like blocks that see τ dᵀ (v, and v_f)
    Tau = ex.Tau[k0:k1, None]
    U, E, D = ex.U[k0:k1], ex.E[k0:k1], ex.D[k0:k1]
    K = k1 - k0

    def rows(pos, vel, alpha, beta) -> np.ndarray:
        out = _zeros((K, m))
        out[:, :n] = pos
        for b in range(nv):
            out[:, n * (b + 1) : n * (b + 2)] = vel
        out[:, m - 2] = alpha
        out[:, m - 1] = beta
        return out

    tau = Tau[:, 0]
    zero = _zeros((K, n))
    # range (eq. 21 times Φ = I + Aτ, eq. 26): r(σ) = (d, τd, [τd], τ, τ²/2), d = d_k + e σ + u σ²/2
    a0, a1 = 2 * A + B + 1, A + B + 1  # exponents of d and of e + τu/2
    out = [
        [
            (rows(D << A, Tau * D, tau << a0, (tau * tau) << (A + B)), A + a0),
            (rows(E << (A + 1), D + 2 * Tau * E, 1 << a0, tau << a1), a0),
            (rows(U << A, 2 * E + Tau * U, 0, 1 << (A + B)), a1),
            (rows(zero, U, 0, 0), B + 1),
        ]
    ]
    if any(s.startswith("dvl") for s in aug.sensors):
        # eq. 41 (water profiling, or no current) / eq. 48 (bottom lock with current): constant
        for i in range(n):
            r = _zeros((K, m))
            r[:, n + i] = 1
            if aug.current and "dvl-bottom" in aug.sensors:
                r[:, 2 * n + i] = 1
            out.append([(r, 0)])
    if "depth" in aug.sensors:
        ez = _zeros((K, n))
        ez[:, n - 1] = 1
        out.append([(rows(ez * (1 << A), ez * Tau, 0, 0), A), (rows(zero, ez, 0, 0), 0)])
    return out


# ------------------------------------------------------------------ exact linear algebra
def _rref(M: Sequence[Sequence[Fraction | int]]) -> tuple[list[list[Fraction]], list[int]]:
    """Reduced row echelon form over ℚ and the pivot columns."""
    R = [list(map(Fraction, row)) for row in M]
    rows, cols = len(R), (len(R[0]) if R else 0)
    pivots: list[int] = []
    r = 0
    for c in range(cols):
        p = next((i for i in range(r, rows) if R[i][c] != 0), None)
        if p is None:
            continue
        R[r], R[p] = R[p], R[r]
        inv = 1 / R[r][c]
        R[r] = [x * inv for x in R[r]]
        for i in range(rows):
            if i != r and R[i][c] != 0:
                f = R[i][c]
                R[i] = [a - f * b for a, b in zip(R[i], R[r], strict=True)]
        pivots.append(c)
        r += 1
        if r == rows:
            break
    return R[:r], pivots


def exact_rank(M: np.ndarray | list) -> int:
    """Rank over ℚ of a matrix of integers or :class:`~fractions.Fraction` (no tolerance).

    Parameters
    ----------
    M : ndarray of object or list of lists, shape (rows, cols)
        The matrix; entries are integers or fractions.

    Returns
    -------
    int
        Its exact rank (0 for a matrix without rows).
    """
    rows = [list(r) for r in np.asarray(M, dtype=object)]
    return len(_rref(rows)[1]) if rows else 0


def _primitive(v: list[Fraction]) -> list[int]:
    """The integer multiple of ``v`` with coprime entries (small when the relation is simple)."""
    den = 1
    for q in v:
        den = den * q.denominator // gcd(den, q.denominator)
    ints = [int(q * den) for q in v]
    g = 0
    for k in ints:
        g = gcd(g, k)
    return [k // g for k in ints] if g else ints


def _kernel(basis: list[list[int]], m: int) -> np.ndarray:
    """Integer vectors ``w`` spanning ``{w : b·w = 0 for every b in basis}``, shape (m - r, m)."""
    if not basis:
        W = _zeros((m, m))
        for i in range(m):
            W[i, i] = 1
        return W
    R, piv = _rref(basis)
    free = [c for c in range(m) if c not in piv]
    W = _zeros((len(free), m))
    for j, f in enumerate(free):
        w = [Fraction(0)] * m
        w[f] = Fraction(1)
        for row, pc in zip(R, piv, strict=True):
            w[pc] = -row[f]
        W[j] = _primitive(w)
    return W


# ------------------------------------------------------------------ rank profile
@dataclass(frozen=True)
class ExactRankProfile:
    """Exact rank of the held-input Gramian ``G(t_{k+1}, t_0)`` interval by interval.

    Attributes
    ----------
    dim : int
        State dimension ``m`` of the augmented model.
    rank : int
        Exact rank of the Gramian of the whole trajectory.
    full_rank_interval : int or None
        First interval ``k`` (0-based, ``[t_k, t_{k+1})``) after which the Gramian is exactly
        non-singular; None if it never is.
    full_rank_from_t : float or None
        ``t_{k+1}`` [s] for that interval; None if never.
    increases : tuple of (int, int)
        ``(k, rank)`` at every interval where the exact rank grows: e.g. ``((0, 3), (1, 5),
        (2, 6))`` for a 2D circle, range only.
    """

    dim: int
    rank: int
    full_rank_interval: int | None
    full_rank_from_t: float | None
    increases: tuple[tuple[int, int], ...]

    def ranks(self, n_intervals: int) -> tuple[int, ...]:
        """Exact rank after each of the first ``n_intervals`` intervals.

        Parameters
        ----------
        n_intervals : int
            Number of intervals.

        Returns
        -------
        tuple of int
            The rank of ``G(t_{k+1}, t_0)`` for ``k = 0 .. n_intervals - 1`` (after a full-rank
            interval the profile stays at full rank).
        """
        out, r, it = [], 0, iter(self.increases)
        nxt = next(it, None)
        for k in range(n_intervals):
            while nxt is not None and nxt[0] <= k:
                r = nxt[1]
                nxt = next(it, None)
            out.append(r)
        return tuple(out)

    def to_dict(self) -> dict:
        """The exact keys merged into the ``gramian`` dict of ``obsplan analyze --json``.

        Returns
        -------
        dict
            ``rank_exact``, ``full_rank_interval_exact`` and ``full_rank_from_t_exact`` [s].
        """
        return {
            "rank_exact": int(self.rank),
            "full_rank_interval_exact": self.full_rank_interval,
            "full_rank_from_t_exact": self.full_rank_from_t,
        }


def exact_rank_profile(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    structure_rtol: float = STRUCTURE_RTOL,
) -> ExactRankProfile:
    """Exact rank of the held-input augmented Gramian of the path's structure, interval by
    interval.

    Parameters
    ----------
    traj : Trajectory
        Trajectory; only its times ``t`` [s] and inputs ``u`` [m/s²] (held on each interval)
        enter.
    model : VehicleModel or AugmentedModel
        Vehicle model (sensors, current) or its augmented model.
    structure_rtol : float, optional
        Relative tolerance of the input classes (:func:`structural_inputs`); 0 computes the
        exact rank of the inputs as stored (round-off included).

    Returns
    -------
    ExactRankProfile
        Stops at the first exactly full-rank interval (later ones cannot lower the rank: the
        Gramian only grows); a deficient trajectory is checked to its last interval.

    Raises
    ------
    ValueError
        If the model and the trajectory differ in dimension.
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    if aug.dim != traj.dim:
        raise ValueError(f"model is {aug.dim}D but the trajectory is {traj.dim}D")
    ex, m = _Exact.of(traj, structure_rtol), aug.state_dim
    K = len(ex.H)
    basis: list[list[int]] = []
    W = _kernel(basis, m)
    increases: list[tuple[int, int]] = []
    k0, block = 0, _FIRST_BLOCK
    while k0 < K and len(basis) < m:
        k1 = min(K, k0 + block)
        # all coefficient vectors of the block, in interval order (interval index in `owner`)
        vecs = [R for row in _coefficients(aug, ex, k0, k1) for R, _ in row]
        V = np.stack(vecs, axis=1).reshape(-1, m)
        owner = np.repeat(np.arange(k0, k1), len(vecs))
        j = 0
        while j < len(V) and len(basis) < m:
            hit = np.flatnonzero((np.dot(V[j:], W.T) != 0).any(axis=1))
            if hit.size == 0:
                break
            j += int(hit[0])
            basis.append([int(x) for x in V[j]])
            W = _kernel(basis, m)
            if increases and increases[-1][0] == owner[j]:
                increases.pop()  # one entry per interval: the rank after it
            increases.append((int(owner[j]), len(basis)))
            j += 1
        k0, block = k1, min(2 * block, _MAX_BLOCK)
    full = len(basis) == m
    k_full = increases[-1][0] if full else None
    return ExactRankProfile(
        dim=m,
        rank=len(basis),
        full_rank_interval=k_full,
        full_rank_from_t=None if k_full is None else float(traj.t[k_full + 1]),
        increases=tuple(increases),
    )


# ------------------------------------------------------------------ exact Gramian
def _output_weights(aug: AugmentedModel, scales: Scales | None) -> list[Fraction]:
    """Squared output scaling of each row type of :func:`_coefficients` (1 in SI units)."""
    n_types = 1 + (aug.dim if any(s.startswith("dvl") for s in aug.sensors) else 0)
    n_types += 1 if "depth" in aug.sensors else 0
    if scales is None:
        return [Fraction(1)] * n_types
    L, T = Fraction(scales.length_m), Fraction(scales.time_s)
    w = [1 / L**4]  # ȳ / L² (eq. 19)
    w += [T**2 / L**2] * (n_types - 1 - (1 if "depth" in aug.sensors else 0))  # DVL v T / L
    if "depth" in aug.sensors:
        w.append(1 / L**2)  # p_z / L
    return w


def _state_scale(aug: AugmentedModel, scales: Scales | None) -> list[Fraction]:
    """``z_nd / z`` per state (``scaling.py``): p/L, v T/L, [v_f T/L], α T/L², β T²/L²."""
    if scales is None:
        return [Fraction(1)] * aug.state_dim
    L, T = Fraction(scales.length_m), Fraction(scales.time_s)
    return augmented_state_scale(aug.state_dim, aug.dim, L, T)


def exact_gramian(
    traj: Trajectory,
    model: VehicleModel | AugmentedModel,
    scales: Scales | None = None,
) -> list[list[Fraction]]:
    """The held-input Gramian ``G(t_N, t_0)`` (eq. 25) as exact rationals, ``m × m``.

    ``scales=None``: SI units (as ``gramian(traj, model, scales=None)``); with ``scales`` the
    nondimensionalised Gramian of :func:`~obsplan.observability.gramian.gramian`, exactly
    (times ``t/T``, states and outputs as in ``scaling.py``).

    Parameters
    ----------
    traj : Trajectory
        Trajectory; only its times [s] and held inputs [m/s²] enter (as stored, no structure
        classes).
    model : VehicleModel or AugmentedModel
        Vehicle model (sensors, current) or its augmented model.
    scales : Scales or None, optional
        Nondimensionalisation; None: SI units.

    Returns
    -------
    list of list of Fraction
        The ``m × m`` Gramian, symmetric positive semi-definite.

    Raises
    ------
    ValueError
        If the model and the trajectory differ in dimension.
    """
    aug = model if isinstance(model, AugmentedModel) else augmented_model(model)
    if aug.dim != traj.dim:
        raise ValueError(f"model is {aug.dim}D but the trajectory is {traj.dim}D")
    ex, m = _Exact.of(traj), aug.state_dim
    K, A = len(ex.H), ex.A
    Hp = [np.array([1] * K, dtype=object)]
    for _ in range(7):
        Hp.append(Hp[-1] * ex.H)
    G = [[Fraction(0)] * m for _ in range(m)]
    for weight, row in zip(_output_weights(aug, scales), _coefficients(aug, ex, 0, K), strict=True):
        for i, (Ri, Mi) in enumerate(row):
            for j, (Rj, Mj) in enumerate(row):
                S = np.dot((Ri * Hp[i + j + 1][:, None]).T, Rj)  # Σ_k h^{i+j+1} R_i R_jᵀ
                den = (i + j + 1) * (1 << (Mi + Mj + A * (i + j + 1)))
                for a in range(m):
                    for b in range(m):
                        if S[a, b]:
                            G[a][b] += weight * Fraction(int(S[a, b]), den)
    if scales is not None:
        s = _state_scale(aug, scales)
        T = Fraction(scales.time_s)
        # z = z_nd / s, dτ = T dτ_nd: G_nd = S⁻¹ G S⁻¹ / T (weights above scale the outputs)
        G = [[G[a][b] / (s[a] * s[b] * T) for b in range(m)] for a in range(m)]
    return G


def _negative_eigenvalues(M: list[list[int]]) -> int | None:
    """Number of negative eigenvalues of a symmetric integer matrix: sign changes of its leading
    principal minors (Jacobi / Sylvester's law of inertia), computed fraction-free (Bareiss);
    None if a minor is exactly zero (then shift and retry)."""
    A = [row[:] for row in M]
    m, prev, sign, changes = len(A), 1, 1, 0
    for k in range(m):
        pivot = A[k][k]  # the leading principal minor of order k + 1
        if pivot == 0:
            return None
        s = 1 if pivot > 0 else -1
        changes += s != sign
        sign = s
        for i in range(k + 1, m):
            for j in range(k + 1, m):
                A[i][j] = (A[i][j] * pivot - A[i][k] * A[k][j]) // prev
        prev = pivot
    return changes


def exact_min_eigenvalue(
    G: list[list[Fraction]], equilibrate: bool = False, rtol: float = 1e-4
) -> tuple[Fraction, Fraction]:
    """Enclosure ``(lo, hi)`` of the smallest eigenvalue of a symmetric PSD rational matrix.

    With ``equilibrate`` the eigenvalue is that of ``D G D``, ``D = diag(G)^-1/2`` (the matrix
    of the rank test, ``scaling.py``), i.e. the smallest root of ``det(G - λ diag G)``: still
    rational arithmetic. Bisection on the exact inertia of ``G - λ B``, ``hi / lo <= 1 + rtol``.
    ``(0, 0)`` if ``G`` is exactly singular.

    Parameters
    ----------
    G : list of list of Fraction
        Symmetric positive semi-definite matrix, ``m × m`` (e.g. :func:`exact_gramian`).
    equilibrate : bool, optional
        Enclose the smallest eigenvalue of ``D G D`` instead of ``G``.
    rtol : float, optional
        Relative width of the enclosure.

    Returns
    -------
    lo, hi : Fraction
        Bounds of the smallest eigenvalue, ``lo <= λ_min <= hi``.
    """
    m = len(G)
    if exact_rank(G) < m:
        return Fraction(0), Fraction(0)
    B = [Fraction(G[i][i]) if equilibrate else Fraction(1) for i in range(m)]
    den = 1
    for x in [*(Fraction(v) for row in G for v in row), *B]:
        den = den * x.denominator // gcd(den, x.denominator)
    Gi = [[int(Fraction(v) * den) for v in row] for row in G]
    Bi = [int(b * den) for b in B]

    def below(lam: Fraction) -> bool:  # is some eigenvalue < lam ?
        while True:
            a, b = lam.numerator, lam.denominator  # G - λB, times b·den: integers
            M = [[b * Gi[i][j] - (a * Bi[i] if i == j else 0) for j in range(m)] for i in range(m)]
            neg = _negative_eigenvalues(M)
            if neg is not None:
                return neg > 0
            lam *= 1 + Fraction(1, 1 << 40)  # an exact zero minor: shift λ imperceptibly

    trace = sum((Fraction(G[i][i]) / B[i] for i in range(m)), Fraction(0))  # >= λ_max >= λ_min
    hi = Fraction(2) ** (trace.numerator.bit_length() - trace.denominator.bit_length() + 1)
    lo = hi / 2
    while below(lo):
        hi, lo = lo, lo / 2
    while hi > lo * (1 + Fraction(rtol)):
        mid = (lo + hi) / 2  # dyadic, like lo and hi: small denominators
        if below(mid):
            hi = mid
        else:
            lo = mid
    return lo, hi
