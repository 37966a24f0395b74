"""The logged-mission CSV (``obsplan estimate LOG.csv``): read into a
:class:`~obsplan.estimation.replay.log.MissionLog`, and written (simulated logs, examples).

One header row, then one row per time ``t`` [s] (non-decreasing; rows of one instant may share
it), with whichever readings were logged then; an empty cell (or ``nan``) means "none in this
row" (docs/guides/real-inputs.md, "Logged missions"):

====================  ======  =========================================================
columns               unit    meaning
====================  ======  =========================================================
``ux,uy[,uz]``        m/s²    inputs, held until the next row that has them
``dvx,dvy[,dvz]``     m/s     DVL velocities (bottom-track unless ``dvl_mode="water"``)
``range``             m       range to the beacon (needed: at least one)
``depth``             m       depth ``p_z`` (3D)
``bx,by[,bz]``        m       the beacon at this range (a moving beacon)
``px,py[,pz]``        m       true positions (scoring only)
====================  ======  =========================================================

A log is 3D when any group has its ``z`` column; then every group must have it. Inputs or DVL
velocities (or both) are needed. Other columns are ignored. The file goes through the one CSV
reader (:func:`obsplan.core.csvtable.read_table`) after its size is checked
(:func:`obsplan.core.budget.check_file_rows`, :func:`~obsplan.core.budget.check_log_rows`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from obsplan.core.budget import check_file_rows, check_log_rows, estimate_rows
from obsplan.core.csvtable import read_table, write_table
from obsplan.core.errors import InputError
from obsplan.estimation.replay.log import MissionLog

#: The vector column groups of a log, by their field in :class:`MissionLog`.
GROUPS = {"u": "u", "dvl": "dv", "beacon": "b", "truth": "p"}
EXAMPLE_HEADER = "t,ux,uy,range"


def _dimension(columns: tuple[str, ...], where: str) -> int:
    """2 or 3 from the groups' ``z`` columns; an error for a group without both x and y or a
    group without ``z`` in a 3D log."""
    present = {f: p for f, p in GROUPS.items() if f"{p}x" in columns or f"{p}y" in columns}
    for prefix in present.values():
        missing = [f"{prefix}{a}" for a in "xy" if f"{prefix}{a}" not in columns]
        if missing:
            raise InputError(f"{where}: missing column {missing[0]!r} (beside {prefix}x/{prefix}y)")
    z = [p for p in present.values() if f"{p}z" in columns]
    if not z:
        return 2
    lacking = [p for p in present.values() if p not in z]
    if lacking:
        raise InputError(
            f"{where}: unknown dimension: column {z[0]}z makes the log 3D but {lacking[0]}z is "
            f"missing; give {lacking[0]}z too, or remove {z[0]}z for a 2D log"
        )
    return 3


def read_mission_log(
    path: str | Path, dvl_mode: str = "bottom", where: str | None = None
) -> MissionLog:
    """Read a logged-mission CSV (module docstring).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    dvl_mode : {"bottom", "water"}, optional
        What the ``dv*`` columns measure (bottom-track ``v + v_f`` or water-track ``v``).
    where : str or None, optional
        How messages name the file; default its path.

    Returns
    -------
    MissionLog
        The log.

    Raises
    ------
    InputError
        A file that is missing, too large or malformed (row and column named), without a range
        column or any range, without inputs and DVL columns, of unknown dimension, or whose
        times go back (the row named).
    """
    where = where or str(path)
    check_file_rows(path, where)
    if Path(path).is_file():
        check_log_rows(estimate_rows(path), where)  # before it is parsed
    table = read_table(path, EXAMPLE_HEADER)
    cols = table.columns
    if "t" not in cols:
        raise InputError(
            f"{where}: missing column 't' [s]; the header must start e.g. {EXAMPLE_HEADER}"
        )
    if "range" not in cols:
        raise InputError(f"{where}: no 'range' column [m]; the beacon's ranges are needed")
    if not (table.has("ux") or table.has("uy") or table.has("dvx") or table.has("dvy")):
        raise InputError(
            f"{where}: neither inputs (ux,uy[,uz] m/s²) nor DVL velocities (dvx,dvy[,dvz] m/s); "
            "one of them is needed to carry the position between ranges"
        )
    n = _dimension(cols, where)
    check_log_rows(len(table.rows), where)
    t = table.numbers(["t"])[:, 0]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(
            f"{where}: row {table.lines[k]}, column 't': time {t[k]!r} is before the previous "
            f"row's {t[k - 1]!r}; times must not decrease (sort the log by t)"
        )
    axes = "xyz"[:n]
    fields = {
        f: table.numbers([f"{p}{a}" for a in axes], blank=True)
        for f, p in GROUPS.items()
        if table.has(f"{p}x")
    }
    depth = table.numbers(["depth"], blank=True)[:, 0] if table.has("depth") else None
    if depth is not None and n == 2:
        raise InputError(
            f"{where}: a 'depth' column needs a 3D log (uz or dvz and the other z columns)"
        )
    return MissionLog(
        t=t,
        ranges=table.numbers(["range"], blank=True)[:, 0],
        dvl_mode=dvl_mode,
        depth=depth,
        dim=n,
        source=where,
        **fields,
    )


def write_mission_log(log: MissionLog, path: str | Path) -> Path:
    """Write ``log`` as a logged-mission CSV (NaN cells as ``nan``), atomically.

    Parameters
    ----------
    log : MissionLog
        The log.
    path : str or Path
        The file (replaced whole).

    Returns
    -------
    Path
        ``path``.
    """
    axes = "xyz"[: log.dim]
    header, cols = ["t"], [log.t[:, None]]
    for f, p in GROUPS.items():
        a = getattr(log, f)
        if a is not None:
            header += [f"{p}{x}" for x in axes]
            cols.append(a)
    header.append("range")
    cols.append(log.ranges[:, None])
    if log.depth is not None:
        header.append("depth")
        cols.append(log.depth[:, None])
    return write_table(path, header, np.hstack(cols))


__all__ = ["read_mission_log", "write_mission_log"]
