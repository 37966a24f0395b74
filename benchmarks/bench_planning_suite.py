"""The planner's honest verdict: every shipped problem and the problem suite, planned and validated.

Run (minutes; the full validation Monte Carlo of every path):

    MPLBACKEND=Agg python benchmarks/bench_planning_suite.py [--runs N] [--max-runs N]
        [--open-loop] [--ekf-update second-order] [--navigation gsf] [--json out.json]
        [--truth-runs N] [--markdown docs/results/generated/suite-table.md] [FILES...]

For each problem (default: ``problems/*.toml`` then ``problems/suite/*.toml``) this runs
``obsplan.plan`` exactly as ``obsplan plan`` does and prints: solver status, solve time, and the
planned path's ratio to the lawn-mower and to the best *fitted* baseline (the lowest value of that
metric among the lawn-mower, circle, straight line and the paper's lawn-mower) of the EKF and KF
position RMSE, the EKF final error and the final posterior CRB, the closest approach to the
beacon, whether the plan beats every baseline on the headline metrics, and the baselines that
could not be fitted. Medians of the ratios to the lawn-mower are over ``problems/suite``.

The validation is the problem's (closed loop unless ``--open-loop``; runs added until every
verdict is decided or ``validation.max_runs``), so the table also has: the runs it took, the
true paths' closest approach to the beacon over all runs of the plan (``true min``), the plan's
runs inside ``min_range`` (``in``) and breaking any limit (``brk``), and the verdicts against the
lawn-mower and the circle on EKF RMSE, EKF final, KF RMSE and KF final: ``B`` better and
decided at 95 %, ``W`` worse and decided, ``t`` a tie (not decided at the cap). The verdict's
notes (an EKF that diverges on the plan, with the Gaussian-sum filter beside it; a diagnostic
objective) follow their row. ``--objective gramian`` keeps the problems whose objective kind
starts with ``gramian``. ``--set SECTION.FIELD=VALUE`` (repeatable; VALUE a TOML value, a bare
word taken as a string) changes a field of every problem, checked as the problem file's are:
e.g. ``--set objective.kind=pcrb-position --set objective.mode=final`` plans every problem for
its final bound. ``--markdown FILE`` also writes the table and its summary as the Markdown page
the documentation includes (``docs/results/suite.md``): the site's suite numbers are this
script's output, not copied by hand.

A problem whose beacon is planned (``beacon.motion = "planned"``, the ASV problems) is planned
and validated by ``obsplan plan``'s flow for it (:func:`~obsplan.planning.plan
.plan_moving_beacon`): the vehicle flies the same path with every beacon, so its row has no
ratios; its circle column is ``beacon-circle``, its true closest approach is the vehicle's to
the planned craft, and a paragraph under the table gives the planned beacon's verdicts on the
EKF's RMSE over the lines and its final error against every beacon baseline (``--truth-runs``
does not apply to it). ``--update-rows FILE`` puts the rows of the problems run into a page an
earlier ``--markdown`` wrote, in place (a problem's row replaced, a new one after the shipped
problems' rows), keeps the other rows and the summary as they were (its medians and counts are
of the earlier run's rows) and says under the first line which command wrote the new rows: e.g.
the ASV rows without re-running the whole suite.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
import tomllib
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from obsplan.planning import load_problem  # noqa: E402
from obsplan.planning.beacon import plan_beacon  # noqa: E402
from obsplan.planning.plan import plan, plan_moving_beacon  # noqa: E402
from obsplan.planning.problem.parse import problem_from_dict, problem_to_dict  # noqa: E402
from obsplan.planning.validation.validate import validate_paths  # noqa: E402
from obsplan.planning.validation.verdict import metric_value  # noqa: E402
from obsplan.sweeps.spec import parse_path, set_fields  # noqa: E402

#: The verdicts shown against these baselines, on these metrics.
VERDICT_BASELINES = ("lawnmower", "circle")
VERDICT_METRICS = ("ekf.rmse_pos", "ekf.final_pos_err", "kf.rmse_pos", "kf.final_pos_err")

#: The planned beacon's verdicts against each beacon baseline (a moving-beacon problem's row).
BEACON_METRICS = ("ekf.rmse_pos_lines", "ekf.final_pos_err")

#: (column, verdict metric key) of the ratios reported.
RATIOS = (
    ("EKF rmse", "ekf.rmse_pos"),
    ("EKF final", "ekf.final_pos_err"),
    ("KF rmse", "kf.rmse_pos"),
    ("KF final", "kf.final_pos_err"),
    ("bound final", "crlb.final_pos_std"),
)


def _letter_of(d: dict) -> str:
    """``B``/``W`` decided better/worse, ``t`` a tie."""
    return {"better": "B", "worse": "W"}.get(d["outcome"], "t")


def parse_set(item: str) -> tuple[str, object]:
    """``SECTION.FIELD=VALUE`` -> ``(path, value)``, VALUE read as TOML (a bare word as a
    string); the path as a sweep axis's (:func:`obsplan.sweeps.spec.parse_path`)."""
    path, sep, text = item.partition("=")
    if not sep:
        raise SystemExit(f"--set {item!r}: expected SECTION.FIELD=VALUE, e.g. objective.mode=final")
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()
    parse_path(path.strip())
    return path.strip(), value


def with_fields(pb, sets: list[tuple[str, object]]):
    """``pb`` with the ``--set`` fields, through the problem file's own checks."""
    if not sets:
        return pb
    return problem_from_dict(set_fields(problem_to_dict(pb), dict(sets)))


def run_one(
    path: Path,
    runs: int | None,
    max_runs: int | None,
    open_loop: bool,
    truth_runs: int = 0,
    ekf_update: str | None = None,
    navigation: str | None = None,
    sets: list[tuple[str, object]] | None = None,
) -> dict:
    pb = with_fields(load_problem(path), sets or [])
    if navigation:
        pb = replace(pb, validation=replace(pb.validation, navigation=navigation))
    if open_loop:
        pb = replace(pb, validation=replace(pb.validation, mode="open-loop"))
    if ekf_update:
        pb = replace(pb, validation=replace(pb.validation, ekf_update=ekf_update))
    if pb.beacon_motion.motion == "planned":
        return beacon_row(path, pb, runs, max_runs)
    t0 = time.perf_counter()
    res = plan(pb, runs=runs, max_runs=max_runs)
    wall = time.perf_counter() - t0
    row: dict = {
        "problem": str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path),
        "objective": f"{pb.objective.kind}"
        + (f"/{pb.objective_mode}" if pb.objective.kind.endswith(("position", "std")) else ""),
        "status": res.solve.status,
        "success": bool(res.success),
        "converged_starts": sum(st.success for st in res.solve.starts),
        "starts": len(res.solve.starts),
        "solve_s": res.solve.wall_s,
        "wall_s": wall,
        "closest_m": res.metrics["planned"].closest_approach_m if res.trajectory else None,
        "beats_all": res.verdict.beats_all,
        "not_fitted": sorted(res.not_fitted),
        "lawnmower": {},
        "best": {},
        "mode": pb.validation.mode,
        "runs": None,
        "verdicts": {},
        "notes": list(res.verdict.notes),
        "solver_note": res.solve.note,
        "kf_guard": None if res.solve.kf_guard is None else res.solve.kf_guard.to_dict(),
        "ekf_guard": None if res.solve.ekf_guard is None else res.solve.ekf_guard.to_dict(),
    }
    v = res.validation
    if "planned" in v:
        r = v["planned"].result
        row["runs"] = int(r.runs)
        t = r.truth
        row["true_closest_m"] = t.closest_range_m
        row["runs_inside_min_range"] = t.runs_inside_min_range
        row["any_violation_fraction"] = t.any_violation_fraction
        row["violation_fraction"] = t.violation_fraction
        row["tracking_rmse_m"] = t.tracking_rmse_m
        row["baselines_true_closest_m"] = {
            k: x.result.truth.closest_range_m for k, x in v.items() if k != "planned"
        }
        if truth_runs:  # the plan alone, many runs: is min_range kept in >= 99.9 % of them?
            big = validate_paths({"planned": res.trajectory}, pb, runs=truth_runs, filters=("ekf",))
            tb = big["planned"].result.truth
            row["truth_runs"] = {
                "runs": tb.runs,
                "runs_inside_min_range": tb.runs_inside_min_range,
                "closest_range_m": tb.closest_range_m,
                "violation_fraction": tb.violation_fraction,
            }
        comps = res.verdict.comparisons
        # every decided loss, against every baseline compared (not only the two columns)
        row["losses"] = sorted(
            f"{b} {k}" for b, c in comps.items() for k in c if c[k].outcome == "worse"
        )
        for b in VERDICT_BASELINES:
            if b in comps:
                row["verdicts"][b] = {
                    k: {
                        "outcome": comps[b][k].outcome,
                        "ratio": comps[b][k].ratio,
                        "ci": comps[b][k].ci,
                    }
                    for k in VERDICT_METRICS
                }
    if "planned" in v:
        for _, key in RATIOS:
            p = metric_value(v["planned"], key)
            base = {k: metric_value(x, key) for k, x in v.items() if k != "planned"}
            lm = base.get("lawnmower")
            finite = [b for b in base.values() if b is not None]
            row["lawnmower"][key] = None if p is None or not lm else p / lm
            row["best"][key] = None if p is None or not finite else p / min(finite)
    return row


def beacon_row(path: Path, pb, runs: int | None, max_runs: int | None) -> dict:
    """The row of a problem whose beacon is planned (``obsplan plan``'s flow for it,
    :func:`~obsplan.planning.plan.plan_moving_beacon`): the vehicle flies the same path with
    every beacon, so the ratio columns (planned / lawn-mower) do not apply; the verdicts are the
    planned beacon's against each beacon baseline (``beacon_verdicts``), ``beacon-circle`` in the
    circle's column; the true closest approach is the vehicle's to the planned beacon."""
    t0 = time.perf_counter()
    res = plan_moving_beacon(pb, plan_beacon, runs=runs, max_runs=max_runs)
    wall = time.perf_counter() - t0
    truth = res.validation["planned"].result.truth
    comps = res.verdict.comparisons
    verdicts = {
        b: {
            k: {"outcome": c[k].outcome, "ratio": c[k].ratio, "ci": c[k].ci}
            for k in (*BEACON_METRICS, *VERDICT_METRICS)
            if k in c
        }
        for b, c in comps.items()
    }
    return {
        "problem": str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path),
        "objective": "planned beacon"
        + (" and vehicle, jointly" if res.joint is not None else "")
        + " (pcrb lines + final)",
        "status": res.solve.status,
        "success": bool(res.success),
        "solve_s": res.planning_s,
        "wall_s": wall,
        "closest_m": None,
        "beats_all": res.verdict.beats_all,
        "not_fitted": [],
        "lawnmower": {},
        "best": {},
        "mode": pb.validation.mode,
        "runs": int(res.validation["planned"].result.runs),
        "true_closest_m": truth.closest_range_m,
        # None where the distance is not checked on the true paths (3D: a horizontal distance)
        "runs_inside_min_range": (
            truth.runs_inside_min_range if truth.limits and truth.limits.min_range else None
        ),
        "any_violation_fraction": truth.any_violation_fraction,
        "violation_fraction": truth.violation_fraction,
        "verdicts": {"circle": {k: verdicts["beacon-circle"][k] for k in VERDICT_METRICS}},
        "beacon_verdicts": verdicts,
        "notes": list(res.verdict.notes),
    }


def beacon_letters(r: dict) -> str:
    """``beacon-fixed BB, beacon-circle Bt, ...``: EKF RMSE over the lines and EKF final."""
    return ", ".join(
        f"{b} " + "".join(_letter_of(d[k]) if k in d else "-" for k in BEACON_METRICS)
        for b, d in r["beacon_verdicts"].items()
    )


#: Number words of the page's sentences ("the twenty suite rows").
WORDS = (
    "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen "
    "fifteen sixteen seventeen eighteen nineteen twenty twenty-one twenty-two twenty-three "
    "twenty-four twenty-five twenty-six twenty-seven twenty-eight twenty-nine thirty"
).split()


def _word(n: int) -> str:
    return WORDS[n] if n < len(WORDS) else str(n)


def _cell(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def letters_of(r: dict) -> str:
    """The verdict letters against the lawn-mower and the circle (``BBBB / BtBB``)."""
    return " / ".join(
        "".join(_letter_of(d) for d in r["verdicts"].get(b, {}).values()) or "-"
        for b in VERDICT_BASELINES
    )


def _name(r: dict) -> str:
    return r["problem"].removeprefix("obsplan/").removeprefix("problems/")


def table_row(r: dict) -> str:
    """One row of the Markdown table."""
    lm = r["lawnmower"]
    t = r.get("truth_runs") or {}
    closest = _cell(t.get("closest_range_m", r.get("true_closest_m")))
    inside = t.get("runs_inside_min_range", r.get("runs_inside_min_range"))
    breaks = r.get("any_violation_fraction")
    cells = [
        f"`{_name(r)}`", r["objective"], r["status"], f"{r['solve_s']:.0f}",
        *(_cell(lm.get(k)) for _, k in RATIOS),
        "-" if r["runs"] is None else str(r["runs"]), closest,
        "-" if inside is None else str(inside),
        "-" if breaks is None else f"{100 * breaks:.0f} %", letters_of(r),
    ]  # fmt: skip
    return "| " + " | ".join(cells) + " |"


def beacon_sentences(rows: list[dict], earlier: dict[str, str] | None = None) -> list[str]:
    """A paragraph on the rows of planned beacons: their verdicts against every beacon
    baseline (none without such rows); ``earlier``: the verdicts an earlier paragraph gave, by
    problem (``"`name`"``), kept where ``rows`` has no new ones."""
    new = {
        f"`{_name(r)}`": f"`{_name(r)}` {beacon_letters(r)}" for r in rows if "beacon_verdicts" in r
    }
    merged = dict(earlier or {})
    merged.update(new)
    said = list(merged.values())
    if not said:
        return []
    return [
        f"{BEACON_PARAGRAPH} the vehicle flies its lawn-mower with every beacon (planned "
        "jointly: the planned vehicle with the planned beacon, the lawn-mower with every "
        "baseline and with `beacon-planned`, the craft planned alone for it), so the ratio "
        "columns do not apply; the circle's column is `beacon-circle`, the true closest "
        "approach (a range) and the runs inside `min_range` are the vehicle's to the planned "
        "craft over the validation's runs (not flown alone; `min_range` is the craft's "
        "`min_distance`, checked in 2D only: `-` in 3D), and the planned beacon's verdicts on "
        "the EKF's RMSE over the survey lines and its final error against each beacon "
        "baseline are: " + "; ".join(said) + ".",
        "",
    ]


#: How the paragraph on planned beacons begins (found again by ``--update-rows``).
BEACON_PARAGRAPH = 'Planned beacons (`beacon.motion = "planned"`):'


def update_page(text: str, rows: list[dict], command: str, wall_s: float) -> str:
    """``text`` (a page :func:`markdown_page` wrote) with the rows of ``rows`` replaced, or
    inserted after the shipped problems' rows, and a line saying which command wrote them; the
    other rows and the summary are left as the earlier command wrote them (the summary's
    counts and medians are of its own rows), the planned beacons' paragraph rewritten."""
    lines = text.rstrip("\n").split("\n")
    new = {f"| `{_name(r)}` |": table_row(r) for r in rows}
    # rows the page has are replaced where they stand (a suite row too, below the first suite
    # line); the others are inserted before the suite's rows
    present = {k for k in new if any(line.startswith(k) for line in lines)}
    everything = [r for r in rows if "beacon_verdicts" in r]
    out, inserted, kept = [], set(present), []
    earlier: dict[str, str] = {}
    for line in lines:
        if line.startswith(BEACON_PARAGRAPH):
            if not everything:  # no planned beacon re-run: its verdicts stay those of before
                kept = [line, ""]
            earlier = _beacon_verdicts_said(line)
            continue
        key = next((k for k in new if line.startswith(k)), None)
        if key is not None:
            out.append(new[key])
            continue
        if line.startswith("| `suite/") and not inserted >= set(new):
            out += [new[k] for k in new if k not in inserted]
            inserted |= set(new)
        out.append(line)
    missing = [new[k] for k in new if k not in inserted]
    if missing:
        raise SystemExit("--update-rows: the page has no table to put the rows in")
    names = ", ".join(f"`{_name(r)}`" for r in rows)
    note = (
        f"Rows of {names} by `{command}` ({wall_s / 60:.0f} min wall); the other rows and the "
        "summary by the command above."
    )
    ran = {f"`{_name(r)}`" for r in rows}
    out = [x for x in out if not (x.startswith("Rows of ") and _row_names(x) <= ran)]
    out.insert(1, note)
    tail = beacon_sentences(everything, earlier) if everything else kept
    return "\n".join(out).rstrip("\n") + "\n\n" + "\n".join(tail)


def _beacon_verdicts_said(paragraph: str) -> dict[str, str]:
    """The per-problem verdicts of a planned beacons' paragraph (:func:`beacon_sentences`), by
    problem (``"`name`"``)."""
    body = paragraph.split(" are: ", 1)[1].rstrip().removesuffix(".")
    return {seg.split(" ", 1)[0]: seg for seg in body.split("; ")}


def _row_names(note: str) -> set[str]:
    """The problems a ``Rows of ... by`` line names (a later run of all of them supersedes it)."""
    return set(re.findall(r"`[^`]+\.toml`", note.split(" by ", 1)[0]))


def markdown_page(rows: list[dict], command: str, wall_s: float) -> str:
    """The suite table and its summary as Markdown (the page ``docs/results/suite.md``
    includes)."""
    head = [
        "problem", "objective", "status", "solve [s]", "EKF RMSE", "EKF final", "KF RMSE",
        "KF final", "final bound", "runs", "plan's true closest, alone [m]",
        "runs inside `min_range`, alone", "breaks", "vs lawn-mower / circle",
    ]  # fmt: skip
    out = [
        f"Written by `{command}` ({wall_s / 60:.0f} min wall); ratios planned / lawn-mower.",
        "",
        "| " + " | ".join(head) + " |",
        "|---|---|---|" + "---:|" * (len(head) - 4) + "---|",
    ]
    for r in rows:
        out.append(table_row(r))
    suite = [r for r in rows if "/suite/" in r["problem"]] or rows
    med = []
    for col, key in RATIOS[:4]:
        vals = [r["lawnmower"][key] for r in suite if r["lawnmower"].get(key) is not None]
        if vals:
            med.append(f"{col} {statistics.median(vals):.2f}")
    decided = sum(
        bool(r["verdicts"])
        and all(d["outcome"] == "better" for b in r["verdicts"].values() for d in b.values())
        for r in rows
    )
    worse = [
        r["problem"].rsplit("/", 1)[-1]
        for r in rows
        if any(d["outcome"] == "worse" for b in r["verdicts"].values() for d in b.values())
    ]
    ahead = sum(r["beats_all"] and r["success"] for r in rows)
    out += [
        "",
        f"Medians over the {_word(len(suite))} suite rows, planned / lawn-mower: "
        + ", ".join(med)
        + f". {_word(ahead).capitalize()} of {_word(len(rows))} converged and are ahead of every "
        f"fitted baseline on every headline metric; {_word(decided)} of {_word(len(rows))} beat "
        "both the lawn-mower and the circle with every verdict decided at 95 %; a verdict is "
        f"decided against the plan on {_word(len(worse))}"
        + (f" ({', '.join(worse)})" if worse else "")
        + ".",
        "",
        *beacon_sentences(rows),
    ]
    return "\n".join(out)


def fmt(x: float | None) -> str:
    return "   -  " if x is None else f"{x:6.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", help="problem files (default: shipped and suite)")
    ap.add_argument("--runs", type=int, default=None, help="override validation.runs")
    ap.add_argument("--max-runs", type=int, default=None, help="override validation.max_runs")
    ap.add_argument("--open-loop", action="store_true", help="validate in open loop")
    ap.add_argument(
        "--truth-runs",
        type=int,
        default=0,
        metavar="N",
        help="also fly the plan alone N times (EKF only) and report its true closest approach "
        "and runs inside min_range",
    )
    ap.add_argument(
        "--ekf-update",
        choices=("first-order", "second-order"),
        help="override validation.ekf_update (the EKF's range update)",
    )
    ap.add_argument(
        "--navigation",
        choices=("ekf", "gsf"),
        help="override validation.navigation (the filter the vehicle steers on)",
    )
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument(
        "--markdown",
        metavar="FILE",
        help="also write the table and its summary as Markdown (the docs' suite page)",
    )
    ap.add_argument(
        "--update-rows",
        metavar="FILE",
        help="replace (or add) the rows of the problems run in FILE, a page --markdown wrote, "
        "keeping its other rows and its summary, and say which command wrote them",
    )
    ap.add_argument(
        "--objective",
        metavar="PREFIX",
        help="only the problems whose objective.kind starts with PREFIX (e.g. gramian, lwo)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help="change a field of every problem (repeatable), e.g. objective.mode=final",
    )
    args = ap.parse_args(argv)
    sets = [parse_set(item) for item in args.set]
    files = [Path(f).resolve() for f in args.files] or sorted((ROOT / "problems").glob("*.toml"))
    if not args.files:
        files += sorted((ROOT / "problems" / "suite").glob("*.toml"))
    if args.objective:
        files = [f for f in files if load_problem(f).objective.kind.startswith(args.objective)]
    rows = []
    t_start = time.perf_counter()
    head = (
        f"{'problem':34s} {'objective':34s} {'status':26s} {'solve':>6s}  "
        + "  ".join(f"{c:>13s}" for c, _ in RATIOS)
        + f"  {'closest':>7s} {'runs':>5s} {'true min':>8s} {'in':>3s} {'brk':>5s}"
        + "  lm/circle  verdict"
    )
    print("ratios planned/lawn-mower | planned/best baseline")
    print(head)
    print("-" * len(head))
    for f in files:
        r = run_one(
            f,
            args.runs,
            args.max_runs,
            args.open_loop,
            args.truth_runs,
            args.ekf_update,
            args.navigation,
            sets,
        )
        rows.append(r)
        cells = "  ".join(
            f"{fmt(r['lawnmower'].get(k))}|{fmt(r['best'].get(k))}" for _, k in RATIOS
        )
        letters = letters_of(r).replace(" ", "")
        # behind on a mean but not decided worse is a tie, not a loss; ahead on every mean
        # with a verdict not decided is not yet a win
        if "W" in letters:
            verdict = "LOSES"
        elif r["beats_all"]:
            verdict = "beats all" if "t" not in letters else "ahead, ties"
        else:
            verdict = "ties"
        if r["not_fitted"]:
            verdict += f" (not fitted: {', '.join(r['not_fitted'])})"
        closest = "-" if r["closest_m"] is None else f"{r['closest_m']:.1f}"
        truth = "    -        -   -     -"
        if r["runs"] is not None:
            truth = (
                f"{r['runs']:5d} {r['true_closest_m']:8.2f} "
                f"{'-' if r['runs_inside_min_range'] is None else r['runs_inside_min_range']:>3} "
                f"{100 * r['any_violation_fraction']:4.0f}%"
            )
        print(
            f"{r['problem'][-34:]:34s} {r['objective'][:34]:34s} {r['status'][:26]:26s} "
            f"{r['solve_s']:6.1f}  {cells}  {closest:>7s} {truth}  {letters:9s}  {verdict}",
            flush=True,
        )
        for note in r["notes"]:  # an EKF lost on the plan, a diagnostic objective
            print(f"    {note}", flush=True)
        if "beacon_verdicts" in r:  # EKF RMSE over the lines and final, per beacon baseline
            print(f"    {beacon_letters(r)}", flush=True)
        if "truth_runs" in r:
            tb = r["truth_runs"]
            print(
                f"    plan alone, {tb['runs']} runs: {tb['runs_inside_min_range']} inside "
                f"min_range, true closest {tb['closest_range_m']:.2f} m",
                flush=True,
            )
        if args.json:  # rows so far, so that an interrupted run keeps them
            Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    suite = [r for r in rows if "/suite/" in r["problem"]] or rows
    print()
    print(f"medians over {len(suite)} suite problems, planned / lawn-mower:")
    for col, key in RATIOS:
        vals = [r["lawnmower"][key] for r in suite if r["lawnmower"].get(key) is not None]
        if vals:
            print(f"  {col:12s} {statistics.median(vals):.3f}  (worst {max(vals):.3f})")
    wins = sum(r["beats_all"] and r["success"] for r in rows)
    print(
        f"solver success and ahead on the mean of every headline metric (decided or not): "
        f"{wins} of {len(rows)} problems"
    )
    decided = [
        r
        for r in rows
        if r["verdicts"]
        and all(d["outcome"] == "better" for b in r["verdicts"].values() for d in b.values())
    ]
    print(
        f"plan better than the lawn-mower and the circle on EKF/KF RMSE and final, every verdict "
        f"decided at 95 %: {len(decided)} of {len(rows)} problems"
    )
    worse = [
        Path(r["problem"]).stem
        for r in rows
        if any(d["outcome"] == "worse" for b in (r["verdicts"] or {}).values() for d in b.values())
    ]
    print(
        f"a verdict decided against the plan (W) on {len(worse)} of {len(rows)} problems"
        + (f": {', '.join(worse)}" if worse else "")
    )
    kept = []
    for r in rows:  # the plan-alone runs when there are, else the validation's
        t = r.get("truth_runs") or (
            None
            if r["runs"] is None
            else {"runs": r["runs"], "runs_inside_min_range": r["runs_inside_min_range"]}
        )
        inside = None if t is None else t["runs_inside_min_range"]
        if inside is not None and inside <= 0.001 * t["runs"]:
            kept.append(r)
    print(f"plan's true path outside min_range in >= 99.9 % of runs: {len(kept)} of {len(rows)}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    command = "python benchmarks/bench_planning_suite.py " + " ".join(
        a for a in (argv if argv is not None else sys.argv[1:])
    )
    if args.update_rows:
        page = Path(args.update_rows)
        page.write_text(
            update_page(
                page.read_text(encoding="utf-8"),
                rows,
                command.strip(),
                time.perf_counter() - t_start,
            ),
            encoding="utf-8",
        )
        print(f"updated {args.update_rows}")
    if args.markdown:
        Path(args.markdown).write_text(
            markdown_page(rows, command.strip(), time.perf_counter() - t_start), encoding="utf-8"
        )
        print(f"wrote {args.markdown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
