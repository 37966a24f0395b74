"""Benchmark of the exact (rational) rank profile against the conditioning rank test.

    python benchmarks/bench_structural.py [--samples 60000]

Prints one table: for trajectories that reach exact full rank at once (circles), late (the paper
lawn-mower: a straight first leg) or never (straight lines, bottom-lock DVL with current: the
whole trajectory is certified), the wall time of

* ``exact_rank_profile`` (big-int arithmetic, early exit at full rank), and
* the baseline doing the conditioning job on the same trajectory: ``gramian_report`` (cumulative
  Gramians and the equilibrated eigenvalues of every prefix, for ``full_rank_from_t``),

their ratio, and both answers (exact interval/time and exact rank; conditioning time and rank).
Timings are wall-clock on whatever machine runs it: compare ratios, not seconds.
"""

from __future__ import annotations

import argparse
import time

from obsplan.model.vehicle import make_model
from obsplan.observability.gramian import gramian_report
from obsplan.observability.structural import exact_rank_profile
from obsplan.trajectory import generators as gen


def cases(samples: int) -> list[tuple[str, object, object]]:
    dt = 0.01
    T = samples * dt
    zsine = gen.circle_z(50.0, 2.6, T, z0=10.0, z_motion="sine", z_amp=5.0, z_period=90.0)
    return [
        ("circle 2D, range", gen.circle(50.0, 2.6, T).sample(dt), make_model(2, "range")),
        (
            "circle+sine z, range+dvl-water, current",
            zsine.sample(dt),
            make_model(3, "range,dvl-water", current=True),
        ),
        ("paper lawn-mower 2D, range", gen.paper_lawnmower(2).sample(dt), make_model(2, "range")),
        (
            "line along x, varying accel, range",
            gen.straight(
                (-100.0, 60.0),
                (1.0, 0.0),
                0.1,
                accel=gen.sine_profile(0.02, 0.01, 20.0),
                duration=T,
            ).sample(dt),
            make_model(2, "range"),
        ),
        (
            "circle+sine z, range+dvl-bottom, current",
            zsine.sample(dt),
            make_model(3, "range,dvl-bottom", current=True),
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=60000)
    args = ap.parse_args()
    rows = []
    for name, traj, model in cases(args.samples):
        t0 = time.perf_counter()
        prof = exact_rank_profile(traj, model)
        t_exact = time.perf_counter() - t0
        t0 = time.perf_counter()
        rep = gramian_report(traj, model)
        t_cond = time.perf_counter() - t0
        exact = "never" if prof.full_rank_from_t is None else f"{prof.full_rank_from_t:.2f} s"
        cond = "never" if rep.full_rank_from_t is None else f"{rep.full_rank_from_t:.2f} s"
        rows.append(
            (
                name,
                str(traj.n_samples),
                f"{t_exact:.3f}",
                f"{t_cond:.3f}",
                f"{t_exact / t_cond:.2f}",
                f"{exact}, rank {prof.rank}/{prof.dim}",
                f"{cond}, rank {rep.rank}/{rep.dim}",
            )
        )
    head = (
        "trajectory",
        "N",
        "exact [s]",
        "gramian_report [s]",
        "ratio",
        "exact: full from, rank",
        "conditioning: full from, rank",
    )
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    for r in (head, tuple("-" * w for w in widths), *rows):
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())


if __name__ == "__main__":
    main()
