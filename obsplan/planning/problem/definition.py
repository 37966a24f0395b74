"""A planning problem: what a problem file holds, checked on construction.

Construction runs the cheap checks of :mod:`obsplan.planning.problem.checks` (unknown kinds,
infeasible combinations such as a start faster than the speed limit, a depth band or operating
area that does not contain the start, a mission that does not fit the horizon); the structural
rank checks, which cost CasADi work, run in :meth:`PlanningProblem.from_dict` (the loader's way
in: :mod:`obsplan.planning.problem.parse`) and in ``solve()``. A free line order
(``mission.order = "free"``) is resolved there too, not on construction.

A problem and its file mapping convert both ways through :mod:`obsplan.planning.problem.mapping`
(below this module, so that :meth:`PlanningProblem.with_changes` checks an edit with the file's
rules and errors without importing the loader).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from obsplan.core.errors import field_error
from obsplan.planning.problem.checks import check_structure, check_values, order_lines
from obsplan.planning.problem.mapping import problem_to_dict, problem_to_toml, sections_from_dict
from obsplan.planning.problem.schema import SCHEMA
from obsplan.planning.problem.sections import ProblemData

#: The sections of a problem file that :meth:`PlanningProblem.with_changes` takes as mappings.
FILE_SECTIONS = (*SCHEMA, "origin")


@dataclass(frozen=True)
class PlanningProblem(ProblemData):
    """A complete planning problem (the sections of :class:`ProblemData`), checked on construction.

    Build it with :func:`~obsplan.planning.problem.parse.load_problem` (a file or a shipped
    problem's name), :meth:`from_dict` (a mapping; also
    :func:`~obsplan.planning.problem.parse.problem_from_dict`), which order free survey lines and
    run the structural checks, or directly: ``__post_init__`` runs the loader's cheap checks
    (:func:`~obsplan.planning.problem.checks.check_values`, no solver work). Edit one with
    :meth:`with_changes`; write it with :meth:`to_dict` / :meth:`to_toml`.
    """

    def __post_init__(self) -> None:
        check_values(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], name: str = "") -> PlanningProblem:
        """Build and check a problem from a problem file's mapping, as the loader does.

        Parameters
        ----------
        data
            ``{section: {field: value}}`` as ``tomllib`` reads a problem file
            (docs/problem-files.md).
        name
            The name when ``[problem] name`` is not given.

        Returns
        -------
        PlanningProblem
            Checked (every check, the structural ones of
            :func:`~obsplan.planning.problem.checks.check_structure` included), a free line
            order resolved.

        Raises
        ------
        ProblemError
            Naming the ``section.field`` at fault and what it should be.
        """
        pb = order_lines(cls(**sections_from_dict(data, name)))
        check_structure(pb)
        return pb

    def to_dict(self) -> dict[str, Any]:
        """The canonical problem-file mapping
        (:func:`~obsplan.planning.problem.mapping.problem_to_dict`).

        Returns
        -------
        dict
            ``{section: {field: value}}`` with every field (defaults resolved);
            ``PlanningProblem.from_dict(pb.to_dict()) == pb``.
        """
        return problem_to_dict(self)

    def to_toml(self) -> str:
        """The text of a problem file of this problem.

        Returns
        -------
        str
            TOML with every field (defaults resolved); ``problem_from_dict(tomllib.loads(
            pb.to_toml())) == pb``, and :func:`~obsplan.planning.problem.parse.load_problem`
            reads it back from a file.

        Examples
        --------
        >>> import tomllib
        >>> from obsplan import PlanningProblem, load_problem
        >>> pb = load_problem("localise")
        >>> text = pb.to_toml()
        >>> print(text.splitlines()[2:4])
        ['[problem]', 'name = "localise: 2D range-only, free localisation"']
        >>> PlanningProblem.from_dict(tomllib.loads(text)) == pb
        True
        """
        return problem_to_toml(self)

    def with_changes(self, **changes: Any) -> PlanningProblem:
        """A copy with fields of sections changed, checked like a problem file.

        Parameters
        ----------
        **changes
            Per section, either a mapping of the file's fields to change, merged into the
            problem's own (``horizon={"steps": 20}``; a value of None drops the field, so that
            its default applies), by the section names of a problem file (``problem``,
            ``vehicle``, ``beacon``, ``start``, ``limits``, ``horizon``, ``objective``,
            ``scales``, ``validation``, ``mission``, ``origin``); or a whole section object by
            the field name of the problem (``horizon=Horizon(...)``, ``mission=None``,
            ``start_position=(0.0, 50.0)``).

        Returns
        -------
        PlanningProblem
            With any mapping given: rebuilt from the merged file mapping by
            :meth:`from_dict` (every check of the loader, with its errors); with section objects
            only: the copy checked on construction (the cheap checks, as before).

        Raises
        ------
        ProblemError
            Naming the ``section.field`` at fault (``horizon.steps: expected an integer, got
            '20'``), or the unknown section.

        Examples
        --------
        >>> from obsplan import load_problem
        >>> pb = load_problem("localise").with_changes(
        ...     horizon={"steps": 20}, objective={"kind": "gramian-log-det"}
        ... )
        >>> pb.horizon, pb.objective.kind
        (Horizon(duration=600.0, steps=20), 'gramian-log-det')
        >>> pb.with_changes(horizon={"steps": "20"})
        Traceback (most recent call last):
        ...
        obsplan.core.errors.ProblemError: horizon.steps: expected an integer, got '20'
        """
        edits = {k: v for k, v in changes.items() if isinstance(v, Mapping)}
        objects = {k: v for k, v in changes.items() if k not in edits}
        own = {f.name for f in fields(self)}
        for key in edits:
            if key not in FILE_SECTIONS:
                raise field_error(key, f"unknown section; sections are {', '.join(FILE_SECTIONS)}")
        for key in objects:
            if key not in own:
                raise field_error(
                    key,
                    "not a field of the problem; give a section's changes as a mapping "
                    f"({', '.join(FILE_SECTIONS)}) or a field's value ({', '.join(sorted(own))})",
                )
        pb = replace(self, **objects) if objects else self
        if not edits:
            return pb
        data = pb.to_dict()
        for section, edit in edits.items():
            merged = dict(data.get(section, {}))
            for key, value in edit.items():
                if value is None:
                    merged.pop(key, None)
                else:
                    merged[key] = value
            data[section] = merged
        return type(self).from_dict(data, self.name)
