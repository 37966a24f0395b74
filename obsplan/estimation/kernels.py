"""Compiled kernels (numba) of the truth, the filters and the per-run statistics.

One call filters a batch of runs (``simulate.BATCH``) from the first epoch to the last, so a
Monte Carlo is a short Python loop over batches (Ctrl-C is honoured between them). State arrays
carry the batch's members on their last axis (``X`` (m, B), ``P`` (m, m, B)), so the innermost
loops run over contiguous members and vectorise; the members are runs, or for the Gaussian sum
the components of the runs. The equations are those of :mod:`obsplan.estimation.kalman`,
:mod:`~obsplan.estimation.filters.ekf` and :mod:`~obsplan.estimation.filters.kf`, written out in
loops:

* prediction over a segment: ``x⁺ = F x + g``, ``P⁺ = F P Fᵀ + Q`` with ``F = I + N`` and ``N``
  strictly upper triangular, given as rows ``(row, col, mult, power)``: ``N[row, col] = mult ·
  T^power``;
* update: one scalar Joseph update per output row with a sparse measurement row
  (``P - (k wᵀ + w kᵀ)``, ``w = b - s k/2``, ``b = P h``, ``s = hᵀ b + r``), exactly symmetric;
  a member without that reading gets a zero gain and is left exactly as it was;
* statistics on the navigation state ``(p, p')`` at the records (per run: the mixture of its
  members), written to a per-run buffer that is added to the sums of the run's group (flagged
  by the divergence monitor or not).

Small helpers take few array arguments (work buffers are packed into one array per purpose):
in numba each array argument of an inlined call costs ~10 ns of reference counting, more than a
4-state update. The helpers called once per epoch or record for a whole batch (``predict``,
``ekf_measure``, ``record_batch``) are compiled functions of their own, shared by the EKF, the
KF and the closed loop (:mod:`obsplan.estimation.montecarlo.loop_kernels`) instead of inlined
copies. The batch kernels (``ekf_batch``, ``kf_batch``) and the per-epoch steps of the filters'
epoch by epoch interface (``ekf_predict``, ``kf_predict``, ``kf_measure``) take their model,
records, outputs and corrections as keyword-named bundles
(:mod:`obsplan.estimation.filters.bundles`), unpacked once per call.
Compiled on first use and cached on disk (``cache=True``, in the per-user folder of
:mod:`obsplan.estimation.jitcache` unless ``NUMBA_CACHE_DIR`` is set); this module is
imported lazily, so ``import obsplan`` does not load numba.

Packed layouts
--------------
* segment / record tables (rows), float: ``T, S0, S1, S2, τ_a, dp (n), dv (n)``
  (:data:`TAB_T` ...), then for records the true ``(p, p')`` (2n);
* ``ws`` (5, ·, B): ``b, k, w, val`` (per state, per member), then per member the scalars
  ``ν, r, ok, s, gain, Σ NIS, count, Σ log-likelihood``, the weight ``β`` of the next update
  (1 but for a range the late-arrival model doubts, :func:`late_weight`) and its
  log-likelihood's correction, the extent of a late arrival in the row's units, then the
  transition's coefficients;
* ``nw`` (5 + 6n, 2n): rows ``mean, e, y, off, corr`` then ``C`` (2n rows), ``L`` (2n),
  ``q_nav`` (2n);
* input corrections (closed loop, :mod:`obsplan.estimation.montecarlo.closedloop`): ``ce`` (E, 2n,
  R) and ``cr`` (Nr, 2n, R), the response ``c = (p, v)`` of run ``r`` to its input corrections at
  the epochs and records; a filter that predicts with the plan's inputs adds ``c_b - F c_a`` over a
  segment (empty arrays: open loop, no correction);
* linear output rows ``lin`` (outputs, 5): ``nnz, idx0, idx1, var, off``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from obsplan.estimation import jitcache
from obsplan.estimation.channel import LATE_MAX_M, LATE_PRIOR, REACQUIRE_AFTER
from obsplan.estimation.columns import (
    COL_AXES,
    COL_NEES,
    COL_SE_VEL,
    COL_VAR_VEL,
    INFO_FINAL_POS,
    INFO_FINAL_STD,
    INFO_FINAL_VEL,
    INFO_FLAG_TIME,
    INFO_FLAGGED,
    INFO_LAST_ABOVE,
    INFO_NIS,
    INFO_NONFINITE,
    INFO_RANGES_USED,
    INFO_RMSE_LINES,
    INFO_RMSE_POS,
    N_GATE,
    TM_AREA_OUT,
    TM_CLOSEST,
    TM_DEPTH_OUT,
    TM_FARTHEST,
    TM_PREV,
    TM_SAMPLES,
    TM_SPEED_MAX,
    TM_TRACK_LAST,
    TM_TRACK_SS,
)

# the cache folder is chosen when a function is decorated: before the first decorator
jitcache.configure()
jit = nb.njit(cache=True, nogil=True)
inline = nb.njit(cache=True, nogil=True, inline="always")

TAB_T, TAB_S0, TAB_S1, TAB_S2, TAB_TAU, TAB_G = 0, 1, 2, 3, 4, 5
WS_B, WS_K, WS_W, WS_VAL, WS_SC = 0, 1, 2, 3, 4
SC_NU, SC_R, SC_OK, SC_S, SC_G, SC_NIS, SC_CNT, SC_LL = 0, 1, 2, 3, 4, 5, 6, 7
SC_BETA, SC_LLR, SC_LATE, SC_COEF = 8, 9, 10, 11
NW_MEAN, NW_E, NW_Y, NW_OFF, NW_CORR, NW_C = 0, 1, 2, 3, 4, 5


# ----------------------------------------------------------------------------- truth
@inline
def span_metrics(tm, j, xb, K, n, beacon, box, has_box, k0):
    """Add ``K`` consecutive samples of true path ``j`` to its metrics ``tm[j]`` (``stats.TM_*``).

    ``xb`` (≥ K, 3n) rows: true position ``p``, true inertial velocity ``p'``, reference
    position. Ranges, speed and tracking error are kept squared (their roots are taken once, by
    :meth:`~obsplan.estimation.montecarlo.stats.TruthStats.from_metrics`); the closest range is
    refined to the chord between consecutive samples, also across spans (``tm[j, TM_PREV:]`` holds
    the last ``p - b``). ``box`` (3, 2): the area (rows x, y) and depth band (row z) bounds, checked
    when ``has_box``. Accumulators are scalars: this runs at every sample of every run.

    Parameters
    ----------
    tm : ndarray, shape (J, N_TM)
        The paths' metrics (``TM_*`` of :mod:`obsplan.estimation.columns`), updated in place.
    j : int
        The path (or run) whose row is updated.
    xb : ndarray, shape (>= K, 3n)
        The samples, rows as above [m, m/s].
    K : int
        Number of samples of ``xb`` to add.
    n : int
        Spatial dimension.
    beacon : ndarray, shape (Nb, n)
        Beacon position [m] at every sample of the path (``Nb = N``, a moving beacon) or one
        row (a fixed beacon).
    box : ndarray, shape (3, 2)
        Area and depth bounds [m] (:meth:`TruthLimits.box
        <obsplan.estimation.montecarlo.guidance.TruthLimits.box>`).
    has_box : bool
        Whether any bound of ``box`` is finite (:func:`bounded`).
    k0 : int
        The path's sample of ``xb[0]`` (the row of a moving beacon).
    """
    moving = beacon.shape[0] > 1
    close, far = tm[j, TM_CLOSEST], tm[j, TM_FARTHEST]
    ss, vmax = tm[j, TM_TRACK_SS], tm[j, TM_SPEED_MAX]
    area, depth = tm[j, TM_AREA_OUT], tm[j, TM_DEPTH_OUT]
    e2 = tm[j, TM_TRACK_LAST]
    first = tm[j, TM_SAMPLES] == 0.0
    for k in range(K):
        r2 = 0.0
        aa = 0.0
        ab = 0.0
        dd = 0.0
        v2 = 0.0
        e2 = 0.0
        kb = k0 + k if moving else 0
        kp = kb - 1 if moving else 0
        for i in range(n):
            rel = xb[k, i] - beacon[kb, i]
            a = xb[k - 1, i] - beacon[kp, i] if k > 0 else tm[j, TM_PREV + i]
            s = rel - a
            r2 += rel * rel
            aa += a * a
            ab += a * s
            dd += s * s
            v2 += xb[k, n + i] * xb[k, n + i]
            e = xb[k, i] - xb[k, 2 * n + i]
            e2 += e * e
        if ab < 0.0 and ab + dd > 0.0 and not (first and k == 0):  # closest point inside
            close = min(close, max(aa - ab * ab / dd, 0.0))
        close = min(close, r2)
        far = max(far, r2)
        vmax = max(vmax, v2)
        ss += e2
        if has_box:
            for i in range(min(n, 2)):
                area = max(area, box[i, 0] - xb[k, i], xb[k, i] - box[i, 1])
            if n == 3:
                depth = max(depth, box[2, 0] - xb[k, 2], xb[k, 2] - box[2, 1])
    tm[j, TM_CLOSEST], tm[j, TM_FARTHEST] = close, far
    tm[j, TM_TRACK_SS], tm[j, TM_SPEED_MAX] = ss, vmax
    tm[j, TM_AREA_OUT], tm[j, TM_DEPTH_OUT] = area, depth
    tm[j, TM_TRACK_LAST] = e2
    tm[j, TM_SAMPLES] += K
    if K > 0:
        kb = k0 + K - 1 if moving else 0
        for i in range(n):
            tm[j, TM_PREV + i] = xb[K - 1, i] - beacon[kb, i]


@inline
def bounded(box):
    """Whether any bound of ``box`` (3, 2) is finite.

    Parameters
    ----------
    box : ndarray, shape (3, 2)
        Area and depth bounds [m], ±inf where unlimited.

    Returns
    -------
    bool
        True if some bound is finite.
    """
    for i in range(3):
        if box[i, 0] > -math.inf or box[i, 1] < math.inf:
            return True
    return False


#: Samples per span of :func:`span_metrics` in the open loop (a buffer that stays in cache).
SPAN = 1024


@jit
def truth_deviation(z, L, h, expo, n, cur, points, out, noms, beacon, box, tm):
    """``δ_{k+1} = (I + h_k A) δ_k + diag(h_k^expo) L z_k`` over all steps; ``out[i] = δ`` at
    ``points[i]`` (``expo = 0``: a per-step ``L``). With paths ``noms`` (J, N, 2n) (their
    nominal ``(p, p')``), the true path ``nom + δ`` of each is added to the metrics ``tm[j]``
    (:func:`span_metrics`, reference the nominal itself) at every sample, span by span.

    Parameters
    ----------
    z : ndarray, shape (N - 1, r)
        Standard normals, row ``k`` driving step ``k``.
    L : ndarray, shape (m, r)
        Noise factor of a step (:func:`~obsplan.estimation.montecarlo.truth.truth_factor`).
    h : ndarray, shape (N - 1,)
        Steps [s].
    expo : ndarray, shape (m,)
        Exponents of the step in the factor, ``diag(h_k^expo) L``.
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    points : ndarray of int, shape (P,)
        Samples where ``δ`` is kept, sorted.
    out : ndarray, shape (P, m)
        Receives ``δ`` at ``points`` (zero-initialised by the caller).
    noms : ndarray, shape (J, N, 2n)
        Nominal ``(p, p')`` of each path [m, m/s] (``J`` may be 0).
    beacon : ndarray, shape (N, n) or (1, n)
        Beacon position [m] at every sample (a moving beacon) or one row (a fixed beacon).
    box : ndarray, shape (3, 2)
        Area and depth bounds [m].
    tm : ndarray, shape (J, N_TM)
        The paths' metrics, updated in place.
    """
    m, r = L.shape
    J = noms.shape[0]
    N = z.shape[0] + 1
    d = np.zeros(m)
    sc = np.ones(m)
    has_box = bounded(box)
    dspan = np.zeros((SPAN, m))
    xb = np.zeros((SPAN, 3 * n))
    scaled = False
    for i in range(m):
        scaled = scaled or expo[i] != 0.0
    h_prev = -1.0
    P = points.shape[0]
    pi = 0
    while pi < P and points[pi] == 0:
        pi += 1  # δ_0 = 0 (out is zero-initialised)
    for k0 in range(0, N, SPAN):
        K = min(SPAN, N - k0)
        for kk in range(K):
            k = k0 + kk
            if k > 0:
                hk = h[k - 1]
                if scaled and hk != h_prev:  # uniform grids: one power per run
                    h_prev = hk
                    for i in range(m):
                        sc[i] = hk ** expo[i]
                for i in range(n):
                    vel = d[n + i]
                    if cur:
                        vel += d[2 * n + i]
                    d[i] += hk * vel
                for i in range(m):
                    acc = 0.0
                    for j in range(r):
                        acc += L[i, j] * z[k - 1, j]
                    d[i] += sc[i] * acc
                while pi < P and points[pi] == k:
                    for i in range(m):
                        out[pi, i] = d[i]
                    pi += 1
            for i in range(m):
                dspan[kk, i] = d[i]
        for jp in range(J):
            for kk in range(K):
                k = k0 + kk
                for i in range(n):
                    xb[kk, i] = noms[jp, k, i] + dspan[kk, i]
                    nu = noms[jp, k, n + i] + dspan[kk, n + i]
                    xb[kk, n + i] = nu + (dspan[kk, 2 * n + i] if cur else 0.0)
                    xb[kk, 2 * n + i] = noms[jp, k, i]
            span_metrics(tm, jp, xb, K, n, beacon, box, has_box, k0)


# ----------------------------------------------------------------------------- Kalman steps
# Batched over the members of a batch (runs, or the components of the runs' Gaussian sums),
# the last axis of every state array, so the innermost loops run over contiguous members.


@inline
def noise_terms(Q, qt, S0, S1, S2, mq):
    """``Q = S0 q0 + S1 q1 + S2 q2`` on the first ``mq`` states, for every member.

    Parameters
    ----------
    Q : ndarray, shape (m, m, B)
        Receives the composed noise (its first ``mq`` rows and columns).
    qt : ndarray, shape (3, mq, mq)
        The terms ``q0, q1, q2`` (:func:`~obsplan.estimation.kalman.composed_noise_terms`).
    S0, S1, S2 : float
        The segment's noise sums (:mod:`obsplan.estimation.epochs`).
    mq : int
        Number of kinematic states.
    """
    B = Q.shape[2]
    for i in range(mq):
        for j in range(mq):
            v = S0 * qt[0, i, j] + S1 * qt[1, i, j] + S2 * qt[2, i, j]
            for b in range(B):
                Q[i, j, b] = v


@jit
def predict(X, P, tab, e, n, tr, Q, ws):
    """``x ← (I + N) x + g``, ``P ← (I + N) P (I + N)ᵀ + Q`` in place, every member.

    ``N`` is strictly upper triangular with its entries sorted by row, so the row operations
    ``P[r] += c P[s]`` (then the same on columns) read rows not yet modified: no temporaries.
    The upper triangle is mirrored, so ``P`` stays exactly symmetric. ``g`` is the segment's
    ``dp`` on the first ``n`` states and ``dv`` on the next ``n``.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' states and covariances, updated in place.
    tab : ndarray, shape (E, 5 + 2n)
        Segment table (module docstring, "Packed layouts").
    e : int
        The segment (row of ``tab``).
    n : int
        Spatial dimension.
    tr : ndarray, shape (K, 4)
        Entries ``(row, col, mult, power)`` of ``N``, sorted by row.
    Q : ndarray, shape (m, m, B)
        The segment's process noise.
    ws : ndarray
        Workspace (module docstring); holds the transition's coefficients.
    """
    m, B = X.shape
    T = tab[e, TAB_T]
    K = tr.shape[0]
    for t in range(K):
        c = tr[t, 2]
        for _ in range(int(tr[t, 3])):  # not T ** p: numba's float ** int is 40x slower here
            c *= T
        ws[WS_SC, SC_COEF + t, 0] = c
        r, s = int(tr[t, 0]), int(tr[t, 1])
        for b in range(B):
            X[r, b] += c * X[s, b]
    for i in range(n):
        gp, gv = tab[e, TAB_G + i], tab[e, TAB_G + n + i]
        for b in range(B):
            X[i, b] += gp
            X[n + i, b] += gv
    for t in range(K):
        c, r, s = ws[WS_SC, SC_COEF + t, 0], int(tr[t, 0]), int(tr[t, 1])
        for j in range(m):
            for b in range(B):
                P[r, j, b] += c * P[s, j, b]  # F P
    for t in range(K):
        c, r, s = ws[WS_SC, SC_COEF + t, 0], int(tr[t, 0]), int(tr[t, 1])
        for i in range(m):
            for b in range(B):
                P[i, r, b] += c * P[i, s, b]  # (F P) Fᵀ
    for i in range(m):
        for j in range(i, m):
            for b in range(B):
                v = P[i, j, b] + Q[i, j, b]
                P[i, j, b] = v
                P[j, i, b] = v


@inline
def correct_inputs(X, ce, e, T, n, G):
    """Add run ``b // G``'s response to its input corrections over segment ``e``:
    ``c_e - F(T) c_{e-1}`` on ``(p, v)`` (the prediction used the plan's inputs).

    Parameters
    ----------
    X : ndarray, shape (m, B)
        The members' states, updated in place.
    ce : ndarray, shape (E, 2n, R)
        The runs' responses to their input corrections at the epochs [m, m/s].
    e : int
        The segment (``e > 0``).
    T : float
        Its length [s].
    n : int
        Spatial dimension.
    G : int
        Members per run.
    """
    B = X.shape[1]
    for i in range(n):
        for b in range(B):
            g = b // G
            X[i, b] += ce[e, i, g] - ce[e - 1, i, g] - T * ce[e - 1, n + i, g]
            X[n + i, b] += ce[e, n + i, g] - ce[e - 1, n + i, g]


@inline
def update_rows(X, P, iw, ws, nnz):
    """Scalar Joseph update of every member with the sparse row ``h[iw[:nnz]] = ws[WS_VAL]``.

    Per member: innovation, variance and validity (0/1) in ``ws[WS_SC, SC_NU/SC_R/SC_OK]``; an
    invalid member gets a zero gain (exactly unchanged). Adds the NIS, count and
    log-likelihood of the innovation to ``ws[WS_SC, SC_NIS/SC_CNT/SC_LL]``. With a weight
    ``β = ws[WS_SC, SC_BETA] < 1`` (:func:`late_weight`) the update is the moment-matched
    mixture of the update and none: ``x += β K ν``, ``P -= c K s Kᵀ`` with
    ``c = β - β(1-β) ν²/s``, written in the Joseph-like form ``P - (K' wᵀ + w K'ᵀ)`` with
    ``K' = c' K``, ``c' = 1 - sqrt(1 - c)`` (so that ``2c' - c'² = c``; ``β = 1``: ``c' = 1``,
    the ordinary update, exactly). The weight and its log-likelihood correction
    (``SC_LLR``) are reset to 1 and 0.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' states and covariances, updated in place.
    iw : ndarray of int, shape (m,)
        State indices of the row's non-zero entries (the first ``nnz``).
    ws : ndarray
        Workspace (module docstring): the row's values, innovations, variances, validity.
    nnz : int
        Number of non-zero entries of the row.
    """
    m, B = X.shape
    for i in range(m):
        for b in range(B):
            ws[WS_B, i, b] = 0.0
        for t in range(nnz):
            j = iw[t]
            for b in range(B):
                ws[WS_B, i, b] += P[i, j, b] * ws[WS_VAL, t, b]
    for b in range(B):
        ws[WS_SC, SC_S, b] = ws[WS_SC, SC_R, b]
    for t in range(nnz):
        j = iw[t]
        for b in range(B):
            ws[WS_SC, SC_S, b] += ws[WS_VAL, t, b] * ws[WS_B, j, b]
    for b in range(B):
        s, nu, ok = ws[WS_SC, SC_S, b], ws[WS_SC, SC_NU, b], ws[WS_SC, SC_OK, b]
        ws[WS_SC, SC_NIS, b] += ok * nu * nu / s
        ws[WS_SC, SC_CNT, b] += ok
        ws[WS_SC, SC_LL, b] -= ok * 0.5 * (nu * nu / s + math.log(s))
        ws[WS_SC, SC_LL, b] += ok * ws[WS_SC, SC_LLR, b]
        ws[WS_SC, SC_G, b] = ok / s
        beta = ws[WS_SC, SC_BETA, b]
        c = beta - beta * (1.0 - beta) * nu * nu / s
        ws[WS_SC, SC_LLR, b] = 1.0 - math.sqrt(1.0 - c)  # c', in the spent slot
        ws[WS_SC, SC_BETA, b] = beta * nu  # the state's step is K β ν
    for i in range(m):
        for b in range(B):
            k = ws[WS_B, i, b] * ws[WS_SC, SC_G, b]
            X[i, b] += k * ws[WS_SC, SC_BETA, b]
            k = k * ws[WS_SC, SC_LLR, b]
            ws[WS_K, i, b] = k
            ws[WS_W, i, b] = ws[WS_B, i, b] - 0.5 * ws[WS_SC, SC_S, b] * k  # w = b - s k / 2
    for b in range(B):
        ws[WS_SC, SC_BETA, b] = 1.0
        ws[WS_SC, SC_LLR, b] = 0.0
    for i in range(m):
        for j in range(i, m):
            for b in range(B):
                v = P[i, j, b] - (ws[WS_K, i, b] * ws[WS_W, j, b] + ws[WS_W, i, b] * ws[WS_K, j, b])
                P[i, j, b] = v
                P[j, i, b] = v


@inline
def linear_updates(X, P, Y, e, lin, iw, ws, G):
    """Updates with the linear output rows ``1..`` (DVL, depth); member b reads run ``b // G``.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' states and covariances, updated in place.
    Y : ndarray, shape (E, outputs, R)
        The readings (NaN: no report).
    e : int
        The epoch.
    lin : ndarray, shape (outputs, 5)
        The linear output rows (module docstring).
    iw : ndarray of int, shape (m,)
        Scratch for the rows' state indices.
    ws : ndarray
        Workspace (module docstring).
    G : int
        Members per run.
    """
    B = X.shape[1]
    for o in range(1, Y.shape[1]):
        nnz = int(lin[o, 0])
        for t in range(nnz):
            iw[t] = int(lin[o, 1 + t])
        any_ok = False
        for b in range(B):
            yo = Y[e, o, b // G]
            ok = math.isfinite(yo)
            any_ok = any_ok or ok
            pred = lin[o, 4]
            for t in range(nnz):
                ws[WS_VAL, t, b] = 1.0
                pred += X[iw[t], b]
            ws[WS_SC, SC_NU, b] = yo - pred if ok else 0.0
            ws[WS_SC, SC_R, b] = lin[o, 3]
            ws[WS_SC, SC_OK, b] = 1.0 if ok else 0.0
        if any_ok:
            update_rows(X, P, iw, ws, nnz)


@inline
def late_weight(nu, s, late):
    """The posterior probability ``β`` that a range is the direct arrival, and the log ratio of
    its two-component likelihood to the Gaussian one (:mod:`obsplan.estimation.channel`, the
    late-arrival-aware update).

    Parameters
    ----------
    nu : float
        The innovation [m] (reading minus prediction).
    s : float
        Its predicted variance [m²].
    late : float
        The extent of a late arrival's innovation: the largest excess ``L`` [m] (the prior is
        :data:`~obsplan.estimation.channel.LATE_PRIOR`) of the range, ``r L`` of the
        half-squared form at the reading ``r`` (``½(r̂ + e)² - ½ r̂² ≈ r e``; the excess's
        uniform density is taken as uniform in the row's units).

    Returns
    -------
    beta : float
        ``(1-ε) N(ν; 0, s) / ((1-ε) N(ν; 0, s) + ε ℓ(ν))``, ``ℓ(ν) = (Φ(ν/√s) - Φ((ν-L)/√s))/L``.
    llr : float
        ``log((1-ε) N + ε ℓ) - log N`` (the Gaussian log-likelihood plus it is the mixture's).
    """
    sd = math.sqrt(s)
    z = nu / sd
    gauss = math.exp(-0.5 * z * z) / (math.sqrt(2.0 * math.pi) * sd)
    tail = 0.5 * (math.erfc(-z / math.sqrt(2.0)) - math.erfc(-(nu - late) / (sd * math.sqrt(2.0))))
    direct = (1.0 - LATE_PRIOR) * gauss
    mix = direct + LATE_PRIOR * tail / late
    if not mix > 0.0:  # both densities underflow far below the prediction: a direct range
        return 1.0, 0.0
    llr = math.log(mix) + 0.5 * z * z + math.log(math.sqrt(2.0 * math.pi) * sd)
    return direct / mix, llr


#: The innovation gate's actions (:func:`gate_action`).
GATE_USE, GATE_REACQUIRE, GATE_REJECT = 0, 1, 2


@inline
def gate_action(nis, gate, run, reacquire_after, short):
    """The innovation gate's rule for one range: the Monte Carlo's filters (:func:`gate_rows`)
    and the replay's (:mod:`obsplan.estimation.replay.smoother`) both decide by it.

    Parameters
    ----------
    nis : float
        The range's normalised innovation squared ``ν²/s`` (the smallest over a Gaussian sum's
        components).
    gate : float
        The largest NIS of a range used (``inf``: no gate).
    run : float
        Ranges rejected in a row before this one.
    reacquire_after : int
        Rejections in a row after which the filter re-acquires
        (:data:`~obsplan.estimation.channel.REACQUIRE_AFTER`); 0: never.
    short : bool
        The late-arrival-aware rule and the range shorter than predicted: a late arrival is
        never short, so the filter is wrong, not the range, and re-acquires on it at once.

    Returns
    -------
    int
        :data:`GATE_USE` (NIS within the gate), :data:`GATE_REACQUIRE` (widen the position
        prior to put the range on the gate, then use it) or :data:`GATE_REJECT`.
    """
    if not nis > gate:
        return GATE_USE
    if reacquire_after > 0 and (run >= reacquire_after or short):
        return GATE_REACQUIRE
    return GATE_REJECT


@inline
def gate_rows(X, P, iw, ws, nnz, npos, G, gate, rg, late):
    """The innovation gate on a range row of every run, before its update (with ``gate =
    inf`` it only counts).

    Per run, the range is used when the smallest NIS ``ν²/s`` of its members (one: the EKF, the
    KF; a Gaussian sum's components: the range fits some branch) is at most ``gate``; else it is
    rejected (its members' validity set to 0), unless the run has rejected
    :data:`~obsplan.estimation.channel.REACQUIRE_AFTER` ranges in a row, or (``late``) the
    range is shorter than every member predicts (a late arrival is never short: the filter is
    wrong, not the range): then it re-acquires (the replay's widening,
    :mod:`obsplan.estimation.replay.smoother`): each member whose NIS is above the gate gets the
    isotropic position variance ``(ν²/gate - s)/|h_p|²`` that puts it on the gate, and the range
    is used with its full weight. A range used without re-acquisition gets the late-arrival
    weight of :func:`late_weight` when ``late``.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' priors (``P`` widened in place on re-acquisition).
    iw : ndarray of int, shape (m,)
        State indices of the row's non-zero entries (the first ``nnz``; the first ``npos`` of
        them the position).
    ws : ndarray
        Workspace: the row's values, innovations, variances and validity (module docstring).
    nnz, npos : int
        Non-zero entries of the row; those on the position.
    G : int
        Members per run.
    gate : float
        The largest NIS of a range used (``inf``: no gate).
    rg : ndarray, shape (4, R)
        Per run: ranges used, rejected, re-acquisitions, the current run of rejections.
    late : bool
        The late-arrival-aware gate: a range shorter than predicted is never rejected, and a
        range used gets the weight of :func:`late_weight` (with each member's extent
        ``ws[WS_SC, SC_LATE]`` set by the row; not on re-acquisition, which trusts its range).
    """
    B = X.shape[1]
    for g in range(B // G):
        b0 = g * G
        seen = False
        short = True  # every member predicts a longer range than the reading
        best = math.inf
        for c in range(G):
            b = b0 + c
            if ws[WS_SC, SC_OK, b] == 0.0:
                continue
            seen = True
            if gate < math.inf:
                hph = 0.0
                for t in range(nnz):
                    acc = 0.0
                    for u in range(nnz):
                        acc += P[iw[t], iw[u], b] * ws[WS_VAL, u, b]
                    hph += ws[WS_VAL, t, b] * acc
                s = hph + ws[WS_SC, SC_R, b]
                ws[WS_SC, SC_S, b] = s  # scratch until update_rows sets it
                nu = ws[WS_SC, SC_NU, b]
                best = min(best, nu * nu / s)
                short = short and nu < 0.0
        if not seen:
            continue
        act = gate_action(best, gate, rg[3, g], REACQUIRE_AFTER, late and short)
        if act == GATE_USE:
            rg[0, g] += 1.0
            rg[3, g] = 0.0
            if late and gate < math.inf:
                for c in range(G):
                    b = b0 + c
                    if ws[WS_SC, SC_OK, b] != 0.0:
                        ext = ws[WS_SC, SC_LATE, b]
                        beta, llr = late_weight(ws[WS_SC, SC_NU, b], ws[WS_SC, SC_S, b], ext)
                        ws[WS_SC, SC_BETA, b] = beta
                        ws[WS_SC, SC_LLR, b] = llr
        elif act == GATE_REACQUIRE:
            for c in range(G):
                b = b0 + c
                if ws[WS_SC, SC_OK, b] == 0.0:
                    continue
                nu, s = ws[WS_SC, SC_NU, b], ws[WS_SC, SC_S, b]
                hh = 0.0
                for t in range(npos):
                    hh += ws[WS_VAL, t, b] * ws[WS_VAL, t, b]
                if nu * nu > gate * s and hh > 0.0:
                    d = (nu * nu / gate - s) / hh
                    for t in range(npos):
                        P[iw[t], iw[t], b] += d
            rg[0, g] += 1.0
            rg[2, g] += 1.0
            rg[3, g] = 0.0
        else:
            for c in range(G):
                b = b0 + c
                ws[WS_SC, SC_OK, b] = 0.0
                ws[WS_SC, SC_NU, b] = 0.0
                ws[WS_SC, SC_R, b] = 1.0
            rg[1, g] += 1.0
            rg[3, g] += 1.0


# ----------------------------------------------------------------------------- statistics
@inline
def nees(nw, n2):
    """``eᵀ C⁻¹ e`` by Cholesky (NaN if ``C`` is not positive definite); ``e``, ``C`` in ``nw``.

    Parameters
    ----------
    nw : ndarray, shape (5 + 6n, 2n)
        Navigation work array (module docstring): ``e`` in row ``NW_E``, ``C`` from ``NW_C``;
        the factor and the whitened error are written into it.
    n2 : int
        ``2n``, the dimension of ``(p, p')``.

    Returns
    -------
    float
        The NEES.
    """
    C, L = NW_C, NW_C + n2
    for j in range(n2):
        s = nw[C + j, j]
        for k in range(j):
            s -= nw[L + j, k] * nw[L + j, k]
        if not s > 0.0:
            return np.nan
        nw[L + j, j] = math.sqrt(s)
        for i in range(j + 1, n2):
            s = nw[C + i, j]
            for k in range(j):
                s -= nw[L + i, k] * nw[L + j, k]
            nw[L + i, j] = s / nw[L + j, j]
    acc = 0.0
    for i in range(n2):
        s = nw[NW_E, i]
        for k in range(i):
            s -= nw[L + i, k] * nw[NW_Y, k]
        y = s / nw[L + i, i]
        nw[NW_Y, i] = y
        acc += y * y
    return acc


@inline
def record_epoch(x, P, ri, n, cur, rec, buf, ex, nw, keep_ex):
    """Record sample ``ri`` (based at the epoch where ``x``, ``P`` are the posterior).

    The navigation estimate ``(p + off, v [+ v_f])`` and its covariance are predicted from the
    epoch over the record's segment, ``(p, ν)⁺ = (p + T ν + dp, ν + dv) + corr``, ``C⁺ = (I + T
    A) C (I + T A)ᵀ + Q(S)`` with ``A = [[0, I], [0, 0]]``, the composed noise of ``q_nav`` and
    the run's input correction ``nw[NW_CORR]``; then errors against the truth (``rec`` after the
    table columns), variances and NEES go to ``buf[ri]``.

    Parameters
    ----------
    x : ndarray, shape (m,)
        The posterior mean at the epoch.
    P : ndarray, shape (m, m)
        Its covariance.
    ri : int
        The record.
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    rec : ndarray, shape (Nr, 5 + 4n)
        The run's record table with its truth (module docstring).
    buf : ndarray, shape (Nr, COL_AXES + 2n)
        The run's record buffer (``COL_*`` of :mod:`obsplan.estimation.columns`).
    ex : ndarray, shape (2, Nr, 2n)
        Receives the estimate and std when ``keep_ex``.
    nw : ndarray, shape (5 + 6n, 2n)
        Navigation work array (module docstring), ``NW_OFF`` and ``NW_CORR`` set by the caller.
    keep_ex : bool
        Keep this run's history in ``ex``.
    """
    n2 = 2 * n
    C, Qz = NW_C, NW_C + 2 * n2
    G = TAB_G + n2  # the truth's columns in ``rec``
    for i in range(n):
        nw[NW_MEAN, i] = x[i] + nw[NW_OFF, i]
        nw[NW_MEAN, n + i] = x[n + i] + (x[2 * n + i] if cur else 0.0)
    for a in range(n2):
        for c in range(n2):
            acc = P[a, c]
            if cur:
                if a >= n:
                    acc += P[a + n, c]
                if c >= n:
                    acc += P[a, c + n]
                if a >= n and c >= n:
                    acc += P[a + n, c + n]
            nw[C + a, c] = acc
    S0, S1, S2, T = rec[ri, TAB_S0], rec[ri, TAB_S1], rec[ri, TAB_S2], rec[ri, TAB_T]
    if S0 > 0.0:
        for i in range(n):
            nw[NW_MEAN, i] += T * nw[NW_MEAN, n + i] + rec[ri, TAB_G + i]
            nw[NW_MEAN, n + i] += rec[ri, TAB_G + n + i]
        # entry (a, c) reads only its own block entries: in place is safe
        for a in range(n):
            for c in range(n):
                pp = nw[C + a, c] + T * (nw[C + a, n + c] + nw[C + n + a, c])
                pp += T * T * nw[C + n + a, n + c] + S0 * nw[Qz + a, c]
                pp += S1 * (nw[Qz + a, n + c] + nw[Qz + n + a, c]) + S2 * nw[Qz + n + a, n + c]
                pv = nw[C + a, n + c] + T * nw[C + n + a, n + c]
                pv += S0 * nw[Qz + a, n + c] + S1 * nw[Qz + n + a, n + c]
                vp = nw[C + n + a, c] + T * nw[C + n + a, n + c]
                vp += S0 * nw[Qz + n + a, c] + S1 * nw[Qz + n + a, n + c]
                nw[C + a, c] = pp
                nw[C + a, n + c] = pv
                nw[C + n + a, c] = vp
        for a in range(n):
            for c in range(n):
                nw[C + n + a, n + c] += S0 * nw[Qz + n + a, n + c]
    sv = 0.0
    vv = 0.0
    for i in range(n2):
        nw[NW_MEAN, i] += nw[NW_CORR, i]
        nw[NW_E, i] = nw[NW_MEAN, i] - rec[ri, G + i]
    for i in range(n):
        ep = nw[NW_E, i]
        ev = nw[NW_E, n + i]
        sv += ev * ev
        vv += nw[C + n + i, n + i]
        buf[ri, COL_AXES + i] = ep * ep
        buf[ri, COL_AXES + n + i] = nw[C + i, i]
    buf[ri, COL_SE_VEL] = sv
    buf[ri, COL_VAR_VEL] = vv
    buf[ri, COL_NEES] = nees(nw, n2)
    if keep_ex:
        for i in range(n2):
            ex[0, ri, i] = nw[NW_MEAN, i]
            ex[1, ri, i] = math.sqrt(max(nw[C + i, i], 0.0))


@jit
def finish_run(buf, t_rec, thr, bound, window, nis_sum, nis_cnt, sums, info, rec_w):
    """Per-run verdicts from the record buffer, then add the buffer to its group's sums.

    Also the run's own position RMSE over the records and over the records of weight 1 in
    ``rec_w`` (e.g. the samples flown on survey lines; NaN if none).

    The divergence monitor flags the run when its NEES averaged over the records of the final
    ``window`` seconds is above ``bound`` (it ends inconsistent: a transient it recovers from is
    not a divergence), or when its error is non-finite; the flag time is the last time its NEES
    rose above ``bound`` (NaN if never). ``sums[1]`` collects flagged runs, ``sums[0]`` the others.

    Parameters
    ----------
    buf : ndarray, shape (Nr, COL_AXES + 2n)
        The run's record buffer.
    t_rec : ndarray, shape (Nr,)
        Recorded times [s].
    thr : float
        Convergence threshold on the position error [m].
    bound : float
        The monitor's bound on one run's NEES.
    window : float
        The monitor's final window [s].
    nis_sum, nis_cnt : float
        The run's sum of normalised innovations squared and their number.
    sums : ndarray, shape (2, Nr, COL_AXES + 2n)
        The group sums, added to.
    info : ndarray, shape (N_INFO,)
        Receives the run's verdicts (``INFO_*`` of :mod:`obsplan.estimation.columns`).
    rec_w : ndarray, shape (Nr,)
        Weights of the records of the subset RMSE.
    """
    Nr, ncol = buf.shape
    n = (ncol - COL_AXES) // 2
    last_above = -1
    nonfinite = False
    flagged = False
    flag_time = np.nan
    first_bad = np.nan
    start = -1
    for j in range(Nr):
        pos2 = 0.0
        for i in range(n):
            pos2 += buf[j, COL_AXES + i]
        if not math.sqrt(pos2) <= thr:
            last_above = j
        if not math.isfinite(pos2) and not nonfinite:
            nonfinite = True
            first_bad = t_rec[j]
        if not buf[j, COL_NEES] <= bound:
            if start < 0:
                start = j
        else:
            start = -1
    tail = 0.0
    k = 0
    for j in range(Nr - 1, -1, -1):
        if t_rec[Nr - 1] - t_rec[j] > window and k > 0:
            break
        tail += buf[j, COL_NEES]
        k += 1
    if not tail / k <= bound:
        flagged = True
        if start >= 0:
            flag_time = t_rec[start]
    if nonfinite and not (flagged and flag_time <= first_bad):
        flagged = True
        flag_time = first_bad
    g = 1 if flagged else 0
    for j in range(Nr):
        for c in range(ncol):
            sums[g, j, c] += buf[j, c]
    last = Nr - 1
    pos2 = 0.0
    var2 = 0.0
    for i in range(n):
        pos2 += buf[last, COL_AXES + i]
        var2 += buf[last, COL_AXES + n + i]
    info[INFO_FINAL_POS] = math.sqrt(pos2)
    info[INFO_FINAL_VEL] = math.sqrt(buf[last, COL_SE_VEL])
    info[INFO_FINAL_STD] = math.sqrt(var2)
    info[INFO_LAST_ABOVE] = last_above
    info[INFO_NONFINITE] = 1.0 if nonfinite else 0.0
    info[INFO_FLAGGED] = 1.0 if flagged else 0.0
    info[INFO_FLAG_TIME] = flag_time
    info[INFO_NIS] = nis_sum / nis_cnt if nis_cnt > 0 else np.nan
    ss = 0.0
    sw = 0.0
    wn = 0.0
    for j in range(Nr):
        pos2 = 0.0
        for i in range(n):
            pos2 += buf[j, COL_AXES + i]
        ss += pos2
        sw += rec_w[j] * pos2
        wn += rec_w[j]
    info[INFO_RMSE_POS] = math.sqrt(ss / Nr)
    info[INFO_RMSE_LINES] = math.sqrt(sw / wn) if wn > 0 else np.nan


@jit
def workspaces(m, B, n, nw_off, qz):
    """``ws`` (batched), ``iw``, ``nw`` (per run, for the records) of a filter of ``m`` states.

    Parameters
    ----------
    m : int
        Number of states.
    B : int
        Number of members.
    n : int
        Spatial dimension.
    nw_off : ndarray, shape (n,)
        Offset added to the estimated position (the beacon for the KF's relative positions).
    qz : ndarray, shape (2n, 2n)
        Per-step process noise of ``(p, p')``.

    Returns
    -------
    ws : ndarray, shape (5, max(m, SC_COEF + 2m), B)
        Update workspace (module docstring).
    iw : ndarray of int, shape (m,)
        Row indices.
    nw : ndarray, shape (5 + 6n, 2n)
        Navigation work array.
    """
    ws = np.zeros((WS_SC + 1, max(m, SC_COEF + 2 * m), B))
    ws[WS_SC, SC_BETA] = 1.0
    iw = np.zeros(m, dtype=np.int64)
    nw = np.zeros((NW_C + 6 * n, 2 * n))
    for i in range(n):
        nw[NW_OFF, i] = nw_off[i]
    for a in range(2 * n):
        for c in range(2 * n):
            nw[NW_C + 4 * n + a, c] = qz[a, c]
    return ws, iw, nw


@inline
def mixture_weights(lw, w, g, G):
    """``w`` of run ``g``'s ``G`` members (``g G .. g G + G - 1``): ``exp(lw)`` normalised;
    returns the largest log weight (subtracted before the exponential).

    Parameters
    ----------
    lw : ndarray, shape (B,)
        The members' log weights.
    w : ndarray, shape (B,)
        Receives the weights of run ``g``'s members.
    g : int
        The run.
    G : int
        Members per run.

    Returns
    -------
    float
        The largest log weight of the run's members.
    """
    b0 = g * G
    top = lw[b0]
    for c in range(1, G):
        top = max(top, lw[b0 + c])
    tot = 0.0
    for c in range(G):
        w[b0 + c] = math.exp(lw[b0 + c] - top)
        tot += w[b0 + c]
    for c in range(G):
        w[b0 + c] /= tot
    return top


@jit
def record_batch(X, P, lw, w, G, e, ri, n, cur, rec, buf, ex, ex_run, nw, xm, Pm, ce, cr):
    """Record sample ``ri`` (based at epoch ``e``) for every run of the batch (its members'
    mixture: weights ``exp(lw)`` over its ``G`` members, ``w`` (B,) scratch; one member: the
    member itself), with each run's input correction ``cr[ri] - F ce[e]`` (none when ``ce`` is
    empty).

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' posteriors at epoch ``e``.
    lw, w : ndarray, shape (B,)
        The members' log weights; scratch for their weights.
    G : int
        Members per run.
    e, ri : int
        The epoch the record is based at, and the record.
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    rec : ndarray, shape (R, Nr, 5 + 4n)
        Each run's record table with its truth.
    buf : ndarray, shape (R, Nr, COL_AXES + 2n)
        Each run's record buffer.
    ex : ndarray, shape (2, Nr, 2n)
        Receives run ``ex_run``'s estimate and std.
    ex_run : int
        The run whose history is kept (-1: none).
    nw, xm, Pm : ndarray
        Navigation work array (module docstring) and scratch mean (m,) and covariance (m, m).
    ce, cr : ndarray, shapes (E, 2n, R), (Nr, 2n, R)
        Input corrections at the epochs and records (module docstring; empty: open loop).
    """
    m, B = X.shape
    corr = ce.shape[0] > 0
    for g in range(B // G):
        b0 = g * G
        mixture_weights(lw, w, g, G)
        for i in range(m):
            acc = 0.0
            for c in range(G):
                acc += w[b0 + c] * X[i, b0 + c]
            xm[i] = acc
        for i in range(m):
            for j in range(i, m):
                acc = 0.0
                for c in range(G):
                    b = b0 + c
                    acc += w[b] * (P[i, j, b] + (X[i, b] - xm[i]) * (X[j, b] - xm[j]))
                Pm[i, j] = acc
                Pm[j, i] = acc
        T = rec[g, ri, TAB_T]
        for i in range(n):
            if corr:
                nw[NW_CORR, i] = cr[ri, i, g] - ce[e, i, g] - T * ce[e, n + i, g]
                nw[NW_CORR, n + i] = cr[ri, n + i, g] - ce[e, n + i, g]
            else:
                nw[NW_CORR, i] = 0.0
                nw[NW_CORR, n + i] = 0.0
        record_epoch(xm, Pm, ri, n, cur, rec[g], buf[g], ex, nw, g == ex_run)


# ----------------------------------------------------------------------------- EKF
@inline
def ekf_range_row(X, P, Y, e, iw, ws, n, G, beacon, half_sq, second, var_r, ks, kb, Hs, T):
    """The range row of every member, linearised at its prior; returns whether any reports.

    ``second``: the Gaussian second-order update (Jazwinski 1970, sec. 9.3; Bar-Shalom, Li and
    Kirubarajan 2001, sec. 10.3): with ``δ ~ N(0, P_pp)`` the range's quadratic term
    ``½ δᵀ M δ`` (``M = I`` for the half-squared form, ``(I - u uᵀ)/ρ`` for the range) adds its
    mean ``½ tr(M P_pp)`` to the prediction and its variance ``½ tr((M P_pp)²)`` to the
    reading's. Where the position is uncertain on the scale of ``sqrt(2 ρ σ_r)`` the first-order
    update takes the curvature of the range for information it does not have. With the range's
    calibration states the row is :func:`calibrated_row`'s.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' priors.
    Y : ndarray, shape (E, outputs, R)
        The readings; column 0 the range [m] (NaN: no report).
    e : int
        The epoch.
    iw : ndarray of int, shape (m,)
        Receives the row's state indices (the position, then ``ks`` and ``kb`` if any).
    ws : ndarray
        Workspace: receives the row, innovation, variance and validity of every member.
    n : int
        Spatial dimension.
    G : int
        Members per run.
    beacon : ndarray, shape (E, n) or (1, n)
        Beacon position [m] of each epoch's range (a moving beacon) or one row (a fixed beacon).
    half_sq : bool
        The half-squared range form (else the range).
    second : bool
        The Gaussian second-order update.
    var_r : float
        Variance of the range noise [m²].
    ks, kb : int
        Indices of the range-scale state ``k`` and the range-bias state ``β`` (-1: none).
    Hs, T : ndarray, shape (q, q)
        Scratch for :func:`calibrated_row` (``q`` the row's entries; unused without one).

    Returns
    -------
    bool
        True if some member has a range reading to update with.
    """
    B = X.shape[1]
    any_ok = False
    eb = e if beacon.shape[0] > 1 else 0
    cal = ks >= 0 or kb >= 0
    for i in range(n):
        iw[i] = i
    q = n
    if ks >= 0:
        iw[q] = ks
        q += 1
    if kb >= 0:
        iw[q] = kb
        q += 1
    for b in range(B):
        rm = Y[e, 0, b // G]
        ok = math.isfinite(rm)
        rho2 = 0.0
        for i in range(n):
            h = X[i, b] - beacon[eb, i]
            ws[WS_VAL, i, b] = h
            rho2 += h * h
        nu = 0.0
        r = 1.0
        if cal:
            ok = ok and rho2 > 0.0  # at the beacon the range has no gradient
            if ok:
                nu, r = calibrated_row(
                    X, P, ws, iw, n, q, b, ks, kb, half_sq, second, rm, rho2, var_r, Hs, T
                )
        elif half_sq:
            nu = 0.5 * rm * rm - 0.5 * var_r - 0.5 * rho2
            r = rm * rm * var_r + 0.5 * var_r * var_r
            if second:  # M = I
                tr1 = 0.0
                tr2 = 0.0
                for i in range(n):
                    tr1 += P[i, i, b]
                    for j in range(n):
                        tr2 += P[i, j, b] * P[i, j, b]
                nu -= 0.5 * tr1
                r += 0.5 * tr2
        else:
            rho = math.sqrt(rho2)
            ok = ok and rho > 0.0  # at the beacon the range has no gradient: no information
            for i in range(n):
                ws[WS_VAL, i, b] = ws[WS_VAL, i, b] / rho if ok else 0.0
            nu = rm - rho
            r = var_r
            if second and ok:
                # M = (I - u uᵀ)/ρ, w = P u: tr(M P) = (tr P - uᵀw)/ρ and
                # tr((M P)²) = (tr(P²) - 2|w|² + (uᵀw)²)/ρ²
                trp = 0.0
                trp2 = 0.0
                ww = 0.0
                uw = 0.0
                for i in range(n):
                    trp += P[i, i, b]
                    wi = 0.0
                    for j in range(n):
                        trp2 += P[i, j, b] * P[i, j, b]
                        wi += P[i, j, b] * ws[WS_VAL, j, b]
                    ww += wi * wi
                    uw += ws[WS_VAL, i, b] * wi
                nu -= 0.5 * (trp - uw) / rho
                r += 0.5 * (trp2 - 2.0 * ww + uw * uw) / (rho * rho)
        if not ok:
            for i in range(q):
                ws[WS_VAL, i, b] = 0.0
        ws[WS_SC, SC_NU, b] = nu if ok else 0.0
        ws[WS_SC, SC_R, b] = r if ok else 1.0
        ws[WS_SC, SC_OK, b] = 1.0 if ok else 0.0
        ws[WS_SC, SC_LATE, b] = LATE_MAX_M * rm if half_sq and ok else LATE_MAX_M
        any_ok = any_ok or ok
    return any_ok


@inline
def calibrated_row(X, P, ws, iw, n, q, b, ks, kb, half_sq, second, rm, rho2, var_r, Hs, T):
    """Member ``b``'s range row with the range's calibration states: the scale ``k = X[ks, b]``
    and the bias ``β = X[kb, b]`` (1 and 0 where absent), over the row's states ``z`` (the
    position, then ``k``, then ``β``: ``iw[:q]``).

    The range predicts ``r̃ = k ρ + β`` with gradient ``g = (k u, ρ, 1)`` and Hessian
    ``[[k M, u, 0], [uᵀ, 0, 0], [0, 0, 0]]`` (``u = (p - b)/ρ``, ``M = (I - u uᵀ)/ρ``); the
    range form's row is ``r̃``'s, the half-squared ``h = ½ r̃²``'s: gradient ``r̃ g``, Hessian
    ``g gᵀ + r̃ ∇²r̃``. Second order the Hessian ``H`` over ``z`` with the prior ``P_zz`` adds
    ``½ tr(H P_zz)`` to the prediction and ``½ tr((H P_zz)²)`` to the reading's variance: the
    scale's cross block ``∂²h/∂p∂k`` couples its covariance with the position's, which matters
    early in a run, where the position std is metres and the scale's percents.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' priors.
    ws : ndarray
        Workspace holding ``p - b`` in ``ws[WS_VAL, :n, b]``; receives the row there.
    iw : ndarray of int
        The row's state indices (``q`` of them).
    n, q, b, ks, kb : int
        Spatial dimension, the row's entries, member, the calibration states' indices.
    half_sq, second : bool
        The half-squared range form; the Gaussian second-order update.
    rm, rho2, var_r : float
        The reading [m], ``ρ² > 0`` at the prior [m²], the range noise variance [m²].
    Hs, T : ndarray, shape (>= q, >= q)
        Scratch: the Hessian and its product with the prior.

    Returns
    -------
    tuple of float
        The innovation and the reading's variance.
    """
    k = X[ks, b] if ks >= 0 else 1.0
    rho = math.sqrt(rho2)
    rt = k * rho + (X[kb, b] if kb >= 0 else 0.0)
    for i in range(q):
        for j in range(q):
            Hs[i, j] = 0.0
    for i in range(n):
        ws[WS_VAL, i, b] /= rho  # u
    for i in range(n):
        ui = ws[WS_VAL, i, b]
        for j in range(n):
            Hs[i, j] = k * ((1.0 if i == j else 0.0) - ui * ws[WS_VAL, j, b]) / rho
        if ks >= 0:
            Hs[i, n] = ui
            Hs[n, i] = ui
    for i in range(n):
        ws[WS_VAL, i, b] *= k
    if ks >= 0:
        ws[WS_VAL, n, b] = rho
    if kb >= 0:
        ws[WS_VAL, q - 1, b] = 1.0
    if half_sq:
        nu = 0.5 * rm * rm - 0.5 * var_r - 0.5 * rt * rt
        r = rm * rm * var_r + 0.5 * var_r * var_r
        for i in range(q):
            for j in range(q):
                Hs[i, j] = ws[WS_VAL, i, b] * ws[WS_VAL, j, b] + rt * Hs[i, j]
        for i in range(q):
            ws[WS_VAL, i, b] *= rt
    else:
        nu = rm - rt
        r = var_r
    if second:
        for i in range(q):
            for j in range(q):
                acc = 0.0
                for c in range(q):
                    acc += Hs[i, c] * P[iw[c], iw[j], b]
                T[i, j] = acc
        for i in range(q):
            nu -= 0.5 * T[i, i]
            for j in range(q):
                r += 0.5 * T[i, j] * T[j, i]
    return nu, r


@jit
def ekf_measure(
    X,
    P,
    Y,
    e,
    lw,
    w,
    G,
    iw,
    ws,
    n,
    beacon,
    half_sq,
    second,
    var_r,
    lin,
    run_nis,
    run_cnt,
    gate,
    rg,
    ks,
    kb,
):
    """The EKF's updates at epoch ``e`` (range row, then the linear rows) of every member, and
    their NIS: per run, or for a Gaussian sum (``G > 1``) the mixture's with the prior weights,
    whose log weights ``lw`` then grow by the innovations' log-likelihoods.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' states and covariances, updated in place.
    Y : ndarray, shape (E, outputs, R)
        The readings (NaN: no report).
    e : int
        The epoch.
    lw, w : ndarray, shape (B,)
        The members' log weights (updated); scratch for their weights.
    G : int
        Members per run.
    iw, ws : ndarray
        Row indices and workspace (module docstring).
    n : int
        Spatial dimension.
    beacon, half_sq, second, var_r
        As for :func:`ekf_range_row`.
    lin : ndarray, shape (outputs, 5)
        The linear output rows.
    run_nis, run_cnt : ndarray, shape (R,)
        Each run's sum of normalised innovations squared and their number, added to.
    gate : float
        The innovation gate on the ranges (:func:`gate_rows`; ``inf``: none).
    rg : ndarray, shape (4, R)
        Each run's gate counters (:func:`gate_rows`).
    ks, kb : int
        Indices of the range-scale and range-bias states (-1: none; :func:`ekf_range_row`).
    """
    B = X.shape[1]
    R = B // G
    nnz = n + (ks >= 0) + (kb >= 0)
    Hs = np.empty((nnz, nnz))
    T = np.empty((nnz, nnz))
    for b in range(B):
        ws[WS_SC, SC_NIS, b] = 0.0
        ws[WS_SC, SC_CNT, b] = 0.0
        ws[WS_SC, SC_LL, b] = 0.0
    if ekf_range_row(X, P, Y, e, iw, ws, n, G, beacon, half_sq, second, var_r, ks, kb, Hs, T):
        gate_rows(X, P, iw, ws, nnz, n, G, gate, rg, True)
        update_rows(X, P, iw, ws, nnz)
    if Y.shape[1] > 1:
        linear_updates(X, P, Y, e, lin, iw, ws, G)
    if G == 1:
        for b in range(B):
            run_nis[b] += ws[WS_SC, SC_NIS, b]
            run_cnt[b] += ws[WS_SC, SC_CNT, b]
        return
    for g in range(R):
        b0 = g * G
        top = mixture_weights(lw, w, g, G)
        for c in range(G):
            run_nis[g] += w[b0 + c] * ws[WS_SC, SC_NIS, b0 + c]
            lw[b0 + c] += ws[WS_SC, SC_LL, b0 + c] - top
        run_cnt[g] += ws[WS_SC, SC_CNT, b0]


@jit
def ekf_predict(X, P, Q, ws, mdl, e, cor, G):
    """The EKF's prediction of every member to epoch ``e`` (``e > 0``) over segment ``e``, with
    each run's input correction (``cor``,
    :data:`~obsplan.estimation.filters.bundles.Corrections`).

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' states and covariances, updated in place.
    Q : ndarray, shape (m, m, B)
        Scratch for the segment's process noise.
    ws : ndarray
        Workspace (module docstring).
    mdl : EkfModel
        The model bundle (:mod:`obsplan.estimation.filters.bundles`).
    e : int
        The epoch.
    cor : Corrections
        The runs' input corrections (empty: open loop).
    G : int
        Members per run.
    """
    m = X.shape[0]
    tab = mdl.tab
    noise_terms(Q, mdl.qt, tab[e, TAB_S0], tab[e, TAB_S1], tab[e, TAB_S2], m)
    predict(X, P, tab, e, mdl.n, mdl.tr, Q, ws)
    if cor.ce.shape[0] > 0:
        correct_inputs(X, cor.ce, e, tab[e, TAB_T], mdl.n, G)


@jit
def ekf_batch(X0, P0, lw0, G, Y, mdl, rcd, out, cor):
    """EKF runs over the epochs, batched (see :mod:`obsplan.estimation.filters.ekf`).

    ``X0`` (m, B), ``P0`` (m, m, B): the members; run ``g`` of the batch owns members
    ``g G .. g G + G - 1`` (``G = 1``: the EKF; ``G > 1``: the components of a Gaussian sum,
    :mod:`obsplan.estimation.filters.gsf`, whose log weights ``lw0`` grow by their innovations'
    log-likelihoods and whose mixture is recorded). ``Y`` (E, outputs, runs) the readings; the
    bundles (:mod:`obsplan.estimation.filters.bundles`): ``mdl`` an ``EkfModel``, ``rcd`` the
    ``Records``, ``out`` the ``Outputs`` (``ex`` receives run ``ex_run``'s history), ``cor``
    the runs' input ``Corrections`` (closed loop; empty: none).

    Parameters
    ----------
    X0, P0, lw0 : ndarray, shapes (m, B), (m, m, B), (B,)
        The members' initial states, covariances and log weights.
    G : int
        Members per run.
    Y : ndarray, shape (E, outputs, R)
        The readings.
    mdl, rcd, out, cor : EkfModel, Records, Outputs, Corrections
        The bundles.
    """
    tab, qt, tr, lin, n, cur = mdl.tab, mdl.qt, mdl.tr, mdl.lin, mdl.n, mdl.cur
    beacon, half_sq, second, sig_r = mdl.beacon, mdl.half_sq, mdl.second, mdl.sig_r
    rec_base, rec, qz, t_rec = rcd.rec_base, rcd.rec, rcd.qz, rcd.t_rec
    thr, bound, window, rec_w = rcd.thr, rcd.bound, rcd.window, rcd.rec_w
    sums, info, ex_run, ex = out.sums, out.info, out.ex_run, out.ex
    ce, cr = cor.ce, cor.cr
    m, B = X0.shape
    R = B // G
    E = tab.shape[0]
    X = X0.copy()
    P = P0.copy()
    lw = lw0.copy()
    Q = np.zeros((m, m, B))
    ws, iw, nw = workspaces(m, B, n, np.zeros(n), qz)
    w = np.ones(B)
    xm = np.empty(m)
    Pm = np.empty((m, m))
    buf = np.zeros((R, rec_base.shape[0], COL_AXES + 2 * n))
    run_nis = np.zeros(R)
    run_cnt = np.zeros(R)
    rg = np.zeros((N_GATE + 1, R))
    var_r = sig_r * sig_r
    # typed int64 from the start: a literal 0 makes numba compile record_batch a second time
    # for the Literal[int] it sees before the loop's increment widens the type
    ri = np.int64(0)
    n_rec = rec_base.shape[0]
    corr = ce.shape[0] > 0
    Sp = (-1.0, -1.0, -1.0)
    for e in range(E):
        if e > 0:
            S = (tab[e, TAB_S0], tab[e, TAB_S1], tab[e, TAB_S2])
            if S != Sp:  # equal segments repeat on uniform grids
                Sp = S
                noise_terms(Q, qt, S[0], S[1], S[2], m)
            predict(X, P, tab, e, n, tr, Q, ws)
            if corr:
                correct_inputs(X, ce, e, tab[e, TAB_T], n, G)
        ekf_measure(
            X,
            P,
            Y,
            e,
            lw,
            w,
            G,
            iw,
            ws,
            n,
            beacon,
            half_sq,
            second,
            var_r,
            lin,
            run_nis,
            run_cnt,
            mdl.gate,
            rg,
            mdl.ks,
            mdl.kb,
        )
        while ri < n_rec and rec_base[ri] == e:
            record_batch(X, P, lw, w, G, e, ri, n, cur, rec, buf, ex, ex_run, nw, xm, Pm, ce, cr)
            ri += 1
    for g in range(R):
        finish_run(buf[g], t_rec, thr, bound, window, run_nis[g], run_cnt[g], sums, info[g], rec_w)
        for j in range(N_GATE):
            info[g, INFO_RANGES_USED + j] = rg[j, g]


# ----------------------------------------------------------------------------- augmented KF
@inline
def kf_chain_noise(Q, kw, qk, rule, tab, e, mx, n, cur, qdiag, couple):
    """Cross (x, chain) and chain blocks of the composed process noise of the augmented KF.

    ``Σ_j Φ(τ_j) Γ(σ_j) q Γ(σ_j)ᵀ Φ(τ_j)ᵀ`` by the segment's Gauss rule (``rule[e]``: nodes,
    weights), with the chain rows ``Γ_c = [E(σ), J(τ_a + σ)]`` of
    :mod:`obsplan.estimation.filters.kf` (``E`` only when ``couple``; its gains ``c0 + σ c1`` and
    ``c1`` per member in rows 0, 1 of ``kw``). ``Γ_c`` and ``q Γ_cᵀ`` live in rows 2–4 and 5–7 of
    ``kw``. Without noise on ``(p0·ν0, |ν0|²)`` (the default) their columns are skipped.

    Parameters
    ----------
    Q, kw, qk, rule, tab, e, mx, n, cur, qdiag, couple : as :func:`kf_predict` and ``KfModel``
    """
    mw = qk.shape[0]
    has_ab = False
    for i in range(mw):
        for j in range(mx, mw):
            if qk[i, j] != 0.0:
                has_ab = True
    if not has_ab:
        mw = mx
    B = Q.shape[2]
    kc = mx  # first chain state (κ)
    T = tab[e, TAB_T]
    tau_a = tab[e, TAB_TAU]
    for i in range(mx + 3):
        for c in range(3):
            for b in range(B):
                Q[kc + c, i, b] = 0.0
                Q[i, kc + c, b] = 0.0
    for q in range(rule.shape[2]):
        om = rule[e, 1, q]
        if om == 0.0:
            continue
        sg = rule[e, 0, q]
        tau = T - sg
        ta = tau_a + sg
        for i in range(3):
            for j in range(mw):
                for b in range(B):
                    kw[2 + i, j, b] = 0.0
        if couple:
            for i in range(n):
                for b in range(B):
                    cp = kw[0, i, b] + sg * kw[1, i, b]
                    cv = kw[1, i, b]
                    kw[2, i, b] = cp  # κ: c_p · w_p
                    kw[3, i, b] = cv  # φ: c_v · w_p + c_p · w_ν
                    kw[3, n + i, b] = cp
                    kw[4, n + i, b] = cv  # γ: c_v · w_ν
                    if cur:
                        kw[3, 2 * n + i, b] = cp
                        kw[4, 2 * n + i, b] = cv
        if has_ab:  # the configured noise of (p0·ν0, |ν0|²) in the chain coordinates: J(τ_a + σ)
            for b in range(B):
                kw[2, mx, b] = ta
                kw[2, mx + 1, b] = 0.5 * ta * ta
                kw[3, mx, b] = 1.0
                kw[3, mx + 1, b] = ta
                kw[4, mx + 1, b] = 0.5
        if tau != 0.0:  # Γ ← Φ_c(τ) Γ (in place, row order matters)
            for j in range(mw):
                for b in range(B):
                    kw[2, j, b] += tau * kw[3, j, b] + tau * tau * kw[4, j, b]
                    kw[3, j, b] += 2.0 * tau * kw[4, j, b]
        for c in range(3):
            for i in range(mw):
                if qdiag:
                    qi = qk[i, i]
                    for b in range(B):
                        kw[5 + c, i, b] = qi * kw[2 + c, i, b]
                else:
                    for b in range(B):
                        kw[5 + c, i, b] = 0.0
                    for j in range(mw):
                        qij = qk[i, j]
                        for b in range(B):
                            kw[5 + c, i, b] += qij * kw[2 + c, j, b]
        for a in range(3):
            for c in range(a, 3):
                for j in range(mw):
                    for b in range(B):
                        Q[kc + a, kc + c, b] += om * kw[2 + a, j, b] * kw[5 + c, j, b]
        for i in range(mx):
            for c in range(3):
                for b in range(B):
                    val = kw[5 + c, i, b]
                    if i < n:
                        val += tau * kw[5 + c, n + i, b]
                        if cur:
                            val += tau * kw[5 + c, 2 * n + i, b]
                    Q[i, kc + c, b] += om * val
    for a in range(3):
        for c in range(a):
            for b in range(B):
                Q[kc + a, kc + c, b] = Q[kc + c, kc + a, b]
    for i in range(mx):
        for c in range(3):
            for b in range(B):
                Q[kc + c, i, b] = Q[i, kc + c, b]


@inline  # inlined in kf_batch (no per-epoch bundle passing); compiled alone from Python
def kf_predict(X, P, Q, kw, ws, mdl, e, cor, Sp):
    """The augmented KF's prediction of every run to epoch ``e`` (``e > 0``) over segment ``e``:
    the coupling's gains at the segment's start, the composed noise (kinematic terms, then the
    chain's, :func:`kf_chain_noise`), the transition and each run's input correction. ``Sp``
    (3,): the noise sums of the last segment (its kinematic terms are kept when they repeat).

    Parameters
    ----------
    X, P : ndarray, shapes (mx + 3, R), (mx + 3, mx + 3, R)
        The runs' states and covariances in chain coordinates, updated in place.
    Q : ndarray, shape (mx + 3, mx + 3, R)
        Scratch for the segment's process noise.
    kw : ndarray, shape (8, len(qk), R)
        Work rows of :func:`kf_chain_noise` (coupling gains, ``Γ_c``, ``q Γ_cᵀ``).
    ws : ndarray
        Workspace (module docstring).
    mdl : KfModel
        The model bundle (:mod:`obsplan.estimation.filters.bundles`).
    e : int
        The epoch.
    cor : Corrections
        The runs' input corrections (empty: open loop).
    Sp : ndarray, shape (3,)
        The last segment's noise sums, updated.
    """
    n, cur, ep_d, ce = mdl.n, mdl.cur, mdl.ep_d, cor.ce
    mx = mdl.kc
    B = X.shape[1]
    corr = ce.shape[0] > 0
    for i in range(n):
        for b in range(B):
            dp, dv = ep_d[e - 1, i], ep_d[e - 1, n + i]
            if corr:
                dp += ce[e - 1, i, b]
                dv += ce[e - 1, n + i, b]
            nu_i = X[n + i, b] + (X[2 * n + i, b] if cur else 0.0)
            kw[0, i, b] = X[i, b] - dp  # c_p at the segment's start
            kw[1, i, b] = nu_i - dv  # c_v
    tab = mdl.tab
    S0, S1, S2 = tab[e, TAB_S0], tab[e, TAB_S1], tab[e, TAB_S2]
    if S0 != Sp[0] or S1 != Sp[1] or S2 != Sp[2]:  # equal segments repeat on uniform grids
        Sp[0], Sp[1], Sp[2] = S0, S1, S2
        noise_terms(Q, mdl.qt, S0, S1, S2, mx)
    kf_chain_noise(Q, kw, mdl.qk, mdl.rule, tab, e, mx, n, cur, mdl.qdiag, mdl.couple)
    predict(X, P, tab, e, n, mdl.tr, Q, ws)
    if corr:
        correct_inputs(X, ce, e, tab[e, TAB_T], n, 1)


@inline
def kf_scale_row(P, ws, n, b, kc, ks, A, g1):
    """Member ``b``'s KF range row with the scale state ``g``: the bilinear prediction ``(1 +
    g) A`` (``A = dᵀp + κ - ½|d|²``) by its exact Gaussian moments.

    The row on ``(p, κ, g)`` is ``((1 + ĝ) d, 1 + ĝ, Â)``; the mean is ``(1 + ĝ) Â + P_gA`` and
    the variance adds ``P_gg P_AA + P_gA²`` to the reading's (the product's second-order
    terms, exact for a Gaussian prior). Writes the row into ``ws[WS_VAL]`` (its first ``n``
    entries ``d`` on entry).

    Parameters
    ----------
    P : ndarray, shape (m, m, R)
        The runs' priors.
    ws : ndarray
        Workspace (module docstring).
    n, b, kc, ks : int
        Spatial dimension, run, index of ``κ`` and of ``g``.
    A : float
        ``Â`` at the prior [m²].
    g1 : float
        ``1 + ĝ``.

    Returns
    -------
    mean : float
        The prediction's mean [m²].
    var : float
        The variance it adds to the reading's [m⁴].
    """
    pga = P[kc, ks, b]
    paa = P[kc, kc, b]
    for i in range(n):
        di = ws[WS_VAL, i, b]
        pga += di * P[i, ks, b]
        paa += 2.0 * di * P[i, kc, b]
        for j in range(n):
            paa += di * ws[WS_VAL, j, b] * P[i, j, b]
    for i in range(n):
        ws[WS_VAL, i, b] *= g1
    ws[WS_VAL, n, b] = g1
    ws[WS_VAL, n + 1, b] = A
    return g1 * A + pga, P[ks, ks, b] * paa + pga * pga


@inline
def kf_bias_row(X, ws, nnz, b, kb, wp, y0, var_r):
    """Run ``b``'s KF range row with the range-bias state ``β = X[kb, b]`` (module kf, "A range
    bias"): the prediction ``W + β (R_t - R_0)`` with ``R_0 = r_0 - β`` (``r_0`` from the anchor
    ``y0 = ½ r_0² - ½ σ²``) and ``R_t = sqrt(R_0² + 2 W)``, linearised at the prior: the row on
    ``W``'s states (``ws[WS_VAL, :nnz - 1, b]`` on entry) times ``1 + β/R_t``, and on ``β``
    ``R_t - R_0 + β (1 - R_0/R_t)``.

    Parameters
    ----------
    X : ndarray, shape (m, R)
        The runs' priors.
    ws : ndarray
        Workspace: the row on ``W``'s states; receives the whole row.
    nnz, b, kb : int
        The row's entries (the bias's last), the run, the bias's index.
    wp : float
        ``W`` at the prior [m²] (``½ R_t² - ½ R_0²`` of the unbiased ranges).
    y0, var_r : float
        The anchor [m²] and the range noise variance [m²].

    Returns
    -------
    float
        ``β (R_t - R_0)``, what the bias adds to the prediction [m²].
    """
    beta = X[kb, b]
    r0 = math.sqrt(max(2.0 * y0 + var_r, 0.0)) - beta
    # a prior far off (early in a run) can put R_t² below zero: the floor, a relative 1e-12 of
    # R_0², keeps the row finite; the update then moves the state back where R_t² > 0
    rt = math.sqrt(max(r0 * r0 + 2.0 * wp, 1e-12 * (1.0 + r0 * r0)))
    fac = 1.0 + beta / rt
    for i in range(nnz - 1):
        ws[WS_VAL, i, b] *= fac
    ws[WS_VAL, nnz - 1, b] = rt - r0 + beta * (1.0 - r0 / rt)
    return beta * (rt - r0)


@inline  # inlined in kf_batch (no per-epoch bundle passing); compiled alone from Python
def kf_measure(X, P, Y, e, iw, ws, mdl, anc, cor, run_nis, run_cnt, rg):
    """The augmented KF's updates at epoch ``e`` (the linear range row ``ȳ``, bilinear with a
    scale state ``mdl.ks``, :func:`kf_scale_row`, with the entry ``r_m - r_0`` on a range-bias
    state ``mdl.kb`` (module kf, "A range bias"); then the linear rows) of every run, and their
    NIS; epoch 0 is the anchor ``y0`` (``ȳ_0 ≡ 0``). The range gate is late-arrival aware as
    the EKF's (:func:`gate_rows`; a late range is long in ``ȳ`` too, by about ``r`` times its
    excess).

    Parameters
    ----------
    X, P : ndarray, shapes (mx + 3, R), (mx + 3, mx + 3, R)
        The runs' states and covariances in chain coordinates, updated in place.
    Y : ndarray, shape (E, outputs, R)
        The readings (NaN: no report).
    e : int
        The epoch.
    iw, ws : ndarray
        Row indices and workspace (module docstring).
    mdl : KfModel
        The model bundle.
    anc : Anchors
        The runs' anchors ``y0`` and their variances.
    cor : Corrections
        The runs' input corrections (empty: open loop).
    run_nis, run_cnt : ndarray, shape (R,)
        Each run's sum of normalised innovations squared and their number, added to.
    rg : ndarray, shape (4, R)
        Each run's gate counters (:func:`gate_rows`, with the gate ``mdl.gate``).
    """
    n, ep_d, ce, y0, var0 = mdl.n, mdl.ep_d, cor.ce, anc.y0, anc.var0
    var_r = mdl.sig_r * mdl.sig_r
    kc, ks, kb = mdl.kc, mdl.ks, mdl.kb
    nnz = n + 1 + (ks >= 0) + (kb >= 0)
    B = X.shape[1]
    corr = ce.shape[0] > 0
    for b in range(B):
        ws[WS_SC, SC_NIS, b] = 0.0
        ws[WS_SC, SC_CNT, b] = 0.0
    if e > 0:
        # ȳ = y - y0 + ½|d|² = dᵀp + κ (+ noise): linear; with the scale state g,
        # ȳ = (1 + g) A + ½|d|², A = dᵀp + κ - ½|d|² (module kf's "A sound-speed scale")
        for i in range(n):
            iw[i] = i
        iw[n] = kc
        if ks >= 0:
            iw[n + 1] = ks
        if kb >= 0:
            iw[nnz - 1] = kb
        any_ok = False
        for b in range(B):
            rm = Y[e, 0, b]
            ok = math.isfinite(rm)
            pred = X[kc, b]
            d2 = 0.0
            for i in range(n):
                di = ep_d[e, i] + (ce[e, i, b] if corr else 0.0)
                d2 += di * di
                ws[WS_VAL, i, b] = di
                pred += di * X[i, b]
            ws[WS_VAL, n, b] = 1.0
            r = rm * rm * var_r + 0.5 * var_r * var_r + (var0[b] if mdl.inflate else 0.0)
            ym = 0.5 * rm * rm - 0.5 * var_r - y0[b]  # the measured y - y0
            nu = ym + 0.5 * d2 - pred
            wp = pred - 0.5 * d2  # W = A, or (1 + g) A with the scale state
            if ks >= 0:
                mean, dvar = kf_scale_row(P, ws, n, b, kc, ks, wp, 1.0 + X[ks, b])
                nu = ym - mean
                r += dvar
                wp *= 1.0 + X[ks, b]
            if kb >= 0:
                nu -= kf_bias_row(X, ws, nnz, b, kb, wp, y0[b], var_r)
            ws[WS_SC, SC_NU, b] = nu if ok else 0.0
            ws[WS_SC, SC_R, b] = r if ok else 1.0
            ws[WS_SC, SC_OK, b] = 1.0 if ok else 0.0
            ws[WS_SC, SC_LATE, b] = LATE_MAX_M * rm if ok else LATE_MAX_M
            any_ok = any_ok or ok
        if any_ok:
            gate_rows(X, P, iw, ws, nnz, n, 1, mdl.gate, rg, True)
            update_rows(X, P, iw, ws, nnz)
    if Y.shape[1] > 1:
        linear_updates(X, P, Y, e, mdl.lin, iw, ws, 1)
    for b in range(B):
        run_nis[b] += ws[WS_SC, SC_NIS, b]
        run_cnt[b] += ws[WS_SC, SC_CNT, b]


@jit
def kf_batch(Z0, P0, Y, mdl, anc, rcd, out, cor):
    """Augmented-KF runs over the epochs, batched over runs (see
    :mod:`obsplan.estimation.filters.kf`).

    ``Z0`` (m, R), ``P0`` (m, m, R); ``anc`` the runs' ``Anchors``; ``mdl`` a ``KfModel`` whose
    ``ep_d`` (E, 2n) holds the input displacement ``d`` and its rate ``ḋ`` of the plan's inputs
    at the epochs (a run's own is ``ep_d + ce``: the displacement of its input corrections is
    ``c``); other arguments as :func:`ekf_batch`.

    Parameters
    ----------
    Z0, P0 : ndarray, shapes (m, R), (m, m, R)
        The runs' initial states and covariances in chain coordinates.
    Y : ndarray, shape (E, outputs, R)
        The readings.
    mdl, anc, rcd, out, cor : KfModel, Anchors, Records, Outputs, Corrections
        The bundles.
    """
    n, cur = mdl.n, mdl.cur
    rec_base, rec, t_rec = rcd.rec_base, rcd.rec, rcd.t_rec
    sums, info, ex_run, ex = out.sums, out.info, out.ex_run, out.ex
    ce, cr = cor.ce, cor.cr
    m, B = Z0.shape
    E = mdl.tab.shape[0]
    X = Z0.copy()
    P = P0.copy()
    Q = np.zeros((m, m, B))
    ws, iw, nw = workspaces(m, B, n, mdl.beacon[0], rcd.qz)
    moving = mdl.beacon.shape[0] > 1
    kw = np.zeros((8, mdl.qk.shape[0], B))
    lw = np.zeros(B)
    w = np.ones(B)
    xm = np.empty(m)
    Pm = np.empty((m, m))
    buf = np.zeros((B, rec_base.shape[0], COL_AXES + 2 * n))
    run_nis = np.zeros(B)
    run_cnt = np.zeros(B)
    rg = np.zeros((N_GATE + 1, B))
    ri = np.int64(0)  # int64, not Literal[int] (as in ekf_batch)
    n_rec = rec_base.shape[0]
    one = np.int64(1)  # the KF is one member per run; a literal 1 would compile record_batch anew
    Sp = np.full(3, -1.0)
    for e in range(E):
        if e > 0:
            kf_predict(X, P, Q, kw, ws, mdl, e, cor, Sp)
        kf_measure(X, P, Y, e, iw, ws, mdl, anc, cor, run_nis, run_cnt, rg)
        if moving:  # a record based at epoch e predicts r with ν: absolute at b_e (kf_relative)
            for i in range(n):
                nw[NW_OFF, i] = mdl.beacon[e, i]
        while ri < n_rec and rec_base[ri] == e:
            record_batch(X, P, lw, w, one, e, ri, n, cur, rec, buf, ex, ex_run, nw, xm, Pm, ce, cr)
            ri += 1
    for g in range(B):
        finish_run(
            buf[g],
            t_rec,
            rcd.thr,
            rcd.bound,
            rcd.window,
            run_nis[g],
            run_cnt[g],
            sums,
            info[g],
            rcd.rec_w,
        )
        for j in range(N_GATE):
            info[g, INFO_RANGES_USED + j] = rg[j, g]
