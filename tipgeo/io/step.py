"""STEP (``.step``, ``.stp``): an AP214 solid (B-rep) through the OpenCASCADE
bindings OCP (``pip install "tipgeo[step]"``), in one of two forms
(``step_form``):

* ``'exact'``: the spec's solid with exact surfaces — planes, cylinders,
  cones; the helicoid (any height-field cutter surface) as a bicubic B-spline
  fitted within half the tip's build tolerance — made by OCCT booleans of
  exact solids (:mod:`tipgeo.io.brep`), its edges' 3D curves and p-curves
  agreeing within 0.025 nm (2.5e-8 mm) so that the file read back passes OCCT's
  ``BRepCheck_Analyzer`` and ``BOPAlgo_ArgumentAnalyzer`` (curve on
  surface, small edges, self-interference), every tolerance ≤ 1 µm;
* ``'faceted'``: one planar face per triangle of the mesh; the tip must be a
  closed, consistently oriented mesh (faces pointing outwards).

``'auto'`` (the default) writes the exact form for a tip built from a spec
whose every cutter gives exact bounds, and the faceted form otherwise
(simulated, imported or custom-cutter tips).

Unit mm, the cannula frame (+z along the needle axis towards the tip, heel at
z = 0), coordinates as doubles. Export only; no labels.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

from ..tip import Tip
from .brep import exact_solid, exact_supported, ocp_missing
from .common import ExportError
from .registry import STEP_FORMS, ExportOptions, register_exporter

__all__ = ["STEP_FORMS", "precheck_step", "step_form_for", "step_solid", "write_step"]


def _ocp() -> SimpleNamespace:
    """The OCP classes the STEP writer uses (:class:`~tipgeo.io.brep.OcpMissing`,
    a MissingToolError and an ExportError, if OCP is missing)."""
    try:
        from OCP.BRep import BRep_Builder
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeShapeOnMesh
        from OCP.gp import gp_Pnt
        from OCP.IFSelect import IFSelect_RetDone
        from OCP.Interface import Interface_Static
        from OCP.Message import Message, Message_Gravity
        from OCP.Poly import Poly_Triangle, Poly_Triangulation
        from OCP.StepBasic import StepBasic_Product
        from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
        from OCP.TCollection import TCollection_HAsciiString
        from OCP.TopAbs import TopAbs_FACE
        from OCP.TopExp import TopExp_Explorer
        from OCP.TopoDS import TopoDS_Shell, TopoDS_Solid
    except ImportError as exc:
        raise ocp_missing(exc) from exc
    return SimpleNamespace(
        BRep_Builder=BRep_Builder, BRepBuilderAPI_MakeShapeOnMesh=BRepBuilderAPI_MakeShapeOnMesh,
        gp_Pnt=gp_Pnt, IFSelect_RetDone=IFSelect_RetDone, Interface_Static=Interface_Static,
        Message=Message, Message_Gravity=Message_Gravity, Poly_Triangle=Poly_Triangle,
        Poly_Triangulation=Poly_Triangulation, StepBasic_Product=StepBasic_Product,
        STEPControl_AsIs=STEPControl_AsIs, STEPControl_Writer=STEPControl_Writer,
        TCollection_HAsciiString=TCollection_HAsciiString, TopAbs_FACE=TopAbs_FACE,
        TopExp_Explorer=TopExp_Explorer, TopoDS_Shell=TopoDS_Shell, TopoDS_Solid=TopoDS_Solid)


def step_solid(tip: Tip) -> Any:
    """The tip as an OCCT solid bounded by one planar face per triangle, the
    faces pointing outwards (mm, cannula frame).

    ``BRepBuilderAPI_MakeShapeOnMesh`` shares the edges of neighbouring
    triangles by construction, so the faces form a closed shell without
    ``BRepBuilderAPI_Sewing`` (which is slow on large meshes).
    """
    occ = _ocp()
    if not tip.is_watertight:
        raise ExportError("STEP export needs a closed, consistently oriented triangle mesh; "
                          "this tip has open or non-manifold edges")
    v, f = tip.vertices, tip.faces + 1
    if tip.volume < 0:  # inside out: flip, so the faces point outwards
        f = f[:, ::-1]
    tri = occ.Poly_Triangulation(len(v), len(f), False)
    for i, (x, y, z) in enumerate(v.tolist(), 1):
        tri.SetNode(i, occ.gp_Pnt(x, y, z))
    for i, (a, b, c) in enumerate(f.tolist(), 1):
        tri.SetTriangle(i, occ.Poly_Triangle(a, b, c))
    maker = occ.BRepBuilderAPI_MakeShapeOnMesh(tri)
    maker.Build()
    if not maker.IsDone():
        raise ExportError("STEP export: OCCT could not build faces from the triangles")
    builder = occ.BRep_Builder()
    shell = occ.TopoDS_Shell()
    builder.MakeShell(shell)
    n_faces = 0
    explorer = occ.TopExp_Explorer(maker.Shape(), occ.TopAbs_FACE)
    while explorer.More():
        builder.Add(shell, explorer.Current())
        n_faces += 1
        explorer.Next()
    if n_faces != len(f):
        raise ExportError(f"STEP export: OCCT made {n_faces} faces from {len(f)} triangles "
                          f"(degenerate triangles?); the shell would not close")
    shell.Closed(True)
    solid = occ.TopoDS_Solid()
    builder.MakeSolid(solid)
    builder.Add(solid, shell)  # the faces keep the (outward) triangle orientation
    return solid


def step_form_for(tip: Tip, form: str = "auto") -> str:
    """The STEP form ``'exact'`` or ``'faceted'`` :func:`write_step` writes
    for ``tip`` when asked for ``form`` (``'auto'`` picks exact where it
    exists); ExportError when ``'exact'`` is asked of a tip without it."""
    if form == "faceted":
        return form
    why = (exact_supported(tip.spec) if tip.source == "cad"
           else f"the tip comes from '{tip.source}', not from its spec")
    if why is None:
        return "exact"
    if form == "exact":
        raise ExportError(f"exact STEP export: {why}; use step_form='faceted'")
    return "faceted"


def _exact(tip: Tip) -> Any:
    """The exact solid of a CAD tip (an OCCT solid, mm), checked against its
    mesh: the volumes differ by at most the build tolerance times the area."""
    if tip.spec is None or tip.tolerance is None:
        raise ExportError("exact STEP export: the tip has no spec or no build tolerance; "
                          "use step_form='faceted'")
    es = exact_solid(tip.spec, tip.tolerance)
    dv, bound = abs(es.volume - tip.volume), tip.tolerance * tip.area
    if not dv <= bound:
        raise ExportError(f"exact STEP export: the exact solid's volume {es.volume:.9g} mm³ "
                          f"differs from the mesh's {tip.volume:.9g} mm³ by {dv:.3g} mm³, more "
                          f"than tolerance × area = {bound:.3g} mm³; use step_form='faceted'")
    return es.shape


def write_step(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as a STEP AP214 solid (unit mm, product named
    ``opts.name``) in the form ``opts.step_form`` (see the module docstring),
    leaving OCCT's global settings as they were."""
    occ = _ocp()
    static = occ.Interface_Static
    # silence OCCT's console chatter while we work; OCCT's STEP settings are
    # global too: set ours and restore the caller's afterwards
    levels = [(pr, pr.GetTraceLevel()) for pr in occ.Message.DefaultMessenger_s().Printers()]
    saved_unit = static.CVal_s("write.step.unit")
    saved_pcurves = static.IVal_s("write.surfacecurve.mode")
    saved_precision = static.IVal_s("write.precision.mode")
    try:
        for printer, _ in levels:
            printer.SetTraceLevel(occ.Message_Gravity.Message_Fail)
        exact = step_form_for(tip, opts.step_form) == "exact"
        solid = _exact(tip) if exact else step_solid(tip)
        # Faceted: no p-curves (write.surfacecurve.mode 0): planar faces do not
        # need them; leaving them out makes the file 2.3x smaller and 40 %
        # faster. Exact: p-curves kept, as CAD systems expect on curved faces.
        static.SetCVal_s("write.step.unit", "MM")
        static.SetIVal_s("write.surfacecurve.mode", 1 if exact else 0)
        # the file's uncertainty (what a reader gives every edge and vertex)
        # is the solid's greatest tolerance, so that no edge of the read
        # solid is tighter than it was made (≤ EDGE_TOL_MAX_MM, 1 µm)
        static.SetIVal_s("write.precision.mode", 1)
        writer = occ.STEPControl_Writer()
        if writer.Transfer(solid, occ.STEPControl_AsIs) != occ.IFSelect_RetDone:
            raise ExportError("STEP export: OCCT could not translate the solid")
        model = writer.Model()
        name = occ.TCollection_HAsciiString(opts.name)
        for i in range(1, model.NbEntities() + 1):  # the one PRODUCT comes first
            entity = model.Value(i)
            if isinstance(entity, occ.StepBasic_Product):
                entity.SetId(name)
                entity.SetName(name)
                break
        if writer.Write(str(tmp)) != occ.IFSelect_RetDone:
            raise ExportError(f"STEP export: OCCT could not write '{tmp}'")
    finally:
        if saved_unit:
            static.SetCVal_s("write.step.unit", saved_unit)
        static.SetIVal_s("write.surfacecurve.mode", saved_pcurves)
        static.SetIVal_s("write.precision.mode", saved_precision)
        for printer, level in levels:
            printer.SetTraceLevel(level)


def precheck_step(tip: Tip, opts: ExportOptions) -> None:
    """What :func:`write_step` would refuse before it works: OCP missing, the
    exact form asked of a tip without one (ExportError)."""
    _ocp()
    step_form_for(tip, opts.step_form)


register_exporter(".step", write_step, precheck_step)
register_exporter(".stp", write_step, precheck_step)
