"""A batch of Monte Carlo runs as a filter sees it: what it filters and where its statistics go.

A filter (:class:`~obsplan.estimation.filters.base.Filter`) filters a batch of runs on one
trajectory at once. What the batch brings to it, its *inputs*, is a :class:`RunBatch`: the
shared epochs (:class:`~obsplan.estimation.epochs.RunContext`), each run's initial filter state,
the readings and, in closed loop, the responses to the runs' input corrections. That is all the
epoch-by-epoch interface (:meth:`Filter.begin`) needs. The compiled run with the statistics
(:meth:`Filter.run`) also needs a :class:`RunRecord`: the truth the errors are measured against
and the arrays the statistics are added to (and, for one run, its history).

Both are frozen: a filter never rebinds their fields, it only writes into the record's arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from obsplan.estimation.epochs import RunContext


@dataclass(frozen=True, eq=False)
class RunBatch:
    """What a batch of ``R`` runs brings to a filter (its inputs; never written).

    Attributes
    ----------
    ctx : RunContext
        The epochs and records every run shares.
    states : sequence of tuple, length R
        Each run's initial filter state, from the filter's own :meth:`Filter.start
        <obsplan.estimation.filters.base.Filter.start>` (a batch belongs to one filter).
    Y : (E, outputs, R)
        The readings at the epochs in the model's output order (NaN: no report): range [m],
        DVL [m/s], depth [m].
    corrections : (ce (E, 2n, R), cr (Nr, 2n, R)), optional
        Each run's response (position [m], velocity [m/s]) to its input corrections at the
        epochs and the records (closed loop: the inputs it applied are the plan's plus
        corrections); ``None`` (default): the plan's inputs.
    """

    ctx: RunContext
    states: Sequence[tuple]
    Y: np.ndarray
    corrections: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def runs(self) -> int:
        """Number of runs ``R``."""
        return len(self.states)


@dataclass(frozen=True, eq=False)
class RunRecord:
    """Where a filter's compiled run of a :class:`RunBatch` puts its statistics (its outputs).

    ``sums``, ``info`` and ``example`` are written in place (``sums`` is added to: the batches
    of one path may share it).

    Attributes
    ----------
    truth_rec : (R, Nr, 2n)
        The runs' true ``(p, p')`` [m, m/s] at the records (what the errors are measured
        against).
    sums : (2, Nr, 3 + 2n)
        The sums of the statistics at the records over the unflagged runs (row 0) and the
        flagged ones (row 1), columns ``COL_*`` of :mod:`obsplan.estimation.columns`.
    info : (R, N_INFO)
        Receives the runs' verdicts (``INFO_*`` of :mod:`obsplan.estimation.columns`).
    ex_run : int
        The run of the batch whose history ``example`` keeps (-1: none).
    example : (2, Nr, 2n), optional
        Receives run ``ex_run``'s estimate and std of ``(p, p')`` [m, m/s] at the records;
        ``None`` (default): no history is kept.
    """

    truth_rec: np.ndarray
    sums: np.ndarray
    info: np.ndarray
    ex_run: int = -1
    example: np.ndarray | None = None
