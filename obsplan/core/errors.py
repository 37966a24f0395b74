"""Exception hierarchy.

The command line maps :class:`InputError` (a problem with what the user gave) to exit code 2 and
any other :class:`ObsplanError` (a solver or validation failure) to exit code 1. Messages name the
field, row or column at fault and say how to fix it; they are shown to the user without a
traceback.
"""

from __future__ import annotations


class ObsplanError(Exception):
    """Base class of every error obsplan raises on purpose."""


class InputError(ObsplanError, ValueError):
    """Bad user input: a file, an option, a problem definition."""


class TrajectoryFormatError(InputError):
    """A trajectory CSV (or array) that is not of the documented form."""


class ProblemError(InputError):
    """A planning problem file or object that is malformed or infeasible."""


class ConfigError(InputError):
    """A bad model, sensor or filter configuration."""


class SolverError(ObsplanError):
    """An optimisation or estimation run that failed (not a user error)."""


def field_error(where: str, msg: str) -> ProblemError:
    """The error of one field: ``ProblemError("section.field: msg")`` (every problem error names
    its field first, so that the user sees what to fix).

    Parameters
    ----------
    where : str
        The field at fault, as ``section.field`` of the problem file.
    msg : str
        What is wrong with it and how to fix it.

    Returns
    -------
    ProblemError
        The error, for the caller to raise.
    """
    return ProblemError(f"{where}: {msg}")
