"""The acoustic channel: how the ranges of the truth simulation depart from Gaussian ones.

A range at sea is a one-way travel time times a sound speed. The truth simulation of the Monte
Carlo (:mod:`obsplan.estimation.montecarlo`) corrupts every range it draws by the
:class:`Channel`; the filters do not know the channel (they keep their Gaussian model of
``validation.range_std``), which is the point: the channel measures how the product's filters
survive ranges as the sea gives them. A reading of the range sensor at true range ``ρ`` is

    y = (1 + s) ρ + c Δt + ε + m,        ε ~ N(0, σ_r²)

* ``s`` (``sound_speed_scale``): the relative error of the sound speed the modem converts travel
  times with; every range is scaled by ``1 + s``;
* ``c Δt`` (``clock_offset_s``, ``c`` = :data:`SOUND_SPEED`): a constant offset between the
  beacon's and the vehicle's clocks is a constant bias of every one-way travel time;
* ``m``: with probability ``outlier_fraction`` the range is a multipath arrival, late by an
  excess uniform in ``outlier_excess_m`` ``(lo, hi)`` [m] (a later arrival is a longer path:
  ``m > 0``), else ``m = 0``;
* ``ρ̇ δ`` (``ping_jitter_s`` = ``j``): the ping leaves at ``δ`` uniform in ``[-j, j]`` from its
  scheduled time but is stamped at the schedule (the filters update at the scheduled epoch), so
  the range is the one of ``δ`` later, to first order ``ρ + ρ̇ δ``; ``ρ̇`` is the path's planned
  range rate (as the growing loss below, a property of the path);
* with probability ``dropout`` the ping is lost (no reading); beyond ``dropout_range_m`` the
  probability grows linearly in the range, from ``dropout`` to 1 at twice that range. The range
  the growth is judged on is the path's planned (nominal) range at the ping, so the loss pattern
  is a property of the path and the uniforms, the same for every filter flown on it.

The anchor range at the first sample (the KF's ``y0`` and every filter's start) is neither lost
(as :class:`~obsplan.estimation.config.EstimationConfig` ``dropout`` already) nor late: the
filters start from a fix the operator checked. It is scaled and biased like every range.

The channel keeps the problem's own ping rate (``validation.range_rate``): sparse pings (one per
10-30 s) are a property of the problem, not of the channel.

Presets (:data:`CHANNEL_PRESETS`)
---------------------------------
``"ideal"``
    No fault: the Gaussian ranges of the paper and of every validation before the channel existed
    (bit-identical numbers).
``"at-sea"``
    10 % multipath outliers late by 2-30 m, 20 % of pings lost and a 1 % sound-speed scale
    error, no clock offset. Sources: the channel simulated for field work with a single ranging
    surface vehicle by Masmitja et al. (range-only target tracking with an ASV; their simulator
    ``imasmitja/RLforUTracking`` scales ranges by 1.01 and drops 20 % of the pings); the
    multipath rate and excess are the late arrivals of metres to tens of metres that shallow-water
    one-way-travel-time ranging sees (a longer path than the direct one; docs/validation.md, "The
    acoustic channel", gives the table of sources). A clock offset is zero in the preset because
    one-way-travel-time modems synchronise their clocks (a residual offset is a user field,
    ``channel_clock_offset``); so is the ping jitter, because a modem stamps its ranges with the
    time they were taken (``channel_ping_jitter`` models a modem that does not).

The innovation gate
-------------------
The filters of the Monte Carlo can gate ranges by their normalised innovation squared
``NIS = ν²/s`` at the chi-square quantile of one degree of freedom at a confidence
(:data:`GATE_PROBABILITY`, the replay's: :mod:`obsplan.estimation.replay.smoother` explains the
choice) and re-acquire after :data:`REACQUIRE_AFTER` consecutive rejections (the next range is
used after widening the position prior isotropically so that its NIS is on the gate). The gate
of the EKF and the Gaussian sum (range rows) is one-sided: multipath only ever lengthens a
range, so a range *shorter* than the filter predicts by more than the gate cannot be a late
arrival; it says the filter is wrong, and the filter re-acquires on it at once instead of
rejecting it (with sparse pings, five rejected ranges are a minute or more in which a wrong
state drifts on). Inside the gate the
EKF and the Gaussian sum (range form) weigh each range by a late-arrival-aware likelihood: a
reading is either the Gaussian range (prior ``1 - ε``) or a late arrival (prior ``ε``,
:data:`LATE_PRIOR`) whose excess is uniform on ``[0, L]`` (:data:`LATE_MAX_M`), so that its
innovation's density is ``ℓ(ν) = (Φ(ν/√s) - Φ((ν - L)/√s)) / L``. The posterior probability
that the range is the direct one, ``β = (1-ε) N(ν; 0, s) / ((1-ε) N(ν; 0, s) + ε ℓ(ν))``, is
one-sided: a short range (``ν < 0``) cannot be late and keeps ``β ≈ 1``, a long one of a few
``√s`` falls to ``β ≈ 0``. The update is the moment-matched mixture of "update" and "no update"
(the probabilistic data association update with one reading, Bar-Shalom, Daum and Huang 2009):
``x += β K ν``, ``P -= β K s Kᵀ - β(1-β) (K ν)(K ν)ᵀ``, which keeps the covariance honest
about a range it cannot tell from a late one (a hard gate would instead trust it fully or drop
it); a Gaussian sum's components are weighted by the same two-component likelihood. By default
(:func:`default_gate`) the gate is on when the channel has outliers and off otherwise: with
Gaussian ranges a gate only throws away valid information, and the ideal channel's numbers stay
those of before.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import casadi as ca
import numpy as np
from scipy.stats import chi2

from obsplan.core.errors import ConfigError

#: Sound speed [m/s] that turns a clock offset into a range bias (nominal sea water).
SOUND_SPEED = 1500.0
#: Confidence of the innovation gate (:mod:`obsplan.estimation.replay.smoother`: why 0.999).
GATE_PROBABILITY = 0.999
#: Consecutive rejected ranges after which a filter re-acquires (the replay's rule).
REACQUIRE_AFTER = 5
#: A run is *lost* when its final position error exceeds this many times the bound (the
#: posterior CRB's final position std of the path).
LOST_FACTOR = 10.0
#: Prior standard deviation of the range-scale state of the EKF and the Gaussian sum (relative):
#: a sound speed known to ±30 m/s of 1500 m/s (the spread of sea water's from 0 to 30 °C at a
#: given salinity is about 60 m/s) is known to 2 %.
SCALE_PRIOR_STD = 0.02
#: Prior standard deviation [m] of the range-bias state of the EKF and the Gaussian sum: a clock
#: offset of 2 ms (at :data:`SOUND_SPEED`). One-way-travel-time modems run synchronised clocks,
#: so a residual offset is milliseconds; an offset of many of this prior's stds is a setup error
#: (an unsynchronised clock) to correct before filtering, not to learn from the ranges.
BIAS_PRIOR_STD_M = 3.0
#: The filters' model of late arrivals (the late-arrival-aware update, module docstring): the prior
#: probability that a range is a multipath arrival and the largest excess [m] they expect, the
#: multipath statistics stated for the at-sea preset (its sources, module docstring). The
#: filters never read the truth's channel: these are their own assumptions.
LATE_PRIOR = 0.1
LATE_MAX_M = 30.0
#: Largest excess of a late arrival [m] accepted: beyond it a "range" is not the beacon's.
MAX_EXCESS_M = 1e5
#: Largest clock offset [s] accepted.
MAX_CLOCK_OFFSET_S = 10.0
#: The planner's model of a loss growing with range (:meth:`Channel.arrival_probability`) rounds
#: the two corners of the truth's linear growth over this fraction of ``dropout_range_m``: IPOPT
#: needs a twice-differentiable objective, and 2 % of the range moves the expected information
#: by at most 1 % of a ping's.
ARRIVAL_SMOOTH = 0.02
#: Smallest arrival probability the planner's expected information takes: beyond twice
#: ``dropout_range_m`` every ping is lost, and the floor keeps the range variance it divides
#: finite (a thousandth of a ping's information is none for any recursion).
ARRIVAL_FLOOR = 1e-3


@dataclass(frozen=True)
class Channel:
    """The faults of the acoustic channel the truth's ranges go through (module docstring).

    Parameters
    ----------
    name : str
        The preset it came from (``"ideal"``, ``"at-sea"``) or ``"custom"``.
    dropout : float
        Probability that a ping is lost, in ``[0, 1)``.
    dropout_range_m : float
        Range [m] beyond which the loss probability grows linearly to 1 at twice this range;
        ``inf``: no growth.
    outlier_fraction : float
        Probability that a range is a late multipath arrival, in ``[0, 1)``.
    outlier_excess_m : tuple of float
        ``(lo, hi)`` [m], ``0 <= lo <= hi``: the excess path length of a late arrival, uniform.
    sound_speed_scale : float
        Relative sound-speed error ``s``: every range is multiplied by ``1 + s`` (``|s| < 0.5``).
    clock_offset_s : float
        Clock offset [s] between the beacon and the vehicle: a range bias of
        ``SOUND_SPEED · clock_offset_s``.
    ping_jitter_s : float
        Half-width [s] of the uniform error of a ping's time against its stamp (``>= 0``).
    """

    name: str = "ideal"
    dropout: float = 0.0
    dropout_range_m: float = math.inf
    outlier_fraction: float = 0.0
    outlier_excess_m: tuple[float, float] = (2.0, 30.0)
    sound_speed_scale: float = 0.0
    clock_offset_s: float = 0.0
    ping_jitter_s: float = 0.0

    def __post_init__(self) -> None:
        for f in ("dropout", "outlier_fraction"):
            v = float(getattr(self, f))
            if not 0.0 <= v < 1.0:
                raise ConfigError(f"channel {f} must be a probability in [0, 1), got {v!r}")
            object.__setattr__(self, f, v)
        d = float(self.dropout_range_m)
        if not d > 0.0:
            raise ConfigError(
                f"channel dropout_range_m must be a range > 0 m (inf: no growth), got {d!r}"
            )
        object.__setattr__(self, "dropout_range_m", d)
        ex = tuple(float(x) for x in np.ravel(self.outlier_excess_m))
        if len(ex) != 2 or not (0.0 <= ex[0] <= ex[1] <= MAX_EXCESS_M):
            raise ConfigError(
                f"channel outlier_excess_m must be [lo, hi] with 0 <= lo <= hi <= {MAX_EXCESS_M:g}"
                f" m (a late arrival is longer), got {self.outlier_excess_m!r}"
            )
        object.__setattr__(self, "outlier_excess_m", ex)
        s = float(self.sound_speed_scale)
        if not abs(s) < 0.5:
            raise ConfigError(f"channel sound_speed_scale must be in (-0.5, 0.5), got {s!r}")
        object.__setattr__(self, "sound_speed_scale", s)
        c = float(self.clock_offset_s)
        if not abs(c) <= MAX_CLOCK_OFFSET_S:
            raise ConfigError(
                f"channel clock_offset_s must be within ±{MAX_CLOCK_OFFSET_S:g} s, got {c!r}"
            )
        object.__setattr__(self, "clock_offset_s", c)
        j = float(self.ping_jitter_s)
        if not 0.0 <= j <= MAX_CLOCK_OFFSET_S:
            raise ConfigError(
                f"channel ping_jitter_s must be in [0, {MAX_CLOCK_OFFSET_S:g}] s, got {j!r}"
            )
        object.__setattr__(self, "ping_jitter_s", j)

    @property
    def range_bias_m(self) -> float:
        """The range bias [m] of the clock offset, ``SOUND_SPEED · clock_offset_s``."""
        return SOUND_SPEED * self.clock_offset_s

    @property
    def has_outliers(self) -> bool:
        """Whether some ranges are late arrivals."""
        return self.outlier_fraction > 0.0

    @property
    def is_ideal(self) -> bool:
        """Whether the channel has no fault at all (its ranges are the Gaussian ones)."""
        return (
            self.dropout == 0.0
            and self.outlier_fraction == 0.0
            and self.sound_speed_scale == 0.0
            and self.clock_offset_s == 0.0
            and self.ping_jitter_s == 0.0
        )

    def describe(self) -> str:
        """The channel's faults in words, for a report line.

        Returns
        -------
        str
            E.g. ``"10 % late arrivals (+2-30 m), 20 % pings lost, sound speed +1 %"``;
            ``"no fault"`` for the ideal channel.
        """
        said = []
        if self.outlier_fraction:
            lo, hi = self.outlier_excess_m
            said.append(f"{100 * self.outlier_fraction:g} % late arrivals (+{lo:g}-{hi:g} m)")
        if self.dropout:
            grows = (
                f", more beyond {self.dropout_range_m:g} m"
                if math.isfinite(self.dropout_range_m)
                else ""
            )
            said.append(f"{100 * self.dropout:g} % pings lost{grows}")
        if self.sound_speed_scale:
            said.append(f"sound speed {100 * self.sound_speed_scale:+g} %")
        if self.clock_offset_s:
            said.append(f"clock offset {self.clock_offset_s:g} s ({self.range_bias_m:+g} m)")
        if self.ping_jitter_s:
            said.append(f"ping jitter {self.ping_jitter_s:g} s")
        return ", ".join(said) or "no fault"

    def to_dict(self) -> dict:
        """JSON-ready fields (``report.json`` ``validation.channel``).

        Returns
        -------
        dict
            ``name`` and every field; ``dropout_range_m`` None when infinite; also the
            ``range_bias_m`` of the clock offset.
        """
        out = asdict(self)
        out["outlier_excess_m"] = list(self.outlier_excess_m)
        if not math.isfinite(self.dropout_range_m):
            out["dropout_range_m"] = None
        out["range_bias_m"] = self.range_bias_m
        return out

    def drop_probability(self, rho: np.ndarray) -> np.ndarray:
        """The loss probability of pings at ranges ``rho`` [m].

        Parameters
        ----------
        rho : ndarray
            Ranges [m].

        Returns
        -------
        ndarray
            ``dropout`` up to ``dropout_range_m``, growing linearly to 1 at twice it.
        """
        rho = np.asarray(rho, float)
        p = np.full(rho.shape, self.dropout)
        if math.isfinite(self.dropout_range_m):
            grow = np.clip(rho / self.dropout_range_m - 1.0, 0.0, 1.0)
            p = p + (1.0 - p) * grow
        return p

    @property
    def loses_pings(self) -> bool:
        """Whether some pings are lost (a dropout, or a loss growing with range)."""
        return self.dropout > 0.0 or math.isfinite(self.dropout_range_m)

    def arrival_probability(self, rel):
        """The probability that a ping arrives, for the planner's expected information.

        A range that arrives with probability ``q`` carries in expectation ``q`` times the
        information ``h hᵀ / R`` of one that always does (the Fisher information of a reading
        present with a probability that does not depend on the state): a recursion on the
        expected information divides the range variance by ``q``. ``q = 1 -``
        :meth:`drop_probability`, with the growth's corners at ``dropout_range_m`` and twice it
        rounded over :data:`ARRIVAL_SMOOTH` of that range, falling from ``1 - dropout`` to
        :data:`ARRIVAL_FLOOR` instead of 0.

        Parameters
        ----------
        rel : ndarray or casadi.SX/MX, shape (n, J)
            Positions relative to the beacon [m], one column per range epoch.

        Returns
        -------
        float or ndarray or casadi expression, shape (1, J)
            ``q`` per epoch; a float ``1 - dropout`` when the loss does not grow with range.
        """
        q0 = 1.0 - self.dropout
        if not math.isfinite(self.dropout_range_m):
            return q0
        w = ARRIVAL_SMOOTH
        # 1 m² under the root keeps the range differentiable at the beacon
        if isinstance(rel, np.ndarray):
            r = np.sqrt(np.sum(rel**2, axis=0, keepdims=True) + 1.0)
            x = r / self.dropout_range_m - 1.0
            grow = w * (np.logaddexp(0.0, x / w) - np.logaddexp(0.0, (x - 1.0) / w))
        else:
            r = ca.sqrt(ca.sum1(rel**2) + 1.0)
            x = r / self.dropout_range_m - 1.0

            def softplus(z):
                return ca.fmax(z, 0.0) + ca.log1p(ca.exp(-ca.fabs(z)))

            grow = w * (softplus(x / w) - softplus((x - 1.0) / w))
        return ARRIVAL_FLOOR + (q0 - ARRIVAL_FLOOR) * (1.0 - grow)

    def expected_variance(self, rho, rel):
        """The range variances ``rho`` of a recursion on the expected information: divided by
        :meth:`arrival_probability`; ``rho`` itself when the channel loses no ping (the ideal
        channel's numbers unchanged).

        Parameters
        ----------
        rho : ndarray or casadi expression, shape (1, J)
            The range variances at the epochs (in the recursion's units).
        rel : ndarray or casadi expression, shape (n, J)
            The positions relative to the beacon there [m].

        Returns
        -------
        ndarray or casadi expression, shape (1, J)
            The variances of the expected information.
        """
        if not self.loses_pings:
            return rho
        return rho / self.arrival_probability(rel)


#: The named channels (module docstring).
CHANNEL_PRESETS: dict[str, Channel] = {
    "ideal": Channel(name="ideal"),
    "at-sea": Channel(
        name="at-sea",
        dropout=0.2,
        outlier_fraction=0.1,
        outlier_excess_m=(2.0, 30.0),
        sound_speed_scale=0.01,
    ),
}
#: The fields of a channel a user may set (every one but its name).
CHANNEL_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(Channel) if f.name != "name")


def channel_preset(name: str, **changes: object) -> Channel:
    """The preset ``name`` with some fields changed (the result is named ``"custom"`` when a
    change differs from the preset).

    Parameters
    ----------
    name : str
        A key of :data:`CHANNEL_PRESETS`.
    **changes
        Fields of :class:`Channel` (not ``name``); None values are ignored.

    Returns
    -------
    Channel
        The channel.

    Raises
    ------
    ConfigError
        For an unknown preset or field, or a value out of range.
    """
    base = CHANNEL_PRESETS.get(str(name))
    if base is None:
        raise ConfigError(
            f"channel: unknown channel {name!r}; choose from {', '.join(CHANNEL_PRESETS)}"
        )
    given = {k: v for k, v in changes.items() if v is not None}
    bad = sorted(set(given) - set(CHANNEL_FIELDS))
    if bad:
        known = ", ".join(CHANNEL_FIELDS)
        raise ConfigError(f"channel: unknown field {bad[0]!r}; fields are {known}")
    out = replace(base, **given)  # type: ignore[arg-type]
    if out != base:
        out = replace(out, name="custom")
    return out


def gate_nis(probability: float | None) -> float:
    """The NIS threshold of a gate at ``probability`` (chi-square, one degree of freedom).

    Parameters
    ----------
    probability : float or None
        Confidence in (0, 1]; 1 or None: no gate.

    Returns
    -------
    float
        The threshold; ``inf`` for no gate.
    """
    if probability is None or probability >= 1.0:
        return math.inf
    return float(chi2.ppf(probability, 1))


def default_gate(channel: Channel) -> float | None:
    """The gate's confidence by default: :data:`GATE_PROBABILITY` when the channel has outliers,
    None (no gate) otherwise (module docstring).

    Parameters
    ----------
    channel : Channel
        The channel.

    Returns
    -------
    float or None
        The confidence, or None.
    """
    return GATE_PROBABILITY if channel.has_outliers else None


def channel_errors(
    channel: Channel,
    rows: np.ndarray,
    u_drop: np.ndarray,
    u_out: np.ndarray,
    u_excess: np.ndarray,
    u_jitter: np.ndarray,
    rho: np.ndarray | None,
    rho_dot: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The additive errors and the lost pings of one run's ranges.

    Parameters
    ----------
    channel : Channel
        The channel.
    rows : ndarray of int, shape (K,)
        The epochs of the range reports (row 0: the anchor, never lost nor late).
    u_drop, u_out, u_excess, u_jitter : ndarray, shape (K,)
        The run's uniforms of loss, of multipath, of the excess and of the ping's time (its
        seeded streams).
    rho : ndarray, shape (K,) or None
        The path's nominal range at the reports [m] (for a loss probability growing with range;
        None: no growth is possible).
    rho_dot : ndarray, shape (K,) or None, optional
        The path's nominal range rate at the reports [m/s] (for the ping jitter; None: none).

    Returns
    -------
    add : ndarray, shape (K,)
        ``c Δt + ρ̇ δ + m`` [m] (module docstring).
    lost : ndarray of bool, shape (K,)
        The lost pings.
    """
    anchor = rows == 0
    if rho is None or not math.isfinite(channel.dropout_range_m):
        p = np.full(rows.size, channel.dropout)
    else:
        p = channel.drop_probability(rho)
    lost = (u_drop < p) & ~anchor
    late = (u_out < channel.outlier_fraction) & ~anchor
    lo, hi = channel.outlier_excess_m
    add = np.where(late, lo + (hi - lo) * u_excess, 0.0) + channel.range_bias_m
    if channel.ping_jitter_s > 0.0 and rho_dot is not None:
        add = add + rho_dot * channel.ping_jitter_s * (2.0 * u_jitter - 1.0)
    return add, lost
