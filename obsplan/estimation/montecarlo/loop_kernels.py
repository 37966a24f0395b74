"""Compiled kernel of the closed loop: EKF navigation, guidance and truth, step by step.

One call advances a batch of runs (members on the last axis, as in
:mod:`obsplan.estimation.kernels`) from their current sample to ``k_end``. Per run it carries, at
the current sample ``k`` (:mod:`obsplan.estimation.montecarlo.closedloop`):

* ``c`` (2n): the response of ``(p, v)`` to the input corrections ``Δu = u - u_plan``,
  ``c_{k+1} = F c_k + G Δu_k``;
* ``d`` (m): the estimate's offset, ``x̂ = x_plan + c + d``; ``d_{k+1} = F d_k`` (no noise: the
  inputs are known), and it jumps at the updates;
* ``δ`` (m): the open-loop process-noise deviation, ``δ_{k+1} = F δ_k + L_k z_k`` (the same
  seeded normals as :func:`obsplan.estimation.kernels.truth_deviation`);

so the truth is ``x = x_plan + c + δ``. At a measurement epoch the EKF's covariance is predicted
over the whole gap (the composed prediction of the open loop: it does not depend on the inputs),
its mean is ``x_plan + c + d``, the readings are computed at the truth plus their pre-drawn
noise, and it updates. At a record the statistics are taken (with the input correction
``c_k - F c_e``, as the passive filters do). Then the guidance
(:mod:`obsplan.estimation.montecarlo.guidance`) gives ``u_k`` from the estimate and ``c``, ``d``,
``δ`` step to ``k + 1``.

The parts are compiled separately: ``nav_measure`` and ``nav_record`` once per epoch or record
for the whole batch, ``nav_run`` once per gap between them (one inlined function took minutes to
compile). Inside a gap the steps call only inlined helpers with plain arrays: a namedtuple
argument costs the reference counts of all its arrays, per call (measured: passing the bundles
per step made a run-step 380 ns instead of 50). Argument bundles (namedtuples, built by
:mod:`obsplan.estimation.montecarlo.closedloop`): ``pt`` the path (shared by all runs), ``gn`` the
gains, ``st`` the runs' state (mutated in place; ``st.pos`` holds ``k``, whether the measurement at
``k`` is done, the last epoch and the number of buffered truth samples), ``io`` the per-run
inputs and outputs. The truth metrics are taken from a per-run buffer of samples
(:func:`~obsplan.estimation.kernels.span_metrics`, the open loop's).
"""

from __future__ import annotations

import math

import numpy as np

from obsplan.estimation.columns import TM_ACCEL, TM_SAT
from obsplan.estimation.kernels import (
    TAB_G,
    TAB_S0,
    TAB_S1,
    TAB_S2,
    ekf_measure,
    inline,
    jit,
    mixture_weights,
    noise_terms,
    predict,
    record_batch,
    span_metrics,
)
from obsplan.estimation.montecarlo.guidance import SPEED_RESERVE_CAP

#: Relative slack of the speed limit: a plan flown exactly at the bound is not "corrected" for
#: the round-off of its own chord inputs.
SPEED_SLACK = 1e-9
#: The speed reserve never takes the bound on the estimated speed below this fraction of it.
SPEED_FLOOR = 1.0 - SPEED_RESERVE_CAP


@jit
def nav_measure(pt, gn, st, io, k, e):
    """Epoch ``e`` at sample ``k``: predict the covariance over the gap, the mean ``x_plan + c +
    d``, the readings at the truth, the EKF's updates; then ``d``, ``ce[e] = c`` and every run's
    bound on the estimated speed (:func:`speed_bounds`).

    Parameters
    ----------
    pt, gn, st, io : NavPath, NavGains, NavState, NavIO
        The bundles (module docstring; built by :mod:`obsplan.estimation.montecarlo.closedloop`).
    k : int
        The sample.
    e : int
        The epoch at that sample.
    """
    n = pt.n
    n2 = 2 * n
    X, P = st.X, st.P
    m, B = X.shape
    if e > 0:
        S0, S1, S2 = pt.tab[e, TAB_S0], pt.tab[e, TAB_S1], pt.tab[e, TAB_S2]
        if S0 != st.Sp[0] or S1 != st.Sp[1] or S2 != st.Sp[2]:  # repeats on uniform grids
            st.Sp[0], st.Sp[1], st.Sp[2] = S0, S1, S2
            noise_terms(st.Q, pt.qt, S0, S1, S2, m)
        predict(X, P, pt.tab, e, n, pt.tr, st.Q, st.ws)
    G = pt.G
    R = B // G
    if G == 1:  # set exactly (X + (target - X) is not target to the last bit)
        for i in range(m):
            for b in range(B):
                X[i, b] = pt.xplan[k, i] + st.d[i, b] + (st.c[i, b] if i < n2 else 0.0)
    else:  # the members predicted with the plan's inputs, shifted by the corrections' response
        for g in range(R):
            mixture_weights(st.lw, st.w, g, G)
            for i in range(m):
                sh = pt.xplan[k, i] + st.d[i, g] + (st.c[i, g] if i < n2 else 0.0)
                for c in range(G):
                    sh -= st.w[g * G + c] * X[i, g * G + c]
                for c in range(G):
                    X[i, g * G + c] += sh
    Y = io.Y
    eb = e if pt.beacon.shape[0] > 1 else 0  # a moving beacon: its row of epoch e
    for b in range(R):  # device readings at the true state x_plan + c + δ
        rho2 = 0.0
        for i in range(n):
            rel = pt.xplan[k, i] + st.c[i, b] + st.dl[i, b] - pt.beacon[eb, i]
            rho2 += rel * rel
        Y[e, 0, b] = math.sqrt(rho2) * pt.rscale + io.Yn[e, 0, b]  # rscale: the sound speed
        for o in range(1, Y.shape[1]):  # the EKF's linear rows are the clean readings
            val = pt.lin[o, 4]
            for t in range(int(pt.lin[o, 0])):
                j = int(pt.lin[o, 1 + t])
                val += pt.xplan[k, j] + st.dl[j, b] + (st.c[j, b] if j < n2 else 0.0)
            Y[e, o, b] = val + io.Yn[e, o, b]
    ekf_measure(
        X,
        P,
        Y,
        e,
        st.lw,
        st.w,
        G,
        st.iw,
        st.ws,
        n,
        pt.beacon,
        pt.half_sq,
        pt.second,
        pt.sig_r * pt.sig_r,
        pt.lin,
        io.run_nis,
        io.run_cnt,
        pt.gate,
        io.rg,
        pt.ks,
        pt.kb,
    )
    for g in range(R):  # the estimate's offset: its mixture's mean (one member: w = 1 exactly)
        mixture_weights(st.lw, st.w, g, G)
        for i in range(m):
            acc = 0.0
            for c in range(G):
                acc += st.w[g * G + c] * X[i, g * G + c]
            st.d[i, g] = acc - pt.xplan[k, i] - (st.c[i, g] if i < n2 else 0.0)
    for i in range(n2):
        for b in range(R):
            io.ce[e, i, b] = st.c[i, b]
    speed_bounds(X, P, st.lw, st.w, G, st.vl, gn.kv, gn.vmax, n, pt.cur)


@inline
def speed_bounds(X, P, lw, w, G, vl, kv, vmax, n, cur):
    """Per run, from its members' ``X`` (m, B), covariances ``P`` (m, m, B) and log weights
    ``lw`` after an update (``w`` (B,) scratch), the bound ``vl`` (B / G,) on the estimated
    speed: ``vmax`` less ``kv`` stds of the inertial velocity's noisiest axis (guidance.py,
    "Speed reserve"; of a Gaussian sum, the mixture's variance), at least ``SPEED_FLOOR vmax``.

    Parameters
    ----------
    X, P : ndarray, shapes (m, B), (m, m, B)
        The members' posteriors.
    lw, w : ndarray, shape (B,)
        Their log weights; scratch for the weights.
    G : int
        Members per run.
    vl : ndarray, shape (B / G,)
        Receives each run's bound on the estimated speed [m/s].
    kv : float
        Velocity stds kept below the bound (``Guidance.speed_k``).
    vmax : float
        The speed bound [m/s] (inf: none, ``vl`` untouched).
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    """
    if vmax == math.inf:
        return
    for g in range(P.shape[2] // G):
        mixture_weights(lw, w, g, G)  # one member: w = 1 and the spread 0, exactly
        sv = 0.0
        for i in range(n):
            mean = 0.0
            for c in range(G):
                b = g * G + c
                mean += w[b] * (X[n + i, b] + (X[2 * n + i, b] if cur else 0.0))
            var = 0.0
            for c in range(G):
                b = g * G + c
                vb = P[n + i, n + i, b]
                if cur:  # inertial velocity v + v_f
                    vb += P[2 * n + i, 2 * n + i, b] + 2.0 * P[n + i, 2 * n + i, b]
                dv = X[n + i, b] + (X[2 * n + i, b] if cur else 0.0) - mean
                var += w[b] * (vb + dv * dv)
            sv = max(sv, var)
        vl[g] = max(vmax - kv * math.sqrt(max(sv, 0.0)), SPEED_FLOOR * vmax)


@jit
def nav_record(pt, st, io, k, ri, e_last):
    """Record ``ri`` at sample ``k``: the truth's ``(p, p')``, ``cr[ri] = c``, the statistics.

    Parameters
    ----------
    pt, st, io : NavPath, NavState, NavIO
        The bundles (module docstring).
    k : int
        The sample.
    ri : int
        The record at that sample.
    e_last : int
        The last epoch at or before it.
    """
    n = pt.n
    B = st.X.shape[1] // pt.G
    g0 = TAB_G + 2 * n
    for b in range(B):
        for i in range(n):
            io.rec[b, ri, g0 + i] = pt.xplan[k, i] + st.c[i, b] + st.dl[i, b]
            nu = pt.nuplan[k, i] + st.c[n + i, b] + st.dl[n + i, b]
            io.rec[b, ri, g0 + n + i] = nu + (st.dl[2 * n + i, b] if pt.cur else 0.0)
        for i in range(2 * n):
            io.cr[ri, i, b] = st.c[i, b]
    record_batch(
        st.X,
        st.P,
        st.lw,
        st.w,
        pt.G,
        e_last,
        ri,
        n,
        pt.cur,
        io.rec,
        io.buf,
        io.ex,
        io.ex_run,
        st.nw,
        st.xm,
        st.Pm,
        io.ce,
        io.cr,
    )


@inline
def buffer_truth(xb, j, xplan, nuplan, c, dl, ref, kr, has_ref, k, n, cur):
    """Row ``j`` of every run's metric buffer: the true ``(p, p')`` at sample ``k`` and the
    reference position (the plan, or ``ref[kr]``).

    Parameters
    ----------
    xb : ndarray, shape (R, span, 3n)
        The runs' metric buffers (rows of :func:`~obsplan.estimation.kernels.span_metrics`).
    j : int
        The row to write.
    xplan, nuplan : ndarray, shapes (N, m), (N, n)
        The plan's states and inertial velocities [m, m/s].
    c : ndarray, shape (2n, R)
        The runs' responses to their input corrections.
    dl : ndarray, shape (m, R)
        The runs' process-noise deviations ``δ``.
    ref : ndarray, shape (K + 1, 3n, R)
        The runs' references ``(p, p', u)`` (used when ``has_ref``).
    kr : int
        Row of ``ref`` at sample ``k``.
    has_ref : bool
        The runs follow ``ref`` (else the plan).
    k : int
        The sample.
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    """
    B = c.shape[1]
    for i in range(n):
        xp, vp = xplan[k, i], nuplan[k, i]
        for b in range(B):
            xb[b, j, i] = xp + c[i, b] + dl[i, b]
            nu = vp + c[n + i, b] + dl[n + i, b]
            xb[b, j, n + i] = nu + (dl[2 * n + i, b] if cur else 0.0)
            xb[b, j, 2 * n + i] = ref[kr, i, b] if has_ref else xp


@jit
def flush_metrics(pt, st, io, k_last):
    """Add the buffered samples of every run to its truth metrics.

    Parameters
    ----------
    pt, st, io : NavPath, NavState, NavIO
        The bundles (module docstring).
    k_last : int
        The sample of the last buffered row (the rows are consecutive samples).
    """
    K = st.pos[3]
    for b in range(io.xb.shape[0]):
        span_metrics(io.tm, b, io.xb[b], K, pt.n, pt.beacon_s, pt.box, pt.has_box, k_last - K + 1)
    st.pos[3] = 0


@inline
def guide(U, V, sat, c, d, ref, kr, has_ref, xplan, nuplan, uplan, k, amax, gains, vl, hk, n, cur):
    """The commands of every run at sample ``k`` into ``U`` (n, B) (guidance.py): ``gains`` are
    ``(Kp, Kd, v_max)``, ``vl`` (B,) the per-run bound on the estimated speed; ``sat`` (B,) is 1
    where a run's command saturated, ``V`` (n, B) receives the estimated inertial velocities
    ``p̂'``. ``d`` is the estimate's offset (or, for ``Guidance.on_truth``, the truth's ``δ``).

    Parameters
    ----------
    U, V, sat : ndarray, shapes (n, B), (n, B), (B,)
        Receive the commands [m/s²], the estimated inertial velocities [m/s], the saturation.
    c, d : ndarray, shapes (2n, B), (m, B)
        The runs' responses to their corrections and the estimate's offsets.
    ref, kr, has_ref
        As for :func:`buffer_truth`.
    xplan, nuplan, uplan : ndarray, shapes (N, m), (N, n), (N, n)
        The plan's states, inertial velocities and inputs.
    k : int
        The sample.
    amax : ndarray, shape (n,)
        The guidance's acceleration bounds [m/s²].
    gains : tuple of float
        ``(Kp, Kd, v_max)``.
    vl : ndarray, shape (B,)
        The runs' bounds on the estimated speed [m/s].
    hk : float
        The step [s].
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    """
    B = c.shape[1]
    kp, kd, vmax = gains
    for b in range(B):
        sat[b] = 0.0
    for i in range(n):
        a = amax[i]
        xp, vp, up = xplan[k, i], nuplan[k, i], uplan[k, i]
        for b in range(B):
            ep = c[i, b] + d[i, b]
            ev = c[n + i, b] + d[n + i, b] + (d[2 * n + i, b] if cur else 0.0)
            V[i, b] = vp + ev
            if has_ref:
                u = ref[kr, 2 * n + i, b] + kp * (ref[kr, i, b] - xp - ep)
                u += kd * (ref[kr, n + i, b] - V[i, b])
            else:
                u = up - kp * ep - kd * ev
            if u > a or u < -a:
                u = a if u > 0 else -a
                sat[b] = 1.0
            U[i, b] = u
    if vmax < math.inf:
        for b in range(B):
            lim2 = vl[b] * (1.0 + SPEED_SLACK)
            lim2 *= lim2
            vp2 = 0.0
            for i in range(n):
                v = V[i, b] + hk * U[i, b]
                vp2 += v * v
            if vp2 > lim2:  # project v̂ + h u onto the speed ball, then the box again
                sat[b] = 1.0
                f = vl[b] / math.sqrt(vp2)
                for i in range(n):
                    u = ((f - 1.0) * V[i, b] + f * hk * U[i, b]) / hk
                    U[i, b] = min(max(u, -amax[i]), amax[i])


@inline
def propagate(c, d, dl, U, sat, tm, uplan, alim, k, hk, n, cur, L, sc, z, kz):
    """``c``, ``d``, ``δ`` of every run from sample ``k`` to ``k + 1`` with the commands ``U``;
    the saturation count and the largest ``|u_i| / accel_i`` go to the metrics ``tm``.

    Parameters
    ----------
    c, d, dl : ndarray, shapes (2n, B), (m, B), (m, B)
        The runs' ``c``, ``d`` and ``δ``, updated in place.
    U, sat : ndarray, shapes (n, B), (B,)
        The commands [m/s²] and whether they saturated (:func:`guide`).
    tm : ndarray, shape (B, N_TM)
        The runs' truth metrics, updated.
    uplan : ndarray, shape (N, n)
        The plan's inputs [m/s²].
    alim : ndarray, shape (n,)
        The truth's acceleration limits [m/s²] (inf: none).
    k : int
        The sample.
    hk : float
        The step [s].
    n : int
        Spatial dimension.
    cur : bool
        Whether the state has the current ``v_f``.
    L, sc : ndarray, shapes (m, r), (m,)
        The process-noise factor and its step scaling ``h_k^expo``.
    z : ndarray, shape (K, r, B)
        Process-noise normals.
    kz : int
        Row of ``z`` of this step.
    """
    B = c.shape[1]
    m, r = L.shape
    h2 = 0.5 * hk * hk
    for b in range(B):
        tm[b, TM_SAT] += sat[b]
    for i in range(n):
        up, inv_a = uplan[k, i], 1.0 / alim[i]
        for b in range(B):
            du = U[i, b] - up
            tm[b, TM_ACCEL] = max(tm[b, TM_ACCEL], abs(U[i, b]) * inv_a)
            c[i, b] += hk * c[n + i, b] + h2 * du
            c[n + i, b] += hk * du
            if cur:
                d[i, b] += hk * (d[n + i, b] + d[2 * n + i, b])
                dl[i, b] += hk * (dl[n + i, b] + dl[2 * n + i, b])
            else:
                d[i, b] += hk * d[n + i, b]
                dl[i, b] += hk * dl[n + i, b]
    for i in range(m):
        s = sc[i]
        for j in range(r):
            lij = s * L[i, j]
            if lij != 0.0:
                for b in range(B):
                    dl[i, b] += lij * z[kz, j, b]


@jit
def nav_run(pt, gn, st, io, z, ref, ka, has_ref, k_from, k_to):
    """Steps ``k_from → k_to`` (no epoch or record strictly between them): guidance, then ``c``,
    ``d``, ``δ`` step, then the new sample's truth is buffered. One call per gap between events,
    the bundles unpacked once: per step only arrays are passed to the inlined parts.

    Parameters
    ----------
    pt, gn, st, io : NavPath, NavGains, NavState, NavIO
        The bundles (module docstring; built by :mod:`obsplan.estimation.montecarlo.closedloop`).
    z : ndarray, shape (K, r, B)
        Process-noise normals of the steps from ``ka``.
    ref : ndarray, shape (K + 1, 3n, B)
        The runs' references from sample ``ka`` (used when ``has_ref``).
    ka : int
        The sample the rows of ``z`` and ``ref`` start at.
    has_ref : bool
        The runs follow ``ref`` (else the plan).
    k_from, k_to : int
        The samples the steps go from and to.
    """
    n, cur, h, expo = pt.n, pt.cur, pt.h, pt.expo
    xplan, nuplan, uplan, amax, alim, L = pt.xplan, pt.nuplan, pt.uplan, gn.amax, pt.alim, pt.L
    c, d, dl, U, V, sat, sc, pos = st.c, st.d, st.dl, st.u, st.nu, st.sat, st.sc, st.pos
    vl = st.vl
    tm, xb = io.tm, io.xb
    gains = (gn.kp, gn.kd, gn.vmax)
    on_truth = gn.truth != 0.0
    m = L.shape[0]
    for k in range(k_from, k_to):
        hk = h[k]
        if pt.scaled and hk != st.hp[0]:  # uniform grids: one power per run of steps
            st.hp[0] = hk
            for i in range(m):
                sc[i] = hk ** expo[i]
        kr = k - ka
        guide(
            U,
            V,
            sat,
            c,
            dl if on_truth else d,
            ref,
            kr,
            has_ref,
            xplan,
            nuplan,
            uplan,
            k,
            amax,
            gains,
            vl,
            hk,
            n,
            cur,
        )
        propagate(c, d, dl, U, sat, tm, uplan, alim, k, hk, n, cur, L, sc, z, kr)
        buffer_truth(xb, pos[3], xplan, nuplan, c, dl, ref, kr + 1, has_ref, k + 1, n, cur)
        pos[3] += 1
        if pos[3] == xb.shape[1]:
            flush_metrics(pt, st, io, k + 1)


@jit
def navigate(pt, gn, st, io, z, ref, ka, has_ref, k_end):
    """Advance the batch from ``st.pos`` to sample ``k_end`` (its measurement included, its
    command not). ``z`` (K, r, B) are the process-noise normals of steps ``ka ..``, ``ref``
    (K + 1, 3n, B) the runs' references ``(p, p', u)`` from sample ``ka`` (``has_ref``; else the
    plan). The truth of a sample is buffered for the metrics when the step to it is taken
    (sample 0 here); the measurement does not change the truth, so the order is free.

    Parameters
    ----------
    pt, gn, st, io : NavPath, NavGains, NavState, NavIO
        The bundles (module docstring; built by :mod:`obsplan.estimation.montecarlo.closedloop`).
    z, ref, ka, has_ref
        As for :func:`nav_run`.
    k_end : int
        The sample to advance to.
    """
    k, phase, e_last = st.pos[0], st.pos[1], st.pos[2]
    while True:
        if phase == 0:
            if k == 0:
                buffer_truth(
                    io.xb, 0, pt.xplan, pt.nuplan, st.c, st.dl, ref, 0, has_ref, 0, pt.n, pt.cur
                )
                st.pos[3] = 1
            e = pt.ep_of[k]
            if e >= 0:
                nav_measure(pt, gn, st, io, k, e)
                e_last = e
            ri = pt.rec_of[k]
            if ri >= 0:
                nav_record(pt, st, io, k, ri, e_last)
            phase = 1
        if k >= k_end:
            break
        k_next = min(k_end, pt.nxt[k])
        nav_run(pt, gn, st, io, z, ref, ka, has_ref, k, k_next)
        k = k_next
        phase = 0
    st.pos[0], st.pos[1], st.pos[2] = k, phase, e_last
    flush_metrics(pt, st, io, k)


def empty_reference(n: int, B: int) -> np.ndarray:
    """Placeholder for ``ref`` when the runs follow the plan.

    Parameters
    ----------
    n : int
        Spatial dimension.
    B : int
        Number of runs in the batch.

    Returns
    -------
    ndarray, shape (1, 3n, B)
        Zeros (the reference layout of :func:`navigate`: ``(p, p', u)`` per run).
    """
    return np.zeros((1, 3 * n, B))
