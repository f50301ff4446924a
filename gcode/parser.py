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

from . import ast
from .errors import GCodeError, check_limit
from .lexer import (
    MAX_LINE_LENGTH,
    Token,
    UnsupportedError,
    iter_lines,
    split_comment,
    tokenize_line,
)
from .strings import FUNCTIONS as _EVALUATED_STRING_FUNCTIONS

__all__ = ["parse", "parse_expression", "is_statement", "G_CODES", "WORD_LETTERS",
           "AXIS_LETTERS", "MOTION_KEYWORDS", "MODE_KEYWORDS", "MAX_NESTING",
           "MAX_EXPR_DEPTH", "DEFAULT_MAX_STATEMENTS", "DEFAULT_MAX_TOKENS",
           "DEFAULT_MAX_LINES", "NO_MOTION", "G_NO_MOTION", "UNSIMULATED_MOTION", "IO_NAME",
           "MAX_MACROS", "MAX_EXPANSIONS", "MAX_PROGRAM_EXPANSIONS", "STRING_FUNCTIONS",
           "STATUS_FUNCTIONS"]

#: G codes accepted (``G00``–``G03`` may be written with a leading zero).
G_CODES = frozenset({0, 1, 2, 3, 4, 17, 40, 41, 42, 44, 66, 70, 71, 75, 76, 84, 90, 91, 92, 98,
                     108, 109, 359, 360, 361})
#: Letters that may start a word (P: the dwell time of G4, s).
WORD_LETTERS = frozenset("GXYZABCIJKFETNP")
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

#: Statements that move nothing the simulation follows: parsed, recorded by
#: the interpreter as "no motion" with what they do, otherwise ignored. The
#: value is what the statement does (its mode word, if any, is added).
NO_MOTION = {
    "VELOCITY": "velocity blending (corner speed kept between moves)",
    "ROUNDING": "corner rounding",
    "CRITICAL": "critical section (runs without interruption)",
    "WAIT": "waits for a condition (motion done, in position, a mode)",
    "FILEOPEN": "opens a file", "FILECLOSE": "closes a file", "FILEWRITE": "writes a file",
    "FILEREAD": "reads a file", "FILEPRINT": "writes a file", "FILEDELETE": "deletes a file",
    "FILEEXISTS": "tests a file", "FILEPOS": "moves a file pointer",
    "FILEREADLINE": "reads a file", "FILEWRITELINE": "writes a file",
    "FILEAPPEND": "opens a file for appending", "FILERENAME": "renames a file",
    "MSGDISPLAY": "shows a message", "MSGCLEAR": "clears messages", "MSGBOX": "shows a box",
    "MSGLAMP": "sets a lamp", "MSGSHOW": "shows a message", "MSGHIDE": "hides messages",
    "DISPLAY": "shows a message", "FORMAT": "formats a string", "STRCOPY": "copies a string",
    "STRFORMAT": "formats a string", "STRINSERT": "edits a string", "STRDELETE": "edits a string",
    "STRUPR": "edits a string", "STRLWR": "edits a string", "STRTONUM": "converts a string",
    "NUMTOSTR": "converts a number", "STRCONCAT": "joins strings", "STRLEN": "measures a string",
    "SCOPETRIG": "triggers the scope", "DATAACQ": "data acquisition", "DISABLE": "disables drives",
    "BRAKE": "sets a brake", "FAULTACK": "acknowledges faults", "ACKNOWLEDGEALL":
    "acknowledges faults", "PLANE": "selects a plane", "SETGAIN": "sets servo gains",
    "PROGRAM": "A3200 task control: runs, loads, pauses or stops a program on a task (the "
               "other program is not simulated here)",
    "DBLTOSTR": "converts a number to a string",
    "FARCALL": "calls another program file and waits for it (not simulated here)",
}
#: String functions: an assignment whose right side uses one (or a string)
#: sets a string, recorded as no motion (``$s = "x=" + DBLTOSTR($x, 3)``).
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
G_NO_MOTION = {108: "velocity blending on (VELOCITY ON)", 109: "velocity blending off",
               359: "wait mode: no wait (G359)", 360: "wait mode: auto (G360)",
               361: "wait mode: in position (G361)",
               66: "G66: a modal mode the simulation does not model (recorded, no motion)"}
#: Keywords that move axes in ways tipgeo cannot simulate: an error in every mode.
UNSIMULATED_MOTION = frozenset({"HOME", "MOVEABS", "MOVEINC", "MOVETO", "INDEX", "CAMSYNC",
                                "GEAR", "SCAN", "OSCILLATE", "HOMEASYNC"})

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
_DIRECTIVE = re.compile(rf"{_WS_RE}*#{_WS_RE}*([A-Za-z]*)")
_MACRO_DEF = re.compile(rf"{_WS_RE}*#{_WS_RE}*define{_WS_RE}+([A-Za-z_][A-Za-z0-9_]*)(\(?)",
                        re.IGNORECASE)
_MACRO_USE = re.compile(r"(?<![A-Za-z0-9_$.])[A-Za-z_][A-Za-z0-9_]*")
_PARAMS = re.compile(rf"{_WS_RE}*([A-Za-z_][A-Za-z0-9_]*){_WS_RE}*(,|\))")
#: Most parameters of a function-like macro.
MAX_MACRO_PARAMS = 32
_SUB_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: I/O system variables: ``$DO``, ``$DI``, ``$AO``, ``$AI`` (a glued number too: ``$DO0``).
IO_NAME = re.compile(r"(?:do|di|ao|ai)[0-9]*\Z")
#: Most ``#define`` macros in one program.
MAX_MACROS = 10_000
#: Most macro replacements made in one line, nested ones included.
MAX_EXPANSIONS = 4096
#: Most macro replacements in a whole program: about 2.3 µs each measured, so
#: reaching it costs about 2–3 s of CPU.
MAX_PROGRAM_EXPANSIONS = 1_000_000


class _Open:
    """A line that opens a block: ``REPEAT``, ``WHILE``, ``IF``, ``DFS``."""

    def __init__(self, kind: str, head, span: ast.Span):
        self.kind, self.head, self.span = kind, head, span


class _Branch:
    """``ELSEIF cond THEN`` (head the condition) or ``ELSE`` (head None)."""

    def __init__(self, head, span: ast.Span):
        self.head, self.span = head, span


class _Close:
    """A line that closes a block: ``END REPEAT``, ``ENDWHILE``, ``ENDIF``, ``ENDDFS``."""

    def __init__(self, kind: str, span: ast.Span):
        self.kind, self.span = kind, span


_CLOSERS = {"REPEAT": "END REPEAT", "WHILE": "ENDWHILE", "IF": "ENDIF", "DFS": "ENDDFS",
            "FOR": "NEXT"}


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
    stack: list[_Frame] = [_Frame(None, None, None)]
    subs: dict[str, ast.Sub] = {}
    macros: dict[str, str] = {}
    warnings: list[str] = []
    count = 0
    tokens = 0
    expansions = [MAX_PROGRAM_EXPANSIONS]     # replacements left for the whole program
    for lineno, line in enumerate(iter_lines(text), 1):
        if lineno > max_lines:
            raise GCodeError(f"more than {max_lines} lines (max_lines = {max_lines})", lineno, 1,
                             line[:20])
        head = line.lstrip(" \t\f\v")[:1]
        if head in _ENSEMBLE_START and (m := _ENSEMBLE.match(line)) is not None:
            raise GCodeError(
                f"this is Ensemble AeroBasic, not A3200 AeroBasic: {m.group(1).split()[0].upper()}"
                " belongs to the Ensemble dialect (HEADER … END HEADER, PROGRAM … END PROGRAM, "
                "DIM … AS, ' comments); tipgeo reads A3200 programs — translate it (DVAR "
                "$name for DIM, no HEADER/PROGRAM block) or write it for the A3200",
                lineno, m.start(1) + 1, m.group(1))
        if head == "#":
            count += 1
            _check_count(count, max_statements, lineno, 1, line[:40])
            lexed: list[Token] = []
            try:
                _directive(line, lineno, macros, lexed)
            except UnsupportedError as err:
                tokens = _count_tokens(tokens, lexed, max_tokens, lineno)
                if not lenient:
                    raise
                warnings.append(f"{err} (statement skipped)")
                continue
            tokens = _count_tokens(tokens, lexed, max_tokens, lineno)
            continue
        lexed = []   # filled even when lexing fails: skipped text costs too
        try:
            item = _Line(line, lineno, lexed, macros, expansions).statement()
        except UnsupportedError as err:
            tokens = _count_tokens(tokens, lexed, max_tokens, lineno)
            if not lenient or _STRUCTURAL.match(line):
                raise
            code = _expand(line[:split_comment(line)], macros, lineno, budget=expansions)[0] \
                if macros else line[:split_comment(line)]
            if _MOTION_HINT.search(code):
                raise GCodeError(f"{err.reason}; this statement moves an axis, and a move tipgeo "
                                 "cannot evaluate is an error even in lenient mode", err.line,
                                 err.column, err.text) from None
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
        top = stack[-1]
        if isinstance(item, _Open):
            if len(stack) > MAX_NESTING:
                raise GCodeError(f"{item.kind} nested deeper than {MAX_NESTING} blocks",
                                 span.line, span.col, span.text)
            if item.kind == "DFS" and len(stack) > 1:
                raise GCodeError(f"DFS inside {top.kind} (line {top.span.line}): a subroutine is "
                                 "defined at the top level", span.line, span.col, span.text)
            stack.append(_Frame(item.kind, item.head, span))
        elif isinstance(item, _Branch):
            word = "ELSE" if item.head is None else "ELSEIF"
            if top.kind != "IF":
                raise GCodeError(f"{word} without IF", span.line, span.col, span.text)
            if top.branches[-1][0] is None:
                raise GCodeError(f"{word} after ELSE", span.line, span.col, span.text)
            top.branches.append((item.head, []))
        elif isinstance(item, _Close):
            if top.kind != item.kind:
                closer = _CLOSERS[item.kind]
                if top.kind is None:
                    raise GCodeError(f"{closer} without {item.kind}", span.line, span.col,
                                     span.text)
                raise GCodeError(f"{closer} cannot close the {top.kind} of line "
                                 f"{top.span.line} (expected {_CLOSERS[top.kind]})", span.line,
                                 span.col, span.text)
            stack.pop()
            node = top.node()
            if isinstance(node, ast.Sub):
                if node.name in subs:
                    raise GCodeError(f"subroutine {node.name} is defined twice (first at line "
                                     f"{subs[node.name].span.line})", span.line, span.col,
                                     span.text)
                subs[node.name] = node
            else:
                stack[-1].body.append(node)
        else:
            top.body.append(item)
    if len(stack) > 1:
        top = stack[-1]
        raise GCodeError(f"{top.kind} without {_CLOSERS[top.kind]}", top.span.line, top.span.col,
                         top.span.text)
    return ast.Program(tuple(stack[0].body), tuple(warnings), tuple(subs.values()),
                       tuple(macros.items()))


class _Frame:
    """A block being parsed: its kind, header and branches of statements."""

    def __init__(self, kind: str | None, head, span: ast.Span | None):
        self.kind, self.span = kind, span
        self.branches: list[tuple] = [(head, [])]

    @property
    def body(self) -> list:
        return self.branches[-1][1]

    def node(self):
        head, body = self.branches[0]
        if self.kind == "REPEAT":
            return ast.Repeat(head, tuple(body), self.span)
        if self.kind == "WHILE":
            return ast.While(head, tuple(body), self.span)
        if self.kind == "DFS":
            return ast.Sub(head, tuple(body), self.span)
        if self.kind == "FOR":
            return ast.For(*head, tuple(body), self.span)
        return ast.If(tuple((c, tuple(b)) for c, b in self.branches), self.span)


def _directive(line: str, lineno: int, macros: dict[str, str], lexed: list) -> None:
    """Apply one preprocessor line: ``#define NAME text`` or ``#undef NAME``."""
    d = _DIRECTIVE.match(line)
    word = d.group(1).lower()
    col = line.index("#") + 1
    if word == "define":
        m = _MACRO_DEF.match(line)
        if m is None:
            raise GCodeError("#define needs a macro name", lineno, col, line[col - 1:col + 19])
        name = m.group(1)
        end, params = m.end(), None
        if m.group(2):              # NAME( right after the name: function-like
            end, params = _macro_params(line, m, lineno)
        body = line[end:]
        body = body[:split_comment(body)].strip()
        if len(body) > MAX_LINE_LENGTH:
            raise GCodeError(f"macro {name} expands to more than MAX_LINE_LENGTH = "
                             f"{MAX_LINE_LENGTH} characters", lineno, m.start(1) + 1, name)
        offset = end + (len(line[end:]) - len(line[end:].lstrip()))
        try:
            tokenize_line(body, lineno, out=lexed)   # its tokens are checked and charged
        except GCodeError as err:
            raise type(err)(err.reason, lineno, err.column + offset, err.text) from None
        if name not in macros and len(macros) >= MAX_MACROS:
            raise GCodeError(f"more than {MAX_MACROS} macros (MAX_MACROS)", lineno,
                             m.start(1) + 1, name)
        macros[name] = body if params is None else ast.FunctionMacro(params, body)
    elif word == "undef":
        rest = line[d.end():]
        m = _SUB_NAME.match(rest.strip())
        if m is None:
            raise GCodeError("#undef needs a macro name", lineno, col, line[col - 1:col + 19])
        macros.pop(m.group(0), None)
    else:
        raise GCodeError(f"preprocessor directive #{d.group(1)} is not supported (only #define "
                         "and #undef): the statements it would select or bring in cannot be "
                         "checked", lineno, col, line[col - 1:d.end()])


def _macro_params(line: str, m, lineno: int) -> tuple[int, tuple[str, ...]]:
    """The parameter list of ``#define NAME(a, b)``: (end of the list in
    ``line``, the names)."""
    pos, params = m.end(), []
    rest = line[pos:]
    if rest.lstrip(" \t").startswith(")"):
        return pos + rest.index(")") + 1, ()
    while True:
        p = _PARAMS.match(line, pos)
        if p is None:
            raise GCodeError(f"macro {m.group(1)}: expected a parameter name followed by ',' or "
                             "')'", lineno, pos + 1, line[pos:pos + 20])
        if p.group(1) in params:
            raise GCodeError(f"macro {m.group(1)}: parameter {p.group(1)} is named twice",
                             lineno, p.start(1) + 1, p.group(1))
        params.append(p.group(1))
        if len(params) > MAX_MACRO_PARAMS:
            raise GCodeError(f"macro {m.group(1)}: more than {MAX_MACRO_PARAMS} parameters "
                             "(MAX_MACRO_PARAMS)", lineno, p.start(1) + 1, p.group(1))
        pos = p.end()
        if p.group(2) == ")":
            return pos, tuple(params)


def _call_args(code: str, start: int, name: str, lineno: int) -> tuple[int, list[str]] | None:
    """The arguments of a function-like macro used at ``code[start:]`` (just
    after its name): (end of the use, argument texts), or None when no ``(``
    follows (the name is then left alone, as in C). Commas inside parentheses
    or strings do not split; the ``)`` must be on the same line."""
    i = start
    while i < len(code) and code[i] in " \t":
        i += 1
    if i >= len(code) or code[i] != "(":
        return None
    depth, args, arg0, j = 0, [], i + 1, i
    in_string = False
    while j < len(code):
        c = code[j]
        if c == '"':
            in_string = not in_string
        elif not in_string:
            if c == "(":
                depth += 1
            elif c == ")":
                depth -= 1
                if depth == 0:
                    args.append(code[arg0:j])
                    return j + 1, args
            elif c == "," and depth == 1:
                args.append(code[arg0:j])
                arg0 = j + 1
        j += 1
    raise GCodeError(f"macro {name}: its arguments are not closed with ')' on this line",
                     lineno, i + 1, code[i:i + 20])


def _substitute(body: str, params: tuple[str, ...], args: list[str]) -> str:
    """``body`` with each parameter name (outside strings) replaced by its argument."""
    values = dict(zip(params, args))
    strings = _string_spans(body)
    out, pos = [], 0
    for m in _MACRO_USE.finditer(body):
        if m.group(0) in values and not any(a <= m.start() < b for a, b in strings):
            out.append(body[pos:m.start()])
            out.append(values[m.group(0)])
            pos = m.end()
    out.append(body[pos:])
    return "".join(out)


def _expand(code: str, macros: dict[str, str], lineno: int,
            active: frozenset = frozenset(), budget: list | None = None) -> tuple[str, list]:
    """``code`` with every macro name replaced, and the pieces it was made of:
    ``(start in the result, start in code, length in code, from a macro)``.

    As in C, a replacement is rescanned for further macros, except the ones
    being expanded (no recursion); the result is at most MAX_LINE_LENGTH
    characters and costs at most MAX_EXPANSIONS replacements (empty macros
    nested in each other would otherwise cost exponential time for nothing)."""
    if budget is None:
        budget = [MAX_PROGRAM_EXPANSIONS]
    if len(budget) == 1:            # a new line: its own bound, within the program's
        budget = [budget, MAX_EXPANSIONS]
    out: list[str] = []
    pieces: list[tuple[int, int, int, bool]] = []
    pos = 0
    size = 0
    strings = _string_spans(code)
    for m in _MACRO_USE.finditer(code):
        name = m.group(0)
        if m.start() < pos or name not in macros or name in active \
                or any(a <= m.start() < b for a, b in strings):
            continue
        rep, use_end = macros[name], m.end()
        if isinstance(rep, ast.FunctionMacro):
            call = _call_args(code, m.end(), name, lineno)
            if call is None:
                continue
            use_end, args = call
            if args == [""] and not rep.params:
                args = []
            if len(args) != len(rep.params):
                raise GCodeError(f"macro {name} takes {len(rep.params)} argument(s) "
                                 f"({', '.join(rep.params)}), {len(args)} given", lineno,
                                 m.start() + 1, code[m.start():use_end])
            try:                    # arguments are expanded first, then substituted
                args = [_expand(a.strip(), macros, lineno, active, budget)[0] for a in args]
            except GCodeError as err:
                raise GCodeError(err.reason, lineno, m.start() + 1, name) from None
            rep = _substitute(rep.body, rep.params, args)
            if len(rep) > MAX_LINE_LENGTH:
                raise GCodeError(f"line is longer than MAX_LINE_LENGTH = {MAX_LINE_LENGTH} "
                                 "characters after macro expansion", lineno, m.start() + 1, name)
        if m.start() > pos:
            out.append(code[pos:m.start()])
            pieces.append((size, pos, m.start() - pos, False))
            size += m.start() - pos
        budget[1] -= 1
        budget[0][0] -= 1
        if budget[1] < 0:
            raise GCodeError(f"more than {MAX_EXPANSIONS} macro replacements in one line "
                             "(MAX_EXPANSIONS)", lineno, m.start() + 1, name)
        if budget[0][0] < 0:
            raise GCodeError(f"more than {MAX_PROGRAM_EXPANSIONS} macro replacements in the "
                             "program (MAX_PROGRAM_EXPANSIONS)", lineno, m.start() + 1, name)
        if len(active) >= MAX_NESTING:
            raise GCodeError(f"macros nested deeper than {MAX_NESTING}", lineno, m.start() + 1,
                             name)
        if _MACRO_USE.search(rep) is not None:
            try:
                rep = _expand(rep, macros, lineno, active | {name}, budget)[0]
            except GCodeError as err:    # located at this use, not inside a replacement
                raise GCodeError(err.reason, lineno, m.start() + 1, name) from None
        out.append(rep)
        pieces.append((size, m.start(), use_end - m.start(), True))
        size += len(rep)
        pos = use_end
        if size > MAX_LINE_LENGTH:
            raise GCodeError(f"line is longer than MAX_LINE_LENGTH = {MAX_LINE_LENGTH} "
                             "characters after macro expansion", lineno, m.start() + 1, name)
    out.append(code[pos:])
    pieces.append((size, pos, len(code) - pos, False))
    return "".join(out), pieces


def _string_spans(code: str) -> list[tuple[int, int]]:
    spans = []
    i = code.find('"')
    while i >= 0:
        j = code.find('"', i + 1)
        if j < 0:
            spans.append((i, len(code)))
            break
        spans.append((i, j + 1))
        i = code.find('"', j + 1)
    return spans


def _origin(pieces: list, index: int) -> tuple[int, int | None]:
    """1-based source column of character ``index`` of an expanded line, and
    the width to report when it came from a macro (else None)."""
    for start, src, length, macro in reversed(pieces):
        if index >= start:
            if macro:
                return src + 1, length
            return src + 1 + (index - start), None
    return index + 1, None


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


class _Line:
    """Recursive-descent parser of the tokens of one line."""

    def __init__(self, line: str, lineno: int, tokens: list[Token] | None = None,
                 macros: dict[str, str] | None = None, expansions: list | None = None):
        self.line, self.lineno = line, lineno
        self.cond = False           # inside an IF/WHILE condition: '=' compares
        self.pos = 0
        if not macros:
            self.tokens: list[Token] = tokenize_line(line, lineno, out=tokens)
            return
        end = split_comment(line)
        code, pieces = _expand(line[:end], macros, lineno, budget=expansions)
        if len(pieces) == 1:        # no macro used on this line
            self.tokens = tokenize_line(line, lineno, out=tokens)
            return
        raw: list[Token] = []
        try:
            tokenize_line(code, lineno, out=raw)
        except GCodeError as err:
            col = _origin(pieces, err.column - 1)[0] if err.column else 0
            raise type(err)(err.reason, lineno, col, err.text) from None
        finally:
            mapped = []
            for tok in raw:
                col, width = _origin(pieces, tok.col - 1)
                mapped.append(Token(tok.kind, tok.value, col, tok.text, width))
            if tokens is not None:
                tokens.extend(mapped)
        self.tokens = mapped

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
        nxt = self.tokens[self.pos + 1] if self.pos + 1 < len(toks) else None
        after = nxt.value if nxt is not None and nxt.kind == "ident" else None
        if kw == "DVAR":
            return self.dvar(span)
        if kw == "REPEAT":
            self.advance()
            if self.peek() is None:
                raise self.error("REPEAT needs a count", start)
            count, _ = self.expr(0)
            self.expect_end()
            return _Open("REPEAT", count, span)
        if kw in ("WHILE", "IF", "ELSEIF"):
            self.advance()
            if self.peek() is None:
                raise self.error(f"{kw} needs a condition", start)
            cond = self.condition()
            closing = "DO" if kw == "WHILE" else "THEN"
            tok = self.peek()
            if tok is not None and tok.kind == "ident" and tok.value == closing:
                self.advance()
            elif kw != "WHILE":
                raise self.error(f"{kw} … needs THEN at the end of its line", tok or start)
            if self.peek() is not None:
                raise self.error(f"unexpected {self.peek().text!r}: {kw} … {closing} ends its "
                                 "line; write the statements on the lines below", self.peek())
            return _Open(kw, cond, span) if kw != "ELSEIF" else _Branch(cond, span)
        if kw == "FOR":
            return self.for_head(start, span)
        if kw == "NEXT":
            self.advance()
            if self.peek() is not None and self.peek().kind == "var":
                self.advance()
            self.expect_end()
            return _Close("FOR", span)
        if kw == "ELSE":
            self.advance()
            self.expect_end()
            return _Branch(None, span)
        if kw in ("ENDREPEAT", "ENDWHILE", "ENDIF", "ENDDFS") or (
                kw == "END" and after in ("REPEAT", "WHILE", "IF", "DFS")):
            kind = kw[3:] if kw != "END" else after
            self.pos += 1 if kw != "END" else 2
            self.expect_end()
            return _Close(kind, span)
        if kw in ("DFS", "CALL"):
            self.advance()
            name = self.name(start)
            if kw == "DFS":
                self.expect_end()
                return _Open("DFS", name, span)
            return self.call(name, span)
        if kw == "DWELL":
            self.advance()
            if self.peek() is None:
                raise self.error("DWELL needs a time (s)", start)
            seconds, _ = self.expr(0)
            self.expect_end()
            return ast.Dwell(seconds, span)
        if kw == "FREERUN":
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
        if kw in UNSIMULATED_MOTION:
            raise self.error(f"{kw} moves axes in a way tipgeo cannot simulate; a move that "
                             "cannot be evaluated is an error in every mode", start)
        if kw in NO_MOTION:
            self.pos = len(self.tokens)
            what = NO_MOTION[kw]
            if kw in _TASK_WORD and after is None and len(toks) > self.tokens.index(start) + 2 \
                    and nxt.kind == "num" and toks[toks.index(start) + 2].kind == "ident":
                after = toks[toks.index(start) + 2].value   # PROGRAM 1 RUN "other.pgm"
            if after is not None and len(after) > 1:
                kw, what = f"{kw} {after}", f"{what}: {after}"
            return ast.NoMotion(kw, what, span)
        if kw in MODE_KEYWORDS:
            return self.mode(span)
        if kw.startswith("PSO") and len(kw) > 3:
            return self.pso(span)
        if kw in MOTION_KEYWORDS or len(kw) == 1:
            return self.block(span)
        raise self.error(f"unknown keyword {start.text!r}", start, UnsupportedError)

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
        return _Open("FOR", (var.value, first, end, step), span)

    def need_expr(self, after: Token) -> ast.Expr:
        if self.peek() is None:
            raise self.error(f"expected a value after {after.text!r}", after)
        return self.expr(0)[0]

    def keyword_expr(self, word: str, start: Token) -> ast.Expr:
        tok = self.peek()
        if tok is None or tok.kind != "ident" or tok.value != word:
            raise self.error(f"FOR … needs {word}", tok or start)
        self.advance()
        return self.need_expr(tok)

    def name(self, head: Token) -> str:
        """The subroutine name after ``DFS``/``CALL`` (letters, digits, ``_``), upper-case."""
        tok = self.peek()
        if tok is None or tok.kind != "ident":
            raise self.error(f"{head.value} needs a subroutine name", tok or head)
        m = _SUB_NAME.match(self.line, tok.col - 1) if tok.width is None else None
        text = m.group(0) if m is not None else tok.text
        stop = tok.col - 1 + len(text)
        while self.peek() is not None and self.peek().col - 1 < stop:
            self.advance()
        return text.upper()

    def call(self, name: str, span: ast.Span) -> ast.Call:
        args: list[tuple[str, ast.Expr]] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind == "op" and tok.value == ",":
                continue
            if tok.kind != "ident" or len(tok.value) != 1:
                raise self.error(f"CALL arguments are letter words (P1 Q$x), found {tok.text!r}",
                                 tok)
            if self.peek() is None or self.peek().kind in ("ident", "str"):
                raise self.error(f"the argument {tok.text} needs a value", tok)
            value, _ = self.unary(0)
            if any(letter == tok.value for letter, _ in args):
                raise self.error(f"argument {tok.value} given twice", tok)
            args.append((tok.value, value))
        return ast.Call(name, tuple(args), span)

    def assignment(self, span: ast.Span):
        var = self.advance()
        index: list = []
        while (tok := self.peek()) is not None:
            if tok.kind == "op" and tok.value == "[":
                self.advance()
                if self.peek() is None:
                    raise self.error("'[' needs an index", tok)
                value, _ = self.expr(0)
                close = self.peek()
                if close is None or not (close.kind == "op" and close.value == "]"):
                    raise self.error("expected ']'", close or tok)
                self.advance()
                index.append(value)
            elif tok.kind == "op" and tok.value == ".":
                self.advance()
                field = self.peek()
                if field is None or field.kind != "ident":
                    raise self.error("expected a field name after '.'", field or tok)
                self.advance()
                index.append(field.value)
            elif tok.kind == "num" and tok.text.startswith(".") and tok.text[1:].isdigit():
                self.advance()           # $DO0.0: output 0 of bank 0
                index.append(tok.text)
            else:
                break
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
        if index or IO_NAME.match(var.value):
            return ast.SysAssign(var.value, tuple(index), expr, span)
        return ast.Assign(var.value, expr, span)

    def special_assignment(self, var: Token, span: ast.Span):
        """A status read, a string expression or a file/message function on
        the right of ``$var =``, or None for an ordinary expression."""
        tok = self.peek()
        rest = self.tokens[self.pos:]
        if tok.kind == "ident" and tok.value in STATUS_FUNCTIONS:
            self.pos = len(self.tokens)     # $z = AXISSTATUS(Z, DATAITEM_…)
            return ast.StatusRead(var.value, tok.value, span)
        stringy = any(t.kind == "str" or (t.kind == "ident" and t.value in STRING_FUNCTIONS)
                      for t in rest)
        evaluated = all(t.kind != "ident" or t.value in _EVALUATED_STRING_FUNCTIONS
                        for t in rest)
        if stringy and evaluated:
            tree = self.string_expr()
            self.expect_end()
            return ast.StringAssign(var.value, tree, span)
        if tok.kind == "ident" and tok.value in NO_MOTION and tok.value not in STRING_FUNCTIONS:
            kw = self.advance().value       # $h = FILEOPEN "log.txt", 2
            self.pos = len(self.tokens)
            return ast.NoMotion(kw, f"{NO_MOTION[kw]} (result in {self.source(var)})", span)
        if stringy:
            self.pos = len(self.tokens)     # $s = FORMAT(…): recorded, not evaluated
            return ast.NoMotion("STRING", f"sets the string {self.source(var)} (not "
                                "evaluated)", span)
        return None

    def string_expr(self):
        """``term ('+' term)*`` of a string expression (see :mod:`gcode.strings`)."""
        left = self.string_term()
        while self.is_op("+"):
            self.advance()
            left = ("cat", left, self.string_term())
        return left

    def string_term(self):
        tok = self.peek()
        if tok is None:
            prev = self.tokens[self.pos - 1]
            raise self.error(f"expected a value after {prev.text!r}", prev)
        nxt = self.tokens[self.pos + 1] if self.pos + 1 < len(self.tokens) else None
        if tok.kind == "str":
            self.advance()
            return ("lit", tok.value)
        if tok.kind == "ident" and tok.value in _EVALUATED_STRING_FUNCTIONS:
            return self.string_call(tok)
        if tok.kind == "var" and (nxt is None or (nxt.kind == "op" and nxt.value in "+,)")):
            self.advance()
            return ("var", tok.value)
        return ("num", self.term(0)[0])

    def string_call(self, head: Token):
        self.advance()
        if not self.is_op("("):
            raise self.error(f"{head.value} needs '(' and its arguments", self.peek() or head)
        self.advance()
        kinds, _ = _EVALUATED_STRING_FUNCTIONS[head.value]
        args = []
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
        return ("call", head.value, tuple(args))

    def dvar(self, span: ast.Span) -> ast.DVar:
        head = self.advance()
        names: list[str] = []
        while (tok := self.peek()) is not None:
            self.advance()
            if tok.kind == "var":
                names.append(tok.value)
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
                if tok.kind == "ident" and re.fullmatch(r"[A-Z][A-Z0-9_]*", tok.value):
                    args.append(tok.value)      # any axis name: X Y Z C, D, U, AA …
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
        ends = [w for w in words if w.letter == "M"]
        if ends:
            if len(words) - sum(w.letter == "N" for w in words) != 1 or keywords:
                raise GCodeError(f"{ends[0].span.text} (end of program) must stand alone",
                                 *_where(ends[0].span))
            return ast.Mode("END", (f"M{int(ends[0].value.value)}",), span)
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
        if name == "M":
            tok = self.tokens[first] if self.pos == first + 1 else None
            if tok is not None and tok.kind == "num" and tok.text.isdigit() \
                    and tok.value in (2, 30):
                return ast.Word("M", ast.Num(float(tok.value)), ast.Span(*where))
        if name not in WORD_LETTERS:
            what = "M words other than M2 and M30 (end of program) are" if name == "M" else \
                f"{name} words are"
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
            nxt = self.peek()
            if nxt is not None and nxt.kind == "op" and nxt.value in "[.":
                raise self.error(f"{tok.text}{nxt.text}…: reading an input, system variable or "
                                 "array element cannot be simulated", tok)
            return ast.Var(tok.value), 1
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
