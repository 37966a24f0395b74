"""Both observability verdicts for one trajectory: :func:`analyze` -> :class:`ObservabilityReport`.

* ``lwo``: the observability rank condition (eq. 9, Theorem 3.4) at every sample, frozen input
  (:mod:`obsplan.observability.lwo`);
* ``gramian``: rank and scaled metrics of the exact Gramian of the augmented LTV model
  (eqs. 19-27; :mod:`obsplan.observability.gramian`).

The beacon only enters the LWO test: the augmented Gramian depends on the inputs alone. A sample
on the beacon is not an error: with the half-squared range O is defined there and simply loses
rank; with the plain range (``range_form="range"``) O is undefined there (``∇|p-b|``) and those
rows count as zero rows, i.e. the rank condition is not met at that sample.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from obsplan.errors import InputError
from obsplan.model import RangeForm, make_model, parse_sensors
from obsplan.observability.gramian import GramianReport, gramian_report
from obsplan.observability.lwo import LWOReport, lwo_report
from obsplan.observability.scaling import DEFAULT_SCALES, Scales
from obsplan.trajectory import Trajectory


@dataclass(frozen=True)
class ObservabilityReport:
    """Local (LWO) and global (Gramian) observability of a trajectory.

    Attributes
    ----------
    dim
        Spatial dimension (2 or 3).
    sensors
        Canonical sensor names, e.g. ``("range", "dvl-water")``.
    current
        Whether an unknown constant current is part of the state.
    lwo
        Rank condition along the trajectory.
    gramian
        Augmented-Gramian verdict and metrics (in the report's fixed scales).
    """

    dim: int
    sensors: tuple[str, ...]
    current: bool
    lwo: LWOReport
    gramian: GramianReport

    def to_dict(self) -> dict:
        """The keys of ``obsplan analyze --json`` (PRODUCT.md), JSON-serialisable."""
        return {
            "dim": int(self.dim),
            "sensors": list(self.sensors),
            "current": bool(self.current),
            "lwo": self.lwo.to_dict(),
            "gramian": self.gramian.to_dict(),
        }


def analyze(
    trajectory: Trajectory,
    sensors: str | Iterable[str] = ("range",),
    current: bool = False,
    beacon: Sequence[float] | None = None,
    scales: Scales = DEFAULT_SCALES,
    range_form: RangeForm = "half-squared",
) -> ObservabilityReport:
    """Both observability verdicts of ``trajectory``.

    Parameters
    ----------
    trajectory
        The sampled path (positions [m], inertial velocities [m/s], piecewise-constant inputs
        [m/s²]).
    sensors
        Sensor names or a comma-separated string, e.g. ``"range,dvl-water"``.
    current
        Include an unknown constant ocean current in the state.
    beacon
        Beacon position, shape ``(n,)`` [m]; the origin by default.
    scales
        Fixed length/time scales of ``min_eig``, ``log_det``, ``condition``.
    range_form
        ``"half-squared"`` (the paper's ``½|p-b|²``) or ``"range"``.

    Raises
    ------
    InputError
        If ``trajectory`` is not a :class:`Trajectory`; ``ConfigError`` (an ``InputError``) for
        unknown sensors, a beacon of the wrong dimension, a bad range form or bad scales.
    """
    if not isinstance(trajectory, Trajectory):
        raise InputError(
            f"trajectory must be an obsplan Trajectory, got {type(trajectory).__name__}; "
            "read a CSV with obsplan.trajectory.read_csv"
        )
    if not isinstance(scales, Scales):
        raise InputError(f"scales must be an obsplan Scales, got {type(scales).__name__}")
    model = make_model(
        dim=trajectory.dim,
        sensors=parse_sensors(sensors),
        current=bool(current),
        beacon=beacon,
        range_form=range_form,
    )
    return ObservabilityReport(
        dim=model.dim,
        sensors=model.sensors,
        current=model.current,
        lwo=lwo_report(trajectory, model),
        gramian=gramian_report(trajectory, model, scales),
    )
