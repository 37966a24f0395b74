"""Bounded work: the cost of a request, estimated before any work starts, and its limits.

Every verb asks here before it allocates or solves anything, from the problem file and from the
command line alike; a request beyond a limit is refused with its figure, the limit and the fix
(an :class:`~obsplan.core.errors.InputError`: exit 2). The limits:

========================  ==========================  =========================================
what                      limit                       why
========================  ==========================  =========================================
IPOPT starts              :data:`MAX_STARTS`          each start is a full solve
IPOPT iterations          :data:`MAX_ITERATIONS`      per start; IPOPT's own counter is an int
Monte Carlo runs          :data:`MAX_RUNS`            per path
filter samples per run    :data:`MAX_SAMPLES`         the filters loop over samples
sweep tasks               :data:`MAX_TASKS`           counted before the axes are expanded
rows of an input file     :data:`MAX_ROWS`            estimated from the file size first
memory                    ``OBSPLAN_MAX_MEMORY``      default :data:`DEFAULT_MAX_MEMORY` bytes
time                      ``OBSPLAN_MAX_HOURS``       default :data:`DEFAULT_MAX_HOURS` hours
========================  ==========================  =========================================

The two environment variables raise (or lower) the memory and time limits: a number of bytes
with an optional ``K``/``M``/``G``/``T`` suffix (powers of 1024), and a number of hours. The
estimates are rough on purpose (they are upper bounds of the arrays kept, and typical speeds of
the kernels measured in ``benchmarks/``); they exist to refuse requests that are absurd, not to
plan a cluster.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

from obsplan.core.errors import InputError

MAX_STARTS = 256
MAX_ITERATIONS = 100_000
MAX_RUNS = 10_000
MAX_SAMPLES = 2_000_000
MAX_TASKS = 100_000
MAX_ROWS = 2_000_000
#: Default memory limit [bytes]: the Monte Carlo budget used so far (1e9 stored numbers of
#: runs x samples x 3n, four quantities of 8 bytes each).
DEFAULT_MAX_MEMORY = 32e9
#: Default time limit [h] of one command.
DEFAULT_MAX_HOURS = 24.0

#: Bytes kept per run, filter sample and state component by a Monte Carlo (four float64
#: quantities: truth, estimate, error, standard deviation).
MC_BYTES_PER_ELEMENT = 32
#: Seconds per run-step of one filter (open-loop kernels measured at ~0.1 µs; 1 µs is safe).
MC_SECONDS_PER_RUN_STEP = 1e-6
#: Seconds per IPOPT iteration and grid step (N = 1000 iterates in ~0.1 s in the benchmarks).
NLP_SECONDS_PER_ITERATION_STEP = 1e-4
#: Iterations a start typically needs (the estimate of time; ``max_iter`` only bounds it).
TYPICAL_ITERATIONS = 300

_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


@dataclass(frozen=True)
class Cost:
    """The estimated cost of a request.

    Attributes
    ----------
    memory_bytes : float
        Peak memory of the arrays kept [bytes].
    seconds : float
        Rough time on one core [s].
    what : str
        What was estimated (used in messages).
    """

    memory_bytes: float
    seconds: float
    what: str

    def __add__(self, other: Cost) -> Cost:
        return Cost(
            max(self.memory_bytes, other.memory_bytes),
            self.seconds + other.seconds,
            f"{self.what} and {other.what}",
        )


def max_memory() -> float:
    """The memory limit [bytes]: ``OBSPLAN_MAX_MEMORY`` or :data:`DEFAULT_MAX_MEMORY`.

    Returns
    -------
    float
        The limit [bytes].

    Raises
    ------
    InputError
        If ``OBSPLAN_MAX_MEMORY`` is not a positive number of bytes (optional ``K``/``M``/``G``/
        ``T`` suffix).
    """
    text = os.environ.get("OBSPLAN_MAX_MEMORY", "").strip()
    if not text:
        return DEFAULT_MAX_MEMORY
    m = re.fullmatch(r"([0-9.eE+]+)\s*([KMGT]?)i?B?", text, flags=re.IGNORECASE)
    try:
        value = float(m.group(1)) * _UNITS[m.group(2).upper()] if m else math.nan
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(
            f"OBSPLAN_MAX_MEMORY={text!r}: expected a number of bytes, e.g. 16G or 512M"
        )
    return value


def max_hours() -> float:
    """The time limit [h]: ``OBSPLAN_MAX_HOURS`` or :data:`DEFAULT_MAX_HOURS`.

    Returns
    -------
    float
        The limit [h].

    Raises
    ------
    InputError
        If ``OBSPLAN_MAX_HOURS`` is not a positive number.
    """
    text = os.environ.get("OBSPLAN_MAX_HOURS", "").strip()
    if not text:
        return DEFAULT_MAX_HOURS
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"OBSPLAN_MAX_HOURS={text!r}: expected a number of hours, e.g. 48")
    return value


def _bytes(x: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if x < 1024 or unit == "TiB":
            return f"{x:.3g} {unit}"
        x /= 1024
    return f"{x:.3g} TiB"  # pragma: no cover


def _hours(s: float) -> str:
    return f"{s / 3600:.3g} h" if s >= 3600 else f"{s:.3g} s"


# ------------------------------------------------------------------------------ counts
def check_count(
    value: float,
    limit: float,
    field: str,
    unit: str,
    fix: str = "",
    error: type[InputError] = InputError,
) -> None:
    """Refuse ``value`` beyond ``limit``: ``"<field>: <value> <unit>, more than the limit of
    <limit> <unit>; <fix>"`` (``error`` lets a problem check raise its own type).

    Parameters
    ----------
    value : float
        The requested count (NaN is refused too).
    limit : float
        The largest count allowed.
    field : str
        The setting or option that asked for ``value`` (starts the message).
    unit : str
        What is counted, e.g. ``"starts"``.
    fix : str, optional
        What the user can do instead (appended to the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``value`` is more than ``limit`` or NaN.
    """
    if not value <= limit:  # also refuses NaN
        shown = f"{value:.4g}" if isinstance(value, float) else f"{value}"
        raise error(
            f"{field}: {shown} {unit}, more than the limit of {limit:.0f} {unit}"
            + (f"; {fix}" if fix else "")
        )


def check_starts(n: int, field: str = "objective.starts", error=InputError) -> None:
    """At most :data:`MAX_STARTS` IPOPT starts.

    Parameters
    ----------
    n : int
        Number of IPOPT starts requested.
    field : str, optional
        The setting that asked for them (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    check_count(n, MAX_STARTS, field, "starts", "each start is a full IPOPT solve", error)


def check_iterations(n: float, field: str = "objective.max_iter", error=InputError) -> None:
    """At most :data:`MAX_ITERATIONS` IPOPT iterations per start.

    Parameters
    ----------
    n : float
        IPOPT iteration limit requested per start.
    field : str, optional
        The setting that asked for it (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    check_count(n, MAX_ITERATIONS, field, "iterations", "IPOPT's limit per start", error)


def check_runs(n: int, field: str = "--runs", error=InputError) -> None:
    """At most :data:`MAX_RUNS` Monte Carlo runs.

    Parameters
    ----------
    n : int
        Number of Monte Carlo runs requested.
    field : str, optional
        The option that asked for them (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    fix = f"use at most {MAX_RUNS} (a few hundred runs give the statistics)"
    check_count(n, MAX_RUNS, field, "Monte Carlo runs", fix, error)


def check_samples(samples: float, field: str, fix: str = "", error=InputError) -> None:
    """At most :data:`MAX_SAMPLES` filter samples per run.

    Parameters
    ----------
    samples : float
        Filter samples per run (duration over filter step).
    field : str
        The setting that makes the samples (named in the message), e.g. a filter step.
    fix : str, optional
        What the user can do instead (appended to the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``samples`` is beyond the limit.
    """
    check_count(samples, MAX_SAMPLES, field, "samples per run", fix, error)


def check_tasks(n: float, field: str = "axes", error=InputError) -> None:
    """At most :data:`MAX_TASKS` tasks in a sweep (checked before the axes are expanded).

    Parameters
    ----------
    n : float
        Number of tasks (the product of the axes' lengths).
    field : str, optional
        The setting that makes them (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    check_count(n, MAX_TASKS, field, "tasks", "split the sweep or use fewer axis values", error)


def check_rows(n: float, field: str, error=InputError) -> None:
    """At most :data:`MAX_ROWS` rows of an input file.

    Parameters
    ----------
    n : float
        Number of rows (counted or estimated).
    field : str
        The option or setting naming the file (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    check_count(n, MAX_ROWS, field, "rows", "cut or decimate the file first", error)


def estimate_rows(path: str | Path, probe_bytes: int = 1 << 16) -> float:
    """Rows of a text file, estimated from its size and its first ``probe_bytes`` (no full read).

    Parameters
    ----------
    path : str or Path
        The text file.
    probe_bytes : int, optional
        How many bytes at its start are read to measure the mean line length [bytes].

    Returns
    -------
    float
        The number of lines: exact if the whole file fits in the probe, else the file size over
        the mean line length of the probe.

    Raises
    ------
    OSError
        If the file cannot be read.
    """
    path = Path(path)
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(probe_bytes)
    lines = head.count(b"\n")
    if len(head) >= size:
        return float(lines + (1 if head and not head.endswith(b"\n") else 0))
    return size * max(lines, 1) / len(head)


def check_file_rows(path: str | Path, field: str, error=InputError) -> None:
    """Refuse a text file estimated (:func:`estimate_rows`) to hold more than :data:`MAX_ROWS`
    rows, before reading it (a folder, a device or a named pipe is left to the reader, which
    refuses it without opening it: :func:`obsplan.core.textfiles.check_regular_file`).

    Parameters
    ----------
    path : str or Path
        The input file.
    field : str
        The option or setting naming the file (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If the file is estimated to hold more than :data:`MAX_ROWS` rows.
    """
    if not Path(path).is_file():
        return
    try:
        rows = estimate_rows(path)
    except OSError:
        return  # the reader says what is wrong with the file
    if rows > MAX_ROWS:
        raise error(
            f"{field} {path}: about {rows:.3g} rows ({_bytes(Path(path).stat().st_size)}), more "
            f"than the limit of {MAX_ROWS:,}; cut or decimate the file first"
        )


# ------------------------------------------------------------------------------ estimates
def monte_carlo_cost(runs: int, samples: float, dim: int, filters: int = 2) -> Cost:
    """Memory and time of ``runs`` Monte Carlo runs of ``samples`` filter samples in ``dim``-D.

    Parameters
    ----------
    runs : int
        Number of Monte Carlo runs.
    samples : float
        Filter samples per run.
    dim : int
        Spatial dimension (2 or 3); the state has ``2 * dim`` components or more.
    filters : int, optional
        Number of filters run on each sample path (the time scales with it).

    Returns
    -------
    Cost
        The memory of the arrays kept (:data:`MC_BYTES_PER_ELEMENT` per run, sample and 3
        ``dim`` components) and the time (:data:`MC_SECONDS_PER_RUN_STEP` per run-step).
    """
    elements = float(runs) * float(samples) * 3 * dim
    seconds = float(runs) * float(samples) * filters * MC_SECONDS_PER_RUN_STEP
    return Cost(elements * MC_BYTES_PER_ELEMENT, seconds, f"{runs} runs x {samples:.4g} samples")


def planning_cost(steps: int, starts: int, max_iter: int) -> Cost:
    """Rough time of ``starts`` IPOPT starts on a grid of ``steps`` (typical iteration counts).

    Parameters
    ----------
    steps : int
        Number of steps ``N`` of the transcription grid.
    starts : int
        Number of IPOPT starts.
    max_iter : int
        IPOPT iteration limit per start (the estimate uses at most
        :data:`TYPICAL_ITERATIONS`).

    Returns
    -------
    Cost
        Memory of the NLP [bytes] and time [s] of all starts.
    """
    iters = min(max_iter, TYPICAL_ITERATIONS)
    seconds = float(starts) * iters * steps * NLP_SECONDS_PER_ITERATION_STEP
    # the NLP of N steps: tens of kilobytes per step for the expanded graph and IPOPT's matrices
    return Cost(steps * 5e4, seconds, f"{starts} starts of N = {steps}")


def check_cost(cost: Cost, field: str, fix: str = "", error=InputError) -> None:
    """Refuse a cost beyond the memory or time limit (``OBSPLAN_MAX_MEMORY``/``_HOURS``).

    Parameters
    ----------
    cost : Cost
        The estimated cost of the request.
    field : str
        The setting or option blamed in the message.
    fix : str, optional
        What the user can do instead (appended to the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If the memory is beyond :func:`max_memory` or the time beyond
        :func:`max_hours`.
    """
    mem, hours = max_memory(), max_hours()
    tail = f"; {fix}" if fix else ""
    if not cost.memory_bytes <= mem:
        raise error(
            f"{field}: {cost.what} would need ~{_bytes(cost.memory_bytes)}, more than the limit "
            f"of {_bytes(mem)} (OBSPLAN_MAX_MEMORY){tail}"
        )
    if not cost.seconds <= hours * 3600:
        raise error(
            f"{field}: {cost.what} would take ~{_hours(cost.seconds)}, more than the limit of "
            f"{hours:g} h (OBSPLAN_MAX_HOURS){tail}"
        )


def check_monte_carlo(
    runs: int,
    samples: float,
    dim: int,
    field: str,
    fix: str = "",
    error=InputError,
    samples_field: str | None = None,
) -> None:
    """Runs, samples per run, and the memory and time of the whole Monte Carlo.

    ``field`` names the runs (and the whole cost); ``samples_field`` the setting that makes the
    samples per run (a filter step such as ``validation.dt``; default ``field``), so that too
    many samples are blamed on the step, not on the runs.

    Parameters
    ----------
    runs : int
        Number of Monte Carlo runs.
    samples : float
        Filter samples per run.
    dim : int
        Spatial dimension (2 or 3).
    field : str
        The option that asks for the runs (and is blamed for the whole cost).
    fix : str, optional
        What the user can do instead (appended to the messages).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).
    samples_field : str or None, optional
        The setting that makes the samples per run; None: ``field``.

    Raises
    ------
    InputError
        (or ``error``) If the runs, the samples per run, the memory or the time are beyond their
        limits.
    """
    check_runs(runs, field, error)
    check_samples(samples, samples_field or field, fix, error)
    max_runs = max_memory() / (float(samples) * 3 * dim * MC_BYTES_PER_ELEMENT)
    hint = f"use at most {int(max_runs)} runs" + (f" or {fix}" if fix else "")
    check_cost(monte_carlo_cost(runs, samples, dim), field, hint, error)
