"""The seams hold: no import cycle among the library's modules (imports
inside functions counted, ``if TYPE_CHECKING:`` blocks not), no ``_private``
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


def _runtime_nodes(tree: ast.AST):
    """Every node except those under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                stack.extend(child.orelse)
                continue
            stack.append(child)


def _absolute(mod: str, is_pkg: bool, level: int, name: str | None) -> str:
    if not level:
        return name or ""
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _imports():
    """(module, imported module, imported name or None) for every import."""
    for mod, (path, is_pkg) in MODULES.items():
        for node in _runtime_nodes(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                for a in node.names:
                    yield mod, a.name, None
            elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
                target = _absolute(mod, is_pkg, node.level, node.module)
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    yield (mod, sub, None) if sub in MODULES else (mod, target, a.name)


IMPORTS = list(_imports())


def _graph() -> dict[str, set[str]]:
    g = {m: set() for m in MODULES}
    for mod, target, _ in IMPORTS:
        if target in MODULES and target != mod:
            g[mod].add(target)
    return g


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
