"""The documentation site builds with Sphinx, warnings as errors (a broken reference, a page in no
table of contents, a docstring numpydoc cannot read all fail here)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytestmark = pytest.mark.slow


def test_the_site_builds_with_warnings_as_errors(tmp_path):
    # the generated API pages are written into the source tree: start from none
    shutil.rmtree(DOCS / "reference" / "generated", ignore_errors=True)
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html"]
        + [str(DOCS), str(tmp_path / "html")],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-6000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-6000:]
    html = tmp_path / "html"
    for page in ("index", "getting-started", "guides/plan-a-survey", "results/suite"):
        assert (html / f"{page}.html").is_file(), page
    api = (html / "reference" / "generated" / "obsplan.load_problem.html").read_text(
        encoding="utf-8"
    )
    assert "Parameters" in api and "Returns" in api  # numpydoc rendered the sections
    # the suite page includes the benchmark's generated table
    assert "suite/torpedo.toml" in (html / "results" / "suite.html").read_text(encoding="utf-8")
    # every page of docs/ is part of the site (Sphinx warns about one in no toctree)
    pages = {p.relative_to(DOCS).with_suffix("").as_posix() for p in DOCS.rglob("*.md")}
    # conf.py exclude_patterns (the generated results tables are included by their pages)
    excluded = ("_build", "reference/generated", "notebooks/README", "results/generated")
    pages = {p for p in pages if not p.startswith(excluded)}
    missing = [p for p in pages if not (html / f"{p}.html").is_file()]
    assert not missing, missing
