"""The column layout of the compiled kernels' buffers: what the kernels fill and the statistics
read.

One place for the indices, below both: the kernels (:mod:`obsplan.estimation.kernels`,
:mod:`obsplan.estimation.montecarlo.loop_kernels`) write these columns and per-run entries, and
:mod:`obsplan.estimation.montecarlo.stats` turns them into statistics.
"""

from __future__ import annotations

#: Columns of the kernels' per-record buffer: NEES, ``|e_v|²``, ``tr P_vv``, then ``e_p,i²`` and
#: ``P_pp,ii``.
COL_NEES, COL_SE_VEL, COL_VAR_VEL, COL_AXES = 0, 1, 2, 3
#: Per-run info of the kernels (see :class:`StatsSums`).
INFO_FINAL_POS, INFO_FINAL_VEL, INFO_FINAL_STD, INFO_LAST_ABOVE = 0, 1, 2, 3
INFO_NONFINITE, INFO_FLAGGED, INFO_FLAG_TIME, INFO_NIS = 4, 5, 6, 7
INFO_RMSE_POS, INFO_RMSE_LINES = 8, 9
#: Ranges the filter used, rejected by its innovation gate, and its re-acquisitions (per run;
#: the kernels' gate counters ``rg`` (N_GATE, R) in this order, then the run of rejections).
INFO_RANGES_USED, INFO_RANGES_REJECTED, INFO_REACQUIRED = 10, 11, 12
N_INFO = 13
#: Rows of the kernels' gate counters copied to the per-run info.
N_GATE = 3
#: Row of the kernels' gate counters holding the current run of consecutive rejections.
GATE_RUN = 3
#: Per-run truth metrics of the kernels (see :class:`TruthStats`): closest and farthest range
#: squared [m²], ``Σ |p - p_ref|²`` over samples [m²], last ``|p - p_ref|²`` [m²], max ``|p'|²``
#: [m²/s²] (squares: one root per run at the end, not one per sample), max distance outside the
#: area box and the depth band [m], saturated steps, samples, max ``|u_i| / bound_i``.
TM_CLOSEST, TM_FARTHEST, TM_TRACK_SS, TM_TRACK_LAST, TM_SPEED_MAX = 0, 1, 2, 3, 4
TM_AREA_OUT, TM_DEPTH_OUT, TM_SAT, TM_SAMPLES, TM_ACCEL = 5, 6, 7, 8, 9
#: ``p - b`` of the last sample added (3 columns; the chord to the next span starts there).
TM_PREV = 10
N_TM = 13
