"""The planning grid: decision variables in intrinsic units, and the exact path they describe.

Decision variables
------------------
``W`` of shape ``(3n, N)``, column ``k`` = ``(U_k, P_{k+1}, V_{k+1})`` (stage ordering, so the KKT
matrix is banded); the start node is fixed. The variables are in *intrinsic* units of the
problem, not the user's: ``U = u / a`` (per-axis bound, so ``|U_i| <= 1``), ``V = v / v_max``
(``|V| <= 1``) and ``P = (p - b) / L_p`` with ``L_p = max(|p_0 - b|, v_max T_f / 4)``, ``b`` the
beacon (its start ``b(0)`` when it moves on a known path). Every
constraint is written in those units, so the conditioning IPOPT sees does not depend on the
problem's size, its units or its metric ``[scales]``.

Between nodes the path is the exact quadratic of the double integrator under the held input:
:meth:`Grid.sample_operator` gives positions and velocities at any times as an affine map of
``vec(W)``, :func:`dynamics_residual` the exact zero-order-hold steps, :func:`midpoints` the
interval midpoints.

A beacon on a known path ``b(t)`` (``beacon.motion = "path"``): the decision variables stay
relative to its start ``b0 = b(0)``, so the dynamics are the vehicle's own double integrator;
what needs the position relative to the beacon at a time ``s`` subtracts the known offset
``b(s) - b0`` (:meth:`Grid.beacon_offset`): :meth:`Grid.sample_operator`'s constant, and the
distance limits at the nodes and midpoints. ``si_nodes`` and ``midpoints`` stay relative to
``b0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp

from obsplan.model.beacon import BeaconPath
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.trajectory.sampled import Trajectory


@dataclass(frozen=True)
class Grid:
    """The planning grid and the intrinsic units of the decision variables (module docstring).

    The start ``(p0, v0)`` enters the path only here (:meth:`si_nodes`, :meth:`sample_operator`):
    the one place to make it an NLP parameter for re-solves from an estimated state.
    """

    n: int
    N: int
    h: float  # planning step [s]
    p0: np.ndarray  # start position relative to the beacon [m]
    v0: np.ndarray  # start velocity [m/s]
    a: np.ndarray  # per-axis input bound [m/s^2] = unit of U
    v_max: float  # speed bound [m/s] = unit of V
    Lp: float  # unit of P [m]
    beacon: np.ndarray  # [m]; a moving beacon's start b(0)
    #: The beacon's known path (None: fixed at ``beacon``).
    beacon_path: BeaconPath | None = None

    @classmethod
    def from_problem(cls, pb: PlanningProblem) -> Grid:
        """The grid of a problem: its horizon, start, limits and beacon, and the intrinsic units.

        Parameters
        ----------
        pb : PlanningProblem
            The problem: ``horizon`` (``N`` steps of ``h`` [s]), start state, beacon,
            ``limits.accel`` and ``limits.speed``.

        Returns
        -------
        Grid
            With ``Lp = max(|p0 - b|, v_max T / 4, 1e-3)`` [m] (``b`` the beacon's start
            ``b(0)`` when it moves on a known path, which the grid then keeps).
        """
        path = pb.beacon_path
        b = pb.beacon_start
        p0 = pb.p0 - b
        T = pb.horizon.duration
        v_max = pb.limits.speed
        return cls(
            n=pb.dim,
            N=pb.horizon.steps,
            h=pb.horizon.dt,
            p0=p0,
            v0=pb.v0.copy(),
            a=pb.accel.copy(),
            v_max=v_max,
            Lp=max(float(np.linalg.norm(p0)), v_max * T / 4.0, 1e-3),
            beacon=b,
            beacon_path=path,
        )

    def beacon_offset(self, s: np.ndarray) -> np.ndarray:
        """The beacon's displacement from its start, ``b(s) - b(0)`` [m], shape ``(n, J)``.

        Parameters
        ----------
        s : ndarray, shape (J,)
            Times [s] from the start, in ``[0, N h]``.

        Returns
        -------
        ndarray, shape (n, J)
            Zeros for a fixed beacon.
        """
        s = np.atleast_1d(np.asarray(s, float))
        if self.beacon_path is None:
            return np.zeros((self.n, s.size))
        return (self.beacon_path.position(s) - self.beacon).T

    @property
    def times(self) -> np.ndarray:
        """Node times ``t_k``, k = 0..N [s]."""
        return np.arange(self.N + 1) * self.h

    def to_trajectory(self, W: np.ndarray) -> Trajectory:
        """Scaled ``W`` ``(3n, N)`` to an SI :class:`Trajectory` on the planning grid.

        Parameters
        ----------
        W : ndarray, shape (3n, N)
            The path's decision variables in intrinsic units (column ``k``: ``U_k, P_{k+1},
            V_{k+1}``).

        Returns
        -------
        Trajectory
            On the node times ``t_k`` [s], from the start state; positions [m] in the problem's
            frame (beacon added back), velocities [m/s], inputs [m/s²] (the last one repeated
            at ``t_N``).
        """
        n = self.n
        U, P, V = W[:n], W[n : 2 * n], W[2 * n :]
        p = np.vstack([self.p0, (P * self.Lp).T]) + self.beacon
        v = np.vstack([self.v0, (V * self.v_max).T])
        u = (U * self.a[:, None]).T
        u = np.vstack([u, u[-1:]])
        return Trajectory(t=self.times, p=p, v=v, u=u)

    def from_trajectory(self, traj: Trajectory) -> np.ndarray:
        """SI trajectory on this grid to scaled ``W`` ``(3n, N)``.

        Parameters
        ----------
        traj : Trajectory
            A path with ``N + 1`` samples on this grid (its first sample is not read: the start
            is fixed).

        Returns
        -------
        ndarray, shape (3n, N)
            The decision variables in intrinsic units.

        Raises
        ------
        ValueError
            If ``traj`` does not have ``N + 1`` samples.
        """
        if traj.n_samples != self.N + 1:
            raise ValueError(f"trajectory has {traj.n_samples} samples, grid has {self.N + 1}")
        U = (traj.u[:-1] / self.a).T
        P = ((traj.p[1:] - self.beacon) / self.Lp).T
        V = (traj.v[1:] / self.v_max).T
        return np.vstack([U, P, V])

    def si_nodes(self, W):
        """SI ``(u (n, N), p - b (n, N+1), v (n, N+1))`` of symbolic or numeric ``W``.

        Parameters
        ----------
        W : ndarray or casadi.MX or casadi.SX, shape (3n, N)
            The path's decision variables in intrinsic units.

        Returns
        -------
        u : ndarray or casadi expression, shape (n, N)
            Inputs [m/s²].
        p : ndarray or casadi expression, shape (n, N + 1)
            Positions relative to the beacon (its start ``b(0)`` when it moves) [m], the fixed
            start first.
        v : ndarray or casadi expression, shape (n, N + 1)
            Velocities [m/s], the fixed start first.
        """
        n = self.n
        U, P, V = W[:n, :], W[n : 2 * n, :], W[2 * n :, :]
        if isinstance(W, np.ndarray):
            u = U * self.a[:, None]
            p = np.hstack([self.p0[:, None], P * self.Lp])
            v = np.hstack([self.v0[:, None], V * self.v_max])
            return u, p, v
        u = ca.diag(ca.DM(self.a)) @ U
        p = ca.horzcat(ca.DM(self.p0), P * self.Lp)
        v = ca.horzcat(ca.DM(self.v0), V * self.v_max)
        return u, p, v

    def sample_operator(
        self, s: np.ndarray
    ) -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix, np.ndarray]:
        """Affine maps from ``vec(W)`` (column-major) to positions and velocities at times ``s``.

        Returns ``(Mp, cp, Mv, cv)`` with ``p(s) - b(s) = reshape(Mp w + cp, (n, J))`` [m] (the
        beacon at ``s`` when it moves on a known path: its offset is in ``cp``) and
        ``v(s) = reshape(Mv w + cv, (n, J))`` [m/s] (the exact quadratic between nodes).

        Parameters
        ----------
        s : ndarray, shape (J,)
            Times [s] from the start, in ``[0, N h]``.

        Returns
        -------
        Mp : scipy.sparse.csc_matrix, shape (n J, 3 n N)
            Positions' linear part [m per intrinsic unit].
        cp : ndarray, shape (n, J)
            Positions' constant part (the fixed start's contribution, less the moving beacon's
            offset ``b(s) - b(0)``) [m].
        Mv : scipy.sparse.csc_matrix, shape (n J, 3 n N)
            Velocities' linear part [m/s per intrinsic unit].
        cv : ndarray, shape (n, J)
            Velocities' constant part [m/s].
        """
        n, N, h = self.n, self.N, self.h
        s = np.asarray(s, float)
        J = s.size
        k = np.clip(np.floor(s / h + 1e-9).astype(int), 0, N - 1)
        sig = s - k * h
        rows_p, cols_p, vals_p = [], [], []
        rows_v, cols_v, vals_v = [], [], []
        cp = np.zeros((n, J))
        cv = np.zeros((n, J))
        for i in range(n):
            r = np.arange(J) * n + i  # row of (i, j) in vec of an (n, J) array
            # input u_k = a_i U[i, k]: column k*3n + i
            cu = k * 3 * n + i
            rows_p.append(r)
            cols_p.append(cu)
            vals_p.append(0.5 * self.a[i] * sig**2)
            rows_v.append(r)
            cols_v.append(cu)
            vals_v.append(self.a[i] * sig)
            # node k: fixed start for k = 0, else P, V of column k-1
            first = k == 0
            cp[i, first] = self.p0[i] + self.v0[i] * sig[first]
            cv[i, first] = self.v0[i]
            later = ~first
            colp = (k[later] - 1) * 3 * n + n + i
            colv = (k[later] - 1) * 3 * n + 2 * n + i
            rows_p += [r[later], r[later]]
            cols_p += [colp, colv]
            vals_p += [np.full(later.sum(), self.Lp), self.v_max * sig[later]]
            rows_v.append(r[later])
            cols_v.append(colv)
            vals_v.append(np.full(later.sum(), self.v_max))
        shape = (n * J, 3 * n * N)
        Mp = sp.csc_matrix(
            (np.concatenate(vals_p), (np.concatenate(rows_p), np.concatenate(cols_p))), shape
        )
        Mv = sp.csc_matrix(
            (np.concatenate(vals_v), (np.concatenate(rows_v), np.concatenate(cols_v))), shape
        )
        if self.beacon_path is not None:
            cp = cp - self.beacon_offset(s)
        return Mp, cp, Mv, cv


def apply_operator(M: sp.csc_matrix, c: np.ndarray, w, n: int):
    """``reshape(M w + c, (n, J))`` for CasADi ``w`` (vec of W) or a numpy vector.

    Parameters
    ----------
    M : scipy.sparse.csc_matrix, shape (n J, 3 n N)
        A linear part of :meth:`Grid.sample_operator`.
    c : ndarray, shape (n, J)
        Its constant part.
    w : ndarray or casadi.MX, shape (3 n N,)
        ``vec(W)``, column-major.
    n : int
        Spatial dimension.

    Returns
    -------
    ndarray or casadi.MX, shape (n, J)
        The sampled positions or velocities (SI, as ``M`` and ``c``).
    """
    J = c.shape[1]
    if isinstance(w, np.ndarray):
        return (M @ w).reshape(J, n).T + c
    return ca.reshape(ca.DM(M) @ w, n, J) + ca.DM(c)


def dynamics_residual(grid: Grid, W):
    """Exact ZOH double integrator residuals in intrinsic units, shape ``(2n, N)``.

    Parameters
    ----------
    grid : Grid
        The planning grid.
    W : casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    casadi.MX, shape (2n, N)
        Position residuals (divided by ``Lp``) over velocity residuals (divided by ``v_max``):
        zero on a path that integrates its inputs exactly.
    """
    u, p, v = grid.si_nodes(W)
    h = grid.h
    rp = (p[:, 1:] - p[:, :-1] - v[:, :-1] * h - 0.5 * h**2 * u) / grid.Lp
    rv = (v[:, 1:] - v[:, :-1] - h * u) / grid.v_max
    return ca.vertcat(rp, rv)


def distance_times(grid: Grid) -> np.ndarray:
    """The times [s] of the distance limits' points: nodes ``1..N``, then the ``N`` interval
    midpoints.

    Parameters
    ----------
    grid : Grid
        The planning grid.

    Returns
    -------
    ndarray, shape (2N,)
        ``t_1..t_N``, then ``t_0 + h/2 .. t_{N-1} + h/2``.
    """
    t = grid.times
    return np.concatenate([t[1:], t[:-1] + grid.h / 2])


def midpoints(grid: Grid, W):
    """SI ``(p - b, v)`` at the interval midpoints, each ``(n, N)``.

    Parameters
    ----------
    grid : Grid
        The planning grid.
    W : ndarray or casadi.MX, shape (3n, N)
        The path's decision variables.

    Returns
    -------
    p : ndarray or casadi expression, shape (n, N)
        Positions relative to the beacon (its start ``b(0)`` when it moves) [m] at
        ``t_k + h / 2``.
    v : ndarray or casadi expression, shape (n, N)
        Velocities [m/s] there.
    """
    u, p, v = grid.si_nodes(W)
    t = 0.5 * grid.h
    return p[:, :-1] + v[:, :-1] * t + 0.5 * u * t**2, v[:, :-1] + u * t
