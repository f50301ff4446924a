"""The seams hold: no import cycle among the library's modules (imports
inside functions counted, ``if TYPE_CHECKING:`` blocks not), none between its
units even with type-only imports counted (issue 30: the old circle
``cutters → io → tip → spec → cutters`` ran through one), no ``_private``
name imported from another module, cam/ and gcode/ on tipgeo's public API
only, and no module outside ``tipgeo/cutters/`` dispatching on a cutter
class."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("tipgeo", "cam", "gcode")


def _modules() -> dict[str, tuple[Path, bool]]:
    out = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            out[".".join(parts[:-1] if is_pkg else parts)] = (f, is_pkg)
    return out


MODULES = _modules()


def _nodes(tree: ast.AST, type_checking: bool = False):
    """Every node, or (``type_checking`` False) every node outside the bodies
    of ``if TYPE_CHECKING:`` (their ``else:`` runs, so it stays)."""
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


def _absolute(mod: str, is_pkg: bool, level: int, name: str | None) -> str:
    if not level:
        return name or ""
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _imports(type_checking: bool = False):
    """(module, imported module, imported name or None) for every import
    (with the type-only ones when ``type_checking``)."""
    for mod, (path, is_pkg) in MODULES.items():
        for node in _nodes(ast.parse(path.read_text(encoding="utf-8")), type_checking):
            if isinstance(node, ast.Import):
                for a in node.names:
                    yield mod, a.name, None
            elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
                target = _absolute(mod, is_pkg, node.level, node.module)
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    yield (mod, sub, None) if sub in MODULES else (mod, target, a.name)


IMPORTS = list(_imports())


def _graph(type_checking: bool = False) -> dict[str, set[str]]:
    """Module -> the project modules it imports: ``from p import name`` is an
    edge to ``p.name`` when that is a module, else to ``p``. The parents
    Python also runs (``a/__init__`` for ``a.b``) are not edges: a package
    re-exporting its submodules would otherwise be a circle with each."""
    g: dict[str, set[str]] = {m: set() for m in MODULES}
    for mod, target, _ in (IMPORTS if not type_checking else _imports(True)):
        if target in MODULES and target != mod:
            g[mod].add(target)
    return g


def _unit(mod: str) -> str:
    """A module's unit: its first two dotted parts (``tipgeo.cutters``,
    ``tipgeo.io``, ``cam.mill``, ``gcode.parser``)."""
    return ".".join(mod.split(".")[:2])


def _collapse(g: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph between units (edges inside one unit dropped)."""
    out: dict[str, set[str]] = {_unit(m): set() for m in g}
    for a, targets in g.items():
        out[_unit(a)] |= {_unit(b) for b in targets if _unit(b) != _unit(a)}
    return out


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan,
    iterative)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in g:
        if root in index:
            continue
        work = [(root, iter(sorted(g[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
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
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    assert _cycles(_graph()) == []


def test_no_private_names_across_modules():
    bad = [f"{mod} imports {name} from {target}" for mod, target, name in IMPORTS
           if name and name.startswith("_") and not name.startswith("__")
           and target in MODULES]
    assert bad == []


def test_cam_and_gcode_use_only_tipgeo_public_modules():
    bad = [f"{mod} imports {target}" for mod, target, _ in IMPORTS
           if mod.split(".")[0] in ("cam", "gcode") and target.startswith("tipgeo.")
           and any(p.startswith("_") for p in target.split(".")[1:])]
    assert bad == []


@pytest.mark.parametrize("mod", sorted(m for m in MODULES if not m.startswith("tipgeo.cutters")))
def test_no_dispatch_on_cutter_classes_outside_cutters(mod):
    from tipgeo.cutters import __all__ as cutter_names

    classes = {n for n in cutter_names if n.endswith("Cutter") and n != "Cutter"}  # base: ok
    tree = ast.parse(MODULES[mod][0].read_text(encoding="utf-8"))
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ("isinstance",
                                                                             "issubclass"):
            names = {n.id if isinstance(n, ast.Name) else getattr(n, "attr", None)
                     for n in ast.walk(node.args[1])}
            bad += sorted(names & classes)
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) \
                and node.left.attr == "kind" and any(
                    isinstance(c, ast.Constant) and isinstance(c.value, str)
                    and c.value in _kinds() for c in node.comparators):
            bad.append(ast.unparse(node))
    assert bad == [], f"{mod} dispatches on cutter classes: {bad}"


def _kinds() -> set[str]:
    from tipgeo.cutters import CUTTER_KINDS

    return set(CUTTER_KINDS)


def test_imports_inside_functions_and_type_checking_blocks_are_edges():
    every, run = _graph(type_checking=True), _graph()
    assert "tipgeo.spec" in every["tipgeo.tip"]  # under `if TYPE_CHECKING:` only
    assert "tipgeo.spec" not in run["tipgeo.tip"]
    assert "tipgeo.names" in run["tipgeo.cutters.base"]  # inside check_name only
    assert "tipgeo.cutters" in run["tipgeo.spec"]  # `from .cutters import Cutter`


def test_the_old_circle_would_be_found():
    """The edge the mesh cutter had (``from ..io import load_tip``) closes the
    issue's circle again: between units, and between modules once the
    type-only ``tip → spec`` counts."""
    g = _graph(type_checking=True)
    g["tipgeo.cutters.custom"].add("tipgeo.io")
    circle = {"tipgeo.cutters.custom", "tipgeo.io", "tipgeo.tip", "tipgeo.spec"}
    assert any(circle <= set(c) for c in _cycles(g))
    assert ["tipgeo.cutters", "tipgeo.io", "tipgeo.spec", "tipgeo.tip"] in _cycles(_collapse(g))


def test_no_circle_between_units_type_only_imports_counted():
    """Units (a module's first two dotted parts), every import counted: a lower
    unit never names a higher one, not even in an annotation. A circle inside
    one unit that closes only through type-only imports (a result type and
    the module reporting it) never runs and is allowed; the three top-level
    packages are not compared (``tipgeo.cli`` drives ``cam`` and ``gcode``
    by design)."""
    assert _cycles(_collapse(_graph(type_checking=True))) == []
