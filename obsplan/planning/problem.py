"""Planning problems: the TOML problem file, its frozen dataclasses and its validation.

One table, :data:`SCHEMA`, lists every field with its type, unit, default and meaning; the loader,
the error messages and ``docs/problem-files.md`` all come from it, so they cannot drift apart.
Every check that can fail is done here, before any solver runs: unknown keys, wrong types, and
infeasible combinations (start faster than the speed limit, a zero acceleration bound, fewer than
2 steps, a depth band or operating area that does not contain the start, an objective that the
sensors make structurally impossible).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from obsplan.errors import ConfigError, ProblemError
from obsplan.io.geodetic import GeodeticOrigin, resolve_problem_geodetic
from obsplan.model import VehicleModel, parse_sensors
from obsplan.observability.scaling import Scales

OBJECTIVES: tuple[str, ...] = (
    "pcrb-position",
    "gramian-min-eig",
    "gramian-log-det",
    "lwo-condition",
    "kf-position-std",
)
#: Objectives that follow an estimator's covariance along the path and so have a time mode.
TIMED_OBJECTIVES: tuple[str, ...] = ("pcrb-position", "kf-position-std")
#: ``objective.mode`` values; ``auto`` is ``final`` for kf-position-std (its historical meaning)
#: and ``average-and-final`` for pcrb-position.
MODES: tuple[str, ...] = ("auto", "final", "mission-average", "average-and-final")
#: Largest ``horizon.steps`` the planner accepts: the NLP grows linearly in N and IPOPT's time
#: faster; N = 1000 solves in seconds to a minute (README benchmarks), 5000 is already hours.
MAX_STEPS = 5000
#: Longest horizon [s] and largest speed [m/s], acceleration [m/s²] and coordinate [m] accepted:
#: far beyond any vehicle (a bound keeps absurd inputs from overflowing the checks' arithmetic).
MAX_DURATION_S = 1e7
MAX_MAGNITUDE = 1e7
#: Budget of the validation Monte Carlo: runs x filter samples x state size (~8 bytes each per
#: stored quantity); beyond it the simulation would need tens of GiB.
MAX_MC_SIZE = 1e9
#: Where ``obsplan plan`` looks when no problem file is given.
PROBLEMS_DIR = Path(__file__).resolve().parents[2] / "problems"
DEFAULT_PROBLEM = PROBLEMS_DIR / "default.toml"


@dataclass(frozen=True)
class FieldSpec:
    """One documented field of the problem file."""

    name: str
    kind: str  # "int", "float", "bool", "str", "str-list", "vec", "vec-or-float", "range", "area"
    default: Any
    unit: str
    doc: str
    required: bool = False


_NONE = None
SCHEMA: dict[str, tuple[FieldSpec, ...]] = {
    "problem": (
        FieldSpec("name", "str", "", "-", "Free-text name shown in reports (default: file stem)."),
    ),
    "vehicle": (
        FieldSpec("dim", "int", 2, "-", "Spatial dimension n: 2 or 3."),
        FieldSpec(
            "sensors",
            "str-list",
            ["range"],
            "-",
            'Sensor names: "range" (required), "dvl-bottom" (alias "dvl"), "dvl-water", "depth".',
        ),
        FieldSpec(
            "current",
            "bool",
            False,
            "-",
            "Estimate an unknown constant ocean current v_f (state (p, v, v_f), eqs. 28-30).",
        ),
        FieldSpec(
            "current_velocity",
            "vec",
            _NONE,
            "m/s",
            "True current v_f of the validation's truth simulation; default zeros; non-zero "
            "only with current = true.",
        ),
        FieldSpec(
            "range_form",
            "str",
            "half-squared",
            "-",
            'Range output of the filters: "half-squared" (y = |p-b|^2/2, eq. 3) or "range".',
        ),
    ),
    "origin": (
        FieldSpec(
            "latitude",
            "float",
            _NONE,
            "deg",
            "WGS84 latitude of the origin of the local north-east-down frame (x north, y east, "
            "z down = depth; obsplan.io.geodetic). Needed by beacon.geodetic / start.geodetic; "
            "reports carry it and `obsplan export` writes geodetic waypoints with it.",
        ),
        FieldSpec("longitude", "float", _NONE, "deg", "WGS84 longitude of the origin."),
        FieldSpec(
            "altitude",
            "float",
            0.0,
            "m",
            "Ellipsoidal height of the depth-0 surface at the origin (depth = altitude - height).",
        ),
    ),
    "beacon": (
        FieldSpec("position", "vec", _NONE, "m", "Beacon position b (n values); default origin."),
        FieldSpec(
            "geodetic",
            "vec",
            _NONE,
            "deg, deg[, m]",
            "Instead of position: [latitude, longitude] (2D) or [latitude, longitude, depth] "
            "(3D) about [origin].",
        ),
    ),
    "start": (
        FieldSpec("position", "vec", _NONE, "m", "Start position p(0) (n values).", True),
        FieldSpec("velocity", "vec", _NONE, "m/s", "Start inertial velocity p'(0); default zeros."),
        FieldSpec(
            "geodetic",
            "vec",
            _NONE,
            "deg, deg[, m]",
            "Instead of position (then not required): [latitude, longitude] (2D) or "
            "[latitude, longitude, depth] (3D) about [origin].",
        ),
    ),
    "limits": (
        FieldSpec(
            "accel",
            "vec-or-float",
            _NONE,
            "m/s^2",
            "Per-axis acceleration bound |u_i| <= a_i: one number for all axes or n values.",
            True,
        ),
        FieldSpec(
            "speed",
            "float",
            _NONE,
            "m/s",
            "Speed bound |p'| <= v_max (speed over ground; with a current choose it so that "
            "the speed through water stays feasible).",
            True,
        ),
        FieldSpec(
            "depth",
            "range",
            _NONE,
            "m",
            "3D only: [z_min, z_max] band for p_z on the whole continuous path; default none.",
        ),
        FieldSpec(
            "min_range",
            "float",
            5.0,
            "m",
            "Minimum distance |p-b| to the beacon on the whole continuous path (mooring, "
            "transducer blanking); 0 disables it. The start must respect it.",
        ),
        FieldSpec(
            "max_range",
            "float",
            _NONE,
            "m",
            "Maximum distance |p-b| to the beacon (acoustic range) on the whole continuous "
            "path; default none.",
        ),
        FieldSpec(
            "min_speed",
            "float",
            0.0,
            "m/s",
            "Minimum speed through the water |p' - v_f| (v_f = vehicle.current_velocity) on the "
            "whole continuous path, for vehicles that cannot hover; the start velocity must "
            "respect it. 0 disables it.",
        ),
        FieldSpec(
            "area",
            "area",
            _NONE,
            "m",
            "Operating area {x = [min, max], y = [min, max]} on the whole continuous path; "
            "the lawn-mower baseline covers it. Default none (the lawn-mower then covers a square "
            "of side speed*duration/4 centred on the start).",
        ),
    ),
    "horizon": (
        FieldSpec("duration", "float", _NONE, "s", "Planning horizon T_f.", True),
        FieldSpec(
            "steps",
            "int",
            _NONE,
            "-",
            "Number N of constant-acceleration intervals (N + 1 nodes), N >= 2.",
            True,
        ),
    ),
    "objective": (
        FieldSpec(
            "kind",
            "str",
            "pcrb-position",
            "-",
            "One of " + ", ".join(OBJECTIVES) + " (docs/problem-files.md has their formulations).",
        ),
        FieldSpec(
            "mode",
            "str",
            "auto",
            "-",
            'For pcrb-position and kf-position-std: "final" (position std at the end), '
            '"mission-average" (its time average over the mission) or "average-and-final" (the '
            'sum of the two, each relative to its value on the lawn-mower); "auto" is '
            "average-and-final for pcrb-position and final for kf-position-std.",
        ),
        FieldSpec(
            "starts",
            "int",
            4,
            "-",
            "Number of initial guesses: lawn-mower, circle, then seeded random ones.",
        ),
        FieldSpec("seed", "int", 0, "-", "Seed of the random initial guesses."),
        FieldSpec("max_iter", "int", 1000, "-", "IPOPT iteration limit per start."),
        FieldSpec(
            "tol",
            "float",
            _NONE,
            "-",
            "IPOPT convergence tolerance (tol) of the NLP, whose objective is normalised to 1 on "
            "the lawn-mower; default 1e-8, or 1e-4 for pcrb-position and kf-position-std (L-BFGS "
            "converges slowly: at N = 1000, 1e-5 takes 5x the iterations for a 0.4 % better "
            "bound).",
        ),
    ),
    "scales": (
        FieldSpec(
            "length_m",
            "float",
            100.0,
            "m",
            "Length scale L of the Gramian metrics and objectives (obsplan.observability.scaling).",
        ),
        FieldSpec("time_s", "float", 100.0, "s", "Time scale T of the Gramian metrics."),
    ),
    "validation": (
        FieldSpec("runs", "int", 50, "-", "Monte Carlo runs per trajectory (EKF and KF)."),
        FieldSpec("seed", "int", 0, "-", "Seed of the Monte Carlo runs (same for every path)."),
        FieldSpec(
            "dt", "float", 0.1, "s", "Filter prediction step; must divide the planning step."
        ),
        FieldSpec("range_rate", "float", 1.0, "Hz", "Range measurement rate."),
        FieldSpec("range_std", "float", 0.1, "m", "Range noise standard deviation (on |p-b|)."),
        FieldSpec("dvl_rate", "float", 10.0, "Hz", "DVL rate (if a DVL is fitted)."),
        FieldSpec("dvl_std", "float", 1e-3, "m/s", "DVL noise standard deviation per axis."),
        FieldSpec("depth_rate", "float", 1.0, "Hz", "Depth gauge rate (if fitted)."),
        FieldSpec("depth_std", "float", 0.1, "m", "Depth noise standard deviation."),
        FieldSpec(
            "init_pos_error",
            "float",
            1.0,
            "m",
            "Initial position error standard deviation per axis (filters' prior and draws).",
        ),
        FieldSpec(
            "init_vel_error",
            "float",
            0.1,
            "m/s",
            "Initial velocity error standard deviation per axis.",
        ),
    ),
}


@dataclass(frozen=True)
class VehicleSpec:
    """Vehicle: dimension, sensors and current (see :data:`SCHEMA` for units and defaults)."""

    dim: int = 2
    sensors: tuple[str, ...] = ("range",)
    current: bool = False
    current_velocity: tuple[float, ...] = (0.0, 0.0)
    range_form: str = "half-squared"


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
class Limits:
    """Limits: per-axis acceleration [m/s²], speed [m/s], depth band and area [m], distance to the
    beacon [m] and minimum speed through the water [m/s] (see :data:`SCHEMA`)."""

    accel: tuple[float, ...]
    speed: float
    depth: tuple[float, float] | None = None
    area: Area | None = None
    min_range: float = 5.0
    max_range: float | None = None
    min_speed: float = 0.0


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
    """Objective kind and multi-start settings."""

    kind: str = "pcrb-position"
    mode: str = "auto"
    starts: int = 4
    seed: int = 0
    max_iter: int = 1000
    tol: float | None = None

    @property
    def solver_tol(self) -> float:
        """``tol`` with the default of :data:`SCHEMA` resolved."""
        if self.tol is not None:
            return self.tol
        return 1e-4 if self.kind in TIMED_OBJECTIVES else 1e-8


@dataclass(frozen=True)
class ValidationSpec:
    """Monte Carlo validation settings: runs, seed, filter step [s], rates [Hz], noises, prior."""

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


@dataclass(frozen=True)
class PlanningProblem:
    """A complete planning problem (what a problem file holds), validated on construction.

    Build it with :func:`load_problem` / :func:`problem_from_dict`, or directly; ``__post_init__``
    runs the same checks as the loader.
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

    def __post_init__(self) -> None:
        _check_problem(self)

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
        """``objective.mode`` with ``auto`` resolved (see :data:`MODES`)."""
        mode = self.objective.mode
        if mode == "auto":
            return "final" if self.objective.kind == "kf-position-std" else "average-and-final"
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
        """The area the lawn-mower baseline covers: ``limits.area`` or the documented default."""
        if self.limits.area is not None:
            return self.limits.area
        side = self.limits.speed * self.horizon.duration / 4.0
        cx, cy = float(self.p0[0]), float(self.p0[1])
        return Area(x=(cx - side / 2, cx + side / 2), y=(cy - side / 2, cy + side / 2))

    def estimation_config(self):
        """The filters' configuration (:class:`~obsplan.estimation.config.EstimationConfig`).

        The paper's covariances at step ``validation.dt`` with the prior of ``p`` and ``v`` set by
        ``init_pos_error`` / ``init_vel_error``, the problem's rates and noises, and the true
        current ``vehicle.current_velocity``. Used by the validation and by the planning KF.
        """
        from obsplan.estimation.config import EstimationConfig, paper_covariances

        model, val, n = self.model, self.validation, self.dim
        cov = paper_covariances(model, val.dt)
        for key in ("p0_ekf", "p0_kf"):
            d = np.diag(cov[key]).copy()
            d[:n] = val.init_pos_error**2
            d[n : 2 * n] = val.init_vel_error**2
            cov[key] = np.diag(d)
        rates = {"range": val.range_rate}
        noise = {"range": val.range_std}
        for s in model.sensors:
            if s.startswith("dvl"):
                rates[s], noise[s] = val.dvl_rate, val.dvl_std
            elif s == "depth":
                rates[s], noise[s] = val.depth_rate, val.depth_std
        return EstimationConfig(
            model=model,
            rates_hz=rates,
            noise=noise,
            true_current=self.vehicle.current_velocity if self.vehicle.current else None,
            init_error="sample",
            **cov,
        )

    def with_changes(self, **sections: Any) -> PlanningProblem:
        """A copy with whole sections replaced (``horizon=Horizon(...)``, ``objective=...``)."""
        from dataclasses import replace

        return replace(self, **sections)


# ------------------------------------------------------------------------------ parsing
def _err(path: str, msg: str) -> ProblemError:
    return ProblemError(f"{path}: {msg}")


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _parse_value(section: str, spec: FieldSpec, raw: Any, dim: int) -> Any:
    where = f"{section}.{spec.name}"
    k = spec.kind
    if k == "int":
        if not isinstance(raw, int) or isinstance(raw, bool):
            raise _err(where, f"expected an integer, got {raw!r}")
        return int(raw)
    if k == "float":
        if not _is_number(raw) or not math.isfinite(raw):
            raise _err(where, f"expected a finite number [{spec.unit}], got {raw!r}")
        return float(raw)
    if k == "bool":
        if not isinstance(raw, bool):
            raise _err(where, f"expected true or false, got {raw!r}")
        return raw
    if k == "str":
        if not isinstance(raw, str):
            raise _err(where, f"expected a string, got {raw!r}")
        return raw
    if k == "str-list":
        if isinstance(raw, str):
            raw = [s for s in raw.split(",")]
        if not isinstance(raw, list) or not all(isinstance(s, str) for s in raw):
            raise _err(where, f'expected a list of names such as ["range"], got {raw!r}')
        return raw
    if k in ("vec", "vec-or-float"):
        if k == "vec-or-float" and _is_number(raw):
            raw = [raw] * dim
        if (
            not isinstance(raw, list)
            or len(raw) != dim
            or not all(_is_number(x) and math.isfinite(x) for x in raw)
        ):
            raise _err(
                where,
                f"expected {dim} finite numbers [{spec.unit}] (vehicle.dim = {dim}), got {raw!r}",
            )
        return tuple(float(x) for x in raw)
    if k == "range":
        if (
            not isinstance(raw, list)
            or len(raw) != 2
            or not all(_is_number(x) and math.isfinite(x) for x in raw)
        ):
            raise _err(where, f"expected [min, max] in {spec.unit}, got {raw!r}")
        lo, hi = float(raw[0]), float(raw[1])
        if not lo < hi:
            raise _err(where, f"min must be below max, got [{lo:g}, {hi:g}]")
        return (lo, hi)
    if k == "area":
        if not isinstance(raw, dict):
            raise _err(where, f"expected a table {{x = [min, max], y = [min, max]}}, got {raw!r}")
        unknown = sorted(set(raw) - {"x", "y"})
        if unknown:
            raise _err(f"{where}.{unknown[0]}", "unknown key; an area has only x and y")
        axes = {}
        for ax in ("x", "y"):
            if ax not in raw:
                raise _err(f"{where}.{ax}", "missing; give [min, max] in m")
            axes[ax] = _parse_value(where, FieldSpec(ax, "range", None, "m", ""), raw[ax], dim)
        return Area(x=axes["x"], y=axes["y"])
    raise AssertionError(k)  # pragma: no cover


def _section_values(data: Mapping[str, Any], section: str, dim: int) -> dict[str, Any]:
    raw = data.get(section, {})
    if not isinstance(raw, dict):
        raise _err(section, f"expected a table [{section}], got {raw!r}")
    specs = {s.name: s for s in SCHEMA[section]}
    unknown = sorted(set(raw) - set(specs))
    if unknown:
        raise _err(
            f"{section}.{unknown[0]}",
            f"unknown key (a typo?); [{section}] accepts {', '.join(specs)}",
        )
    out: dict[str, Any] = {}
    for name, spec in specs.items():
        if name in raw:
            out[name] = _parse_value(section, spec, raw[name], dim)
        elif spec.required:
            raise _err(f"{section}.{name}", f"missing; {spec.doc} [{spec.unit}]")
        else:
            out[name] = spec.default
    return out


def problem_from_dict(data: Mapping[str, Any], name: str = "") -> PlanningProblem:
    """Build and validate a problem from the parsed TOML mapping.

    Raises
    ------
    ProblemError
        Naming the ``section.field`` at fault and what it should be.
    """
    data, origin = resolve_problem_geodetic(data)  # [origin] + *.geodetic -> metric positions
    unknown = sorted(set(data) - set(SCHEMA))
    if unknown:
        raise _err(unknown[0], f"unknown section; sections are {', '.join(SCHEMA)}")
    dim_raw = data.get("vehicle", {}).get("dim", 2) if isinstance(data.get("vehicle"), dict) else 2
    if dim_raw not in (2, 3) or isinstance(dim_raw, bool):
        raise _err("vehicle.dim", f"must be 2 or 3, got {dim_raw!r}")
    dim = int(dim_raw)
    s = {sec: _section_values(data, sec, dim) for sec in SCHEMA}
    veh = s["vehicle"]
    try:
        sensors = parse_sensors(veh["sensors"])
    except ConfigError as exc:
        raise _err("vehicle.sensors", str(exc)) from None
    vehicle = VehicleSpec(
        dim=dim,
        sensors=sensors,
        current=veh["current"],
        current_velocity=veh["current_velocity"] or (0.0,) * dim,
        range_form=veh["range_form"],
    )
    lim = s["limits"]
    return PlanningProblem(
        name=s["problem"]["name"] or name,
        vehicle=vehicle,
        beacon=s["beacon"]["position"] or (0.0,) * dim,
        start_position=s["start"]["position"],
        start_velocity=s["start"]["velocity"] or (0.0,) * dim,
        limits=Limits(
            accel=lim["accel"],
            speed=lim["speed"],
            depth=lim["depth"],
            area=lim["area"],
            min_range=lim["min_range"],
            max_range=lim["max_range"],
            min_speed=lim["min_speed"],
        ),
        horizon=Horizon(**s["horizon"]),
        objective=ObjectiveSpec(**s["objective"]),
        scales=_scales(s["scales"]),
        validation=ValidationSpec(**s["validation"]),
        origin=origin,
    )


def problem_to_dict(pb: PlanningProblem) -> dict[str, Any]:
    """The canonical problem-file mapping of ``pb``: ``problem_from_dict(problem_to_dict(pb))``
    rebuilds an equal problem. Every field of :data:`SCHEMA` is present (defaults resolved), so
    the mapping identifies the problem (sweeps hash it)."""
    veh, lim, hor, obj, val = pb.vehicle, pb.limits, pb.horizon, pb.objective, pb.validation
    limits: dict[str, Any] = {
        "accel": list(lim.accel),
        "speed": lim.speed,
        "min_range": lim.min_range,
        "min_speed": lim.min_speed,
    }
    if lim.depth is not None:
        limits["depth"] = list(lim.depth)
    if lim.area is not None:
        limits["area"] = {"x": list(lim.area.x), "y": list(lim.area.y)}
    if lim.max_range is not None:
        limits["max_range"] = lim.max_range
    out: dict[str, Any] = {
        "problem": {"name": pb.name},
        "vehicle": {
            "dim": veh.dim,
            "sensors": list(veh.sensors),
            "current": veh.current,
            "current_velocity": list(veh.current_velocity),
            "range_form": veh.range_form,
        },
        "beacon": {"position": list(pb.beacon)},
        "start": {"position": list(pb.start_position), "velocity": list(pb.start_velocity)},
        "limits": limits,
        "horizon": {"duration": hor.duration, "steps": hor.steps},
        "objective": {
            f: getattr(obj, f) for f in obj.__dataclass_fields__ if getattr(obj, f) is not None
        },
        "scales": {"length_m": pb.scales.length_m, "time_s": pb.scales.time_s},
        "validation": {f: getattr(val, f) for f in val.__dataclass_fields__},
    }
    if pb.origin is not None:
        o = pb.origin
        out["origin"] = {"latitude": o.latitude, "longitude": o.longitude, "altitude": o.altitude}
    return out


def _scales(vals: dict[str, float]) -> Scales:
    try:
        return Scales(**vals)
    except ConfigError as exc:
        raise ProblemError(str(exc)) from None


def load_problem(path: str | Path | None = None) -> PlanningProblem:
    """Load and validate a problem file (TOML); ``None`` loads ``problems/default.toml``.

    Raises
    ------
    ProblemError
        If the file is missing, is not TOML, or any field is unknown, mistyped or infeasible.
    """
    if path is None:
        # problems/ sits beside the package in a clone (editable install); a copied-out
        # install finds it in the working directory instead
        candidates = (DEFAULT_PROBLEM, Path.cwd() / "problems" / "default.toml")
        path = next((c for c in candidates if c.is_file()), None)
        if path is None:
            raise ProblemError(
                f"the default problem {DEFAULT_PROBLEM} is not installed; run from a clone of "
                "the repository (pip install -e .) or pass a PROBLEM.toml"
            )
    path = Path(path)
    if not path.is_file():
        raise ProblemError(f"problem file not found: {path}")
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemError(f"{path}: not valid TOML: {exc}") from None
    try:
        return problem_from_dict(data, name=path.stem)
    except ProblemError as exc:
        raise ProblemError(f"{path}: {exc}") from None


# ------------------------------------------------------------------------------ checks
def _check_problem(pb: PlanningProblem) -> None:
    veh, lim, hor, obj, val = pb.vehicle, pb.limits, pb.horizon, pb.objective, pb.validation
    n = veh.dim
    if n not in (2, 3):
        raise _err("vehicle.dim", f"must be 2 or 3, got {n!r}")
    if veh.range_form not in ("half-squared", "range"):
        raise _err(
            "vehicle.range_form", f'must be "half-squared" or "range", got {veh.range_form!r}'
        )
    try:
        sensors = parse_sensors(veh.sensors)
        VehicleModel(dim=n, sensors=sensors, current=veh.current)
    except ConfigError as exc:
        raise _err("vehicle.sensors", str(exc)) from None
    for where, vec in (
        ("vehicle.current_velocity", veh.current_velocity),
        ("beacon.position", pb.beacon),
        ("start.position", pb.start_position),
        ("start.velocity", pb.start_velocity),
        ("limits.accel", lim.accel),
    ):
        if len(vec) != n or not all(math.isfinite(float(x)) for x in vec):
            raise _err(where, f"expected {n} finite numbers (vehicle.dim = {n}), got {vec!r}")
    if any(x != 0.0 for x in veh.current_velocity) and not veh.current:
        raise _err(
            "vehicle.current_velocity",
            "is non-zero but vehicle.current = false; set current = true to model it",
        )
    if any(not a > 0 for a in lim.accel):
        raise _err("limits.accel", f"every bound must be > 0 m/s^2, got {list(lim.accel)}")
    if not lim.speed > 0:
        raise _err("limits.speed", f"must be > 0 m/s, got {lim.speed}")
    for where, vec in (
        ("beacon.position", pb.beacon),
        ("start.position", pb.start_position),
        ("start.velocity", pb.start_velocity),
        ("limits.accel", lim.accel),
        ("limits.speed", (lim.speed,)),
    ):
        if any(abs(float(x)) > MAX_MAGNITUDE for x in vec):
            raise _err(
                where, f"{list(vec)} is beyond {MAX_MAGNITUDE:g} in SI units; check the units"
            )
    speed0 = float(np.linalg.norm(pb.v0))
    if speed0 > lim.speed:
        raise _err(
            "start.velocity",
            f"start speed {speed0:.4g} m/s exceeds limits.speed = {lim.speed:g} m/s; "
            "lower the start velocity or raise the limit",
        )
    if lim.depth is not None:
        if n != 3:
            raise _err("limits.depth", "a depth band needs vehicle.dim = 3")
        lo, hi = lim.depth
        z0 = pb.start_position[2]
        if not lo <= z0 <= hi:
            raise _err(
                "limits.depth",
                f"band [{lo:g}, {hi:g}] m does not contain the start depth "
                f"start.position[2] = {z0:g} m",
            )
    if lim.area is not None:
        a = lim.area
        x0, y0 = pb.start_position[0], pb.start_position[1]
        if not (a.x[0] <= x0 <= a.x[1] and a.y[0] <= y0 <= a.y[1]):
            raise _err(
                "limits.area",
                f"x = [{a.x[0]:g}, {a.x[1]:g}], y = [{a.y[0]:g}, {a.y[1]:g}] m does not contain "
                f"the start ({x0:g}, {y0:g}) m",
            )
    if not (math.isfinite(hor.duration) and hor.duration > 0):
        raise _err("horizon.duration", f"must be > 0 s, got {hor.duration}")
    if hor.duration > MAX_DURATION_S:
        raise _err(
            "horizon.duration",
            f"{hor.duration:g} s is beyond the planner's range ({MAX_DURATION_S:g} s, "
            f"{MAX_DURATION_S / 86400:.3g} days); plan the mission in shorter pieces",
        )
    if hor.steps < 2:
        raise _err("horizon.steps", f"must be at least 2, got {hor.steps}")
    if hor.steps > MAX_STEPS:
        raise _err(
            "horizon.steps",
            f"{hor.steps} exceeds the planner's limit of {MAX_STEPS} constant-acceleration "
            f"intervals (the solve would take hours); use at most {MAX_STEPS} "
            f"(a step of {hor.duration / MAX_STEPS:.3g} s or longer)",
        )
    _check_range_and_speed_limits(pb)
    if obj.kind not in OBJECTIVES:
        raise _err(
            "objective.kind", f"unknown objective {obj.kind!r}; choose from {', '.join(OBJECTIVES)}"
        )
    if obj.mode not in MODES:
        raise _err("objective.mode", f"must be one of {', '.join(MODES)}, got {obj.mode!r}")
    if obj.mode != "auto" and obj.kind not in TIMED_OBJECTIVES:
        raise _err(
            "objective.mode",
            f"{obj.kind} has no time mode (only {', '.join(TIMED_OBJECTIVES)} do); remove "
            'objective.mode or set it to "auto"',
        )
    if obj.starts < 1:
        raise _err("objective.starts", f"must be at least 1, got {obj.starts}")
    if obj.max_iter < 1:
        raise _err("objective.max_iter", f"must be at least 1, got {obj.max_iter}")
    if obj.tol is not None and not 0 < obj.tol < 1:
        raise _err("objective.tol", f"must be in (0, 1), got {obj.tol}")
    if obj.seed < 0 or val.seed < 0:
        raise _err("objective.seed" if obj.seed < 0 else "validation.seed", "must be >= 0")
    if val.runs < 1:
        raise _err("validation.runs", f"must be at least 1, got {val.runs}")
    for name in (
        "dt",
        "range_rate",
        "range_std",
        "dvl_rate",
        "dvl_std",
        "depth_rate",
        "depth_std",
        "init_pos_error",
        "init_vel_error",
    ):
        x = getattr(val, name)
        if not (math.isfinite(x) and x > 0):
            raise _err(f"validation.{name}", f"must be > 0, got {x}")
    ratio = hor.dt / val.dt
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
        raise _err(
            "validation.dt",
            f"the filter step {val.dt:g} s must divide the planning step "
            f"horizon.duration / horizon.steps = {hor.dt:g} s",
        )
    fitted = {"range_rate": True}
    fitted["dvl_rate"] = any(s.startswith("dvl") for s in pb.model.sensors)
    fitted["depth_rate"] = "depth" in pb.model.sensors
    for name in ("range_rate", "dvl_rate", "depth_rate"):
        # a sensor that is not fitted keeps its default rate and must not veto the filter step
        if fitted[name] and getattr(val, name) > 1.0 / val.dt * (1 + 1e-9):
            raise _err(
                f"validation.{name}",
                f"{getattr(val, name):g} Hz is faster than the filter step "
                f"validation.dt = {val.dt:g} s allows",
            )
    if hor.duration * val.range_rate < 2:
        raise _err(
            "validation.range_rate",
            f"gives fewer than 2 ranges over horizon.duration = {hor.duration:g} s",
        )
    reach = 0.5 * min(lim.accel) * hor.duration**2
    if reach < val.range_std:
        raise _err(
            "limits.accel",
            f"at {min(lim.accel):g} m/s^2 the inputs move the vehicle at most {reach:.3g} m over "
            f"the horizon (a T^2 / 2), less than the range noise validation.range_std = "
            f"{val.range_std:g} m: no path can excite the observability; raise the limit or "
            "lengthen horizon.duration",
        )
    samples = hor.duration / val.dt + 1
    size = val.runs * samples * 3 * n
    if size > MAX_MC_SIZE:
        runs_max = int(MAX_MC_SIZE / (samples * 3 * n))
        raise _err(
            "validation.runs",
            f"{val.runs} runs of {samples:.0f} filter steps are too large for the validation "
            f"Monte Carlo (would need ~{size * 8 * 4 / 2**30:.0f} GiB); use at most {runs_max} "
            "runs or a longer validation.dt",
        )
    _check_objective_structure(pb)


def _margins(pb: PlanningProblem) -> tuple[float, float]:
    """Between-node margins of the range and speed limits (see ``planning/objectives.py``).

    Returns ``(tau, a_norm)``: the planner enforces the limits at nodes and midpoints, each point
    covering ``±tau = h/4`` of the path, where the distance to the beacon moves by at most
    ``|v| tau + a_norm tau² / 2`` and the speed by at most ``a_norm tau``.
    """
    return pb.horizon.dt / 4.0, float(np.linalg.norm(pb.accel))


def _check_range_and_speed_limits(pb: PlanningProblem) -> None:
    lim = pb.limits
    for name in ("min_range", "min_speed"):
        x = getattr(lim, name)
        if not (math.isfinite(x) and x >= 0):
            raise _err(f"limits.{name}", f"must be >= 0 (0 disables it), got {x}")
    r0 = float(np.linalg.norm(pb.p0 - np.asarray(pb.beacon, float)))
    tau, a = _margins(pb)
    s0 = float(np.linalg.norm(pb.v0))
    need = lim.min_range + s0 * tau + 0.5 * a * tau**2 if lim.min_range > 0 else 0.0
    if r0 < lim.min_range:
        raise _err(
            "start.position",
            f"the start is {r0:.4g} m from the beacon, inside limits.min_range = "
            f"{lim.min_range:g} m; move the start away from the beacon or lower limits.min_range",
        )
    if r0 < need:
        raise _err(
            "horizon.steps",
            f"the start is {r0:.4g} m from the beacon; between nodes the planner keeps "
            f"limits.min_range = {lim.min_range:g} m with a margin |v0| h/4 + |a| h^2/32 = "
            f"{need - lim.min_range:.3g} m at the planning step h = {pb.horizon.dt:.3g} s, which "
            "the start does not have: use more horizon.steps (a shorter step), or move the "
            "start away from the beacon",
        )
    if lim.max_range is not None:
        if not (math.isfinite(lim.max_range) and lim.max_range > lim.min_range):
            raise _err(
                "limits.max_range",
                f"must be a distance above limits.min_range = {lim.min_range:g} m, got "
                f"{lim.max_range}",
            )
        reach = r0 + s0 * tau + 0.5 * a * tau**2
        if reach > lim.max_range:
            raise _err(
                "start.position",
                f"the start is {r0:.4g} m from the beacon, beyond (or too close to) "
                f"limits.max_range = {lim.max_range:g} m; move the start or raise max_range",
            )
    if lim.min_speed > 0:
        if lim.min_speed >= lim.speed:
            raise _err(
                "limits.min_speed",
                f"{lim.min_speed:g} m/s must be below limits.speed = {lim.speed:g} m/s",
            )
        w0 = float(np.linalg.norm(pb.v0 - pb.current_array))
        need_w = lim.min_speed + a * tau
        if w0 < need_w:
            raise _err(
                "start.velocity",
                f"the speed through the water at the start, |v0 - v_f| = {w0:.4g} m/s, is below "
                f"limits.min_speed = {lim.min_speed:g} m/s plus the planner's between-node "
                f"margin ({need_w:.4g} m/s in all); start the vehicle moving or lower min_speed",
            )


def _check_objective_structure(pb: PlanningProblem) -> None:
    """Refuse objectives that the sensors make impossible for every input, before solving."""
    from obsplan.observability.lwo import lwo_structural_max_rank
    from obsplan.planning.structure import gramian_generic_rank

    kind = pb.objective.kind
    veh = pb.vehicle
    model = VehicleModel(dim=veh.dim, sensors=parse_sensors(veh.sensors), current=veh.current)
    if kind == "lwo-condition":
        r = lwo_structural_max_rank(model)
        if r < model.state_dim:
            raise _err(
                "objective.kind",
                f"lwo-condition is impossible with sensors {','.join(model.sensors)} in "
                f"{veh.dim}D: the LWO matrix has rank at most {r} < {model.state_dim} for every "
                "state and input (e.g. 3D range-only, eq. 38); add a DVL or depth sensor, or use "
                "a gramian-* objective",
            )
    elif kind.startswith("gramian"):
        r, m = gramian_generic_rank(model)
        if r < m:
            raise _err(
                "objective.kind",
                f"{kind} is impossible with sensors {','.join(model.sensors)}"
                f"{' and an unknown current' if veh.current else ''}: the augmented Gramian has "
                f"rank {r} < {m} for every input (section 4.3); use kf-position-std or change "
                "the sensors",
            )


def schema_markdown() -> str:
    """The field tables of ``docs/problem-files.md`` (one per section), from :data:`SCHEMA`."""
    out: list[str] = []
    for section, fields in SCHEMA.items():
        out.append(f"### `[{section}]`\n")
        out.append("| field | unit | default | meaning |")
        out.append("|---|---|---|---|")
        for f in fields:
            if f.required:
                default = "**required**"
            elif f.default is None:
                default = "see meaning"
            else:
                default = repr(f.default).replace("'", '"')
                default = default.replace("True", "true").replace("False", "false")
            doc = f.doc.replace("|", "\\|")
            out.append(f"| `{f.name}` | {f.unit} | {default} | {doc} |")
        out.append("")
    return "\n".join(out)
