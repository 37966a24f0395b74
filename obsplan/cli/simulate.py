"""``obsplan simulate TRAJ.csv``: EKF and augmented KF Monte Carlo along a trajectory CSV.

In closed loop by default, as ``obsplan plan`` validates: the simulated vehicle steers its
estimate onto the trajectory (:class:`~obsplan.estimation.montecarlo.guidance.Guidance`;
``--navigation`` the filter it steers on, the Gaussian sum by default, whose statistics are always
reported); ``--open-loop`` flies its accelerations blind. Process noise is the physical white
acceleration noise (``--accel-noise``, m/s²/√Hz) unless ``--paper-noise`` selects the paper's
per-step ``Q``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from typing import Any

import numpy as np

from obsplan.cli.common import (
    Applies,
    OutputDir,
    add_beacon_path_argument,
    add_channel_argument,
    add_output_arguments,
    add_vehicle_arguments,
    channel_error,
    check_applies,
    check_seed,
    given_fact,
    read_trajectory,
    resolve_beacon,
    resolve_beacon_path,
)
from obsplan.core import budget
from obsplan.core.errors import ConfigError, InputError, ProblemError
from obsplan.estimation.channel import Channel, channel_preset
from obsplan.estimation.config import DEFAULT_ACCEL_NOISE, EstimationConfig
from obsplan.estimation.montecarlo.guidance import NAVIGATION_FILTERS, Guidance, TruthLimits
from obsplan.estimation.montecarlo.simulate import (
    DEFAULT_FILTERS,
    FILTERS,
    MonteCarloResult,
    monte_carlo,
)
from obsplan.estimation.schedule import read_ping_times, sample_rate
from obsplan.model.vehicle import make_model

#: Options that apply only to some runs (:func:`obsplan.cli.common.check_applies`).
APPLIES = (Applies("--navigation", "the closed loop (the filter it steers on)", "closed"),)
#: Acceleration bound [m/s²] of the guidance without a problem (the default problem's), raised to
#: the trajectory's largest input so that its own feed-forward never saturates.
DEFAULT_GUIDANCE_ACCEL = 0.05
#: Options that a problem file's [vehicle], [beacon] and [validation] sections replace.
PROBLEM_REPLACES = {
    "sensors": "vehicle.sensors",
    "current": "vehicle.current",
    "beacon": "beacon.position",
    "beacon_geodetic": "beacon.geodetic",
    "beacon_path": "[beacon]",
    "origin": "[origin]",
    "rates": "validation.*_rate",
    "range_times": "validation.range_times",
    "noise": "validation.*_std",
    "dt": "validation.dt",
    "init_error": "validation.init_pos_error / init_vel_error",
    "no_process_noise": "the validation's process noise",
    "accel_noise": "validation.accel_noise",
    "paper_noise": "validation.process_noise_model",
    "accel": "limits.accel",
    "speed": "limits.speed",
    "filters": "the validation's filters (EKF and KF)",
}


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``simulate`` verb.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The sub-parsers of the ``obsplan`` parser (:func:`obsplan.cli.build_parser`).

    Returns
    -------
    argparse.ArgumentParser
        The parser of ``obsplan simulate``: ``TRAJ.csv``, the vehicle options
        (:func:`~obsplan.cli.common.add_vehicle_arguments`), ``--beacon-path``, ``--rates``,
        ``--noise``, ``--dt``, ``--problem``, ``--runs``, ``--seed``, ``--filters``,
        ``--init-error``, ``--no-process-noise``, ``--open-loop``, ``--navigation``,
        ``--accel-noise``, ``--paper-noise``, ``--accel``, ``--speed``, ``--json``, ``--out``,
        ``--force`` and ``--quiet``.
    """
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
    add_beacon_path_argument(p)
    p.add_argument(
        "--rates",
        metavar="S=HZ,...",
        default=None,
        help="report rate per sensor [Hz], e.g. range=0.1 (default: every sample)",
    )
    p.add_argument(
        "--range-times",
        metavar="PINGS.csv",
        default=None,
        help="a ping schedule (e.g. a log's range times): a CSV with a column t [s, on the "
        "trajectory's clock]; the ranges report at the first sample at or after each ping "
        "instead of at --rates' range rate",
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
    p.add_argument(
        "--open-loop",
        action="store_true",
        help="fly the trajectory's accelerations blind (default: closed loop, the vehicle "
        "steers its estimate onto the trajectory)",
    )
    p.add_argument(
        "--navigation",
        choices=NAVIGATION_FILTERS,
        default=None,
        help="closed loop: the filter the vehicle steers on (default gsf, the Gaussian sum, or "
        "validation.navigation with --problem)",
    )
    p.add_argument(
        "--accel-noise",
        metavar="A",
        type=float,
        default=None,
        help="white acceleration noise intensity [m/s^2/sqrt(Hz)] of the truth and the filters "
        f"(default {DEFAULT_ACCEL_NOISE:.3g}, the paper's per-step Q at a 0.1 s step)",
    )
    p.add_argument(
        "--paper-noise",
        action="store_true",
        default=None,
        help="the paper's per-step process noise Q = diag(1e-3 dt)^2 (its intensity changes "
        "with the step) instead of --accel-noise",
    )
    p.add_argument(
        "--accel",
        metavar="A",
        type=float,
        default=None,
        help="closed loop: the vehicle's acceleration bound per axis [m/s^2] (default "
        f"{DEFAULT_GUIDANCE_ACCEL:g}, or the trajectory's largest input if larger)",
    )
    p.add_argument(
        "--speed",
        metavar="V",
        type=float,
        default=None,
        help="closed loop: the vehicle's speed bound [m/s] (default none)",
    )
    add_channel_argument(p)
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    add_output_arguments(p, "figures", None)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def parse_pairs(text: str, option: str) -> dict[str, float]:
    """``"range=0.1,dvl=100"`` -> ``{"range": 0.1, "dvl": 100.0}``.

    Parameters
    ----------
    text : str
        ``SENSOR=NUMBER`` pairs separated by commas (empty items are skipped; ``""``: none).
    option : str
        The option, for the message (``"--rates"``).

    Returns
    -------
    dict of str to float
        Sensor -> number, in the option's unit (a rate [Hz], a noise std [m] or [m/s]).

    Raises
    ------
    InputError
        An item without ``=`` or whose value is not a number.
    """
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


def check_filter_grid(traj, dt: float | None, runs: int) -> None:
    """Refuse, before allocating anything, a filter grid or Monte Carlo beyond the limits of
    :mod:`obsplan.core.budget` (samples per run, runs, memory and time).

    Parameters
    ----------
    traj : Trajectory
        The trajectory to simulate along.
    dt : float or None
        The filter step [s] (``--dt`` or ``validation.dt``); None: the trajectory's own
        samples.
    runs : int
        The Monte Carlo runs.

    Raises
    ------
    InputError
        A ``dt`` that is not a positive number, more samples per run than
        :data:`obsplan.core.budget.MAX_SAMPLES`, or a Monte Carlo beyond the memory or time
        budget.
    """
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise InputError(f"--dt {dt:g}: the filter step must be a positive number of seconds")
    samples = traj.n_samples if dt is None else traj.duration / dt + 1
    field = f"--dt {dt:g} s" if dt is not None else f"the {traj.n_samples} trajectory samples"
    fix = (
        f"choose --dt >= {traj.duration / (budget.MAX_SAMPLES - 1):.3g} s"
        if dt is not None
        else "resample the trajectory more coarsely (--dt)"
    )
    budget.check_samples(samples, field, fix)
    budget.check_monte_carlo(runs, samples, traj.dim, "--runs", "a coarser --dt")


def _problem_mode(args: argparse.Namespace, traj):
    from dataclasses import replace

    from obsplan.planning.problem.parse import load_problem

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
    if args.open_loop:
        pb = replace(pb, validation=replace(pb.validation, mode="open-loop"))
    if args.navigation is not None:
        pb = replace(pb, validation=replace(pb.validation, navigation=args.navigation))
    if args.channel is not None:
        try:
            pb = pb.with_changes(validation={"channel": args.channel})
        except ProblemError as exc:
            raise channel_error(exc) from None
    return pb


def _guidance(args: argparse.Namespace, traj) -> tuple[Guidance | None, TruthLimits | None]:
    """Without a problem: the guidance law and the limits the true paths are checked against
    (``--accel``, ``--speed``; open loop: no guidance, the limits given)."""
    for opt in ("accel", "speed"):
        x = getattr(args, opt)
        if x is not None and not (np.isfinite(x) and x > 0):
            raise InputError(f"--{opt} {x:g}: must be a positive bound")
    if args.accel_noise is not None:
        if not (np.isfinite(args.accel_noise) and args.accel_noise >= 0):
            raise InputError(f"--accel-noise {args.accel_noise:g}: must be an intensity >= 0")
        if args.paper_noise:
            raise InputError(
                "--accel-noise and --paper-noise are two settings of the same process noise; "
                "give one"
            )
    accel = args.accel
    if accel is None:
        largest = float(np.max(np.abs(traj.u))) if traj.u.size else 0.0
        accel = max(DEFAULT_GUIDANCE_ACCEL, largest)
    limits = TruthLimits(accel=accel, speed=args.speed)
    if args.open_loop:
        return None, limits
    nav = args.navigation or "gsf"
    return Guidance.from_limits(accel, args.speed, error_scale_m=1.0, navigation=nav), limits


def _filters(args: argparse.Namespace) -> tuple[str, ...]:
    """``--filters`` (default: the EKF and the augmented KF)."""
    if args.filters is None:
        return DEFAULT_FILTERS
    return tuple(s.strip() for s in args.filters.split(",") if s.strip())


def _check_beacon_clear(args: argparse.Namespace, traj, pb, beacon, path=None) -> None:
    """Refuse a beacon at the trajectory's start: the geometry every plan refuses
    (:func:`obsplan.planning.problem.checks.check_start_clear`, at the problem's
    ``limits.min_range``, or the default one without a problem)."""
    from obsplan.planning.problem.checks import check_start_clear

    if pb is not None:
        where = f"beacon.position of --problem {args.problem}"
        check_start_clear(traj.p[0], pb.beacon, pb.limits.min_range, where=where, fix=_CLEAR)
        return
    if path is not None:
        where = f"--beacon-path {args.beacon_path} (at the trajectory's start)"
        check_start_clear(traj.p[0], path.position(traj.t[0])[0], where=where, fix=_CLEAR)
        return
    if args.beacon is not None:
        where = f"--beacon {args.beacon}"
    elif args.beacon_geodetic is not None:
        where = f"--beacon-geodetic {args.beacon_geodetic}"
    else:
        where = "the beacon (at the origin: no --beacon given)"
    check_start_clear(traj.p[0], beacon or np.zeros(traj.dim), where=where, fix=_CLEAR)


_CLEAR = (
    "so close the range says nothing of the bearing and an EKF linearised there diverges: "
    "place the beacon at least that far from the trajectory's first sample, as every plan does"
)


def run(args: argparse.Namespace) -> int:
    """Execute ``obsplan simulate``; 0, or 1 if a filter diverged.

    Prints the Monte Carlo's summary (JSON with ``--json``) and, with ``--out``, writes the
    figures.

    Parameters
    ----------
    args : argparse.Namespace
        The arguments parsed by the parser of :func:`add_parser`.

    Returns
    -------
    int
        0; 1 when a filter diverged (non-finite estimates) in any run.

    Raises
    ------
    InputError
        A bad seed, ``--runs``, trajectory, beacon (or one at the trajectory's start), beacon
        path (malformed, of another dimension, not covering the trajectory, or given with
        ``--beacon``), filter
        grid or option value, an option that does not apply (:data:`APPLIES`) or that
        ``--problem`` replaces (:data:`PROBLEM_REPLACES`), a problem of another dimension, or
        an ``--out`` folder that cannot be written or replaced (exit 2).
    """
    check_seed(args.seed)
    if args.runs is not None and args.runs < 1:
        raise InputError(f"--runs {args.runs}: needs at least 1 run")
    if args.runs is not None:
        budget.check_runs(args.runs, "--runs")  # before reading the trajectory
    closed = not args.open_loop
    check_applies(args, APPLIES, {"closed": given_fact(closed, "--open-loop flies blind")})
    traj = read_trajectory(args.trajectory, "simulate")
    pb = _problem_mode(args, traj) if args.problem else None
    beacon = None if pb is not None else resolve_beacon(args, traj.dim)[0]
    path = (
        None
        if pb is not None
        else resolve_beacon_path(args, traj.dim, beacon, float(traj.t[0]), float(traj.t[-1]))
    )
    _check_beacon_clear(args, traj, pb, beacon, path)
    runs = args.runs if args.runs is not None else (pb.validation.runs if pb else 50)
    check_filter_grid(traj, pb.validation.dt if pb else args.dt, runs)
    # the output folder is checked before the (long) simulation, written only at the end
    out = (
        OutputDir(args.out, args.force, inputs=[args.trajectory, args.problem], verb="simulate")
        if args.out is not None
        else None
    )
    with out or contextlib.nullcontext():
        if pb is not None:
            from obsplan.planning.validation.validate import validate_paths

            val = validate_paths(
                {"trajectory": traj},
                pb,
                runs=runs,
                progress=_progress(args),
                filters=_filters(args),
            )
            res = val["trajectory"].result
            from obsplan.trajectory.sampled import resample

            fine = resample(traj, pb.validation.dt)
        else:
            fine = traj
            if args.dt is not None:
                from obsplan.trajectory.sampled import resample

                fine = resample(traj, args.dt, name="--dt")
            model = make_model(
                traj.dim, args.sensors or "range", current=bool(args.current), beacon=beacon
            )
            guidance, limits = _guidance(args, fine)
            common: dict[str, Any] = {
                "rates_hz": parse_pairs(args.rates or "", "--rates"),
                "noise": parse_pairs(args.noise or "", "--noise"),
                "init_error": _init_error(args.init_error or "sample"),
                "process_noise": not args.no_process_noise,
                "beacon_path": path,
                "channel": _channel(args.channel),
                "range_times": (
                    None
                    if args.range_times is None
                    else read_ping_times(args.range_times, f"--range-times {args.range_times}")
                ),
            }
            if args.paper_noise:
                cfg = EstimationConfig.paper(model, 1.0 / sample_rate(fine), **common)
            else:
                cfg = EstimationConfig(model=model, accel_noise=args.accel_noise, **common)
            res = monte_carlo(
                fine,
                cfg,
                runs=runs,
                seed=args.seed or 0,
                progress=_progress(args),
                filters=_filters(args),
                guidance=guidance,
                limits=limits,
            )
        if args.json:
            out_json = res.to_dict()
            if pb is not None:
                out_json["problem"] = pb.name or str(args.problem)
            print(json.dumps(out_json, indent=2))
        else:
            print(res.summary(args.trajectory))
        if out is not None:
            written = _write_figures(out, res, fine, pb, args)
            if not args.json:
                print("figures: " + ", ".join(str(p) for p in written))
    diverged = [n for n, s in res.filter_stats().items() if s.diverged_runs]
    if diverged:
        print(
            f"obsplan simulate: failed: {', '.join(diverged)} diverged (non-finite estimates)",
            file=sys.stderr,
        )
        return 1
    return 0


def _channel(name: str | None) -> Channel:
    """The ``--channel`` preset (ideal when not given)."""
    try:
        return channel_preset(name or "ideal")
    except ConfigError as exc:
        raise channel_error(exc) from None


def _progress(args: argparse.Namespace) -> bool:
    return not (args.quiet or args.json)


def _write_figures(out: OutputDir, res: MonteCarloResult, fine, pb, args) -> list:
    """estimation.png, monte_carlo.png (and with a problem, plan's filters.png), atomically."""
    from obsplan.estimation.bounds.crlb import sampled_rank_over_time
    from obsplan.estimation.montecarlo import plots
    from obsplan.observability.gramian import augmented_model
    from obsplan.trajectory.relative import relative_samples

    staging = out.stage()
    written = []
    cfg = res.config
    if pb is not None:
        from obsplan.planning.figures import plot_filter_errors
        from obsplan.planning.validation.validate import PathValidation

        # the figure `obsplan plan` writes as filters.png, for this one path
        fig = plot_filter_errors({"trajectory": PathValidation("trajectory", res)}, problem=pb.name)
        written.append(plots.save(fig, staging / "filters.png"))
    # a moving beacon: the rank of the motion relative to it (docs/guides/observability.md)
    rel = fine if cfg.beacon_path is None else relative_samples(fine, cfg.beacon_path)
    ranks = sampled_rank_over_time(rel, cfg)
    idx = np.searchsorted(fine.t, res.t)
    full = augmented_model(cfg.model).state_dim
    fig = plots.scenario_figure(fine, res, res.t, ranks[idx], full, title=args.trajectory)
    written.append(plots.save(fig, staging / "estimation.png"))
    written.append(plots.save(plots.plot_monte_carlo(res), staging / "monte_carlo.png"))
    out.commit()
    return [out.path / p.name for p in written]
