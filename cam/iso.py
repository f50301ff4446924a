"""What every ISO (RS-274 / Fanuc-style) program tipgeo writes shares: plain
ASCII comments a generic parser accepts, the program start (``%``, program
number, safety line) and end (spindle stop, ``M30``, ``%``).

Comments: one pair of parentheses, nothing nested in them (``(`` and ``)``
become ``[`` and ``]``), no ``;`` (a comment start on many controls; it becomes
``,``), no ``%`` (the tape delimiter), ASCII only (Greek letters spelt out,
``°`` as ``deg``, ``§`` as ``sec.``, dashes as ``-``; anything else by its
compatibility decomposition, else ``?``).
"""

from __future__ import annotations

import unicodedata

from .machine import CamError

__all__ = ["SAFETY_LINE", "iso_comment", "iso_end", "iso_start", "check_program_number"]

#: The safety block at the start of a program: XY plane, mm, cutter radius and
#: tool length compensation off, canned cycles off, absolute, feed per minute.
SAFETY_LINE = "G17 G21 G40 G49 G80 G90 G94"

_SPELL = {
    "(": "[", ")": "]", ";": ",", "%": " pct", "§": "sec. ", "—": "-", "–": "-",
    "−": "-", "°": " deg", "µ": "u", "μ": "u", "×": "x", "·": "*", "≤": "<=", "≥": ">=",
    "≈": "~", "→": "->", "←": "<-", "…": "...", "’": "'", "‘": "'", "“": '"', "”": '"',
    "ξ": "xi", "φ": "phi", "ϕ": "phi", "θ": "theta", "β": "beta", "γ": "gamma",
    "α": "alpha", "δ": "delta", "ε": "eps", "λ": "lambda", "ψ": "psi", "ω": "omega",
    "Δ": "Delta", "π": "pi", "ρ": "rho", "σ": "sigma", "τ": "tau", "η": "eta", "κ": "kappa",
    "\t": " ", "\r": " ", "\n": " ",
}


def _ascii(ch: str) -> str:
    if ch in _SPELL:
        return _SPELL[ch]
    if " " <= ch <= "~":
        return ch
    plain = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode("ascii")
    return "".join(_SPELL.get(c, c) for c in plain if " " <= c <= "~") or "?"


def iso_comment(text: str) -> str:
    """``text`` as one ISO comment ``(…)``: ASCII, no nested parentheses, no
    ``;`` or ``%`` inside (see the module docstring)."""
    body = " ".join("".join(_ascii(c) for c in str(text)).split())
    return f"({body})"


def check_program_number(number: int) -> int:
    """``number`` if it is a valid ISO program number (1…9999), else CamError."""
    if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= 9999:
        raise CamError(f"program_number = {number!r} is out of range; allowed an integer "
                         f"1…9999 (the O-number)")
    return number


def iso_start(number: int, title: str) -> list[str]:
    """The first lines of a program: ``%``, ``O<number> (title)`` and the
    :data:`SAFETY_LINE`."""
    return ["%", f"O{check_program_number(number):04d} {iso_comment(title)}", SAFETY_LINE]


def iso_end() -> list[str]:
    """The last lines of a program: spindle stop, program end and rewind
    (``M30``), the closing ``%`` and a final newline."""
    return ["M5", "M30", "%", ""]
