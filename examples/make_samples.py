"""Write the sample inputs the README's examples use (deterministic: run it again, same bytes).

* ``examples/log.csv`` — a logged track, positions only (``t,px,py``), 1 Hz for 300 s of a
  lawn-mower leg pattern with 5 cm position noise: what ``obsplan analyze log.csv`` fits on the
  fly and ``obsplan import`` turns into a trajectory CSV;
* ``examples/dive.tlog`` — the same survey, 3D at 4 m depth (5 cm noise on every axis), as a
  MAVLink telemetry log of ``LOCAL_POSITION_NED`` messages (needs ``pymavlink``:
  ``pip install 'obsplan[mavlink]'``);
* ``examples/geodetic.toml`` — the default problem with the beacon and the start given in
  latitude and longitude about an ``[origin]`` (a smaller horizon grid and Monte Carlo, so that
  the README's example runs in seconds);
* ``examples/mission-log.csv`` — a logged mission for ``obsplan estimate``: a 4-leg lawn-mower
  (200 m legs 40 m apart at 1 m/s, from (50, -100) m) flown with white-acceleration process
  noise, bottom-track DVL velocities every 2 s, ranges to the beacon at the origin every 10-30 s
  with 10 % multipath outliers and 10 % dropouts, and the true positions (``px,py``) for scoring.

    python examples/make_samples.py [--out FOLDER]
"""

from __future__ import annotations

import argparse
import struct
from pathlib import Path

import numpy as np

from obsplan.core.csvtable import write_table
from obsplan.estimation.replay.simulate import simulate_log
from obsplan.io.missionlog import write_mission_log
from obsplan.model.frames import GeodeticOrigin, local_to_geodetic
from obsplan.trajectory import generators

HERE = Path(__file__).resolve().parent
#: Origin of the geodetic sample: off Livorno, Italy (WGS84 degrees).
ORIGIN = GeodeticOrigin(43.5, 10.2)
#: Position noise of the logged samples [m] and their rate [Hz].
NOISE_M = 0.05
RATE_HZ = 1.0
#: Seconds of the sample survey.
DURATION_S = 300.0
#: MAVLink time stamp of the log's first record [µs since 1970].
T0_US = 1_700_000_000_000_000


def survey() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times [s], true positions (N, 2) [m] and velocities (N, 2) [m/s] of the sample survey."""
    traj = generators.lawnmower((-80.0, 60.0), 80.0, 20.0, 3, 0.5).sample(1.0 / RATE_HZ)
    keep = traj.t <= DURATION_S + 1e-9
    return traj.t[keep], traj.p[keep], traj.v[keep]


def write_log_csv(out: Path) -> Path:
    """``log.csv``: ``t,px,py`` with seeded 5 cm noise."""
    t, p, _ = survey()
    noisy = p + np.random.default_rng(0).normal(0.0, NOISE_M, p.shape)
    return write_table(out / "log.csv", ["t", "px", "py"], np.column_stack([t, noisy]))


def write_tlog(out: Path) -> Path:
    """``dive.tlog``: LOCAL_POSITION_NED records (8-byte big-endian µs stamp, then the packet)."""
    from pymavlink.dialects.v20 import ardupilotmega as mav2

    t, p, v = survey()
    rng = np.random.default_rng(1)
    noisy = np.column_stack([p, np.full(t.size, 4.0)]) + rng.normal(0.0, NOISE_M, (t.size, 3))
    link = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
    path = out / "dive.tlog"
    with open(path, "wb") as fh:
        for k, tk in enumerate(t):
            ms = int(round(tk * 1000))
            msg = mav2.MAVLink_local_position_ned_message(
                ms, *(float(x) for x in noisy[k]), float(v[k, 0]), float(v[k, 1]), 0.0
            )
            fh.write(struct.pack(">Q", T0_US + ms * 1000))
            fh.write(msg.pack(link))
    return path


def write_geodetic_problem(out: Path) -> Path:
    """``geodetic.toml``: the default problem's beacon (0, 0) and start (-80, 60) m, geodetic."""
    lat, lon, _ = (
        [float(x) for x in a]
        for a in local_to_geodetic(np.array([[0.0, 0.0], [-80.0, 60.0]]), ORIGIN)
    )
    text = f"""\
# The default problem (problems/default.toml) with the beacon and the start in latitude and
# longitude about an origin: the local frame is north-east-down about [origin] (docs/geodetic.md).
# Written by examples/make_samples.py. A coarser grid and a smaller Monte Carlo than the default
# (100 steps, 2 starts, 20 runs) keep the README's example to seconds.

[problem]
name = "geodetic: 2D range-only off Livorno"

[vehicle]
dim = 2
sensors = ["range"]

[origin]
latitude = {ORIGIN.latitude!r}         # deg (WGS84)
longitude = {ORIGIN.longitude!r}        # deg

[beacon]
geodetic = [{lat[0]!r}, {lon[0]!r}]          # deg, deg: (0, 0) m

[start]
geodetic = [{lat[1]!r}, {lon[1]!r}]   # deg, deg: (-80, 60) m
velocity = [0.0, 0.0]          # m/s, from rest

[limits]
accel = 0.05                   # m/s^2 per axis
speed = 1.0                    # m/s
area = {{ x = [-110.0, 110.0], y = [-110.0, 110.0] }}   # m, in the local frame

[horizon]
duration = 600.0               # s
steps = 100                    # 6 s per constant-acceleration interval

[objective]
kind = "pcrb-position"
starts = 2

[validation]
runs = 20
dt = 0.1                       # s, filter step (divides the 6 s steps)
"""
    path = out / "geodetic.toml"
    path.write_text(text, encoding="utf-8")
    return path


def write_mission_log_csv(out: Path) -> Path:
    """``mission-log.csv``: a simulated DVL log with multipath and dropouts (seeded)."""
    traj = generators.lawnmower((50.0, -100.0), 200.0, 40.0, 4, 1.0).sample(2.0)
    sim = simulate_log(
        traj, inputs=False, dvl="bottom", accel_std=0.001, outlier_fraction=0.1, dropout=0.1,
        seed=47,
    )  # fmt: skip
    return write_mission_log(sim.log, out / "mission-log.csv")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE, help="folder to write into (default: here)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for write in (write_log_csv, write_tlog, write_geodetic_problem, write_mission_log_csv):
        print(f"wrote {write(args.out)}")


if __name__ == "__main__":
    main()
