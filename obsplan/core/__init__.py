"""Infrastructure every stage stands on: errors, files and folders that cannot lose data, signals,
the cost budget, user text files and CSV tables.

Nothing here knows about vehicles, beacons or paths. It imports nothing of obsplan outside
``obsplan.core`` (and :mod:`obsplan.version`).
"""
