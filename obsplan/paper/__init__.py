"""The paper's results recomputed: Tables 1–3 and the checked claims of sections 5–7
(:mod:`~obsplan.paper.tables`), and the scenarios of Figs. 1–9 run through the filters
(:mod:`~obsplan.paper.figures`).

Imports the model, trajectory, observability and estimation stages; nothing of planning.
"""
