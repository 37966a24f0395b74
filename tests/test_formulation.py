"""The NLP's extension points: parts appended after the objective, objective terms by registry.

Other modules (missions with per-line timing variables, covariance-dependent margins) add
variables and constraints through :class:`~obsplan.planning.transcription.blocks.FormulationPart`;
these tests pin where they go and that the solver, the packing of guesses and the projection still
see the path first.
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from obsplan.planning import load_problem
from obsplan.planning.objectives.guards import ekf_guard_part, kf_guard_part
from obsplan.planning.objectives.linearisation import linearisation_part
from obsplan.planning.objectives.registry import REGISTRY
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.sections import Horizon
from obsplan.planning.solver.formulation import PARTS, build_formulation
from obsplan.planning.transcription.blocks import ConstraintBlock, FormulationPart, VariableBlock
from obsplan.planning.transcription.grid import Grid
from obsplan.planning.transcription.guesses import reference_path
from obsplan.planning.transcription.mission import mission_part


def _problem(kind: str):
    pb = load_problem(LOCALISE_PROBLEM)
    return replace(
        pb,
        horizon=Horizon(duration=pb.horizon.duration, steps=12),
        objective=replace(pb.objective, kind=kind, starts=1),
    )


def _part(pb, grid, W):
    """Two variables ``s``, ``s_0 = mean(U_x)`` and ``s_1 >= 0``: a constraint that uses both."""
    s = ca.MX.sym("s", 2)
    g = s[0] - ca.sum2(W[0, :]) / grid.N
    var = VariableBlock("s", s, np.array([-1.0, 0.0]), np.array([1.0, np.inf]), _init)
    return FormulationPart("test", (var,), (ConstraintBlock("mean", g, np.zeros(1), np.zeros(1)),))


def _init(W):
    return np.array([W[0].mean(), 0.5])


@pytest.mark.parametrize("kind", ["gramian-log-det", "lwo-condition", "kf-position-std"])
def test_a_part_is_appended_after_the_objective(kind):
    pb = _problem(kind)
    plain = build_formulation(pb)
    form = build_formulation(pb, parts=(_part, lambda pb, grid, W: None))
    assert PARTS == (mission_part, linearisation_part, kf_guard_part, ekf_guard_part)
    # a mission's constraints: None without a [mission]
    assert mission_part(pb, Grid.from_problem(pb), ca.MX.sym("W", 3 * pb.dim, 4)) is None
    # variables: the path, the objective's lifting, then the part's two
    n_plain = plain.w.numel()
    assert form.w.numel() == n_plain + 2
    assert np.array_equal(form.lbx[:n_plain], plain.lbx)
    assert np.array_equal(form.lbx[n_plain:], [-1.0, 0.0])
    # constraints: the path constraints first, then the objective's, then the part's one
    assert form.n_path_constraints == plain.n_path_constraints
    assert form.g.numel() == plain.g.numel() + 1
    assert [c.name for c in form.constraints][-1] == "mean"
    # a guess is packed with every block's initial values, in order
    ref = reference_path(pb)
    x0 = form.pack(ref)
    assert x0.size == form.w.numel()
    assert np.array_equal(x0[:n_plain], plain.pack(ref))
    W = form.grid.from_trajectory(ref)
    assert x0[-2:] == pytest.approx(_init(W))
    # and the part's constraint evaluates on that vector as built
    g = ca.Function("g", [form.w], [form.g])(x0)
    assert float(g[-1]) == pytest.approx(0.0, abs=1e-12)  # s_0 is initialised at mean(U_x)
    _, rest = form.unpack(x0)
    assert rest.size == form.w.numel() - form.n_w


@pytest.mark.parametrize("kind", ["lwo-condition", "kf-position-std"])
def test_a_term_is_normalised_on_the_reference_path(kind):
    # the objectives without lifting variables: f is exactly 1 on the reference path (so IPOPT
    # sees an objective of order 1) and to_objective maps it back to the numeric value there.
    # (The lifted Gramian objectives start their lifting off its optimum, e.g. min-eig's t at
    # half of lambda_min, so their f at a packed guess is not the objective.)
    pb = _problem(kind)
    form = build_formulation(pb)
    ref = reference_path(pb)
    # (f - penalty: the linearisation penalty is not the objective's)
    f = float(ca.Function("f", [form.w], [form.f - form.penalty])(form.pack(ref)))
    # tolerances: the same floating-point operations in another order (CasADi against numpy)
    assert f == pytest.approx(1.0, rel=1e-12)
    assert form.lifted_value(f) == pytest.approx(REGISTRY[kind].value(ref, pb), rel=1e-9)
