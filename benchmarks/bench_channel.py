"""The product's filters through the acoustic channel: ideal against at-sea, on the shipped
problems.

Run (a few minutes per problem on one core):

    MPLBACKEND=Agg python benchmarks/bench_channel.py [FILE ...] [--runs 100] [--json out.json]

Without files: every problem of ``problems/*.toml`` with a fixed beacon (a planned beacon's
path is planned and validated by ``plan_moving_beacon``, not compared here). For each problem
the script plans as ``obsplan plan`` does (validation off), then flies the plan and the
lawn-mower over the same ``--runs`` closed-loop runs (one batch, the problem's seed: every
channel sees the same noise, initial errors and, in the at-sea channel, the same lost and late
pings) with

* ``ideal``: Gaussian ranges (today's validation; no gate);
* ``at-sea``: the preset (10 % multipath +2...30 m, 20 % lost pings, 1 % sound-speed scale),
  the filters gated at 0.999 with re-acquisition (the EKF and Gaussian sum one-sided, with the
  late-arrival-aware update inside the gate, :mod:`obsplan.estimation.channel`) and the EKF and
  Gaussian sum with a range-scale state (the defaults);
* ``at-sea, no gate``: the same ranges, ``validation.gate = "off"``;
* ``at-sea, no scale state``: the same ranges, ``validation.scale_state = "off"``;
* ``at-sea, no scale error``: the preset without its sound-speed error (gated): what the
  outliers and lost pings alone cost;
* ``at-sea, no outliers`` and ``at-sea, no lost pings``: the preset without its multipath or
  without its lost pings, and ``ideal, scale state``: Gaussian ranges to filters with the
  range-scale state, what the state alone costs; ``at-sea, 2 ms clock offset`` (a 3 m range
  bias the preset does not have: the filters' range-bias state on, ``validation.bias_state =
  "auto"``) and the same without the bias state (``--channels`` picks these; they are not in
  the default set).

Per path and channel it prints the EKF's position RMSE and mean final error, the lost runs of
the EKF, the KF and the Gaussian sum (final error over 10x the path's posterior-CRB final std,
:data:`obsplan.estimation.channel.LOST_FACTOR`), the EKF's ranges used and rejected per run,
its time-averaged NEES of ``(p, p')`` (dof ``2n``) with the fraction of record times whose
run-averaged NEES is inside the 95 % band, and the EKF RMSE's ratio to the ideal channel's.
``--kf`` adds a table of the augmented KF: its errors, its own final std against the bound (a
KF whose std is near ten bounds "loses" runs by chance while consistent), its NEES and lost
runs.
The aim it checks: in the at-sea preset the gated EKF's RMSE within 1.5x the ideal's, and no
more lost runs than with the ideal channel.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.validation.validate import validate_paths  # noqa: E402

#: The channels compared: label -> the [validation] changes.
CHANNELS = {
    "ideal": {},
    "at-sea": {"channel": "at-sea"},
    "at-sea, no gate": {"channel": "at-sea", "gate": "off"},
    "at-sea, no scale state": {"channel": "at-sea", "scale_state": "off"},
    "at-sea, no scale error": {"channel": "at-sea", "channel_sound_speed_scale": 0.0},
    "at-sea, no outliers": {"channel": "at-sea", "channel_outlier_fraction": 0.0},
    "at-sea, no lost pings": {"channel": "at-sea", "channel_dropout": 0.0},
    "ideal, scale state": {"scale_state": "on"},
    "at-sea, 2 ms clock offset": {"channel": "at-sea", "channel_clock_offset": 0.002},
    "at-sea, 2 ms clock offset, no bias state": {
        "channel": "at-sea",
        "channel_clock_offset": 0.002,
        "bias_state": "off",
    },
}
#: Channels run only when ``--channels`` names them (diagnostics of one component's cost, and
#: the clock offset the preset does not have).
OPTIONAL = (
    "at-sea, no outliers",
    "at-sea, no lost pings",
    "ideal, scale state",
    "at-sea, 2 ms clock offset",
    "at-sea, 2 ms clock offset, no bias state",
)
#: The acceptance's bound on the at-sea EKF RMSE relative to the ideal's.
RMSE_RATIO = 1.5
FILTERS = ("ekf", "kf", "gsf")
#: The augmented KF's numbers of ``--kf``'s table.
KF_KEYS = ("rmse_pos", "final_pos_err", "final_pos_std", "nees_mean", "nees_inside_fraction")


def _rows(path: Path, runs: int, channels: list[str]) -> list[dict]:
    pb = load_problem(path)
    res = plan(pb, validate=False)
    paths = {"planned": res.trajectory}
    if "lawnmower" in res.baselines:
        paths["lawnmower"] = res.baselines["lawnmower"].trajectory
    out = []
    ideal: dict[str, float] = {}
    for label in channels:
        change = CHANNELS[label]
        pbc = pb.with_changes(validation=change) if change else pb
        vals = validate_paths(paths, pbc, runs=runs, filters=FILTERS)
        for name, v in vals.items():
            r = v.result
            d = {f: r.filter_dict(f) for f in FILTERS}
            ekf = d["ekf"]
            if label == "ideal":
                ideal[name] = ekf["rmse_pos"]
            out.append(
                {
                    "problem": path.stem,
                    "path": name,
                    "channel": label,
                    "ekf_rmse": ekf["rmse_pos"],
                    "ekf_final": ekf["final_pos_err"],
                    "lost": {f: d[f]["lost_runs"] for f in FILTERS},
                    "used": ekf["ranges_used"],
                    "rejected": ekf["ranges_rejected"],
                    "nees": ekf["nees_mean"],
                    "nees_inside": ekf["nees_inside_fraction"],
                    "ratio": ekf["rmse_pos"] / ideal[name],
                    "bound": r.crlb_final_pos_std,
                    "kf": {k: d["kf"][k] for k in KF_KEYS},
                }
            )
    return out


def _fmt(rows: list[dict], runs: int) -> str:
    head = (
        "| problem | path | channel | EKF RMSE [m] | EKF final [m] | lost EKF/KF/GSF "
        f"(of {runs}) | ranges used/run | rejected/run | EKF NEES (in band) | RMSE / ideal |"
    )
    lines = [head, "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lost = "/".join(str(r["lost"][f]) for f in FILTERS)
        lines.append(
            f"| {r['problem']} | {r['path']} | {r['channel']} | {r['ekf_rmse']:.3f} | "
            f"{r['ekf_final']:.3f} | {lost} | {r['used']:.1f} | {r['rejected']:.1f} | "
            f"{r['nees']:.3g} ({r['nees_inside']:.2f}) | {r['ratio']:.2f} |"
        )
    return "\n".join(lines)


def _fmt_kf(rows: list[dict], runs: int) -> str:
    """The augmented KF per path and channel: its errors, its own final std and both against
    the bound (a run is lost beyond 10 bounds), its NEES and lost runs."""
    lines = [
        "| problem | path | channel | KF RMSE [m] | KF final [m] | KF final std [m] | "
        f"bound final [m] | KF std / bound | KF NEES (in band) | KF lost (of {runs}) |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        k = r["kf"]
        lines.append(
            f"| {r['problem']} | {r['path']} | {r['channel']} | {k['rmse_pos']:.3f} | "
            f"{k['final_pos_err']:.3f} | {k['final_pos_std']:.3f} | {r['bound']:.3f} | "
            f"{k['final_pos_std'] / r['bound']:.1f} | {k['nees_mean']:.3g} "
            f"({k['nees_inside_fraction']:.2f}) | {r['lost']['kf']} |"
        )
    return "\n".join(lines)


def _acceptance(rows: list[dict]) -> list[str]:
    """The at-sea (gated) rows that miss an acceptance point, in words."""
    ideal = {(r["problem"], r["path"]): r for r in rows if r["channel"] == "ideal"}
    misses = []
    for r in rows:
        if r["channel"] != "at-sea":
            continue
        base = ideal[(r["problem"], r["path"])]
        if r["ratio"] > RMSE_RATIO:
            misses.append(
                f"{r['problem']} {r['path']}: EKF RMSE {r['ratio']:.2f}x the ideal's "
                f"(> {RMSE_RATIO})"
            )
        for f in FILTERS:
            if r["lost"][f] > base["lost"][f]:
                misses.append(
                    f"{r['problem']} {r['path']}: {f} lost {r['lost'][f]} runs "
                    f"(ideal {base['lost'][f]})"
                )
    return misses


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--kf", action="store_true", help="also the augmented KF's table")
    ap.add_argument(
        "--channels",
        nargs="+",
        choices=list(CHANNELS),
        default=[c for c in CHANNELS if c not in OPTIONAL],
        help="the channels compared (default all; 'ideal' is always run first)",
    )
    args = ap.parse_args()
    channels = ["ideal"] + [c for c in args.channels if c != "ideal"]
    files = args.files or [
        f
        for f in sorted((ROOT / "problems").glob("*.toml"))
        if not load_problem(f).beacon_motion.moving
    ]
    rows: list[dict] = []
    t0 = time.perf_counter()
    for f in files:
        rows += _rows(f, args.runs, channels)
        print(f"{f.stem}: done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    print(_fmt(rows, args.runs))
    if args.kf:
        print()
        print(_fmt_kf(rows, args.runs))
    misses = _acceptance(rows)
    print()
    print("acceptance (at-sea, gated): " + ("met" if not misses else "missed:"))
    for m in misses:
        print(f"- {m}")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
