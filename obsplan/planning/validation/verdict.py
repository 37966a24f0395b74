"""The plan against each baseline, metric by metric, in numbers, with confidence, and in words.

A metric is *better* when the plan's value is strictly lower than the baseline's (every metric
here is an error, a standard deviation or a bound). A value that is missing or not finite (a
filter that diverged, a bound that was not computed) is never better. The words list every metric
on which the plan loses, and every verdict that is a tie, so that a user is never told nothing.

Confidence. Every path is validated with the same seeds, so the runs are paired. For the metrics
estimated from the runs (EKF and KF RMSE and final error) the ratio ``plan / baseline`` gets a
paired bootstrap interval: ``bootstrap`` resamples of the runs with replacement (the same runs
on both paths), the percentile interval at ``confidence``, seeded by the validation's seed
(both :class:`~obsplan.planning.tuning.Tuning`'s, as the divergence and stress thresholds).
The final error is the mean over runs of each run's final error, so its interval is exactly that
of the reported ratio. The RMSE is the time average of the RMS over runs, which the per-run
values do not determine: the bootstrap is of the ratio of the runs' RMS over runs and time
(``sqrt(mean rmse_runs²)``), and its interval, relative to that ratio on all runs, is carried to
the reported ratio (the same relative spread assumed: a plan whose error falls fast has a much
lower time-averaged RMSE ratio than its overall RMS ratio, so the interval of the latter would
not contain the reported ratio). A verdict is
*decided* when that interval excludes 1 on the side of ``better`` (the plan's value below the
baseline's and the whole interval below 1, or above and above); otherwise it is a *tie* at that
confidence. The bounds (PCRB) are computed, not sampled: their interval is the ratio itself,
decided unless the two are equal. :func:`validate_until_decided` adds batches of runs (doubling
the total) until every run-estimated verdict is decided or ``validation.max_runs`` is reached.

Final errors also keep their paired standard error (``noise`` = two standard errors of the mean
per-run difference; a loss inside it is reported as such).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import scipy.stats

from obsplan.estimation.montecarlo.simulate import DEFAULT_FILTERS
from obsplan.estimation.montecarlo.stats import FilterStats
from obsplan.model.beacon import BeaconPath
from obsplan.planning.objectives.evaluate import PathMetrics
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.schema import OBJECTIVE_KINDS
from obsplan.planning.problem.sections import ObjectiveSpec
from obsplan.planning.tuning import tuning
from obsplan.planning.validation.validate import PathValidation, merge_validations, validate_paths
from obsplan.trajectory.sampled import Trajectory

#: ``(key, words)`` of every compared metric, in report order.
METRICS: tuple[tuple[str, str], ...] = (
    ("ekf.rmse_pos", "EKF position RMSE"),
    ("ekf.final_pos_err", "EKF final position error"),
    ("kf.rmse_pos", "KF position RMSE"),
    ("kf.final_pos_err", "KF final position error"),
    ("crlb.mean_pos_std", "mission-average position bound (PCRB)"),
    ("crlb.final_pos_std", "final position bound (PCRB)"),
)
#: Compared too when the problem has survey lines: the RMSE over the samples flown on them.
LINES_METRICS: tuple[tuple[str, str], ...] = (
    ("ekf.rmse_pos_lines", "EKF position RMSE on the survey lines"),
    ("kf.rmse_pos_lines", "KF position RMSE on the survey lines"),
)
#: The metrics a plan must win on against every baseline to be called a win.
HEADLINE = ("ekf.rmse_pos", "ekf.final_pos_err", "kf.rmse_pos")
#: Metrics estimated from the runs, and the per-run array whose mean the interval is about.
RUN_METRICS: dict[str, str] = {
    "ekf.rmse_pos": "rmse_pos_runs",
    "ekf.final_pos_err": "final_pos_err_runs",
    "kf.rmse_pos": "rmse_pos_runs",
    "kf.final_pos_err": "final_pos_err_runs",
}
#: The per-run values of :data:`LINES_METRICS` (their intervals; they do not add batches).
LINES_RUN_METRICS: dict[str, str] = {
    "ekf.rmse_pos_lines": "rmse_pos_lines_runs",
    "kf.rmse_pos_lines": "rmse_pos_lines_runs",
}


def metric_value(v: PathValidation, key: str) -> float | None:
    """A compared metric of one path's validation [m] (None if not available).

    Parameters
    ----------
    v : PathValidation
        The path's Monte Carlo result.
    key : str
        ``"group.name"`` of :data:`METRICS` or :data:`LINES_METRICS` (e.g. ``"ekf.rmse_pos"``,
        ``"crlb.final_pos_std"``).

    Returns
    -------
    float or None
        The value [m]; None when the filter was not run, or the value is missing or not finite.
    """
    r = v.result
    group, name = key.split(".")
    if group == "crlb":
        val = getattr(r.crlb, name, None)
    elif name == "rmse_pos_lines":
        # RMS over the runs of each run's RMSE on the lines (as report.json's rmse_pos_lines)
        runs = getattr(getattr(r, group, None), "rmse_pos_lines_runs", None)
        x = np.asarray([] if runs is None else runs, float)
        val = float(np.sqrt(np.mean(x**2))) if x.size and np.all(np.isfinite(x)) else None
    else:
        stats = getattr(r, group, None)
        val = None if stats is None else getattr(stats, name, None)
    if val is None or not math.isfinite(float(val)):
        return None
    return float(val)


@dataclass(frozen=True)
class Comparison:
    """One metric of the plan against one baseline."""

    metric: str
    planned: float | None
    baseline: float | None
    noise: float | None = None
    ci: tuple[float, float] | None = None

    @property
    def ratio(self) -> float | None:
        """``planned / baseline`` (None when either is missing or the baseline is 0)."""
        if self.planned is None or self.baseline is None or self.baseline == 0:
            return None
        return self.planned / self.baseline

    @property
    def better(self) -> bool:
        if self.planned is None:
            return False
        return self.baseline is None or self.planned < self.baseline

    @property
    def within_noise(self) -> bool:
        """The difference is below two standard errors of the paired Monte Carlo difference."""
        if self.noise is None or self.planned is None or self.baseline is None:
            return False
        return abs(self.planned - self.baseline) < self.noise

    @property
    def decided(self) -> bool:
        """The interval of the ratio excludes 1 on the side of :attr:`better` (module
        docstring); a value missing on exactly one side decides too (a diverged filter loses)."""
        if (self.planned is None) != (self.baseline is None):
            return True
        if self.ci is None:
            return False
        lo, hi = self.ci
        return hi < 1.0 if self.better else lo > 1.0

    @property
    def outcome(self) -> str:
        """``"better"``, ``"worse"`` (both decided) or ``"tie"``."""
        if not self.decided:
            return "tie"
        return "better" if self.better else "worse"

    def to_dict(self) -> dict:
        """The comparison's entry under ``verdict.baselines`` in report.json.

        Returns
        -------
        dict
            The two values [m], their ratio, the noise, the interval (a list, or None) and the
            derived ``better``, ``within_noise``, ``decided`` and ``outcome``.
        """
        return {
            "planned": self.planned,
            "baseline": self.baseline,
            "ratio": self.ratio,
            "better": bool(self.better),
            "noise": self.noise,
            "within_noise": self.within_noise,
            "ci": None if self.ci is None else [float(self.ci[0]), float(self.ci[1])],
            "decided": bool(self.decided),
            "outcome": self.outcome,
        }


@dataclass(frozen=True)
class Verdict:
    """Every comparison of the plan with every validated baseline, and the baselines not fitted.

    Attributes
    ----------
    comparisons : dict
        ``{baseline: {metric: Comparison}}``.
    not_fitted : dict
        ``{baseline: reason}`` for baselines the problem cannot fit.
    runs : int
        Monte Carlo runs behind the comparisons (0: no validation).
    notes : tuple of str
        Further sentences: an EKF that diverges on the plan while the KF converges, or that lost
        track on a few of the plan's runs (with the Gaussian-sum filter validated beside it), an
        objective kind that is a diagnostic, a baseline that wins while breaking the limits the
        plan keeps (:func:`limit_notes`).
    """

    comparisons: Mapping[str, Mapping[str, Comparison]]
    not_fitted: Mapping[str, str]
    runs: int = 0
    notes: tuple[str, ...] = ()

    @property
    def beats_all(self) -> bool:
        """The plan is better on every headline metric against every validated baseline."""
        return bool(self.comparisons) and all(
            c[k].better for c in self.comparisons.values() for k in HEADLINE if k in c
        )

    @property
    def beats_all_decided(self) -> bool:
        """:attr:`beats_all`, each of those verdicts decided at ``Tuning.confidence``."""
        return self.beats_all and all(
            c[k].decided for c in self.comparisons.values() for k in HEADLINE if k in c
        )

    @property
    def all_decided(self) -> bool:
        """Every run-estimated verdict (:data:`RUN_METRICS`) is decided."""
        return all(
            c.decided
            for comps in self.comparisons.values()
            for k, c in comps.items()
            if k in RUN_METRICS
        )

    def _words(self, name: str, key: str, c: Comparison) -> str:
        pv = "n/a (diverged or missing)" if c.planned is None else f"{c.planned:.3g} m"
        bv = "n/a" if c.baseline is None else f"{c.baseline:.3g} m"
        ratio = f" ({c.ratio:.2f}x" if c.ratio is not None else ""
        if ratio and c.ci is not None and c.ci[0] != c.ci[1]:
            ratio += f", {100 * tuning().confidence:.0f} % interval [{c.ci[0]:.2f}, {c.ci[1]:.2f}]"
        ratio += ")" if ratio else ""
        return f"against the {name}: {dict((*METRICS, *LINES_METRICS))[key]} {pv} vs {bv}{ratio}"

    def losses(self) -> list[str]:
        """One sentence per (baseline, metric) the plan does not win, ending in what it is: a
        loss (decided at ``Tuning.confidence``) or a tie.

        Returns
        -------
        list of str
            In baseline then metric order; empty when the plan wins every comparison.
        """
        out = []
        for name, comps in self.comparisons.items():
            for key, c in comps.items():
                if c.better:
                    continue
                if c.decided:  # the interval decides; two standard errors may say otherwise
                    out.append(self._words(name, key, c) + ", a loss")
                    continue
                noise = (
                    f", within the Monte Carlo noise (+-{c.noise:.2g} m)" if c.within_noise else ""
                )
                out.append(self._words(name, key, c) + noise + ", a tie")
        return out

    def ties(self) -> list[str]:
        """One sentence per (baseline, metric) not decided at ``Tuning.confidence``.

        Returns
        -------
        list of str
            The values, their ratio and its interval, in baseline then metric order.
        """
        return [
            self._words(name, key, c)
            for name, comps in self.comparisons.items()
            for key, c in comps.items()
            if not c.decided
        ]

    def summary(self) -> list[str]:
        """Plain-words lines for the terminal.

        Returns
        -------
        list of str
            The headline, the losses and ties (indented), the notes and the baselines not
            fitted.
        """
        lines = []
        if not self.comparisons:
            lines.append("no validation was run: nothing says the plan localises better")
        elif self.beats_all and not self.losses():
            # ahead on every metric is a win only where the interval says so: the ties follow
            lines.append(
                "the plan beats every validated baseline on every metric"
                if not self.ties()
                else "the plan is ahead of every validated baseline on every metric, but not "
                "decidedly on the ties below"
            )
        else:
            head = "beats" if self.beats_all else "does NOT beat"
            lines.append(
                f"the plan {head} every baseline on EKF RMSE, EKF final error and KF RMSE; "
                "it does not win here:"
            )
            lines += [f"  - {s}" for s in self.losses()]
        ties = self.ties()
        if self.comparisons and ties:
            lines.append(
                f"ties (not decided at {100 * tuning().confidence:.0f} % confidence after "
                f"{self.runs} "
                "runs; the interval of the ratio contains 1):"
            )
            lines += [f"  - {s}" for s in ties]
        elif self.comparisons:
            lines.append(
                f"every verdict is decided at {100 * tuning().confidence:.0f} % confidence "
                f"({self.runs} runs)"
            )
        lines += list(self.notes)
        for name, why in self.not_fitted.items():
            lines.append(f"baseline {name} not fitted: {why}")
        return lines

    def to_dict(self) -> dict:
        """The ``verdict`` entry of report.json.

        Returns
        -------
        dict
            The headline flags, the headline metrics, the confidence, bootstrap resamples and
            runs, every comparison by baseline and metric, the losses, ties and notes in words,
            and the baselines not fitted.
        """
        return {
            "beats_all": self.beats_all,
            "beats_all_decided": self.beats_all_decided,
            "headline_metrics": list(HEADLINE),
            "confidence": tuning().confidence,
            "bootstrap": tuning().bootstrap,
            "runs": int(self.runs),
            "baselines": {
                name: {k: c.to_dict() for k, c in comps.items()}
                for name, comps in self.comparisons.items()
            },
            "losses": self.losses(),
            "ties": self.ties(),
            "notes": list(self.notes),
            "not_fitted": dict(self.not_fitted),
        }


#: What the verdict of a scale-free ``lwo-condition`` plan (``objective.weights = "none"``) says:
#: that form is a diagnostic, not a plan to fly.
LWO_NOTE = (
    'lwo-condition with weights = "none" is a diagnostic of local, node-by-node observability: '
    "scale-free, it ignores the range's distance, the rates and the process noise, and its plans "
    "do not serve the filters (suite/lwo-dvl3d.toml: EKF final error 3.7x, final bound 4.2x the "
    'lawn-mower\'s); to fly, keep the default weights = "information"'
)


#: What the verdict of a plan on the paper's Gramian formulation (``window = "mission"``,
#: ``weights = "none"``) says: kept for research and comparison, it does not serve the filters.
#: The evidence is ``benchmarks/bench_planning_suite.py`` on the suite's seven Gramian problems
#: with ``--set objective.window=mission --set objective.weights=none`` (with their defaults none
#: loses a verdict).
GRAMIAN_PAPER_NOTE = (
    '{kind} with window = "mission" and weights = "none" is the paper\'s formulation, kept '
    "for research and comparison: it scores the information on the initial state over the whole "
    "horizon, every output row alike and without process noise, and its plans do not serve the "
    "filters (on 5 of the suite's 7 Gramian problems they lose a verdict to a baseline; "
    "suite/gramian-current-water-dvl.toml: the EKF diverged on 10 of 400 runs, RMSE 26x the "
    'lawn-mower\'s); to fly, keep the defaults window = "auto", weights = "information"'
)


def objective_notes(pb: PlanningProblem) -> tuple[str, ...]:
    """What the verdict says about the objective itself, whatever the numbers.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its objective's kind and form.

    Returns
    -------
    tuple of str
        :data:`LWO_NOTE` or :data:`GRAMIAN_PAPER_NOTE` for the paper's (scale-free) forms,
        else empty.
    """
    obj = pb.objective
    if not obj.paper_form:
        return ()
    if obj.kind == "lwo-condition":
        return (LWO_NOTE,)
    if obj.kind.startswith("gramian-"):
        return (GRAMIAN_PAPER_NOTE.format(kind=obj.kind),)
    return ()


def stress_notes(metrics: Mapping[str, PathMetrics], runs: int) -> tuple[str, ...]:
    """A sentence when the plan's peak EKF linearisation stress is above
    ``Tuning.stress_note_level`` and some baseline's (the verdict
    against that one may not see the plan's rare losses), and the validation ran fewer than
    ``Tuning.stress_note_runs`` runs; empty otherwise.

    Parameters
    ----------
    metrics : Mapping of str to PathMetrics
        Every path's metrics by name (``"planned"`` and the baselines).
    runs : int
        Monte Carlo runs of the validation.

    Returns
    -------
    tuple of str
        The sentence, or nothing.
    """
    plan = metrics.get("planned")
    level = tuning().stress_note_level
    if plan is None or runs >= tuning().stress_note_runs:
        return ()
    b = plan.ekf_linearisation_stress
    others = {
        name: m.ekf_linearisation_stress
        for name, m in metrics.items()
        if name != "planned" and math.isfinite(m.ekf_linearisation_stress)
    }
    if not others or not math.isfinite(b) or b <= level:
        return ()
    calm = min(others, key=others.__getitem__)
    if b <= others[calm]:
        return ()
    return (
        f"the plan's EKF linearisation stress peaks at {b:.2f} range stds (the {calm}'s at "
        f"{others[calm]:.2f}): most plans measured above {level} lost the EKF on a "
        f"few runs in 1000, which {runs} runs rarely see: validate with more runs (--runs 1000) "
        "before trusting the EKF's verdicts",
    )


def limit_notes(
    validation: Mapping[str, PathValidation],
    comparisons: Mapping[str, Mapping[str, Comparison]],
    confidence: float,
) -> tuple[str, ...]:
    """A sentence when the plan's true paths broke a limit more often than the keep-out allows,
    and one per baseline the plan does not beat on every run metric whose true paths broke a
    limit more often than the keep-out allows and more often than the plan's.

    The plan keeps its limits at ``confidence`` (``limits.keepout_confidence``) with margins and
    reserves (:mod:`obsplan.planning.solver.margins`); a baseline is flown on its nominal path
    without them. The sentence states that difference, not a cause of the loss: a lawn-mower laid
    inside the area by the plan's margin can win the same verdict (docs/results/suite.md, "Choosing
    the objective"). "More often than allowed": the one-sided binomial test of its breaking runs
    against the share ``1 - confidence`` rejects at ``Tuning.confidence`` (with 100 runs at 0.999: 2
    breaking runs). ``confidence = 0`` (no margins): nothing to say.

    Parameters
    ----------
    validation : Mapping of str to PathValidation
        Every path's validation (``"planned"`` and the baselines), with their true paths'
        limit checks.
    comparisons : Mapping of str to Mapping of str to Comparison
        ``{baseline: {metric: Comparison}}`` of the verdict.
    confidence : float
        ``limits.keepout_confidence`` of the plan, in ``[0, 1)``.

    Returns
    -------
    tuple of str
        The sentences, possibly none.
    """
    plan = validation.get("planned")
    if plan is None or not 0 < confidence < 1 or plan.result.truth is None:
        return ()
    allowed = 1.0 - confidence
    tp = plan.result.truth

    def too_often(t) -> bool:
        k = t.any_violation_runs
        return k > 0 and scipy.stats.binom.sf(k - 1, t.runs, allowed) < 1.0 - tuning().confidence

    out = []
    if too_often(tp):
        out.append(
            f"the plan's true path broke a limit on {100 * tp.any_violation_fraction:.1f} % of "
            f"the runs ({tp.breaks_words()}), more often than limits.keepout_confidence = "
            f"{confidence:g} allows: its margins are sized per point on the Cramér-Rao bound, "
            "which the filter the vehicle steers on may not reach, and a start inside a margin "
            "cannot keep it (the keep-out line says whether the margins were held); raise "
            "limits.keepout_confidence for wider margins, or add a sensor for the limit that "
            "breaks"
        )
    for name, comps in comparisons.items():
        tb = validation[name].result.truth
        if tb is None or all(c.better for k, c in comps.items() if k in RUN_METRICS):
            continue
        if tb.any_violation_fraction <= tp.any_violation_fraction or not too_often(tb):
            continue
        out.append(
            f"the {name}'s true path broke a limit on {100 * tb.any_violation_fraction:.1f} % "
            f"of the runs ({tb.breaks_words()}), the plan's on "
            f"{100 * tp.any_violation_fraction:.1f} %: the plan keeps margins and speed and "
            f"acceleration reserves to hold its limits at limits.keepout_confidence = "
            f"{confidence:g}, the {name} is flown on its nominal path without them"
        )
    return tuple(out)


def verdict(
    validation: Mapping[str, PathValidation],
    not_fitted: Mapping[str, str],
    notes: Sequence[str] = (),
    lines: bool = False,
    keepout_confidence: float = 0.0,
    objective: ObjectiveSpec | None = None,
) -> Verdict:
    """Compare ``validation["planned"]`` with every other validated path (intervals seeded by the
    validation's seed; ``notes``: said first, e.g. :func:`objective_notes`; ``lines``: also on
    :data:`LINES_METRICS`, for a survey; ``keepout_confidence``: the plan's
    ``limits.keepout_confidence``, for :func:`limit_notes`).

    Parameters
    ----------
    validation : Mapping of str to PathValidation
        Every path's validation by name; ``"planned"`` is compared with each other one.
    not_fitted : Mapping of str to str
        Baselines the problem cannot fit, with the reason.
    notes : sequence of str, optional
        Sentences said first.
    lines : bool, optional
        Compare the RMSE on the survey lines too.
    keepout_confidence : float, optional
        The plan's ``limits.keepout_confidence`` (0: no limit notes).
    objective : ObjectiveSpec or None, optional
        The plan's objective, for :func:`estimator_notes` (None: no such notes).

    Returns
    -------
    Verdict
        Without a ``"planned"`` path, no comparisons (only ``not_fitted`` and ``notes``).
    """
    metrics = (*METRICS, *LINES_METRICS) if lines else METRICS
    comps: dict[str, dict[str, Comparison]] = {}
    plan = validation.get("planned")
    if plan is None:
        return Verdict(comps, dict(not_fitted), notes=tuple(notes))
    for b, (name, v) in enumerate(validation.items()):
        if name == "planned":
            continue
        comps[name] = {}
        for m, (key, _) in enumerate(metrics):
            pv, bv = metric_value(plan, key), metric_value(v, key)
            if key in RUN_METRICS or key in LINES_RUN_METRICS:
                ci = _interval(plan, v, key, (int(plan.result.seed), b, m), pv, bv)
            else:  # a computed bound: no sampling noise
                ci = None if pv is None or bv is None or bv == 0 else (pv / bv, pv / bv)
            comps[name][key] = Comparison(key, pv, bv, paired_noise(plan, v, key), ci)
    return Verdict(
        comps,
        dict(not_fitted),
        int(plan.result.runs),
        (
            *notes,
            *filter_notes(validation),
            *limit_notes(validation, comps, keepout_confidence),
            *estimator_notes(comps, objective),
        ),
    )


#: The two filters whose verdicts the objective can trade, by the key's prefix.
_ESTIMATORS = {"ekf": "EKF", "kf": "augmented KF"}


def estimator_notes(
    comparisons: Mapping[str, Mapping[str, Comparison]], objective: ObjectiveSpec | None
) -> tuple[str, ...]:
    """A sentence per baseline against which one filter's verdict is a decided loss while the
    other's is a decided win: which estimator the plan serves there and why.

    The objective scores one estimator's information: ``kf-position-std`` the augmented KF's
    predicted std (with the posterior CRB at ``objective.pcrb_weight``), every other kind what an
    EKF can use. The augmented KF reads the ranges through its linear model of the half-squared
    range (eqs. 20-24), whose information differs from the EKF's; ``objective.kf_guard``
    (:mod:`obsplan.planning.objectives.guards`) holds its *predicted* std at a multiple of the
    lawn-mower's, and ``objective.ekf_guard`` the EKF's bound under an observability objective,
    which a loss in the Monte Carlo says the runs did not follow.

    Parameters
    ----------
    comparisons : Mapping of str to Mapping of str to Comparison
        ``{baseline: {metric: Comparison}}`` of the verdict.
    objective : ObjectiveSpec or None
        The plan's objective (None: nothing to say).

    Returns
    -------
    tuple of str
        The sentences, possibly none.
    """
    if objective is None:
        return ()
    out = []
    for name, comps in comparisons.items():
        lost: dict[str, list[str]] = {g: [] for g in _ESTIMATORS}
        won = dict.fromkeys(_ESTIMATORS, False)
        for key, c in comps.items():
            group = key.split(".")[0]
            if key not in RUN_METRICS or group not in _ESTIMATORS or not c.decided:
                continue
            if c.better:
                won[group] = True
            else:
                lost[group].append(dict((*METRICS, *LINES_METRICS))[key])
        for loser, winner in (("kf", "ekf"), ("ekf", "kf")):
            if lost[loser] and won[winner]:
                out.append(_served_words(name, winner, loser, lost[loser], objective))
    return tuple(out)


def _served_words(
    name: str, winner: str, loser: str, lost: Sequence[str], obj: ObjectiveSpec
) -> str:
    """The sentence of :func:`estimator_notes` for one baseline."""
    kf_objective = obj.kind == "kf-position-std"
    served = "kf" if kf_objective else "ekf"
    why = (
        f"objective kf-position-std scores the augmented KF's std, with the EKF's bound at "
        f"objective.pcrb_weight = {obj.resolved_pcrb_weight:g}"
        if kf_objective
        else f"its objective, {obj.kind}, scores the information an EKF uses"
    )
    head = f"the plan serves the {_ESTIMATORS[served]} ({why})"
    loses = f"the {_ESTIMATORS[loser]}'s verdict against the {name} on {', '.join(lost)}"
    if loser != served and kf_objective:
        return f"{head} and loses {loses}; raise objective.pcrb_weight to weigh the EKF more"
    if loser != served:
        held = (
            "objective.kf_guard = 0 turned off the guard on the KF's predicted std"
            if obj.kf_guard == 0
            else "objective.kf_guard holds the KF's predicted std (its Riccati recursion on the "
            "nominal path) at the lawn-mower's only where the EKF's bound does not pay for it "
            "(solver.kf_guard and solver.note say whether it did), and the runs' errors may "
            "differ from the prediction; a kf_guard set lower holds it in every solve"
        )
        return (
            f"{head} and loses {loses}: the augmented KF reads the ranges through its linear "
            f"model of the half-squared range, whose information differs; {held}"
        )
    tail = (
        f"{head}, yet loses {loses} where the {_ESTIMATORS[winner]} wins: the filter did not "
        "realise the plan's information on these runs (the notes above say what else differs)"
    )
    if OBJECTIVE_KINDS[obj.kind].timed:  # pcrb-position: the bound is the objective itself
        return tail
    guard = (
        "objective.ekf_guard = 0 turned off the guard on the EKF's bound"
        if obj.ekf_guard == 0
        else "objective.ekf_guard holds the EKF's bound (the posterior CRB on the nominal path) "
        "at the lawn-mower's where the plan exceeded it (solver.ekf_guard and solver.note say "
        "whether it did), which the runs' errors follow only to within the EKF's linearisation"
    )
    return f"{tail}; {guard}"


def ekf_diverges(v: PathValidation) -> bool:
    """The EKF diverges on this path while the KF converges: the divergence monitor flags at
    least ``Tuning.diverged_fraction`` of its EKF runs (fewer of its
    KF runs), or its final error is ``Tuning.diverged_ratio`` times
    the KF's.

    Parameters
    ----------
    v : PathValidation
        A path's Monte Carlo result.

    Returns
    -------
    bool
        False when either filter was not run.
    """
    r = v.result
    e, k = r.ekf, r.kf
    if e is None or k is None or r.runs < 1:
        return False
    tun = tuning()
    if k.flagged_runs >= tun.diverged_fraction * r.runs:
        return False
    far = (
        not math.isfinite(e.final_pos_err) or e.final_pos_err > tun.diverged_ratio * k.final_pos_err
    )
    return e.flagged_runs >= tun.diverged_fraction * r.runs or far


def filter_notes(validation: Mapping[str, PathValidation]) -> tuple[str, ...]:
    """Sentences on an EKF that diverges on the plan while the KF converges, with the
    Gaussian-sum filter's numbers on the plan and the baselines when it was run.

    Parameters
    ----------
    validation : Mapping of str to PathValidation
        Every path's validation by name (``"planned"`` is the one judged).

    Returns
    -------
    tuple of str
        A diverging EKF, or the few runs on which it lost track, and then the Gaussian-sum
        filter's line; empty when neither applies.
    """
    plan = validation.get("planned")
    if plan is None:
        return ()
    r = plan.result
    if not ekf_diverges(plan):
        lost = _rare_losses(plan)
        if lost is None:
            return ()
        return (lost, *_gsf_line(validation))
    e, k = cast(FilterStats, r.ekf), cast(FilterStats, r.kf)  # ekf_diverges(plan) ran both
    out = [
        f"the EKF diverges on the plan while the KF converges: {e.flagged_runs} of {r.runs} EKF "
        f"runs flagged by the divergence monitor (KF {k.flagged_runs}), EKF final error "
        f"{e.final_pos_err:.3g} m against the KF's {k.final_pos_err:.3g} m; fly it with the KF "
        "or a Gaussian-sum filter"
        + (
            " (the vehicle of this validation steers on the Gaussian sum: the EKF's errors "
            "stay out of its true path)"
            if r.guidance is not None and r.guidance.navigation == "gsf"
            else ""
        )
    ]
    return (*out, *_gsf_line(validation))


def _rare_losses(plan: PathValidation) -> str | None:
    """A sentence when the divergence monitor flagged some of the plan's EKF runs, fewer than
    ``Tuning.diverged_fraction`` (not a diverging EKF, but a few such runs dominate an RMSE over
    runs: one run of 200 at 21 m RMSE tripled an unseen plan's EKF RMSE); None otherwise."""
    r = plan.result
    e = r.ekf
    if e is None or e.flagged_runs < 1:
        return None
    return (
        f"the EKF lost track on {e.flagged_runs} of {r.runs} runs of the plan (flagged by the "
        f"divergence monitor): their position RMSE {e.flagged.rmse_pos:.3g} m, the other "
        f"runs' {e.unflagged.rmse_pos:.3g} m, all runs' {e.rmse_pos:.3g} m (the verdict counts "
        "every run)"
    )


def _gsf_line(validation: Mapping[str, PathValidation]) -> tuple[str, ...]:
    """The Gaussian-sum filter's RMSE and final error on the plan and the baselines, when run."""
    gsf = {n: (v.result.filters or {}).get("gsf") for n, v in validation.items()}
    if gsf.get("planned") is None:
        return ()
    g = cast(FilterStats, gsf["planned"])
    base = ", ".join(
        f"{n} {s.rmse_pos:.3g} / {s.final_pos_err:.3g} m"
        for n, s in gsf.items()
        if n != "planned" and s is not None
    )
    return (
        f"  Gaussian-sum filter (RMSE / final error): plan {g.rmse_pos:.3g} / "
        f"{g.final_pos_err:.3g} m" + (f"; {base}" if base else ""),
    )


def _interval(plan, v, key, seed, pv, bv) -> tuple[float, float] | None:
    """The interval of the ratio ``pv / bv`` of a run-estimated metric (module docstring)."""
    a, b = _runs(plan, key), _runs(v, key)
    rms = key.endswith(("rmse_pos", "rmse_pos_lines"))
    ci = ratio_interval(a, b, seed, rms=rms)
    if ci is None or not rms or pv is None or not bv:
        return ci
    # the RMSE is the time average of the RMS over runs, not a function of the per-run RMSEs:
    # the bootstrap's relative spread about the ratio of the runs' RMS is carried to it
    if a is None or b is None:  # pragma: no cover - ci is None then
        return None
    full = math.sqrt(np.mean(np.square(a)) / np.mean(np.square(b)))
    scale = (pv / bv) / full
    return (ci[0] * scale, ci[1] * scale)


def _runs(v: PathValidation, key: str) -> np.ndarray | None:
    group, _ = key.split(".")
    stats = getattr(v.result, group, None)
    field = {**RUN_METRICS, **LINES_RUN_METRICS}[key]
    return None if stats is None else getattr(stats, field, None)


def ratio_interval(
    a: np.ndarray | None,
    b: np.ndarray | None,
    seed: int | Sequence[int] = 0,
    rms: bool = False,
) -> tuple[float, float] | None:
    """Paired bootstrap interval of ``mean(a) / mean(b)`` at ``Tuning.confidence`` (``rms``: of
    ``sqrt(mean(a²) / mean(b²))``).

    Parameters
    ----------
    a, b
        Per-run values of the plan and of a baseline on the same runs, shape (runs,) [m].
    seed
        Seed of the resampling.
    rms
        Compare root mean squares (of per-run RMSEs: the RMS over runs and time) instead of
        means.

    Returns
    -------
    (lo, hi) or None
        None when the runs are missing, unpaired, fewer than 2 or not all finite, or the
        baseline's mean is not positive.
    """
    if a is None or b is None:
        return None
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = a.size
    if n < 2 or b.size != n or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return None
    if rms:
        a, b = a * a, b * b
    if not b.mean() > 0:
        return None
    rng = np.random.default_rng(seed)
    tun = tuning()
    resamples = tun.bootstrap
    ratios = np.empty(resamples)
    chunk = max(1, 2_000_000 // n)  # bounded memory: chunk x n indices at a time
    for s in range(0, resamples, chunk):
        idx = rng.integers(0, n, size=(min(chunk, resamples - s), n))
        mb = b[idx].mean(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios[s : s + idx.shape[0]] = a[idx].mean(axis=1) / mb
    tail = 100.0 * (1.0 - tun.confidence) / 2.0
    lo, hi = np.nanpercentile(ratios, [tail, 100.0 - tail])
    if rms:
        lo, hi = math.sqrt(lo), math.sqrt(hi)
    return (float(lo), float(hi))


def validate_until_decided(
    paths: Mapping[str, Trajectory],
    pb: PlanningProblem,
    *,
    runs: int | None = None,
    max_runs: int | None = None,
    progress: bool = False,
    filters: Sequence[str] = DEFAULT_FILTERS,
    lines: Mapping[str, np.ndarray] | None = None,
    beacons: Mapping[str, BeaconPath] | None = None,
) -> dict[str, PathValidation]:
    """:func:`~obsplan.planning.validation.validate.validate_paths` in batches until decided
    (``lines``: each path's samples on the survey lines, for its ``rmse_pos_lines``;
    ``beacons``: each path's moving beacon).

    The first batch has ``runs`` (default ``validation.runs``) runs. While a run-estimated
    verdict of ``paths["planned"]`` against a baseline is undecided, a batch as large as all the
    runs so far is added (runs ``k ..`` of the same seed, merged exactly: the total doubles),
    up to ``max(runs, max_runs)`` runs (default ``validation.max_runs``). Without a
    ``"planned"`` path, one batch.

    Parameters
    ----------
    paths : Mapping of str to Trajectory
        Name -> path (``"planned"`` and the baselines).
    pb : PlanningProblem
        The problem: its ``[validation]`` (runs, max_runs, seed, filters' settings).
    runs : int or None, optional
        Runs of the first batch; None: ``validation.runs``.
    max_runs : int or None, optional
        Cap on the total; None: ``validation.max_runs``.
    progress : bool, optional
        A progress bar over runs.
    filters : sequence of str, optional
        Estimators to run (as :func:`~obsplan.planning.validation.validate.validate_paths`).
    lines : Mapping of str to ndarray or None, optional
        Name -> boolean mask of the filter samples on the survey lines.
    beacons : Mapping of str to BeaconPath or None, optional
        Name -> the moving beacon that path is flown with (none: the problem's beacon).

    Returns
    -------
    dict of str to PathValidation
        Name -> its validation over all the runs (merged).
    """
    done = pb.validation.runs if runs is None else int(runs)
    cap = max(done, pb.validation.max_runs if max_runs is None else int(max_runs))
    common: dict[str, Any] = dict(progress=progress, filters=filters, lines=lines, beacons=beacons)
    parts = [validate_paths(paths, pb, runs=done, **common)]
    merged = parts[0]
    while done < cap and "planned" in paths and not verdict(merged, {}).all_decided:
        k = min(done, cap - done)
        parts.append(validate_paths(paths, pb, runs=k, run_start=done, **common))
        done += k
        merged = merge_validations(parts)
    return merged


def paired_noise(a: PathValidation, b: PathValidation, key: str) -> float | None:
    """Two standard errors [m] of the mean per-run difference of a final error (else None).

    Parameters
    ----------
    a, b : PathValidation
        The plan's and a baseline's validations, on the same runs.
    key : str
        The metric (only ``"ekf.final_pos_err"`` and ``"kf.final_pos_err"`` have one).

    Returns
    -------
    float or None
        The noise [m]; None for other metrics, missing or unpaired runs, fewer than 2, or a
        non-finite difference.
    """
    group, name = key.split(".")
    if name != "final_pos_err" or group not in ("ekf", "kf"):
        return None
    sa, sb = getattr(a.result, group, None), getattr(b.result, group, None)
    ra = getattr(sa, "final_pos_err_runs", None)
    rb = getattr(sb, "final_pos_err_runs", None)
    if ra is None or rb is None or len(ra) != len(rb) or len(ra) < 2:
        return None
    d = np.asarray(ra, float) - np.asarray(rb, float)
    if not np.all(np.isfinite(d)):
        return None
    return float(2.0 * d.std(ddof=1) / math.sqrt(d.size))
