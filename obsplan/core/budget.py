"""Bounded work: the cost of a request, estimated before any work starts, and its limits.

Every verb asks here before it allocates or solves anything, from the problem file and from the
command line alike; a request beyond a limit is refused with its figure, the limit and the fix
(an :class:`~obsplan.core.errors.InputError`: exit 2). The limits:

========================  ==================================  ===================================
what                      limit                               why
========================  ==================================  ===================================
IPOPT starts              :data:`MAX_STARTS`                  each start is a full solve
IPOPT iterations          :data:`MAX_ITERATIONS`              per start; IPOPT's own counter is
                                                              an int
Monte Carlo runs          :data:`MAX_RUNS`                    per path: ``runs``, ``max_runs``,
                                                              ``--runs``, ``--max-runs`` alike
filter samples per run    :data:`MAX_SAMPLES`                 the filters loop over samples
sweep tasks               :data:`MAX_TASKS`                   counted before the axes are
                                                              expanded
rows of an input file     :data:`MAX_ROWS`                    estimated from the file size first
rows of a mission log     :data:`MAX_LOG_ROWS`                the replay keeps 3 covariances a row
problem or sweep file     :data:`MAX_TOML_BYTES`              parsed at ~1.5 MB/s, in memory
survey lines              :data:`MAX_LINES`                   given or generated (counted from
                                                              ``mission.spacing`` first)
waypoints                 :data:`MAX_WAYPOINTS`               and their time windows
polygon corners           :data:`MAX_POLYGON_CORNERS`         every line crosses every edge
names                     :data:`MAX_NAME_CHARS`              ``problem.name``, ``sweep.name``:
                                                              reports, figure titles
local Dask workers        :data:`MAX_WORKERS_PER_CORE` x      a worker is a process (memory,
                          cores                               seconds to start); tasks are
                                                              single-threaded
memory                    ``OBSPLAN_MAX_MEMORY``              default :data:`DEFAULT_MAX_MEMORY`
                                                              bytes
time                      ``OBSPLAN_MAX_HOURS``               default :data:`DEFAULT_MAX_HOURS`
                                                              hours
========================  ==================================  ===================================

Every count that drives memory or time is checked here *before* the work it drives: a count
that would build a list (lines from a spacing, waypoints of a file) is refused from its length
or from its arithmetic, never after building it.

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
#: Most rows of a logged mission replayed by ``obsplan estimate``
#: (:mod:`obsplan.estimation.replay`). The replay is a Python loop of ~50-100 µs a row (~20 s at
#: the limit) and keeps the filtered, predicted and smoothed covariances of every row: 3 x 81
#: floats a row in 3D with current, ~400 MB at the limit. A day of a 1 Hz DVL is 86,400 rows.
MAX_LOG_ROWS = 200_000
#: Largest problem or sweep file [bytes]. The largest real one is a sweep whose axes list
#: :data:`MAX_TASKS` values (~1-2 MB); Python's TOML parser reads ~1.5 MB/s, so a parse takes
#: seconds at most, where a 1 GB file (the limit of other text files) took ten minutes.
MAX_TOML_BYTES = 8_000_000
#: Most survey lines (given, or generated from ``mission.spacing``). A line and the turn to the
#: next take several planning intervals (at most ``horizon.steps`` = 5000: ten per line), and
#: checking that the mission fits the horizon takes ~2.5 ms per line: at most ~1 s. Counted
#: from the area's width and the spacing before any line is generated (1e-7 m over 200 m was
#: 2e9 lines: 11 GB in a minute).
MAX_LINES = 500
#: Most ``mission.waypoints`` (and ``mission.windows``): each is reached at a planning node and
#: checked like a line (~2 ms each); 300,000 of them ran for minutes.
MAX_WAYPOINTS = 500
#: Most corners of a ``mission.area`` polygon: every generated line is intersected with every
#: edge (lines x corners work, at most 500,000 intersections).
MAX_POLYGON_CORNERS = 1000
#: Longest name [characters] (``problem.name``, ``sweep.name``): a name heads every report,
#: progress line and figure title (matplotlib lays out a title's text: a 1 MB name made a 5 s
#: run take 88 s). 200 characters is a long sentence.
MAX_NAME_CHARS = 200
#: Most worker processes of a local Dask cluster per core. Tasks are single-threaded and
#: CPU-bound: beyond one worker per core they only share the cores, while each worker is a
#: process of its own (~0.2-0.5 GB once CasADi and numba are loaded) that takes seconds to
#: start (48 workers on 2 cores took minutes). Two per core leaves room for a worker waiting
#: on its output; a larger cluster is an existing scheduler's (``--scheduler``).
MAX_WORKERS_PER_CORE = 2
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


def check_max_runs(n: int, field: str = "--max-runs", error=InputError) -> None:
    """At most :data:`MAX_RUNS` runs for the doubling validation (``validation.max_runs``): a
    verdict that never decides doubles its runs up to this cap.

    Parameters
    ----------
    n : int
        The cap requested on the runs of the doubling validation [runs].
    field : str, optional
        The option or setting that asked for them (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    fix = f"use at most {MAX_RUNS} (the runs double until every verdict is decided or this cap)"
    check_count(n, MAX_RUNS, field, "Monte Carlo runs", fix, error)


def check_lines(n: float, field: str = "mission.lines", fix: str = "", error=InputError) -> None:
    """At most :data:`MAX_LINES` survey lines (``n`` may be a float count, even infinite).

    Parameters
    ----------
    n : float
        Number of survey lines, given or computed from the area and the spacing before any
        line is generated [lines]; may be infinite.
    field : str, optional
        The setting that asks for the lines (named in the message).
    fix : str, optional
        What the user can do instead (appended to the message); empty: split the survey.
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit (or NaN).
    """
    fix = fix or f"plan at most {MAX_LINES} lines at a time (split the survey)"
    check_count(n, MAX_LINES, field, "lines", fix, error)


def check_waypoints(n: float, field: str = "mission.waypoints", error=InputError) -> None:
    """At most :data:`MAX_WAYPOINTS` waypoints (or their time windows).

    Parameters
    ----------
    n : float
        Number of waypoints (or time windows) [points].
    field : str, optional
        The setting that lists them (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    fix = f"plan at most {MAX_WAYPOINTS} waypoints at a time (split the mission)"
    check_count(n, MAX_WAYPOINTS, field, "points", fix, error)


def check_corners(n: float, field: str = "mission.area.polygon", error=InputError) -> None:
    """At most :data:`MAX_POLYGON_CORNERS` corners of a polygon.

    Parameters
    ----------
    n : float
        Number of corners of the polygon [corners].
    field : str, optional
        The setting that gives the polygon (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    fix = f"simplify the polygon to at most {MAX_POLYGON_CORNERS} corners"
    check_count(n, MAX_POLYGON_CORNERS, field, "corners", fix, error)


def check_name_length(text: str, field: str, error=InputError) -> None:
    """A name of at most :data:`MAX_NAME_CHARS` characters (it heads reports and figures).

    Parameters
    ----------
    text : str
        The name (its length is counted in characters).
    field : str
        The setting that gives the name (named in the message), e.g. ``"problem.name"``.
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``text`` is longer than the limit.
    """
    fix = "shorten it (it heads every report, progress line and figure title)"
    check_count(len(text), MAX_NAME_CHARS, field, "characters", fix, error)


def check_workers(n: int, cores: int, field: str = "--workers", error=InputError) -> None:
    """At least one and at most :data:`MAX_WORKERS_PER_CORE` x ``cores`` local worker processes.

    Parameters
    ----------
    n : int
        Number of local worker processes requested [processes].
    cores : int
        Cores this process may use [cores] (fewer than one counts as one).
    field : str, optional
        The option that asked for the workers (named in the message).
    error : type of InputError, optional
        The exception raised (a problem check passes its own subclass).

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is less than 1 or beyond the limit.
    """
    if n < 1:
        raise error(f"{field} must be at least 1, got {n}")
    limit = MAX_WORKERS_PER_CORE * max(1, cores)
    fix = (
        f"{MAX_WORKERS_PER_CORE} per core on the {cores} core{'s' if cores != 1 else ''} this "
        f"process may use; tasks are single-threaded, so more workers only share the cores: "
        f"use at most {limit}, or an existing cluster with --scheduler ADDRESS"
    )
    check_count(n, limit, field, "worker processes", fix, error)


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


def check_log_rows(n: float, field: str, error=InputError) -> None:
    """At most :data:`MAX_LOG_ROWS` rows of a logged mission (counted or estimated).

    Parameters
    ----------
    n : float
        Number of rows.
    field : str
        The argument naming the log (named in the message).
    error : type of InputError, optional
        The exception raised.

    Raises
    ------
    InputError
        (or ``error``) If ``n`` is beyond the limit.
    """
    check_count(
        n, MAX_LOG_ROWS, field, "rows", "cut the log into legs or decimate its DVL rows", error
    )


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
