"""Ablation simulator: a laser toolpath → the serrated tip it cuts.

Frames: the machine frame of :mod:`gcode.interpreter` (X along the rim, Y
along the punch axis, +Y into the material, C the punch's rotation in
degrees) is mapped onto the punch in the cannula frame (+z along the axis
towards the tip; γ about +z; mm):

=========================  =================================================
machine                    cannula frame
=========================  =================================================
X − X0                     u, tangential offset from the serration centre
Y − Y0                     z_rim − z (depth below the rim, the inner-wall edge)
C + γ0 (deg)               γ of the serration centre line
beam (machine −Z)          radial, through the wall
=========================  =================================================

Every beam-on move sweeps the beam spot (a disc of the beam radius) in the
(u, z) plane; the swept region of each C position is extruded radially
through the wall and subtracted from the tip. Material the cuts isolate (the
slug inside a notch contour) falls out: the largest piece is kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypedDict, runtime_checkable

import manifold3d as m3d
import numpy as np

from tipgeo.arrays import FloatArray, IntArray
from tipgeo.errors import TipGeoError
from tipgeo.tip import Tip
from tipgeo.tolerances import tol

from .emitter import laser_serrations
from .errors import GCodeError
from .interpreter import Segment, Toolpath
from .motion import Point

if TYPE_CHECKING:
    from tipgeo.cannula import Cannula
    from tipgeo.construct import BuildContext
    from tipgeo.cutters.base import Cutter
    from tipgeo.spec import TipSpec

__all__ = ["ablate", "AblationResult", "swept_region", "compare_with_cutter", "notch_arcs",
           "Comparison", "RadiusFigures", "SpacingFigures", "NotchFigures", "NotchArcs"]


@dataclass
class AblationResult:
    """The ablated tip and what was cut (mm, degrees)."""

    tip: Tip
    c_angles_deg: list[float]
    notches: int
    slugs_removed: int


class RadiusFigures(TypedDict):
    """The notch radius (mm): the spec's, the fitted mean and largest error."""

    spec: float
    fitted_mean: float | None
    fitted_max_error: float | None


class SpacingFigures(TypedDict):
    """The notch spacing (degrees): the spec's and the largest fitted error."""

    spec: float
    fitted_max_error: float | None


class NotchFigures(TypedDict):
    """One notch of :func:`compare_with_cutter` (mm; its C angle in degrees)."""

    c_deg: float
    radius_mm: float | None
    radius_error_mm: float | None
    material_left_mm: float
    overcut_mm: float


class Comparison(TypedDict):
    """What :func:`compare_with_cutter` found (mm, degrees)."""

    notches_sim: int
    notches_cad: int
    radius_mm: RadiusFigures
    spacing_deg: SpacingFigures
    hausdorff_mm: float
    material_left_mm: float
    overcut_mm: float
    tolerance_mm: float
    inner_radius_mm: float
    slugs_removed: int
    per_notch: list[NotchFigures]


class NotchArcs(TypedDict):
    """The beam-on arcs of one notch (:func:`notch_arcs`; mm, degrees)."""

    c_deg: float
    arcs: int
    min_radius_mm: float | None
    max_radius_mm: float | None


@runtime_checkable
class _Sharpens(Protocol):
    """A laser cutter that gives its sharp-edged self
    (:meth:`tipgeo.cutters.serration.SerrationCutter.sharp`)."""

    def sharp(self) -> Cutter: ...


def _disc(center: Point, r: float, chordal: float) -> FloatArray:
    n = max(12, math.ceil(math.pi / math.acos(max(1 - chordal / r, -1.0)))) if r > chordal else 12
    a = np.linspace(0, 2 * math.pi, n, endpoint=False)
    return np.stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a)], 1)


def _stadium(p: Point, q: Point, r: float, chordal: float) -> FloatArray:
    """Polygon of the segment pq swept by a disc of radius r (CCW)."""
    d = np.subtract(q, p)
    L = float(np.hypot(*d))
    if L < tol.gcode.length:
        return _disc(p, r, chordal)
    ang = math.atan2(d[1], d[0])
    n = max(6, math.ceil(math.pi / (2 * math.acos(max(1 - chordal / r, -1.0)))))
    a1 = ang - math.pi / 2 + np.linspace(0, math.pi, n + 1)      # cap around q
    a2 = ang + math.pi / 2 + np.linspace(0, math.pi, n + 1)      # cap around p
    cap_q = np.stack([q[0] + r * np.cos(a1), q[1] + r * np.sin(a1)], 1)
    cap_p = np.stack([p[0] + r * np.cos(a2), p[1] + r * np.sin(a2)], 1)
    return np.concatenate([cap_q, cap_p])


def _arc_band(seg: Segment, r: float, chordal: float) -> list[FloatArray]:
    """Polygon of an arc swept by a disc of radius r."""
    R = seg.radius
    c = seg.center
    if c is None:               # not an arc: its chord
        return [_stadium(seg.start, seg.end, r, chordal)]
    sweep = seg.sweep
    a0 = math.atan2(seg.start[1] - c[1], seg.start[0] - c[0])
    if abs(sweep) >= 2 * math.pi - tol.gcode.full_turn:
        outer = _disc(c, R + r, chordal)
        if R - r > tol.gcode.point:
            inner = _disc(c, R - r, chordal)[::-1]
            return [outer, inner]
        return [outer]
    ro = R + r
    step = 2 * math.acos(max(1 - chordal / ro, -1.0))
    n = max(4, math.ceil(abs(sweep) / step))
    a = a0 + np.linspace(0, sweep, n + 1)
    if sweep < 0:
        a = a[::-1]  # run CCW
    outer = np.stack([c[0] + ro * np.cos(a), c[1] + ro * np.sin(a)], 1)
    ri = max(R - r, 0.0)
    inner = np.stack([c[0] + ri * np.cos(a[::-1]), c[1] + ri * np.sin(a[::-1])], 1)
    band = np.concatenate([outer, inner])
    ends = [_disc(seg.start, r, chordal), _disc(seg.end, r, chordal)]
    return [band] + ends


def swept_region(segments: list[Segment], beam_radius: float,
                 chordal: float) -> m3d.CrossSection:
    """The 2-D region (machine X, Y) the beam disc sweeps along ``segments``,
    as a manifold3d CrossSection."""
    polys = []
    seen: set[tuple[object, ...]] = set()
    for s in segments:
        key = (s.kind, round(s.start[0], 9), round(s.start[1], 9), round(s.end[0], 9),
               round(s.end[1], 9), None if s.center is None else
               (round(s.center[0], 9), round(s.center[1], 9), s.ccw))
        if key in seen:
            continue  # a finishing pass repeats the same path
        seen.add(key)
        if s.kind == "arc" and s.radius > 0:
            for p in _arc_band(s, beam_radius, chordal):
                polys.append(m3d.CrossSection([p]))
        else:
            polys.append(m3d.CrossSection([_stadium(s.start, s.end, beam_radius, chordal)]))
    if not polys:
        return m3d.CrossSection()
    return m3d.CrossSection.batch_boolean(polys, m3d.OpType.Add)


def ablate(toolpath: Toolpath, spec: TipSpec, *, beam_diameter: float = 0.020,
           origin: tuple[float, float] = (0.0, 0.0), gamma0_deg: float = 0.0,
           tolerance: float | None = None) -> AblationResult:
    """Cut the beam-on moves of ``toolpath`` into the tip of ``spec`` (its
    cutters before any serration cutter: the plain punch).

    Parameters
    ----------
    toolpath : Toolpath — from :func:`gcode.interpreter.interpret`
    spec : TipSpec — the punch (a serration cutter in it is ignored)
    beam_diameter : float — mm
    origin : (X0, Y0) — program coordinates of the serration centre on the rim
    gamma0_deg : float — γ of C = 0
    tolerance : float — chordal tolerance of the cut (mm); default the build's
    """
    from tipgeo import progress as pg
    from tipgeo.build import build_tip
    from tipgeo.construct import BuildContext

    base_cutters = [c for c in spec.cutters if c.process != "laser"]
    if not base_cutters:
        raise GCodeError("the spec has no punch cutter to ablate (only serrations)")
    plain = spec.with_(cutters=base_cutters)
    tip0 = build_tip(plain, tolerance=tolerance)
    chordal = tip0.tolerance if tip0.tolerance is not None else tol.chordal
    cannula = plain.cannula
    r_b = beam_diameter / 2
    if not r_b > 0:
        raise GCodeError(f"beam_diameter = {beam_diameter:g} mm must be positive")
    groups = _beam_groups(toolpath)
    names = _label_names(tip0)
    mesh = m3d.Mesh64(np.array(tip0.vertices, order="C"),
                      np.array(tip0.faces, dtype=np.uint64, order="C"),
                      face_id=np.array(tip0.label_ids, dtype=np.uint64))
    solid = m3d.Manifold(mesh)
    ctx = BuildContext(cannula=cannula, chordal=chordal, segments=tip0.segments or 360,
                       z_bottom=-cannula.length, z_top=float(tip0.bounds[1, 2]))
    ctx.labels.names = names
    cuts: list[m3d.Manifold] = []
    notches = 0
    bar = pg.bar(len(groups), "laser: ablation", unit="notch")
    for c_deg, segs in sorted(groups.items()):
        bar.update()
        gamma = math.radians(c_deg + gamma0_deg)
        polys = _notch_polygons(segs, gamma, c_deg, tuple(base_cutters), cannula, r_b, chordal,
                                origin)
        if polys is None:
            continue
        cuts += _notch_prisms(ctx, polys, gamma, c_deg, cannula)
        notches += 1
    bar.close()
    if cuts:
        with pg.stage("laser: ablation (boolean)"):
            solid = solid - m3d.Manifold.batch_boolean(cuts, m3d.OpType.Add)
    if solid.status() != m3d.Error.NoError or solid.is_empty():
        raise TipGeoError(f"ablation left no valid solid ({solid.status()})")
    parts = solid.decompose()
    parts.sort(key=lambda m: m.volume(), reverse=True)
    out = parts[0].to_mesh64()
    v = np.asarray(out.vert_properties)[:, :3]
    f = np.asarray(out.tri_verts).astype(np.int64)
    ids = np.asarray(out.face_id).astype(np.int64)
    tip = Tip(v, f, ids, tuple(names), spec=None, tolerance=chordal, segments=tip0.segments,
              source="laser simulation",
              meta={"c_angles_deg": sorted(groups), "slugs": len(parts) - 1})
    return AblationResult(tip, sorted(groups), notches, len(parts) - 1)


def _beam_groups(toolpath: Toolpath) -> dict[float, list[Segment]]:
    """The beam-on moves grouped by their C angle (degrees); C must not move
    while the beam fires."""
    on = [s for s in toolpath.segments if s.beam]
    if not on:
        raise GCodeError("the program never fires the laser (no PSOCONTROL … FIRE moves)")
    groups: dict[float, list[Segment]] = {}
    for s in on:
        if abs(s.c1 - s.c0) > tol.gcode.c_angle:
            raise GCodeError(f"line {s.line}: the beam fires during a C move; the simulator "
                             "needs C fixed while cutting")
        groups.setdefault(round(s.c0, 9), []).append(s)
    return groups


def _label_names(tip0: Tip) -> list[str]:
    """The plain tip's face labels with ``cut:laser`` and ``aux`` added."""
    names = list(tip0.label_names)
    for extra in ("cut:laser", "aux"):
        if extra not in names:
            names.append(extra)
    return names


def _notch_polygons(segs: list[Segment], gamma: float, c_deg: float, prev: tuple[Cutter, ...],
                    cannula: Cannula, r_b: float, chordal: float,
                    origin: tuple[float, float]) -> list[FloatArray] | None:
    """The region the beam sweeps at one C angle, in the (u, z) frame of the
    rim there (mm), or None if it is empty."""
    edges = [cut.edge_z(np.array([gamma]), cannula.r_i, cannula) for cut in prev]
    z_rim = min(float(np.min(np.atleast_1d(z))) for z in edges if z is not None)
    region = swept_region(segs, r_b, chordal)
    if region.is_empty():
        return None
    x0, y0 = origin
    # machine (X, Y) → (u, z): u = X − X0, z = z_rim − (Y − Y0)
    polys = []
    for poly in region.to_polygons():
        p = np.asarray(poly, float)
        q = np.stack([p[:, 0] - x0, z_rim - (p[:, 1] - y0)], 1)
        polys.append(q[::-1])  # the Y flip mirrors: keep CCW
    return polys


def _notch_prisms(ctx: BuildContext, polys: list[FloatArray], gamma: float, c_deg: float,
                  cannula: Cannula) -> list[m3d.Manifold]:
    """Prisms through the wall at angle ``gamma`` for the notch polygons."""
    half = max(float(np.abs(np.concatenate(polys)[:, 0]).max()), tol.gcode.half_floor)
    if not half < cannula.r_i:
        raise GCodeError(f"the cut at C = {c_deg:g}° is {2 * half:.4g} mm wide; wider "
                         f"than the bore ({2 * cannula.r_i:.4g} mm)")
    r0 = 0.5 * math.sqrt(cannula.r_i ** 2 - half ** 2)
    thick = cannula.r_o + ctx.margin - r0
    w = np.array([math.cos(gamma), math.sin(gamma), 0.0])
    u = np.array([-math.sin(gamma), math.cos(gamma), 0.0])
    mat = np.stack([u, [0.0, 0.0, 1.0], w, r0 * w], 1)
    cuts = []
    for q in polys:
        sec = m3d.CrossSection([q])
        if sec.area() <= 0:
            continue
        for part in sec.decompose():
            for outline in part.to_polygons():
                poly = np.asarray(outline, float)
                if len(poly) >= 3:
                    cuts.append(_prism(ctx, poly, thick, "cut:laser").transform(mat))
    return cuts


def _prism(ctx: BuildContext, poly: FloatArray, thick: float, label: str) -> m3d.Manifold:
    """A prism over ``poly`` whose outline may hold holes: triangulate the
    outline only (the holes are separate decomposed parts)."""
    area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    if area < 0:
        poly = poly[::-1]
    return ctx.prism(poly, thick, label)


def compare_with_cutter(result: AblationResult, spec: TipSpec, *,
                        beam_diameter: float = 0.020) -> Comparison:
    """Compare an ablated tip with the serration cutter of ``spec`` built
    exactly (edge radius 0, the laser cuts sharp edges): notch count, fitted
    notch radius and spacing, the Hausdorff distance, and its two signed
    parts: ``material_left_mm`` (the farthest the simulated part stands
    outside the CAD solid) and ``overcut_mm`` (the farthest CAD's surface
    lies outside the simulated part) (mm, degrees; vertex-sampled, so each
    includes up to the meshes' chordal tolerance ``tolerance_mm``)."""
    import trimesh

    from tipgeo.build import build_tip

    ser = [c for c in spec.cutters if c.process == "laser"]
    if len(ser) != 1 or not isinstance(ser[0], _Sharpens):
        raise GCodeError("the spec needs exactly one serration cutter to compare with")
    s = ser[0]
    facts = laser_serrations(spec)
    sharp = s.sharp()
    cad_spec = spec.with_(cutters=[c if c is not s else sharp for c in spec.cutters])
    cad = build_tip(cad_spec, tolerance=result.tip.tolerance)
    sim = result.tip
    chordal = sim.tolerance if sim.tolerance is not None else tol.chordal
    # notch radius: circle fit to the laser faces' vertices on the inner wall, per notch
    cannula = spec.cannula
    v = sim.vertices[np.unique(sim.faces[sim.mask("cut:laser")])]
    rho = np.hypot(v[:, 0], v[:, 1])
    wall = np.abs(rho - cannula.r_i) < 2 * chordal + tol.gcode.point
    pts = v[wall]
    ang = np.arctan2(pts[:, 1], pts[:, 0])
    radii: list[float] = []
    centers: list[float] = []
    fitted: dict[float, float] = {}
    rim = float(cad.bounds[1, 2])
    for g in result.c_angles_deg:
        gr = math.radians(g) + facts.rotation
        d = np.angle(np.exp(1j * (ang - gr)))
        sel = np.abs(d) < facts.spacing / 2
        p = pts[sel]
        if len(p) < 5:
            continue
        u = cannula.r_i * np.sin(np.angle(np.exp(1j * (np.arctan2(p[:, 1], p[:, 0]) - gr))))
        z = p[:, 2]
        # the arc well below the rim: not the lead-in nor a bite at the rim corner
        below = z < rim - 0.25 * facts.arc_radius
        u, z = u[below], z[below]
        A = np.stack([u, z, np.ones_like(u)], 1)
        b = u ** 2 + z ** 2
        sol, *_ = np.linalg.lstsq(A, b, rcond=None)
        cu, cz = sol[0] / 2, sol[1] / 2
        radii.append(math.sqrt(sol[2] + cu ** 2 + cz ** 2))
        centers.append(math.degrees(gr + math.asin(np.clip(cu / cannula.r_i, -1, 1))))
        fitted[g] = radii[-1]
    spacing = np.diff(sorted(centers)) if len(centers) > 1 else np.array([])
    ma = trimesh.Trimesh(sim.vertices, sim.faces, process=False)
    mb = trimesh.Trimesh(cad.vertices, cad.faces, process=False)
    proximity: Any = trimesh.proximity          # trimesh's functions are untyped
    d_ab = proximity.closest_point(mb, sim.vertices)[1].max()
    d_ba = proximity.closest_point(ma, cad.vertices)[1].max()
    # signed (+ inside): a simulated vertex outside CAD is material left; a
    # CAD vertex outside the simulated part was cut away
    sd_sim = -proximity.signed_distance(mb, sim.vertices)
    sd_cad = -proximity.signed_distance(ma, cad.vertices)
    left, over = float(sd_sim.max()), float(sd_cad.max())
    per_notch = _per_notch(result.c_angles_deg, facts.rotation, fitted, sim.vertices, sd_sim,
                           cad.vertices, sd_cad, facts.arc_radius)
    return {"notches_sim": result.notches, "notches_cad": facts.count,
            "radius_mm": {"spec": facts.arc_radius,
                          "fitted_mean": float(np.mean(radii)) if radii else None,
                          "fitted_max_error": float(np.max(np.abs(np.array(radii)
                                                                  - facts.arc_radius)))
                          if radii else None},
            "spacing_deg": {"spec": math.degrees(facts.spacing),
                            "fitted_max_error": float(np.max(np.abs(
                                spacing - math.degrees(facts.spacing))))
                            if len(spacing) else None},
            "hausdorff_mm": float(max(d_ab, d_ba)),
            "material_left_mm": max(left, 0.0), "overcut_mm": max(over, 0.0),
            "tolerance_mm": float(chordal), "inner_radius_mm": float(cannula.r_i),
            "slugs_removed": result.slugs_removed, "per_notch": per_notch}


def _per_notch(c_angles_deg: list[float], rotation: float, fitted: dict[float, float],
               v_sim: FloatArray, left_sim: FloatArray, v_cad: FloatArray,
               over_cad: FloatArray, arc_radius: float) -> list[NotchFigures]:
    """Each notch's figures: the vertices of both meshes go to the notch
    nearest in angle about the axis (γ = C + the cutter's rotation); per
    notch the fitted radius (mm; None where too few wall points), its error,
    and the largest material left and overcut in its sector (mm, ≥ 0)."""
    cs = np.radians(np.asarray(c_angles_deg, float)) + rotation
    if len(cs) == 0:
        return []

    def nearest(v: FloatArray) -> IntArray:
        a = np.arctan2(v[:, 1], v[:, 0])
        d = np.abs(np.angle(np.exp(1j * (a[:, None] - cs[None, :]))))
        index: IntArray = np.argmin(d, axis=1)
        return index

    ns, nc = nearest(v_sim), nearest(v_cad)
    out: list[NotchFigures] = []
    for j, g in enumerate(c_angles_deg):
        r = fitted.get(g)
        ls, oc = left_sim[ns == j], over_cad[nc == j]
        out.append({"c_deg": float(g),
                    "radius_mm": None if r is None else float(r),
                    "radius_error_mm": None if r is None else float(abs(r - arc_radius)),
                    "material_left_mm": float(max(ls.max(), 0.0)) if ls.size else 0.0,
                    "overcut_mm": float(max(oc.max(), 0.0)) if oc.size else 0.0})
    return out


def notch_arcs(toolpath: Toolpath) -> list[NotchArcs]:
    """The beam-on arcs of each notch (grouped by the C angle they are cut
    at): how many, and the smallest and largest radius of the beam centre's
    path (mm, after cutter compensation; 0 where an arc collapsed to its
    centre). Shows whether a program's per-notch variables (Appendix C's
    roughing ``$radius``) start each notch afresh: equal figures at every C
    when they do."""
    groups: dict[float, list[float]] = {}
    for s in toolpath.segments:
        if s.beam and s.kind == "arc":
            groups.setdefault(round(s.c0, 9), []).append(s.radius)
        elif s.beam:
            groups.setdefault(round(s.c0, 9), [])
    return [{"c_deg": float(c), "arcs": len(r),
             "min_radius_mm": float(min(r)) if r else None,
             "max_radius_mm": float(max(r)) if r else None}
            for c, r in sorted(groups.items())]
