"""The layer order of ``docs/design.md`` ("Layers"), enforced on the source.

Every module under ``airfisheye_bench/``, ``datamodules/`` and ``models/`` is parsed with :mod:`ast` (nothing is
imported); every ``import`` of a project module, at module level or inside a function, is an edge from the
importing module's *unit* (a row entry of :data:`LAYERS`) to the imported one's. The rules:

- an edge stays in its unit or goes to a unit of an earlier row;
- the module graph has no cycle (a cycle inside a unit hides an order the layers do not show);
- a project module is imported at module level, never inside a function: a deferred import hid the upward
  edges this test now forbids, and nothing of the project is an optional dependency. Two units may defer, with
  a comment, and their edges still must go down: ``cli``, whose console entry points each import their own
  command when called, so that one command does not load every other's dependencies; and ``config_checks``,
  which reads every choice list one way, from the module that defines it, when its key is checked (so a mistyped
  value is answered before torch or the model zoo is imported; docs/design.md, "Layers");
- a third-party (or standard-library) import inside a function carries a comment, on its line or the line above,
  saying why it is deferred (an optional or slow-to-import dependency used by one path: ``onnxruntime``,
  ``matplotlib``, ``scipy``, ...); an import right below such a commented one shares its reason.

``scripts/``, ``train.py`` and ``tests/`` may import anything and are not checked.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("airfisheye_bench", "datamodules", "models")

#: Bottom first. A unit is a subpackage or top-level module of ``airfisheye_bench`` (``io``, ``runs``, ...) or a
#: top-level package (``models``, ``datamodules``). Units of one row may not import each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "moved"),
    ("constants", "atomic"),
    ("geometry",),
    ("metrics",),
    ("specs",),
    ("io",),
    ("models",),
    ("config_checks",),
    ("synth",),
    ("datamodules",),
    ("viz",),
    ("runs", "checkpointing", "sweeps", "progress"),
    ("tracking",),
    ("tasks",),
    ("evaluation", "training"),
    ("export", "prediction"),
    ("studies", "dataset_tools"),
    ("cli",),
)
RANK = {unit: rank for rank, row in enumerate(LAYERS) for unit in row}
TOP = LAYERS[-1][0]  # the console entry points
#: Units allowed to import a project module inside a function, with a comment saying why (see the docstring).
DEFERRING = frozenset({TOP, "config_checks"})


@dataclass(frozen=True)
class Edge:
    """One import statement's target: ``source`` imports ``target`` at ``path:line``."""

    source: str
    target: str
    path: str
    line: int
    local: bool  # inside a function body

    def where(self) -> str:
        return f"{self.path}:{self.line}"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _source_files() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


MODULES = {_module_name(p): p for p in _source_files()}


def unit_of(module: str) -> str:
    """``airfisheye_bench.io.codecs`` -> ``io``; ``models.nlspn.model`` -> ``models``."""
    parts = module.split(".")
    if parts[0] == "airfisheye_bench":
        return parts[1] if len(parts) > 1 else "airfisheye_bench"
    return parts[0]


def _function_local_nodes(tree: ast.AST) -> set[int]:
    local: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            local.update(id(sub) for sub in ast.walk(node) if isinstance(sub, (ast.Import, ast.ImportFrom)))
    return local


def _targets(node: ast.Import | ast.ImportFrom, module: str, is_package: bool) -> list[str]:
    """Absolute names of the modules ``node`` imports (``from pkg import submodule`` names the submodule)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        origin = ".".join(base + ([node.module] if node.module else []))
    else:
        origin = node.module or ""
    names = [f"{origin}.{alias.name}" for alias in node.names]
    submodules = [name for name in names if name in MODULES]
    return submodules if len(submodules) == len(names) else [origin, *submodules]


@dataclass(frozen=True)
class Statement:
    """One ``import`` statement of a checked module."""

    module: str
    path: str
    node: ast.Import | ast.ImportFrom
    local: bool  # inside a function body
    targets: tuple[str, ...]
    lines: tuple[str, ...]  # the file's source lines

    @property
    def project(self) -> tuple[str, ...]:
        return tuple(t for t in self.targets if t.split(".")[0] in PACKAGES)


def _statements() -> list[Statement]:
    out = []
    for path in _source_files():
        source = path.read_text(encoding="utf-8")
        tree = ast.parse(source, filename=str(path))
        module, is_package = _module_name(path), path.name == "__init__.py"
        local = _function_local_nodes(tree)
        lines = tuple(source.splitlines())
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                targets = tuple(_targets(node, module, is_package))
                out.append(Statement(module, rel, node, id(node) in local, targets, lines))
    return out


STATEMENTS = _statements()
EDGES = [Edge(s.module, target, s.path, s.node.lineno, s.local) for s in STATEMENTS for target in s.project]


def test_every_module_belongs_to_a_layer() -> None:
    unknown = sorted(
        f"{unit_of(m)} ({p.relative_to(ROOT)})"
        for m, p in MODULES.items()
        if unit_of(m) not in RANK and m != "airfisheye_bench"
    )
    assert not unknown, (
        "modules outside the layer order; add their unit to LAYERS here and to docs/design.md (Layers): "
        + ", ".join(unknown)
    )


def test_the_package_root_imports_nothing_of_the_project() -> None:
    # Only the finder of the moved import paths (standard library only): importing the package stays free.
    edges = [
        e.where() for e in EDGES if e.source == "airfisheye_bench" and e.target != "airfisheye_bench.moved"
    ]
    assert not edges, f"airfisheye_bench/__init__.py must stay empty of project imports: {edges}"


def test_imports_go_down_the_layers() -> None:
    upward = []
    for edge in EDGES:
        source, target = unit_of(edge.source), unit_of(edge.target)
        if source == target or target == "airfisheye_bench" or source not in RANK or target not in RANK:
            continue
        if RANK[target] >= RANK[source]:
            rule = "a unit of the same row" if RANK[target] == RANK[source] else "a higher layer"
            upward.append(f"{edge.where()}: {source} imports {edge.target} ({target}, {rule})")
    order = " < ".join(", ".join(row) for row in LAYERS)
    assert not upward, f"imports against the layer order ({order}):\n  " + "\n  ".join(upward)


def test_no_import_cycle_between_modules() -> None:
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    where: dict[tuple[str, str], str] = {}
    for edge in EDGES:
        if edge.target in MODULES and edge.target != edge.source:
            graph[edge.source].add(edge.target)
            where.setdefault((edge.source, edge.target), edge.where())
    cycles = [c for c in _strongly_connected(graph) if len(c) > 1]
    details = []
    for cycle in cycles:
        members = set(cycle)
        inner = sorted(f"{where[(a, b)]} ({a} -> {b})" for a in cycle for b in graph[a] if b in members)
        details.append("cycle " + ", ".join(sorted(cycle)) + ":\n    " + "\n    ".join(inner))
    assert not cycles, "import cycles:\n  " + "\n  ".join(details)


def _commented(s: Statement) -> bool:
    line, above = s.lines[s.node.lineno - 1], s.lines[s.node.lineno - 2].strip() if s.node.lineno > 1 else ""
    return "#" in line or above.startswith("#")


def test_no_function_local_import_of_a_project_module() -> None:
    local = sorted(
        f"{s.path}:{s.node.lineno}: {', '.join(s.project)}"
        for s in STATEMENTS
        if s.local and s.project and not (unit_of(s.module) in DEFERRING and _commented(s))
    )
    assert not local, (
        "project modules are imported at module level (a deferred import hides a layer edge; only "
        f"{sorted(DEFERRING)} defer, with a comment):\n  " + "\n  ".join(local)
    )


def test_function_local_third_party_imports_say_why() -> None:
    silent = []
    explained: dict[str, int] = {}  # file -> last line of its last explained local import (a group shares it)
    for s in sorted(
        (s for s in STATEMENTS if s.local and not s.project), key=lambda s: (s.path, s.node.lineno)
    ):
        first = s.node.lineno
        if _commented(s) or explained.get(s.path) == first - 1:
            explained[s.path] = s.node.end_lineno or first
            continue
        silent.append(f"{s.path}:{first}: {s.lines[first - 1].strip()}")
    assert not silent, (
        "imports inside a function need a comment saying why they are deferred (an optional or slow dependency "
        "used by one path), else belong at the top of the module:\n  " + "\n  ".join(silent)
    )


def test_design_doc_states_the_enforced_order() -> None:
    order = " < ".join(", ".join(f"`{unit}`" for unit in row) for row in LAYERS)
    assert order in (ROOT / "docs" / "design.md").read_text(encoding="utf-8"), (
        f"docs/design.md (Layers) must state the order this test enforces: {order}"
    )


def _strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm, iterative (the module graph is a few hundred nodes)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    components.append(component)
    return components


@pytest.mark.parametrize(
    ("module", "unit"),
    [
        ("airfisheye_bench.io.codecs", "io"),
        ("airfisheye_bench.runs", "runs"),
        ("airfisheye_bench.runs.results", "runs"),
        ("airfisheye_bench.studies.paired", "studies"),
        ("models.nlspn.model", "models"),
    ],
)
def test_unit_of(module: str, unit: str) -> None:
    assert unit_of(module) == unit


@pytest.mark.parametrize(
    ("graph", "cyclic"),
    [({"a": {"b"}, "b": {"c"}, "c": set()}, False), ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, True)],
)
def test_cycle_finder(graph: dict[str, set[str]], cyclic: bool) -> None:
    assert any(len(c) > 1 for c in _strongly_connected(graph)) is cyclic
