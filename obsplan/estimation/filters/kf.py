"""Kalman filter on the augmented linear model (eqs. 19–24; DVL/depth rows of eq. 41), with the
process-noise coupling of its output modelled.

The paper's model
-----------------
``z = (p - b, v[, v_f], α, β)`` with ``α = p0ᵀν0``, ``β = |ν0|²`` (``AugmentedModel``, positions
relative to the beacon ``b``) and the range output

    ȳ = y - y0 + ½|d|² = dᵀp + τ α + ½ τ² β                                         (eq. 19–21)

where ``y = ½ r²`` comes from the range reading (:mod:`obsplan.estimation.sensors`), ``y0`` is the
reading at the first sample, ``d`` the displacement of the known inputs (eq. 15), ``τ = t - t0``.

The process-noise coupling
--------------------------
Eq. 21 holds when ``p = p0 + ν0 τ + d``. With process noise the truth is ``p = p0 + ν0 τ + d + n``
(``n``: the position the noise has added since ``t0``, ``w``: the velocity) and then exactly

    ȳ = dᵀp + τ α + ½ τ² β + e,          e = (p - d)·n - ½|n|²

a term that grows like ``|p| σ_n`` (metres times metres) and is correlated over the whole run, so
a KF that ignores it becomes over-confident on long runs. ``e`` is not Markov by itself, but with
``f = (p - d)·(ν - ḋ) - α - τβ`` and ``g = ½|ν - ḋ|² - ½β`` the triple is: over a step ``h`` whose
noise ``(w_p, w_ν)`` enters at its end,

    e⁺ = e + h f + h² g + c_p·w_p + ½|w_p|²
    f⁺ = f + 2h g     + c_v·w_p + c_p·w_ν + w_p·w_ν          c_p = (p - d)⁻,  c_v = (ν - ḋ)⁻
    g⁺ = g            + c_v·w_ν + ½|w_ν|²

(``⁻``: the noise-free prediction at the step's end). The filter keeps the quadratic terms'
contribution out (they are ``O(q)`` against ``O(|p|² q)``) and evaluates ``c_p``, ``c_v`` at its
own prediction, the usual treatment of a state-dependent noise gain.

Coordinates of the filter
-------------------------
``α``, ``β``, the anchor's error ``β_a = -ε_0`` (``y0_mode="augment"``) and ``e, f, g`` enter the
output only through ``κ = β_a + τα + ½τ²β + e``. With ``φ = α + τβ + f`` and ``γ = ½β + g``

    κ' = φ,   φ' = 2γ,   γ' = 0 (+ noise),     ȳ = dᵀ p + κ

so the filter runs on ``z = (p - b, v[, v_f], κ, φ, γ)``, as many states as the paper's with the
anchor (``κ(t0) = β_a``, ``φ(t0) = α``, ``γ(t0) = ½β``): ``F = I + N`` with the chain
``κ ← φ (T), κ ← γ (T²), φ ← γ (2T)``. Without the coupling this is the paper's KF exactly, in a
time-varying linear change of coordinates (its estimates and covariance of ``(p, v)`` are the
same); the configured noise of ``(α, β)`` enters the chain through ``J(τ) = [[τ, ½τ²], [1, τ],
[0, ½]]``. ``y0_mode="inflate"`` starts ``κ`` known (variance 0) and adds ``var(y0)`` to every
range variance instead (over-confident: the common error is averaged as if independent).

A moving beacon
---------------
With a known beacon path (``EstimationConfig.beacon_path``) the filter keeps its coordinates:
positions relative to the beacon ``r = p - b``, the vehicle's own velocity. The beacon's motion
is then a known displacement of ``r`` alone: with ``D = d - (b - b0)``, ``r = r0 + ν0 τ + D (+
n)`` and ``ȳ = y - y0 + ½|D|² = Dᵀr + τα + ½τ²β`` with ``α = r0·ν0``, ``β = |ν0|²``: eq. 21 with
``D`` for ``d``; the chain, the coupling (``r - D = r0 + ν0 τ + n``) and the velocity rows are
unchanged. It is exact for the beacon sampled at the epochs, however it moves between them (the
velocity jumps of a piecewise-linear path need no impulse: they are inside ``b``), and it is
built by :func:`~obsplan.estimation.filters.bundles.kf_relative`; records add back the beacon of
their epoch. A depth gauge reads ``r_z + b_z``, so it needs the beacon at a constant depth.

A sound-speed scale
-------------------
A sound-speed error scales every range, the anchor's too: ``r_m = k r`` (``k = 1 + s``), so the
measured ``y - y0 = k² (½ r² - ½ r0²) + η - η0`` (``η``: the reading's noise on ``y``). With
``g = k² - 1`` and ``A = ½ r² - ½ r0² = dᵀp + κ - ½|d|²`` the range row becomes

    ȳ = y - y0 + ½|d|² = (1 + g) A + ½|d|² + η

bilinear in the state (the anchor's error enters ``κ`` times ``1 + g``: a term ``g η0`` of
second order is left out). The filter updates with its exact Gaussian moments: the row ``((1 +
ĝ) d, 1 + ĝ, Â)`` on ``(p, κ, g)``, the mean ``(1 + ĝ) Â + P_gA`` and the variance ``R + P_gg
P_AA + P_gA²`` — the second-order filter, exact for a bilinear output under a Gaussian prior
(early on ``P_gg P_AA`` dominates: at 100 m from the beacon with a 10 m position std and the 2 %
scale prior it is about ``(0.04 · 1000 m²)² = 1600 m⁴`` against ``R ≈ 100 m⁴`` for a 0.1 m
range noise). ``g`` is
the filter's last state, constant, with prior ``N(0, (2 σ_s)²)`` for a scale prior ``N(1,
σ_s²)`` (``g ≈ 2 s``). It is observable only where ``A`` is not a quadratic in time, i.e.
where the path manoeuvres, as the EKF's scale state. Using the *measured* ``y - y0`` as the
coefficient of a linear scale row instead would keep the filter linear but correlate that
coefficient with the reading's own noise (an errors-in-variables bias of ``g`` towards
``-1``, large on short noisy runs).

A range bias
------------
A clock offset adds ``β_r`` to every range, the anchor's too: ``r_m = k r + β_r + ε``. With the
scaled true ranges ``R_t = k r(t)``, ``R_0 = k r(t_0)`` the measured ``y - y0 = ½ r_m² - ½ r_0²``
(``r_0`` the anchor's reading) is

    y - y0 = W + β_r (R_t - R_0) + (R_t + β_r) ε + ...,     W = ½ R_t² - ½ R_0² = (1 + g) A

(exactly: ``½ (R + β_r)² = ½ R² + β_r R + ½ β_r²``, the ``½ β_r²`` cancels in the difference), and
``R_0 = r_0 - β_r`` (the anchor's noise left out), ``R_t = sqrt(R_0² + 2 W)``. The row is
linearised at the prior as the EKF's: on ``W``'s states the row above times ``1 + β̂_r/R_t``, on
``β_r`` ``R_t - R_0 + β̂_r (1 - R_0/R_t)``, the prediction adds ``β̂_r (R_t - R_0)``; the reading's
variance is unchanged (the noise's coefficient ``R_t + β_r`` is the measured range). ``β_r`` is the
filter's last state, constant, with prior ``N(0, σ_β²)``. The exact identity
``y - y0 = W + β_r (r_m - r_0)`` would keep the row linear, but its coefficient ``r_m - r_0``
carries the reading's own noise: where the chain's free polynomial explains the range's
change, what is left of the coefficient is that noise, correlated with the reading's, and the
estimate of ``β_r`` is biased by a sizeable fraction of the range (errors in variables), so the
predicted ``R_t - R_0`` is used instead.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation import kalman
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.config import EstimationConfig, ProcessNoise, Y0Mode
from obsplan.estimation.filters import bundles
from obsplan.estimation.filters.base import Filter, FilterRun, register
from obsplan.model.vehicle import VehicleModel
from obsplan.observability.gramian import augmented_model


def anchor(r0: np.ndarray | float, sigma_r: float) -> tuple[np.ndarray, np.ndarray]:
    """``y0 = ½ r0² - ½ σ²`` and its variance ``r0² σ² + ½ σ⁴`` from the first range reading.

    Parameters
    ----------
    r0 : float or ndarray
        First range reading(s) [m].
    sigma_r : float
        Standard deviation of the range noise [m].

    Returns
    -------
    y0 : ndarray
        The anchor ``y0`` [m²], unbiased.
    var0 : ndarray
        Its variance [m⁴].
    """
    r0 = np.asarray(r0, float)
    return 0.5 * r0**2 - 0.5 * sigma_r**2, r0**2 * sigma_r**2 + 0.5 * sigma_r**4


@register
class AugmentedKalmanFilter(Filter):
    """Augmented KF of one vehicle model (module docstring).

    Parameters
    ----------
    model : VehicleModel
        Vehicle model (sensors, current, beacon); the KF always uses ``ȳ`` built from ``½ r²``.
    q, p0 : ndarray
        Per-step process-noise and initial covariances of the paper's augmented state
        ``(p, v[, v_f], α, β)``, shape ``(2n+2, 2n+2)`` (or ``(3n+2, ...)`` with current).
    noise : dict of str to float
        Standard deviation per sensor (range [m] on ``r``).
    y0_mode : {"augment", "inflate"}, optional
        ``"augment"`` or ``"inflate"`` (module docstring).
    coupling : bool, optional
        Model the process-noise coupling ``e`` of the output (default); ``False`` is the paper's
        output model.
    scale_std : float or None, optional
        With a value, the state gets a last entry ``g = k² - 1`` of the range scale ``k``
        (``1 + s`` of a sound-speed error), constant, with prior ``N(0, (2 scale_std)²)``
        (module docstring, "A sound-speed scale"). None (default): no scale state.
    bias_std : float or None, optional
        With a value [m], the state gets a last entry ``β_r``, a range bias (a clock offset's
        ``c Δt``), constant, with prior ``N(0, bias_std²)`` (module docstring, "A range bias").
        None (default): none.
    """

    name = "kf"
    description = "Kalman filter on the augmented linear model (process-noise coupling modelled)"

    def __init__(
        self,
        model: VehicleModel,
        q: np.ndarray,
        p0: np.ndarray,
        noise: dict[str, float],
        y0_mode: Y0Mode = "augment",
        coupling: bool = True,
        scale_std: float | None = None,
        bias_std: float | None = None,
    ) -> None:
        self.model = model
        self.p0 = np.array(p0, dtype=float)
        n, mx = model.dim, model.state_dim
        self.aug = augmented_model(model)
        #: the prior std of the scale state ``g`` (``2 scale_std``: ``g ≈ 2 s``), None: none
        self.scale_g_std = None if scale_std is None else 2.0 * float(scale_std)
        #: the index of the scale state ``g``, -1 without one
        self.scale_index = -1 if scale_std is None else mx + 3
        #: the prior std [m] of the range-bias state, None: none
        self.bias_std = None if bias_std is None else float(bias_std)
        self.state_dim = mx + 3 + (scale_std is not None) + (bias_std is not None)
        #: the index of the range-bias state, -1 without one
        self.bias_index = -1 if bias_std is None else self.state_dim - 1
        self.noise = dict(noise)
        self.y0_mode = y0_mode
        self.coupling = bool(coupling)
        self.q = np.ascontiguousarray(q, dtype=float)
        self.q_diag = not np.any(self.q - np.diag(np.diag(self.q)))
        qx = self.q[:mx, :mx]
        self.q_terms = kalman.composed_noise_terms(qx, n, model.current)
        self.q_nav = kalman.nav_noise(qx, n, model.current)
        kc = mx  # κ, φ, γ follow the kinematic states
        self.transition = kalman.Transition.build(
            kalman.kinematic_entries(n, model.current)
            + [(kc, kc + 1, 1.0, 1), (kc, kc + 2, 1.0, 2), (kc + 1, kc + 2, 2.0, 1)]
        )
        #: The beacon [m] the relative positions start from: the model's, or a moving beacon's
        #: at the first range (set by the Monte Carlo's ``PathSetup``; :func:`bundles.kf_relative
        #: <obsplan.estimation.filters.bundles.kf_relative>` moves it with the beacon).
        self.origin = model.beacon_array
        bz = model.beacon_array[2] if model.dim == 3 else 0.0
        self.rows = kalman.linear_rows(model, self.noise, bz)
        self._tr, self._lin = self.transition.packed(), self.rows.packed()

    @classmethod
    def from_config(
        cls, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise
    ) -> AugmentedKalmanFilter:
        """The augmented KF of ``config`` (``p0_kf``, ``q_kf``, ``y0_mode``, ``kf_coupling``,
        ``scale_prior_std``, ``bias_prior_std``).

        Parameters
        ----------
        config : EstimationConfig
            The model, sensor noises and filter options.
        cov : dict of str to ndarray
            Initial covariances ``p0_ekf``, ``p0_kf`` (:meth:`EstimationConfig.covariances
            <obsplan.estimation.config.EstimationConfig.covariances>`).
        pn : ProcessNoise
            Process noise: per-step covariances or intensities, as the epoch plan it runs on.

        Returns
        -------
        AugmentedKalmanFilter
            The filter.
        """
        return cls(
            config.model,
            pn.q_kf,
            cov["p0_kf"],
            dict(config.noise),
            config.y0_mode,
            config.kf_coupling,
            config.scale_prior_std,
            config.bias_prior_std,
        )

    def to_chain(self, mz: int) -> np.ndarray:
        """``M`` with ``z_chain(t0) = M (p - b, v[, v_f], α, β)``: ``φ = α``, ``γ = ½β``, ``κ = 0``
        (the anchor's variance is added to ``κ`` by :meth:`start`; the scale's and the bias's
        rows are zero).

        Parameters
        ----------
        mz : int
            Size of the paper's augmented state (``2n + 2``, or ``3n + 2`` with current).

        Returns
        -------
        ndarray, shape (state_dim, mz)
            The map to the filter's chain coordinates.
        """
        mx = self.model.state_dim
        M = np.zeros((self.state_dim, mz))
        M[:mx, :mx] = np.eye(mx)
        M[mx + 1, mx] = 1.0
        M[mx + 2, mx + 1] = 0.5
        return M

    def start(
        self, xhat0: np.ndarray, extra0: np.ndarray | None = None, r0: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, float, float]:
        """``(z0, P0, y0, var0)`` of the filter (``P0``: ``p0`` in chain coordinates, with the
        anchor's variance in ``augment`` mode).

        Parameters
        ----------
        xhat0 : ndarray, shape (state_dim of the model,)
            Initial estimate of ``(p, v[, v_f])`` (absolute positions).
        extra0 : ndarray, shape (2,), optional
            Initial estimates of ``(p0ᵀν0, |ν0|²)``; by default computed from ``xhat0``.
        r0 : float, optional
            Range reading at the first sample [m] (the anchor ``y0``).

        Returns
        -------
        z0 : ndarray, shape (state_dim,)
            Initial state in chain coordinates.
        P0 : ndarray, shape (state_dim, state_dim)
            Its covariance.
        y0 : float
            The anchor [m²].
        var0 : float
            The anchor's variance [m⁴].

        Raises
        ------
        ConfigError
            If ``r0`` is missing or not finite.
        """
        if r0 is None:
            r0 = np.nan
        if not np.isfinite(r0):
            raise ConfigError(
                "the augmented KF needs a range reading at the first sample (the anchor y0 of "
                "eq. 19); make the range report at t0"
            )
        n, mx = self.model.dim, self.model.state_dim
        xhat0 = np.asarray(xhat0, float)
        prel = xhat0[:n] - self.origin
        nu = xhat0[n : 2 * n] + (xhat0[2 * n : 3 * n] if self.model.current else 0.0)
        if extra0 is None:
            extra0 = np.array([prel @ nu, nu @ nu])
        zp = np.concatenate([prel, xhat0[n:mx], extra0])
        M = self.to_chain(mx + 2)
        y0, var0 = anchor(r0, self.noise["range"])
        P = M @ self.p0 @ M.T
        if self.y0_mode == "augment":
            P[mx, mx] += float(var0)
        if self.scale_g_std is not None:
            P[self.scale_index, self.scale_index] = self.scale_g_std**2
        if self.bias_std is not None:
            P[self.bias_index, self.bias_index] = self.bias_std**2
        return M @ zp, kalman.symmetrize(P), float(y0), float(var0)

    def run(self, batch: RunBatch, record: RunRecord) -> None:
        """Filter a batch of runs (as :meth:`ExtendedKalmanFilter.run`; ``batch.states`` from
        :meth:`start`).

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`), readings and, in
            closed loop, input corrections.
        record : RunRecord
            The truth at the records and the arrays the statistics are written into.
        """
        from obsplan.estimation import kernels  # numba is loaded on first use

        ctx = batch.ctx
        Z0, P0, anc = self._members(batch.states)
        kernels.kf_batch(
            Z0,
            P0,
            np.ascontiguousarray(batch.Y),
            mdl=bundles.kf_model(self.model, ctx, self),
            anc=anc,
            rcd=bundles.records(ctx, record.truth_rec, self.q_nav),
            out=bundles.outputs(ctx, record.sums, record.info, record.ex_run, record.example),
            cor=bundles.corrections(ctx, batch.corrections),
        )

    def _members(self, states: Sequence) -> tuple[np.ndarray, np.ndarray, bundles.Anchors]:
        """``Z0`` (m, R), ``P0`` (m, m, R) and the anchors of the runs' starts."""
        Z0 = np.ascontiguousarray(np.stack([st[0] for st in states], axis=1))
        P0 = np.ascontiguousarray(np.stack([st[1] for st in states], axis=2))
        y0 = np.array([st[2] for st in states], dtype=float)
        var0 = np.array([st[3] for st in states], dtype=float)
        return Z0, P0, bundles.Anchors(y0=y0, var0=var0)

    # ------------------------------------------------------------------ epoch by epoch
    def begin(self, batch: RunBatch) -> FilterRun:
        """The runs of ``batch`` at epoch 0, before its update (:meth:`Filter.begin`).

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`) and readings.

        Returns
        -------
        FilterRun
            The runs at epoch 0, not yet updated.
        """
        from obsplan.estimation import kernels

        ctx = batch.ctx
        Z0, P0, anc = self._members(batch.states)
        m, B = Z0.shape
        n = self.model.dim
        ws, iw, _ = kernels.workspaces(m, B, n, self.origin, self.q_nav)
        parts = {
            "mdl": bundles.kf_model(self.model, ctx, self),
            "anc": anc,
            "cor": bundles.corrections(ctx, batch.corrections),
            "Q": np.zeros((m, m, B)),
            "kw": np.zeros((8, self.q.shape[0], B)),
            "Sp": np.full(3, -1.0),
            "ws": ws,
            "iw": iw,
        }
        return FilterRun(
            ctx=ctx,
            Y=np.ascontiguousarray(batch.Y),
            X=Z0.copy(),
            P=P0.copy(),
            lw=np.zeros(B),
            G=1,
            parts=parts,
            run_nis=np.zeros(B),
            run_cnt=np.zeros(B),
            rg=np.zeros((4, B)),
        )

    def predict(self, run: FilterRun) -> None:
        """Predict ``run`` to its next epoch (:meth:`Filter.predict`).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).
        """
        from obsplan.estimation import kernels

        p, e = run.parts, run.epoch + 1
        kernels.kf_predict(run.X, run.P, p["Q"], p["kw"], p["ws"], p["mdl"], e, p["cor"], p["Sp"])
        run.epoch, run.updated = e, False

    def update(self, run: FilterRun) -> None:
        """Update ``run`` with the readings of its current epoch (:meth:`Filter.update`).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).

        Raises
        ------
        ConfigError
            If the current epoch is updated already.
        """
        from obsplan.estimation import kernels

        if run.updated:
            raise ConfigError(f"epoch {run.epoch} is updated already; predict to the next first")
        p = run.parts
        kernels.kf_measure(
            run.X,
            run.P,
            run.Y,
            run.epoch,
            p["iw"],
            p["ws"],
            p["mdl"],
            p["anc"],
            p["cor"],
            run.run_nis,
            run.run_cnt,
            run.rg,
        )
        run.updated = True
