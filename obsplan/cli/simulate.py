"""``obsplan simulate TRAJ.csv``: EKF and augmented KF Monte Carlo along a trajectory CSV."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from obsplan.cli.common import (
    add_output_arguments,
    add_vehicle_arguments,
    output_dir,
    parse_beacon,
    read_trajectory,
)
from obsplan.errors import InputError
from obsplan.estimation.config import EstimationConfig
from obsplan.estimation.schedule import sample_rate
from obsplan.estimation.simulate import MonteCarloResult, monte_carlo
from obsplan.model import make_model


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``simulate`` verb."""
    p = subparsers.add_parser(
        "simulate",
        help="Monte Carlo of the EKF and the augmented KF along a trajectory CSV",
        description=(
            "Simulate noisy truths along a trajectory CSV and run the EKF (nonlinear model) and "
            "the KF (augmented linear model, eqs. 19-24) with the paper's R, Q and P0 (section 7) "
            "at the trajectory's sample rate; report errors, standard deviations, NEES and the "
            "posterior Cramer-Rao bound."
        ),
    )
    p.add_argument("trajectory", metavar="TRAJ.csv", help="trajectory CSV file")
    add_vehicle_arguments(p)
    p.add_argument(
        "--rates",
        metavar="S=HZ,...",
        default="",
        help="report rate per sensor [Hz], e.g. range=0.1 (default: every sample)",
    )
    p.add_argument(
        "--noise",
        metavar="S=SIGMA,...",
        default="",
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
    p.add_argument("--runs", type=int, default=50, help="Monte Carlo runs (default 50)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--init-error",
        metavar="sample|E1,E2,...",
        default="sample",
        help="initial estimate error x0_hat - x0 of (p [m], v [m/s][, v_f [m/s]]), or "
        "'sample' to draw it from P0 (default)",
    )
    p.add_argument("--no-process-noise", action="store_true", help="truth without process noise")
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
    for name in ("ekf", "kf"):
        s = getattr(res, name)
        if s is None:
            continue
        conv = "never" if s.convergence_time is None else f"{s.convergence_time:.1f} s"
        lines.append(
            f"{name.upper():8s} {s.final_pos_err:9.3f}m {s.final_pos_std:9.3f}m "
            f"{s.rmse_pos:8.3f}m {s.nees_mean:7.2f} {conv:>11s} {100 * s.converged_fraction:8.0f}%"
        )
    lo, hi = (res.ekf or res.kf).nees_bounds
    lines.append(
        f"CRB final position std {res.crlb_final_pos_std:.3f} m; consistent NEES in "
        f"[{lo:.2f}, {hi:.2f}] (95 %, dof {2 * cfg.model.dim}); "
        f"convergence: error below {cfg.convergence_threshold_m:g} m"
    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Execute ``obsplan simulate``."""
    traj = read_trajectory(args.trajectory, "simulate")
    if args.dt is not None:
        from obsplan.validation import resample

        if not args.dt > 0:
            raise InputError(f"--dt {args.dt:g}: the filter step must be > 0 s")
        traj = resample(traj, args.dt, name="--dt")
    out = output_dir(args.out, args.force) if args.out else None
    if args.runs < 1:
        raise InputError(f"--runs {args.runs}: needs at least 1 run")
    model = make_model(
        traj.dim,
        args.sensors,
        current=args.current,
        beacon=parse_beacon(args.beacon, traj.dim),
    )
    cfg = EstimationConfig.paper(
        model,
        1.0 / sample_rate(traj),
        rates_hz=parse_pairs(args.rates, "--rates"),
        noise=parse_pairs(args.noise, "--noise"),
        init_error=_init_error(args.init_error),
        process_noise=not args.no_process_noise,
    )
    res = monte_carlo(
        traj, cfg, runs=args.runs, seed=args.seed, progress=not (args.quiet or args.json)
    )
    if args.json:
        print(json.dumps(res.to_dict(), indent=2))
    else:
        print(format_result(res, args.trajectory))
    if out is not None:
        from obsplan import plots
        from obsplan.estimation.crlb import sampled_rank_over_time
        from obsplan.observability.gramian import augmented_model

        ranks = sampled_rank_over_time(traj, cfg)
        idx = np.searchsorted(traj.t, res.t)
        full = augmented_model(model).state_dim
        fig = plots.scenario_figure(traj, res, res.t, ranks[idx], full, title=args.trajectory)
        written = [plots.save(fig, out / "estimation.png")]
        written.append(plots.save(plots.plot_monte_carlo(res), out / "monte_carlo.png"))
        if not args.json:
            print("figures: " + ", ".join(str(p) for p in written))
    diverged = [n for n in ("ekf", "kf") if getattr(res, n) and getattr(res, n).diverged_runs]
    if diverged:
        print(
            f"obsplan simulate: failed: {', '.join(diverged)} diverged (non-finite estimates)",
            file=sys.stderr,
        )
        return 1
    return 0
