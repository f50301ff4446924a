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
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import TypedDict, TypeVar, cast

from tipgeo.tolerances import tol

from . import ast
from .errors import GCodeError, check_limit
from .expr import evaluate
from .motion import (
    ARC_TOLERANCE,
    MAX_ANGLE_DEG,
    MAX_POSITION_MM,
    BlockContext,
    Evaluate,
    MachineState,
    Move,
    Segment,
    apply_block,
    compensate,
)
from .parser import IO_NAME as _IO
from .parser import MAX_NESTING
from .strings import evaluate_string

__all__ = ["Segment", "Toolpath", "interpret", "Limits", "NoMotionRecord", "ARC_TOLERANCE",
           "MAX_POSITION_MM", "MAX_ANGLE_DEG", "MAX_CALL_DEPTH", "MAX_IO_NAMES"]

#: Deepest nesting of subroutine calls (CALL inside a DFS …).
MAX_CALL_DEPTH = MAX_NESTING
#: Most different outputs and system variables one run writes (``$DO[i].X`` for
#: 10 000 values of i), so that the record of their values stays small.
MAX_IO_NAMES = 10_000
#: Seconds per microsecond (PSOPULSE times are in µs).
S_PER_US = 1e-6


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

    def __post_init__(self) -> None:
        for f in fields(self):
            check_limit(f.name, getattr(self, f.name))


class NoMotionRecord(TypedDict):
    """A statement that moved nothing (:attr:`Toolpath.no_motion`): its source
    line and text, its kind (``VELOCITY``, ``I/O``, ``G359`` …), what it did
    (its last effect) and how many times it was executed."""

    line: int
    statement: str
    kind: str
    effect: str
    executed: int


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
    no_motion: list[NoMotionRecord] = field(default_factory=list)
    #: last value written to each system variable or output (``$DO[0].X`` …)
    io: dict[str, float] = field(default_factory=dict)
    #: string variables at the end of the run (name without ``$`` → text)
    strings: dict[str, str] = field(default_factory=dict)

    def summary(self) -> dict[str, object]:
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
            pulses = int(round(t_on / (self.pulse_period_us * S_PER_US)))
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
    run = _Run(program, tools, limits, default_feed)
    try:
        run.body(program.body)
    except _EndOfProgram:
        pass
    segments = compensate(run.raw, run.warnings)
    st = run.st
    return Toolpath(segments, st.period_us, st.on_us,
                    "seconds" if st.time_per_unit == 1.0 else "minutes", run.warnings,
                    rapid_speed, run.dwells, list(run.notes.values()), run.io, run.strings)


class _EndOfProgram(Exception):
    """``END``, ``END PROGRAM``, ``M2`` or ``M30``: nothing after it runs."""


class _Run:
    """One run of a program: the machine state, variables, records and the
    counts checked against :class:`Limits`. Each statement type has one
    method (:data:`_EXECUTE`); moves are applied by :mod:`gcode.motion`."""

    def __init__(self, program: ast.Program, tools: dict[int, float], limits: Limits,
                 default_feed: float | None):
        self.st = MachineState()
        self.tools, self.limits = tools, limits
        self.vars: dict[str, float] = {}
        self.strings: dict[str, str] = {}
        self.raw: list[Move] = []          # programmed moves, compensated afterwards
        self.warnings: list[str] = list(program.warnings)
        self.st.default_feed, self.st.warnings = default_feed, self.warnings
        self.executed = 0                  # statements
        self.ops = 0                       # operations (see Limits.max_operations)
        self.weights: dict[int, int] = {}  # id(statement) -> its operations
        self.subs = {sub.name: sub for sub in program.subroutines}
        self.dwells: list[tuple[float, bool, int]] = []
        self.notes: dict[tuple[int, int], NoMotionRecord] = {}
        self.io: dict[str, float] = {}
        self.depth = 0                     # subroutine calls in progress
        self.ctx = BlockContext(self.ev, _err, self.raw, tools, self.note, self.dwell)

    # -- services ---------------------------------------------------------------------
    def ev(self, expr: ast.Expr, span: ast.Span) -> float:
        return evaluate(expr, self.vars, span=span)

    def note(self, span: ast.Span, kind: str, effect: str) -> None:
        rec = self.notes.get((span.line, span.col))
        if rec is None:
            rec = self.notes[(span.line, span.col)] = {
                "line": span.line, "statement": span.text, "kind": kind, "effect": effect,
                "executed": 0}
        rec["effect"] = effect
        rec["executed"] += 1

    def dwell(self, seconds: float, span: ast.Span) -> None:
        if not seconds >= 0:
            raise _err(f"dwell time {seconds:g} s: must be ≥ 0", span)
        self.dwells.append((seconds, self.st.laser, span.line))
        self.check_moves(span, "moves and dwells")

    def check_moves(self, span: ast.Span, what: str = "moves") -> None:
        limit = self.limits.max_segments
        if len(self.raw) + len(self.dwells) > limit:
            raise _err(f"more than {limit} {what} (max_segments = {limit})", span)

    def weight(self, s: ast.Stmt) -> int:
        w = self.weights.get(id(s))
        if w is None:
            w = self.weights[id(s)] = _weight(s)
        return w

    def charge(self, s: ast.Stmt) -> None:
        """Count one execution of ``s`` (its header, for a loop) against the bounds."""
        self.executed += 1
        limit = self.limits.max_statements
        if self.executed > limit:
            raise _err(f"more than {limit} statements executed "
                       f"(max_statements = {limit}; runaway loop?)", s.span)
        self.ops += self.weight(s)
        limit = self.limits.max_operations
        if self.ops > limit:
            raise _err(f"more than {limit} operations executed "
                       f"(max_operations = {limit}; runaway loop?)", s.span)

    # -- statements ----------------------------------------------------------------------
    def body(self, statements: Iterable[ast.Stmt]) -> None:
        for s in statements:
            self.charge(s)
            handler = _EXECUTE.get(type(s))
            if handler is None:  # pragma: no cover - parser guarantees the node types
                raise GCodeError(f"unknown statement {type(s).__name__}")
            handler(self, s)

    def block(self, s: ast.Block) -> None:
        apply_block(self.st, s, self.ctx)
        self.check_moves(s.span)

    def assign(self, s: ast.Assign) -> None:
        self.vars[s.name] = self.ev(s.expr, s.span)

    def pso(self, s: ast.Pso) -> None:
        _pso(self.st, s, self.ev)

    def mode(self, s: ast.Mode) -> None:
        _mode(self.st, s)

    def repeat(self, s: ast.Repeat) -> None:
        k = _repeat_count(self.ev(s.count, s.span), s, self.limits.max_repeat)
        if not s.body or k == 0:
            return          # nothing to run: no empty loop of a billion passes
        limit = self.limits.max_statements
        # each pass executes every statement of the body at least once
        if k * len(s.body) > limit - self.executed:
            raise _err(f"REPEAT {k} × {len(s.body)} statements would execute more than "
                       f"{limit} statements (max_statements = {limit}; runaway loop?)", s.span)
        per_pass = sum(self.weight(b) for b in s.body)
        limit = self.limits.max_operations
        if k * per_pass > limit - self.ops:
            raise _err(f"REPEAT {k} × {per_pass} operations would execute more than "
                       f"{limit} operations (max_operations = {limit}; runaway loop?)", s.span)
        for _ in range(k):
            self.body(s.body)

    def for_loop(self, s: ast.For) -> None:
        start, end = self.ev(s.start, s.span), self.ev(s.end, s.span)
        step = 1.0 if s.step is None else self.ev(s.step, s.span)
        k = _for_passes(start, end, step, s)
        if k > self.limits.max_repeat:
            raise _err(f"FOR runs {k} passes, more than max_repeat = "
                       f"{self.limits.max_repeat}", s.span)
        for i in range(k):
            self.vars[s.var] = start + i * step
            self.body(s.body)
            self.charge(s)

    def while_loop(self, s: ast.While) -> None:
        while self.ev(s.cond, s.span) != 0.0:
            self.body(s.body)
            self.charge(s)

    def if_(self, s: ast.If) -> None:
        for i, (cond, body) in enumerate(s.branches):
            if i and cond is not None:
                self.ops += _size(cond)
            if cond is None or self.ev(cond, s.span) != 0.0:
                self.body(body)
                return

    def dvar(self, s: ast.DVar) -> None:
        for n in s.names:
            self.vars.setdefault(n, 0.0)

    def call(self, s: ast.Call) -> None:
        sub = self.subs.get(s.name)
        if sub is None:
            have = ", ".join(sorted(self.subs)) or "none"
            raise _err(f"CALL {s.name}: no subroutine DFS {s.name} in this program "
                       f"(have {have})", s.span)
        if self.depth >= MAX_CALL_DEPTH:
            raise _err(f"subroutine calls nested deeper than {MAX_CALL_DEPTH} "
                       "(MAX_CALL_DEPTH; endless recursion?)", s.span)
        values = [(letter.lower(), self.ev(v, s.span)) for letter, v in s.args]
        saved = [(name, self.vars.get(name)) for name, _ in values]
        self.vars.update(values)
        self.depth += 1
        try:
            self.body(sub.body)
        finally:
            self.depth -= 1
            for name, old in saved:
                if old is None:
                    self.vars.pop(name, None)
                else:
                    self.vars[name] = old

    def dwell_statement(self, s: ast.Dwell) -> None:
        self.dwell(self.ev(s.seconds, s.span), s.span)

    def sys_assign(self, s: ast.SysAssign) -> None:
        key = _io_key(s, self.ev)
        if key not in self.io and len(self.io) >= MAX_IO_NAMES:
            raise _err(f"more than {MAX_IO_NAMES} different outputs and system "
                       "variables written (MAX_IO_NAMES)", s.span)
        self.io[key] = self.ev(s.expr, s.span)
        self.note(s.span, "I/O" if _IO.match(s.name) else "system variable",
                  f"sets {key} = {self.io[key]:.12g}")

    def no_motion(self, s: ast.NoMotion) -> None:
        self.note(s.span, s.keyword, s.what)

    def status_read(self, s: ast.StatusRead) -> None:
        self.vars.pop(s.name, None)
        self.strings.pop(s.name, None)
        self.note(s.span, "STATUS", f"reads {s.function} into ${s.name}: a value known only "
                  "on the machine (using it later is an error)")

    def string_assign(self, s: ast.StringAssign) -> None:
        value = evaluate_string(s.parts, self.vars, self.strings, s.span)
        if isinstance(value, str):
            self.strings[s.name] = value
            self.vars.pop(s.name, None)
            self.note(s.span, "STRING", f"sets the string ${s.name} = {value[:60]!r}")
        else:
            self.vars[s.name] = value
            self.strings.pop(s.name, None)
            self.note(s.span, "STRING", f"sets ${s.name} = {value:.12g} (string function)")


_S = TypeVar("_S", bound=ast.Stmt)
_Execute = Callable[[_Run, ast.Stmt], None]


def _on(kind: type[_S], method: Callable[[_Run, _S], None]) -> tuple[type, _Execute]:
    """A row of :data:`_EXECUTE`. The table is looked up by a statement's exact
    type, so ``method`` is only ever given a ``kind``: the cast is safe."""
    return kind, cast(_Execute, method)


#: The method that executes each statement type.
_EXECUTE: dict[type, _Execute] = dict([
    _on(ast.Block, _Run.block), _on(ast.Assign, _Run.assign), _on(ast.Pso, _Run.pso),
    _on(ast.Mode, _Run.mode), _on(ast.Repeat, _Run.repeat), _on(ast.For, _Run.for_loop),
    _on(ast.While, _Run.while_loop), _on(ast.If, _Run.if_), _on(ast.DVar, _Run.dvar),
    _on(ast.Call, _Run.call), _on(ast.Dwell, _Run.dwell_statement),
    _on(ast.SysAssign, _Run.sys_assign), _on(ast.NoMotion, _Run.no_motion),
    _on(ast.StatusRead, _Run.status_read), _on(ast.StringAssign, _Run.string_assign)])


def _err(msg: str, span: ast.Span) -> GCodeError:
    return GCodeError(msg, span.line, span.col, span.text)


def _repeat_count(n: float, s: ast.Repeat, max_repeat: int) -> int:
    k = round(n)
    if abs(n - k) > tol.gcode.whole * max(1.0, abs(n)) or k < 0:
        raise _err(f"REPEAT count {n:.12g} is not a whole number ≥ 0", s.span)
    if k > max_repeat:
        raise _err(f"REPEAT count {k} exceeds max_repeat = {max_repeat}", s.span)
    return k


def _for_passes(start: float, end: float, step: float, s: ast.For) -> int:
    """Passes of ``FOR $v = start TO end STEP step`` (0 if it never starts)."""
    if step == 0.0:
        raise _err("FOR … STEP 0 never ends", s.span)
    n = (end - start) / step
    if n < 0:
        return 0
    return int(math.floor(n + tol.gcode.whole * max(1.0, abs(n)))) + 1


def _io_key(s: ast.SysAssign, ev: Evaluate) -> str:
    """``$DO[0].X``-style name of a system variable assignment, indices evaluated."""
    parts = [f"${s.name.upper()}"]
    for part in s.index:
        if isinstance(part, str):
            parts.append(part if part.startswith(".") else f".{part}")
        else:
            parts.append(f"[{ev(part, s.span):.12g}]")
    return "".join(parts)


def _tool_table(tool_radii: Mapping[int, float]) -> dict[int, float]:
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


def _size(expr: ast.Expr) -> int:
    """Number of nodes of an expression tree."""
    n = 0
    stack: list[ast.Expr] = [expr]
    while stack:
        node = stack.pop()
        n += 1
        if isinstance(node, (ast.Neg, ast.Not)):
            stack.append(node.operand)
        elif isinstance(node, (ast.BinOp, ast.Compare, ast.Logic)):
            stack.append(node.left)
            stack.append(node.right)
    return n


def _index_size(index: Iterable[ast.IndexPart]) -> int:
    return sum(1 if isinstance(i, str) else _size(i) for i in index)


#: Operations one execution of each statement type costs (see Limits).
_WEIGHTS = {
    ast.Repeat: lambda s: _size(s.count),
    ast.For: lambda s: _size(s.start) + _size(s.end) + (_size(s.step) if s.step else 0),
    ast.Assign: lambda s: _size(s.expr),
    ast.Block: lambda s: len(s.words) + len(s.keywords) + sum(
        _size(w.value) for w in s.words if w.value is not None),
    ast.Pso: lambda s: _index_size(s.args),
    ast.DVar: lambda s: len(s.names),
    ast.Mode: lambda s: len(s.args),
    ast.While: lambda s: _size(s.cond),
    ast.If: lambda s: _size(s.branches[0][0]),
    ast.Call: lambda s: 1 + sum(_size(v) for _, v in s.args),
    ast.Dwell: lambda s: _size(s.seconds),
    ast.SysAssign: lambda s: _size(s.expr) + _index_size(s.index),
}


def _weight(s: ast.Stmt) -> int:
    """Operations one execution of statement ``s`` costs (see Limits)."""
    f = _WEIGHTS.get(type(s))
    return 1 if f is None else f(s)   # NoMotion, StatusRead, StringAssign: 1


_MODES = {"SECONDS": ("time_per_unit", 1.0), "MINUTES": ("time_per_unit", 60.0),
          "METRIC": ("scale", 1.0), "ENGLISH": ("scale", 25.4),
          "ABSOLUTE": ("absolute", True), "INCREMENTAL": ("absolute", False)}


def _mode(st: MachineState, s: ast.Mode) -> None:
    k = s.keyword
    if k == "END":
        raise _EndOfProgram
    if k in _MODES:
        name, value = _MODES[k]
        setattr(st, name, value)
    elif k != "ENABLE":
        raise _err(f"keyword {k} is not supported", s.span)


def _pso(st: MachineState, s: ast.Pso, ev: Evaluate) -> None:
    args = list(s.args)
    if s.command == "PSOCONTROL":
        _pso_control(st, s, args)
    elif s.command == "PSOPULSE":
        if "TIME" in args:
            _pso_time(st, s, args, ev)
        if "CYCLES" in args:
            _pso_cycles(s, args, ev)
    # other PSO commands configure the output and do not change the path


def _pso_control(st: MachineState, s: ast.Pso, args: list[ast.PsoArg]) -> None:
    words = {a for a in args if isinstance(a, str)}
    if words & {"FIRE", "ON", "ARM"}:
        st.laser = True       # ARM: pulses on distance events while moving — beam on
    elif words & {"OFF", "RESET"}:
        st.laser = False
    else:
        raise _err("PSOCONTROL needs FIRE, ON, ARM, OFF or RESET", s.span)


def _pso_time(st: MachineState, s: ast.Pso, args: list[ast.PsoArg], ev: Evaluate) -> None:
    i = args.index("TIME")
    nums = [a for a in args[i + 1:i + 3] if not isinstance(a, str)]
    if len(nums) != 2:
        raise _err("PSOPULSE TIME needs a period and an on time (µs)", s.span)
    period, on = ev(nums[0], s.span), ev(nums[1], s.span)
    if not (period > 0 and 0 < on <= period):
        raise _err(f"PSOPULSE TIME {period:g} {on:g}: need period > 0 and "
                   "0 < on ≤ period (µs)", s.span)
    st.period_us, st.on_us = period, on


def _pso_cycles(s: ast.Pso, args: list[ast.PsoArg], ev: Evaluate) -> None:
    i = args.index("CYCLES")
    count = args[i + 1] if i + 1 < len(args) else None
    if count is None or isinstance(count, str):
        raise _err("PSOPULSE CYCLES needs a pulse count", s.span)
    n = ev(count, s.span)
    if n != int(n) or n < 1:
        raise _err(f"PSOPULSE CYCLES {n:g}: the pulse count must be a whole number ≥ 1",
                   s.span)
