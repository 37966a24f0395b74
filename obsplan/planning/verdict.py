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
#: The metrics a plan must win on against every baseline to be called a win.
HEADLINE = ("ekf.rmse_pos", "ekf.final_pos_err", "kf.rmse_pos")
#: The EKF "diverges" on a path when the divergence monitor flags at least this fraction of its
#: runs, or its final error is :data:`DIVERGED_RATIO` times the KF's; the KF "converges" when
#: fewer than this fraction of its runs are flagged.
DIVERGED_FRACTION = 0.1
DIVERGED_RATIO = 3.0


def metric_value(v: PathValidation, key: str) -> float | None:
    """A compared metric of one path's validation [m] (None if not available)."""
    r = v.result
    group, name = key.split(".")
    if group == "crlb":
        val = getattr(r.crlb, name, None)
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
    notes : tuple of str
        Further sentences about the filters (an EKF that diverges on the plan while the KF
        converges, and the Gaussian-sum filter validated beside it).
    """

    comparisons: Mapping[str, Mapping[str, Comparison]]
    not_fitted: Mapping[str, str]
    notes: tuple[str, ...] = ()

    @property
    def beats_all(self) -> bool:
        """The plan is better on every headline metric against every validated baseline."""
        return bool(self.comparisons) and all(
            c[k].better for c in self.comparisons.values() for k in HEADLINE if k in c
        )

    def losses(self) -> list[str]:
        """One sentence per (baseline, metric) the plan does not win."""
        words = dict(METRICS)
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
        lines += list(self.notes)
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
            "notes": list(self.notes),
            "not_fitted": dict(self.not_fitted),
        }


#: What the verdict of an ``lwo-condition`` plan says: the kind is a diagnostic, not a plan to fly.
LWO_NOTE = (
    "lwo-condition is a diagnostic of local, node-by-node observability: scale-free, it ignores "
    "the range's distance, the rates and the process noise, and its plans do not serve the "
    "filters (suite/lwo-dvl3d.toml: EKF final error 3.4x, final bound 4.1x the lawn-mower's); "
    "to fly, plan with pcrb-position or a Gramian objective"
)


def verdict(
    validation: Mapping[str, PathValidation],
    not_fitted: Mapping[str, str],
    objective: str | None = None,
) -> Verdict:
    """Compare ``validation["planned"]`` with every other validated path (``objective``: the
    problem's ``objective.kind``, for the notes)."""
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
                for key, _ in METRICS
            }
    notes = filter_notes(validation)
    if objective == "lwo-condition":
        notes = (LWO_NOTE, *notes)
    return Verdict(comps, dict(not_fitted), notes)


def ekf_diverges(v: PathValidation) -> bool:
    """The EKF diverges on this path while the KF converges (:data:`DIVERGED_FRACTION`)."""
    r = v.result
    e, k = r.ekf, r.kf
    if e is None or k is None or r.runs < 1:
        return False
    if k.flagged_runs >= DIVERGED_FRACTION * r.runs:
        return False
    far = not math.isfinite(e.final_pos_err) or e.final_pos_err > DIVERGED_RATIO * k.final_pos_err
    return e.flagged_runs >= DIVERGED_FRACTION * r.runs or far


def filter_notes(validation: Mapping[str, PathValidation]) -> tuple[str, ...]:
    """Sentences on an EKF that diverges on the plan while the KF converges, with the
    Gaussian-sum filter's numbers on the plan and the baselines when it was run."""
    plan = validation.get("planned")
    if plan is None or not ekf_diverges(plan):
        return ()
    r = plan.result
    e, k = r.ekf, r.kf
    out = [
        f"the EKF diverges on the plan while the KF converges: {e.flagged_runs} of {r.runs} EKF "
        f"runs flagged by the divergence monitor (KF {k.flagged_runs}), EKF final error "
        f"{e.final_pos_err:.3g} m against the KF's {k.final_pos_err:.3g} m; fly it with the KF "
        "or a Gaussian-sum filter"
    ]
    gsf = {n: (v.result.filters or {}).get("gsf") for n, v in validation.items()}
    if gsf.get("planned") is not None:
        g = gsf["planned"]
        base = ", ".join(
            f"{n} {s.rmse_pos:.3g} / {s.final_pos_err:.3g} m"
            for n, s in gsf.items()
            if n != "planned" and s is not None
        )
        out.append(
            f"  Gaussian-sum filter (RMSE / final error): plan {g.rmse_pos:.3g} / "
            f"{g.final_pos_err:.3g} m" + (f"; {base}" if base else "")
        )
    return tuple(out)


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
