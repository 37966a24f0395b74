"""The README and the docs are executable: every command and code block runs, in order, from a
fresh folder (one per document).

The README is parsed, not copied: every fenced block (``bash``, ``sh``, a block without a
language: shell commands; ``python``: a script; ``toml``: a file that must load) and every
command in the ``example`` column of a table runs in document order, in a fresh folder holding
what a clone has that the README uses (``problems/``, ``examples/``), with the installed
``obsplan`` and ``python`` first on ``PATH``. Each command must exit 0. Python blocks run as
scripts (``python block.py``), as a user who saves them would run them.

Conventions, as HTML comments on the lines right before a block (or before a table):

* ``<!-- readme-test: skip REASON -->`` — the block cannot run in a test (a cluster, a scheduler);
* ``<!-- readme-test: skip-line N: REASON -->`` — the same for the N-th command of the block;
* ``<!-- readme-test: creates PATH [PATH ...] -->`` — these paths exist after the block;
* ``<!-- readme-test: prints TEXT -->`` — the block's output contains TEXT;
* ``<!-- readme-test: writes PATH -->`` — (a TOML block) saved at PATH, loaded, removed.

The pages of ``docs/`` follow the same conventions, each from its own fresh folder; MyST directive
blocks (```` ```{toctree} ````) are the site's structure and ``text`` blocks are printed output,
not commands.

Installing is the one thing the test does not redo: ``python3 -m venv``, ``. .venv/bin/activate``
and ``pip install`` steps are dropped from a command (the test runs in the environment that is
already installed; the rest of the command runs). Everything the README writes must be ignored by
``.gitignore``, so that following the README never leaves untracked files in a clone.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import pytest

#: end-to-end: the slow tier (docs/development.md)
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: What a clone holds that README commands read.
COPIED = ("problems", "examples")
TIMEOUT_S = 900
_DIRECTIVE = re.compile(r"^\s*<!--\s*readme-test:\s*(.*?)\s*-->\s*$")
_INSTALL = re.compile(
    r"^(python3? -m venv\b|\. \.venv/bin/activate$|source \.venv/|pip3? install\b)"
)

_SHELL = {"", "bash", "sh", "shell", "console"}
#: Blocks that are not run: printed output.
_OUTPUT = {"text"}
DOCS = ROOT / "docs"


@dataclass
class Block:
    """One runnable unit of the README: a fenced block or the example commands of a table."""

    lang: str
    body: str
    line: int
    directives: list[str] = field(default_factory=list)

    def directive(self, name: str) -> list[str]:
        """The arguments of every ``name`` directive (``skip: REASON`` or ``skip REASON``)."""
        return [
            d[len(name) :].strip(" :") for d in self.directives if d.split()[0].rstrip(":") == name
        ]


def parse_readme(text: str) -> list[Block]:
    """The README's blocks in document order, each with the directives right before it."""
    lines = text.splitlines()
    out: list[Block] = []
    pending: list[str] = []
    i = 0
    while i < len(lines):
        ln = lines[i]
        m = _DIRECTIVE.match(ln)
        if m:
            pending.append(m.group(1))
            i += 1
            continue
        if ln.startswith("```"):
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            lang = ln[3:].strip()
            if not lang.startswith("{") and lang not in _OUTPUT:  # a directive; printed output
                out.append(Block(lang, "\n".join(lines[i + 1 : j]), i + 1, pending))
            pending, i = [], j + 1
            continue
        if ln.startswith("|") and i + 1 < len(lines) and re.match(r"^\|[-:| ]+\|$", lines[i + 1]):
            header = [c.strip().lower() for c in ln.strip("|").split("|")]
            j = i + 2
            cmds = []
            while j < len(lines) and lines[j].startswith("|"):
                if "example" in header:
                    cell = lines[j].strip("|").split("|")[header.index("example")]
                    cmds += [c for c in re.findall(r"`([^`]+)`", cell) if c.startswith("obsplan ")]
                j += 1
            if cmds:
                out.append(Block("sh", "\n".join(cmds), i + 1, pending))
            pending, i = [], j
            continue
        if ln.strip():
            pending = []  # a directive applies to the block right after it
        i += 1
    return out


def shell_commands(body: str) -> list[str]:
    """Commands of a shell block: continuations joined, comments and blank lines dropped."""
    cmds, cur = [], ""
    for ln in body.splitlines():
        if cur == "" and ln.lstrip().startswith("#"):
            continue
        cur += ln.rstrip()
        if cur.endswith("\\"):
            cur = cur[:-1] + " "
            continue
        cur = re.sub(r"\s+#\s.*$", "", cur).strip()
        if cur:
            cmds.append(cur)
        cur = ""
    return cmds


def without_install(cmd: str) -> str:
    """``cmd`` without its venv/activate/pip steps (the environment is installed already)."""
    return " && ".join(p for p in cmd.split(" && ") if not _INSTALL.match(p.strip()))


def test_parser_reads_blocks_directives_tables_and_commands():
    text = """
<!-- readme-test: skip-line 2: the suite -->
<!-- readme-test: creates a/b c -->
```bash
# a comment
python3 -m venv .venv && . .venv/bin/activate && pip install -e . && obsplan plan --out a
obsplan sweep x.toml --out s \\
    --workers 2     # trailing comment
```
text
| verb | example | what |
|---|---|---|
| `plan` | `obsplan plan p.toml` | plans; see `plan.csv` |
"""
    blocks = parse_readme(text)
    assert [b.lang for b in blocks] == ["bash", "sh"]
    assert blocks[0].directive("creates") == ["a/b c"]
    assert blocks[0].directive("skip-line") == ["2: the suite"]
    assert Block("sh", "", 1, ["skip: a cluster"]).directive("skip") == ["a cluster"]
    cmds = shell_commands(blocks[0].body)
    assert " ".join(cmds[1].split()) == "obsplan sweep x.toml --out s --workers 2"
    assert without_install(cmds[0]) == "obsplan plan --out a"
    assert blocks[1].body == "obsplan plan p.toml" and blocks[1].directives == []


def _env() -> dict[str, str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    return env


def _run(cmd: list[str] | str, cwd: Path, what: str) -> str:
    proc = subprocess.run(
        cmd,
        shell=isinstance(cmd, str),
        executable="/bin/bash" if isinstance(cmd, str) else None,
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"{what} exited {proc.returncode}:\n{output[-4000:]}"
    assert "Traceback" not in output, f"{what}:\n{output[-4000:]}"
    return output


def _run_block(block: Block, clone: Path, scripts: Path, doc: str = "README.md") -> str:
    where = f"{doc} line {block.line}"
    if block.lang in _SHELL:
        skipped = {int(d.split(":")[0]) for d in block.directive("skip-line")}
        out = ""
        for k, cmd in enumerate(shell_commands(block.body), start=1):
            cmd = without_install(cmd)
            if k in skipped or not cmd:
                continue
            out += _run(cmd, clone, f"{where}: {cmd!r}")
        return out
    if block.lang == "python":
        script = scripts / f"{Path(doc).stem}_line_{block.line}.py"
        script.write_text(block.body + "\n", encoding="utf-8")
        return _run([sys.executable, str(script)], clone, f"{where} (python script)")
    if block.lang == "toml":
        data = tomllib.loads(block.body)
        for target in block.directive("writes"):
            path = clone / target
            path.write_text(block.body, encoding="utf-8")
            try:
                if "sweep" in data:
                    from obsplan.sweeps import expand, load_sweep

                    assert expand(load_sweep(path)), where
            finally:
                path.unlink()  # an example to read, not a file the README leaves behind
        return ""
    pytest.fail(f"{where}: a ```{block.lang} block; give it a readme-test directive or a language")


def run_document(path: Path, tmp_path: Path) -> tuple[Path, int]:
    """Run every block of the document at ``path`` in order from a fresh folder; returns the
    folder and how many blocks ran."""
    doc = path.relative_to(ROOT).as_posix()
    clone = tmp_path / "clone"
    clone.mkdir()
    for name in COPIED:
        shutil.copytree(ROOT / name, clone / name)
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    ran = 0
    for block in parse_readme(path.read_text(encoding="utf-8")):
        if block.directive("skip"):
            assert block.directive("skip")[0], f"{doc} line {block.line}: skip needs a reason"
            continue
        output = _run_block(block, clone, scripts, doc)
        ran += 1
        for paths in block.directive("creates"):
            for p in paths.split():
                assert (clone / p).exists(), f"{doc} line {block.line}: {p} was not created"
        for text in block.directive("prints"):
            assert text in output, f"{doc} line {block.line}: {text!r} not in the output"
    return clone, ran


def _pages() -> list[Path]:
    """Every page of the documentation site with a block to run (in ``docs/``, not a build)."""
    return [
        p
        for p in sorted(DOCS.rglob("*.md"))
        if "_build" not in p.parts and parse_readme(p.read_text(encoding="utf-8"))
    ]


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.relative_to(DOCS).as_posix())
def test_every_block_of_a_docs_page_runs_in_order_from_a_fresh_folder(page, tmp_path):
    _, ran = run_document(page, tmp_path)
    assert ran >= 1


def test_every_readme_block_runs_in_order_from_a_fresh_folder(tmp_path):
    clone, ran = run_document(README, tmp_path)
    assert ran >= 3
    # everything the README wrote is ignored by the repository's .gitignore
    made = sorted(p.name for p in clone.iterdir() if p.name not in COPIED)
    made += [p.relative_to(clone).as_posix() for n in COPIED for p in (clone / n).rglob("*")]
    made = [m for m in made if not (ROOT / m).exists()]
    for name in made:
        probe = f"{name}/x" if (clone / name).is_dir() else name
        proc = subprocess.run(
            ["git", "-C", str(ROOT), "check-ignore", "-q", "--no-index", probe], check=False
        )
        assert proc.returncode == 0, f"the README writes {name}, which .gitignore does not cover"
