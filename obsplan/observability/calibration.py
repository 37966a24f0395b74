"""Along which paths a range's scale and bias are observable: the local Gramian with them.

A sound-speed error scales every range and a clock offset biases it (:mod:`obsplan.estimation.
channel`): the reading is ``k |p - b| + β``. The filters can carry ``k`` as a state
(``validation.scale_state``); whether a path lets them learn it is a question of the local
observability Gramian (:mod:`obsplan.observability.local_gramian`) about ``(x(t_0), k, β)``:
the range row gains the columns ``∂r/∂k = |p - b|`` and ``∂r/∂β = 1`` at ``k = 1, β = 0``.

A parameter ``θ`` is observable along the path when no direction the Gramian cannot see moves
it: the rank of the Gramian with ``θ`` exceeds the rank of the one without by the number of
parameters added. (A null vector of the vehicle's own Gramian is one of the larger one too,
since both are PSD; so the rank grows by the count exactly when no null vector has a ``θ``
component.) The rank is the unit-invariant one of :func:`~obsplan.observability.scaling.
numerical_rank` at :data:`~obsplan.observability.scaling.RANK_TOL`, and the Gramian of the
first ``j`` intervals is the partial sum, so the first time a parameter becomes observable is
read off the partial sums; once observable it stays so (the null space of a partial sum only
shrinks).

What it says (derived here, checked by ``tests/test_calibration.py``):

* **A straight line at constant speed, no velocity reference** (range only, or a water-track
  DVL with an unknown current): the range is ``sqrt(A + 2Bτ + Cτ²)`` (``A = |p_0 - b|²``,
  ``B = (p_0 - b)·v_0``, ``C = |v_0|²``), and ``k²`` only rescales ``(A, B, C)``, which the
  unknown start can do as well: the scale is **not** observable; the bias is (it is not a
  square root of a quadratic).
* **The same line with a bottom-lock DVL** (or no current): the DVL gives ``C``, so ``k²C``
  gives ``k``: observable.
* **A circle about the beacon**: the range is constant, so ``k R + β`` is one number: scale and
  bias together are **not** observable (each alone is: the known turn gives the radius,
  ``R = |u|/ω²``).
* A turning path, or one whose range changes at changing speed, separates both.

Units: the metric scales (``r / L``; ``β / L``; ``k`` dimensionless) of the local Gramian, and
unit weights on every row: a rank needs no noise model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.observability.local_gramian import linearised_model, local_interval_gramians
from obsplan.observability.scaling import DEFAULT_SCALES, RANK_TOL, Scales, numerical_rank
from obsplan.trajectory.relative import relative_trajectory
from obsplan.trajectory.sampled import Trajectory

#: The parameter sets tested, in the report's order: their names and columns past ``x(t_0)``.
PARAMETERS = {"scale": (0,), "bias": (1,), "scale_and_bias": (0, 1)}


@dataclass(frozen=True)
class CalibrationReport:
    """Whether a range's scale ``k``, its bias ``β`` and both together are observable along a
    path (module docstring), and from when.

    Attributes
    ----------
    from_t : dict of str to float or None
        Per parameter set (``"scale"``, ``"bias"``, ``"scale_and_bias"``): the end time [s] of
        the first interval after which it is observable; None if it never is on the path.
    state_rank : int
        The rank of the vehicle's own local Gramian over the path (of ``state_dim``).
    state_dim : int
        The dimension of ``x(t_0)``.
    """

    from_t: dict[str, float | None]
    state_rank: int
    state_dim: int

    @property
    def observable(self) -> dict[str, bool]:
        """Per parameter set: observable over the whole path (it becomes so at some time)."""
        return {k: self.from_t[k] is not None for k in PARAMETERS}

    def to_dict(self) -> dict:
        """The JSON form: per parameter set ``{"observable": bool, "from_t": float | None}``.

        Returns
        -------
        dict
            Keys ``scale``, ``bias``, ``scale_and_bias``.
        """
        return {
            k: {"observable": bool(self.observable[k]), "from_t": self.from_t[k]}
            for k in PARAMETERS
        }

    def summary(self) -> str:
        """One line per parameter set, in words.

        Returns
        -------
        str
            E.g. ``range scale (sound speed): observable from t = 42 s``.
        """
        names = {
            "scale": "range scale (sound speed)",
            "bias": "range bias (clock offset)",
            "scale_and_bias": "scale and bias together",
        }
        lines = []
        for k, name in names.items():
            t = self.from_t[k]
            said = f"observable from t = {t:g} s" if t is not None else "NOT observable"
            lines.append(f"{name}: {said}")
        return "\n".join(lines)


def calibration_report(
    traj: Trajectory,
    model: VehicleModel,
    scales: Scales = DEFAULT_SCALES,
    rank_tol: float = RANK_TOL,
    beacon_path: BeaconPath | None = None,
) -> CalibrationReport:
    """Observability of the range's scale and bias along ``traj`` (module docstring).

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    model : VehicleModel
        Its sensors (a model always has the range), current and fixed beacon.
    scales : Scales, optional
        Metric scales of the Gramian.
    rank_tol : float, optional
        Tolerance of the unit-invariant rank.
    beacon_path : BeaconPath or None, optional
        A beacon on a known path (the test runs on the motion relative to it).

    Returns
    -------
    CalibrationReport
        The verdicts.
    """
    lm = linearised_model(model)
    beacon = model.beacon_array
    if beacon_path is not None:
        traj, _ = relative_trajectory(traj, beacon_path)
        beacon = np.zeros(model.dim)
    w = np.ones(lm.n_outputs)
    G = np.cumsum(local_interval_gramians(traj, lm, beacon, w, scales, calibration=True), axis=0)
    m = lm.state_dim
    base = np.atleast_1d(numerical_rank(G[:, :m, :m], rank_tol))
    from_t: dict[str, float | None] = {}
    for name, cols in PARAMETERS.items():
        idx = list(range(m)) + [m + c for c in cols]
        ok = np.atleast_1d(numerical_rank(G[:, idx][:, :, idx], rank_tol)) - base == len(cols)
        first = np.flatnonzero(ok)
        from_t[name] = float(traj.t[first[0] + 1]) if first.size else None
    return CalibrationReport(from_t=from_t, state_rank=int(base[-1]), state_dim=m)
