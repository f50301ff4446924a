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
C angle, the laser (PSOCONTROL … FIRE/ON/OFF) and its pulse timing (PSOPULSE
… TIME period on CYCLES n, µs).

Cutter compensation offsets lines and arcs by the tool radius to the chosen
side of the travel direction; concave joints are trimmed to the offsets'
intersection, convex joints get a round corner about the programmed point;
the move that switches compensation on (off) ramps from (to) the
uncompensated point. An arc smaller than the tool collapses to its centre
(with a warning).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import ast
from .errors import GCodeError
from .expr import evaluate

__all__ = ["Segment", "Toolpath", "interpret", "Limits"]


@dataclass(frozen=True)
class Limits:
    """Bounds that keep a hostile program from hanging or exhausting memory."""

    max_repeat: int = 1_000_000
    max_statements: int = 20_000_000
    max_segments: int = 2_000_000


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
            if d < 1e-12:
                d = 2 * math.pi
        else:
            d = -((-d) % (2 * math.pi))
            if d > -1e-12:
                d = -2 * math.pi
        return d

    @property
    def length(self) -> float:
        """XY path length (mm)."""
        if self.kind == "arc":
            return abs(self.sweep) * self.radius
        return math.dist(self.start, self.end)

    def points(self, chordal: float = 1e-4) -> np.ndarray:
        """(k, 2) points along the move (arcs within ``chordal`` mm)."""
        if self.kind != "arc" or self.radius <= 0:
            return np.array([self.start, self.end], float)
        r = self.radius
        step = 2 * math.acos(max(1 - chordal / r, -1.0)) if chordal < r else math.pi / 2
        n = max(2, math.ceil(abs(self.sweep) / max(step, 1e-9)))
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

    def summary(self) -> dict:
        """Path length, beam-on length (mm), estimated time (s) from the
        feeds (rapids at ``rapid_speed`` mm/s, C moves at their E feed) and
        the pulse count from the repetition rate."""
        path = sum(s.length for s in self.segments)
        on = sum(s.length for s in self.segments if s.beam)
        t = 0.0
        t_on = 0.0
        for s in self.segments:
            dt = s.length / (s.feed if s.feed else self.rapid_speed)
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


def interpret(program: ast.Program, *, tool_radii: dict[int, float] | None = None,
              limits: Limits = Limits(), rapid_speed: float = 10.0) -> Toolpath:
    """Run ``program`` and return its :class:`Toolpath`.

    Parameters
    ----------
    program : gcode.ast.Program
    tool_radii : {tool number: radius mm} — the tool table (default T0 = 0,
        T1 = 0.010 mm: the 20 µm beam of the thesis's laser)
    limits : Limits — loop, statement and segment bounds (GCodeError beyond)
    rapid_speed : float — mm/s used to time G0 moves
    """
    tools = {0: 0.0, 1: 0.010} if tool_radii is None else dict(tool_radii)
    st = _State()
    vars_: dict[str, float] = {}
    declared: set[str] = set()
    raw: list[dict] = []          # programmed moves, compensation applied afterwards
    warnings: list[str] = list(program.warnings)
    count = [0]

    def err(msg, span: ast.Span):
        return GCodeError(msg, span.line, span.col, span.text)

    def ev(expr, span):
        return evaluate(expr, vars_, span=span)

    def run(body):
        for s in body:
            count[0] += 1
            if count[0] > limits.max_statements:
                raise err(f"more than {limits.max_statements} statements executed "
                          "(runaway loop?)", s.span)
            if isinstance(s, ast.Repeat):
                n = ev(s.count, s.span)
                k = round(n)
                if abs(n - k) > 1e-9 * max(1.0, abs(n)) or k < 0:
                    raise err(f"REPEAT count {n:.12g} is not a whole number ≥ 0", s.span)
                if k > limits.max_repeat:
                    raise err(f"REPEAT count {k} exceeds the limit {limits.max_repeat}",
                              s.span)
                for _ in range(int(k)):
                    run(s.body)
            elif isinstance(s, ast.Assign):
                vars_[s.name] = ev(s.expr, s.span)
            elif isinstance(s, ast.DVar):
                for n in s.names:
                    declared.add(n)
                    vars_.setdefault(n, 0.0)
            elif isinstance(s, ast.Mode):
                _mode(st, s, err)
            elif isinstance(s, ast.Pso):
                _pso(st, s, ev, err)
            elif isinstance(s, ast.Block):
                _block(st, s, ev, err, raw, tools)
                if len(raw) > limits.max_segments:
                    raise err(f"more than {limits.max_segments} moves", s.span)
            else:  # pragma: no cover - parser guarantees the node types
                raise GCodeError(f"unknown statement {type(s).__name__}")

    run(program.body)
    segments = _compensate(raw, warnings)
    return Toolpath(segments, st.period_us, st.on_us,
                    "seconds" if st.time_per_unit == 1.0 else "minutes", warnings, rapid_speed)


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
    elif k in ("ENABLE", "END"):
        pass
    else:
        raise err(f"keyword {k} is not supported", s.span)


def _pso(st: _State, s: ast.Pso, ev, err) -> None:
    args = list(s.args)
    if s.command == "PSOCONTROL":
        words = [a for a in args if isinstance(a, str)]
        if "FIRE" in words or "ON" in words:
            st.laser = True
        elif "OFF" in words or "RESET" in words:
            st.laser = False
        else:
            raise err("PSOCONTROL needs FIRE, ON, OFF or RESET", s.span)
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
    # other PSO commands configure the output and do not change the path


def _block(st: _State, b: ast.Block, ev, err, raw, tools) -> None:
    target: dict[str, float] = {}
    center: dict[str, float] = {}
    g92 = False
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
            elif code in (44, 98):
                pass  # axis selection for compensation / accepted as in Appendix C
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
            if not val > 0:
                raise err(f"F{val:g}: feed must be positive", w.span)
            st.feed = val * st.scale
        elif w.letter == "E":
            if not val > 0:
                raise err(f"E{val:g}: rotary feed must be positive", w.span)
            st.rotary_feed = val
        elif w.letter == "T":
            t = int(round(val))
            if t not in tools:
                raise err(f"T{t}: no such tool in the tool table (have "
                          f"{', '.join(f'T{k}' for k in sorted(tools))})", w.span)
            st.tool = t
        elif w.letter in "AB":
            continue
        else:
            raise err(f"word {w.letter} is not supported", w.span)
    if g92:  # preset: the current position takes the given values
        for a, v in target.items():
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
    motion = st.motion
    if motion in ("line", "cw", "ccw") and st.feed is None and any(
            new[a] != st.pos[a] for a in ("X", "Y", "Z")):
        raise err("a feed move before any F word", b.span)
    move = {"kind": "rapid" if motion == "rapid" else ("arc" if motion in ("cw", "ccw")
                                                        else "line"),
            "start": (st.pos["X"], st.pos["Y"]), "end": (new["X"], new["Y"]),
            "c0": st.pos["C"], "c1": new["C"], "beam": st.laser,
            "feed": None if motion == "rapid" else st.feed / st.time_per_unit,
            "rotary_feed": None if st.rotary_feed is None else st.rotary_feed / st.time_per_unit,
            "line": b.span.line, "span": b.span,
            "tool_r": tools[st.tool],
            "comp_before": st.comp}
    if move["kind"] == "arc":
        if "I" not in center and "J" not in center:
            raise err("arc without I or J (centre offset)", b.span)
        cx = st.pos["X"] + center.get("I", 0.0)
        cy = st.pos["Y"] + center.get("J", 0.0)
        r0 = math.dist((cx, cy), move["start"])
        r1 = math.dist((cx, cy), move["end"])
        if abs(r0 - r1) > 1e-6 * max(1.0, r0):
            raise err(f"arc end is {abs(r0 - r1) * 1e3:.4g} µm off its circle "
                      f"(radius {r0:.6g} vs {r1:.6g} mm)", b.span)
        move["center"] = (cx, cy)
        move["ccw"] = motion == "ccw"
    if comp_change is not None:
        st.comp = comp_change
    move["comp_after"] = st.comp
    raw.append(move)
    st.pos = new


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
    if rn <= 1e-12:
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
        if abs(den) > 1e-12:
            t = ((q[0] - p[0]) * e[1] - (q[1] - p[1]) * e[0]) / den
            pts.append((p[0] + t * d[0], p[1] + t * d[1]))
    else:
        if ga[0] == "c" and gb[0] == "c":
            (c0, r0), (c1, r1) = (ga[1], ga[2]), (gb[1], gb[2])
            dd = math.dist(c0, c1)
            if 1e-12 < dd <= r0 + r1 and dd >= abs(r0 - r1):
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
                if math.dist(p_end, cur["start"]) > 1e-9:
                    q = _intersect(out[-1], cur, m["start"]) if (
                        out[-1]["kind"] != "point" and cur["kind"] != "point") else None
                    if q is not None and math.dist(q, m["start"]) <= 2 * m["tool_r"] + 1e-9:
                        out[-1] = _trim_end(out[-1], q)
                        cur = _trim_start(cur, q)
                    else:  # convex corner: round it about the programmed point
                        side = m["comp_after"]
                        out.append(dict(m, kind="arc", start=p_end, end=cur["start"],
                                        center=m["start"], ccw=(side < 0)))
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
        elif out and math.dist(out[-1]["end"], mm["start"]) > 1e-9 and \
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
                            bool(m.get("ccw", True)), m.get("rotary_feed")))
    return segs


def _trim_end(m, q):
    return dict(m, end=q)


def _trim_start(m, q):
    return dict(m, start=q)
