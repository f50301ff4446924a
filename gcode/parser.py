"""Parser of Aerotech A3200 AeroBasic: the thesis's laser program (Appendix C)
and the A3200 that laser-writing and direct-ink-writing programs are written in.

One statement per line, keywords case-insensitive, comments ``;``, ``//`` or
``'`` to the end of the line (outside a ``"string"``). Statements (see
:mod:`gcode.ast`); "interpreted" ones change the toolpath or its time,
"no motion" ones are parsed, recorded with what they do and reported by
``tipgeo gcode check``:

=========================================  =========================================
``#define NAME text``, ``#undef NAME``     preprocessor: object-like macros,
``#define NAME(a, b) text``                and function-like ones (the ``(``
                                           right after the name, arguments on
                                           the line of the use, each expanded
                                           before it is substituted), replaced
                                           and rescanned C-style before the line
                                           is read; tokens keep the line and
                                           column of the macro's use.
                                           ``#include``/``#if…`` and the ``#``/``##``
                                           operators are refused
``DVAR $a, $b`` (any of space, tab,        :class:`~gcode.ast.DVar` (arrays
comma), ``DVAR $pts[100]``                 ``$pts[n]`` declared)
``$name = expr``                           :class:`~gcode.ast.Assign`
``$DO[0].X = 1``, ``$AO[0].X = 2``,        :class:`~gcode.ast.SysAssign` — I/O and
``$DO0.0 = 0``, ``$global[2] = 4``         system variables: no motion, value
                                           recorded
``REPEAT n`` … ``END REPEAT``              :class:`~gcode.ast.Repeat` (``ENDREPEAT``)
``WHILE cond [DO]`` … ``ENDWHILE``         :class:`~gcode.ast.While`
``IF cond THEN`` … ``ELSEIF cond THEN``    :class:`~gcode.ast.If`; conditions have
… ``ELSE`` … ``ENDIF``                     ``== = <> != < > <= >=``, ``AND OR NOT``
``FOR $i = a TO b [STEP s]`` … ``NEXT``    :class:`~gcode.ast.For`
``DFS name`` … ``ENDDFS``                  :class:`~gcode.ast.Sub`, anywhere at the
                                           top level (usually after ``END
                                           PROGRAM``)
``CALL name P1 Q$x``                       :class:`~gcode.ast.Call`; the letters are
                                           ``$p``, ``$q`` … inside the subroutine
``DWELL t``, ``G4 P t``                    :class:`~gcode.ast.Dwell`, seconds, in the
                                           time
``PSOPULSE X TIME 10, 5 CYCLES 1e7``       :class:`~gcode.ast.Pso` (any ``PSO…``
                                           command: command, axis letter, then
                                           keywords and expressions)
``SECONDS MINUTES METRIC ENGLISH           :class:`~gcode.ast.Mode`; ``END``, ``END
ABSOLUTE INCREMENTAL ENABLE END``,         PROGRAM``, ``M2``, ``M30`` end the
``END PROGRAM``, ``M2``, ``M30``           program
``G01 G41 X$comp F $feed``                 :class:`~gcode.ast.Block` of words and
                                           motion keywords (``LINEAR`` ``RAPID``
                                           ``CW`` ``CCW``)
``VELOCITY ON``, ``ROUNDING``, ``WAIT …``, :class:`~gcode.ast.NoMotion` (see
``CRITICAL START/END``, ``FREERUN A 1``    :data:`NO_MOTION`; FREERUN of an axis
(not X Y Z C), file, message and string    outside X Y Z C), and the mode G codes
commands (``FILECLOSE $h``, ``$h =         of :data:`G_NO_MOTION` (``G108``,
FILEOPEN "f", 2``, ``$s = "text"``)        ``G359`` …)
=========================================  =========================================

A3200 task control is recorded as no motion: ``PROGRAM 1 RUN "f.pgm"``,
``PROGRAM PAUSE``/``STOP`` (kind ``PROGRAM RUN`` …), ``WAIT (TASKSTATUS(…)
== …) -1``; ``ENABLE`` takes any axis names (``ENABLE X Y D U``); ``FREERUN``
of any axis is recorded (a path axis X Y Z C keeps its position: not
simulated); ``G66`` is a row of :data:`G_NO_MOTION`; an assignment whose
right side holds a string or a string function (:data:`STRING_FUNCTIONS`:
``DBLTOSTR`` …) sets a string (recorded, kind ``STRING``).

Every statement keyword is a row of :data:`gcode.commands.COMMANDS` (its
arguments, effect, and whether the simulator models it); the parser reads a
statement with the row's statement parser, and accepts no keyword that is not
a row. The job is split: :mod:`gcode.lexer` (tokens), :mod:`gcode.macros`
(``#define``), :mod:`gcode.expressions` (expressions), this module
(statements and blocks), :mod:`gcode.interpreter` (running them) and
:mod:`gcode.motion` (moves).

Refused in every mode, even lenient: Ensemble AeroBasic (``HEADER … END
HEADER``, ``PROGRAM`` alone on its line, ``DIM … AS``), named as that
dialect; moves tipgeo cannot simulate (:data:`UNSIMULATED_MOTION`:
``HOME``, ``MOVEINC`` …); and, in lenient mode, any skipped statement
that names a motion G code or keyword or an axis with a value (a move that
cannot be evaluated is never dropped).

Words are a letter of :data:`WORD_LETTERS` and a value: a number, a
``$variable``, a parenthesised expression, or a sign applied to one of those
(``X-0.05``, ``X$comp``, ``F $feed``, ``I-$radius``, ``X-($radius*2)``,
``G0 X (2*$r-2*$c)``), glued or spaced. A bare axis letter (``G44 X Y``) is a
word with value None. G codes are those of :data:`G_CODES`; a leading ``N``
line number is accepted and dropped; ``P`` is G4's dwell time. Expressions
have ``+ - * /``, unary signs and parentheses with the usual precedence,
left-associative (and, in conditions or parentheses, comparisons below
them, then NOT, AND, OR); a minus
directly before a number literal is folded into it (``-0.05`` is
``Num(-0.05)``), any other unary minus is :class:`~gcode.ast.Neg`. Inside
PSO arguments expressions follow one another without separator (``TIME 10
5``; commas may separate them too), so ``TIME 10 -5`` is one argument, 5.

Errors are :class:`~gcode.errors.GCodeError` with the 1-based line and column
of the offending text and that text; nothing else escapes :func:`parse`, for
any string. Parentheses and blocks (REPEAT, WHILE, IF, DFS) nest at most
:data:`MAX_NESTING` deep and expression trees are at most
:data:`MAX_EXPR_DEPTH` deep, so downstream recursion is bounded; a program
has at most :data:`MAX_MACROS` macros, and one line at most
:data:`MAX_EXPANSIONS` macro replacements (the program at most
:data:`MAX_PROGRAM_EXPANSIONS`) and, expanded, at most
:data:`~gcode.lexer.MAX_LINE_LENGTH` characters. ``#define``/``#undef``
lines count as statements.

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
from collections.abc import Callable

from . import ast
from .commands import COMMANDS, RECORDED, commands_by_parser
from .commands import G_CODES as _G_TABLE
from .commands import WORD_LETTERS as _LETTERS
from .errors import GCodeError, check_limit
from .expressions import MAX_EXPR_DEPTH, ExpressionParser
from .lexer import Token, UnsupportedError, iter_lines, split_comment, tokenize_line
from .macros import (
    MAX_EXPANSIONS,
    MAX_MACROS,
    MAX_NESTING,
    MAX_PROGRAM_EXPANSIONS,
    SUB_NAME,
    Budget,
    Macros,
    Piece,
    directive,
    expand,
    origin,
)
from .strings import FUNCTIONS as _EVALUATED_STRING_FUNCTIONS

__all__ = ["parse", "parse_expression", "is_statement", "G_CODES", "WORD_LETTERS",
           "AXIS_LETTERS", "MOTION_KEYWORDS", "MODE_KEYWORDS", "MAX_NESTING",
           "MAX_EXPR_DEPTH", "DEFAULT_MAX_STATEMENTS", "DEFAULT_MAX_TOKENS",
           "DEFAULT_MAX_LINES", "NO_MOTION", "G_NO_MOTION", "UNSIMULATED_MOTION", "IO_NAME",
           "MAX_MACROS", "MAX_EXPANSIONS", "MAX_PROGRAM_EXPANSIONS", "STRING_FUNCTIONS",
           "STATUS_FUNCTIONS"]

#: G codes accepted (``G00``–``G03`` may be written with a leading zero): the
#: rows of :data:`gcode.commands.G_CODES`.
G_CODES = frozenset(_G_TABLE)
#: Letters that may start a word (P: the dwell time of G4, s).
WORD_LETTERS = frozenset(_LETTERS)
#: Axis letters: may stand bare (``G44 X Y``), name PSO and ENABLE axes.
AXIS_LETTERS = frozenset("XYZABC")
#: Motion keywords allowed inside a block.
MOTION_KEYWORDS = frozenset(commands_by_parser("block"))
#: Keyword statements (:class:`~gcode.ast.Mode`).
MODE_KEYWORDS = frozenset(commands_by_parser("mode"))
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

#: Statements that move nothing the simulation follows: parsed, recorded by
#: the interpreter as "no motion" with what they do, otherwise ignored. The
#: value is what the statement does (its mode word, if any, is added).
NO_MOTION = {k: c.effect for k, c in commands_by_parser("no_motion").items()}
#: String functions: an assignment whose right side uses one (or a string)
#: sets a string (evaluated when every function in it is one of
#: :data:`gcode.strings.FUNCTIONS`, else recorded).
STRING_FUNCTIONS = frozenset({"DBLTOSTR", "STRLEN", "FORMAT", "NUMTOSTR", "STRTONUM",
                              "STRCONCAT", "STRUPR", "STRLWR", "STRFORMAT", "STRINSERT",
                              "STRDELETE", "STRCOPY", "STRTODBL"})
#: Controller status functions: ``$x = AXISSTATUS(Z, DATAITEM_…)`` reads a value
#: known only on the machine (:class:`~gcode.ast.StatusRead`).
STATUS_FUNCTIONS = frozenset({"AXISSTATUS", "TASKSTATUS", "SYSTEMSTATUS", "AXISFAULT",
                              "AXISPARAMETER", "TASKPARAMETER", "SYSTEMPARAMETER"})
#: Statements whose recorded kind takes the first word after a task number
#: (``PROGRAM 1 RUN "f.pgm"`` → ``PROGRAM RUN``).
_TASK_WORD = frozenset({"PROGRAM"})
#: G codes that set a mode the simulation has no use for (recorded as no motion).
G_NO_MOTION = {g.code: g.effect for g in _G_TABLE.values() if g.simulated == RECORDED}
#: Keywords that move axes in ways tipgeo cannot simulate: an error in every mode.
UNSIMULATED_MOTION = frozenset(commands_by_parser("unsimulated"))
#: I/O system variables: ``$DO``, ``$DI``, ``$AO``, ``$AI`` (a glued number too: ``$DO0``).
IO_NAME = re.compile(r"(?:do|di|ao|ai)[0-9]*\Z")

_WS_RE = r"[ \t\f\v]"
_STRUCTURAL = re.compile(
    rf"{_WS_RE}*(?:N[0-9]+{_WS_RE}*)?(?:REPEAT|WHILE|IF|ELSEIF|ELSE|DFS|FOR|NEXT|"
    rf"END{_WS_RE}*(?:REPEAT|WHILE|IF|DFS)|ENDIF|ENDWHILE|ENDDFS|#)(?![A-Za-z0-9_])",
    re.IGNORECASE)
_MOTION_HINT = re.compile(
    r"(?<![A-Za-z0-9_$.])(?:G0*[0-3](?![0-9.])|LINEAR|RAPID|CW|CCW|[XYZC]\s*[-+.0-9$(])",
    re.IGNORECASE)
_ENSEMBLE = re.compile(
    rf"{_WS_RE}*(HEADER|END{_WS_RE}+HEADER|PROGRAM(?={_WS_RE}*(?:[;']|//|\r?$))|"
    rf"DIM{_WS_RE}+[A-Za-z_$][A-Za-z0-9_$]*"
    rf"(?:{_WS_RE}*\([^)]*\))?{_WS_RE}+AS)(?![A-Za-z0-9_])", re.IGNORECASE)
_ENSEMBLE_START = frozenset("HhPpDdEe")


#: ``FOR $var = start TO end [STEP step]``: the variable and the expressions.
_ForHead = tuple[str, ast.Expr, ast.Expr, ast.Expr | None]
#: What opens a block: REPEAT's count, WHILE's and IF's condition, FOR's head,
#: DFS's name; None for the program's top level.
_Head = ast.Expr | str | _ForHead | None
#: The expression node types (:data:`gcode.ast.Expr`), for isinstance.
_EXPR_TYPES = (ast.Num, ast.Var, ast.Neg, ast.BinOp, ast.Compare, ast.Logic, ast.Not)


class _Open:
    """A line that opens a block: ``REPEAT``, ``WHILE``, ``IF``, ``FOR``, ``DFS``."""

    def __init__(self, kind: str, head: _Head, span: ast.Span):
        self.kind, self.head, self.span = kind, head, span


class _Branch:
    """``ELSEIF cond THEN`` (head the condition) or ``ELSE`` (head None)."""

    def __init__(self, head: ast.Expr | None, span: ast.Span):
        self.head, self.span = head, span


class _Close:
    """A line that closes a block: ``END REPEAT``, ``ENDWHILE``, ``ENDIF``, ``NEXT``, ``ENDDFS``."""

    def __init__(self, kind: str, span: ast.Span):
        self.kind, self.span = kind, span


#: What one line reads as: a statement or a block marker.
_Item = ast.Stmt | _Open | _Branch | _Close

_CLOSERS = {"REPEAT": "END REPEAT", "WHILE": "ENDWHILE", "IF": "ENDIF", "DFS": "ENDDFS",
            "FOR": "NEXT"}
_END_BLOCKS = ("REPEAT", "WHILE", "IF", "DFS")


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
    p = _Program(lenient, max_statements, max_tokens)
    for lineno, line in enumerate(iter_lines(text), 1):
        if lineno > max_lines:
            raise GCodeError(f"more than {max_lines} lines (max_lines = {max_lines})", lineno, 1,
                             line[:20])
        p.line(line, lineno)
    return p.program()


class _Program:
    """The state of :func:`parse`: open blocks, subroutines, macros, warnings
    and the counts checked against the bounds."""

    def __init__(self, lenient: bool, max_statements: int, max_tokens: int):
        self.lenient, self.max_statements, self.max_tokens = lenient, max_statements, max_tokens
        self.stack: list[_Frame] = [_Frame(None, None, ast.Span(0, 0, ""))]
        self.subs: dict[str, ast.Sub] = {}
        self.macros: Macros = {}
        self.warnings: list[str] = []
        self.count = 0
        self.tokens = 0
        # replacements left for the program, and its bound
        self.expansions = [MAX_PROGRAM_EXPANSIONS, MAX_PROGRAM_EXPANSIONS]

    def line(self, line: str, lineno: int) -> None:
        """Read one source line."""
        head = line.lstrip(" \t\f\v")[:1]
        if head in _ENSEMBLE_START and (m := _ENSEMBLE.match(line)) is not None:
            raise _ensemble_error(m, lineno)
        if head == "#":
            self.directive(line, lineno)
            return
        lexed: list[Token] = []   # filled even when lexing fails: skipped text costs too
        try:
            item = _Line(line, lineno, lexed, self.macros, self.expansions).statement()
        except UnsupportedError as err:
            self.charge_tokens(lexed, lineno)
            self.skip(err, line, lineno)
            return
        self.charge_tokens(lexed, lineno)
        if item is not None:
            self.add(item)

    def charge_tokens(self, lexed: list[Token], lineno: int) -> None:
        self.tokens = _count_tokens(self.tokens, lexed, self.max_tokens, lineno)

    def charge_statement(self, line: int, col: int, text: str) -> None:
        self.count += 1
        _check_count(self.count, self.max_statements, line, col, text)

    def directive(self, line: str, lineno: int) -> None:
        self.charge_statement(lineno, 1, line[:40])
        lexed: list[Token] = []
        try:
            directive(line, lineno, self.macros, lexed)
        except UnsupportedError as err:
            self.charge_tokens(lexed, lineno)
            if not self.lenient:
                raise
            self.warnings.append(f"{err} (statement skipped)")
            return
        self.charge_tokens(lexed, lineno)

    def skip(self, err: UnsupportedError, line: str, lineno: int) -> None:
        """Lenient mode: skip a statement outside the subset, unless it moves."""
        if not self.lenient or _STRUCTURAL.match(line):
            raise err
        code = line[:split_comment(line)]
        if self.macros:
            code = expand(code, self.macros, lineno, budget=self.expansions)[0]
        if _MOTION_HINT.search(code):
            raise GCodeError(f"{err.reason}; this statement moves an axis, and a move tipgeo "
                             "cannot evaluate is an error even in lenient mode", err.line,
                             err.column, err.text) from None
        self.charge_statement(err.line, err.column, err.text)
        self.warnings.append(f"{err} (statement skipped)")

    def add(self, item: _Item) -> None:
        span = item.span
        self.charge_statement(span.line, span.col, span.text)
        if isinstance(item, _Open):
            self.open(item)
        elif isinstance(item, _Branch):
            self.branch(item)
        elif isinstance(item, _Close):
            self.close(item)
        else:
            self.stack[-1].body.append(item)

    def open(self, item: _Open) -> None:
        span, top = item.span, self.stack[-1]
        if len(self.stack) > MAX_NESTING:
            raise GCodeError(f"{item.kind} nested deeper than {MAX_NESTING} blocks",
                             *_where(span))
        if item.kind == "DFS" and len(self.stack) > 1:
            raise GCodeError(f"DFS inside {top.kind} (line {top.span.line}): a subroutine is "
                             "defined at the top level", *_where(span))
        self.stack.append(_Frame(item.kind, item.head, span))

    def branch(self, item: _Branch) -> None:
        top = self.stack[-1]
        word = "ELSE" if item.head is None else "ELSEIF"
        if top.kind != "IF":
            raise GCodeError(f"{word} without IF", *_where(item.span))
        if top.branches[-1][0] is None:
            raise GCodeError(f"{word} after ELSE", *_where(item.span))
        top.branches.append((item.head, []))

    def close(self, item: _Close) -> None:
        span, top = item.span, self.stack[-1]
        if top.kind != item.kind:
            closer = _CLOSERS[item.kind]
            if top.kind is None:
                raise GCodeError(f"{closer} without {item.kind}", *_where(span))
            raise GCodeError(f"{closer} cannot close the {top.kind} of line "
                             f"{top.span.line} (expected {_CLOSERS[top.kind]})", *_where(span))
        self.stack.pop()
        node = top.node()
        if not isinstance(node, ast.Sub):
            self.stack[-1].body.append(node)
            return
        if node.name in self.subs:
            raise GCodeError(f"subroutine {node.name} is defined twice (first at line "
                             f"{self.subs[node.name].span.line})", *_where(span))
        self.subs[node.name] = node

    def program(self) -> ast.Program:
        if len(self.stack) > 1:
            top = self.stack[-1]
            raise GCodeError(f"{top.kind} without {_CLOSERS.get(top.kind or '')}",
                             *_where(top.span))
        return ast.Program(tuple(self.stack[0].body), tuple(self.warnings),
                           tuple(self.subs.values()), tuple(self.macros.items()))


def _ensemble_error(m: re.Match[str], lineno: int) -> GCodeError:
    return GCodeError(
        f"this is Ensemble AeroBasic, not A3200 AeroBasic: {m.group(1).split()[0].upper()}"
        " belongs to the Ensemble dialect (HEADER … END HEADER, PROGRAM … END PROGRAM, "
        "DIM … AS, ' comments); tipgeo reads A3200 programs — translate it (DVAR "
        "$name for DIM, no HEADER/PROGRAM block) or write it for the A3200",
        lineno, m.start(1) + 1, m.group(1))


class _Frame:
    """A block being parsed: its kind, header and branches of statements
    (``(condition, statements)``; the condition is None but for IF's)."""

    def __init__(self, kind: str | None, head: _Head, span: ast.Span):
        self.kind, self.head, self.span = kind, head, span
        first = head if isinstance(head, _EXPR_TYPES) else None
        self.branches: list[tuple[ast.Expr | None, list[ast.Stmt]]] = [(first, [])]

    @property
    def body(self) -> list[ast.Stmt]:
        return self.branches[-1][1]

    def node(self) -> ast.Stmt | ast.Sub:
        head, body = self.head, tuple(self.branches[0][1])
        if self.kind == "IF" or head is None:
            return ast.If(tuple((c, tuple(b)) for c, b in self.branches), self.span)
        if isinstance(head, str):                   # DFS name
            return ast.Sub(head, body, self.span)
        if isinstance(head, tuple):                 # FOR $var = start TO end STEP step
            return ast.For(*head, body, self.span)
        if self.kind == "REPEAT":
            return ast.Repeat(head, body, self.span)
        return ast.While(head, body, self.span)


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
    expr, _ = p.disjunction(0)
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


def _where(span: ast.Span) -> tuple[int, int, str]:
    return span.line, span.col, span.text


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


class _Line(ExpressionParser):
    """Recursive-descent parser of the tokens of one line: the statement
    parsers ``st_<name>``, one for each ``parser`` of the command table
    (:data:`_STATEMENT_PARSERS`)."""

    def __init__(self, line: str, lineno: int, tokens: list[Token] | None = None,
                 macros: Macros | None = None, expansions: Budget | None = None):
        self.line, self.lineno = line, lineno
        self.cond = False           # inside an IF/WHILE condition: '=' compares
        self.pos = 0
        if not macros:
            self.tokens: list[Token] = tokenize_line(line, lineno, out=tokens)
            return
        end = split_comment(line)
        code, pieces = expand(line[:end], macros, lineno, budget=expansions)
        if len(pieces) == 1:        # no macro used on this line
            self.tokens = tokenize_line(line, lineno, out=tokens)
            return
        self.tokens = _expanded_tokens(code, pieces, lineno, tokens)

    # -- statements -------------------------------------------------------------
    def statement(self) -> _Item | None:
        """The line's statement, a block marker, or None for an empty line."""
        toks = self.tokens
        if not toks or (self.line_number() and self.peek() is None):
            return None
        span = ast.Span(self.lineno, toks[0].col, self.line[toks[0].col - 1:toks[-1].end])
        start = self.tokens[self.pos]       # there is one: checked above
        if start.kind == "var":
            return self.assignment(span)
        if start.kind != "ident":
            raise self.error(f"expected a statement, found {start.text!r}", start)
        cmd = COMMANDS.get(start.str_value)
        if cmd is not None:
            return _STATEMENT_PARSERS[cmd.parser](self, start, span)
        if len(start.str_value) == 1:
            return self.st_block(start, span)
        raise self.error(f"unknown keyword {start.text!r}", start, UnsupportedError)

    def line_number(self) -> bool:
        """Skip a leading ``N`` line number; True if there was one."""
        first = self.tokens[0]
        if not (first.kind == "ident" and first.value == "N"):
            return False
        self.advance()
        num = self.peek()
        if num is None or num.kind != "num" or not num.text.isdigit():
            raise self.error("N must be followed by a line number", first)
        self.advance()
        return True

    def next_word(self) -> str | None:
        """The identifier after the statement's first token, if any."""
        nxt = self.tokens[self.pos + 1] if self.pos + 1 < len(self.tokens) else None
        return nxt.str_value if nxt is not None and nxt.kind == "ident" else None

    def st_dvar(self, start: Token, span: ast.Span) -> ast.DVar:
        return self.dvar(span)

    def st_repeat(self, start: Token, span: ast.Span) -> _Open:
        self.advance()
        if self.peek() is None:
            raise self.error("REPEAT needs a count", start)
        count, _ = self.expr(0)
        self.expect_end()
        return _Open("REPEAT", count, span)

    def st_if(self, start: Token, span: ast.Span) -> _Open | _Branch:
        """``IF``/``ELSEIF cond THEN``, ``WHILE cond [DO]``."""
        kw = start.str_value
        self.advance()
        if self.peek() is None:
            raise self.error(f"{kw} needs a condition", start)
        cond = self.condition()
        closing = "DO" if kw == "WHILE" else "THEN"
        if self.is_word(closing):
            self.advance()
        elif kw != "WHILE":
            raise self.error(f"{kw} … needs THEN at the end of its line", self.peek() or start)
        if (extra := self.peek()) is not None:
            raise self.error(f"unexpected {extra.text!r}: {kw} … {closing} ends its "
                             "line; write the statements on the lines below", extra)
        return _Open(kw, cond, span) if kw != "ELSEIF" else _Branch(cond, span)

    def st_else(self, start: Token, span: ast.Span) -> _Branch:
        self.advance()
        self.expect_end()
        return _Branch(None, span)

    def st_close(self, start: Token, span: ast.Span) -> _Close:
        """``ENDREPEAT``, ``ENDWHILE``, ``ENDIF``, ``ENDDFS``."""
        self.advance()
        self.expect_end()
        return _Close(start.str_value[3:], span)

    def st_for(self, start: Token, span: ast.Span) -> _Open:
        return self.for_head(start, span)

    def st_next(self, start: Token, span: ast.Span) -> _Close:
        self.advance()
        if (var := self.peek()) is not None and var.kind == "var":
            self.advance()
        self.expect_end()
        return _Close("FOR", span)

    def st_dfs(self, start: Token, span: ast.Span) -> _Open:
        self.advance()
        name = self.name(start)
        self.expect_end()
        return _Open("DFS", name, span)

    def st_call(self, start: Token, span: ast.Span) -> ast.Call:
        self.advance()
        return self.call(self.name(start), span)

    def st_dwell(self, start: Token, span: ast.Span) -> ast.Dwell:
        self.advance()
        if self.peek() is None:
            raise self.error("DWELL needs a time (s)", start)
        seconds, _ = self.expr(0)
        self.expect_end()
        return ast.Dwell(seconds, span)

    def st_freerun(self, start: Token, span: ast.Span) -> ast.NoMotion:
        self.advance()
        axis = self.peek()
        if axis is None or axis.kind != "ident":
            raise self.error("FREERUN needs an axis", axis or start)
        self.pos = len(self.tokens)
        if axis.value in ("X", "Y", "Z", "C"):
            return ast.NoMotion("FREERUN", f"path axis {axis.value} runs free at a velocity "
                                "with no end point: recorded, not simulated (its position "
                                "is left where it was)", span)
        return ast.NoMotion("FREERUN", f"auxiliary axis {axis.value} runs free (not a path "
                            "axis: X Y Z C)", span)

    def st_unsimulated(self, start: Token, span: ast.Span) -> _Item:
        raise self.error(f"{start.value} moves axes in a way tipgeo cannot simulate; a move "
                         "that cannot be evaluated is an error in every mode", start)

    def st_no_motion(self, start: Token, span: ast.Span) -> ast.NoMotion:
        kw = start.str_value
        what = NO_MOTION[kw]
        after = self.next_word()
        toks, i = self.tokens, self.pos
        if kw in _TASK_WORD and after is None and len(toks) > i + 2 \
                and toks[i + 1].kind == "num" and toks[i + 2].kind == "ident":
            after = toks[i + 2].str_value   # PROGRAM 1 RUN "other.pgm"
        self.pos = len(self.tokens)
        if after is not None and len(after) > 1:
            kw, what = f"{kw} {after}", f"{what}: {after}"
        return ast.NoMotion(kw, what, span)

    def st_mode(self, start: Token, span: ast.Span) -> ast.Mode | _Close:
        kind = self.next_word()
        if start.value == "END" and kind is not None and kind in _END_BLOCKS:
            self.pos += 2                    # END REPEAT, END WHILE, END IF, END DFS
            self.expect_end()
            return _Close(kind, span)
        return self.mode(span)

    def st_pso(self, start: Token, span: ast.Span) -> ast.Pso:
        return self.pso(span)

    def st_block(self, start: Token, span: ast.Span) -> ast.Block | ast.Mode:
        return self.block(span)

    def for_head(self, start: Token, span: ast.Span) -> _Open:
        """``FOR $var = start TO end [STEP step]``."""
        self.advance()
        var = self.peek()
        if var is None or var.kind != "var":
            raise self.error("FOR needs a $variable", var or start)
        self.advance()
        if not self.is_op("="):
            raise self.error(f"expected '=' after FOR {var.text}", self.peek() or var)
        self.advance()
        first = self.need_expr(var)
        end = self.keyword_expr("TO", start)
        step = self.keyword_expr("STEP", start) if self.peek() is not None else None
        self.expect_end()
        return _Open("FOR", (var.str_value, first, end, step), span)

    def keyword_expr(self, word: str, start: Token) -> ast.Expr:
        tok = self.peek()
        if tok is None or not self.is_word(word):
            raise self.error(f"FOR … needs {word}", tok or start)
        self.advance()
        return self.need_expr(tok)

    def name(self, head: Token) -> str:
        """The subroutine name after ``DFS``/``CALL`` (letters, digits, ``_``), upper-case."""
        tok = self.peek()
        if tok is None or tok.kind != "ident":
            raise self.error(f"{head.value} needs a subroutine name", tok or head)
        m = SUB_NAME.match(self.line, tok.col - 1) if tok.width is None else None
        text = m.group(0) if m is not None else tok.text
        stop = tok.col - 1 + len(text)
        while (nxt := self.peek()) is not None and nxt.col - 1 < stop:
            self.advance()
        return text.upper()

    def call(self, name: str, span: ast.Span) -> ast.Call:
        args: list[tuple[str, ast.Expr]] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind == "op" and tok.value == ",":
                continue
            if tok.kind != "ident" or len(tok.str_value) != 1:
                raise self.error(f"CALL arguments are letter words (P1 Q$x), found {tok.text!r}",
                                 tok)
            if (arg := self.peek()) is None or arg.kind in ("ident", "str"):
                raise self.error(f"the argument {tok.text} needs a value", tok)
            value, _ = self.unary(0)
            if any(letter == tok.value for letter, _ in args):
                raise self.error(f"argument {tok.value} given twice", tok)
            args.append((tok.str_value, value))
        return ast.Call(name, tuple(args), span)

    def assignment(self, span: ast.Span) -> _Item:
        var = self.advance()
        index = self.index_suffix()
        if not self.is_op("="):
            tok = self.peek() or var
            raise self.error(f"expected '=' after {self.source(var)}", tok)
        eq = self.advance()
        if self.peek() is None:
            raise self.error(f"expected an expression after {var.text} =", eq)
        special = self.special_assignment(var, span)
        if special is not None:
            return special
        expr, _ = self.expr(0)
        self.expect_end()
        if index or IO_NAME.match(var.str_value):
            return ast.SysAssign(var.str_value, tuple(index), expr, span)
        return ast.Assign(var.str_value, expr, span)

    def index_suffix(self) -> list[ast.IndexPart]:
        """``[i]``, ``.X`` and glued ``.0`` parts after a system variable's name."""
        index: list[ast.IndexPart] = []
        while (tok := self.peek()) is not None:
            if tok.kind == "op" and tok.value == "[":
                index.append(self.bracket_index(tok))
            elif tok.kind == "op" and tok.value == ".":
                self.advance()
                field = self.peek()
                if field is None or field.kind != "ident":
                    raise self.error("expected a field name after '.'", field or tok)
                self.advance()
                index.append(field.str_value)
            elif tok.kind == "num" and tok.text.startswith(".") and tok.text[1:].isdigit():
                self.advance()           # $DO0.0: output 0 of bank 0
                index.append(tok.text)
            else:
                break
        return index

    def bracket_index(self, tok: Token) -> ast.Expr:
        self.advance()
        if self.peek() is None:
            raise self.error("'[' needs an index", tok)
        value, _ = self.expr(0)
        if not self.is_op("]"):
            raise self.error("expected ']'", self.peek() or tok)
        self.advance()
        return value

    def special_assignment(self, var: Token, span: ast.Span) -> ast.Stmt | None:
        """A status read, a string expression or a file/message function on
        the right of ``$var =`` (a token follows it), or None for an ordinary
        expression."""
        tok = self.tokens[self.pos]
        rest = self.tokens[self.pos:]
        if tok.kind == "ident" and tok.str_value in STATUS_FUNCTIONS:
            self.pos = len(self.tokens)     # $z = AXISSTATUS(Z, DATAITEM_…)
            return ast.StatusRead(var.str_value, tok.str_value, span)
        stringy = any(t.kind == "str" or (t.kind == "ident" and t.str_value in STRING_FUNCTIONS)
                      for t in rest)
        evaluated = all(t.kind != "ident" or t.str_value in _EVALUATED_STRING_FUNCTIONS
                        for t in rest)
        if stringy and evaluated:
            tree = self.string_expr()
            self.expect_end()
            return ast.StringAssign(var.str_value, tree, span)
        if tok.kind == "ident" and tok.str_value in NO_MOTION \
                and tok.str_value not in STRING_FUNCTIONS:
            kw = self.advance().str_value   # $h = FILEOPEN "log.txt", 2
            self.pos = len(self.tokens)
            return ast.NoMotion(kw, f"{NO_MOTION[kw]} (result in {self.source(var)})", span)
        if stringy:
            self.pos = len(self.tokens)     # $s = FORMAT(…): recorded, not evaluated
            return ast.NoMotion("STRING", f"sets the string {self.source(var)} (not "
                                "evaluated)", span)
        return None

    def dvar(self, span: ast.Span) -> ast.DVar:
        head = self.advance()
        names: list[str] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind == "var":
                names.append(tok.str_value)
                if self.is_op("["):                 # an array: DVAR $pts[100]
                    self.advance()
                    if self.peek() is None:
                        raise self.error("'[' needs a size", tok)
                    self.expr(0)
                    if not self.is_op("]"):
                        raise self.error("expected ']'", self.peek() or tok)
                    self.advance()
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
                if tok.kind == "ident" and re.fullmatch(r"[A-Z][A-Z0-9_]*", tok.str_value):
                    args.append(tok.str_value)  # any axis name: X Y Z C, D, U, AA …
                elif not (tok.kind == "op" and tok.value == ","):
                    raise self.error(f"ENABLE expects axis names, found {tok.text!r}", tok)
            if not args:
                raise self.error("ENABLE needs at least one axis", head)
        elif head.value == "END" and (tok := self.peek()) is not None and tok.kind == "ident" \
                and tok.value == "PROGRAM":
            self.advance()
            args.append("PROGRAM")
            self.expect_end()
        else:
            self.expect_end()
        return ast.Mode(head.str_value, tuple(args), span)

    def pso(self, span: ast.Span) -> ast.Pso:
        head = self.advance()
        axis = self.peek()
        if axis is None or axis.kind != "ident" or axis.value not in AXIS_LETTERS:
            raise self.error(f"{head.value} needs an axis letter", axis or head)
        self.advance()
        args: list[ast.PsoArg] = []
        while (tok := self.peek()) is not None:
            if tok.kind == "op" and tok.value == ",":
                self.advance()
            elif tok.kind == "ident":
                self.advance()
                args.append(tok.str_value)
            else:
                expr, _ = self.expr(0)
                args.append(expr)
        return ast.Pso(head.str_value, axis.str_value, tuple(args), span)

    def block(self, span: ast.Span) -> ast.Block | ast.Mode:
        words: list[ast.Word] = []
        keywords: list[str] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind != "ident":
                if tok.kind == "op" and tok.value == ")":
                    raise self.error("unbalanced parenthesis: unexpected ')'", tok)
                raise self.error(f"expected a word, found {tok.text!r}", tok)
            if tok.str_value in MOTION_KEYWORDS:
                keywords.append(tok.str_value)
                continue
            if len(tok.str_value) > 1:
                raise self.error(f"unknown keyword {tok.text!r}", tok, UnsupportedError)
            words.append(self.word(tok))
        ends = [w for w in words if w.letter == "M"]
        if ends:
            if len(words) - sum(w.letter == "N" for w in words) != 1 or keywords:
                raise GCodeError(f"{ends[0].span.text} (end of program) must stand alone",
                                 *_where(ends[0].span))
            end = ends[0].value             # M2 or M30: a number (word)
            code = int(end.value) if isinstance(end, ast.Num) else 0
            return ast.Mode("END", (f"M{code}",), span)
        return ast.Block(tuple(words), tuple(keywords), span)

    def word(self, letter: Token) -> ast.Word:
        name = letter.str_value
        first = self.pos
        value: ast.Expr | None = None
        if (nxt := self.peek()) is not None and (
                nxt.kind in ("num", "var") or (nxt.kind == "op" and nxt.str_value in "(+-")):
            value, _ = self.unary(0)
        text = self.source(letter)
        where = (self.lineno, letter.col, text)
        plain = self.tokens[first] if self.pos == first + 1 else None   # one token: G1, M30
        if name == "M" and plain is not None and _end_word(plain):
            return ast.Word("M", ast.Num(float(plain.value)), ast.Span(*where))
        _check_letter(name, where)
        if name == "G":
            value = _g_code(plain, text, where)
        if value is None and name not in AXIS_LETTERS:
            raise GCodeError(f"the {name} word needs a value", *where)
        return ast.Word(name, value, ast.Span(*where))


def _end_word(tok: Token | None) -> bool:
    """``M2`` or ``M30``: the end of the program."""
    return tok is not None and tok.kind == "num" and tok.text.isdigit() and tok.value in (2, 30)


def _check_letter(name: str, where: tuple[int, int, str]) -> None:
    if name not in WORD_LETTERS:
        what = "M words other than M2 and M30 (end of program) are" if name == "M" else \
            f"{name} words are"
        raise UnsupportedError(f"{what} not supported", *where)
    if name == "N":
        raise GCodeError("a line number N must start the line", *where)


def _g_code(tok: Token | None, text: str, where: tuple[int, int, str]) -> ast.Num:
    if tok is None or tok.kind != "num":
        raise GCodeError("a G code must be a plain number", *where)
    if not tok.text.isdigit() or tok.value not in G_CODES:
        raise UnsupportedError(f"unsupported G code {text}", *where)
    return ast.Num(float(tok.value))


def _expanded_tokens(code: str, pieces: list[Piece], lineno: int,
                     tokens: list[Token] | None) -> list[Token]:
    """Tokens of a macro-expanded line, located where their text was written
    (a replacement's tokens at the macro's use)."""
    raw: list[Token] = []
    try:
        tokenize_line(code, lineno, out=raw)
    except GCodeError as err:
        col = origin(pieces, err.column - 1)[0] if err.column else 0
        raise type(err)(err.reason, lineno, col, err.text) from None
    finally:
        mapped: list[Token] = []
        for tok in raw:
            col, width = origin(pieces, tok.col - 1)
            mapped.append(Token(tok.kind, tok.value, col, tok.text, width))
        if tokens is not None:
            tokens.extend(mapped)
    return mapped


#: The statement parser of each ``parser`` of :data:`gcode.commands.COMMANDS`.
_STATEMENT_PARSERS: dict[str, Callable[[_Line, Token, ast.Span], _Item]] = {
    "dvar": _Line.st_dvar, "repeat": _Line.st_repeat, "if": _Line.st_if, "else": _Line.st_else,
    "close": _Line.st_close, "for": _Line.st_for, "next": _Line.st_next, "dfs": _Line.st_dfs,
    "call": _Line.st_call, "dwell": _Line.st_dwell, "freerun": _Line.st_freerun,
    "unsimulated": _Line.st_unsimulated, "no_motion": _Line.st_no_motion,
    "mode": _Line.st_mode, "pso": _Line.st_pso, "block": _Line.st_block,
}
