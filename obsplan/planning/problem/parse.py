"""Problem files to :class:`~obsplan.planning.problem.definition.PlanningProblem` and back.

:func:`load_problem` reads a TOML file (or a shipped problem by name: :func:`shipped_files`),
:func:`problem_from_dict` a parsed mapping (the sweeps build problems this way),
:func:`problem_to_dict` writes the canonical mapping. The conversion itself, field by field by
:data:`~obsplan.planning.problem.schema.SCHEMA` (types, units, defaults: an unknown key is an
error), geodetic fields included, is :mod:`obsplan.planning.problem.mapping`'s, which
:class:`~obsplan.planning.problem.definition.PlanningProblem` also uses for its ``from_dict``,
``with_changes`` and ``to_toml``. The loader runs every check, the structural ones included, so
a problem it returns can be solved.
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from obsplan.core.errors import ProblemError
from obsplan.core.textfiles import read_toml
from obsplan.planning.problem.definition import PlanningProblem
from obsplan.planning.problem.mapping import (
    origin_of,
    problem_to_dict,
    problem_to_toml,
    resolve_problem_files,
    resolve_problem_geodetic,
)

__all__ = [
    "DEFAULT_PROBLEM",
    "LOCALISE_PROBLEM",
    "PROBLEMS_DIR",
    "load_problem",
    "origin_of",
    "problem_from_dict",
    "problem_to_dict",
    "problem_to_toml",
    "resolve_problem_geodetic",
    "shipped_file",
    "shipped_files",
]


#: The shipped problems, suite and sweeps: package data (``obsplan/problems/``, also the clone's
#: ``problems/``), so every install has them. A plain folder: obsplan is not run from a zip.
PROBLEMS_DIR = Path(str(resources.files("obsplan").joinpath("problems")))
DEFAULT_PROBLEM = PROBLEMS_DIR / "default.toml"
#: The free localisation problem (no ``[mission]``): the default before missions.
LOCALISE_PROBLEM = PROBLEMS_DIR / "localise.toml"


def shipped_files() -> dict[str, Path]:
    """Every shipped problem and sweep file by its name: its path under :data:`PROBLEMS_DIR`
    without ``.toml`` (``"default"``, ``"suite/far-start"``, ``"sweeps/beacon-placement"``),
    in that order: the problems at the top, then the suite, then the sweeps.

    Returns
    -------
    dict of str to Path
        Name -> the TOML file under :data:`PROBLEMS_DIR`.
    """
    files = sorted(PROBLEMS_DIR.rglob("*.toml"), key=lambda f: (len(f.parts), str(f)))
    return {f.relative_to(PROBLEMS_DIR).with_suffix("").as_posix(): f for f in files}


def shipped_file(name: str) -> Path | None:
    """The shipped file called ``name`` (:func:`shipped_files`; ``.toml`` optional), or None.

    Parameters
    ----------
    name : str
        A shipped name such as ``"default"`` or ``"suite/far-start"`` (``.toml`` optional).

    Returns
    -------
    Path or None
        The file, or None when no shipped file has that name.
    """
    return shipped_files().get(name.removesuffix(".toml"))


def problem_from_dict(data: Mapping[str, Any], name: str = "") -> PlanningProblem:
    """Build and validate a problem from the parsed TOML mapping (every check, the structural
    ones of :func:`~obsplan.planning.problem.checks.check_structure` included):
    :meth:`PlanningProblem.from_dict
    <obsplan.planning.problem.definition.PlanningProblem.from_dict>`.

    Parameters
    ----------
    data : Mapping of str to Any
        ``{section: {field: value}}`` as ``tomllib`` reads a problem file.
    name : str, default ""
        The name when ``[problem] name`` is not given.

    Returns
    -------
    PlanningProblem

    Raises
    ------
    ProblemError
        Naming the ``section.field`` at fault and what it should be.
    """
    return PlanningProblem.from_dict(data, name)


def load_problem(path: str | Path | None = None) -> PlanningProblem:
    """Load and validate a problem file (TOML); ``None`` loads the shipped default.

    Parameters
    ----------
    path : str or Path or None, default None
        A problem file, or the name of a shipped one (``"suite/far-start"``: ``obsplan
        problems`` lists them, :func:`shipped_files`) when no such file exists; None: the
        default problem (``problems/default.toml``, a 2D survey of three lines).

    Returns
    -------
    PlanningProblem
        Checked, its free line order resolved and its structure checked
        (:func:`problem_from_dict`).

    Raises
    ------
    ProblemError
        If the file is missing, is not TOML, or any field is unknown, mistyped or infeasible.

    Examples
    --------
    >>> from obsplan import load_problem
    >>> pb = load_problem()  # the default problem (problems/default.toml): a survey
    >>> pb.model.dim, pb.objective.kind, pb.mission.kind, len(pb.mission.lines)
    (2, 'pcrb-position', 'survey', 3)
    """
    path = Path(DEFAULT_PROBLEM if path is None else path)
    if not path.exists():
        path = shipped_file(str(path)) or path  # a shipped problem by name ("suite/far-start")
    if not path.exists():
        raise ProblemError(
            f"problem file not found: {path} (`obsplan problems` lists the shipped ones by name)"
        )
    data = resolve_problem_files(
        read_toml(path, "a problem file (TOML)", error=ProblemError), path.parent
    )
    try:
        return problem_from_dict(data, name=path.stem)
    except ProblemError as exc:
        raise ProblemError(f"{path}: {exc}") from None
