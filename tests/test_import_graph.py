"""The import graph of tipgeo, cam and gcode has no circle (issue 30).

Built statically with :mod:`ast` from the source files: import statements at
module top level and inside functions and classes, and — where said — those
under ``if TYPE_CHECKING:`` (a type-only import is still a dependency the
reader and the type checker follow; the old circle ``cutters → io → tip →
spec → cutters`` ran through one, ``tip → spec``).

An edge ``a → b`` means module ``a`` names module ``b`` in an import:
``from p import name`` is an edge to ``p.name`` when that is a module, else
to ``p`` (its ``__init__``). The parents Python also runs when it imports
``a.b.c`` (``a/__init__``, ``a/b/__init__``) are not edges: every package
whose ``__init__`` re-exports its submodules would otherwise be a circle with
each of them, which is how packages work, not a design dependency.

Asserted at two granularities:

1. **units** — a module collapsed to its first two dotted parts
   (``tipgeo.cutters``, ``tipgeo.io``, ``tipgeo.tip``, ``tipgeo.spec``,
   ``cam.mill``, ``gcode.parser``; the granularity of the issue's circle),
   EVERY import counted, type-only ones too: no circle (edges inside one
   unit ignored). This is the layering: a lower unit never names a higher
   one, not even in an annotation.
2. **modules** (``tipgeo.cutters.custom``, ``tipgeo.io.load`` …), the imports
   that run (top level and inside functions): no circle.

Allowed, so not asserted: a circle between modules of ONE unit that closes
only through ``if TYPE_CHECKING:`` imports (a result type and the module
that reports it naming each other in annotations, e.g.
``tipgeo.inspect.compare`` ⇄ ``tipgeo.inspect.report``): it never runs and
stays inside one package. And the coarsest granularity, the three top-level
packages: the command line ``tipgeo.cli`` drives ``cam`` and ``gcode``
(``tipgeo mill``, ``tipgeo laser``), which are built on tipgeo's library, so
``tipgeo ⇄ cam`` there by design; one level down (1.) the CLI and the
library are separate units and the graph is a DAG.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("tipgeo", "cam", "gcode")


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package ``__init__``)."""
    out = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            out[".".join(parts[:-1] if is_pkg else parts)] = (f, is_pkg)
    return out


MODULES = _modules()


def _absolute(mod: str, is_pkg: bool, level: int, name: str | None) -> str:
    """The absolute module a (possibly relative) ``from`` import names."""
    if not level:
        return name or ""
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _targets(mod: str, is_pkg: bool, node: ast.AST) -> Iterator[str]:
    """The modules one import statement names (any, in- or outside the
    project)."""
    if isinstance(node, ast.Import):
        for a in node.names:
            yield a.name
    elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
        base = _absolute(mod, is_pkg, node.level, node.module)
        for a in node.names:
            sub = f"{base}.{a.name}"
            yield sub if sub in MODULES else base


def _nodes(tree: ast.AST, type_checking: bool) -> Iterator[ast.AST]:
    """Every node, or (``type_checking`` False) every node outside the
    bodies of ``if TYPE_CHECKING:`` (their ``else:`` runs, so it stays)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if not type_checking and isinstance(child, ast.If) \
                    and "TYPE_CHECKING" in ast.unparse(child.test):
                stack.extend(child.orelse)
                continue
            stack.append(child)


def _module_graph(*, type_checking: bool) -> dict[str, set[str]]:
    """Module -> the project modules it imports (with the type-only imports
    when ``type_checking``)."""
    g: dict[str, set[str]] = {m: set() for m in MODULES}
    for mod, (path, is_pkg) in MODULES.items():
        for node in _nodes(ast.parse(path.read_text(encoding="utf-8")), type_checking):
            g[mod] |= {t for t in _targets(mod, is_pkg, node) if t in MODULES and t != mod}
    return g


def _collapse(g: dict[str, set[str]], unit: Callable[[str], str]) -> dict[str, set[str]]:
    """The graph between units (edges inside one unit dropped)."""
    out: dict[str, set[str]] = {unit(m): set() for m in g}
    for a, targets in g.items():
        out[unit(a)] |= {unit(b) for b in targets if unit(b) != unit(a)}
    return out


def _unit(mod: str) -> str:
    return ".".join(mod.split(".")[:2])


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node, each sorted
    (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    for root in sorted(g):
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        work = [(root, iter(sorted(g[root])))]
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(g[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out)


def test_the_cycle_finder_finds_cycles_and_only_cycles():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"d"}, "d": {"c", "a"}}) == [["a", "b"],
                                                                               ["c", "d"]]
    assert _cycles({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == []


def test_imports_inside_functions_and_type_checking_blocks_are_edges():
    every, run = _module_graph(type_checking=True), _module_graph(type_checking=False)
    assert "tipgeo.spec" in every["tipgeo.tip"]  # under `if TYPE_CHECKING:` only
    assert "tipgeo.spec" not in run["tipgeo.tip"]
    assert "tipgeo.names" in run["tipgeo.cutters.base"]  # inside check_name only
    assert "tipgeo.cutters.base" in run["tipgeo.spec"]  # `from .cutters.base import …`
    assert "tipgeo.cutters" in run["tipgeo.spec"]  # `from .cutters import Cutter`


def test_the_old_circle_would_be_found():
    """The edge the mesh cutter had (``from ..io import load_tip``) closes the
    circle of the issue again: between units, and between modules once the
    type-only ``tip → spec`` counts."""
    g = _module_graph(type_checking=True)
    g["tipgeo.cutters.custom"].add("tipgeo.io")
    circle = {"tipgeo.cutters.custom", "tipgeo.io", "tipgeo.tip", "tipgeo.spec"}
    assert any(circle <= set(c) for c in _cycles(g))
    assert ["tipgeo.cutters", "tipgeo.io", "tipgeo.spec", "tipgeo.tip"] in _cycles(
        _collapse(g, _unit))


def test_no_circle_between_units():
    assert _cycles(_collapse(_module_graph(type_checking=True), _unit)) == []


def test_no_circle_between_modules_at_run_time():
    assert _cycles(_module_graph(type_checking=False)) == []
