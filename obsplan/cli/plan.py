"""``obsplan plan [PROBLEM.toml] [--out DIR]``: plan a path, compare with baselines, validate."""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

from obsplan.cli.common import OutputDir
from obsplan.core import budget
from obsplan.core.errors import InputError
from obsplan.planning.figures import (
    plot_filter_errors,
    plot_gramian_eigs,
    plot_paths,
    plot_speed,
    save_figure,
)
from obsplan.planning.plan import PlanResult, plan
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import DEFAULT_PROBLEM, load_problem
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.replan import ReplanResult, replan_monte_carlo, replan_nodes
from obsplan.planning.validation.verdict import metric_value
from obsplan.trajectory.sampled import write_csv

DEFAULT_OUT = "obsplan-plan"
FIGURES = ("path.png", "gramian.png", "filters.png", "speed.png")


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``plan`` verb."""
    p = subparsers.add_parser(
        "plan",
        help="plan an observability-optimal path and validate it against baselines",
        description=(
            "Solve a planning problem (TOML; see docs/problem-files.md), compare the plan with "
            "the lawn-mower and other baselines under the same limits, run EKF/KF Monte Carlo "
            "on each, and write DIR/plan.csv, DIR/report.json and figures."
        ),
    )
    p.add_argument(
        "problem",
        nargs="?",
        metavar="PROBLEM.toml",
        help=f"problem file (default: {DEFAULT_PROBLEM.relative_to(DEFAULT_PROBLEM.parents[1])})",
    )
    p.add_argument(
        "--out", metavar="DIR", default=DEFAULT_OUT, help=f"output folder ({DEFAULT_OUT})"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace DIR whole if it is an earlier obsplan output (old files removed)",
    )
    p.add_argument(
        "--runs", type=int, metavar="N", help="override validation.runs (the first batch)"
    )
    p.add_argument(
        "--max-runs",
        type=int,
        metavar="N",
        help="override validation.max_runs: runs are added (doubling) until every verdict is "
        "decided at 95 %% confidence or N runs are reached; N = --runs: one batch",
    )
    p.add_argument("--steps", type=int, metavar="N", help="override horizon.steps")
    p.add_argument("--starts", type=int, metavar="N", help="override objective.starts")
    p.add_argument("--no-validate", action="store_true", help="skip the Monte Carlo validation")
    p.add_argument(
        "--replan",
        type=float,
        metavar="EVERY",
        help="also validate with receding-horizon replanning: every EVERY s (a multiple of the "
        "planning step) each run re-solves from its estimate (report.json key 'replan')",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--verbose", action="store_true", help="show IPOPT's output")
    return p


def _apply_overrides(pb: PlanningProblem, args: argparse.Namespace) -> PlanningProblem:
    """The command-line overrides, checked against the same limits as the problem file's."""
    if args.runs is not None and args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.max_runs is not None and args.max_runs < 1:
        raise InputError(f"--max-runs must be at least 1, got {args.max_runs}")
    if args.steps is not None:
        pb = replace(pb, horizon=Horizon(duration=pb.horizon.duration, steps=args.steps))
    if args.starts is not None:
        budget.check_starts(args.starts, "--starts")
        pb = replace(pb, objective=replace(pb.objective, starts=args.starts))
    if args.runs is not None and not args.no_validate:
        samples = pb.horizon.duration / pb.validation.dt + 1
        budget.check_monte_carlo(args.runs, samples, pb.dim, "--runs", "a longer validation.dt")
    if args.replan is not None:
        if args.no_validate:
            raise InputError("--replan runs inside the validation: drop --no-validate")
        replan_nodes(pb, args.replan)  # a bad EVERY is an input error before any work
    return pb


def _fmt(x: float | None, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec)


def summary_table(result: PlanResult) -> str:
    """Planned vs baselines: objective, bounds, Monte Carlo errors [m], closest approach [m] of
    the path and of the true paths over all runs, runs inside ``min_range``, runs breaking any
    limit on their true path [%]."""
    head = (
        f"{'path':<16} {'objective':>10} {'PCRB avg':>9} {'PCRB fin':>9} {'EKF rmse':>9} "
        f"{'EKF fin':>8} {'KF rmse':>8} {'closest':>8} {'limits':>6} {'true min':>8} "
        f"{'in min_r':>8} {'breaks':>7}"
    )
    missions = result.missions
    if missions:
        head += f" {'EKF lines':>9} {'mission':>8}"
    lines = [head, "-" * len(head)]
    for name, m in result.metrics.items():
        v = result.validation.get(name)
        r = v.result if v is not None else None
        ekf = r.ekf if r is not None else None
        kf = r.kf if r is not None else None
        truth = r.truth if r is not None else None
        inside = "-" if truth is None else str(truth.runs_inside_min_range)
        breaks = "-" if truth is None else f"{100 * truth.any_violation_fraction:.1f}%"
        lines.append(
            f"{name:<16} {_fmt(m.objective):>10} {_fmt(m.pcrb_mean_pos_std):>9} "
            f"{_fmt(m.pcrb_final_pos_std):>9} "
            f"{_fmt(ekf.rmse_pos if ekf else None):>9} "
            f"{_fmt(ekf.final_pos_err if ekf else None):>8} "
            f"{_fmt(kf.rmse_pos if kf else None):>8} {_fmt(m.closest_approach_m, '.1f'):>8} "
            f"{'ok' if m.within_limits else 'NO':>6} "
            f"{_fmt(truth.closest_range_m if truth else None, '.2f'):>8} {inside:>8} {breaks:>7}"
        )
        if missions:
            lines_rmse = metric_value(v, "ekf.rmse_pos_lines") if v is not None else None
            done = missions[name].complete if name in missions else None
            word = "-" if done is None else ("done" if done else "NOT")
            lines[-1] += f" {_fmt(lines_rmse):>9} {word:>8}"
    if result.validation:
        r0 = next(iter(result.validation.values())).result
        lines.append(
            f"validation: {r0.mode}, {r0.runs} runs per path; 'true min' is the closest approach "
            "of the true paths over all runs, 'breaks' the runs whose true path breaks a limit"
        )
        for name, v in result.validation.items():
            broken = "" if v.result.truth is None else v.result.truth.breaks_words()
            if broken:
                lines.append(f"  {name}: the true path breaks {broken} of the runs")
    return "\n".join(lines)


def write_outputs(result: PlanResult, out: Path, replan: ReplanResult | None = None) -> list[Path]:
    """Write plan.csv (if a path was found), report.json and the figures into ``out``
    (``replan``: its :meth:`~obsplan.planning.replan.ReplanResult.to_dict` under ``replan``).

    With a geodetic problem (an ``[origin]``) report.json carries the origin and
    ``plan-geodetic.csv`` has the plan as time, latitude, longitude[, depth].
    """
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    pb = result.problem
    origin = getattr(pb, "origin", None)
    if result.trajectory is not None:
        written.append(write_csv(result.trajectory, out / "plan.csv"))
        if origin is not None:
            from obsplan.io.waypoints import write_geodetic_samples

            written.append(
                write_geodetic_samples(result.trajectory, origin, out / "plan-geodetic.csv")
            )
    report = out / "report.json"
    doc = result.to_dict()
    if replan is not None:
        doc["replan"] = replan.to_dict()
    if origin is not None:
        doc["origin"] = origin.to_dict()
    report.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    written.append(report)
    paths = result.paths()
    written.append(save_figure(plot_paths(paths, pb), out / FIGURES[0]))
    written.append(save_figure(plot_gramian_eigs(paths, pb), out / FIGURES[1]))
    if result.validation:
        fig = plot_filter_errors(result.validation, problem=pb.name)
        written.append(save_figure(fig, out / FIGURES[2]))
    if pb.mission is not None:
        written.append(save_figure(plot_speed(paths, pb), out / FIGURES[3]))
    return written


def run(args: argparse.Namespace) -> int:
    """Run the verb; 0 on success, 1 if no start converged (outputs are still written)."""
    # validate the problem and the output folder before any work
    pb = _apply_overrides(load_problem(args.problem), args)
    out = OutputDir(args.out, args.force, inputs=[args.problem or DEFAULT_PROBLEM], verb="plan")
    with out:  # Ctrl-C or an error: no output folder, an old one untouched
        result = plan(
            pb,
            validate=not args.no_validate,
            runs=args.runs,
            max_runs=args.max_runs,
            progress=not args.quiet,
            verbose=args.verbose,
        )
        rep = None
        if args.replan is not None and result.trajectory is not None:
            rep = replan_monte_carlo(
                pb,
                result.trajectory,
                args.replan,
                baselines={k: b.trajectory for k, b in result.baselines.items()},
                runs=args.runs,
                processes=None,
                progress=not args.quiet,
            )
        staged = write_outputs(result, out.stage(), rep)
        written = [out.final(p) for p in staged]
        out.commit()  # DIR replaced whole: no stale file of an earlier run survives
    s = result.solve
    converged = sum(st.success for st in s.starts)
    print(
        f"{pb.name or 'problem'}: {pb.objective.kind}, N = {pb.horizon.steps}: {s.status} "
        f"({converged} of {len(s.starts)} starts converged; plan from {s.chosen}), "
        f"{s.wall_s:.1f} s solve, {result.wall_s:.1f} s total"
    )
    if s.note:
        print(f"note: {s.note}")
    for st in s.starts:
        if not st.success and st.note:
            print(f"start {st.label}: {st.note}")
    k = result.keepout
    if k is not None and k.k > 0:
        print(
            f"keep-out at {k.confidence:.4g} confidence: margins up to "
            f"{k.max_range_margin_m:.2f} m "
            f"(range), {k.max_box_margin_m:.2f} m (area/depth), up to {k.max_accel_reserve:.0%} "
            f"of the acceleration kept for the guidance; {k.rounds} re-solve(s), "
            + ("held" + (f" ({k.note})" if k.note else "") if k.held else f"NOT held: {k.note}")
        )
    print(summary_table(result))
    for line in result.verdict.summary():
        print(line)
    if result.robustness is not None:
        r = result.robustness
        print(f"robustness (prior x{r.prior:g}, range noise x{r.range_noise:g}, not replanned):")
        for line in r.verdict.summary():
            print(f"  {line}")
    if rep is not None:
        for line in rep.summary():
            print(line)
    print(f"wrote {', '.join(str(p) for p in written)}")
    if not result.success:
        print(
            "obsplan plan: failed: no start converged"
            + (" (the best feasible iterate was written)" if result.trajectory is not None else ""),
            file=sys.stderr,
        )
        return 1
    return 0
