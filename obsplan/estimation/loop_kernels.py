"""Compiled kernel of the closed loop: EKF navigation, guidance and truth, step by step.

One call advances a batch of runs (members on the last axis, as in
:mod:`obsplan.estimation.kernels`) from their current sample to ``k_end``. Per run it carries, at
the current sample ``k`` (:mod:`obsplan.estimation.closedloop`):

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
(:mod:`obsplan.estimation.guidance`) gives ``u_k`` from the estimate and ``c``, ``d``, ``δ``
step to ``k + 1``.

The four parts are compiled separately (each is called once per epoch, record or step for the
whole batch, so the call costs nothing next to the work; one inlined function took minutes to
compile). Argument bundles (namedtuples, built by :mod:`obsplan.estimation.closedloop`):
``pt`` the path (shared by all runs), ``gn`` the gains, ``st`` the runs' state (mutated in place;
``st.pos`` holds ``k``, whether the measurement at ``k`` is done, and the last epoch), ``io`` the
per-run inputs and outputs.
"""

from __future__ import annotations

import math

import numpy as np

from obsplan.estimation.kernels import (
    TAB_G,
    TAB_S0,
    TAB_S1,
    TAB_S2,
    ekf_measure,
    inline,
    jit,
    noise_terms,
    predict,
    record_batch,
    span_metrics,
)
from obsplan.estimation.stats import TM_ACCEL, TM_SAT

#: Relative slack of the speed limit: a plan flown exactly at the bound is not "corrected" for
#: the round-off of its own chord inputs.
SPEED_SLACK = 1e-9


@jit
def nav_measure(pt, st, io, k, e):
    """Epoch ``e`` at sample ``k``: predict the covariance over the gap, the mean ``x_plan + c +
    d``, the readings at the truth, the EKF's updates; then ``d`` and ``ce[e] = c``."""
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
    for i in range(m):
        for b in range(B):
            X[i, b] = pt.xplan[k, i] + st.d[i, b] + (st.c[i, b] if i < n2 else 0.0)
    Y = io.Y
    for b in range(B):  # device readings at the true state x_plan + c + δ
        rho2 = 0.0
        for i in range(n):
            rel = pt.xplan[k, i] + st.c[i, b] + st.dl[i, b] - pt.beacon[i]
            rho2 += rel * rel
        Y[e, 0, b] = math.sqrt(rho2) + io.Yn[e, 0, b]
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
        1,
        st.iw,
        st.ws,
        n,
        pt.beacon,
        pt.half_sq,
        pt.sig_r * pt.sig_r,
        pt.lin,
        io.run_nis,
        io.run_cnt,
    )
    for i in range(m):
        for b in range(B):
            st.d[i, b] = X[i, b] - pt.xplan[k, i] - (st.c[i, b] if i < n2 else 0.0)
    for i in range(n2):
        for b in range(B):
            io.ce[e, i, b] = st.c[i, b]


@jit
def nav_record(pt, st, io, k, ri, e_last):
    """Record ``ri`` at sample ``k``: the truth's ``(p, p')``, ``cr[ri] = c``, the statistics."""
    n = pt.n
    B = st.X.shape[1]
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
        1,
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


@jit
def nav_metrics(pt, st, io, ref, ka, has_ref, k):
    """Buffer the true path's sample ``k`` of each run (reference: the plan or ``ref``) for its
    metrics; a full buffer is added to them (:func:`flush_metrics`)."""
    n = pt.n
    B = st.X.shape[1]
    j = st.pos[3]
    xb = io.xb
    for b in range(B):
        for i in range(n):
            xb[b, j, i] = pt.xplan[k, i] + st.c[i, b] + st.dl[i, b]
            nu = pt.nuplan[k, i] + st.c[n + i, b] + st.dl[n + i, b]
            xb[b, j, n + i] = nu + (st.dl[2 * n + i, b] if pt.cur else 0.0)
            xb[b, j, 2 * n + i] = ref[k - ka, i, b] if has_ref else pt.xplan[k, i]
    st.pos[3] = j + 1
    if j + 1 == xb.shape[1]:
        flush_metrics(pt, st, io)


@jit
def flush_metrics(pt, st, io):
    """Add the buffered samples of every run to its truth metrics."""
    K = st.pos[3]
    for b in range(io.xb.shape[0]):
        span_metrics(io.tm, b, io.xb[b], K, pt.n, pt.beacon, pt.box, pt.has_box)
    st.pos[3] = 0


@inline
def guide(pt, gn, st, ref, ka, has_ref, k, b, hk):
    """The command of run ``b`` at sample ``k`` into ``st.u`` (guidance.py); returns whether it
    saturated. ``st.nu`` receives the estimated inertial velocity."""
    n = pt.n
    c, d = st.c, st.d
    sat = False
    for i in range(n):
        ep = c[i, b] + d[i, b]
        ev = c[n + i, b] + d[n + i, b] + (d[2 * n + i, b] if pt.cur else 0.0)
        st.nu[i] = pt.nuplan[k, i] + ev
        if has_ref:
            kr = k - ka
            dp = ref[kr, i, b] - pt.xplan[k, i] - ep
            dv = ref[kr, n + i, b] - st.nu[i]
            uff = ref[kr, 2 * n + i, b]
        else:
            dp, dv, uff = -ep, -ev, pt.uplan[k, i]
        u = uff + gn.kp * dp + gn.kd * dv
        a = gn.amax[i]
        if u > a or u < -a:
            u = a if u > 0 else -a
            sat = True
        st.u[i] = u
    if gn.vmax < math.inf:
        vp2 = 0.0
        for i in range(n):
            vp = st.nu[i] + hk * st.u[i]
            vp2 += vp * vp
        vmax = gn.vmax
        if vp2 > (vmax * (1.0 + SPEED_SLACK)) ** 2:  # project v̂ + h u onto the speed ball
            sat = True
            f = vmax / math.sqrt(vp2)
            for i in range(n):
                u = ((f - 1.0) * st.nu[i] + f * hk * st.u[i]) / hk
                a = gn.amax[i]
                st.u[i] = min(max(u, -a), a)
    return sat


@jit
def nav_step(pt, gn, st, io, z, ref, ka, has_ref, k):
    """Guidance at sample ``k``, then ``c``, ``d``, ``δ`` of every run step to ``k + 1``."""
    n = pt.n
    m, B = st.X.shape
    L = pt.L
    r = L.shape[1]
    hk = pt.h[k]
    if pt.scaled and hk != st.hp[0]:  # uniform grids: one power per call
        st.hp[0] = hk
        for i in range(m):
            st.sc[i] = hk ** pt.expo[i]
    kz = k - ka
    for b in range(B):
        if guide(pt, gn, st, ref, ka, has_ref, k, b, hk):
            io.tm[b, TM_SAT] += 1.0
        ratio = 0.0
        for i in range(n):
            du = st.u[i] - pt.uplan[k, i]
            ratio = max(ratio, abs(st.u[i]) / pt.alim[i])
            st.c[i, b] += hk * st.c[n + i, b] + 0.5 * hk * hk * du
            st.c[n + i, b] += hk * du
            st.d[i, b] += hk * (st.d[n + i, b] + (st.d[2 * n + i, b] if pt.cur else 0.0))
            st.dl[i, b] += hk * (st.dl[n + i, b] + (st.dl[2 * n + i, b] if pt.cur else 0.0))
        io.tm[b, TM_ACCEL] = max(io.tm[b, TM_ACCEL], ratio)
    if r > 0:
        for i in range(m):
            s = st.sc[i]
            for j in range(r):
                lij = s * L[i, j]
                if lij != 0.0:
                    for b in range(B):
                        st.dl[i, b] += lij * z[kz, j, b]


@jit
def navigate(pt, gn, st, io, z, ref, ka, has_ref, k_end):
    """Advance the batch from ``st.pos`` to sample ``k_end`` (its measurement included, its
    command not). ``z`` (K, r, B) are the process-noise normals of steps ``ka ..``, ``ref``
    (K + 1, 3n, B) the runs' references ``(p, p', u)`` from sample ``ka`` (``has_ref``; else the
    plan)."""
    k, phase, e_last = st.pos[0], st.pos[1], st.pos[2]
    while True:
        if phase == 0:
            e = pt.ep_of[k]
            if e >= 0:
                nav_measure(pt, st, io, k, e)
                e_last = e
            ri = pt.rec_of[k]
            if ri >= 0:
                nav_record(pt, st, io, k, ri, e_last)
            nav_metrics(pt, st, io, ref, ka, has_ref, k)
            phase = 1
        if k >= k_end:
            break
        nav_step(pt, gn, st, io, z, ref, ka, has_ref, k)
        k += 1
        phase = 0
    st.pos[0], st.pos[1], st.pos[2] = k, phase, e_last
    flush_metrics(pt, st, io)


def empty_reference(n: int, B: int) -> np.ndarray:
    """Placeholder for ``ref`` when the runs follow the plan."""
    return np.zeros((1, 3 * n, B))
