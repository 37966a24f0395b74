"""Measurement epochs of a schedule and the exact composed predictions between them.

The filters only do work where something happens: at a *measurement epoch* (a sample where at
least one sensor reports; sample 0 always is one) and at a *record* (a sample where statistics are
taken). Between two epochs ``a < b`` the ``k = b - a`` steps of the per-step model
``x_{j+1} = (I + h_j A) x_j + G_j u_j + w_j`` (``A² = 0`` on ``(p, v[, v_f])``) compose exactly:

    F_ab = I + T A,                               T = t_b - t_a
    g_ab = Σ_j (I + τ_j A) G_j u_j,                τ_j = t_b - t_{j+1}
    Q_ab = Σ_j (I + τ_j A) q (I + τ_j A)ᵀ = S0 q + S1 (A q + q Aᵀ) + S2 A q Aᵀ

with ``S0 = k``, ``S1 = Σ τ_j``, ``S2 = Σ τ_j²`` (on a uniform grid ``S1 = h k(k-1)/2`` and
``S2 = h² (k-1)k(2k-1)/6``). With the physical process noise (an intensity ``W``,
:mod:`obsplan.estimation.config`) the same form holds with ``q = W`` and the continuous integral
``S0 = T``, ``S1 = T²/2``, ``S2 = T³/3`` over the whole gap, whatever the steps inside it.
:class:`EpochPlan` holds these per segment, computed once per trajectory (independent of the
runs), vectorised over all steps.

When the per-step noise gain depends on the step (the augmented KF's process-noise coupling,
:mod:`obsplan.estimation.filters.kf`), ``Q_ab = Σ_j M(σ_j) q M(σ_j)ᵀ`` with ``M`` a polynomial of
degree ≤ 4 in ``σ_j = t_{j+1} - t_a``: the sum is computed exactly by a discrete Gauss rule of
``min(k, 5)`` nodes (exact to degree 9) for the measure ``Σ_j δ(σ - σ_j)``, also stored here.
With the physical noise the sum is the integral ``∫_0^T M(σ) W M(σ)ᵀ dσ``, of degree ≤ 6 in
``σ``: the 5-node Gauss–Legendre rule on ``[0, T]`` is exact.

A moving beacon
---------------
With ``EstimationConfig.beacon_path`` (a :class:`~obsplan.model.beacon.BeaconPath`, linearly
interpolated) every range is taken to the beacon's position at its *transmission*: a range is a
one-way travel time, so the reading at epoch ``t_e`` left the beacon at ``t_e - r/c``
(:data:`SOUND_SPEED` ``c = 1500`` m/s). :func:`epoch_beacons` fixes these positions once per
trajectory, with ``r`` the range of the *nominal* path (a fixed point, three iterations: each
contracts by ``|b'|/c``, about 1e-3); the truth, the filters and the posterior CRB all range to
the same ``(E, n)`` array. What this neglects is the beacon's motion during the difference of the
true and the nominal travel times: ``|b'| |r_true - r_nom| / c``, 1.3 mm for a beacon at 2 m/s and
a true path 1 m off the nominal (against ``|b'| r / c`` = 1.3 m at 1 km had the beacon been taken
at the reception epoch). Before the path's first sample (the first ``r/c`` seconds) its first
position is held. The truth's metrics (closest approach) use the beacon at each sample's own time
(:func:`sample_beacons`). A fixed beacon is the single row ``(1, n)``, broadcast by the kernels:
its results are those of the model's beacon, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.schedule import Schedule
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.trajectory.sampled import Trajectory

#: Nodes of the discrete Gauss rule per segment (exact for polynomials of degree ≤ 9).
GAUSS_NODES = 5
#: Default bound on the number of recorded samples (see :func:`record_samples`).
MAX_RECORDS = 1000
#: Speed of sound [m/s] turning a range into its one-way travel time (module docstring).
SOUND_SPEED = 1500.0
#: Fixed-point iterations of the transmission time (each contracts the error by ``|b'|/c``).
TRANSMIT_ITERATIONS = 3


def _covered(path: BeaconPath, t: np.ndarray) -> None:
    path.check_covers(float(t[0]), float(t[-1]), "beacon_path", error=ConfigError)


def epoch_beacons(
    model: VehicleModel, path: BeaconPath | None, t: np.ndarray, p: np.ndarray
) -> np.ndarray:
    """The beacon position each range of epochs ``t`` is taken to (module docstring).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (its fixed beacon when ``path`` is None).
    path : BeaconPath or None
        The moving beacon; None: the model's fixed beacon.
    t : ndarray, shape (E,)
        Epoch (reception) times [s], increasing.
    p : ndarray, shape (E, n)
        Nominal vehicle positions at the epochs [m].

    Returns
    -------
    ndarray, shape (E, n), or (1, n) for a fixed beacon
        Beacon positions at the transmission times [m], C-contiguous.

    Raises
    ------
    ConfigError
        A path that does not cover ``t``.
    """
    if path is None:
        return np.ascontiguousarray(model.beacon_array[None, :])
    t = np.asarray(t, float)
    _covered(path, t)
    ts = t
    for _ in range(TRANSMIT_ITERATIONS):
        b = path.position(np.maximum(ts, path.start))
        ts = t - np.linalg.norm(np.asarray(p, float) - b, axis=1) / SOUND_SPEED
    return np.ascontiguousarray(path.position(np.maximum(ts, path.start)))


def sample_beacons(model: VehicleModel, path: BeaconPath | None, t: np.ndarray) -> np.ndarray:
    """The beacon position at each sample time ``t`` (the truth's closest approach).

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (its fixed beacon when ``path`` is None).
    path : BeaconPath or None
        The moving beacon; None: the model's fixed beacon.
    t : ndarray, shape (N,)
        Sample times [s], increasing.

    Returns
    -------
    ndarray, shape (N, n), or (1, n) for a fixed beacon
        Beacon positions [m], C-contiguous.

    Raises
    ------
    ConfigError
        A path that does not cover ``t``.
    """
    if path is None:
        return np.ascontiguousarray(model.beacon_array[None, :])
    _covered(path, np.asarray(t, float))
    return np.ascontiguousarray(path.position(t))


def record_samples(n_samples: int, record_every: int | None) -> np.ndarray:
    """Samples where statistics are recorded: every ``record_every``-th and the last.

    ``None`` records every ``max(1, N // MAX_RECORDS)``-th sample (about ``MAX_RECORDS`` points).

    Parameters
    ----------
    n_samples : int
        Number of samples ``N`` of the trajectory.
    record_every : int or None
        Stride between recorded samples; None: chosen from :data:`MAX_RECORDS`.

    Returns
    -------
    ndarray of int, shape (Nr,)
        Indices of the recorded samples, increasing, the last one ``N - 1``.

    Raises
    ------
    ConfigError
        If ``record_every`` is below 1.
    """
    stride = max(1, n_samples // MAX_RECORDS) if record_every is None else int(record_every)
    if stride < 1:
        raise ConfigError(
            f"record_every must be a positive number of samples, got {record_every!r}"
        )
    rec = np.zeros(n_samples, dtype=bool)
    rec[::stride] = True
    rec[-1] = True
    return np.flatnonzero(rec)


def _gauss_rule(sigma: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray]:
    """``K``-node Gauss rule of the discrete measure ``Σ δ(σ - σ_j)`` (Stieltjes + Golub–Welsch).

    Exact for polynomials of degree ``≤ 2K - 1``; ``σ`` is scaled to ``[0, 1]`` for conditioning.
    """
    T = float(sigma.max())
    x = sigma / T
    p_prev = np.zeros_like(x)
    p = np.ones_like(x)
    alpha = np.zeros(K)
    beta = np.zeros(K)
    norm_prev = 1.0
    for j in range(K):
        norm = float(p @ p)
        alpha[j] = float((x * p) @ p) / norm
        if j > 0:
            beta[j] = norm / norm_prev
        p, p_prev = (x - alpha[j]) * p - beta[j] * p_prev, p
        norm_prev = norm
    J = np.diag(alpha) + np.diag(np.sqrt(beta[1:]), 1) + np.diag(np.sqrt(beta[1:]), -1)
    lam, V = np.linalg.eigh(J)
    return lam * T, sigma.size * V[0] ** 2


@dataclass(frozen=True, eq=False)
class SegmentTable:
    """Composed predictions over segments ``(a_i, b_i]`` of a trajectory (arrays of length S).

    Attributes
    ----------
    T : (S,)
        ``t_b - t_a`` [s].
    sums : (S, 3)
        ``S0, S1, S2`` (count, ``Σ τ_j``, ``Σ τ_j²``).
    dp, dv : (S, n)
        Position and velocity increments of the inputs, ``g_ab`` [m, m/s].
    tau_a : (S,)
        ``t_a - t_0`` [s].
    nodes, weights : (S, GAUSS_NODES)
        Discrete Gauss rule over ``σ_j = t_{j+1} - t_a`` (unused entries have weight 0).
    """

    T: np.ndarray
    sums: np.ndarray
    dp: np.ndarray
    dv: np.ndarray
    tau_a: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray

    def packed(self) -> np.ndarray:
        """Rows ``T, S0, S1, S2, τ_a, dp, dv`` (the kernels' table layout), shape (S, 5 + 2n).

        Returns
        -------
        ndarray, shape (S, 5 + 2n)
            The table, C-contiguous (layout: :mod:`obsplan.estimation.kernels`).
        """
        return np.ascontiguousarray(
            np.column_stack([self.T, self.sums, self.tau_a, self.dp, self.dv])
        )

    def rule(self) -> np.ndarray:
        """Gauss nodes and weights, shape (S, 2, GAUSS_NODES).

        Returns
        -------
        ndarray, shape (S, 2, GAUSS_NODES)
            ``[:, 0]`` the nodes ``σ`` [s], ``[:, 1]`` the weights; C-contiguous.
        """
        return np.ascontiguousarray(np.stack([self.nodes, self.weights], axis=1))


def segment_table(
    traj: Trajectory, a: np.ndarray, b: np.ndarray, rules: bool, continuous: bool = False
) -> SegmentTable:
    """:class:`SegmentTable` of the segments ``a_i → b_i`` (sample indices, ``a_i ≤ b_i``).

    Empty segments (``a = b``) are the identity. ``rules`` computes the Gauss rules (only the
    augmented KF needs them); ``continuous`` the noise sums and rules of an intensity (module
    docstring) instead of per-step noise.

    Parameters
    ----------
    traj : Trajectory
        The sampled path (times [s] and held inputs [m/s²]).
    a, b : ndarray of int, shape (S,)
        First and last sample of each segment.
    rules : bool
        Compute the Gauss rules.
    continuous : bool, optional
        Noise sums of an intensity instead of per-step noise.

    Returns
    -------
    SegmentTable
        The composed predictions of the segments.
    """
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    S = a.size
    n = traj.dim
    t = traj.t
    h = np.diff(t)
    k = b - a
    T = t[b] - t[a]
    sums = np.zeros((S, 3))
    dp = np.zeros((S, n))
    dv = np.zeros((S, n))
    nodes = np.zeros((S, GAUSS_NODES))
    weights = np.zeros((S, GAUSS_NODES))
    nz = np.flatnonzero(k > 0)
    if nz.size:
        # the steps of every non-empty segment, concatenated (segments may overlap: records)
        seg = np.repeat(nz, k[nz])
        starts = np.concatenate([[0], np.cumsum(k[nz])[:-1]])
        j = a[seg] + (np.arange(seg.size) - np.repeat(starts, k[nz]))
        tau = t[b[seg]] - t[j + 1]
        hu = h[j, None] * traj.u[j]
        sums[nz, 0] = k[nz]
        sums[nz, 1] = np.add.reduceat(tau, starts)
        sums[nz, 2] = np.add.reduceat(tau * tau, starts)
        dv[nz] = np.add.reduceat(hu, starts, axis=0)
        dp[nz] = np.add.reduceat((0.5 * h[j] + tau)[:, None] * hu, starts, axis=0)
        if continuous:
            sums[:, 0], sums[:, 1], sums[:, 2] = T, 0.5 * T**2, T**3 / 3.0
            if rules:
                x, w = np.polynomial.legendre.leggauss(GAUSS_NODES)
                nodes[nz] = 0.5 * T[nz, None] * (x + 1.0)
                weights[nz] = 0.5 * T[nz, None] * w
        elif rules:
            sigma = t[j + 1] - t[a[seg]]
            small = k[nz] <= GAUSS_NODES  # the points themselves: exact
            col = np.arange(seg.size) - np.repeat(starts, k[nz])
            in_small = np.repeat(small, k[nz])
            nodes[seg[in_small], col[in_small]] = sigma[in_small]
            weights[seg[in_small], col[in_small]] = 1.0
            cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
            for i, s0 in zip(nz[~small], starts[~small], strict=True):
                sg = sigma[s0 : s0 + k[i]]
                x = sg / sg[-1]
                # uniform grids repeat the same normalised points: one rule per shape
                key = np.round(x, 12).tobytes()
                rule = cache.get(key)
                if rule is None:
                    rule = cache.setdefault(key, _gauss_rule(x, GAUSS_NODES))
                nodes[i] = rule[0] * sg[-1]
                weights[i] = rule[1]
    return SegmentTable(
        T=T, sums=sums, dp=dp, dv=dv, tau_a=t[a] - t[0], nodes=nodes, weights=weights
    )


@dataclass(frozen=True, eq=False)
class EpochPlan:
    """Where the filters work along one trajectory: epochs, records and their segments.

    Attributes
    ----------
    epochs : (E,) int
        Samples where at least one sensor reports (``epochs[0] == 0``).
    reports : (E, S) bool
        Which sensor (in ``Schedule.sensors`` order) reports at each epoch.
    segments : SegmentTable
        Row ``e`` composes ``epochs[e-1] → epochs[e]`` (row 0 is empty).
    records : (Nr,) int
        Recorded samples.
    rec_base : (Nr,) int
        Index of the last epoch at or before each record.
    rec_segments : SegmentTable
        ``epochs[rec_base] → records`` (empty where a record is an epoch).
    points : (P,) int
        Samples where the truth is needed (epochs and records, sorted).
    epoch_pt, rec_pt : (E,), (Nr,) int
        Index of each epoch / record in ``points``.
    seg_tab, seg_rule, rec_tab : ndarray
        ``segments`` and ``rec_segments`` in the kernels' packed layout.
    continuous : bool
        The noise sums are those of an intensity (physical noise), not of per-step noise.
    """

    epochs: np.ndarray
    reports: np.ndarray
    segments: SegmentTable
    records: np.ndarray
    rec_base: np.ndarray
    rec_segments: SegmentTable
    points: np.ndarray
    epoch_pt: np.ndarray
    rec_pt: np.ndarray
    seg_tab: np.ndarray
    seg_rule: np.ndarray
    rec_tab: np.ndarray
    continuous: bool = False

    @property
    def n_epochs(self) -> int:
        return int(self.epochs.size)


def epoch_plan(
    traj: Trajectory,
    schedule: Schedule,
    records: np.ndarray,
    rules: bool = True,
    continuous: bool = False,
) -> EpochPlan:
    """The :class:`EpochPlan` of ``schedule`` on ``traj`` with recorded samples ``records``
    (``continuous``: noise sums of an intensity, :func:`segment_table`).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    schedule : Schedule
        Which sensor reports at which sample.
    records : ndarray of int, shape (Nr,)
        Recorded samples (:func:`record_samples`).
    rules : bool, optional
        Compute the Gauss rules of the segments (the augmented KF needs them).
    continuous : bool, optional
        Noise sums of an intensity (physical process noise) instead of per-step noise.

    Returns
    -------
    EpochPlan
        The epochs, records and their composed segments.
    """
    any_report = np.array(schedule.mask.any(axis=1), dtype=bool)
    any_report[0] = True
    epochs = np.flatnonzero(any_report).astype(np.int64)
    records = np.asarray(records, dtype=np.int64)
    a = np.concatenate([[0], epochs[:-1]])
    segs = segment_table(traj, a, epochs, rules, continuous)
    rec_base = np.searchsorted(epochs, records, side="right") - 1
    rec_segs = segment_table(traj, epochs[rec_base], records, False, continuous)
    points = np.union1d(epochs, records).astype(np.int64)
    return EpochPlan(
        epochs=epochs,
        reports=np.ascontiguousarray(schedule.mask[epochs]),
        segments=segs,
        records=records,
        rec_base=rec_base.astype(np.int64),
        rec_segments=rec_segs,
        points=points,
        epoch_pt=np.searchsorted(points, epochs).astype(np.int64),
        rec_pt=np.searchsorted(points, records).astype(np.int64),
        seg_tab=segs.packed(),
        seg_rule=segs.rule(),
        rec_tab=rec_segs.packed(),
        continuous=bool(continuous),
    )


def input_displacement(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """``d(t_k, t_0)`` of eq. 15 and its rate ``ḋ`` from the inputs alone (exact ZOH), (N, n).

    Parameters
    ----------
    traj : Trajectory
        The sampled path; only its times and inputs are used.

    Returns
    -------
    d : ndarray, shape (N, n)
        Displacement due to the inputs [m].
    d_dot : ndarray, shape (N, n)
        Its rate [m/s].
    """
    z = np.zeros(traj.dim)
    tr = Trajectory.from_inputs(traj.t, z, z, traj.u)
    return tr.p, tr.v


@dataclass(frozen=True, eq=False)
class RunContext:
    """What every run of a Monte Carlo shares: the epoch plan and the monitor's settings.

    Attributes
    ----------
    plan : EpochPlan
    t_rec : (Nr,)
        Recorded times [s].
    d_epochs : (E, 2n)
        Input displacement ``d`` (eq. 15) [m] and its rate ``ḋ`` [m/s] at the epochs.
    threshold_m : float
        Convergence threshold on the position error [m].
    nees_bound : float
        The monitor's bound on one run's NEES (99.9 % quantile of ``χ²(2n)``).
    window_s : float
        The final stretch [s] over which the monitor averages a run's NEES.
    rec_w : (Nr,), optional
        Weight 1 for the records of the subset whose RMSE is reported per run (e.g. samples on
        survey lines), 0 elsewhere; default none (that RMSE is NaN).
    beacons : (E, n) or (1, n), optional
        The beacon each epoch's range is taken to [m] (:func:`epoch_beacons`); one row: a fixed
        beacon; default the origin.
    gate_nis : float, optional
        The filters' innovation gate on the ranges: the largest NIS of a range used
        (:mod:`obsplan.estimation.channel`); default ``inf``, no gate.
    """

    plan: EpochPlan
    t_rec: np.ndarray
    d_epochs: np.ndarray
    threshold_m: float
    nees_bound: float
    window_s: float
    rec_w: np.ndarray | None = None
    beacons: np.ndarray | None = None
    gate_nis: float = math.inf

    def __post_init__(self) -> None:
        if self.rec_w is None:
            object.__setattr__(self, "rec_w", np.zeros(self.t_rec.size))
        if self.beacons is None:
            object.__setattr__(self, "beacons", np.zeros((1, self.d_epochs.shape[1] // 2)))

    @property
    def beacon_moves(self) -> bool:
        """Whether the beacon is given per epoch (a moving beacon)."""
        return self.beacons is not None and self.beacons.shape[0] > 1

    def corrections(self, ce: np.ndarray | None, cr: np.ndarray | None):
        """The kernels' input-correction arrays (empty: open loop).

        Parameters
        ----------
        ce : ndarray, shape (E, 2n, R), or None
            Response ``(p, v)`` of each run to its input corrections at the epochs [m, m/s];
            None: open loop.
        cr : ndarray, shape (Nr, 2n, R), or None
            The same at the records.

        Returns
        -------
        ce, cr : ndarray
            C-contiguous arrays, or empty ``(0, 2n, 1)`` arrays in open loop (layout:
            :mod:`obsplan.estimation.kernels`).
        """
        if ce is None:
            z = np.zeros((0, self.d_epochs.shape[1], 1))
            return z, z
        return np.ascontiguousarray(ce), np.ascontiguousarray(cr)

    @property
    def no_example(self) -> np.ndarray:
        """Placeholder for the kernels' example array when a batch keeps none."""
        return np.zeros((2, 1, self.d_epochs.shape[1]))

    def records_with_truth(self, truth_rec: np.ndarray) -> np.ndarray:
        """The record table with each run's true ``(p, p')`` appended (the kernels' ``rec``).

        ``truth_rec`` (R, Nr, 2n) -> (R, Nr, 5 + 4n).

        Parameters
        ----------
        truth_rec : ndarray, shape (R, Nr, 2n)
            True position [m] and inertial velocity [m/s] of each run at the records.

        Returns
        -------
        ndarray, shape (R, Nr, 5 + 4n)
            The record table of each run, C-contiguous.
        """
        tab = np.broadcast_to(self.plan.rec_tab, (truth_rec.shape[0], *self.plan.rec_tab.shape))
        return np.ascontiguousarray(np.concatenate([tab, truth_rec], axis=2))


def nominal_states(traj: Trajectory, model: VehicleModel, current: np.ndarray) -> np.ndarray:
    """Noise-free true states ``(p, v[, v_f])`` along ``traj``, shape (N, state_dim).

    Parameters
    ----------
    traj : Trajectory
        The sampled path (inertial velocities ``v + v_f``).
    model : VehicleModel
        The vehicle model (with or without current).
    current : ndarray, shape (n,)
        The true current ``v_f`` [m/s] (ignored without current).

    Returns
    -------
    ndarray, shape (N, state_dim)
        Position [m], velocity through the water [m/s] and, with current, ``v_f`` [m/s].
    """
    parts = [traj.p, traj.v - current] if model.current else [traj.p, traj.v]
    if model.current:
        parts.append(np.broadcast_to(current, traj.p.shape))
    return np.hstack(parts)
