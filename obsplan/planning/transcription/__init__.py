"""The planning problem as an NLP's pieces: the grid of decision variables and the exact path they
describe (:mod:`~.grid`), initial guesses (:mod:`~.guesses`), the building blocks and the
objective interface (:mod:`~.blocks`), and the mission's constraints (:mod:`~.mission`).

Imports the problem, missions and baselines rooms.
"""
