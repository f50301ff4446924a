"""Line lexer of the A3200 AeroBasic subset (see :mod:`gcode.parser`).

A program is lexed one line at a time (AeroBasic has one statement per line).
A comment runs from ``;``, ``//`` or ``'`` to the end of the line and is
dropped (outside a string). Tokens:

``num``    an unsigned number: ``12``, ``0.05``, ``.5``, ``1.``, ``1e-3``,
           ``2.5E+4`` (the sign is a separate ``op`` token);
``var``    ``$name`` (``[A-Za-z_][A-Za-z0-9_]*``), value lower-cased, no ``$``;
``ident``  a run of ASCII letters (``G``, ``X``, ``REPEAT``, ``PSOPULSE``),
           value upper-cased; digits are never part of such an identifier, so
           ``G01`` is ``G`` then ``01`` and ``X$comp`` is ``X`` then ``$comp``.
           A name with an underscore (``Tip_Plate``, ``_x2``) is one
           identifier, digits included (an undefined macro name, say);
``str``    a double-quoted string (``"a; b"``), value without the quotes;
``op``     one of ``+ - * / = , ( ) [ ] < >``, the pairs ``<= >= == <> !=``,
           and ``.`` when a letter follows it (``$DO[0].X``).

An ``e``/``E`` directly after the digits of a number, followed by digits
(optionally signed), is an exponent: ``X1E5`` is X = 100000, not the words
``X1`` and ``E5`` (write ``X1 E5``).

Only ASCII letters, digits and the characters above are code; any other
character (outside a comment) is an error.

Cost bounds, checked while lexing so that hostile input is refused before
work is spent on it: a line (comment included) is at most
:data:`MAX_LINE_LENGTH` characters — :func:`iter_lines` refuses a longer one
without copying it — and holds at most :data:`MAX_LINE_TOKENS` tokens —
:func:`tokenize_line` stops at the first token beyond. Legitimate programs
are far inside both: Appendix C's longest line is 120 characters and 24
tokens, the emitter's 149 characters. (A 5 MB one-line expression is refused
in about 30 ms of CPU, allocating nothing; without the bounds it took 16 s
and 900 MB.)
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from .errors import GCodeError

__all__ = ["Token", "UnsupportedError", "split_comment", "tokenize_line", "split_lines",
           "iter_lines", "MAX_LINE_LENGTH", "MAX_LINE_TOKENS"]

#: Longest line accepted, in characters (its comment included, its line break
#: not). Appendix C's longest is 120, the emitter's 149.
MAX_LINE_LENGTH = 4096
#: Most tokens in one line, that is in one statement. Appendix C's most is 24;
#: an expression can use at most about 400 (see :data:`gcode.parser.MAX_EXPR_DEPTH`).
MAX_LINE_TOKENS = 1024

_WS = " \t\f\v"
_LETTERS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz")
_DIGITS = frozenset("0123456789")
_NAME_START = _LETTERS | {"_"}
_NAME_CHARS = _NAME_START | _DIGITS
_OPS = frozenset("+-*/=,()[]<>")
_PAIRS = frozenset({"<=", ">=", "==", "<>", "!="})
_NUMBER = re.compile(r"(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_EOL = re.compile(r"\r\n?|\n")


class UnsupportedError(GCodeError):
    """Text that is well formed but outside the supported subset (an unknown
    keyword, G code or word letter, a foreign character).

    :func:`gcode.parser.parse` skips the statement with a warning in lenient
    mode; otherwise it is raised like any :class:`~gcode.errors.GCodeError`.
    """


@dataclass(frozen=True)
class Token:
    """One token of a line.

    Attributes
    ----------
    kind : str
        ``num``, ``var``, ``ident``, ``str`` or ``op``.
    value : float or str
        The number (``num``), the lower-case name (``var``), the upper-case
        identifier (``ident``) or the operator character (``op``).
    col : int
        1-based column of the token's first character.
    text : str
        The token's source text.
    width : int or None
        Source characters the token stands for when that differs from
        ``len(text)``: a token of a macro's replacement has the column and
        width of the macro's name where it was used.
    """

    kind: str
    value: float | str
    col: int
    text: str
    width: int | None = None

    @property
    def str_value(self) -> str:
        """``value`` of a name, operator, ``$variable`` or string token (a
        str); for a number token, its source text."""
        return self.value if isinstance(self.value, str) else self.text

    @property
    def end(self) -> int:
        """0-based index just past the token in its line."""
        return self.col - 1 + (len(self.text) if self.width is None else self.width)


def split_lines(text: str) -> list[str]:
    """Split program text into lines (``\\n``, ``\\r\\n`` or ``\\r``).

    Unlike :meth:`str.splitlines`, other Unicode separators (``\\x0b``,
    ``\\u2028`` …) are not line breaks, so line numbers match what an editor
    shows for ordinary files. A leading byte-order mark is dropped.
    """
    if text.startswith("\ufeff"):
        text = text[1:]
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def iter_lines(text: str, max_length: int = MAX_LINE_LENGTH) -> Iterator[str]:
    """The lines of ``text`` one at a time, split like :func:`split_lines`.

    A line longer than ``max_length`` characters raises before it is copied,
    so a huge one-line input costs no memory; nothing is read past it.

    Parameters
    ----------
    text : str
        Program text.
    max_length : int
        Longest line accepted (default :data:`MAX_LINE_LENGTH`).

    Yields
    ------
    str
        Each line without its line break.

    Raises
    ------
    GCodeError
        A line longer than ``max_length`` (at its column ``max_length + 1``).
    """
    start = 1 if text.startswith("\ufeff") else 0
    lineno = 0
    for m in _EOL.finditer(text, start):
        lineno += 1
        end = m.start()
        if end - start > max_length:
            raise _too_long(text, start, end, lineno, max_length)
        yield text[start:end]
        start = m.end()
    if len(text) - start > max_length:
        raise _too_long(text, start, len(text), lineno + 1, max_length)
    yield text[start:]


def _too_long(text: str, start: int, end: int, lineno: int, max_length: int) -> GCodeError:
    cut = start + max_length
    return GCodeError(f"line of {end - start} characters is longer than MAX_LINE_LENGTH = "
                      f"{max_length}", lineno, max_length + 1, text[cut:min(end, cut + 20)])


def split_comment(line: str) -> int:
    """Index where the comment of ``line`` starts (``len(line)`` if none).

    Parameters
    ----------
    line : str
        One source line.

    Returns
    -------
    int
        Index of the first ``;``, ``//`` or ``'`` outside a double-quoted
        string.
    """
    semi = line.find(";")
    slash = line.find("//")
    tick = line.find("'")
    ends = [i for i in (semi, slash, tick) if i >= 0]
    end = min(ends) if ends else len(line)
    quote = line.find('"', 0, end)
    while quote >= 0:        # a comment sign inside a string is not one
        close = line.find('"', quote + 1)
        if close < 0:
            return end if end < len(line) else len(line)
        if close > end:
            return split_comment(line[close + 1:]) + close + 1
        quote = line.find('"', close + 1, end)
    return end


def tokenize_line(line: str, lineno: int = 0, *, max_length: int = MAX_LINE_LENGTH,
                  max_tokens: int = MAX_LINE_TOKENS,
                  out: list[Token] | None = None) -> list[Token]:
    """Tokens of one source line, its comment dropped.

    Parameters
    ----------
    line : str
        One line, without its line break.
    lineno : int
        1-based line number, for error messages.
    max_length : int
        Longest line accepted (default :data:`MAX_LINE_LENGTH`); a longer
        one is refused before any token is made.
    max_tokens : int
        Most tokens accepted (default :data:`MAX_LINE_TOKENS`); lexing stops
        at the first token beyond.
    out : list, optional
        Append the tokens to this list (and return it); the tokens made
        before an error stay there, so a caller can count the work done.

    Returns
    -------
    list of Token
        ``out`` when given.

    Raises
    ------
    GCodeError
        A malformed number (``1.2.3``, ``.``), a number out of range
        (``1e999``), a ``$`` not followed by a name, a line longer than
        ``max_length`` or with more than ``max_tokens`` tokens;
        :class:`UnsupportedError` for a character that is not code.
    """
    if len(line) > max_length:
        raise _too_long(line, 0, len(line), lineno, max_length)
    end = split_comment(line)
    tokens: list[Token] = [] if out is None else out
    base = len(tokens)
    max_tokens += base
    i = 0
    while i < end:
        ch = line[i]
        if ch in _WS:
            i += 1
            continue
        if len(tokens) >= max_tokens:
            j = min(_token_end(line, i, end), i + 20)
            limit = max_tokens - base
            raise GCodeError(f"line has more than {limit} tokens (MAX_LINE_TOKENS = {limit})",
                             lineno, i + 1, line[i:j])
        tok, i = _scanner(line, i, end)(line, i, end, lineno)
        tokens.append(tok)
    return tokens


def _scanner(line: str, i: int, end: int) -> Callable[[str, int, int, int], tuple[Token, int]]:
    """The function that reads the token starting at ``line[i]``."""
    ch = line[i]
    if ch in _NAME_START:
        return _scan_name
    if ch == '"':
        return _scan_string
    if ch == "." and i + 1 < end and line[i + 1] in _LETTERS:
        return _scan_op                  # $DO[0].X
    if ch in _DIGITS or ch == ".":
        return _scan_number
    if ch == "$":
        return _scan_var
    if ch in _OPS or line[i:i + 2] in _PAIRS:
        return _scan_op
    return _scan_foreign


def _scan_name(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    j = i + 1
    while j < end and line[j] in _LETTERS:
        j += 1
    if line[i] == "_" or (j < end and line[j] == "_"):   # a name: Tip_Plate_2
        while j < end and line[j] in _NAME_CHARS:
            j += 1
    return Token("ident", line[i:j].upper(), i + 1, line[i:j]), j


def _scan_string(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    j = line.find('"', i + 1, end)
    if j < 0:
        raise GCodeError("unterminated string", lineno, i + 1, line[i:min(end, i + 20)])
    return Token("str", line[i + 1:j], i + 1, line[i:j + 1]), j + 1


def _scan_number(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    j = _number_end(line, i, end)
    text = line[i:j]
    if not _NUMBER.match(text):
        raise GCodeError("malformed number", lineno, i + 1, text)
    value = float(text)
    if not math.isfinite(value):
        raise GCodeError("number out of range", lineno, i + 1, text)
    return Token("num", value, i + 1, text), j


def _scan_var(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    j = i + 1
    if not (j < end and line[j] in _NAME_START):
        raise GCodeError("'$' must be followed by a variable name", lineno, i + 1, "$")
    j += 1
    while j < end and line[j] in _NAME_CHARS:
        j += 1
    return Token("var", line[i + 1:j].lower(), i + 1, line[i:j]), j


def _scan_op(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    pair = line[i:i + 2]
    if pair in _PAIRS:
        return Token("op", pair, i + 1, pair), i + 2
    return Token("op", line[i], i + 1, line[i]), i + 1


def _scan_foreign(line: str, i: int, end: int, lineno: int) -> tuple[Token, int]:
    raise UnsupportedError(f"unexpected character {line[i]!r}", lineno, i + 1, line[i])


def _token_end(line: str, i: int, end: int) -> int:
    """Index past the (roughly delimited) token at ``i``, for messages."""
    j = i + 1
    while j < end and line[j] not in _WS and line[j] not in _OPS:
        j += 1
    return j


def _number_end(line: str, i: int, end: int) -> int:
    """Index past the number-like run starting at ``i``: digits and dots, an
    optional exponent, and any dots or digits glued after it (so that
    ``1.2.3`` and ``1e5.2`` are reported whole)."""
    j = i
    while j < end and (line[j] in _DIGITS or line[j] == "."):
        j += 1
    if j < end and line[j] in "eE":
        k = j + 1
        if k < end and line[k] in "+-":
            k += 1
        if k < end and line[k] in _DIGITS:
            while k < end and line[k] in _DIGITS:
                k += 1
            j = k
            while j < end and (line[j] in _DIGITS or line[j] == "."):
                j += 1
    return j
