"""Monte Carlo of the filters along a path, open or closed loop: the simulated truth and its
guidance, the runs, their statistics and results, and their figures.

Imports the estimation floor, :mod:`obsplan.estimation.filters` and
:mod:`obsplan.estimation.bounds`.
"""
