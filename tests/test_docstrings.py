"""Every public function and method of the package has numpydoc sections (numpydoc's validator).

Public: a name without a leading underscore, defined in a module of ``obsplan/`` (not re-exported
from elsewhere), that module's own functions and classes, and a public class's own methods.
Enforced per object: a docstring (``GL08``), every parameter documented (``PR01``) and none that
does not exist (``PR02``), and a ``Returns`` section when the function returns a value
(``RT01``). The API reference of the documentation site (``docs/reference/``) is built from
these docstrings.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest
from numpydoc.validate import validate

import obsplan

#: The numpydoc checks every public function and method passes, and what each means.
CHECKS = {
    "GL08": "no docstring",
    "PR01": "a parameter is not documented",
    "PR02": "a documented parameter does not exist",
    "RT01": "no Returns section",
}

MODULES = sorted(
    m.name
    for m in pkgutil.walk_packages(obsplan.__path__, "obsplan.")
    if not m.name.endswith("__main__")  # running it is running the command
)


def _public(module_name: str) -> list[tuple[str, object]]:
    """``(qualified name, object)`` of every public function, class and method of a module."""
    module = importlib.import_module(module_name)
    out: list[tuple[str, object]] = []
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module_name:
            continue
        if inspect.isfunction(obj):
            out.append((f"{module_name}.{name}", obj))
        elif inspect.isclass(obj):
            out.append((f"{module_name}.{name}", obj))
            for member, fn in vars(obj).items():
                fn = fn.__func__ if isinstance(fn, classmethod | staticmethod) else fn
                if not member.startswith("_") and inspect.isfunction(fn):
                    out.append((f"{module_name}.{name}.{member}", fn))
    return out


def _defects(qualname: str, obj: object) -> list[str]:
    checks = {"GL08"} if inspect.isclass(obj) else set(CHECKS)
    errors = validate(qualname)["errors"]
    return [f"{qualname}: {CHECKS[c]} ({msg})" for c, msg in errors if c in checks]


def one_line_only(a, b):
    """A summary and nothing else."""
    return a + b


def test_the_check_finds_missing_sections():
    found = _defects(f"{__name__}.one_line_only", one_line_only)
    assert any(CHECKS["PR01"] in d for d in found) and any(CHECKS["RT01"] in d for d in found)


@pytest.mark.parametrize("module_name", MODULES)
def test_every_public_function_has_numpydoc_sections(module_name):
    defects = [d for q, o in _public(module_name) for d in _defects(q, o)]
    assert not defects, "\n".join(defects)
