"""Result objects a script lives on, and problems edited from Python.

``PlanResult`` / ``ValidationResult`` (``summary``, ``plot``, ``save``, ``to_dict``, reprs,
pickling), ``obsplan.validate`` reproducing ``report.json``, ``MonteCarloResult`` (``summary``,
``plot``, ``to_dict``, reprs), ``PlanningProblem.with_changes`` (mappings checked by the file's
rules, errors naming the field) and ``to_toml`` (round trip of every shipped problem).
"""

from __future__ import annotations

import doctest
import json
import os
import pickle
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import matplotlib.pyplot as plt
import pytest
from matplotlib.figure import Figure

import obsplan
from obsplan.cli import main
from obsplan.core.errors import ConfigError, InputError, ProblemError
from obsplan.core.outputs import MARKER
from obsplan.core.textfiles import toml_text
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem import sections
from obsplan.planning.problem.parse import (
    load_problem,
    problem_from_dict,
    problem_to_dict,
    shipped_files,
)
from obsplan.planning.results import PlanResult, ValidationResult
from obsplan.trajectory import generators

ROOT = Path(__file__).resolve().parents[1]
#: The free localisation problem made small: 40 steps of 3 s, one start, 4 runs.
SMALL = {
    "horizon": {"duration": 120, "steps": 40},
    "objective": {"starts": 1},
    "validation": {"runs": 4, "max_runs": 4},
}
#: The table's head and the words every verdict ends with.
TABLE_HEAD = "path              objective  PCRB avg"


@pytest.fixture(scope="module")
def small_problem():
    return load_problem("localise").with_changes(**SMALL)


@pytest.fixture(scope="module")
def checked(small_problem):
    """The lawn-mower validated as if it were the plan (no solve: fast)."""
    path = baselines(small_problem)["lawnmower"].trajectory
    return obsplan.validate(path, small_problem)


@pytest.fixture(scope="module")
def planned(small_problem, tmp_path_factory):
    """A small plan and the folder the command line wrote for the same problem."""
    folder = tmp_path_factory.mktemp("cli")
    problem_file = folder / "small.toml"
    problem_file.write_text(small_problem.to_toml())
    out = folder / "out"
    assert main(["plan", str(problem_file), "--out", str(out), "--quiet"]) == 0
    return obsplan.plan(small_problem), out


# ------------------------------------------------------------------------ problems from Python
def test_with_changes_merges_mappings_into_the_sections():
    pb = load_problem("localise")
    new = pb.with_changes(horizon={"steps": 20}, objective={"kind": "gramian-log-det"})
    assert new.horizon == sections.Horizon(duration=pb.horizon.duration, steps=20)
    assert new.objective.kind == "gramian-log-det"
    # every other field as it was, the objective's own settings included
    assert new.objective.starts == pb.objective.starts and new.limits == pb.limits
    assert new.validation == pb.validation and new.name == pb.name
    # the same edit as section objects gives the same problem
    same = pb.with_changes(
        horizon=sections.Horizon(duration=pb.horizon.duration, steps=20),
        objective=sections.ObjectiveSpec(kind="gramian-log-det", starts=pb.objective.starts),
    )
    assert same == new
    # None drops a field: its default applies (localise has an operating area)
    assert pb.limits.area is not None
    assert pb.with_changes(limits={"area": None}).limits.area is None


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"horizon": {"steps": "20"}}, r"^horizon\.steps: expected an integer, got '20'"),
        ({"horizon": {"steps": 0}}, r"horizon\.steps"),
        ({"horizon": {"stepz": 20}}, r"^horizon\.stepz: unknown key"),
        ({"limits": {"accel": [0.05]}}, r"^limits\.accel: expected 2 finite numbers"),
        ({"validation": {"mode": "sideways"}}, r"validation\.mode"),
        ({"horizn": {"steps": 20}}, r"^horizn: unknown section"),
        ({"horizn": sections.Horizon(600.0, 20)}, r"^horizn: not a field of the problem"),
    ],
)
def test_with_changes_errors_name_the_field(changes, match):
    with pytest.raises(ProblemError, match=match):
        load_problem("localise").with_changes(**changes)


def test_section_types_are_exported():
    for name in ("Area", "Horizon", "Limits", "ObjectiveSpec", "ValidationSpec", "VehicleSpec"):
        assert getattr(obsplan, name) is getattr(sections, name)
    assert obsplan.PlanningProblem is type(load_problem("localise"))
    assert obsplan.__all__ == sorted(obsplan.__all__)
    for name in obsplan.__all__:  # each documented in the facade's table
        assert f"``{name}``" in obsplan.__doc__, name


@pytest.mark.parametrize(
    "func",
    [obsplan.PlanningProblem.with_changes, obsplan.PlanningProblem.to_toml, toml_text],
    ids=lambda f: f.__qualname__,
)
def test_the_examples_run(func):
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    out: list[str] = []
    tests = doctest.DocTestFinder().find(func, func.__qualname__, globs={"toml_text": toml_text})
    assert tests and tests[0].examples
    for t in tests:
        runner.run(t, out=out.append)
    assert runner.summarize(verbose=False).failed == 0, "".join(out)


@pytest.mark.parametrize(
    "name", [n for n in shipped_files() if not n.startswith("sweeps/")], ids=str
)
def test_to_toml_round_trips_every_shipped_problem(name, tmp_path):
    pb = load_problem(name)
    text = pb.to_toml()
    assert problem_from_dict(tomllib.loads(text)) == pb
    assert tomllib.loads(text) == problem_to_dict(pb)
    path = tmp_path / "p.toml"
    path.write_text(text)
    assert load_problem(path) == pb


# -------------------------------------------------------------------- a validation's result
def test_summary_has_the_table_and_the_verdict_words(checked):
    text = checked.summary()
    assert text.splitlines()[0].startswith(TABLE_HEAD)
    assert text.splitlines()[0] == checked.table().splitlines()[0]
    for name in ("planned", "lawnmower", "circle"):
        assert any(line.startswith(name) for line in text.splitlines()), name
    assert "validation: closed-loop, 4 runs per path" in text
    # the lawn-mower against itself: no decided win, and the words say which verdicts tie
    assert not checked.verdict.beats_all_decided
    for line in checked.verdict.summary():
        assert line in text


def test_summary_says_the_stress_channel_and_its_counts(small_problem):
    """With ``validation.stress_channel`` the summary's robustness row names the channel, its
    faults and, per path, the ranges used and rejected and the runs lost in it; report.json
    carries the channel."""
    pb = small_problem.with_changes(validation={"stress_channel": "at-sea"})
    path = baselines(pb)["lawnmower"].trajectory
    res = obsplan.validate(path, pb)
    text = res.summary()
    head = "robustness (prior x1, range noise x1, channel at-sea (10 % late arrivals"
    assert head in text and "not replanned):" in text
    rows = text[text.index(head) :].splitlines()
    assert any(r.strip().startswith("lawnmower: ekf ") and ", lost " in r for r in rows), text
    assert "channel at-sea" not in text[: text.index(head)]  # the nominal rows: ideal channel
    assert res.to_dict()["robustness"]["channel"]["name"] == "at-sea"


def test_validate_flies_the_path_as_plan_does(checked, small_problem):
    assert checked.trajectory is not None
    assert set(checked.validation) == {"planned", *checked.baselines}
    first = checked.validation["planned"].result
    assert first.mode == "closed-loop" and first.runs == 4
    assert first.config.ekf_update == small_problem.validation.ekf_update == "second-order"
    assert first.guidance is not None and first.guidance.navigation == "gsf"
    # the same path twice: the same runs, so the same numbers
    planned, mower = checked.validation["planned"], checked.validation["lawnmower"]
    assert planned.to_dict() == mower.to_dict()


def test_reprs_are_short(checked):
    text = repr(checked)
    assert text.startswith("<ValidationResult localise") and "\n" not in text
    assert len(text) < 200
    html = checked._repr_html_()
    assert html.count("<table>") == 1 and "<th>EKF rmse</th>" in html
    assert "<td>lawnmower</td>" in html


def test_plot_returns_figures_and_draws_into_an_ax(checked):
    figs = checked.plot("all")
    assert set(figs) == {"path", "gramian", "filters"}  # no [mission]: no speed figure
    assert all(isinstance(f, Figure) for f in figs.values())
    for f in figs.values():
        plt.close(f)
    fig, ax = plt.subplots()
    assert checked.plot("filters", ax=ax) is fig
    assert ax.lines, "nothing drawn into the given ax"
    plt.close(fig)
    with pytest.raises(ConfigError, match="no \\[mission\\]"):
        checked.plot("speed")
    with pytest.raises(ConfigError, match="one of path, gramian, filters, speed, all"):
        checked.plot("map")
    with pytest.raises(ConfigError, match="give no ax"):
        checked.plot("all", ax=ax)


def test_pickling_round_trips(checked):
    again = pickle.loads(pickle.dumps(checked))
    assert isinstance(again, ValidationResult)
    assert again.summary() == checked.summary()
    assert again.to_dict() == checked.to_dict()
    assert again.problem == checked.problem


def test_save_writes_the_files_whole_and_refuses_a_foreign_folder(checked, tmp_path):
    out = tmp_path / "out"
    written = checked.save(out)
    names = ["plan.csv", "report.json", "path.png", "gramian.png", "filters.png"]
    assert [p.name for p in written] == names
    assert json.loads((out / "report.json").read_text()) == json.loads(
        json.dumps(checked.to_dict())
    )
    assert (out / MARKER).is_file()
    with pytest.raises(InputError, match="not empty.*force=True"):
        checked.save(out)
    checked.save(out, force=True)  # an earlier obsplan output is replaced whole
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    with pytest.raises(InputError, match="not an obsplan output"):
        checked.save(mine, force=True)
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]


# ---------------------------------------------------------------------------- a plan's result
@pytest.mark.slow
def test_plan_result_is_what_the_command_line_prints_and_writes(planned, capsys):
    result, out = planned
    assert isinstance(result, PlanResult) and result.success
    lines = result.summary().splitlines()
    assert lines[0].startswith("localise: 2D range-only, free localisation: pcrb-position, N = 40")
    assert TABLE_HEAD in result.summary()
    # the files of the command line, the same report but for the wall times
    saved = result.save(out.parent / "saved")
    assert sorted(p.name for p in saved) == sorted(
        p.name for p in out.iterdir() if p.name != MARKER
    )
    cli_report = json.loads((out / "report.json").read_text())
    own = json.loads(json.dumps(result.to_dict()))
    assert json.loads((out.parent / "saved" / "report.json").read_text()) == own
    assert list(own) == list(cli_report)
    assert _without_times(own) == _without_times(cli_report)
    assert (out.parent / "saved" / "plan.csv").read_text() == (out / "plan.csv").read_text()
    again = pickle.loads(pickle.dumps(result))
    assert again.to_dict() == result.to_dict() and again.summary() == result.summary()
    assert repr(result).startswith("<PlanResult localise") and "Solve_Succeeded" in repr(result)


@pytest.mark.slow
def test_validate_reproduces_the_reports_validation(planned, small_problem):
    """plan.csv and its problem, validated again: report.json's numbers to the last digit."""
    _, out = planned
    report = json.loads((out / "report.json").read_text())
    traj = obsplan.read_csv(out / "plan.csv")
    again = json.loads(json.dumps(obsplan.validate(traj, small_problem).to_dict()))
    for key in ("validation", "verdict", "metrics", "mission", "robustness"):
        assert again[key] == report[key], key


def _without_times(x):
    if isinstance(x, dict):
        return {k: _without_times(v) for k, v in x.items() if k not in ("wall_s", "build_s")}
    if isinstance(x, list):
        return [_without_times(v) for v in x]
    return x


@pytest.mark.slow
def test_a_ten_line_script_runs(tmp_path):
    """The issue's script, on the small problem, run as a user runs a saved script."""
    script = tmp_path / "script.py"
    script.write_text(
        textwrap.dedent(
            f"""\
            import obsplan

            pb = obsplan.load_problem("localise").with_changes(**{SMALL!r})
            r = obsplan.plan(pb)
            print(r.summary())
            r.save("out")
            figs = r.plot("all")
            print(sorted(figs))
            """
        )
    )
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert TABLE_HEAD in proc.stdout and "['filters', 'gramian', 'path']" in proc.stdout
    assert {"plan.csv", "report.json", "path.png"} <= {p.name for p in (tmp_path / "out").iterdir()}


# ---------------------------------------------------------------------- a Monte Carlo's result
@pytest.fixture(scope="module")
def mc():
    traj = generators.circle(30.0, 1.5, 20.0).sample(0.1)
    cfg = obsplan.EstimationConfig.paper(obsplan.make_model(2, "range"), 0.1)
    return obsplan.monte_carlo(traj, cfg, runs=4, seed=0)


def test_monte_carlo_summary_is_what_simulate_prints(mc):
    lines = mc.summary("circle.csv").splitlines()
    assert lines[0] == "circle.csv: 4 runs, seed 0, 20.0 s, sensors range"
    assert lines[1].split() == ["filter", "final", "err", "final", "std", "RMSE", "NEES"] + [
        "conv.",
        "time",
        "converged",
    ]
    assert [line.split()[0] for line in lines[2:4]] == ["EKF", "KF"]
    assert lines[4].startswith("CRB final position std")


def test_monte_carlo_to_dict_keeps_the_stable_keys(mc):
    d = mc.to_dict()
    assert list(d)[:5] == ["runs", "seed", "ekf", "kf", "crlb_final_pos_std"]
    for name in ("ekf", "kf"):
        assert {"final_pos_err", "rmse_pos", "final_pos_std", "nees_mean"} <= set(d[name])
    json.dumps(d, allow_nan=False)


def test_monte_carlo_plot_reprs_and_pickle(mc):
    fig = mc.plot()
    assert isinstance(fig, Figure)
    plt.close(fig)
    fig, ax = plt.subplots()
    assert mc.plot("errors", ax=ax) is fig and ax.lines
    plt.close(fig)
    run = mc.plot("run")
    assert len(run.axes) == 6
    plt.close(run)
    with pytest.raises(ConfigError, match="one of errors, run"):
        mc.plot("map")
    text = repr(mc)
    assert text.startswith("<MonteCarloResult 4 runs, seed 0, open-loop") and "\n" not in text
    assert "<table>" in mc._repr_html_()
    again = pickle.loads(pickle.dumps(mc))
    assert again.summary() == mc.summary() and again.to_dict() == mc.to_dict()
