"""What a mission asks of a path in time: the ``[mission]`` itself (:mod:`~.spec`), the plain
lawn-mower's constant-speed schedule (:mod:`~.schedule`), the order of free lines
(:mod:`~.order`), the independent check that a path completes it (:mod:`~.check`) and the
schedule flown on the planning grid (:mod:`~.lawnmower`).

Mission functions take what they use, a :class:`~obsplan.planning.missions.spec.MissionContext`
(the mission, the start, the limits and the horizon), never a whole problem: the problem, one
floor up, holds a mission. Imports the model, the trajectory stage, the core and the planning
stage's floor (:mod:`obsplan.planning.tuning`) only.
"""
