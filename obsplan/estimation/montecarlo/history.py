"""One Monte Carlo run recorded whole (run 0): what the figures of a run draw.

Below :mod:`~obsplan.estimation.montecarlo.results` (which holds it as ``example``) and
:mod:`~obsplan.estimation.montecarlo.plots` (which draws it), so that a result can carry its own
figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class RunHistory:
    """Everything about one run (run 0), for figures.

    Attributes
    ----------
    t : ndarray, shape (Nr,)
        Recorded times [s].
    truth : ndarray, shape (Nr, 2n)
        True ``(p, p')``.
    estimate, std : dict[str, ndarray (Nr, 2n)]
        Per filter, the estimate of ``(p, p')`` and its per-component standard deviation.
    range_t, range_m : ndarray
        Times [s] and values [m] of the range readings (NaN where dropped).
    """

    t: np.ndarray
    truth: np.ndarray
    estimate: dict[str, np.ndarray]
    std: dict[str, np.ndarray]
    range_t: np.ndarray
    range_m: np.ndarray

    def pos_error(self, name: str) -> np.ndarray:
        """``|p̂ - p|`` of filter ``name`` over time, shape (Nr,) [m].

        Parameters
        ----------
        name : str
            A filter of the run (a key of ``estimate``), e.g. ``"ekf"``.

        Returns
        -------
        ndarray, shape (Nr,)
            The norm of the position error at each recorded time [m].
        """
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, :n] - self.truth[:, :n], axis=1)

    def vel_error(self, name: str) -> np.ndarray:
        """``|p̂' - p'|`` of filter ``name`` over time, shape (Nr,) [m/s].

        Parameters
        ----------
        name : str
            A filter of the run (a key of ``estimate``), e.g. ``"ekf"``.

        Returns
        -------
        ndarray, shape (Nr,)
            The norm of the velocity error at each recorded time [m/s].
        """
        n = self.truth.shape[1] // 2
        return np.linalg.norm(self.estimate[name][:, n:] - self.truth[:, n:], axis=1)
