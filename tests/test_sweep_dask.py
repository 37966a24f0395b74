"""Sweeps on real Dask clusters: a LocalCluster of two worker processes, a scheduler and a worker
started as separate processes, Ctrl-C and resume through the command line, a worker killed while
running a task, a lost scheduler, and the sharded Monte Carlo.

No mocks: every test runs real planning tasks (tiny: 12-24 steps, one start, a few Monte Carlo
runs) on real worker processes. Results are compared between runs exactly, except for the
columns that measure time or place (``obsplan.sweeps.comparable``): every solve and every Monte
Carlo run is seeded and each worker runs single-threaded BLAS, so nothing else may differ.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import glob
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from obsplan.cli import main
from obsplan.sweeps import (
    ClusterError,
    comparable,
    expand,
    local_cluster,
    read_table,
    run_task,
    sweep,
    sweep_from_dict,
    worker_threads,
)
from obsplan.sweeps.store import read_report

#: end-to-end: the slow tier (docs/development.md)
pytestmark = pytest.mark.slow


distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
#: Seconds any single wait on a subprocess or a file may take before the test fails (generous:
#: the CI machine has 2 cores shared with other jobs; typical waits are 1-5 s).
WAIT_S = 120.0

BASE = {
    "vehicle": {"dim": 2, "sensors": ["range"]},
    "start": {"position": [-80.0, 60.0]},
    "limits": {"accel": 0.05, "speed": 1.0},
    "horizon": {"duration": 120.0, "steps": 24},
    "objective": {"starts": 1},
    "validation": {"runs": 3, "dt": 1.0},
}
#: Six tasks of several seconds each (a 24-step plan, its keep-out re-solve, a 3-run validation):
#: an interrupt after two finished tasks still finds work in flight; the file's cost is these
#: plans, run about three times over (reference, resume, lost scheduler).
STUDY = {
    "sweep": {"name": "study", "mode": "plan"},
    "base": BASE,
    "axes": {"limits.accel": [0.02, 0.05, 0.08], "beacon.position": [[0.0, 0.0], [50.0, 0.0]]},
    "figures": {"metrics": ["min_eig", "ekf.rmse_pos"]},  # 4 figures, not 14: seconds saved
}


def write_study(folder: Path, study: dict = STUDY) -> Path:
    """``study`` (STUDY by default) as a sweep file (for the command line)."""
    name = study["sweep"]["name"]
    lines = [f'[sweep]\nname = "{name}"\nmode = "{study["sweep"].get("mode", "plan")}"\n']
    for section, values in study["base"].items():
        lines.append(f"[base.{section}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in values.items()]
    lines.append("[axes]")
    lines += [f'"{k}" = {json.dumps(v)}' for k, v in study["axes"].items()]
    if "figures" in study:
        lines.append(f"[figures]\nmetrics = {json.dumps(study['figures']['metrics'])}")
    path = folder / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    with path.open("rb") as fh:
        parsed = tomllib.load(fh)
    assert parsed["axes"] == study["axes"] and parsed["base"] == study["base"]  # the same study
    return path


@pytest.fixture(scope="module")
def client():
    """A LocalCluster of two one-thread worker processes (the sweep's default kind)."""
    cluster = local_cluster(2, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def reference(client, tmp_path_factory):
    """STUDY run once, uninterrupted, on the LocalCluster: (table, folder)."""
    out = tmp_path_factory.mktemp("reference")
    df = sweep(STUDY, out, client=client, progress=False)
    return df, out


def wait_for(predicate, what: str, timeout: float = WAIT_S) -> None:
    t0 = time.monotonic()
    while not predicate():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(0.05)


def reports(out: Path) -> list[str]:
    return sorted(glob.glob(str(out / "tasks" / "*" / "report.json")))


# ------------------------------------------------------------------------------ local cluster
def test_local_cluster_sweep_writes_everything(reference, client):
    df, out = reference
    tasks = expand(sweep_from_dict(STUDY))
    assert len(df) == 6 and df["status"].tolist() == ["done"] * 6
    assert df["task_id"].tolist() == [t.id for t in tasks]
    # the tasks ran on both worker processes, not in this one
    workers = set(df["worker"])
    assert len(workers) == 2 and not any(w.endswith(f":{os.getpid()}") for w in workers)
    for t in tasks:
        folder = out / "tasks" / t.id
        assert (folder / "plan.csv").read_text().startswith("t,px,py,vx,vy,ux,uy")
        assert json.loads((folder / "report.json").read_text())["sweep"]["status"] == "done"
    # the table on disk is the returned one, in both formats
    pd.testing.assert_frame_equal(read_table(out), df, check_dtype=False)
    csv = pd.read_csv(out / "results.csv")
    assert csv["task_id"].tolist() == df["task_id"].tolist()
    assert np.allclose(csv["metrics.planned.min_eig"], df["metrics.planned.min_eig"])
    # one figure per metric of [figures] and axis, planned and lawn-mower side by side
    figures = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert figures == [
        "ekf.rmse_pos_vs_beacon.position.png",
        "ekf.rmse_pos_vs_limits.accel.png",
        "min_eig_vs_beacon.position.png",
        "min_eig_vs_limits.accel.png",
    ]
    # the report's keys became columns by themselves
    assert {"solver.status", "validation.planned.ekf.rmse_pos", "metrics.lawnmower.min_eig"} <= set(
        df.columns
    )


def test_worker_result_equals_an_in_process_run(reference):
    """What came back from a worker process is what this process computes for the same task."""
    df, out = reference
    task = expand(sweep_from_dict(STUDY))[4]
    here = run_task(task)
    there = read_report(out, task.id)
    assert here["status"] == "done"
    for key in ("metrics", "validation"):
        assert here["report"][key] == there[key]
    assert here["report"]["solver"]["objective"] == there["solver"]["objective"]
    assert here["plan_csv"] == (out / "tasks" / task.id / "plan.csv").read_text()


def test_workers_are_single_threaded_processes(client):
    info = client.run(worker_threads)
    assert len(info) == 2 and len({i["pid"] for i in info.values()}) == 2
    assert all(n == 1 for n in client.nthreads().values())
    for i in info.values():
        assert set(i["env"].values()) == {"1"}, i["env"]
        if not sys.platform.startswith("linux"):
            continue  # the loaded libraries are found through /proc/self/maps
        # read back from the loaded OpenBLAS libraries themselves (numpy's, scipy's)
        assert i["openblas_threads"], "no OpenBLAS library found in the worker"
        assert set(i["openblas_threads"].values()) == {1}, i["openblas_threads"]


def test_rerun_skips_finished_tasks(reference, client):
    df, out = reference
    before = {p: os.stat(p).st_mtime_ns for p in reports(out)}
    started = []
    again = sweep(STUDY, out, client=client, progress=False, on_start=started.append)
    assert started[0].finished == 6 and started[0].to_run == 0
    assert {p: os.stat(p).st_mtime_ns for p in reports(out)} == before
    pd.testing.assert_frame_equal(comparable(again), comparable(df))


def test_baselines_mode(client, tmp_path):
    study = {
        "sweep": {"name": "bl", "mode": "baselines", "combine": "zip"},
        "base": BASE,
        "figures": {"metrics": ["min_eig"]},
        # the same 2 s planning step: the circle of 48 s is the first half of the one of 96 s
        "axes": {"horizon.duration": [48.0, 96.0], "horizon.steps": [24, 48]},
    }
    df = sweep(study, tmp_path / "bl", client=client, progress=False)
    assert df["status"].tolist() == ["done", "done"]
    assert not any(c.startswith(("solver.", "metrics.planned")) for c in df.columns)
    assert df["validation.lawnmower.ekf.rmse_pos"].notna().all()
    # the Gramian cannot shrink over a longer horizon of the same path (eq. 25 sums PSD terms)
    le = df["metrics.circle.log_det"].to_numpy(float)
    assert le[1] > le[0]
    assert not list((tmp_path / "bl" / "tasks").glob("*/plan.csv"))
    assert (tmp_path / "bl" / "figures" / "min_eig_vs_horizon.duration.png").is_file()


# ------------------------------------------------------------------------------ a killed worker
def crashing_runner(task, crash_dir: str):
    """run_task, except that the worker process dies while a marker file for the task holds a
    positive count (decremented first, so the marker survives the crash)."""
    marker = Path(crash_dir) / task.id
    if marker.exists():
        left = int(marker.read_text())
        if left > 0:
            marker.write_text(str(left - 1))
            os._exit(17)  # the worker process dies mid-task, as a segfault in IPOPT would
    return run_task(task)


def test_killed_worker_is_retried_then_reported(client, tmp_path):
    # the runner travels by value: the workers need not import this test module
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    crash_dir = tmp_path / "crash"
    crash_dir.mkdir()
    runner = functools.partial(crashing_runner, crash_dir=str(crash_dir))
    study = {**STUDY, "sweep": {"name": "crash"}, "axes": {"limits.speed": [0.8, 0.9, 1.1]}}
    a, b, c = expand(sweep_from_dict(study))
    (crash_dir / a.id).write_text("1")  # dies once: the retry succeeds
    (crash_dir / b.id).write_text("5")  # dies every time: retried once, then failed
    df = sweep(study, tmp_path / "out", client=client, progress=False, runner=runner)
    rows = df.set_index("task_id")
    assert rows.loc[a.id, "status"] == "done" and rows.loc[a.id, "attempts"] == 2
    assert rows.loc[c.id, "status"] == "done" and rows.loc[c.id, "attempts"] == 1
    assert rows.loc[b.id, "status"] == "failed" and rows.loc[b.id, "attempts"] == 2
    assert "worker process died" in rows.loc[b.id, "error"]
    assert "KilledWorker" in rows.loc[b.id, "error"]
    assert (crash_dir / b.id).read_text() == "3"  # exactly two attempts died
    # one failed task among done ones changes no column's type, in memory, in the table the
    # command line rewrites from the stored reports, and in parquet
    sweep_file = write_study(tmp_path, study)
    argv = ["sweep", str(sweep_file), "--out", str(tmp_path / "out"), "--quiet", "--no-figures"]
    assert main(argv) == 1  # nothing left to run: the table is rebuilt from the reports
    for table in (df, read_table(tmp_path / "out")):
        types = {col: str(table[col].dtype) for col in table.columns}
        assert types["solver.success"] == "boolean" and types["solver.iterations"] == "Int64"
        assert types["error"] == types["status"] == types["solver.status"] == "string"
        assert types["attempts"] == "Int64" and types["limits.speed [m/s]"] == "float64"
        assert types["metrics.planned.min_eig"] == "float64"
        failed = table.set_index("task_id").loc[b.id]
        assert pd.isna(failed["solver.success"]) and pd.isna(failed["solver.iterations"])
    pd.testing.assert_frame_equal(read_table(tmp_path / "out"), df)
    client.wait_for_workers(2, timeout=WAIT_S)  # the nannies restarted the killed workers
    stored = read_report(tmp_path / "out", b.id)
    assert stored["sweep"]["status"] == "failed" and "metrics" not in stored


# ------------------------------------------------------------------------------ Ctrl-C, resume
def run_cli(args: list[str], **kw) -> subprocess.Popen:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.Popen(
        [sys.executable, "-m", "obsplan", "sweep", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        **kw,
    )


def test_ctrl_c_then_rerun_resumes_and_equals_an_uninterrupted_run(reference, client, tmp_path):
    ref_df, _ = reference
    sweep_file = write_study(tmp_path)
    out = tmp_path / "out"
    args = [str(sweep_file), "--out", str(out), "--workers", "2", "--quiet", "--no-figures"]
    # a new session: SIGINT to the whole process group, as a terminal's Ctrl-C does
    proc = run_cli(args, start_new_session=True)
    try:
        wait_for(lambda: len(reports(out)) >= 2 or proc.poll() is not None, "2 finished tasks")
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=WAIT_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "sweep study: 6 tasks, 0 already done, 6 to run on tcp://" in stdout
    assert "Traceback" not in stderr  # neither the client nor a worker process printed one
    finished = {p: os.stat(p).st_mtime_ns for p in reports(out)}
    assert 2 <= len(finished) < 6, "the interrupt came too late to test resuming"
    # one line, and a true one: how many finished tasks are kept (not also "nothing was written")
    assert [line for line in stderr.splitlines() if line.strip()] == [
        f"obsplan sweep: interrupted; {len(finished)} finished tasks are kept in {out}; run the "
        "same command again to resume"
    ], stderr
    table = read_table(out)  # written on the way out: finished rows and pending ones
    assert (table["status"] == "done").sum() == len(finished)
    assert (table["status"] == "pending").sum() == 6 - len(finished)
    assert not list(out.rglob(".*tmp*")), "a temporary file was left behind"

    # the same sweep file again (through the API, on the shared cluster: the folder is the same)
    started = []
    df = sweep(sweep_file, out, client=client, progress=False, on_start=started.append)
    assert (started[0].finished, started[0].to_run) == (len(finished), 6 - len(finished))
    # the finished tasks were not computed again
    assert {p: os.stat(p).st_mtime_ns for p in finished} == finished
    pd.testing.assert_frame_equal(comparable(df), comparable(ref_df))
    pd.testing.assert_frame_equal(comparable(read_table(out)), comparable(ref_df))


# ------------------------------------------------------------------------------ external cluster
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def dask_processes(port: int, workers: int = 1, scheduler_file: Path | None = None):
    """``dask scheduler`` (writing ``scheduler_file`` if given) and ``dask worker`` as separate
    processes; stopped on exit, even on failure (each by its own pid)."""
    dask_cli = str(Path(sys.executable).with_name("dask"))
    env = {**os.environ, "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    address = f"tcp://127.0.0.1:{port}"
    extra = [] if scheduler_file is None else ["--scheduler-file", str(scheduler_file)]
    procs = [
        subprocess.Popen(
            [dask_cli, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"]
            + extra,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
    ]
    try:
        procs.append(
            subprocess.Popen(
                [
                    dask_cli,
                    "worker",
                    address,
                    "--nthreads",
                    "1",
                    "--nworkers",
                    str(workers),
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                env=env,
            )
        )
        with distributed.Client(address, timeout=WAIT_S) as c:
            c.wait_for_workers(workers, timeout=WAIT_S)
        yield address, procs
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_external_scheduler_lost_then_resumed(reference, tmp_path):
    ref_df, _ = reference
    out = tmp_path / "out"
    port = free_port()
    with dask_processes(port) as (address, procs):
        scheduler = procs[0]

        def kill_scheduler_after_first_task() -> None:
            with contextlib.suppress(AssertionError):
                wait_for(lambda: len(reports(out)) >= 1, "a finished task")
            scheduler.kill()

        killer = threading.Thread(target=kill_scheduler_after_first_task, daemon=True)
        killer.start()
        with pytest.raises(ClusterError, match="run the same command again to resume"):
            sweep(STUDY, out, scheduler=address, progress=False)
        killer.join(WAIT_S)
    finished = {p: os.stat(p).st_mtime_ns for p in reports(out)}
    assert 1 <= len(finished) < 6
    assert (read_table(out)["status"] == "done").sum() == len(finished)

    with dask_processes(free_port(), workers=2) as (address, _):
        df = sweep(STUDY, out, scheduler=address, progress=False)
    assert {p: os.stat(p).st_mtime_ns for p in finished} == finished
    pd.testing.assert_frame_equal(comparable(df), comparable(ref_df))


# ------------------------------------------------------------------------------ Monte Carlo
#: Two cheap tasks (baselines only, no solver): for the command-line tests of a cluster.
SMALL = {
    "sweep": {"name": "small", "mode": "baselines"},
    "base": BASE,
    "axes": {"beacon.position": [[0.0, 0.0], [50.0, 0.0]]},
}


def test_scheduler_file_and_dask_scheduler_address_are_honoured(tmp_path, capsys):
    sweep_file = write_study(tmp_path, SMALL)
    scheduler_file = tmp_path / "scheduler.json"
    args = ["--quiet", "--no-figures"]
    with dask_processes(free_port(), scheduler_file=scheduler_file) as (address, _):
        # HPC: the file the scheduler wrote (`dask scheduler --scheduler-file FILE`)
        code = main(
            [
                "sweep",
                str(sweep_file),
                "--out",
                str(tmp_path / "a"),
                "--scheduler-file",
                str(scheduler_file),
                *args,
            ]
        )
        stdout = capsys.readouterr().out
        assert code == 0 and f"2 to run on {address} (1 worker)" in stdout, stdout
        # Dask's own configuration, in the environment of the installed command
        proc = subprocess.run(
            [
                str(Path(sys.executable).with_name("obsplan")),
                "sweep",
                str(sweep_file),
                "--out",
                str(tmp_path / "b"),
                *args,
            ],
            env={**os.environ, "DASK_SCHEDULER_ADDRESS": address, "MPLBACKEND": "Agg"},
            capture_output=True,
            text=True,
            timeout=WAIT_S,
        )
        assert proc.returncode == 0, proc.stderr
        assert f"2 to run on {address} (1 worker)" in proc.stdout, proc.stdout
    pd.testing.assert_frame_equal(
        comparable(read_table(tmp_path / "a")), comparable(read_table(tmp_path / "b"))
    )


def test_a_missing_scheduler_file_exits_2(tmp_path, capsys):
    missing = tmp_path / "nowhere.json"
    code = main(
        [
            "sweep",
            str(write_study(tmp_path, SMALL)),
            "--out",
            str(tmp_path / "o"),
            "--scheduler-file",
            str(missing),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and f"--scheduler-file {missing}: no such file" in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_a_killed_scheduler_process_is_one_line_and_exit_1(tmp_path):
    out = tmp_path / "out"
    with dask_processes(free_port()) as (address, procs):
        proc = run_cli(
            [
                str(write_study(tmp_path)),
                "--out",
                str(out),
                "--scheduler",
                address,
                "--quiet",
                "--no-figures",
            ]
        )
        try:
            wait_for(lambda: len(reports(out)) >= 1 or proc.poll() is not None, "a finished task")
            procs[0].kill()  # the scheduler process dies mid-sweep
            stdout, stderr = proc.communicate(timeout=WAIT_S)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    n = len(reports(out))
    assert 1 <= n < 6, "the scheduler died too late to test"
    assert proc.returncode == 1, stderr  # a failure, not an interruption (130)
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr  # no distributed traceback
    assert lines[0].startswith("obsplan sweep: failed: lost the Dask scheduler with "), lines
    kept = f"{n} finished task{'s are' if n != 1 else ' is'} kept in {out}"
    assert kept in lines[0] and "run the same command again to resume" in lines[0]
    assert (read_table(out)["status"] == "done").sum() == n  # the table was written on the way out


def test_sharded_monte_carlo_equals_the_unsharded_run(client):
    from obsplan.estimation.montecarlo import simulate
    from obsplan.planning.problem.parse import problem_from_dict
    from obsplan.planning.problem.validation_setup import estimation_config
    from obsplan.sweeps import sharded_monte_carlo
    from obsplan.trajectory.sampled import resample

    pb = problem_from_dict(BASE)
    from obsplan.planning import baselines

    traj = resample(baselines(pb)["lawnmower"].trajectory, pb.validation.dt)
    config = estimation_config(pb)
    whole = simulate.monte_carlo(traj, config, runs=5, seed=11)
    merged = sharded_monte_carlo(traj, config, runs=5, seed=11, shards=3, client=client)
    assert merged.runs == 5 and merged.seed == 11
    assert_same(merged.to_dict(), whole.to_dict(), "result")
    # and every per-time and per-run array of each filter (runs in the same order)
    for name in ("ekf", "kf"):
        got, want = getattr(merged, name), getattr(whole, name)
        for f in dataclasses.fields(want):
            if isinstance(getattr(want, f.name), np.ndarray):
                assert_same(getattr(got, f.name), getattr(want, f.name), f"{name}.{f.name}")
    assert_same(merged.crlb_pos_std_t, whole.crlb_pos_std_t, "crlb_pos_std_t")


def assert_same(got, want, where: str) -> None:
    """Equal structure; floats to 1e-12 relative (the acceptance: exact merge, round-off only;
    an absolute 1e-12 for values that are zero), everything else exactly."""
    if isinstance(want, np.ndarray):
        assert isinstance(got, np.ndarray) and got.shape == want.shape, where
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, err_msg=where)
    elif isinstance(want, dict):
        assert isinstance(got, dict) and got.keys() == want.keys(), where
        for key in want:
            if key != "wall_s":  # a time, not a result
                assert_same(got[key], want[key], f"{where}.{key}")
    elif isinstance(want, list | tuple):
        assert isinstance(got, list | tuple) and len(got) == len(want), where
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            assert_same(g, w, f"{where}[{k}]")
    elif isinstance(want, float) and not isinstance(got, bool):
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12, nan_ok=True), where
    else:
        assert got == want, where
