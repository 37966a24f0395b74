"""Solve time of every observability objective (default and the paper's form) by grid size.

Run (minutes):

    MPLBACKEND=Agg python benchmarks/bench_gramian_objectives.py [--starts K] [--quick]

Cases: 2D range-only (``problems/suite/gramian-offset-beacon.toml``) at N = 200 and N = 1000, and
3D range + bottom-lock DVL (``problems/range-dvl3d.toml``) at N = 600; for each,
``gramian-min-eig``, ``gramian-log-det`` and ``lwo-condition`` with their default
(information-weighted; windowed for the Gramians) settings and with ``window = "mission"``,
``weights = "none"`` (the paper's; for ``lwo-condition`` the scale-free conditioning). Each row is
one ``solve`` as ``obsplan plan`` runs it (multi-start, coarse-to-fine above N = 250) with
``--starts`` starts in one process, and prints its wall and CPU time (the machine may be shared:
the load average is printed before and after), its IPOPT iterations and status, the windows and the
budget of the issue (2D N = 200: 20 s, N = 1000: 60 s; 3D DVL N = 600: 90 s), flagging a row whose
wall time is over it and a solve that did not converge (any status but ``Solve_Succeeded``).
``--quick`` runs the N = 200 case only; ``--kind K`` (repeatable) only those objectives;
``--linearisation-bound K`` sets ``objective.linearisation_bound`` on every row (a bound on an
exact-Hessian objective is solved with that Hessian without the penalty's curvature).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.objectives.windowed import paper_form, window_settings  # noqa: E402
from obsplan.planning.problem.sections import Horizon  # noqa: E402
from obsplan.planning.solver.ipopt import SUCCESS_STATUS  # noqa: E402
from obsplan.planning.solver.solve import solve  # noqa: E402

#: (label, problem file, steps, budget [s]).
CASES = (
    ("2D range, N=200", "problems/suite/gramian-offset-beacon.toml", 200, 20.0),
    ("2D range, N=1000", "problems/suite/gramian-offset-beacon.toml", 1000, 60.0),
    ("3D range+DVL, N=600", "problems/range-dvl3d.toml", 600, 90.0),
)
KINDS = ("gramian-min-eig", "gramian-log-det", "lwo-condition")
FORMS = (("windowed", {}), ("paper", {"window": "mission", "weights": "none"}))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=1, help="starts per solve (default 1)")
    ap.add_argument("--quick", action="store_true", help="the N = 200 case only")
    ap.add_argument("--kind", action="append", choices=KINDS, help="only this objective")
    ap.add_argument(
        "--linearisation-bound",
        type=float,
        default=None,
        metavar="K",
        help="objective.linearisation_bound of every row (default: each kind's own)",
    )
    args = ap.parse_args(argv)
    head = (
        f"{'case':22s} {'objective':16s} {'form':11s} {'windows':>8s} {'wall s':>7s} "
        f"{'cpu s':>6s} {'budget':>6s} {'iters':>5s}  status"
    )
    print("load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in os.getloadavg()))
    print(head)
    print("-" * (len(head) + 20))
    for label, path, steps, budget in CASES[:1] if args.quick else CASES:
        base = load_problem(ROOT / path)
        base = replace(base, horizon=Horizon(base.horizon.duration, steps))
        for kind in args.kind or KINDS:
            for form, fields in FORMS:
                obj = replace(base.objective, kind=kind, starts=args.starts, **fields)
                if args.linearisation_bound is not None:
                    obj = replace(obj, linearisation_bound=args.linearisation_bound)
                pb = replace(base, objective=obj)
                ws = window_settings(pb)
                nw = "1" if paper_form(pb) else f"{len(ws.starts)}x{ws.window_s:.0f}s"
                if kind == "lwo-condition":  # node by node, over one past window each
                    nw = "-" if paper_form(pb) else f"{ws.window_s:.0f}s"
                    form = "scale-free" if paper_form(pb) else "information"
                t0, c0 = time.perf_counter(), time.process_time()
                res = solve(pb, processes=1)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                flags = [] if res.status == SUCCESS_STATUS else ["NOT CONVERGED"]
                flags += [] if wall <= budget else ["OVER BUDGET"]
                print(
                    f"{label:22s} {kind:16s} {form:11s} {nw:>8s} {wall:7.1f} {cpu:6.1f} "
                    f"{budget:6.0f} {res.iterations:5d}  {res.status}"
                    + "".join(f"  {f}" for f in flags),
                    flush=True,
                )
    print("load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
