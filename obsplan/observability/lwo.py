"""Local weak observability: the Lie-derivative observability matrix of eq. 9, built by CasADi.

Matrix
------
For each output ``h_j`` of :class:`~obsplan.model.vehicle.VehicleModel` (in sensor order) the rows
are the state gradients ``∇_x L^k h_j`` for ``k = 0..K`` (eq. 8-9); rows that are structurally zero
(e.g. ``∇ L^4 y = 0`` for the half-squared range) are dropped, so the half-squared range gives the
four rows of eq. 13 and a DVL the identity block of eq. 40. Nothing is typed by hand: the rows come
from ``VehicleModel.f_expr`` / ``h_expr`` for any sensor set, range form and current option.

Inputs. With ``input_derivatives = 0`` the input ``u`` is a constant parameter (the
piecewise-constant inputs of trajectories and CSVs): this is the paper's "frozen-input" matrix
(eqs. 13, 35, 38, 44, 50). With ``input_derivatives = m > 0`` the extended Lie derivative
``L^{k+1} h = ∂_x(L^k h)·f + Σ_i ∂_{u^(i)}(L^k h)·u^(i+1)`` is used, with ``u^(m+1) = 0``: the
matrix of a smooth, time-varying input. The two differ: on the centred circle (eq. 37) the frozen
matrix has ``det O = 6ω⁴ρ⁴`` (the paper's value, right for eq. 35) but with ``u' = -ω² v`` the
determinant of the first four rows is ``4ω⁴ρ⁴``; in 3D the frozen range-only matrix has at most 4
non-zero rows (eq. 38), while with input derivatives its rank can exceed 4.

Choice of K. Every output is a polynomial of degree ≤ 2 in ``(p, v, v_f)`` (``½|p-b|²``, ``v``,
``v + v_f``, ``p_z``) and ``ẋ = A x + B u`` with ``A² = 0``. For the half-squared range with
constant input, ``y' = p·ν``, ``y'' = |ν|² + p·u``, ``y''' = 3 ν·u``, and ``y'''' = 3|u|²`` has no
state in it; each input derivative adds one order (``p·u^(m)`` first appears in ``y^(m+2)``, its
state gradient is gone two orders later), so ``∇ L^k y = 0`` for ``k ≥ 4 + m``. DVL and depth
rows vanish sooner. For the plain range ``r = √(2y)``, ``(r, ṙ, ..., r^(k))`` is a smooth function
of ``(y, ..., y^(k))`` with a triangular Jacobian of diagonal ``1/r`` (r > 0), so its rows span the
same space as the half-squared rows of the same orders. Hence ``K = 3 + m`` orders already contain
every row that can raise the rank; ``tests/test_lwo.py`` checks that two more orders never do.

Evaluation along a trajectory
-----------------------------
A trajectory gives ``p``, the inertial velocity ``ν = p'`` and ``u``. The state is
``x = (p, ν)``, or with current ``x = (p, ν - v_f, v_f)`` with a nominal ``v_f = 0``: every row of
O depends on the state only through ``p`` and ``ν = v + v_f`` (the range rows) or is constant (DVL
rows), so the split does not change O (tested). For ``input_derivatives > 0`` the derivatives of u
are estimated from the samples by finite differences (:func:`input_derivative_estimates`).

Moving beacon
-------------
With a beacon on a known path ``b(t)`` (:class:`~obsplan.model.beacon.BeaconPath`) the outputs
depend on time, and the Lie derivatives gain ``∂_t``. In the coordinates ``(r, v[, v_f])`` with
``r = p - b`` the dynamics are ``r' = v (+ v_f) - b'``, ``v' = u``: the range rows are those of a
beacon fixed at the origin evaluated at the relative state ``(r, ν - b')`` with the relative input
``u - b''`` (the shift ``v -> v - b'`` has the identity for Jacobian, so the gradient rows do not
change; DVL rows are constant and the depth row ``p_z = r_z + b_z`` has the gradient ``e_z``
either way). So every function below that takes ``beacon_path`` evaluates today's matrix on
:func:`~obsplan.trajectory.relative.relative_samples` with the beacon at the origin: one place
for the logic, and ``beacon_path=None`` runs exactly today's code. The beacon's ``b'`` and ``b''``
are those of the smooth path its samples are taken from (a local test cannot see the impulses of
a piecewise-linear path; :mod:`obsplan.model.beacon`). Between two samples ``b''`` varies, so
the "sampling is exact" argument below holds for a held relative input only (a fixed beacon, or
one at constant velocity or constant acceleration): the verdict is that of the samples.

Rank test
---------
O mixes units (rows of m², m²/s, ..., columns of m and m/s). Changing units multiplies O by fixed
diagonal matrices on both sides, so the test first *nondimensionalises* with a length ``ℓ`` and a
time ``T`` taken from the trajectory itself (``ℓ`` = RMS range to the beacon, ``T = ℓ / RMS speed``)
which change covariantly with the units: the dimensionless O, hence every verdict, is the same in
metres/seconds as in kilometres/hours (to round-off). The rank is then the number of singular values
above ``LWO_RANK_TOL · σ_max`` per sample. Rows are *not* normalised one by one: near the beacon a
row such as ``(p, 0)`` is round-off only, and normalising it would invent a direction.

Held inputs: sampling is exact
------------------------------
With the input held constant, O at a later point of one hold interval is an invertible transform
of O at its start: for the flow ``φ_τ`` of ``ẋ = f(x, u)`` (``u`` fixed) every output satisfies
``L^k h(φ_τ(x)) = Σ_j τ^j/j! L^{k+j} h(x)`` (a finite sum: the Lie derivatives are polynomials
that vanish from order ``K + 1`` on), hence ``O(φ_τ(x)) Dφ_τ = T(τ) O(x)`` with ``T`` block
upper-triangular with unit diagonal and ``det Dφ_τ = 1``. So the rank of O is constant on each
hold interval and ``d/dt det O = 0`` there (``tests/test_paper_record.py`` proves it with sympy):
checking every sample of a held-input trajectory (a CSV) *is* the paper's "at all times" rule.
For a smooth input (a path flown with ``u = p''``) it is not: O varies within a sampling interval
and can lose rank between samples. :func:`lwo_path_report` checks analytic paths
(``obsplan.trajectory.AnalyticPath``) between samples by root finding.

The rank is always computed on the half-squared rows. For ``r > 0`` the plain-range rows of orders
``0..K`` span exactly the same space (triangular chain rule above), but they are badly conditioned:
``∇ r^(k)`` carries terms in ``1/r^(2k-1)`` that cancel, and measured on 6e4-sample lines their
numerical rank drops by one or two at ordinary samples. At ``r = 0`` the plain range is not
differentiable, O is undefined (NaN from :func:`lwo_matrices`), and the documented verdict is
the half-squared one, which is rank deficient there (the row ``(p - b, 0)`` vanishes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Protocol

import casadi as ca
import numpy as np
from scipy.optimize import brentq, minimize_scalar

from obsplan.core.errors import InputError
from obsplan.model.beacon import BeaconPath
from obsplan.model.vehicle import VehicleModel
from obsplan.trajectory.relative import relative_samples
from obsplan.trajectory.sampled import Trajectory

#: Relative tolerance on the singular values of the dimensionless O at one sample.
#: Entries are low-degree polynomials of the samples (a few flops: relative error ~1e-15), and the
#: samples of a long trajectory carry relative errors up to ~1e-13 (exact integration of 6e4 steps,
#: CSV round trip at 17 digits). A singular value of 1e-9 σ_max is a direction that is 1e-9
#: independent at the trajectory's own scale, e.g. a straight line passing 1e-9 ℓ (0.1 µm at
#: 100 m) from the beacon, which no vehicle can tell from a radial one. Four decades above
#: round-off, far below any manoeuvre; measured margins in tests/test_lwo.py.
LWO_RANK_TOL: float = 1e-9


def lwo_orders(model: VehicleModel, input_derivatives: int = 0) -> int:
    """Highest Lie-derivative order ``K = 3 + input_derivatives`` used for ``model``.

    See the module docstring for why no higher order can raise the rank.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (the bound is the same for every sensor set and range form).
    input_derivatives : int, optional
        ``m``: number of time derivatives of ``u`` treated as extra inputs.

    Returns
    -------
    int
        ``K = 3 + m``.
    """
    del model  # the bound holds for every sensor set and range form of VehicleModel
    return 3 + int(input_derivatives)


def _check_m(input_derivatives: int) -> int:
    m = int(input_derivatives)
    if m != input_derivatives or m < 0:
        raise InputError(
            f"input_derivatives must be a non-negative integer, got {input_derivatives!r}"
        )
    return m


def _lie_gradients(model: VehicleModel, x, us, orders: int) -> list[list]:
    """Per output, the gradient rows ``∇_x L^k h_j`` for ``k = 0..orders`` (SX, zeros kept)."""
    m = len(us) - 1
    xdot = model.f_expr(x, us[0])
    h = model.h_expr(x)
    out = []
    for j in range(h.shape[0]):
        L = h[j]
        rows = []
        for _k in range(orders + 1):
            rows.append(ca.jacobian(L, x))
            # extended Lie derivative: d/dt through x and through u, u', ... (u^(m+1) = 0)
            dL = ca.jtimes(L, x, xdot)
            for i in range(m):
                dL += ca.jtimes(L, us[i], us[i + 1])
            L = ca.simplify(dL) if dL.is_scalar() else dL
        out.append(rows)
    return out


@cache
def _lwo_function(model: VehicleModel, m: int, orders: int) -> ca.Function:
    x = ca.SX.sym("x", model.state_dim)
    us = [ca.SX.sym(f"u{i}" if i else "u", model.dim) for i in range(m + 1)]
    rows = [ca.densify(g) for out in _lie_gradients(model, x, us, orders) for g in out if g.nnz()]
    O = ca.vertcat(*rows) if rows else ca.SX.zeros(0, model.state_dim)
    names = ["x"] + [f"u{i}" if i else "u" for i in range(m + 1)]
    return ca.Function("lwo_matrix", [x, *us], [O], names, ["O"])


def taylor_moments(orders: int, tau: float) -> np.ndarray:
    """``H_ik = ∫_{-τ}^0 s^(i+k) / (i! k!) ds``, shape ``(orders + 1, orders + 1)``: the second
    moments of the Taylor coefficients ``s^k / k!`` over the past window ``[-τ, 0]``.

    Parameters
    ----------
    orders : int
        Highest Lie-derivative order ``K``.
    tau : float
        Length of the past window ``τ`` (in the time unit of the caller).

    Returns
    -------
    ndarray, shape (orders + 1, orders + 1)
        The symmetric moment matrix ``H``.
    """
    i = np.arange(orders + 1)
    n = i[:, None] + i[None, :]
    fact = np.array([math.factorial(int(k)) for k in i], float)
    return (-1.0) ** n * tau ** (n + 1) / ((n + 1) * fact[:, None] * fact[None, :])


@cache
def local_information_function(model: VehicleModel, tau: float | None) -> ca.Function:
    """CasADi ``I(x, u, w)``: the information about the state now from the outputs over the
    past ``τ``, with the input held (the LWO matrix, eq. 9, with its rows weighted).

    Under a held input every output is a finite Taylor sum in its Lie derivatives (module
    docstring, "Held inputs"): ``h_j(x(t + s)) = Σ_k s^k/k! L^k h_j(x(t))``, so its gradient
    with respect to ``x(t)`` is ``Σ_k s^k/k! ∇L^k h_j``. Read continuously with ``w_j``
    information per unit time (rate / variance) over ``s ∈ [-τ, 0]``, the Fisher information is
    ``Σ_j w_j O_jᵀ H(τ) O_j`` with ``O_j`` the rows ``∇L^k h_j``, ``k = 0..3`` (:func:`lwo_orders`)
    and ``H`` of :func:`taylor_moments`. Inputs ``x`` (state_dim,), ``u`` (n,), ``w``
    (output_dim,), and with ``tau = None`` a fourth, ``H`` itself (``(K + 1)²``, column-major:
    a window per call); output ``I`` (state_dim × state_dim), in the units of ``x``, ``u``,
    ``τ``.

    Parameters
    ----------
    model : VehicleModel
        The vehicle model (sensors, range form, current, beacon).
    tau : float or None
        Length ``τ`` of the past window, in the time unit of the caller; None: ``H`` is an input.

    Returns
    -------
    casadi.Function
        ``I(x, u, w)`` or ``I(x, u, w, H)``, built once per model and ``tau`` (cached).
    """
    x = ca.SX.sym("x", model.state_dim)
    u = ca.SX.sym("u", model.dim)
    w = ca.SX.sym("w", model.output_dim)
    K = lwo_orders(model) + 1
    Hs = ca.SX.sym("H", K * K)
    H = ca.reshape(Hs, K, K) if tau is None else ca.DM(taylor_moments(K - 1, float(tau)))
    info = ca.SX.zeros(model.state_dim, model.state_dim)
    for j, rows in enumerate(_lie_gradients(model, x, [u], lwo_orders(model))):
        O = ca.vertcat(*rows)
        info = info + w[j] * (O.T @ H @ O)
    if tau is None:
        return ca.Function("lwo_information", [x, u, w, Hs], [info], ["x", "u", "w", "H"], ["I"])
    return ca.Function("lwo_information", [x, u, w], [info], ["x", "u", "w"], ["I"])


def lwo_matrix_function(
    model: VehicleModel, input_derivatives: int = 0, *, orders: int | None = None
) -> ca.Function:
    """CasADi function ``O(x, u[, u1..um])`` of the Lie-derivative observability matrix (eq. 9).

    Parameters
    ----------
    model : VehicleModel
        Vehicle model (any sensors, range form, current, beacon).
    input_derivatives : int, optional
        ``m``: number of time derivatives of ``u`` treated as extra inputs (extended Lie
        derivatives; ``u^(m+1) = 0``). ``0``: constant input, the paper's matrices.
    orders : int or None, optional
        Highest Lie-derivative order ``K``; default :func:`lwo_orders` (``3 + m``), enough for rank.

    Returns
    -------
    casadi.Function
        Inputs ``x`` (state_dim,), ``u`` (n,) [m/s²] and ``u1..um`` (n,) [m/s^(2+i)]; output ``O``
        of shape ``(rows, state_dim)``, the non-zero gradient rows ordered by output, then order.
        Built from SX; callable with numbers, SX or MX (e.g. inside an ``Opti`` problem).
    """
    m = _check_m(input_derivatives)
    K = lwo_orders(model, m) if orders is None else int(orders)
    return _lwo_function(model, m, K)


def _trajectory_state(traj: Trajectory, model: VehicleModel) -> np.ndarray:
    """States ``(p, ν)`` or ``(p, ν, 0)`` at every sample, shape ``(N, state_dim)``."""
    parts = [traj.p, traj.v]
    if model.current:
        parts.append(np.zeros_like(traj.v))  # nominal v_f = 0: O depends on v + v_f only
    return np.hstack(parts)


def input_derivative_estimates(traj: Trajectory, order: int) -> list[np.ndarray]:
    """Finite-difference estimates of ``u', ..., u^(order)`` at the samples, each ``(N, n)``.

    Uses ``numpy.gradient`` (second-order central differences, one-sided at the ends) on the
    sample times, applied repeatedly. Piecewise-constant inputs have zero derivative except at
    their jumps, where this estimate is a smoothed spike: use ``input_derivatives > 0`` only for
    trajectories that sample a smooth input.

    Parameters
    ----------
    traj : Trajectory
        The sampled path.
    order : int
        Highest derivative estimated.

    Returns
    -------
    list of ndarray, shape (N, n)
        ``u', ..., u^(order)`` [m/s³, ...]; empty for ``order = 0``.
    """
    out: list[np.ndarray] = []
    cur = traj.u
    for _ in range(order):
        cur = np.gradient(cur, traj.t, axis=0) if traj.n_samples > 1 else np.zeros_like(cur)
        out.append(cur)
    return out


def _check_dims(traj: Trajectory, model: VehicleModel) -> None:
    if traj.dim != model.dim:
        raise InputError(
            f"the model is {model.dim}D but the trajectory is {traj.dim}D; build the model with "
            f"dim={traj.dim}"
        )


def _relative(
    traj: Trajectory, model: VehicleModel, beacon_path: BeaconPath | None
) -> tuple[Trajectory, VehicleModel]:
    """The trajectory and model the rank test evaluates: unchanged for a fixed beacon; relative
    to a moving one, with the beacon at the origin (module docstring, "Moving beacon")."""
    if beacon_path is None:
        return traj, model
    _check_dims(traj, model)
    return relative_samples(traj, beacon_path), replace(model, beacon=None)


def lwo_matrices(
    traj: Trajectory,
    model: VehicleModel,
    input_derivatives: int = 0,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """O (eq. 9) at every sample of ``traj``, in SI units, shape ``(N, rows, state_dim)``.

    The state at each sample is ``(p, ν)`` (``(p, ν, 0)`` with current; see module docstring); the
    input is ``u[k]``. With the ``"range"`` range form, O is not defined at a sample on the beacon
    (``r = 0``): those rows are NaN there (:func:`lwo_ranks` does not use them; module docstring).
    With ``beacon_path`` the state is relative to the moving beacon and the input is ``u - b''``
    (module docstring, "Moving beacon").

    Parameters
    ----------
    traj : Trajectory
        The sampled path (positions [m], velocities [m/s], held inputs [m/s²]).
    model : VehicleModel
        The vehicle model (sensors, range form, current, beacon).
    input_derivatives : int, optional
        ``m``: number of time derivatives of ``u`` used (estimated by
        :func:`input_derivative_estimates`).
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (it replaces ``model.beacon``); None: the
        model's fixed beacon.

    Returns
    -------
    ndarray, shape (N, rows, state_dim)
        O at every sample, SI units (rows of m², m²/s, ..., columns of m and m/s).

    Raises
    ------
    InputError
        If the model, the trajectory or the beacon path differ in dimension, the path does not
        cover the trajectory, or ``input_derivatives`` is not a non-negative integer.
    """
    m = _check_m(input_derivatives)
    _check_dims(traj, model)
    traj, model = _relative(traj, model, beacon_path)
    fn = lwo_matrix_function(model, m)
    N = traj.n_samples
    x = _trajectory_state(traj, model)
    us = [traj.u, *input_derivative_estimates(traj, m)]
    out = np.asarray(fn.map(N, "serial")(x.T, *(u.T for u in us)))
    rows = fn.size1_out(0)
    return out.reshape(rows, N, model.state_dim).transpose(1, 0, 2)


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(a**2, axis=1))))


def characteristic_scales(
    traj: Trajectory, model: VehicleModel, beacon_path: BeaconPath | None = None
) -> tuple[float, float]:
    """Length ``ℓ`` [m] and time ``T`` [s] of a trajectory, covariant with the units.

    ``ℓ`` is the RMS range to the beacon (else the RMS distance from the mean position, else 1);
    ``T = ℓ / RMS speed`` (else ``√(ℓ / RMS |u|)``, else the duration). With ``beacon_path``
    the range is to the moving beacon and the speed (acceleration) is the larger of the
    vehicle's and the relative one: a beacon trailing the vehicle leaves a relative speed of
    round-off size, which ``ℓ / speed`` would blow up to an O(1) direction.

    Parameters
    ----------
    traj : Trajectory
        The sampled path (positions [m], velocities [m/s], held inputs [m/s²]).
    model : VehicleModel
        The vehicle model (sensors, range form, current, beacon).
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (it replaces ``model.beacon``).

    Returns
    -------
    ell : float
        Length scale ``ℓ`` [m].
    T : float
        Time scale [s].

    Raises
    ------
    InputError
        If the model, the trajectory or the beacon path differ in dimension, or the path does
        not cover the trajectory.
    """
    _check_dims(traj, model)
    own = traj
    traj, model = _relative(traj, model, beacon_path)
    rel = traj.p - model.beacon_array
    ell = float(np.sqrt(np.mean(np.sum(rel**2, axis=1))))
    if not ell > 0:
        spread = traj.p - traj.p.mean(axis=0)
        ell = float(np.sqrt(np.mean(np.sum(spread**2, axis=1)))) or 1.0
    speed = float(np.sqrt(np.mean(np.sum(traj.v**2, axis=1))))
    accel = float(np.sqrt(np.mean(np.sum(traj.u**2, axis=1))))
    if beacon_path is not None:
        speed, accel = max(speed, _rms(own.v)), max(accel, _rms(own.u))
    if speed > 0:
        T = ell / speed
    elif accel > 0:
        T = float(np.sqrt(ell / accel))
    else:
        T = traj.duration
    return ell, T


def _dimensionless(
    traj: Trajectory,
    model: VehicleModel,
    input_derivatives: int,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """O of the trajectory (relative to ``beacon_path`` if given) nondimensionalised by
    :func:`characteristic_scales` (of the relative trajectory)."""
    ell, T = characteristic_scales(traj, model, beacon_path)
    traj, model = _relative(traj, model, beacon_path)
    tr = Trajectory(
        t=traj.t / T,
        p=(traj.p - model.beacon_array) / ell,
        v=traj.v * T / ell,
        u=traj.u * T**2 / ell,
    )
    return lwo_matrices(tr, _nd_model(model), input_derivatives)


def _nd_model(model: VehicleModel) -> VehicleModel:
    """The same model in the dimensionless frame: beacon at the origin, half-squared range (same
    row space as the plain range for r > 0, well conditioned; see module docstring)."""
    return VehicleModel(
        dim=model.dim,
        sensors=model.sensors,
        current=model.current,
        beacon=None,
        range_form="half-squared",
    )


def ranks_of(O: np.ndarray, tol: float = LWO_RANK_TOL) -> np.ndarray:
    """Rank of each matrix of a stack ``(N, rows, cols)``: singular values above ``tol · σ_max``.

    The matrices should be dimensionless (as :func:`lwo_ranks` makes them).

    Parameters
    ----------
    O : ndarray, shape (N, rows, cols)
        Observability matrices.
    tol : float, optional
        Relative tolerance on the singular values.

    Returns
    -------
    ndarray of int, shape (N,)
        The rank of each matrix (0 for a zero matrix).
    """
    s = np.linalg.svd(np.asarray(O, float), compute_uv=False)
    smax = s[..., :1]
    return np.sum((s > tol * smax) & (smax > 0), axis=-1).astype(int)


def lwo_ranks(
    traj: Trajectory,
    model: VehicleModel,
    input_derivatives: int = 0,
    beacon_path: BeaconPath | None = None,
) -> np.ndarray:
    """Unit-invariant rank of O at every sample, shape ``(N,)`` int.

    O is nondimensionalised by :func:`characteristic_scales` and its singular values compared with
    ``LWO_RANK_TOL · σ_max``; the range rows are taken in half-squared form (module docstring).

    Parameters
    ----------
    traj : Trajectory
        The sampled path (positions [m], velocities [m/s], held inputs [m/s²]).
    model : VehicleModel
        The vehicle model (sensors, range form, current, beacon).
    input_derivatives : int, optional
        ``m``: number of time derivatives of ``u`` used.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (module docstring, "Moving beacon"); None:
        the model's fixed beacon.

    Returns
    -------
    ndarray of int, shape (N,)
        Rank of O at each sample; full rank is ``model.state_dim``.
    """
    return ranks_of(_dimensionless(traj, model, input_derivatives, beacon_path))


@dataclass(frozen=True)
class LWOReport:
    """Verdict of the observability rank condition (Theorem 3.4) along a trajectory.

    Attributes
    ----------
    along_trajectory
        O has full column rank at every sample: "locally weakly observable along the trajectory"
        (section 4.1). A sufficient condition: False does not prove unobservability.
    full_rank_fraction
        Fraction of samples where O has full column rank.
    min_rank
        Smallest rank over the samples.
    state_dim
        Number of states (full column rank).
    ranks
        Rank at each sample, shape ``(N,)``.
    """

    along_trajectory: bool
    full_rank_fraction: float
    min_rank: int
    state_dim: int
    ranks: np.ndarray = field(repr=False, compare=False)

    def to_dict(self) -> dict:
        """The ``lwo`` keys of ``obsplan analyze --json``.

        Returns
        -------
        dict
            ``along_trajectory``, ``full_rank_fraction``, ``min_rank``, ``state_dim`` (not the
            per-sample ranks).
        """
        return {
            "along_trajectory": bool(self.along_trajectory),
            "full_rank_fraction": float(self.full_rank_fraction),
            "min_rank": int(self.min_rank),
            "state_dim": int(self.state_dim),
        }


def lwo_report(
    traj: Trajectory,
    model: VehicleModel,
    input_derivatives: int = 0,
    beacon_path: BeaconPath | None = None,
) -> LWOReport:
    """Rank of O along ``traj`` summarised as an :class:`LWOReport`.

    Parameters
    ----------
    traj : Trajectory
        The sampled path (positions [m], velocities [m/s], held inputs [m/s²]).
    model : VehicleModel
        The vehicle model (sensors, range form, current, beacon).
    input_derivatives : int, optional
        ``m``: number of time derivatives of ``u`` used.
    beacon_path : BeaconPath or None, optional
        A moving beacon covering ``traj``'s span (module docstring, "Moving beacon"); None:
        the model's fixed beacon.

    Returns
    -------
    LWOReport
        The verdict, the fraction of full-rank samples and the rank at each sample.
    """
    ranks = lwo_ranks(traj, model, input_derivatives, beacon_path)
    full = ranks == model.state_dim
    ranks.setflags(write=False)
    return LWOReport(
        along_trajectory=bool(np.all(full)),
        full_rank_fraction=float(np.mean(full)),
        min_rank=int(ranks.min()),
        state_dim=model.state_dim,
        ranks=ranks,
    )


def lwo_structural_max_rank(
    model: VehicleModel, input_derivatives: int = 0, samples: int = 64, seed: int = 0
) -> int:
    """Largest rank of O over random states and inputs (its generic rank).

    Parameters
    ----------
    model : VehicleModel
        Vehicle model.
    input_derivatives : int, optional
        As in :func:`lwo_matrix_function`.
    samples : int, optional
        Number of random (state, input) points, standard normal in dimensionless units.
    seed : int, optional
        Seed of the generator.

    Returns
    -------
    int
        E.g. 4 for 3D range-only with constant input: the frozen matrix can never reach 6.
    """
    m = _check_m(input_derivatives)
    fn = lwo_matrix_function(replace(model, range_form="half-squared"), m)
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((model.state_dim, samples))
    x[: model.dim] += model.beacon_array[:, None]
    us = [rng.standard_normal((model.dim, samples)) for _ in range(m + 1)]
    out = np.asarray(fn.map(samples, "serial")(x, *us))
    rows = fn.size1_out(0)
    O = out.reshape(rows, samples, model.state_dim).transpose(1, 0, 2)
    return int(ranks_of(O).max())


# ------------------------------------------------------------------ smooth paths, between samples
class SmoothPath(Protocol):
    """A path with analytic pieces, e.g. :class:`obsplan.trajectory.AnalyticPath`."""

    @property
    def dim(self) -> int: ...

    @property
    def breakpoints(self) -> np.ndarray: ...

    def evaluate(
        self, t: np.ndarray | float, piece: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at times ``t``.

        Parameters
        ----------
        t : float or ndarray, shape (N,)
            Times [s] from the start of the path.
        piece : int or None, optional
            Index of the piece whose formulas are used; None: the piece containing each time.

        Returns
        -------
        pos, vel, acc : ndarray, shape (N, dim)
            Positions [m], velocities [m/s] and accelerations [m/s²].
        """
        ...


@dataclass(frozen=True)
class RankDrop:
    """Where O (eq. 9, input frozen at the path's own acceleration) loses rank on a smooth path.

    ``t_start == t_end`` for an isolated instant (a zero of ``det O``, located by root finding);
    otherwise O is rank deficient on ``[t_start, t_end]`` [s] (e.g. a constant-speed leg).
    ``rank``: the rank there; ``piece``: index of the path's piece.
    """

    t_start: float
    t_end: float
    rank: int
    piece: int

    @property
    def isolated(self) -> bool:
        return self.t_start == self.t_end

    def to_dict(self) -> dict:
        """The drop as a plain mapping (for JSON outputs).

        Returns
        -------
        dict
            ``t_start`` and ``t_end`` [s], ``rank`` and ``piece``.
        """
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class PathLWOReport:
    """LWO along a smooth path at *every* instant, not only at samples.

    Attributes
    ----------
    along_trajectory
        O has full column rank at every instant of the path (no :class:`RankDrop`).
    drops
        Isolated instants and intervals where the rank drops, in time order.
    state_dim
        Number of states.
    min_rank
        Smallest rank found.
    tol
        Relative singular-value tolerance of the rank (as :data:`LWO_RANK_TOL`).
    """

    along_trajectory: bool
    drops: tuple[RankDrop, ...]
    state_dim: int
    min_rank: int
    tol: float

    @property
    def zeros(self) -> tuple[float, ...]:
        """Times [s] of the isolated rank drops."""
        return tuple(d.t_start for d in self.drops if d.isolated)

    def to_dict(self) -> dict:
        """The report as a plain mapping (for JSON outputs).

        Returns
        -------
        dict
            ``along_trajectory``, ``drops`` (:meth:`RankDrop.to_dict` each), ``state_dim``,
            ``min_rank`` and ``tol``.
        """
        return {
            "along_trajectory": bool(self.along_trajectory),
            "drops": [d.to_dict() for d in self.drops],
            "state_dim": int(self.state_dim),
            "min_rank": int(self.min_rank),
            "tol": float(self.tol),
        }


def lwo_path_report(
    path: SmoothPath,
    model: VehicleModel,
    *,
    points_per_piece: int = 256,
    tol: float = LWO_RANK_TOL,
) -> PathLWOReport:
    """Rank of O along a smooth path, including between samples.

    The input is the path's acceleration ``u(t) = p''(t)``, frozen at each instant (the paper's
    matrices, e.g. eq. 37's ``det O = 6ω⁴ρ⁴``). On each analytic piece O is sampled at
    ``points_per_piece`` times; every sign change of ``det O`` (square O) is located by Brent's
    root finding, and every local minimum of ``σ_min/σ_max`` by bounded minimisation (touching
    zeros, non-square O), to ≲1e-8 of the sample spacing. Runs of three or more rank-deficient
    samples are reported as intervals (an analytic ``det O`` that vanishes on an interval vanishes
    on the whole piece). Two zeros closer than the sample spacing can cancel in the sign test:
    raise ``points_per_piece`` for paths with fast features.

    Parameters
    ----------
    path : SmoothPath
        Smooth path with ``dim``, ``breakpoints`` [s] and ``evaluate(t, piece)`` returning
        positions [m], velocities [m/s], accelerations [m/s²]; see :class:`SmoothPath`.
    model : VehicleModel
        Vehicle model (sensors, current, beacon). Ranks use the half-squared range rows and the
        dimensionless O of :func:`lwo_ranks` (scales of the path sampled on the check grid).
    points_per_piece : int, optional
        Samples per piece, ``>= 3``.
    tol : float, optional
        Relative singular-value tolerance.

    Returns
    -------
    PathLWOReport
        The verdict and every isolated instant or interval where the rank drops.

    Raises
    ------
    InputError
        If the model and the path differ in dimension, or ``points_per_piece`` is not an
        integer >= 3.
    """
    if path.dim != model.dim:
        raise InputError(
            f"the model is {model.dim}D but the path is {path.dim}D; build the model with "
            f"dim={path.dim}"
        )
    npts = int(points_per_piece)
    if npts != points_per_piece or npts < 3:
        raise InputError(f"points_per_piece must be an integer >= 3, got {points_per_piece!r}")
    bp = np.asarray(path.breakpoints, float)
    pieces = [i for i in range(len(bp) - 1) if bp[i + 1] > bp[i]]  # zero-length pieces: nothing
    grids = [np.linspace(bp[i], bp[i + 1], npts) for i in pieces]
    states = [path.evaluate(g, piece=i) for i, g in zip(pieces, grids, strict=True)]
    # scales from the path itself (as lwo_ranks takes them from a trajectory)
    keep = [slice(None)] + [slice(1, None)] * (len(grids) - 1)  # breakpoints once
    sample = Trajectory(
        t=np.concatenate([g[k] for g, k in zip(grids, keep, strict=True)]),
        p=np.concatenate([s[0][k] for s, k in zip(states, keep, strict=True)]),
        v=np.concatenate([s[1][k] for s, k in zip(states, keep, strict=True)]),
        u=np.concatenate([s[2][k] for s, k in zip(states, keep, strict=True)]),
    )
    ell, T = characteristic_scales(sample, model)
    fn = lwo_matrix_function(_nd_model(model))
    nx = model.state_dim

    def matrices(p: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        x = [(p - model.beacon_array) / ell, v * T / ell]
        if model.current:
            x.append(np.zeros_like(v))  # nominal v_f = 0: O depends on v + v_f only
        X = np.hstack(x)
        out = np.asarray(fn.map(len(X), "serial")(X.T, (a * T**2 / ell).T))
        return out.reshape(fn.size1_out(0), len(X), nx).transpose(1, 0, 2)

    def at(t: float, piece: int) -> np.ndarray:
        return matrices(*path.evaluate(t, piece=piece))[0]

    def ratio(O: np.ndarray) -> float:
        s = np.linalg.svd(O, compute_uv=False)
        # fewer rows than states (3D range only): structurally deficient, ratio 0
        return float(s[nx - 1] / s[0]) if len(s) == nx and s[0] > 0 else 0.0

    drops: list[RankDrop] = []
    min_rank = nx
    for i, g, (p, v, a) in zip(pieces, grids, states, strict=True):
        O = matrices(p, v, a)
        ranks = ranks_of(O, tol)
        min_rank = min(min_rank, int(ranks.min()))
        bad = ranks < nx
        found: list[float] = []
        # runs of deficient samples: intervals (3+) or isolated samples
        edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(int), 0]))
        for lo, hi in zip(edges[::2], edges[1::2], strict=True):
            if hi - lo >= 3:
                drops.append(RankDrop(float(g[lo]), float(g[hi - 1]), int(ranks[lo:hi].min()), i))
            else:
                found += [float(x) for x in g[lo:hi]]
        span = float(g[-1] - g[0])
        if O.shape[1] == O.shape[2]:
            det = np.linalg.det(O)
            for jz in np.flatnonzero((np.sign(det[:-1]) * np.sign(det[1:])) < 0):
                j = int(jz)
                if bad[j] or bad[j + 1]:
                    continue
                found.append(
                    brentq(
                        lambda t, i=i: float(np.linalg.det(at(t, i))),
                        g[j],
                        g[j + 1],
                        xtol=1e-12 * max(span, 1e-300),
                        rtol=4 * np.finfo(float).eps,
                    )
                )
        r = np.array([ratio(m) for m in O])
        for j in range(len(g)):
            left, right = float(r[max(j - 1, 0)]), float(r[min(j + 1, len(g) - 1)])
            # a zero between samples shows as a sample at most half its larger neighbour (V or
            # parabola); round-off wiggles of a flat ratio do not, and are not refined
            if bad[j] or r[j] > min(left, right) or r[j] > 0.5 * max(left, right):
                continue
            lo_t, hi_t = g[max(j - 1, 0)], g[min(j + 1, len(g) - 1)]
            res = minimize_scalar(
                lambda s, i=i, lo_t=lo_t: ratio(at(lo_t + s, i)),
                bounds=(0.0, hi_t - lo_t),
                method="bounded",
                options={"xatol": 1e-12 * max(span, 1e-300)},
            )
            if res.fun <= tol:
                found.append(float(lo_t + res.x))
        for t in sorted(found):
            if any(
                (d.piece == i and d.t_start <= t <= d.t_end)
                or (d.isolated and abs(t - d.t_start) <= 1e-9 * span)
                for d in drops
            ):
                continue  # inside a deficient run, or the same zero found twice
            rk = int(ranks_of(at(t, i)[None], tol)[0])
            rk = min(rk, nx - 1)  # a located zero: the limit of the rank is below full
            min_rank = min(min_rank, rk)
            drops.append(RankDrop(t, t, rk, i))
    drops.sort(key=lambda d: d.t_start)
    return PathLWOReport(
        along_trajectory=not drops,
        drops=tuple(drops),
        state_dim=nx,
        min_rank=min_rank,
        tol=float(tol),
    )
