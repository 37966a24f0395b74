"""Send SIGINT to a real ``obsplan`` process once it has started working (CLI tests)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time


def interrupt_after(cmd: list[str], marker: bytes, delay: float, timeout: float = 120.0):
    """Run ``cmd``; once ``marker`` appears on its stderr wait ``delay`` s and send SIGINT.

    Returns (exit code, stderr text)."""
    code, err, _ = interrupt_after_timed(cmd, marker, delay, timeout)
    return code, err


def interrupt_after_timed(cmd: list[str], marker: bytes, delay: float, timeout: float = 120.0):
    """:func:`interrupt_after`, also returning the seconds from the SIGINT to the exit."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from obsplan.cli import main; sys.exit(main())", *cmd],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    seen = threading.Event()
    chunks: list[bytes] = []

    def reader():
        while True:
            b = os.read(proc.stderr.fileno(), 4096)
            if not b:
                return
            chunks.append(b)
            if marker in b"".join(chunks):
                seen.set()

    threading.Thread(target=reader, daemon=True).start()
    try:
        assert seen.wait(timeout), b"".join(chunks).decode(errors="replace")
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        t_sig = time.perf_counter()
        code = proc.wait(timeout=timeout)
        after = time.perf_counter() - t_sig
    finally:
        if proc.poll() is None:  # pragma: no cover - only when the test fails
            proc.kill()
    time.sleep(0.1)
    return code, b"".join(chunks).decode(errors="replace"), after
