"""Evaluation and printing of AeroBasic expressions (:mod:`gcode.ast` trees).

Our own evaluator — never Python's ``eval`` — with explicit errors: an
unknown ``$variable``, a division by zero, or a result that is not finite
(overflow) raise :class:`~gcode.errors.GCodeError`, located at the statement
``span`` when one is given. Both functions walk the tree with an explicit
stack, so any depth is safe.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import TypeGuard

from . import ast
from .errors import GCodeError

__all__ = ["evaluate", "to_source", "variables_in"]

# binding strength of each operator (higher binds tighter); unary minus binds tightest
_OR, _AND, _NOT, _CMP, _ADD, _MUL, _NEG = 1, 2, 3, 4, 5, 6, 7
_PRECEDENCE = {"+": _ADD, "-": _ADD, "*": _MUL, "/": _MUL}
_COMPARE: dict[str, Callable[[float, float], bool]] = {
    "==": lambda a, b: a == b, "<>": lambda a, b: a != b, "<": lambda a, b: a < b,
    ">": lambda a, b: a > b, "<=": lambda a, b: a <= b, ">=": lambda a, b: a >= b}


def evaluate(expr: ast.Expr, variables: Mapping[str, float],
             span: ast.Span | None = None) -> float:
    """Value of an expression.

    Parameters
    ----------
    expr : gcode.ast.Expr
        The tree (:class:`~gcode.ast.Num`, :class:`~gcode.ast.Var`,
        :class:`~gcode.ast.Neg`, :class:`~gcode.ast.BinOp`, and the
        conditions :class:`~gcode.ast.Compare`, :class:`~gcode.ast.Logic`,
        :class:`~gcode.ast.Not`, which give 1.0 or 0.0).
    variables : mapping of str to float
        Variable values by lower-case name, without the ``$``.
    span : gcode.ast.Span, optional
        The statement the expression belongs to; errors then carry its line,
        column and text.

    Returns
    -------
    float
        A finite value.

    Raises
    ------
    GCodeError
        Unknown variable (the message names ``$name``), division by zero, a
        non-finite number or result, or a node that is not an expression.
    """
    def fail(message: str) -> GCodeError:
        if span is None:
            return GCodeError(message)
        return GCodeError(message, span.line, span.col, span.text)

    if type(expr) is ast.Num and type(expr.value) is float and math.isfinite(expr.value):
        return expr.value         # fast path: a literal (most words)
    values: list[float] = []
    stack: list[tuple[object, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if isinstance(node, ast.Num):
            values.append(_literal(node.value, fail))
        elif isinstance(node, ast.Var):
            values.append(_variable(node.name, variables, fail))
        elif isinstance(node, (ast.Neg, ast.Not)):
            if ready:
                value = values.pop()
                values.append(-value if isinstance(node, ast.Neg) else float(value == 0.0))
            else:
                stack.append((node, True))
                stack.append((node.operand, False))
        elif _is_binary(node):
            if not ready:           # both operands first, then the operator
                stack.append((node, True))
                stack.append((node.right, False))
                stack.append((node.left, False))
                continue
            right = values.pop()
            left = values.pop()
            values.append(_binary(node, left, right, fail))
        else:
            raise fail(f"not an expression: {node!r}")
    return values[0]


def _literal(value: object, fail: Callable[[str], GCodeError]) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise fail(f"not a finite number: {value!r}")
    return float(value)


def _variable(name: str, variables: Mapping[str, float],
              fail: Callable[[str], GCodeError]) -> float:
    if name not in variables:
        raise fail(f"unknown variable ${name}")
    try:
        value = float(variables[name])
    except (TypeError, ValueError, OverflowError):
        raise fail(f"variable ${name} is not a number: {variables[name]!r}") from None
    if not math.isfinite(value):
        raise fail(f"variable ${name} is not finite: {value!r}")
    return value


def _is_binary(node: object) -> TypeGuard[ast.BinOp | ast.Compare | ast.Logic]:
    return (isinstance(node, ast.BinOp) and node.op in _PRECEDENCE) or (
        isinstance(node, ast.Compare) and node.op in _COMPARE) or (
        isinstance(node, ast.Logic) and node.op in ("AND", "OR"))


def _binary(node: ast.BinOp | ast.Compare | ast.Logic, left: float, right: float,
            fail: Callable[[str], GCodeError]) -> float:
    """The value of a binary node (arithmetic, comparison, AND/OR) of two values."""
    if isinstance(node, ast.Compare):
        return float(_COMPARE[node.op](left, right))
    if isinstance(node, ast.Logic):
        if node.op == "AND":
            return float(left != 0.0 and right != 0.0)
        return float(left != 0.0 or right != 0.0)
    if node.op == "+":
        result = left + right
    elif node.op == "-":
        result = left - right
    elif node.op == "*":
        result = left * right
    elif right == 0.0:
        raise fail(f"division by zero in {to_source(node)}")
    else:
        result = left / right
    if not math.isfinite(result):
        raise fail(f"result out of range in {to_source(node)}")
    return result


def to_source(expr: ast.Expr) -> str:
    """AeroBasic source of an expression, with the parentheses it needs.

    ``parse_expression(to_source(e))`` evaluates like ``e`` (a minus before a
    number literal is folded into the number, so the tree may differ there).

    Parameters
    ----------
    expr : gcode.ast.Expr

    Returns
    -------
    str
        E.g. ``-($radius * 2)``, ``2 * $radius_i - 2 * $comp_i``.
    """
    # Iterative: a work stack of nodes (with the precedence their context
    # needs) and of literal strings, the output assembled left to right.
    out: list[str] = []
    work: list[tuple[object, int] | str] = [(expr, 0)]
    while work:
        item = work.pop()
        if isinstance(item, str):
            out.append(item)
            continue
        node, need = item
        if isinstance(node, ast.Num):
            text = _number(node.value)
            out.append(f"({text})" if text.startswith("-") and need > _ADD else text)
        elif isinstance(node, ast.Var):
            out.append(f"${node.name}")
        elif isinstance(node, ast.Neg):
            out.append("-")
            work.append((node.operand, _NEG))
        elif isinstance(node, ast.Not):
            if need > _NOT:
                work.append(")")
            work.append((node.operand, _NOT))
            work.append("NOT " if need <= _NOT else "(NOT ")
        elif isinstance(node, (ast.BinOp, ast.Compare, ast.Logic)):
            if isinstance(node, ast.BinOp):
                prec = _PRECEDENCE.get(node.op, _ADD)
            elif isinstance(node, ast.Compare):
                prec = _CMP
            else:
                prec = _AND if node.op == "AND" else _OR
            parens = prec < need or (prec == _CMP and need == _CMP)
            if parens:
                work.append(")")
            work.append((node.right, prec + 1))
            work.append(f" {node.op} ")
            work.append((node.left, prec))
            if parens:
                work.append("(")
        else:
            out.append(repr(node))
    return "".join(out)


def variables_in(expr: ast.Expr) -> set[str]:
    """Names of the variables an expression reads.

    Parameters
    ----------
    expr : gcode.ast.Expr

    Returns
    -------
    set of str
        Lower-case names without ``$``.
    """
    names: set[str] = set()
    stack: list[object] = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Var):
            names.add(node.name)
        elif isinstance(node, (ast.Neg, ast.Not)):
            stack.append(node.operand)
        elif isinstance(node, (ast.BinOp, ast.Compare, ast.Logic)):
            stack.extend((node.left, node.right))
    return names


def _number(value: float) -> str:
    """Shortest round-tripping text of a number (``2`` rather than ``2.0``)."""
    if isinstance(value, float) and math.isfinite(value) and value.is_integer() \
            and abs(value) < 1e16:
        return str(int(value))
    return repr(value)
