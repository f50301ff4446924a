"""The ``#define`` preprocessor of A3200 AeroBasic (see :mod:`gcode.parser`):
object-like and function-like macros, replaced and rescanned C-style before a
line is read; a replacement's tokens keep the line and column of the macro's
use. Cost bounds: :data:`MAX_MACROS` macros, :data:`MAX_MACRO_PARAMS`
parameters, :data:`MAX_EXPANSIONS` replacements a line and
:data:`MAX_PROGRAM_EXPANSIONS` a program, expanded lines at most
:data:`~gcode.lexer.MAX_LINE_LENGTH` characters, macros nested at most
:data:`MAX_NESTING` deep.
"""

from __future__ import annotations

import re

from . import ast
from .errors import GCodeError
from .lexer import MAX_LINE_LENGTH, Token, split_comment, tokenize_line

__all__ = ["directive", "expand", "origin", "MAX_MACROS", "MAX_MACRO_PARAMS", "MAX_EXPANSIONS",
           "MAX_PROGRAM_EXPANSIONS", "MAX_NESTING", "SUB_NAME"]

#: Deepest nesting of parentheses, blocks and macros.
MAX_NESTING = 64
_WS_RE = r"[ \t\f\v]"
_DIRECTIVE = re.compile(rf"{_WS_RE}*#{_WS_RE}*([A-Za-z]*)")
_MACRO_DEF = re.compile(rf"{_WS_RE}*#{_WS_RE}*define{_WS_RE}+([A-Za-z_][A-Za-z0-9_]*)(\(?)",
                        re.IGNORECASE)
_MACRO_USE = re.compile(r"(?<![A-Za-z0-9_$.])[A-Za-z_][A-Za-z0-9_]*")
_PARAMS = re.compile(rf"{_WS_RE}*([A-Za-z_][A-Za-z0-9_]*){_WS_RE}*(,|\))")
#: Most parameters of a function-like macro.
MAX_MACRO_PARAMS = 32
SUB_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: Most ``#define`` macros in one program.
MAX_MACROS = 10_000
#: Most macro replacements made in one line, nested ones included.
MAX_EXPANSIONS = 4096
#: Most macro replacements in a whole program: about 2.3 µs each measured, so
#: reaching it costs about 2–3 s of CPU.
MAX_PROGRAM_EXPANSIONS = 1_000_000

#: The macros of a program: name → replacement text or a function-like macro.
Macros = dict[str, str | ast.FunctionMacro]
#: Replacements left and the bound: ``[left, bound]`` (mutated as they are made).
Budget = list[int]
#: A line's budget within its program's: ``(program, line)``.
_Budgets = tuple[Budget, Budget]
#: A piece of an expanded line: (start in the result, start in the code, length
#: in the code, from a macro).
Piece = tuple[int, int, int, bool]


def directive(line: str, lineno: int, macros: Macros, lexed: list[Token]) -> None:
    """Apply one preprocessor line: ``#define NAME text`` or ``#undef NAME``."""
    d = _DIRECTIVE.match(line)
    if d is None:
        raise GCodeError("expected a preprocessor line starting with '#'", lineno, 1, line[:20])
    word = d.group(1).lower()
    col = line.index("#") + 1
    if word == "define":
        m = _MACRO_DEF.match(line)
        if m is None:
            raise GCodeError("#define needs a macro name", lineno, col, line[col - 1:col + 19])
        name = m.group(1)
        end = m.end()
        params: tuple[str, ...] | None = None
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
        u = SUB_NAME.match(rest.strip())
        if u is None:
            raise GCodeError("#undef needs a macro name", lineno, col, line[col - 1:col + 19])
        macros.pop(u.group(0), None)
    else:
        raise GCodeError(f"preprocessor directive #{d.group(1)} is not supported (only #define "
                         "and #undef): the statements it would select or bring in cannot be "
                         "checked", lineno, col, line[col - 1:d.end()])


def _macro_params(line: str, m: re.Match[str], lineno: int) -> tuple[int, tuple[str, ...]]:
    """The parameter list of ``#define NAME(a, b)``: (end of the list in
    ``line``, the names)."""
    pos, params = m.end(), list[str]()
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
    depth, args, arg0, j = 0, list[str](), i + 1, i
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
    out, pos = list[str](), 0
    for m in _MACRO_USE.finditer(body):
        if m.group(0) in values and not any(a <= m.start() < b for a, b in strings):
            out.append(body[pos:m.start()])
            out.append(values[m.group(0)])
            pos = m.end()
    out.append(body[pos:])
    return "".join(out)


def expand(code: str, macros: Macros, lineno: int, active: frozenset[str] = frozenset(),
           budget: Budget | _Budgets | None = None) -> tuple[str, list[Piece]]:
    """``code`` with every macro name replaced, and the pieces it was made of:
    ``(start in the result, start in code, length in code, from a macro)``.

    As in C, a replacement is rescanned for further macros, except the ones
    being expanded (no recursion); the result is at most MAX_LINE_LENGTH
    characters and costs at most MAX_EXPANSIONS replacements (empty macros
    nested in each other would otherwise cost exponential time for nothing)."""
    if budget is None:
        budget = [MAX_PROGRAM_EXPANSIONS, MAX_PROGRAM_EXPANSIONS]
    # a new line (a list): its own bound, within the program's
    both = (budget, [MAX_EXPANSIONS]) if isinstance(budget, list) else budget
    out: list[str] = []
    pieces: list[Piece] = []
    pos = 0
    size = 0
    strings = _string_spans(code)
    for m in _MACRO_USE.finditer(code):
        name = m.group(0)
        if m.start() < pos or name not in macros or name in active \
                or any(a <= m.start() < b for a, b in strings):
            continue
        use = _replacement(code, m, macros, lineno, active, both)
        if use is None:
            continue
        rep, use_end = use
        if m.start() > pos:
            out.append(code[pos:m.start()])
            pieces.append((size, pos, m.start() - pos, False))
            size += m.start() - pos
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


def _replacement(code: str, m: re.Match[str], macros: Macros, lineno: int,
                 active: frozenset[str], budget: _Budgets) -> tuple[str, int] | None:
    """The expanded replacement of the macro used at ``m`` and the end of its
    use in ``code`` (None: a function-like macro without arguments, left alone)."""
    name = m.group(0)
    macro, use_end = macros[name], m.end()
    if isinstance(macro, ast.FunctionMacro):
        call = _call_args(code, m.end(), name, lineno)
        if call is None:
            return None
        use_end, args = call
        rep = _apply_function_macro(macro, args, code[m.start():use_end], m.start(), name, lineno,
                                    macros, active, budget)
    else:
        rep = macro
    _charge(budget, active, lineno, m.start(), name)
    if _MACRO_USE.search(rep) is not None:
        try:
            rep = expand(rep, macros, lineno, active | {name}, budget)[0]
        except GCodeError as err:    # located at this use, not inside a replacement
            raise GCodeError(err.reason, lineno, m.start() + 1, name) from None
    return rep, use_end


def _apply_function_macro(rep: ast.FunctionMacro, args: list[str], use: str, start: int,
                          name: str, lineno: int, macros: Macros, active: frozenset[str],
                          budget: _Budgets) -> str:
    """The body of a function-like macro with its (expanded) arguments."""
    if args == [""] and not rep.params:
        args = []
    if len(args) != len(rep.params):
        raise GCodeError(f"macro {name} takes {len(rep.params)} argument(s) "
                         f"({', '.join(rep.params)}), {len(args)} given", lineno,
                         start + 1, use)
    try:                    # arguments are expanded first, then substituted
        args = [expand(a.strip(), macros, lineno, active, budget)[0] for a in args]
    except GCodeError as err:
        raise GCodeError(err.reason, lineno, start + 1, name) from None
    text = _substitute(rep.body, rep.params, args)
    if len(text) > MAX_LINE_LENGTH:
        raise GCodeError(f"line is longer than MAX_LINE_LENGTH = {MAX_LINE_LENGTH} "
                         "characters after macro expansion", lineno, start + 1, name)
    return text


def _charge(budget: _Budgets, active: frozenset[str], lineno: int, start: int,
            name: str) -> None:
    """Count one replacement against the line's and the program's bounds."""
    program, line = budget
    line[0] -= 1
    program[0] -= 1
    if line[0] < 0:
        raise GCodeError(f"more than {MAX_EXPANSIONS} macro replacements in one line "
                         "(MAX_EXPANSIONS)", lineno, start + 1, name)
    if program[0] < 0:
        raise GCodeError(f"more than {program[1]} macro replacements in the "
                         "program (MAX_PROGRAM_EXPANSIONS)", lineno, start + 1, name)
    if len(active) >= MAX_NESTING:
        raise GCodeError(f"macros nested deeper than {MAX_NESTING}", lineno, start + 1,
                         name)


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


def origin(pieces: list[Piece], index: int) -> tuple[int, int | None]:
    """1-based source column of character ``index`` of an expanded line, and
    the width to report when it came from a macro (else None)."""
    for start, src, length, macro in reversed(pieces):
        if index >= start:
            if macro:
                return src + 1, length
            return src + 1 + (index - start), None
    return index + 1, None
