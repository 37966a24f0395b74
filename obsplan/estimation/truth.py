"""Truth simulation: the vehicle along a trajectory, perturbed by process noise, and its readings.

The truth of run ``r`` at sample ``k`` is ``x_k = x̄_k + δ_k`` where ``x̄`` is the trajectory's state
(``p``, ``v = p' - v_f``, ``v_f``) and ``δ_{k+1} = F_k δ_k + w_k``, ``w_k ~ N(0, Q)`` (exact ZOH
``F_k``): with no process noise the truth is the trajectory itself. Readings are the device
quantities (range ``r`` [m], DVL [m/s], depth [m]) plus Gaussian noise, drawn only where the
schedule says the sensor reports. Every run has its own random stream, spawned from one seed,
so run ``r`` is the same whatever the number of runs; noise is drawn in chunks, not per step.
"""

from __future__ import annotations

import numpy as np

from obsplan.estimation.schedule import Schedule
from obsplan.estimation.sensors import true_readings
from obsplan.model import VehicleModel
from obsplan.trajectory import Trajectory

CHUNK = 1024


def nominal_states(traj: Trajectory, model: VehicleModel, current: np.ndarray) -> np.ndarray:
    """Noise-free true states ``(p, v[, v_f])`` along ``traj``, shape (N, state_dim)."""
    parts = [traj.p, traj.v - current] if model.current else [traj.p, traj.v]
    if model.current:
        parts.append(np.broadcast_to(current, traj.p.shape))
    return np.hstack(parts)


def run_generators(seed: int, runs: int) -> list[np.random.Generator]:
    """One independent generator per run, spawned from ``seed``."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)]


def _factor(Q: np.ndarray) -> np.ndarray:
    """``L`` with ``L Lᵀ = Q`` for a PSD (possibly singular) ``Q``."""
    lam, V = np.linalg.eigh(0.5 * (Q + Q.T))
    return V * np.sqrt(np.clip(lam, 0.0, None))


class TruthSimulator:
    """Batched truth and readings, advanced one sample at a time.

    Parameters
    ----------
    traj, model
        The path and the vehicle model (sensors, current, beacon).
    current
        True current ``v_f`` [m/s], shape (n,).
    q
        Per-step process-noise covariance (state_dim²) or ``None`` for no process noise.
    noise
        Standard deviation per sensor (range [m], DVL [m/s], depth [m]).
    schedule
        When each sensor reports.
    gens
        One generator per run.
    dropout
        Probability per sensor that a scheduled reading is missing (never the range at ``k = 0``).
    """

    def __init__(
        self,
        traj: Trajectory,
        model: VehicleModel,
        current: np.ndarray,
        q: np.ndarray | None,
        noise: dict[str, float],
        schedule: Schedule,
        gens: list[np.random.Generator],
        dropout: dict[str, float] | None = None,
    ) -> None:
        self.traj, self.model, self.schedule, self.gens = traj, model, schedule, gens
        self.noise = noise
        self.dropout = dropout or {}
        self.nominal = nominal_states(traj, model, current)
        self.R, self.m = len(gens), model.state_dim
        self.L = None if q is None or not np.any(q) else _factor(q)
        self.delta = np.zeros((self.R, self.m))
        self._widths = {s: (model.dim if s.startswith("dvl") else 1) for s in model.sensors}
        self._nmeas = sum(self._widths.values())
        self._chunk_start = -1
        self._F: dict[float, np.ndarray] = {}
        self._w: np.ndarray | None = None
        self._e: np.ndarray | None = None
        self._u: np.ndarray | None = None

    def _draw(self, k: int) -> None:
        size = min(CHUNK, self.traj.n_samples - k)
        ns = len(self.model.sensors)
        w, e, u = [], [], []
        for g in self.gens:
            w.append(g.standard_normal((size, self.m)) if self.L is not None else None)
            e.append(g.standard_normal((size, self._nmeas)))
            u.append(g.random((size, ns)) if self.dropout else None)
        self._w = np.stack(w, axis=1) if self.L is not None else None
        self._e = np.stack(e, axis=1)
        self._u = np.stack(u, axis=1) if self.dropout else None
        self._chunk_start = k

    def state(self, k: int) -> np.ndarray:
        """True states at sample ``k``, shape (R, state_dim) (call with k = 0, 1, 2, ...)."""
        return self.nominal[k] + self.delta

    def readings(self, k: int) -> dict[str, np.ndarray]:
        """Noisy readings of the sensors that report at sample ``k`` (NaN where dropped)."""
        if k == 0 or k - self._chunk_start >= CHUNK:
            self._draw(k)
        j = k - self._chunk_start
        x = self.state(k)
        clean = true_readings(self.model, x)
        out: dict[str, np.ndarray] = {}
        col = 0
        for i, s in enumerate(self.model.sensors):
            wdt = self._widths[s]
            if self.schedule.mask[k, i]:
                val = clean[s] + self.noise[s] * self._e[j, :, col : col + wdt]
                p = self.dropout.get(s, 0.0)
                if p > 0 and not (s == "range" and k == 0):
                    val[self._u[j, :, i] < p] = np.nan
                out[s] = val
            col += wdt
        return out

    def advance(self, k: int) -> None:
        """Move the perturbation from sample ``k`` to ``k + 1``."""
        if self.L is None:
            return
        dt = float(self.traj.t[k + 1] - self.traj.t[k])
        F = self._F.get(dt)
        if F is None:
            F = self._F.setdefault(dt, self.model.transition(dt)[0])
        j = k - self._chunk_start
        self.delta = self.delta @ F.T + self._w[j] @ self.L.T
