"""The suite page's table (docs/results/suite.md, which includes the table and summary that
``benchmarks/bench_planning_suite.py --markdown`` wrote) covers every shipped problem, once, with
the objective it names."""

from __future__ import annotations

import re
from pathlib import Path

from obsplan.planning import load_problem
from obsplan.planning.baselines.beacon import BEACON_BASELINES

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
INCLUDE = "```{include} generated/suite-table.md\n```"
#: the page as the site renders it: the generated table in place of its include directive
PAGE = (
    (RESULTS / "suite.md")
    .read_text(encoding="utf-8")
    .replace(INCLUDE, (RESULTS / "generated" / "suite-table.md").read_text(encoding="utf-8"))
)
SECTION = "# The planner's verdict on the problem suite"
NUMBERS = (
    "zero one two three four five six seven eight nine ten eleven twelve thirteen "
    "fourteen fifteen sixteen seventeen eighteen nineteen twenty twenty-one twenty-two "
    "twenty-three twenty-four twenty-five"
).split()


def _section() -> str:
    assert PAGE.startswith(SECTION)
    assert INCLUDE not in PAGE, "suite.md no longer includes the generated table"
    return PAGE


def _rows() -> dict[str, list[str]]:
    rows: dict[str, list[str]] = {}
    for line in _section().splitlines():
        m = re.match(r"\| `([\w/.-]+\.toml)` \|", line)
        if m:
            assert m.group(1) not in rows, f"two suite rows for {m.group(1)}"
            rows[m.group(1)] = [c.strip() for c in line.strip().strip("|").split("|")]
    return rows


def _shipped() -> dict[str, Path]:
    files = {p.name: p for p in sorted((ROOT / "problems").glob("*.toml"))}
    files |= {f"suite/{p.name}": p for p in sorted((ROOT / "problems/suite").glob("*.toml"))}
    return files


def test_every_shipped_problem_has_one_row_naming_its_objective():
    rows, files = _rows(), _shipped()
    assert sorted(rows) == sorted(files)
    for name, path in files.items():
        pb = load_problem(path)
        if pb.beacon_motion.motion == "planned":  # plan_moving_beacon: the beacon's bound
            assert rows[name][1].startswith("planned beacon"), name
            continue
        # "pcrb-position/average-and-final": the kind, then the time mode of a timed objective
        assert rows[name][1].split("/")[0] == pb.objective.kind, name


def test_the_planned_beacons_rows_say_their_verdicts_and_who_wrote_them():
    """Rows put in by --update-rows: the command that wrote them is said, and the paragraph
    gives each planned beacon's verdicts against every beacon baseline."""
    table = (RESULTS / "generated" / "suite-table.md").read_text(encoding="utf-8")
    moving = [n for n, p in _shipped().items() if load_problem(p).beacon_motion.motion == "planned"]
    para = next(x for x in table.splitlines() if x.startswith("Planned beacons"))
    for name in moving:
        assert f"`{name}` beacon-" in para, name
        said = para.split(f"`{name}` ", 1)[1].split(";", 1)[0]
        for baseline in BEACON_BASELINES:  # a joint plan's beacon-planned may come first
            assert f"{baseline} " in said, (name, baseline)
        assert any(x.startswith("Rows of ") and f"`{name}`" in x for x in table.splitlines())


def test_the_section_counts_the_suite_as_it_is():
    n = len(list((ROOT / "problems/suite").glob("*.toml")))
    assert f"{NUMBERS[n]} of `problems/suite/`" in _section()
    assert f"Medians over the {NUMBERS[n]} suite rows" in _section()


def test_the_table_is_the_benchmarks_output():
    """The page's table was written by the benchmark, with the command that wrote it."""
    table = (RESULTS / "generated" / "suite-table.md").read_text(encoding="utf-8")
    assert table.startswith("Written by `python benchmarks/bench_planning_suite.py ")
    assert "--markdown docs/results/generated/suite-table.md" in table.splitlines()[0]
