"""The qualitative claims of section 7 (Figs. 1–9) at the paper's initial conditions.

Reduced for the test budget: model rate 20 Hz instead of 100 Hz (Q kept at the paper's noise per
unit time, ``PaperScenario.config``), 12 seeded runs per figure (seed 0), full path durations.
Every threshold below is set from a measured value (quoted in each test, measured at 20 Hz,
12 runs, seed 0) with a margin of about 2x, never tuned to make a claim pass. 12 runs rather
than 4 since the Monte Carlo is epoch-based and cheap: with 4, one diverged EKF run decided a
claim. "Converged" means an error below 0.5 m that stays below
(``FilterStats.converged_fraction`` per run, ``convergence_time`` for the RMSE over runs); the
EKF's runs that end inconsistent are flagged by the divergence monitor (``FilterStats.flagged``)
and its claims are about the others, with the flagged share bounded.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from obsplan.paper.figures import SCENARIOS, run_scenario, write_figures

DT, RUNS = 0.05, 12


@cache
def run(fig: int):
    return run_scenario(fig, dt=DT, runs=RUNS, seed=0)


def full_rank_time(r) -> float | None:
    full = r.rank >= r.full_rank
    return float(r.rank_t[np.argmax(full)]) if full.any() else None


def initial_error(r) -> float:
    return float(np.linalg.norm(r.scenario.init_error[: r.traj.dim]))


def unconverged_are_flagged(s) -> bool:
    """Every run that does not end below the threshold is flagged by the monitor."""
    return bool(np.all(s.run_flagged[s.final_pos_err_runs > s.threshold_m]))


def test_fig1_straight_line_ekf_converges_kf_does_not():
    r = run(1)
    ekf, kf = r.result.ekf, r.result.kf
    # measured: 11 of 12 EKF runs end below 0.5 m (median 0.20 m), the other is flagged (the line
    # is only weakly LWO)
    assert np.median(ekf.final_pos_err_runs) < 0.5
    assert ekf.flagged_runs <= 3 and unconverged_are_flagged(ekf)
    # measured: KF p_y std 63 m at 200 s and its error stays ≈ the initial 1.4 m; never converged
    assert kf.pos_std_axes_t[-1, 1] > 30.0
    assert kf.converged_fraction == 0.0 and kf.convergence_time is None
    assert kf.final_pos_err > 0.5 * initial_error(r)
    assert full_rank_time(r) is None  # the Gramian never has full rank (rank 3 of 6)


def test_fig2_circle_both_converge():
    r = run(2)
    ekf, kf = r.result.ekf, r.result.kf
    # measured: EKF 0.019 m (CRB 0.018 m), KF 0.041 m; every run converged, none flagged
    assert ekf.converged_fraction == 1.0 and kf.converged_fraction == 1.0
    assert ekf.flagged_runs == 0
    assert ekf.final_pos_err < 3 * r.result.crlb_final_pos_std
    assert kf.final_pos_err < 0.1


def test_fig3_lawnmower_kf_converges_once_gramian_full_rank():
    r = run(3)
    ekf, kf = r.result.ekf, r.result.kf
    t_full = full_rank_time(r)
    assert t_full is not None and 100.0 < t_full < 250.0  # measured 168.65 s: the first turn
    # measured: 8 of 12 EKF runs converge (final 0.034 m, CRB 0.035 m); the 4 others are flagged
    assert ekf.unflagged.converged_fraction == 1.0 and ekf.unflagged.runs >= 6
    assert unconverged_are_flagged(ekf)
    assert np.median(ekf.final_pos_err_runs) < 2 * r.result.crlb_final_pos_std
    before = r.result.t < t_full
    # measured: KF RMSE >= 0.99 m and p_y std up to 51 m on the first leg: not converged
    assert np.min(kf.rmse_pos_t[before]) > kf.threshold_m
    assert np.max(kf.pos_std_axes_t[before, 1]) > 20.0
    # measured: converged (RMSE < 0.5 m for good) from 175.65 s, final 0.082 m
    assert kf.convergence_time is not None and kf.convergence_time > t_full
    assert kf.converged_fraction == 1.0


def test_fig4_far_start_ekf_fails_kf_converges():
    r = run(4)
    ekf, kf = r.result.ekf, r.result.kf
    # measured: EKF RMSE peaks at 144 m (initial 10 m), never converged over the runs (7 of 12
    # flagged), final 1.32 m against the KF's 0.11 m (the KF has a transient up to 30 m when its
    # Gramian becomes full rank, the paper's "transient phase", then converges at 273 s)
    assert np.max(ekf.rmse_pos_t) > 3 * initial_error(r)
    assert ekf.convergence_time is None
    assert ekf.flagged_runs >= 3 and unconverged_are_flagged(ekf)
    assert kf.convergence_time is not None and kf.converged_fraction == 1.0
    assert kf.final_pos_err < ekf.final_pos_err


@pytest.mark.parametrize("fig", [5, 6])
def test_fig5_fig6_3d_range_only_ekf_fails_kf_converges_after_full_rank(fig):
    r = run(fig)
    ekf, kf = r.result.ekf, r.result.kf
    t_full = full_rank_time(r)
    assert t_full is not None  # measured 65.0 s (Fig. 5), 87.05 s (Fig. 6)
    # measured: EKF final error 4.8 m / 8.5 m (CRB 0.06 / 0.13 m); 1 / 3 of 12 runs diverge
    # while their covariance is small (std 0.06 / 0.13 m): the paper's "error significant"
    assert ekf.final_pos_err > 10 * r.result.crlb_final_pos_std
    assert ekf.converged_fraction < 1.0 and unconverged_are_flagged(ekf)
    assert ekf.final_pos_err > 5 * ekf.final_pos_std
    # measured: KF final 0.22 m / 0.27 m; its error falls after the Gramian is full rank
    assert kf.final_pos_err < 1.0
    after = r.result.t > t_full
    assert np.max(kf.rmse_pos_t[~after]) > 2 * kf.final_pos_err


def test_fig7_out_of_plane_circle_dvl_ekf_converges_kf_does_not():
    r = run(7)
    ekf, kf = r.result.ekf, r.result.kf
    assert full_rank_time(r) is None  # rank 7 of 8
    # measured: EKF 0.019 m (CRB 0.014 m); KF keeps its 2 m z error with its 1 m prior std
    assert ekf.converged_fraction == 1.0
    assert kf.converged_fraction == 0.0
    assert kf.rmse_pos_axes_t[-1, 2] > 1.0 and kf.pos_std_axes_t[-1, 2] > 0.5


def test_fig8_exciting_z_dvl_both_converge():
    r = run(8)
    ekf, kf = r.result.ekf, r.result.kf
    # measured (z = 5 + 4 sin(2πt/90 s), see paper_figures): EKF: 11 of 12 runs converge (median
    # 0.030 m), 1 flagged; KF 0.027 m, every run
    assert ekf.flagged_runs <= 2 and unconverged_are_flagged(ekf)
    assert ekf.unflagged.converged_fraction == 1.0
    assert kf.converged_fraction == 1.0
    assert kf.final_pos_err < 0.1


def test_fig9_case_b_both_converge_more_slowly_than_fig8():
    r8, r9 = run(8), run(9)
    e8, k8, e9, k9 = r8.result.ekf, r8.result.kf, r9.result.ekf, r9.result.kf
    # measured: EKF converged at 80 s (44.75 s at 100 % range rate, unflagged runs), final
    # 0.092 m, every run
    assert e9.converged_fraction == 1.0
    assert e9.unflagged.convergence_time > e8.unflagged.convergence_time
    # measured: KF RMSE falls 2.45 -> 0.37 m over 300 s (Fig. 8: 0.03 m): converging, slower
    assert k9.rmse_pos_t[-1] < 0.5 * k9.rmse_pos_t[0]
    assert k9.final_pos_err > 2 * k8.final_pos_err
    t_full = full_rank_time(r9)
    assert t_full is not None and t_full > full_rank_time(r8)  # 50 s vs 7.75 s


@pytest.mark.slow
def test_write_figures_quick(tmp_path):
    paths = write_figures(tmp_path, quick=True, progress=False)
    assert [p.name for p in paths] == [f"fig{s.fig}.png" for s in SCENARIOS]
    for p in paths:
        assert p.stat().st_size > 10_000
