"""Expressions of A3200 AeroBasic (see :mod:`gcode.parser`): a recursive-descent
parser over one line's tokens, mixed into the statement parser.

Grammar (loosest first): ``OR``, ``AND``, ``NOT``, a comparison (``== <> !=
< > <= >=``, and ``=`` inside a condition), ``+ -``, ``* /``, unary signs,
then a number, a ``$variable`` or a parenthesised expression. A minus
directly before a number literal is folded into it. Trees are at most
:data:`MAX_EXPR_DEPTH` deep and parentheses nest at most
:data:`~gcode.macros.MAX_NESTING` deep, so later recursion is bounded.

String expressions (``"a" + DBLTOSTR($x, 3)``) are read by
:meth:`ExpressionParser.string_expr` into the tuples of :mod:`gcode.strings`.
"""

from __future__ import annotations

from . import ast
from .errors import GCodeError
from .lexer import Token
from .macros import MAX_NESTING
from .strings import FUNCTIONS as _EVALUATED_STRING_FUNCTIONS

__all__ = ["ExpressionParser", "MAX_EXPR_DEPTH"]

#: Deepest expression tree (long operator chains count too).
MAX_EXPR_DEPTH = 200


class ExpressionParser:
    """Token helpers and the expression grammar; the subclass sets
    ``tokens``, ``pos``, ``line``, ``lineno`` and ``cond``."""

    tokens: list[Token]
    pos: int
    line: str
    lineno: int
    cond: bool = False

    # -- token helpers ----------------------------------------------------------
    def peek(self) -> Token | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def advance(self) -> Token:
        tok = self.tokens[self.pos]
        self.pos += 1
        return tok

    def is_op(self, chars: str) -> bool:
        tok = self.peek()
        return tok is not None and tok.kind == "op" and tok.str_value in chars

    def is_word(self, word: str) -> bool:
        tok = self.peek()
        return tok is not None and tok.kind == "ident" and tok.value == word

    def error(self, message: str, tok: Token, cls: type[GCodeError] = GCodeError) -> GCodeError:
        return cls(message, self.lineno, tok.col, tok.text)

    def source(self, first: Token) -> str:
        """Source text from ``first`` to the last consumed token."""
        return self.line[first.col - 1:self.tokens[self.pos - 1].end]

    def expect_end(self) -> None:
        tok = self.peek()
        if tok is None:
            return
        if tok.kind == "op" and tok.value == ")":
            raise self.error("unbalanced parenthesis: unexpected ')'", tok)
        raise self.error(f"unexpected {tok.text!r}", tok)

    def need_expr(self, after: Token) -> ast.Expr:
        """An expression that must follow ``after``."""
        if self.peek() is None:
            raise self.error(f"expected a value after {after.text!r}", after)
        return self.expr(0)[0]

    # -- expressions ------------------------------------------------------------
    def condition(self) -> ast.Expr:
        """A condition of IF/ELSEIF/WHILE: ``=`` compares there."""
        self.cond = True
        try:
            node, _ = self.disjunction(0)
        finally:
            self.cond = False
        return node

    def disjunction(self, nest: int) -> tuple[ast.Expr, int]:
        """``conjunction (OR conjunction)*``."""
        left, depth = self.conjunction(nest)
        while (tok := self.peek()) is not None and tok.kind == "ident" and tok.value == "OR":
            self.advance()
            right, rdepth = self.conjunction(nest)
            depth = self.deeper(max(depth, rdepth), tok)
            left = ast.Logic("OR", left, right)
        return left, depth

    def conjunction(self, nest: int) -> tuple[ast.Expr, int]:
        """``negation (AND negation)*``."""
        left, depth = self.negation(nest)
        while (tok := self.peek()) is not None and tok.kind == "ident" and tok.value == "AND":
            self.advance()
            right, rdepth = self.negation(nest)
            depth = self.deeper(max(depth, rdepth), tok)
            left = ast.Logic("AND", left, right)
        return left, depth

    def negation(self, nest: int) -> tuple[ast.Expr, int]:
        """``NOT* comparison`` (iterative: long NOT chains cost no recursion)."""
        nots: list[Token] = []
        while (tok := self.peek()) is not None and tok.kind == "ident" and tok.value == "NOT":
            nots.append(self.advance())
        node, depth = self.comparison(nest)
        for tok in reversed(nots):
            depth = self.deeper(depth, tok)
            node = ast.Not(node)
        return node, depth

    def comparison(self, nest: int) -> tuple[ast.Expr, int]:
        """``expr (op expr)?`` with op ``== <> != < > <= >=`` (and ``=`` in a condition)."""
        left, depth = self.expr(nest)
        tok = self.peek()
        if tok is not None and tok.kind == "op" and (
                tok.value in ("==", "<>", "!=", "<", ">", "<=", ">=")
                or (tok.value == "=" and self.cond)):
            self.advance()
            right, rdepth = self.expr(nest)
            depth = self.deeper(max(depth, rdepth), tok)
            op = {"=": "==", "!=": "<>"}.get(tok.value, tok.value)
            left = ast.Compare(op, left, right)
        return left, depth

    def expr(self, nest: int) -> tuple[ast.Expr, int]:
        """``term (('+'|'-') term)*``; returns the tree and its depth."""
        left, depth = self.term(nest)
        while self.is_op("+-"):
            op = self.advance()
            right, rdepth = self.term(nest)
            depth = self.deeper(max(depth, rdepth), op)
            left = ast.BinOp(op.str_value, left, right)
        return left, depth

    def term(self, nest: int) -> tuple[ast.Expr, int]:
        """``unary (('*'|'/') unary)*``."""
        left, depth = self.unary(nest)
        while self.is_op("*/"):
            op = self.advance()
            right, rdepth = self.unary(nest)
            depth = self.deeper(max(depth, rdepth), op)
            left = ast.BinOp(op.str_value, left, right)
        return left, depth

    def unary(self, nest: int) -> tuple[ast.Expr, int]:
        """``('+'|'-')* primary``; a minus next to a number literal is folded."""
        signs: list[Token] = []
        while self.is_op("+-"):
            signs.append(self.advance())
        literal = (first := self.peek()) is not None and first.kind == "num"
        node, depth = self.primary(nest)
        for sign in reversed(signs):
            if sign.value == "+":
                continue
            if literal and isinstance(node, ast.Num):     # a number token makes a Num
                node = ast.Num(-node.value)
                literal = False
            else:
                node = ast.Neg(node)
                depth = self.deeper(depth, sign)
        return node, depth

    def primary(self, nest: int) -> tuple[ast.Expr, int]:
        tok = self.peek()
        if tok is None:
            prev = self.tokens[self.pos - 1]
            raise self.error(f"expected a value after {prev.text!r}", prev)
        self.advance()
        if tok.kind == "num":
            return ast.Num(float(tok.value)), 1
        if tok.kind == "var":
            nxt = self.peek()
            if nxt is not None and nxt.kind == "op" and nxt.str_value in "[.":
                raise self.error(f"{tok.text}{nxt.text}…: reading an input, system variable or "
                                 "array element cannot be simulated", tok)
            return ast.Var(tok.str_value), 1
        if tok.kind == "op" and tok.value == "(":
            if nest >= MAX_NESTING:
                raise self.error(f"parentheses nested deeper than {MAX_NESTING}", tok)
            inner, depth = self.disjunction(nest + 1)
            close = self.peek()
            if close is None:
                raise self.error("unbalanced parenthesis: '(' is never closed", tok)
            if not (close.kind == "op" and close.value == ")"):
                raise self.error(f"expected ')' but found {close.text!r}", close)
            self.advance()
            return inner, depth
        if tok.kind == "op" and tok.value == ")":
            raise self.error("unbalanced parenthesis: unexpected ')'", tok)
        raise self.error(f"expected a number, $variable or '(' but found {tok.text!r}", tok)

    def deeper(self, depth: int, tok: Token) -> int:
        if depth + 1 > MAX_EXPR_DEPTH:
            raise self.error(f"expression deeper than {MAX_EXPR_DEPTH} levels", tok)
        return depth + 1

    # -- string expressions -----------------------------------------------------
    def string_expr(self) -> ast.StringTree:
        """``term ('+' term)*`` of a string expression (see :mod:`gcode.strings`)."""
        left = self.string_term()
        while self.is_op("+"):
            self.advance()
            left = ("cat", left, self.string_term())
        return left

    def string_term(self) -> ast.StringTree:
        tok = self.peek()
        if tok is None:
            prev = self.tokens[self.pos - 1]
            raise self.error(f"expected a value after {prev.text!r}", prev)
        nxt = self.tokens[self.pos + 1] if self.pos + 1 < len(self.tokens) else None
        if tok.kind == "str":
            self.advance()
            return ("lit", tok.str_value)
        if tok.kind == "ident" and tok.str_value in _EVALUATED_STRING_FUNCTIONS:
            return self.string_call(tok)
        if tok.kind == "var" and (nxt is None or (nxt.kind == "op" and nxt.str_value in "+,)")):
            self.advance()
            return ("var", tok.str_value)
        return ("num", self.term(0)[0])

    def string_call(self, head: Token) -> ast.StringTree:
        self.advance()
        if not self.is_op("("):
            raise self.error(f"{head.value} needs '(' and its arguments", self.peek() or head)
        self.advance()
        kinds, _ = _EVALUATED_STRING_FUNCTIONS[head.str_value]
        args: list[ast.StringTree] = []
        for i, kind in enumerate(kinds):
            if i:
                if not self.is_op(","):
                    raise self.error(f"{head.value} takes {len(kinds)} arguments",
                                     self.peek() or head)
                self.advance()
            args.append(self.string_expr() if kind == "str" else ("num", self.need_expr(head)))
        if not self.is_op(")"):
            raise self.error(f"expected ')' to close {head.value}(", self.peek() or head)
        self.advance()
        return ("call", head.str_value, tuple(args))
