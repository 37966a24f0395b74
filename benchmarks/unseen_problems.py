"""Seeded random problems of the suite's kinds, for checking the planner on problems it was not
tuned on.

Run:

    python benchmarks/unseen_problems.py --seed 36 --out /tmp/unseen
    MPLBACKEND=Agg python benchmarks/bench_planning_suite.py /tmp/unseen/*.toml

For each geometry (2D range-only, 2D with 0.2 Hz ranges, 2D with an unknown current and a
water-profiling DVL, 3D with a depth gauge, 3D with a bottom-lock DVL, 3D range-only) and each
observability objective (``gramian-min-eig``, ``gramian-log-det``, ``lwo-condition``, or the
kinds given with ``--kinds``), a problem is drawn with probability ``--keep``: the beacon
anywhere within 40 m of the origin (3D: 30-60 m deep), the start 50-110 m from it in a random
direction (3D: 3-15 m deep), a square area 20-50 m beyond both, a horizon of 480, 600 or 900 s
at one node per 3 s, ranges at 0.5 or 1 Hz (0.2 Hz for the slow geometry) with 0.1 or 0.2 m
noise. Every file is read back with the planner's loader; one it rejects (e.g. ``lwo-condition``
on 3D range-only, whose LWO matrix is rank deficient) is not written, and its error is printed.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.core.errors import ProblemError  # noqa: E402
from obsplan.planning import load_problem  # noqa: E402

GEOMETRIES = ("2d-range", "2d-range-slow", "2d-current", "3d-depth", "3d-dvl", "3d-range")
KINDS = ("gramian-min-eig", "gramian-log-det", "lwo-condition")


def _vec(x) -> str:
    return "[" + ", ".join(f"{float(v):.1f}" for v in np.atleast_1d(x)) + "]"


def _vehicle_lines(geometry: str) -> list[str]:
    """``[vehicle]``'s dimension and sensors for ``geometry`` (the current is drawn by the
    caller)."""
    dim = 3 if geometry.startswith("3d") else 2
    sensors = ["range"] + {"2d-current": ["dvl-water"], "3d-depth": ["depth"]}.get(geometry, [])
    if geometry == "3d-dvl":
        sensors.append("dvl-bottom")
    return [f"dim = {dim}", "sensors = [" + ", ".join(f'"{s}"' for s in sensors) + "]"]


def _toml(
    name: str,
    geometry: str,
    kind: str,
    vehicle: list[str],
    beacon: np.ndarray,
    start: np.ndarray,
    velocity: np.ndarray,
    limits: list[str],
    horizon: tuple[float, int],
    range_lines: list[str],
) -> str:
    """The problem file: the sections in order, the validation's sensor lines from
    ``geometry``."""
    validation = ["runs = 50", "dt = 0.1", *range_lines]
    if geometry == "3d-depth":
        validation += ["depth_rate = 1.0", "depth_std = 0.05"]
    if geometry in ("2d-current", "3d-dvl"):
        validation += ["dvl_rate = 5.0", f"dvl_std = {0.001 if geometry == '2d-current' else 0.01}"]
    sections = {
        "problem": [f'name = "{name}: {geometry}, {kind}"'],
        "vehicle": vehicle,
        "beacon": [f"position = {_vec(beacon)}"],
        "start": [f"position = {_vec(start)}", f"velocity = {_vec(velocity)}"],
        "limits": limits,
        "horizon": [f"duration = {horizon[0]}", f"steps = {horizon[1]}"],
        "objective": [f'kind = "{kind}"', "starts = 3"],
        "validation": validation,
    }
    return "\n".join(f"[{k}]\n" + "\n".join(v) + "\n" for k, v in sections.items())


def problem_text(
    rng: np.random.Generator, geometry: str, kind: str, edge_start: bool = False
) -> str:
    """One problem file (TOML) of ``geometry`` and ``kind``, drawn from ``rng``; with
    ``edge_start`` the start 1-5 m inside the area's edge (3D: 0.5-3 m below the depth band's
    top), as a survey from a corner or a vehicle at the surface."""
    dim = 3 if geometry.startswith("3d") else 2
    ang = rng.uniform(0.0, 2.0 * np.pi)
    dist = rng.uniform(50.0, 110.0)
    beacon = rng.uniform(-40.0, 40.0, 2)
    start = beacon + dist * np.array([np.cos(ang), np.sin(ang)])
    half = float(np.max(np.abs(np.r_[beacon, start])) + rng.uniform(20.0, 50.0))
    duration = float(rng.choice([480.0, 600.0, 900.0]))
    if edge_start:  # drawn last: without the flag a seed writes the problems it always did
        i = int(np.argmax(np.abs(start)))  # the area keeps the beacon 10 m inside its edge
        start[i] = np.sign(start[i]) * max(abs(start[i]), float(np.max(np.abs(beacon))) + 10.0)
        half = float(np.max(np.abs(start))) + rng.uniform(1.0, 5.0)
    vehicle = _vehicle_lines(geometry)
    if geometry == "2d-current":
        current = rng.uniform(-0.12, 0.12, 2).round(3).tolist()
        vehicle += ["current = true", f"current_velocity = {current}"]
    limits = ["accel = 0.05", "speed = 1.0"]
    if dim == 3:
        bz, sz = rng.uniform(30.0, 60.0), rng.uniform(3.0, 15.0)
        if edge_start:
            sz = 2.0 + rng.uniform(0.5, 3.0)
        beacon, start = np.r_[beacon, bz], np.r_[start, sz]
        limits = ["accel = [0.05, 0.05, 0.02]", "speed = 1.0", f"depth = [2.0, {bz - 10.0:.1f}]"]
    limits.append(f"area = {{ x = [{-half:.1f}, {half:.1f}], y = [{-half:.1f}, {half:.1f}] }}")
    rate = 0.2 if geometry == "2d-range-slow" else float(rng.choice([0.5, 1.0]))
    ranges = [f"range_rate = {rate}", f"range_std = {float(rng.choice([0.1, 0.2]))}"]
    horizon = (duration, int(duration / 3.0))
    return _toml(
        "unseen", geometry, kind, vehicle, beacon, start, np.zeros(dim), limits, horizon, ranges
    )


def wide_problem_text(rng: np.random.Generator, geometry: str, kind: str) -> str:
    """One problem file (TOML) of ``geometry`` and ``kind`` from a wider family than
    :func:`problem_text`'s: other vehicles (acceleration 0.02-0.2 m/s², speed 0.5-2 m/s), the
    beacon within 60 m of the origin and the start 30-300 m from it (far starts), a rectangular
    area 15-80 m beyond both on each axis, a moving start on half the problems (0.1-0.6 of the
    speed bound, in a random direction), horizons of 300-1200 s (at most 300 nodes), ranges at
    0.2-1 Hz (0.1-0.2 Hz for the slow geometry) with 0.05-0.5 m noise, a current up to 0.2 m/s,
    3D beacons 20-100 m deep."""
    dim = 3 if geometry.startswith("3d") else 2
    accel = float(rng.uniform(0.02, 0.2))
    speed = float(rng.uniform(0.5, 2.0))
    beacon = rng.uniform(-60.0, 60.0, 2)
    ang = rng.uniform(0.0, 2.0 * np.pi)
    start = beacon + rng.uniform(30.0, 300.0) * np.array([np.cos(ang), np.sin(ang)])
    half = np.maximum(np.abs(beacon), np.abs(start)) + rng.uniform(15.0, 80.0, 2)
    v0 = np.zeros(dim)
    if rng.random() < 0.5:
        head = rng.uniform(0.0, 2.0 * np.pi)
        v0[:2] = rng.uniform(0.1, 0.6) * speed * np.array([np.cos(head), np.sin(head)])
    duration = float(rng.choice([300.0, 600.0, 900.0, 1200.0]))
    steps = min(int(duration / 3.0), 300)
    vehicle = _vehicle_lines(geometry)
    if geometry == "2d-current":
        c = rng.uniform(0.02, 0.2) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        vehicle += ["current = true", f"current_velocity = {c.round(3).tolist()}"]
    limits = [f"accel = {accel:.3f}", f"speed = {speed:.2f}"]
    if dim == 3:
        bz, sz = rng.uniform(20.0, 100.0), rng.uniform(3.0, 15.0)
        beacon, start = np.r_[beacon, bz], np.r_[start, sz]
        za = accel * rng.uniform(0.3, 0.6)
        limits = [f"accel = [{accel:.3f}, {accel:.3f}, {za:.3f}]", f"speed = {speed:.2f}"]
        limits.append(f"depth = [2.0, {bz - 10.0:.1f}]")
    limits.append(
        f"area = {{ x = [{-half[0]:.1f}, {half[0]:.1f}], y = [{-half[1]:.1f}, {half[1]:.1f}] }}"
    )
    slow = geometry == "2d-range-slow"
    rate = float(rng.choice([0.1, 0.2] if slow else [0.2, 0.5, 1.0]))
    ranges = [f"range_rate = {rate}", f"range_std = {float(rng.choice([0.05, 0.1, 0.2, 0.5]))}"]
    return _toml(
        "unseen (wide)",
        geometry,
        kind,
        vehicle,
        beacon,
        start,
        v0,
        limits,
        (duration, steps),
        ranges,
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=36)
    ap.add_argument("--out", type=Path, required=True, help="folder to write the problems to")
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), help="objective kinds")
    ap.add_argument("--keep", type=float, default=0.55, help="chance of each geometry x kind")
    ap.add_argument(
        "--edge-start",
        action="store_true",
        help="start 1-5 m inside the area's edge (3D: 0.5-3 m below the depth band's top)",
    )
    ap.add_argument(
        "--wide",
        action="store_true",
        help="draw from a wider family: other vehicles, far and moving starts, rectangular "
        "areas, other horizons, rates and noises (wide_problem_text)",
    )
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    n = 0
    for geometry in GEOMETRIES:
        for kind in args.kinds:
            if rng.random() >= args.keep:
                continue
            if args.wide:
                text = wide_problem_text(rng, geometry, kind)
            else:
                text = problem_text(rng, geometry, kind, args.edge_start)
            path = args.out / f"{n + 1:02d}-{geometry}-{kind}.toml"
            if path.exists():
                print(f"{path} exists: not replaced", file=sys.stderr)
                continue
            path.write_text(text)
            try:
                load_problem(path)
            except ProblemError as e:
                path.unlink()  # this script wrote it a moment ago
                print(f"skipped {geometry}, {kind}: {e}", file=sys.stderr)
                continue
            n += 1
            print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
