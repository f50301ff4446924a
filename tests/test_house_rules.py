"""The house rules a newcomer can rely on (issue 30), checked on the source.

- every function and method of ``tipgeo``, ``cam`` and ``gcode`` has a
  cyclomatic complexity of at most :data:`MAX_COMPLEXITY` (radon's grade C or
  better), the figure CI's ``xenon`` gate checks too;
- every tolerance lives in :mod:`tipgeo.tolerances` with its reason: a small
  float literal (0 < |x| < 1e-3) appears nowhere else, except as the value of
  a documented module-level ``UPPER_CASE`` constant (a unit factor, a physical
  constant) — so no loose ``1e-9`` hides in a function body;
- the packages ship their ``py.typed`` marker, so users' type checkers read
  tipgeo's annotations (CI runs ``mypy --strict`` on all three packages).
"""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("tipgeo", "cam", "gcode")

#: Highest cyclomatic complexity a function may have (radon grade C: 11–20).
MAX_COMPLEXITY = 20

#: Literals below this magnitude are tolerances (or unit factors) by nature.
SMALL_FLOAT = 1.0e-3


def _sources() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def _complex_functions(source: str, name: str) -> list[str]:
    from radon.complexity import cc_visit

    found = []
    for block in cc_visit(source):
        blocks = [block, *getattr(block, "methods", []), *getattr(block, "closures", [])]
        for b in blocks:
            if b.complexity > MAX_COMPLEXITY:
                found.append(f"{name}:{b.lineno} {b.fullname} ({b.complexity})")
    return found


def test_no_function_above_complexity_limit():
    pytest.importorskip("radon", reason="pip install radon (in the test extra)")
    found = [f for p in _sources()
             for f in _complex_functions(p.read_text(encoding="utf-8"),
                                         str(p.relative_to(ROOT)))]
    assert not found, "functions above complexity 20:\n" + "\n".join(found)


def test_complexity_check_sees_a_complex_function():
    """The check above can fail: a function of 21 branches is reported."""
    pytest.importorskip("radon", reason="pip install radon (in the test extra)")
    def source(branches: int) -> str:
        body = "".join(f"    if x == {i}:\n        return {i}\n" for i in range(branches))
        return f"def f(x):\n{body}    return -1\n"

    assert _complex_functions(source(20), "toy.py") == ["toy.py:1 f (21)"]
    assert _complex_functions(source(19), "toy.py") == []


def _documented_constant(tree: ast.Module, comments: set[int]) -> set[int]:
    """Ids of the literal nodes that are the value of a module-level
    UPPER_CASE constant with a ``#:`` comment on the line above."""
    allowed: set[int] = set()
    for stmt in tree.body:
        target = None
        if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1:
            target = stmt.targets[0]
        elif isinstance(stmt, ast.AnnAssign):
            target = stmt.target
        if (isinstance(target, ast.Name) and target.id.isupper()
                and stmt.lineno - 1 in comments and stmt.value is not None):
            allowed.update(id(n) for n in ast.walk(stmt.value))
    return allowed


def _loose_literals(source: str, name: str) -> list[str]:
    tree = ast.parse(source)
    comments = {tok.start[0] for tok in tokenize.generate_tokens(io.StringIO(source).readline)
                if tok.type == tokenize.COMMENT and tok.string.startswith("#:")}
    allowed = _documented_constant(tree, comments)
    return [f"{name}:{node.lineno} {node.value!r}" for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and type(node.value) is float
            and 0.0 < abs(node.value) < SMALL_FLOAT and id(node) not in allowed]


def test_tolerances_live_in_tolerances_module():
    found = [f for p in _sources() if p.name != "tolerances.py"
             for f in _loose_literals(p.read_text(encoding="utf-8"), str(p.relative_to(ROOT)))]
    assert not found, ("small float literals outside tipgeo/tolerances.py (move a tolerance "
                       "there with its reason; name a unit factor as a documented "
                       "UPPER_CASE module constant):\n" + "\n".join(found))


def test_literal_check_sees_a_loose_tolerance():
    """The check above can fail, and lets a documented constant through."""
    loose = "def f(x):\n    return abs(x) < 1e-9\n"
    assert _loose_literals(loose, "toy.py") == ["toy.py:2 1e-09"]
    named = "#: N/mm² per Pa.\nMPA_PER_PA = 1.0e-6\n"
    assert _loose_literals(named, "toy.py") == []
    undocumented = "MPA_PER_PA = 1.0e-6\n"
    assert _loose_literals(undocumented, "toy.py") == ["toy.py:1 1e-06"]


@pytest.mark.parametrize("package", PACKAGES)
def test_package_ships_py_typed(package):
    import importlib.resources

    assert importlib.resources.files(package).joinpath("py.typed").is_file()
