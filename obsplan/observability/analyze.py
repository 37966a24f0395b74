"""Both observability verdicts for one trajectory: :func:`analyze` -> :class:`ObservabilityReport`.

* ``lwo``: the observability rank condition (eq. 9, Theorem 3.4) at every sample, frozen input
  (:mod:`obsplan.observability.lwo`);
* ``gramian``: rank and scaled metrics of the exact Gramian of the augmented LTV model
  (eqs. 19-27; :mod:`obsplan.observability.gramian`), and beside them its exact rank in rational
  arithmetic (:mod:`obsplan.observability.structural`).

Two first-full-rank times, two definitions (JSON keys of the ``gramian`` dict):

* ``full_rank_from_t`` [s] (stable key): the *conditioning* time, the first sample whose
  equilibrated Gramian has every eigenvalue above ``rank_tol`` (``RANK_TOL``, 1e-10): the time
  the verdicts use. It moves with the tolerance.
* ``full_rank_interval_exact`` (0-based interval ``[t_k, t_{k+1})``) and
  ``full_rank_from_t_exact = t_{k+1}`` [s]: the first interval after which the held-input
  Gramian is non-singular in exact arithmetic, typically 3-4 intervals after excitation starts;
  ``rank_exact`` is the exact rank over the whole trajectory. Exact ranks are of the path's
  *structure*: inputs that are zero, parallel or in a subspace to ``STRUCTURE_RTOL`` (1e-9
  relative) are made exactly so first, so round-off cannot read as excitation (a straight 3D line
  with range and DVL is rank 6 of 8 in every exact key; see ``structural.py``).
  ``null`` where the Gramian is never exactly non-singular, or when ``exact=False``.

Moving beacon (``beacon_path``): only the motion relative to the beacon matters, and both tests
are today's on the relative trajectory (``lwo.py`` and ``gramian.py``, "Moving beacon"). The
exact rank profile is not computed for a moving beacon (its keys are ``null``): its rational
arithmetic integrates held inputs, and the relative velocity jumps at the beacon's knots.
``to_dict`` then adds ``"beacon_motion": "path"``.

A fixed beacon only enters the LWO test: the augmented Gramian depends on the inputs alone. A
sample on the beacon is not an error: with the half-squared range O is defined there and simply
loses rank; with the plain range (``range_form="range"``) O is undefined there (``∇|p-b|``) and
those rows count as zero rows, i.e. the rank condition is not met at that sample.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from obsplan.core.errors import InputError
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import RangeForm, make_model, parse_sensors
from obsplan.observability.calibration import CalibrationReport, calibration_report
from obsplan.observability.gramian import GramianReport, gramian_report
from obsplan.observability.lwo import LWOReport, lwo_report
from obsplan.observability.scaling import DEFAULT_SCALES, RANK_TOL, Scales
from obsplan.observability.structural import ExactRankProfile, exact_rank_profile
from obsplan.trajectory.sampled import Trajectory


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
    exact
        Exact rank of the held-input Gramian interval by interval; None if not computed.
    rank_tol
        Tolerance of the conditioning rank test behind ``gramian.rank`` and
        ``gramian.full_rank_from_t`` (eigenvalues of the equilibrated Gramian).
    beacon_motion
        ``"fixed"``, or ``"path"`` for a beacon on a known path.
    calibration
        Whether the range's scale and bias are observable along the path
        (:mod:`obsplan.observability.calibration`); None if not asked for.
    """

    dim: int
    sensors: tuple[str, ...]
    current: bool
    lwo: LWOReport
    gramian: GramianReport
    exact: ExactRankProfile | None = None
    rank_tol: float = RANK_TOL
    beacon_motion: str = "fixed"
    calibration: CalibrationReport | None = None

    def to_dict(self) -> dict:
        """The stable keys of ``obsplan analyze --json``, JSON-serialisable.

        The ``gramian`` dict carries the stable keys plus ``rank_tol``, ``rank_exact``,
        ``full_rank_interval_exact`` and ``full_rank_from_t_exact`` (module docstring).

        Returns
        -------
        dict
            ``dim``, ``sensors``, ``current``, ``lwo`` (:meth:`LWOReport.to_dict`) and
            ``gramian``; non-finite metrics are None. A moving beacon adds
            ``"beacon_motion": "path"`` and the range's calibration ``"range_calibration"``
            (:meth:`CalibrationReport.to_dict`) when asked for (the default keys are the
            stable ones only).
        """
        g = self.gramian.to_dict()
        g["rank_tol"] = float(self.rank_tol)
        if self.exact is not None:
            g.update(self.exact.to_dict())
        else:
            g.update(rank_exact=None, full_rank_interval_exact=None, full_rank_from_t_exact=None)
        out = {
            "dim": int(self.dim),
            "sensors": list(self.sensors),
            "current": bool(self.current),
            "lwo": self.lwo.to_dict(),
            "gramian": g,
        }
        if self.beacon_motion != "fixed":
            out["beacon_motion"] = self.beacon_motion
        if self.calibration is not None:
            out["range_calibration"] = self.calibration.to_dict()
        return out


def analyze(
    trajectory: Trajectory,
    sensors: str | Iterable[str] = ("range",),
    current: bool = False,
    beacon: Sequence[float] | None = None,
    scales: Scales = DEFAULT_SCALES,
    range_form: RangeForm = "half-squared",
    exact: bool = True,
    beacon_path: BeaconPath | None = None,
    calibration: bool = False,
) -> ObservabilityReport:
    """Both observability verdicts of ``trajectory``.

    Parameters
    ----------
    trajectory : Trajectory
        The sampled path (positions [m], inertial velocities [m/s], piecewise-constant inputs
        [m/s²]).
    sensors : str or iterable of str, optional
        Sensor names or a comma-separated string, e.g. ``"range,dvl-water"``.
    current : bool, optional
        Include an unknown constant ocean current in the state.
    beacon : sequence of float or None, optional
        Beacon position, shape ``(n,)`` [m]; the origin by default.
    scales : Scales, optional
        Fixed length/time scales of ``min_eig``, ``log_det``, ``condition``.
    range_form : {"half-squared", "range"}, optional
        ``"half-squared"`` (the paper's ``½|p-b|²``) or ``"range"``.
    exact : bool, optional
        Also compute the exact rank profile of the held-input Gramian (``report.exact``); not
        with ``beacon_path`` (module docstring).
    beacon_path : BeaconPath or None, optional
        A beacon moving on a known path covering the trajectory's span, of its dimension;
        excludes ``beacon``. None: a fixed beacon.
    calibration : bool, optional
        Also say whether the range's scale (a sound-speed error) and bias (a clock offset) are
        observable along the path (``report.calibration``).

    Returns
    -------
    ObservabilityReport
        The LWO rank condition at every sample, the augmented Gramian's verdict and metrics, and
        (with ``exact``) its exact rank profile.

    Raises
    ------
    InputError
        If ``trajectory`` is not a :class:`Trajectory`; ``ConfigError`` (an ``InputError``) for
        unknown sensors, a beacon of the wrong dimension, a bad range form or bad scales; both
        ``beacon`` and ``beacon_path``, or a beacon path of another dimension or that does not
        cover the trajectory.

    Examples
    --------
    A circle about the beacon is observable with range only (rank 6 of the augmented state):

    >>> from obsplan import analyze
    >>> from obsplan.trajectory import generators
    >>> report = analyze(generators.circle(50.0, 1.0, 120.0).sample(1.0))
    >>> g = report.to_dict()["gramian"]
    >>> g["full_rank"], g["rank"], g["dim"]
    (True, 6, 6)
    """
    if not isinstance(trajectory, Trajectory):
        raise InputError(
            f"trajectory must be an obsplan Trajectory, got {type(trajectory).__name__}; "
            "read a CSV with obsplan.trajectory.sampled.read_csv"
        )
    if not isinstance(scales, Scales):
        raise InputError(f"scales must be an obsplan Scales, got {type(scales).__name__}")
    if beacon_path is not None and beacon is not None:
        raise InputError("give either a fixed beacon or a beacon path, not both")
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
        lwo=lwo_report(trajectory, model, beacon_path=beacon_path),
        gramian=gramian_report(trajectory, model, scales, RANK_TOL, beacon_path=beacon_path),
        exact=exact_rank_profile(trajectory, model) if exact and beacon_path is None else None,
        rank_tol=RANK_TOL,
        beacon_motion="fixed" if beacon_path is None else "path",
        calibration=(
            calibration_report(trajectory, model, scales, RANK_TOL, beacon_path)
            if calibration
            else None
        ),
    )
