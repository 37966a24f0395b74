"""The planning NLP: path constraints, bounds, and the assembly of every block.

``x = (vec(W), objective's lifting variables, parts' variables)`` and
``g = (path constraints, objective's constraints, parts' constraints)``; the path ``W`` and its
constraints come first, so the projection onto the limits (:mod:`obsplan.planning.solver.ipopt`)
uses their leading rows. IPOPT minimises ``f``, the objective normalised on the reference path
(:mod:`obsplan.planning.transcription.blocks`).

Limits on the continuous path
-----------------------------
* Inputs: box bounds. Speed: ``|V_k|² <= 1`` at the nodes, exact because ``|v(t)|²`` is convex on
  an interval of constant acceleration. Area and depth band: node bounds tightened by
  ``a h² / 8``, the largest overshoot of a parabola with ``|p''| <= a`` over an interval ``h``.
* Distance to the beacon and speed through the water are enforced at the nodes and the midpoints
  of the intervals; each point covers ``±τ = h/4`` of the path, over which the distance moves by at
  most ``|v| τ + |a| τ²/2`` and the speed through the water by at most ``|a| τ`` (``|a|`` the norm
  of the per-axis bounds). So ``|p - b| - |v| τ >= r_min + |a| τ²/2`` at those points guarantees
  ``|p(t) - b| >= r_min`` everywhere (similarly for ``r_max`` and ``v_min``); the start is checked
  by the problem's construction (:mod:`obsplan.planning.problem.checks`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from obsplan.planning.objectives.guards import ekf_guard_part, kf_guard_part
from obsplan.planning.objectives.linearisation import linearisation_part
from obsplan.planning.objectives.registry import objective_of
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.transcription.blocks import (
    ConstraintBlock,
    FormulationPart,
    Hessian,
    NLPContext,
    PartBuilder,
    VariableBlock,
)
from obsplan.planning.transcription.grid import (
    Grid,
    distance_times,
    dynamics_residual,
    midpoints,
)
from obsplan.planning.transcription.guesses import reference_path
from obsplan.planning.transcription.mission import mission_part
from obsplan.planning.tuning import tuning
from obsplan.trajectory.sampled import Trajectory

#: Builders of the parts appended to every NLP after the objective, in order (each returns None
#: for a problem it does not apply to): a mission's survey lines with their timing variables, the
#: penalty on the EKF's linearisation stress, the augmented KF's guard.
PARTS: tuple[PartBuilder, ...] = (
    mission_part,
    linearisation_part,
    kf_guard_part,
    ekf_guard_part,
)


@dataclass(frozen=True, eq=False)
class Formulation:
    """The NLP of a problem: symbols, bounds and helpers to pack/unpack and evaluate.

    ``f`` is the objective divided by its magnitude on the reference path and signed so that
    IPOPT minimises it, plus the parts' ``penalty`` (``objective_f`` the same without it, when
    there is one); ``to_objective`` maps the solver's ``f`` without the penalty back to the
    objective.
    ``variables`` and ``constraints`` are the blocks after ``W`` and in ``g``, in order (the path
    constraints first: ``n_path_constraints`` rows, on ``W`` only). ``parameters`` are the
    NLP's parameters (``nlpsol``'s ``p``) with ``parameter_values`` their values; none yet (a
    re-solve from an estimated state will make the start one).
    """

    problem: PlanningProblem
    grid: Grid
    w: ca.MX
    f: ca.MX
    g: ca.MX
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    variables: tuple[VariableBlock, ...]
    constraints: tuple[ConstraintBlock, ...]
    to_objective: Callable[[float], float]  # solver's f -> the objective in the user's units
    hessian: Hessian
    n_path_constraints: int  # the first rows of g: dynamics and limits (no lifting)
    parameters: ca.MX
    parameter_values: np.ndarray
    penalty: ca.MX = field(default_factory=lambda: ca.MX(0.0))
    # f without the penalty, its own graph (the Hessian IPOPT gets need not rely on CasADi
    # cancelling the penalty out of f - penalty); None: f is the objective alone
    objective_f: ca.MX | None = None

    @property
    def n_w(self) -> int:
        return 3 * self.grid.n * self.grid.N

    def pack(self, traj: Trajectory) -> np.ndarray:
        """Initial guess vector from a trajectory on the planning grid.

        Parameters
        ----------
        traj : Trajectory
            A path with ``N + 1`` samples on the planning grid (its start is not read: it is
            fixed).

        Returns
        -------
        ndarray, shape (len(lbx),)
            ``vec(W)`` (column-major, intrinsic units), then each variable block's initial value
            ``init(W)``, in the order of :attr:`variables`.
        """
        W = self.grid.from_trajectory(traj)
        extra = [np.asarray(v.init(W), float).reshape(-1) for v in self.variables]
        return np.concatenate([W.reshape(-1, order="F"), *extra])

    def unpack(self, x: np.ndarray) -> tuple[Trajectory, np.ndarray]:
        """Solution vector to ``(trajectory [SI], variables after W)``.

        Parameters
        ----------
        x : ndarray, shape (len(lbx),)
            A solution (or guess) vector, laid out as :meth:`pack` makes it.

        Returns
        -------
        traj : Trajectory
            The path of ``W`` on the planning grid, from the fixed start: positions [m],
            velocities [m/s], inputs [m/s²].
        extra : ndarray, shape (len(lbx) - n_w,)
            The variables after ``W`` (the objective's lifting variables, then the parts'), as
            the solver returned them.
        """
        x = np.asarray(x, float).reshape(-1)
        n, N = self.grid.n, self.grid.N
        W = x[: self.n_w].reshape(3 * n, N, order="F")
        return self.grid.to_trajectory(W), x[self.n_w :]

    def lifted_value(self, f: float, x: np.ndarray | None = None) -> float:
        """The solver's objective ``f`` in the user's sign and units.

        Parameters
        ----------
        f : float
            The solver's objective value (normalised, minimised, penalty included).
        x : ndarray, shape (len(lbx),), optional
            The solution vector ``f`` was reached at: the parts' penalty there is taken out of
            ``f`` first. Without it ``f`` is taken as the objective alone.

        Returns
        -------
        float
            The objective in its own sign and units (:attr:`to_objective`).
        """
        return float(self.to_objective(float(f) - self.penalty_value(x)))

    def penalty_value(self, x: np.ndarray | None) -> float:
        """The parts' penalty at the solution vector ``x`` (0 without ``x`` or penalty).

        Parameters
        ----------
        x : ndarray, shape (len(lbx),) or None
            A solution vector (:meth:`pack`'s layout).

        Returns
        -------
        float
            The penalty term of ``f`` at ``x`` (normalised like ``f``); 0.0 when ``x`` is None
            or no part adds a penalty.
        """
        if x is None or self.penalty.is_constant():  # no part adds one: the constant 0
            return 0.0
        fn = ca.Function("obsplan_penalty", [self.w, self.parameters], [self.penalty])
        return float(fn(np.asarray(x, float).reshape(-1), self.parameter_values))


def box_bounds(grid: Grid, pb: PlanningProblem) -> tuple[np.ndarray, np.ndarray]:
    """Bounds ``(lbW, ubW)`` of ``W`` ``(3n, N)``: inputs, operating area and depth band.

    Parameters
    ----------
    grid : Grid
        The planning grid: its intrinsic units, step ``h`` [s], input bounds ``a`` [m/s²] and
        beacon [m].
    pb : PlanningProblem
        The problem: ``limits.area`` and ``limits.depth`` (either may be absent).

    Returns
    -------
    lbW, ubW : ndarray, shape (3n, N)
        Lower and upper bounds in intrinsic units: ±1 on the inputs ``U``; on the positions
        ``P`` the area and depth band tightened by ``a h² / 8`` (so the path between nodes stays
        inside); ``-inf`` / ``inf`` elsewhere (the speed is a constraint, not a bound).
    """
    n, N = grid.n, grid.N
    lim = pb.limits
    lbW = np.full((3 * n, N), -np.inf)
    ubW = np.full((3 * n, N), np.inf)
    lbW[:n] = -1.0
    ubW[:n] = 1.0
    # area / depth: node bounds tightened by the parabola's overshoot a h^2 / 8
    margin = grid.a * grid.h**2 / 8.0
    boxes: list[tuple[int, tuple[float, float]]] = []
    if lim.area is not None:
        boxes += [(0, lim.area.x), (1, lim.area.y)]
    if lim.depth is not None:
        boxes.append((2, lim.depth))
    for axis, (lo, hi) in boxes:
        b = grid.beacon[axis]
        lbW[n + axis] = (lo - b + margin[axis]) / grid.Lp
        ubW[n + axis] = (hi - b - margin[axis]) / grid.Lp
    return lbW, ubW


def path_constraints(grid: Grid, pb: PlanningProblem, Wsym) -> list[ConstraintBlock]:
    """Dynamics and limit constraints of ``W`` (module docstring), in intrinsic units.

    Parameters
    ----------
    grid : Grid
        The planning grid.
    pb : PlanningProblem
        The problem: its ``limits`` (ranges, minimum speed) and water current.
    Wsym : casadi.MX, shape (3n, N)
        The symbolic path ``W``.

    Returns
    -------
    list of ConstraintBlock
        In order: ``dynamics`` (``2 n N`` equalities), ``speed`` (``|V_k|² <= 1`` at the ``N``
        nodes), then, when the limit is set, ``min_range`` and ``max_range`` (distance to the
        beacon divided by ``Lp``) and ``min_speed`` (speed through the water squared over
        ``v_max²``), each at nodes ``1..N`` then the ``N`` interval midpoints, with the margins
        of the module docstring.
    """
    n, N = grid.n, grid.N
    lim = pb.limits
    zeros = np.zeros(2 * n * N)
    out = [ConstraintBlock("dynamics", ca.vec(dynamics_residual(grid, Wsym)), zeros, zeros.copy())]
    V = Wsym[2 * n :, :]
    # exact: |v(t)|^2 is convex between nodes
    out.append(ConstraintBlock("speed", ca.sum1(V**2).T, np.full(N, -np.inf), np.ones(N)))

    _, p, v = grid.si_nodes(Wsym)
    pm, vm = midpoints(grid, Wsym)
    pts_p = ca.horzcat(p[:, 1:], pm)
    if grid.beacon_path is not None:  # relative to the beacon where it is at each point
        pts_p = pts_p - ca.DM(grid.beacon_offset(distance_times(grid)))
    pts_v = ca.horzcat(v[:, 1:], vm)
    tau = grid.h / 4.0
    a_norm = float(np.linalg.norm(grid.a))
    K = 2 * N
    if lim.min_range > 0 or lim.max_range is not None:
        dist = ca.sqrt(ca.sum1(pts_p**2))
        # the smooth |v| (a squared-speed floor, Tuning.speed_eps): the margin is conservative
        # by at most τ sqrt(eps) v_max
        spd = ca.sqrt(ca.sum1(pts_v**2) + tuning().speed_eps * grid.v_max**2)
        slack = 0.5 * a_norm * tau**2
        L = grid.Lp
        if lim.min_range > 0:
            lo = np.full(K, (lim.min_range + slack) / L)
            g = ((dist - spd * tau) / L).T
            out.append(ConstraintBlock("min_range", g, lo, np.full(K, np.inf)))
        if lim.max_range is not None:
            hi = np.full(K, (lim.max_range - slack) / L)
            g = ((dist + spd * tau) / L).T
            out.append(ConstraintBlock("max_range", g, np.full(K, -np.inf), hi))
    if lim.min_speed > 0:
        w = pts_v - ca.repmat(ca.DM(pb.current_array), 1, K)
        lo = np.full(K, ((lim.min_speed + a_norm * tau) / grid.v_max) ** 2)
        g = (ca.sum1(w**2) / grid.v_max**2).T
        out.append(ConstraintBlock("min_speed", g, lo, np.full(K, np.inf)))
    return out


def _hessian(objective: Hessian, built: Sequence[FormulationPart]) -> Hessian:
    """The NLP's Hessian mode: the objective's, except with a penalty part. An exact objective
    Hessian then leaves out the penalty's curvature (``exact-without-penalty``), unless the part
    is an estimator's guard: its penalty is a function of the whole path's covariance (the
    mission mean and final std), not of a few epochs, and without its curvature the KF-guarded
    ``lwo-condition`` re-solves stopped at the iteration limit where a limited-memory Hessian
    converges (docs/problem-files.md, "The estimators' guards")."""
    names = {part.name for part in built if part.penalty is not None}
    if not names or objective != "exact":
        return objective
    guarded = names & {"kf_guard", "ekf_guard"}
    return "limited-memory" if guarded else "exact-without-penalty"


def build_formulation(pb: PlanningProblem, parts: Sequence[PartBuilder] = PARTS) -> Formulation:
    """Assemble the NLP (variables, objective, constraints, bounds) of ``pb``.

    The objective is the registered one of ``pb.objective.kind``
    (:data:`obsplan.planning.objectives.registry.REGISTRY`), normalised by its value on
    :func:`~obsplan.planning.transcription.guesses.reference_path` (the lawn-mower); ``parts`` are
    appended after it (default :data:`PARTS`).

    Parameters
    ----------
    pb : PlanningProblem
        The problem.
    parts : sequence of PartBuilder, optional
        Builders of the parts appended after the objective, in order; a builder returning None
        adds nothing. Default :data:`PARTS`.

    Returns
    -------
    Formulation
        Symbols, bounds and blocks of the NLP. Its Hessian is the objective's, except that an
        exact one leaves out the parts' penalty's curvature (``exact-without-penalty``): that
        penalty's exact Hessian is dense and can exhaust memory; with the KF guard's penalty
        it is limited-memory (:func:`_hessian`).
    """
    grid = Grid.from_problem(pb)
    n, N = grid.n, grid.N
    Wsym = ca.MX.sym("W", 3 * n, N)
    lbW, ubW = box_bounds(grid, pb)
    path = path_constraints(grid, pb, Wsym)
    reference = reference_path(pb)
    built: list[FormulationPart] = [
        part for build in parts if (part := build(pb, grid, Wsym)) is not None
    ]
    ctx = NLPContext(
        problem=pb,
        grid=grid,
        W=Wsym,
        reference=reference,
        W_ref=grid.from_trajectory(reference),
        parts={part.name: part for part in built},
    )
    term = objective_of(pb).nlp(ctx)
    variables = (*term.variables, *(v for part in built for v in part.variables))
    constraints = (*path, *term.constraints, *(c for part in built for c in part.constraints))
    penalties = [part.penalty for part in built if part.penalty is not None]
    penalty = sum(penalties[1:], penalties[0]) if penalties else ca.MX(0.0)
    return Formulation(
        problem=pb,
        grid=grid,
        w=ca.vertcat(ca.vec(Wsym), *(v.sym for v in variables)),
        f=term.f + penalty,
        g=ca.vertcat(*(c.g for c in constraints)),
        lbx=np.concatenate([lbW.reshape(-1, order="F"), *(v.lb for v in variables)]),
        ubx=np.concatenate([ubW.reshape(-1, order="F"), *(v.ub for v in variables)]),
        lbg=np.concatenate([c.lb for c in constraints]),
        ubg=np.concatenate([c.ub for c in constraints]),
        variables=variables,
        constraints=constraints,
        to_objective=term.to_objective,
        # a penalty's covariance recursion has a dense exact Hessian (a 3D DVL problem ran out of
        # 24 GB building it): the objective's and constraints' exact one without the penalty's
        # curvature then (its gradient is exact). L-BFGS instead left lwo-condition at
        # Maximum_Iterations at N = 1000 (benchmarks/bench_gramian_objectives.py)
        hessian=_hessian(term.hessian, built),
        n_path_constraints=int(sum(c.size for c in path)),
        parameters=ca.MX.sym("p", 0),
        parameter_values=np.zeros(0),
        penalty=penalty,
        objective_f=term.f if penalties else None,
    )
