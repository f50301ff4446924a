"""String expressions of A3200 AeroBasic: parsed by :mod:`gcode.parser`,
evaluated here (never by Python's ``eval``).

A string expression is a tree of tuples:

``("lit", text)``          a ``"string"`` literal;
``("var", name)``          a ``$variable``: its string if one was assigned,
                           else its number;
``("num", expr)``          a numeric :mod:`gcode.ast` expression;
``("call", NAME, args)``   a function of :data:`FUNCTIONS`;
``("cat", left, right)``   ``left + right``: two strings joined, or two
                           numbers added.

Functions evaluated (as the A3200 help describes them; its exact text is not
at hand here, so only these well-defined ones are evaluated — any other string
function, ``FORMAT`` say, is recorded without a value):

=================  =========================  ==================================
``DBLTOSTR(x, n)``  number, digits → string    ``x`` with ``n`` decimals (n whole,
                                               0–15), e.g. ``DBLTOSTR(0.25, 3)``
                                               is ``"0.250"``
``STRLEN(s)``       string → number            number of characters
``STRUPR(s)``       string → string            upper case
``STRLWR(s)``       string → string            lower case
``STRTODBL(s)``     string → number            the number written in ``s``
=================  =========================  ==================================

Errors are :class:`~gcode.errors.GCodeError` located at the statement: an
unknown variable, a number added to a string, a bad digit count, a string
that is not a number (``STRTODBL``), a result longer than
:data:`MAX_STRING_LENGTH` characters.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping

from . import ast
from .errors import GCodeError
from .expr import evaluate

_Fail = Callable[[str], GCodeError]

__all__ = ["FUNCTIONS", "MAX_STRING_LENGTH", "evaluate_string"]

#: Evaluated string functions: name → kinds of their arguments (``num`` or
#: ``str``) and the kind of their result.
FUNCTIONS: dict[str, tuple[tuple[str, ...], str]] = {
    "DBLTOSTR": (("num", "num"), "str"),
    "STRLEN": (("str",), "num"),
    "STRUPR": (("str",), "str"),
    "STRLWR": (("str",), "str"),
    "STRTODBL": (("str",), "num"),
}
#: Longest string a program may build (characters): a cost bound.
MAX_STRING_LENGTH = 4096
_NUMBER = re.compile(r"\s*[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*\Z")


def evaluate_string(tree: ast.StringTree, numbers: Mapping[str, float],
                    strings: Mapping[str, str], span: ast.Span) -> str | float:
    """Value of a string expression (a str, or a float for ``STRLEN`` …).

    Parameters
    ----------
    tree : tuple
        See the module docstring.
    numbers : dict
        Numeric variables by lower-case name.
    strings : dict
        String variables by lower-case name.
    span : gcode.ast.Span
        The statement, for errors.
    """
    def fail(message: str) -> GCodeError:
        return GCodeError(message, span.line, span.col, span.text)

    value: str | float
    if tree[0] == "lit":
        value = tree[1]
    elif tree[0] == "num":
        value = evaluate(tree[1], numbers, span=span)
    elif tree[0] == "var":
        value = _variable(tree[1], numbers, strings, fail)
    elif tree[0] == "cat":
        value = _join(evaluate_string(tree[1], numbers, strings, span),
                      evaluate_string(tree[2], numbers, strings, span), fail)
    else:
        args = [evaluate_string(a, numbers, strings, span) for a in tree[2]]
        value = _call(tree[1], args, fail)
    if isinstance(value, str) and len(value) > MAX_STRING_LENGTH:
        raise fail(f"string longer than {MAX_STRING_LENGTH} characters (MAX_STRING_LENGTH)")
    return value


def _variable(name: str, numbers: Mapping[str, float], strings: Mapping[str, str],
              fail: _Fail) -> str | float:
    if name in strings:
        return strings[name]
    if name in numbers:
        return float(numbers[name])
    raise fail(f"unknown variable ${name}")


def _join(left: str | float, right: str | float, fail: _Fail) -> str | float:
    if isinstance(left, str) and isinstance(right, str):
        return left + right
    if isinstance(left, float) and isinstance(right, float):
        result = left + right
        if not math.isfinite(result):
            raise fail("result out of range")
        return result
    raise fail("'+' joins two strings or adds two numbers; convert a number with "
               "DBLTOSTR(value, digits) first")


def _call(name: str, args: list[str | float], fail: _Fail) -> str | float:
    kinds, _ = FUNCTIONS[name]
    for i, (want, value) in enumerate(zip(kinds, args)):
        if (want == "str") != isinstance(value, str):
            raise fail(f"{name}: argument {i + 1} must be a "
                       f"{'string' if want == 'str' else 'number'}")
    if name == "DBLTOSTR":
        value, digits = float(args[0]), float(args[1])   # numbers: checked above
        if digits != int(digits) or not 0 <= digits <= 15:
            raise fail(f"DBLTOSTR: the number of decimals must be a whole number 0–15, "
                       f"not {digits:g}")
        return f"{value:.{int(digits)}f}"
    text = str(args[0])                                  # a string: checked above
    if name == "STRLEN":
        return float(len(text))
    if name == "STRUPR":
        return text.upper()
    if name == "STRLWR":
        return text.lower()
    if not _NUMBER.match(text):        # STRTODBL
        raise fail(f"STRTODBL: {text[:40]!r} is not a number")
    return float(text)
