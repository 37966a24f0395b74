"""Extended Kalman filter on the nonlinear model (paper section 7, eqs. 4–5, 28–30, 48–49).

State ``x = (p, v[, v_f])`` of :class:`obsplan.model.VehicleModel`. Between measurement epochs
the exact ZOH prediction composes (:mod:`obsplan.estimation.epochs`); at an epoch the filter
updates with the sensors that report, the range linearised once at the prior, in closed form for
either range form:

* ``"half-squared"``: ``h = ½|p - b|²``, ``H = (p - b)ᵀ`` on ``p``; the reading ``r_m`` enters as
  ``y = ½ r_m² - ½ σ_r²`` with variance ``r_m² σ_r² + ½ σ_r⁴`` (:mod:`obsplan.estimation.sensors`);
* ``"range"``: ``h = |p - b|``, ``H = (p - b)ᵀ / |p - b|``, ``y = r_m``, variance ``σ_r²``; at the
  beacon itself (``p̂ = b``) the range has no gradient and the update is skipped;

then the linear DVL (``v``, or ``v + v_f`` bottom-locked with current) and depth (``p_z``) rows.
"""

from __future__ import annotations

import numpy as np

from obsplan.estimation import kalman
from obsplan.estimation.epochs import RunContext
from obsplan.model import VehicleModel


class ExtendedKalmanFilter:
    """EKF of one vehicle model with per-step process noise ``q`` and sensor noises.

    Parameters
    ----------
    model
        Vehicle model (sensors, current, beacon, range form).
    q
        Per-step process-noise covariance, shape ``(state_dim, state_dim)``.
    p0
        Initial covariance of ``(p, v[, v_f])``.
    noise
        Measurement standard deviation per sensor (range [m] on ``r``, DVL [m/s], depth [m]).
    """

    name = "ekf"

    def __init__(
        self, model: VehicleModel, q: np.ndarray, p0: np.ndarray, noise: dict[str, float]
    ) -> None:
        self.model = model
        self.p0 = np.array(p0, dtype=float)
        n, m = model.dim, model.state_dim
        self.state_dim = m
        self.noise = dict(noise)
        self.q = np.asarray(q, float)
        self.q_terms = kalman.composed_noise_terms(self.q, n, model.current)
        self.q_nav = kalman.nav_noise(self.q, n, model.current)
        self.transition = kalman.Transition.build(kalman.kinematic_entries(n, model.current))
        self.rows = kalman.linear_rows(model, self.noise, 0.0)
        self._tr, self._lin = self.transition.packed(), self.rows.packed()

    def start(
        self, xhat0: np.ndarray, extra0: np.ndarray | None = None, r0: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The filter's ``(x0, P0)`` from the estimate ``xhat0`` of ``(p, v[, v_f])`` (the KF's
        extras and anchor range are not used)."""
        return np.array(xhat0, dtype=float), self.p0.copy()

    def run(
        self,
        ctx: RunContext,
        states: list[tuple[np.ndarray, np.ndarray]],
        Y: np.ndarray,
        truth_rec: np.ndarray,
        sums: np.ndarray,
        info: np.ndarray,
        ex_run: int = -1,
        example: np.ndarray | None = None,
        corrections: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Filter a batch of runs over the epochs of ``ctx`` and add their statistics to ``sums``.

        ``states`` from :meth:`start` (one per run), ``Y`` (E, output_dim, R) the readings at
        the epochs (NaN: no report), ``truth_rec`` (R, Nr, 2n) the true ``(p, p')`` at the
        records; ``info`` (R, N_INFO) receives the runs' verdicts (``stats.INFO_*``) and
        ``example`` (2, Nr, 2n) the estimate and std of run ``ex_run`` of the batch.
        ``corrections`` ``(ce (E, 2n, R), cr (Nr, 2n, R))``: each run's response to its input
        corrections at the epochs and records (closed loop: the inputs it applied are the
        plan's plus corrections); ``None``: the plan's inputs.
        """
        X0 = np.ascontiguousarray(np.stack([st[0] for st in states], axis=1))
        P0 = np.ascontiguousarray(np.stack([st[1] for st in states], axis=2))
        self._batch(
            ctx,
            X0,
            P0,
            np.zeros(len(states)),
            1,
            Y,
            truth_rec,
            sums,
            info,
            ex_run,
            example,
            corrections,
        )

    def _batch(
        self, ctx, X0, P0, lw0, G, Y, truth_rec, sums, info, ex_run, example, corrections
    ) -> None:
        from obsplan.estimation import kernels

        m, plan = self.model, ctx.plan
        ce, cr = ctx.corrections(*(corrections or (None, None)))
        kernels.ekf_batch(
            X0,
            P0,
            lw0,
            G,
            plan.seg_tab,
            self.q_terms,
            self._tr,
            np.ascontiguousarray(Y),
            m.dim,
            m.current,
            m.beacon_array,
            m.range_form == "half-squared",
            float(self.noise["range"]),
            self._lin,
            plan.rec_base,
            ctx.records_with_truth(truth_rec),
            self.q_nav,
            ctx.t_rec,
            ctx.threshold_m,
            ctx.nees_bound,
            ctx.window_s,
            sums,
            info,
            ex_run if example is not None else -1,
            ctx.no_example if example is None else example,
            ce,
            cr,
            ctx.rec_w,
        )
