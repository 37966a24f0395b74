"""Nothing lost: the output-folder rules of ``obsplan.core.outputs``, one test per class of defect.

Each test generates members of its class over the verbs and the states an output folder can be
in (a folder of the user's with various files, an earlier output of another verb, an earlier
output holding files the user added, a folder that appears or changes while the run works, two
runs into the same folder, a read-only place as root) and asserts the exit code, the one line of
the message, and that every file of the user's is still there, byte-identical.

Refusals that come before any work run with the work replaced by a failure (``no_work``); the
members that must reach the commit run the real, small commands (``--no-validate``, ``--steps``,
``--runs 2``, ``--quick --no-figures``); a change "during the run" is made by a hook between the
check and the commit (:data:`HOOKS`); two concurrent runs are two processes that wait for each
other before committing.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from obsplan.cli import main
from obsplan.core.atomic import TargetChanged, identity, put_in_place, staging_dir
from obsplan.core.outputs import MARKER, ResumableDir, foreign_files, read_marker, write_marker
from obsplan.sweeps.store import check_code
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import write_csv

ROOT = Path(__file__).resolve().parents[1]
LOCALISE = str(ROOT / "problems" / "localise.toml")
#: The verbs that write a folder, and those that write one file.
FOLDER_VERBS = ("plan", "simulate", "paper", "sweep")
WHOLE_VERBS = ("plan", "simulate", "paper")  # written whole, replaced by --force
FILE_VERBS = ("import", "export")
#: A function each verb calls after its output was checked and before it commits: a hook there
#: changes the output "during the run".
HOOKS = {
    "plan": "obsplan.cli.plan.plan",
    "simulate": "obsplan.cli.simulate.monte_carlo",
    "paper": "obsplan.cli.paper.paper_report",
    "sweep": "obsplan.sweeps.run.check_code",
    "import": "obsplan.cli.import_track.fit_track",
    "export": "obsplan.io.waypoints.waypoints_from_trajectory",
}
#: What an earlier output of each verb holds (fake: the files, then the marker listing them).
EARLIER = {
    "plan": {"plan.csv": b"t,px,py\n0,1,2\n", "report.json": b"{}\n", "path.png": b"\x89PNG1"},
    "simulate": {"estimation.png": b"\x89PNG2", "monte_carlo.png": b"\x89PNG3"},
    "paper": {"tables.txt": b"Table 1\n", "tables.json": b"{}\n", "fig1.png": b"\x89PNG4"},
    "sweep": {
        "sweep.json": json.dumps({"sweep": {"name": "s"}, "tasks": []}).encode(),
        "results.csv": b"task_id,task\n",
        "tasks/abc/report.json": b"{}\n",
    },
}


# ------------------------------------------------------------------------------ helpers
@pytest.fixture
def inputs(tmp_path):
    """A trajectory, a position-only track and a small sweep file named "s"."""
    d = tmp_path / "in"
    d.mkdir()
    traj = gen.circle(30.0, 1.5, 20.0).sample(0.1)
    write_csv(traj, d / "traj.csv")
    rows = "\n".join(f"{t:.1f},{p[0]:.4f},{p[1]:.4f}" for t, p in zip(traj.t, traj.p, strict=True))
    (d / "track.csv").write_text("t,px,py\n" + rows + "\n")
    (d / "s.toml").write_text(
        f'[sweep]\nname = "s"\nbase = "{LOCALISE}"\nmode = "baselines"\n'
        "[base.horizon]\nsteps = 20\n[base.validation]\nruns = 2\n"
        '[axes]\n"limits.speed" = [1.0, 1.2]\n'
    )
    return d


def argv_of(verb: str, inputs: Path, out: Path | str, force: bool = False) -> list[str]:
    """The small, real command of ``verb`` writing to ``out``."""
    small = ["--steps", "40", "--starts", "1", "--runs", "2", "--quiet", "--no-validate"]
    argv = {
        "plan": ["plan", LOCALISE, "--out", str(out), *small],
        "simulate": ["simulate", str(inputs / "traj.csv"), "--runs", "2", "--quiet"]
        + ["--out", str(out)],
        "paper": ["paper", "--quick", "--no-figures", "--quiet", "--out", str(out)],
        "sweep": ["sweep", str(inputs / "s.toml"), "--out", str(out), "--workers", "1"]
        + ["--quiet", "--no-figures"],
        "import": ["import", str(inputs / "track.csv"), "--out", str(out)],
        "export": ["export", str(inputs / "traj.csv"), "--waypoints", str(out)],
    }[verb]
    return [*argv, "--force"] if force else argv


@pytest.fixture
def no_work(monkeypatch):
    """Every verb's work replaced by a failure: a refusal must come before it."""

    def never(*a, **k):
        raise AssertionError("work started before the output was checked")

    for target in (
        "obsplan.cli.plan.plan",
        "obsplan.cli.simulate.monte_carlo",
        "obsplan.cli.paper.all_rows",
        "obsplan.cli.import_track.fit_track",
        "obsplan.io.waypoints.waypoints_from_trajectory",
        "obsplan.sweeps.run.dask_client",
    ):
        monkeypatch.setattr(target, never)


def snapshot(folder: Path) -> dict[str, object]:
    """Every entry under ``folder`` (hidden ones too): file bytes, ``<dir>``, a link's target."""
    out: dict[str, object] = {}
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            out[rel] = ("link", os.readlink(p))
        elif p.is_dir():
            out[rel] = "<dir>"
        else:
            out[rel] = p.read_bytes()
    return out


def one_line(err: str) -> str:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def earlier_output(folder: Path, verb: str) -> Path:
    """``folder`` as an earlier run of ``verb`` leaves it (files, then the marker)."""
    for rel, data in EARLIER[verb].items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    write_marker(folder, verb, record=verb != "sweep")
    return folder


def during(monkeypatch, verb: str, action) -> None:
    """Call ``action()`` after ``verb`` checked its output and before it commits."""
    mod, name = HOOKS[verb].rsplit(".", 1)
    module = importlib.import_module(mod)
    real = getattr(module, name)

    def hooked(*a, **k):
        result = real(*a, **k)
        action()
        return result

    monkeypatch.setattr(module, name, hooked)
    if verb == "sweep":  # the claim comes first inside the cluster's block: no cluster needed
        monkeypatch.setattr("obsplan.sweeps.run.dask_client", lambda *a, **k: _no_cluster())


@contextlib.contextmanager
def _no_cluster():
    yield None  # a sweep that got past its claim fails on this, loudly


# ------------------------------------------------------------------------------ 1. user folders
USER_FOLDERS = {
    # the folder: a results table, a valid sweep.json (of the very sweep run) and figures
    "results": {
        "results.csv": b"a,b\n1,2\n",
        "sweep.json": json.dumps({"sweep": {"name": "s"}, "tasks": []}).encode(),
        "figures/mine.png": b"\x89PNG mine",
    },
    "notes": {"notes.md": b"# my notes\n"},
    "dotfile-only": {".envrc": b"export X=1\n"},
    "empty-subfolder": {"mydata/": None},
    "foreign-marker": {MARKER: b"not obsplan's\n", "data.csv": b"1,2\n"},
}


def user_folder(folder: Path, state: str) -> Path:
    folder.mkdir(parents=True)
    for rel, data in USER_FOLDERS[state].items():
        if data is None:
            (folder / rel).mkdir(parents=True)
            continue
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    return folder


@pytest.mark.parametrize("force", [True, False], ids=["force", "no-force"])
@pytest.mark.parametrize("state", list(USER_FOLDERS))
@pytest.mark.parametrize("verb", FOLDER_VERBS)
def test_a_folder_obsplan_did_not_make_is_never_written(
    verb, state, force, inputs, tmp_path, no_work, capsys
):
    """Class 1: ``--force`` (or not) on a user's folder exits 2 before any work; nothing of the
    folder is replaced, nothing is added (no marker), and the message says what it holds."""
    out = user_folder(tmp_path / "w" / "uf", state)
    before = snapshot(tmp_path / "w")
    assert main(argv_of(verb, inputs, out, force)) == 2
    err = one_line(capsys.readouterr().err)
    assert "even with --force" in err and "choose a new or empty folder" in err, err
    if state == "foreign-marker":
        assert f"has a {MARKER} file that obsplan did not write" in err, err
    else:
        assert f"is not an obsplan output folder (it has no {MARKER} file" in err, err
        # it says what the folder holds (the "sweep None" said nothing)
        first = sorted(USER_FOLDERS[state])[0].split("/")[0]
        assert first in err and "None" not in err, err
    assert snapshot(tmp_path / "w") == before


# ------------------------------------------------------------------------------ 3. whose output
@pytest.mark.parametrize(
    "verb, other", [(v, o) for v in FOLDER_VERBS for o in FOLDER_VERBS if o != v]
)
def test_an_output_of_another_verb_is_never_replaced(
    verb, other, inputs, tmp_path, no_work, capsys
):
    """Class 3: the marker's verb decides: a plan or a simulation never replaces a resumable
    sweep, a sweep never writes into a plan's folder, even with ``--force``."""
    out = tmp_path / "w" / "o"
    out.mkdir(parents=True)
    earlier_output(out, other)  # only what the other verb wrote
    before = snapshot(tmp_path / "w")
    assert main(argv_of(verb, inputs, out, force=True)) == 2
    err = one_line(capsys.readouterr().err)
    held = "is a resumable `obsplan sweep` folder" if other == "sweep" else f"`obsplan {other}`"
    assert held in err and f"`obsplan {verb}` never writes over" in err, err
    assert snapshot(tmp_path / "w") == before


#: What a user adds to an earlier output (or changes in it); the names the message must give.
ADDITIONS = {
    "notes": (lambda o: (o / "notes.md").write_text("mine\n"), ["notes.md"]),
    "subfolder": (
        lambda o: ((o / "mydata").mkdir(), (o / "mydata" / "x.bin").write_bytes(b"\0\1")),
        ["mydata/"],
    ),
    "empty-subfolder": (lambda o: (o / "keep").mkdir(), ["keep/"]),
    "hidden": (lambda o: (o / ".notes").write_text("mine\n"), [".notes"]),
    "changed-file": (
        lambda o: (o / sorted(p.name for p in o.iterdir() if p.name != MARKER)[0]).write_bytes(
            b"edited by the user"
        ),
        ["(changed since obsplan wrote it)"],
    ),
    "link": (lambda o: (o / "data").symlink_to("/etc/hostname"), ["data"]),
    "several": (
        lambda o: [(o / f"n{i}.txt").write_text(str(i)) for i in range(6)],
        ["n0.txt", "n3.txt", "and 2 more", "6 files"],
    ),
}


@pytest.mark.parametrize("addition", list(ADDITIONS))
@pytest.mark.parametrize("verb", WHOLE_VERBS)
def test_force_refuses_an_earlier_output_holding_files_of_the_user(
    verb, addition, inputs, tmp_path, no_work, capsys
):
    """Class 3: ``--force`` replaces only what obsplan wrote; a folder holding anything else
    (added, or changed since) is refused with the list of those files, before any work."""
    out = tmp_path / "w" / "o"
    out.mkdir(parents=True)
    earlier_output(out, verb)
    add, names = ADDITIONS[addition]
    add(out)
    before = snapshot(tmp_path / "w")
    assert main(argv_of(verb, inputs, out, force=True)) == 2
    err = one_line(capsys.readouterr().err)
    assert "that obsplan did not write (or that changed since)" in err, err
    assert all(n in err for n in names), err
    assert snapshot(tmp_path / "w") == before


@pytest.mark.parametrize("verb", WHOLE_VERBS)
def test_an_output_of_an_older_obsplan_is_not_guessed_at(verb, inputs, tmp_path, no_work, capsys):
    """A marker without the list of files (an older obsplan wrote it): ``--force`` cannot tell
    obsplan's files from the user's, so it refuses and says how to proceed."""
    out = tmp_path / "w" / "o"
    out.mkdir(parents=True)
    earlier_output(out, verb)
    (out / MARKER).write_text(json.dumps({"written_by": f"obsplan {verb}", "version": "0.0"}))
    before = snapshot(tmp_path / "w")
    assert main(argv_of(verb, inputs, out, force=True)) == 2
    err = one_line(capsys.readouterr().err)
    assert "of an older obsplan that did not record the files it wrote" in err, err
    assert snapshot(tmp_path / "w") == before


@pytest.mark.parametrize(
    "verb", [pytest.param("plan", marks=pytest.mark.slow), "simulate", "paper"]
)
def test_force_replaces_an_earlier_output_of_the_verb_whole(verb, inputs, tmp_path, capsys):
    """The other side of class 3: an earlier output holding only what obsplan wrote (even files
    this run does not write) is replaced whole; the new marker lists exactly the new files."""
    out = tmp_path / "w" / "o"
    assert main(argv_of(verb, inputs, out)) == 0
    (out / "old-figure.png").write_bytes(b"written by an earlier run")
    write_marker(out, verb)  # as that earlier run recorded it
    capsys.readouterr()
    assert main(argv_of(verb, inputs, out)) == 2  # without --force: one line naming --force
    assert "pass --force to replace it" in one_line(capsys.readouterr().err)
    assert main(argv_of(verb, inputs, out, force=True)) == 0
    assert not (out / "old-figure.png").exists()
    marker = read_marker(out)
    assert marker is not None and marker.verb == verb
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert sorted(marker.files or {}) == [f for f in files if f != MARKER]
    assert foreign_files(out, marker) == []
    assert [p.name for p in (tmp_path / "w").iterdir()] == ["o"]  # nothing aside, nothing hidden


# ------------------------------------------------------------------------------ 2. during the run
def _appears(out: Path):
    def act():
        out.mkdir()
        (out / "theirs.txt").write_text("another program's file\n")

    return act


def _file_added(out: Path):
    return lambda: (out / "notes.md").write_text("written while obsplan worked\n")


def _replaced(out: Path):
    def act():
        out.rename(out.with_name("moved-by-the-user"))
        out.mkdir()
        (out / "theirs.txt").write_text("a new folder of the same name\n")

    return act


#: (state at the check, change during the run, phrase of the message).
CHANGES = {
    "absent-then-created": (None, _appears, "appeared while this run was working"),
    "empty-then-a-file": ("empty", _file_added, "is not an obsplan output folder"),
    "earlier-then-a-file": ("earlier", _file_added, "notes.md"),
    "earlier-then-replaced": ("earlier", _replaced, "was replaced, removed or changed while"),
}


@pytest.mark.parametrize("change", list(CHANGES))
@pytest.mark.parametrize("verb", FOLDER_VERBS)
def test_the_commit_leaves_a_folder_that_changed_during_the_run(
    verb, change, inputs, tmp_path, monkeypatch, capsys
):
    """Class 2: the commit checks the target again (identity and contents): a folder created,
    replaced or given a file of someone else's while the run worked is left as it is, exit 2;
    nothing of the run is left behind (no staging folder, no marker added)."""
    state, act, phrase = CHANGES[change]
    if verb == "sweep" and change == "earlier-then-a-file":
        pytest.skip("a sweep adds to its folder, deleting nothing: test_a_sweep_resumes_...")
    work = tmp_path / "w"
    work.mkdir()
    out = work / "o"
    if state == "empty":
        out.mkdir()
    elif state == "earlier":
        out.mkdir()
        earlier_output(out, verb)
    during(monkeypatch, verb, act(out))
    code = main(argv_of(verb, inputs, out, force=state == "earlier"))
    err = capsys.readouterr().err
    assert code == 2, err
    assert phrase in one_line(err), err
    after = snapshot(work)
    if act is _appears or act is _replaced:
        assert after.get("o/theirs.txt", b"").startswith(b"a") and not (out / MARKER).exists()
    if act is _file_added:
        assert after["o/notes.md"] == b"written while obsplan worked\n"
    if state == "earlier":  # the earlier output is whole, wherever the user put it
        home = out if act is _file_added else work / "moved-by-the-user"
        for rel, data in EARLIER[verb].items():
            assert (home / rel).read_bytes() == data
    left = [k for k in after if k.startswith(".") or ".tmp-" in k or ".old-" in k]
    assert left == [], after.keys()  # no staging folder, no old copy


@pytest.mark.parametrize("change", ["absent-then-created", "existing-then-changed"])
@pytest.mark.parametrize("verb", FILE_VERBS)
def test_an_output_file_that_changed_during_the_run_is_left_alone(
    verb, change, inputs, tmp_path, monkeypatch, capsys
):
    """Class 2 for the verbs that write one file: a file that appeared or changed after the
    check is kept as it is; exit 2."""
    work = tmp_path / "w"
    work.mkdir()
    out = work / "out.csv"
    if change == "existing-then-changed":
        out.write_text("the user's file\n")
    during(monkeypatch, verb, lambda: out.write_text("written meanwhile\n"))
    code = main(argv_of(verb, inputs, out, force=change != "absent-then-created"))
    err = capsys.readouterr().err
    assert code == 2, err
    phrase = "appeared" if change == "absent-then-created" else "was replaced, removed or changed"
    assert phrase in one_line(err), err
    assert snapshot(work) == {"out.csv": b"written meanwhile\n"}


_RACE = """
import os, sys, time, importlib
from pathlib import Path
gate, hook = Path(sys.argv[1]), sys.argv[2]
mod, name = hook.rsplit(".", 1)
module = importlib.import_module(mod)
real = getattr(module, name)
def waiting(*a, **k):
    result = real(*a, **k)
    (gate / str(os.getpid())).touch()
    deadline = time.monotonic() + 120
    while len(list(gate.iterdir())) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    return result
setattr(module, name, waiting)
# a run refused at its check never reaches the hook: its exit opens the gate too
import atexit
atexit.register(lambda: (gate / f"{os.getpid()}-exit").touch())
from obsplan.cli import main
sys.exit(main(sys.argv[3:]))
"""


def race(verb: str, argv: list[str], gate: Path) -> list[tuple[int, str]]:
    """Two processes run ``argv``; each waits, once its work is done, for the other's: both
    checked the output before either commits."""
    gate.mkdir()
    env = {**os.environ, "MPLBACKEND": "Agg"}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _RACE, str(gate), HOOKS[verb], *argv],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            env=env,
        )
        for _ in range(2)
    ]
    results = []
    for p in procs:
        _, err = p.communicate(timeout=300)
        results.append((p.returncode, err.decode()))
    return results


@pytest.mark.slow
@pytest.mark.parametrize("state", ["absent", "earlier"])
@pytest.mark.parametrize("verb", ["plan", "simulate", "paper", "sweep"])
def test_two_runs_into_one_folder_one_wins(verb, state, inputs, tmp_path):
    """Class 2: two runs to the same ``--out`` at once: exactly one writes it, the other exits 2
    with one line; the folder is the winner's, whole, and nothing is left beside it."""
    work = tmp_path / "w"
    work.mkdir()
    out = work / "o"
    if state == "earlier":
        out.mkdir()
        earlier_output(out, verb)
    results = race(verb, argv_of(verb, inputs, out, force=state == "earlier"), tmp_path / "gate")
    codes = sorted(code for code, _ in results)
    if verb == "sweep" and state == "earlier":
        # the second sweep into an existing folder is refused at its check: the folder is locked
        assert codes == [0, 2], results
        err = next(e for c, e in results if c == 2)
        assert "another obsplan run is writing into it" in err, err
        return
    assert codes == [0, 2], results
    err = next(e for c, e in results if c == 2)
    phrase = "appeared while" if state == "absent" else "was replaced, removed or changed while"
    assert phrase in err and err.count("\n") == 1, err
    marker = read_marker(out)
    assert marker is not None and marker.verb == verb
    if verb != "sweep":
        assert marker.files and foreign_files(out, marker) == []
    assert sorted(p.name for p in work.iterdir()) == ["o"]


def test_a_sweep_into_a_folder_another_run_writes_exits_2_at_once(inputs, tmp_path, capsys):
    """Class 2 for the resumable folder: it is locked while a run writes into it; a second run
    is refused at its check (before any cluster starts), and can run once the first ended."""
    out = tmp_path / "w" / "o"
    out.mkdir(parents=True)
    earlier_output(out, "sweep")
    before = snapshot(out)
    with ResumableDir(out, "sweep"):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr("obsplan.sweeps.run.dask_client", lambda *a, **k: 1 / 0)
            assert main(argv_of("sweep", inputs, out)) == 2
        err = one_line(capsys.readouterr().err)
        assert "another obsplan run is writing into it now" in err, err
    assert snapshot(out) == before
    ResumableDir(out, "sweep").release()  # free again


def test_two_claims_of_a_new_resumable_folder_one_wins(tmp_path):
    out = tmp_path / "new" / "o"
    first, second = ResumableDir(out, "sweep"), ResumableDir(out, "sweep")
    assert first.claim() == out and (out / MARKER).is_file()
    (out / "sweep.json").write_text("{}")
    with pytest.raises(Exception, match="appeared while this run was working"):
        second.claim()
    first.release()
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "sweep.json"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["o"]


@pytest.mark.parametrize("kind", ["folder", "file"])
def test_put_in_place_never_replaces_what_it_did_not_check(kind, tmp_path):
    """The primitive under every commit: a target that appeared, or that is not the one checked,
    stays; a verification failing after the exchange puts the old target back."""
    target, other = tmp_path / "t", tmp_path / "other"

    def make(path: Path, text: str) -> None:
        if kind == "folder":
            path.mkdir()
            (path / "f").write_text(text)
        else:
            path.write_text(text)

    def content(path: Path) -> str:
        return (path / "f" if kind == "folder" else path).read_text()

    staged = tmp_path / ".t.tmp-1-00000000"
    make(staged, "new")
    make(target, "newcomer")
    with pytest.raises(TargetChanged) as exc:
        put_in_place(staged, target, None)  # absent at the check
    assert exc.value.appeared and content(target) == "newcomer" and content(staged) == "new"
    make(other, "checked")
    with pytest.raises(TargetChanged):
        put_in_place(staged, target, identity(other))  # another one was checked
    assert content(target) == "newcomer" and content(staged) == "new"

    def refuse(old: Path) -> None:
        assert content(old) == "newcomer"  # the old target, moved out of the way
        raise RuntimeError("holds something new")

    with pytest.raises(RuntimeError):
        put_in_place(staged, target, identity(target), verify=refuse)
    assert content(target) == "newcomer" and content(staged) == "new"
    old = put_in_place(staged, target, identity(target))
    assert old is not None and content(target) == "new" and content(old) == "newcomer"
    assert not staged.exists()


# ------------------------------------------------------------------------------ 4. read-only
#: Where ``--out`` points, relative to a read-only (mode 555) folder ``ro``.
READ_ONLY_PLACES = ["ro", "ro/sub", "ro/a/b", "ro/earlier"]


@pytest.mark.parametrize("place", READ_ONLY_PLACES)
@pytest.mark.parametrize("verb", FOLDER_VERBS + FILE_VERBS)
def test_a_read_only_place_is_refused_for_root_too(verb, place, inputs, tmp_path, no_work, capsys):
    """Class 4: the mode bits judge, for root as for anyone, the folder itself and the place a
    new folder or file is created in, however deep; the same answer for ``ro`` and ``ro/sub``."""
    ro = tmp_path / "w" / "ro"
    ro.mkdir(parents=True)
    force = place == "ro/earlier"
    if force:
        if verb in FILE_VERBS:
            (ro / "earlier").write_text("the user's file\n")
        else:
            (ro / "earlier").mkdir()
            earlier_output(ro / "earlier", verb)
    if verb == "sweep" and force:
        pytest.skip("a sweep resumes inside its own folder: test_a_sweep_resumes_...")
    out = tmp_path / "w" / place
    if verb in FILE_VERBS and place in ("ro", "ro/sub", "ro/a/b"):
        out = out / "out.csv"
    before = snapshot(tmp_path / "w")
    ro.chmod(0o555)
    try:
        code = main(argv_of(verb, inputs, out, force))
    finally:
        ro.chmod(0o755)
    assert code == 2
    err = one_line(capsys.readouterr().err)
    assert "read-only" in err and ("chmod u+w" in err or "make it writable" in err), err
    assert snapshot(tmp_path / "w") == before


@pytest.mark.slow
def test_a_sweep_resumes_in_its_folder_keeping_the_users_files(inputs, tmp_path, capsys):
    """A sweep adds to its own folder and deletes nothing: a file the user put there stays, also
    when added during the run; its parent may be read-only (only the folder is written)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    out = ro / "s"
    assert main(argv_of("sweep", inputs, out)) == 0
    (out / "notes.md").write_text("the user's notes\n")
    ro.chmod(0o555)
    try:
        with pytest.MonkeyPatch.context() as mp:
            real = check_code  # a file added after the check; the real cluster runs

            def hooked(*a, **k):
                real(*a, **k)
                (out / "later.md").write_text("added meanwhile\n")

            mp.setattr("obsplan.sweeps.run.check_code", hooked)
            assert main(argv_of("sweep", inputs, out)) == 0
    finally:
        ro.chmod(0o755)
    assert (out / "notes.md").read_text() == "the user's notes\n"
    assert (out / "later.md").read_text() == "added meanwhile\n"
    assert "2 already done, 0 to run" in capsys.readouterr().out


def test_the_read_only_rule_is_the_same_as_root_and_as_a_user(tmp_path):
    """The answer does not depend on who runs: ``os.access`` and the mode bits agree here."""
    from obsplan.core.outputs import OutputDir

    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        msgs = []
        for out in (ro, ro / "sub", ro / "a" / "b"):
            with pytest.raises(Exception, match="read-only") as exc:
                OutputDir(out, False, verb="plan")
            msgs.append(str(exc.value))
    finally:
        ro.chmod(0o755)
    assert list(ro.iterdir()) == []
    assert "it is read-only (mode 555)" in msgs[1] and msgs[1].endswith(msgs[2].split(": ", 1)[1])


# ------------------------------------------------------------------------------ 5. the words
@pytest.mark.parametrize(
    "manifest, phrase",
    [
        ({"sweep": {"combine": "zip"}}, "names no sweep, so it cannot be resumed"),
        ([1, 2], "not the manifest of an obsplan sweep (it holds a list)"),
        ({"sweep": {"name": "another"}}, "holds the results of sweep 'another', not 's'"),
    ],
)
def test_a_sweep_folder_says_what_it_holds(manifest, phrase, inputs, tmp_path, no_work, capsys):
    """Class 5: a sweep's folder whose ``sweep.json`` is not this sweep's says what it holds and
    what to do (never "holds the results of sweep None")."""
    out = tmp_path / "o"
    out.mkdir()
    write_marker(out, "sweep", record=False)
    (out / "sweep.json").write_text(json.dumps(manifest))
    before = snapshot(out)
    assert main(argv_of("sweep", inputs, out)) == 2
    err = one_line(capsys.readouterr().err)
    assert phrase in err and "None" not in err, err
    assert snapshot(out) == before


def test_a_staging_folder_of_a_live_run_is_not_an_output(tmp_path):
    """A run's hidden staging folder beside ``--out`` is not touched by another run's check."""
    live = staging_dir(tmp_path / "o")
    from obsplan.core.outputs import OutputDir

    OutputDir(tmp_path / "o", False, verb="plan")
    assert live.is_dir()
    os.rmdir(live)
