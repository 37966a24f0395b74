"""The craft's path in the NLP: decision variables in intrinsic units, the exact path between
nodes, and its limits.

Decision variables
------------------
``W`` of shape ``(6, N)``, column ``k`` = ``(U_k, B_{k+1}, V_{k+1})`` (stage ordering, as the
vehicle's grid, :mod:`obsplan.planning.transcription.grid`); the start node ``(b_0, v_0)`` is the
craft's and fixed. Intrinsic units: ``U = a / accel`` per axis (``|U_i| <= 1``),
``V = v / speed`` (``|V| <= 1``) and ``B = (b - b_0) / L`` with ``L = speed · step``, the distance
the craft covers in a planning step, so the dynamics read ``B_{k+1} = B_k + V_k + (accel step /
2 speed) U_k`` with coefficients of order one, and the conditioning IPOPT sees does not depend on
the problem's units or size. (A unit of the size of the survey, a quarter of the distance flown
over the horizon as the vehicle's grid has it, took 1.3-1.8x the iterations on a 2D lawn-mower.)
Only the horizontal components are variables; in 3D ``b_z`` is the craft's start depth.

Between nodes ``t_k`` (every ``step`` seconds from the vehicle's first sample; the last interval
ends at its last sample, half a step to one and a half long, or the whole of a short horizon) the
acceleration is held, so the path is the exact quadratic ``b(t_k + s) = b_k + v_k s + a_k s²/2``:
:meth:`CraftGrid.state` gives it at any time as an affine function of ``W``.

Limits, and why they hold between the points where they are imposed
--------------------------------------------------------------------
* ``|a_i| <= accel_i``: bounds on ``U``, exact (held);
* ``|b'| <= speed``: at the nodes. On an interval ``b'(s) = v_k + a_k s`` is affine, so ``|b'|²`` is
  convex in ``s`` and its maximum is at an end: the bound holds everywhere;
* the area: bounds on ``B`` at the nodes, each side moved in by ``accel_i h²/8``. Along an axis
  ``b_i(s)`` is a parabola of curvature ``a_i``: it leaves the chord between its nodes by at most
  ``|a_i| h²/8``, so the path stays in the area;
* the minimum horizontal distance and the maximum (3D) range to the vehicle: at check points
  every ``check_dt`` seconds (and the horizon's end), tightened by ``margin = V_rel check_dt / 2``
  with ``V_rel`` the vehicle's largest (horizontal, for the distance) speed plus the craft's:
  the distance is ``V_rel``-Lipschitz in time, so it keeps the limit between check points. The
  first sample (both starts given) is not a constraint.

The beacon the range at epoch ``t_e`` is taken to is the craft at the transmission time
``t_e - r/c`` (:func:`~obsplan.estimation.epochs.epoch_beacons`: three fixed-point iterations from
the vehicle's nominal position, :data:`~obsplan.estimation.epochs.TRANSMIT_ITERATIONS`), on the
quadratic of the interval that ends at or holds ``t_e``. When ``t_e - r/c`` falls in the interval
before (an epoch within ``r/c`` after a node), the quadratic is extended across the node: the error
is at most ``|Δa| (r/c)²/2`` (8 mm for ``|Δa|`` = 0.4 m/s² at 300 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from obsplan.core.errors import InputError
from obsplan.estimation.epochs import SOUND_SPEED, TRANSMIT_ITERATIONS
from obsplan.model.beacon import BeaconPath, BeaconVehicle
from obsplan.trajectory.sampled import Trajectory, position_at

#: Default spacing of the check points of the distance limits [s] (module docstring).
CHECK_DT = 2.0


@dataclass(frozen=True, eq=False)
class CraftGrid:
    """Nodes, intrinsic units and limits of the craft's path (module docstring).

    Attributes
    ----------
    craft : BeaconVehicle
        The craft and its limits.
    nodes : ndarray, shape (N + 1,)
        Node times [s], from the vehicle's first sample to its last.
    L : float
        Unit of ``B`` [m].
    check_t : ndarray, shape (C,)
        Check times of the distance limits [s].
    check_p : ndarray, shape (C, n)
        The vehicle there [m].
    min_margin, range_margin : ndarray, shape (C,)
        Tightening of the minimum horizontal distance and of the maximum range at each check
        point [m]: the check spacing's, plus the margin for the vehicle's true path when given
        (:func:`craft_grid`).
    """

    craft: BeaconVehicle
    nodes: np.ndarray
    L: float
    check_t: np.ndarray
    check_p: np.ndarray
    min_margin: np.ndarray
    range_margin: np.ndarray

    @property
    def N(self) -> int:
        """Number of intervals."""
        return int(self.nodes.size - 1)

    @property
    def h(self) -> np.ndarray:
        """Interval lengths [s], shape (N,)."""
        return np.diff(self.nodes)

    @property
    def b0(self) -> np.ndarray:
        """Horizontal start [m]."""
        return np.asarray(self.craft.start[:2], float)

    def si_nodes(self, W):
        """Node accelerations, positions and velocities in SI units.

        Parameters
        ----------
        W : ndarray or casadi.SX, shape (6, N)
            Decision variables (intrinsic units).

        Returns
        -------
        a : list, N entries of shape (2,)
            Accelerations on each interval [m/s²].
        b, v : list, N + 1 entries of shape (2,)
            Positions [m] and velocities [m/s] at the nodes (entry 0: the start).
        """
        c = self.craft
        const = _constant(W)
        acc, b0 = const(c.accel), const(self.b0)
        a = [acc * _col(W, k, 0) for k in range(self.N)]
        b = [b0] + [b0 + self.L * _col(W, k, 2) for k in range(self.N)]
        v = [const(c.velocity)] + [c.speed * _col(W, k, 4) for k in range(self.N)]
        return a, b, v

    def interval(self, t: float) -> int:
        """The interval ``(t_k, t_{k+1}]`` holding ``t`` (interval 0 for the first node).

        Parameters
        ----------
        t : float
            A time [s] within the nodes.

        Returns
        -------
        int
            Interval index ``k``.
        """
        return int(np.clip(np.searchsorted(self.nodes, t, side="left") - 1, 0, self.N - 1))

    def state(self, nodes_si: tuple, k: int, s):
        """Horizontal position and velocity at ``t_k + s`` on interval ``k`` (exact quadratic).

        Parameters
        ----------
        nodes_si : tuple
            :meth:`si_nodes` of ``W``.
        k : int
            Interval.
        s : float or casadi.SX
            Time since node ``k`` [s].

        Returns
        -------
        b, v : shape (2,)
            Position [m] and velocity [m/s].
        """
        a, b, v = nodes_si
        return b[k] + v[k] * s + 0.5 * a[k] * s**2, v[k] + a[k] * s

    def full(self, bxy):
        """The 3D position of a horizontal one (``z`` the craft's depth); 2D unchanged.

        Parameters
        ----------
        bxy : shape (2,)
            Horizontal position [m].

        Returns
        -------
        shape (n,)
            Position [m].
        """
        if self.craft.dim == 2:
            return bxy
        if isinstance(bxy, np.ndarray):
            return np.append(bxy, self.craft.start[2])
        return ca.vertcat(bxy, float(self.craft.start[2]))

    def epoch_beacons(self, W, times: np.ndarray, p: np.ndarray):
        """Beacon at transmission for ranges received at ``times`` by the vehicle at ``p``.

        Parameters
        ----------
        W : ndarray or casadi.SX, shape (6, N)
            Decision variables.
        times : ndarray, shape (E,)
            Reception times [s].
        p : ndarray, shape (E, n)
            The vehicle's nominal positions there [m].

        Returns
        -------
        ndarray or casadi.SX, shape (n, E)
            Beacon positions [m] (module docstring).
        """
        nodes_si = self.si_nodes(W)
        cols = []
        for te, pe in zip(times, p, strict=True):
            k = self.interval(float(te))
            s = float(te - self.nodes[k])
            if s <= 0.0:  # the first node: the start, held before it (epoch_beacons)
                cols.append(self.full(nodes_si[1][0]))
                continue
            ts = s
            pe_c = _constant(W)(pe)
            for _ in range(TRANSMIT_ITERATIONS):
                b = self.full(self.state(nodes_si, k, ts)[0])
                ts = s - _norm(pe_c - b) / SOUND_SPEED
            cols.append(self.full(self.state(nodes_si, k, ts)[0]))
        if isinstance(W, np.ndarray):
            return np.column_stack(cols)
        return ca.horzcat(*cols)

    def constraints(self, W) -> tuple[list, list, list]:
        """The path's constraints ``lo <= g <= hi`` (module docstring), in intrinsic units.

        Parameters
        ----------
        W : casadi.SX, shape (6, N)
            Decision variables.

        Returns
        -------
        g : list of casadi.SX
            Constraint expressions.
        lo, hi : list of float
            Their bounds.
        """
        c = self.craft
        a, b, v = self.si_nodes(W)
        g, lo, hi = [], [], []
        for k, hk in enumerate(self.h):
            bn = b[k] + v[k] * hk + 0.5 * a[k] * hk**2
            vn = v[k] + a[k] * hk
            g += [(b[k + 1] - bn) / self.L, (v[k + 1] - vn) / c.speed]
            lo += [0.0] * 4
            hi += [0.0] * 4
            g.append(ca.sumsqr(_col(W, k, 4)))
            lo.append(-math.inf)
            hi.append(1.0)
        nodes_si = (a, b, v)
        for i, (te, pe) in enumerate(zip(self.check_t, self.check_p, strict=True)):
            k = self.interval(float(te))
            bxy = self.state(nodes_si, k, float(te - self.nodes[k]))[0]
            dxy = ca.sumsqr(ca.DM(pe[:2]) - bxy)
            if c.min_distance > 0:
                d = c.min_distance + float(self.min_margin[i])
                g.append(dxy / d**2)
                lo.append(1.0)
                hi.append(math.inf)
            if c.max_range is not None:
                dz = float(pe[2] - c.start[2]) if c.dim == 3 else 0.0
                r = c.max_range - float(self.range_margin[i])
                g.append((dxy + dz**2) / r**2)
                lo.append(-math.inf)
                hi.append(1.0)
        return g, lo, hi

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Simple bounds on ``W`` (6, N): ``|U_i| <= 1``, ``|V_i| <= 1``, the shrunk area on ``B``.

        Returns
        -------
        lo, hi : ndarray, shape (6, N)
            Bounds (``±inf`` where none).
        """
        c = self.craft
        lo = np.full((6, self.N), -np.inf)
        hi = np.full((6, self.N), np.inf)
        lo[[0, 1, 4, 5]] = -1.0
        hi[[0, 1, 4, 5]] = 1.0
        if c.area is not None:
            shrink = np.asarray(c.accel, float) * float(np.max(self.h)) ** 2 / 8.0
            lo[2:4] = ((c.area[:, 0] + shrink - self.b0) / self.L)[:, None]
            hi[2:4] = ((c.area[:, 1] - shrink - self.b0) / self.L)[:, None]
            if np.any(lo[2:4, 0] > hi[2:4, 0]):
                raise InputError(
                    f"beacon vehicle area is narrower than the path's overshoot between planning "
                    f"nodes ({shrink.tolist()} m per side); widen the area or shorten the step"
                )
        return lo, hi

    def from_path(self, path: BeaconPath) -> np.ndarray:
        """Decision variables ``W`` (6, N) read off a beacon path: its positions and velocities
        at the nodes, the accelerations their differences (clipped to the limits); a guess, not
        necessarily on the dynamics.

        Parameters
        ----------
        path : BeaconPath
            The path, covering the nodes.

        Returns
        -------
        ndarray, shape (6, N)
            The guess (intrinsic units).
        """
        c = self.craft
        t = self.nodes
        b = path.position(t)[:, :2]
        v = np.gradient(b, t, axis=0)
        v[0] = c.velocity
        sp = np.linalg.norm(v, axis=1, keepdims=True)
        v = v * np.minimum(1.0, c.speed / np.maximum(sp, 1e-12))
        a = np.clip(np.diff(v, axis=0) / self.h[:, None], -c.accel, c.accel)
        W = np.empty((6, self.N))
        W[0:2] = (a / c.accel).T
        W[2:4] = ((b[1:] - self.b0) / self.L).T
        W[4:6] = (v[1:] / c.speed).T
        return W

    def samples(self, W: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, positions and velocities of the path, fine enough that linear interpolation
        between samples is within ``tol`` of it: a parabola of curvature ``|a|`` leaves its chord
        over ``δ`` by at most ``|a| δ²/8``, so each interval is cut in pieces of at most
        ``sqrt(8 tol / |a|_max)``, ``|a|_max = |accel|``.

        Parameters
        ----------
        W : ndarray, shape (6, N)
            Decision variables.
        tol : float
            Largest distance [m] between the path and its linear interpolation.

        Returns
        -------
        t : ndarray, shape (M,)
        positions, velocities : ndarray, shape (M, n)
            In 3D ``z`` is the craft's depth and ``v_z = 0``.
        """
        nodes_si = self.si_nodes(W)
        dmax = math.sqrt(8.0 * tol / float(np.linalg.norm(self.craft.accel)))
        ts, bs, vs = [], [], []
        for k, hk in enumerate(self.h):
            m = max(1, math.ceil(hk / dmax))
            for s in np.arange(m) * (hk / m):
                bk, vk = self.state(nodes_si, k, float(s))
                ts.append(self.nodes[k] + s)
                bs.append(self.full(np.asarray(bk, float)))
                vs.append(self.full(np.asarray(vk, float)))
        bk, vk = self.state(nodes_si, self.N - 1, float(self.h[-1]))
        ts.append(self.nodes[-1])
        bs.append(self.full(np.asarray(bk, float)))
        vs.append(self.full(np.asarray(vk, float)))
        vel = np.array(vs)
        if self.craft.dim == 3:
            vel[:, 2] = 0.0
        return np.array(ts), np.array(bs), vel


def _col(W, k: int, row: int):
    """Rows ``row, row + 1`` of column ``k`` of ``W`` (numpy (2,) or CasADi (2, 1))."""
    return W[row : row + 2, k]


def _constant(W):
    """How a numeric vector joins expressions of ``W``: an array for numbers, a column ``DM``
    for CasADi (numpy would broadcast a CasADi column into an object array)."""
    if isinstance(W, np.ndarray):
        return lambda x: np.asarray(x, float)
    return lambda x: ca.DM(np.asarray(x, float).reshape(-1, 1))


def _norm(x):
    if isinstance(x, np.ndarray):
        return float(np.linalg.norm(x))
    return ca.norm_2(x)


def craft_grid(
    vehicle: Trajectory,
    craft: BeaconVehicle,
    step: float,
    check_dt: float = CHECK_DT,
    truth_margins: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> CraftGrid:
    """The :class:`CraftGrid` of a craft serving ``vehicle`` with planning step ``step`` [s].

    Parameters
    ----------
    vehicle : Trajectory
        The vehicle's fixed path (its first and last samples are the horizon).
    craft : BeaconVehicle
        The craft and its limits.
    step : float
        Planning step [s], > 0.
    check_dt : float, optional
        Spacing of the check points of the distance limits [s] (module docstring).
    truth_margins : tuple of three ndarray (M,), optional
        Times [s] and the margins [m] the vehicle's *true* path needs on ``min_distance`` and on
        ``max_range`` there (:func:`~obsplan.planning.solver.margins.craft_distance_margins`),
        interpolated linearly at the check points and added to the check spacing's; None: none.

    Returns
    -------
    CraftGrid
        Nodes, units, check points and margins.

    Raises
    ------
    InputError
        A craft of another dimension than the vehicle, a non-positive step or check spacing, or
        margins that leave no room within ``max_range``.
    """
    if craft.dim != vehicle.dim:
        raise InputError(
            f"beacon vehicle is {craft.dim}D (start {craft.start.tolist()}) but the vehicle's path "
            f"is {vehicle.dim}D; give the craft's start with {vehicle.dim} coordinates"
        )
    for name, val in (("step", step), ("check_dt", check_dt)):
        if not (math.isfinite(val) and val > 0):
            raise InputError(f"{name} must be a positive time in seconds, got {val!r}")
    t0, tf = float(vehicle.t[0]), float(vehicle.t[-1])
    N = max(1, math.ceil((tf - t0) / step - 1e-9))
    if N > 1 and (tf - t0) - (N - 1) * step < 0.5 * step:
        N -= 1  # a sliver of a last interval joins the one before (at most 1.5 steps long)
    nodes = np.append(t0 + step * np.arange(N), tf)
    L = craft.speed * step
    C = max(1, math.ceil((tf - t0) / check_dt - 1e-9))
    check_t = np.linspace(t0, tf, C + 1)[1:]
    vmax_h = float(np.max(np.linalg.norm(vehicle.v[:, :2], axis=1)))
    vmax = float(np.max(np.linalg.norm(vehicle.v, axis=1)))
    dt_c = (tf - t0) / C
    min_margin = np.full(check_t.size, 0.5 * dt_c * (vmax_h + craft.speed))
    range_margin = np.full(check_t.size, 0.5 * dt_c * (vmax + craft.speed))
    if truth_margins is not None:
        mt, mh, mr = (np.asarray(a, float) for a in truth_margins)
        min_margin += np.interp(check_t, mt, mh)
        range_margin += np.interp(check_t, mt, mr)
    if craft.max_range is not None and np.max(range_margin) >= craft.max_range:
        raise InputError(
            f"beacon vehicle max_range {craft.max_range} m is within the check margin "
            f"{np.max(range_margin):.3g} m; lower check_dt, or limits.keepout_confidence"
        )
    return CraftGrid(
        craft=craft,
        nodes=nodes,
        L=L,
        check_t=check_t,
        check_p=position_at(vehicle, check_t),
        min_margin=min_margin,
        range_margin=range_margin,
    )
