"""Restore the line breaks of a program pasted as run-on text.

The laser program of the thesis (Appendix C) reached its markdown with most
line breaks lost, ``$`` escaped as ``\\$``, and comments running into the
statements that followed them. The thesis errata give the rule: statements
are separated where a new G-word, keyword or assignment starts; ``;`` starts
a comment. :func:`restore_line_breaks` applies it:

* In code, a new statement starts at a G-word (``G1``, ``G 92``), a
  statement keyword (``REPEAT``, ``END REPEAT``, ``ENDREPEAT``, ``END``,
  ``DVAR``, ``SECONDS``, ``MINUTES``, ``METRIC``, ``ENGLISH``, ``ABSOLUTE``,
  ``INCREMENTAL``, ``ENABLE``, ``PSO…``, ``LINEAR``, ``RAPID``, ``CW``,
  ``CCW``), a tool word ``T<n>`` or an assignment ``$name =`` — except that
  G-words at the start of a block stay together: ``G01 G41 X$comp F $feed``
  is one block (and one line), while ``G1 Y -0.05 G40 X$comp`` is two.
  Keywords are case-insensitive in code.
* A comment (``;`` or ``//``) runs until a real statement starts: an
  upper-case G-word, ``T<n>``, statement keyword or ``$name =`` whose text
  (up to the next such start or comment sign) :func:`gcode.parser.is_statement`
  accepts. So English in comments stays there (``; Make serrations all
  around the circumference``, ``; activate possible compensation on x and y
  axe``), while ``; set zero G92 C0`` gives up ``G92 C0``.
* Each statement goes on its own line with its comment:
  ``code ; comment`` (``code ;`` for an empty one); a comment-only line is
  kept as it is. Blank lines are dropped.

Markdown backslash escapes (``\\$``, ``\\_``, ``\\*`` …) are undone first.
The function never raises on a string, and restoring restored text changes
nothing (unless that text still holds backslash escapes, which are undone
again).
"""

from __future__ import annotations

import re

from .lexer import split_lines
from .parser import is_statement

__all__ = ["restore_line_breaks", "unescape_markdown"]

_ESCAPE = re.compile(r"\\([!-/:-@\[-`{-~])")
_KEYWORDS = frozenset({"REPEAT", "ENDREPEAT", "END", "DVAR", "SECONDS", "MINUTES", "METRIC",
                       "ENGLISH", "ABSOLUTE", "INCREMENTAL", "ENABLE", "LINEAR", "RAPID",
                       "CW", "CCW"})
_WS = " \t\f\v"
_VAR = re.compile(r"\$[A-Za-z_][A-Za-z0-9_]*")
_ASSIGN_AFTER_VAR = re.compile(r"[ \t\f\v]*=(?!=)")
_DIGITS_AFTER = re.compile(r"[ \t\f\v]*[0-9]+")
_REPEAT_AFTER_END = re.compile(r"[ \t\f\v]+REPEAT(?![A-Za-z])", re.IGNORECASE)
_LETTERS = re.compile(r"[A-Za-z]+")
# Statement starts inside a comment: upper case only, not glued to a word.
_COMMENT_START = re.compile(
    r"(?<![A-Za-z0-9_$.])(?:G[0-9]+|T[0-9]+|\$[A-Za-z_][A-Za-z0-9_]*[ \t\f\v]*=(?!=)"
    r"|(?:END[ \t\f\v]+REPEAT|ENDREPEAT|REPEAT|END|DVAR|SECONDS|MINUTES|METRIC|ENGLISH"
    r"|ABSOLUTE|INCREMENTAL|ENABLE|LINEAR|RAPID|CCW|CW|PSO[A-Z]+)(?![A-Za-z0-9_]))")


def unescape_markdown(text: str) -> str:
    """Undo markdown backslash escapes of ASCII punctuation (``\\$`` → ``$``).

    Parameters
    ----------
    text : str

    Returns
    -------
    str
    """
    return _ESCAPE.sub(r"\1", text)


def restore_line_breaks(text: str) -> str:
    """One statement per line, following the thesis errata (module doc).

    Parameters
    ----------
    text : str
        Program text with lost line breaks and markdown escapes, e.g. the
        Appendix C listing as it stands in the thesis markdown.

    Returns
    -------
    str
        The program, one statement (with its comment) per line, ending in a
        newline (empty string for a blank input).
    """
    if not isinstance(text, str):
        raise TypeError(f"restore_line_breaks() needs a str, not {type(text).__name__}")
    out: list[str] = []
    for line in split_lines(unescape_markdown(text)):
        for code, marker, comment in _split_line(line):
            code = code.strip(_WS)
            if code and marker:
                comment = comment.strip(_WS)
                out.append(f"{code} {marker} {comment}" if comment else f"{code} {marker}")
            elif code:
                out.append(code)
            elif marker:
                out.append(f"{marker}{comment.rstrip(_WS)}")
    return "".join(f"{line}\n" for line in out)


def _split_line(line: str) -> list[tuple[str, str, str]]:
    """``(code, comment marker, comment)`` of each statement of one line."""
    result: list[tuple[str, str, str]] = []
    n = len(line)
    start = 0          # where the current statement's code starts
    i = 0
    has_tokens = False  # the current statement has code tokens
    only_g = True       # …and they are all G-words (or a leading N number)
    while i < n:
        ch = line[i]
        if ch == ";" or line.startswith("//", i):
            marker = "//" if ch == "/" else ";"
            body = i + len(marker)
            cut = _comment_end(line, body)
            result.append((line[start:i], marker, line[body:cut]))
            start = i = cut
            has_tokens, only_g = False, True
            continue
        if ch in _WS:
            i += 1
            continue
        kind, end = _code_token(line, i)
        if kind in ("g", "n"):
            splits = has_tokens and not only_g
        elif kind == "start":
            splits = has_tokens
        else:
            splits = False
        if splits:
            result.append((line[start:i], "", ""))
            start = i
            only_g = True
        only_g = only_g and kind in ("g", "n")
        has_tokens = True
        i = end
    if line[start:].strip(_WS):
        result.append((line[start:], "", ""))
    return result


def _code_token(line: str, i: int) -> tuple[str, int]:
    """Kind and end of the code token at ``i``: ``g`` (G-word), ``n`` (line
    number), ``start`` (another statement start) or ``other``."""
    ch = line[i]
    if ch == "$":
        m = _VAR.match(line, i)
        if m is None:
            return "other", i + 1
        if _ASSIGN_AFTER_VAR.match(line, m.end()):
            return "start", m.end()
        return "other", m.end()
    m = _LETTERS.match(line, i)
    if m is None:
        return "other", i + 1
    word = m.group().upper()
    end = m.end()
    if word in ("G", "N", "T") and (digits := _DIGITS_AFTER.match(line, end)):
        return {"G": "g", "N": "n", "T": "start"}[word], digits.end()
    if word == "END":
        after = _REPEAT_AFTER_END.match(line, end)
        return "start", after.end() if after else end
    if word in _KEYWORDS or (word.startswith("PSO") and len(word) > 3):
        return "start", end
    return "other", end


def _comment_end(line: str, i: int) -> int:
    """Where the comment whose text starts at ``i`` ends: at the first real
    statement start in it, else at the end of the line."""
    starts = [m.start() for m in _COMMENT_START.finditer(line, i)]
    for k, pos in enumerate(starts):
        stop = starts[k + 1] if k + 1 < len(starts) else len(line)
        semi = line.find(";", pos, stop)
        slash = line.find("//", pos, stop)
        stop = min(x for x in (stop, semi, slash) if x >= 0)
        if is_statement(line[pos:stop]):
            return pos
    return len(line)
