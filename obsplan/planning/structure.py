"""Structural (input-independent) rank checks used to refuse impossible objectives early."""

from __future__ import annotations

from functools import cache

import numpy as np

from obsplan.model import VehicleModel
from obsplan.observability.gramian import augmented_model, gramian, rank_scales
from obsplan.observability.scaling import numerical_rank
from obsplan.trajectory import Trajectory


@cache
def gramian_generic_rank(model: VehicleModel) -> tuple[int, int]:
    """Rank of the augmented Gramian for a generic (seeded random) input, and its size.

    The Gramian's rank is the same for almost every input, so one random, richly exciting input
    gives the structural rank: a deficit here is a deficit for every input (e.g. an unknown
    current with bottom-lock DVL, section 4.3).

    Returns
    -------
    (rank, state_dim) of the augmented model.
    """
    rng = np.random.default_rng(12345)
    n = model.dim
    t = np.linspace(0.0, 100.0, 41)
    traj = Trajectory.from_inputs(
        t, rng.normal(size=n) * 10, rng.normal(size=n), rng.normal(size=(40, n))
    )
    aug = augmented_model(model)
    return int(numerical_rank(gramian(traj, aug, rank_scales(traj)))), aug.state_dim
