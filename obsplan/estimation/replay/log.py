"""A logged mission: what a vehicle records, row by row, for the replay of :mod:`~.smoother`.

Each row ``k`` has a time ``t_k`` and whichever readings were logged then (NaN: none in that row):

* inputs ``u`` [m/s²] (commanded or measured accelerations), held from ``t_k`` to ``t_{k+1}``; a
  row without inputs keeps the last ones (zero before the first);
* DVL velocities [m/s]: bottom-track ``v (+ v_f)`` or water-track ``v``
  (:attr:`MissionLog.dvl_mode`);
* a range [m] to the beacon, with the beacon's position of that row when it moves;
* a depth [m] (``p_z``, 3D only);
* optionally the truth ``p`` [m] (a simulated log, or a log with an external fix), used only to
  score the estimate.

A log needs ranges and at least one of inputs and DVL velocities (without either, nothing
propagates the position between ranges).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.core.errors import InputError

#: The two DVL modes of a log: bottom-track measures ``v + v_f``, water-track ``v``.
DVL_MODES = ("bottom", "water")


def _array(
    a: np.ndarray | None, shape: tuple[int, ...], name: str, where: str
) -> np.ndarray | None:
    if a is None:
        return None
    out = np.array(a, dtype=float)
    if out.shape != shape:
        raise InputError(f"{where}: {name} must have shape {shape}, got {out.shape}")
    if np.any(np.isinf(out)):
        raise InputError(
            f"{where}: {name} has an infinite value at row {np.argwhere(np.isinf(out))[0][0]}"
        )
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class MissionLog:
    """One logged mission, rows in time order (module docstring).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Row times [s], non-decreasing (readings of one instant may share a time).
    ranges : ndarray, shape (N,)
        Range to the beacon [m]; NaN in rows without one.
    u : ndarray, shape (N, n) or None
        Inputs [m/s²]; a NaN row holds the previous inputs.
    dvl : ndarray, shape (N, n) or None
        DVL velocities [m/s]; NaN rows have none.
    dvl_mode : {"bottom", "water"}
        What the DVL measures: ``v + v_f`` (bottom-track) or ``v`` (water-track).
    depth : ndarray, shape (N,) or None
        Depth ``p_z`` [m] (3D logs); NaN rows have none.
    beacon : ndarray, shape (N, n) or None
        The beacon's position [m] per row (a moving beacon); needed in every row with a range.
        None: the beacon is given apart (fixed or a path).
    truth : ndarray, shape (N, n) or None
        True positions [m], for scoring only.
    dim : int
        Spatial dimension ``n`` (2 or 3).
    source : str
        Where the log came from, for messages.

    Raises
    ------
    InputError
        A shape that does not fit, times not finite or decreasing (the row named), no range,
        neither inputs nor DVL velocities, depth in 2D or a range row without its beacon.
    """

    t: np.ndarray
    ranges: np.ndarray
    u: np.ndarray | None = None
    dvl: np.ndarray | None = None
    dvl_mode: str = "bottom"
    depth: np.ndarray | None = None
    beacon: np.ndarray | None = None
    truth: np.ndarray | None = None
    dim: int = 2
    source: str = "log"

    def __post_init__(self) -> None:
        where, n = self.source, self.dim
        if n not in (2, 3):
            raise InputError(f"{where}: the dimension must be 2 or 3, got {n!r}")
        t = np.array(self.t, dtype=float).reshape(-1)
        N = t.size
        if N < 2 or not np.all(np.isfinite(t)):
            raise InputError(f"{where}: needs at least 2 rows with finite times t [s]")
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            k = int(back[0]) + 1
            raise InputError(
                f"{where}: time goes back at row {k} (t = {t[k]:g} s after {t[k - 1]:g} s); "
                "sort the rows by t"
            )
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "ranges", _array(self.ranges, (N,), "ranges", where))
        for name in ("u", "dvl", "beacon", "truth"):
            object.__setattr__(self, name, _array(getattr(self, name), (N, n), name, where))
        object.__setattr__(self, "depth", _array(self.depth, (N,), "depth", where))
        self._check_content(where)

    def _check_content(self, where: str) -> None:
        if self.dvl_mode not in DVL_MODES:
            raise InputError(
                f"{where}: dvl_mode must be 'bottom' or 'water', got {self.dvl_mode!r}"
            )
        if not np.any(np.isfinite(self.ranges)):
            raise InputError(f"{where}: the log has no range; it needs a 'range' column [m]")
        if self.u is None and self.dvl is None:
            raise InputError(
                f"{where}: the log has neither inputs (ux,uy[,uz]) nor DVL velocities "
                "(dvx,dvy[,dvz]); nothing carries the position between ranges"
            )
        if self.depth is not None and self.dim != 3:
            raise InputError(f"{where}: a depth column needs a 3D log (uz or dvz columns)")
        if self.beacon is not None:
            missing = np.flatnonzero(
                np.isfinite(self.ranges) & ~np.all(np.isfinite(self.beacon), 1)
            )
            if missing.size:
                raise InputError(
                    f"{where}: row {int(missing[0])} has a range but no beacon position; give "
                    "the beacon (bx,by[,bz]) in every row with a range"
                )
        for name in ("u", "dvl", "beacon", "truth"):
            a = getattr(self, name)
            if a is not None:
                part = np.isfinite(a).any(axis=1) & ~np.isfinite(a).all(axis=1)
                if part.any():
                    raise InputError(
                        f"{where}: row {int(np.argmax(part))} has only some components of "
                        f"{name}; give all {self.dim} or none"
                    )

    @property
    def n_rows(self) -> int:
        """Number of rows ``N``."""
        return int(self.t.size)

    @property
    def range_rows(self) -> np.ndarray:
        """Indices of the rows with a range, shape ``(R,)``."""
        return np.flatnonzero(np.isfinite(self.ranges))

    @property
    def sensors(self) -> tuple[str, ...]:
        """The model's sensor names this log reads (:data:`obsplan.model.vehicle.SENSORS`)."""
        out = ["range"]
        if self.dvl is not None:
            out.append(f"dvl-{self.dvl_mode}")
        if self.depth is not None:
            out.append("depth")
        return tuple(out)
