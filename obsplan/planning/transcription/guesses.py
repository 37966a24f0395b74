"""Initial guesses of the planner, the reference path objectives are normalised by, and the
coarse grid a fine problem is first solved on.

* :func:`initial_guesses`: ``objective.starts`` guesses, the lawn-mower and the circle (when they
  fit the limits), then seeded random smooth inputs (:func:`random_guess`); with a mission, its
  two lawn-mowers only (plain and accelerated, at most ``objective.starts``);
* :func:`reference_path`: the first guess (the lawn-mower, or the first guess if it is unfit);
  every objective is divided by its value there, so IPOPT sees an objective of order 1;
* :func:`excited_path`: a seeded random path exciting every axis (the Gramian equilibration's
  second reference);
* :func:`coarse_problem` / :func:`refine`: the coarse-to-fine pass of
  :func:`~obsplan.planning.solver.solve.solve` (grids that nest,
  ``Tuning.coarse_steps``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from obsplan.core.errors import ProblemError
from obsplan.planning.baselines.vehicle import baselines as all_baselines
from obsplan.planning.baselines.vehicle import mission_starts
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory


def random_guess(pb: PlanningProblem, seed: int | Sequence[int]) -> Trajectory:
    """A smooth random input sequence within the acceleration bounds, integrated exactly.

    Per axis, a sum of three sinusoids with random periods (1/8 to 1/2 of the horizon) and
    phases, scaled to 80 % of the bound. Limits other than the inputs are left to the solver.

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its planning grid, start state and acceleration bounds.
    seed : int or sequence of int
        Seed of :func:`numpy.random.default_rng` (the planner passes ``(objective.seed, i)``).

    Returns
    -------
    Trajectory
        On the planning grid ``pb.times``, from the start state.
    """
    rng = np.random.default_rng(seed)
    t = pb.times
    T = pb.horizon.duration
    tm = 0.5 * (t[:-1] + t[1:])
    u = np.zeros((t.size - 1, pb.dim))
    for i in range(pb.dim):
        periods = rng.uniform(T / 8, T / 2, 3)
        phases = rng.uniform(0, 2 * np.pi, 3)
        w = sum(np.sin(2 * np.pi * tm / P + ph) for P, ph in zip(periods, phases, strict=True))
        u[:, i] = 0.8 * pb.accel[i] * w / max(np.max(np.abs(w)), 1e-12)
    return Trajectory.from_inputs(t, pb.p0, pb.v0, u)


def initial_guesses(pb: PlanningProblem) -> list[tuple[str, Trajectory]]:
    """``objective.starts`` guesses: lawn-mower and circle (if they fit), then seeded random;
    with a mission, the lawn-mowers that fly it in the planner's line windows
    (:func:`~obsplan.planning.baselines.vehicle.mission_starts`; random paths are far from every
    line).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: ``objective.starts`` and ``objective.seed``, its baselines or mission.

    Returns
    -------
    list of (str, Trajectory)
        At most ``objective.starts`` named guesses (``"lawnmower"``, ``"circle"``,
        ``"random-0"``, ...), each on the planning grid ``pb.times``.
    """
    if pb.mission is not None:
        out = [(b.name, b.trajectory) for b in mission_starts(pb)]
        if out:
            return out[: pb.objective.starts]
    else:
        fitted = all_baselines(pb)
        out = [(k, fitted[k].trajectory) for k in ("lawnmower", "circle") if k in fitted]
    i = 0
    while len(out) < pb.objective.starts:
        out.append((f"random-{i}", random_guess(pb, (pb.objective.seed, i))))
        i += 1
    return out[: pb.objective.starts]


def reference_path(pb: PlanningProblem) -> Trajectory:
    """The path objectives are normalised by: the lawn-mower (with a mission, on the planner's
    schedule), or the first guess if it is unfit.

    Parameters
    ----------
    pb : PlanningProblem
        The problem.

    Returns
    -------
    Trajectory
        The first of :func:`initial_guesses`, on the planning grid ``pb.times``.
    """
    return initial_guesses(pb)[0][1]


def excited_path(pb: PlanningProblem) -> Trajectory:
    """A seeded random path that excites every axis (the equilibration's second reference).

    Parameters
    ----------
    pb : PlanningProblem
        The problem: its planning grid, start state, acceleration bounds and ``objective.seed``.

    Returns
    -------
    Trajectory
        :func:`random_guess` with the seed ``(objective.seed, 7919)``.
    """
    return random_guess(pb, (pb.objective.seed, 7919))


def coarse_problem(pb: PlanningProblem) -> PlanningProblem | None:
    """The problem on the coarse grid ``N / k <= coarse_steps`` (``k`` the smallest divisor of
    ``N`` that gets there, ``Tuning.coarse_steps``), each start's coarse plan, a path of
    the fine grid too, then that start's fine guess (:func:`refine`); None if N is small or prime,
    or for a mission.

    Parameters
    ----------
    pb : PlanningProblem
        The fine problem (``horizon.steps = N``).

    Returns
    -------
    PlanningProblem or None
        ``pb`` with ``horizon.steps = N / k`` (same duration); None when there is no coarse pass
        (also when the coarse step fails a construction check).
    """
    N = pb.horizon.steps
    coarse_steps = tuning().coarse_steps
    if N <= coarse_steps or pb.mission is not None:
        # a mission's guesses (its lawn-mowers) are feasible and close: measured on the default
        # survey at N = 320 on a loaded machine, 26 s from them directly against 38 s with a
        # coarse pass first (not a controlled comparison: the load varied)
        return None
    for k in range(2, N // 50 + 1):
        if N % k == 0 and N // k <= coarse_steps:
            try:
                coarse = replace(pb, horizon=Horizon(pb.horizon.duration, N // k))
            except ProblemError:  # e.g. the coarse step cannot keep a limit from the start
                return None
            return coarse
    return None


def refine(traj: Trajectory, pb: PlanningProblem) -> Trajectory:
    """A coarse path on the planning grid of ``pb`` (the same path when the grids nest).

    Parameters
    ----------
    traj : Trajectory
        A path on a coarser grid of the same horizon (the coarse plan).
    pb : PlanningProblem
        The fine problem.

    Returns
    -------
    Trajectory
        On ``pb.times``, from the start state, each fine interval holding the input of the
        coarse interval it lies in [m/s²].
    """
    t = pb.times
    mid = 0.5 * (t[:-1] + t[1:])
    k = np.clip(np.searchsorted(traj.t, mid, side="right") - 1, 0, traj.n_samples - 2)
    return Trajectory.from_inputs(t, pb.p0, pb.v0, traj.u[k])
