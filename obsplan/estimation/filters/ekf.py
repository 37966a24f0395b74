"""Extended Kalman filter on the nonlinear model (paper section 7, eqs. 4–5, 28–30, 48–49).

State ``x = (p, v[, v_f])`` of :class:`obsplan.model.vehicle.VehicleModel`. Between measurement
epochs the exact ZOH prediction composes (:mod:`obsplan.estimation.epochs`); at an epoch the filter
updates with the sensors that report, the range linearised once at the prior, in closed form for
either range form:

* ``"half-squared"``: ``h = ½|p - b|²``, ``H = (p - b)ᵀ`` on ``p``; the reading ``r_m`` enters as
  ``y = ½ r_m² - ½ σ_r²`` with variance ``r_m² σ_r² + ½ σ_r⁴`` (:mod:`obsplan.estimation.sensors`);
* ``"range"``: ``h = |p - b|``, ``H = (p - b)ᵀ / |p - b|``, ``y = r_m``, variance ``σ_r²``; at the
  beacon itself (``p̂ = b``) the range has no gradient and the update is skipped;

then the linear DVL (``v``, or ``v + v_f`` bottom-locked with current) and depth (``p_z``) rows.

With ``second_order`` (``EstimationConfig.ekf_update = "second-order"``) the range update is the
Gaussian second-order filter's: the range's curvature over the prior, ``½ δᵀ M δ`` with
``δ ~ N(0, P_pp)``, adds its mean ``½ tr(M P_pp)`` to the predicted reading and its variance
``½ tr((M P_pp)²)`` to the reading's (``M = I`` half-squared, ``(I - u uᵀ)/|p - b|`` for the
range). It matters where the position std reaches ``sqrt(2 |p - b| σ_r)``: a wide prior, a
long range-only leg, a close pass.

The range's calibration states (``EstimationConfig.scale_state``, ``bias_state``), constant,
follow the kinematic state: the scale ``k`` (nominal 1) then the bias ``β`` (nominal 0); the
range row predicts ``k |p - b| + β`` and its second-order terms take the Hessian over the
position and these states together (:func:`obsplan.estimation.kernels.calibrated_row`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation import kalman
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.config import EstimationConfig, ProcessNoise
from obsplan.estimation.filters import bundles
from obsplan.estimation.filters.base import Filter, FilterRun, register
from obsplan.model.vehicle import VehicleModel


def calibration_prior(
    scale_std: float | None, bias_std: float | None
) -> tuple[np.ndarray, list[float]]:
    """The range's calibration states, in their order (the scale, then the bias): their
    nominal values and prior variances; the absent ones left out.

    Parameters
    ----------
    scale_std, bias_std : float or None
        The prior std of the scale (relative) and of the bias [m]; None: no such state.

    Returns
    -------
    nominal : ndarray, shape (c,)
        The scale's 1, the bias's 0.
    variances : list of float
        Their prior variances.
    """
    states = [(1.0, scale_std), (0.0, bias_std)]
    present = [(nom, float(std) ** 2) for nom, std in states if std is not None]
    return np.array([nom for nom, _ in present]), [var for _, var in present]


def pad_calibration(a: np.ndarray, variances: Sequence[float]) -> np.ndarray:
    """``a`` (m, m) with a last row and column per range-calibration state (the scale, then the
    bias), zero but for their diagonal ``variances``; ``a`` itself when there is none.

    Parameters
    ----------
    a : ndarray, shape (m, m)
        A covariance (or noise term) of the kinematic state.
    variances : sequence of float
        The calibration states' entries, in their order.

    Returns
    -------
    ndarray, shape (m + len(variances), m + len(variances))
        The padded matrix.
    """
    if not len(variances):
        return a
    m, c = a.shape[0], len(variances)
    out = np.zeros((m + c, m + c))
    out[:m, :m] = a
    out[m:, m:] = np.diag(np.asarray(variances, float))
    return out


@register
class ExtendedKalmanFilter(Filter):
    """EKF of one vehicle model with per-step process noise ``q`` and sensor noises.

    Parameters
    ----------
    model : VehicleModel
        Vehicle model (sensors, current, beacon, range form).
    q : ndarray, shape (state_dim, state_dim)
        Per-step process-noise covariance, shape ``(state_dim, state_dim)``.
    p0 : ndarray, shape (state_dim, state_dim)
        Initial covariance of ``(p, v[, v_f])``.
    noise : dict of str to float
        Measurement standard deviation per sensor (range [m] on ``r``, DVL [m/s], depth [m]).
    second_order : bool, optional
        The Gaussian second-order range update (module docstring); default the first-order.
    scale_std : float or None, optional
        With a value, the state gets a last entry ``k``, the range scale (``1 + s`` of a
        sound-speed error), constant, with prior ``N(1, scale_std²)``: the range row predicts
        ``k |p - b|`` (``½ k² |p - b|²`` half-squared). None (default): no scale state.
    bias_std : float or None, optional
        With a value [m], the state gets a last entry ``β``, a range bias (a clock offset's
        ``c Δt``), constant, with prior ``N(0, bias_std²)``: the range row predicts
        ``k |p - b| + β`` (``½ (k |p - b| + β)²`` half-squared). None (default): none.
    """

    name = "ekf"
    description = "extended Kalman filter on the nonlinear model"

    def __init__(
        self,
        model: VehicleModel,
        q: np.ndarray,
        p0: np.ndarray,
        noise: dict[str, float],
        second_order: bool = False,
        scale_std: float | None = None,
        bias_std: float | None = None,
    ) -> None:
        self.model = model
        self.second_order = bool(second_order)
        n, m = model.dim, model.state_dim
        self.scale_std = None if scale_std is None else float(scale_std)
        self.bias_std = None if bias_std is None else float(bias_std)
        #: the calibration states' nominal values (the scale's 1, the bias's 0), in their order
        self.calibration_nominal, variances = calibration_prior(self.scale_std, self.bias_std)
        c = len(variances)
        #: the index of the range-scale state, -1 without one
        self.scale_index = -1 if scale_std is None else m
        #: the index of the range-bias state, -1 without one
        self.bias_index = -1 if bias_std is None else m + c - 1
        self.p0 = pad_calibration(np.array(p0, dtype=float), variances)
        self.state_dim = m + c
        self.noise = dict(noise)
        self.q = np.asarray(q, float)
        terms = kalman.composed_noise_terms(self.q, n, model.current)
        zero = [0.0] * c  # the calibration is constant: no process noise
        self.q_terms = np.ascontiguousarray(np.stack([pad_calibration(t, zero) for t in terms]))
        self.q_nav = kalman.nav_noise(self.q, n, model.current)
        self.transition = kalman.Transition.build(kalman.kinematic_entries(n, model.current))
        self.rows = kalman.linear_rows(model, self.noise, 0.0)
        self._tr, self._lin = self.transition.packed(), self.rows.packed()

    @classmethod
    def from_config(
        cls, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise
    ) -> ExtendedKalmanFilter:
        """The EKF of ``config`` (``p0_ekf``, ``q_ekf``, noises, ``ekf_update``, the range's
        calibration states).

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
        ExtendedKalmanFilter
            The filter.
        """
        second = config.ekf_update == "second-order"
        scale, bias = config.scale_prior_std, config.bias_prior_std
        return cls(config.model, pn.q_ekf, cov["p0_ekf"], dict(config.noise), second, scale, bias)

    def start(
        self, xhat0: np.ndarray, extra0: np.ndarray | None = None, r0: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The filter's ``(x0, P0)`` from the estimate ``xhat0`` of ``(p, v[, v_f])`` (the KF's
        extras and anchor range are not used).

        Parameters
        ----------
        xhat0 : ndarray, shape (state_dim of the model,)
            Initial estimate of ``(p, v[, v_f])`` [m, m/s] (absolute positions).
        extra0 : ndarray, shape (2,), optional
            Initial estimates of ``(p0ᵀν0, |ν0|²)`` (the augmented KF's extra states).
        r0 : float, optional
            Range reading at the first sample [m] (the augmented KF's anchor ``y0``).

        Returns
        -------
        x0 : ndarray, shape (state_dim,)
            Initial estimate.
        P0 : ndarray, shape (state_dim, state_dim)
            Initial covariance (the filter's ``p0``).
        """
        x0 = np.append(np.asarray(xhat0, dtype=float), self.calibration_nominal)
        return x0, self.p0.copy()

    def run(self, batch: RunBatch, record: RunRecord) -> None:
        """Filter ``batch`` over its epochs and add the runs' statistics to ``record``.

        ``batch.states`` from :meth:`start` (one per run); shapes and units as documented on
        :class:`~obsplan.estimation.batch.RunBatch` and
        :class:`~obsplan.estimation.batch.RunRecord`: ``record.sums`` is added to,
        ``record.info`` receives the runs' verdicts and ``record.example`` the estimate and std
        of run ``record.ex_run`` of the batch. With ``batch.corrections`` (closed loop) each
        run's inputs are the plan's plus its corrections.

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`), readings and, in
            closed loop, input corrections.
        record : RunRecord
            The truth at the records and the arrays the statistics are written into.
        """
        X0, P0, lw0 = self._members(batch.states)
        self._batch(batch, record, X0, P0, lw0, 1)

    def _members(self, states: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``X0`` (m, R), ``P0`` (m, m, R), ``lw0`` (R,) of the runs' starts."""
        X0 = np.ascontiguousarray(np.stack([st[0] for st in states], axis=1))
        P0 = np.ascontiguousarray(np.stack([st[1] for st in states], axis=2))
        return X0, P0, np.zeros(len(states))

    def _batch(
        self,
        batch: RunBatch,
        record: RunRecord,
        X0: np.ndarray,
        P0: np.ndarray,
        lw0: np.ndarray,
        G: int,
    ) -> None:
        """The compiled run of ``batch``'s members ``X0, P0, lw0`` (``G`` per run)."""
        from obsplan.estimation import kernels  # numba is loaded on first use

        ctx = batch.ctx
        kernels.ekf_batch(
            X0,
            P0,
            lw0,
            G,
            np.ascontiguousarray(batch.Y),
            mdl=bundles.ekf_model(self.model, ctx, self),
            rcd=bundles.records(ctx, record.truth_rec, self.q_nav),
            out=bundles.outputs(ctx, record.sums, record.info, record.ex_run, record.example),
            cor=bundles.corrections(ctx, batch.corrections),
        )

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
        X0, P0, lw0 = self._members(batch.states)
        return self._begin(batch, X0, P0, lw0, 1)

    def _begin(
        self, batch: RunBatch, X0: np.ndarray, P0: np.ndarray, lw0: np.ndarray, G: int
    ) -> FilterRun:
        """``batch``'s members ``X0, P0, lw0`` (``G`` per run) at epoch 0."""
        from obsplan.estimation import kernels

        ctx = batch.ctx
        m, B = X0.shape
        ws, iw, _ = kernels.workspaces(m, B, self.model.dim, np.zeros(self.model.dim), self.q_nav)
        parts = {
            "mdl": bundles.ekf_model(self.model, ctx, self),
            "cor": bundles.corrections(ctx, batch.corrections),
            "Q": np.zeros((m, m, B)),
            "ws": ws,
            "iw": iw,
            "w": np.ones(B),
        }
        R = B // G
        return FilterRun(
            ctx=ctx,
            Y=np.ascontiguousarray(batch.Y),
            X=X0.copy(),
            P=P0.copy(),
            lw=np.array(lw0, dtype=float),
            G=G,
            parts=parts,
            run_nis=np.zeros(R),
            run_cnt=np.zeros(R),
            rg=np.zeros((4, R)),
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
        kernels.ekf_predict(run.X, run.P, p["Q"], p["ws"], p["mdl"], e, p["cor"], run.G)
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

        p, mdl = run.parts, run.parts["mdl"]
        if run.updated:
            raise ConfigError(f"epoch {run.epoch} is updated already; predict to the next first")
        kernels.ekf_measure(
            run.X,
            run.P,
            run.Y,
            run.epoch,
            run.lw,
            p["w"],
            run.G,
            p["iw"],
            p["ws"],
            mdl.n,
            mdl.beacon,
            mdl.half_sq,
            mdl.second,
            mdl.sig_r * mdl.sig_r,
            mdl.lin,
            run.run_nis,
            run.run_cnt,
            mdl.gate,
            run.rg,
            mdl.ks,
            mdl.kb,
        )
        run.updated = True
