"""The sections of a problem file as frozen dataclasses, and :class:`ProblemData`, all of them.

The fields, units and defaults are declared once in :mod:`obsplan.planning.problem.schema`.
:class:`ProblemData` is what the checks (:mod:`obsplan.planning.problem.checks`) read; the
package holds its checked form, :class:`~obsplan.planning.problem.definition.PlanningProblem`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from obsplan.estimation.channel import Channel, channel_preset
from obsplan.estimation.config import DEFAULT_ACCEL_NOISE
from obsplan.estimation.schedule import read_ping_times
from obsplan.model.beacon import BeaconPath, BeaconVehicle, read_beacon_path
from obsplan.model.frames import GeodeticOrigin
from obsplan.model.vehicle import VehicleModel
from obsplan.observability.scaling import Scales
from obsplan.planning.missions.spec import Mission, MissionContext
from obsplan.planning.problem.schema import (
    KF_PCRB_WEIGHT,
    LINEARISATION_BOUND,
    LINEARISATION_KINDS,
    LINEARISED_KINDS,
    OBJECTIVE_KINDS,
)


@dataclass(frozen=True)
class VehicleSpec:
    """Vehicle: dimension, sensors and current (units and defaults:
    :data:`~obsplan.planning.problem.schema.SCHEMA`)."""

    dim: int = 2
    sensors: tuple[str, ...] = ("range",)
    current: bool = False
    current_velocity: tuple[float, ...] = (0.0, 0.0)
    range_form: str = "half-squared"
    #: With a moving beacon: a trajectory CSV the vehicle flies, or ``"lawnmower"``; None: the
    #: vehicle is planned.
    path: str | None = None


@dataclass(frozen=True)
class Area:
    """Axis-aligned operating area [m]: ``x`` and ``y`` as ``(min, max)``."""

    x: tuple[float, float]
    y: tuple[float, float]

    @property
    def width(self) -> float:
        return self.x[1] - self.x[0]

    @property
    def height(self) -> float:
        return self.y[1] - self.y[0]

    @property
    def center(self) -> tuple[float, float]:
        return (0.5 * (self.x[0] + self.x[1]), 0.5 * (self.y[0] + self.y[1]))


@dataclass(frozen=True)
class BeaconMotion:
    """How the beacon moves (``[beacon] motion`` and its fields; units and defaults:
    :data:`~obsplan.planning.problem.schema.SCHEMA`): ``"fixed"`` at ``beacon.position``,
    ``"path"`` along the CSV ``path`` (resolved against the problem file's folder by the
    loader; or a :class:`~obsplan.model.beacon.BeaconPath` given in memory, e.g. a planned
    craft's path while the vehicle is planned for it, which a problem file cannot hold), or
    ``"planned"``: a surface craft starting at ``beacon.position`` with the limits
    ``speed`` [m/s], per-axis ``accel`` [m/s²], start ``velocity`` [m/s], ``area``, ``max_range``
    and horizontal ``min_distance`` [m]."""

    motion: str = "fixed"
    path: str | BeaconPath | None = None
    speed: float | None = None
    accel: tuple[float, float] | None = None
    velocity: tuple[float, float] | None = None
    area: Area | None = None
    max_range: float | None = None
    min_distance: float = 0.0

    @property
    def moving(self) -> bool:
        """The beacon moves (``motion`` is not ``"fixed"``)."""
        return self.motion != "fixed"


@dataclass(frozen=True)
class Limits:
    """Limits: per-axis acceleration [m/s²], speed [m/s], depth band and area [m], distance to the
    beacon [m] and minimum speed through the water [m/s]
    (:data:`~obsplan.planning.problem.schema.SCHEMA`)."""

    accel: tuple[float, ...]
    speed: float
    depth: tuple[float, float] | None = None
    area: Area | None = None
    min_range: float = 5.0
    max_range: float | None = None
    min_speed: float = 0.0
    keepout_confidence: float = 0.999


@dataclass(frozen=True)
class Horizon:
    """Planning horizon: ``duration`` [s] split into ``steps`` constant-input intervals."""

    duration: float
    steps: int

    @property
    def dt(self) -> float:
        """Planning step ``duration / steps`` [s]."""
        return self.duration / self.steps


@dataclass(frozen=True)
class ObjectiveSpec:
    """Objective kind, multi-start settings and the Gramian objectives' weights and windows."""

    kind: str = "pcrb-position"
    mode: str = "auto"
    starts: int = 4
    seed: int = 0
    max_iter: int = 1000
    tol: float | None = None
    weights: str = "information"
    system: str = "auto"
    window: float | str = "auto"
    stride: float | str = "auto"
    anchor: str = "current"
    robust_prior: tuple[float, ...] = ()
    robust_range_noise: tuple[float, ...] = ()
    robust_aggregate: str = "worst"
    pcrb_weight: float | None = None
    linearisation_bound: float | None = None
    kf_guard: float | None = None
    ekf_guard: float | None = None

    @property
    def paper_form(self) -> bool:
        """The paper's formulation: unit weights (``weights = "none"``) and, for the Gramian
        kinds, one window over the mission (``G(t_N, t_0)``); ``lwo-condition``'s scale-free form
        reads no window."""
        if self.weights != "none":
            return False
        if self.kind == "lwo-condition":
            return True
        return self.window == "mission" and self.resolved_system == "augmented"

    @property
    def resolved_system(self) -> str:
        """The model whose Gramian the Gramian kinds score (``system``): ``"auto"`` is the
        vehicle's model linearised about the path (``"linearised"``) for the kinds of
        :data:`~obsplan.planning.problem.schema.LINEARISED_KINDS` with information weights,
        otherwise the paper's augmented model (``"augmented"``); every other kind reads
        ``"augmented"`` (``lwo-condition`` and the estimator kinds have their own models)."""
        if not self.kind.startswith("gramian-"):
            return "augmented"
        if self.system != "auto":
            return self.system
        if self.kind in LINEARISED_KINDS and self.weights == "information":
            return "linearised"
        return "augmented"

    @property
    def resolved_linearisation_bound(self) -> float:
        """``linearisation_bound`` [range stds], or its default: 0.25 for the kinds of
        :data:`~obsplan.planning.problem.schema.LINEARISATION_KINDS` weighted by information, 0
        (off) otherwise."""
        if self.linearisation_bound is not None:
            return float(self.linearisation_bound)
        if self.kind in LINEARISATION_KINDS and self.weights == "information":
            return LINEARISATION_BOUND
        return 0.0

    @property
    def resolved_pcrb_weight(self) -> float:
        """The posterior CRB's weight in ``kf-position-std``'s objective (``pcrb_weight``, or
        :data:`~obsplan.planning.problem.schema.KF_PCRB_WEIGHT`); 0 for every other kind."""
        if self.kind != "kf-position-std":
            return 0.0
        return KF_PCRB_WEIGHT if self.pcrb_weight is None else float(self.pcrb_weight)

    @property
    def solver_tol(self) -> float:
        """``tol``, or the kind's default
        (:data:`~obsplan.planning.problem.schema.OBJECTIVE_KINDS`)."""
        if self.tol is not None:
            return self.tol
        kind = OBJECTIVE_KINDS[self.kind]
        if kind.windowed_tol is not None and not self.paper_form:
            return kind.windowed_tol
        return kind.default_tol


#: ``validation.channel_*`` fields -> the :class:`~obsplan.estimation.channel.Channel` field
#: each sets.
CHANNEL_KEYS: dict[str, str] = {
    "channel_dropout": "dropout",
    "channel_dropout_range": "dropout_range_m",
    "channel_outlier_fraction": "outlier_fraction",
    "channel_outlier_excess": "outlier_excess_m",
    "channel_sound_speed_scale": "sound_speed_scale",
    "channel_clock_offset": "clock_offset_s",
    "channel_ping_jitter": "ping_jitter_s",
}


@dataclass(frozen=True)
class ValidationSpec:
    """Monte Carlo validation settings: runs, seed, filter step [s], rates [Hz], noises, prior,
    process noise [m/s²/√Hz], closed or open loop, cap on the runs."""

    runs: int = 50
    seed: int = 0
    dt: float = 0.1
    range_rate: float = 1.0
    range_std: float = 0.1
    dvl_rate: float = 10.0
    dvl_std: float = 1e-3
    depth_rate: float = 1.0
    depth_std: float = 0.1
    init_pos_error: float = 1.0
    init_vel_error: float = 0.1
    accel_noise: float = DEFAULT_ACCEL_NOISE
    process_noise_model: str = "physical"
    mode: str = "closed-loop"
    ekf_update: str = "second-order"
    navigation: str = "gsf"
    max_runs: int = 400
    stress_prior: float = 1.0
    stress_range_noise: float = 1.0
    stress_channel: str | None = None
    channel: str = "ideal"
    channel_dropout: float | None = None
    channel_dropout_range: float | None = None
    channel_outlier_fraction: float | None = None
    channel_outlier_excess: tuple[float, float] | None = None
    channel_sound_speed_scale: float | None = None
    channel_clock_offset: float | None = None
    channel_ping_jitter: float | None = None
    gate: float | str = "auto"
    scale_state: str = "auto"
    range_times: str | None = None
    bias_state: str = "auto"

    def channel_model(self) -> Channel:
        """The acoustic channel of the validation: the preset ``channel`` with the
        ``channel_*`` fields that are given.

        Returns
        -------
        Channel
            The channel (:mod:`obsplan.estimation.channel`).

        Raises
        ------
        ConfigError
            For an unknown preset or a field out of range.
        """
        return channel_preset(
            self.channel, **{CHANNEL_KEYS[k]: getattr(self, k) for k in CHANNEL_KEYS}
        )


@dataclass(frozen=True)
class ProblemData:
    """The sections of a planning problem and what follows from them, not yet checked.

    The checks (:mod:`obsplan.planning.problem.checks`) read this; what the rest of the package
    holds is its checked form, :class:`~obsplan.planning.problem.definition.PlanningProblem`.
    """

    vehicle: VehicleSpec
    beacon: tuple[float, ...]
    start_position: tuple[float, ...]
    start_velocity: tuple[float, ...]
    limits: Limits
    horizon: Horizon
    objective: ObjectiveSpec = field(default_factory=ObjectiveSpec)
    scales: Scales = field(default_factory=Scales)
    validation: ValidationSpec = field(default_factory=ValidationSpec)
    name: str = ""
    #: Origin of the local north-east-down frame when the problem was given geodetically.
    origin: GeodeticOrigin | None = None
    #: What the vehicle must do besides localising (None: free localisation).
    mission: Mission | None = None
    #: How the beacon moves (default: fixed at ``beacon``).
    beacon_motion: BeaconMotion = field(default_factory=BeaconMotion)

    @cached_property
    def model(self) -> VehicleModel:
        """The vehicle model (beacon included)."""
        v = self.vehicle
        return VehicleModel(
            dim=v.dim,
            sensors=v.sensors,
            current=v.current,
            beacon=self.beacon,
            range_form=v.range_form,  # type: ignore[arg-type]
        )

    @property
    def dim(self) -> int:
        return self.vehicle.dim

    @cached_property
    def range_times(self) -> np.ndarray | None:
        """The ping schedule of ``validation.range_times`` [s from the start], or None.

        Raises
        ------
        TrajectoryFormatError
            A file that is missing or malformed (:func:`~obsplan.estimation.schedule.
            read_ping_times`).
        """
        name = self.validation.range_times
        return None if name is None else read_ping_times(name, where="validation.range_times")

    @cached_property
    def beacon_path(self) -> BeaconPath | None:
        """The known beacon path of ``beacon.motion = "path"`` (read from ``beacon.path``),
        else None.

        Raises
        ------
        TrajectoryFormatError
            A file that is missing or malformed, or of another dimension than the vehicle's.
        """
        bm = self.beacon_motion
        if bm.motion != "path" or bm.path is None:
            return None
        if isinstance(bm.path, BeaconPath):
            return bm.path
        return read_beacon_path(bm.path, self.dim, where="beacon.path")

    @property
    def beacon_start(self) -> np.ndarray:
        """Where the beacon is at ``t = 0`` [m], shape ``(n,)``: ``beacon.position``, or the
        start of its known path (``beacon.motion = "path"``)."""
        path = self.beacon_path
        return np.asarray(self.beacon, float) if path is None else path.position(0.0)[0]

    @cached_property
    def beacon_vehicle(self) -> BeaconVehicle | None:
        """The craft of ``beacon.motion = "planned"`` (start ``beacon.position``), else None.

        Raises
        ------
        InputError
            A limit that is not positive, a start velocity above the speed, a start outside
            the craft's area.
        """
        bm = self.beacon_motion
        if bm.motion != "planned" or bm.speed is None or bm.accel is None:
            return None
        area = None if bm.area is None else np.array([bm.area.x, bm.area.y], float)
        return BeaconVehicle(
            start=np.asarray(self.beacon, float),
            speed=float(bm.speed),
            accel=np.asarray(bm.accel, float),
            velocity=np.asarray(bm.velocity or (0.0, 0.0), float),
            area=area,
            max_range=bm.max_range,
            min_distance=float(bm.min_distance),
        )

    @property
    def p0(self) -> np.ndarray:
        """Start position, shape (n,) [m]."""
        return np.asarray(self.start_position, float)

    @property
    def v0(self) -> np.ndarray:
        """Start inertial velocity, shape (n,) [m/s]."""
        return np.asarray(self.start_velocity, float)

    @property
    def accel(self) -> np.ndarray:
        """Per-axis acceleration bounds, shape (n,) [m/s²]."""
        return np.asarray(self.limits.accel, float)

    @property
    def times(self) -> np.ndarray:
        """Planning grid ``t_k = k dt``, shape (N + 1,) [s]."""
        return np.linspace(0.0, self.horizon.duration, self.horizon.steps + 1)

    @property
    def objective_mode(self) -> str:
        """``objective.mode`` with ``auto`` resolved
        (:data:`~obsplan.planning.problem.schema.MODES`): the kind's own
        (:attr:`~obsplan.planning.problem.schema.ObjectiveKind.auto_mode`), except that with survey
        lines ``average-and-final`` becomes ``lines-and-final`` (the samples the sonar data needs
        instead of the whole mission's: the transits and turns do not count)."""
        mode = self.objective.mode
        if mode == "auto":
            mode = OBJECTIVE_KINDS[self.objective.kind].auto_mode
            if mode == "average-and-final" and self.mission is not None and self.mission.lines:
                return "lines-and-final"
        return mode

    @property
    def current_array(self) -> np.ndarray:
        """The current ``v_f`` assumed by the limits and the validation, shape (n,) [m/s]."""
        return np.asarray(self.vehicle.current_velocity, float)

    @property
    def filter_times(self) -> np.ndarray:
        """The validation's filter grid ``k * validation.dt`` over the horizon, shape (M,) [s]."""
        steps = int(round(self.horizon.duration / self.validation.dt))
        return np.linspace(0.0, self.horizon.duration, steps + 1)

    def coverage_area(self) -> Area:
        """The area the lawn-mower baseline covers: ``limits.area`` or the documented default.

        Returns
        -------
        Area
            ``limits.area``, or else a square of side ``limits.speed * horizon.duration / 4``
            [m] centred on the start.
        """
        if self.limits.area is not None:
            return self.limits.area
        side = self.limits.speed * self.horizon.duration / 4.0
        cx, cy = float(self.p0[0]), float(self.p0[1])
        return Area(x=(cx - side / 2, cx + side / 2), y=(cy - side / 2, cy + side / 2))

    @cached_property
    def mission_context(self) -> MissionContext:
        """What the mission's timing needs of the problem (:mod:`obsplan.planning.missions`)."""
        return MissionContext(
            mission=self.mission,
            start_position=tuple(float(x) for x in self.start_position),
            start_velocity=tuple(float(x) for x in self.start_velocity),
            accel_limit=tuple(float(x) for x in self.limits.accel),
            speed_limit=float(self.limits.speed),
            min_speed=float(self.limits.min_speed),
            duration=float(self.horizon.duration),
            steps=int(self.horizon.steps),
        )
