r"""Serration arcs: micro-serrations laser-cut into a biopsy punch's rim
(thesis §5.1.2, Fig. 5.2, Table 5.1, Appendix C).

Frame and units: cannula frame (+z along the axis towards the tip), mm, rad.

Each serration is a straight notch through the wall along the radial
direction (the laser beam crosses the wall radially) whose profile, seen
along the beam in the plane (u, z) — u tangential, z axial — is::

          z_e ──────┐  ╭ r_s                 ╮  ┌────── rim (cutting edge)
                    │ ╱                       ╲ │
                    │                           │
                     ╲         r_c            ╱          z_c = z_e − depth + r_c
                       ╲_____________________╱
                               depth below z_e

an arc of radius r_c (centre z_c) whose lowest point lies ``depth`` below the
rim height z_e, straight sides (when depth > r_c) up past the rim, and the
two serration edges rounded with radius r_s (the thesis's r_s ≈ 15 µm). The
rim height z_e is where the preceding cutters (e.g. the punch's cone) put
the cutting edge on the inner wall at the serration's angle. Serrations sit
at γ_k = rotation + k ρ, k = 0 … n_s − 1.

Neighbouring notches must not overlap on the inner wall (where they are
widest in angle): ρ ≥ 2 asin(W / r_i), W the profile's half-width; a closer
spacing is a :class:`SpecError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import manifold3d as m3d
import numpy as np

from .. import validate as v
from ..arrays import AnyArray, FloatArray, IntArray
from ..cannula import Cannula
from ..construct import AUX, BuildContext
from ..errors import SpecError
from ..tolerances import tol
from .base import Cutter, OptimizerKey, check_name
from .surfaces import NotchPrism, Surface
from .toml import round_for_toml as _r

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["SerrationCutter", "SerrationProfile", "SerrationFacts", "SERRATION_PRESETS",
           "MAX_SERRATIONS"]

#: Most serrations on one rim: each is a boolean cut and an edge piece, so the
#: cost of a build grows with the count (Appendix C cuts 16; 256 builds in
#: seconds, thousands run for minutes). Checked before any geometry.
MAX_SERRATIONS = 256

#: Table 5.1 arc radii r_c (mm) with our serration counts n_s. The thesis
#: gives only r_c; Appendix C cuts 16 serrations of r_c = 150 µm. We keep 16
#: where the notches fit and otherwise take the largest n_s whose spacing
#: leaves at least a quarter of a notch width of rim between neighbours on
#: the inner wall of the 2.0 mm punch (ρ ≥ 1.25 · 2 asin((r_c + r_s)/r_i)).
SERRATION_PRESETS: dict[str, tuple[float, int]] = {
    "C1": (0.050, 16),
    "C2": (0.150, 16),
    "C3": (0.250, 9),
    "C4": (0.400, 5),
    "C5": (0.600, 3),
}


@dataclass(frozen=True)
class SerrationProfile:
    """The notch profile in its (u, z) plane (mm); see the module docstring."""

    r_c: float
    depth: float
    r_s: float
    z_e: float

    @property
    def z_c(self) -> float:
        return self.z_e - self.depth + self.r_c

    @property
    def straight(self) -> bool:
        """True when the fillets meet straight sides (z_e − r_s ≥ z_c)."""
        return self.z_e - self.r_s >= self.z_c

    def fillet(self) -> tuple[float, float, float, float]:
        """(u_F, z_F, u_T, z_T): right fillet centre and its tangent point
        with the side/arc (u ≥ 0 half; mirror for the left)."""
        r_c, r_s, z_c, z_e = self.r_c, self.r_s, self.z_c, self.z_e
        if self.straight:
            return r_c + r_s, z_e - r_s, r_c, z_e - r_s
        zf = z_e - r_s
        uf = math.sqrt(max((r_c + r_s) ** 2 - (zf - z_c) ** 2, 0.0))
        k = r_c / (r_c + r_s)
        return uf, zf, k * uf, z_c + k * (zf - z_c)

    @property
    def half_width(self) -> float:
        """Largest |u| of the notch at the rim (mm)."""
        if self.r_s > 0:
            return self.fillet()[0]
        if self.straight:
            return self.r_c
        return math.sqrt(max(self.r_c ** 2 - (self.z_e - self.z_c) ** 2, 0.0))

    def polygon(self, chordal: float, z_top: float) -> FloatArray:
        """(k, 2) CCW polygon of the notch (u, z), up to ``z_top``."""
        r_c, r_s, z_c = self.r_c, self.r_s, self.z_c

        def nseg(r: float, span: float) -> int:
            if r <= 0:
                return 1
            return max(2, math.ceil(span / (2 * math.acos(max(1 - chordal / r, -1.0)))))

        uf, zf, ut, zt = self.fillet()
        if self.straight:  # the arc ends level with its centre; the sides go on up
            a_t = 0.0
        elif self.r_s > 0:
            a_t = math.atan2(zt - z_c, ut)              # end of the main arc (right)
        else:
            a_t = math.atan2(self.z_e - z_c, self.half_width)
        a = np.linspace(-0.5 * math.pi, a_t, nseg(r_c, a_t + 0.5 * math.pi) + 1)
        right: list[FloatArray] = [np.stack([r_c * np.cos(a), z_c + r_c * np.sin(a)], 1)]
        if self.r_s > 0:
            if self.straight:
                right.append(np.array([[r_c, zf]]))
            b0 = math.atan2(zt - zf, ut - uf)
            b = np.linspace(b0, 0.5 * math.pi, nseg(r_s, abs(b0 - 0.5 * math.pi)) + 1)
            right.append(np.stack([uf + r_s * np.cos(b), zf + r_s * np.sin(b)], 1))
            w = uf
        else:
            w = self.half_width if not self.straight else r_c
            right.append(np.array([[w, self.z_e]]))
        right.append(np.array([[w, z_top]]))
        half = np.concatenate(right)
        left = half[::-1] * np.array([-1.0, 1.0])
        poly = np.concatenate([half, left[:-1]])  # left ends at the shared bottom point
        keep = np.r_[True, np.linalg.norm(np.diff(poly, axis=0), axis=1) > tol.dedup]
        return poly[keep]

    def outline(self, z_top: float) -> tuple[tuple[Any, ...], ...]:
        """The exact closed notch outline up to ``z_top`` (mm), counter-clockwise
        in (u, z): circular arcs (three points each) and straight lines, as
        :class:`~tipgeo.cutters.surfaces.NotchPrism` takes it. Main arc
        through the lowest point (0, z_c − r_c); straight sides u = ±r_c up to
        the fillets when depth > r_c; fillets of radius r_s; vertical walls
        from the rim up to ``z_top``; the top closed by a line."""
        r_c, r_s, z_c, z_e = self.r_c, self.r_s, self.z_c, self.z_e
        right: list[tuple[Any, ...]] = []  # pieces of the right half, from the bottom up

        def arc(cu: float, cz: float, r: float, a0: float, a1: float) -> tuple[Any, ...]:
            am = 0.5 * (a0 + a1)
            return ("arc", (cu + r * math.cos(a0), cz + r * math.sin(a0)),
                    (cu + r * math.cos(am), cz + r * math.sin(am)),
                    (cu + r * math.cos(a1), cz + r * math.sin(a1)))

        if r_s > 0:
            uf, zf, ut, zt = self.fillet()
            a_t = 0.0 if self.straight else math.atan2(zt - z_c, ut)
            right.append(arc(0.0, z_c, r_c, -0.5 * math.pi, a_t))
            if self.straight and zf > z_c:
                right.append(("line", (r_c, z_c), (r_c, zf)))
            b0 = math.pi if self.straight else math.atan2(zt - zf, ut - uf)
            right.append(arc(uf, zf, r_s, b0, 0.5 * math.pi))
            w, z_w = uf, z_e
        elif self.straight:
            right.append(arc(0.0, z_c, r_c, -0.5 * math.pi, 0.0))
            w, z_w = r_c, z_c
        else:
            w = self.half_width
            right.append(arc(0.0, z_c, r_c, -0.5 * math.pi, math.atan2(z_e - z_c, w)))
            w, z_w = w, z_e
        right.append(("line", (w, z_w), (w, z_top)))

        def mirror(piece: tuple[Any, ...]) -> tuple[Any, ...]:
            kind, *pts = piece
            return (kind, *[(-u, z) for u, z in reversed(pts)])

        left = [mirror(pc) for pc in reversed(right)]  # from the top down to the bottom
        # the main arc is one piece through the bottom point: join its halves
        (_, l0, lm, _), (_, _, rm, r1) = left[-1], right[0]
        bottom = ("arc", l0, (0.0, z_c - r_c), r1)
        del lm, rm
        pieces = [bottom, *right[1:], ("line", (w, z_top), (-w, z_top)), *left[:-1]]
        return tuple(pieces)

    def bottom(self, u: FloatArray) -> FloatArray:
        """Lowest z of the notch above tangential offset u (+inf outside)."""
        u = np.abs(np.asarray(u, float))
        uf, zf, ut, _ = self.fillet() if self.r_s > 0 else (0, 0, self.half_width, 0)
        w = self.half_width
        out = np.full(u.shape, np.inf)
        on_arc = u <= min(ut, self.r_c)
        out[on_arc] = self.z_c - np.sqrt(np.maximum(self.r_c ** 2 - u[on_arc] ** 2, 0.0))
        if self.r_s > 0:
            on_f = (u > ut) & (u <= uf)
            out[on_f] = zf + np.sqrt(np.maximum(self.r_s ** 2 - (u[on_f] - uf) ** 2, 0.0))
            if self.straight:
                out[(u > ut) & (u <= ut + tol.straight_edge)] = self.z_c
        elif self.straight:
            out[(u <= w)] = np.where(u[u <= w] <= self.r_c, out[u <= w], self.z_c)
        return out

    def signed_distance(self, u: FloatArray, z: FloatArray) -> FloatArray:
        """Exact 2-D signed distance to the notch (< 0 inside), for the part of
        the profile below the rim (the top is open)."""
        u = np.abs(np.asarray(u, float))
        z = np.asarray(z, float)
        r_c, z_c = self.r_c, self.z_c
        # pieces: main arc (lower half up to tangent), side segment, fillet arc
        d_arc = np.abs(np.hypot(u, z - z_c) - r_c)
        ang = np.arctan2(z - z_c, u)
        uf, zf, ut, zt = self.fillet() if self.r_s > 0 else (
            self.r_c, self.z_e, self.half_width, self.z_e)
        # the arc ends where the fillet (or the rim) takes over, or level with
        # its centre where straight sides go on up
        a_t = 0.0 if self.straight else math.atan2(zt - z_c, ut)
        u_t, z_t = (r_c, z_c) if self.straight else (ut, zt)
        # beyond the arc's span use the distance to its end point
        d_arc = np.where(ang <= a_t, d_arc, np.hypot(u - u_t, z - z_t))
        d = d_arc
        if self.straight:
            top = zf if self.r_s > 0 else self.z_e
            zz = np.clip(z, z_c, top)
            d = np.minimum(d, np.hypot(u - r_c, z - zz))
        if self.r_s > 0:
            b = np.arctan2(z - zf, u - uf)
            b0 = math.atan2(zt - zf, ut - uf)
            inside_span = (b >= 0.5 * math.pi) & (b <= b0)
            df = np.where(inside_span, np.abs(np.hypot(u - uf, z - zf) - self.r_s),
                          np.minimum(np.hypot(u - ut, z - zt), np.hypot(u - uf, z - self.z_e)))
            d = np.minimum(d, df)
        # vertical wall above the rim
        w = self.half_width
        d = np.minimum(d, np.where(z >= self.z_e, np.abs(u - w), np.hypot(u - w, z - self.z_e)))
        inside = z > self.bottom(u)
        return np.where(inside, -d, d)


@dataclass(frozen=True)
class SerrationFacts:
    """What a laser program needs to know of a serration cutter
    (:meth:`SerrationCutter.serration_facts`); mm and radians, cannula frame
    (+z along the axis toward the tip, γ about +z from the heel).

    Attributes
    ----------
    arc_radius : float — r_c, the notch arc's radius (mm)
    depth : float — the notch's depth below the rim (mm)
    count : int — n_s, the number of serrations
    spacing : float — ρ, the angle between consecutive serrations (rad)
    rotation : float — γ of the first serration (rad)
    edge_radius : float — r_s, the rounding of the serration edges (mm)
    """

    arc_radius: float
    depth: float
    count: int
    spacing: float
    rotation: float
    edge_radius: float


@dataclass(frozen=True, kw_only=True)
class SerrationCutter(Cutter):
    """Serration arcs on a punch rim (see the module docstring).

    Parameters
    ----------
    arc_radius : float
        r_c (mm), > 0.
    count : int, optional
        n_s serrations evenly spaced (ρ = 2π/n_s). Give ``count`` or ``spacing``.
    spacing : float, optional
        ρ (rad) between consecutive serrations; n_s = ⌊2π/ρ⌋.
    depth : float, optional
        Depth of the notch below the rim (mm); default r_c (a half circle).
    edge_radius : float
        r_s (mm) ≥ 0, rounding of the serration edges.
    rotation : float
        γ of the first serration (rad).
    name : str
        Faces labelled ``cut:<name>``.
    """

    arc_radius: float
    count: int | None = None
    spacing: float | None = None
    depth: float | None = None
    edge_radius: float = 0.0
    rotation: float = 0.0
    name: str = "serrations"
    kind = "serration"
    needs_previous = True
    process = "laser"
    toml_keys = {"arc_radius_mm": "r_c", "count": "n_s", "spacing_deg": "ρ, instead of count",
                 "depth_mm": "default r_c", "edge_radius_mm": "r_s, default 0",
                 "rotation_deg": "γ of the first"}
    optimizer_keys = {"arc_radius_mm": OptimizerKey(),
                      "count": OptimizerKey(integer=True, replaces=("spacing_deg",)),
                      "spacing_deg": OptimizerKey(replaces=("count",)),
                      "depth_mm": OptimizerKey(), "edge_radius_mm": OptimizerKey(),
                      "rotation_deg": OptimizerKey()}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        t.need("arc_radius_mm")
        which = t.one_of("count", "spacing_deg")
        kw: dict[str, Any] = {
            "arc_radius": t.mm("arc_radius_mm"), "depth": t.mm("depth_mm"),
            "rotation": t.deg("rotation_deg", default=0.0), "name": t.str("name", "serrations")}
        if "edge_radius_mm" in t:
            kw["edge_radius"] = t.mm("edge_radius_mm")
        if which == "count":
            kw["count"] = t.int("count")
        else:
            kw["spacing"] = t.deg("spacing_deg")
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"arc_radius_mm": self.arc_radius}
        if self.count is not None:
            d["count"] = self.count
        else:
            d["spacing_deg"] = _r(math.degrees(self.rho))
        d["depth_mm"] = self.depth
        d["edge_radius_mm"] = self.edge_radius
        if self.rotation:
            d["rotation_deg"] = _r(math.degrees(self.rotation))
        return d

    def __post_init__(self) -> None:
        r_c = v.feature_length("arc_radius", self.arc_radius, hi=50.0)
        object.__setattr__(self, "arc_radius", r_c)
        if (self.count is None) == (self.spacing is None):
            raise SpecError("give exactly one of count (n_s) and spacing (rho); got "
                            f"count = {self.count!r}, spacing = {self.spacing!r}")
        if self.count is not None:
            n = v.integer("count", self.count, lo=1, hi=10 ** 9)
            if n > MAX_SERRATIONS:
                raise SpecError(f"count = {n} serrations is out of range; allowed 1 ≤ value ≤ "
                                f"{MAX_SERRATIONS} (the build's cost grows with the count; cut "
                                "more in several passes of fewer)")
            object.__setattr__(self, "count", n)
        else:
            sp = v.angle("spacing", self.spacing, lo=0.0, hi=2 * math.pi, lo_open=True)
            if math.floor(2 * math.pi / sp + tol.rel) > MAX_SERRATIONS:
                raise SpecError(f"spacing = {math.degrees(sp):.6g}° gives "
                                f"{math.floor(2 * math.pi / sp + tol.rel):,} serrations; allowed "
                                f"spacing > {360 / (MAX_SERRATIONS + 1):.6g}° (at most "
                                f"{MAX_SERRATIONS} serrations: the build's cost grows with the "
                                "count)")
            object.__setattr__(self, "spacing", sp)
        depth = r_c if self.depth is None else v.feature_length("depth", self.depth, hi=1000.0)
        object.__setattr__(self, "depth", depth)
        object.__setattr__(self, "edge_radius",
                           v.length("edge_radius", self.edge_radius, lo=0.0, lo_open=False,
                                    hi=50.0))
        object.__setattr__(self, "rotation", v.angle("rotation", self.rotation))
        check_name(self.name)

    @property
    def n(self) -> int:
        """Number of serrations n_s."""
        if self.count is not None:
            return self.count
        return max(1, int(math.floor(2 * math.pi / self.rho + tol.rel)))

    @property
    def symmetry_order(self) -> int:
        return self.count if self.count is not None else 1

    @property
    def rho(self) -> float:
        """Spacing ρ (rad)."""
        if self.spacing is not None:
            return self.spacing
        return 2 * math.pi / cast(int, self.count)  # __post_init__: one of the two is set

    @property
    def _depth(self) -> float:
        """Depth (mm): ``__post_init__`` replaces None by the arc radius."""
        return cast(float, self.depth)

    def serration_facts(self) -> SerrationFacts:
        """The serrations as a laser program cuts them (:class:`SerrationFacts`:
        r_c, depth, n_s, ρ, first γ, r_s; mm and rad): what :mod:`gcode`
        asks of the cutter instead of reading its fields."""
        depth = self.depth if self.depth is not None else self.arc_radius
        return SerrationFacts(arc_radius=self.arc_radius, depth=depth, count=self.n,
                              spacing=self.rho, rotation=self.rotation,
                              edge_radius=self.edge_radius)

    def sharp(self) -> SerrationCutter:
        """The same serrations with sharp edges (r_s = 0): what the laser cuts,
        its beam leaving no edge fillet (the CAD that
        :func:`gcode.ablation.compare_with_cutter` compares a simulated cut with)."""
        return SerrationCutter(arc_radius=self.arc_radius, count=self.count,
                               spacing=self.spacing, depth=self.depth, edge_radius=0.0,
                               rotation=self.rotation, name=self.name)

    def angles(self) -> FloatArray:
        """γ_k of every serration (rad)."""
        return self.rotation + self.rho * np.arange(self.n, dtype=np.float64)

    def face_labels(self) -> tuple[str, ...]:
        return (self.label,)

    def check(self, cannula: Cannula) -> None:
        """Reject serrations wider than the wall allows or overlapping."""
        prof = SerrationProfile(self.arc_radius, self._depth, self.edge_radius, 0.0)
        w = prof.half_width
        if not w < cannula.r_i:
            raise SpecError(f"arc_radius = {self.arc_radius:.6g} mm with edge_radius = "
                            f"{self.edge_radius:.6g} mm makes notches {2 * w:.4g} mm wide; "
                            f"allowed narrower than the bore ({2 * cannula.r_i:.4g} mm)")
        need = 2 * math.asin(w / cannula.r_i)
        if self.n > 1 and self.rho < need * (1 + tol.rel):
            n_max = int(math.floor(2 * math.pi / need))
            which = (f"count = {self.count}" if self.count is not None
                     else f"spacing = {math.degrees(self.rho):.6g}°")
            raise SpecError(
                f"{which}: serrations of arc_radius {self.arc_radius * 1e3:.6g} µm overlap on "
                f"the inner wall; allowed spacing ≥ {math.degrees(need):.4g}° "
                f"(count ≤ {n_max})")
        if self.count is None and 2 * math.pi - (self.n - 1) * self.rho < need * (1 - tol.rel):
            raise SpecError(f"spacing = {math.degrees(self.rho):.6g}°: the last serration "
                            "overlaps the first; allowed 2π/spacing close to a whole number")

    def rim_heights(self, cannula: Cannula, previous: tuple[Cutter, ...]) -> FloatArray:
        """Rim height z_e (mm) on the inner wall at every serration."""
        g = self.angles()
        zs = []
        for c in previous:
            z = c.edge_z(g, cannula.r_i, cannula)
            if z is not None:
                zs.append(np.asarray(z, float))
        if not zs:
            raise SpecError(f"serration cutter '{self.name}' needs a preceding cutter with a "
                            "known edge height (e.g. conical) to cut into; allowed after "
                            "bevel, multiplane, lancet, conical or helical cutters")
        return np.asarray(np.min(zs, axis=0), dtype=np.float64)

    def profiles(self, cannula: Cannula,
                 previous: tuple[Cutter, ...]) -> list[SerrationProfile]:
        """The notch profile of every serration."""
        out = []
        for z_e in self.rim_heights(cannula, previous):
            if not z_e - self.depth > -cannula.length:
                raise SpecError(f"depth = {self.depth:.6g} mm reaches the base of the cannula "
                                f"(rim at z = {z_e:.4g} mm, length {cannula.length:.4g} mm)")
            out.append(SerrationProfile(self.arc_radius, self._depth, self.edge_radius,
                                        float(z_e)))
        return out

    def z_upper(self, cannula: Cannula) -> float:
        return math.inf

    def exact_bounds(self, cannula: Cannula,
                     previous: tuple[Cutter, ...] = ()) -> tuple[Surface, ...] | None:
        """One :class:`~tipgeo.cutters.surfaces.NotchPrism` per serration (the
        notches are removed): the exact outline (:meth:`SerrationProfile.outline`)
        up to above the preceding cutters' material, through the wall as in
        :meth:`solid`."""
        if not previous:
            return None
        self.check(cannula)
        tops = [c.z_upper(cannula) for c in previous]
        top = min(t for t in tops if math.isfinite(t)) if any(map(math.isfinite, tops)) else None
        if top is None:
            return None
        margin = tol.margin_ratio * cannula.r_o
        out = []
        for g, prof in zip(self.angles(), self.profiles(cannula, previous)):
            r0 = 0.5 * math.sqrt(cannula.r_i ** 2 - prof.half_width ** 2)
            out.append(NotchPrism(prof.outline(max(top, prof.z_e) + 2 * margin), float(g), r0,
                                  cannula.r_o + margin, self.label))
        return tuple(out)

    def solid(self, ctx: BuildContext) -> Any:
        cannula = ctx.cannula
        self.check(cannula)
        notches = []
        for g, prof in zip(self.angles(), self.profiles(cannula, ctx.previous)):
            # the inner cap of the prism lies in the bore, clear of both walls
            r0 = 0.5 * math.sqrt(cannula.r_i ** 2 - prof.half_width ** 2)
            thick = cannula.r_o + ctx.margin - r0
            poly = prof.polygon(ctx.chordal, ctx.z_hi + ctx.margin)
            prism = ctx.prism(poly, thick, self.label)
            w = np.array([math.cos(g), math.sin(g), 0.0])
            u = np.array([-math.sin(g), math.cos(g), 0.0])
            mat = np.stack([u, [0.0, 0.0, 1.0], w, r0 * w], 1)
            notches.append(prism.transform(mat))
        big = ctx.frustum(ctx.z_lo, ctx.reach, ctx.z_hi, ctx.reach, AUX, AUX)
        return big - m3d.Manifold.batch_boolean(notches, m3d.OpType.Add)

    def _local(self, p: FloatArray) -> tuple[IntArray, FloatArray, FloatArray]:
        g = self.angles()
        ang = np.arctan2(p[:, 1], p[:, 0])
        k = np.rint((ang - self.rotation) / self.rho).astype(int) % self.n
        gk = g[k]
        u = -np.sin(gk) * p[:, 0] + np.cos(gk) * p[:, 1]
        return k, gk, u

    def implicit(self, points: FloatArray, cannula: Cannula,
                 previous: tuple[Cutter, ...] = ()) -> tuple[FloatArray, FloatArray]:
        """Signed distance (mm) to the nearest notch, > 0 inside a notch
        (removed), with its gradient by central differences (h = 1e-7 mm).
        ``previous`` are the cutters before this one (they set the rim)."""
        p = np.asarray(points, float).reshape(-1, 3)
        profs = self.profiles(cannula, previous)

        def f(q: FloatArray) -> FloatArray:
            k, _, u = self._local(q)
            out = np.empty(len(q))
            for j in np.unique(k):
                s = k == j
                out[s] = -profs[j].signed_distance(u[s], q[s, 2])
            return out

        h = tol.fd_step_fine
        val = f(p)
        grad = np.stack([(f(p + h * e) - f(p - h * e)) / (2 * h) for e in np.eye(3)], 1)
        return val, grad

    def edge_faces(self, gamma: FloatArray, radius: float | FloatArray, cannula: Cannula,
                   previous: tuple[Cutter, ...] = ()) -> tuple[FloatArray, AnyArray] | None:
        """Notch bottoms on the cylinder: face ``cut:<name>.arc`` or
        ``cut:<name>.fillet`` (+inf between notches; the straight sides are
        vertical and appear as jumps of the edge)."""
        if not previous:
            return None
        g = np.asarray(gamma, float).ravel()
        p = np.stack([radius * np.cos(g), radius * np.sin(g), np.zeros_like(g)], 1)
        k, _, u = self._local(p)
        profs = self.profiles(cannula, previous)
        z = np.full(g.shape, np.inf)
        face = np.full(g.shape, self.label, dtype=object)
        for j in np.unique(k):
            s = k == j
            pr = profs[j]
            z[s] = pr.bottom(u[s])
            ut = pr.fillet()[2] if pr.r_s > 0 else pr.half_width
            on_arc = np.abs(u[s]) <= min(ut, pr.r_c)
            face[s] = np.where(on_arc, f"{self.label}.arc", f"{self.label}.fillet")
        return z.reshape(np.shape(gamma)), face.reshape(np.shape(gamma))

    def normals(self, points: FloatArray, cannula: Cannula,
                previous: tuple[Cutter, ...] = ()) -> FloatArray:
        _, g = self.implicit(points, cannula, previous=previous)
        return np.asarray(g / np.linalg.norm(g, axis=1, keepdims=True), dtype=np.float64)

    def edge_z(self, gamma: FloatArray, radius: float | FloatArray, cannula: Cannula,
               previous: tuple[Cutter, ...] = ()) -> FloatArray | None:
        """Lowest z of the notches on the cylinder of ``radius`` (+inf between
        notches); needs the preceding cutters for the rim heights."""
        found = self.edge_faces(gamma, radius, cannula, previous)
        return None if found is None else found[0]
