"""The one interface of the Monte Carlo's filters, and their registry.

Every filter (:mod:`~obsplan.estimation.filters.ekf`, :mod:`~obsplan.estimation.filters.kf`,
:mod:`~obsplan.estimation.filters.gsf`) is a :class:`Filter`: built from a configuration
(:meth:`Filter.from_config`), it turns a run's common start into its own initial state
(:meth:`Filter.start`) and filters a batch of runs, a :class:`~obsplan.estimation.batch.RunBatch`
(the epochs of a :class:`~obsplan.estimation.epochs.RunContext`, the runs' starts and readings),
either in one compiled call with the statistics (:meth:`Filter.run`, what the Monte Carlo uses,
into a :class:`~obsplan.estimation.batch.RunRecord`) or epoch by epoch (:meth:`Filter.begin`,
then :meth:`Filter.predict` / :meth:`Filter.update`, with :meth:`Filter.state` and
:meth:`Filter.covariance` at any epoch). Both paths call the same kernels
(:mod:`obsplan.estimation.kernels`) through the same argument bundles
(:mod:`obsplan.estimation.filters.bundles`).

A filter class registers itself under its :attr:`Filter.name` with :func:`register`;
:func:`make_filter` builds one by name from :data:`REGISTRY`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import numpy as np

from obsplan.core.errors import ConfigError
from obsplan.estimation.batch import RunBatch, RunRecord
from obsplan.estimation.config import EstimationConfig, ProcessNoise
from obsplan.estimation.epochs import RunContext
from obsplan.model.vehicle import VehicleModel


@dataclass(eq=False)
class FilterRun:
    """A batch of runs being filtered epoch by epoch (:meth:`Filter.begin`); mutated in place.

    Attributes
    ----------
    ctx
        The epochs and records of the runs.
    Y : (E, outputs, R)
        The readings at the epochs (NaN: no report).
    X : (m, B), P : (m, m, B)
        The members' states and covariances (``B = R G``: ``G`` members per run).
    lw : (B,)
        The members' log weights (``G > 1``: a Gaussian sum).
    G : int
        Members per run.
    epoch : int
        The epoch the state is at; ``updated`` whether its readings are applied.
    run_nis, run_cnt : (R,)
        Each run's sum of normalised innovations squared and their number.
    rg : (4, R)
        Each run's range gate counters (:func:`obsplan.estimation.kernels.gate_rows`).
    parts : dict
        The kernels' bundles and work arrays (filter-specific).
    """

    ctx: RunContext
    Y: np.ndarray
    X: np.ndarray
    P: np.ndarray
    lw: np.ndarray
    G: int
    parts: dict[str, Any]
    epoch: int = 0
    updated: bool = False
    run_nis: np.ndarray | None = None
    run_cnt: np.ndarray | None = None
    rg: np.ndarray | None = None


class Filter(ABC):
    """A filter of the Monte Carlo (module docstring).

    Attributes
    ----------
    name : str
        Registry key (``"ekf"``, ``"kf"``, ``"gsf"``).
    description : str
        One line for the CLI's help.
    model : VehicleModel
    state_dim : int
        Size of the filter's own state (:meth:`state`).
    """

    name: ClassVar[str]
    description: ClassVar[str]
    model: VehicleModel
    state_dim: int

    @classmethod
    @abstractmethod
    def from_config(
        cls, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise
    ) -> Filter:
        """The filter of ``config`` (priors ``cov``, process noise ``pn``).

        Parameters
        ----------
        config : EstimationConfig
            The model, sensor noises and filter options.
        cov : dict of str to ndarray
            Initial covariances ``p0_ekf``, ``p0_kf`` (:meth:`EstimationConfig.covariances
            <obsplan.estimation.config.EstimationConfig.covariances>`).
        pn : ProcessNoise
            Process noise: per-step covariances or intensities, as the epoch plan it runs on.

        Returns
        -------
        Filter
            The filter.
        """

    @abstractmethod
    def start(
        self, xhat0: np.ndarray, extra0: np.ndarray | None = None, r0: float | None = None
    ) -> tuple:
        """A run's initial filter state from the common start ``(x̂0, extra0, r0)``.

        Parameters
        ----------
        xhat0 : ndarray, shape (state_dim of the model,)
            Initial estimate of ``(p, v[, v_f])`` [m, m/s] (absolute positions).
        extra0 : ndarray, shape (2,), optional
            Initial estimates of ``(p0ᵀν0, |ν0|²)`` (the augmented KF's extra states).
        r0 : float, optional
            Range reading at the first sample [m] (the augmented KF's anchor ``y0``).

        Returns
        -------
        tuple
            The filter's own initial state of the run (its form is the filter's).
        """

    @abstractmethod
    def run(self, batch: RunBatch, record: RunRecord) -> None:
        """Filter ``batch`` over all its epochs in one compiled call, adding the statistics to
        ``record`` (:meth:`ExtendedKalmanFilter.run
        <obsplan.estimation.filters.ekf.ExtendedKalmanFilter.run>`).

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`), readings and, in
            closed loop, input corrections.
        record : RunRecord
            The truth at the records and the arrays the statistics are written into.
        """

    @abstractmethod
    def begin(self, batch: RunBatch) -> FilterRun:
        """The runs of ``batch`` (states from :meth:`start`) at epoch 0, before its update.

        Parameters
        ----------
        batch : RunBatch
            The runs' shared epochs, initial states (from :meth:`start`) and readings.

        Returns
        -------
        FilterRun
            The runs at epoch 0, not yet updated.
        """

    @abstractmethod
    def predict(self, run: FilterRun) -> None:
        """Predict ``run`` to its next epoch (exact composed prediction over the segment).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).
        """

    @abstractmethod
    def update(self, run: FilterRun) -> None:
        """Update ``run`` with the readings of its current epoch (once per epoch).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).
        """

    def state(self, run: FilterRun) -> np.ndarray:
        """The runs' estimates in the filter's state, ``(state_dim, R)`` (a Gaussian sum: its
        mixture's mean).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered.

        Returns
        -------
        ndarray, shape (state_dim, R)
            The estimates (a copy).
        """
        return _mixture(run)[0]

    def covariance(self, run: FilterRun) -> np.ndarray:
        """The runs' covariances, ``(state_dim, state_dim, R)`` (a Gaussian sum: its mixture's,
        the spread of the means included).

        Parameters
        ----------
        run : FilterRun
            The runs being filtered.

        Returns
        -------
        ndarray, shape (state_dim, state_dim, R)
            The covariances (a copy).
        """
        return _mixture(run)[1]

    def filter_all(self, run: FilterRun) -> FilterRun:
        """Update at the current epoch, then predict and update at every later one.

        Parameters
        ----------
        run : FilterRun
            The runs being filtered (mutated in place).

        Returns
        -------
        FilterRun
            ``run``, at the last epoch and updated.
        """
        if not run.updated:
            self.update(run)
        while run.epoch + 1 < run.ctx.plan.seg_tab.shape[0]:
            self.predict(run)
            self.update(run)
        return run


def _mixture(run: FilterRun) -> tuple[np.ndarray, np.ndarray]:
    m, B = run.X.shape
    G = run.G
    if G == 1:
        return run.X.copy(), run.P.copy()
    lw = run.lw.reshape(B // G, G)
    w = np.exp(lw - lw.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    X = run.X.reshape(m, B // G, G)
    P = run.P.reshape(m, m, B // G, G)
    mean = np.einsum("rg,irg->ir", w, X)
    dx = X - mean[:, :, None]
    cov = np.einsum("rg,ijrg->ijr", w, P) + np.einsum("rg,irg,jrg->ijr", w, dx, dx)
    return mean, cov


#: The filters by name, in registration order.
REGISTRY: dict[str, type[Filter]] = {}

F = TypeVar("F", bound=type[Filter])


def register(cls: F) -> F:
    """Class decorator: add a :class:`Filter` to :data:`REGISTRY` under its ``name``.

    Returns
    -------
    type of Filter
        ``cls`` itself.

    Raises
    ------
    ValueError
        If a filter of that name is registered already.
    """
    if cls.name in REGISTRY:
        raise ValueError(f"a filter named {cls.name!r} is registered already")
    REGISTRY[cls.name] = cls
    return cls


def make_filter(
    name: str, config: EstimationConfig, cov: dict[str, np.ndarray], pn: ProcessNoise
) -> Filter:
    """The registered filter ``name`` for ``config`` (priors in ``cov``, process noise ``pn``:
    per-step covariances or intensities, as the epoch plan it runs on).

    Parameters
    ----------
    name : str
        Registry key (``"ekf"``, ``"kf"``, ``"gsf"``).
    config : EstimationConfig
        The model, sensor noises and filter options.
    cov : dict of str to ndarray
        Initial covariances ``p0_ekf``, ``p0_kf``.
    pn : ProcessNoise
        Process noise.

    Returns
    -------
    Filter
        The filter.

    Raises
    ------
    ConfigError
        For an unknown name.
    """
    cls = REGISTRY.get(name)
    if cls is None:
        raise ConfigError(f"unknown filter {name!r}; choose from {', '.join(REGISTRY)}")
    return cls.from_config(config, cov, pn)


def stacked(states: Sequence[tuple], axis: int, pick: Callable = lambda s: s) -> np.ndarray:
    """Contiguous stack of one entry of every run's state.

    Parameters
    ----------
    states : sequence of tuple
        Each run's filter state (:meth:`Filter.start`).
    axis : int
        Axis of the result along which the runs are stacked.
    pick : callable, optional
        Takes a run's state and returns the entry to stack; default the state itself.

    Returns
    -------
    ndarray
        The stacked entries, C-contiguous.
    """
    return np.ascontiguousarray(np.stack([pick(s) for s in states], axis=axis))
