"""Plans for the channel: planning on the expected information of the pings that arrive against
planning for the ideal channel, both flown in the channel.

Run (minutes per problem on one core):

    MPLBACKEND=Agg python benchmarks/bench_channel_plan.py [FILE ...] [--runs 200] [--json out.json]

Without files: ``problems/localise.toml``, ``lowrate-range.toml``, ``range3d.toml`` and
``default.toml``. For each problem the script plans as ``obsplan plan`` does (validation off)
for the ideal channel, then for each channel below with that channel in ``[validation]`` (the
objective then divides every range's variance by the probability that its ping arrives,
:meth:`obsplan.estimation.channel.Channel.expected_variance`), and flies both plans and the
lawn-mower through the channel over the same ``--runs`` closed-loop runs (one batch, the
problem's seed: the same noise, initial errors, lost and late pings on every path):

* ``at-sea``: the preset (20 % of pings lost at any range, 10 % late, 1 % scale);
* ``at-sea, loss grows``: the preset with the loss growing beyond ``D`` (to every ping lost at
  ``2D``), ``D`` half the farthest range of the ideal plan's path to the beacon: the link
  degrades over the outer half of the ranges that plan flies.

Per problem and channel it prints the EKF's and the KF's position RMSE and mean final error of
the three paths, the EKF's ranges used per run, and the channel plan's ratios to the ideal
plan's (below 1: planning for the channel paid).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.plan import plan  # noqa: E402
from obsplan.planning.validation.validate import validate_paths  # noqa: E402
from obsplan.trajectory.sampled import Trajectory  # noqa: E402

DEFAULT = ("localise", "lowrate-range", "range3d", "default")
FILTERS = ("ekf", "kf")


def _half_range(tr: Trajectory, beacon) -> float:
    p = tr.p
    return 0.5 * float(np.max(np.linalg.norm(p - np.asarray(beacon, float), axis=1)))


def _rows(path: Path, runs: int) -> list[dict]:
    pb = load_problem(path)
    t0 = time.perf_counter()
    ideal = plan(pb, validate=False)
    D = _half_range(ideal.trajectory, pb.beacon)
    channels = {
        "at-sea": {"channel": "at-sea"},
        f"at-sea, loss grows beyond {D:.0f} m": {
            "channel": "at-sea",
            "channel_dropout_range": round(D, 1),
        },
    }
    out = []
    for label, change in channels.items():
        pbc = pb.with_changes(validation=change)
        planned = plan(pbc, validate=False)
        paths = {"ideal plan": ideal.trajectory, "channel plan": planned.trajectory}
        if "lawnmower" in ideal.baselines:
            paths["lawnmower"] = ideal.baselines["lawnmower"].trajectory
        vals = validate_paths(paths, pbc, runs=runs, filters=FILTERS)
        row: dict = {"problem": path.stem, "channel": label, "converged": planned.success}
        for name, v in vals.items():
            d = {f: v.result.filter_dict(f) for f in FILTERS}
            row[name] = {
                "ekf_rmse": d["ekf"]["rmse_pos"],
                "ekf_final": d["ekf"]["final_pos_err"],
                "kf_rmse": d["kf"]["rmse_pos"],
                "kf_final": d["kf"]["final_pos_err"],
                "used": d["ekf"]["ranges_used"],
            }
        out.append(row)
    print(f"{path.stem}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return out


def _fmt(rows: list[dict]) -> str:
    keys = ("ekf_rmse", "ekf_final", "kf_rmse", "kf_final")
    lines = [
        "| problem | channel | path | EKF RMSE [m] | EKF final [m] | KF RMSE [m] | KF final [m] "
        "| ranges used/run |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        for name in ("ideal plan", "channel plan", "lawnmower"):
            if name not in r:
                continue
            v = r[name]
            cells = " | ".join(f"{v[k]:.3f}" for k in keys)
            lines.append(
                f"| {r['problem']} | {r['channel']} | {name} | {cells} | {v['used']:.1f} |"
            )
        a, b = r["channel plan"], r["ideal plan"]
        ratios = " | ".join(f"{a[k] / b[k]:.2f}x" for k in keys)
        lines.append(f"| {r['problem']} | {r['channel']} | channel / ideal plan | {ratios} | |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    files = args.files or [ROOT / "problems" / f"{n}.toml" for n in DEFAULT]
    rows: list[dict] = []
    for f in files:
        rows += _rows(f, args.runs)
    print(_fmt(rows))
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
