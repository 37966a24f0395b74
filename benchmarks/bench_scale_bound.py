"""What an unknown range scale costs any estimator: the posterior CRB with the scale as a state.

Run (a minute per problem):

    python benchmarks/bench_scale_bound.py [FILE ...]

Without files: every problem of ``problems/*.toml`` with a fixed beacon. For each the script
plans as ``obsplan plan`` does (validation off) and, on the plan and the lawn-mower, runs the
posterior CRB of the validation (:func:`obsplan.estimation.bounds.crlb.posterior_crlb`'s
recursion, the problem's prior, process noise, rates and noises) twice: as the product reports
it, and with a constant range scale ``k`` added to the state (prior ``N(1, σ_s²)``, σ_s
:data:`~obsplan.estimation.channel.SCALE_PRIOR_STD`, the filters' scale state's prior; the range
row ``k |p - b|`` at ``k = 1``: its scale entry ``|p - b|``, written in the half-squared form of
:func:`~obsplan.estimation.bounds.crlb.range_information` as ``|p - b|²``). It prints the bound's
time-averaged position std and its final std, each with its ratio to the bound without the
scale; and the time-averaged bound at sea: with the scale, each range kept with probability
``(1 - dropout)(1 - outliers)`` of the at-sea preset (its lost pings, and its late arrivals as
if the estimator knew which they are: a bound no gate can beat). Time-averaged as the Monte
Carlo's ``rmse_pos`` is: the mean over the samples of the per-time value (``--rms``: the root
mean square over the samples instead, which weighs the early, large stds far more and is not
the RMSE's functional). ``--scale-prior``: another prior std of the scale than the filters'.

No estimator that learns the scale from the same ranges can beat the second bound, so its ratio
to the first is the least an RMSE can grow by when the filters carry the scale state
(``docs/validation.md``, "What the scale state costs", compares it with the EKF's).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.estimation.bounds.crlb import (  # noqa: E402
    pcrb_model_of,
    posterior_crlb,
    range_information,
)
from obsplan.estimation.bounds.riccati import make_epochs, run_recursion  # noqa: E402
from obsplan.estimation.channel import CHANNEL_PRESETS, SCALE_PRIOR_STD  # noqa: E402
from obsplan.estimation.epochs import epoch_beacons, nominal_states  # noqa: E402
from obsplan.estimation.schedule import make_schedule, sample_rate  # noqa: E402
from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.problem.validation_setup import estimation_config  # noqa: E402
from obsplan.trajectory.sampled import resample  # noqa: E402


def _pad(a: np.ndarray, rows: int = 1, cols: int = 1) -> np.ndarray:
    return np.pad(np.asarray(a, float), ((0, rows), (0, cols)))


def bound_std(traj, config, scale_std: float | None, kept: float = 1.0) -> np.ndarray:
    """The posterior CRB's position std [m] at every sample of ``traj`` (with a scale state of
    prior std ``scale_std``; None: without one), each range kept with probability ``kept``
    (the expected information of a range present at random: ``kept`` times its own, exact for
    a loss independent of the state)."""
    model = config.model
    dt = 1.0 / sample_rate(traj)
    p0 = config.covariances(dt)["p0_ekf"]
    schedule = make_schedule(traj, model.sensors, config.rates_hz)
    epochs = make_epochs(traj.t, schedule.mask)
    rec = pcrb_model_of(config, dt)
    xs = nominal_states(traj, model, config.current_array)
    n, m = model.dim, rec.m
    t_ep = traj.t[epochs.index]
    rel = (
        xs[epochs.index, :n] - epoch_beacons(model, config.beacon_path, t_ep, xs[epochs.index, :n])
    ).T
    h, rho = range_information(rel, config.noise["range"])
    rho = rho / kept
    if scale_std is not None:
        rec = replace(
            rec,
            A=_pad(rec.A),
            q=_pad(rec.q),
            q1=_pad(rec.q1),
            q2=_pad(rec.q2),
            nav=_pad(rec.nav, rows=0),
            rows=_pad(rec.rows, rows=0),
            range_support=(*rec.range_support, m),
        )
        h = np.vstack([h, np.sum(rel**2, axis=0, keepdims=True)])  # ∂(½ k² r²)/∂k at k = 1
        p0 = _pad(p0)
        p0[m, m] = scale_std**2
    _, D = run_recursion(rec, epochs, p0, h, rho)
    var = np.maximum(epochs.sample_values(np.asarray(D)), 0.0)
    return np.sqrt(var[:n].sum(axis=0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument(
        "--rms", action="store_true", help="root mean square over time instead of the mean"
    )
    ap.add_argument(
        "--scale-prior",
        type=float,
        default=SCALE_PRIOR_STD,
        help=f"the scale's prior std (default {SCALE_PRIOR_STD:g}, the filters')",
    )
    args = ap.parse_args()
    files = args.files or [
        f
        for f in sorted((ROOT / "problems").glob("*.toml"))
        if not load_problem(f).beacon_motion.moving
    ]
    sea = CHANNEL_PRESETS["at-sea"]
    kept = (1.0 - sea.dropout) * (1.0 - sea.outlier_fraction)
    average = "RMS" if args.rms else "mean"
    print(
        f"| problem | path | bound {average} [m] | with the scale | ratio | at sea, with the "
        "scale | ratio | bound final [m] | with the scale | ratio |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for f in files:
        pb = load_problem(f)
        res = plan(pb, validate=False)
        paths = {"planned": res.trajectory}
        if "lawnmower" in res.baselines:
            paths["lawnmower"] = res.baselines["lawnmower"].trajectory
        config = estimation_config(pb)
        for name, traj in paths.items():
            fine = resample(traj, pb.validation.dt)
            a, b = bound_std(fine, config, None), bound_std(fine, config, args.scale_prior)
            # the recursion without the scale is the product's bound, to round-off
            np.testing.assert_allclose(a, posterior_crlb(fine, config).pos_std_t, rtol=1e-9)
            c = bound_std(fine, config, args.scale_prior, kept)
            if args.rms:
                rms_a, rms_b, rms_c = (float(np.sqrt(np.mean(x**2))) for x in (a, b, c))
            else:
                rms_a, rms_b, rms_c = (float(np.mean(x)) for x in (a, b, c))
            print(
                f"| {f.stem} | {name} | {rms_a:.3f} | {rms_b:.3f} | {rms_b / rms_a:.2f}x | "
                f"{rms_c:.3f} | {rms_c / rms_a:.2f}x | "
                f"{a[-1]:.3f} | {b[-1]:.3f} | {b[-1] / a[-1]:.2f}x |",
                flush=True,
            )


if __name__ == "__main__":
    main()
