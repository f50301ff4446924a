"""User names that become part of a path or of a foreign file's content.

A spec's ``name``, a cutter's ``name`` (face labels ``cut:<name>``), a study's
``name`` and a tissue's name end up in file names (``<name>_axisymmetric.inp``,
``optimum-<objective>.toml``) and inside solver decks, G-code comments and
reports. They are checked once, at load, against one form:

    :data:`NAME_FORM` — ASCII letters, digits, ``_``, ``-`` and ``.``; the first
    character a letter, digit or ``_`` (no leading ``.``: no hidden file, no
    ``..``; no leading ``-``: never read as an option); at most
    :data:`MAX_NAME_LEN` characters.

Free text (descriptions) is not restricted; its writers escape it by their
format's rules (:func:`one_line`).
"""

from __future__ import annotations

import re
import unicodedata

from .errors import SpecError
from .validate import brief

__all__ = ["MAX_NAME_LEN", "NAME_FORM", "NAME_RULE", "is_name", "check_name", "safe_name",
           "one_line"]

#: Longest name accepted (characters).
MAX_NAME_LEN = 64

#: The form of a name (a full match).
NAME_FORM = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,%d}" % (MAX_NAME_LEN - 1))  # noqa: UP031

#: The form in words, for messages.
NAME_RULE = (f"allowed 1–{MAX_NAME_LEN} ASCII letters, digits, '_', '-' and '.', "
             "not starting with '.' or '-'")


def is_name(value: object) -> bool:
    """Whether ``value`` is a str of the form :data:`NAME_FORM`."""
    return isinstance(value, str) and NAME_FORM.fullmatch(value) is not None


def check_name(key: str, value: object, *, empty: bool = False) -> str:
    """``value`` if it is a valid name (or ``""`` when ``empty`` allows it),
    else a one-line :class:`SpecError` naming ``key``, the value and the form."""
    if empty and value == "":
        return ""
    if not isinstance(value, str):
        raise SpecError(f"{key} = {brief(value)} is not a string; expected a name ({NAME_RULE})")
    if not is_name(value):
        raise SpecError(f"{key} = {brief(value)} is not a valid name; {NAME_RULE}")
    return value


def safe_name(text: str, default: str = "tip") -> str:
    """A valid name made from ``text`` (e.g. a file's stem): every other
    character becomes ``_``, a leading ``.``/``-`` gets a ``_`` before it,
    the result is cut to :data:`MAX_NAME_LEN`."""
    s = re.sub(r"[^A-Za-z0-9_.\-]", "_", str(text))
    if not s:
        return default
    if s[0] in ".-":
        s = "_" + s
    return s[:MAX_NAME_LEN]


def one_line(text: object) -> str:
    """``text`` on one line: every line break (CR, LF, VT, FF, NEL, U+2028/9)
    and every other control character becomes a space."""
    return "".join(" " if (unicodedata.category(c) in ("Cc", "Zl", "Zp")) else c
                   for c in str(text))
