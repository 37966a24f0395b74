"""The scenarios of the paper's Figs. 1–9 (section 7) run through both filters, and their figures.

The paper gives the initial states and estimates of each figure but not the speeds, durations or
accelerations; our choices, consistent with the text, are:

========  =======================================================================================
Fig. 1    2D straight line parallel to x from (-100, 60) m, v0 = (0.1, 0) m/s, constant
          u_x = 0.005 m/s² (u_x ≠ 0 makes it LWO, eq. 36), 200 s (just past the closest
          approach to the beacon, x = 0 at t ≈ 180 s).
Fig. 2    2D circle through p0 = (51, 2) m with v0 = (0, 2.6) m/s: radius 51 m centred at
          (0, 2) m (2 m from the beacon), 2.6 m/s, 300 s (2.4 laps).
Fig. 3    2D lawn-mower from rest at (-80, 60) m (``generators.lawnmower``): legs of 160 m along
          x stacked every 30 m towards -y, semicircular turns, cruise 2 m/s, the first leg
          accelerating from rest; 4 legs (3 turns).
Fig. 4    Fig. 3 with the far initial estimate (-81, 50) m.
Fig. 5    3D: the circle of Fig. 2 in (x, y) (radius 51 m centred at (0, 1) m, p0 = (51, 1, 4) m)
          with a straight descent along z from v_z = -0.01 m/s whose sink rate varies,
          ``v_z = v_z0 - 0.1 (1 - cos(2π t / 60 s))`` m/s. A constant u_z ≠ 0 leaves d_z ∝ t²
          (parallel to the ``|v0|²`` column), u_z = 0 leaves d_z = 0, and a single dive that ends
          leaves d_z affine afterwards (in the span of the τ and 1 columns): in each case the z
          information stops growing, and the KF's z error drifts with the process noise.
Fig. 6    3D lawn-mower of Fig. 3 flown at 2 m/s from (-80, 60, 5) m, v0 = (2, 0, 0) m/s, with
          the descent of Fig. 5 starting from v_z = 0.
Fig. 7    3D circle of radius 50 m at z = 5 m (out of the beacon's plane), 2.6 m/s, range + DVL.
Fig. 8    Fig. 7's circle with z = 5 + 4 sin(2π t / 90 s) m, range + DVL. With DVL, O is full
          rank iff det[p; v; u] ≠ 0, i.e. ω²|z0| > A|ω² − Ω²| at every instant (Table 2, note 7):
          0.0135 > 0.0087 here, whereas z = 5 + 2 sin(2π t / 60 s) (0.0135 < 0.0165) loses rank
          at isolated instants; a period equal to the lap's (121 s) would tilt the path into a
          plane (Gramian rank 6/8). The amplitude keeps the vertical acceleration A Ω² near that
          of the 60 s, 2 m sine (0.019 vs 0.022 m/s²): the KF's z information grows with it.
Fig. 9    Fig. 8 with the range at 0.1 Hz (case B); DVL and prediction at 100 Hz.
========  =======================================================================================

All at the paper's 100 Hz with the paper's R, Q and P0 (:meth:`EstimationConfig.paper`), truth
with process noise. ``quick=True`` shortens the paths and lowers the model rate to 10 Hz for a
fast preview (``Q`` keeps the paper's noise per unit time, see :meth:`PaperScenario.config`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from obsplan.estimation.bounds.crlb import sampled_rank_over_time
from obsplan.estimation.config import EstimationConfig, paper_covariances
from obsplan.estimation.montecarlo.simulate import MonteCarloResult, monte_carlo
from obsplan.model.vehicle import make_model
from obsplan.observability.gramian import augmented_model, rank_over_time
from obsplan.trajectory import generators as gen
from obsplan.trajectory.sampled import Trajectory

#: The paper's model step [s] (100 Hz, section 7).
PAPER_DT = 0.01


def _with_z(traj: Trajectory, z0: float, vz0: float, uz: np.ndarray) -> Trajectory:
    """Add a vertical motion with inputs ``uz`` (one per sample) to a 2D trajectory."""
    zt = Trajectory.from_inputs(
        traj.t, np.array([0.0, z0]), np.array([0.0, vz0]), np.column_stack([0 * uz, uz])
    )
    return Trajectory(
        t=traj.t,
        p=np.column_stack([traj.p, zt.p[:, 1]]),
        v=np.column_stack([traj.v, zt.v[:, 1]]),
        u=np.column_stack([traj.u, uz]),
    )


#: Descent of Figs. 5–6: extra sink rate [m/s] varying with this period [s].
DESCENT_DV, DESCENT_PERIOD = 0.1, 60.0


def _descent(t: np.ndarray, dv: float = DESCENT_DV, period: float = DESCENT_PERIOD) -> np.ndarray:
    """``u_z`` of a straight descent whose sink rate grows and shrinks: ``v_z(t) = v_z0 -
    dv (1 - cos(2π t/period))``, sampled at interval midpoints."""
    w = 2 * np.pi / period
    tm = t + 0.5 * np.median(np.diff(t))
    return -dv * w * np.sin(w * tm)


@dataclass(frozen=True)
class PaperScenario:
    """One figure of section 7.

    Attributes
    ----------
    fig : int
    title : str
    build : callable (dt, quick) -> Trajectory
    dim, sensors : model
    init_error : tuple
        ``x̂0 - x0`` of ``(p, v)`` from the paper's stated estimates.
    rates_hz : dict
    claim : str
        The paper's qualitative result.
    """

    fig: int
    title: str
    build: Callable[[float, bool], Trajectory]
    dim: int
    sensors: str
    init_error: tuple[float, ...]
    rates_hz: dict
    claim: str

    def config(self, dt: float) -> EstimationConfig:
        """The paper's filter configuration of this figure for model step ``dt`` [s].

        ``R`` and ``P0`` are the paper's; ``Q`` is the paper's at 100 Hz scaled by
        ``dt / 0.01 s`` so that a coarser step keeps the same noise per unit time (the paper's
        ``Q ∝ Ts²`` per step would make the noise intensity grow with the step).

        Parameters
        ----------
        dt : float
            Model (prediction) step [s].

        Returns
        -------
        EstimationConfig
            The model, process and initial covariances, initial estimate error and sensor rates
            of this figure.
        """
        model = make_model(self.dim, self.sensors)
        cov = paper_covariances(model, PAPER_DT)
        scale = dt / PAPER_DT
        return EstimationConfig(
            model=model,
            q_ekf=cov["q_ekf"] * scale,
            q_kf=cov["q_kf"] * scale,
            p0_ekf=cov["p0_ekf"],
            p0_kf=cov["p0_kf"],
            init_error=np.asarray(self.init_error),
            rates_hz=self.rates_hz,
        )


def _fig1(dt: float, quick: bool) -> Trajectory:
    return gen.straight((-100.0, 60.0), (1.0, 0.0), 0.1, accel=0.005, duration=200.0).sample(dt)


def _fig2(dt: float, quick: bool) -> Trajectory:
    return gen.circle(51.0, 2.6, 100.0 if quick else 300.0, center=(0.0, 2.0)).sample(dt)


def _lawn(dt: float, quick: bool, from_rest: bool) -> Trajectory:
    kw: dict[str, Any] = {"initial_speed": 0.0} if from_rest else {}
    return gen.lawnmower(
        (-80.0, 60.0), 160.0, 30.0, 3 if quick else 4, 2.0, first_turn="right", **kw
    ).sample(dt)


def _fig3(dt: float, quick: bool) -> Trajectory:
    return _lawn(dt, quick, True)


def _fig5(dt: float, quick: bool) -> Trajectory:
    xy = gen.circle(51.0, 2.6, 100.0 if quick else 300.0, center=(0.0, 1.0)).sample(dt)
    return _with_z(xy, 4.0, -0.01, _descent(xy.t))


def _fig6(dt: float, quick: bool) -> Trajectory:
    xy = _lawn(dt, quick, False)
    return _with_z(xy, 5.0, 0.0, _descent(xy.t))


def _fig7(dt: float, quick: bool) -> Trajectory:
    return gen.circle(50.0, 2.6, 100.0 if quick else 300.0, z=5.0).sample(dt)


def _fig8(dt: float, quick: bool) -> Trajectory:
    path = gen.circle_z(50.0, 2.6, 100.0 if quick else 300.0, z0=5.0, z_amp=4.0, z_period=90.0)
    return path.sample(dt)


SCENARIOS: tuple[PaperScenario, ...] = (
    PaperScenario(
        1,
        "Straight line in 2D",
        _fig1,
        2,
        "range",
        (-1.0, 1.0, 0.1, 0.0),
        {},
        "EKF converges; KF does not (p_y error and std stay large)",
    ),
    PaperScenario(
        2, "Circle in 2D", _fig2, 2, "range", (-1.0, -2.0, 0.0, 0.0), {}, "both converge"
    ),
    PaperScenario(
        3,
        "Lawn-mower in 2D",
        _fig3,
        2,
        "range",
        (-1.0, 1.0, 0.0, 0.0),
        {},
        "EKF converges; KF converges once the first turn makes the Gramian full rank",
    ),
    PaperScenario(
        4,
        "Lawn-mower in 2D, far initial estimate",
        _fig3,
        2,
        "range",
        (-1.0, -10.0, 0.0, 0.0),
        {},
        "EKF fails; KF converges",
    ),
    PaperScenario(
        5,
        "Circle in 3D with straight z",
        _fig5,
        3,
        "range",
        (-1.0, -1.0, 1.0, 0.0, 0.0, 0.0),
        {},
        "EKF does not converge; KF converges after the Gramian is full rank",
    ),
    PaperScenario(
        6,
        "Lawn-mower in 3D with straight z",
        _fig6,
        3,
        "range",
        (-1.0, 1.0, 1.0, 0.0, 0.0, 0.0),
        {},
        "EKF does not converge; KF converges after the Gramian is full rank",
    ),
    PaperScenario(
        7,
        "Circle in 3D out of the beacon's plane, DVL",
        _fig7,
        3,
        "range,dvl",
        (1.0, -1.0, -2.0, 0.0, 0.0, 0.0),
        {},
        "EKF converges; KF does not",
    ),
    PaperScenario(
        8,
        "Circle in 3D with exciting z, DVL",
        _fig8,
        3,
        "range,dvl",
        (1.0, -1.0, -2.0, 0.0, 0.0, 0.0),
        {},
        "both converge",
    ),
    PaperScenario(
        9,
        "Case B: Fig. 8 with range at 0.1 Hz",
        _fig8,
        3,
        "range,dvl",
        (1.0, -1.0, -2.0, 0.0, 0.0, 0.0),
        {"range": 0.1},
        "both converge, more slowly than in Fig. 8",
    ),
)


def scenario(fig: int) -> PaperScenario:
    """The scenario of figure ``fig`` (1–9).

    Parameters
    ----------
    fig : int
        Figure number of section 7.

    Returns
    -------
    PaperScenario
        Its trajectory builder, model, initial error, rates and the paper's claim.

    Raises
    ------
    KeyError
        If the paper has no such figure.
    """
    for s in SCENARIOS:
        if s.fig == fig:
            return s
    raise KeyError(f"no scenario for figure {fig}; the paper's section 7 has Figs. 1–9")


@dataclass(frozen=True, eq=False)
class ScenarioRun:
    """A scenario's trajectory, Monte Carlo result and Gramian rank over the recorded times."""

    scenario: PaperScenario
    traj: Trajectory
    result: MonteCarloResult
    rank_t: np.ndarray
    rank: np.ndarray
    full_rank: int


def run_scenario(
    fig: int,
    dt: float = PAPER_DT,
    quick: bool = False,
    runs: int = 1,
    seed: int = 0,
    progress: bool = False,
    **overrides: Any,
) -> ScenarioRun:
    """Run the scenario of figure ``fig`` (paper's initial conditions).

    ``overrides`` replace fields of the :class:`EstimationConfig` (e.g. ``process_noise``).

    Parameters
    ----------
    fig : int
        Figure number (1–9).
    dt : float, optional
        Model step [s]; the paper's 0.01 s by default.
    quick : bool, optional
        Shorter paths (a fast preview).
    runs : int, optional
        Number of Monte Carlo runs.
    seed : int, optional
        Seed of the random generator.
    progress : bool, optional
        Show a progress bar over runs.
    **overrides
        Fields of :class:`EstimationConfig` to replace.

    Returns
    -------
    ScenarioRun
        The trajectory, the Monte Carlo result of both filters and the Gramian rank at the
        recorded times (of the sampled ranges when a rate is set).
    """
    sc = scenario(fig)
    traj = sc.build(dt, quick)
    cfg = sc.config(dt)
    if overrides:
        cfg = replace(cfg, **overrides)
    res = monte_carlo(traj, cfg, runs=runs, seed=seed, progress=progress)
    if sc.rates_hz:
        ranks = sampled_rank_over_time(traj, cfg)
    else:
        ranks = rank_over_time(traj, cfg.model)
    idx = np.searchsorted(traj.t, res.t)
    return ScenarioRun(
        scenario=sc,
        traj=traj,
        result=res,
        rank_t=res.t,
        rank=ranks[idx],
        full_rank=augmented_model(cfg.model).state_dim,
    )


def write_figures(out_dir: Path, quick: bool = False, progress: bool = True) -> list:
    """Run the scenarios of Figs. 1–9 and write one PNG per figure to ``out_dir``.

    Returns the list of written paths. ``quick`` uses shorter paths at 10 Hz (well under a minute).

    Parameters
    ----------
    out_dir : Path
        Folder of the PNG files (created if missing).
    quick : bool, optional
        Shorter paths at 10 Hz.
    progress : bool, optional
        Show a progress bar over runs.

    Returns
    -------
    list of Path
        ``fig1.png`` to ``fig9.png`` in ``out_dir``.
    """
    from obsplan.estimation.montecarlo import plots

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    dt = 0.1 if quick else PAPER_DT
    written = []
    for sc in SCENARIOS:
        run = run_scenario(sc.fig, dt=dt, quick=quick, progress=progress)
        fig = plots.scenario_figure(
            run.traj,
            run.result,
            run.rank_t,
            run.rank,
            run.full_rank,
            title=f"Fig. {sc.fig}: {sc.title}",
        )
        path = out_dir / f"fig{sc.fig}.png"
        fig.savefig(path, dpi=110)
        plots.close(fig)
        written.append(path)
    return written


__all__ = [
    "PAPER_DT",
    "SCENARIOS",
    "PaperScenario",
    "ScenarioRun",
    "run_scenario",
    "scenario",
    "write_figures",
]
