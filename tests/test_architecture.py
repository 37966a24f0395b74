"""The package's architecture, checked on its source: imports go one way and functions stay short.

Every ``import`` statement in ``obsplan/`` is read from the syntax tree, wherever it is (module
level, inside functions, inside ``try``), so a function-level import cannot hide a cycle. The one
exception is an import under ``if TYPE_CHECKING:``: it never runs and serves annotations only
(``planning/checks.py`` annotates with the ``PlanningProblem`` whose construction runs it).

* :data:`STAGES` gives every module its stage; a module may import its own stage and lower ones;
* the module graph has no cycle;
* inside ``obsplan/planning`` the rooms of :data:`PLANNING_ORDER` import only earlier rooms;
* no function in ``obsplan/planning`` (and ``obsplan/estimation``) is longer than 100 lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import obsplan

PACKAGE = Path(obsplan.__file__).resolve().parent

#: ``(stage, modules)`` from the bottom up; a module (or a package and everything in it) may
#: import only from its own stage or a lower one. The longest listed prefix of a module's name
#: gives its stage.
STAGES: tuple[tuple[str, tuple[str, ...]], ...] = (
    # no obsplan imports but the errors: exceptions, the version, signals, atomic file writes,
    # safe output folders, the cost budget, the vehicle model, geodetic conversions, reading user
    # text files (encodings, magnitudes)
    (
        "foundations",
        (
            "errors",
            "version",
            "interrupts",
            "atomic",
            "outputs",
            "budget",
            "model",
            "geodesy",
            "textfiles",
        ),
    ),
    # sampled paths, their CSV form (csvtable) and the motion classes of Tables 1-3
    ("trajectory", ("trajectory", "csvtable", "generators")),
    ("observability", ("observability",)),
    ("estimation", ("estimation",)),
    # the paper's scenarios and figures: observability and estimation, nothing from planning
    ("paper", ("paper", "paper_figures", "plots")),
    ("planning", ("planning",)),
    # real inputs and outputs, parameter studies: beside each other, above planning
    ("io-sweeps", ("io", "sweeps")),
    # the command line and the public facade (obsplan/__init__.py imports every stage)
    ("cli", ("cli", "__main__", "")),
)

#: The rooms of ``obsplan/planning`` from the bottom up: each imports only rooms before it.
PLANNING_ORDER: tuple[str, ...] = (
    "schema",  # the problem file declared: fields, units, defaults, objective kinds
    "mission_spec",  # the [mission]: lines, waypoints, end region, generated lines
    "mission_schedule",  # the mission's constant-speed schedule: windows, shortest horizon
    "mission_order",  # mission.order = "free": the order and directions of the lines
    "checks",  # cheap checks (on construction) and structural rank checks (before solving)
    "problem",  # the frozen dataclasses
    "parse",  # files and mappings <-> problems (geodetic fields included)
    "validation_setup",  # the validation's filter configuration and epochs
    "feasibility",  # independent numpy check of the limits on the continuous path
    "mission_check",  # independent numpy check that a path completes the mission
    "mission_baselines",  # the schedule flown on the planning grid (mission lawn-mowers)
    "baselines",  # lawn-mower, circle, ...
    "grid",  # decision variables in intrinsic units, sample operator, dynamics
    "guesses",  # initial guesses, reference path, coarse grid
    "blocks",  # NLP building blocks and the objective interface
    "mission_part",  # the mission's constraints (lines, waypoints, end region)
    "windowed_gramian",  # information-weighted windowed Gramians
    "gramian_objectives",
    "lwo_objective",
    "estimator_objectives",
    "robust",  # an estimator objective over a family of conditions (worst case or mean)
    "objectives",  # the registry by objective.kind
    "linearisation",  # the EKF's linearisation stress along a path, the planner's penalty on it
    "evaluate",  # objective values and path metrics on a path
    "formulation",  # path constraints, bounds, assembly
    "ipopt",  # nlpsol construction and calls, projection, Ctrl-C
    "starts",  # one IPOPT run per guess, serial or in processes
    "solve",  # strategy: multi-start, coarse-to-fine, candidates
    "margins",  # keep-out margins from the predicted uncertainty, re-solve with tightened limits
    "validation",  # Monte Carlo of the filters on every path
    "verdict",
    "stress",  # every path re-validated at stated multiples of the prior and range noise
    "figures",
    "replan",  # receding-horizon re-solves inside the closed-loop Monte Carlo
    "plan",  # solve + baselines + metrics + validation
    "__init__",  # the planning package's public API
)

MAX_FUNCTION_LINES = 100


def _module_name(path: Path) -> str:
    parts = ("obsplan", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES: dict[str, Path] = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _import_nodes(tree: ast.AST):
    """Every Import/ImportFrom node, anywhere, except the bodies of ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        stack.extend(ast.iter_child_nodes(node))


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
    assert "obsplan.planning.validation" in GRAPH["obsplan.cli.simulate"]
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


def test_planning_rooms_import_only_earlier_rooms():
    rooms = {
        f"obsplan.planning.{r}" if r != "__init__" else "obsplan.planning": i
        for i, r in enumerate(PLANNING_ORDER)
    }
    planning = {m for m in MODULES if m == "obsplan.planning" or m.startswith("obsplan.planning.")}
    assert planning == set(rooms), "PLANNING_ORDER must list every planning module"
    bad = [
        f"{a} imports {b}, a later room"
        for a in sorted(planning)
        for b in sorted(GRAPH[a] & planning)
        if rooms[b] >= rooms[a]
    ]
    assert not bad, "\n".join(bad)


def _long_functions(folder: Path) -> list[str]:
    out = []
    for path in sorted(folder.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1  # the def to its last line
                if lines > MAX_FUNCTION_LINES:
                    out.append(
                        f"{path.relative_to(folder)}:{node.lineno} {node.name}: {lines} lines"
                    )
    return out


def test_long_function_finder_counts_from_def_to_last_line(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES - 1))
    (tmp_path / "ok.py").write_text(f"def f():\n{body}\n")  # exactly the limit
    assert _long_functions(tmp_path) == []
    (tmp_path / "long.py").write_text(f"def g():\n{body}\n    return 0\n")
    assert _long_functions(tmp_path) == [f"long.py:1 g: {MAX_FUNCTION_LINES + 1} lines"]


@pytest.mark.parametrize("folder", ["planning", "estimation"])
def test_no_function_longer_than_100_lines(folder):
    long = _long_functions(PACKAGE / folder)
    assert not long, "\n".join(long)


def test_every_objective_kind_is_registered():
    from obsplan.planning.objectives import REGISTRY
    from obsplan.planning.schema import OBJECTIVE_KINDS

    assert list(REGISTRY) == list(OBJECTIVE_KINDS)
    assert all(o.kind == k for k, o in REGISTRY.items())
