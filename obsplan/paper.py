"""The paper's Tables 1–3 (sections 5–6) and checked claims of sections 6–7, recomputed.

Each :class:`TableRow` is one motion class of a table (its label as printed) flown by one
representative trajectory of :mod:`obsplan.generators` (the call is stored in the row). Where a
verdict depends on the trajectory's parameters (acceleration on a straight leg, the z motion of a
3D circle, ...) the class gets several rows, one per variant, all carrying the paper's verdict of
that class. For every sensor configuration (column) a :class:`Cell` holds the paper's verdicts
transcribed exactly, our verdicts computed by :func:`obsplan.observability.analyze` (LWO along the
trajectory, eq. 9; full rank of the exact augmented Gramian, eqs. 19–27) with the ranks behind
them, and the keys of the :data:`NOTES` that explain a disagreement or a condition.

Rank verdicts do not depend on the sampling interval, so ``quick=True`` samples at 0.1 s instead
of the paper's 0.01 s (same durations).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cache

from obsplan import generators as gen
from obsplan.generators import DT
from obsplan.observability.analyze import ObservabilityReport, analyze
from obsplan.trajectory import Trajectory

QUICK_DT: float = 0.1
#: Lap time of the paper's circle (ρ = 50 m at 2.6 m/s, Fig. 2) [s].
LAP_S: float = 2.0 * math.pi * 50.0 / 2.6


# ------------------------------------------------------------------ results
@dataclass(frozen=True)
class Verdict:
    """Local weak observability along the trajectory (``lwo``) and Gramian full rank (``o``)."""

    lwo: bool
    o: bool

    def __str__(self) -> str:
        return f"{'YES' if self.lwo else 'NO'}/{'YES' if self.o else 'NO'}"

    def to_dict(self) -> dict[str, bool]:
        return {"lwo": bool(self.lwo), "o": bool(self.o)}


YES_YES = Verdict(True, True)
YES_NO = Verdict(True, False)
NO_YES = Verdict(False, True)
NO_NO = Verdict(False, False)


@dataclass(frozen=True)
class Evidence:
    """The ranks behind one of our verdicts.

    ``lwo_min_rank`` / ``state_dim``: smallest rank of O over the samples; ``lwo_fraction``: share
    of samples where O has full rank; ``gramian_rank`` / ``gramian_dim``: unit-invariant rank of
    the augmented Gramian over the whole trajectory; ``full_rank_from_t`` [s]: first full-rank time.
    """

    lwo_min_rank: int
    state_dim: int
    lwo_fraction: float
    gramian_rank: int
    gramian_dim: int
    full_rank_from_t: float | None

    @classmethod
    def of(cls, rep: ObservabilityReport) -> Evidence:
        return cls(
            lwo_min_rank=rep.lwo.min_rank,
            state_dim=rep.lwo.state_dim,
            lwo_fraction=rep.lwo.full_rank_fraction,
            gramian_rank=rep.gramian.rank,
            gramian_dim=rep.gramian.dim,
            full_rank_from_t=rep.gramian.full_rank_from_t,
        )

    def __str__(self) -> str:
        return f"O {self.lwo_min_rank}/{self.state_dim}, G {self.gramian_rank}/{self.gramian_dim}"

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class Cell:
    """One sensor configuration (a column of the table) of one row."""

    column: str
    sensors: tuple[str, ...]
    current: bool
    paper: Verdict | None
    ours: Verdict
    evidence: Evidence
    notes: tuple[str, ...] = ()

    @property
    def agrees(self) -> bool | None:
        """Whether both verdicts equal the paper's; None where the paper has no verdict."""
        return None if self.paper is None else self.paper == self.ours

    @property
    def differing(self) -> tuple[str, ...]:
        """Which verdicts differ from the paper's: a subset of ``("LWO", "O")``."""
        if self.paper is None:
            return ()
        out = ("LWO",) if self.paper.lwo != self.ours.lwo else ()
        return out + (("O",) if self.paper.o != self.ours.o else ())

    def to_dict(self) -> dict:
        return {
            "column": self.column,
            "sensors": list(self.sensors),
            "current": self.current,
            "paper": None if self.paper is None else self.paper.to_dict(),
            "ours": self.ours.to_dict(),
            "agrees": self.agrees,
            "differing": list(self.differing),
            "evidence": self.evidence.to_dict(),
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class TableRow:
    """A motion class of Table 1, 2 or 3 flown by one representative trajectory."""

    key: str
    table: int
    dim: int
    motion: str
    variant: str
    trajectory: str
    cells: tuple[Cell, ...]

    @property
    def agrees(self) -> bool | None:
        """False if any cell disagrees; None if the paper has no verdict for this row."""
        vals = [c.agrees for c in self.cells if c.agrees is not None]
        return None if not vals else all(vals)

    @property
    def notes(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(n for c in self.cells for n in c.notes))

    def to_dict(self) -> dict:
        return {
            "key": self.key,
            "table": self.table,
            "dim": self.dim,
            "motion": self.motion,
            "variant": self.variant,
            "trajectory": self.trajectory,
            "agrees": self.agrees,
            "cells": [c.to_dict() for c in self.cells],
        }


@dataclass(frozen=True)
class Claim:
    """A statement of sections 6–7 checked by computation; ``paper`` and ``ours`` as text."""

    key: str
    section: str
    statement: str
    paper: str
    ours: str
    agrees: bool
    trajectory: str
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


# ------------------------------------------------------------------ explanations
NOTES: dict[str, str] = {
    "lwo-needs-accel": (
        "LWO along the trajectory needs full rank at every sample. With range only, the last row "
        "of O (eq. 13) is (0, 3u): at constant speed (u = 0) O has rank <= 3 (eq. 36: det O = "
        "-3 u_x^2 q^2 = 0). Straight legs are LWO only with a non-zero acceleration at every "
        "sample, as eq. 36 itself says; the table's unconditional YES holds for the accelerating "
        "variants only. With water-profiling DVL and current the same row (0, 3u, 3u) decides."
    ),
    "t1-radial": (
        "O has rank 2 on every sample of a radial leg (p, v, u all along the line): LWO cannot "
        "hold at every sample once a radial leg is flown, whatever the circle before it. Table 1 "
        "says YES, Table 2 (range column, same motion) says NO: the paper contradicts itself; "
        "NO is right. O is YES: the Gramian is cumulative and full rank after the circle."
    ),
    "dvl-const-speed": (
        "With DVL the velocity block is measured, so O is full rank iff {p, v, u} span the plane; "
        "on a non-radial line p and v already do (v != 0): LWO holds even at constant speed."
    ),
    "planar-3d": (
        "Not in the paper: it shows what 'sufficiently exciting along z' requires. A sinusoid in "
        "z with the circle's own period gives z - z0 proportional to y: the path lies in a tilted "
        "plane, the displacement d never leaves it and the Gramian has rank 6/8. The z motion "
        "must differ from the horizontal one (another period or an aperiodic motion)."
    ),
    "straight-z": (
        "A straight z motion at constant vertical speed has u_z = 0, hence d_z(t, t0) = 0 "
        "(eq. 15) and zero p_z and v_z rows in the Gramian (eq. 27): rank 6/8, exactly the "
        "argument of section 5.2 for planar paths. Section 7.2 nevertheless says the KF of Fig. 5 "
        "(circle with a straight motion along z) converges once the LTV system satisfies the "
        "observability condition. A constant u_z != 0 is not enough either: d_z = u_z t^2/2 is "
        "collinear with the |nu0|^2 column (rank 7/8)."
    ),
    "dvl-zsine-condition": (
        "With DVL, O is full rank iff det[p; v; u] != 0. For p = (rho cos wt, rho sin wt, "
        "z0 + A sin Wt) this is w rho^2 (w^2 z0 + A (w^2 - W^2) sin Wt): LWO at every instant "
        "needs w^2 |z0| > A |w^2 - W^2| (our trajectory: z0 = 10 m, A = 5 m, W = 2pi/90 s). A z "
        "oscillation about the beacon's plane (z0 = 0) loses rank at isolated instants, which a "
        "sampled test with chord inputs does not see."
    ),
    "water-circle": (
        "With water-profiling DVL the DVL rows measure v, and the range row sees p, v_f and "
        "(p0.nu0, |nu0|^2) exactly as range-only sees (p, v, ...) of the nu-system (eq. 32-34). "
        "On a circle that is full rank, so the augmented Gramian is full rank (8/8): v is "
        "measured, nu = v + v_f is observable from range, hence v_f too. Section 6.3 and Table 3 "
        "say O: NO. On straight lines it is rank deficient (rank <= 2 + 4). Bottom-lock is "
        "always deficient: (w, -w) in (v, v_f) changes no output."
    ),
    "radial-water": (
        "A radial leg: p, nu and u are parallel, so the range rows of O_w have rank 2 in the "
        "(p, v_f) block: LWO fails with water-profiling DVL too."
    ),
    "water-3d-exciting": (
        "Not in Table 3 (only straight and circular motions): a 3D circle with a sinusoidal z "
        "motion and water-profiling DVL has a full-rank Gramian (11/11): v is measured and the "
        "range row sees (p, v_f, ...) as range-only sees (p, v, ...), which this path makes "
        "full rank (Table 1). With bottom lock it stays deficient ((w, -w) in (v, v_f)). LWO is "
        "structurally impossible in 3D with current (at most 4 + 3 = 7 < 9 rows of O)."
    ),
    "fig3-legs": (
        "Fig. 3's claim that the whole lawn-mower is LWO needs u != 0 at every sample; with "
        "constant-speed legs (the paper does not give the legs' speed profile) O has rank 3 on "
        "the legs."
    ),
    "gramian-straight-rank": (
        "On any straight line d(t, t0) is parallel to the line, so every row of C Phi lies in "
        "the span of (e, 0, 0, 0), (0, e, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1): range-only rank "
        "<= 4 in 2D and 3D, and + n with DVL (v measured); 2 if u = 0, 3 if u is constant. The "
        "Gramian depends on the inputs only, so radial and non-radial lines have the same rank."
    ),
}


# ------------------------------------------------------------------ trajectories
@dataclass(frozen=True)
class _Call:
    """A generator call that can be run (with a ``dt``) and printed with its parameters."""

    fn: Callable[..., Trajectory]
    kwargs: tuple[tuple[str, object], ...]
    base: _Call | None = field(default=None)

    def __call__(self, dt: float) -> Trajectory:
        kw = dict(self.kwargs, dt=dt)
        if self.base is not None:
            return self.fn(self.base(dt), **kw)
        return self.fn(**kw)

    def __str__(self) -> str:
        def fmt(v: object) -> str:
            if isinstance(v, float):
                return f"{v:.6g}"
            if isinstance(v, tuple):
                return "(" + ", ".join(fmt(x) for x in v) + ")"
            return repr(v)

        args = ([str(self.base)] if self.base is not None else []) + [
            f"{k}={fmt(v)}" for k, v in self.kwargs
        ]
        return f"{self.fn.__name__}({', '.join(args)})"


def _call(fn: Callable[..., Trajectory], **kw: object) -> _Call:
    return _Call(fn, tuple(kw.items()))


def _then(fn: Callable[..., Trajectory], base: _Call, **kw: object) -> _Call:
    """``fn(base(dt), **kw)``: a generator that extends another trajectory."""
    return _Call(fn, tuple(kw.items()), base)


_VARYING = gen.sine_profile(0.02, 0.01, 20.0)  # 0.01–0.03 m/s², never zero
_CIRCLE = {"radius": 50.0, "speed": 2.6}  # Fig. 2
_ZSINE = _call(
    gen.circle_z, **_CIRCLE, duration=180.0, z0=10.0, z_motion="sine", z_amp=5.0, z_period=90.0
)

#: The representative trajectories (generator calls; ``dt`` is given when they are flown).
SCENARIOS: dict[str, _Call] = {
    "2d-radial": _call(
        gen.straight,
        p0=(-80.0, 60.0),
        direction=(0.8, -0.6),
        speed0=0.5,
        accel=_VARYING,
        duration=60.0,
    ),
    # Fig. 1: p0 = (-100, 60) m, v0 = (0.1, 0) m/s, parallel to x
    "2d-line-const-speed": _call(
        gen.straight, p0=(-100.0, 60.0), direction=(1.0, 0.0), speed0=0.1, accel=0.0, duration=100.0
    ),
    "2d-line-const-accel": _call(
        gen.straight,
        p0=(-100.0, 60.0),
        direction=(1.0, 0.0),
        speed0=0.1,
        accel=0.02,
        duration=100.0,
    ),
    "2d-line-varying": _call(
        gen.straight,
        p0=(-100.0, 60.0),
        direction=(1.0, 0.0),
        speed0=0.1,
        accel=_VARYING,
        duration=100.0,
    ),
    "2d-circle": _call(gen.circle, **_CIRCLE, duration=120.0),
    "2d-circle+radial": _call(
        gen.circle_then_straight,
        **_CIRCLE,
        circle_duration=120.0,
        straight_duration=30.0,
        radial=True,
        straight_accel=0.02,
    ),
    "2d-circle+line-accel": _call(
        gen.circle_then_straight,
        **_CIRCLE,
        circle_duration=120.0,
        straight_duration=30.0,
        radial=False,
        straight_accel=0.02,
    ),
    "2d-circle+line-const": _call(
        gen.circle_then_straight,
        **_CIRCLE,
        circle_duration=120.0,
        straight_duration=30.0,
        radial=False,
        straight_accel=0.0,
    ),
    "2d-lawnmower": _call(gen.paper_lawnmower, dim=2),
    "3d-radial": _call(
        gen.straight,
        p0=(-80.0, 60.0, 20.0),
        direction=(0.8, -0.6, -0.2),
        speed0=0.5,
        accel=_VARYING,
        duration=60.0,
    ),
    "3d-line": _call(
        gen.straight,
        p0=(-100.0, 60.0, 5.0),
        direction=(1.0, 0.0, 0.0),
        speed0=0.1,
        accel=_VARYING,
        duration=100.0,
    ),
    "3d-circle-plane": _call(gen.circle, **_CIRCLE, duration=120.0, z=0.0),
    # Fig. 7: p0 = (50, 0, 5) m, v0 = (0, 2.6, 0) m/s
    "3d-circle-out": _call(gen.circle, **_CIRCLE, duration=120.0, z=5.0),
    "3d-circle-zsine": _ZSINE,
    "3d-circle-zsine-lap": _call(
        gen.circle_z, **_CIRCLE, duration=180.0, z0=10.0, z_motion="sine", z_amp=5.0, z_period=LAP_S
    ),
    # Fig. 5: p0 = (51, 1, 4) m, v0 = (0, 2.6, -0.01) m/s
    "3d-circle-zstraight": _call(
        gen.circle_z, **_CIRCLE, duration=180.0, z0=4.0, z_motion="straight", z_speed=-0.01
    ),
    "3d-circle-zsine+line": _then(gen.then_straight, _ZSINE, duration=30.0),
    "3d-lawnmower": _call(gen.paper_lawnmower, dim=3),
}


@cache
def scenario(name: str, quick: bool = False) -> Trajectory:
    """The trajectory :data:`SCENARIOS` ``[name]``, sampled at 0.01 s (0.1 s if ``quick``)."""
    return SCENARIOS[name](QUICK_DT if quick else DT)


@cache
def _analysis(
    name: str, sensors: tuple[str, ...], current: bool, quick: bool
) -> ObservabilityReport:
    return analyze(scenario(name, quick), sensors=sensors, current=current)


# ------------------------------------------------------------------ tables as data
RANGE = ("range",)
DVL = ("range", "dvl-bottom")
DVL_WATER = ("range", "dvl-water")
#: (column heading, sensors, current) of each table.
COLUMNS: dict[int, tuple[tuple[str, tuple[str, ...], bool], ...]] = {
    1: (("range", RANGE, False),),
    2: (("range", RANGE, False), ("range + DVL", DVL, False)),
    3: (
        ("range + DVL (bottom lock)", DVL, True),
        ("range + DVL (water profiling)", DVL_WATER, True),
    ),
}


@dataclass(frozen=True)
class _Spec:
    key: str
    dim: int
    motion: str
    variant: str
    scenario: str
    paper: tuple[Verdict | None, ...]
    notes: tuple[tuple[str, ...], ...]
    current: bool | None  # overrides the columns' (Table 1's ocean-current rows)


# The paper's verdicts, transcribed one line per (motion class, our variant):
#   key | dim | motion as printed | our variant | scenario | paper LWO/O per column | notes per
#   column (";" between columns, "," between notes) | "current" to force the ocean current.
# "-" marks a row the paper has no verdict for (ours only, to show a condition).
_TABLE1 = """
2d-straight-radial       |2| Straight (radial)                | varying acceleration                  | 2d-radial            | NO/NO   | gramian-straight-rank
2d-straight-const-accel  |2| Straight (not radial)            | constant acceleration (Fig. 1 start)  | 2d-line-const-accel  | YES/NO  |
2d-straight-varying      |2| Straight (not radial)            | varying acceleration, never zero      | 2d-line-varying      | YES/NO  |
2d-straight-const-speed  |2| Straight (not radial)            | constant speed (Fig. 1 start)         | 2d-line-const-speed  | YES/NO  | lwo-needs-accel
2d-circle                |2| Circular                         | centred on the beacon (eq. 37)        | 2d-circle            | YES/YES |
2d-circle-radial         |2| Circular + Straight (radial)     | accelerating radial leg               | 2d-circle+radial     | YES/YES | t1-radial
2d-circle-straight-accel |2| Circular + Straight (not radial) | accelerating leg                      | 2d-circle+line-accel | YES/YES |
2d-circle-straight-const |2| Circular + Straight (not radial) | constant-speed leg                    | 2d-circle+line-const | YES/YES | lwo-needs-accel
3d-straight-radial       |3| Straight (radial and not radial) | radial, varying acceleration          | 3d-radial            | NO/NO   | gramian-straight-rank
3d-straight-not-radial   |3| Straight (radial and not radial) | not radial, varying acceleration      | 3d-line              | NO/NO   | gramian-straight-rank
3d-circle-plane          |3| Circular                         | in the beacon's plane (z = 0)         | 3d-circle-plane      | NO/NO   |
3d-circle-out            |3| Circular                         | out of the beacon's plane (z = 5 m)   | 3d-circle-out        | NO/NO   |
3d-circle-zsine          |3| Circular in (x, y) and suff. exciting along z axis | sinusoidal z, period 90 s (lap 121 s) | 3d-circle-zsine | NO/YES |
3d-circle-zsine-lap      |3| Circular in (x, y) and suff. exciting along z axis | sinusoidal z with the lap's period | 3d-circle-zsine-lap | - | planar-3d
3d-circle-zstraight      |3| Circular in (x, y) and suff. exciting along z axis | straight z, constant speed (Fig. 5) | 3d-circle-zstraight | NO/YES | straight-z
3d-circle-zsine-straight |3| Circular in (x, y) and suff. exciting along z axis + Straight | sinusoidal z, then a tangent leg | 3d-circle-zsine+line | NO/YES |
current-2d-circle        |2| 2D/3D with ocean currents        | 2D circle                             | 2d-circle            | NO/NO   | | current
current-3d-zsine         |3| 2D/3D with ocean currents        | 3D circle, sinusoidal z               | 3d-circle-zsine      | NO/NO   | | current
"""  # noqa: E501

_TABLE2 = """
2d-straight-radial       |2| Straight (radial)                | varying acceleration                 | 2d-radial            | NO/NO   NO/NO   | gramian-straight-rank; gramian-straight-rank
2d-straight-const-accel  |2| Straight (not radial)            | constant acceleration (Fig. 1 start) | 2d-line-const-accel  | YES/NO  YES/NO  |
2d-straight-const-speed  |2| Straight (not radial)            | constant speed (Fig. 1 start)        | 2d-line-const-speed  | YES/NO  YES/NO  | lwo-needs-accel; dvl-const-speed
2d-circle                |2| Circular                         | centred on the beacon (eq. 37)       | 2d-circle            | YES/YES YES/YES |
2d-circle-radial         |2| Circular + Straight (radial)     | accelerating radial leg              | 2d-circle+radial     | NO/YES  NO/YES  | t1-radial;
2d-circle-straight-accel |2| Circular + Straight (not radial) | accelerating leg                     | 2d-circle+line-accel | YES/YES YES/YES |
2d-circle-straight-const |2| Circular + Straight (not radial) | constant-speed leg                   | 2d-circle+line-const | YES/YES YES/YES | lwo-needs-accel; dvl-const-speed
3d-straight-radial       |3| Straight (radial and not radial) | radial, varying acceleration         | 3d-radial            | NO/NO   NO/NO   | gramian-straight-rank; gramian-straight-rank
3d-straight-not-radial   |3| Straight (radial and not radial) | not radial, varying acceleration     | 3d-line              | NO/NO   NO/NO   | gramian-straight-rank; gramian-straight-rank
3d-circle-plane          |3| Circular (in the plane of the beacon)     | z = 0                       | 3d-circle-plane      | NO/NO   NO/NO   |
3d-circle-out            |3| Circular (out of the plane of the beacon) | z = 5 m (Fig. 7)            | 3d-circle-out        | NO/NO   YES/NO  |
3d-circle-zsine          |3| Circular in (x, y) and suff. excit. along z axis | sinusoidal z about z0 = 10 m (Fig. 8) | 3d-circle-zsine | NO/YES YES/YES | ; dvl-zsine-condition
3d-circle-zsine-straight |3| Circular in (x, y) and suff. excit. along z axis + Straight | sinusoidal z, then a tangent leg | 3d-circle-zsine+line | NO/YES NO/YES |
"""  # noqa: E501

_TABLE3 = """
2d-circle               |2| Straight and circular | circle centred on the beacon               | 2d-circle           | NO/NO YES/NO | ; water-circle
2d-straight-const-accel |2| Straight and circular | straight, not radial, constant acceleration | 2d-line-const-accel | NO/NO YES/NO |
2d-straight-const-speed |2| Straight and circular | straight, not radial, constant speed       | 2d-line-const-speed | NO/NO YES/NO | ; lwo-needs-accel
2d-straight-radial      |2| Straight and circular | straight, radial                           | 2d-radial           | NO/NO YES/NO | ; radial-water
3d-circle-out           |3| Straight and circular | circle out of the beacon's plane (z = 5 m) | 3d-circle-out       | NO/NO NO/NO  |
3d-straight-not-radial  |3| Straight and circular | straight, not radial                       | 3d-line             | NO/NO NO/NO  |
3d-circle-zsine         |3| Circular in (x, y) and suff. excit. along z axis (not in Table 3) | sinusoidal z about z0 = 10 m | 3d-circle-zsine | - - | water-3d-exciting; water-3d-exciting
"""  # noqa: E501


def _verdict(text: str) -> Verdict | None:
    if text == "-":
        return None
    lwo, o = text.split("/")
    return Verdict(lwo == "YES", o == "YES")


def _parse(table: str, ncols: int) -> tuple[_Spec, ...]:
    specs = []
    for line in table.strip().splitlines():
        key, dim, motion, variant, name, paper, notes, *flag = (f.strip() for f in line.split("|"))
        verdicts = tuple(_verdict(v) for v in paper.split())
        per_col = [
            tuple(n.strip() for n in col.split(",") if n.strip()) for col in notes.split(";")
        ]
        per_col += [()] * (ncols - len(per_col))
        if len(verdicts) != ncols or len(per_col) != ncols or name not in SCENARIOS:
            raise AssertionError(f"bad table line: {line}")  # a transcription typo, not input
        if any(n not in NOTES for col in per_col for n in col):
            raise AssertionError(f"unknown note in: {line}")
        current = True if flag and flag[0] == "current" else None
        specs.append(_Spec(key, int(dim), motion, variant, name, verdicts, tuple(per_col), current))
    return tuple(specs)


_SPECS: dict[int, tuple[_Spec, ...]] = {
    1: _parse(_TABLE1, 1),
    2: _parse(_TABLE2, 2),
    3: _parse(_TABLE3, 2),
}


def _row(table: int, spec: _Spec, quick: bool) -> TableRow:
    cells = []
    for i, (column, sensors, current) in enumerate(COLUMNS[table]):
        cur = current if spec.current is None else spec.current
        rep = _analysis(spec.scenario, sensors, cur, quick)
        ours = Verdict(rep.lwo.along_trajectory, rep.gramian.full_rank)
        notes = spec.notes[i]
        cells.append(Cell(column, sensors, cur, spec.paper[i], ours, Evidence.of(rep), notes))
    return TableRow(
        key=f"t{table}-{spec.key}",
        table=table,
        dim=spec.dim,
        motion=spec.motion,
        variant=spec.variant,
        trajectory=str(SCENARIOS[spec.scenario]),
        cells=tuple(cells),
    )


@cache
def _table(table: int, quick: bool) -> tuple[TableRow, ...]:
    return tuple(_row(table, s, quick) for s in _SPECS[table])


def table1(quick: bool = False) -> tuple[TableRow, ...]:
    """Table 1 (range only; the last rows with ocean current), paper beside ours."""
    return _table(1, bool(quick))


def table2(quick: bool = False) -> tuple[TableRow, ...]:
    """Table 2 (range, and range + DVL), paper beside ours."""
    return _table(2, bool(quick))


def table3(quick: bool = False) -> tuple[TableRow, ...]:
    """Table 3 (range + DVL with ocean current, bottom lock and water profiling)."""
    return _table(3, bool(quick))


def all_rows(quick: bool = False) -> tuple[TableRow, ...]:
    """Rows of Tables 1, 2 and 3 in order."""
    return table1(quick) + table2(quick) + table3(quick)


# ------------------------------------------------------------------ claims of sections 6–7
def _ranks(name: str, sensors: tuple[str, ...], quick: bool) -> Evidence:
    return Evidence.of(_analysis(name, sensors, False, quick))


@cache
def claims(quick: bool = False) -> tuple[Claim, ...]:
    """Rank statements of sections 6.1–6.2 and figure claims of section 7, recomputed."""
    out: list[Claim] = []

    g2 = [
        _ranks(n, s, quick).gramian_rank
        for n in ("2d-radial", "2d-line-varying")
        for s in (RANGE, DVL)
    ]
    out.append(
        Claim(
            "6.1-gramian-2d-straight",
            "6.1",
            "Gramian rank of 2D straight lines (radial and not), range -> range + DVL",
            "4 -> 5",
            f"radial {g2[0]} -> {g2[1]}, not radial {g2[2]} -> {g2[3]} (varying accel.)",
            g2 == [4, 5, 4, 5],
            str(SCENARIOS["2d-line-varying"]),
            ("gramian-straight-rank",),
        )
    )
    lr = [_ranks(n, DVL, quick).lwo_min_rank for n in ("3d-radial", "3d-line")]
    out.append(
        Claim(
            "6.2-lwo-3d-straight",
            "6.2",
            "Rank of O (eq. 45), 3D straight lines with DVL",
            "4 radial, 5 not radial",
            f"{lr[0]} radial, {lr[1]} not radial",
            lr == [4, 5],
            str(SCENARIOS["3d-line"]),
        )
    )
    g3 = [_ranks(n, s, quick).gramian_rank for n in ("3d-radial", "3d-line") for s in (RANGE, DVL)]
    out.append(
        Claim(
            "6.2-gramian-3d-straight",
            "6.2",
            "Gramian rank of 3D straight lines, range -> range + DVL",
            "6 -> 7 not radial, 4 -> 6 radial",
            f"{g3[2]} -> {g3[3]} not radial, {g3[0]} -> {g3[1]} radial",
            g3 == [4, 6, 6, 7],
            str(SCENARIOS["3d-line"]),
            ("gramian-straight-rank",),
        )
    )
    lm = _analysis("2d-lawnmower", RANGE, False, quick)
    out.append(
        Claim(
            "7.1-fig3-lwo",
            "7.1 (Fig. 3)",
            "2D lawn-mower: states along the whole trajectory LWO",
            "LWO along the trajectory",
            f"LWO at {lm.lwo.full_rank_fraction:.0%} of samples (min rank {lm.lwo.min_rank}/4); "
            f"Gramian full rank from t = {lm.gramian.full_rank_from_t:.1f} s",
            lm.lwo.along_trajectory,
            str(SCENARIOS["2d-lawnmower"]),
            ("fig3-legs",),
        )
    )
    for key, sec, what, name in (
        (
            "7.2-fig5-gramian",
            "7.2 (Fig. 5)",
            "3D circle with a straight motion along z",
            "3d-circle-zstraight",
        ),
        (
            "7.2-fig6-gramian",
            "7.2 (Fig. 6)",
            "3D lawn-mower with a straight motion along z",
            "3d-lawnmower",
        ),
    ):
        ev = _ranks(name, RANGE, quick)
        out.append(
            Claim(
                key,
                sec,
                f"{what}: the LTV system becomes observable (KF converges)",
                "Gramian full rank",
                f"Gramian rank {ev.gramian_rank}/{ev.gramian_dim}",
                ev.gramian_rank == ev.gramian_dim,
                str(SCENARIOS[name]),
                ("straight-z",),
            )
        )
    return tuple(out)


# ------------------------------------------------------------------ rendering
def _note_numbers(rows: Iterable[TableRow], extra: Iterable[Claim] = ()) -> dict[str, int]:
    keys: list[str] = []
    for r in rows:
        keys += r.notes
    for c in extra:
        keys += c.notes
    return {k: i for i, k in enumerate(dict.fromkeys(keys), start=1)}


def _cell_text(c: Cell, numbers: dict[str, int]) -> str:
    paper = "  -    " if c.paper is None else f"{c.paper!s:<7}"
    mark = "≠" if c.agrees is False else " "
    refs = ",".join(str(numbers[n]) for n in c.notes)
    refs = f"[{refs}]" if refs else ""
    return f"{paper} {c.ours!s:<7}{mark} ({c.evidence}) {refs}"


def _grid(headers: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(headers)]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip()

    return [line(headers), line(["-" * w for w in widths]), *(line(r) for r in body)]


_TITLES = {
    1: "Table 1: range only (last rows: with ocean current)",
    2: "Table 2: range and range + DVL",
    3: "Table 3: range + DVL with ocean current",
}


def render_tables(rows: Sequence[TableRow], claim_list: Sequence[Claim] = ()) -> str:
    """Plain-text tables: per column ``paper ours`` (LWO/O), ``≠`` where they differ, ranks.

    Each cell reads ``paper ours ≠ (O rank/n, G rank/m) [notes]``: ``O`` is the smallest rank of
    the LWO matrix over the samples, ``G`` the rank of the augmented Gramian. Numbered notes
    explaining every disagreement (and conditions behind some agreements) follow the tables.
    """
    numbers = _note_numbers(rows, claim_list)
    out: list[str] = []
    for table in sorted({r.table for r in rows}):
        trs = [r for r in rows if r.table == table]
        cols = [c.column for c in trs[0].cells]
        headers = [
            "Dim",
            "Motion (paper)",
            "Our trajectory",
            *(f"{c}: paper ours" for c in cols),
            "Agree",
        ]
        body = [
            [
                f"{r.dim}D",
                r.motion,
                r.variant,
                *(_cell_text(c, numbers) for c in r.cells),
                {True: "yes", False: "NO", None: "n/a"}[r.agrees],
            ]
            for r in trs
        ]
        out += [_TITLES.get(table, f"Table {table}"), "", *_grid(headers, body), ""]
    if claim_list:
        body = [
            [
                c.section,
                c.statement,
                c.paper,
                c.ours,
                "yes" if c.agrees else "NO",
                ",".join(str(numbers[n]) for n in c.notes),
            ]
            for c in claim_list
        ]
        out += ["Claims of sections 6-7", ""]
        out += _grid(["Section", "Statement", "Paper", "Ours", "Agree", "Notes"], body) + [""]
    out += [
        "Verdicts: LWO/O = locally weakly observable along the trajectory (O full rank at "
        "every sample, eq. 9) / augmented Gramian full rank (eqs. 19-27). ≠: ours differs.",
        "",
    ]
    if numbers:
        out += ["Notes", ""]
        for key, i in numbers.items():
            out += textwrap.wrap(f"[{i}] {NOTES[key]}", width=100, subsequent_indent="    ")
        out.append("")
    traj = {r.trajectory: None for r in rows} | {c.trajectory: None for c in claim_list}
    out += ["Trajectories (obsplan.generators; dt = sampling interval)", ""]
    out += [f"  {t}" for t in traj] + [""]
    return "\n".join(out)


def paper_report(quick: bool = False) -> dict:
    """Tables 1–3 and the checked claims as a JSON-serialisable dict."""
    rows = all_rows(quick)
    cl = claims(quick)
    numbers = _note_numbers(rows, cl)
    cells = [c for r in rows for c in r.cells]
    return {
        "dt": QUICK_DT if quick else DT,
        "tables": {str(t): [r.to_dict() for r in rows if r.table == t] for t in (1, 2, 3)},
        "claims": [c.to_dict() for c in cl],
        "notes": {k: {"number": i, "text": NOTES[k]} for k, i in numbers.items()},
        "summary": {
            "rows": len(rows),
            "cells": len(cells),
            "cells_disagreeing": sum(c.agrees is False for c in cells),
            "cells_not_in_paper": sum(c.agrees is None for c in cells),
            "claims_disagreeing": sum(not c.agrees for c in cl),
        },
    }
