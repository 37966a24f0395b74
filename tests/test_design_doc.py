"""docs/design.md names every module of the package and every verb of the command line.

A new module or verb without its line in the design note fails here, so the note stays the map
a new engineer reads first.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from obsplan.cli import VERBS

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "obsplan"
DESIGN = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")


def _modules() -> list[Path]:
    return sorted(p.relative_to(PACKAGE) for p in PACKAGE.rglob("*.py"))


def _section(title: str) -> str:
    """The text of the ``## title`` section (to the next ``## ``)."""
    m = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", DESIGN, re.S | re.M)
    assert m, f"docs/design.md has no '## {title}' section"
    return m.group(1)


@pytest.mark.parametrize("module", _modules(), ids=str)
def test_every_module_is_named(module):
    """Each module's file name appears in the layout (a subpackage's modules in its entry)."""
    layout = _section("Layout (data flows top to bottom)")
    if module.parent == Path("."):
        assert re.search(rf"^\s+{re.escape(module.name)}\s", layout, re.M), (
            f"docs/design.md: the layout has no line for obsplan/{module}"
        )
        return
    folder = module.parts[0]
    rel = "/".join(module.parts[1:])  # inside its stage's folder: "filters/base.py", "plan.py"
    # the subpackage's entry: from its "folder/" line to the next top-level entry
    m = re.search(rf"^      {folder}/(.*?)(?=^      \S)", layout, re.S | re.M)
    assert m, f"docs/design.md: the layout has no entry for obsplan/{folder}/"
    if folder == "planning":  # its rooms have a section of their own
        text = _section("The planning rooms")
        assert re.search(rf"^    {re.escape(rel)}\s", text, re.M), (
            f"docs/design.md: the planning rooms do not list {rel}"
        )
    elif module.name != "__init__.py":
        assert re.search(rf"(?<![\w/]){re.escape(rel)}\b", m.group(1)), (
            f"docs/design.md: the obsplan/{folder}/ entry does not name {rel}"
        )


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_is_named(verb):
    verbs = _section("The verbs")
    assert re.search(rf"^    {verb}\s+cli/\w+\.py: ", verbs, re.M), (
        f"docs/design.md: 'The verbs' has no line for obsplan {verb}"
    )


def test_the_note_cites_only_files_in_the_repository():
    assert "PRODUCT.md" not in DESIGN and "../shared" not in DESIGN
