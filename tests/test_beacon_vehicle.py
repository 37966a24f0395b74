"""The planned beacon's craft (:class:`obsplan.model.BeaconVehicle`): its limits are checked once,
where it is made, with the field named."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from obsplan.core.errors import InputError
from obsplan.model import BeaconVehicle


def _craft(**kw):
    base = dict(start=[0.0, 0.0, 0.0], speed=2.0, accel=0.2, velocity=[0.0, 0.0])
    return BeaconVehicle(**(base | kw))


def test_a_scalar_accel_bounds_both_horizontal_axes_and_the_craft_pickles():
    b = _craft(area=[[-50, 50], [-20, 20]], max_range=400.0, min_distance=10.0)
    assert b.dim == 3
    np.testing.assert_array_equal(b.accel, [0.2, 0.2])
    c = pickle.loads(pickle.dumps(b))
    np.testing.assert_array_equal(c.area, b.area)
    assert (c.max_range, c.min_distance) == (400.0, 10.0)
    with pytest.raises(ValueError):
        b.start[0] = 1.0  # frozen arrays: a plan cannot move the craft's start behind its back


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        (dict(speed=0.0), "speed"),
        (dict(accel=[0.2, -0.1]), "accel"),
        (dict(velocity=[3.0, 0.0]), "start velocity"),
        (dict(velocity=[0.0, 0.0, 0.0]), "velocity"),
        (dict(area=[[1, 5], [-5, 5]]), "outside its area"),
        (dict(area=[[5, 1], [-5, 5]]), "area"),
        (dict(max_range=0.0), "max_range"),
        (dict(min_distance=-1.0), "min_distance"),
        (dict(start=[0.0]), "start"),
    ],
)
def test_a_bad_limit_is_refused_naming_it(kw, field):
    with pytest.raises(InputError, match=field):
        _craft(**kw)
