"""Planning the beacon: the path of the craft (ASV, ship) carrying the beacon, chosen so that the
vehicle flying a fixed path localises best (:func:`plan_beacon`).

Imports the planning floor (tuning), the solver room (IPOPT's status words and calls), the
estimation stage (the posterior CRB's recursion, epochs, schedules), the model (the craft, beacon
paths) and trajectories; nothing from validation, replanning or results, which use it.
"""

from obsplan.planning.beacon.planner import (
    BeaconPlan,
    BeaconStart,
    beacon_objective,
    circle_guesses,
    flyable_path,
    plan_beacon,
    planning_step,
    range_epoch_times,
    resolve_beacon,
)

__all__ = [
    "BeaconPlan",
    "BeaconStart",
    "beacon_objective",
    "circle_guesses",
    "flyable_path",
    "plan_beacon",
    "planning_step",
    "range_epoch_times",
    "resolve_beacon",
]
