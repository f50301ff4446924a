"""Emitter: a serration spec → an AeroBasic laser program in the style of the
thesis's Appendix C.

Machine frame and program zero (see :mod:`gcode.interpreter`): X along the
rim (mm), Y along the punch axis with +Y into the material (mm), C the punch's
rotation (deg, +C = +γ). Program zero (X0, Y0) = (0, 0) is the centre line of
the first serration at the rim (the cutting edge on the inner wall); the
operator jogs the beam there, then to the start point the first ``G92`` names.

For every serration the program cuts ``roughing`` passes of concentric arcs,
each ``dist_R = (1 − overlap)·beam`` smaller than the last, then ``finishing``
passes on the final contour r_c; cutter compensation (``G41``, tool T1 = the
beam radius) keeps the beam's edge on the programmed radius. The roughing
radius is reset for every serration (Appendix C as printed keeps shrinking it
across serrations). ``LINEAR C…`` indexes the punch by ρ between serrations.

Numbers are printed with fixed decimals per word kind — lengths 4 (0.1 µm),
angles 4, feeds 3 — never ``%g``; the output is deterministic and ASCII only.

A complete A3200 program. The controller's defaults are not relied on: every
program states, in this order, the conventions of the A3200 programming
manual (AeroBasic command reference) and of the public A3200 laser-writing
programs that follow it:

``ENABLE X Y C``
    Enables the drives of the axes the program moves (X, Y and the punch's
    C). A program must not assume an operator enabled them.
``METRIC`` (G71), ``SECONDS`` (G76)
    Distance units mm and time units s, so that F is mm/s and E deg/s;
    without them the units are whatever the controller was left in.
``G90`` (absolute) then ``G91`` (incremental)
    The G92 presets are given absolutely; every move after them is
    incremental, as in Appendix C. Both modes are written, never implied.
``PSOCONTROL X RESET``
    Returns the position-synchronised output (PSO) to its default state, so
    that no set-up left by an earlier program (windows, distances, arrays)
    shapes this program's pulses.
``PSOPULSE X TIME period, on CYCLES n``
    The pulse generator: total period and on time in µs, written with the
    comma between them as the manual's syntax and public programs do.
``PSOOUTPUT X PULSE``
    Routes the pulse generator to the PSO output; the output pin itself
    (``PSOOUTPUT X CONTROL …``) is wiring, left to the machine's set-up file.
``PSOCONTROL X OFF``
    The laser is off before the first move. Then ``PSOCONTROL X FIRE`` /
    ``OFF`` around each cut, as before.
``PSOCONTROL X OFF``, ``T0``, ``END PROGRAM``
    At the end: laser off, tool unloaded, and the end of the program stated
    (``END PROGRAM``, the AeroBasic program end; ``M2`` is its G-code
    synonym and is read too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from tipgeo import validate as v
from tipgeo.errors import SpecError
from tipgeo.tolerances import tol

from .dialects import AEROBASIC, comment

if TYPE_CHECKING:
    from tipgeo.cutters.serration import SerrationFacts
    from tipgeo.spec import TipSpec

__all__ = ["LaserParams", "emit_program", "laser_serrations", "LENGTH_DECIMALS", "LASER_TOML_KEYS"]

LENGTH_DECIMALS = 4
ANGLE_DECIMALS = 4
FEED_DECIMALS = 3


@dataclass(frozen=True, kw_only=True)
class LaserParams:
    """Process parameters of the laser program (defaults: Appendix C).

    Parameters
    ----------
    beam_diameter : float — mm (0.020)
    overlap : float — radial overlap of consecutive passes, 0 ≤ · < 1 (0.95)
    roughing_depth : float — radial depth cut by the roughing passes, mm (0.020)
    finishing_passes : int — passes on the final contour (80)
    feed : float — mm/s (0.1)
    pulse_period_us, pulse_on_us : float — PSOPULSE TIME, µs (10, 5: 100 kHz)
    compensation : float — lead-in/lead-out length along X with G41/G40, mm (0.05)
    clearance : float — start the cut this far outside the rim along −Y, mm (0.05)
    rotary_feed : float — C indexing feed, deg/s (5)
    power_w : float — laser power for the header, W (0.75)
    """

    beam_diameter: float = 0.020
    overlap: float = 0.95
    roughing_depth: float = 0.020
    finishing_passes: int = 80
    feed: float = 0.1
    pulse_period_us: float = 10.0
    pulse_on_us: float = 5.0
    compensation: float = 0.05
    clearance: float = 0.05
    rotary_feed: float = 5.0
    power_w: float = 0.75

    def __post_init__(self) -> None:
        v.length("beam_diameter", self.beam_diameter, hi=1.0)
        v.real("overlap", self.overlap, lo=0.0, hi=1.0, hi_open=True)
        v.length("roughing_depth", self.roughing_depth, lo=0.0, lo_open=False, hi=5.0)
        v.integer("finishing_passes", self.finishing_passes, lo=0, hi=100_000)
        v.real("feed", self.feed, lo=0.0, lo_open=True, hi=1000.0, unit="mm/s")
        v.real("pulse_period_us", self.pulse_period_us, lo=0.0, lo_open=True, hi=1e6)
        v.real("pulse_on_us", self.pulse_on_us, lo=0.0, lo_open=True, hi=self.pulse_period_us)
        v.length("compensation", self.compensation, hi=5.0)
        v.length("clearance", self.clearance, hi=5.0)
        v.real("rotary_feed", self.rotary_feed, lo=0.0, lo_open=True, hi=1e4, unit="deg/s")
        v.real("power_w", self.power_w, lo=0.0, hi=1e3)
        if not self.compensation > self.beam_diameter / 2:
            raise SpecError(f"compensation = {self.compensation:g} mm must exceed the beam "
                            f"radius {self.beam_diameter / 2:g} mm (the G41 lead-in)")

    @classmethod
    def from_toml(cls, path: str | Path) -> LaserParams:
        """The laser station's parameters from a TOML file (sample:
        ``samples/machines/a3200-laser.toml``): the keys of
        :data:`LASER_TOML_KEYS`, each with its unit in its name (feeds per
        minute, converted to the mm/s and deg/s the program is written in);
        a key left out keeps its default.

        Raises :class:`gcode.GCodeError` (one line, naming the file, the key,
        its value and the allowed range) for an unreadable file, an unknown
        key, a value of the wrong type or out of range.
        """
        from tipgeo.errors import SpecError as _SpecError
        from tipgeo.tomlio import loads_toml, read_text_file

        from .errors import GCodeError

        try:
            data = loads_toml(read_text_file(path, "laser file"), f"laser file '{path}'")
        except _SpecError as e:
            raise GCodeError(str(e)) from None
        return cls.from_dict(data, source=f"laser file '{path}'")

    @classmethod
    def from_dict(cls, table: object, *, source: str = "laser table") -> LaserParams:
        """:meth:`from_toml` of a table already read (a dict)."""
        from tipgeo.validate import brief

        from .errors import GCodeError

        if not isinstance(table, dict):
            raise GCodeError(f"{source}: expected a table of keys, not {brief(table)}")
        kw: dict[str, float] = {}
        passes = cls.finishing_passes
        try:
            for key, val in table.items():
                if key not in LASER_TOML_KEYS:
                    raise SpecError(f"key {brief(key)} is not known; allowed: "
                                    + ", ".join(LASER_TOML_KEYS))
                field_, scale, lo, hi, unit = LASER_TOML_KEYS[key]
                if field_ == "finishing_passes":
                    passes = v.integer(key, val, lo=int(lo), hi=int(hi))
                    continue
                if key == "pulse_on_us" and "pulse_period_us" in table:
                    hi = v.real("pulse_period_us", table["pulse_period_us"], lo=0.0,
                                lo_open=True, hi=1e6, unit="µs")
                x = v.real(key, val, lo=lo, hi=hi, lo_open=key not in _CLOSED_LOW,
                           hi_open=key == "overlap", unit=unit)
                kw[field_] = x / scale
            beam = kw.get("beam_diameter", cls.beam_diameter)
            comp = kw.get("compensation", cls.compensation)
            if not comp > beam / 2:
                raise SpecError(f"compensation_mm = {comp:g} is out of range; allowed value > "
                                f"the beam radius beam_diameter_um / 2 = {beam * 500:g} µm = "
                                f"{beam / 2:g} mm")
            on = kw.get("pulse_on_us", cls.pulse_on_us)
            per = kw.get("pulse_period_us", cls.pulse_period_us)
            if on > per:
                raise SpecError(f"pulse_on_us = {on:g} is out of range; allowed 0 < value ≤ "
                                f"pulse_period_us = {per:g} (µs)")
            return cls(finishing_passes=passes, **kw)
        except SpecError as e:
            raise GCodeError(f"{source}: {e}") from None

    @property
    def pass_step(self) -> float:
        """dist_R: radial step between roughing passes (mm)."""
        return (1.0 - self.overlap) * self.beam_diameter

    @property
    def roughing_passes(self) -> int:
        """Number of roughing passes: roughing_depth / dist_R, rounded."""
        return int(round(self.roughing_depth / self.pass_step)) if self.pass_step > 0 else 0

    @property
    def tool_radius(self) -> float:
        """T1's radius in the tool table: the beam radius (mm)."""
        return self.beam_diameter / 2


#: The laser station's TOML keys (:meth:`LaserParams.from_toml`): key →
#: (LaserParams field, key units per field unit, lo, hi, unit). Lower ends
#: are open (the value must exceed them) except for ``overlap``,
#: ``roughing_depth_um``, ``finishing_passes`` and ``power_w``, which may be 0;
#: ``overlap`` stays below 1.
LASER_TOML_KEYS: dict[str, tuple[str, float, float, float, str]] = {
    "beam_diameter_um": ("beam_diameter", 1000.0, 0.0, 1000.0, "µm"),
    "overlap": ("overlap", 1.0, 0.0, 1.0, ""),
    "roughing_depth_um": ("roughing_depth", 1000.0, 0.0, 5000.0, "µm"),
    "finishing_passes": ("finishing_passes", 1.0, 0, 100_000, ""),
    "feed_mm_min": ("feed", 60.0, 0.0, 60_000.0, "mm/min"),
    "pulse_period_us": ("pulse_period_us", 1.0, 0.0, 1e6, "µs"),
    "pulse_on_us": ("pulse_on_us", 1.0, 0.0, 1e6, "µs"),
    "compensation_mm": ("compensation", 1.0, 0.0, 5.0, "mm"),
    "clearance_mm": ("clearance", 1.0, 0.0, 5.0, "mm"),
    "rotary_feed_deg_min": ("rotary_feed", 60.0, 0.0, 600_000.0, "deg/min"),
    "power_w": ("power_w", 1.0, 0.0, 1000.0, "W"),
}
_CLOSED_LOW = {"overlap", "roughing_depth_um", "power_w"}


def _mm(x: float) -> str:
    s = f"{x:.{LENGTH_DECIMALS}f}"
    return "0." + "0" * LENGTH_DECIMALS if s == "-0." + "0" * LENGTH_DECIMALS else s


def _deg(x: float) -> str:
    return f"{x:.{ANGLE_DECIMALS}f}"


@runtime_checkable
class _LaserCutter(Protocol):
    """A cutter the laser makes (``process == "laser"``): it tells its
    serrations (:meth:`tipgeo.cutters.serration.SerrationCutter.serration_facts`)."""

    def serration_facts(self) -> SerrationFacts: ...


def laser_serrations(spec: TipSpec) -> SerrationFacts:
    """The serrations of ``spec``'s one laser cutter, as the cutter tells
    them (mm, rad; cannula frame). SpecError unless there is exactly one
    laser cutter and it tells its serrations."""
    ser = [c for c in spec.cutters if c.process == "laser"]
    if len(ser) != 1:
        raise SpecError(f"spec '{spec.name}' has {len(ser)} serration cutters; the laser "
                        "program needs exactly one")
    s = ser[0]
    if not isinstance(s, _LaserCutter):
        raise SpecError(f"cutter '{s.name}' is cut by the laser but tells no serrations "
                        "(serration_facts); the laser program needs a serration cutter")
    return s.serration_facts()


def emit_program(spec: TipSpec, laser: LaserParams | None = None, *,
                 name: str | None = None) -> str:
    """The AeroBasic program that cuts ``spec``'s serrations.

    Parameters
    ----------
    spec : TipSpec — a punch with a preceding cutter and a SerrationCutter
    laser : LaserParams — process parameters (default: Appendix C's)

    Returns
    -------
    str — the program text (deterministic)
    """
    laser = laser or LaserParams()
    s = laser_serrations(spec)
    r_c, rho, n = s.arc_radius, math.degrees(s.spacing), s.count
    y_c = s.depth - r_c  # arc centre, +Y into the material from the rim
    if not r_c > laser.tool_radius:
        raise SpecError(f"arc_radius = {r_c:g} mm is not larger than the beam radius "
                        f"{laser.tool_radius:g} mm")
    if laser.roughing_depth >= r_c - laser.tool_radius + tol.gcode.length:
        raise SpecError(f"roughing_depth = {laser.roughing_depth:g} mm leaves no arc: "
                        f"allowed < arc_radius − beam radius = {r_c - laser.tool_radius:g} mm")
    comp, lead = laser.compensation, laser.clearance
    start_x = r_c - comp
    c = spec.cannula
    rep = 1e3 / laser.pulse_period_us
    lines = [
        f"; {name or spec.name or 'serrations'} - micro-serrations, written by tipgeo",
        "; units: mm, seconds, degrees. Machine frame: X along the rim, Y along the punch "
        "axis (+Y into the material), C turns the punch (+C = +gamma).",
        "; program zero X0 Y0: centre line of the first serration on the rim (inner-wall "
        "cutting edge); jog the beam there, then to the G92 start point below.",
        f"; punch: d_e {_mm(c.outer_diameter)} mm, d_i {_mm(c.inner_diameter)} mm",
        f"; serrations: r_c {_mm(r_c)} mm, n_s {n}, rho {_deg(rho)} deg, depth "
        f"{_mm(s.depth)} mm (arc centre Y {_mm(y_c)} mm)",
        f"; beam diameter {_mm(laser.beam_diameter)} mm (tool T1 radius "
        f"{_mm(laser.tool_radius)} mm), pass overlap {laser.overlap:.4f}, pass step "
        f"{_mm(laser.pass_step)} mm",
        f"; roughing depth {_mm(laser.roughing_depth)} mm ({laser.roughing_passes} passes), "
        f"finishing passes {laser.finishing_passes}",
        f"; feed {laser.feed:.{FEED_DECIMALS}f} mm/s, pulses: period "
        f"{laser.pulse_period_us:.3f} us ({rep:.3f} kHz), on {laser.pulse_on_us:.3f} us, "
        f"laser power {laser.power_w:.3f} W",
        f"; compensation lead {_mm(comp)} mm, clearance {_mm(lead)} mm, C feed "
        f"{laser.rotary_feed:.{FEED_DECIMALS}f} deg/s",
        "",
        "DVAR $feed, $beam_dia, $overlap_R, $dist_R, $passover, $pass2, $radius, $comp, "
        "$radius_i, $comp_i",
        "",
        "ENABLE X Y C ; enable the drives of the axes this program moves",
        "METRIC ; distance units: mm (G71)",
        "SECONDS ; time units: s, so F is mm/s and E deg/s (G76)",
        "G90 ; absolute positions for the presets below",
        "",
        f"$beam_dia = {_mm(laser.beam_diameter)}",
        f"$overlap_R = {laser.overlap:.4f}",
        "$dist_R = (1-$overlap_R)*$beam_dia",
        f"$passover = {laser.roughing_passes} ; roughing passes ({_mm(laser.roughing_depth)} mm "
        "/ $dist_R)",
        f"$pass2 = {laser.finishing_passes} ; finishing passes",
        f"$radius_i = {_mm(r_c)}",
        f"$comp_i = {_mm(comp)}",
        f"$feed = {laser.feed:.{FEED_DECIMALS}f}",
        "",
        f"G92 X{_mm(start_x)} Y{_mm(-lead)} ; the beam at the start point",
        "G92 C0.0000",
        "T0",
        "G44 X Y ; cutter compensation on the X and Y axes",
        "T1 ; the laser beam (tool radius = beam radius)",
        "G91 ; incremental: every move below is relative to the last",
        "PSOCONTROL X RESET ; the PSO to its default state",
        f"PSOPULSE X TIME {laser.pulse_period_us:.3f}, {laser.pulse_on_us:.3f} CYCLES 10000000 "
        "; period, on time (us)",
        "PSOOUTPUT X PULSE ; the pulse generator drives the PSO output",
        "PSOCONTROL X OFF ; laser off until the first cut",
        "",
        f"REPEAT {n} ; every serration",
        "$radius = $radius_i",
        "$comp = $comp_i",
        "REPEAT $passover ; roughing",
        "PSOCONTROL X FIRE",
        "G01 G41 X$comp F $feed",
        f"G01 Y{_mm(lead + y_c)}",
        "G03 X-($radius*2) Y0 I-$radius J0",
        "PSOCONTROL X OFF",
        f"G01 Y{_mm(-(lead + y_c))}",
        "G40 X$comp",
        "G00 X(2*$radius_i-2*$comp_i)",
        "$radius = $radius - $dist_R",
        "$comp = $comp - $dist_R",
        "END REPEAT",
        "REPEAT $pass2 ; finishing on the final contour",
        "PSOCONTROL X FIRE",
        "G01 G41 X$comp_i F $feed",
        f"G01 Y{_mm(lead + y_c)}",
        "G03 X-($radius_i*2) Y0 I-$radius_i J0",
        "PSOCONTROL X OFF",
        f"G01 Y{_mm(-(lead + y_c))}",
        "G40 X$comp_i",
        "G00 X(2*$radius_i-2*$comp_i)",
        "END REPEAT",
        f"LINEAR C{_deg(rho)} E{laser.rotary_feed:.{FEED_DECIMALS}f} ; next serration",
        "END REPEAT",
        "",
        "PSOCONTROL X OFF ; laser off",
        "T0 ; unload the tool: laser beam",
        "END PROGRAM",
        "",
    ]
    return "\n".join(_with_comments(ln) for ln in lines)


def _with_comments(line: str) -> str:
    """``line`` with its comment (from the first ``;``) rewritten by the one
    comment writer (:func:`gcode.dialects.comment`, AeroBasic row): one line,
    ASCII, whatever the user's spec name holds."""
    i = line.find(";")
    if i < 0:
        return line
    code = line[:i].rstrip()
    text = comment(AEROBASIC, line[i + 1:])
    return f"{code} {text}" if code else text
