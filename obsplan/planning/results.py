"""What planning and validating return: the numbers a script lives on, in words, figures and files.

:class:`ValidationResult` is a path validated as ``obsplan plan`` validates its plan
(:func:`~obsplan.planning.plan.validate`): the path as ``planned`` beside every baseline, their
metrics, the Monte Carlo of each, the verdict and the robustness row. :class:`PlanResult`
(:func:`~obsplan.planning.plan.plan`) is that and the solve: the keep-out margins, the replanned
Monte Carlo when asked for, the wall time.

Both are frozen and picklable and carry what the command line shows: ``summary()`` (the printed
table and the verdict in words), ``plot(kind)`` (the figures of :mod:`obsplan.planning.figures`,
``ax`` for one panel), ``to_dict()`` (``report.json``), ``save(folder)`` (the files of ``obsplan
plan``: ``plan.csv``, ``report.json``, the figures), a one-line ``repr`` and a small HTML table
for notebooks. ``obsplan plan`` prints :meth:`PlanResult.summary` and writes
:meth:`PlanResult.write_files` into its output folder.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
from matplotlib.figure import Figure

from obsplan.core.errors import ConfigError
from obsplan.core.outputs import OutputDir
from obsplan.estimation.channel import LOST_FACTOR
from obsplan.model.beacon import BeaconPath, write_beacon_csv
from obsplan.planning.baselines.beacon import BeaconBaseline
from obsplan.planning.baselines.vehicle import Baseline
from obsplan.planning.beacon_replan import BeaconReplanResult, BeaconSamples
from obsplan.planning.figures import (
    plot_beacon_paths,
    plot_filter_errors,
    plot_gramian_eigs,
    plot_paths,
    plot_speed,
    save_figure,
)
from obsplan.planning.missions.check import MissionCheck
from obsplan.planning.missions.schedule import mission_schedule, planner_schedule
from obsplan.planning.objectives.evaluate import PathMetrics
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.validation_setup import channel_dict
from obsplan.planning.replan import ReplanResult
from obsplan.planning.solver.margins import KeepoutReport
from obsplan.planning.solver.solve import SolveResult
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.stress import Robustness, stress_problem
from obsplan.planning.validation.validate import PathValidation
from obsplan.planning.validation.verdict import (
    Verdict,
    metric_value,
    objective_notes,
    stress_notes,
    verdict,
)
from obsplan.trajectory.sampled import Trajectory, write_csv, write_geodetic_samples

#: The figures ``obsplan plan`` writes, by the ``kind`` of :meth:`ValidationResult.plot`:
#: ``filters`` only with a validation, ``speed`` only with a ``[mission]``.
FIGURES = {
    "path": "path.png",
    "gramian": "gramian.png",
    "filters": "filters.png",
    "speed": "speed.png",
}
#: The columns of the summary table: title, width (the first left-aligned, the rest right).
_COLUMNS = (
    ("path", 16),
    ("objective", 10),
    ("PCRB avg", 9),
    ("PCRB fin", 9),
    ("EKF rmse", 9),
    ("EKF fin", 8),
    ("KF rmse", 8),
    ("closest", 8),
    ("limits", 6),
    ("true min", 8),
    ("in min_r", 8),
    ("breaks", 7),
)
_MISSION_COLUMNS = (("EKF lines", 9), ("mission", 8))


def _fmt(x: float | None, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, spec)


def _text_row(cells: list[str], widths: list[int]) -> str:
    return " ".join(
        f"{c:<{w}}" if i == 0 else f"{c:>{w}}"
        for i, (c, w) in enumerate(zip(cells, widths, strict=True))
    )


@dataclass(frozen=True, eq=False, repr=False)
class ValidationResult:
    """A path validated against the baselines as ``obsplan plan`` validates its plan.

    Returned by :func:`~obsplan.planning.plan.validate`; :class:`PlanResult` extends it with the
    solve.

    Attributes
    ----------
    problem : PlanningProblem
    trajectory : Trajectory or None
        The path validated as ``"planned"`` (the plan; None when no feasible path was found).
    baselines : dict[str, Baseline]
    metrics : dict[str, PathMetrics]
        ``"planned"`` (when there is a path) and every baseline, computed the same way.
    validation : dict[str, PathValidation]
        Monte Carlo per path (empty when not run).
    not_fitted : dict[str, str]
        Baselines the problem cannot fit, with the reason.
    robustness : Robustness or None
        Every path re-validated at ``validation.stress_*``
        (:mod:`obsplan.planning.validation.stress`).
    missions : dict[str, MissionCheck]
        Per path, the independent mission check (empty without a ``[mission]``).
    """

    problem: PlanningProblem
    trajectory: Trajectory | None
    baselines: dict[str, Baseline]
    metrics: dict[str, PathMetrics]
    validation: dict[str, PathValidation]
    not_fitted: dict[str, str] = field(default_factory=dict)
    robustness: Robustness | None = None
    missions: dict[str, MissionCheck] = field(default_factory=dict)

    # ------------------------------------------------------------------------------ numbers
    @property
    def verdict(self) -> Verdict:
        """The plan against every validated baseline (:mod:`obsplan.planning.validation.verdict`);
        with a mission, only against the paths that complete it."""
        val = dict(self.validation)
        not_fitted = dict(self.not_fitted)
        for name, chk in self.missions.items():
            if not chk.complete and name in val and name != "planned":
                del val[name]
                not_fitted[name] = "does not complete the mission (not compared)"
        survey = self.problem.mission is not None and bool(self.problem.mission.lines)
        runs = int(val["planned"].result.runs) if "planned" in val else 0
        notes = (*objective_notes(self.problem), *stress_notes(self.metrics, runs))
        return verdict(
            val,
            not_fitted,
            notes,
            lines=survey,
            keepout_confidence=self.problem.limits.keepout_confidence,
            objective=self.problem.objective,
        )

    def paths(self) -> dict[str, Trajectory]:
        """``planned`` (when there is a path) then every baseline.

        Returns
        -------
        dict of str to Trajectory
            Name -> path, in that order: the paths the figures draw.
        """
        out: dict[str, Trajectory] = {}
        if self.trajectory is not None:
            out["planned"] = self.trajectory
        out.update({k: b.trajectory for k, b in self.baselines.items()})
        return out

    def validation_dict(self) -> dict:
        """``report.json``'s ``validation``: ``mode`` (``"closed-loop"`` or ``"open-loop"``),
        ``channel`` (:func:`channel_dict`) and one entry per validated path (empty when no
        validation was run).

        Returns
        -------
        dict
            ``{"mode": ..., <path>: <its Monte Carlo's dict>, ...}``, or ``{}``; JSON-serialisable.
        """
        return validation_report(self.problem, self.validation)

    def to_dict(self) -> dict:
        """The keys of ``report.json`` that a validation fills: ``metrics``, ``validation``,
        ``verdict``, ``problem``, ``baselines``, ``baselines_not_fitted``, ``mission``,
        ``problem_file``, ``robustness`` (and ``origin`` for a geodetic problem), with the values
        ``obsplan plan`` writes for its plan.

        Returns
        -------
        dict
            JSON-serialisable with ``allow_nan=False``.
        """
        return self._report(None)

    def _report(self, plan: PlanResult | None) -> dict:
        """report.json in its key order; the solve's keys from ``plan``."""
        pb = self.problem
        out: dict = {} if plan is None else {"solver": plan.solve.to_dict()}
        out.update(
            {
                "metrics": {k: m.to_dict() for k, m in self.metrics.items()},
                "validation": self.validation_dict(),
                "verdict": self.verdict.to_dict(),
                "problem": {
                    "name": pb.name,
                    "dim": pb.dim,
                    "sensors": list(pb.vehicle.sensors),
                    "current": pb.vehicle.current,
                    "objective": pb.objective.kind,
                    "objective_mode": pb.objective_mode,
                    "steps": pb.horizon.steps,
                    "duration_s": pb.horizon.duration,
                    "scales": {"length_m": pb.scales.length_m, "time_s": pb.scales.time_s},
                    "schedule": _schedule_dict(pb),
                },
                "baselines": {k: b.description for k, b in self.baselines.items()},
                "baselines_not_fitted": dict(self.not_fitted),
                "mission": {k: c.to_dict() for k, c in self.missions.items()},
                "problem_file": pb.to_dict(),
            }
        )
        if plan is not None:
            out["keepout"] = None if plan.keepout is None else plan.keepout.to_dict()
        out["robustness"] = None if self.robustness is None else self.robustness.to_dict()
        if plan is not None:
            out["wall_s"] = float(plan.wall_s)
            if plan.replan is not None:
                out["replan"] = plan.replan.to_dict()
        if pb.origin is not None:
            out["origin"] = pb.origin.to_dict()
        return out

    # ------------------------------------------------------------------------------- words
    def _table_cells(self) -> tuple[list[tuple[str, int]], list[list[str]]]:
        """The summary table's columns and rows, as the text table shows them."""
        missions = self.missions
        columns = list(_COLUMNS) + (list(_MISSION_COLUMNS) if missions else [])
        rows = []
        for name, m in self.metrics.items():
            v = self.validation.get(name)
            r = v.result if v is not None else None
            ekf = r.ekf if r is not None else None
            kf = r.kf if r is not None else None
            truth = r.truth if r is not None else None
            cells = [
                name,
                _fmt(m.objective),
                _fmt(m.pcrb_mean_pos_std),
                _fmt(m.pcrb_final_pos_std),
                _fmt(ekf.rmse_pos if ekf else None),
                _fmt(ekf.final_pos_err if ekf else None),
                _fmt(kf.rmse_pos if kf else None),
                _fmt(m.closest_approach_m, ".1f"),
                "ok" if m.within_limits else "NO",
                _fmt(truth.closest_range_m if truth else None, ".2f"),
                "-" if truth is None else str(truth.runs_inside_min_range),
                "-" if truth is None else f"{100 * truth.any_violation_fraction:.1f}%",
            ]
            if missions:
                lines_rmse = metric_value(v, "ekf.rmse_pos_lines") if v is not None else None
                done = missions[name].complete if name in missions else None
                cells += [_fmt(lines_rmse), "-" if done is None else ("done" if done else "NOT")]
            rows.append(cells)
        return columns, rows

    def table(self) -> str:
        """Planned vs baselines: objective, bounds, Monte Carlo errors [m], closest approach [m]
        of the path and of the true paths over all runs, runs inside ``min_range``, runs
        breaking any limit on their true path [%] (with a mission: the EKF RMSE over the lines
        and whether the path completes it); the lines under it name the validation.

        Returns
        -------
        str
            The table ``obsplan plan`` prints, one line per path.
        """
        columns, rows = self._table_cells()
        widths = [w for _, w in columns]
        head = _text_row([c for c, _ in columns], widths)
        lines = [head, "-" * len(head)] + [_text_row(cells, widths) for cells in rows]
        if self.validation:
            r0 = next(iter(self.validation.values())).result
            lines.append(
                f"validation: {r0.mode}, {r0.runs} runs per path; 'true min' is the closest "
                "approach of the true paths over all runs, 'breaks' the runs whose true path "
                "breaks a limit"
            )
            for name, v in self.validation.items():
                broken = "" if v.result.truth is None else v.result.truth.breaks_words()
                if broken:
                    lines.append(f"  {name}: the true path breaks {broken} of the runs")
            lines += channel_lines(self.problem, self.validation)
        return "\n".join(lines)

    def summary(self) -> str:
        """The table and the verdict in words (and the robustness row's), as ``obsplan plan``
        prints them.

        Returns
        -------
        str
            Lines for the terminal.
        """
        lines = [self.table(), *self.verdict.summary()]
        if self.robustness is not None:
            r = self.robustness
            lines.append(f"robustness ({r.condition}, not replanned):")
            lines += [f"  {line}" for line in r.verdict.summary()]
            spb = stress_problem(self.problem)
            lines += [f"  {line}" for line in channel_lines(spb, r.validation)]
        return "\n".join(lines)

    def _headline(self) -> str:
        pb = self.problem
        return f"{pb.name or 'problem'}: {pb.objective.kind}, N = {pb.horizon.steps}"

    def _verdict_word(self) -> str:
        if not self.validation:
            return "not validated"
        v = self.verdict
        runs = f"{v.runs} runs"
        if v.beats_all_decided:
            return f"beats every baseline ({runs})"
        if v.beats_all:
            return f"ahead of every baseline, with ties ({runs})"
        return f"does not beat every baseline ({runs})"

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self._headline()}: {self._verdict_word()}>"

    def _repr_html_(self) -> str:
        columns, rows = self._table_cells()
        esc = html.escape
        head = "".join(f"<th>{esc(c)}</th>" for c, _ in columns)
        body = "".join(
            "<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>" for cells in rows
        )
        words = "<br>".join(esc(s) for s in self.verdict.summary())
        return (
            f"<p><b>{esc(type(self).__name__)}</b> {esc(self._headline())}</p>"
            f"<table><tr>{head}</tr>{body}</table><p>{words}</p>"
        )

    # ----------------------------------------------------------------------------- figures
    def _figures(self) -> dict[str, Callable[..., Figure]]:
        """The figures ``obsplan plan`` writes, by kind, each a function of ``ax``."""
        pb, paths = self.problem, self.paths()
        out: dict[str, Callable[..., Figure]] = {
            "path": lambda ax=None: plot_paths(paths, pb, ax=ax),
            "gramian": lambda ax=None: plot_gramian_eigs(paths, pb, ax=ax),
        }
        ship = pb.beacon_path
        if ship is not None:  # the vehicle and the beacon on its known path, range links
            flown = next(iter(paths.values()))
            out = {"path": lambda ax=None: plot_beacon_paths(flown, {"beacon": ship}, pb, ax=ax)}
        if self.validation:
            val = self.validation
            out["filters"] = lambda ax=None: plot_filter_errors(val, ax=ax, problem=pb.name)
        if pb.mission is not None:
            out["speed"] = lambda ax=None: plot_speed(paths, pb, ax=ax)
        return out

    def plot(self, kind: str = "path", ax=None) -> Figure | dict[str, Figure]:
        """A figure of ``obsplan plan`` (:mod:`obsplan.planning.figures`).

        Parameters
        ----------
        kind : str, default "path"
            ``"path"`` (the paths with the beacon, the limits and the mission; in 3D a depth
            panel beside it unless ``ax`` is given), ``"gramian"`` (the smallest eigenvalue of
            the scaled Gramian over time), ``"filters"`` (the filters' position RMSE and the
            bound over time; needs a validation), ``"speed"`` (speed over time; needs a
            ``[mission]``), or ``"all"``: each of those the command line writes.
        ax : matplotlib.axes.Axes or None, default None
            A matplotlib Axes to draw into (one kind only); None: a new figure.

        Returns
        -------
        Figure or dict[str, Figure]
            The figure drawn (``ax.figure`` when ``ax`` is given); for ``"all"``, the figures by
            kind. Nothing is shown or saved.

        Raises
        ------
        ConfigError
            An unknown kind, one this result cannot draw, or ``ax`` with ``"all"``.
        """
        figures = self._figures()
        if kind == "all":
            if ax is not None:
                raise ConfigError('plot("all") makes one figure per kind: give no ax')
            return {k: make() for k, make in figures.items()}
        if kind not in FIGURES:
            raise ConfigError(f"plot kind {kind!r}: one of {', '.join((*FIGURES, 'all'))}")
        if kind not in figures:
            why = "no validation was run" if kind == "filters" else "the problem has no [mission]"
            raise ConfigError(f"plot kind {kind!r}: {why}")
        return figures[kind](ax=ax)

    # ------------------------------------------------------------------------------- files
    def write_files(self, folder: str | Path) -> list[Path]:
        """Write ``plan.csv`` (when there is a path), ``report.json`` and the figures into
        ``folder``, as ``obsplan plan`` does (no protection of what is there: :meth:`save`);
        with a beacon on a known path, ``beacon.csv`` too (``t,bx,by[,bz],vbx,vby[,vbz]``: the
        path at the plan's samples, its velocity that of the segment starting there).

        With a geodetic problem (an ``[origin]``) ``plan-geodetic.csv`` has the path as time,
        latitude, longitude[, depth] and speed.

        Parameters
        ----------
        folder : str or Path
            Created if missing; files of the same names are replaced.

        Returns
        -------
        list of Path
            The files written, in order.
        """
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        written: list[Path] = []
        pb = self.problem
        if self.trajectory is not None:
            written.append(write_csv(self.trajectory, out / "plan.csv"))
            if pb.origin is not None:
                written.append(
                    write_geodetic_samples(self.trajectory, pb.origin, out / "plan-geodetic.csv")
                )
        ship = pb.beacon_path
        if ship is not None and self.trajectory is not None:  # the known path on the plan's grid
            t = self.trajectory.t
            written.append(
                write_beacon_csv(out / "beacon.csv", t, ship.position(t), ship.velocity(t))
            )
        written.append(_write_report(out, self.to_dict()))
        for kind, make in self._figures().items():  # one at a time: drawn, saved, closed
            written.append(save_figure(make(), out / FIGURES[kind]))
        return written

    def save(self, folder: str | Path, *, force: bool = False) -> list[Path]:
        """Save the files of ``obsplan plan`` into ``folder``, whole or not at all.

        The folder is checked and replaced as the command line's ``--out`` is
        (:class:`~obsplan.core.outputs.OutputDir`): a new or empty folder, or with ``force`` an
        earlier obsplan output, replaced whole; any other folder is refused.

        Parameters
        ----------
        folder : str or Path
            The output folder.
        force : bool, default False
            Replace an earlier obsplan output folder (its old files removed).

        Returns
        -------
        list of Path
            The files written (:meth:`write_files`), at their final place.

        Raises
        ------
        InputError
            A non-empty folder without ``force``, or one that is not an obsplan output.
        """
        return _save_whole(folder, force, self.write_files)


@dataclass(frozen=True, eq=False, repr=False, kw_only=True)
class PlanResult(ValidationResult):
    """Everything ``obsplan plan`` reports: the solve, and the plan validated against the
    baselines (:class:`ValidationResult`).

    Attributes
    ----------
    solve : SolveResult
        Multi-start outcome (status, iterations, wall time, every start); ``trajectory`` is its
        path.
    wall_s : float
        Total time [s].
    keepout : KeepoutReport or None
        How the plan keeps its limits with the keep-out margins
        (:mod:`obsplan.planning.solver.margins`).
    replan : ReplanResult or None
        The receding-horizon replanned Monte Carlo (``plan(..., replan=EVERY)``;
        :mod:`obsplan.planning.replan`).
    """

    solve: SolveResult
    wall_s: float
    keepout: KeepoutReport | None = None
    replan: ReplanResult | None = None

    @property
    def success(self) -> bool:
        """The flown path is a converged solution of the problem it was last solved for
        (``solve.success``; the exit code of ``obsplan plan``)."""
        return self.solve.success and self.trajectory is not None

    def to_dict(self) -> dict:
        """``report.json`` (stable keys ``solver``, ``metrics``, ``validation``; then
        ``verdict``, ``problem``, ``baselines``, ``baselines_not_fitted``, ``mission``,
        ``problem_file``, ``keepout``, ``robustness``, ``wall_s``, and ``replan`` / ``origin``
        when there are).

        Returns
        -------
        dict
            JSON-serialisable with ``allow_nan=False``.
        """
        return self._report(self)

    def header(self) -> str:
        """The first lines ``obsplan plan`` prints: the solve's status, starts and times, its
        note, and the keep-out margins.

        Returns
        -------
        str
            Lines for the terminal: the status line, a ``note:`` line when the solve has one, a
            ``start LABEL:`` line with the reason of each start that did not converge, a
            ``keep-out`` line when margins were applied.
        """
        s, pb = self.solve, self.problem
        converged = sum(st.success for st in s.starts)
        lines = [
            f"{pb.name or 'problem'}: {pb.objective.kind}, N = {pb.horizon.steps}: {s.status} "
            f"({converged} of {len(s.starts)} starts converged; plan from {s.chosen}), "
            f"{s.wall_s:.1f} s solve, {self.wall_s:.1f} s total"
        ]
        if s.note:
            lines.append(f"note: {s.note}")
        lines.extend(
            f"start {st.label}: {st.note}" for st in s.starts if not st.success and st.note
        )
        k = self.keepout
        if k is not None and k.k > 0:
            lines.append(
                f"keep-out at {k.confidence:.4g} confidence: margins up to "
                f"{k.max_range_margin_m:.2f} m "
                f"(range), {k.max_box_margin_m:.2f} m (area/depth), up to "
                f"{k.max_accel_reserve:.0%} of the acceleration kept for the guidance; "
                f"{k.rounds} re-solve(s), "
                + ("held" + (f" ({k.note})" if k.note else "") if k.held else f"NOT held: {k.note}")
            )
        return "\n".join(lines)

    def summary(self) -> str:
        """What ``obsplan plan`` prints (but the files it wrote): :meth:`header`, the table and
        the verdict in words (:meth:`ValidationResult.summary`), and the replanned Monte
        Carlo's lines.

        Returns
        -------
        str
            Lines for the terminal.
        """
        lines = [self.header(), super().summary()]
        if self.replan is not None:
            lines += self.replan.summary()
        return "\n".join(lines)

    def _verdict_word(self) -> str:
        return f"{self.solve.status}, {super()._verdict_word()}"


def _write_report(out: Path, report: dict) -> Path:
    """``out/report.json``: strict JSON (a NaN is a bug, not a number), indented."""
    path = out / "report.json"
    path.write_text(json.dumps(report, indent=2, allow_nan=False) + "\n")
    return path


def _save_whole(
    folder: str | Path, force: bool, write_files: Callable[[Path], list[Path]]
) -> list[Path]:
    """``write_files`` into ``folder`` whole or not at all, as the command line's ``--out``
    (:class:`~obsplan.core.outputs.OutputDir`): an error or Ctrl-C while writing leaves no
    folder, or an old one untouched."""
    out = OutputDir(folder, force, option="folder", verb="plan", force_option="force=True")
    with out:
        written = [out.final(p) for p in write_files(out.stage())]
        out.commit()
    return written


def validation_report(pb: PlanningProblem, validation: Mapping[str, PathValidation]) -> dict:
    """``report.json``'s ``validation`` of a vehicle's or a beacon's plan: ``mode``
    (``"closed-loop"`` or ``"open-loop"``), ``channel``
    (:func:`~obsplan.planning.problem.validation_setup.channel_dict`) and one entry per
    validated path.

    Parameters
    ----------
    pb : PlanningProblem
        The problem (its ``[validation]``).
    validation : mapping of str to PathValidation
        The validated paths.

    Returns
    -------
    dict
        JSON-serialisable; empty when no validation was run.
    """
    if not validation:
        return {}
    return {
        "mode": pb.validation.mode,
        "channel": channel_dict(pb),
        **{k: v.to_dict() for k, v in validation.items()},
    }


def channel_lines(pb: PlanningProblem, validation: Mapping[str, PathValidation]) -> list[str]:
    """Under a channel with faults: the channel in words and, per path, each filter's ranges
    used and rejected (means per run) and its lost runs (``report.json``'s keys); nothing
    under the ideal channel.

    Parameters
    ----------
    pb : PlanningProblem
        The problem (its ``validation.channel``).
    validation : mapping of str to PathValidation
        The validated paths.

    Returns
    -------
    list of str
        Lines for the terminal.
    """
    channel = pb.validation.channel_model()
    if channel.is_ideal or not validation:
        return []
    info = channel_dict(pb)
    gate = "no gate" if info["gate"] is None else f"gate at {info['gate']:g}"
    scale = ", a range-scale state" if info["scale_state"] else ""
    scale += ", a range-bias state" if info["bias_state"] else ""
    lines = [
        f"channel {channel.name}: {channel.describe()}, unknown to the filters ({gate}{scale}); "
        "per run, ranges used / rejected, and runs lost (final error > "
        f"{LOST_FACTOR:g}x the bound):"
    ]
    for name, v in validation.items():
        cells = []
        for f in v.result.filters or {}:
            d = v.result.filter_dict(f) or {}
            cells.append(
                f"{f} {_fmt(d.get('ranges_used'), '.0f')} / "
                f"{_fmt(d.get('ranges_rejected'), '.0f')}, lost {d.get('lost_runs')}"
            )
        lines.append(f"  {name}: " + "; ".join(cells))
    return lines


def _schedule_dict(pb: PlanningProblem) -> dict | None:
    """The mission's schedules: the lawn-mower's speed, the planner's line speed and lead-in."""
    if pb.mission is None:
        return None
    base, lead = mission_schedule(pb.mission_context), planner_schedule(pb.mission_context)
    return {
        "lawnmower_speed_mps": float(base.speed),
        "planner_speed_mps": float(lead.speed),
        "lead_in_s": float(lead.lead_in),
        "headroom": float(base.headroom),
    }


# ---------------------------------------------------------------------------------- moving beacon
class BeaconSolve(BeaconSamples, Protocol):
    """What :class:`BeaconPlanResult` reads of a beacon planner's result
    (``obsplan.planning.beacon``'s ``BeaconPlan``): its samples
    (:class:`~obsplan.planning.beacon_replan.BeaconSamples`) and its solve."""

    @property
    def success(self) -> bool: ...

    @property
    def status(self) -> str: ...

    @property
    def iterations(self) -> int: ...

    @property
    def wall_s(self) -> float: ...

    @property
    def objective(self) -> float | None: ...


#: The metrics a planned beacon is judged on against each beacon baseline (the first is the
#: survey's when the vehicle has lines, else the whole path's).
BEACON_HEADLINE: tuple[str, ...] = ("ekf.rmse_pos_lines", "ekf.rmse_pos", "ekf.final_pos_err")
_BEACON_COLUMNS = (
    ("beacon", 14),
    ("PCRB avg", 9),
    ("PCRB fin", 9),
    ("EKF rmse", 9),
    ("EKF lines", 9),
    ("EKF fin", 8),
    ("KF rmse", 8),
    ("limits", 6),
    ("planned", 7),
)


@dataclass(frozen=True, eq=False)
class BeaconBound:
    """The posterior CRB of the vehicle's position with one beacon path [m]: its mean over the
    path, over the survey lines (None without lines) and its final value."""

    mean_pos_std: float
    lines_pos_std: float | None
    final_pos_std: float

    def to_dict(self) -> dict:
        """``report.json``'s ``metrics`` entry of a beacon path.

        Returns
        -------
        dict
            ``pcrb_mean_pos_std``, ``pcrb_lines_pos_std``, ``pcrb_final_pos_std`` [m].
        """
        return {
            "pcrb_mean_pos_std": self.mean_pos_std,
            "pcrb_lines_pos_std": self.lines_pos_std,
            "pcrb_final_pos_std": self.final_pos_std,
        }


#: The name, in a joint plan's report, of the beacon planned alone for the vehicle's lawn-mower
#: (the first round): what obsplan plans without moving the vehicle, compared like a baseline.
ALONE = "beacon-planned"


@dataclass(frozen=True, eq=False)
class JointPlan:
    """The vehicle and the beacon planned jointly (``beacon.motion = "planned"`` without
    ``vehicle.path``): the rounds of :func:`~obsplan.planning.plan.plan_moving_beacon`.

    Attributes
    ----------
    vehicle_solve : SolveResult or None
        The vehicle planner's solve of the last kept round (the vehicle planned for the beacon
        path before it); None when no round was kept (the vehicle flies the lawn-mower).
    objectives : tuple of float
        The beacon planner's objective [m²] (the vehicle's weighted position variance,
        :mod:`~obsplan.planning.beacon.recursion`) after each round, the first the beacon
        planned for the lawn-mower; kept rounds only.
    stop : str
        Why the rounds stopped, in words.
    """

    vehicle_solve: SolveResult | None
    objectives: tuple[float, ...]
    stop: str

    @property
    def rounds(self) -> int:
        """Rounds kept (0: the lawn-mower with its planned beacon)."""
        return len(self.objectives) - 1

    def to_dict(self) -> dict:
        """``report.json``'s ``solver.joint``.

        Returns
        -------
        dict
            ``rounds``, ``objectives`` [m²], ``stop`` and the vehicle solve's ``success``,
            ``status``, ``iterations`` (None without a kept round).
        """
        v = self.vehicle_solve
        return {
            "rounds": self.rounds,
            "objectives": [float(x) for x in self.objectives],
            "stop": self.stop,
            "vehicle": None
            if v is None
            else {
                "success": bool(v.success),
                "status": str(v.status),
                "iterations": int(v.iterations),
            },
        }


def truth_distance_notes(validation: Mapping[str, PathValidation]) -> tuple[str, ...]:
    """A sentence per beacon path whose Monte Carlo's true vehicle paths broke the distance
    limits between the craft and the vehicle (``min_range`` and ``max_range`` of
    :func:`~obsplan.planning.problem.validation_setup.truth_limits`): the nominal paths keep
    them, the true ones stray from them by the estimation and tracking errors.

    Parameters
    ----------
    validation : Mapping of str to PathValidation
        Every beacon path's validation.

    Returns
    -------
    tuple of str
        The sentences, in the order of ``validation`` (none when no run broke them).
    """
    words = {
        "min_range": "came closer than the craft's min_distance",
        "max_range": "went beyond the largest range",
    }
    out = []
    for name, val in validation.items():
        tr = val.result.truth
        if tr is None or tr.limits is None:
            continue
        viol, excess = tr.violations(), tr.worst_excess
        said = [
            f"{words[k]} ({getattr(tr.limits, k):g} m) on {int(np.sum(viol[k]))} of {tr.runs} "
            f"runs (by up to {excess.get(k, 0.0):.2g} m)"
            for k in words
            if k in viol and np.any(viol[k])
        ]
        if said:
            out.append(f"with the {name} beacon the vehicle's true path " + " and ".join(said))
    return tuple(out)


@dataclass(frozen=True, eq=False, repr=False)
class BeaconPlanResult:
    """What ``obsplan plan`` reports for a planned beacon serving a vehicle on a given path, or
    planned jointly with the vehicle.

    Attributes
    ----------
    problem : PlanningProblem
        A problem with ``beacon.motion = "planned"``.
    vehicle : Trajectory
        The vehicle's path (``plan.csv``), on the planning grid or the file's: ``vehicle.path``,
        or the path planned jointly with the beacon.
    solve : BeaconSolve
        The beacon planner's result: the planned beacon path, status, iterations, time.
    baselines : dict[str, BeaconBaseline]
        The beacon baselines by name (:data:`~obsplan.planning.baselines.beacon.BEACON_BASELINES`).
    bounds : dict[str, BeaconBound]
        ``"planned"`` and every baseline: the vehicle's posterior CRB with that beacon.
    validation : dict[str, PathValidation]
        ``"planned"`` and every baseline: the Monte Carlo of the vehicle's filters on its path
        with that beacon (same runs and seeds: paired); empty without validation.
    lines : bool
        The vehicle has survey lines (``ekf.rmse_pos_lines`` is compared).
    wall_s : float
        Total time [s].
    planned_breaks : str
        The craft's limits the planned path breaks, in words (empty: none;
        :func:`~obsplan.planning.baselines.beacon.craft_limit_breaks`).
    planning_s : float
        Time [s] the flow took to plan: the baselines, the planner and the bounds (not the
        validation); NaN when not measured.
    distance_margin_m : float
        The largest margin [m] the planned craft keeps beyond ``min_distance`` from the vehicle's
        nominal path so that its true path keeps it at ``limits.keepout_confidence``
        (:func:`~obsplan.planning.solver.margins.craft_distance_margins`); 0: none kept.
    baseline_vehicle : Trajectory or None
        Planned jointly: the path the vehicle flies with the beacon baselines (its mission's
        lawn-mower, what it would fly without obsplan); None: ``vehicle``.
    joint : JointPlan or None
        Planned jointly: the rounds; None otherwise.
    beacon_alone : BeaconPath or None
        Planned jointly: the beacon planned alone for the vehicle's lawn-mower (the first
        round), compared as :data:`ALONE`; None otherwise.
    replan : BeaconReplanResult or None
        The craft re-planned every ``--replan`` seconds in the closed-loop Monte Carlo, beside
        the one-shot planned beacon (:mod:`obsplan.planning.beacon_replan`); None: not asked.
    """

    problem: PlanningProblem
    vehicle: Trajectory
    solve: BeaconSolve
    baselines: dict[str, BeaconBaseline]
    bounds: dict[str, BeaconBound]
    validation: dict[str, PathValidation]
    lines: bool
    wall_s: float
    planned_breaks: str = ""
    planning_s: float = math.nan
    distance_margin_m: float = 0.0
    baseline_vehicle: Trajectory | None = None
    joint: JointPlan | None = None
    beacon_alone: BeaconPath | None = None
    replan: BeaconReplanResult | None = None

    @property
    def success(self) -> bool:
        """The beacon planner converged, and so did the vehicle planner where a joint round was
        kept (the exit code of ``obsplan plan``)."""
        v = None if self.joint is None else self.joint.vehicle_solve
        return bool(self.solve.success) and (v is None or bool(v.success))

    @property
    def trajectory(self) -> Trajectory:
        """The vehicle's path (what ``plan.csv`` holds)."""
        return self.vehicle

    def beacons(self) -> dict[str, BeaconPath]:
        """``planned``, planned jointly the beacon planned alone (:data:`ALONE`), then every
        baseline's beacon path.

        Returns
        -------
        dict of str to BeaconPath
            Name -> path.
        """
        alone = {} if self.beacon_alone is None else {ALONE: self.beacon_alone}
        return {
            "planned": self.solve.path,
            **alone,
            **{k: b.path for k, b in self.baselines.items()},
        }

    @property
    def verdict(self) -> Verdict:
        """The planned beacon against every beacon baseline
        (:func:`~obsplan.planning.validation.verdict.verdict`, with the survey lines' RMSE)."""
        notes = tuple(
            f"{name} breaks the craft's limits ({b.breaks}); it is compared all the same"
            for name, b in self.baselines.items()
            if b.breaks
        )
        if self.planned_breaks:
            notes = (f"the planned beacon breaks the craft's limits: {self.planned_breaks}", *notes)
        notes = (*notes, *truth_distance_notes(self.validation))
        return verdict(self.validation, {}, notes, lines=self.lines)

    def outcomes(self) -> dict[str, str]:
        """Per baseline, ``"beats"`` (every headline metric better, decided at 95 %),
        ``"loses"`` (one of them worse, decided) or ``"ties"``; the headline metrics are
        :data:`BEACON_HEADLINE` without the lines' RMSE when the vehicle has no lines.

        Returns
        -------
        dict of str to str
            Baseline name -> outcome (empty without validation).
        """
        keys = [k for k in BEACON_HEADLINE if self.lines or k != "ekf.rmse_pos_lines"]
        out = {}
        for name, comps in self.verdict.comparisons.items():
            cs = [comps[k] for k in keys if k in comps]
            if cs and all(c.outcome == "better" for c in cs):
                out[name] = "beats"
            elif any(c.outcome == "worse" for c in cs):
                out[name] = "loses"
            else:
                out[name] = "ties"
        return out

    def to_dict(self) -> dict:
        """``report.json``: ``solver``, ``metrics``, ``validation``, ``verdict`` (with
        ``outcomes`` per baseline), ``beacon``, ``problem``, ``problem_file``, ``wall_s``, and
        ``replan`` when the craft was re-planned (:meth:`BeaconReplanResult.to_dict`).

        Returns
        -------
        dict
            JSON-serialisable with ``allow_nan=False``.
        """
        pb, s = self.problem, self.solve
        obj = None if s.objective is None or not math.isfinite(s.objective) else s.objective
        craft = pb.beacon_vehicle
        assert craft is not None
        val = validation_report(pb, self.validation)
        return {
            "solver": {
                "success": bool(s.success),
                "status": str(s.status),
                "iterations": int(s.iterations),
                "wall_s": float(s.wall_s),
                "planning_s": None if not math.isfinite(self.planning_s) else self.planning_s,
                "objective": obj,
                "joint": None if self.joint is None else self.joint.to_dict(),
            },
            "metrics": {k: b.to_dict() for k, b in self.bounds.items()},
            "validation": val,
            "verdict": {**self.verdict.to_dict(), "outcomes": self.outcomes()},
            "beacon": {
                "motion": pb.beacon_motion.motion,
                "vehicle_path": pb.vehicle.path,
                "craft": {
                    "start": craft.start.tolist(),
                    "speed": craft.speed,
                    "accel": craft.accel.tolist(),
                    "velocity": craft.velocity.tolist(),
                    "area": None if craft.area is None else craft.area.tolist(),
                    "max_range": craft.max_range,
                    "min_distance": craft.min_distance,
                    "distance_margin_m": self.distance_margin_m,
                },
                "paths": {
                    "planned": {"description": "planned", "breaks": self.planned_breaks},
                    **(
                        {}
                        if self.beacon_alone is None
                        else {
                            ALONE: {
                                "description": "planned alone for the vehicle's lawn-mower",
                                "breaks": "",
                            }
                        }
                    ),
                    **{
                        k: {"description": b.description, "breaks": b.breaks}
                        for k, b in self.baselines.items()
                    },
                },
            },
            "problem": {
                "name": pb.name,
                "dim": pb.dim,
                "sensors": list(pb.vehicle.sensors),
                "duration_s": pb.horizon.duration,
            },
            "problem_file": pb.to_dict(),
            "wall_s": float(self.wall_s),
            **({} if self.replan is None else {"replan": self.replan.to_dict()}),
        }

    def table(self) -> str:
        """Each beacon path: the bound, the filters' errors [m], whether it keeps the craft's
        limits, and what the planned beacon does against it (beats, ties, loses).

        Returns
        -------
        str
            The table ``obsplan plan`` prints, one line per beacon path.
        """
        widths = [w for _, w in _BEACON_COLUMNS]
        head = _text_row([c for c, _ in _BEACON_COLUMNS], widths)
        outcomes = self.outcomes()
        rows = [head, "-" * len(head)]
        breaks = {"planned": self.planned_breaks}
        breaks.update({k: b.breaks for k, b in self.baselines.items()})
        for name, bd in self.bounds.items():
            v = self.validation.get(name)
            r = None if v is None else v.result
            cells = [
                name,
                _fmt(bd.mean_pos_std),
                _fmt(bd.final_pos_std),
                _fmt(r.ekf.rmse_pos if r is not None and r.ekf else None),
                _fmt(metric_value(v, "ekf.rmse_pos_lines") if v is not None else None),
                _fmt(r.ekf.final_pos_err if r is not None and r.ekf else None),
                _fmt(r.kf.rmse_pos if r is not None and r.kf else None),
                "NO" if breaks.get(name) else "ok",
                outcomes.get(name, "-"),
            ]
            rows.append(_text_row(cells, widths))
        rows += channel_lines(self.problem, self.validation)
        return "\n".join(rows)

    def summary(self) -> str:
        """What ``obsplan plan`` prints: the planner's status, the table, which baselines the
        planned beacon beats, ties and loses to, and the verdict in words.

        Returns
        -------
        str
            Lines for the terminal.
        """
        s, pb, j = self.solve, self.problem, self.joint
        what = f"beacon planned for the vehicle's path ({pb.vehicle.path})"
        if j is not None:
            what = "vehicle and beacon planned jointly"
        lines = [
            f"{pb.name or 'problem'}: {what}: {s.status}, {int(s.iterations)} iterations, "
            f"{float(s.wall_s):.1f} s solve, {self.wall_s:.1f} s total",
        ]
        if j is not None:
            lines.append(self._joint_line(j))
        lines.append(self.table())
        if self.validation:
            groups: dict[str, list[str]] = {}
            for name, o in self.outcomes().items():
                groups.setdefault(o, []).append(name)
            said = {"beats": "beats", "ties": "ties with", "loses": "loses to"}
            conf = f"{100 * tuning().confidence:.0f} %"
            parts = [f"{said[o]} {', '.join(groups[o])}" for o in said if o in groups]
            who = "the planned beacon" if self.joint is None else "the plan (vehicle and beacon)"
            lines.append(f"{who} {'; '.join(parts)} (decided at {conf})")
        lines += self.verdict.summary()
        if self.replan is not None:
            lines += self.replan.summary()
        return "\n".join(lines)

    def plot(self, ax=None) -> Figure:
        """The vehicle's and the beacon's paths with range links
        (:func:`~obsplan.planning.figures.plot_beacon_paths`; ``path.png`` of ``obsplan plan``).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw on; None makes a new figure.

        Returns
        -------
        matplotlib.figure.Figure
            The figure.
        """
        return plot_beacon_paths(
            self.vehicle,
            self.beacons(),
            self.problem,
            ax=ax,
            baseline_vehicle=self.baseline_vehicle,
        )

    @staticmethod
    def _joint_line(j: JointPlan) -> str:
        """The joint rounds in words: objective per round, the vehicle's last solve, the stop."""
        objs = " -> ".join(f"{math.sqrt(x):.4g}" for x in j.objectives)
        v = j.vehicle_solve
        veh = (
            "the vehicle flies its lawn-mower"
            if v is None
            else f"vehicle solve {v.status}, {int(v.iterations)} iterations"
        )
        return (
            f"joint rounds kept: {j.rounds} (objective, rms position std [m]: {objs}); {veh}; "
            f"stopped: {j.stop}; the baselines' beacons serve the vehicle on its lawn-mower"
        )

    def __repr__(self) -> str:
        return f"<BeaconPlanResult {self.problem.name or 'problem'}: {self.solve.status}>"

    def write_files(self, folder: str | Path) -> list[Path]:
        """Write ``plan.csv`` (the vehicle's path), ``beacon.csv`` (the planned beacon:
        ``t,bx,by[,bz],vbx,vby[,vbz]``), ``report.json`` and the figures into ``folder``.

        Parameters
        ----------
        folder : str or Path
            Created if missing; files of the same names are replaced.

        Returns
        -------
        list of Path
            The files written, in order.
        """
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        s = self.solve
        written = [
            write_csv(self.vehicle, out / "plan.csv"),
            write_beacon_csv(out / "beacon.csv", s.times, s.positions, s.velocities),
        ]
        written.append(_write_report(out, self.to_dict()))
        fig = self.plot()
        written.append(save_figure(fig, out / FIGURES["path"]))
        if self.validation:
            fig = plot_filter_errors(self.validation, problem=self.problem.name)
            written.append(save_figure(fig, out / FIGURES["filters"]))
        return written

    def save(self, folder: str | Path, *, force: bool = False) -> list[Path]:
        """Save the files of ``obsplan plan`` into ``folder``, whole or not at all (as
        :meth:`ValidationResult.save`).

        Parameters
        ----------
        folder : str or Path
            The output folder.
        force : bool, default False
            Replace an earlier obsplan output folder.

        Returns
        -------
        list of Path
            The files written, at their final place.
        """
        return _save_whole(folder, force, self.write_files)
