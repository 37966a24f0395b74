"""``python -m obsplan`` is the ``obsplan`` command (``obsplan/__main__.py``)."""

from __future__ import annotations

import subprocess
import sys

from obsplan.version import __version__


def test_python_dash_m_runs_the_command_and_passes_its_exit_code():
    ok = subprocess.run(
        [sys.executable, "-m", "obsplan", "--version"], capture_output=True, text=True, timeout=60
    )
    assert ok.returncode == 0 and __version__ in ok.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "obsplan", "analyze", "no-such-file.csv"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "no-such-file.csv" in bad.stderr
