"""The vehicle's motion relative to a moving beacon, as a trajectory of its own.

With ``r = p - b`` the range depends on ``r`` alone and ``r'' = u - b''``: the vehicle seen from
the beacon is again a double integrator, driven by ``u - b''``, ranging to a beacon fixed at the
origin. Every observability test of a fixed beacon therefore applies to the relative trajectory
unchanged; these two functions build it for the two tests (why two: :mod:`obsplan.model.beacon`).

* :func:`relative_samples` (the LWO rank test): at the trajectory's own samples,
  ``(t, p - b, ν - b', u - b'')`` with ``b'``, ``b''`` the smooth-path estimates of
  :meth:`~obsplan.model.beacon.BeaconPath.derivative_estimates`.
* :func:`relative_trajectory` (the augmented Gramian): exact for the piecewise-linear beacon
  path. Its samples are the trajectory's and the beacon's knots inside its span; at an inserted
  knot the vehicle's state is the exact integral of its held input. Between two samples the
  beacon moves at constant velocity, so the relative input is the held ``u`` and the relative
  velocity jumps at each knot by the change of the beacon's velocity (the impulse of ``b''``).
  The Gramian's closed form reads ``d`` and ``e`` from positions and velocities
  (``gramian.py``): the jumps are inside them, exactly.

The velocity columns of these trajectories are relative velocities, ``ν - b'``; with an unknown
current the observability tests evaluate the range rows at ``ν = v + v_f`` only (``lwo.py``,
``gramian.py``), so the current needs nothing more.
"""

from __future__ import annotations

import numpy as np

from obsplan.core.errors import InputError
from obsplan.model.beacon import BeaconPath
from obsplan.trajectory.sampled import Trajectory


def _check(traj: Trajectory, path: BeaconPath, where: str) -> None:
    if path.dim != traj.dim:
        raise InputError(
            f"{where}: the beacon path is {path.dim}D but the trajectory is {traj.dim}D; give "
            f"{'t,bx,by,bz' if traj.dim == 3 else 't,bx,by'}"
        )
    path.check_covers(float(traj.t[0]), float(traj.t[-1]), where)


def relative_samples(traj: Trajectory, path: BeaconPath, where: str = "beacon path") -> Trajectory:
    """The trajectory relative to the beacon at its own samples, with the beacon's smooth-path
    derivatives: ``(t, p - b(t), ν - b'(t), u - b''(t))``.

    Parameters
    ----------
    traj : Trajectory
        The vehicle's sampled path (positions [m], inertial velocities [m/s], held inputs
        [m/s²]).
    path : BeaconPath
        The beacon's path, covering ``traj``'s time span.
    where : str, optional
        What gave the path, first in an error message.

    Returns
    -------
    Trajectory
        ``N`` samples at ``traj.t``: relative positions [m], velocities [m/s], accelerations
        [m/s²].

    Raises
    ------
    InputError
        A path of another dimension, or one that does not cover ``traj``.
    """
    _check(traj, path, where)
    vb, ab = path.derivative_estimates(traj.t)
    return Trajectory(t=traj.t, p=traj.p - path.position(traj.t), v=traj.v - vb, u=traj.u - ab)


def relative_trajectory(
    traj: Trajectory, path: BeaconPath, where: str = "beacon path"
) -> tuple[Trajectory, np.ndarray]:
    """The trajectory relative to the piecewise-linear beacon path, exact, on the union of its
    samples and the path's knots.

    Parameters
    ----------
    traj : Trajectory
        The vehicle's sampled path (positions [m], inertial velocities [m/s], held inputs
        [m/s²]).
    path : BeaconPath
        The beacon's path, covering ``traj``'s time span.
    where : str, optional
        What gave the path, first in an error message.

    Returns
    -------
    relative : Trajectory
        ``N + K`` samples (``K`` knots strictly inside the span and not at a sample): relative
        positions ``p - b`` [m], relative velocities ``ν - b'`` [m/s] (``b'`` of the segment
        starting at the sample), the held inputs ``u`` [m/s²].
    samples : ndarray of int, shape (N,)
        Index in ``relative`` of each sample of ``traj``.

    Raises
    ------
    InputError
        A path of another dimension, or one that does not cover ``traj``.
    """
    _check(traj, path, where)
    knots = np.setdiff1d(path.knots_within(float(traj.t[0]), float(traj.t[-1])), traj.t)
    t = np.union1d(traj.t, knots)
    k = np.searchsorted(traj.t, t, side="right") - 1  # the held interval of each time
    s = (t - traj.t[k])[:, None]  # exactly 0 at the trajectory's own samples
    p = traj.p[k] + traj.v[k] * s + 0.5 * traj.u[k] * s**2
    v = traj.v[k] + traj.u[k] * s
    rel = Trajectory(t=t, p=p - path.position(t), v=v - path.velocity(t), u=traj.u[k])
    return rel, np.searchsorted(t, traj.t)
