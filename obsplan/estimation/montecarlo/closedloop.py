"""Closed-loop Monte Carlo: the vehicle steers its estimate onto the plan, as it does at sea.

Open loop (:func:`obsplan.estimation.montecarlo.simulate.monte_carlo` without guidance) the
simulated vehicle executes the planned accelerations blind and the process noise drives it away from
the plan with nothing pulling it back. Here the navigation filter (the EKF) runs inside the loop and
the :class:`~obsplan.estimation.montecarlo.guidance.Guidance` law feeds its estimate back at every
filter step. The dynamics are linear and the inputs are known to the vehicle, which makes this exact
and cheap (:mod:`obsplan.estimation.montecarlo.loop_kernels`): with ``x_plan`` the plan's states,

    truth     x = x_plan + c + δ,     c_{k+1} = F c_k + G (u_k - u_plan,k)
    estimate  x̂ = x_plan + c + d,     d_{k+1} = F d_k between updates

where ``δ`` is the open-loop process-noise deviation (the same seeded streams, so run ``r`` has
the same noise, initial error and reading noise in both modes) and the feedback is a function of
``c + d``. The readings are computed inside the loop at the true state; the EKF's covariance uses
the exact composed prediction between epochs. The other filters (augmented KF, Gaussian sum) run
passively afterwards on the same true path and readings with each run's *applied* inputs: their
predictions add ``c_b - F c_a`` per segment and the KF's input displacement is ``d + c_p``.

Receding-horizon replanning runs inside this loop: :meth:`ClosedLoop.advance` simulates to a
time, :meth:`ClosedLoop.snapshot` returns every run's estimate, covariance and truth there, and
the next :meth:`~ClosedLoop.advance` continues with a new reference trajectory per run (the truth
is still written relative to the first plan, whose inputs ``c`` corrects). Runs are independent:
a Monte Carlo of many runs can be simulated as several :class:`ClosedLoop` objects of a few runs
(``run_start``), merged exactly by :func:`~obsplan.estimation.montecarlo.results.merge_monte_carlo`.

A moving beacon that is re-planned during the runs (the craft's receding horizon,
:mod:`obsplan.planning.beacon_replan`) changes its future mid-run: :meth:`ClosedLoop.set_beacon`
replaces the beacon of every epoch and sample after the current one, for all the loop's runs (one
beacon per loop, so a per-run beacon is a loop of one run). The ranges the truth reads, the EKF's
updates, the passive filters run after the loop and the truth's closest approach all take the
beacon from the same arrays, so all of them see the new path; the posterior CRB passed to
:meth:`ClosedLoop.result` is the caller's.
"""

from __future__ import annotations

import time
from collections import namedtuple
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation import kalman
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.bounds.crlb import CRLBResult, posterior_crlb
from obsplan.estimation.columns import COL_AXES, INFO_RANGES_USED, N_GATE
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.epochs import epoch_beacons, sample_beacons, segment_table
from obsplan.estimation.filters.ekf import ExtendedKalmanFilter
from obsplan.estimation.filters.gsf import GaussianSumFilter
from obsplan.estimation.montecarlo.guidance import Guidance, TruthLimits
from obsplan.estimation.montecarlo.results import MonteCarloResult, build_result
from obsplan.estimation.montecarlo.runs import (
    DEFAULT_FILTERS,
    PathSetup,
    check_filters,
    check_runs,
    draw_run,
    start_of,
)
from obsplan.estimation.montecarlo.stats import TruthStats, empty_metrics
from obsplan.estimation.montecarlo.truth import (
    STREAM_PROCESS,
    corrupt_ranges,
    reading_noise,
    run_rng,
)
from obsplan.model.beacon import BeaconPath
from obsplan.trajectory.sampled import Trajectory

#: Samples advanced per kernel call: bounds the process-noise normals held at once.
CHUNK = 4096
#: Samples of each run buffered for its truth metrics (``span_metrics``) before they are added.
METRIC_SPAN = 256
#: Relative tolerance when matching a time or a reference's samples to the filter grid.
GRID_RTOL = 1e-9

NavPath = namedtuple(
    "NavPath",
    "h xplan nuplan uplan ep_of rec_of nxt tab qt tr lin qz beacon beacon_s n cur half_sq second "
    "sig_r L expo scaled box has_box alim G rscale gate ks kb",
)
NavGains = namedtuple("NavGains", "kp kd amax vmax kv truth")
NavState = namedtuple("NavState", "pos X P c d dl Q Sp ws iw nw xm Pm lw w sc hp u nu sat vl")
NavIO = namedtuple("NavIO", "Yn Y ce cr rec buf run_nis run_cnt rg tm xb ex ex_run")


@dataclass(frozen=True, eq=False)
class ClosedLoopState:
    """Every run of a :class:`ClosedLoop` at its current sample (after the update there).

    Attributes
    ----------
    t : float
        Time [s].
    k : int
        Sample index on the filter grid.
    runs : ndarray of int, shape (R,)
        Run indices in the seed's streams.
    estimate : ndarray, shape (R, m)
        The EKF's estimate of ``(p, v[, v_f])`` (``v`` through the water).
    covariance : ndarray, shape (R, m, m)
        Its covariance.
    truth : ndarray, shape (R, m)
        The true state.
    c : ndarray, shape (R, 2n)
        Response of ``(p, v)`` to the input corrections so far (relative to the first plan).
    d : ndarray, shape (R, m)
        ``estimate - x_plan - c``.
    """

    t: float
    k: int
    runs: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray
    truth: np.ndarray
    c: np.ndarray
    d: np.ndarray


def _grid_index(t: np.ndarray, when: float, what: str) -> int:
    k = int(np.searchsorted(t, when - GRID_RTOL * max(1.0, abs(when))))
    if k >= t.size or abs(t[k] - when) > GRID_RTOL * max(1.0, abs(when)) + 1e-12:
        raise ConfigError(
            f"{what} = {when!r} s is not a sample of the filter grid ({t[0]:g} .. {t[-1]:g} s, "
            f"step {t[1] - t[0]:g} s)"
        )
    return k


class ClosedLoop:
    """Closed-loop runs of one path (module docstring).

    Parameters
    ----------
    traj : Trajectory
        The plan on the filter grid (its samples are the filter steps; its ``u`` the feed-forward).
    config : EstimationConfig
        Filters, sensors, noises, priors (as for ``monte_carlo``).
    runs, seed, run_start : int, optional
        Runs ``run_start .. run_start + runs - 1`` of the seed's streams.
    guidance : Guidance
        The guidance law (gains, acceleration and speed bounds).
    limits : TruthLimits or None, optional
        What the true paths are checked against
        (:class:`~obsplan.estimation.montecarlo.stats.TruthStats`).
    record_every : int or None, optional
        Statistics every this many samples (default ~1000 records).
    lines : ndarray of bool, shape (N,), optional
        Boolean mask (N,) of the samples of the per-run subset RMSE (``rmse_pos_lines_runs``).
    filters : sequence of str, optional
        Filters whose statistics are reported; the EKF navigates whatever this is.
    """

    def __init__(
        self,
        traj: Trajectory,
        config: EstimationConfig,
        runs: int = 50,
        seed: int = 0,
        run_start: int = 0,
        *,
        guidance: Guidance,
        limits: TruthLimits | None = None,
        record_every: int | None = None,
        lines: np.ndarray | None = None,
        filters: Sequence[str] = DEFAULT_FILTERS,
    ) -> None:
        self._t0 = time.perf_counter()
        runs, seed, run_start = check_runs(runs, seed, run_start)
        if not isinstance(guidance, Guidance):
            raise ConfigError("guidance must be a Guidance (e.g. Guidance.from_limits(accel))")
        self.names = check_filters(filters)
        if guidance.navigation not in self.names:  # computed in the loop: always reported
            self.names = (*self.names, guidance.navigation)
        if limits is not None and not isinstance(limits, TruthLimits):
            raise ConfigError("limits must be a TruthLimits or None")
        self.setup = setup = PathSetup(traj, config, self.names, record_every, runs, lines, limits)
        self.traj, self.config, self.guidance, self.limits = traj, config, guidance, limits
        self.seed, self.run_start = seed, run_start
        self.run_ids = np.arange(run_start, run_start + runs)
        self.nav_name = guidance.navigation
        nav = setup.filters[self.nav_name]
        self.nav_mixture = nav if isinstance(nav, GaussianSumFilter) else None
        # the members' filter (prediction, rows, noise): the EKF, or the Gaussian sum's
        self.nav_filter: ExtendedKalmanFilter = cast(
            ExtendedKalmanFilter, nav if self.nav_mixture is None else self.nav_mixture.ekf
        )
        self.members = 1 if self.nav_mixture is None else self.nav_mixture.components
        self._draws = [draw_run(setup, seed, int(r)) for r in self.run_ids]
        self._procs = [run_rng(seed, int(r), STREAM_PROCESS) for r in self.run_ids]
        self._refs: list | None = None
        self._result: MonteCarloResult | None = None
        self._pt = self._path_bundle()
        self._gn = self._gains_bundle()
        self._st, self._io = self._state_bundles()

    # ------------------------------------------------------------------ bundles
    def _path_bundle(self):
        s, f, model = self.setup, self.nav_filter, self.config.model
        N = self.traj.n_samples
        ep_of = np.full(N, -1, dtype=np.int64)
        ep_of[s.plan.epochs] = np.arange(s.plan.n_epochs)
        rec_of = np.full(N, -1, dtype=np.int64)
        rec_of[s.records] = np.arange(s.records.size)
        # the next sample with an epoch or a record after each sample (the last is a record)
        events = np.flatnonzero((ep_of >= 0) | (rec_of >= 0))
        nxt = events[
            np.minimum(np.searchsorted(events, np.arange(N), side="right"), events.size - 1)
        ]
        lim = self.limits or TruthLimits()
        return NavPath(
            h=np.ascontiguousarray(self.traj.dt),
            xplan=self._xplan(),
            nuplan=np.ascontiguousarray(self.traj.v),
            uplan=np.ascontiguousarray(self.traj.u),
            ep_of=ep_of,
            rec_of=rec_of,
            nxt=nxt.astype(np.int64),
            tab=s.plan.seg_tab,
            qt=f.q_terms,
            tr=f.transition.packed(),
            lin=f.rows.packed(),
            qz=f.q_nav,
            beacon=s.ctx.beacons,
            beacon_s=s.sample_beacons,
            n=model.dim,
            cur=bool(model.current),
            half_sq=model.range_form == "half-squared",
            second=bool(f.second_order),
            sig_r=float(self.config.noise["range"]),
            L=np.ascontiguousarray(s.L),
            expo=np.asarray(s.expo, float),
            scaled=bool(np.any(s.expo != 0)),
            box=s.box,
            has_box=bool(np.any(np.isfinite(s.box))),
            alim=lim.accel_bounds(model.dim),
            G=self.members,
            rscale=1.0 + self.config.channel.sound_speed_scale,
            gate=s.ctx.gate_nis,
            ks=int(f.scale_index),
            kb=int(f.bias_index),
        )

    def _xplan(self) -> np.ndarray:
        """The plan's states in the navigation filter's state: with range-calibration states
        their nominal values appended (the estimate is the plan plus the offset ``d``)."""
        s = self.setup.states
        nom = self.nav_filter.calibration_nominal
        return np.ascontiguousarray(np.hstack([s, np.broadcast_to(nom, (s.shape[0], nom.size))]))

    def _gains_bundle(self):
        g, n = self.guidance, self.config.model.dim
        vmax = np.inf if g.speed is None else float(g.speed)
        return NavGains(
            kp=g.kp, kd=g.kd, amax=g.bounds(n), vmax=vmax, kv=g.speed_k, truth=float(g.on_truth)
        )

    def _state_bundles(self):
        from obsplan.estimation import kernels

        s, model = self.setup, self.config.model
        n, m, R = model.dim, model.state_dim, self.run_ids.size
        E, Nr = s.plan.n_epochs, s.records.size
        x0 = s.states[0]
        err0 = np.stack([dr.err0 for dr in self._draws], axis=1)
        G = self.members
        mf = self.nav_filter.state_dim  # m, plus the range's calibration states
        if mf > m:  # the calibration starts at its nominal values: no offset
            err0 = np.vstack([err0, np.zeros((mf - m, R))])
            x0 = np.append(x0, self.nav_filter.calibration_nominal)
        if self.nav_mixture is None:
            X0 = x0[:, None] + err0
            P0 = np.repeat(np.asarray(self.nav_filter.p0, float)[:, :, None], R, axis=2)
            lw0 = np.zeros(R)
        else:  # the members of run b are columns b G .. b G + G - 1 (the kernels' layout)
            starts = [self.nav_mixture.start(x0[:m] + dr.err0) for dr in self._draws]
            X0 = np.concatenate([a[0] for a in starts], axis=0).T
            P0 = np.concatenate([a[1] for a in starts], axis=0).transpose(1, 2, 0)
            lw0 = np.concatenate([a[2] for a in starts])
        ws, iw, nw = kernels.workspaces(mf, R * G, n, np.zeros(n), self.nav_filter.q_nav)
        st = NavState(
            pos=np.zeros(4, dtype=np.int64),
            X=np.ascontiguousarray(X0),
            P=np.ascontiguousarray(P0),
            c=np.zeros((2 * n, R)),
            d=np.ascontiguousarray(err0),
            dl=np.zeros((m, R)),
            Q=np.zeros((mf, mf, R * G)),
            Sp=-np.ones(3),
            ws=ws,
            iw=iw,
            nw=nw,
            xm=np.empty(mf),
            Pm=np.empty((mf, mf)),
            lw=lw0,
            w=np.ones(R * G),
            sc=np.ones(m),
            hp=-np.ones(1),
            u=np.zeros((n, R)),
            nu=np.zeros((n, R)),
            sat=np.zeros(R),
            vl=np.full(R, np.inf),
        )
        Yn = np.stack([self._reading_noise(dr) for dr in self._draws], axis=2)
        ex_run = int(np.flatnonzero(self.run_ids == 0)[0]) if 0 in self.run_ids else -1
        io = NavIO(
            Yn=np.ascontiguousarray(Yn),
            Y=np.full(Yn.shape, np.nan),
            ce=np.zeros((E, 2 * n, R)),
            cr=np.zeros((Nr, 2 * n, R)),
            rec=s.ctx.records_with_truth(np.zeros((R, Nr, 2 * n))),
            buf=np.zeros((R, Nr, COL_AXES + 2 * n)),
            run_nis=np.zeros(R),
            run_cnt=np.zeros(R),
            rg=np.zeros((N_GATE + 1, R)),
            tm=empty_metrics(R),
            xb=np.zeros((R, METRIC_SPAN, 3 * n)),
            ex=np.zeros((2, Nr, 2 * n)) if ex_run >= 0 else s.ctx.no_example,
            ex_run=ex_run,
        )
        from obsplan.estimation.montecarlo.loop_kernels import speed_bounds

        gn = self._gn  # the prior's, until the first update
        speed_bounds(st.X, st.P, st.lw, st.w, G, st.vl, gn.kv, gn.vmax, n, bool(model.current))
        return st, io

    # ------------------------------------------------------------------ stepping
    @property
    def k(self) -> int:
        """Current sample index."""
        return int(self._st.pos[0])

    @property
    def t(self) -> float:
        """Current time [s]."""
        return float(self.traj.t[self.k])

    def advance(
        self, until_t: float, references: Trajectory | Sequence[Trajectory] | None = None
    ) -> None:
        """Simulate to time ``until_t`` [s] (a sample of the grid), its measurement update
        included; the command there is applied by the next call.

        ``references``: from the current sample on, a new reference for every run (one
        trajectory) or one per run, on the filter grid from the current time to at least
        ``until_t``; ``None`` keeps the references in force (at first the plan).

        Parameters
        ----------
        until_t : float
            Time to simulate to [s], a sample of the filter grid, not before the current time.
        references : Trajectory or sequence of Trajectory or None, optional
            New reference(s) from the current sample on.

        Raises
        ------
        ConfigError
            If the loop is finished, ``until_t`` is not a sample of the grid or is in the past,
            or a reference does not fit the grid.
        """
        from obsplan.estimation.montecarlo.loop_kernels import empty_reference, navigate

        if self._result is not None:
            raise ConfigError("this ClosedLoop is finished (result() was called)")
        k_end = _grid_index(self.traj.t, float(until_t), "until_t")
        if k_end < self.k:
            raise ConfigError(f"until_t = {until_t!r} s is before the current time {self.t:g} s")
        if references is not None:
            self._set_references(references)
        n, R = self.config.model.dim, self.run_ids.size
        ka = self.k
        while True:
            kb = min(k_end, ka + CHUNK)
            z = self._normals(kb - ka)
            has_ref = self._refs is not None
            ref = self._reference_chunk(ka, kb) if has_ref else empty_reference(n, R)
            navigate(self._pt, self._gn, self._st, self._io, z, ref, ka, has_ref, kb)
            if kb >= k_end:
                break
            ka = kb

    def _normals(self, steps: int) -> np.ndarray:
        """The next ``steps`` rows of every run's process-noise stream, (steps, r, R)."""
        r = self.setup.L.shape[1]
        if r == 0 or steps == 0:
            return np.zeros((steps, r, self.run_ids.size))
        return np.ascontiguousarray(
            np.stack([g.standard_normal((steps, r)) for g in self._procs], axis=2)
        )

    def _set_references(self, references) -> None:
        R, k0, t = self.run_ids.size, self.k, self.traj.t
        refs = [references] * R if isinstance(references, Trajectory) else list(references)
        if len(refs) != R:
            raise ConfigError(f"references: expected one trajectory or {R}, got {len(refs)}")
        out = []
        for j, ref in enumerate(refs):
            if not isinstance(ref, Trajectory) or ref.dim != self.traj.dim:
                raise ConfigError(f"references[{j}] must be a {self.traj.dim}D Trajectory")
            tk = t[k0 : k0 + ref.n_samples]
            scale = GRID_RTOL * max(1.0, float(np.abs(t).max()))
            if tk.size != ref.n_samples or np.max(np.abs(ref.t - tk)) > scale:
                raise ConfigError(
                    f"references[{j}] must be sampled on the filter grid from the current time "
                    f"{t[k0]:g} s (its samples start at {ref.t[0]:g} s, step {ref.dt[0]:g} s)"
                )
            out.append((k0, np.hstack([ref.p, ref.v, ref.u])))
        self._refs = out

    def _reference_chunk(self, ka: int, kb: int) -> np.ndarray:
        cols = []
        assert self._refs is not None  # the caller checks: references were set
        for j, (k0, arr) in enumerate(self._refs):
            if kb - k0 >= arr.shape[0]:
                raise ConfigError(
                    f"the reference of run {self.run_ids[j]} ends at "
                    f"{self.traj.t[k0 + arr.shape[0] - 1]:g} s, before {self.traj.t[kb]:g} s"
                )
            cols.append(arr[ka - k0 : kb - k0 + 1])
        return np.ascontiguousarray(np.stack(cols, axis=2))

    def set_beacon(self, path: BeaconPath) -> None:
        """Replace the moving beacon after the current sample by ``path`` for every run of this
        loop (module docstring): the beacon of each range epoch after the current sample (at
        transmission, :func:`~obsplan.estimation.epochs.epoch_beacons`), of each sample after it
        (the truth's closest approach) and the channel's nominal ranges there. What is already
        simulated is kept; ``path`` need only cover the current time to the end.

        Parameters
        ----------
        path : BeaconPath
            The beacon's path [m] from the current time to the path's end, at least (before the
            current time it should be the one in force: a range received just after it was sent
            just before).

        Raises
        ------
        ConfigError
            If the loop is finished, the beacon is fixed (one row: not a moving beacon's), or
            ``path`` has another dimension or does not cover the rest of the path.
        """
        if self._result is not None:
            raise ConfigError("this ClosedLoop is finished (result() was called)")
        s, k = self.setup, self.k
        beacons = s.ctx.beacons
        if beacons.shape[0] < 2 or s.sample_beacons.shape[0] < 2:
            raise ConfigError("set_beacon needs a moving beacon (config.beacon_path)")
        if not isinstance(path, BeaconPath) or path.dim != self.traj.dim:
            raise ConfigError(f"set_beacon: path must be a {self.traj.dim}D BeaconPath")
        t, model = self.traj.t, self.config.model
        ep = s.plan.epochs
        fut = np.flatnonzero(ep > k)
        smp = np.arange(k + 1, t.size)
        if smp.size == 0:
            return
        path.check_covers(float(t[k]), float(t[-1]), "set_beacon path")
        if fut.size:
            # in place: the kernels' and the passive filters' array
            beacons[fut] = epoch_beacons(model, path, t[ep[fut]], self.traj.p[ep[fut]])
            rel = self.traj.p[ep] - beacons  # the channel's nominal ranges, as PathSetup has them
            s.rho_epochs[:] = np.linalg.norm(rel, axis=1)
            vb = np.gradient(beacons, t[ep], axis=0) if ep.size > 1 else np.zeros_like(rel)
            with np.errstate(invalid="ignore", divide="ignore"):
                rd = np.einsum("ki,ki->k", rel, self.traj.v[ep] - vb) / s.rho_epochs
            s.rho_dot_epochs[:] = np.where(s.rho_epochs > 0, rd, 0.0)
            # the channel's losses and late arrivals follow the new ranges (the same draws)
            Yn = np.stack([self._reading_noise(dr) for dr in self._draws], axis=2)
            self._io.Yn[fut] = Yn[fut]
        s.sample_beacons[smp] = sample_beacons(model, path, t[smp])

    # ------------------------------------------------------------------ reading out
    def snapshot(self) -> ClosedLoopState:
        """Every run's estimate, covariance and truth at the current sample.

        Returns
        -------
        ClosedLoopState
            The navigation filter's estimate and covariance (a Gaussian sum: its mixture's),
            the truth and the input responses of every run.
        """
        s, st, model = self.setup, self._st, self.config.model
        n, m = model.dim, model.state_dim
        k, e_last = self.k, int(st.pos[2])
        c = np.zeros((m, st.c.shape[1]))
        c[: 2 * n] = st.c
        xplan = s.states[k][:, None]
        P = np.moveaxis(st.P, 2, 0).copy()
        mf = st.X.shape[0]  # the filter's state: m, or m + 1 with a range-scale state
        G = self.members
        if G > 1:  # each run's mixture covariance about its mean (the members' spread included)
            R = st.c.shape[1]
            lw = st.lw.reshape(R, G)
            w = np.exp(lw - lw.max(axis=1, keepdims=True))
            w /= w.sum(axis=1, keepdims=True)
            X = st.X.T.reshape(R, G, mf)
            dev = X - np.einsum("rg,rgi->ri", w, X)[:, None, :]
            P = np.einsum(
                "rg,rgij->rij", w, P.reshape(R, G, mf, mf) + dev[..., :, None] * dev[..., None, :]
            )
        P = P[:, :m, :m]  # the kinematic state (the scale is not the vehicle's)
        ke = int(s.plan.epochs[e_last])
        if k > ke:  # the prior, predicted from the last epoch (exact)
            seg = segment_table(self.traj, np.array([ke]), np.array([k]), False, s.noise.continuous)
            S0, S1, S2 = seg.sums[0]
            q = self.nav_filter.q_terms[:, :m, :m]
            F = self.nav_filter.transition.matrix(m, float(seg.T[0]))
            P = F @ P @ F.T + (S0 * q[0] + S1 * q[1] + S2 * q[2])
        return ClosedLoopState(
            t=self.t,
            k=k,
            runs=self.run_ids.copy(),
            estimate=(xplan + c + st.d[:m]).T.copy(),
            covariance=kalman.symmetrize(P),
            truth=(xplan + c + st.dl).T.copy(),
            c=st.c.T.copy(),
            d=st.d[:m].T.copy(),
        )

    def result(self, crlb: CRLBResult | None = None) -> MonteCarloResult:
        """Finish the runs (to the end of the path with the references in force), run the
        passive filters and return the statistics (``crlb``: the bound along the plan, computed
        if not given).

        Parameters
        ----------
        crlb : CRLBResult or None, optional
            The posterior CRB along the plan; None: computed here.

        Returns
        -------
        MonteCarloResult
            The closed loop's statistics (the same object on later calls).
        """
        if self._result is not None:
            return self._result
        if self.k < self.traj.n_samples - 1 or self._st.pos[1] == 0:
            self.advance(float(self.traj.t[-1]))
        self._finish_filters()
        truth = TruthStats.from_metrics(self._io.tm, self.limits)
        if crlb is None:
            crlb = posterior_crlb(self.traj, self.config, self.setup.schedule)
        self._result = build_result(
            self.setup,
            self.run_ids.size,
            self.seed,
            self.run_start,
            time.perf_counter() - self._t0,
            crlb,
            truth,
            mode="closed-loop",
            guidance=self.guidance,
        )
        return self._result

    def _reading_noise(self, dr) -> np.ndarray:
        """Run ``dr``'s reading noise at the epochs, with the channel's bias, late arrivals and
        lost pings (the clean range, scaled, is added in the loop)."""
        s = self.setup
        model, reports = self.config.model, s.plan.reports
        y = reading_noise(model, reports, dict(self.config.noise), dr.readings)
        corrupt_ranges(
            model, y, reports, self.config.channel, dr.channel, s.rho_epochs, s.rho_dot_epochs
        )
        return y

    def _finish_filters(self) -> None:
        from obsplan.estimation import kernels

        s, io, model = self.setup, self._io, self.config.model
        n, ctx = model.dim, self.setup.ctx
        nav = self.nav_name
        if nav in self.names:
            for b in range(self.run_ids.size):
                kernels.finish_run(
                    io.buf[b],
                    ctx.t_rec,
                    ctx.threshold_m,
                    ctx.nees_bound,
                    ctx.window_s,
                    io.run_nis[b],
                    io.run_cnt[b],
                    s.sums[nav],
                    s.info[nav][b],
                    ctx.rec_w,
                )
                s.info[nav][b, INFO_RANGES_USED : INFO_RANGES_USED + N_GATE] = io.rg[:N_GATE, b]
            if io.ex_run >= 0:
                s.hist[nav] = io.ex
        x0 = s.states[0]
        b0 = ctx.beacons[0]
        starts = [start_of(model, x0, dr, io.Y[0, 0, b], b0) for b, dr in enumerate(self._draws)]
        truth_rec = np.ascontiguousarray(io.rec[:, :, kernels.TAB_G + 2 * n :])
        Nr = s.records.size
        for name in self.names:
            if name == nav:
                continue
            f = s.filters[name]
            batch = RunBatch(ctx, [f.start(*st) for st in starts], io.Y, (io.ce, io.cr))
            ex = np.zeros((2, Nr, 2 * n)) if io.ex_run >= 0 else None
            f.run(batch, RunRecord(truth_rec, s.sums[name], s.info[name], io.ex_run, ex))
            if ex is not None:
                s.hist[name] = ex
        if io.ex_run >= 0:
            s.hist["truth"] = truth_rec[io.ex_run]
            s.hist["range"] = io.Y[s.range_rows, 0, io.ex_run].copy()
