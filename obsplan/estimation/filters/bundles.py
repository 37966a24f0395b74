"""Keyword-named argument bundles of the compiled filters (:mod:`obsplan.estimation.kernels`).

A batch kernel takes a handful of bundles instead of thirty positional arrays: each bundle is a
namedtuple of arrays and scalars (numba passes namedtuples as typed tuples), built here by
name from the filter and the run context and unpacked once at the top of the kernel. A bundle
costs the reference counts of all its members per call, so the kernels pass plain arrays to the
helpers they call per epoch; the bundles cross only the Python-numba boundary, once per batch.

Layouts of the arrays are those of :mod:`obsplan.estimation.kernels` (module docstring).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.epochs import RunContext
from obsplan.model.vehicle import VehicleModel

#: What the EKF (and the Gaussian sum's components) predict and update with: the segment table
#: ``tab``, the composed process-noise terms ``qt`` (3, m, m), the transition's packed entries
#: ``tr``, the linear output rows ``lin``, the dimension ``n``, current ``cur``, the beacon of each
#: epoch's range ``beacon`` (E, n) (one row (1, n): a fixed beacon),
#: range form ``half_sq``, the second-order range update ``second`` and the range noise
#: ``sig_r`` [m], the innovation gate on the ranges ``gate`` (the largest NIS used; ``inf``:
#: none) and the indices ``ks`` of the range-scale state and ``kb`` of the range-bias state
#: (-1: none).
EkfModel = namedtuple("EkfModel", "tab qt tr lin n cur beacon half_sq second sig_r gate ks kb")

#: What the augmented KF predicts and updates with: as :data:`EkfModel` plus the segments'
#: Gauss rules ``rule``, the input displacement and rate at the epochs ``ep_d`` (E, 2n), the
#: full augmented noise ``qk``, whether it is diagonal ``qdiag``, the coupling switch
#: ``couple`` and ``inflate`` (``y0_mode="inflate"``), the index ``kc`` of the first chain state
#: ``ks`` of the range-scale state and ``kb`` of the range-bias state (-1: none). With a moving
#: beacon ``tab`` and ``ep_d`` are the relative motion's (:func:`kf_relative`).
KfModel = namedtuple(
    "KfModel", "tab rule ep_d qt qk qdiag couple tr lin n cur beacon sig_r inflate gate kc ks kb"
)

#: The KF's anchors per run: ``y0`` (R,) and their variances ``var0`` (R,).
Anchors = namedtuple("Anchors", "y0 var0")

#: The records: epoch of each ``rec_base`` (Nr,), the per-run table with the truth ``rec``
#: (R, Nr, cols), the navigation noise ``qz`` (2n, 2n), the record times ``t_rec``, the
#: convergence threshold ``thr`` [m], the NEES bound ``bound``, the monitor window ``window``
#: [s] and the records' weights ``rec_w`` of the subset RMSE.
Records = namedtuple("Records", "rec_base rec qz t_rec thr bound window rec_w")

#: Where the statistics go: the group sums ``sums`` (2, Nr, cols), the per-run verdicts
#: ``info`` (R, N_INFO), the run ``ex_run`` whose history is kept in ``ex`` (2, Nr, 2n) (-1:
#: none).
Outputs = namedtuple("Outputs", "sums info ex_run ex")

#: The runs' input corrections (closed loop) at the epochs ``ce`` (E, 2n, R) and the records
#: ``cr`` (Nr, 2n, R); empty arrays: open loop.
Corrections = namedtuple("Corrections", "ce cr")


def ekf_model(model: VehicleModel, ctx: RunContext, filt) -> EkfModel:
    """The :data:`EkfModel` of an EKF ``filt`` on the epochs of ``ctx``.

    Parameters
    ----------
    model : VehicleModel
        The filter's vehicle model.
    ctx : RunContext
        The epochs the runs share.
    filt : ExtendedKalmanFilter
        The filter (its noise terms, transition and linear rows).

    Returns
    -------
    EkfModel
        The bundle (layouts: :mod:`obsplan.estimation.kernels`).
    """
    return EkfModel(
        tab=ctx.plan.seg_tab,
        qt=filt.q_terms,
        tr=filt._tr,
        lin=filt._lin,
        n=int(model.dim),
        cur=bool(model.current),
        beacon=ctx.beacons,
        half_sq=model.range_form == "half-squared",
        second=bool(filt.second_order),
        sig_r=float(filt.noise["range"]),
        gate=float(ctx.gate_nis),
        ks=int(filt.scale_index),
        kb=int(filt.bias_index),
    )


def kf_model(model: VehicleModel, ctx: RunContext, filt) -> KfModel:
    """The :data:`KfModel` of an augmented KF ``filt`` on the epochs of ``ctx``.

    Parameters
    ----------
    model : VehicleModel
        The filter's vehicle model.
    ctx : RunContext
        The epochs the runs share.
    filt : AugmentedKalmanFilter
        The filter (its noise, transition, linear rows and options).

    Returns
    -------
    KfModel
        The bundle (layouts: :mod:`obsplan.estimation.kernels`).

    Raises
    ------
    ConfigError
        A moving beacon whose depth changes, with a depth gauge (:func:`kf_relative`).
    """
    tab, ep_d, lin = kf_relative(model, ctx, filt._lin)
    return KfModel(
        tab=tab,
        rule=ctx.plan.seg_rule,
        ep_d=ep_d,
        qt=filt.q_terms,
        qk=filt.q,
        qdiag=bool(filt.q_diag),
        couple=bool(filt.coupling),
        tr=filt._tr,
        lin=lin,
        n=int(model.dim),
        cur=bool(model.current),
        beacon=ctx.beacons,
        sig_r=float(filt.noise["range"]),
        inflate=filt.y0_mode == "inflate",
        gate=float(ctx.gate_nis),
        kc=int(model.state_dim),
        ks=int(filt.scale_index),
        kb=int(filt.bias_index),
    )


#: First column of the input displacement ``dp`` in a segment table (kernels' ``TAB_G``).
_TAB_DP = 5


def kf_relative(
    model: VehicleModel, ctx: RunContext, lin: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The augmented KF's segment table, input displacement and linear rows relative to a moving
    beacon (unchanged, the same arrays, for a fixed one).

    The KF's positions are ``r = p - b``. With the beacon known at every epoch, its motion is a
    known displacement of ``r`` and nothing else: over segment ``e`` the prediction of ``r`` gains
    ``-(b_e - b_{e-1})`` (``dp`` of the table), and ``r = r0 + ν0 τ + D`` with ``D = d - (b -
    b_0)``, so the range output ``ȳ = y - y0 + ½|D|² = Dᵀr + τ α + ½ τ² β`` keeps the form of
    eq. 21 with ``D`` for ``d`` (``ep_d``'s positions) and ``α = r0·ν0``, ``β = |ν0|²`` of the
    *vehicle's* velocity: the velocity states, the rate ``ḋ`` and the process-noise coupling
    (``r - D = r0 + ν0 τ + n``) are those of a fixed beacon. Exact for any beacon motion sampled
    at the epochs, the impulses of a piecewise-linear path included. A depth gauge reads
    ``r_z + b_z``: its offset is the beacon's depth, which must then be constant.

    Parameters
    ----------
    model : VehicleModel
        The filter's vehicle model.
    ctx : RunContext
        The epochs and the beacon of each (``ctx.beacons``).
    lin : ndarray, shape (outputs, 5)
        The filter's linear rows (depth offset: the model's beacon depth).

    Returns
    -------
    tab : ndarray, shape (E, 5 + 2n)
        Segment table of the relative motion.
    ep_d : ndarray, shape (E, 2n)
        ``(D, ḋ)`` at the epochs [m, m/s].
    lin : ndarray, shape (outputs, 5)
        The linear rows with the depth offset of the beacon's depth.

    Raises
    ------
    ConfigError
        A depth gauge with a beacon whose depth changes along its path.
    """
    if not ctx.beacon_moves:
        return ctx.plan.seg_tab, ctx.d_epochs, lin
    n = int(model.dim)
    b = np.asarray(ctx.beacons, float)
    tab = ctx.plan.seg_tab.copy()
    tab[1:, _TAB_DP : _TAB_DP + n] -= np.diff(b, axis=0)
    ep_d = ctx.d_epochs.copy()
    ep_d[:, :n] -= b - b[0]
    lin = lin.copy()
    if "depth" in model.sensors:
        if np.any(b[:, 2] != b[0, 2]):
            raise ConfigError(
                "the augmented KF with a depth gauge needs the moving beacon at a constant depth "
                f"(its path goes from bz = {b[:, 2].min():g} to {b[:, 2].max():g} m); run the "
                "EKF or the Gaussian sum, or drop the depth gauge"
            )
        lin[model.output_slices["depth"].start, 4] = b[0, 2]
    return np.ascontiguousarray(tab), np.ascontiguousarray(ep_d), lin


def records(ctx: RunContext, truth_rec: np.ndarray, q_nav: np.ndarray) -> Records:
    """The :data:`Records` of ``ctx`` with the true ``(p, p')`` ``truth_rec`` (R, Nr, 2n).

    Parameters
    ----------
    ctx : RunContext
        The records and the monitor's settings.
    truth_rec : ndarray, shape (R, Nr, 2n)
        True position [m] and inertial velocity [m/s] of each run at the records.
    q_nav : ndarray, shape (2n, 2n)
        Per-step process noise of the navigation state
        (:func:`obsplan.estimation.kalman.nav_noise`).

    Returns
    -------
    Records
        The bundle.
    """
    return Records(
        rec_base=ctx.plan.rec_base,
        rec=ctx.records_with_truth(truth_rec),
        qz=q_nav,
        t_rec=ctx.t_rec,
        thr=float(ctx.threshold_m),
        bound=float(ctx.nees_bound),
        window=float(ctx.window_s),
        rec_w=ctx.rec_w,
    )


def outputs(
    ctx: RunContext,
    sums: np.ndarray,
    info: np.ndarray,
    ex_run: int = -1,
    example: np.ndarray | None = None,
) -> Outputs:
    """The :data:`Outputs`; without ``example`` no run's history is kept.

    Parameters
    ----------
    ctx : RunContext
        The run context (its placeholder example array).
    sums : ndarray, shape (2, Nr, cols)
        Group sums the statistics are added to.
    info : ndarray, shape (R, N_INFO)
        Receives the runs' verdicts.
    ex_run : int, optional
        The run whose history is kept (-1: none).
    example : ndarray, shape (2, Nr, 2n), optional
        Receives that run's estimate and std.

    Returns
    -------
    Outputs
        The bundle.
    """
    return Outputs(
        sums=sums,
        info=info,
        ex_run=int(ex_run) if example is not None else -1,
        ex=ctx.no_example if example is None else example,
    )


def corrections(
    ctx: RunContext, corrections: tuple[np.ndarray, np.ndarray] | None = None
) -> Corrections:
    """The :data:`Corrections` (``None``: open loop, the plan's inputs).

    Parameters
    ----------
    ctx : RunContext
        The run context (:meth:`~obsplan.estimation.epochs.RunContext.corrections`).
    corrections : tuple of (ndarray, ndarray) or None, optional
        ``(ce (E, 2n, R), cr (Nr, 2n, R))`` in closed loop; None: open loop.

    Returns
    -------
    Corrections
        The bundle.
    """
    ce, cr = ctx.corrections(*(corrections or (None, None)))
    return Corrections(ce=ce, cr=cr)
