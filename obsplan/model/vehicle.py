"""Vehicle model: a double integrator measured by a single range beacon (section 2).

``p' = v (+ v_f)``, ``v' = u`` in 2D or 3D (eqs. 1–2, 28–30), with outputs from any subset of

* ``range``: the paper's ``y = ½|p - b|²`` (eq. 3) or the plain range ``r = |p - b|``;
* ``dvl-bottom``: DVL in bottom-lock, ``v + v_f`` (eq. 48);
* ``dvl-water``: DVL in water-profiling, ``v`` (eq. 49);
* ``depth``: ``p_z`` (3D only).

Dynamics and outputs are CasADi expressions, so the same model feeds the Lie-derivative test, the
planner and the EKF.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import casadi as ca
import numpy as np

from obsplan.core.errors import ConfigError

SENSORS: tuple[str, ...] = ("range", "dvl-bottom", "dvl-water", "depth")
SENSOR_ALIASES: dict[str, str] = {"dvl": "dvl-bottom"}
RangeForm = Literal["half-squared", "range"]
_AXES = "xyz"


def parse_sensors(sensors: str | Iterable[str]) -> tuple[str, ...]:
    """Normalise a sensor list (``"range,dvl-water"`` or an iterable) to canonical names.

    Parameters
    ----------
    sensors : str or iterable of str
        Sensor names, comma-separated in a string; case and spaces are ignored and ``"dvl"``
        means ``"dvl-bottom"``.

    Returns
    -------
    tuple of str
        The canonical names, in the order of :data:`SENSORS`.

    Raises
    ------
    ConfigError
        On an unknown name, a duplicate, or both DVL modes at once.
    """
    items = sensors.split(",") if isinstance(sensors, str) else list(sensors)
    out: list[str] = []
    for raw in items:
        name = SENSOR_ALIASES.get(raw.strip().lower(), raw.strip().lower())
        if not name:
            continue
        if name not in SENSORS:
            raise ConfigError(
                f"unknown sensor {raw!r} in sensors; choose from {', '.join(SENSORS)} "
                "(e.g. --sensors range,dvl-water)"
            )
        if name in out:
            raise ConfigError(f"sensor {name!r} is listed twice in sensors")
        out.append(name)
    if "dvl-bottom" in out and "dvl-water" in out:
        raise ConfigError("sensors: choose one DVL mode, dvl-bottom or dvl-water, not both")
    # canonical order, so that equal sets compare equal
    return tuple(s for s in SENSORS if s in out)


#: The cached CasADi attributes of :class:`VehicleModel` (left out of its pickle).
_CASADI_CACHE = frozenset({"x_sym", "u_sym", "f", "h", "H"})


@dataclass(frozen=True)
class VehicleModel:
    """Double integrator with a range beacon and optional DVL, depth gauge and ocean current.

    Parameters
    ----------
    dim : int
        Spatial dimension ``n`` (2 or 3).
    sensors : tuple of str
        Sensor names (see :data:`SENSORS`); must include ``"range"``.
    current : bool
        If true, an unknown constant ocean current ``v_f`` is appended to the state (eqs. 28–31).
    beacon : tuple of float or None
        Beacon position, shape ``(n,)`` [m]; the origin by default.
    range_form : {"half-squared", "range"}
        ``"half-squared"`` for ``½|p-b|²`` [m²] (the paper), ``"range"`` for ``|p-b|`` [m].

    Raises
    ------
    ConfigError
        For a dimension other than 2 or 3, sensors without ``"range"``, ``"depth"`` in 2D, an
        unknown range form or a beacon that is not ``n`` finite coordinates.
    """

    dim: int = 2
    sensors: tuple[str, ...] = ("range",)
    current: bool = False
    beacon: tuple[float, ...] | None = None
    range_form: RangeForm = "half-squared"
    _beacon: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.dim not in (2, 3):
            raise ConfigError(f"dim must be 2 or 3, got {self.dim!r}")
        sensors = parse_sensors(self.sensors)
        if "range" not in sensors:
            raise ConfigError("sensors must include 'range' (the beacon is the only position fix)")
        if "depth" in sensors and self.dim != 3:
            raise ConfigError("sensor 'depth' needs dim = 3 (there is no depth axis in 2D)")
        if self.range_form not in ("half-squared", "range"):
            raise ConfigError(
                f"range_form must be 'half-squared' or 'range', got {self.range_form!r}"
            )
        beacon = np.zeros(self.dim) if self.beacon is None else np.asarray(self.beacon, float)
        if beacon.shape != (self.dim,) or not np.all(np.isfinite(beacon)):
            raise ConfigError(
                f"beacon must be {self.dim} finite coordinates [m], got {self.beacon!r}"
            )
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "beacon", tuple(float(b) for b in beacon))
        object.__setattr__(self, "_beacon", beacon)

    # ----------------------------------------------------------------- sizes and names
    @property
    def beacon_array(self) -> np.ndarray:
        """Beacon position as an array, shape ``(n,)`` [m]."""
        return self._beacon.copy()

    @property
    def state_dim(self) -> int:
        """``2n``, or ``3n`` with current."""
        return (3 if self.current else 2) * self.dim

    @property
    def state_names(self) -> tuple[str, ...]:
        axes = _AXES[: self.dim]
        names = [f"p{a}" for a in axes] + [f"v{a}" for a in axes]
        if self.current:
            names += [f"vf{a}" for a in axes]
        return tuple(names)

    @property
    def output_names(self) -> tuple[str, ...]:
        axes = _AXES[: self.dim]
        names: list[str] = []
        for s in self.sensors:
            if s == "range":
                names.append("y" if self.range_form == "half-squared" else "r")
            elif s.startswith("dvl"):
                names += [f"dvl_{a}" for a in axes]
            elif s == "depth":
                names.append("depth")
        return tuple(names)

    @property
    def output_slices(self) -> dict[str, slice]:
        """Where each sensor's outputs sit in the stacked output vector."""
        out: dict[str, slice] = {}
        i = 0
        for s in self.sensors:
            k = self.dim if s.startswith("dvl") else 1
            out[s] = slice(i, i + k)
            i += k
        return out

    @property
    def output_dim(self) -> int:
        return len(self.output_names)

    # ----------------------------------------------------------------- CasADi symbols
    def __getstate__(self) -> dict:
        """The pickled state: the fields without the cached CasADi symbols and functions (SX
        symbols do not pickle; they are rebuilt on first use)."""
        return {k: v for k, v in self.__dict__.items() if k not in _CASADI_CACHE}

    @cached_property
    def x_sym(self) -> ca.SX:
        """State symbol, shape ``(state_dim, 1)``."""
        return ca.SX.sym("x", self.state_dim)

    @cached_property
    def u_sym(self) -> ca.SX:
        """Input (acceleration) symbol, shape ``(n, 1)`` [m/s²]."""
        return ca.SX.sym("u", self.dim)

    def split_state(self, x: ca.SX | np.ndarray) -> tuple:
        """Return ``(p, v)`` or ``(p, v, v_f)`` views of a state vector.

        Parameters
        ----------
        x : casadi.SX or ndarray, shape (state_dim,)
            State: position [m], velocity [m/s] and, with current, the current [m/s].

        Returns
        -------
        tuple
            ``(p, v)`` or ``(p, v, v_f)``, each of ``n`` components (slices of ``x``).
        """
        n = self.dim
        parts = (x[:n], x[n : 2 * n])
        return parts + (x[2 * n : 3 * n],) if self.current else parts

    def f_expr(self, x: ca.SX, u: ca.SX) -> ca.SX:
        """Continuous-time dynamics ``x' = f(x, u)`` (eqs. 4, 47).

        Parameters
        ----------
        x : casadi.SX, shape (state_dim, 1)
            State symbol or expression.
        u : casadi.SX, shape (n, 1)
            Input: the acceleration [m/s²].

        Returns
        -------
        casadi.SX, shape (state_dim, 1)
            ``x'``: velocity (plus current), acceleration and, with current, zeros.
        """
        parts = self.split_state(x)
        pdot = parts[1] + parts[2] if self.current else parts[1]
        xdot = [pdot, u]
        if self.current:
            xdot.append(ca.SX.zeros(self.dim))
        return ca.vertcat(*xdot)

    def h_expr(self, x: ca.SX) -> ca.SX:
        """Stacked outputs ``y = h(x)`` in the order of :attr:`sensors` (eqs. 3, 39, 48, 49).

        Parameters
        ----------
        x : casadi.SX, shape (state_dim, 1)
            State symbol or expression.

        Returns
        -------
        casadi.SX, shape (output_dim, 1)
            The outputs: range term [m² or m], DVL velocity [m/s], depth [m]
            (:attr:`output_slices`).
        """
        parts = self.split_state(x)
        p, v = parts[0], parts[1]
        rel = p - ca.DM(self._beacon)
        ys = []
        for s in self.sensors:
            if s == "range":
                sq = ca.dot(rel, rel)
                ys.append(0.5 * sq if self.range_form == "half-squared" else ca.sqrt(sq))
            elif s == "dvl-bottom":
                ys.append(v + parts[2] if self.current else v)
            elif s == "dvl-water":
                ys.append(v)
            elif s == "depth":
                ys.append(p[2])
        return ca.vertcat(*ys)

    @cached_property
    def f(self) -> ca.Function:
        """CasADi ``f(x, u) -> xdot``."""
        return ca.Function("f", [self.x_sym, self.u_sym], [self.f_expr(self.x_sym, self.u_sym)])

    @cached_property
    def h(self) -> ca.Function:
        """CasADi ``h(x) -> y`` (stacked outputs)."""
        return ca.Function("h", [self.x_sym], [self.h_expr(self.x_sym)])

    @cached_property
    def H(self) -> ca.Function:
        """CasADi ``H(x) -> dh/dx``, shape ``(output_dim, state_dim)``."""
        y = self.h_expr(self.x_sym)
        return ca.Function("H", [self.x_sym], [ca.jacobian(y, self.x_sym)])

    # ----------------------------------------------------------------- exact discretisation
    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact ZOH discretisation ``x_{k+1} = F x_k + G u_k`` for a step of ``dt`` [s].

        Parameters
        ----------
        dt : float
            Step [s].

        Returns
        -------
        F : ndarray, shape (state_dim, state_dim)
            State transition matrix.
        G : ndarray, shape (state_dim, n)
            Input matrix of a zero-order-held acceleration [m/s²].
        """
        n = self.dim
        eye = np.eye(n)
        F = np.eye(self.state_dim)
        F[:n, n : 2 * n] = dt * eye
        if self.current:
            F[:n, 2 * n : 3 * n] = dt * eye
        G = np.zeros((self.state_dim, n))
        G[:n] = 0.5 * dt**2 * eye
        G[n : 2 * n] = dt * eye
        return F, G

    def range_to_beacon(self, p: np.ndarray) -> np.ndarray:
        """Euclidean range ``|p - b|`` [m] for positions of shape ``(..., n)``.

        Parameters
        ----------
        p : ndarray, shape (..., n)
            Positions [m], in the frame of the beacon.

        Returns
        -------
        ndarray, shape (...)
            Distance of each position to the beacon [m].
        """
        return np.linalg.norm(np.asarray(p, float) - self._beacon, axis=-1)


def make_model(
    dim: int = 2,
    sensors: str | Sequence[str] = ("range",),
    current: bool = False,
    beacon: Sequence[float] | None = None,
    range_form: RangeForm = "half-squared",
) -> VehicleModel:
    """Convenience constructor accepting ``"range,dvl-water"`` strings for ``sensors``.

    Parameters
    ----------
    dim : int, optional
        Spatial dimension ``n`` (2 or 3).
    sensors : str or sequence of str, optional
        Sensor names (:func:`parse_sensors`); must include ``"range"``.
    current : bool, optional
        Append an unknown constant ocean current ``v_f`` [m/s] to the state.
    beacon : sequence of float or None, optional
        Beacon position, shape ``(n,)`` [m]; None: the origin.
    range_form : {"half-squared", "range"}, optional
        Range output ``½|p-b|²`` [m²] (the paper) or ``|p-b|`` [m].

    Returns
    -------
    VehicleModel
        The model.

    Raises
    ------
    ConfigError
        For an invalid configuration (:class:`VehicleModel`).

    Examples
    --------
    >>> from obsplan import make_model
    >>> m = make_model(3, "range,dvl-water", beacon=(0.0, 0.0, 10.0))
    >>> m.sensors, m.state_dim
    (('range', 'dvl-water'), 6)
    """
    return VehicleModel(
        dim=dim,
        sensors=parse_sensors(sensors),
        current=current,
        beacon=None if beacon is None else tuple(beacon),
        range_form=range_form,
    )
