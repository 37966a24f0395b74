"""``obsplan sweep SWEEP.toml --out DIR [--workers N | --scheduler ADDRESS | --scheduler-file
FILE]``: a parameter study on Dask; ``obsplan sweep --report DIR`` redraws its figures from the
table."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from obsplan.cli.common import Applies, check_applies
from obsplan.core.errors import InputError
from obsplan.core.outputs import check_name

# obsplan.sweeps (pandas, Dask) is imported when the verb runs: every `obsplan` command imports
# this module to build its parser
if TYPE_CHECKING:
    from obsplan.sweeps.run import SweepStart

#: Failed tasks listed at the end (the rest are in the table's ``error`` column).
SHOW_FAILED = 5
#: Options of running a sweep, refused with ``--report``, which only redraws the figures
#: (:func:`~obsplan.cli.common.check_applies`).
APPLIES = tuple(
    Applies(option, "running a sweep", "run")
    for option in (
        "--workers",
        "--scheduler",
        "--scheduler-file",
        "--retry-failed",
        "--no-figures",
        "--force",
        "--quiet",
    )
)


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``sweep`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan sweep``: ``SWEEP.toml`` (optional), ``--out``, ``--workers`` or
        ``--scheduler`` or ``--scheduler-file``, ``--report``, ``--retry-failed``, ``--no-figures``,
        ``--force`` and ``--quiet``.
    """
    p = subparsers.add_parser(
        "sweep",
        help="run a parameter study (many problems) on Dask, resumable",
        description=(
            "Expand a sweep file (a base problem and axes of problem-file fields; see "
            "docs/sweep-files.md) into tasks, validate them all, run them on Dask workers and "
            "write DIR/results.parquet, DIR/results.csv (one row per task), DIR/tasks/<id>/ "
            "(report.json, plan.csv) and DIR/figures/. Re-running the same command resumes: "
            "finished tasks are skipped."
        ),
    )
    p.add_argument("sweep_file", nargs="?", metavar="SWEEP.toml", help="the sweep file")
    p.add_argument("--out", metavar="DIR", help="output folder (created, or resumed)")
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes of a local Dask cluster (default: one per core)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="use an existing Dask cluster, e.g. tcp://10.0.0.5:8786 (default without "
        "--workers: Dask's DASK_SCHEDULER_ADDRESS when set, else a local cluster)",
    )
    where.add_argument(
        "--scheduler-file",
        metavar="FILE",
        help="use the Dask cluster whose scheduler wrote FILE "
        "(`dask scheduler --scheduler-file FILE`, as on HPC)",
    )
    p.add_argument(
        "--report",
        metavar="DIR",
        help="only redraw DIR/figures/ from DIR/results.parquet (no SWEEP.toml)",
    )
    p.add_argument(
        "--retry-failed", action="store_true", help="run again the tasks recorded as failed"
    )
    p.add_argument("--no-figures", action="store_true", help="do not draw DIR/figures/")
    p.add_argument(
        "--force",
        action="store_true",
        help="write into a DIR that holds another sweep, or whose tasks were computed by other "
        "obsplan code (they are computed again); never into a folder no obsplan sweep made",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _announce(info: SweepStart, quiet: bool) -> None:
    head = (
        f"sweep {info.name}: {info.tasks} tasks"
        + (f" ({info.unique} distinct problems)" if info.unique != info.tasks else "")
        + f", {info.finished} already done, {info.to_run} to run"
    )
    if info.scheduler is not None:
        n = len(info.worker_threads)
        head += f" on {info.scheduler} ({n} worker{'s' if n != 1 else ''})"
    print(head, flush=True)
    if info.dashboard and not quiet:
        print(f"dashboard: {info.dashboard}", flush=True)
    if any(t > 1 for t in info.worker_threads):
        print(
            "obsplan sweep: warning: some workers have several threads; tasks run one at a "
            "time per worker process (IPOPT must not run in threads): start workers with "
            "`dask worker ADDRESS --nthreads 1 --nworkers N`",
            file=sys.stderr,
        )


def kept(out: Path) -> str:
    """What an interrupted or broken-off sweep leaves in ``out``, in words (one true clause).

    Parameters
    ----------
    out : Path
        The sweep's ``--out`` folder.

    Returns
    -------
    str
        ``"nothing was written"`` when the folder does not exist, else how many finished tasks
        it keeps and that running the same command again resumes.
    """
    from obsplan.sweeps.store import finished_tasks

    if not out.is_dir():
        return "nothing was written"
    n = finished_tasks(out)
    if n == 0:
        return f"no task had finished; run the same command again to start the sweep in {out}"
    return (
        f"{n} finished task{'s are' if n != 1 else ' is'} kept in {out}; run the same command "
        "again to resume"
    )


def _quiet_dask_logs() -> None:
    """Silence the ``distributed`` loggers: Dask logs a lost connection or a dead worker as
    tracebacks (``distributed.client`` has a level and a handler of its own, so setting the
    parent's level is not enough); the sweep reports both itself, in one line."""
    import distributed  # noqa: F401 - configures its loggers on import

    for name, logger in list(logging.Logger.manager.loggerDict.items()):
        if name == "distributed" or name.startswith("distributed."):
            if isinstance(logger, logging.Logger):
                logger.setLevel(logging.CRITICAL)


def run(args: argparse.Namespace) -> int:
    """Run the verb; 0 when every task finished, 1 if any failed or the scheduler was lost,
    130 on Ctrl-C.

    With ``--report DIR`` only redraws the figures of a finished sweep.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 when every task is done (or the figures were redrawn); 1 when any task failed (the
        first :data:`SHOW_FAILED` are named on stderr).

    Raises
    ------
    InputError
        ``--report`` with ``SWEEP.toml``, ``--out`` or an option of running a sweep
        (:data:`APPLIES`), no ``SWEEP.toml`` or no ``--out``, or a bad sweep file or folder
        (exit 2).
    ClusterError
        The Dask scheduler was lost (:class:`obsplan.sweeps.run.ClusterError`; finished tasks
        are kept; exit 1).
    KeyboardInterrupt
        Ctrl-C (or SIGTERM), with ``kept`` (:func:`kept`) saying what the folder keeps; exit
        130 / 143 by :func:`obsplan.cli.main`.
    """
    from obsplan.sweeps.figures import redraw_figures
    from obsplan.sweeps.run import sweep
    from obsplan.sweeps.store import FIGURES, RESULTS_CSV, RESULTS_PARQUET

    if args.report is not None:
        if args.sweep_file is not None or args.out is not None:
            raise InputError(
                "--report DIR redraws the figures of a finished sweep; give it alone "
                "(no SWEEP.toml, no --out)"
            )
        check_applies(args, APPLIES, {"run": "--report only redraws a sweep's figures"})
        written = redraw_figures(args.report)
        print(f"wrote {len(written)} figures to {Path(args.report) / FIGURES}")
        return 0
    if args.sweep_file is None:
        raise InputError("give a SWEEP.toml (or --report DIR to redraw a sweep's figures)")
    if args.out is None:
        raise InputError("give --out DIR, the folder for the results (re-use it to resume)")
    out = check_name(args.out, "--out")  # "" is not the working folder
    _quiet_dask_logs()
    try:
        df = sweep(
            args.sweep_file,
            out,
            workers=args.workers,
            scheduler=args.scheduler,
            scheduler_file=args.scheduler_file,
            retry_failed=args.retry_failed,
            progress=not args.quiet,
            figures=not args.no_figures,
            force=args.force,
            on_start=lambda info: _announce(info, args.quiet),
        )
    except KeyboardInterrupt as exc:
        # the one line `obsplan` prints for the interruption says what is kept
        exc.kept = kept(out)  # type: ignore[attr-defined]
        raise
    counts = df["status"].value_counts()
    done, failed = int(counts.get("done", 0)), int(counts.get("failed", 0))
    figs = sorted((out / FIGURES).glob("*.png")) if not args.no_figures else []
    print(f"{done} done, {failed} failed of {len(df)} tasks")
    print(
        f"wrote {out / RESULTS_PARQUET}, {out / RESULTS_CSV}, {out / 'tasks'}/"
        + (f", {len(figs)} figures in {out / FIGURES}" if figs else "")
    )
    if failed:
        bad = df[df["status"] == "failed"]
        for _, r in bad.head(SHOW_FAILED).iterrows():
            print(f"  task {r['task']} ({r['task_id']}): {r['error']}", file=sys.stderr)
        more = (
            f" ({failed - SHOW_FAILED} more in {out / RESULTS_CSV})" if failed > SHOW_FAILED else ""
        )
        print(
            f"obsplan sweep: failed: {failed} tasks failed{more}; fix the cause and re-run with "
            "--retry-failed",
            file=sys.stderr,
        )
        return 1
    return 0
