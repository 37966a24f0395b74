"""The one process pool (``run_forked``: the multi-start and the replanned Monte Carlo) under
SIGINT and SIGTERM sent to the whole process group, as a terminal's Ctrl-C and a batch
scheduler's stop are.

A worker of ``multiprocessing.Pool`` that died of SIGTERM while idle held the pool's queue lock,
and the parent then blocked for ever in ``pool.terminate()`` (``plan --starts 2`` hung 8 times in
8). Now the workers ignore both signals, the parent alone raises, kills its workers (SIGKILL) and
exits 130 / 143 at once; nothing waits on a lock a worker could hold.

Each moment is generated from what the run shows (a marker on its stderr and a delay after it):
a pool whose workers are all busy, one worker idle after the first result, the moment a start's
progress bar moves. Each run must end with the signal's exit code within :data:`EXIT_S`, one line
on stderr and no traceback, no process of its group left, nothing written.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import psutil
import pytest

from obsplan.planning.solver.starts import WorkerDied, run_forked

ROOT = Path(__file__).resolve().parents[1]
#: Seconds from the signal to the parent's exit (it kills its workers, it does not wait).
EXIT_S = 5.0
#: Seconds the group's processes may take to be gone once the parent has exited.
GRACE_S = 5.0
SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: A pool of two workers over two items: item 0 returns at once, item 1 sleeps, so that after
#: "result 0" one worker is idle (waiting for an item that never comes) and one busy.
POOL_SCRIPT = textwrap.dedent(
    """
    import sys, time
    from obsplan.core import interrupts
    from obsplan.planning.solver.starts import run_forked

    def work(state, item):
        time.sleep(item)
        return item

    def on_result(i, r):
        print(f"result {i}", file=sys.stderr, flush=True)

    interrupts.install()
    try:
        print("forking", file=sys.stderr, flush=True)
        run_forked(work, None, [0.3, 60.0], 2, on_result)
    except KeyboardInterrupt as exc:
        print(f"interrupted: {exc}", file=sys.stderr, flush=True)
        sys.exit(interrupts.exit_code() or 130)
    sys.exit(0)
    """
)


def _group_alive(pgid: int) -> list[int]:
    alive = []
    for p in psutil.process_iter(["pid", "status"]):
        try:
            if os.getpgid(p.pid) == pgid and p.info["status"] != psutil.STATUS_ZOMBIE:
                alive.append(p.pid)
        except (ProcessLookupError, psutil.Error):
            continue
    return alive


def signal_group_at(argv: list[str], marker: bytes, delay: float, sig: int, cwd: Path) -> dict:
    """Start ``argv`` in its own process group, wait for ``marker`` on its stderr and ``delay``
    more seconds, send ``sig`` to the whole group; what happened."""
    proc = subprocess.Popen(
        argv,
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    chunks: list[bytes] = []
    seen = threading.Event()

    def reader() -> None:
        while b := os.read(proc.stderr.fileno(), 4096):
            chunks.append(b)
            if marker in b"".join(chunks):
                seen.set()
        seen.set()

    threading.Thread(target=reader, daemon=True).start()
    try:
        assert seen.wait(300), b"".join(chunks).decode(errors="replace")
        time.sleep(delay)
        finished_first = proc.poll() is not None
        t0 = time.monotonic()
        if not finished_first:
            os.killpg(proc.pid, sig)
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            code = None  # hung: the failure this file is about
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    deadline = time.monotonic() + GRACE_S
    while (alive := _group_alive(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    for pid in alive:  # pragma: no cover - only when the test fails: leak nothing
        with contextlib.suppress(psutil.Error):
            psutil.Process(pid).kill()
    time.sleep(0.2)
    err = b"".join(chunks).decode(errors="replace")
    return {
        "code": code,
        "took": took,
        "alive": alive,
        "finished_first": finished_first,
        "err": err,
        "marker_seen": marker in b"".join(chunks),
    }


def _assert_stopped(r: dict, sig: int) -> None:
    assert r["code"] is not None, f"hung after {signal.Signals(sig).name}: {r['err'][-800:]}"
    assert r["code"] == 128 + sig, r
    assert r["took"] < EXIT_S, r
    assert not r["alive"], r
    assert "Traceback" not in r["err"], r["err"]


# ------------------------------------------------------------------------------ the pool itself
@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
@pytest.mark.parametrize(
    "marker, delay",
    [
        (b"forking", 0.0),  # while the workers are forked
        (b"forking", 1.0),  # both busy
        (b"result 0", 0.0),  # one worker idle, just after its result
        (b"result 0", 1.0),  # one idle (the hang of multiprocessing.Pool), one busy
    ],
    ids=["forking", "busy", "idle-at-once", "idle"],
)
def test_the_pool_stops_at_once_on_a_signal_to_the_group(marker, delay, sig, tmp_path):
    r = signal_group_at([sys.executable, "-c", POOL_SCRIPT], marker, delay, sig, tmp_path)
    assert r["marker_seen"] and not r["finished_first"], r
    _assert_stopped(r, sig)
    assert f"interrupted: {signal.Signals(sig).name}" in r["err"], r["err"]
    assert sorted(p.name for p in tmp_path.iterdir()) == []


#: The pool's normal end (every result in, the workers asked to leave) with SIGTERM arriving
#: in it, as the first worker is asked to leave: no worker may outlive the call (they ignore
#: SIGTERM, and ``multiprocessing``'s exit handler would wait for them for ever).
END_SCRIPT = textwrap.dedent(
    """
    import os, signal, sys
    from multiprocessing.connection import Connection
    from obsplan.core import interrupts
    from obsplan.planning.solver.starts import run_forked

    send = Connection.send

    def send_with_a_signal(self, obj):
        if obj is None:  # the first "leave": the signal comes now
            Connection.send = send
            os.kill(os.getpid(), signal.SIGTERM)
        return send(self, obj)

    Connection.send = send_with_a_signal
    interrupts.install()
    try:
        run_forked(lambda state, item: item, None, [1, 2, 3, 4], 3)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr, flush=True)
        sys.exit(interrupts.exit_code())
    """
)


def test_a_signal_while_the_pool_ends_leaves_no_worker(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-c", END_SCRIPT],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        start_new_session=True,
    )
    assert proc.returncode == 143 and "interrupted" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def _kill_self_on(state: int, item: int) -> int:
    if item == state:
        os.kill(os.getpid(), signal.SIGKILL)  # killed from outside: out of memory, a user
    time.sleep(0.05)
    return item


def _raise_on(state: int, item: int) -> int:
    if item == state:
        raise ValueError(f"item {item} is bad")
    time.sleep(0.05)
    return item


@pytest.mark.parametrize("bad", [0, 3, 5])
def test_a_worker_killed_from_outside_is_an_error_not_a_hang(bad):
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    t0 = time.monotonic()
    with pytest.raises(WorkerDied, match=f"item {bad + 1} of 6"):
        run_forked(_kill_self_on, bad, list(range(6)), 2)
    assert time.monotonic() - t0 < 10
    left = {p.pid for p in psutil.Process().children(recursive=True)} - before
    assert not left


@pytest.mark.parametrize("bad", [0, 2, 5])
def test_an_exception_in_a_worker_is_raised_and_the_workers_end(bad):
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    seen: list[int] = []
    with pytest.raises(ValueError, match=f"item {bad} is bad"):
        run_forked(_raise_on, bad, list(range(6)), 3, lambda i, _: seen.append(i))
    assert seen == list(range(len(seen))) and len(seen) <= bad  # in order, none past the bad one
    left = {p.pid for p in psutil.Process().children(recursive=True)} - before
    assert not left


# ------------------------------------------------------------------------------ the command line
MAIN = "import sys; from obsplan.cli import main; sys.exit(main())"


def _obsplan(*args: str) -> list[str]:
    return [sys.executable, "-c", MAIN, *args]


PLAN = ("plan", str(ROOT / "problems" / "localise.toml"), "--starts", "2", "--no-validate")
#: ``--replan`` with 15 runs: three batches of 5 on two workers, so that one worker is idle
#: while the last batch flies.
REPLAN = (
    "plan",
    str(ROOT / "problems" / "localise.toml"),
    *("--steps", "40", "--starts", "1", "--runs", "15", "--max-runs", "15", "--replan", "150"),
)


@pytest.mark.slow
@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: signal.Signals(s).name)
@pytest.mark.parametrize(
    "argv, marker, delay",
    [
        (PLAN, b"| 0/2 [", 0.5),  # both starts running
        (PLAN, b"| 1/2 [", 0.0),  # the first start's result: its worker idle (the hang)
        (PLAN, b"| 1/2 [", 0.5),
        (REPLAN, b"replanned runs:   0%", 1.0),  # two batches flying
        (REPLAN, b"/15 [", 0.2),  # a batch done: its worker takes the last or waits idle
    ],
    ids=["plan-busy", "plan-idle-at-once", "plan-idle", "replan-busy", "replan-batch-done"],
)
def test_plan_and_replan_stop_at_once_on_a_signal_to_the_group(argv, marker, delay, sig, tmp_path):
    out = tmp_path / "o"
    r = signal_group_at(_obsplan(*argv, "--out", str(out)), marker, delay, sig, tmp_path)
    if r["finished_first"] or (r["code"] == 0 and out.is_dir()):
        pytest.skip("the run ended before the signal (a faster machine than measured)")
    _assert_stopped(r, sig)
    lines = [ln for ln in r["err"].replace("\r", "\n").splitlines() if "obsplan plan:" in ln]
    assert len(lines) == 1 and "interrupted" in lines[0], r["err"][-800:]
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written
