"""Running a sweep on Dask: local cluster or an existing one, resume, retries, nothing lost.

:func:`sweep` expands and validates every task first (a bad task is an error before anything
runs or any file is written), skips the tasks whose report is already in ``DIR`` (keyed by task
id, so a re-run of the same command, or of an extended sweep, resumes), and sends the others to
Dask workers as plain data. Each result is written to ``DIR/tasks/<id>/`` the moment it arrives,
and the table ``DIR/results.{parquet,csv}`` is rewritten every ten seconds or so and on the way
out, whatever the way out is (end, Ctrl-C, a lost scheduler): only the tasks in flight are lost.

Workers: by default a :class:`distributed.LocalCluster` of one-thread worker processes (one per
core; at most :data:`~obsplan.core.budget.MAX_WORKERS_PER_CORE` per core, refused before any
work; SIGINT and SIGTERM stop their start at once) with the BLAS/OpenMP pools pinned to one
thread (set in the nanny before the worker process starts, so it holds from the worker's first
import; :func:`obsplan.sweeps.tasks.worker_threads` reads it back). A task whose worker dies
is retried ``retries`` times (default once), then recorded as failed with the error. On a local
cluster the scheduler itself re-runs nothing (``allowed-failures = 0``), so "retried once" means
exactly one more attempt; an existing scheduler applies its own
``distributed.scheduler.allowed-failures`` first.

An existing scheduler (``--scheduler``, ``--scheduler-file``, ``DASK_SCHEDULER_ADDRESS``) is
probed before Dask connects (:func:`probe_scheduler`: its handshake within
:data:`CONNECT_TIMEOUT_S` in all, at most :data:`HANDSHAKE_MAX_BYTES` read), and a scheduler file
is checked to be a JSON object with a string ``"address"`` (:func:`scheduler_file_address`): a
silent or foreign service, or a file that is not one, is one line and exit 2.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import dataclasses
import functools
import importlib.util
import json
import logging
import os
import signal
import socket
import struct
import sys
import tempfile
import time
import uuid
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

import obsplan.sweeps.spec as specs
from obsplan.core import budget, interrupts
from obsplan.core.errors import InputError, ObsplanError
from obsplan.core.textfiles import read_text
from obsplan.estimation import jitcache
from obsplan.sweeps.spec import SweepSpec, Task, as_spec, expand, unique_tasks
from obsplan.sweeps.store import (
    check_code,
    check_out,
    finished_tasks,
    read_report,
    write_manifest,
    write_task,
)
from obsplan.sweeps.table import build_table, write_table
from obsplan.sweeps.tasks import THREAD_ENV, run_task
from obsplan.version import __version__

#: Seconds between two rewrites of the results table while tasks arrive (at least; a table that
#: takes long to write, thousands of rows, is rewritten at most 10 % of the time). The table is a
#: view of the task reports, each written when its task ends, so nothing is lost in between; it
#: is also written on the way out. Rewriting it often took CPU from the workers on a small
#: machine (measured in benchmarks/bench_sweep.py: "client" CPU per task).
FLUSH_S = 10.0
#: Seconds to wait for a connection to an existing scheduler, its handshake included: an address
#: where no Dask scheduler answers in this time is refused (exit 2).
CONNECT_TIMEOUT_S = 10.0
#: Most bytes of a scheduler's first message read by :func:`probe_scheduler` (a Dask handshake
#: is ~60 bytes).
HANDSHAKE_MAX_BYTES = 1 << 16
#: Largest scheduler file read [bytes] (Dask writes a few hundred bytes of JSON).
MAX_SCHEDULER_FILE_BYTES = 1_000_000
#: Seconds the client waits for a lost scheduler to come back before giving up.
LOST_SCHEDULER_S = 20.0
#: Seconds a worker process gets to stop when the sweep is interrupted, before it is killed.
KILL_TIMEOUT_S = 0.5
#: Seconds the workers of a local cluster may take to start (SIGINT and SIGTERM are honoured
#: meanwhile; a few seconds each on a loaded machine, at most two per core start).
START_TIMEOUT_S = 300.0
#: Seconds an interrupted start of a local cluster may take to stop (workers killed, closed).
ABORT_S = 10.0


class ClusterError(ObsplanError):
    """The Dask scheduler was lost during a sweep (finished tasks are kept; re-run to resume)."""


@dataclass(frozen=True)
class SweepStart:
    """What a sweep is about to do (passed to ``on_start``; the CLI prints it).

    Attributes
    ----------
    name : str
    tasks : int
        Tasks (rows) of the sweep.
    unique : int
        Distinct problems among them.
    finished : int
        Already in ``DIR`` (skipped).
    to_run : int
    scheduler : str or None
        Scheduler address (None when nothing runs).
    dashboard : str or None
        Dask dashboard address, when the scheduler serves one.
    worker_threads : tuple[int, ...]
        Threads of each worker (tasks run one at a time per worker process whatever this is).
    """

    name: str
    tasks: int
    unique: int
    finished: int
    to_run: int
    scheduler: str | None = None
    dashboard: str | None = None
    worker_threads: tuple[int, ...] = ()


def default_workers() -> int:
    """Worker processes of a local cluster: one per core this process may run on
    (``dask.system.CPU_COUNT`` honours CPU affinity, e.g. ``taskset``, and cgroup quotas, e.g.
    a SLURM allocation or a container, where ``os.cpu_count()`` counts the whole machine).

    Returns
    -------
    int
        The cores this process may use, at least one [processes].
    """
    import dask.system

    return max(1, int(dask.system.CPU_COUNT))


def check_workers(workers: int | None, field: str = "--workers") -> None:
    """Refuse a local cluster of fewer than one or more than
    :data:`~obsplan.core.budget.MAX_WORKERS_PER_CORE` worker processes per core
    (:func:`obsplan.core.budget.check_workers`), before anything starts.

    Parameters
    ----------
    workers : int or None
        Worker processes asked for [processes]; None (one per core) is not checked.
    field : str, optional
        The option that asked for them (named in the message).

    Raises
    ------
    InputError
        If ``workers`` is less than 1 or more than
        :data:`~obsplan.core.budget.MAX_WORKERS_PER_CORE` per core of :func:`default_workers`.
    """
    if workers is not None:
        budget.check_workers(workers, default_workers(), field)


def local_cluster(workers: int | None = None, **kwargs: Any):
    """A :class:`distributed.LocalCluster` of ``workers`` one-thread worker processes (default:
    one per core; at most :func:`check_workers` allows), BLAS/OpenMP pinned to one thread, no
    scheduler-side re-runs of a task whose worker died, at most one task queued per worker, and
    Dask's scratch space in a temporary folder removed with the cluster.

    The scheduler and the cluster's event-loop thread start with SIGINT blocked
    (:func:`obsplan.core.interrupts.spawning`), and the worker processes the loop thread spawns
    inherit it: a terminal's Ctrl-C reaches the parent alone. The workers then start while
    SIGINT and SIGTERM are honoured: an interruption kills the workers already spawned and
    closes the cluster at once (:func:`_abort_start`), instead of waiting for every worker to
    start (minutes with many workers on a small machine).

    Parameters
    ----------
    workers : int or None, optional
        Worker processes [processes]; None: :func:`default_workers` (one per core).
    **kwargs
        Passed to :class:`distributed.LocalCluster` (except ``n_workers``, ``threads_per_worker``
        and ``processes``, set here); by default ``dashboard_address=":8787"`` (another free
        port if it is taken), ``silence_logs=logging.CRITICAL`` and
        ``preload=["obsplan.sweeps.tasks"]``.

    Returns
    -------
    distributed.LocalCluster
        The cluster, its workers started; its scratch folder is removed when it closes.

    Raises
    ------
    InputError
        If ``workers`` is beyond what :func:`check_workers` allows.
    ClusterError
        If the workers do not start within :data:`START_TIMEOUT_S` seconds (the cluster is
        stopped).
    """
    from multiprocessing import resource_tracker

    import dask
    import distributed  # noqa: F401 - its configuration first: dask.config.set below restores
    # the configuration it found, and would drop a section distributed added meanwhile

    n = workers if workers is not None else default_workers()
    check_workers(n)
    # multiprocessing's resource tracker started now, before the signals are held: started by
    # the cluster's loop thread (the nannies' first queue), it would unblock SIGINT there, and
    # the workers spawned from that thread would get a terminal's Ctrl-C while they import
    resource_tracker.ensure_running()
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    environ.update(THREAD_ENV)
    # Dask's default MALLOC_TRIM_THRESHOLD_=65536 returns memory to the OS eagerly; it also
    # freezes glibc's mmap threshold at 128 kB, and IPOPT/CasADi in a worker thread then ran
    # 20-50 % slower than in a plain process (benchmarks/bench_sweep.py): keep glibc's defaults
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    # the scratch folders of the scheduler and the workers (Dask's "dask-scratch-space", left in
    # the system temp folder otherwise) in a folder removed with the cluster: closed by
    # dask_client, or when the cluster object is collected or the interpreter exits
    scratch = tempfile.TemporaryDirectory(prefix="obsplan-dask-", ignore_cleanup_errors=True)
    config = {
        "temporary-directory": scratch.name,
        "distributed.nanny.pre-spawn-environ": environ,
        "distributed.scheduler.allowed-failures": 0,
        # no task queued behind the running one on a worker (with the client's feed of one
        # task per worker thread, _run): a worker that dies takes no bystander with it
        "distributed.scheduler.worker-saturation": 1.0,
    }
    kwargs.setdefault("dashboard_address", ":8787")
    # a worker death is reported by the sweep itself (the task's error), not by log lines
    kwargs.setdefault("silence_logs", logging.CRITICAL)
    kwargs.setdefault("preload", ["obsplan.sweeps.tasks"])  # its dask_setup: workers ignore Ctrl-C
    # the configuration is read when the nannies are made, during _start_workers: held till then
    with dask.config.set(config), warnings.catch_warnings():
        # port 8787 taken (another cluster): Dask serves the dashboard on a free port instead,
        # and the sweep reports the address it got
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        with interrupts.spawning():  # the scheduler and the loop thread: seconds at most
            cluster = _cluster_class()(n_workers=0, threads_per_worker=1, processes=True, **kwargs)
        cluster.scratch = scratch
        _start_workers(cluster, n)
    return cluster


def _start_workers(cluster: Any, n: int) -> None:
    """Start ``n`` workers of ``cluster`` and wait for them, honouring SIGINT and SIGTERM: on an
    interruption (or a failure) the cluster is stopped at once and the exception raised."""
    cluster.scale(n)

    async def grow() -> None:
        await cluster._correct_state()

    future = asyncio.run_coroutine_threadsafe(grow(), cluster.loop.asyncio_loop)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            try:
                future.result(timeout=0.1)  # short waits: a signal is raised here at once
                break
            except concurrent.futures.TimeoutError:
                if time.monotonic() > deadline:
                    raise ClusterError(
                        f"the {n} workers of the local cluster did not start within "
                        f"{START_TIMEOUT_S:.0f} s; use fewer --workers"
                    ) from None
    except BaseException:
        _abort_start(cluster, future)
        raise


def _worker_pids(cluster: Any) -> list[int]:
    """The worker processes the nannies of ``cluster`` have spawned so far."""
    pids = []
    for nanny in list(getattr(cluster, "_created", ())):
        proc = getattr(getattr(nanny, "process", None), "process", None)
        with contextlib.suppress(Exception):
            if proc is not None and proc.pid:
                pids.append(int(proc.pid))
    return pids


def _abort_start(cluster: Any, starting: concurrent.futures.Future) -> None:
    """Stop a cluster whose workers are starting, without waiting for them: kill (SIGKILL) every
    worker process spawned, again until the start has given up (a nanny may spawn its process
    meanwhile), then close the cluster. Nothing of theirs is kept: no task ran."""
    deadline = time.monotonic() + ABORT_S
    while True:
        for pid in _worker_pids(cluster):
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        if starting.done() or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    with contextlib.suppress(Exception):
        cluster.close(timeout=ABORT_S)


@functools.cache
def _cluster_class() -> type:
    """:class:`distributed.LocalCluster` that removes its scratch folder when it closes
    (defined on first use: distributed is imported only when a sweep runs)."""
    from distributed import LocalCluster

    class ScratchCluster(LocalCluster):
        scratch: tempfile.TemporaryDirectory | None = None

        async def _close(self) -> None:
            try:
                await super()._close()
            finally:
                if self.scratch is not None:
                    self.scratch.cleanup()

    return ScratchCluster


def configured_scheduler() -> str | None:
    """The scheduler address of Dask's own configuration (``scheduler-address``: the
    ``DASK_SCHEDULER_ADDRESS`` environment variable or a Dask config file), or None.

    Returns
    -------
    str or None
        The address, e.g. ``"tcp://host:8786"``; None if none is configured.
    """
    import dask

    address = dask.config.get("scheduler-address", None)
    return str(address) if address else None


def _one_cluster(workers: Any, scheduler: Any, scheduler_file: Any) -> None:
    """Refuse more than one of ``--workers``, ``--scheduler`` and ``--scheduler-file``."""
    given = [
        n
        for n, v in (
            ("--workers", workers),
            ("--scheduler", scheduler),
            ("--scheduler-file", scheduler_file),
        )
        if v is not None
    ]
    if len(given) > 1:
        raise InputError(
            f"{' and '.join(given)} exclude each other: an existing cluster has its own "
            "workers, and one scheduler is enough"
        )


#: What to do about an address where no Dask scheduler answers.
_SCHEDULER_FIX = (
    "check the address (a scheduler listens on tcp://HOST:8786 by default; 8787 is its "
    "dashboard) or start one with `dask scheduler`"
)


def scheduler_file_address(path: str | Path) -> str:
    """The scheduler's address in a scheduler file (``dask scheduler --scheduler-file FILE``
    writes a JSON object with a string ``"address"``), checked before it is used.

    Parameters
    ----------
    path : str or Path
        The scheduler file (refused beyond :data:`MAX_SCHEDULER_FILE_BYTES` bytes).

    Returns
    -------
    str
        The scheduler's address, stripped of surrounding blanks, e.g. ``"tcp://host:8786"``.

    Raises
    ------
    InputError
        Naming ``--scheduler-file FILE`` and what is wrong: no such file, not a text file, not
        JSON, or no string ``"address"``.
    """
    where = f"--scheduler-file {path}"
    if not Path(path).is_file():
        raise InputError(
            f"{where}: no such file; start the scheduler with `dask scheduler "
            f"--scheduler-file {path}` (on a file system the client sees) and give the same path"
        )
    fix = (
        f"give the file `dask scheduler --scheduler-file {path}` writes, a JSON object "
        'such as {"address": "tcp://HOST:8786", ...}'
    )
    with contextlib.suppress(OSError):  # read_text says what else is wrong
        if (size := Path(path).stat().st_size) > MAX_SCHEDULER_FILE_BYTES:
            raise InputError(
                f"{where}: {size / 1e6:,.1f} MB, not a scheduler file (Dask writes a few "
                f"hundred bytes); {fix}"
            )
    try:
        text = read_text(path, "a Dask scheduler file (JSON)", max_bytes=MAX_SCHEDULER_FILE_BYTES)
    except InputError as exc:
        raise InputError(f"--scheduler-file {exc}") from None
    try:
        data = json.loads(text)
    except ValueError as exc:  # JSONDecodeError, or a number too long to convert
        raise InputError(f"{where}: not JSON ({str(exc)[:120]}); {fix}") from None
    address = data.get("address") if isinstance(data, dict) else None
    if not isinstance(address, str) or not address.strip():
        got = (
            f'"address" is {json.dumps(address)[:80]}'
            if isinstance(data, dict) and "address" in data
            else f'no "address" in {json.dumps(data)[:80]}'
        )
        raise InputError(f"{where}: {got}, not the scheduler's address as a string; {fix}")
    return address.strip()


def _recv(sock: socket.socket, n: int, deadline: float) -> tuple[bytes, str]:
    """Up to ``n`` bytes from ``sock`` before ``deadline`` (time.monotonic()); with why it
    stopped short: ``""`` (all read), ``"timeout"`` or ``"closed"``."""
    data = b""
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            return data, "timeout"
        sock.settimeout(left)
        try:
            chunk = sock.recv(n - len(data))
        except TimeoutError:
            return data, "timeout"
        except OSError:  # reset by the peer
            return data, "closed"
        if not chunk:
            return data, "closed"
        data += chunk
    return data, ""


def _is_handshake(body: bytes) -> bool:
    """Whether ``body`` (a message's frames, after its 8-byte length) is a Dask comm handshake:
    a msgpack mapping naming the peer's ``python`` (and ``compression``, ``pickle-protocol``)."""
    try:
        import msgpack
        from distributed.protocol.utils import unpack_frames

        for frame in unpack_frames(body):
            msg = msgpack.loads(bytes(frame), raw=False)
            if isinstance(msg, dict) and "python" in msg:
                return True
    except Exception:  # noqa: BLE001 - any garbage is simply not a handshake
        return False
    return False


def probe_scheduler(address: str, where: str, timeout: float | None = None) -> None:
    """Refuse, within ``timeout`` seconds in all (default :data:`CONNECT_TIMEOUT_S`), an address
    where no Dask scheduler answers, before Dask connects to it.

    A Dask scheduler speaks first: right after a TCP connection is accepted it sends its
    handshake (an 8-byte length, then msgpack frames naming its Python). Dask's own client
    waits for it without a limit (a silent service, e.g. the dashboard's port 8787, hung the
    sweep for ever) and allocates whatever length a foreign service's first bytes spell (an
    SSH banner: "Unable to allocate 2.82 EiB"). The probe reads at most
    :data:`HANDSHAKE_MAX_BYTES`, checks the message, answers with the same handshake (so the
    scheduler logs no aborted connection) and closes. Addresses of other transports than
    ``tcp://`` (``tls://``, ``ucx://``) are left to Dask's connect timeout.

    ``where`` names the option and what the user gave (``"--scheduler tcp://h:8787"``,
    ``"--scheduler-file FILE"``).

    Parameters
    ----------
    address : str
        The scheduler's address, e.g. ``"tcp://host:8786"``.
    where : str
        The option and what the user gave (starts every message).
    timeout : float or None, optional
        Time for the connection and the handshake in all [s]; None: :data:`CONNECT_TIMEOUT_S`.

    Raises
    ------
    InputError
        ``"<where>: not an address (...)"``, ``"<where>: cannot reach a Dask scheduler there
        (...)"`` (nothing listens) or ``"<where>: not a Dask scheduler at ADDRESS: <what it
        did>; <fix>"``.
    """
    from distributed.comm.addressing import parse_address, parse_host_port

    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    try:
        scheme, loc = parse_address(address)
        if scheme != "tcp":
            return
        host, port = parse_host_port(loc)
        port = int(port)
        if not 0 < port < 65536:
            raise ValueError(f"port {port} is not in 1..65535")
    except (ValueError, TypeError) as exc:
        named = "" if where.endswith(address) else f"{address!r} is "
        raise InputError(
            f"{where}: {named}not an address ({exc}); give the scheduler's, tcp://HOST:8786 "
            "(8786 is its default port)"
        ) from None
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:  # refused, unreachable, unknown host, or the connect timed out
        raise InputError(
            f"{where}: cannot reach a Dask scheduler there"
            + ("" if where.endswith(address) else f", at {address}")
            + f" ({type(exc).__name__}: {exc}); {_SCHEDULER_FIX}"
        ) from None
    with sock:
        head, stop = _recv(sock, 8, deadline)
        why = ""
        if not head:
            why = (
                f"it accepted the connection but sent nothing in {timeout:g} s (a Dask "
                "scheduler greets at once)"
                if stop == "timeout"
                else "it closed the connection without a word"
            )
        elif len(head) < 8 or not 16 <= struct.unpack("<Q", head)[0] <= HANDSHAKE_MAX_BYTES:
            more, _ = _recv(sock, 56, min(deadline, time.monotonic() + 0.2))
            why = f"it sent {(head + more)[:64]!r}, not a Dask handshake"
        else:
            body, stop = _recv(sock, struct.unpack("<Q", head)[0], deadline)
            if stop or not _is_handshake(body):
                why = (
                    f"it sent {(head + body)[:64]!r}, not a Dask handshake"
                    if not stop
                    else f"it sent {len(head) + len(body)} bytes of a message, then "
                    + ("nothing more" if stop == "timeout" else "closed the connection")
                )
            else:
                with contextlib.suppress(OSError):
                    sock.settimeout(max(0.01, deadline - time.monotonic()))
                    sock.sendall(head + body)  # our handshake: the scheduler's own, returned
        if why:
            raise InputError(f"{where}: not a Dask scheduler at {address}: {why}; {_SCHEDULER_FIX}")


@contextlib.contextmanager
def dask_client(
    workers: int | None = None,
    scheduler: str | None = None,
    client: Any = None,
    scheduler_file: str | Path | None = None,
) -> Iterator[Any]:
    """The client a sweep runs on.

    In order: ``client`` as given (left open); a client of the scheduler at ``scheduler``, of
    the one described by ``scheduler_file`` (written by ``dask scheduler --scheduler-file``,
    the usual way on HPC), or, when no ``workers`` are asked for, of Dask's configured
    ``scheduler-address`` (``DASK_SCHEDULER_ADDRESS``); otherwise a new :func:`local_cluster`
    of ``workers``. Clients and clusters made here are closed on exit.

    Parameters
    ----------
    workers : int or None, optional
        Worker processes of a new local cluster [processes]; None: one per core, or Dask's
        configured scheduler if there is one.
    scheduler : str or None, optional
        Address of an existing Dask scheduler, e.g. ``"tcp://host:8786"``.
    client : distributed.Client or None, optional
        An existing client, yielded as is (left open; the other arguments are then ignored).
    scheduler_file : str or Path or None, optional
        The JSON file of ``dask scheduler --scheduler-file FILE``.

    Yields
    ------
    distributed.Client
        The client of the cluster the sweep runs on.

    Raises
    ------
    InputError
        If more than one of ``workers``, ``scheduler`` and ``scheduler_file`` are given, too
        many ``workers`` (:func:`check_workers`), a scheduler file that is not one
        (:func:`scheduler_file_address`), or no Dask scheduler answers at the address
        (:func:`probe_scheduler`).
    """
    if client is not None:
        yield client
        return
    from distributed import Client

    _one_cluster(workers, scheduler, scheduler_file)
    where: str | None = None
    address: str | None = None
    if scheduler is not None:
        where, address = f"--scheduler {scheduler}", scheduler
    elif scheduler_file is not None:
        where = f"--scheduler-file {scheduler_file}"
        address = scheduler_file_address(scheduler_file)
    elif workers is None and (configured := configured_scheduler()) is not None:
        where = f"DASK_SCHEDULER_ADDRESS (Dask's scheduler-address) {configured}"
        address = configured
    if where is not None and address is not None:
        probe_scheduler(address, where)  # a silent or foreign service: refused in seconds
        try:
            c = Client(address=address, timeout=CONNECT_TIMEOUT_S)
        except Exception as exc:  # noqa: BLE001 - Dask's connection raises anything at all
            raise InputError(
                f"{where}: not a Dask scheduler at {address}: {type(exc).__name__}: "
                f"{str(exc).splitlines()[0][:200] if str(exc) else ''}; {_SCHEDULER_FIX}"
            ) from None
        try:
            yield c
        finally:
            with contextlib.suppress(Exception):
                c.close(timeout=5)
        return
    cluster: Any = None
    local: Client | None = None
    interrupted = False
    try:
        # a signal while the workers start stops them at once (local_cluster)
        with _workers_stderr_quiet():
            cluster = local_cluster(workers)
        local = Client(cluster)
        yield local
    except BaseException:
        interrupted = True
        raise
    finally:
        if local is not None:
            with contextlib.suppress(Exception):
                local.close(timeout=5)
        if cluster is not None:
            if interrupted:
                # a worker busy in IPOPT would get 4 s to finish its task: stop at once instead
                with contextlib.suppress(Exception):
                    cluster.sync(_stop_workers, cluster, KILL_TIMEOUT_S)
            with contextlib.suppress(Exception):
                cluster.close(timeout=10)


@contextlib.contextmanager
def _workers_stderr_quiet() -> Iterator[None]:
    """Start worker processes with their stderr on ``/dev/null``.

    A terminal's Ctrl-C reaches the whole process group, workers included; a worker still
    importing (before its preload ignores SIGINT) would print a traceback of Python's own. The
    sweep reports a worker's death itself (the task's error) and Dask's logs are silenced, so
    nothing of use is lost. The parent's stderr is back when the block ends.
    """
    try:
        saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # pragma: no cover - no /dev/null
        yield
        return
    sys.stderr.flush()
    os.dup2(null, 2)
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


async def _stop_workers(cluster: Any, timeout: float) -> None:
    nannies = list(cluster.workers.values())
    await asyncio.gather(*(n.close(timeout=timeout) for n in nannies), return_exceptions=True)


def _finished(report: Mapping[str, Any] | None, retry_failed: bool) -> bool:
    if report is None:
        return False
    status = report.get("sweep", {}).get("status")
    return status == "done" or (status == "failed" and not retry_failed)


def sweep(
    spec: SweepSpec | str | Path | Mapping[str, Any],
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    client: Any = None,
    scheduler_file: str | Path | None = None,
    retries: int = 1,
    retry_failed: bool = False,
    progress: bool = True,
    figures: bool = True,
    force: bool = False,
    on_start: Callable[[SweepStart], None] | None = None,
    runner: Callable[[Task], dict[str, Any]] | None = None,
) -> pd.DataFrame:
    """Run a parameter study on Dask and return its results table.

    Parameters
    ----------
    spec
        A sweep file path, a parsed sweep mapping or a :class:`SweepSpec`.
    out
        Output folder (``DIR``): created, or resumed if it holds this sweep (or, with
        ``force``, another); locked while the sweep runs.
    workers
        Worker processes of a new local cluster (default: one per core; at most
        :data:`~obsplan.core.budget.MAX_WORKERS_PER_CORE` per core).
    scheduler
        Address of an existing Dask scheduler (``tcp://host:8786``) instead. Without
        ``scheduler``, ``scheduler_file`` or ``workers``, Dask's own ``scheduler-address``
        (``DASK_SCHEDULER_ADDRESS``) is used when set.
    client
        An existing :class:`distributed.Client` instead (left open).
    scheduler_file
        The JSON file of ``dask scheduler --scheduler-file FILE`` (HPC) instead.
    retries
        Further attempts of a task whose worker process died.
    retry_failed
        Run again the tasks stored as failed (default: they count as finished).
    progress
        tqdm progress bar (tasks done, failed, ETA) on stderr.
    figures
        Draw ``DIR/figures/`` when every task has finished.
    force
        Write into a ``DIR`` that holds another sweep, or one whose finished tasks were
        computed by other code (every task is then computed again). Never into a folder no
        sweep made (:class:`obsplan.core.outputs.ResumableDir`).
    on_start
        Called once with a :class:`SweepStart` before the first task is sent.
    runner
        Advanced: replaces :func:`obsplan.sweeps.tasks.run_task` (same signature; must be
        importable or picklable by value on the workers). Results are still keyed by problem,
        mode, version and the package's code fingerprint only.

    Returns
    -------
    pandas.DataFrame
        One row per task (:mod:`obsplan.sweeps.table`), also in ``DIR/results.parquet`` and
        ``DIR/results.csv``.

    Raises
    ------
    SweepFileError
        Bad sweep file or an invalid task (before anything runs).
    InputError
        Bad options (more local ``workers`` than :func:`check_workers` allows) or output
        folder, no Dask scheduler at the address or a bad scheduler file (:func:`dask_client`),
        or ``out``'s finished tasks were computed by other code
        (:func:`obsplan.sweeps.store.check_code`; ``force`` computes them again).
    ClusterError
        The scheduler was lost (finished tasks are kept).
    KeyboardInterrupt
        After writing everything that had finished.

    Examples
    --------
    Two beacon positions of the default problem, baselines only (no solver), one worker:

    >>> import tempfile
    >>> from obsplan import sweep
    >>> from obsplan.planning.problem.parse import PROBLEMS_DIR
    >>> base = str(PROBLEMS_DIR / "localise.toml")
    >>> spec = {"sweep": {"name": "doc", "base": base, "mode": "baselines"},
    ...         "base": {"horizon": {"steps": 20}, "validation": {"runs": 2}},
    ...         "axes": {"beacon.position": [[0.0, 0.0], [50.0, 0.0]]}}
    >>> with tempfile.TemporaryDirectory() as out:
    ...     table = sweep(spec, out, workers=1, progress=False, figures=False)
    >>> len(table)
    2
    """
    spec = as_spec(spec)
    tasks = expand(spec)
    if retries < 0:
        raise InputError(f"retries must be >= 0, got {retries}")
    _one_cluster(workers, scheduler, scheduler_file)  # before any work
    check_workers(workers)
    # checked, nothing written before the cluster is up; locked against another run
    target = check_out(out, force, spec.name)
    out = target.path
    with target:
        code = specs.code_fingerprint()
        check_code(out, code, force)
        unique = unique_tasks(tasks)
        stored: dict[str, dict[str, Any] | None] = {t.id: read_report(out, t.id) for t in unique}
        todo = [t for t in unique if not _finished(stored[t.id], retry_failed)]
        manifest = {
            "obsplan": __version__,
            "code": code,
            "sweep": spec.to_dict(),
            "tasks": [{"id": t.id, "task": t.index + 1, "axes": t.axes} for t in tasks],
        }
        started = False
        info = SweepStart(
            name=spec.name,
            tasks=len(tasks),
            unique=len(unique),
            finished=len(unique) - len(todo),
            to_run=len(todo),
        )

        def flush() -> None:
            write_table(build_table(tasks, stored), out)

        try:
            if todo:
                with dask_client(workers, scheduler, client, scheduler_file) as c:
                    write_manifest(target, manifest)
                    started = True
                    threads = c.nthreads()
                    info = dataclasses.replace(
                        info,
                        scheduler=c.scheduler.address,
                        dashboard=_dashboard(c),
                        worker_threads=tuple(threads.values()),
                    )
                    if on_start is not None:
                        on_start(info)
                    # workers on this machine share its numba cache: say when they compile first
                    local = client is None and scheduler is None and scheduler_file is None
                    note = (
                        jitcache.compile_note()
                        if progress and local and workers_local(workers)
                        else None
                    )
                    task_runner = runner or run_task
                    _run(c, todo, out, stored, spec, task_runner, retries, progress, flush, note)
            else:
                write_manifest(target, manifest)
                started = True
                if on_start is not None:
                    on_start(info)
        finally:
            df = build_table(tasks, stored)
            if started:
                write_table(df, out)
        if figures and not (df["status"] == "pending").any():
            from obsplan.sweeps.figures import figures_from_manifest

            figures_from_manifest(df, out, spec.to_dict())
        return df


def has_bokeh() -> bool:
    """Whether bokeh can be imported here (Dask serves a dashboard page without it, which only
    says that it needs bokeh). Run on the scheduler by :func:`_dashboard`.

    Returns
    -------
    bool
        True if ``bokeh`` is installed (found without importing it); False also for a broken
        installation.
    """
    try:
        return importlib.util.find_spec("bokeh") is not None
    except (ImportError, ValueError):  # a broken or half-removed installation
        return False


def workers_local(workers: int | None) -> bool:
    """Whether a sweep without a given client or scheduler runs on a local cluster (its workers
    then share this machine's numba cache): ``workers`` given, or no Dask scheduler-address
    configured.

    Parameters
    ----------
    workers : int or None
        Worker processes asked for [processes], or None.

    Returns
    -------
    bool
        True if the sweep's workers run on this machine.
    """
    return workers is not None or configured_scheduler() is None


def _dashboard(client: Any) -> str | None:
    """The dashboard link, or None when the scheduler serves none that works (no dashboard
    service, or no bokeh where the scheduler runs)."""
    try:
        services = client.scheduler_info().get("services", {})
        if "dashboard" not in services or not client.run_on_scheduler(has_bokeh):
            return None
    except Exception:  # noqa: BLE001 - informational only
        return None
    return client.dashboard_link


def _run(
    client: Any,
    todo: list[Task],
    out: Path,
    stored: dict[str, dict[str, Any] | None],
    spec: SweepSpec,
    runner: Callable[[Task], dict[str, Any]],
    retries: int,
    progress: bool,
    flush: Callable[[], None],
    note: str | None = None,
) -> None:
    """Feed the tasks to the cluster, at most one per worker thread at a time, and store each
    outcome as it arrives.

    Tasks are not all submitted at once: Dask assigns a small batch of independent tasks to
    workers eagerly, and a worker that dies takes every task assigned to it down (each would then
    be charged an attempt). Keeping one task per worker thread in flight means a crash costs only
    the task that caused it, an interruption loses at most one task per worker, and workers that
    join later (an adaptive or SLURM cluster) are used as they arrive.
    """
    from collections import deque

    from distributed import wait
    from distributed.client import FuturesCancelledError
    from distributed.scheduler import KilledWorker
    from tqdm.auto import tqdm

    attempts: dict[str, int] = {}
    running: dict[Any, Task] = {}
    queue = deque(todo)

    def submit(task: Task) -> None:
        attempts[task.id] = attempts.get(task.id, 0) + 1
        key = f"obsplan-{task.id}-{attempts[task.id]}-{uuid.uuid4().hex[:8]}"
        running[client.submit(runner, task, key=key, pure=False, retries=0)] = task

    def refill() -> None:
        if not queue:
            return
        try:
            slots = max(1, sum(client.nthreads().values()))
        except Exception:  # noqa: BLE001 - scheduler unreachable: handled by the status check
            return
        while queue and len(running) < slots:
            submit(queue.popleft())

    failed = 0
    # ``note``: the workers compile the filters before their first task ends (a cold cache)
    desc = f"{spec.name}: the workers are {note}" if note else spec.name
    bar = tqdm(total=len(todo), desc=desc, unit="task", disable=not progress, leave=True)
    last_flush = time.monotonic()
    flush_every = FLUSH_S
    dirty = False
    lost_since: float | None = None
    try:
        refill()
        while running or queue:
            try:
                done = wait(list(running), timeout=0.5, return_when="FIRST_COMPLETED").done
            except TimeoutError:
                done = set()
            except FuturesCancelledError:  # the client lost its scheduler
                raise ClusterError(_lost(out, len(running))) from None
            if client.status != "running":
                lost_since = lost_since or time.monotonic()
                if client.status in ("closing", "closed") or (
                    time.monotonic() - lost_since > LOST_SCHEDULER_S
                ):
                    raise ClusterError(_lost(out, len(running)))
                continue
            lost_since = None
            for fut in done:
                task = running.pop(fut)
                if fut.status == "finished":
                    outcome = fut.result()
                elif fut.status == "cancelled":
                    raise ClusterError(
                        f"the scheduler dropped task {task.id} (was it restarted?); finished "
                        f"tasks are kept in {out}: run the same command again to resume"
                    )
                else:
                    exc = fut.exception()
                    if isinstance(exc, KilledWorker) and attempts[task.id] <= retries:
                        queue.appendleft(task)
                        continue
                    outcome = _failure(exc, attempts[task.id])
                stored[task.id] = _store(out, task, outcome, attempts[task.id])
                failed += outcome["status"] != "done"
                bar.set_postfix(failed=failed, refresh=False)
                if note:
                    note = None
                    bar.set_description_str(spec.name, refresh=False)
                bar.update(1)
            refill()
            dirty = dirty or bool(done)
            if dirty and time.monotonic() - last_flush > flush_every:
                t0 = time.monotonic()
                flush()
                dirty = False
                last_flush = time.monotonic()
                flush_every = max(FLUSH_S, 10.0 * (last_flush - t0))
    finally:
        bar.close()
        if running:
            with contextlib.suppress(Exception):
                client.cancel(list(running), force=True)


def _lost(out: Path, in_flight: int) -> str:
    """The one line of a lost scheduler: what was lost, what is kept (counted on disk)."""
    n = finished_tasks(out)
    return (
        f"lost the Dask scheduler with {in_flight} task{'s' if in_flight != 1 else ''} in "
        f"flight; {n} finished task{'s are' if n != 1 else ' is'} kept in {out}: run the same "
        "command again to resume"
    )


def _failure(exc: BaseException | None, attempt: int) -> dict[str, Any]:
    """The outcome of a task that did not return: its worker died, or the runner raised."""
    from distributed.scheduler import KilledWorker

    what = (
        "the worker process died while running the task"
        if isinstance(exc, KilledWorker)
        else "the task raised"
    )
    return {
        "status": "failed",
        "error": f"{what} (attempt {attempt}): {type(exc).__name__}: {exc}".splitlines()[0][:500],
        "traceback": None,
        "report": None,
        "plan_csv": None,
        "wall_s": None,
        "worker": None,
    }


def _store(out: Path, task: Task, outcome: Mapping[str, Any], attempts: int) -> dict[str, Any]:
    """Write the task's files; returns the stored report (what the table is built from)."""
    meta = {
        "task_id": task.id,
        "mode": task.mode,
        "status": outcome["status"],
        "error": outcome["error"],
        "traceback": outcome.get("traceback"),
        "attempts": attempts,
        "wall_s": outcome.get("wall_s"),
        "worker": outcome.get("worker"),
        "obsplan": __version__,
        "code": specs.code_fingerprint(),
        "axes": task.axes,
        "problem": task.problem,
    }
    report = {"sweep": meta, **(outcome.get("report") or {})}
    write_task(out, task.id, report, outcome.get("plan_csv"))
    return report
