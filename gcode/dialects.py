"""Program dialects as one table, and the one comment writer every program
writer uses (the mill post :mod:`cam.mill.post`, the grinder's ISO writer
:mod:`cam.iso` / :meth:`cam.program.GrindProgram.to_gcode` and the AeroBasic
emitter :mod:`gcode.emitter`).

A :class:`Dialect` is one row of words and rules per controller:

========================  =====================================================
column                    meaning
========================  =====================================================
``name``                  the table key (``haas``, ``linuxcnc``, ``fanuc``,
                          ``aerobasic``)
``start`` / ``finish``    the tape delimiters before the first and after the
                          last block (``%``; empty where the control wants none)
``program_number``        the program-number block (``O{number:05d}``; empty:
                          the title is a comment instead — LinuxCNC reads
                          ``O`` words as subroutine labels)
``header``                the safety block ``G17 G21 G90 G94 G40 G49 G80``
``tool_change``           ``T{tool} M06``
``length_offset``         the tool length offset taken on a motion line
                          (``G00 G43 H{tool:02d} Z{z}``: a Z word needs a
                          motion mode on its line)
``spindle_on/off``        ``S{rpm} M03`` / ``M05``
``coolant_on/off``        ``M08`` / ``M09``
``home``                  the retract before the end
``end``                   ``M30``
``arcs``                  whether the control takes ``G02``/``G03`` (posts
                          that fit arcs may use them; linear moves otherwise)
``line_numbers``          ``N`` step (0: no line numbers); numbers wrap
                          before ``N{max_line_number}``
``max_block``             the longest block the control reads (characters);
                          comments are clipped to fit, a longer motion block
                          is an error
``comment_open/close``    ``(`` ``)``, or ``;`` with an empty close
``comment_upper``         comments in upper case (Haas screens)
``comment_spell``         characters of user text rewritten in comments:
                          parentheses, ``;`` and ``%`` never reach a comment;
                          newlines, tabs and carriage returns never do either
``active_comments``       comment words the control executes (LinuxCNC
                          ``(MSG,…)``, ``(DEBUG,…)``…): a comment starting with
                          one is defused
========================  =====================================================

Each ISO dialect is proven in the tests by LinuxCNC's ``rs274`` (where it is
installed) and pygcode's ``Machine``; the AeroBasic one by tipgeo's own
A3200 parser.
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass

__all__ = ["Dialect", "DIALECTS", "HAAS", "LINUXCNC", "FANUC", "AEROBASIC", "comment",
           "register_dialect", "FAMILIES",
           "ascii_text", "number_lines", "dialect"]

#: Characters spelt out in ASCII before a comment's own rules apply.
_SPELL = {
    "§": "sec. ", "—": "-", "–": "-",
    "−": "-", "°": " deg", "µ": "u", "μ": "u", "×": "x", "·": "*", "≤": "<=", "≥": ">=",
    "≈": "~", "→": "->", "←": "<-", "…": "...", "’": "'", "‘": "'", "“": '"', "”": '"',
    "ξ": "xi", "φ": "phi", "ϕ": "phi", "θ": "theta", "β": "beta", "γ": "gamma",
    "α": "alpha", "δ": "delta", "ε": "eps", "λ": "lambda", "ψ": "psi", "ω": "omega",
    "Δ": "Delta", "π": "pi", "ρ": "rho", "σ": "sigma", "τ": "tau", "η": "eta", "κ": "kappa",
    "\t": " ", "\r": " ", "\n": " ", "\v": " ", "\f": " ",
}

#: Rewrites for ISO comments in parentheses: nothing nested, no comment start
#: (``;``), no tape delimiter (``%``).
_ISO_SPELL = (("(", "["), (")", "]"), (";", ","), ("%", " pct"))


def _ascii(ch: str) -> str:
    if ch in _SPELL:
        return _SPELL[ch]
    if " " <= ch <= "~":
        return ch
    plain = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode("ascii")
    return "".join(_SPELL.get(c, c) for c in plain if " " <= c <= "~") or "?"


def ascii_text(text: str) -> str:
    """``text`` in printable ASCII on one line (Greek letters spelt out,
    ``°`` as ``deg``, ``§`` as ``sec.``, dashes as ``-``, anything else by its
    compatibility decomposition, else ``?``; whitespace runs as one space)."""
    return " ".join("".join(_ascii(c) for c in str(text)).split())


@dataclass(frozen=True, kw_only=True)
class Dialect:
    """One controller's words and rules (see the module docstring)."""

    name: str
    family: str = "iso"
    start: str = "%"
    program_number: str = "O{number:05d}"
    header: str = "G17 G21 G90 G94 G40 G49 G80"
    tool_change: str = "T{tool} M06"
    work_offset: str = "G54"
    length_offset: str = "G00 G43 H{tool:02d} Z{z}"
    spindle_on: str = "S{rpm} M03"
    spindle_off: str = "M05"
    coolant_on: str = "M08"
    coolant_off: str = "M09"
    home: str = "G28 G91 Z0."
    absolute: str = "G90"
    end: str = "M30"
    finish: str = "%"
    rapid: str = "G00"
    feed: str = "G01"
    arcs: bool = True
    line_numbers: int = 0
    max_line_number: int = 99999
    max_block: int = 256
    comment_open: str = "("
    comment_close: str = ")"
    comment_upper: bool = False
    comment_spell: tuple[tuple[str, str], ...] = _ISO_SPELL
    active_comments: tuple[str, ...] = ()
    max_comment: int = 200


#: Haas VF-2 (the thesis's mill): Fanuc-style, ``%`` delimited, upper-case
#: comments in single parentheses.
HAAS = Dialect(name="haas", comment_upper=True, max_comment=70)
#: LinuxCNC: no O-number (O words are subroutine labels), ``%`` delimited
#: (allowed), comments in parentheses; ``MSG``/``DEBUG``/… comments defused.
LINUXCNC = Dialect(name="linuxcnc", program_number="", max_block=255,
                   active_comments=("MSG", "DEBUG", "PRINT", "LOGOPEN", "LOGAPPEND",
                                    "LOGCLOSE", "LOG", "PROBEOPEN", "PROBECLOSE", "ABORT",
                                    "PY", "TASK"))
#: A generic Fanuc control: four-digit O-number, mixed-case comments,
#: 256-character blocks, no line numbers (``dataclasses.replace(FANUC,
#: line_numbers=10)`` numbers every block N10, N20, …).
FANUC = Dialect(name="fanuc", program_number="O{number:04d}", max_block=256)
#: Aerotech A3200 AeroBasic: comments from ``;`` to the end of the line (as
#: Appendix C writes them; the A3200 also reads ``//`` and ``'``); user text
#: is put on one line, so nothing of it becomes a statement.
AEROBASIC = Dialect(name="aerobasic", family="aerobasic", start="", program_number="",
                    header="", tool_change="", work_offset="", length_offset="",
                    spindle_on="", spindle_off="", coolant_on="", coolant_off="", home="",
                    end="", finish="", comment_open="; ", comment_close="",
                    comment_spell=(), max_block=4096, max_comment=4000)

#: dialect name -> row. Add a controller with :func:`register_dialect`.
DIALECTS: dict[str, Dialect] = {d.name: d for d in (HAAS, LINUXCNC, FANUC, AEROBASIC)}

#: The program families a row can belong to: ``iso`` rows are mill and grinder
#: posts (:data:`cam.mill.post.POSTS` lists them), ``aerobasic`` the laser's.
FAMILIES: tuple[str, ...] = ("iso", "aerobasic")

_DIALECT_NAME = re.compile(r"[a-z][a-z0-9_-]{0,31}")


def register_dialect(row: Dialect) -> Dialect:
    """Add one controller's row to :data:`DIALECTS` (a new controller is one
    :class:`Dialect` and this call; an ``iso`` row is then a post of
    ``tipgeo mill``/``grind``/``gcode --post``, a machine file's
    ``controller``). The name is a lower-case word of at most 32 characters
    (``[a-z][a-z0-9_-]*``); a name taken by another row is an error, the same
    row again is not. Returns ``row``."""
    if not isinstance(row, Dialect):
        raise TypeError(f"register_dialect(row={row!r}): expected a Dialect")
    if not _DIALECT_NAME.fullmatch(row.name):
        raise ValueError(f"dialect name = {row.name!r} is invalid; expected a lower-case word "
                         "of at most 32 characters ([a-z][a-z0-9_-]*)")
    if row.family not in FAMILIES:
        raise ValueError(f"dialect {row.name!r}: family = {row.family!r} is unknown; "
                         "expected one of: " + ", ".join(FAMILIES))
    if not (isinstance(row.max_block, int) and row.max_block >= 16):
        raise ValueError(f"dialect {row.name!r}: max_block = {row.max_block!r}; expected an "
                         "int >= 16 (characters)")
    old = DIALECTS.get(row.name)
    if old is not None and old != row:
        raise ValueError(f"dialect name {row.name!r} is taken by another row")
    DIALECTS[row.name] = row
    return row


def dialect(key: Dialect | str) -> Dialect:
    """The :class:`Dialect` named ``key`` (a row passes through); ``KeyError``
    naming the known ones otherwise."""
    if isinstance(key, Dialect):
        return key
    if key not in DIALECTS:
        raise KeyError(f"dialect {key!r} is unknown; expected one of: " + ", ".join(DIALECTS))
    return DIALECTS[key]


def comment(d: Dialect | str, text: str, *, room: int | None = None) -> str:
    """``text`` as one comment of dialect ``d``: ASCII on one line, the
    dialect's comment characters rewritten (never nested parentheses, no
    ``;`` or ``%`` in ISO comments, never a newline), active comment words
    defused, upper case where the dialect wants it, clipped to
    ``max_comment`` (and to ``room`` characters in all, if given)."""
    d = dialect(d)
    body = ascii_text(text)
    for a, b in d.comment_spell:
        body = body.replace(a, b)
    body = " ".join(body.split())
    if d.comment_upper:
        body = body.upper()
    if d.active_comments:
        head = re.match(r"\s*([A-Za-z]+)\s*,", body)
        if head and head.group(1).upper() in d.active_comments:
            body = body[:head.end() - 1] + ":" + body[head.end():]
    limit = d.max_comment
    if room is not None:
        limit = min(limit, room - len(d.comment_open) - len(d.comment_close))
    body = body[:max(limit, 0)].rstrip()
    return f"{d.comment_open}{body}{d.comment_close}"


def number_lines(d: Dialect | str, lines: list[str]) -> list[str]:
    """``lines`` with ``N`` numbers where the dialect wants them (not on the
    ``%`` delimiters, the program number or comment-only lines), each block
    checked against ``max_block``: ``ValueError`` naming the block if longer."""
    d = dialect(d)
    out, n = [], 0
    for ln in lines:
        plain = (not ln or ln == "%" or ln.startswith(("O", d.comment_open))
                 or not d.line_numbers)
        if not plain:
            n += d.line_numbers
            if n > d.max_line_number:
                n = d.line_numbers
            ln = f"N{n} {ln}"
        if len(ln) > d.max_block:
            raise ValueError(f"block of {len(ln)} characters is longer than {d.name}'s "
                             f"limit of {d.max_block}: {ln[:40]}…")
        out.append(ln)
    return out
