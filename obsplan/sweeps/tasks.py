"""What a worker does with one task, and what it sends back (plain data only).

:func:`run_task` rebuilds the problem from its resolved mapping (cheap, and exactly the problem
the task id hashes), then either plans it (:func:`obsplan.plan` with ``processes=1``: the worker
process is the unit of parallelism, and IPOPT is never run in threads) or, in ``baselines`` mode,
computes the metrics and the Monte Carlo validation of the baselines only. It builds its own
solver; nothing heavy crosses the network in either direction: the result is the
``report.json`` mapping, the plan CSV text, the wall time and where it ran.

One task at a time per process: a worker started with several threads would otherwise run
IPOPT/CasADi concurrently in threads, which crashes or does not speed up (casadi#3456, #3607);
:data:`_ONE_AT_A_TIME` serialises them.
"""

from __future__ import annotations

import ctypes
import os
import re
import signal
import socket
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Any

from obsplan.sweeps.spec import Task

#: Environment variables that pin BLAS/OpenMP pools to one thread in worker processes.
THREAD_ENV: dict[str, str] = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "VECLIB_MAXIMUM_THREADS": "1",
    "NUMEXPR_NUM_THREADS": "1",
}
_ONE_AT_A_TIME = threading.Lock()


def run_task(task: Task) -> dict[str, Any]:
    """Compute one task; exceptions become a ``failed`` outcome (never raised).

    Parameters
    ----------
    task : Task
        The task: its resolved problem mapping and mode (``plan`` or ``baselines``).

    Returns
    -------
    dict
        ``status`` (``"done"`` or ``"failed"``), ``error`` (None or one line),
        ``traceback`` (None or text), ``report`` (the report.json mapping or None),
        ``plan_csv`` (text or None), ``wall_s`` [s], ``worker`` (``host:pid``).
    """
    with _ONE_AT_A_TIME:
        _relax_malloc_trim()
        t0 = time.perf_counter()
        out: dict[str, Any] = {"status": "done", "error": None, "traceback": None}
        try:
            report, csv_text = _compute(task)
            out.update(report=report, plan_csv=csv_text)
        except Exception as exc:  # recorded with the task, never lost
            out.update(
                status="failed",
                error=f"{type(exc).__name__}: {exc}".splitlines()[0][:500],
                traceback=traceback.format_exc(),
                report=None,
                plan_csv=None,
            )
        out["wall_s"] = time.perf_counter() - t0
        out["worker"] = f"{socket.gethostname()}:{os.getpid()}"
        return out


def _compute(task: Task) -> tuple[dict[str, Any], str | None]:
    from obsplan.planning import baselines, path_metrics, plan
    from obsplan.planning.problem.parse import problem_from_dict
    from obsplan.planning.validation.validate import validate_paths
    from obsplan.trajectory.sampled import write_csv

    pb = problem_from_dict(task.problem)
    if task.mode == "plan":
        result = plan(pb, processes=1, progress=False)
        report = result.to_dict()
        csv_text = None
        if result.trajectory is not None:
            # write_csv is the one writer of the trajectory CSV format; the text travels back
            with tempfile.TemporaryDirectory(prefix="obsplan-task-") as tmp:
                csv_text = write_csv(result.trajectory, Path(tmp) / "plan.csv").read_text()
        return report, csv_text
    bls = baselines(pb)
    paths = {k: b.trajectory for k, b in bls.items()}
    validation = validate_paths(paths, pb)
    report = {
        "metrics": {k: path_metrics(tr, pb).to_dict() for k, tr in paths.items()},
        "validation": {k: v.to_dict() for k, v in validation.items()},
        "baselines": {k: b.description for k, b in bls.items()},
    }
    return report, None


_MALLOC_TUNED = False
#: glibc's ``mallopt`` parameters and the values restored in Dask workers (glibc's own ceilings
#: for the dynamic thresholds on 64-bit systems).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_TRIM_BYTES, _MMAP_BYTES = 128 << 20, 32 << 20


def _relax_malloc_trim() -> None:
    """Undo Dask's ``MALLOC_TRIM_THRESHOLD_`` in a worker process started with it (``dask
    worker``'s default): a 64 kB trim threshold, which also pins the mmap threshold at 128 kB,
    made every IPOPT solve and Monte Carlo in a worker thread 20-50 % slower than in a plain
    process (measured with benchmarks/bench_sweep.py). Nothing is changed outside a Dask worker
    or where the variable is not set (a local cluster of obsplan's does not set it)."""
    global _MALLOC_TUNED
    if _MALLOC_TUNED or "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return
    _MALLOC_TUNED = True
    try:
        from distributed import get_worker

        get_worker()
        libc = ctypes.CDLL("libc.so.6")
    except (ImportError, ValueError, OSError):  # not in a worker, or not glibc
        return
    libc.mallopt(_M_TRIM_THRESHOLD, _TRIM_BYTES)
    libc.mallopt(_M_MMAP_THRESHOLD, _MMAP_BYTES)


def dask_setup(worker: Any) -> None:
    """Worker preload of the local cluster (``preload=["obsplan.sweeps.tasks"]``): ignore
    SIGINT in worker processes. A Ctrl-C in the terminal reaches the whole process group; the
    client alone handles it (writes what finished, then closes the cluster), instead of every
    worker dying with a traceback.

    Parameters
    ----------
    worker : distributed.Worker
        The worker being set up (not read).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


# ------------------------------------------------------------------------------ threads
def worker_threads() -> dict[str, Any]:
    """This process's thread settings: the pinning variables and, on Linux, the thread count of
    every OpenBLAS library loaded (numpy's and scipy's), read from the library itself.

    Returns
    -------
    dict of str to Any
        ``env`` (each variable of :data:`THREAD_ENV` -> its value or None),
        ``openblas_threads`` (library file name -> its thread count) and ``pid``.
    """
    env = {k: os.environ.get(k) for k in THREAD_ENV}
    blas: dict[str, int] = {}
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:  # not Linux: only the variables can be reported
        maps = ""
    for lib in sorted(set(re.findall(r"(/\S*openblas\S*\.so\S*)", maps))):
        try:
            handle = ctypes.CDLL(lib)
        except OSError:  # pragma: no cover - a mapped library always loads
            continue
        for sym in (
            "scipy_openblas_get_num_threads64_",
            "scipy_openblas_get_num_threads",
            "openblas_get_num_threads64_",
            "openblas_get_num_threads",
        ):
            fn = getattr(handle, sym, None)
            if fn is not None:
                fn.restype = ctypes.c_int
                blas[Path(lib).name] = int(fn())
                break
    return {"env": env, "openblas_threads": blas, "pid": os.getpid()}
