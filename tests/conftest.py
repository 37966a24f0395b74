"""Fixtures shared by the planner's tests."""

from __future__ import annotations

from dataclasses import replace

import pytest

from obsplan.planning import load_problem
from obsplan.planning.baselines.vehicle import baselines
from obsplan.planning.problem.parse import LOCALISE_PROBLEM
from obsplan.planning.problem.sections import Horizon


@pytest.fixture(scope="session")
def short_problem():
    """The free-localisation problem on a 120 s horizon of 40 steps."""
    pb = load_problem(LOCALISE_PROBLEM)
    return replace(pb, horizon=Horizon(duration=120.0, steps=40))


@pytest.fixture(scope="session")
def lawnmower(short_problem):
    """The lawn-mower baseline of :func:`short_problem`."""
    return baselines(short_problem)["lawnmower"].trajectory
