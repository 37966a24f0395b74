"""The main job's first run against its later runs: cold (a fresh numba cache) and warm wall times.

    python benchmarks/bench_first_run.py [--repeat 2] [--problem NAME] [--kernels]

Runs ``obsplan plan [NAME] --out TMP --quiet`` in fresh processes: first with an empty
``NUMBA_CACHE_DIR`` (what a user's first run pays: the filters' kernels are compiled), then
``--repeat`` times with that cache filled. Prints the wall times side by side and their ratio.
With ``--kernels`` it also compiles every kernel of the default Monte Carlo in one process with
an empty cache and prints the compile time of each (inclusive: a kernel's time contains the
kernels it calls that were not compiled yet), from numba's own compile events.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_plan(problem: str | None, cache: Path, out: Path) -> float:
    """Wall time [s] of one ``obsplan plan`` in a fresh process using the numba cache ``cache``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), MPLBACKEND="Agg", PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "obsplan", "plan", *([problem] if problem else [])]
    cmd += ["--out", str(out), "--quiet", "--force"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"obsplan plan exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    return wall


def kernel_times(cache: Path) -> list[tuple[str, float]]:
    """Compile time [s] of each kernel a closed-loop Monte Carlo of the default plan uses."""
    code = f"""
import os, time, collections, json
os.environ["NUMBA_CACHE_DIR"] = {str(cache)!r}
from numba.core import event
times, starts = collections.defaultdict(float), {{}}
class Listener(event.Listener):
    def on_start(self, e):
        starts[id(e.data["dispatcher"]), str(e.data["args"])] = time.perf_counter()
    def on_end(self, e):
        d = e.data["dispatcher"]
        t0 = starts.get((id(d), str(e.data["args"])), time.perf_counter())
        times[d.py_func.__module__.rsplit(".", 1)[-1] + "." + d.py_func.__name__] += (
            time.perf_counter() - t0)
event.register("numba:compile", Listener())
import obsplan
r = obsplan.plan(obsplan.load_problem(), runs=2, max_runs=2)
print(json.dumps(sorted(times.items(), key=lambda kv: -kv[1])))
"""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(proc.stderr[-2000:])
    import json

    return [(k, float(v)) for k, v in json.loads(proc.stdout.strip().splitlines()[-1])]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="warm runs (default 2)")
    ap.add_argument("--problem", default=None, help="a problem file or shipped name (default)")
    ap.add_argument("--kernels", action="store_true", help="also each kernel's compile time")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = Path(tmp) / "numba", Path(tmp) / "out"
        cold = run_plan(args.problem, cache, out)
        warm = [run_plan(args.problem, cache, out) for _ in range(args.repeat)]
        best = min(warm)
        print(f"{'run':<28} {'wall [s]':>9}")
        print(f"{'cold (empty numba cache)':<28} {cold:9.1f}")
        for i, w in enumerate(warm, 1):
            print(f"{f'warm {i}':<28} {w:9.1f}")
        print(f"cold / best warm: {cold / best:.2f}x")
        if args.kernels:
            kcache = Path(tmp) / "numba-kernels"
            rows = kernel_times(kcache)
            print(f"\n{'kernel (inclusive compile time)':<40} {'[s]':>7}")
            for name, t in rows:
                if t >= 0.2:
                    print(f"{name:<40} {t:7.2f}")
            top = [t for n, t in rows if "." in n]
            print(f"largest inclusive compile: {max(top):.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
