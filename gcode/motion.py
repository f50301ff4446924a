"""Moves: a block of words (``G01 X1 Y2 F0.5``) applied to the machine state,
and cutter compensation of the programmed moves (see :mod:`gcode.interpreter`).

Machine frame: X, Y, Z in mm, C in degrees; feeds in mm (or deg) per time
unit, stored per second in the segments. Every G code is a row of
:data:`gcode.commands.G_CODES` whose ``handler`` names a function of
:data:`_G_HANDLERS` here; every word letter a row of
:data:`gcode.commands.WORD_LETTERS` with a function of :data:`_LETTER_HANDLERS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

from tipgeo.arrays import FloatArray
from tipgeo.tolerances import tol

from . import ast
from .commands import G_CODES
from .errors import GCodeError

__all__ = ["Segment", "MachineState", "BlockContext", "Move", "apply_block", "compensate",
           "ARC_TOLERANCE", "MAX_POSITION_MM", "MAX_ANGLE_DEG"]

#: An arc's end must lie on the circle through its start within this many mm
#: (relative to the radius above 1 mm); its radius must exceed it too.
ARC_TOLERANCE = tol.gcode.arc  # alias, imported by tests
#: Largest |X|, |Y|, |Z| and arc-centre coordinate, mm (1 km: beyond any
#: stage, and far from float overflow in the geometry).
MAX_POSITION_MM = 1e6
#: Largest |C|, degrees (about 2.8 million turns).
MAX_ANGLE_DEG = 1e9

#: A point of the machine's XY plane (mm).
Point = tuple[float, float]
#: The interpreter's evaluator: an expression at a statement → its value.
Evaluate = Callable[[ast.Expr, ast.Span], float]
#: The interpreter's error maker: a message at a statement → the error to raise.
MakeError = Callable[[str, ast.Span], GCodeError]


class Move(TypedDict, total=False):
    """A programmed move before cutter compensation (machine frame, mm and
    degrees; feeds per second): what :func:`apply_block` records and
    :func:`compensate` turns into segments (:class:`Segment`). ``center`` and
    ``ccw`` only for arcs; ``kind`` ``point`` for an arc collapsed to its
    centre."""

    kind: str
    start: Point
    end: Point
    c0: float
    c1: float
    beam: bool
    z0: float
    z1: float
    feed: float | None
    rotary_feed: float | None
    line: int
    span: ast.Span
    tool_r: float
    comp_before: int
    comp_after: int
    center: Point
    ccw: bool


@dataclass
class Segment:
    """One move of the beam centre (machine frame, mm and degrees).

    ``kind`` is ``line``, ``arc`` or ``rapid``; arcs have ``center`` and
    ``ccw``. ``c0``/``c1`` are the C angles at the start and end; ``beam``
    whether the laser fires during the move; ``feed`` in mm/s (None for
    rapids); ``line`` the source line.
    """

    kind: str
    start: tuple[float, float]
    end: tuple[float, float]
    beam: bool
    c0: float
    c1: float
    feed: float | None
    line: int
    center: tuple[float, float] | None = None
    ccw: bool = True
    rotary_feed: float | None = None
    z0: float = 0.0
    z1: float = 0.0

    @property
    def radius(self) -> float:
        if self.center is None:
            return 0.0
        return math.dist(self.start, self.center)

    @property
    def sweep(self) -> float:
        """Signed angle swept by an arc (rad, + counter-clockwise)."""
        if self.center is None:
            return 0.0
        cx, cy = self.center
        a0 = math.atan2(self.start[1] - cy, self.start[0] - cx)
        a1 = math.atan2(self.end[1] - cy, self.end[0] - cx)
        d = a1 - a0
        if self.ccw:
            d = d % (2 * math.pi)
            if d < tol.gcode.full_turn:
                d = 2 * math.pi
        else:
            d = -((-d) % (2 * math.pi))
            if d > -tol.gcode.full_turn:
                d = -2 * math.pi
        return d

    @property
    def length(self) -> float:
        """XY path length (mm)."""
        if self.kind == "arc":
            return abs(self.sweep) * self.radius
        return math.dist(self.start, self.end)

    @property
    def path_length(self) -> float:
        """XYZ path length (mm): the XY length with the Z travel (a line in
        space, or a helix for an arc)."""
        return math.hypot(self.length, self.z1 - self.z0)

    def points(self, chordal: float = tol.gcode.sample_chordal) -> FloatArray:
        """(k, 2) points along the move (arcs within ``chordal`` mm)."""
        c = self.center
        if self.kind != "arc" or c is None or self.radius <= 0:
            return np.array([self.start, self.end], float)
        r = self.radius
        step = 2 * math.acos(max(1 - chordal / r, -1.0)) if chordal < r else math.pi / 2
        n = max(2, math.ceil(abs(self.sweep) / max(step, tol.gcode.step_floor)))
        a0 = math.atan2(self.start[1] - c[1], self.start[0] - c[0])
        a = a0 + np.linspace(0, self.sweep, n + 1)
        return np.stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)], 1)


_AXES = ("X", "Y", "Z", "C")
_MOTION = {0: "rapid", 1: "line", 2: "cw", 3: "ccw"}
_KEYWORD_MOTION = {"RAPID": "rapid", "LINEAR": "line", "CW": "cw", "CCW": "ccw"}
_HOW = {"line": "G01/LINEAR", "cw": "G02/CW", "ccw": "G03/CCW"}


@dataclass
class MachineState:
    """Modal state of the machine while a program runs (mm, degrees, radians for
    the G84 rotation)."""

    pos: dict[str, float] = field(default_factory=lambda: {"X": 0.0, "Y": 0.0, "Z": 0.0,
                                                           "C": 0.0})
    offset: dict[str, float] = field(default_factory=lambda: {"X": 0.0, "Y": 0.0, "Z": 0.0,
                                                              "C": 0.0})
    absolute: bool = True
    scale: float = 1.0            # 25.4 in ENGLISH
    motion: str = "line"
    feed: float | None = None     # mm per time unit
    rotary_feed: float | None = None
    time_per_unit: float = 1.0    # seconds per time unit (SECONDS: 1, MINUTES: 60)
    tool: int = 0
    comp: int = 0                 # 0 off, +1 left (G41), -1 right (G42)
    laser: bool = False
    period_us: float | None = None
    on_us: float | None = None
    default_feed: float | None = None  # mm/s, for a feed move before any F
    rotation: float = 0.0         # G84 X Y F<deg>: program XY frame turned by this (rad)
    warnings: list[str] = field(default_factory=list)


@dataclass
class _Words:
    """What one block's words asked for, before it is applied."""

    target: dict[str, float] = field(default_factory=dict)
    center: dict[str, float] = field(default_factory=dict)
    g4: bool = False
    g84: bool = False
    g92: bool = False
    comp_change: int | None = None
    f_word: tuple[float, ast.Span] | None = None
    p_word: tuple[float, ast.Span] | None = None


class BlockContext:
    """The interpreter's services a block needs: evaluation, errors, the tool
    table, the list of programmed moves, the no-motion record and dwells."""

    def __init__(self, ev: Evaluate, err: MakeError, raw: list[Move], tools: dict[int, float],
                 note: Callable[[ast.Span, str, str], None],
                 dwell: Callable[[float, ast.Span], None]):
        self.ev, self.err, self.raw, self.tools, self.note, self.dwell = \
            ev, err, raw, tools, note, dwell


def apply_block(st: MachineState, b: ast.Block, ctx: BlockContext) -> None:
    """Apply one block: its modes, then its dwell, preset, rotation or move."""
    words = _Words()
    for kw in b.keywords:
        st.motion = _KEYWORD_MOTION[kw]
    for w in b.words:
        _word(st, words, w, ctx)
    if words.g84:
        _rotation(st, words, b, ctx.err)
        return
    _set_feed(st, words, ctx.err)
    if words.g4 or words.p_word is not None:
        _dwell_block(words, b, ctx)
    elif words.g92:
        _preset(st, words, b, ctx.err)
    elif words.comp_change is not None and not words.target:
        st.comp = words.comp_change
    elif words.target or words.center:
        _move(st, words, b, ctx)


def _word(st: MachineState, words: _Words, w: ast.Word, ctx: BlockContext) -> None:
    if w.letter == "N":
        return
    if w.letter == "G":
        _g_word(st, words, w, ctx)
        return
    if w.value is None:
        return  # bare axis names (G44 X Y)
    val = ctx.ev(w.value, w.span)
    handler = _LETTER_HANDLERS.get(w.letter)
    if handler is None:
        raise ctx.err(f"word {w.letter} is not supported", w.span)
    handler(st, words, w, val, ctx)


def _g_word(st: MachineState, words: _Words, w: ast.Word, ctx: BlockContext) -> None:
    code = ctx.ev(w.value, w.span) if w.value is not None else None
    if code is None or code != int(code):
        raise ctx.err("G needs a whole number", w.span)
    row = G_CODES.get(int(code))
    if row is None:
        raise ctx.err(f"G{int(code)} is not supported", w.span)
    _G_HANDLERS[row.handler](st, words, int(code), w, ctx)


# -- G codes (the handler column of gcode.commands.G_CODES) --------------------------------
def _g_motion(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    st.motion = _MOTION[code]


def _g_compensation(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    words.comp_change = {40: 0, 41: 1, 42: -1}[code]


def _g_distance(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    st.absolute = code == 90


def _g_preset(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    words.g92 = True


def _g_dwell(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    words.g4 = True


def _g_rotation(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    words.g84 = True


def _g_units(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    st.scale = 25.4 if code == 70 else 1.0


def _g_time_base(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    st.time_per_unit = 60.0 if code == 75 else 1.0


def _g_record(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    ctx.note(w.span, f"G{code}", G_CODES[code].effect)


def _g_nothing(st: MachineState, words: _Words, code: int, w: ast.Word,
        ctx: BlockContext) -> None:
    pass  # the XY plane (the only one) / compensation axes / as in Appendix C


_GHandler = Callable[[MachineState, _Words, int, ast.Word, BlockContext], None]
_G_HANDLERS: dict[str, _GHandler] = {
    "motion": _g_motion, "compensation": _g_compensation, "distance": _g_distance,
    "preset": _g_preset, "dwell": _g_dwell, "rotation": _g_rotation,
    "units": _g_units, "time_base": _g_time_base, "record": _g_record,
    "nothing": _g_nothing}


# -- word letters (gcode.commands.WORD_LETTERS) ---------------------------------------------
def _w_axis(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    words.target[w.letter] = val * (st.scale if w.letter != "C" else 1.0)


def _w_center(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    words.center[w.letter] = val * st.scale


def _w_feed(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    words.f_word = (val, w.span)


def _w_rotary_feed(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    if not val > 0:
        raise ctx.err(f"E{val:g}: the rotary feed rate E must be > 0 (degrees per time "
                      "unit)", w.span)
    st.rotary_feed = val


def _w_tool(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    if val != int(val) or val < 0:
        raise ctx.err(f"T{val:g}: the tool number T must be a whole number ≥ 0", w.span)
    t = int(val)
    if t not in ctx.tools:
        raise ctx.err(f"T{t}: no such tool in the tool table (have "
                      f"{', '.join(f'T{k}' for k in sorted(ctx.tools))})", w.span)
    st.tool = t


def _w_dwell_time(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    words.p_word = (val, w.span)


def _w_ignored(st: MachineState, words: _Words, w: ast.Word, val: float,
        ctx: BlockContext) -> None:
    pass  # A, B: axes the simulation does not follow


_LetterHandler = Callable[[MachineState, _Words, ast.Word, float, BlockContext], None]
_LETTER_HANDLERS: dict[str, _LetterHandler] = {
    "X": _w_axis, "Y": _w_axis, "Z": _w_axis, "C": _w_axis,
    "I": _w_center, "J": _w_center, "K": _w_center, "F": _w_feed,
    "E": _w_rotary_feed, "T": _w_tool, "P": _w_dwell_time,
    "A": _w_ignored, "B": _w_ignored}


# -- what a block does ------------------------------------------------------------------------
def _rotation(st: MachineState, words: _Words, b: ast.Block, err: MakeError) -> None:
    """G84 X Y F<deg>: the program's XY frame turns (no F: back to 0)."""
    if words.target or words.center:
        raise err("G84 turns the XY frame: give only the axis names and F, the angle (deg)",
                  b.span)
    st.rotation = math.radians(words.f_word[0]) if words.f_word is not None else 0.0


def _set_feed(st: MachineState, words: _Words, err: MakeError) -> None:
    if words.f_word is None:
        return
    value, span = words.f_word
    if not value > 0:
        raise err(f"F{value:g}: the feed rate F must be > 0 (length per time unit)", span)
    st.feed = value * st.scale


def _dwell_block(words: _Words, b: ast.Block, ctx: BlockContext) -> None:
    """G4 P t (the block holds G4 or P: apply_block)."""
    p = words.p_word
    if p is None:
        raise ctx.err("G4 needs P, the dwell time (s)", b.span)
    if not words.g4:
        raise ctx.err("P is the dwell time of G4 (s): give G4 in the same block", p[1])
    if words.target or words.center:
        raise ctx.err("G4 dwells and moves nothing: no axis words in its block", b.span)
    ctx.dwell(p[0], b.span)


def _preset(st: MachineState, words: _Words, b: ast.Block, err: MakeError) -> None:
    """G92: the current position takes the given values."""
    for a, v in words.target.items():
        _check_position(a, v, b.span, err)
        st.offset[a] = st.pos[a] + st.offset[a] - v
        st.pos[a] = v


def _move(st: MachineState, words: _Words, b: ast.Block, ctx: BlockContext) -> None:
    err, tools = ctx.err, ctx.tools
    new = dict(st.pos)
    for a, v in words.target.items():
        new[a] = v if st.absolute else st.pos[a] + v
    if st.rotation and ("X" in words.target or "Y" in words.target):
        _rotate_target(st, words.target, new)
    for a in words.target:
        _check_position(a, new[a], b.span, err)
    motion = st.motion
    if motion != "rapid":
        _need_feed(st, b, err)
    if st.tool not in tools:
        raise err(f"T{st.tool}, the current tool, is not in the tool table (have "
                  f"{', '.join(f'T{k}' for k in sorted(tools)) or 'none'})", b.span)
    kind = "rapid" if motion == "rapid" else ("arc" if motion in ("cw", "ccw") else "line")
    feed = None if motion == "rapid" or st.feed is None else st.feed / st.time_per_unit
    move: Move = {"kind": kind, "start": (st.pos["X"], st.pos["Y"]), "end": (new["X"], new["Y"]),
            "c0": st.pos["C"], "c1": new["C"], "beam": st.laser,
            "z0": st.pos["Z"], "z1": new["Z"],
            "feed": feed,
            "rotary_feed": None if st.rotary_feed is None else st.rotary_feed / st.time_per_unit,
            "line": b.span.line, "span": b.span,
            "tool_r": tools[st.tool],
            "comp_before": st.comp}
    if kind == "arc":
        _arc(st, words, move, b, ctx)
    if words.comp_change is not None:
        st.comp = words.comp_change
    move["comp_after"] = st.comp
    ctx.raw.append(move)
    st.pos = new


def _need_feed(st: MachineState, b: ast.Block, err: MakeError) -> None:
    """A feed move needs a feed: the last F, else the default feed (with a
    warning), else an error."""
    if st.feed is not None:
        return
    how = _HOW[st.motion]
    if st.default_feed is None:
        raise err(f"a {how} move needs a feed rate, but no feed rate (F) has been programmed "
                  "yet: give F (> 0) in this block or before it", b.span)
    st.feed = st.default_feed * st.time_per_unit
    st.warnings.append(f"line {b.span.line}: a {how} move before any F: the default "
                       f"feed {st.default_feed:g} mm/s is used until an F is given")


def _arc(st: MachineState, words: _Words, move: Move, b: ast.Block, ctx: BlockContext) -> None:
    err, center = ctx.err, words.center
    if "I" not in center and "J" not in center:
        raise err("arc without I or J (centre offset)", b.span)
    i, j = center.get("I", 0.0), center.get("J", 0.0)
    if st.rotation:
        cr, sr = math.cos(st.rotation), math.sin(st.rotation)
        i, j = cr * i - sr * j, sr * i + cr * j
    cx, cy = st.pos["X"] + i, st.pos["Y"] + j
    _check_position("arc centre X", cx, b.span, err)
    _check_position("arc centre Y", cy, b.span, err)
    r0 = math.dist((cx, cy), move["start"])
    r1 = math.dist((cx, cy), move["end"])
    arc_tol = tol.gcode.arc * max(1.0, r0)
    ccw = st.motion == "ccw"
    side = st.comp if words.comp_change is None or words.comp_change == st.comp else 0
    tool_r = ctx.tools[st.tool]
    collapses = (side != 0 and side * (1 if ccw else -1) > 0 and tool_r > 0
                 and r0 - tool_r <= tol.gcode.length)
    if r0 <= arc_tol and not collapses:
        raise err(f"arc radius {r0:.6g} mm: I{i:g} J{j:g} put the centre on the start "
                  f"point; the radius must exceed {arc_tol:.3g} mm (ARC_TOLERANCE)", b.span)
    if abs(r0 - r1) > arc_tol:
        raise err(f"arc end is {abs(r0 - r1) * 1e3:.4g} µm off its circle "
                  f"(radius {r0:.6g} mm at the start, {r1:.6g} mm at the end; the "
                  f"tolerance is {arc_tol * 1e3:.3g} µm, ARC_TOLERANCE)", b.span)
    move["center"] = (cx, cy)
    move["ccw"] = ccw


def _rotate_target(st: MachineState, target: dict[str, float], new: dict[str, float]) -> None:
    """``new`` X, Y for a move programmed in the frame turned by G84: the
    programmed coordinates are in the turned frame (+ counter-clockwise)."""
    cr, sr = math.cos(st.rotation), math.sin(st.rotation)
    x, y = st.pos["X"], st.pos["Y"]
    px, py = cr * x + sr * y, -sr * x + cr * y      # current point in the turned frame
    if st.absolute:
        px, py = target.get("X", px), target.get("Y", py)
    else:
        px, py = px + target.get("X", 0.0), py + target.get("Y", 0.0)
    new["X"], new["Y"] = cr * px - sr * py, sr * px + cr * py


def _check_position(axis: str, value: float, span: ast.Span, err: MakeError) -> None:
    if axis == "C":
        if not abs(value) <= MAX_ANGLE_DEG:
            raise err(f"C position {value:.6g}° is beyond ±{MAX_ANGLE_DEG:g}° (MAX_ANGLE_DEG)",
                      span)
    elif not abs(value) <= MAX_POSITION_MM:
        raise err(f"{axis} position {value:.6g} mm is beyond ±{MAX_POSITION_MM:g} mm "
                  "(MAX_POSITION_MM)", span)


# -- cutter compensation --------------------------------------------------------------------------
def _unit(v: Point) -> Point:
    n = math.hypot(*v)
    return (v[0] / n, v[1] / n) if n > 0 else (0.0, 0.0)


def _left(d: Point) -> Point:
    return (-d[1], d[0])


def _offset(move: Move, side: int, r_t: float, warnings: list[str]) -> Move:
    """The move offset by r_t to ``side`` (+1 left, −1 right) of travel."""
    s, e = move["start"], move["end"]
    if move["kind"] != "arc":
        d = _unit((e[0] - s[0], e[1] - s[1]))
        n = _left(d)
        o = (side * r_t * n[0], side * r_t * n[1])
        return move | {"start": (s[0] + o[0], s[1] + o[1]), "end": (e[0] + o[0], e[1] + o[1])}
    c = move["center"]
    r = math.dist(s, c)
    # left of a CCW arc is towards the centre
    towards = side * (1 if move["ccw"] else -1)
    rn = r - towards * r_t
    if rn <= tol.gcode.length:
        warnings.append(f"line {move['line']}: arc radius {r:.6g} mm is not larger than the "
                        f"tool radius {r_t:.6g} mm; the compensated path collapses to its centre")
        rn = 0.0

    def at(p: Point) -> Point:
        u = _unit((p[0] - c[0], p[1] - c[1]))
        return (c[0] + rn * u[0], c[1] + rn * u[1])
    out = move | {"start": at(s), "end": at(e)}
    if rn == 0.0:
        out["kind"] = "point"
    return out


def _direction(m: Move) -> Point:
    """Unit direction of a line move."""
    return _unit((m["end"][0] - m["start"][0], m["end"][1] - m["start"][1]))


def _line_line(p: Point, d: Point, q: Point, e: Point) -> list[Point]:
    """Intersection of the lines p + t d and q + s e (none if parallel)."""
    den = d[0] * e[1] - d[1] * e[0]
    if abs(den) > tol.gcode.parallel:
        t = ((q[0] - p[0]) * e[1] - (q[1] - p[1]) * e[0]) / den
        return [(p[0] + t * d[0], p[1] + t * d[1])]
    return []


def _circle_circle(c0: Point, r0: float, c1: Point, r1: float) -> list[Point]:
    """Intersections of two circles (none if apart, nested or concentric)."""
    dd = math.dist(c0, c1)
    if not (tol.gcode.length < dd <= r0 + r1 and dd >= abs(r0 - r1)):
        return []
    a_ = (r0 * r0 - r1 * r1 + dd * dd) / (2 * dd)
    h = math.sqrt(max(r0 * r0 - a_ * a_, 0.0))
    ex = ((c1[0] - c0[0]) / dd, (c1[1] - c0[1]) / dd)
    m = (c0[0] + a_ * ex[0], c0[1] + a_ * ex[1])
    return [(m[0] - h * ex[1], m[1] + h * ex[0]), (m[0] + h * ex[1], m[1] - h * ex[0])]


def _line_circle(p: Point, d: Point, c: Point, r: float) -> list[Point]:
    """Intersections of the line p + t d (d a unit vector) with a circle."""
    f = (p[0] - c[0], p[1] - c[1])
    bq = f[0] * d[0] + f[1] * d[1]
    cq = f[0] ** 2 + f[1] ** 2 - r * r
    disc = bq * bq - cq
    pts: list[Point] = []
    if disc >= 0:
        for sgn in (-1, 1):
            t = -bq + sgn * math.sqrt(disc)
            pts.append((p[0] + t * d[0], p[1] + t * d[1]))
    return pts


def _intersect(a: Move, b: Move, corner: Point) -> Point | None:
    """Intersection of offset elements a, b (lines or circles) nearest the
    programmed corner, or None."""
    a_arc, b_arc = a["kind"] == "arc", b["kind"] == "arc"
    if not a_arc and not b_arc:
        pts = _line_line(a["start"], _direction(a), b["start"], _direction(b))
    elif a_arc and b_arc:
        pts = _circle_circle(a["center"], math.dist(a["start"], a["center"]),
                             b["center"], math.dist(b["start"], b["center"]))
    else:
        line, circ = (b, a) if a_arc else (a, b)
        pts = _line_circle(line["start"], _direction(line), circ["center"],
                           math.dist(circ["start"], circ["center"]))
    if not pts:
        return None
    return min(pts, key=lambda q: math.dist(q, corner))


def compensate(raw: list[Move], warnings: list[str]) -> list[Segment]:
    """Apply cutter compensation to the programmed moves; the segments."""
    n = len(raw)
    offs: list[Move | None] = [None] * n
    for i, m in enumerate(raw):
        side = m["comp_after"] if m["comp_before"] == m["comp_after"] else 0
        if side and m["tool_r"] > 0 and m["kind"] != "rapid":
            offs[i] = _offset(m, side, m["tool_r"], warnings)
    out: list[Move] = []
    for i, m in enumerate(raw):
        off = offs[i]
        if off is not None:
            _append_offset(out, off.copy(), m, i > 0 and offs[i - 1] is not None)
        else:
            out.append(_uncompensated(m, out, offs[i + 1] if i + 1 < n else None))
    return [_segment(m) for m in out]


def _append_offset(out: list[Move], cur: Move, m: Move, after_offset: bool) -> None:
    """Append a compensated element, joined to the previous compensated one:
    trimmed at their intersection (concave) or by a round corner (convex)."""
    if after_offset and out:
        p_end = out[-1]["end"]
        if math.dist(p_end, cur["start"]) > tol.gcode.point:
            q = _intersect(out[-1], cur, m["start"]) if (
                out[-1]["kind"] != "point" and cur["kind"] != "point") else None
            if q is not None and math.dist(q, m["start"]) <= 2 * m["tool_r"] + tol.gcode.point:
                out[-1] = _trim_end(out[-1], q)
                cur = _trim_start(cur, q)
            else:  # convex corner: round it about the programmed point
                out.append(m | {"kind": "arc", "start": p_end, "end": cur["start"],
                                "center": m["start"], "ccw": m["comp_after"] < 0,
                                "z1": m["z0"]})
    out.append(cur)


def _uncompensated(m: Move, out: list[Move], next_offset: Move | None) -> Move:
    """A move without compensation; the ramps switching it on (off) end
    (start) at the offset path."""
    mm = m.copy()
    if m["comp_before"] != m["comp_after"] and m["comp_after"] and next_offset is not None:
        mm["end"] = next_offset["start"]
        if mm["kind"] == "arc":
            mm["kind"] = "line"
    if m["comp_before"] and not m["comp_after"] and out:
        mm["start"] = out[-1]["end"]
    elif out and math.dist(out[-1]["end"], mm["start"]) > tol.gcode.point and \
            out[-1].get("comp_after") and m["kind"] != "rapid":
        mm["start"] = out[-1]["end"]
    return mm


def _point(p: Point) -> Point:
    return (p[0], p[1])


def _segment(m: Move) -> Segment:
    kind = m["kind"]
    if kind == "point":
        kind = "line"
        m = m | {"start": m["center"], "end": m["center"]}
    return Segment(kind, _point(m["start"]), _point(m["end"]), bool(m["beam"]),
                   float(m["c0"]), float(m["c1"]), m["feed"], int(m["line"]),
                   _point(m["center"]) if kind == "arc" else None,
                   bool(m.get("ccw", True)), m.get("rotary_feed"),
                   float(m.get("z0", 0.0)), float(m.get("z1", 0.0)))


def _trim_end(m: Move, q: Point) -> Move:
    return m | {"end": q}


def _trim_start(m: Move, q: Point) -> Move:
    return m | {"start": q}
