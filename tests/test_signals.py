"""SIGINT and SIGTERM at many moments of a real ``obsplan`` run: exit 130 / 143, nothing left.

For each of ``plan``, ``simulate``, ``paper`` and ``sweep`` the test first runs the command to its
end (exit 0, to know how long a run takes here), then starts it again and again, each time in its
own process group as a terminal starts a job, and sends a signal at evenly spread moments of the
whole run (imports, building, solving, validation, figures, writing): SIGINT to the whole group
(Ctrl-C in a terminal), SIGTERM to the group or to the parent only (a batch scheduler's stop).
Each time it checks

* the exit code: 130 for SIGINT, 143 for SIGTERM, and one line on stderr (or death by the
  signal itself when it came while the interpreter started, before obsplan's first line ran: a
  shell reports that as 130 / 143 too);
* no new file in the output's parent folder (for ``sweep``, whose folder keeps finished tasks to
  resume, only that folder, without any temporary file in it);
* no live process of the group once the parent has exited (the starts' fork pool, Dask's
  nannies and workers).

Moments: every ``OBSPLAN_SIGNAL_STEP`` seconds of the run (0.3 s when set, e.g.
``OBSPLAN_SIGNAL_STEP=0.3``), by default :data:`POINTS` moments spread over the run, so that the
test takes a few minutes at most on a loaded machine.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import psutil
import pytest

from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

#: end-to-end: the slow tier (docs/development.md)
pytestmark = pytest.mark.slow


ROOT = Path(__file__).resolve().parents[1]
#: Moments per verb by default (spread evenly over a whole run).
POINTS = {"plan": 6, "simulate": 5, "paper": 5, "sweep": 4}
#: Runs interrupted at the same time (the machine has few cores).
PARALLEL = 2
#: The ways a signal is sent: (signal, to the whole group?).
MODES = ((signal.SIGINT, True), (signal.SIGTERM, False), (signal.SIGTERM, True))
#: Seconds a child may take to end after its parent exited (SIGTERM through PR_SET_PDEATHSIG).
GRACE_S = 10.0


def _inputs(folder: Path) -> dict[str, list[str]]:
    write_csv(gen.circle(30.0, 1.5, 20.0).sample(0.1), folder / "traj.csv")
    (folder / "s.toml").write_text(
        f'[sweep]\nname = "s"\nbase = "{(ROOT / "problems" / "localise.toml").as_posix()}"\n'
        '[axes]\n"horizon.steps" = [20, 24]\n"objective.starts" = [1]\n"validation.runs" = [2]\n'
    )
    return {
        "plan": [
            "plan",
            str(ROOT / "problems" / "localise.toml"),
            *("--steps", "20", "--starts", "2", "--runs", "2", "--quiet", "--out"),
        ],
        "simulate": ["simulate", str(folder / "traj.csv"), "--runs", "2", "--quiet", "--out"],
        "paper": ["paper", "--quick", "--quiet", "--out"],
        "sweep": ["sweep", str(folder / "s.toml"), "--workers", "1", "--quiet", "--out"],
    }


def _start(argv: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", "import sys; from obsplan.cli import main; sys.exit(main())", *argv],
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,  # its own process group, as a terminal starts a job
        env={**os.environ, "MPLBACKEND": "Agg"},
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


def _leftovers(parent: Path, out: Path, verb: str) -> list[str]:
    """What an interrupted run left that it must not have."""
    names = sorted(p.name for p in parent.iterdir())
    if verb != "sweep":
        return names
    bad = [n for n in names if n != out.name]
    if out.is_dir():
        bad += [str(p) for p in out.rglob("*") if ".tmp-" in p.name or ".old-" in p.name]
    return bad


def _interrupt_at(argv: list[str], parent: Path, delay: float, mode) -> dict:
    sig, group = mode
    out = parent / "out"
    proc = _start([*argv, str(out)], parent)
    err_chunks: list[bytes] = []
    reader = threading.Thread(target=lambda: err_chunks.append(proc.stderr.read()), daemon=True)
    reader.start()
    time.sleep(delay)
    finished_first = proc.poll() is not None
    if not finished_first:
        if group:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
    try:
        code = proc.wait(timeout=180)
    except subprocess.TimeoutExpired:  # pragma: no cover - only when the test fails
        os.killpg(proc.pid, signal.SIGKILL)
        code = proc.wait()
    reader.join(10)
    deadline = time.monotonic() + GRACE_S
    while (alive := _group_alive(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.2)
    for pid in alive:  # pragma: no cover - only when the test fails: do not leak processes
        with contextlib.suppress(psutil.Error):
            psutil.Process(pid).kill()
    return {
        "delay": delay,
        "signal": signal.Signals(sig).name + (" to the group" if group else " to the parent"),
        "code": code,
        "expected": (128 + sig, -sig),
        "finished_first": finished_first,
        "alive": alive,
        "left": _leftovers(parent, out, argv[0]),
        "traceback": b"Traceback" in b"".join(err_chunks),
        "whole": sorted(p.name for p in out.rglob("*") if p.is_file()) if out.is_dir() else None,
        "err": b"".join(err_chunks).decode(errors="replace")[-600:],
    }


def _moments(length: float, verb: str) -> list[float]:
    step = os.environ.get("OBSPLAN_SIGNAL_STEP")
    if step:
        n = max(1, math.ceil(length / float(step)))
        return [k * float(step) for k in range(n)]
    n = POINTS[verb]
    return [(k + 0.5) * length / n for k in range(n)]  # evenly over the whole run


@pytest.mark.parametrize("verb", ["plan", "simulate", "paper", "sweep"])
def test_a_signal_at_any_moment_ends_cleanly(verb, tmp_path):
    argv = _inputs(tmp_path)[verb]
    # the whole run, uninterrupted: exit 0 and an output (the moments span its length)
    full = tmp_path / "full"
    full.mkdir()
    t0 = time.monotonic()
    proc = _start([*argv, str(full / "out")], full)
    _, err = proc.communicate(timeout=600)
    length = time.monotonic() - t0
    assert proc.returncode == 0, err.decode(errors="replace")
    assert (full / "out").is_dir()

    def one(k_delay):
        k, delay = k_delay
        parent = tmp_path / f"p{k}"
        parent.mkdir()
        return _interrupt_at(argv, parent, delay, MODES[k % len(MODES)])

    with ThreadPoolExecutor(PARALLEL) as pool:
        results = list(pool.map(one, enumerate(_moments(length, verb))))
    whole = sorted(p.name for p in (full / "out").rglob("*") if p.is_file())
    bad = []
    for r in results:
        if r["finished_first"]:
            continue  # the run ended before this moment (a faster run than the measured one)
        if r["code"] == 0 and r["whole"] == whole and r["left"] in ([], ["out"]):
            # the signal came after the work was committed, while the interpreter exited: the
            # result is whole and the command said so (exit 0)
            r["finished_first"] = True
            continue
        # Python's own traceback only when the signal came before obsplan's first line ran
        traceback = r["traceback"] and r["code"] >= 0
        if r["code"] not in r["expected"] or r["alive"] or r["left"] or traceback:
            bad.append(r)
    assert not bad, "\n".join(str(r) for r in bad)
    assert any(not r["finished_first"] for r in results), results  # a signal came during work


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_the_starts_processes_end_with_their_parent(sig, tmp_path):
    """A batch scheduler's SIGTERM (or a SIGKILL) to the parent alone, while the starts run in
    worker processes: no worker runs on (exit 143 for SIGTERM, nothing written)."""
    out = tmp_path / "o"
    argv = [
        "plan",
        str(ROOT / "problems" / "localise.toml"),
        "--steps",
        "400",
        "--starts",
        "4",
        "--no-validate",
        "--out",
        str(out),
    ]
    proc = _start(argv, tmp_path)
    seen = b""
    deadline = time.monotonic() + 300
    children: list[psutil.Process] = []
    while time.monotonic() < deadline and not children:
        seen += os.read(proc.stderr.fileno(), 4096)  # the starts' progress bar
        if b"starts" in seen:
            children = psutil.Process(proc.pid).children(recursive=True)
    assert children, seen.decode(errors="replace")
    os.kill(proc.pid, sig)
    code = proc.wait(timeout=120)
    assert code == (143 if sig == signal.SIGTERM else -signal.SIGKILL)
    _, still = psutil.wait_procs(children, timeout=GRACE_S)
    for p in still:  # pragma: no cover - only when the test fails
        p.kill()
    assert not still, still
    if sig == signal.SIGTERM:
        assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_signal_inside_a_weakref_callback_is_raised_not_ignored(capfd):
    """Python cannot raise an exception from a weakref callback or ``__del__`` ("Exception
    ignored in …"): the signal is delivered again and raised in the code that was running."""
    import weakref

    from obsplan.core import interrupts

    class Thing:
        pass

    def callback(ref):
        signal.raise_signal(signal.SIGTERM)
        for _ in range(1000):  # the handler runs here, inside the callback
            pass

    previous = interrupts.install()
    interrupts.reset()
    try:
        thing = Thing()
        ref = weakref.ref(thing, callback)
        with pytest.raises(interrupts.Interrupted) as caught:
            del thing
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:  # raised here, in the interrupted code, not lost
                pass
        assert caught.value.signum == signal.SIGTERM
        assert interrupts.exit_code() == 143
        assert ref() is None
    finally:
        interrupts.reset()
        interrupts.uninstall(previous)
    assert "Exception ignored" not in capfd.readouterr().err
