"""Interpreter: an AeroBasic syntax tree → a toolpath in machine coordinates.

Machine frame (A3200 laser stage, thesis Fig. 5.1): X, Y linear axes in mm
(the program's XY plane is tangent to the punch's rim: X along the rim, Y
along the punch axis, +Y into the material), C the rotary axis turning the
punch about its own axis, in degrees. The beam points along the machine's
−Z, radially into the punch wall. Time base from ``SECONDS``/``MINUTES``
(feeds F in mm per time unit, E in degrees per time unit).

Modal state: units (METRIC; ENGLISH scales linear axes by 25.4, never C),
ABSOLUTE/INCREMENTAL (G90/G91), motion mode (G0–G3; RAPID, LINEAR, CW, CCW),
feeds F and E, tool T (radius from the tool table), cutter compensation
(G40 off, G41 left, G42 right; G44 selects its axes), G92 position preset,
C angle, the laser (PSOCONTROL … FIRE/ON/ARM on, OFF/RESET off) and its pulse timing (PSOPULSE
… TIME period on CYCLES n, µs).

Control flow and the rest of the A3200 language: WHILE, IF/ELSEIF/ELSE
(conditions evaluated as 1/0), CALL of a DFS subroutine with letter
arguments (``$p``, ``$q`` … inside, restored after; calls nest at most
:data:`MAX_CALL_DEPTH`), DWELL and G4 P (seconds whatever the time base;
:attr:`Toolpath.dwells`, counted in the summary's time), G70/G71 and
G75/G76 (units and time base), END/END PROGRAM/M2/M30 stop the run.
Statements that move nothing (I/O and system variables, VELOCITY, G359, file
and message commands …) are recorded in :attr:`Toolpath.no_motion` with what
they did and how often; the last value written to each output in
:attr:`Toolpath.io`. Z moves count in the path length and time (XYZ); the
beam-centre geometry is XY.

Cutter compensation offsets lines and arcs by the tool radius to the chosen
side of the travel direction; concave joints are trimmed to the offsets'
intersection, convex joints get a round corner about the programmed point;
the move that switches compensation on (off) ramps from (to) the
uncompensated point. An arc smaller than the tool collapses to its centre
(with a warning).

What cannot run is a :class:`~gcode.errors.GCodeError` located at its
statement: a feed move (G01–G03, LINEAR, CW, CCW) before any F; F, E ≤ 0; a
tool number that is not whole or not in the tool table; an arc without I/J,
of radius ≤ :data:`ARC_TOLERANCE` (centre on the start point) — unless
cutter compensation collapses it to its centre anyway, as when Appendix C's
roughing radius passes through 0 — or whose end is more than
:data:`ARC_TOLERANCE` off its circle; a position beyond
:data:`MAX_POSITION_MM` (:data:`MAX_ANGLE_DEG` for C); bad PSOPULSE timing
or CYCLES; going past a bound of :class:`Limits`.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field, fields

import numpy as np

from tipgeo.tolerances import tol

from . import ast
from .errors import GCodeError, check_limit
from .expr import evaluate
from .strings import evaluate_string
from .parser import G_NO_MOTION, MAX_NESTING
from .parser import IO_NAME as _IO

__all__ = ["Segment", "Toolpath", "interpret", "Limits", "ARC_TOLERANCE", "MAX_POSITION_MM",
           "MAX_ANGLE_DEG", "MAX_CALL_DEPTH", "MAX_IO_NAMES"]

#: An arc's end must lie on the circle through its start within this many mm
#: (relative to the radius above 1 mm); its radius must exceed it too.
ARC_TOLERANCE = tol.gcode.arc  # alias, imported by tests
#: Largest |X|, |Y|, |Z| and arc-centre coordinate, mm (1 km: beyond any
#: stage, and far from float overflow in the geometry).
MAX_POSITION_MM = 1e6
#: Largest |C|, degrees (about 2.8 million turns).
MAX_ANGLE_DEG = 1e9
#: Deepest nesting of subroutine calls (CALL inside a DFS …).
MAX_CALL_DEPTH = MAX_NESTING
#: Most different outputs and system variables one run writes (``$DO[i].X`` for
#: 10 000 values of i), so that the record of their values stays small.
MAX_IO_NAMES = 10_000


@dataclass(frozen=True)
class Limits:
    """Bounds that keep a hostile program from hanging or exhausting memory.

    Each default is set from measurements so that reaching it costs at most
    about 5 s of CPU on the reference 2-core machine (and, for moves, about
    250 MB); a program near several bounds at once costs at most their sum.
    Appendix C executes 13 541 statements, 75 864 operations and 9 616
    programmed moves (9 974 segments), with REPEAT counts up to 80: every
    default is at least ten times that. Every bound is a whole number ≥ 0
    (TypeError, ValueError otherwise).

    Attributes
    ----------
    max_repeat : int
        Largest ``REPEAT`` count; a larger one is refused before its loop
        starts. Default 1 000 000.
    max_statements : int
        Statements executed, counted once per execution (a REPEAT header
        once, its body's statements once per pass). A REPEAT whose passes
        would certainly go beyond is refused before its loop starts. Default
        1 000 000 (about 1.5–4.5 µs a statement, its operations included).
    max_segments : int
        Programmed moves (before cutter compensation) and dwells together.
        Default 100 000 (about 15–26 µs and 2.2 kB a move, compensation
        included).
    max_operations : int
        Work inside statements, all executions together: one for each
        number, variable or operator of an evaluated expression, each word of
        a block, each argument of a PSO command or ENABLE, each name of a
        DVAR (``$a = $a + 1`` is 3, ``G01 X1 F1`` 6). A REPEAT whose passes
        would certainly go beyond is refused before its loop starts. Default
        4 000 000 (about 0.1–0.9 µs an operation).
    """

    max_repeat: int = 1_000_000
    max_statements: int = 1_000_000
    max_segments: int = 100_000
    max_operations: int = 4_000_000

    def __post_init__(self):
        for f in fields(self):
            check_limit(f.name, getattr(self, f.name))


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

    def points(self, chordal: float = 1e-4) -> np.ndarray:
        """(k, 2) points along the move (arcs within ``chordal`` mm)."""
        if self.kind != "arc" or self.radius <= 0:
            return np.array([self.start, self.end], float)
        r = self.radius
        step = 2 * math.acos(max(1 - chordal / r, -1.0)) if chordal < r else math.pi / 2
        n = max(2, math.ceil(abs(self.sweep) / max(step, tol.gcode.step_floor)))
        a0 = math.atan2(self.start[1] - self.center[1], self.start[0] - self.center[0])
        a = a0 + np.linspace(0, self.sweep, n + 1)
        return np.stack([self.center[0] + r * np.cos(a), self.center[1] + r * np.sin(a)], 1)


@dataclass
class Toolpath:
    """Interpreted program: beam-centre moves and what the run takes."""

    segments: list[Segment]
    pulse_period_us: float | None
    pulse_on_us: float | None
    time_base: str
    warnings: list[str] = field(default_factory=list)
    rapid_speed: float = 10.0
    #: ``(seconds, beam on, source line)`` of every dwell executed (G4 P, DWELL)
    dwells: list[tuple[float, bool, int]] = field(default_factory=list)
    #: statements that moved nothing (one record per source statement: line,
    #: statement, kind, effect, times executed), in order of first execution
    no_motion: list[dict] = field(default_factory=list)
    #: last value written to each system variable or output (``$DO[0].X`` …)
    io: dict[str, float] = field(default_factory=dict)
    #: string variables at the end of the run (name without ``$`` → text)
    strings: dict[str, str] = field(default_factory=dict)

    def summary(self) -> dict:
        """Path length, beam-on length (mm), estimated time (s) from the
        feeds (rapids at ``rapid_speed`` mm/s, C moves at their E feed) plus
        the dwells (a dwell with the beam on counts as beam-on time), and the
        pulse count from the repetition rate."""
        path = sum(s.path_length for s in self.segments)
        on = sum(s.path_length for s in self.segments if s.beam)
        t_dwell = sum(d for d, _, _ in self.dwells)
        t = t_dwell
        t_on = sum(d for d, beam, _ in self.dwells if beam)
        for s in self.segments:
            dt = s.path_length / (s.feed if s.feed else self.rapid_speed)
            if s.c1 != s.c0 and s.rotary_feed:
                dt = max(dt, abs(s.c1 - s.c0) / s.rotary_feed)
            t += dt
            if s.beam:
                t_on += dt
        pulses = None
        if self.pulse_period_us:
            pulses = int(round(t_on / (self.pulse_period_us * 1e-6)))
        cs = sorted({round(s.c0, 9) for s in self.segments if s.beam})
        return {"segments": len(self.segments), "path_length_mm": path,
                "beam_on_length_mm": on, "time_s": t, "beam_on_time_s": t_on,
                "pulse_period_us": self.pulse_period_us,
                "repetition_rate_khz": (1e3 / self.pulse_period_us
                                        if self.pulse_period_us else None),
                "pulses": pulses, "c_angles_with_beam_deg": cs,
                "dwells": len(self.dwells), "dwell_time_s": t_dwell,
                "no_motion_statements": len(self.no_motion),
                "warnings": len(self.warnings)}


# ---------------------------------------------------------------------------------------------
_AXES = ("X", "Y", "Z", "C")
_MOTION = {0: "rapid", 1: "line", 2: "cw", 3: "ccw"}


@dataclass
class _State:
    pos: dict = field(default_factory=lambda: {"X": 0.0, "Y": 0.0, "Z": 0.0, "C": 0.0})
    offset: dict = field(default_factory=lambda: {"X": 0.0, "Y": 0.0, "Z": 0.0, "C": 0.0})
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
    warnings: list | None = None


def interpret(program: ast.Program, *, tool_radii: dict[int, float] | None = None,
              limits: Limits = Limits(), rapid_speed: float = 10.0,
              default_feed: float | None = None) -> Toolpath:
    """Run ``program`` and return its :class:`Toolpath`.

    Parameters
    ----------
    program : gcode.ast.Program
    tool_radii : {tool number: radius mm} — the tool table (default T0 = 0,
        T1 = 0.010 mm: the 20 µm beam of the thesis's laser); numbers whole
        and ≥ 0, radii finite and ≥ 0
    limits : Limits — loop, statement, operation and move bounds (GCodeError
        beyond)
    rapid_speed : float — mm/s used to time G0 moves, finite and > 0
    default_feed : float, optional — mm/s for a feed move (G01–G03) before
        any F: the move runs at it with a warning naming the line (and it
        stays the modal feed until an F); None (default): such a move is an
        error. A feed move after an F always uses the last F (modal).

    Raises
    ------
    GCodeError
        A program that cannot run (located at its statement): a feed move
        before any F, a zero-radius arc or one whose end is off its circle,
        a bad word value, a position out of range, a bound of ``limits``
        exceeded …
    TypeError, ValueError
        Bad ``tool_radii``, ``limits`` or ``rapid_speed``.
    """
    if not isinstance(limits, Limits):
        raise TypeError(f"limits must be a gcode.Limits, not {type(limits).__name__}")
    tools = {0: 0.0, 1: 0.010} if tool_radii is None else _tool_table(tool_radii)
    if isinstance(rapid_speed, bool) or not isinstance(rapid_speed, (int, float)) \
            or not (math.isfinite(rapid_speed) and rapid_speed > 0):
        raise ValueError(f"rapid_speed must be a finite number > 0 (mm/s), not {rapid_speed!r}")
    if default_feed is not None and (isinstance(default_feed, bool) or not isinstance(
            default_feed, (int, float)) or not (math.isfinite(default_feed) and default_feed > 0)):
        raise ValueError(f"default_feed must be a finite number > 0 (mm/s), not {default_feed!r}")
    st = _State()
    vars_: dict[str, float] = {}
    declared: set[str] = set()
    raw: list[dict] = []          # programmed moves, compensation applied afterwards
    warnings: list[str] = list(program.warnings)
    st.default_feed, st.warnings = default_feed, warnings
    max_statements, max_ops = limits.max_statements, limits.max_operations
    executed = 0                  # statements
    ops = 0                       # operations (see Limits.max_operations)
    weights: dict[int, int] = {}  # id(statement) -> its operations (the tree outlives the run)
    subs = {sub.name: sub for sub in program.subroutines}
    dwells: list[tuple[float, bool, int]] = []
    notes: dict[tuple[int, int], dict] = {}
    io: dict[str, float] = {}
    strings: dict[str, str] = {}
    depth = 0                     # subroutine calls in progress

    def note(span: ast.Span, kind: str, effect: str) -> None:
        rec = notes.get((span.line, span.col))
        if rec is None:
            rec = notes[(span.line, span.col)] = {"line": span.line, "statement": span.text,
                                                  "kind": kind, "effect": effect, "executed": 0}
        rec["effect"] = effect
        rec["executed"] += 1

    def dwell(seconds: float, span: ast.Span) -> None:
        if not seconds >= 0:
            raise err(f"dwell time {seconds:g} s: must be ≥ 0", span)
        dwells.append((seconds, st.laser, span.line))
        if len(raw) + len(dwells) > limits.max_segments:
            raise err(f"more than {limits.max_segments} moves and dwells "
                      f"(max_segments = {limits.max_segments})", span)

    def count_one(s) -> None:
        """Charge one more execution of ``s``'s header (a WHILE test)."""
        nonlocal executed, ops
        executed += 1
        if executed > max_statements:
            raise err(f"more than {max_statements} statements executed "
                      f"(max_statements = {max_statements}; runaway loop?)", s.span)
        ops += weight(s)
        if ops > max_ops:
            raise err(f"more than {max_ops} operations executed "
                      f"(max_operations = {max_ops}; runaway loop?)", s.span)

    def err(msg, span: ast.Span):
        return GCodeError(msg, span.line, span.col, span.text)

    def ev(expr, span):
        return evaluate(expr, vars_, span=span)

    def weight(s) -> int:
        w = weights.get(id(s))
        if w is None:
            w = weights[id(s)] = _weight(s)
        return w

    def run(body):
        nonlocal executed, ops, depth
        for s in body:
            executed += 1
            if executed > max_statements:
                raise err(f"more than {max_statements} statements executed "
                          f"(max_statements = {max_statements}; runaway loop?)", s.span)
            w = weights.get(id(s))
            if w is None:
                w = weights[id(s)] = _weight(s)
            ops += w
            if ops > max_ops:
                raise err(f"more than {max_ops} operations executed "
                          f"(max_operations = {max_ops}; runaway loop?)", s.span)
            if isinstance(s, ast.Block):
                _block(st, s, ev, err, raw, tools, note, dwell)
                if len(raw) + len(dwells) > limits.max_segments:
                    raise err(f"more than {limits.max_segments} moves "
                              f"(max_segments = {limits.max_segments})", s.span)
            elif isinstance(s, ast.Assign):
                vars_[s.name] = ev(s.expr, s.span)
            elif isinstance(s, ast.Pso):
                _pso(st, s, ev, err)
            elif isinstance(s, ast.Mode):
                _mode(st, s, err)
            elif isinstance(s, ast.Repeat):
                n = ev(s.count, s.span)
                k = round(n)
                if abs(n - k) > tol.gcode.whole * max(1.0, abs(n)) or k < 0:
                    raise err(f"REPEAT count {n:.12g} is not a whole number ≥ 0", s.span)
                if k > limits.max_repeat:
                    raise err(f"REPEAT count {k} exceeds max_repeat = {limits.max_repeat}",
                              s.span)
                if not s.body or k == 0:
                    continue          # nothing to run: no empty loop of a billion passes
                # each pass executes every statement of the body at least once
                if k * len(s.body) > max_statements - executed:
                    raise err(f"REPEAT {k} × {len(s.body)} statements would execute more than "
                              f"{max_statements} statements (max_statements = "
                              f"{max_statements}; runaway loop?)", s.span)
                per_pass = sum(weight(b) for b in s.body)
                if k * per_pass > max_ops - ops:
                    raise err(f"REPEAT {k} × {per_pass} operations would execute more than "
                              f"{max_ops} operations (max_operations = {max_ops}; "
                              "runaway loop?)", s.span)
                for _ in range(k):
                    run(s.body)
            elif isinstance(s, ast.For):
                start, end = ev(s.start, s.span), ev(s.end, s.span)
                step = 1.0 if s.step is None else ev(s.step, s.span)
                k = _for_passes(start, end, step, s, err)
                if k > limits.max_repeat:
                    raise err(f"FOR runs {k} passes, more than max_repeat = {limits.max_repeat}",
                              s.span)
                for i in range(k):
                    vars_[s.var] = start + i * step
                    run(s.body)
                    count_one(s)
            elif isinstance(s, ast.StatusRead):
                vars_.pop(s.name, None)
                strings.pop(s.name, None)
                note(s.span, "STATUS", f"reads {s.function} into ${s.name}: a value known only "
                     "on the machine (using it later is an error)")
            elif isinstance(s, ast.StringAssign):
                value = evaluate_string(s.parts, vars_, strings, s.span)
                if isinstance(value, str):
                    strings[s.name] = value
                    vars_.pop(s.name, None)
                    note(s.span, "STRING", f"sets the string ${s.name} = {value[:60]!r}")
                else:
                    vars_[s.name] = value
                    strings.pop(s.name, None)
                    note(s.span, "STRING", f"sets ${s.name} = {value:.12g} (string function)")
            elif isinstance(s, ast.DVar):
                for n in s.names:
                    declared.add(n)
                    vars_.setdefault(n, 0.0)
            elif isinstance(s, ast.While):
                while ev(s.cond, s.span) != 0.0:
                    run(s.body)
                    count_one(s)
            elif isinstance(s, ast.If):
                for i, (cond, body) in enumerate(s.branches):
                    if i and cond is not None:
                        ops += _size(cond)
                    if cond is None or ev(cond, s.span) != 0.0:
                        run(body)
                        break
            elif isinstance(s, ast.Call):
                sub = subs.get(s.name)
                if sub is None:
                    have = ", ".join(sorted(subs)) or "none"
                    raise err(f"CALL {s.name}: no subroutine DFS {s.name} in this program "
                              f"(have {have})", s.span)
                if depth >= MAX_CALL_DEPTH:
                    raise err(f"subroutine calls nested deeper than {MAX_CALL_DEPTH} "
                              "(MAX_CALL_DEPTH; endless recursion?)", s.span)
                values = [(letter.lower(), ev(v, s.span)) for letter, v in s.args]
                saved = [(name, vars_.get(name)) for name, _ in values]
                vars_.update(values)
                depth += 1
                try:
                    run(sub.body)
                finally:
                    depth -= 1
                    for name, old in saved:
                        if old is None:
                            vars_.pop(name, None)
                        else:
                            vars_[name] = old
            elif isinstance(s, ast.Dwell):
                dwell(ev(s.seconds, s.span), s.span)
            elif isinstance(s, ast.SysAssign):
                key = _io_key(s, ev)
                if key not in io and len(io) >= MAX_IO_NAMES:
                    raise err(f"more than {MAX_IO_NAMES} different outputs and system "
                              "variables written (MAX_IO_NAMES)", s.span)
                io[key] = ev(s.expr, s.span)
                note(s.span, "I/O" if _IO.match(s.name) else "system variable",
                     f"sets {key} = {io[key]:.12g}")
            elif isinstance(s, ast.NoMotion):
                note(s.span, s.keyword, s.what)
            else:  # pragma: no cover - parser guarantees the node types
                raise GCodeError(f"unknown statement {type(s).__name__}")

    try:
        run(program.body)
    except _EndOfProgram:
        pass
    segments = _compensate(raw, warnings)
    return Toolpath(segments, st.period_us, st.on_us,
                    "seconds" if st.time_per_unit == 1.0 else "minutes", warnings, rapid_speed,
                    dwells, list(notes.values()), io, strings)


def _io_key(s: ast.SysAssign, ev) -> str:
    """``$DO[0].X``-style name of a system variable assignment, indices evaluated."""
    parts = [f"${s.name.upper()}"]
    for part in s.index:
        if isinstance(part, str):
            parts.append(part if part.startswith(".") else f".{part}")
        else:
            parts.append(f"[{ev(part, s.span):.12g}]")
    return "".join(parts)


def _for_passes(start: float, end: float, step: float, s, err) -> int:
    """Passes of ``FOR $v = start TO end STEP step`` (0 if it never starts)."""
    if step == 0.0:
        raise err("FOR … STEP 0 never ends", s.span)
    n = (end - start) / step
    if n < 0:
        return 0
    return int(math.floor(n + tol.gcode.whole * max(1.0, abs(n)))) + 1


def _tool_table(tool_radii) -> dict[int, float]:
    """Validated copy of a tool table {tool number: radius mm}."""
    try:
        items = list(dict(tool_radii).items())
    except (TypeError, ValueError):
        raise TypeError(f"tool_radii must map tool numbers to radii, not {tool_radii!r}") from None
    tools: dict[int, float] = {}
    for k, r in items:
        try:
            t = operator.index(k)
        except TypeError:
            t = None
        if t is None or isinstance(k, bool) or t < 0:
            raise ValueError(f"tool_radii: tool number {k!r} must be a whole number ≥ 0")
        try:
            radius = float(r)
        except (TypeError, ValueError):
            radius = math.nan
        if isinstance(r, bool) or not (math.isfinite(radius) and radius >= 0):
            raise ValueError(f"tool_radii: the radius of T{t}, {r!r}, must be a finite number "
                             "≥ 0 (mm)")
        tools[t] = radius
    return tools


def _size(expr) -> int:
    """Number of nodes of an expression tree."""
    n = 0
    stack = [expr]
    while stack:
        node = stack.pop()
        n += 1
        if isinstance(node, (ast.Neg, ast.Not)):
            stack.append(node.operand)
        elif isinstance(node, (ast.BinOp, ast.Compare, ast.Logic)):
            stack.append(node.left)
            stack.append(node.right)
    return n


def _weight(s) -> int:
    """Operations one execution of statement ``s`` costs (see Limits)."""
    if isinstance(s, ast.Repeat):
        return _size(s.count)
    if isinstance(s, ast.For):
        return _size(s.start) + _size(s.end) + (_size(s.step) if s.step is not None else 0)
    if isinstance(s, ast.Assign):
        return _size(s.expr)
    if isinstance(s, ast.Block):
        return len(s.words) + len(s.keywords) + sum(
            _size(w.value) for w in s.words if w.value is not None)
    if isinstance(s, ast.Pso):
        return sum(1 if isinstance(a, str) else _size(a) for a in s.args)
    if isinstance(s, ast.DVar):
        return len(s.names)
    if isinstance(s, ast.Mode):
        return len(s.args)
    if isinstance(s, ast.While):
        return _size(s.cond)
    if isinstance(s, ast.If):
        return _size(s.branches[0][0])
    if isinstance(s, ast.Call):
        return 1 + sum(_size(v) for _, v in s.args)
    if isinstance(s, ast.Dwell):
        return _size(s.seconds)
    if isinstance(s, ast.SysAssign):
        return _size(s.expr) + sum(1 if isinstance(i, str) else _size(i) for i in s.index)
    return 1  # NoMotion


class _EndOfProgram(Exception):
    """``END``, ``END PROGRAM``, ``M2`` or ``M30``: nothing after it runs."""


def _mode(st: _State, s: ast.Mode, err) -> None:
    k = s.keyword
    if k == "SECONDS":
        st.time_per_unit = 1.0
    elif k == "MINUTES":
        st.time_per_unit = 60.0
    elif k == "METRIC":
        st.scale = 1.0
    elif k == "ENGLISH":
        st.scale = 25.4
    elif k == "ABSOLUTE":
        st.absolute = True
    elif k == "INCREMENTAL":
        st.absolute = False
    elif k == "END":
        raise _EndOfProgram
    elif k == "ENABLE":
        pass
    else:
        raise err(f"keyword {k} is not supported", s.span)


def _pso(st: _State, s: ast.Pso, ev, err) -> None:
    args = list(s.args)
    if s.command == "PSOCONTROL":
        words = [a for a in args if isinstance(a, str)]
        if "FIRE" in words or "ON" in words or "ARM" in words:
            st.laser = True       # ARM: pulses on distance events while moving — beam on
        elif "OFF" in words or "RESET" in words:
            st.laser = False
        else:
            raise err("PSOCONTROL needs FIRE, ON, ARM, OFF or RESET", s.span)
    elif s.command == "PSOPULSE":
        if "TIME" in args:
            i = args.index("TIME")
            nums = [a for a in args[i + 1:i + 3] if not isinstance(a, str)]
            if len(nums) != 2:
                raise err("PSOPULSE TIME needs a period and an on time (µs)", s.span)
            period, on = ev(nums[0], s.span), ev(nums[1], s.span)
            if not (period > 0 and 0 < on <= period):
                raise err(f"PSOPULSE TIME {period:g} {on:g}: need period > 0 and "
                          "0 < on ≤ period (µs)", s.span)
            st.period_us, st.on_us = period, on
        if "CYCLES" in args:
            i = args.index("CYCLES")
            if i + 1 >= len(args) or isinstance(args[i + 1], str):
                raise err("PSOPULSE CYCLES needs a pulse count", s.span)
            n = ev(args[i + 1], s.span)
            if n != int(n) or n < 1:
                raise err(f"PSOPULSE CYCLES {n:g}: the pulse count must be a whole number ≥ 1",
                          s.span)
    # other PSO commands configure the output and do not change the path


def _block(st: _State, b: ast.Block, ev, err, raw, tools, note, dwell) -> None:
    target: dict[str, float] = {}
    center: dict[str, float] = {}
    g92 = False
    g4 = False
    g84 = False
    f_word = None
    p_word = None
    comp_change = None
    for kw in b.keywords:
        st.motion = {"RAPID": "rapid", "LINEAR": "line", "CW": "cw", "CCW": "ccw"}[kw]
    for w in b.words:
        if w.letter == "N":
            continue
        if w.letter == "G":
            code = ev(w.value, b.span) if w.value is not None else None
            if code is None or code != int(code):
                raise err("G needs a whole number", w.span)
            code = int(code)
            if code in _MOTION:
                st.motion = _MOTION[code]
            elif code in (40, 41, 42):
                comp_change = {40: 0, 41: 1, 42: -1}[code]
            elif code == 90:
                st.absolute = True
            elif code == 91:
                st.absolute = False
            elif code == 92:
                g92 = True
            elif code in (17, 44, 98):
                pass  # the XY plane (the only one) / compensation axes / as in Appendix C
            elif code == 4:
                g4 = True
            elif code == 84:
                g84 = True
            elif code in (70, 71):
                st.scale = 25.4 if code == 70 else 1.0
            elif code in (75, 76):
                st.time_per_unit = 60.0 if code == 75 else 1.0
            elif code in G_NO_MOTION:
                note(w.span, f"G{code}", G_NO_MOTION[code])
            else:
                raise err(f"G{code} is not supported", w.span)
            continue
        if w.value is None:
            continue  # bare axis names (G44 X Y)
        val = ev(w.value, w.span)
        if w.letter in _AXES:
            target[w.letter] = val * (st.scale if w.letter != "C" else 1.0)
        elif w.letter in "IJK":
            center[w.letter] = val * st.scale
        elif w.letter == "F":
            f_word = (val, w.span)
        elif w.letter == "E":
            if not val > 0:
                raise err(f"E{val:g}: the rotary feed rate E must be > 0 (degrees per time "
                          "unit)", w.span)
            st.rotary_feed = val
        elif w.letter == "T":
            if val != int(val) or val < 0:
                raise err(f"T{val:g}: the tool number T must be a whole number ≥ 0", w.span)
            t = int(val)
            if t not in tools:
                raise err(f"T{t}: no such tool in the tool table (have "
                          f"{', '.join(f'T{k}' for k in sorted(tools))})", w.span)
            st.tool = t
        elif w.letter == "P":
            p_word = (val, w.span)
        elif w.letter in "AB":
            continue
        else:
            raise err(f"word {w.letter} is not supported", w.span)
    if g84:      # G84 X Y F<deg>: the program's XY frame turns (no F: back to 0)
        if target or center:
            raise err("G84 turns the XY frame: give only the axis names and F, the angle (deg)",
                      b.span)
        st.rotation = math.radians(f_word[0]) if f_word is not None else 0.0
        return
    if f_word is not None:
        if not f_word[0] > 0:
            raise err(f"F{f_word[0]:g}: the feed rate F must be > 0 (length per time unit)",
                      f_word[1])
        st.feed = f_word[0] * st.scale
    if g4 or p_word is not None:
        if not g4:
            raise err("P is the dwell time of G4 (s): give G4 in the same block", p_word[1])
        if p_word is None:
            raise err("G4 needs P, the dwell time (s)", b.span)
        if target or center:
            raise err("G4 dwells and moves nothing: no axis words in its block", b.span)
        dwell(p_word[0], b.span)
        return
    if g92:  # preset: the current position takes the given values
        for a, v in target.items():
            _check_position(a, v, b.span, err)
            st.offset[a] = st.pos[a] + st.offset[a] - v
            st.pos[a] = v
        return
    if comp_change is not None and not target:
        st.comp = comp_change
        return
    if not target and not center:
        return
    new = dict(st.pos)
    for a, v in target.items():
        new[a] = v if st.absolute else st.pos[a] + v
    if st.rotation and ("X" in target or "Y" in target):
        _rotate_target(st, target, new)
    for a in target:
        _check_position(a, new[a], b.span, err)
    motion = st.motion
    if motion != "rapid" and st.feed is None:
        how = {"line": "G01/LINEAR", "cw": "G02/CW", "ccw": "G03/CCW"}[motion]
        if st.default_feed is not None:
            st.feed = st.default_feed * st.time_per_unit
            st.warnings.append(f"line {b.span.line}: a {how} move before any F: the default "
                               f"feed {st.default_feed:g} mm/s is used until an F is given")
    if motion != "rapid" and st.feed is None:
        raise err(f"a {how} move needs a feed rate, but no feed rate (F) has been programmed "
                  "yet: give F (> 0) in this block or before it", b.span)
    if st.tool not in tools:
        raise err(f"T{st.tool}, the current tool, is not in the tool table (have "
                  f"{', '.join(f'T{k}' for k in sorted(tools)) or 'none'})", b.span)
    move = {"kind": "rapid" if motion == "rapid" else ("arc" if motion in ("cw", "ccw")
                                                        else "line"),
            "start": (st.pos["X"], st.pos["Y"]), "end": (new["X"], new["Y"]),
            "c0": st.pos["C"], "c1": new["C"], "beam": st.laser,
            "z0": st.pos["Z"], "z1": new["Z"],
            "feed": None if motion == "rapid" else st.feed / st.time_per_unit,
            "rotary_feed": None if st.rotary_feed is None else st.rotary_feed / st.time_per_unit,
            "line": b.span.line, "span": b.span,
            "tool_r": tools[st.tool],
            "comp_before": st.comp}
    if move["kind"] == "arc":
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
        ccw = motion == "ccw"
        side = st.comp if comp_change is None or comp_change == st.comp else 0
        tool_r = tools[st.tool]
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
    if comp_change is not None:
        st.comp = comp_change
    move["comp_after"] = st.comp
    raw.append(move)
    st.pos = new


def _rotate_target(st: _State, target: dict, new: dict) -> None:
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


def _check_position(axis: str, value: float, span: ast.Span, err) -> None:
    if axis == "C":
        if not abs(value) <= MAX_ANGLE_DEG:
            raise err(f"C position {value:.6g}° is beyond ±{MAX_ANGLE_DEG:g}° (MAX_ANGLE_DEG)",
                      span)
    elif not abs(value) <= MAX_POSITION_MM:
        raise err(f"{axis} position {value:.6g} mm is beyond ±{MAX_POSITION_MM:g} mm "
                  "(MAX_POSITION_MM)", span)


# -- cutter compensation --------------------------------------------------------------------------
def _unit(v):
    n = math.hypot(*v)
    return (v[0] / n, v[1] / n) if n > 0 else (0.0, 0.0)


def _left(d):
    return (-d[1], d[0])


def _offset(move, side: int, r_t: float, warnings: list[str]):
    """The move offset by r_t to ``side`` (+1 left, −1 right) of travel."""
    s, e = move["start"], move["end"]
    if move["kind"] != "arc":
        d = _unit((e[0] - s[0], e[1] - s[1]))
        n = _left(d)
        o = (side * r_t * n[0], side * r_t * n[1])
        return dict(move, start=(s[0] + o[0], s[1] + o[1]), end=(e[0] + o[0], e[1] + o[1]))
    c = move["center"]
    r = math.dist(s, c)
    # left of a CCW arc is towards the centre
    towards = side * (1 if move["ccw"] else -1)
    rn = r - towards * r_t
    if rn <= tol.gcode.length:
        warnings.append(f"line {move['line']}: arc radius {r:.6g} mm is not larger than the "
                        f"tool radius {r_t:.6g} mm; the compensated path collapses to its centre")
        rn = 0.0

    def at(p):
        u = _unit((p[0] - c[0], p[1] - c[1]))
        return (c[0] + rn * u[0], c[1] + rn * u[1])
    out = dict(move, start=at(s), end=at(e))
    if rn == 0.0:
        out["kind"] = "point"
    return out


def _intersect(a, b, corner):
    """Intersection of offset elements a, b (lines or circles) nearest the
    programmed corner, or None."""
    def as_geo(m):
        if m["kind"] == "arc":
            return ("c", m["center"], math.dist(m["start"], m["center"]))
        return ("l", m["start"], _unit((m["end"][0] - m["start"][0],
                                        m["end"][1] - m["start"][1])))
    ga, gb = as_geo(a), as_geo(b)
    pts = []
    if ga[0] == "l" and gb[0] == "l":
        p, d = ga[1], ga[2]
        q, e = gb[1], gb[2]
        den = d[0] * e[1] - d[1] * e[0]
        if abs(den) > tol.gcode.parallel:
            t = ((q[0] - p[0]) * e[1] - (q[1] - p[1]) * e[0]) / den
            pts.append((p[0] + t * d[0], p[1] + t * d[1]))
    else:
        if ga[0] == "c" and gb[0] == "c":
            (c0, r0), (c1, r1) = (ga[1], ga[2]), (gb[1], gb[2])
            dd = math.dist(c0, c1)
            if tol.gcode.length < dd <= r0 + r1 and dd >= abs(r0 - r1):
                a_ = (r0 * r0 - r1 * r1 + dd * dd) / (2 * dd)
                h = math.sqrt(max(r0 * r0 - a_ * a_, 0.0))
                ex = ((c1[0] - c0[0]) / dd, (c1[1] - c0[1]) / dd)
                m = (c0[0] + a_ * ex[0], c0[1] + a_ * ex[1])
                pts += [(m[0] - h * ex[1], m[1] + h * ex[0]), (m[0] + h * ex[1], m[1] - h * ex[0])]
        else:
            line, circ = (ga, gb) if ga[0] == "l" else (gb, ga)
            p, d = line[1], line[2]
            c, r = circ[1], circ[2]
            f = (p[0] - c[0], p[1] - c[1])
            bq = f[0] * d[0] + f[1] * d[1]
            cq = f[0] ** 2 + f[1] ** 2 - r * r
            disc = bq * bq - cq
            if disc >= 0:
                for sgn in (-1, 1):
                    t = -bq + sgn * math.sqrt(disc)
                    pts.append((p[0] + t * d[0], p[1] + t * d[1]))
    if not pts:
        return None
    return min(pts, key=lambda q: math.dist(q, corner))


def _compensate(raw: list[dict], warnings: list[str]) -> list[Segment]:
    """Apply cutter compensation to the programmed moves."""
    out: list[dict] = []
    n = len(raw)
    offs = [None] * n
    for i, m in enumerate(raw):
        side = m["comp_after"] if m["comp_before"] == m["comp_after"] else 0
        if side and m["tool_r"] > 0 and m["kind"] != "rapid":
            offs[i] = _offset(m, side, m["tool_r"], warnings)
    for i, m in enumerate(raw):
        if offs[i] is not None:
            cur = dict(offs[i])
            prev = offs[i - 1] if i > 0 else None
            if prev is not None and out:
                # join with the previous compensated element
                p_end = out[-1]["end"]
                if math.dist(p_end, cur["start"]) > tol.gcode.point:
                    q = _intersect(out[-1], cur, m["start"]) if (
                        out[-1]["kind"] != "point" and cur["kind"] != "point") else None
                    if q is not None and \
                            math.dist(q, m["start"]) <= 2 * m["tool_r"] + tol.gcode.point:
                        out[-1] = _trim_end(out[-1], q)
                        cur = _trim_start(cur, q)
                    else:  # convex corner: round it about the programmed point
                        side = m["comp_after"]
                        out.append(dict(m, kind="arc", start=p_end, end=cur["start"],
                                        center=m["start"], ccw=(side < 0), z1=m["z0"]))
            out.append(cur)
            continue
        mm = dict(m)
        # ramps: switching compensation on (off) starts (ends) at the offset
        if m["comp_before"] != m["comp_after"] and m["comp_after"] and i + 1 < n \
                and offs[i + 1] is not None:
            mm["end"] = offs[i + 1]["start"]
            if mm["kind"] == "arc":
                mm["kind"] = "line"
        if m["comp_before"] and not m["comp_after"] and out:
            mm["start"] = out[-1]["end"]
        elif out and math.dist(out[-1]["end"], mm["start"]) > tol.gcode.point and \
                out[-1].get("comp_after") and m["kind"] != "rapid":
            mm["start"] = out[-1]["end"]
        out.append(mm)
    segs = []
    for m in out:
        kind = m["kind"]
        if kind == "point":
            kind = "line"
            m = dict(m, start=m["center"], end=m["center"], center=None)
        segs.append(Segment(kind, tuple(m["start"]), tuple(m["end"]), bool(m["beam"]),
                            float(m["c0"]), float(m["c1"]), m["feed"], int(m["line"]),
                            tuple(m["center"]) if kind == "arc" else None,
                            bool(m.get("ccw", True)), m.get("rotary_feed"),
                            float(m.get("z0", 0.0)), float(m.get("z1", 0.0))))
    return segs


def _trim_end(m, q):
    return dict(m, end=q)


def _trim_start(m, q):
    return dict(m, start=q)
