"""``obsplan simulate TRAJ.csv``: EKF and augmented KF Monte Carlo along a trajectory CSV."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys

import numpy as np

from obsplan.cli.common import (
    OutputDir,
    add_output_arguments,
    add_vehicle_arguments,
    check_seed,
    read_trajectory,
    resolve_beacon,
)
from obsplan.errors import InputError
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.schedule import sample_rate
from obsplan.estimation.simulate import DEFAULT_FILTERS, FILTERS, MonteCarloResult, monte_carlo
from obsplan.model import make_model
from obsplan.plots import filter_stats

#: Largest filter grid a simulation accepts (samples per run): the filters loop over samples.
MAX_FILTER_SAMPLES = 2_000_000
#: Options that a problem file's [vehicle], [beacon] and [validation] sections replace.
PROBLEM_REPLACES = {
    "sensors": "vehicle.sensors",
    "current": "vehicle.current",
    "beacon": "beacon.position",
    "beacon_geodetic": "beacon.geodetic",
    "rates": "validation.*_rate",
    "noise": "validation.*_std",
    "dt": "validation.dt",
    "init_error": "validation.init_pos_error / init_vel_error",
    "no_process_noise": "the validation's process noise",
    "filters": "the validation's filters (EKF and KF)",
}


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``simulate`` verb."""
    p = subparsers.add_parser(
        "simulate",
        help="Monte Carlo of the EKF and the augmented KF along a trajectory CSV",
        description=(
            "Simulate noisy truths along a trajectory CSV and run the EKF (nonlinear model) and "
            "the KF (augmented linear model, eqs. 19-24) with the paper's R, Q and P0 (section 7) "
            "at the trajectory's sample rate; report errors, standard deviations, NEES and the "
            "posterior Cramer-Rao bound. With --problem P.toml the problem's [validation] "
            "settings are used instead (exactly what `obsplan plan` runs). A position-only "
            "track (t,px,py[,pz]) is fitted on the fly (see obsplan import)."
        ),
    )
    p.add_argument("trajectory", metavar="TRAJ.csv", help="trajectory CSV file")
    add_vehicle_arguments(p)
    p.add_argument(
        "--rates",
        metavar="S=HZ,...",
        default=None,
        help="report rate per sensor [Hz], e.g. range=0.1 (default: every sample)",
    )
    p.add_argument(
        "--noise",
        metavar="S=SIGMA,...",
        default=None,
        help="noise std per sensor: range [m], dvl [m/s], depth [m] (default: the paper's)",
    )
    p.add_argument(
        "--dt",
        metavar="S",
        type=float,
        default=None,
        help="filter step [s]: resample the CSV's piecewise-constant inputs onto this grid (it "
        "must divide every interval; e.g. 0.1 for a plan.csv of 3 s steps); default: the CSV's "
        "own samples",
    )
    p.add_argument(
        "--problem",
        metavar="P.toml",
        default=None,
        help="use this problem's vehicle, beacon and [validation] settings (rates, noises, "
        "prior, filter step, runs, seed), as `obsplan plan` validates its plan",
    )
    p.add_argument(
        "--runs",
        type=int,
        default=None,
        help="Monte Carlo runs (default 50, or validation.runs with --problem)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="random seed, >= 0 (default 0, or validation.seed with --problem)",
    )
    p.add_argument(
        "--filters",
        metavar="NAME,...",
        default=None,
        help=f"filters to run, from {','.join(FILTERS)} (default: {','.join(DEFAULT_FILTERS)})",
    )
    p.add_argument(
        "--init-error",
        metavar="sample|E1,E2,...",
        default=None,
        help="initial estimate error x0_hat - x0 of (p [m], v [m/s][, v_f [m/s]]), or "
        "'sample' to draw it from P0 (default)",
    )
    p.add_argument(
        "--no-process-noise",
        action="store_true",
        default=None,
        help="truth without process noise",
    )
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    add_output_arguments(p, "figures", None)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def parse_pairs(text: str, option: str) -> dict[str, float]:
    """``"range=0.1,dvl=100"`` -> ``{"range": 0.1, "dvl": 100.0}``."""
    out: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, val = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(val)
        except ValueError:
            raise InputError(
                f"{option} {text!r}: expected SENSOR=NUMBER pairs separated by commas, "
                f"e.g. {option} range=0.1"
            ) from None
    return out


def _init_error(text: str) -> str | np.ndarray:
    if text.strip().lower() == "sample":
        return "sample"
    try:
        return np.array([float(s) for s in text.split(",")])
    except ValueError:
        raise InputError(
            f"--init-error {text!r}: expected 'sample' or numbers separated by commas"
        ) from None


def format_result(res: MonteCarloResult, path: str) -> str:
    """Human-readable table of a Monte Carlo result."""
    cfg = res.config
    lines = [
        f"{path}: {res.runs} runs, seed {res.seed}, {res.t[-1] - res.t[0]:.1f} s, "
        f"sensors {','.join(cfg.model.sensors)}",
        f"{'filter':8s} {'final err':>10s} {'final std':>10s} {'RMSE':>9s} {'NEES':>7s} "
        f"{'conv. time':>11s} {'converged':>9s}",
    ]
    for name, s in filter_stats(res).items():
        conv = "never" if s.convergence_time is None else f"{s.convergence_time:.1f} s"
        lines.append(
            f"{name.upper():8s} {s.final_pos_err:9.3f}m {s.final_pos_std:9.3f}m "
            f"{s.rmse_pos:8.3f}m {s.nees_mean:7.2f} {conv:>11s} {100 * s.converged_fraction:8.0f}%"
        )
    lo, hi = next(iter(filter_stats(res).values())).nees_bounds
    lines.append(
        f"CRB final position std {res.crlb_final_pos_std:.3f} m; consistent NEES in "
        f"[{lo:.2f}, {hi:.2f}] (95 %, dof {2 * cfg.model.dim}); "
        f"convergence: error below {cfg.convergence_threshold_m:g} m"
    )
    return "\n".join(lines)


def check_filter_grid(traj, dt: float | None, runs: int) -> None:
    """Refuse, before allocating anything, a filter grid or Monte Carlo beyond the limits.

    The limits: :data:`MAX_FILTER_SAMPLES` samples per run and the validation budget
    ``runs x samples x 3n <= MAX_MC_SIZE`` of :mod:`obsplan.planning.problem`.
    """
    from obsplan.planning.schema import MAX_MC_SIZE

    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise InputError(f"--dt {dt:g}: the filter step must be a positive number of seconds")
    samples = traj.n_samples if dt is None else traj.duration / dt + 1
    what = f"--dt {dt:g} s" if dt is not None else f"{traj.n_samples} samples of the trajectory"
    if samples > MAX_FILTER_SAMPLES:
        fix = (
            f"choose --dt >= {traj.duration / (MAX_FILTER_SAMPLES - 1):.3g} s"
            if dt is not None
            else "resample the trajectory more coarsely"
        )
        raise InputError(
            f"{what} puts {samples:.4g} samples on the filter grid over {traj.duration:g} s, "
            f"more than the limit of {MAX_FILTER_SAMPLES} samples per run; {fix}"
        )
    size = runs * samples * 3 * traj.dim
    if size > MAX_MC_SIZE:
        raise InputError(
            f"--runs {runs} with {samples:.4g} filter samples per run exceeds the Monte Carlo "
            f"budget (runs x samples x 3n <= {MAX_MC_SIZE:g}); use at most "
            f"{int(MAX_MC_SIZE / (samples * 3 * traj.dim))} runs or a coarser --dt"
        )


def _problem_mode(args: argparse.Namespace, traj):
    from dataclasses import replace

    from obsplan.planning.parse import load_problem

    given = [o for o in PROBLEM_REPLACES if getattr(args, o, None) is not None]
    if given:
        opt = "--" + given[0].replace("_", "-")
        raise InputError(
            f"{opt} cannot be combined with --problem: the problem's {PROBLEM_REPLACES[given[0]]} "
            "is used; edit the problem file or drop --problem"
        )
    pb = load_problem(args.problem)
    if pb.dim != traj.dim:
        raise InputError(
            f"--problem {args.problem} is {pb.dim}D (vehicle.dim) but {args.trajectory} is "
            f"{traj.dim}D"
        )
    if args.seed is not None:
        pb = replace(pb, validation=replace(pb.validation, seed=args.seed))
    return pb


def run(args: argparse.Namespace) -> int:
    """Execute ``obsplan simulate``; 0, or 1 if a filter diverged."""
    check_seed(args.seed)
    if args.runs is not None and args.runs < 1:
        raise InputError(f"--runs {args.runs}: needs at least 1 run")
    traj = read_trajectory(args.trajectory, "simulate")
    pb = _problem_mode(args, traj) if args.problem else None
    runs = args.runs if args.runs is not None else (pb.validation.runs if pb else 50)
    check_filter_grid(traj, pb.validation.dt if pb else args.dt, runs)
    # the output folder is checked before the (long) simulation, written only at the end
    out = (
        OutputDir(args.out, args.force, inputs=[args.trajectory, args.problem])
        if args.out
        else None
    )
    with out or contextlib.nullcontext():
        if pb is not None:
            from obsplan.planning.validation import validate_paths

            val = validate_paths({"trajectory": traj}, pb, runs=runs, progress=_progress(args))
            res = val["trajectory"].result
            from obsplan.trajectory import resample

            fine = resample(traj, pb.validation.dt)
        else:
            fine = traj
            if args.dt is not None:
                from obsplan.trajectory import resample

                fine = resample(traj, args.dt, name="--dt")
            beacon, _ = resolve_beacon(args, traj.dim)
            model = make_model(
                traj.dim, args.sensors or "range", current=bool(args.current), beacon=beacon
            )
            cfg = EstimationConfig.paper(
                model,
                1.0 / sample_rate(fine),
                rates_hz=parse_pairs(args.rates or "", "--rates"),
                noise=parse_pairs(args.noise or "", "--noise"),
                init_error=_init_error(args.init_error or "sample"),
                process_noise=not args.no_process_noise,
            )
            filters = DEFAULT_FILTERS
            if args.filters is not None:
                filters = tuple(s.strip() for s in args.filters.split(",") if s.strip())
            res = monte_carlo(
                fine,
                cfg,
                runs=runs,
                seed=args.seed or 0,
                progress=_progress(args),
                filters=filters,
            )
        if args.json:
            out_json = res.to_dict()
            if pb is not None:
                out_json["problem"] = pb.name or str(args.problem)
            print(json.dumps(out_json, indent=2))
        else:
            print(format_result(res, args.trajectory))
        if out is not None:
            written = _write_figures(out, res, fine, pb, args)
            if not args.json:
                print("figures: " + ", ".join(str(p) for p in written))
    diverged = [n for n, s in filter_stats(res).items() if s.diverged_runs]
    if diverged:
        print(
            f"obsplan simulate: failed: {', '.join(diverged)} diverged (non-finite estimates)",
            file=sys.stderr,
        )
        return 1
    return 0


def _progress(args: argparse.Namespace) -> bool:
    return not (args.quiet or args.json)


def _write_figures(out: OutputDir, res: MonteCarloResult, fine, pb, args) -> list:
    """estimation.png, monte_carlo.png (and with a problem, plan's filters.png), atomically."""
    from obsplan import plots
    from obsplan.estimation.crlb import sampled_rank_over_time
    from obsplan.observability.gramian import augmented_model

    staging = out.stage()
    written = []
    cfg = res.config
    if pb is not None:
        from obsplan.planning.figures import plot_filter_errors
        from obsplan.planning.validation import PathValidation

        # the figure `obsplan plan` writes as filters.png, for this one path
        fig = plot_filter_errors({"trajectory": PathValidation("trajectory", res)}, problem=pb.name)
        written.append(plots.save(fig, staging / "filters.png"))
    ranks = sampled_rank_over_time(fine, cfg)
    idx = np.searchsorted(fine.t, res.t)
    full = augmented_model(cfg.model).state_dim
    fig = plots.scenario_figure(fine, res, res.t, ranks[idx], full, title=args.trajectory)
    written.append(plots.save(fig, staging / "estimation.png"))
    written.append(plots.save(plots.plot_monte_carlo(res), staging / "monte_carlo.png"))
    out.commit()
    return [out.path / p.name for p in written]
