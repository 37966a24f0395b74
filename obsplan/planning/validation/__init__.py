"""How every verdict is earned: the Monte Carlo of the filters on each path under identical
conditions (:mod:`~.validate`), the plan against each baseline with confidence and in words
(:mod:`~.verdict`), and the robustness row (:mod:`~.stress`).

Imports the objectives (for the paths' metrics), problem and missions rooms, and the estimation
stage; never the solver.
"""
