"""Sweep throughput: a 16-task plan sweep on a local Dask cluster of 2 worker processes against
the same 16 tasks run serially in one process.

Run (a few minutes on 2 cores):

    MPLBACKEND=Agg python benchmarks/bench_sweep.py [--workers 2] [--repeat 2] [--quick]

The tasks are the default problem (``problems/localise.toml``: 2D range-only, E-optimal, 600 s,
N = 200, 4 starts, 50 Monte Carlo runs per path; ``--steps`` and ``--runs`` shrink it) over 4
acceleration bounds x 4 beacon positions.
The serial baseline calls :func:`obsplan.sweeps.run_task` (exactly what a worker runs) on each
task, one after the other, in a new Python process (timed after its imports; a new process so
that no cache warmed by an earlier repeat helps it, as none helps a new worker). The sweep runs
:func:`obsplan.sweep` on a new LocalCluster (figures off), timed from creating the cluster to the
sweep's return, so it includes starting the workers, shipping tasks, writing every task's files
and the table. With ``--repeat k`` both are run k times, alternating, and the best of each is
reported. Printed:

* speed-up = serial wall / sweep wall (the acceptance expects >= 1.7 on 2 cores);
* the cluster start-up alone;
* per-task overhead = (workers x sweep wall - sum of the tasks' own compute times) / tasks: what
  a task costs beyond its computation (scheduling, transfer, files, cluster start-up shared out,
  and idle workers at the end of the sweep);
* a control: the same tasks split over ``--workers`` plain Python processes started together
  (no Dask): the speed-up the machine allows at the time (on a machine shared with other jobs it
  is far below the core count), and the sweep's speed-up relative to it;
* CPU seconds per task, serial, in the workers and in the client (user + system, from
  getrusage). The load average is printed with the table.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.sweeps import expand, local_cluster, run_task, sweep, sweep_from_dict  # noqa: E402


def study(steps: int | None = None, runs: int | None = None) -> dict:
    """The 16-task study: the default problem, optionally with fewer steps or Monte Carlo runs."""
    base: dict = {}
    if steps is not None:
        base["horizon"] = {"duration": 600.0, "steps": steps}
    if runs is not None:
        base["validation"] = {"runs": runs}
    return {
        "sweep": {"name": "bench", "base": "localise.toml", "mode": "plan"},
        "base": base,
        "axes": {
            "limits.accel": [0.02, 0.035, 0.05, 0.08],
            "beacon.position": [[0.0, 0.0], [50.0, 0.0], [0.0, 50.0], [110.0, 110.0]],
        },
    }


def serial_in_fresh_process(steps: int | None, runs: int | None, parts: int = 1) -> dict:
    """Wall and CPU time [s] of the 16 tasks run one after the other in a new Python process
    (timed inside it, after its imports): cold caches, exactly as each worker starts.

    With ``parts = k``, k such processes run at the same time, each on every k-th task (no Dask):
    the speed-up the machine allows right now (wall: the slowest part's; CPU: summed).
    """
    procs = [
        subprocess.Popen(
            [sys.executable, __file__, "--serial-child", f"--part={i}/{parts}"]
            + _size_args(steps, runs),
            stdout=subprocess.PIPE,
            text=True,
        )
        for i in range(parts)
    ]
    outs = [json.loads(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
    assert all(p.returncode == 0 for p in procs)
    return {"wall": max(o["wall"] for o in outs), "cpu": sum(o["cpu"] for o in outs)}


def _size_args(steps: int | None, runs: int | None) -> list[str]:
    out = []
    if steps is not None:
        out += ["--steps", str(steps)]
    if runs is not None:
        out += ["--runs", str(runs)]
    return out


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def serial_child(steps: int | None, runs: int | None, part: str) -> None:
    i, k = (int(x) for x in part.split("/"))
    tasks = expand(sweep_from_dict(study(steps, runs), base_dir=ROOT / "problems"))[i::k]
    t0, c0 = time.perf_counter(), _cpu_s()
    outcomes = [run_task(t) for t in tasks]
    wall, cpu = time.perf_counter() - t0, _cpu_s() - c0
    assert all(o["status"] == "done" for o in outcomes), [o["error"] for o in outcomes]
    print(json.dumps({"wall": wall, "cpu": cpu}))


def sweep_on_local_cluster(spec, workers: int) -> dict:
    """``obsplan.sweep`` on a new LocalCluster, timed: start-up, sweep, worker and client CPU."""
    import distributed

    t0 = time.perf_counter()
    cluster = local_cluster(workers, dashboard_address=None)
    client = distributed.Client(cluster)
    startup = time.perf_counter() - t0
    try:
        before = client.run(_cpu_s)
        c0 = _cpu_s()
        with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
            t1 = time.perf_counter()
            df = sweep(spec, Path(tmp) / "out", client=client, progress=False, figures=False)
            wall = time.perf_counter() - t1
        client_cpu = _cpu_s() - c0
        after = client.run(_cpu_s)
    finally:
        client.close()
        cluster.close()
    assert (df["status"] == "done").all()
    return {
        "startup": startup,
        "wall": wall,
        "total": startup + wall,
        "compute": float(df["task_wall_s"].sum()),
        "worker_cpu": sum(after[w] - before[w] for w in after),
        "client_cpu": client_cpu,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--steps", type=int, default=None, help="horizon.steps (default: the file's)")
    ap.add_argument("--runs", type=int, default=None, help="validation.runs (default: the file's)")
    ap.add_argument("--quick", action="store_true", help="N = 20, 3 runs (a smoke test)")
    ap.add_argument(
        "--repeat", type=int, default=1, help="run both k times, alternating; report the best"
    )
    ap.add_argument("--serial-child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--part", default="0/1", help=argparse.SUPPRESS)
    args = ap.parse_args()
    steps, runs = (20, 3) if args.quick else (args.steps, args.runs)
    if args.serial_child:
        serial_child(steps, runs, args.part)
        return
    spec = sweep_from_dict(study(steps, runs), base_dir=ROOT / "problems")
    tasks = expand(spec)
    assert len(tasks) == 16

    load0 = os.getloadavg()[0]
    serial: dict | None = None
    plain: dict | None = None
    par: dict | None = None
    for _ in range(args.repeat):
        s = serial_in_fresh_process(steps, runs)
        serial = s if serial is None or s["wall"] < serial["wall"] else serial
        p = sweep_on_local_cluster(spec, args.workers)
        par = p if par is None or p["total"] < par["total"] else par
        c = serial_in_fresh_process(steps, runs, parts=args.workers)
        plain = c if plain is None or c["wall"] < plain["wall"] else plain
    load1 = os.getloadavg()[0]

    n, w = len(tasks), args.workers
    pb = tasks[0].problem
    print(
        f"sweep throughput: {n} plan tasks (N = {pb['horizon']['steps']}, "
        f"{pb['objective']['starts']} starts, {pb['validation']['runs']} runs per path); "
        f"best of {args.repeat}; load average {load0:.1f} -> {load1:.1f} on {os.cpu_count()} "
        "cores"
    )
    print(f"{'run':<40} {'wall [s]':>9} {'per task [s]':>13} {'speed-up':>9}")
    print("-" * 74)
    rows = [
        ("serial, one process", serial["wall"]),
        (f"sweep, LocalCluster {w} workers", par["total"]),
        ("  of which the sweep (cluster up)", par["wall"]),
        (f"control: {w} plain processes, no Dask", plain["wall"]),
    ]
    for name, wall in rows:
        print(f"{name:<40} {wall:9.1f} {wall / n:13.2f} {serial['wall'] / wall:9.2f}")
    print()
    print(f"cluster start-up (LocalCluster + Client)  {par['startup']:7.2f} s")
    print(
        f"per-task overhead (wall)                  {(w * par['total'] - par['compute']) / n:7.2f}"
        " s  = (workers x sweep wall - task compute) / tasks"
    )
    print(
        f"CPU per task: serial {serial['cpu'] / n:.2f} s, workers {par['worker_cpu'] / n:.2f} s, "
        f"client {par['client_cpu'] / n:.3f} s, {w} plain processes {plain['cpu'] / n:.2f} s"
    )
    print(
        f"sweep speed-up / control speed-up       {plain['wall'] / par['total']:7.2f}"
        "  (1.0: Dask costs nothing beyond what the machine allows now)"
    )


if __name__ == "__main__":
    main()
