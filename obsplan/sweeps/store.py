"""The output folder of a sweep: what is written where, atomically, so that nothing is lost.

Layout of ``DIR``::

    sweep.json              the sweep (axes, mode, base) and its task ids, in order
    results.parquet         one row per task (obsplan.sweeps.table)
    results.csv             the same table as CSV
    tasks/<task-id>/        report.json (always, last) and plan.csv (plan mode, if a path exists)
    figures/                the study figures (obsplan.sweeps.figures)

Every file is written to a temporary name in its folder and renamed over the target
(:func:`obsplan.core.atomic.atomic_file`), so an interrupted write leaves the old file or none,
never half of one. A task's ``report.json`` is written after its ``plan.csv``: a task is
finished exactly when its report exists, which is what a re-run checks to resume.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from obsplan.core.atomic import atomic_file
from obsplan.core.errors import InputError
from obsplan.core.outputs import ResumableDir
from obsplan.core.textfiles import read_json

MANIFEST = "sweep.json"
TASKS = "tasks"
REPORT = "report.json"
PLAN = "plan.csv"
RESULTS_PARQUET = "results.parquet"
RESULTS_CSV = "results.csv"
FIGURES = "figures"


def atomic_write(path: Path, write: Callable[[Path], Any]) -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it to ``path``
    (:func:`obsplan.core.atomic.atomic_file`); creates the parent folder.

    Parameters
    ----------
    path : Path
        The file to write.
    write : callable
        ``write(tmp)`` writes the whole content to the temporary path ``tmp``.

    Returns
    -------
    Path
        ``path``, now holding what ``write`` wrote.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path) as tmp:
        write(tmp)
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8).

    Parameters
    ----------
    path : Path
        The file to write.
    text : str
        Its whole content.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def check_out(out: str | Path, force: bool, name: str) -> ResumableDir:
    """Check that the sweep called ``name`` may write into ``out`` (nothing is written).

    Accepted: a new or empty folder, or one an earlier ``obsplan sweep`` made (its marker says
    so): the sweep of that name (``sweep.json``) is resumed, even if its axes changed (tasks are
    keyed by their problem, so the finished ones are reused); another sweep's folder only with
    ``force`` (its table and figures are then replaced). Refused whatever ``force``: a folder
    without the sweep marker (the user's, or another verb's output), a link, the working or
    home folder (or a parent), a folder another run is writing into
    (:class:`obsplan.core.outputs.ResumableDir`, which stays locked until its ``release``).

    Parameters
    ----------
    out : str or Path
        The ``--out`` folder.
    force : bool
        ``--force``: accept another sweep's folder, or one whose manifest names no sweep.
    name : str
        This sweep's name.

    Returns
    -------
    ResumableDir
        The folder, locked for this run (release it when done).

    Raises
    ------
    InputError
        If ``out`` is not a folder this sweep may write into.
    """
    target = ResumableDir(out, "sweep", "--out")
    try:
        path = target.path
        if (path / MANIFEST).is_file() and not force:
            other = sweep_name(read_manifest(path))
            if other is None:
                raise InputError(
                    f"--out {path}: its {MANIFEST} names no sweep, so it cannot be resumed; "
                    "choose a new folder, or pass --force to write this sweep's manifest over it"
                )
            if other != name:
                raise InputError(
                    f"--out {path} holds the results of sweep {other!r}, not {name!r}; choose "
                    "another folder, or pass --force to add this sweep's tasks to it (its table "
                    "and figures are then replaced)"
                )
    except BaseException:
        target.release()
        raise
    return target


def sweep_name(manifest: dict[str, Any]) -> str | None:
    """The name a sweep manifest gives, or None if it names none.

    Parameters
    ----------
    manifest : dict of str to Any
        The contents of ``sweep.json``.

    Returns
    -------
    str or None
        ``manifest["sweep"]["name"]`` when it is a string.
    """
    sweep = manifest.get("sweep")
    name = sweep.get("name") if isinstance(sweep, dict) else None
    return name if isinstance(name, str) else None


def check_code(out: Path, code: str, force: bool) -> None:
    """Refuse to resume a sweep whose finished tasks were computed by other code.

    A task's id includes the code fingerprint (:func:`obsplan.sweeps.spec.code_fingerprint`),
    so results of two codes never share a row; without this check a resume after an update
    would silently compute every task again beside the old ones. ``force`` accepts that (the
    old task folders stay in ``DIR/tasks/`` but leave the table).

    Parameters
    ----------
    out : Path
        The sweep's folder.
    code : str
        This installation's code fingerprint.
    force : bool
        ``--force``: accept the other code's tasks (they are computed again).

    Raises
    ------
    InputError
        If ``out``'s sweep was run by code with another fingerprint and has finished tasks.
    """
    if force or not (out / MANIFEST).is_file():
        return
    old = read_manifest(out).get("code")
    if old == code:
        return
    finished = finished_tasks(out)
    if not finished:
        return
    seen = f"code fingerprint {old}" if old else "no code fingerprint recorded"
    raise InputError(
        f"--out {out}: its {finished} finished tasks were computed by other obsplan code "
        f"({seen}; this installation's is {code}), so new results would not compare with "
        "them; choose a new folder, or pass --force to compute every task again with this "
        f"code (the old task folders stay in {out / TASKS} but leave the table)"
    )


def finished_tasks(out: Path) -> int:
    """Tasks whose report is in ``DIR/tasks/`` (done or failed: finished either way).

    Parameters
    ----------
    out : Path
        The sweep's folder.

    Returns
    -------
    int
        Their number (0 when there is no ``tasks/`` folder).
    """
    return sum(1 for _ in (Path(out) / TASKS).glob(f"*/{REPORT}"))


def task_dir(out: Path, task_id: str) -> Path:
    """The folder of one task's ``report.json`` and ``plan.csv``.

    Parameters
    ----------
    out : Path
        The sweep's folder.
    task_id : str
        The task's id (:func:`obsplan.sweeps.spec.task_id`).

    Returns
    -------
    Path
        ``DIR/tasks/<task_id>`` (not created).
    """
    return out / TASKS / task_id


def read_report(out: Path, task_id: str) -> dict[str, Any] | None:
    """The stored report of a finished task, or None (not run, or unreadable: run again).

    Parameters
    ----------
    out : Path
        The sweep's folder.
    task_id : str
        The task's id.

    Returns
    -------
    dict of str to Any or None
        The parsed ``report.json``.
    """
    path = task_dir(out, task_id) / REPORT
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def write_task(out: Path, task_id: str, report: dict[str, Any], plan_csv: str | None) -> Path:
    """Write ``plan.csv`` (if any), then ``report.json``, atomically; returns the task folder.

    Parameters
    ----------
    out : Path
        The sweep's folder.
    task_id : str
        The task's id.
    report : dict of str to Any
        The task's report (JSON without NaN or infinity).
    plan_csv : str or None
        The planned path as CSV text (plan mode); None for none.

    Returns
    -------
    Path
        The task's folder.
    """
    folder = task_dir(out, task_id)
    folder.mkdir(parents=True, exist_ok=True)
    if plan_csv is not None:
        atomic_write_text(folder / PLAN, plan_csv)
    atomic_write_text(folder / REPORT, json.dumps(report, indent=2, allow_nan=False) + "\n")
    return folder


def write_manifest(out: ResumableDir | str | Path, manifest: dict[str, Any]) -> Path:
    """``DIR/sweep.json``, after :meth:`~obsplan.core.outputs.ResumableDir.claim` (which creates
    ``DIR`` with the sweep marker, or checks it is still the folder checked): from then on
    ``DIR`` is this sweep's folder. A path is checked first (:class:`ResumableDir`).

    Parameters
    ----------
    out : ResumableDir or str or Path
        The checked folder (:func:`check_out`), or a path to check.
    manifest : dict of str to Any
        The sweep (axes, mode, base), its task ids and the code fingerprint.

    Returns
    -------
    Path
        ``DIR/sweep.json``.
    """
    if isinstance(out, ResumableDir):
        path = out.claim()
    else:
        with ResumableDir(out, "sweep") as target:
            path = target.claim()
    return atomic_write_text(path / MANIFEST, json.dumps(manifest, indent=2) + "\n")


def read_manifest(out: Path, *, axes: bool = False) -> dict[str, Any]:
    """``DIR/sweep.json``.

    Parameters
    ----------
    out
        The sweep's folder.
    axes
        Also require the sweep's ``"axes"`` (what redrawing the figures reads).

    Returns
    -------
    dict of str to Any
        The parsed manifest (with a ``"sweep"`` object).

    Raises
    ------
    InputError
        If ``out`` holds no sweep, or a ``sweep.json`` that is not a sweep's manifest (not
        JSON, or JSON of another kind: no ``"sweep"`` object, or without its ``"axes"``).
    """
    path = Path(out) / MANIFEST
    if not path.exists():
        raise InputError(
            f"{out} holds no sweep ({MANIFEST} not found); give the --out folder of a sweep"
        )
    what = "the manifest of an obsplan sweep"
    data = read_json(path, what)
    sweep = data.get("sweep") if isinstance(data, dict) else None
    got = None
    if not isinstance(data, dict):
        kinds = {list: "a list", str: "a string", bool: "a boolean", type(None): "null"}
        got = kinds.get(type(data), "a number")
    elif not isinstance(sweep, dict):
        got = "an object without a 'sweep' object"
    elif axes and not isinstance(sweep.get("axes"), dict):
        got = "a 'sweep' object without its 'axes'"
    if got is not None:
        raise InputError(
            f"{path}: not {what} (it holds {got}); {out} is not a sweep's --out folder: give "
            "another folder"
        )
    return data
