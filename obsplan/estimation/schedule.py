"""Multi-rate measurement schedule (paper section 7.3).

The filters predict at every trajectory sample (the model rate, 100 Hz in the paper). A sensor of
rate ``f`` reports at the first sample of every period ``1/f`` counted from ``t_0``: at sample
``k`` when ``floor((t_k - t_0) f)`` increases (and always at ``k = 0``, so the augmented KF has its
anchor range ``y0``). Case B of the paper (range at 0.1 Hz, the rest at 100 Hz) is
``rates_hz={"range": 0.1}`` on a 100 Hz trajectory. A ping schedule from a log replaces the
range's rate (``range_times``): the range reports at the first sample at or after each ping.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from obsplan.core.budget import check_file_rows
from obsplan.core.csvtable import read_table
from obsplan.core.errors import ConfigError, TrajectoryFormatError
from obsplan.trajectory.sampled import Trajectory

#: Relative slack when comparing a rate with the sample rate (times are floats).
_RATE_SLACK = 1e-6


def sample_rate(traj: Trajectory) -> float:
    """The trajectory's sample rate ``1 / median(dt)`` [Hz].

    Parameters
    ----------
    traj : Trajectory
        The sampled path.

    Returns
    -------
    float
        The model rate [Hz].
    """
    return float(1.0 / np.median(traj.dt))


@dataclass(frozen=True, eq=False)
class Schedule:
    """Which sensor reports at which sample.

    Attributes
    ----------
    sensors : tuple of str
        Sensor names, in the model's order.
    mask : ndarray of bool, shape (N, len(sensors))
        ``mask[k, j]`` is true when sensor ``j`` reports at sample ``k``.
    rates_hz : tuple of float
        The rate of each sensor [Hz].
    """

    sensors: tuple[str, ...]
    mask: np.ndarray
    rates_hz: tuple[float, ...]

    def reports(self, sensor: str) -> np.ndarray:
        """Boolean mask of shape ``(N,)`` of the samples where ``sensor`` reports.

        Parameters
        ----------
        sensor : str
            A canonical sensor name of :attr:`sensors`.

        Returns
        -------
        ndarray of bool, shape (N,)
            The sensor's column of :attr:`mask`.

        Raises
        ------
        ValueError
            If ``sensor`` is not scheduled.
        """
        return self.mask[:, self.sensors.index(sensor)]


def make_schedule(
    traj: Trajectory,
    sensors: tuple[str, ...],
    rates_hz: Mapping[str, float],
    range_times: np.ndarray | None = None,
) -> Schedule:
    """Build the schedule of ``sensors`` on the samples of ``traj``.

    Parameters
    ----------
    traj : Trajectory
        The trajectory whose samples are the model steps.
    sensors : tuple of str
        Canonical sensor names.
    rates_hz : mapping of str to float
        Rate per sensor [Hz]; missing sensors report at every sample.
    range_times : ndarray or None, optional
        A ping schedule (e.g. from a log) [s, on the trajectory's clock], increasing: the range
        then reports at the first sample at or after each time (pings within one sample
        interval are one report; times outside the trajectory are not flown), and at sample 0
        as always; its rate in :attr:`Schedule.rates_hz` is the schedule's mean over the
        trajectory. None: the range's rate.

    Returns
    -------
    Schedule
        The report mask of every sensor at every sample (every sensor reports at sample 0).

    Raises
    ------
    ConfigError
        If a rate is not positive or exceeds the sample rate (reports would be lost).
    """
    fs = sample_rate(traj)
    tau = traj.t - traj.t[0]
    cols, rates = [], []
    for s in sensors:
        if s == "range" and range_times is not None:
            col = np.zeros(traj.n_samples, dtype=bool)
            col[0] = True
            # a slack of 1e-6 of a sample so that a ping stamped at a sample's time is on it
            k = np.searchsorted(traj.t, np.asarray(range_times, float) - 1e-6 / fs, side="left")
            col[k[k < traj.n_samples]] = True
            cols.append(col)
            rates.append(float(col.sum() - 1) / max(float(tau[-1]), 1e-300))
            continue
        f = float(rates_hz.get(s, fs))
        if not (np.isfinite(f) and f > 0):
            raise ConfigError(f"rates_hz[{s!r}] must be a positive rate in Hz, got {f!r}")
        if f > fs * (1 + _RATE_SLACK) + 1e-12:
            raise ConfigError(
                f"rates_hz[{s!r}] = {f:g} Hz exceeds the trajectory's sample rate {fs:g} Hz; "
                "the filters predict at the sample rate: lower the rate or resample the trajectory"
            )
        # a small slack so that t_k = j/f computed in floating point counts as period j
        period = np.floor(tau * f + 1e-6)
        col = np.empty(traj.n_samples, dtype=bool)
        col[0] = True
        col[1:] = period[1:] > period[:-1]
        cols.append(col)
        rates.append(f)
    mask = np.column_stack(cols) if cols else np.zeros((traj.n_samples, 0), dtype=bool)
    mask.setflags(write=False)
    return Schedule(sensors=tuple(sensors), mask=mask, rates_hz=tuple(rates))


def read_ping_times(path: str | Path, where: str | None = None) -> np.ndarray:
    """Read a ping schedule: a CSV with a column ``t`` [s from the mission's start], one row per
    ping (e.g. the range rows of a logged mission); other columns ignored.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    where : str or None, optional
        The field or option that gave the file, first in the messages; default the path.

    Returns
    -------
    ndarray, shape (P,)
        The ping times [s], strictly increasing.

    Raises
    ------
    TrajectoryFormatError
        A missing, too large or malformed file (row and column named), no ``t`` column, fewer
        than 2 rows, a time that does not strictly increase (its row named) or a negative one.
    """
    where = where or str(path)
    check_file_rows(path, where, error=TrajectoryFormatError)
    table = read_table(path, "t")
    t = table.samples(["t"], where, "the header must contain t (ping times [s])")[:, 0]
    if t[0] < 0:
        raise TrajectoryFormatError(
            f"{where}: the first ping is at t = {t[0]:g} s; times are seconds from the "
            "mission's start (t >= 0)"
        )
    return t
