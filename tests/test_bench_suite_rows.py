"""benchmarks/bench_planning_suite.py: a planned beacon's row, and rows updated in place in the
page an earlier run wrote (the other rows and the summary kept, the command that wrote the new
rows said)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_planning_suite.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_planning_suite", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _fixed_row(name: str, ratio: float) -> dict:
    d = {"outcome": "better", "ratio": ratio, "ci": (0.5, 0.9)}
    return {
        "problem": f"obsplan/problems/{name}",
        "objective": "pcrb-position/average-and-final",
        "status": "Solve_Succeeded",
        "success": True,
        "solve_s": 5.0,
        "lawnmower": {k: ratio for _, k in _bench().RATIOS},
        "runs": 50,
        "true_closest_m": 6.0,
        "runs_inside_min_range": 0,
        "any_violation_fraction": 0.0,
        "beats_all": True,
        "verdicts": {"lawnmower": {k: d for k in _bench().VERDICT_METRICS}},
    }


def _beacon_row(name: str) -> dict:
    bench = _bench()
    win = {"outcome": "better", "ratio": 0.6, "ci": (0.5, 0.7)}
    tie = {"outcome": "tie", "ratio": 0.97, "ci": (0.9, 1.05)}
    verdicts = {
        "beacon-fixed": {k: win for k in bench.BEACON_METRICS},
        "beacon-circle": {bench.BEACON_METRICS[0]: win, bench.BEACON_METRICS[1]: tie},
    }
    row = _fixed_row(name, 0.0)
    row.update(
        objective="planned beacon (pcrb lines + final)",
        lawnmower={},
        beacon_verdicts=verdicts,
        verdicts={"circle": {k: win for k in bench.VERDICT_METRICS}},
    )
    return row


def test_rows_are_replaced_or_added_and_the_rest_is_kept():
    bench = _bench()
    fixed = [_fixed_row("a.toml", 0.5), _fixed_row("suite/b.toml", 0.4)]
    page = bench.markdown_page(fixed, "python benchmarks/bench_planning_suite.py X", 600.0)
    new = [_beacon_row("asv.toml"), _fixed_row("a.toml", 0.3)]
    out = bench.update_page(page, new, "python benchmarks/bench_planning_suite.py Y", 60.0)
    lines = out.splitlines()
    assert lines[0] == page.splitlines()[0]  # the earlier command's line stays
    assert lines[1].startswith("Rows of `asv.toml`, `a.toml` by `python benchmarks/")
    rows = [x for x in lines if x.startswith("| `")]
    # a.toml replaced in place, the new row before the suite's, the suite's row untouched
    assert [r.split("|")[1].strip() for r in rows] == ["`a.toml`", "`asv.toml`", "`suite/b.toml`"]
    assert rows[0] == bench.table_row(new[1]) and "0.30" in rows[0]
    assert rows[2] in page.splitlines()
    # the summary of the earlier run is kept; the planned beacons' paragraph is added
    summary = next(x for x in page.splitlines() if x.startswith("Medians over"))
    assert summary in lines
    para = next(x for x in lines if x.startswith(bench.BEACON_PARAGRAPH))
    assert "`asv.toml` beacon-fixed BB, beacon-circle Bt" in para
    # updating again replaces the paragraph and the note instead of repeating them
    again = bench.update_page(out, new, "python benchmarks/bench_planning_suite.py Y", 60.0)
    assert sum(x.startswith(bench.BEACON_PARAGRAPH) for x in again.splitlines()) == 1
    assert sum(x.startswith("Rows of `asv.toml`") for x in again.splitlines()) == 1


def test_an_updated_suite_row_is_replaced_where_it_stands():
    bench = _bench()
    fixed = [
        _fixed_row("a.toml", 0.5),
        _fixed_row("suite/b.toml", 0.4),
        _fixed_row("suite/c.toml", 0.6),
    ]
    page = bench.markdown_page(fixed, "python bench X", 600.0)
    out = bench.update_page(page, [_fixed_row("suite/c.toml", 0.2)], "python bench Y", 60.0)
    rows = [x for x in out.splitlines() if x.startswith("| `")]
    names = [r.split("|")[1].strip() for r in rows]
    assert names == ["`a.toml`", "`suite/b.toml`", "`suite/c.toml`"]  # once, in its place
    assert rows[2] == bench.table_row(_fixed_row("suite/c.toml", 0.2))


def test_a_later_update_keeps_what_it_did_not_rerun_and_drops_what_it_superseded():
    bench = _bench()
    fixed = [_fixed_row("a.toml", 0.5), _fixed_row("suite/b.toml", 0.4)]
    page = bench.markdown_page(fixed, "python bench X", 600.0)
    with_beacon = bench.update_page(page, [_beacon_row("asv.toml")], "python bench Y", 60.0)
    # a fixed-beacon row alone re-run: the planned beacon's paragraph (not re-run) stays
    ship = bench.update_page(with_beacon, [_fixed_row("ship.toml", 0.4)], "python bench Z", 60.0)
    para = [x for x in ship.splitlines() if x.startswith(bench.BEACON_PARAGRAPH)]
    assert len(para) == 1 and "`asv.toml` beacon-fixed BB" in para[0]
    assert any(x.startswith("Rows of `asv.toml` by `python bench Y`") for x in ship.splitlines())
    # both re-run by one command: its line replaces the two it supersedes
    both = [_beacon_row("asv.toml"), _fixed_row("ship.toml", 0.4)]
    last = bench.update_page(ship, both, "python bench W", 60.0)
    notes = [x for x in last.splitlines() if x.startswith("Rows of ")]
    assert notes == [
        "Rows of `asv.toml`, `ship.toml` by `python bench W` (1 min wall); the other rows and "
        "the summary by the command above."
    ]


def test_one_planned_beacon_re_run_keeps_the_others_verdicts_in_the_paragraph():
    bench = _bench()
    fixed = [_fixed_row("a.toml", 0.5), _fixed_row("suite/b.toml", 0.4)]
    page = bench.markdown_page(fixed, "python bench X", 600.0)
    two = bench.update_page(
        page, [_beacon_row("asv.toml"), _beacon_row("asv3d.toml")], "python bench Y", 60.0
    )
    again = _beacon_row("asv3d.toml")
    again["beacon_verdicts"]["beacon-circle"] = {
        k: again["beacon_verdicts"]["beacon-fixed"][k] for k in bench.BEACON_METRICS
    }
    joint = bench.update_page(two, [again, _beacon_row("joint.toml")], "python bench Z", 60.0)
    (para,) = [x for x in joint.splitlines() if x.startswith(bench.BEACON_PARAGRAPH)]
    said = para.split(" are: ", 1)[1].rstrip(".").split("; ")
    # the one not re-run keeps its verdicts, the re-run one has its new ones, in the same order
    assert said == [
        "`asv.toml` beacon-fixed BB, beacon-circle Bt",
        "`asv3d.toml` beacon-fixed BB, beacon-circle BB",
        "`joint.toml` beacon-fixed BB, beacon-circle Bt",
    ]
