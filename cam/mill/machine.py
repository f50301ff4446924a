r"""The three-axis vertical machining centre of thesis §3.2 (Haas VF-2), its
end mills and the milling set-up.

Frames (mm; rad inside, degrees in reports)
--------------------------------------------
=================  ==========================================================
frame              definition
=================  ==========================================================
cannula (x, y, z)  tipgeo's frame: +z along the needle axis towards the tip,
                   heel at γ = 0, z = 0
program (X, Y, Z)  the G-code's work frame (G54): the needle stands in its
                   ER8 collet with its axis vertical and the tip up, so
                   Z = z; program zero is on the needle axis at the heel's
                   height; the needle is clocked in the collet so that the
                   cannula direction γ = ``clocking`` lies along +X (the
                   raster direction): X = x cos c + y sin c,
                   Y = −x sin c + y cos c
machine            Haas machine coordinates: home at X0 Y0 Z0, travels
                   negative; program point P sits at P + ``work_offset``
=================  ==========================================================

The table moves the needle in X and Y, the spindle moves the tool in Z
(§3.2); the controlled point is the tool tip (G43 tool-length offset). With
the tip up, every cut face of a bevel, multi-plane, conical or helical tip is a
height field z = Z(x, y) over the wall's annulus r_i ≤ r ≤ r_o.

Defaults (VF-2 data sheet; thesis §3.2): travels 762 × 406 × 508 mm, rapids
25.4 m/min, cutting feed up to 16.5 m/min, spindle up to 12,000 rpm (the
thesis ran 10,000 rpm; the standard VF-2 spindle gives 8,100 rpm, 12,000 is
the option its speed needs), axis resolution 0.002 mm as the thesis states.
Feeds are mm/min (G94), the unit of the F word.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tipgeo import validate as v
from tipgeo.arrays import FloatArray
from tipgeo.errors import SpecError
from tipgeo.tolerances import tol

from ..machine import AxisLimit, CamError, machine_toml

__all__ = ["MillMachine", "EndMill", "TOOL_KINDS", "DEFAULT_TOOL", "parse_tool"]

#: End-mill kinds: name -> what the corner radius is.
TOOL_KINDS = {"ball": "D/2 (ball nose)", "bull": "0 < r < D/2 (bull nose)",
              "flat": "0 (flat end)"}


@dataclass(frozen=True, kw_only=True)
class EndMill:
    """An end mill: diameter D and corner radius r (mm), kind ``ball``
    (r = D/2), ``bull`` (0 < r < D/2) or ``flat`` (r = 0); its reach (mm out
    of the holder: how deep below the stock top it can cut), flutes, the
    tool/length-offset number, and its material (for the set-up sheet).

    Default: the thesis's carbide ball mill Ø 1.588 mm (1/16 in) on a
    long-reach 12 mm neck.
    """

    kind: str = "ball"
    diameter: float = 1.588
    corner_radius: float | None = None
    reach: float = 12.0
    flutes: int = 2
    number: int = 1
    material: str = "carbide"

    def __post_init__(self) -> None:
        if self.kind not in TOOL_KINDS:
            raise CamError(f"tool kind = {self.kind!r} is not known; expected one of: "
                           + ", ".join(TOOL_KINDS))
        try:
            d = v.length("tool diameter", self.diameter, hi=25.0)
            reach = v.length("tool reach", self.reach, hi=200.0)
            flutes = v.integer("tool flutes", self.flutes, lo=1, hi=12)
            number = v.integer("tool number", self.number, lo=1, hi=200)
        except SpecError as e:
            raise CamError(str(e)) from None
        r = self.corner_radius
        if self.kind == "ball":
            r = 0.5 * d if r is None else r
            if abs(r - 0.5 * d) > tol.cam.mill_ball:
                raise CamError(f"tool corner_radius = {r:g} mm; a ball mill has r = D/2 = "
                               f"{0.5 * d:g} mm")
        elif self.kind == "flat":
            r = 0.0 if r is None else r
            if r != 0.0:
                raise CamError(f"tool corner_radius = {r:g} mm; a flat end mill has r = 0")
        elif r is None or not 0.0 < r < 0.5 * d:
            raise CamError(f"tool corner_radius = {r} mm is out of range; a bull-nose mill "
                           f"needs 0 < r < D/2 = {0.5 * d:g} mm")
        for k, val in (("diameter", d), ("corner_radius", float(r)), ("reach", reach),
                       ("flutes", flutes), ("number", number)):
            object.__setattr__(self, k, val)

    @property
    def radius(self) -> float:
        """D/2 (mm)."""
        return 0.5 * self.diameter

    @property
    def corner(self) -> float:
        """The corner radius r (mm) as the constructor settled it (D/2 for a
        ball, 0 for a flat end)."""
        return float(self.corner_radius or 0.0)

    def describe(self) -> str:
        """One line for sheets and program comments (ASCII)."""
        r = f" r{self.corner_radius:.3f}" if self.kind == "bull" else ""
        return (f"{self.material} {self.kind} end mill D{self.diameter:.3f}{r} mm, "
                f"{self.flutes} flutes, reach {self.reach:g} mm")

    def ocl_cutter(self, allowance: float = 0.0) -> Any:
        """The OpenCAMLib cutter, grown by ``allowance`` (mm) all round (a
        ball of radius R + a; roughing: its CL lowered by a is the real
        tool's, a from the surface)."""
        import opencamlib as ocl

        length = self.reach + 10.0
        d = self.diameter + 2.0 * allowance
        if self.kind == "ball":
            return ocl.BallCutter(d, length)
        if self.kind == "flat" and allowance == 0.0:
            return ocl.CylCutter(d, length)
        return ocl.BullCutter(d, self.corner + allowance, length)


#: The thesis's tool (§3.2).
DEFAULT_TOOL = EndMill()


def parse_tool(text: str, *, number: int = 1) -> EndMill:
    """An end mill from ``KIND:DIAMETER[:CORNER_RADIUS[:REACH]]`` (mm), e.g.
    ``ball:1.588``, ``bull:2:0.25``, ``flat:1``, ``ball:1.588::8``."""
    parts = str(text).split(":")
    if not 2 <= len(parts) <= 4 or parts[0] not in TOOL_KINDS:
        raise CamError(f"tool = {text!r}; expected KIND:DIAMETER[:CORNER_RADIUS[:REACH]] "
                       f"(mm) with KIND one of: {', '.join(TOOL_KINDS)}")
    try:
        vals = [float(p) if p else None for p in parts[1:]]
    except ValueError:
        raise CamError(f"tool = {text!r}: DIAMETER, CORNER_RADIUS and REACH are numbers "
                       "in mm") from None
    diameter = vals[0]
    if diameter is None:
        raise CamError(f"tool = {text!r}: DIAMETER is missing")
    corner = vals[1] if len(vals) > 1 else None
    reach = vals[2] if len(vals) > 2 else None
    if reach is None:
        return EndMill(kind=parts[0], diameter=diameter, corner_radius=corner, number=number)
    return EndMill(kind=parts[0], diameter=diameter, corner_radius=corner, reach=reach,
                   number=number)


@dataclass(frozen=True, kw_only=True)
class MillMachine:
    """The Haas VF-2 (defaults: see the module docstring), overridable from
    TOML like :class:`cam.Machine`.

    Lengths mm, feeds mm/min, speeds rpm; ``x``, ``y``, ``z`` are machine
    travels (Haas machine coordinates) with the axis resolution;
    ``work_offset`` (mm) is program zero in machine coordinates (G54).
    """

    name: str = "Haas VF-2 three-axis vertical machining centre (thesis §3.2)"
    x: AxisLimit = field(default_factory=lambda: AxisLimit(-762.0, 0.0, 0.002))
    y: AxisLimit = field(default_factory=lambda: AxisLimit(-406.0, 0.0, 0.002))
    z: AxisLimit = field(default_factory=lambda: AxisLimit(-508.0, 0.0, 0.002))
    work_offset: tuple[float, float, float] = (-381.0, -203.0, -400.0)
    spindle_rpm_min: float = 100.0
    spindle_rpm_max: float = 12000.0
    feed_min: float = 1.0          # mm/min
    feed_max: float = 16500.0      # mm/min
    rapid: float = 25400.0         # mm/min
    controller: str = "haas"

    @property
    def resolution(self) -> float:
        """The coarsest axis resolution (mm): every programmed coordinate is
        a multiple of it."""
        return max(self.x.resolution, self.y.resolution, self.z.resolution)

    @classmethod
    def from_toml(cls, path: str | Path) -> MillMachine:
        """A machine from a TOML file (sample: ``samples/machines/haas-vf2.toml``):
        top-level keys override the defaults; ``[x]``, ``[y]``, ``[z]`` tables
        give ``lo``, ``hi``, ``resolution`` (mm; a travel hi − lo of zero or
        less is refused). Feeds and the rapid rate in mm/min, speeds in rpm:
        finite and positive, each minimum at most its maximum; ``work_offset``
        three finite numbers (mm); ``controller`` one with a post
        (:data:`cam.mill.post.POSTS`). Anything else is a :class:`CamError`
        naming the key, its value and what is allowed."""
        from tipgeo.validate import brief

        from ..machine import machine_name, machine_number
        from .post import POSTS

        kw = machine_toml(cls, path, ("x", "y", "z"))
        for k, val in kw.items():
            if k in ("x", "y", "z"):
                continue
            if k == "name":
                machine_name(val)
            elif k == "controller":
                if not isinstance(val, str) or val not in POSTS:
                    raise CamError(f"machine controller = {brief(val)} has no post; allowed: "
                                   + ", ".join(sorted(POSTS)))
            elif k == "work_offset":
                try:
                    ok = (isinstance(val, list) and len(val) == 3
                          and all(not isinstance(a, bool) and isinstance(a, (int, float))
                                  and math.isfinite(float(a)) for a in val))
                except OverflowError:
                    ok = False
                if not ok:
                    raise CamError(f"machine work_offset = {brief(val)}: needs three finite "
                                   "numbers (X, Y, Z) in mm")
                val = tuple(float(a) for a in val)
            else:
                val = machine_number(k, val, "rpm" if "rpm" in k else "mm/min")
            kw[k] = val
        for lo, hi, unit in (("spindle_rpm_min", "spindle_rpm_max", "rpm"),
                             ("feed_min", "feed_max", "mm/min")):
            a, b = kw.get(lo, getattr(cls, lo)), kw.get(hi, getattr(cls, hi))
            if a > b:
                raise CamError(f"machine {lo} = {a:g} is above {hi} = {b:g} ({unit})")
        return cls(**kw)

    def check_feed(self, name: str, feed: float) -> float:
        """``feed`` (mm/min) inside the machine's range, or a CamError."""
        if not (isinstance(feed, (int, float)) and self.feed_min <= feed <= self.feed_max):
            raise CamError(f"{name} = {feed} mm/min is outside the machine's feed range "
                           f"[{self.feed_min:g}, {self.feed_max:g}] mm/min")
        return float(feed)

    def check_spindle(self, rpm: float) -> float:
        """``rpm`` inside the spindle's range, or a CamError."""
        if not (isinstance(rpm, (int, float)) and self.spindle_rpm_min <= rpm
                <= self.spindle_rpm_max):
            raise CamError(f"spindle = {rpm} rpm is outside the spindle's range "
                           f"[{self.spindle_rpm_min:g}, {self.spindle_rpm_max:g}] rpm")
        return float(rpm)

    def check_travel(self, lo: FloatArray, hi: FloatArray) -> None:
        """Program-frame bounds ``lo``, ``hi`` (3,) mm inside the travels
        once the work offset is added, or a CamError naming the axis."""
        slack = tol.cam.mill_travel
        for k, ax in enumerate("xyz"):
            lim: AxisLimit = getattr(self, ax)
            for val in (float(lo[k]), float(hi[k])):
                m = val + self.work_offset[k]
                if not lim.lo - slack <= m <= lim.hi + slack:
                    raise CamError(f"axis {ax.upper()} = {m:.4f} mm (program {val:.4f} mm + "
                                   f"work offset {self.work_offset[k]:g} mm) is outside its "
                                   f"travel [{lim.lo:g}, {lim.hi:g}] mm")

    def table(self) -> list[tuple[str, str]]:
        """Rows for reports: parameter, value."""
        rows = [("machine", self.name),
                ("spindle", f"{self.spindle_rpm_min:g}–{self.spindle_rpm_max:g} rpm"),
                ("feeds", f"{self.feed_min:g}–{self.feed_max:g} mm/min, rapid "
                          f"{self.rapid:g} mm/min"),
                ("work offset G54", "X{:g} Y{:g} Z{:g} mm".format(*self.work_offset))]
        for ax in "xyz":
            lim = getattr(self, ax)
            rows.append((ax.upper(), f"[{lim.lo:g}, {lim.hi:g}] mm, resolution "
                                     f"{lim.resolution:g} mm"))
        return rows
