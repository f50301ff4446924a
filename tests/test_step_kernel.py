"""Exact STEP files pass OpenCASCADE's own checks, read back from the file
(STEPControl_Reader), for every sample tip:

* ``BRepCheck_Analyzer``: valid;
* ``BOPAlgo_ArgumentAnalyzer`` — what FreeCAD's "Check geometry" runs —
  with every check on (argument type, self-interference, small edges,
  rebuilt faces, tangent faces, merge vertices and edges, continuity and
  curve on surface): no faulty shape;
* every edge and vertex tolerance ≤ 1 µm (``EDGE_TOL_MAX_MM``), and every
  edge's 3D curve within 0.05 nm (twice ``EDGE_FIT_MM``, half the 0.1 nm
  a STEP reader gives every edge) of each of its p-curves, measured by
  ``BRepLib_ValidateEdge``'s exact method (what the argument analyzer's
  curve-on-surface check measures);
* in memory (tipgeo.io.brep.settle_edges): every edge on a circle or ellipse
  has its range within one period [0, 2π) — where a STEP reader puts it —
  and its p-curves defined there.

Lengths mm, cannula frame. Each tip is built and written once per module.
"""

from __future__ import annotations

import math

import pytest

from tipgeo.io import export_tip
from tipgeo.io.brep import EDGE_FIT_MM, EDGE_TOL_MAX_MM, exact_solid
from tipgeo.presets import preset_names

pytest.importorskip("OCP", reason="cadquery-ocp (the 'step' extra) is not installed: "
                                  'pip install "tipgeo[step]"')

SAMPLES = preset_names()


def _read_step(path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    assert reader.TransferRoots() == 1
    return reader.OneShape()


def _sub(shape, kind) -> list:
    from OCP.TopExp import TopExp_Explorer

    out, e = [], TopExp_Explorer(shape, kind)
    while e.More():
        out.append(e.Current())
        e.Next()
    return out


@pytest.fixture(scope="module")
def read_back(build_preset, tmp_path_factory):
    """name → the solid read back from the tip's exact STEP file (built once)."""
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopoDS import TopoDS

    d = tmp_path_factory.mktemp("kernel")
    cache = {}

    def get(name):
        if name not in cache:
            path = export_tip(build_preset(name), d / f"{name}.step", step_form="exact")
            solids = _sub(_read_step(path), TopAbs_SOLID)
            assert len(solids) == 1
            cache[name] = TopoDS.Solid(solids[0])
        return cache[name]

    return get


@pytest.mark.parametrize("name", SAMPLES)
def test_brepcheck_analyzer_finds_the_read_solid_valid(read_back, name):
    from OCP.BRepCheck import BRepCheck_Analyzer

    assert BRepCheck_Analyzer(read_back(name)).IsValid()


@pytest.mark.parametrize("name", SAMPLES)
def test_argument_analyzer_finds_nothing_with_every_check_on(read_back, name):
    from OCP.BOPAlgo import BOPAlgo_ArgumentAnalyzer

    check = BOPAlgo_ArgumentAnalyzer()
    check.SetShape1(read_back(name))
    for mode in ("ArgumentTypeMode", "SelfInterMode", "SmallEdgeMode", "RebuildFaceMode",
                 "TangentMode", "MergeVertexMode", "MergeEdgeMode", "ContinuityMode",
                 "CurveOnSurfaceMode"):
        setattr(check, mode, True)
        assert getattr(check, mode) is True  # the binding really set it
    check.Perform()
    found = [(r.GetCheckStatus().name, r.GetMaxDistance1()) for r in check.GetCheckResult()]
    assert not check.HasFaulty() and found == []


@pytest.mark.parametrize("name", SAMPLES)
def test_read_tolerances_within_1um_and_curves_on_their_surfaces(read_back, name):
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
    from OCP.TopoDS import TopoDS

    from tipgeo.io.brep import _cos_distance, max_tolerance

    solid = read_back(name)
    assert 0.0 < max_tolerance(solid) <= EDGE_TOL_MAX_MM
    worst = 0.0
    for f in _sub(solid, TopAbs_FACE):
        face = TopoDS.Face(f)
        for e in _sub(face, TopAbs_EDGE):
            edge = TopoDS.Edge(e)
            d = _cos_distance(edge, face)
            assert d <= BRep_Tool.Tolerance_s(edge)
            worst = max(worst, d)
    assert worst <= 2.0 * EDGE_FIT_MM
    for v in _sub(solid, TopAbs_VERTEX):
        assert BRep_Tool.Tolerance_s(TopoDS.Vertex(v)) <= EDGE_TOL_MAX_MM


@pytest.mark.parametrize("name", ["lancet-14G", "helical-14G", "punch-C5"])
def test_periodic_edges_lie_within_one_period_in_memory(build_preset, name):
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopoDS import TopoDS

    tip = build_preset(name)
    es = exact_solid(tip.spec, tip.tolerance)
    assert es.edges["max_tolerance_mm"] <= EDGE_TOL_MAX_MM
    assert es.edges["max_deviation_mm"] <= 2.0 * EDGE_FIT_MM
    n_periodic = 0
    for f in _sub(es.shape, TopAbs_FACE):
        face = TopoDS.Face(f)
        for e in _sub(face, TopAbs_EDGE):
            edge = TopoDS.Edge(e)
            c = BRepAdaptor_Curve(edge)
            if not c.IsPeriodic():
                continue
            n_periodic += 1
            first, last = BRep_Tool.Range_s(edge)
            assert -1e-12 <= first < c.Period() and first < last <= first + c.Period() + 1e-12
            pc = BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0)
            for t in (first, 0.5 * (first + last), last):
                if not pc.IsPeriodic():
                    assert pc.FirstParameter() - 1e-9 <= t <= pc.LastParameter() + 1e-9
                uv = pc.Value(t)
                p = BRep_Tool.Surface_s(face).Value(uv.X(), uv.Y())
                assert p.Distance(c.Value(t)) <= 2.0 * EDGE_FIT_MM
    assert n_periodic > 0


def test_one_period_moves_a_range_one_period_down_exactly():
    """A circle edge ρ = 1, z = 0 on [2π + 1, 2π + 2] with its p-curve the
    line (u, v) = (t, 5) on the cylinder ρ = 1 from z = −5: after
    _one_period its range is [1, 2], the same points at the same parameter
    minus 2π, the p-curve the same (u, v) to 1e-12."""
    from OCP.BRep import BRep_Builder, BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.Geom import Geom_Circle
    from OCP.Geom2d import Geom2d_Line
    from OCP.gp import gp_Ax2, gp_Circ, gp_Dir, gp_Dir2d, gp_Pnt, gp_Pnt2d
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopoDS import TopoDS

    from tipgeo.io.brep import _one_period

    axis = gp_Ax2(gp_Pnt(0, 0, -5), gp_Dir(0, 0, 1))
    cyl = BRepPrimAPI_MakeCylinder(axis, 1.0, 10.0).Shape()
    face = next(TopoDS.Face(f) for f in _sub(cyl, TopAbs_FACE)
                if BRep_Tool.Surface_s(TopoDS.Face(f)).IsUPeriodic())
    two_pi = 2.0 * math.pi
    circle = Geom_Circle(gp_Circ(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 1.0))
    edge = BRepBuilderAPI_MakeEdge(circle, two_pi + 1.0, two_pi + 2.0).Edge()
    builder = BRep_Builder()
    builder.Range(edge, two_pi + 1.0, two_pi + 2.0)  # MakeEdge put it into [0, 2π)
    assert BRep_Tool.Range_s(edge) == pytest.approx((two_pi + 1.0, two_pi + 2.0), abs=1e-12)
    builder.UpdateEdge(edge, Geom2d_Line(gp_Pnt2d(0.0, 5.0), gp_Dir2d(1.0, 0.0)), face, 1e-7)
    surf = BRep_Tool.Surface_s(face)
    assert _one_period(builder, edge, [face]) == 1
    assert BRep_Tool.Range_s(edge) == pytest.approx((1.0, 2.0), abs=1e-12)
    assert BRep_Tool.Range_s(edge, face) == pytest.approx((1.0, 2.0), abs=1e-12)
    curve = BRep_Tool.Curve_s(edge, 0.0, 0.0)
    pc = BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0)
    for k in range(9):
        t = 1.0 + k / 8
        uv = pc.Value(t)
        assert (uv.X(), uv.Y()) == pytest.approx((t + two_pi, 5.0), abs=1e-12)
        assert math.dist(curve.Value(t).Coord(), (math.cos(t), math.sin(t), 0.0)) <= 1e-12
        assert math.dist(surf.Value(uv.X(), uv.Y()).Coord(), curve.Value(t).Coord()) <= 1e-12
    assert _one_period(builder, edge, [face]) == 0  # already within one period
