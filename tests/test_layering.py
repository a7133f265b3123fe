"""The package's shape, read from its source with ``ast`` (nothing is imported).

- **Direction**: imports flow one way across the layers of :data:`LAYERS`
  (config -> render -> lang -> explore -> checker -> pipeline -> mission ->
  analyses/sweep/phm/report -> cli, on a base of shared modules); every import counts:
  module level, inside functions, under ``if TYPE_CHECKING:``, and module paths written
  as strings for ``importlib`` (lazy exports and commands).
- **No cycles** between modules, counting the imports that run when a module is
  imported (module level, outside ``if TYPE_CHECKING:``); and none either when the
  imports inside functions count too (a deferred import hides a circle, it does not
  remove it).
- **No private names across packages**: ``_name`` is imported only within its own
  package (a sub-package is a package of its own); the base layer's ``_modules`` are
  the exception, meant for all.
- **Small modules**: none over :data:`MAX_LINES` lines but those in :data:`LONG_MODULES`.
- **No import of the package root** (``import veribattery``, ``from veribattery import
  name``) from inside the package: the root is the facade for users.

Each test lists every violation, as ``file:line: what``, in one failure message.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
ROOT = "veribattery"

#: Modules and packages directly under veribattery/ -> layer; a layer imports from its
#: own layer and lower ones only. Rank 0 is the base: shared modules every layer may use.
LAYERS: dict[str, int] = {
    "errors": 0, "_types": 0, "_files": 0, "_text": 0, "_memory": 0, "_sparse": 0,
    "_startup": 0, "_named": 0, "_unique": 0, "_lazy": 0, "_numbers": 0, "_collector": 0,
    "config": 1,
    "render": 2,
    "lang": 3,
    "explore": 4,
    "checker": 5,
    "pipeline": 6,
    "mission": 7,
    "analyses": 8, "sweep": 8, "phm": 8, "report": 8, "synthesis": 8, "strategies": 8,
    "cli": 9,
    "__main__": 10,
}
#: The package root, veribattery/__init__.py: the users' facade over every layer but cli.
ROOT_LAYER = 8.5
#: Within the application layer (8), who may import whom, as the code stands: sweep is
#: the grid runner the others use; a report draws on the analyses. analyses and phm do
#: not import each other.
SIBLINGS: dict[str, frozenset[str]] = {
    "sweep": frozenset({"synthesis"}),
    "analyses": frozenset({"sweep"}),
    "phm": frozenset({"sweep"}),
    "report": frozenset({"analyses", "sweep"}),
    "synthesis": frozenset({"strategies"}),
    "strategies": frozenset(),
}
#: Modules allowed over MAX_LINES, each with the reason it stays whole.
LONG_MODULES: dict[str, str] = {}
MAX_LINES = 500

#: When an import runs: as its module is imported; when the enclosing function is
#: called; never (``if TYPE_CHECKING:``, for annotations); or by ``importlib`` from a
#: module path written as a string (lazy exports, the CLI's lazy commands).
AT_IMPORT, IN_FUNCTION, TYPING, BY_NAME = "at import", "in a function", "TYPE_CHECKING", "by name"


@dataclass(frozen=True)
class Import:
    """One import statement's target, where it is written and when it runs."""

    path: Path
    line: int
    importer: str  # dotted module name
    target: str  # the dotted module imported (the most specific one that is a module)
    name: str | None  # the attribute imported from target (None: the module itself)
    when: str  # AT_IMPORT, IN_FUNCTION, TYPING or BY_NAME

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(SRC.parent)}:{self.line}"


@cache
def modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    found = {}
    for path in sorted((SRC / ROOT).rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def package_of(module: str) -> str:
    """The package a module belongs to (a package's __init__ belongs to itself)."""
    return module if modules()[module].name == "__init__.py" else module.rpartition(".")[0]


def unit_of(module: str) -> str:
    """The top-level module or package under veribattery/ that *module* is part of."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ROOT


def layer_of(unit: str) -> float:
    return ROOT_LAYER if unit == ROOT else LAYERS[unit]


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


class _Collector(ast.NodeVisitor):
    """Every import of a veribattery module in one file, with its context."""

    def __init__(self, module: str, path: Path) -> None:
        self.module, self.path = module, path
        self.found: list[Import] = []
        self.depth = 0  # functions enclosing the current node
        self.type_only = 0  # TYPE_CHECKING blocks enclosing the current node

    def _add(self, node: ast.stmt | ast.expr, target: str, name: str | None,
             by_name: bool = False) -> None:
        when = (BY_NAME if by_name else TYPING if self.type_only
                else IN_FUNCTION if self.depth else AT_IMPORT)
        self.found.append(Import(self.path, node.lineno, self.module, target, name, when))

    def _function(self, node: ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) -> None:
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function

    def visit_If(self, node: ast.If) -> None:
        if not _is_type_checking(node.test):
            self.generic_visit(node)
            return
        self.type_only += 1
        for child in node.body:
            self.visit(child)
        self.type_only -= 1
        for child in node.orelse:
            self.visit(child)

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            if alias.name == ROOT or alias.name.startswith(ROOT + "."):
                self._add(node, _deepest_module(alias.name), None)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        source = self._absolute(node)
        if not (source == ROOT or source.startswith(ROOT + ".")):
            return
        for alias in node.names:
            if f"{source}.{alias.name}" in modules():
                self._add(node, f"{source}.{alias.name}", None)
            else:
                self._add(node, _deepest_module(source), alias.name)

    def visit_Constant(self, node: ast.Constant) -> None:
        text = node.value
        if isinstance(text, str) and text.startswith(ROOT + ".") and text in modules():
            self._add(node, text, None, by_name=True)

    def _absolute(self, node: ast.ImportFrom) -> str:
        if node.level == 0:
            return node.module or ""
        base = package_of(self.module).split(".")
        base = base[: len(base) - (node.level - 1)]
        return ".".join([*base, *([node.module] if node.module else [])])


def _deepest_module(dotted: str) -> str:
    """The longest prefix of *dotted* that is a module of the package."""
    parts = dotted.split(".")
    for end in range(len(parts), 0, -1):
        if ".".join(parts[:end]) in modules():
            return ".".join(parts[:end])
    return dotted


@cache
def imports() -> tuple[Import, ...]:
    """Every import of a veribattery module, in every module of the package."""
    found: list[Import] = []
    for module, path in modules().items():
        collector = _Collector(module, path)
        collector.visit(ast.parse(path.read_text(encoding="utf-8"), str(path)))
        found += collector.found
    return tuple(found)


def _report(title: str, violations: list[str]) -> str:
    return f"{len(violations)} {title}:\n" + "\n".join(violations)


# ---------------------------------------------------------------------------
# (a) direction
# ---------------------------------------------------------------------------


def direction_violations() -> Iterator[str]:
    for imp in imports():
        mine, theirs = unit_of(imp.importer), unit_of(imp.target)
        if mine == theirs or theirs == ROOT:  # the root: test (e)
            continue
        if layer_of(mine) > layer_of(theirs):
            continue
        if layer_of(mine) == layer_of(theirs) and theirs in SIBLINGS.get(mine, frozenset()):
            continue
        if layer_of(mine) == 0 == layer_of(theirs):
            continue  # the base modules use each other
        yield (f"{imp.where}: {mine} (layer {layer_of(mine):g}) imports {imp.target} "
               f"({theirs}, layer {layer_of(theirs):g}) {imp.when}")


def test_every_unit_has_a_layer() -> None:
    units = {unit_of(m) for m in modules()} - {ROOT}
    assert len(units) >= 15, units  # the scan found the package
    assert units <= set(LAYERS), f"give these a layer in LAYERS: {sorted(units - set(LAYERS))}"
    application = {u for u, rank in LAYERS.items() if rank == LAYERS["sweep"]}
    assert application == set(SIBLINGS), "SIBLINGS lists every application-layer package"


def test_imports_flow_one_way() -> None:
    assert len(imports()) > 500  # the scan sees the imports
    violations = list(direction_violations())
    assert not violations, _report("imports against the layer order", violations)


# ---------------------------------------------------------------------------
# (b) cycles
# ---------------------------------------------------------------------------


def import_graph(counted: frozenset[str]) -> dict[str, dict[str, Import]]:
    """importer -> {imported module: its first import}, over the imports whose ``when``
    is in *counted*."""
    graph: dict[str, dict[str, Import]] = {m: {} for m in modules()}
    for imp in imports():
        if imp.when in counted and imp.target in modules() and imp.target != imp.importer:
            graph[imp.importer].setdefault(imp.target, imp)
    return graph


def strongly_connected(graph: dict[str, dict[str, Import]]) -> list[list[str]]:
    """Tarjan's components of more than one module, each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in graph[node]:
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def shortest_cycle(graph: dict[str, dict[str, Import]], members: list[str]) -> list[Import]:
    """A shortest cycle through the first module of a component, as its imports."""
    start, inside = members[0], set(members)
    came: dict[str, Import] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for nxt, imp in graph[node].items():
                if nxt == start:
                    path = [imp]
                    while path[0].importer != start:
                        path.insert(0, came[path[0].importer])
                    return path
                if nxt in inside and nxt not in came:
                    came[nxt] = imp
                    following.append(nxt)
        frontier = following
    raise AssertionError(f"no cycle through {start}")


def cycle_violations(counted: frozenset[str]) -> Iterator[str]:
    graph = import_graph(counted)
    for members in strongly_connected(graph):
        steps = "; ".join(f"{imp.where} {imp.importer} -> {imp.target} ({imp.when})"
                          for imp in shortest_cycle(graph, members))
        yield f"cycle among {', '.join(members)}: e.g. {steps}"


def test_no_import_cycles() -> None:
    """No cycle among the imports that run when a module is imported."""
    counted = frozenset({AT_IMPORT})
    assert sum(len(v) for v in import_graph(counted).values()) > 300  # the graph is there
    violations = list(cycle_violations(counted))
    assert not violations, _report("import cycles (module-level imports)", violations)


def test_no_dependency_cycles() -> None:
    """No cycle either when imports inside functions count: a function-local import
    that only defers one side of a mutual dependency still makes a circle."""
    violations = list(cycle_violations(frozenset({AT_IMPORT, IN_FUNCTION})))
    assert not violations, _report("dependency cycles (imports at module level or in "
                                   "functions)", violations)


# ---------------------------------------------------------------------------
# (c) private names
# ---------------------------------------------------------------------------


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_violations() -> Iterator[str]:
    shared = {f"{ROOT}.{unit}" for unit, rank in LAYERS.items() if rank == 0}
    for imp in imports():
        dotted = imp.target + (f".{imp.name}" if imp.name else "")
        parts = dotted.split(".")
        for i, part in enumerate(parts):
            if not _private(part) or ".".join(parts[: i + 1]) in shared:
                continue
            owner = ".".join(parts[:i])  # a package, or the module defining the name
            owner = package_of(owner) if owner in modules() else owner
            if owner != package_of(imp.importer):
                yield (f"{imp.where}: {package_of(imp.importer)} imports the private "
                       f"{'.'.join(parts[: i + 1])} of {owner}")
            break


def test_no_private_names_across_packages() -> None:
    violations = list(private_violations())
    assert not violations, _report("private names imported from another package", violations)


# ---------------------------------------------------------------------------
# (d) module size
# ---------------------------------------------------------------------------


def long_modules() -> dict[str, int]:
    """Module -> line count, for every module over MAX_LINES lines."""
    counts = {m: len(p.read_text(encoding="utf-8").splitlines()) for m, p in modules().items()}
    return {m: n for m, n in counts.items() if n > MAX_LINES}


def test_no_module_over_the_limit() -> None:
    found = long_modules()
    violations = [f"{modules()[m].relative_to(SRC.parent)}:1: {n} lines"
                  for m, n in sorted(found.items(), key=lambda item: -item[1])
                  if m not in LONG_MODULES]
    assert not violations, _report(f"modules over {MAX_LINES} lines", violations)


def test_allowed_long_modules_are_still_long() -> None:
    """An entry of LONG_MODULES goes once its module is short again (or gone)."""
    stale = sorted(set(LONG_MODULES) - set(long_modules()))
    assert not stale, f"no longer over {MAX_LINES} lines: remove from LONG_MODULES: {stale}"


# ---------------------------------------------------------------------------
# (e) the package root
# ---------------------------------------------------------------------------


def root_violations() -> Iterator[str]:
    for imp in imports():
        if imp.target == ROOT and imp.importer != ROOT:
            what = f"from {ROOT} import {imp.name}" if imp.name else f"import {ROOT}"
            yield f"{imp.where}: {imp.importer}: {what}"


def test_package_root_not_imported_from_inside() -> None:
    violations = list(root_violations())
    assert not violations, _report("imports of the package root", violations)
