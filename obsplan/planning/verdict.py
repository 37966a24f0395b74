"""The plan against each baseline, metric by metric, in numbers and in words.

A metric is *better* when the plan's value is strictly lower than the baseline's (every metric
here is an error, a standard deviation or a bound). A value that is missing or not finite (a
filter that diverged, a bound that was not computed) is never better. The words list every metric
on which the plan loses, so that a user is never told nothing.

Final errors are also compared run by run: every path is validated with the same seeds, so the
per-run differences are paired, and their standard error says whether a difference is larger
than the Monte Carlo noise (``noise`` = two standard errors; a loss inside it is reported as
such, still as a loss).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from obsplan.planning.validation import PathValidation

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


def metric_value(v: PathValidation, key: str) -> float | None:
    """A compared metric of one path's validation [m] (None if not available)."""
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

    def to_dict(self) -> dict:
        return {
            "planned": self.planned,
            "baseline": self.baseline,
            "ratio": self.ratio,
            "better": bool(self.better),
            "noise": self.noise,
            "within_noise": self.within_noise,
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
    """

    comparisons: Mapping[str, Mapping[str, Comparison]]
    not_fitted: Mapping[str, str]

    @property
    def beats_all(self) -> bool:
        """The plan is better on every headline metric against every validated baseline."""
        return bool(self.comparisons) and all(
            c[k].better for c in self.comparisons.values() for k in HEADLINE if k in c
        )

    def losses(self) -> list[str]:
        """One sentence per (baseline, metric) the plan does not win."""
        words = dict((*METRICS, *LINES_METRICS))
        out = []
        for name, comps in self.comparisons.items():
            for key, c in comps.items():
                if c.better:
                    continue
                pv = "n/a (diverged or missing)" if c.planned is None else f"{c.planned:.3g} m"
                bv = "n/a" if c.baseline is None else f"{c.baseline:.3g} m"
                ratio = f" ({c.ratio:.2f}x)" if c.ratio is not None else ""
                noise = (
                    f", within the Monte Carlo noise (+-{c.noise:.2g} m)" if c.within_noise else ""
                )
                out.append(f"against the {name}: {words[key]} {pv} vs {bv}{ratio}{noise}")
        return out

    def summary(self) -> list[str]:
        """Plain-words lines for the terminal."""
        lines = []
        if not self.comparisons:
            lines.append("no validation was run: nothing says the plan localises better")
        elif self.beats_all and not self.losses():
            lines.append("the plan beats every validated baseline on every metric")
        else:
            head = "beats" if self.beats_all else "does NOT beat"
            lines.append(
                f"the plan {head} every baseline on EKF RMSE, EKF final error and KF RMSE; "
                "it loses here:"
            )
            lines += [f"  - {s}" for s in self.losses()]
        for name, why in self.not_fitted.items():
            lines.append(f"baseline {name} not fitted: {why}")
        return lines

    def to_dict(self) -> dict:
        return {
            "beats_all": self.beats_all,
            "headline_metrics": list(HEADLINE),
            "baselines": {
                name: {k: c.to_dict() for k, c in comps.items()}
                for name, comps in self.comparisons.items()
            },
            "losses": self.losses(),
            "not_fitted": dict(self.not_fitted),
        }


def verdict(
    validation: Mapping[str, PathValidation],
    not_fitted: Mapping[str, str],
    lines: bool = False,
) -> Verdict:
    """Compare ``validation["planned"]`` with every other validated path (``lines``: also on
    :data:`LINES_METRICS`)."""
    metrics = (*METRICS, *LINES_METRICS) if lines else METRICS
    comps: dict[str, dict[str, Comparison]] = {}
    plan = validation.get("planned")
    if plan is not None:
        for name, v in validation.items():
            if name == "planned":
                continue
            comps[name] = {
                key: Comparison(
                    key, metric_value(plan, key), metric_value(v, key), paired_noise(plan, v, key)
                )
                for key, _ in metrics
            }
    return Verdict(comps, dict(not_fitted))


def paired_noise(a: PathValidation, b: PathValidation, key: str) -> float | None:
    """Two standard errors [m] of the mean per-run difference of a final error (else None)."""
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
