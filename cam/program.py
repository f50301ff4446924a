"""Set-up (inverse kinematics) and grinding programs for a tip spec.

Frames, axes and machine zero: see :mod:`cam.machine`. Lengths mm, angles
deg in programs and reports (rad inside), feeds mm/s, speeds rpm, time s.

For every face of the spec (each plane of a bevel, multi-plane or lancet
cutter; the cone of a conical cutter) the set-up gives: r5 = ϕ_g = ξ + φ
(eq. 2.37), r4 = β + 180° (the face's heel direction turned away from the
wheel), t1 = −h (the face's height on the needle axis brought to the contact
point), H from the contact radius and OC from eq. 2.38. The program approaches
each face clear of the wheel, feeds along Z* to depth, and retracts; conical
faces are ground with the needle spinning.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gcode.dialects import DIALECTS, Dialect, number_lines
from gcode.dialects import dialect as get_dialect
from tipgeo.cutters import ConeSurface, Plane
from tipgeo.jsonio import dumps

from .iso import iso_comment, iso_end, iso_start
from .machine import CamError, Machine

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec

__all__ = ["Face", "GrindProgram", "setup_faces", "make_program", "COLUMNS"]

COLUMNS = ("t", "t1", "t2", "r3", "r4", "r5", "spindle_rpm", "needle_rpm", "feed")


@dataclass(frozen=True)
class Face:
    """One ground face: bevel angle ξ, heel direction β (rad), height h on
    the needle axis (mm), whether the needle spins (conical), its label."""

    label: str
    xi: float
    beta: float
    h: float
    spin: bool = False


def setup_faces(spec: TipSpec, machine: Machine | None = None) -> list[Face]:
    """The faces the grinder must make for ``spec`` (cannula frame): every
    analytic face of the cutters made by grinding (their
    :meth:`~tipgeo.cutters.base.Cutter.surfaces`) — planes ground flat, cones
    with the needle spinning. Each face's wheel angle r5 is checked against
    ``machine``'s travel (default :class:`Machine`) as it is found."""
    m = machine or Machine()
    faces: list[Face] = []
    for c in spec.cutters:
        surfaces = c.surfaces(spec.cannula) if c.process == "grind" else None
        if not surfaces:
            raise CamError(f"cutter '{c.name}' ({c.kind}) cannot be ground on this machine; "
                           "allowed cutters made by grinding (planes and cones: bevel, "
                           "multiplane, lancet, conical)")
        for f in surfaces:
            if isinstance(f, Plane):
                faces.append(Face(f.label, f.xi, f.rotation, f.height))
            elif isinstance(f, ConeSurface):
                faces.append(Face(f.label, f.theta, 0.0, f.r_o / math.tan(f.theta), spin=True))
            else:
                raise CamError(f"cutter '{c.name}': face {f.label} ({type(f).__name__}) cannot "
                               "be ground; allowed planes and cones")
            _check_r5(faces[-1], m)
    return faces


def _check_r5(f: Face, m: Machine) -> None:
    phi_g = math.degrees(f.xi + m.phi)
    if not m.r5.lo <= phi_g <= m.r5.hi:
        flat = " (a flat land at 90° to the axis)" if f.xi >= 0.5 * math.pi else ""
        raise CamError(f"face {f.label}: ξ = {math.degrees(f.xi):.4g}° needs r5 = ϕ_g = "
                       f"{phi_g:.4g}°, outside its travel [{m.r5.lo:g}, {m.r5.hi:g}]°{flat}")


@dataclass
class GrindProgram:
    """A time-stamped axis program (rows of :data:`COLUMNS`) with its set-up."""

    name: str
    machine: Machine
    faces: list[Face]
    rows: list[dict[str, Any]]
    feed: float
    needle_rpm: float

    def summary(self) -> dict[str, Any]:
        """Name, faces, rows, time (s), feed (mm/s), needle speed (rpm) and
        each face's set-up (:meth:`face_setup`)."""
        return {"name": self.name, "faces": len(self.faces), "rows": len(self.rows),
                "time_s": self.rows[-1]["t"] if self.rows else 0.0,
                "feed_mm_s": self.feed, "needle_rpm": self.needle_rpm,
                "setup": [self.face_setup(f) for f in self.faces]}

    def face_setup(self, f: Face) -> dict[str, Any]:
        """The set-up of face ``f``: ξ, r5 = ϕ_g, r4 (deg), t1, t2, H, OC (mm,
        eq. 2.38) and the needle's spin (rpm)."""
        m = self.machine
        phi_g = f.xi + m.phi
        H = m.H
        # eq. 2.38: H = OC (cos φ + sin φ tan(90° − ϕ_g + φ))
        oc = H / (math.cos(m.phi) + math.sin(m.phi) * math.tan(math.pi / 2 - phi_g + m.phi))
        return {"face": f.label, "xi_deg": math.degrees(f.xi),
                "r5_phi_g_deg": math.degrees(phi_g),
                "r4_deg": math.degrees(f.beta + math.pi) % 360.0, "t1_mm": -f.h, "t2_mm": 0.0,
                "H_mm": H, "OC_mm": oc, "spin_rpm": self.needle_rpm if f.spin else 0.0}

    def to_json(self) -> str:
        """The program as JSON: machine, units, summary and rows."""
        return dumps({"machine": self.machine.name, "units": {
            "t1": "mm", "t2": "mm", "r3": "deg", "r4": "deg", "r5": "deg", "feed": "mm/s",
            "t": "s", "spindle_rpm": "rpm", "needle_rpm": "rpm"},
            "summary": self.summary(), "rows": self.rows})

    def to_csv(self) -> str:
        """The rows as CSV (:data:`COLUMNS`; mm, deg, rpm, mm/s, s)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(COLUMNS)
        for r in self.rows:
            w.writerow([f"{r['t']:.4f}", f"{r['t1']:.4f}", f"{r['t2']:.4f}", f"{r['r3']:.4f}",
                        f"{r['r4']:.4f}", f"{r['r5']:.4f}", f"{r['spindle_rpm']:.1f}",
                        f"{r['needle_rpm']:.1f}",
                        "" if r["feed"] is None else f"{r['feed']:.4f}"])
        return buf.getvalue()

    def to_gcode(self, program_number: int = 1000, dialect: Dialect | str = "fanuc") -> str:
        """The ISO program (Fanuc-style G-code) with named axes: Z = t1,
        X = t2, A = r3, C = r4, B = r5; S the wheel speed, F the feed (mm/min),
        M3/M5 the spindle. ``%``, ``O<program_number>`` and the safety line
        :data:`cam.iso.SAFETY_LINE` open it; ``M5``, ``M30`` and ``%`` close
        it; comments are plain ASCII without nested parentheses
        (:func:`cam.iso.iso_comment`). ``dialect``: a row of
        :data:`gcode.dialects.DIALECTS` (``fanuc``, ``linuxcnc``, ``haas``)
        — header, comments, line numbers, block length and end by its rules."""
        m = self.machine
        d = get_dialect(dialect)
        if d.family != "iso":
            raise CamError(f"dialect = {d.name!r} is not an ISO G-code dialect; allowed: "
                           + ", ".join(k for k, v in DIALECTS.items() if v.family == "iso"))

        def c(text: str) -> str:
            return iso_comment(text, d)

        out = iso_start(program_number, f"{self.name}: needle grinding program by tipgeo", d)
        out += [c(f"machine: {m.name}"),
                c(f"units: mm, degrees, feed F in mm/min, phi = {m.phi_deg:g} deg fixed, "
                  f"contact radius {m.contact_radius:g} mm, H = {m.H:.4f} mm"),
                c("axes: Z = t1 needle axis, X = t2, A = r3 about Z*, C = r4 needle rotation, "
                  "B = r5 wheel angle phi_g")]
        for f in self.faces:
            s = self.face_setup(f)
            out.append(c(f"face {f.label}: xi {s['xi_deg']:.4f} deg -> B{s['r5_phi_g_deg']:.4f}, "
                         f"C{s['r4_deg']:.4f}, Z{s['t1_mm']:.4f}, OC {s['OC_mm']:.4f} mm"))
        out.append(d.spindle_on.format(rpm=f"{m.wheel_rpm:.0f}"))
        spin = 0.0
        for r in self.rows:
            if r["needle_rpm"] != spin:
                spin = r["needle_rpm"]
                out.append(c(f"needle spin {spin:.0f} rpm"))
            words = (f"X{r['t2']:.4f} Z{r['t1']:.4f} A{r['r3']:.4f} C{r['r4']:.4f} "
                     f"B{r['r5']:.4f}")
            out.append(f"G00 {words}" if r["feed"] is None
                       else f"G01 {words} F{r['feed'] * 60:.3f}")
        out += iso_end(d)
        try:
            return "\n".join(number_lines(d, out))
        except ValueError as e:
            raise CamError(str(e)) from None

    def setup_sheet(self) -> str:
        """A Markdown set-up sheet."""
        m = self.machine
        lines = [f"# Set-up sheet — {self.name}", "", "## Machine", "",
                 "| parameter | value |", "|---|---|"]
        lines += [f"| {a} | {b} |" for a, b in m.table()]
        lines += ["", "## Faces", "",
                  "| face | ξ (°) | r5 = ϕ_g (°) | r4 (°) | t1 (mm) | H (mm) | OC (mm) | "
                  "needle rpm |", "|---|---|---|---|---|---|---|---|"]
        for f in self.faces:
            s = self.face_setup(f)
            lines.append(f"| {f.label} | {s['xi_deg']:.4f} | {s['r5_phi_g_deg']:.4f} | "
                         f"{s['r4_deg']:.4f} | {s['t1_mm']:.4f} | {s['H_mm']:.4f} | "
                         f"{s['OC_mm']:.4f} | {s['spin_rpm']:.0f} |")
        sm = self.summary()
        lines += ["", f"Feed {self.feed:g} mm/s; total time {sm['time_s']:.1f} s; "
                  f"wheel {m.wheel_rpm:g} rpm.", ""]
        return "\n".join(lines)


def make_program(spec: TipSpec, *, machine: Machine | None = None, feed: float = 0.1,
                 needle_rpm: float = 1000.0, clearance: float = 0.5) -> GrindProgram:
    """The axis program that grinds ``spec`` (see the module docstring).

    Raises :class:`CamError` naming the axis or parameter and its limit when
    the machine cannot do it.
    """
    m = machine or Machine()
    m.check_feed(feed)
    if not 0 < needle_rpm <= m.needle_rpm_max:
        raise CamError(f"needle_rpm = {needle_rpm:g} is outside (0, {m.needle_rpm_max:g}] rpm")
    if not clearance > 0:
        raise CamError(f"clearance = {clearance:g} mm must be positive")
    faces = setup_faces(spec, m)
    rows: list[dict[str, Any]] = []
    t = 0.0
    c, s = math.cos(m.phi), math.sin(m.phi)

    def add(t1: float, t2: float, r3: float, r4: float, r5: float, rpm: float,
            fd: float | None, dist: float) -> None:
        nonlocal t
        m.t1.check("t1", t1, "mm")
        m.t2.check("t2", t2, "mm")
        m.r3.check("r3", r3, "deg")
        m.r4.check("r4", r4, "deg")
        m.r5.check("r5", r5, "deg")
        t += dist / (fd if fd else m.rapid_speed)
        rows.append({"t": t, "t1": t1, "t2": t2, "r3": r3, "r4": r4, "r5": r5,
                     "spindle_rpm": m.wheel_rpm, "needle_rpm": rpm, "feed": fd})

    prev = None
    for f in faces:
        phi_g = math.degrees(f.xi + m.phi)
        r4 = math.degrees(f.beta + math.pi) % 360.0
        t1f, t2f = -f.h, 0.0
        t1a, t2a = t1f - clearance * c, t2f + clearance * s   # clear of the wheel along Z*
        rpm = needle_rpm if f.spin else 0.0
        dist = 0.0 if prev is None else math.hypot(t1a - prev[0], t2a - prev[1])
        add(t1a, t2a, 0.0, r4, phi_g, 0.0, None, dist)        # position (rapid)
        if rpm:
            add(t1a, t2a, 0.0, r4, phi_g, rpm, None, 0.0)      # start spinning
        add(t1f, t2f, 0.0, r4, phi_g, rpm, feed, clearance)    # infeed along Z*
        add(t1a, t2a, 0.0, r4, phi_g, 0.0, None, clearance)    # retract
        prev = (t1a, t2a)
    return GrindProgram(spec.name or "tip", m, faces, rows, feed, needle_rpm)
