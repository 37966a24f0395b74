"""``.ci/run`` runs exactly the README's second command (install, ``mypy obsplan``, the tests)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _readme_second_command() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"## The two commands.*?```bash\n(.*?)```", text, re.S)
    assert block, "README.md: no bash block under 'The two commands'"
    commands = [ln for ln in block.group(1).splitlines() if ln and not ln.startswith("#")]
    assert len(commands) == 2, commands
    return commands[1]


def test_ci_runs_the_readme_second_command():
    ci = [ln for ln in (ROOT / ".ci" / "run").read_text().splitlines() if ln.startswith("python3")]
    assert ci == [_readme_second_command()]


def test_the_command_type_checks_the_package():
    assert "&& mypy obsplan &&" in _readme_second_command()
