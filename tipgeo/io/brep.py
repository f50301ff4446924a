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
(ShapeUpgrade_UnifySameDomain).

Its edges are then settled (:func:`settle_edges`) so that the solid passes
OCCT's own argument check (``BOPAlgo_ArgumentAnalyzer`` with its
curve-on-surface check, as FreeCAD's "Check geometry" runs it) also after a
STEP round trip, every edge and vertex tolerance within ``EDGE_TOL_MAX_MM``:

* an edge on a periodic curve (circle, ellipse) whose range the booleans left
  beyond one period, e.g. [7.87, 9.42] rad, is given the same curve on the
  range one period lower, its p-curves reparametrised to match (a STEP reader
  puts the range of such an edge, known only by its vertices, into [0, 2π):
  it then found no p-curve there and re-projected one 7 nm off);
* an edge whose 3D curve and p-curves disagree by more than
  ``EDGE_FIT_MM`` (the booleans approximate intersection curves to about
  0.3 nm — more than the 0.1 nm a STEP reader gives every edge) is rebuilt:
  points along it are put on both its faces' surfaces by Newton steps (on the
  exact 3D curve where the edge is a line, circle or ellipse), and the 3D
  curve and both p-curves interpolate them at the same parameters, the points
  doubled until curve and p-curves agree within ``EDGE_FIT_MM``;
* each edge's tolerance is then twice its largest measured curve-on-surface
  distance, at least ``tol.step_occ``.

OCP is imported where used; without it the functions raise
:class:`ExportError`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..errors import ExportError, MissingToolError
from ..tolerances import tol

if TYPE_CHECKING:
    from ..cannula import Cannula
    from ..spec import TipSpec

__all__ = ["EDGE_FIT_MM", "EDGE_TOL_MAX_MM", "ExactSolid", "exact_solid", "exact_supported",
           "occ", "OcpMissing", "ocp_missing", "settle_edges"]

#: How to get OCP, for messages.
OCP_INSTALL = 'pip install "tipgeo[step]"'

#: Largest distance (mm) between an edge's 3D curve and its p-curves that
#: :func:`settle_edges` leaves: a quarter of the 1e-7 mm a STEP reader gives
#: every edge (OCCT's Precision::Confusion, the file's uncertainty).
EDGE_FIT_MM = 2.5e-8

#: Largest edge or vertex tolerance (mm) an exact solid may keep (1 µm).
EDGE_TOL_MAX_MM = 1.0e-3

#: Most points :func:`settle_edges` puts along one rebuilt edge.
EDGE_MAX_POINTS = 4097


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
    edges : dict — what :func:`settle_edges` did: ``shifted`` (edges whose
        periodic range was brought into one period), ``rebuilt`` (edges
        rebuilt), ``points`` (most points along a rebuilt edge),
        ``max_deviation_mm`` (largest 3D curve to p-curve distance left) and
        ``max_tolerance_mm`` (largest edge or vertex tolerance)
    """

    shape: Any
    fits: list[dict[str, Any]] = field(default_factory=list)
    faces: dict[str, int] = field(default_factory=dict)
    edges: dict[str, Any] = field(default_factory=dict)

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


def exact_supported(spec: TipSpec | None) -> str | None:
    """None when every cutter of ``spec`` gives exact bounds, else the reason
    (naming the first cutter that does not)."""
    if spec is None:
        return "the tip has no spec (simulated or imported): only its mesh is known"
    for k, c in enumerate(spec.cutters):
        if c.exact_bounds(spec.cannula, tuple(spec.cutters[:k])) is None:
            return (f"cutter '{c.name}' ({c.kind}) has no exact surface description "
                    f"(Cutter.exact_bounds)")
    return None


def exact_solid(spec: TipSpec, tolerance: float) -> ExactSolid:
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
        bounds = cutter.exact_bounds(can, tuple(spec.cutters[:k]))
        if bounds is None:  # exact_form() admitted only cutters with exact bounds
            raise ExportError(f"cutter '{cutter.name}' ({cutter.kind}) has no exact surfaces "
                              "for a STEP B-rep; use step_form = 'faceted'")
        for b in bounds:
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
    res.edges = settle_edges(res.shape)
    if res.edges["max_tolerance_mm"] > EDGE_TOL_MAX_MM:
        raise ExportError(f"exact STEP export: an edge keeps a tolerance of "
                          f"{res.edges['max_tolerance_mm'] * 1e3:.3g} µm, more than "
                          f"{EDGE_TOL_MAX_MM * 1e3:.3g} µm; use step_form='faceted'")
    if not res.is_valid():
        raise ExportError("exact STEP export: OCCT's BRepCheck_Analyzer finds the solid "
                          "invalid; use step_form='faceted'")
    res.faces = _face_kinds(o, res.shape)
    return res


# -- primitives ------------------------------------------------------------------
def _tube(o: Any, ro: float, ri: float, z0: float, z1: float) -> Any:
    """The uncut tube between z0 and z1 (mm) as an OCCT solid."""
    ax = o.gp.gp_Ax2(o.gp.gp_Pnt(0.0, 0.0, z0), o.gp.gp_Dir(0.0, 0.0, 1.0))
    outer = o.BRepPrimAPI.BRepPrimAPI_MakeCylinder(ax, ro, z1 - z0).Shape()
    inner = o.BRepPrimAPI.BRepPrimAPI_MakeCylinder(ax, ri, z1 - z0).Shape()
    return _boolean(o, "Cut", outer, inner, "tube")


def _region(o: Any, b: Any, can: Cannula, z_lo: float, z_hi: float, span: float, tolerance: float,
            res: ExactSolid) -> Any:
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


def _notch(o: Any, b: Any) -> Any:
    """The removed prism of a NotchPrism: its outline's exact lines and arcs
    in the plane (t, z) at ρ = r_in, extruded along w to r_out."""
    c, s = math.cos(b.angle), math.sin(b.angle)
    w = np.array([c, s, 0.0])
    t = np.array([-s, c, 0.0])

    def pnt(uz: tuple[float, float]) -> Any:
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


def fit_height(o: Any, b: Any, can: Cannula, tolerance: float) -> tuple[Any, dict[str, Any]]:
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


def _continued(height: Callable[[FloatArray, FloatArray], ArrayLike],
               radius: float) -> Callable[[ArrayLike, ArrayLike], FloatArray]:
    """``height`` (mm) inside ρ ≤ ``radius``, continued linearly along each
    radius beyond it (slope from a backward difference over ``radius`` ×
    1e-3): a C¹ extension for fitting a surface over a square."""
    d = radius * 1e-3

    def ext(x: ArrayLike, y: ArrayLike) -> FloatArray:
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
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


def _boolean(o: Any, op: str, a: Any, b: Any, what: str) -> Any:
    alg = getattr(o.BRepAlgoAPI, f"BRepAlgoAPI_{op}")(a, b)
    if not alg.IsDone():
        raise ExportError(f"exact STEP export: OCCT's boolean {op} failed for {what}")
    return alg.Shape()


def _subshapes(o: Any, shape: Any, kind: Any) -> list[Any]:
    out = []
    ex = o.TopExp.TopExp_Explorer(shape, kind)
    while ex.More():
        out.append(ex.Current())
        ex.Next()
    return out


def _face_kinds(o: Any, shape: Any) -> dict[str, int]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface

    kinds: dict[str, int] = {}
    for f in _subshapes(o, shape, o.TopAbs.TopAbs_FACE):
        t = BRepAdaptor_Surface(o.TopoDS.TopoDS.Face(f)).GetType()
        name = t.name.removeprefix("GeomAbs_")
        kinds[name] = kinds.get(name, 0) + 1
    return kinds


# -- edges that pass OCCT's curve-on-surface check ---------------------------------
def settle_edges(shape: Any, fit: float = EDGE_FIT_MM) -> dict[str, Any]:
    """Settle the edges of ``shape`` (an OCCT solid, mm) in place: periodic
    ranges into one period, edges whose 3D curve and p-curves disagree by
    more than ``fit`` (mm) rebuilt, tolerances set from the measured
    distances (see the module docstring). Returns the report kept as
    :attr:`ExactSolid.edges`."""
    from OCP.BRep import BRep_Builder, BRep_Tool
    from OCP.BRepLib import BRepLib
    from OCP.collections import (
        IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EdgeFaces,
    )
    from OCP.ShapeFix import ShapeFix_ShapeTolerance
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    o = occ()
    emap = EdgeFaces()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, emap)
    edges = []
    for i in range(1, emap.Size() + 1):
        faces: list[Any] = []
        for f in emap.FindFromIndex(i):
            if not any(f.IsSame(g) for g in faces):
                faces.append(f)
        edges.append((TopoDS.Edge(emap.FindKey(i)), [TopoDS.Face(f) for f in faces]))
    builder = BRep_Builder()
    report: dict[str, Any] = {"edges": len(edges), "shifted": 0, "rebuilt": 0, "points": 0}
    for e, faces in edges:
        report["shifted"] += _one_period(builder, e, faces)
    worst = 0.0
    tolerances = ShapeFix_ShapeTolerance()
    for e, faces in edges:
        devs = [_cos_distance(e, f) for f in faces]
        manifold = len(faces) == 2 and not any(BRep_Tool.IsClosed_s(e, f) for f in faces)
        if manifold and max(devs) > fit:
            kept = _curves(e, faces)
            points = _rebuild(o, builder, e, faces, fit)
            rebuilt = [_cos_distance(e, f) for f in faces]
            if max(rebuilt) < max(devs):
                report["points"] = max(report["points"], points)
                report["rebuilt"] += 1
                devs = rebuilt
            else:  # no better: the booleans' curves stay
                _restore(builder, e, faces, kept)
        dev = max(devs, default=0.0)
        worst = max(worst, dev)
        tolerances.SetTolerance(e, max(tol.step_occ, 2.0 * dev), TopAbs_EDGE)
    for v in _subshapes(o, shape, TopAbs_VERTEX):
        tolerances.SetTolerance(v, tol.step_occ, TopAbs_VERTEX)
    BRepLib.UpdateTolerances_s(shape, False)  # vertices cover their edges again
    report["max_deviation_mm"] = worst
    report["max_tolerance_mm"] = max_tolerance(shape)
    return report


def max_tolerance(shape: Any) -> float:
    """The largest edge or vertex tolerance of ``shape`` (mm)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopoDS import TopoDS

    o = occ()
    t = [BRep_Tool.Tolerance_s(TopoDS.Edge(e)) for e in _subshapes(o, shape, TopAbs_EDGE)]
    t += [BRep_Tool.Tolerance_s(TopoDS.Vertex(v)) for v in _subshapes(o, shape, TopAbs_VERTEX)]
    return max(t, default=0.0)


def _cos_distance(e: Any, f: Any) -> float:
    """The largest distance (mm) between the 3D curve of edge ``e`` and its
    p-curve on face ``f`` (BRepLib_ValidateEdge, exact method: what
    BOPAlgo_ArgumentAnalyzer's curve-on-surface check measures)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.BRepLib import BRepLib_ValidateEdge

    check = BRepLib_ValidateEdge(BRepAdaptor_Curve(e), BRepAdaptor_Curve(e, f).CurveOnSurface(),
                                 BRep_Tool.SameParameter_s(e))
    check.SetExactMethod(True)
    check.Process()
    return check.GetMaxDistance() if check.IsDone() else math.inf


def _one_period(builder: Any, e: Any, faces: list[Any]) -> int:
    """Bring the range of edge ``e`` on a periodic 3D curve into [0, period),
    its p-curves reparametrised to match; 1 if it moved, else 0."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
    from OCP.TopoDS import TopoDS

    curve = BRepAdaptor_Curve(e)
    if not curve.IsPeriodic():
        return 0
    period = curve.Period()
    first, last = BRep_Tool.Range_s(e)
    k = math.floor(first / period + tol.step_period_slack)
    if k == 0:
        return 0
    shift = k * period
    t = BRep_Tool.Tolerance_s(e)
    for f in faces:
        if BRep_Tool.IsClosed_s(e, f):  # a seam: both p-curves
            ef, er = (TopoDS.Edge(e.Oriented(s)) for s in (TopAbs_FORWARD, TopAbs_REVERSED))
            c1, c2 = (_shifted(BRep_Tool.CurveOnSurface_s(x, f, 0.0, 0.0), first, last, shift)
                      for x in (ef, er))
            builder.UpdateEdge(ef, c1, c2, f, t)
        else:
            pc = BRep_Tool.CurveOnSurface_s(e, f, 0.0, 0.0)
            builder.UpdateEdge(e, _shifted(pc, first, last, shift), f, t)
    builder.Range(e, first - shift, last - shift)
    return 1


def _shifted(pc: Any, first: float, last: float, shift: float) -> Any:
    """The 2D curve s ↦ pc(s + shift) on [first − shift, last − shift]: the
    same curve where ``shift`` is a whole number of its periods, else its
    B-spline form on [first, last] with the knots moved by −shift (exact)."""
    from OCP.Geom2d import Geom2d_TrimmedCurve
    from OCP.Geom2dConvert import Geom2dConvert

    if (pc.IsPeriodic()
            and abs(math.remainder(shift, pc.Period())) <= tol.step_period_slack * abs(shift)):
        return pc
    bs = Geom2dConvert.CurveToBSplineCurve_s(Geom2d_TrimmedCurve(pc, first, last))
    n = bs.NbKnots()
    for i in (range(1, n + 1) if shift > 0 else range(n, 0, -1)):  # knots stay increasing
        bs.SetKnot(i, bs.Knot(i) - shift)
    return bs


class _Projector:
    """Point (x, y, z) → (u, v, foot point, unit normal) on one surface, each
    search started from the previous answer (ShapeAnalysis_Surface). Plain
    floats: called thousands of times per edge."""

    def __init__(self, surface: Any):
        from OCP.gp import gp_Pnt, gp_Vec
        from OCP.ShapeAnalysis import ShapeAnalysis_Surface

        self.surface, self.sas, self.prev = surface, ShapeAnalysis_Surface(surface), None
        self._pnt, self._vec = gp_Pnt, gp_Vec

    def __call__(self, x: tuple[float, float, float]
                 ) -> tuple[float, float, tuple[float, float, float], tuple[float, float, float]]:
        p = self._pnt(*x)
        uv = (self.sas.ValueOfUV(p, tol.step_project) if self.prev is None
              else self.sas.NextValueOfUV(self.prev, p, tol.step_project,
                                          tol.step_project_jump))
        self.prev = uv
        foot, du, dv = self._pnt(), self._vec(), self._vec()
        self.surface.D1(uv.X(), uv.Y(), foot, du, dv)
        n = du.Crossed(dv)
        n.Normalize()
        return uv.X(), uv.Y(), foot.Coord(), n.Coord()


def _on_both(p1: _Projector, p2: _Projector,
             x: tuple[float, float, float]) -> tuple[float, float, float]:
    """Newton steps from ``x`` to the nearby point on both surfaces: each
    step goes to the nearest point of the line where their tangent planes
    meet (plain floats, mm)."""
    for _ in range(30):
        _, _, q1, n1 = p1(x)
        _, _, q2, n2 = p2(x)
        c = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]
        r1 = sum(n * (q - xi) for n, q, xi in zip(n1, q1, x))
        r2 = sum(n * (q - xi) for n, q, xi in zip(n2, q2, x))
        det = 1.0 - c * c
        if det <= tol.step_tangent:  # tangent surfaces: no single nearby crossing point
            break
        a, b = (r1 - c * r2) / det, (r2 - c * r1) / det
        step = [a * m1 + b * m2 for m1, m2 in zip(n1, n2)]
        x = (x[0] + step[0], x[1] + step[1], x[2] + step[2])
        if math.sqrt(sum(si * si for si in step)) <= tol.step_walk:
            break
    return x


def _interpolated_2d(surface: Any, uv: FloatArray, params: FloatArray, old: Any,
                     first: float) -> Any:
    """A p-curve on ``surface`` through the points ``uv`` (n × 2) at
    ``params``, on the same sheet of a periodic surface as the p-curve
    ``old`` at its parameter ``first``."""
    from OCP.collections import HArray1_double, HArray1_gp_Pnt2d
    from OCP.Geom2dAPI import Geom2dAPI_Interpolate
    from OCP.gp import gp_Pnt2d

    uv = np.array(uv, dtype=float)
    p0 = old.Value(first)
    for k, periodic, period, ref in ((0, surface.IsUPeriodic(), surface.UPeriod, p0.X()),
                                     (1, surface.IsVPeriodic(), surface.VPeriod, p0.Y())):
        if periodic:
            per = period()
            uv[:, k] = np.unwrap(uv[:, k], period=per)
            uv[:, k] += round((ref - uv[0, k]) / per) * per
    arr, par = HArray1_gp_Pnt2d(1, len(params)), HArray1_double(1, len(params))
    for i, ((u, v), t) in enumerate(zip(uv.tolist(), params.tolist()), 1):
        arr.SetValue(i, gp_Pnt2d(u, v))
        par.SetValue(i, t)
    it = Geom2dAPI_Interpolate(arr, par, False, tol.step_interp)
    it.Perform()
    if not it.IsDone():
        raise ExportError("exact STEP export: OCCT could not interpolate a p-curve")
    return it.Curve()


def _curves(e: Any, faces: list[Any]) -> tuple[Any, list[Any], tuple[float, float]]:
    """The 3D curve, p-curves (on ``faces``) and range of edge ``e``."""
    from OCP.BRep import BRep_Tool

    return (BRep_Tool.Curve_s(e, 0.0, 0.0), [BRep_Tool.CurveOnSurface_s(e, f, 0.0, 0.0)
                                             for f in faces], BRep_Tool.Range_s(e))


def _restore(builder: Any, e: Any, faces: list[Any],
             kept: tuple[Any, list[Any], tuple[float, float]]) -> None:
    """Put back what :func:`_curves` returned."""
    from OCP.BRep import BRep_Tool

    curve, pcurves, (first, last) = kept
    t = BRep_Tool.Tolerance_s(e)
    builder.UpdateEdge(e, curve, t)
    for pc, f in zip(pcurves, faces):
        builder.UpdateEdge(e, pc, f, t)
    builder.Range(e, first, last)


#: A point on an edge (mm) and its (u, v) on each of the edge's two faces.
_EdgeSample = tuple[tuple[float, float, float], tuple[float, float], tuple[float, float]]


def _edge_sampler(curve: Any, surfaces: list[Any], first: float, last: float, exact: bool
                  ) -> tuple[Callable[[float], tuple[float, float, float]], float, float]:
    """(parameter ↦ point of the rebuilt edge, its parameter range): the 3D
    curve itself where it is exact; else chord length along it, each point
    put on both surfaces."""
    if exact:
        def point(t: float) -> tuple[float, float, float]:
            x: tuple[float, float, float] = curve.Value(t).Coord()
            return x
        return point, first, last
    # an approximated intersection, its parameter perhaps running at very
    # uneven speed: the rebuilt edge is parametrised by chord length and
    # its points put on both surfaces
    tt = np.linspace(first, last, 1025)
    dense = np.array([curve.Value(t).Coord() for t in tt.tolist()])
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0),
                                                              axis=1))])
    walk = [_Projector(s) for s in surfaces]

    def on_both(s: float) -> tuple[float, float, float]:
        return _on_both(walk[0], walk[1],
                        curve.Value(float(np.interp(s, length, tt))).Coord())
    return on_both, 0.0, float(length[-1])


def _interpolated_3d(o: Any, pts: list[_EdgeSample], params: FloatArray) -> Any:
    """A 3D curve through the sampled points at ``params``."""
    from OCP.collections import HArray1_double, HArray1_gp_Pnt

    arr, par = HArray1_gp_Pnt(1, len(params)), HArray1_double(1, len(params))
    for i, (p, t) in enumerate(zip(pts, params.tolist()), 1):
        arr.SetValue(i, o.gp.gp_Pnt(*p[0]))
        par.SetValue(i, t)
    it = o.GeomAPI.GeomAPI_Interpolate(arr, par, False, tol.step_interp)
    it.Perform()
    if not it.IsDone():
        raise ExportError("exact STEP export: OCCT could not interpolate an edge")
    return it.Curve()


def _midpoint_errors(curve: Any, pcs: list[Any], surfaces: list[Any],
                     params: FloatArray) -> FloatArray:
    """The largest distance (mm) between the 3D curve and the p-curves' points
    at the midpoint of each interval of ``params`` (where it is largest)."""
    mids = 0.5 * (params[:-1] + params[1:])
    err = np.zeros(len(mids))
    for pc, s in zip(pcs, surfaces):
        for i, t in enumerate(mids.tolist()):
            uv = pc.Value(t)
            err[i] = max(err[i], curve.Value(t).Distance(s.Value(uv.X(), uv.Y())))
    return err


def _refined(params: FloatArray, err: FloatArray, fit: float) -> FloatArray | None:
    """``params`` with every interval that misses ``fit`` split, or None
    when none does or the split would pass EDGE_MAX_POINTS."""
    bad = np.flatnonzero(err > fit)
    if len(bad) == 0:
        return None
    # cubic interpolation's error falls as h⁴: split each interval that
    # misses into as many as should meet the fit, with a margin
    pieces = np.maximum(2, np.ceil(1.25 * (err[bad] / fit) ** 0.25)).astype(int)
    if len(params) + int(np.sum(pieces - 1)) > EDGE_MAX_POINTS:
        return None
    extra = [params[i] + (params[i + 1] - params[i]) * np.arange(1, k) / k
             for i, k in zip(bad.tolist(), pieces.tolist())]
    return np.sort(np.concatenate([params, *extra]))


def _rebuild(o: Any, builder: Any, e: Any, faces: list[Any], fit: float) -> int:
    """Rebuild edge ``e`` between two faces so that its 3D curve and p-curves
    agree within ``fit`` (mm) where interpolation through ≤ EDGE_MAX_POINTS
    points can: points on both surfaces (on the 3D curve itself where it is
    a line, circle or ellipse), splitting every interval whose midpoint
    misses ``fit`` until none does. Returns the number of points used."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Ellipse, GeomAbs_Line

    first, last = BRep_Tool.Range_s(e)
    curve = BRep_Tool.Curve_s(e, 0.0, 0.0)
    exact = BRepAdaptor_Curve(e).GetType() in (GeomAbs_Line, GeomAbs_Circle, GeomAbs_Ellipse)
    surfaces = [BRep_Tool.Surface_s(f) for f in faces]
    olds = [BRep_Tool.CurveOnSurface_s(e, f, 0.0, 0.0) for f in faces]
    projectors = [_Projector(s) for s in surfaces]
    point, lo, hi = _edge_sampler(curve, surfaces, first, last, exact)
    cache: dict[float, _EdgeSample] = {}
    params = np.linspace(lo, hi, 33)
    while True:
        for t in params.tolist():
            if t not in cache:
                x = point(t)
                cache[t] = (x, projectors[0](x)[:2], projectors[1](x)[:2])
        pts = [cache[t] for t in params.tolist()]
        new = curve if exact else _interpolated_3d(o, pts, params)
        pcs = [_interpolated_2d(s, np.array([p[k + 1] for p in pts]), params, old, first)
               for k, (s, old) in enumerate(zip(surfaces, olds))]
        refined = _refined(params, _midpoint_errors(new, pcs, surfaces, params), fit)
        if refined is None:
            break
        params = refined
    t = BRep_Tool.Tolerance_s(e)
    if not exact:
        builder.UpdateEdge(e, new, t)
    for pc, f in zip(pcs, faces):
        builder.UpdateEdge(e, pc, f, t)
    builder.Range(e, float(params[0]), float(params[-1]))
    return len(params)
