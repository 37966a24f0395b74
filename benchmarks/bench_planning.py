"""Planner benchmark: solve time and objective against N, 2D and 3D, each objective; and IPOPT
(CasADi, exact closed-form Gramian, sparse lifted formulation) against scipy SLSQP on the same
objective at N = 50 and 200.

Run (heavy; one core, minutes):

    MPLBACKEND=Agg python benchmarks/bench_planning.py [--quick] [--wall 120]

Each IPOPT solve starts from the lawn-mower baseline (one start, so times are per solve) with an
IPOPT wall-time limit; a solve that hits it is reported with its status. As ``obsplan plan``
does, N > 250 is first solved on a coarse grid and the fine solve starts from that plan: "build"
is the model construction plus that coarse pass, "solve" the fine IPOPT run. SLSQP gets the
acceleration, speed and area limits but not ``limits.min_range`` (its "feasible" column is the
full check, which the minimum range can fail). SLSQP optimises the
inputs only (states by exact integration), with the objective evaluated by the same numpy/CasADi
metric code (:func:`obsplan.planning.objectives.evaluate.objective_value`) and finite-difference
gradients, the speed limit (analytic Jacobian) and the tightened area box (linear) as constraints.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem, solve  # noqa: E402
from obsplan.planning.baselines.vehicle import lawnmower_baseline  # noqa: E402
from obsplan.planning.objectives.evaluate import objective_value  # noqa: E402
from obsplan.planning.problem.definition import PlanningProblem  # noqa: E402
from obsplan.planning.problem.feasibility import check_limits  # noqa: E402
from obsplan.planning.problem.schema import MINIMISED  # noqa: E402
from obsplan.planning.problem.sections import Horizon  # noqa: E402
from obsplan.trajectory.sampled import Trajectory  # noqa: E402

PROBLEMS = {
    # (dim, objective) -> problem file; 3D LWO needs a DVL (eq. 44), 3D range-only cannot (eq. 38);
    # 2D: the free-localisation problem (default.toml is a survey since it gained a mission)
    (2, "pcrb-position"): "localise",
    (3, "pcrb-position"): "range3d",
    (2, "gramian-min-eig"): "localise",
    (2, "gramian-log-det"): "localise",
    (2, "lwo-condition"): "localise",
    (2, "kf-position-std"): "localise",
    (3, "gramian-min-eig"): "range3d",
    (3, "gramian-log-det"): "range3d",
    (3, "lwo-condition"): "range-dvl3d",
    (3, "kf-position-std"): "range3d",
}


def problem(dim: int, kind: str, steps: int) -> PlanningProblem:
    pb = load_problem(ROOT / "problems" / f"{PROBLEMS[(dim, kind)]}.toml")
    # the problem file's defaults for everything else (tolerance, iteration limit, mode)
    obj = replace(pb.objective, kind=kind, starts=1, mode="auto", tol=None)
    return replace(pb, objective=obj, horizon=Horizon(pb.horizon.duration, steps))


def ipopt_row(pb: PlanningProblem, wall: float) -> dict:
    # one start (the lawn-mower: objective.starts = 1), solved as obsplan plan solves it: for
    # N > 250 a coarse pass first (its time is in "build"), then the warm-started fine solve
    t0 = time.perf_counter()
    res = solve(pb, ipopt_options={"max_wall_time": wall}, processes=1)
    total = time.perf_counter() - t0
    s = res.starts[0]
    return {
        "status": s.status,
        "iter": s.iterations,
        "build_s": res.build_s,
        "solve_s": s.wall_s,
        "total_s": total,
        # the returned plan (the best candidate: the start's path or its warm start)
        "objective": res.objective,
        "initial": objective_value(lawnmower_baseline(pb).trajectory, pb),
        "feasible": res.trajectory is not None and check_limits(res.trajectory, pb).ok(),
    }


# ------------------------------------------------------------------------------ SLSQP
def _integration_matrices(pb: PlanningProblem) -> tuple[np.ndarray, np.ndarray]:
    """``v_k = v0 + Mv u`` and ``p_k = p0 + v0 t_k + Mp u`` for nodes 1..N (per axis)."""
    N, h = pb.horizon.steps, pb.horizon.dt
    k = np.arange(1, N + 1)[:, None]
    j = np.arange(N)[None, :]
    Mv = np.where(j < k, h, 0.0)
    Mp = np.where(j < k, h**2 / 2 + (k - 1 - j) * h**2, 0.0)
    return Mv, Mp


def slsqp_row(pb: PlanningProblem, wall: float, maxiter: int = 300) -> dict:
    n, N, h = pb.dim, pb.horizon.steps, pb.horizon.dt
    t = pb.times
    Mv, Mp = _integration_matrices(pb)
    sign = 1.0 if pb.objective.kind in MINIMISED else -1.0
    guess = lawnmower_baseline(pb).trajectory
    x0 = guess.u[:-1].T.reshape(-1)  # axis-major: u[:, 0], then u[:, 1] ...
    deadline = time.perf_counter() + wall

    class Timeout(Exception):
        pass

    def traj(x: np.ndarray) -> Trajectory:
        return Trajectory.from_inputs(t, pb.p0, pb.v0, x.reshape(n, N).T)

    def fun(x: np.ndarray) -> float:
        if time.perf_counter() > deadline:
            raise Timeout
        val = objective_value(traj(x), pb)
        return sign * (val if np.isfinite(val) else -1e3 * sign)

    def speed(x: np.ndarray) -> np.ndarray:
        V = pb.v0[None, :] + (Mv @ x.reshape(n, N).T)
        return pb.limits.speed**2 - np.sum(V**2, axis=1)

    def speed_jac(x: np.ndarray) -> np.ndarray:
        V = pb.v0[None, :] + (Mv @ x.reshape(n, N).T)
        return np.hstack([-2 * V[:, i : i + 1] * Mv for i in range(n)])

    cons = [{"type": "ineq", "fun": speed, "jac": speed_jac}]
    boxes = []
    if pb.limits.area is not None:
        boxes += [(0, pb.limits.area.x), (1, pb.limits.area.y)]
    if pb.limits.depth is not None:
        boxes.append((2, pb.limits.depth))
    for axis, (lo, hi) in boxes:
        margin = pb.accel[axis] * h**2 / 8
        base = pb.p0[axis] + pb.v0[axis] * t[1:]
        J = np.zeros((N, n * N))
        J[:, axis * N : (axis + 1) * N] = Mp
        cons.append(
            {
                "type": "ineq",
                "fun": lambda x, J=J, b=base, c=hi - margin: c - b - J @ x,
                "jac": lambda x, J=J: -J,
            }
        )
        cons.append(
            {
                "type": "ineq",
                "fun": lambda x, J=J, b=base, c=lo + margin: b + J @ x - c,
                "jac": lambda x, J=J: J,
            }
        )
    bounds = [(-a, a) for a in pb.accel for _ in range(N)]
    t0 = time.perf_counter()
    try:
        res = minimize(
            fun,
            x0,
            method="SLSQP",
            bounds=bounds,
            constraints=cons,
            options={"maxiter": maxiter, "ftol": 1e-10},
        )
        x, status, nit = res.x, ("success" if res.success else res.message), res.nit
    except Timeout:
        x, status, nit = None, f"wall time {wall:g} s exceeded", -1
    dt = time.perf_counter() - t0
    if x is None:
        return {"status": status, "iter": nit, "solve_s": dt, "objective": None, "feasible": False}
    tr = traj(x)
    return {
        "status": status,
        "iter": nit,
        "solve_s": dt,
        "objective": objective_value(tr, pb),
        "feasible": check_limits(tr, pb).ok(),
    }


def shipped_problems(wall: float) -> int:
    """Every problems/*.toml at full size with its own multi-start settings."""
    print("## Shipped problems at full size (all starts)\n")
    print(
        "| problem | objective | N | starts | status | best start | wall [s] | objective | "
        "lawn-mower | feasible |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in sorted((ROOT / "problems").glob("*.toml")):
        pb = load_problem(path)
        res = solve(pb, ipopt_options={"max_wall_time": wall})
        lm = objective_value(lawnmower_baseline(pb).trajectory, pb)
        feas = res.trajectory is not None and check_limits(res.trajectory, pb).ok()
        print(
            f"| {path.stem} | {pb.objective.kind} | {pb.horizon.steps} | {len(res.starts)} | "
            f"{res.status} | {res.best_start} | {res.wall_s:.1f} | {fmt(res.objective)} | "
            f"{fmt(lm)} | {feas} |",
            flush=True,
        )
    return 0


def fmt(x, spec=".4g"):
    return "-" if x is None else format(x, spec)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="N = 50 only")
    ap.add_argument(
        "--wall", type=float, default=120.0, help="IPOPT/SLSQP wall limit per solve [s]"
    )
    ap.add_argument("--only", default="", help="comma-separated objectives to run")
    ap.add_argument("--no-slsqp", action="store_true")
    ap.add_argument("--problems", action="store_true", help="only the shipped problems, full size")
    args = ap.parse_args()
    if args.problems:
        return shipped_problems(args.wall)
    Ns = (50,) if args.quick else (50, 200, 1000)
    kinds = [
        k
        for k in (
            "pcrb-position",
            "gramian-min-eig",
            "gramian-log-det",
            "kf-position-std",
            "lwo-condition",
        )
        if not args.only or k in args.only.split(",")
    ]
    print("## IPOPT (CasADi) solve time and objective against N (lawn-mower start, 1 start)\n")
    print(
        "| dim | objective | N | status | iter | build [s] | solve [s] | plan's objective | "
        "lawn-mower | feasible |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    ipopt_results = {}
    for dim in (2, 3):
        for kind in kinds:
            for N in Ns:
                pb = problem(dim, kind, N)
                r = ipopt_row(pb, args.wall)
                ipopt_results[(dim, kind, N)] = r
                print(
                    f"| {dim}D | {kind} | {N} | {r['status']} | {r['iter']} | "
                    f"{r['build_s']:.2f} | {r['solve_s']:.2f} | {fmt(r['objective'])} | "
                    f"{fmt(r['initial'])} | {r['feasible']} |",
                    flush=True,
                )
    if args.no_slsqp:
        return 0
    print("\n## scipy SLSQP on the same objective (inputs only, FD gradients) vs IPOPT\n")
    print(
        "| dim | objective | N | SLSQP status | iter | SLSQP [s] | SLSQP objective | "
        "IPOPT [s] | IPOPT objective | time ratio | feasible |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for dim in (2, 3):
        for kind in ("pcrb-position", "gramian-min-eig", "gramian-log-det"):
            if kind not in kinds:
                continue
            for N in (50, 200) if not args.quick else (50,):
                pb = problem(dim, kind, N)
                s = slsqp_row(pb, args.wall)
                ip = ipopt_results.get((dim, kind, N)) or ipopt_row(pb, args.wall)
                ratio = s["solve_s"] / ip["total_s"]
                print(
                    f"| {dim}D | {kind} | {N} | {s['status']} | {s['iter']} | "
                    f"{s['solve_s']:.2f} | {fmt(s['objective'])} | {ip['total_s']:.2f} | "
                    f"{fmt(ip['objective'])} | {ratio:.3g} | {s['feasible']} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
