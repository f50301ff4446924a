"""Parser of the Aerotech A3200 AeroBasic subset of the thesis's laser program.

The language is the one of Appendix C (micro-serrations ablated with a
pulsed laser): one statement per line, keywords case-insensitive, comments
``;`` or ``//`` to the end of the line. Statements (see :mod:`gcode.ast`):

``DVAR $a, $b``                     :class:`~gcode.ast.DVar` (commas optional)
``$name = expr``                    :class:`~gcode.ast.Assign`
``REPEAT expr`` … ``END REPEAT``    :class:`~gcode.ast.Repeat` (nested; also
                                    ``ENDREPEAT``)
``PSOPULSE X TIME 10 5 CYCLES 1e7`` :class:`~gcode.ast.Pso` (any ``PSO…``
                                    command: command, axis letter, then
                                    upper-case keywords and expressions)
``SECONDS`` ``MINUTES`` ``METRIC``  :class:`~gcode.ast.Mode`; ``ENABLE X Y``
``ENGLISH`` ``ABSOLUTE``            keeps its axes in ``args``; ``END`` ends
``INCREMENTAL`` ``ENABLE`` ``END``  the program
``G01 G41 X$comp F $feed``          :class:`~gcode.ast.Block` of words and
                                    motion keywords (``LINEAR`` ``RAPID``
                                    ``CW`` ``CCW``)

Words are a letter of :data:`WORD_LETTERS` and a value: a number, a
``$variable``, a parenthesised expression, or a sign applied to one of those
(``X-0.05``, ``X$comp``, ``F $feed``, ``I-$radius``, ``X-($radius*2)``,
``G0 X (2*$r-2*$c)``), glued or spaced. A bare axis letter (``G44 X Y``) is a
word with value None. G codes are those of :data:`G_CODES`; a leading ``N``
line number is accepted and dropped. Expressions have ``+ - * /``, unary
signs and parentheses with the usual precedence, left-associative; a minus
directly before a number literal is folded into it (``-0.05`` is
``Num(-0.05)``), any other unary minus is :class:`~gcode.ast.Neg`. Inside
PSO arguments expressions follow one another without separator (``TIME 10
5``; commas may separate them too), so ``TIME 10 -5`` is one argument, 5.

Errors are :class:`~gcode.errors.GCodeError` with the 1-based line and column
of the offending text and that text; nothing else escapes :func:`parse`, for
any string. Parentheses and REPEAT nest at most :data:`MAX_NESTING` deep and
expression trees are at most :data:`MAX_EXPR_DEPTH` deep, so downstream
recursion is bounded.

Cost bounds. A line is at most :data:`~gcode.lexer.MAX_LINE_LENGTH`
characters and :data:`~gcode.lexer.MAX_LINE_TOKENS` tokens (refused while
lexing, before the work is done); a program at most ``max_lines`` lines,
``max_tokens`` tokens and ``max_statements`` statements (arguments of
:func:`parse`, defaults :data:`DEFAULT_MAX_LINES`, :data:`DEFAULT_MAX_TOKENS`,
:data:`DEFAULT_MAX_STATEMENTS`). The defaults are set from measurements so
that reaching any one of them costs at most about 4 s of CPU on the
reference 2-core machine (parsing costs about 5–13 µs a token, 2–3 µs a blank
line) and at most about 200 MB; Appendix C is 50 lines, 47 statements and 244
tokens.
"""

from __future__ import annotations

import re

from . import ast
from .errors import GCodeError, check_limit
from .lexer import Token, UnsupportedError, iter_lines, tokenize_line

__all__ = ["parse", "parse_expression", "is_statement", "G_CODES", "WORD_LETTERS",
           "AXIS_LETTERS", "MOTION_KEYWORDS", "MODE_KEYWORDS", "MAX_NESTING",
           "MAX_EXPR_DEPTH", "DEFAULT_MAX_STATEMENTS", "DEFAULT_MAX_TOKENS",
           "DEFAULT_MAX_LINES"]

#: G codes accepted (``G00``–``G03`` may be written with a leading zero).
G_CODES = frozenset({0, 1, 2, 3, 40, 41, 42, 44, 90, 91, 92, 98})
#: Letters that may start a word.
WORD_LETTERS = frozenset("GXYZABCIJKFETN")
#: Axis letters: may stand bare (``G44 X Y``), name PSO and ENABLE axes.
AXIS_LETTERS = frozenset("XYZABC")
#: Motion keywords allowed inside a block.
MOTION_KEYWORDS = frozenset({"LINEAR", "RAPID", "CW", "CCW"})
#: Keyword statements (:class:`~gcode.ast.Mode`).
MODE_KEYWORDS = frozenset({"SECONDS", "MINUTES", "METRIC", "ENGLISH", "ABSOLUTE",
                           "INCREMENTAL", "ENABLE", "END"})
#: Deepest nesting of parentheses, and of REPEAT blocks.
MAX_NESTING = 64
#: Deepest expression tree (long operator chains count too).
MAX_EXPR_DEPTH = 200
#: Default ``max_statements`` of :func:`parse` (REPEAT and END REPEAT lines
#: count, skipped ones too): 200 000 one-token statements parse in about 2 s.
DEFAULT_MAX_STATEMENTS = 200_000
#: Default ``max_tokens`` of :func:`parse`, all lines together: at most about
#: 4 s of CPU (125 000 ``G1`` lines, the costliest per token measured) and
#: 120 MB of syntax tree.
DEFAULT_MAX_TOKENS = 250_000
#: Default ``max_lines`` of :func:`parse`, blank and comment lines included
#: (about 2–3 µs each).
DEFAULT_MAX_LINES = 1_000_000

_STRUCTURAL = re.compile(r"[ \t\f\v]*(?:N[0-9]+[ \t\f\v]*)?(?:REPEAT|END[ \t\f\v]*REPEAT)\b",
                         re.IGNORECASE)


class _RepeatStart:
    """A ``REPEAT count`` header line."""

    def __init__(self, count: ast.Expr, span: ast.Span):
        self.count, self.span = count, span


class _RepeatEnd:
    """An ``END REPEAT`` line."""

    def __init__(self, span: ast.Span):
        self.span = span


def parse(text: str, *, lenient: bool = False,
          max_statements: int = DEFAULT_MAX_STATEMENTS,
          max_tokens: int = DEFAULT_MAX_TOKENS,
          max_lines: int = DEFAULT_MAX_LINES) -> ast.Program:
    """Parse a program.

    Parameters
    ----------
    text : str
        The program source.
    lenient : bool
        Skip statements outside the subset (unknown keywords, G codes and word
        letters, M words, foreign characters) and record a warning (with line
        and column) in :attr:`~gcode.ast.Program.warnings` instead of raising.
        Syntax errors in supported statements, REPEAT structure errors and
        the cost bounds still raise.
    max_statements : int
        Upper bound on the number of statements (nested ones included,
        skipped ones and REPEAT/END REPEAT lines too); default
        :data:`DEFAULT_MAX_STATEMENTS`.
    max_tokens : int
        Upper bound on the number of tokens of the whole program; default
        :data:`DEFAULT_MAX_TOKENS`.
    max_lines : int
        Upper bound on the number of lines, blank and comment lines included;
        default :data:`DEFAULT_MAX_LINES`.

    Returns
    -------
    gcode.ast.Program

    Raises
    ------
    GCodeError
        Unsupported or malformed text, unbalanced REPEAT/END REPEAT, nesting
        deeper than :data:`MAX_NESTING`, a line longer than
        :data:`~gcode.lexer.MAX_LINE_LENGTH` or with more than
        :data:`~gcode.lexer.MAX_LINE_TOKENS` tokens, more than
        ``max_statements`` statements, ``max_tokens`` tokens or ``max_lines``
        lines (each located at the first line, column and text beyond).
    TypeError, ValueError
        ``text`` is not a str; a bound is not a whole number ≥ 0.
    """
    if not isinstance(text, str):
        raise TypeError(f"parse() needs a str, not {type(text).__name__}")
    check_limit("max_statements", max_statements)
    check_limit("max_tokens", max_tokens)
    check_limit("max_lines", max_lines)
    stack: list[tuple[_RepeatStart | None, list]] = [(None, [])]
    warnings: list[str] = []
    count = 0
    tokens = 0
    for lineno, line in enumerate(iter_lines(text), 1):
        if lineno > max_lines:
            raise GCodeError(f"more than {max_lines} lines (max_lines = {max_lines})", lineno, 1,
                             line[:20])
        lexed: list[Token] = []   # filled even when lexing fails: skipped text costs too
        try:
            item = _Line(line, lineno, lexed).statement()
        except UnsupportedError as err:
            tokens = _count_tokens(tokens, lexed, max_tokens, lineno)
            if not lenient or _STRUCTURAL.match(line):
                raise
            count += 1
            _check_count(count, max_statements, err.line, err.column, err.text)
            warnings.append(f"{err} (statement skipped)")
            continue
        tokens = _count_tokens(tokens, lexed, max_tokens, lineno)
        if item is None:
            continue
        span = item.span
        count += 1
        _check_count(count, max_statements, span.line, span.col, span.text)
        if isinstance(item, _RepeatStart):
            if len(stack) > MAX_NESTING:
                raise GCodeError(f"REPEAT nested deeper than {MAX_NESTING}", span.line,
                                 span.col, span.text)
            stack.append((item, []))
        elif isinstance(item, _RepeatEnd):
            if len(stack) == 1:
                raise GCodeError("END REPEAT without REPEAT", span.line, span.col, span.text)
            head, body = stack.pop()
            stack[-1][1].append(ast.Repeat(head.count, tuple(body), head.span))
        else:
            stack[-1][1].append(item)
    if len(stack) > 1:
        head = stack[-1][0]
        raise GCodeError("REPEAT without END REPEAT", head.span.line, head.span.col,
                         head.span.text)
    return ast.Program(tuple(stack[0][1]), tuple(warnings))


def parse_expression(text: str) -> ast.Expr:
    """Parse one expression (``2+3*4``, ``-($radius*2)``).

    Parameters
    ----------
    text : str
        The expression, on one line (a comment may follow).

    Returns
    -------
    gcode.ast.Expr

    Raises
    ------
    GCodeError
        An empty or malformed expression (line 1, column of the culprit).
    """
    if not isinstance(text, str):
        raise TypeError(f"parse_expression() needs a str, not {type(text).__name__}")
    lines = iter_lines(text)
    first = next(lines)
    second = next(lines, None)
    if second is not None:
        raise GCodeError("an expression must be on one line", 2, 1, second[:40])
    p = _Line(first, 1)
    if not p.tokens:
        raise GCodeError("empty expression", 1, 1, first)
    expr, _ = p.expr(0)
    p.expect_end()
    return expr


def is_statement(line: str) -> bool:
    """True if ``line`` holds exactly one supported statement.

    A ``REPEAT`` header or an ``END REPEAT`` alone counts as a statement; a
    blank or comment-only line does not. Used by :mod:`gcode.restore` to tell
    statements from English in comments.

    Parameters
    ----------
    line : str
        One line of source.

    Returns
    -------
    bool
    """
    if not isinstance(line, str) or "\n" in line or "\r" in line:
        return False
    try:
        return _Line(line, 1).statement() is not None
    except GCodeError:
        return False


def _count_tokens(total: int, lexed: list[Token], limit: int, line: int) -> int:
    """``total`` plus the tokens of one line; GCodeError at the first beyond ``limit``."""
    total += len(lexed)
    if total > limit:
        tok = lexed[len(lexed) - (total - limit)]
        raise GCodeError(f"more than {limit} tokens (max_tokens = {limit})", line, tok.col,
                         tok.text)
    return total


def _check_count(count: int, limit: int, line: int, col: int, text: str) -> None:
    if count > limit:
        raise GCodeError(f"more than {limit} statements (max_statements = {limit})", line, col,
                         text)


class _Line:
    """Recursive-descent parser of the tokens of one line."""

    def __init__(self, line: str, lineno: int, tokens: list[Token] | None = None):
        self.line, self.lineno = line, lineno
        self.tokens: list[Token] = tokenize_line(line, lineno, out=tokens)
        self.pos = 0

    # -- token helpers ----------------------------------------------------------
    def peek(self) -> Token | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def advance(self) -> Token:
        tok = self.tokens[self.pos]
        self.pos += 1
        return tok

    def is_op(self, chars: str) -> bool:
        tok = self.peek()
        return tok is not None and tok.kind == "op" and tok.value in chars

    def error(self, message: str, tok: Token, cls: type = GCodeError) -> GCodeError:
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

    # -- statements -------------------------------------------------------------
    def statement(self):
        """The line's statement, a REPEAT marker, or None for an empty line."""
        toks = self.tokens
        if not toks:
            return None
        if toks[0].kind == "ident" and toks[0].value == "N":
            self.advance()
            num = self.peek()
            if num is None or num.kind != "num" or not num.text.isdigit():
                raise self.error("N must be followed by a line number", toks[0])
            self.advance()
            if self.peek() is None:
                return None
        span = ast.Span(self.lineno, toks[0].col, self.line[toks[0].col - 1:toks[-1].end])
        start = self.peek()
        if start.kind == "var":
            return self.assignment(span)
        if start.kind != "ident":
            raise self.error(f"expected a statement, found {start.text!r}", start)
        kw = start.value
        if kw == "DVAR":
            return self.dvar(span)
        if kw == "REPEAT":
            self.advance()
            if self.peek() is None:
                raise self.error("REPEAT needs a count", start)
            count, _ = self.expr(0)
            self.expect_end()
            return _RepeatStart(count, span)
        nxt = self.tokens[self.pos + 1] if self.pos + 1 < len(toks) else None
        if kw == "ENDREPEAT" or (kw == "END" and nxt is not None and nxt.kind == "ident"
                                 and nxt.value == "REPEAT"):
            self.pos += 1 if kw == "ENDREPEAT" else 2
            self.expect_end()
            return _RepeatEnd(span)
        if kw in MODE_KEYWORDS:
            return self.mode(span)
        if kw.startswith("PSO") and len(kw) > 3:
            return self.pso(span)
        if kw in MOTION_KEYWORDS or len(kw) == 1:
            return self.block(span)
        raise self.error(f"unknown keyword {start.text!r}", start, UnsupportedError)

    def assignment(self, span: ast.Span) -> ast.Assign:
        var = self.advance()
        if not self.is_op("="):
            tok = self.peek() or var
            raise self.error(f"expected '=' after {var.text}", tok)
        eq = self.advance()
        if self.peek() is None:
            raise self.error(f"expected an expression after {var.text} =", eq)
        expr, _ = self.expr(0)
        self.expect_end()
        return ast.Assign(var.value, expr, span)

    def dvar(self, span: ast.Span) -> ast.DVar:
        head = self.advance()
        names: list[str] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind == "var":
                names.append(tok.value)
            elif not (tok.kind == "op" and tok.value == ","):
                raise self.error(f"DVAR expects $variables, found {tok.text!r}", tok)
        if not names:
            raise self.error("DVAR needs at least one $variable", head)
        return ast.DVar(tuple(names), span)

    def mode(self, span: ast.Span) -> ast.Mode:
        head = self.advance()
        args: list[str] = []
        if head.value == "ENABLE":
            while (tok := self.peek()) is not None:
                self.advance()
                if tok.kind == "ident" and tok.value in AXIS_LETTERS:
                    args.append(tok.value)
                elif not (tok.kind == "op" and tok.value == ","):
                    raise self.error(f"ENABLE expects axis letters, found {tok.text!r}", tok)
            if not args:
                raise self.error("ENABLE needs at least one axis", head)
        elif head.value == "END" and (tok := self.peek()) is not None and tok.kind == "ident" \
                and tok.value == "PROGRAM":
            self.advance()
            args.append("PROGRAM")
            self.expect_end()
        else:
            self.expect_end()
        return ast.Mode(head.value, tuple(args), span)

    def pso(self, span: ast.Span) -> ast.Pso:
        head = self.advance()
        axis = self.peek()
        if axis is None or axis.kind != "ident" or axis.value not in AXIS_LETTERS:
            raise self.error(f"{head.value} needs an axis letter", axis or head)
        self.advance()
        args: list = []
        while (tok := self.peek()) is not None:
            if tok.kind == "op" and tok.value == ",":
                self.advance()
            elif tok.kind == "ident":
                self.advance()
                args.append(tok.value)
            else:
                expr, _ = self.expr(0)
                args.append(expr)
        return ast.Pso(head.value, axis.value, tuple(args), span)

    def block(self, span: ast.Span) -> ast.Block:
        words: list[ast.Word] = []
        keywords: list[str] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind != "ident":
                if tok.kind == "op" and tok.value == ")":
                    raise self.error("unbalanced parenthesis: unexpected ')'", tok)
                raise self.error(f"expected a word, found {tok.text!r}", tok)
            if tok.value in MOTION_KEYWORDS:
                keywords.append(tok.value)
                continue
            if len(tok.value) > 1:
                raise self.error(f"unknown keyword {tok.text!r}", tok, UnsupportedError)
            words.append(self.word(tok))
        return ast.Block(tuple(words), tuple(keywords), span)

    def word(self, letter: Token) -> ast.Word:
        name = letter.value
        first = self.pos
        value = None
        if (nxt := self.peek()) is not None and (
                nxt.kind in ("num", "var") or (nxt.kind == "op" and nxt.value in "(+-")):
            value, _ = self.unary(0)
        text = self.source(letter)
        where = (self.lineno, letter.col, text)
        if name not in WORD_LETTERS:
            what = "M words are" if name == "M" else f"{name} words are"
            raise UnsupportedError(f"{what} not supported", *where)
        if name == "N":
            raise GCodeError("a line number N must start the line", *where)
        if name == "G":
            tok = self.tokens[first] if self.pos == first + 1 else None
            if tok is None or tok.kind != "num":
                raise GCodeError("a G code must be a plain number", *where)
            if not tok.text.isdigit() or tok.value not in G_CODES:
                raise UnsupportedError(f"unsupported G code {text}", *where)
            value = ast.Num(float(tok.value))
        if value is None and name not in AXIS_LETTERS:
            raise GCodeError(f"the {name} word needs a value", *where)
        return ast.Word(name, value, ast.Span(self.lineno, letter.col, text))

    # -- expressions ------------------------------------------------------------
    def expr(self, nest: int) -> tuple[ast.Expr, int]:
        """``term (('+'|'-') term)*``; returns the tree and its depth."""
        left, depth = self.term(nest)
        while self.is_op("+-"):
            op = self.advance()
            right, rdepth = self.term(nest)
            depth = self.deeper(max(depth, rdepth), op)
            left = ast.BinOp(op.value, left, right)
        return left, depth

    def term(self, nest: int) -> tuple[ast.Expr, int]:
        """``unary (('*'|'/') unary)*``."""
        left, depth = self.unary(nest)
        while self.is_op("*/"):
            op = self.advance()
            right, rdepth = self.unary(nest)
            depth = self.deeper(max(depth, rdepth), op)
            left = ast.BinOp(op.value, left, right)
        return left, depth

    def unary(self, nest: int) -> tuple[ast.Expr, int]:
        """``('+'|'-')* primary``; a minus next to a number literal is folded."""
        signs: list[Token] = []
        while self.is_op("+-"):
            signs.append(self.advance())
        literal = self.peek() is not None and self.peek().kind == "num"
        node, depth = self.primary(nest)
        for sign in reversed(signs):
            if sign.value == "+":
                continue
            if literal:
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
            return ast.Num(tok.value), 1
        if tok.kind == "var":
            return ast.Var(tok.value), 1
        if tok.kind == "op" and tok.value == "(":
            if nest >= MAX_NESTING:
                raise self.error(f"parentheses nested deeper than {MAX_NESTING}", tok)
            inner, depth = self.expr(nest + 1)
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
