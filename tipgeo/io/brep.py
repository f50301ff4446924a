"""The exact B-rep of a tip spec through OpenCASCADE (OCP): the tube and every
cutter's kept material as exact solids, intersected by OCCT booleans.

Frame and units: cannula frame (+z along the needle axis towards the tip,
heel at z = 0), mm.

The tube r_i ≤ ρ ≤ r_o, −length ≤ z ≤ z_top is two exact cylinders and two
planes. Each cutter gives its kept material as the intersection of the kept
sides of exact surfaces (:meth:`~tipgeo.cutters.base.Cutter.exact_bounds`):

* :class:`~tipgeo.cutters.surfaces.Plane` — a half-space, built as a prism
  of a planar face (an exact plane);
* :class:`~tipgeo.cutters.surfaces.ConeSurface` — the solid cone
  ρ ≤ r_o − z tan θ (an exact cone);
* :class:`~tipgeo.cutters.surfaces.HeightSurface` — the material below a
  height field (the helicoid): a bicubic B-spline interpolating the exact
  heights on a square grid around the wall, refined until its height is within
  ``tol.step_fit_share`` × the build tolerance of the exact surface at every
  cell centre and edge midpoint, extruded downwards;
* :class:`~tipgeo.cutters.surfaces.NotchPrism` — material removed (the
  serration notches): a prism over an outline of exact lines and circular
  arcs, extruded radially through the wall.

The tip is the tube ∩ every kept material (BRepAlgoAPI_Common) minus every
removed prism (BRepAlgoAPI_Cut), with faces of one surface merged again
(ShapeUpgrade_UnifySameDomain). OCP is imported
where used; without it the functions raise :class:`ExportError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ..errors import ExportError, MissingToolError
from ..tolerances import tol

__all__ = ["ExactSolid", "exact_solid", "exact_supported", "occ", "OcpMissing", "ocp_missing"]

#: How to get OCP, for messages.
OCP_INSTALL = 'pip install "tipgeo[step]"'


class OcpMissing(MissingToolError, ExportError):
    """The OpenCASCADE bindings OCP are not installed: a missing external
    tool (exit 3), and a file that could not be written for callers that
    catch :class:`~tipgeo.errors.ExportError`."""


def ocp_missing(exc: ImportError) -> OcpMissing:
    """The error for a failed OCP import, with the install line."""
    return OcpMissing(f"STEP export needs the OpenCASCADE bindings OCP, which are not "
                      f"installed ({exc}); install them with: {OCP_INSTALL}")


def occ() -> SimpleNamespace:
    """The OCP modules the exact B-rep uses (:class:`OcpMissing`, an
    ExportError, if OCP is missing)."""
    try:
        from OCP import (
            GC,
            BRepAlgoAPI,
            BRepBuilderAPI,
            BRepCheck,
            BRepGProp,
            BRepPrimAPI,
            GeomAPI,
            GProp,
            ShapeUpgrade,
            TopAbs,
            TopExp,
            TopoDS,
            gp,
        )
        from OCP.collections import Array2_double
    except ImportError as exc:
        raise ocp_missing(exc) from exc
    return SimpleNamespace(BRepAlgoAPI=BRepAlgoAPI, BRepBuilderAPI=BRepBuilderAPI,
                           BRepCheck=BRepCheck, BRepGProp=BRepGProp, BRepPrimAPI=BRepPrimAPI,
                           GeomAPI=GeomAPI, GProp=GProp, ShapeUpgrade=ShapeUpgrade,
                           TopAbs=TopAbs, TopExp=TopExp, TopoDS=TopoDS, gp=gp, GC=GC,
                           Array2_double=Array2_double)


@dataclass
class ExactSolid:
    """An exact tip solid and how it was made.

    Attributes
    ----------
    shape : OCP TopoDS_Solid — mm, cannula frame
    fits : list of dict — per fitted height field: ``label``, ``grid`` (nodes
        per side), ``max_error_mm`` (largest height error found at the check
        points) and ``tolerance_mm`` (what it had to stay within)
    faces : dict — surface type (``Plane``, ``Cylinder``, ``Cone``,
        ``BSplineSurface``, …) → number of faces
    """

    shape: object
    fits: list = field(default_factory=list)
    faces: dict = field(default_factory=dict)

    @property
    def volume(self) -> float:
        """Volume (mm³) by OCCT's adaptive integration to a relative error of
        ``tol.rel`` (its default fixed-order Gauss rule was 0.06 % off on
        the calibrated helicoid's trimmed B-spline face)."""
        o = occ()
        props = o.GProp.GProp_GProps()
        o.BRepGProp.BRepGProp.VolumeProperties_s(self.shape, props, tol.rel)
        return float(props.Mass())

    def is_valid(self) -> bool:
        """BRepCheck_Analyzer's verdict on the solid."""
        return bool(occ().BRepCheck.BRepCheck_Analyzer(self.shape).IsValid())


def exact_supported(spec) -> str | None:
    """None when every cutter of ``spec`` gives exact bounds, else the reason
    (naming the first cutter that does not)."""
    if spec is None:
        return "the tip has no spec (simulated or imported): only its mesh is known"
    for k, c in enumerate(spec.cutters):
        if c.exact_bounds(spec.cannula, tuple(spec.cutters[:k])) is None:
            return (f"cutter '{c.name}' ({c.kind}) has no exact surface description "
                    f"(Cutter.exact_bounds)")
    return None


def exact_solid(spec, tolerance: float) -> ExactSolid:
    """The exact solid of ``spec`` (mm, cannula frame), non-analytic surfaces
    fitted within ``tol.step_fit_share × tolerance`` (mm).

    Raises
    ------
    ExportError
        OCP missing; a cutter without exact bounds; a fit needing more than
        ``tol.step_fit_max_grid`` nodes a side; a boolean that fails or leaves
        other than one valid solid.
    """
    o = occ()
    why = exact_supported(spec)
    if why is not None:
        raise ExportError(f"exact STEP export: {why}; use step_form='faceted'")
    can = spec.cannula
    margin = tol.margin_ratio * can.r_o
    # the uncut tube reaches past the tip's top (the cutters bound it from above)
    z_top = max(min(c.z_upper(can) for c in spec.cutters), 0.0) + 4.0 * margin
    z_bottom = -can.length
    span = 2.0 * (can.r_o + abs(z_bottom) + abs(z_top)) + 1.0
    res = ExactSolid(shape=None)
    shape = _tube(o, can.r_o, can.r_i, z_bottom, z_top)
    for k, cutter in enumerate(spec.cutters):
        for b in cutter.exact_bounds(can, tuple(spec.cutters[:k])):
            if type(b).__name__ == "NotchPrism":
                shape = _boolean(o, "Cut", shape, _notch(o, b), f"tube − {b.label}")
                continue
            region = _region(o, b, can, z_bottom - 2 * margin, z_top + 2 * margin, span,
                             tolerance, res)
            shape = _boolean(o, "Common", shape, region, f"tube ∩ {b.label}")
    unify = o.ShapeUpgrade.ShapeUpgrade_UnifySameDomain(shape, True, True, False)
    unify.Build()
    shape = unify.Shape()
    solids = _subshapes(o, shape, o.TopAbs.TopAbs_SOLID)
    if len(solids) != 1:
        raise ExportError(f"exact STEP export: the booleans left {len(solids)} solids; "
                          f"expected one")
    res.shape = o.TopoDS.TopoDS.Solid(solids[0])
    if not res.is_valid():
        raise ExportError("exact STEP export: OCCT's BRepCheck_Analyzer finds the solid "
                          "invalid; use step_form='faceted'")
    res.faces = _face_kinds(o, res.shape)
    return res


# -- primitives ------------------------------------------------------------------
def _tube(o, ro: float, ri: float, z0: float, z1: float):
    ax = o.gp.gp_Ax2(o.gp.gp_Pnt(0.0, 0.0, z0), o.gp.gp_Dir(0.0, 0.0, 1.0))
    outer = o.BRepPrimAPI.BRepPrimAPI_MakeCylinder(ax, ro, z1 - z0).Shape()
    inner = o.BRepPrimAPI.BRepPrimAPI_MakeCylinder(ax, ri, z1 - z0).Shape()
    return _boolean(o, "Cut", outer, inner, "tube")


def _region(o, b, can, z_lo: float, z_hi: float, span: float, tolerance: float,
            res: ExactSolid):
    """The kept side of one exact bound as a solid covering the tube."""
    kind = type(b).__name__
    if kind == "Plane":
        n = b.normal
        origin = n * b.offset
        pln = o.gp.gp_Pln(o.gp.gp_Pnt(*origin), o.gp.gp_Dir(*n))
        face = o.BRepBuilderAPI.BRepBuilderAPI_MakeFace(pln, -span, span, -span, span).Face()
        return o.BRepPrimAPI.BRepPrimAPI_MakePrism(face, o.gp.gp_Vec(*(-2.0 * span * n))).Shape()
    if kind == "ConeSurface":
        t = math.tan(b.theta)
        z_apex = b.r_o / t
        ax = o.gp.gp_Ax2(o.gp.gp_Pnt(0.0, 0.0, z_lo), o.gp.gp_Dir(0.0, 0.0, 1.0))
        return o.BRepPrimAPI.BRepPrimAPI_MakeCone(ax, b.r_o - z_lo * t, 0.0,
                                                  z_apex - z_lo).Shape()
    if kind == "HeightSurface":
        surf, fit = fit_height(o, b, can, tolerance)
        res.fits.append(fit)
        face = o.BRepBuilderAPI.BRepBuilderAPI_MakeFace(surf, tol.step_occ).Face()
        depth = fit["z_max_mm"] - z_lo
        return o.BRepPrimAPI.BRepPrimAPI_MakePrism(face, o.gp.gp_Vec(0.0, 0.0, -depth)).Shape()
    raise ExportError(f"exact STEP export: surface {b.label} ({kind}) has no exact solid form")


def _notch(o, b):
    """The removed prism of a NotchPrism: its outline's exact lines and arcs
    in the plane (t, z) at ρ = r_in, extruded along w to r_out."""
    c, s = math.cos(b.angle), math.sin(b.angle)
    w = np.array([c, s, 0.0])
    t = np.array([-s, c, 0.0])

    def pnt(uz):
        x = b.r_in * w + uz[0] * t + np.array([0.0, 0.0, uz[1]])
        return o.gp.gp_Pnt(*x.tolist())

    wire = o.BRepBuilderAPI.BRepBuilderAPI_MakeWire()
    for kind, *pts in b.outline:
        if kind == "arc":
            curve = o.GC.GC_MakeArcOfCircle(*(pnt(q) for q in pts)).Value()
        else:
            curve = o.GC.GC_MakeSegment(pnt(pts[0]), pnt(pts[1])).Value()
        wire.Add(o.BRepBuilderAPI.BRepBuilderAPI_MakeEdge(curve).Edge())
    if not wire.IsDone():
        raise ExportError(f"exact STEP export: the outline of {b.label} is not a closed wire")
    face = o.BRepBuilderAPI.BRepBuilderAPI_MakeFace(wire.Wire(), True).Face()
    depth = (b.r_out - b.r_in) * w
    return o.BRepPrimAPI.BRepPrimAPI_MakePrism(face, o.gp.gp_Vec(*depth.tolist())).Shape()


def fit_height(o, b, can, tolerance: float):
    """A bicubic B-spline z(x, y) interpolating ``b.height`` on an n × n grid
    over the square |x|, |y| ≤ a = r_o (1 + margin), n grown until the height
    error at every cell centre and edge midpoint inside the disc ρ ≤ a (all
    the solid keeps of the face: the tube is ρ ≤ r_o) is within
    ``tol.step_fit_share × tolerance``. Where the square's corners reach
    beyond ``b.radius`` (a surface defined only near the tube, such as a
    helicoid close to its axis), the height is continued linearly along the
    radius from ρ = ``b.radius`` (C¹, outside the tube: it shapes only the
    part of the face the boolean cuts away). Returns the OCCT surface and a
    report dict."""
    a = can.r_o * (1.0 + tol.margin_ratio)
    if a > b.radius:
        raise ExportError(f"exact STEP export: surface {b.label} is defined over ρ ≤ "
                          f"{b.radius:.4g} mm; the fit needs {a:.4g} mm")
    height = b.height if a * math.sqrt(2.0) <= b.radius else _continued(b.height, b.radius)
    budget = tol.step_fit_share * tolerance
    n = 17
    while True:
        xs = np.linspace(-a, a, n)
        X, Y = np.meshgrid(xs, xs, indexing="ij")
        Z = np.asarray(height(X, Y), dtype=float)
        if not np.all(np.isfinite(Z)):
            raise ExportError(f"exact STEP export: surface {b.label} is undefined over part of "
                              f"the square |x|, |y| ≤ {a:.4g} mm")
        arr = o.Array2_double(1, n, 1, n)
        for i, row in enumerate(Z.tolist(), 1):
            for j, z in enumerate(row, 1):
                arr.SetValue(i, j, z)
        api = o.GeomAPI.GeomAPI_PointsToBSplineSurface()
        h = float(xs[1] - xs[0])
        api.Interpolate(arr, -a, h, -a, h)
        if not api.IsDone():
            raise ExportError(f"exact STEP export: OCCT could not interpolate {b.label}")
        surf = api.Surface()
        mid = 0.5 * (xs[:-1] + xs[1:])
        px = np.concatenate([np.repeat(mid, n - 1), np.repeat(mid, n), np.repeat(xs, n - 1)])
        py = np.concatenate([np.tile(mid, n - 1), np.tile(xs, n - 1), np.tile(mid, n)])
        inside = np.hypot(px, py) <= a
        px, py = px[inside], py[inside]
        ze = np.asarray(b.height(px, py), dtype=float)
        zs = np.array([surf.Value(u, v).Z() for u, v in zip(px.tolist(), py.tolist())])
        err = float(np.max(np.abs(zs - ze)))
        if err <= budget:
            return surf, {"label": b.label, "grid": n, "max_error_mm": err,
                          "tolerance_mm": budget, "z_max_mm": float(Z.max())}
        # cubic interpolation error falls as h⁴: aim at half the budget
        grow = (err / (0.5 * budget)) ** 0.25
        n_new = int(math.ceil((n - 1) * min(max(grow, 1.25), 4.0))) + 1
        if n_new > tol.step_fit_max_grid:
            raise ExportError(f"exact STEP export: fitting {b.label} within {budget * 1e3:.3g} µm "
                              f"needs more than {tol.step_fit_max_grid} nodes a side (error "
                              f"{err * 1e3:.3g} µm with {n}); raise the build tolerance")
        n = n_new


def _continued(height, radius: float):
    """``height`` (mm) inside ρ ≤ ``radius``, continued linearly along each
    radius beyond it (slope from a backward difference over ``radius`` ×
    1e-3): a C¹ extension for fitting a surface over a square."""
    d = radius * 1e-3

    def ext(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        rho = np.hypot(x, y)
        out = np.empty(np.broadcast(x, y).shape)
        inn = rho <= radius
        out[inn] = height(x[inn], y[inn])
        if np.any(~inn):
            r = rho[~inn]
            ux, uy = x[~inn] / r, y[~inn] / r
            h0 = np.asarray(height(radius * ux, radius * uy), float)
            h1 = np.asarray(height((radius - d) * ux, (radius - d) * uy), float)
            out[~inn] = h0 + (r - radius) * (h0 - h1) / d
        return out

    return ext


def _boolean(o, op: str, a, b, what: str):
    alg = getattr(o.BRepAlgoAPI, f"BRepAlgoAPI_{op}")(a, b)
    if not alg.IsDone():
        raise ExportError(f"exact STEP export: OCCT's boolean {op} failed for {what}")
    return alg.Shape()


def _subshapes(o, shape, kind) -> list:
    out = []
    ex = o.TopExp.TopExp_Explorer(shape, kind)
    while ex.More():
        out.append(ex.Current())
        ex.Next()
    return out


def _face_kinds(o, shape) -> dict:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    kinds: dict[str, int] = {}
    for f in _subshapes(o, shape, o.TopAbs.TopAbs_FACE):
        t = BRepAdaptor_Surface(o.TopoDS.TopoDS.Face(f)).GetType()
        name = t.name.removeprefix("GeomAbs_")
        kinds[name] = kinds.get(name, 0) + 1
    return kinds
