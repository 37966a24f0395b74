"""Solving the NLP: the formulation (:mod:`~.formulation`), IPOPT (:mod:`~.ipopt`), one run per
start (:mod:`~.starts`), the multi-start strategy (:mod:`~.solve`), and keep-out margins that the
*true* vehicle keeps, with the re-solves they need (:mod:`~.margins`).

Imports the objectives, transcription, baselines, problem and missions rooms.
"""
