"""The robustness row: every path re-validated under stated multiples, without replanning.

``validation.stress_prior`` multiplies the validation's prior std (``init_pos_error``,
``init_vel_error``) and ``validation.stress_range_noise`` its range std; every path (the plan and
the baselines) is flown again through :func:`~obsplan.planning.validation.validate.validate_paths`
under that condition, with the same runs and seed, and compared as the nominal validation is
(:func:`~obsplan.planning.validation.verdict.verdict`). The filters are configured for the condition
(their prior and range noise scaled with the truth's): what changes is the world the plan meets, not
the plan. ``validation.stress_channel`` (a preset of :mod:`obsplan.estimation.channel`, with the
problem's ``channel_*`` fields) sends every path's ranges through that acoustic channel in the row:
the verdict re-run where pings are lost, late and scaled, the filters gated as the channel's
defaults say (:func:`~obsplan.estimation.channel.default_gate`), beside the nominal one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

from obsplan.estimation.channel import Channel
from obsplan.planning.objectives.robust import scaled_problem
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.validation.validate import PathValidation, validate_paths
from obsplan.planning.validation.verdict import Verdict, verdict
from obsplan.trajectory.sampled import Trajectory


def stress_active(pb: PlanningProblem) -> bool:
    """True when ``[validation]`` states a multiple other than 1.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``validation.stress_prior``, ``stress_range_noise`` and
        ``stress_channel``.

    Returns
    -------
    bool
        Either multiple differs from 1 or a stress channel is set (the robustness row is then
        run).
    """
    val = pb.validation
    return (
        val.stress_prior != 1.0 or val.stress_range_noise != 1.0 or val.stress_channel is not None
    )


@dataclass(frozen=True, eq=False)
class Robustness:
    """Validation of every path under the stress condition (``robustness`` of report.json).

    Attributes
    ----------
    prior, range_noise : float
        The multiples of the prior std and of the range std.
    validation : dict[str, PathValidation]
        Per path, as the nominal validation.
    channel : Channel or None
        The acoustic channel of the row (``validation.stress_channel``), None: the nominal
        validation's.
    """

    prior: float
    range_noise: float
    validation: dict[str, PathValidation]
    channel: Channel | None = None

    @property
    def condition(self) -> str:
        """The condition in words, e.g. ``"prior x1, range noise x1, channel at-sea"``."""
        words = f"prior x{self.prior:g}, range noise x{self.range_noise:g}"
        if self.channel is not None:
            words += f", channel {self.channel.name} ({self.channel.describe()})"
        return words

    @property
    def verdict(self) -> Verdict:
        """The plan against every baseline under the condition."""
        return verdict(self.validation, {})

    def to_dict(self) -> dict:
        """The ``robustness`` entry of report.json.

        Returns
        -------
        dict
            The two multiples, the channel (:meth:`~obsplan.estimation.channel.Channel.to_dict`,
            None: the nominal one), every path's validation
            (:meth:`~obsplan.planning.validation.validate.PathValidation.to_dict`) and the
            verdict under the condition.
        """
        return {
            "prior": self.prior,
            "range_noise": self.range_noise,
            "channel": None if self.channel is None else self.channel.to_dict(),
            "validation": {k: v.to_dict() for k, v in self.validation.items()},
            "verdict": self.verdict.to_dict(),
        }


def stress_validate(
    paths: Mapping[str, Trajectory],
    pb: PlanningProblem,
    *,
    runs: int | None = None,
    progress: bool = False,
) -> Robustness:
    """Validate ``paths`` under ``pb``'s stress multiples (module docstring).

    Parameters
    ----------
    paths : Mapping of str to Trajectory
        Name -> path (``"planned"`` and the baselines), on the planning grid.
    pb : PlanningProblem
        The problem: its ``[validation]`` and stress multiples.
    runs : int or None, optional
        Override ``validation.runs``.
    progress : bool, optional
        A progress bar over runs.

    Returns
    -------
    Robustness
        Every path's validation under the condition (same runs and seed as the nominal one).
    """
    val, spb = pb.validation, stress_problem(pb)
    res = validate_paths(paths, spb, runs=runs, progress=progress)
    channel = None if val.stress_channel is None else spb.validation.channel_model()
    return Robustness(val.stress_prior, val.stress_range_noise, res, channel)


def stress_problem(pb: PlanningProblem) -> PlanningProblem:
    """The problem of the robustness row: the prior and range stds times the stress multiples,
    the ranges through ``validation.stress_channel`` when set (module docstring).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    PlanningProblem
        The condition's problem (its ``validation.channel`` the stress channel when set).
    """
    val = pb.validation
    spb = scaled_problem(pb, val.stress_prior, val.stress_range_noise)
    if val.stress_channel is None:
        return spb
    return replace(spb, validation=replace(spb.validation, channel=val.stress_channel))
