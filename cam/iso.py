"""What every ISO (RS-274 / Fanuc-style) program tipgeo writes shares, by
the dialect table :data:`gcode.dialects.DIALECTS`: plain ASCII comments a
generic parser accepts, the program start (``%``, program number, safety line)
and end (spindle stop, ``M30``, ``%``).

Comments (:func:`gcode.dialects.comment`, the one comment writer): one pair
of parentheses, nothing nested in them (``(`` and ``)`` become ``[`` and
``]``), no ``;`` (a comment start on many controls; it becomes ``,``), no
``%`` (the tape delimiter), ASCII only (Greek letters spelt out, ``°`` as
``deg``, ``§`` as ``sec.``, dashes as ``-``; anything else by its
compatibility decomposition, else ``?``), never a newline.
"""

from __future__ import annotations

from gcode.dialects import DIALECTS, FANUC, Dialect, comment, dialect

from .machine import CamError

__all__ = ["SAFETY_LINE", "iso_comment", "iso_end", "iso_start", "check_program_number",
           "DIALECTS", "Dialect"]

#: The safety block at the start of a program: XY plane, mm, absolute, feed
#: per minute, cutter radius and tool length compensation off, canned cycles
#: off (every ISO row of :data:`gcode.dialects.DIALECTS` writes it).
SAFETY_LINE = FANUC.header


def iso_comment(text: str, d: Dialect | str = FANUC) -> str:
    """``text`` as one ISO comment ``(…)``: ASCII, no nested parentheses, no
    ``;`` or ``%`` inside (the one comment writer,
    :func:`gcode.dialects.comment`)."""
    return comment(d, text)


def check_program_number(number: int) -> int:
    """``number`` if it is a valid ISO program number (1…9999), else CamError."""
    if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= 9999:
        raise CamError(f"program_number = {number!r} is out of range; allowed an integer "
                         f"1…9999 (the O-number)")
    return number


def iso_start(number: int, title: str, d: Dialect | str = FANUC) -> list[str]:
    """The first lines of a program in dialect ``d``: the tape delimiter
    (``%``), ``O<number> (title)`` (the title alone where the dialect has no
    program number) and the header (safety line)."""
    d = dialect(d)
    check_program_number(number)
    title = comment(d, title)
    first = f"{d.program_number.format(number=number)} {title}" if d.program_number else title
    return [x for x in (d.start, first, d.header) if x]


def iso_end(d: Dialect | str = FANUC) -> list[str]:
    """The last lines of a program in dialect ``d``: spindle stop, program end
    and rewind (``M30``), the closing delimiter (``%``) and a final newline."""
    d = dialect(d)
    return [x for x in (d.spindle_off, d.end, d.finish) if x] + [""]
