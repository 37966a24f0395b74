"""``obsplan plan [PROBLEM.toml] [--out DIR]``: plan a path, compare with baselines, validate."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from obsplan.cli.common import OutputDir, add_channel_argument, channel_error
from obsplan.core import budget
from obsplan.core.errors import InputError, ProblemError
from obsplan.planning.beacon import plan_beacon
from obsplan.planning.plan import (
    check_beacon_plannable,
    check_beacon_replan,
    plan,
    plan_moving_beacon,
)
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.parse import DEFAULT_PROBLEM, load_problem
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.replan import replan_nodes

DEFAULT_OUT = "obsplan-plan"


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``plan`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan plan``: ``PROBLEM.toml`` (optional), ``--out``, ``--force``,
        ``--runs``, ``--max-runs``, ``--steps``, ``--starts``, ``--no-validate``, ``--replan``,
        ``--quiet`` and ``--verbose``.
    """
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
        "planning step) each run re-solves from its estimate; with a planned beacon and "
        "vehicle.path the beacon's craft re-plans instead (report.json key 'replan')",
    )
    add_channel_argument(p)
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--verbose", action="store_true", help="show IPOPT's output")
    return p


def _apply_overrides(pb: PlanningProblem, args: argparse.Namespace) -> PlanningProblem:
    """The command-line overrides, checked against the same limits as the problem file's."""
    if args.runs is not None and args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.max_runs is not None and args.max_runs < 1:
        raise InputError(f"--max-runs must be at least 1, got {args.max_runs}")
    if args.max_runs is not None:
        budget.check_runs(args.max_runs, "--max-runs")
    if args.steps is not None:
        pb = replace(pb, horizon=Horizon(duration=pb.horizon.duration, steps=args.steps))
    if args.starts is not None:
        budget.check_starts(args.starts, "--starts")
        pb = replace(pb, objective=replace(pb.objective, starts=args.starts))
    if args.max_runs is not None:
        budget.check_max_runs(args.max_runs, "--max-runs")
    samples = pb.horizon.duration / pb.validation.dt + 1
    if args.runs is not None and not args.no_validate:
        budget.check_monte_carlo(args.runs, samples, pb.dim, "--runs", "a longer validation.dt")
    if args.max_runs is not None and not args.no_validate:
        fix = "a longer validation.dt"
        budget.check_monte_carlo(args.max_runs, samples, pb.dim, "--max-runs", fix)
    if args.channel is not None:
        try:
            pb = pb.with_changes(validation={"channel": args.channel})
        except ProblemError as exc:
            raise channel_error(exc) from None
    if args.replan is not None:
        if args.no_validate:
            raise InputError("--replan runs inside the validation: drop --no-validate")
        if pb.beacon_motion.motion != "planned":  # a planned beacon: its craft's step
            replan_nodes(pb, args.replan)  # a bad EVERY is an input error before any work
    return pb


def run(args: argparse.Namespace) -> int:
    """Run the verb; 0 when the flown path converged (``solver.success``), else 1 (outputs are
    still written).

    Plans (:func:`obsplan.planning.plan.plan`), writes ``plan.csv``, ``report.json`` and the
    figures into ``--out`` (replaced whole) and prints the summary.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0 when a start converged; 1 when none did (the best feasible iterate, if any, is
        written).

    Raises
    ------
    InputError
        A problem that does not load, an override out of its limits (``--runs``,
        ``--max-runs``, ``--starts``, ``--replan``), ``--replan`` with ``--no-validate``, or an
        ``--out`` folder that cannot be written or replaced (exit 2).
    """
    # validate the problem and the output folder before any work
    pb = _apply_overrides(load_problem(args.problem), args)
    if pb.beacon_motion.motion == "planned":
        return _run_moving_beacon(pb, args)
    check_beacon_plannable(pb)  # a known beacon path: what is not built is refused before output
    out = OutputDir(args.out, args.force, inputs=[args.problem or DEFAULT_PROBLEM], verb="plan")
    with out:  # Ctrl-C or an error: no output folder, an old one untouched
        result = plan(
            pb,
            validate=not args.no_validate,
            runs=args.runs,
            max_runs=args.max_runs,
            progress=not args.quiet,
            verbose=args.verbose,
            replan=args.replan,
        )
        staged = result.write_files(out.stage())
        written = [out.final(p) for p in staged]
        out.commit()  # DIR replaced whole: no stale file of an earlier run survives
    print(result.summary())
    print(f"wrote {', '.join(str(p) for p in written)}")
    if not result.success:
        print(
            f"obsplan plan: failed: the flown path is not a converged solution "
            f"(solver.status {result.solve.status})"
            + (" (the best feasible path was written)" if result.trajectory is not None else ""),
            file=sys.stderr,
        )
        return 1
    return 0


def _run_moving_beacon(pb: PlanningProblem, args: argparse.Namespace) -> int:
    """``obsplan plan`` of a beacon planned for a vehicle on a given path, or jointly with the
    vehicle (:func:`~obsplan.planning.plan.plan_moving_beacon`): ``plan.csv`` (the vehicle's
    path), ``beacon.csv``, ``report.json`` and the figures; 0 when the planners converged."""
    check_beacon_plannable(pb)  # what is not built yet is refused before any output
    if args.replan is not None:
        check_beacon_replan(pb, args.replan)  # joint planning or a bad EVERY: before any output
    out = OutputDir(args.out, args.force, inputs=[args.problem or DEFAULT_PROBLEM], verb="plan")
    with out:
        result = plan_moving_beacon(
            pb,
            plan_beacon,
            validate=not args.no_validate,
            runs=args.runs,
            max_runs=args.max_runs,
            progress=not args.quiet,
            replan=args.replan,
            processes=None,
        )
        written = [out.final(p) for p in result.write_files(out.stage())]
        out.commit()
    print(result.summary())
    print(f"wrote {', '.join(str(p) for p in written)}")
    if not result.success:
        v = None if result.joint is None else result.joint.vehicle_solve
        which = (
            f"the vehicle's plan did not converge (solver.joint.vehicle.status {v.status})"
            if v is not None and not v.success
            else f"the beacon's plan did not converge (solver.status {result.solve.status})"
        )
        print(f"obsplan plan: failed: {which}; the best paths were written", file=sys.stderr)
        return 1
    return 0
