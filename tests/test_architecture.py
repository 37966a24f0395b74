"""The package's architecture, checked on its source: imports go one way and functions stay short.

Every ``import`` statement in ``obsplan/`` is read from the syntax tree, wherever it is (module
level, inside functions, inside ``try``, under ``if TYPE_CHECKING:``): a type-only import is
still an arrow for the reader, so it counts like any other.

* :data:`STAGES` gives every module its stage; a module may import its own stage and lower ones;
* the module graph has no cycle;
* inside ``obsplan/planning`` and ``obsplan/estimation`` the rooms of :data:`ROOMS` (sub-packages
  by role, and the top modules) import only earlier rooms;
* no module imports the facade (``__init__``) of a package it is inside;
* every package's ``__init__`` says what its room does and what it may import;
* no function in ``obsplan/planning`` (and ``obsplan/estimation``) is longer than 100 lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import obsplan

PACKAGE = Path(obsplan.__file__).resolve().parent

#: ``(stage, packages)`` from the bottom up; a module may import only from its own stage or a
#: lower one. The longest listed prefix of a module's name gives its stage.
STAGES: tuple[tuple[str, tuple[str, ...]], ...] = (
    # infrastructure: errors, signals, atomic files, safe output folders, the cost budget, user
    # text files, CSV tables; and the version
    ("core", ("core", "version")),
    # the vehicle model and its frames (local NED, geodetic)
    ("model", ("model",)),
    # sampled paths, their CSV form, and the analytic paths of the generators
    ("trajectory", ("trajectory",)),
    ("observability", ("observability",)),
    ("estimation", ("estimation",)),
    # the paper's scenarios and figures: observability and estimation, nothing from planning
    ("paper", ("paper",)),
    ("planning", ("planning",)),
    # real inputs and outputs, parameter studies: beside each other, above planning
    ("io-sweeps", ("io", "sweeps")),
    # the command line and the public facade (obsplan/__init__.py imports every stage)
    ("cli", ("cli", "__main__", "")),
)

#: The rooms of the two big stages from the bottom up: each imports only rooms before it. A room
#: is a sub-package (everything in it) or a module; ``""`` is the stage's floor, its modules
#: directly in the stage's folder (a floor module may import other floor modules).
ROOMS: dict[str, tuple[str, ...]] = {
    "estimation": (
        "",  # configuration, process noise and Kalman structure, schedules, epochs, kernels
        "filters",  # EKF, augmented KF, Gaussian sum behind one interface
        "bounds",  # Riccati recursions, posterior CRB, closed-loop covariance
        "montecarlo",  # truth, guidance, runs, statistics, results, figures
        "replay",  # one logged mission: gated EKF, RTS smoother, result, simulated logs
        "__init__",
    ),
    "planning": (
        "",  # the planner's tuning
        "missions",  # the mission in time: spec, schedule, order, completion, lawn-mower
        "problem",  # schema, sections, checks, the problem, files, limits of a path
        "baselines",  # the paths a user would otherwise fly
        "transcription",  # grid, guesses, NLP blocks, the mission's constraints
        "objectives",  # every objective.kind, its registry, values on a path
        "solver",  # formulation, IPOPT, starts, multi-start, keep-out margins
        "beacon",  # the craft carrying the beacon, planned for a vehicle on a fixed path
        "validation",  # Monte Carlo of every path, verdict, robustness
        "figures",
        "replan",  # receding-horizon re-solves inside the closed-loop Monte Carlo
        "beacon_replan",  # the craft's receding horizon inside the closed-loop Monte Carlo
        "results",  # PlanResult, ValidationResult: summary, figures, report, files
        "plan",  # solve + baselines + metrics + validation; validate a given path
        "__init__",
    ),
}

MAX_FUNCTION_LINES = 100


def _module_name(path: Path) -> str:
    parts = ("obsplan", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES: dict[str, Path] = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _import_nodes(tree: ast.AST):
    """Every Import/ImportFrom node, anywhere (``if TYPE_CHECKING:`` bodies included)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node


def _imports(name: str, path: Path) -> set[str]:
    """The obsplan modules that module ``name`` imports (``from pkg import mod`` is ``pkg.mod``)."""
    out: set[str] = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in _import_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            base = node.module or ""
            if node.level:  # relative: from the package, up level - 1
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names
            ]
        out.update(t for t in targets if t == "obsplan" or t.startswith("obsplan."))
    out.discard(name)
    return out


GRAPH: dict[str, set[str]] = {name: _imports(name, path) for name, path in MODULES.items()}


def _stage(name: str) -> int:
    """Index in :data:`STAGES` of the longest listed prefix of ``name``."""
    best, best_len = -1, -1
    for i, (_, prefixes) in enumerate(STAGES):
        for prefix in prefixes:
            full = f"obsplan.{prefix}" if prefix else "obsplan"
            if (name == full or name.startswith(full + ".")) and len(full) > best_len:
                best, best_len = i, len(full)
    return best


def test_the_import_scan_sees_function_level_imports():
    # the cli imports its verbs' heavy dependencies inside functions: the scan must see them
    assert "obsplan.io.waypoints" in GRAPH["obsplan.cli.export"]
    assert "obsplan.planning.validation.validate" in GRAPH["obsplan.cli.simulate"]
    # ... and the facade's lazy obsplan.sweep
    assert "obsplan.sweeps" in GRAPH["obsplan"]


def test_every_module_has_a_stage_and_every_stage_entry_exists():
    assert all(_stage(m) >= 0 for m in MODULES)
    for _, prefixes in STAGES:
        for prefix in prefixes:
            full = f"obsplan.{prefix}" if prefix else "obsplan"
            assert full in MODULES, f"{full} is in STAGES but not in the package"


def test_no_import_goes_up_a_stage():
    bad = [
        f"{a} ({STAGES[_stage(a)][0]}) imports {b} ({STAGES[_stage(b)][0]})"
        for a, targets in GRAPH.items()
        for b in sorted(targets)
        if _stage(b) > _stage(a)
    ]
    assert not bad, "\n".join(bad)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    assert _cycles(GRAPH) == []


def _room(stage: str, module: str) -> int:
    """Index in ``ROOMS[stage]`` of the room holding ``module`` (a module of that stage)."""
    rest = module[len(f"obsplan.{stage}") :].lstrip(".")
    if not rest:
        return ROOMS[stage].index("__init__")
    head = rest.split(".")[0]
    if head in ROOMS[stage]:
        return ROOMS[stage].index(head)
    assert "." not in rest, f"{module} is in no room of {stage}"
    return ROOMS[stage].index("")


@pytest.mark.parametrize("stage", sorted(ROOMS))
def test_rooms_import_only_earlier_rooms(stage):
    prefix = f"obsplan.{stage}"
    inside = {m for m in MODULES if m == prefix or m.startswith(prefix + ".")}
    for room in ROOMS[stage]:
        if room not in ("", "__init__"):
            assert f"{prefix}.{room}" in MODULES, f"ROOMS lists {prefix}.{room}, not in the package"
    bad = [
        f"{a} imports {b}, a later room"
        for a in sorted(inside)
        for b in sorted(GRAPH[a] & inside)
        if _room(stage, b) > _room(stage, a)
    ]
    assert not bad, "\n".join(bad)


def test_no_module_imports_a_facade_it_is_inside():
    packages = {m for m, p in MODULES.items() if p.name == "__init__.py"}
    bad = [
        f"{a} imports {b}, the facade of its own package"
        for a, targets in GRAPH.items()
        for b in sorted(targets & packages)
        if a.startswith(b + ".")
    ]
    assert not bad, "\n".join(bad)


def test_every_package_says_what_its_room_does_and_may_import():
    bad = []
    for name, path in MODULES.items():
        if path.name != "__init__.py" or name in ("obsplan", "obsplan.cli"):
            continue
        doc = ast.get_docstring(ast.parse(path.read_text())) or ""
        if "import" not in doc.lower():
            bad.append(f"{name}: the docstring does not say what the room may import")
    assert not bad, "\n".join(bad)


def _long_functions(folder: Path) -> list[str]:
    out = []
    for path in sorted(folder.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1  # the def to its last line
                body0 = node.body[0]
                if isinstance(body0, ast.Expr) and isinstance(body0.value, ast.Constant):
                    # the docstring is documentation, not code: numpydoc sections must not push
                    # a function over the limit
                    lines -= body0.end_lineno - body0.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    out.append(
                        f"{path.relative_to(folder)}:{node.lineno} {node.name}: {lines} lines"
                    )
    return out


def test_long_function_finder_counts_code_from_def_to_last_line(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES - 1))
    (tmp_path / "ok.py").write_text(f"def f():\n{body}\n")  # exactly the limit
    assert _long_functions(tmp_path) == []
    (tmp_path / "long.py").write_text(f"def g():\n{body}\n    return 0\n")
    assert _long_functions(tmp_path) == [f"long.py:1 g: {MAX_FUNCTION_LINES + 1} lines"]
    # a docstring does not count, however long
    doc = '    """Doc.\n\n' + "    more\n" * 50 + '    """\n'
    (tmp_path / "long.py").write_text(f"def g():\n{doc}{body}\n")
    assert _long_functions(tmp_path) == []


@pytest.mark.parametrize("folder", ["planning", "estimation"])
def test_no_function_longer_than_100_lines(folder):
    long = _long_functions(PACKAGE / folder)
    assert not long, "\n".join(long)


def test_every_objective_kind_is_registered():
    from obsplan.planning.objectives.registry import REGISTRY
    from obsplan.planning.problem.schema import OBJECTIVE_KINDS

    assert list(REGISTRY) == list(OBJECTIVE_KINDS)
    assert all(o.kind == k for k, o in REGISTRY.items())
