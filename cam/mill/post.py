"""G-code posts as tables: one row of the dialect table
(:data:`gcode.dialects.DIALECTS`: Haas VF-2, LinuxCNC, generic Fanuc) per
controller, one post function for all.

The post writes the start delimiter (``%``), the program number (or the title
as a comment where the dialect has none), the header
(``G17 G21 G90 G94 G40 G49 G80``), the tool call, the spindle, the tool
length offset on a motion line (``G00 G43 H01 Z…``), the coolant, modal moves
with fixed decimals (3 for X, Y, Z on the 0.002 mm grid; 1 for F), the
retract, ``M30`` and ``%``; line numbers and the block-length limit by the
dialect; ASCII only; every comment through the one comment writer
:func:`gcode.dialects.comment`. Program frame and units:
:mod:`cam.mill.machine` (mm, mm/min).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING

from gcode.dialects import DIALECTS, HAAS, Dialect, number_lines
from gcode.dialects import comment as _comment
from tipgeo.arrays import FloatArray

from ..machine import CamError

if TYPE_CHECKING:
    from .toolpath import MillToolpath

__all__ = ["Post", "POSTS", "HAAS", "post_program", "comment", "DECIMALS"]

#: A post is a row of the dialect table :data:`gcode.dialects.DIALECTS`.
Post = Dialect


class _IsoPosts(Mapping[str, Dialect]):
    """The ``iso`` rows of :data:`~gcode.dialects.DIALECTS`, read live: a
    dialect registered later (:func:`gcode.dialects.register_dialect`) is a
    post too."""

    def __getitem__(self, key: str) -> Dialect:
        row = DIALECTS[key]
        if row.family != "iso":
            raise KeyError(key)
        return row

    def __iter__(self) -> Iterator[str]:
        return iter([k for k, d in DIALECTS.items() if d.family == "iso"])

    def __len__(self) -> int:
        return sum(1 for d in DIALECTS.values() if d.family == "iso")


#: controller name -> post table (the ISO rows of the dialect table).
POSTS: Mapping[str, Dialect] = _IsoPosts()

#: Fixed decimals per word: 3 for X, Y, Z (the 0.002 mm grid), 1 for F.
DECIMALS = {"X": 3, "Y": 3, "Z": 3, "F": 1}


def _number(word: str, value: float) -> str:
    """``word`` with ``value`` in fixed decimals (never exponents; −0 → 0)."""
    d = DECIMALS[word]
    text = f"{value:.{d}f}"
    if float(text) == 0.0:
        text = f"{0.0:.{d}f}"
    return f"{word}{text}"


def comment(post: Dialect | str, text: str) -> str:
    """One comment by the dialect's rules (:func:`gcode.dialects.comment`)."""
    return _comment(post, text)


def post_program(toolpath: MillToolpath, post: Post | str | None = None) -> str:
    """The G-code of a :class:`~cam.mill.toolpath.MillToolpath` (program
    frame, mm, feeds mm/min)."""
    if isinstance(post, str) or post is None:
        key = post or toolpath.machine.controller
        if key not in POSTS:
            raise CamError(f"controller = {key!r} has no post; expected one of: "
                           + ", ".join(POSTS))
        post = POSTS[key]
    tp, prm, st, tool = toolpath, toolpath.params, toolpath.setup, toolpath.tool
    title = comment(post, f"{tp.name} milled tip-up")
    out: list[str] = [post.start] if post.start else []
    out.append(post.program_number.format(number=prm.program_number) + " " + title
               if post.program_number else title)
    notes = [f"tipgeo mill: {tp.name}",
             f"machine {tp.machine.name}",
             f"tool T{tool.number}: {tool.describe()}",
             "program zero G54: needle axis at heel height, tip up",
             f"needle clocked {math.degrees(st.clocking):.3f} deg: gamma of +X",
             f"stock top Z{st.z_top:.3f}, safe Z{st.z_safe:.3f} mm",
             f"finish step-over {st.stepover:.3f} mm for scallop {prm.scallop * 1e3:g} um",
             f"roughing allowance {prm.allowance:.3f} mm, step-down {prm.stepdown:.3f} mm",
             "units mm, feeds mm/min"]
    out += [comment(post, n) for n in notes]
    out.append(post.header)
    out.append(post.tool_change.format(tool=tool.number) + " "
               + comment(post, tool.describe()))
    out.append(post.work_offset)
    out.append(post.spindle_on.format(rpm=int(round(prm.spindle_rpm))))
    out.append(post.length_offset.format(tool=tool.number, z=_number("Z", st.z_safe)[1:]))
    if prm.coolant:
        out.append(post.coolant_on)
    rapid_in_offset = post.length_offset.split()[0] == post.rapid
    state: dict[str, str | None] = {"X": None, "Y": None, "Z": _number("Z", st.z_safe), "F": None,
             "G": post.rapid if rapid_in_offset else None}

    def move(g: str, p: Sequence[float] | FloatArray, f: float | None = None) -> None:
        words = []
        for k, val in zip("XYZ", p):
            w = _number(k, val)
            if w != state[k]:
                words.append(w)
                state[k] = w
        if not words:
            return
        if g != state["G"]:
            words.insert(0, g)
            state["G"] = g
        if f is not None:
            w = _number("F", f)
            if w != state["F"]:
                words.append(w)
                state["F"] = w
        out.append(" ".join(words))

    kind = None
    for ps in tp.passes:
        if ps.kind != kind:
            kind = ps.kind
            out.append(comment(post, f"{kind}ing passes"))
        p0 = ps.points[0]
        move(post.rapid, (p0[0], p0[1], st.z_safe))
        above = (p0[2] if ps.clear_start else max(p0[2], st.z_top)) + prm.approach
        move(post.rapid, (p0[0], p0[1], min(above, st.z_safe)))
        move(post.feed, p0, prm.plunge_feed)
        for p in ps.points[1:]:
            move(post.feed, p, ps.feed)
        move(post.rapid, (ps.points[-1][0], ps.points[-1][1], st.z_safe))
    if prm.coolant:
        out.append(post.coolant_off)
    out.append(post.spindle_off)
    out.append(post.home)
    out.append(post.absolute)
    out.append(post.end)
    if post.finish:
        out.append(post.finish)
    try:
        text = "\n".join(number_lines(post, out)) + "\n"
    except ValueError as e:
        raise CamError(str(e)) from None
    if not text.isascii():
        raise CamError("the program is not ASCII")  # comments are sanitised: a bug otherwise
    return text

