"""The sweep runner's way to its cluster: an address where no Dask scheduler answers, a scheduler
file that is not one, and a local cluster interrupted while its workers start.

Dask's client waits for a scheduler's handshake without a limit and allocates whatever length a
service's first bytes spell: ``--scheduler`` at the dashboard's port 8787 (a natural typo) or any
silent service hung for ever, a service that greets first (an SSH banner) ended in
``ArrayMemoryError: Unable to allocate 2.82 EiB``; a binary ``--scheduler-file`` in an
``AssertionError``, ``{"address": 5}`` in a ``TypeError``. ``sweep --workers 48`` on 2 cores
ignored Ctrl-C for minutes while its workers started.

Now each is one line and exit 2 (``not a Dask scheduler at ADDRESS: ...``, the file's fault
named), within the connect deadline; a signal while the workers start ends the sweep at once.
The services are real sockets served by the test: silent ones, ones that send bytes, ones that
hang up.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest

import obsplan.sweeps.run as run
from obsplan.cli import main
from obsplan.core import budget
from obsplan.sweeps.run import default_workers

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
LOCALISE = ROOT / "problems" / "localise.toml"
#: The connect deadline of the in-process tests (the command's own is 10 s: a slow test below).
DEADLINE_S = 1.5
#: Seconds beyond the deadline a refusal may take (a loaded 2-core machine).
MARGIN_S = 2.0
MAIN = "import sys; from obsplan.cli import main; sys.exit(main())"
#: Seconds after which an in-process call is cut (a regression: Dask waiting for ever).
CUT_S = 30


@contextlib.contextmanager
def service(greeting: bytes | None | str) -> Iterator[str]:
    """A TCP service on 127.0.0.1 that accepts every connection and then sends ``greeting``
    (``None``: says nothing, ``"close"``: hangs up at once), holding the connection open; its
    address."""
    srv = socket.socket()
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)
    conns: list[socket.socket] = []

    def serve() -> None:
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            if greeting == "close":
                conn.close()
                continue
            conns.append(conn)
            if isinstance(greeting, bytes):
                with contextlib.suppress(OSError):
                    conn.sendall(greeting)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    finally:
        with contextlib.suppress(OSError):
            srv.shutdown(socket.SHUT_RDWR)
        srv.close()
        for c in conns:
            c.close()
        thread.join(5)


def sweep_file(folder: Path, name: str = "s") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(
        f'[sweep]\nname = "{name}"\nbase = {json.dumps(str(LOCALISE))}\nmode = "baselines"\n'
        '[axes]\n"horizon.steps" = [20, 24]\n"validation.runs" = [2]\n'
    )
    return path


def refused(argv: list[str], capsys, *needles: str, within: float) -> str:
    """In-process ``obsplan sweep``: exit 2 within ``within`` s, one line containing every
    needle, nothing written."""
    capsys.readouterr()
    t0 = time.perf_counter()
    with cut_after(CUT_S):
        code = main([str(a) for a in argv])
    took = time.perf_counter() - t0
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err[-800:]
    assert len(lines) == 1 and "Traceback" not in err, err[-800:]
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert took < within, f"{took:.1f} s: {lines[0]}"
    return lines[0]


class Hung(Exception):
    """The call ran past :data:`CUT_S` (Dask's client waited for a handshake for ever)."""


@contextlib.contextmanager
def cut_after(seconds: float) -> Iterator[None]:
    """Turn a hang into a failure (SIGALRM), instead of hanging the suite."""

    def alarm(signum, frame):
        raise Hung(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture
def short_deadline(monkeypatch):
    monkeypatch.setattr(run, "CONNECT_TIMEOUT_S", DEADLINE_S)


# ------------------------------------------------------------------------------ --scheduler
SILENT = {
    "silent": None,  # accepts and says nothing (the dashboard's port: HTTP waits for a request)
    "one-byte": b"\x3a",  # the start of a handshake, then nothing
    "length-only": (58).to_bytes(8, "little"),  # a handshake's length, then nothing
    "half-message": (58).to_bytes(8, "little") + b"\x01" + bytes(7),
}


@pytest.mark.parametrize("greeting", list(SILENT.values()), ids=list(SILENT))
def test_a_silent_service_is_not_a_scheduler(greeting, tmp_path, capsys, short_deadline):
    with service(greeting) as address:
        line = refused(
            ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler", address],
            capsys,
            "--scheduler",
            f"not a Dask scheduler at {address}",
            within=DEADLINE_S + MARGIN_S,
        )
    assert "8786" in line  # the fix: where a scheduler listens
    assert not (tmp_path / "o").exists()


FOREIGN = {
    "ssh": b"SSH-2.0-OpenSSH_9.6p1 Ubuntu-3ubuntu13\r\n",  # spelled 2.82 EiB to Dask
    "http": b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n",
    "smtp": b"220 mail.example.com ESMTP Postfix\r\n",
    "zeros": bytes(64),
    "garbage-frames": (40).to_bytes(8, "little") + b"\xff" * 40,  # a length, then no handshake
    # Dask's framing (a length, one frame) around a msgpack mapping {"a": 1}: not a handshake
    "not-a-dask-mapping": (20).to_bytes(8, "little")
    + (1).to_bytes(8, "little")
    + (4).to_bytes(8, "little")
    + b"\x81\xa1a\x01",
}


@pytest.mark.parametrize("greeting", list(FOREIGN.values()), ids=list(FOREIGN))
def test_a_foreign_service_is_not_a_scheduler(greeting, tmp_path, capsys, short_deadline):
    with service(greeting) as address:
        line = refused(
            ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler", address],
            capsys,
            f"not a Dask scheduler at {address}: it sent ",
            within=DEADLINE_S + MARGIN_S,
        )
    assert "EiB" not in line and "Error" not in line


def test_a_service_that_hangs_up_is_not_a_scheduler(tmp_path, capsys, short_deadline):
    with service("close") as address:
        refused(
            ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler", address],
            capsys,
            f"not a Dask scheduler at {address}",
            within=DEADLINE_S + MARGIN_S,
        )


@pytest.mark.parametrize(
    "address, needle",
    [
        ("tcp://", "not an address"),
        ("tcp://127.0.0.1", "not an address"),  # no port
        ("tcp://127.0.0.1:notaport", "not an address"),
        ("tcp://127.0.0.1:1", "cannot reach a Dask scheduler there"),  # nothing listens
    ],
)
def test_a_bad_address_is_named(address, needle, tmp_path, capsys, short_deadline):
    refused(
        ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler", address],
        capsys,
        "--scheduler",
        needle,
        within=DEADLINE_S + MARGIN_S,
    )


def test_dask_scheduler_address_at_a_silent_service(tmp_path, capsys, short_deadline, monkeypatch):
    with service(None) as address:
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
        import dask

        dask.config.refresh()
        try:
            refused(
                ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o"],
                capsys,
                "DASK_SCHEDULER_ADDRESS",
                f"not a Dask scheduler at {address}",
                within=DEADLINE_S + MARGIN_S,
            )
        finally:
            monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
            dask.config.refresh()


# ------------------------------------------------------------------------------ --scheduler-file
BAD_FILES = {
    "binary": (b"\x00\x01\x02\xff" * 64, "not a text file"),
    "latin-1": ('{"address": "tcp://h\xf4te:8786"}'.encode("latin-1"), "not UTF-8"),
    "address-number": (b'{"address": 5}', '"address" is 5'),
    "address-null": (b'{"address": null}', '"address" is null'),
    "address-empty": (b'{"address": ""}', '"address" is ""'),
    "address-list": (b'{"address": ["tcp://h:8786"]}', '"address" is ["tcp://h:8786"]'),
    "no-address": (b'{"id": "Scheduler-1"}', 'no "address"'),
    "a-list": (b'["tcp://h:8786"]', 'no "address"'),
    "a-string": (b'"tcp://h:8786"', 'no "address"'),
    "empty": (b"", "not JSON"),
    "not-json": (b"address = tcp://h:8786\n", "not JSON"),
    "huge": (b'{"address": "' + b"x" * 2_000_000 + b'"}', "MB, not a scheduler file"),
}


@pytest.mark.parametrize("content, needle", list(BAD_FILES.values()), ids=list(BAD_FILES))
def test_a_bad_scheduler_file_is_named(content, needle, tmp_path, capsys, short_deadline):
    path = tmp_path / "scheduler.json"
    path.write_bytes(content)
    line = refused(
        ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler-file", path],
        capsys,
        f"--scheduler-file {path}",
        needle,
        within=MARGIN_S,
    )
    assert len(line) < 600 and not (tmp_path / "o").exists()


def test_a_scheduler_file_of_a_silent_service(tmp_path, capsys, short_deadline):
    with service(None) as address:
        path = tmp_path / "scheduler.json"
        path.write_text(json.dumps({"type": "Scheduler", "address": address}))
        refused(
            ["sweep", sweep_file(tmp_path), "--out", tmp_path / "o", "--scheduler-file", path],
            capsys,
            f"--scheduler-file {path}",
            f"not a Dask scheduler at {address}",
            within=DEADLINE_S + MARGIN_S,
        )


@pytest.mark.slow
@pytest.mark.parametrize("greeting", [None, FOREIGN["ssh"]], ids=["silent", "ssh"])
def test_the_command_refuses_a_service_within_its_deadline(greeting, tmp_path):
    """The installed command, its own 10 s deadline: the issue's rows, end to end."""
    with service(greeting) as address:
        t0 = time.monotonic()
        proc = subprocess.run(
            [sys.executable, "-c", MAIN, "sweep", str(sweep_file(tmp_path))]
            + ["--out", str(tmp_path / "o"), "--scheduler", address],
            capture_output=True,
            text=True,
            timeout=120,
        )
        took = time.monotonic() - t0
    assert proc.returncode == 2, proc.stderr[-800:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"not a Dask scheduler at {address}" in lines[0], proc.stderr
    assert took < run.CONNECT_TIMEOUT_S + 15  # the imports, then the deadline at most


# ------------------------------------------------------------------------------ local workers
def _group_alive(pgid: int) -> list[int]:
    alive = []
    for p in psutil.process_iter(["pid", "status"]):
        try:
            if os.getpgid(p.pid) == pgid and p.info["status"] != psutil.STATUS_ZOMBIE:
                alive.append(p.pid)
        except (ProcessLookupError, psutil.Error):
            continue
    return alive


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("delay", [0.0, 0.7, 2.0])
def test_a_signal_while_the_workers_start_ends_the_sweep_at_once(delay, sig, tmp_path):
    """The most local workers allowed (two per core), a signal to the whole process group at
    generated moments after the first process of the workers' start appears: exit 130 / 143
    within seconds, no process left, nothing written. A moment after the workers had all
    started (the sweep's first line is out) is skipped: it is test_signals.py's."""
    workers = budget.MAX_WORKERS_PER_CORE * default_workers()
    out = tmp_path / "o"
    proc = subprocess.Popen(
        [sys.executable, "-c", MAIN, "sweep", str(sweep_file(tmp_path)), "--out", str(out)]
        + ["--workers", str(workers), "--quiet", "--no-figures"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    try:
        parent = psutil.Process(proc.pid)
        deadline = time.monotonic() + 120
        while not parent.children() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(delay)
        if proc.poll() is not None:
            pytest.skip("the sweep had ended before the signal (a faster machine)")
        t0 = time.monotonic()
        os.killpg(proc.pid, sig)
        try:
            stdout, stderr = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"no exit 60 s after {signal.Signals(sig).name} while the workers start")
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    grace = time.monotonic() + 10
    while (alive := _group_alive(proc.pid)) and time.monotonic() < grace:
        time.sleep(0.1)
    for pid in alive:  # pragma: no cover - only when the test fails: leak nothing
        with contextlib.suppress(psutil.Error):
            psutil.Process(pid).kill()
    err = stderr.decode(errors="replace")
    if b"to run on" in stdout:  # printed once every worker has started
        pytest.skip("the workers had started before the signal (a faster machine)")
    assert proc.returncode == 128 + sig, err[-800:]
    assert took < 5.0, f"{took:.1f} s to stop"
    assert not alive, alive
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted" in lines[0] and "Traceback" not in err, err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
