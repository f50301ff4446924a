"""G-code posts as tables: one :class:`Post` row of words per controller.

The Haas post (Fanuc-style) writes ``%``, the program number, a safety line
(``G17 G21 G40 G49 G80 G90``), the tool call and length offset, the spindle
and coolant, modal moves with fixed decimals (3 for X, Y, Z on the 0.002 mm
grid; 1 for F), ``M30`` and ``%``; ASCII only; comments in single parentheses
without nested ones. Another controller is another :class:`Post` in
:data:`POSTS`. Program frame and units: :mod:`cam.mill.machine` (mm, mm/min).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ..machine import CamError

__all__ = ["Post", "POSTS", "HAAS", "post_program", "comment"]


@dataclass(frozen=True, kw_only=True)
class Post:
    """The words one controller needs (``{…}`` fields filled by the post)."""

    name: str
    start: str = "%"
    program_number: str = "O{number:05d}"
    safety: str = "G17 G21 G40 G49 G80 G90"
    tool_change: str = "T{tool} M06"
    work_offset: str = "G54"
    spindle_on: str = "S{rpm} M03"
    length_offset: str = "G43 H{tool:02d} Z{z}"
    coolant_on: str = "M08"
    coolant_off: str = "M09"
    spindle_off: str = "M05"
    home: str = "G28 G91 Z0."
    absolute: str = "G90"
    end: str = "M30"
    finish: str = "%"
    rapid: str = "G00"
    feed: str = "G01"
    decimals: tuple[tuple[str, int], ...] = (("X", 3), ("Y", 3), ("Z", 3), ("F", 1))
    comment_open: str = "("
    comment_close: str = ")"
    max_comment: int = 70

    def number(self, word: str, value: float) -> str:
        """``word`` with ``value`` in fixed decimals (never exponents; −0 → 0)."""
        d = dict(self.decimals)[word]
        text = f"{value:.{d}f}"
        if float(text) == 0.0:
            text = f"{0.0:.{d}f}"
        return f"{word}{text}"


HAAS = Post(name="haas")

#: controller name -> post table.
POSTS: dict[str, Post] = {"haas": HAAS}


def comment(post: Post, text: str) -> str:
    """One comment: ASCII, no parentheses inside, upper case, clipped."""
    for a, b in (("§", "SEC "), ("µ", "u"), ("°", " DEG"), ("−", "-"), ("–", "-")):
        text = text.replace(a, b)
    t = text.encode("ascii", "replace").decode("ascii").replace("?", "-")
    t = re.sub(r"[()]", "", t).replace(post.comment_open, "").replace(post.comment_close, "")
    t = re.sub(r"\s+", " ", t).strip().upper()[:post.max_comment]
    return f"{post.comment_open}{t}{post.comment_close}"


def post_program(toolpath, post: Post | str | None = None) -> str:
    """The G-code of a :class:`~cam.mill.toolpath.MillToolpath` (program
    frame, mm, feeds mm/min)."""
    if isinstance(post, str) or post is None:
        key = post or toolpath.machine.controller
        if key not in POSTS:
            raise CamError(f"controller = {key!r} has no post; expected one of: "
                           + ", ".join(POSTS))
        post = POSTS[key]
    tp, prm, st, tool = toolpath, toolpath.params, toolpath.setup, toolpath.tool
    out: list[str] = [post.start, post.program_number.format(number=prm.program_number)
                      + " " + comment(post, f"{tp.name} milled tip-up")]
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
    out.append(post.safety)
    out.append(post.tool_change.format(tool=tool.number) + " "
               + comment(post, tool.describe()))
    out.append(post.work_offset)
    out.append(post.spindle_on.format(rpm=int(round(prm.spindle_rpm))))
    out.append(post.length_offset.format(tool=tool.number, z=post.number("Z", st.z_safe)[1:]))
    if prm.coolant:
        out.append(post.coolant_on)
    state = {"X": None, "Y": None, "Z": post.number("Z", st.z_safe), "F": None, "G": None}

    def move(g: str, p, f=None):
        words = []
        for k, val in zip("XYZ", p):
            w = post.number(k, val)
            if w != state[k]:
                words.append(w)
                state[k] = w
        if not words:
            return
        if g != state["G"]:
            words.insert(0, g)
            state["G"] = g
        if f is not None:
            w = post.number("F", f)
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
    out.append(post.finish)
    text = "\n".join(out) + "\n"
    if not text.isascii():
        raise CamError("the program is not ASCII")  # comments are sanitised: a bug otherwise
    return text

