"""Monte Carlo runs sharded over Dask workers, merged exactly.

Run ``i`` of a Monte Carlo draws from its own stream of the seed (independent of how many runs
are done, and where), so runs ``0 .. n-1`` split into contiguous shards ``[start, start + k)``
compute exactly the runs of the unsharded call; the statistics are merged from their sums
(:func:`obsplan.estimation.montecarlo.simulate.merge_monte_carlo`), not as means of means, so the
merged result equals the unsharded one to round-off.
"""

from __future__ import annotations

from typing import Any


def shard_bounds(runs: int, shards: int) -> list[tuple[int, int]]:
    """``(run_start, runs)`` of ``shards`` contiguous shards covering ``runs`` runs, sizes
    differing by at most one (empty shards dropped).

    Parameters
    ----------
    runs : int
        Monte Carlo runs in all, at least 1.
    shards : int
        Number of shards, at least 1.

    Returns
    -------
    list of (int, int)
        ``(run_start, runs)`` of each non-empty shard, in run order; the larger shards first.

    Raises
    ------
    InputError
        If ``runs`` or ``shards`` is below 1.
    """
    if runs < 1 or shards < 1:
        from obsplan.core.errors import InputError

        raise InputError(f"runs and shards must be at least 1, got {runs} and {shards}")
    base, extra = divmod(runs, shards)
    out, start = [], 0
    for i in range(shards):
        k = base + (i < extra)
        if k:
            out.append((start, k))
        start += k
    return out


def sharded_monte_carlo(traj, config, runs: int, seed: int, shards: int, client: Any, **kwargs):
    """:func:`~obsplan.estimation.montecarlo.simulate.monte_carlo` of ``runs`` runs split into
    ``shards`` tasks on the Dask ``client``, merged exactly.

    Parameters
    ----------
    traj : Trajectory
        The truth path (sent once to the cluster).
    config : EstimationConfig
    runs, seed
        As for ``monte_carlo``: the result equals ``monte_carlo(traj, config, runs, seed)``.
    shards
        Number of tasks.
    client : distributed.Client
    **kwargs
        Passed to every shard's ``monte_carlo`` (e.g. ``filters=("kf",)``).

    Returns
    -------
    MonteCarloResult
    """
    from obsplan.estimation.montecarlo.simulate import merge_monte_carlo, monte_carlo

    traj_f, config_f = client.scatter([traj, config], broadcast=False)
    futures = [
        client.submit(
            monte_carlo,
            traj_f,
            config_f,
            runs=k,
            seed=seed,
            run_start=start,
            progress=False,
            pure=False,
            **kwargs,
        )
        for start, k in shard_bounds(runs, shards)
    ]
    return merge_monte_carlo(client.gather(futures))
