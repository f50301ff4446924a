"""Exact STEP export (tipgeo.io.brep, tipgeo.io.step): exact planes, cylinders
and cones, the helicoid as a fitted B-spline, made by OCCT booleans; read
back with OCP's STEP reader and checked by BRepCheck_Analyzer, meshed by
gmsh; multi-output commands that say what they cannot write before writing.

Tolerances (mm, cannula frame):

* volume: the mesh's vertices lie on the exact surfaces and its facets within
  the build tolerance ``t`` of them, so |V_exact − V_mesh| ≤ t · area;
* the fitted helicoid: its height within ``tol.step_fit_share · t`` of the
  cutter's exact height (what the fit guarantees at its check points), checked
  here at fresh random points over the tube wall;
* gmsh's coarse tetrahedra: their total volume within 1 % of OCCT's (the
  facets of a 0.4 mm mesh cut the curved walls by ~(h/2)²/(2r)).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from tipgeo.errors import ExportError
from tipgeo.io import check_export, export_many, export_tip
from tipgeo.tip import Tip
from tipgeo.tolerances import tol

pytest.importorskip("OCP", reason="cadquery-ocp (the 'step' extra) is not installed")

#: preset → the exact surface kinds its STEP must hold (OCCT names)
CASES = {
    "bevel-14G-xi15": {"Cylinder": 2, "Plane": 2},
    "lancet-14G": {"Cylinder": 2, "Plane": 5},
    "punch-plain": {"Cylinder": 2, "Cone": 1, "Plane": 2},
    "helical-14G": {"Cylinder": 2, "BSplineSurface": 1, "Plane": 1},
    # 3 notches (arc + 2 fillets each) cut the cone into 3 pieces
    "punch-C5": {"Cylinder": 2 + 3 * 3, "Cone": 3, "Plane": 4},
}


def _read_step(path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    reader = STEPControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    return reader.OneShape()


def _sub(shape, kind) -> list:
    from OCP.TopExp import TopExp_Explorer

    out, e = [], TopExp_Explorer(shape, kind)
    while e.More():
        out.append(e.Current())
        e.Next()
    return out


def _face_kinds(shape) -> dict:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopoDS import TopoDS

    kinds: dict[str, int] = {}
    for f in _sub(shape, TopAbs_FACE):
        k = BRepAdaptor_Surface(TopoDS.Face(f)).GetType().name.removeprefix("GeomAbs_")
        kinds[k] = kinds.get(k, 0) + 1
    return kinds


@pytest.fixture(scope="module")
def exported(build_preset, tmp_path_factory):
    d = tmp_path_factory.mktemp("step")
    return {n: (build_preset(n), export_tip(build_preset(n), d / f"{n}.step")) for n in CASES}


@pytest.mark.parametrize("name", list(CASES))
def test_exact_step_is_a_valid_closed_solid(exported, name):
    from OCP.BRepCheck import BRepCheck_Analyzer, BRepCheck_NoError, BRepCheck_Shell
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_SHELL, TopAbs_SOLID
    from OCP.TopoDS import TopoDS

    tip, path = exported[name]
    text = path.read_text(errors="replace")
    assert text.startswith("ISO-10303-21;") and f"PRODUCT('{name}','{name}'" in text
    shape = _read_step(path)
    solids = _sub(shape, TopAbs_SOLID)
    assert len(solids) == 1
    solid = TopoDS.Solid(solids[0])
    assert BRepCheck_Analyzer(solid).IsValid()
    shells = _sub(solid, TopAbs_SHELL)
    assert len(shells) == 1
    assert BRepCheck_Shell(TopoDS.Shell(shells[0])).Closed() == BRepCheck_NoError
    assert _face_kinds(solid) == CASES[name]  # exact surfaces, not a face per triangle
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(solid, props, 1e-9)
    assert props.Mass() > 0
    assert abs(props.Mass() - tip.volume) <= tip.tolerance * tip.area
    # the same place and orientation (a plane turned by π keeps the volume):
    # boundaries within t move the first moment by ≤ t·area·max|p|, so the
    # centroids differ by ≤ t·area·(max|p| + |c|)/V
    c = props.CentreOfMass()
    c_exact = np.array([c.X(), c.Y(), c.Z()])
    tri = tip.vertices[tip.faces]
    six_v = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    c_mesh = (six_v[:, None] * tri.sum(axis=1)).sum(axis=0) / (4.0 * six_v.sum())
    reach = np.linalg.norm(tip.vertices, axis=1).max()
    bound = tip.tolerance * tip.area * (reach + np.linalg.norm(c_mesh)) / tip.volume
    assert np.linalg.norm(c_exact - c_mesh) <= bound


def test_helicoid_bspline_is_within_the_fit_tolerance(exported):
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_BSplineSurface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopoDS import TopoDS

    tip, path = exported["helical-14G"]
    cutter, can = tip.spec.cutters[0], tip.spec.cannula
    faces = [TopoDS.Face(f) for f in _sub(_read_step(path), TopAbs_FACE)
             if BRepAdaptor_Surface(TopoDS.Face(f)).GetType() == GeomAbs_BSplineSurface]
    assert len(faces) == 1
    surf = BRep_Tool.Surface_s(faces[0])
    rng = np.random.default_rng(7)
    rho = np.sqrt(rng.uniform(can.r_i ** 2, can.r_o ** 2, 400))
    g = rng.uniform(0.0, 2 * np.pi, 400)
    x, y = rho * np.cos(g), rho * np.sin(g)
    pts = [surf.Value(u, v) for u, v in zip(x.tolist(), y.tolist())]  # parameters are (x, y)
    got = np.array([[p.X(), p.Y(), p.Z()] for p in pts])
    np.testing.assert_allclose(got[:, :2], np.c_[x, y], rtol=0, atol=1e-12)
    want = cutter.height(x, y, can)
    assert np.max(np.abs(got[:, 2] - want)) <= tol.step_fit_share * tip.tolerance


@pytest.mark.parametrize("name", ["helical-14G", "punch-plain"])
def test_gmsh_meshes_the_exact_volume(exported, name):
    gmsh = pytest.importorskip("gmsh")
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    _, path = exported[name]
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(_read_step(path), props, 1e-9)
    gmsh.initialize(["-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        assert len(gmsh.model.getEntities(3)) == 1
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.4)  # coarse: a test, not an analysis
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 12)
        gmsh.model.mesh.generate(3)
        _, _, conn = gmsh.model.mesh.getElements(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
    finally:
        gmsh.finalize()
    xyz = np.zeros((int(tags.max()) + 1, 3))
    xyz[tags] = coords.reshape(-1, 3)
    tet = np.asarray(conn[0], dtype=np.int64).reshape(-1, 4)
    a, b, c, d = (xyz[tet[:, k]] for k in range(4))
    vols = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0
    assert len(tet) > 100 and np.all(np.abs(vols) > 0)
    assert abs(np.abs(vols).sum() - props.Mass()) <= 0.01 * props.Mass()


def test_faceted_form_and_auto_choice(tmp_path):
    from tipgeo import build_tip, preset

    tip = build_tip(preset("bevel-14G-xi15"), tolerance=1e-2)  # few facets: fast to read
    shape = _read_step(export_tip(tip, tmp_path / "f.step", step_form="faceted"))
    assert _face_kinds(shape) == {"Plane": len(tip.faces)}
    # a tip without its spec has no exact form: auto writes it faceted, exact refuses
    bare = Tip(tip.vertices, tip.faces, tip.label_ids, tip.label_names)
    assert _face_kinds(_read_step(export_tip(bare, tmp_path / "b.step"))) == \
        {"Plane": len(tip.faces)}
    with pytest.raises(ExportError, match="no spec.*step_form='faceted'"):
        export_tip(bare, tmp_path / "e.step", step_form="exact")
    assert not (tmp_path / "e.step").exists()


def test_export_many_says_what_fails_before_writing(build_preset, tmp_path, monkeypatch):
    tip = build_preset("bevel-14G-xi15")
    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    outs = [tmp_path / "a.stl", tmp_path / "b.step", tmp_path / "c.ply"]
    with pytest.raises(ExportError, match=r'tipgeo\[step\]'):
        check_export(tip, outs[1])
    seen = []

    def on_error(path, exc):
        seen.append((path, sorted(p.name for p in tmp_path.iterdir())))

    rep = export_many(tip, outs, on_error=on_error)
    assert seen == [(outs[1], [])]  # told before anything was written
    assert rep.written == [outs[0], outs[2]] and [p for p, _ in rep.failed] == [outs[1]]
    assert "OCP" in rep.failed[0][1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.stl", "c.ply"]
    with pytest.raises(ExportError):  # without a handler: raised before any write
        export_many(tip, [tmp_path / "d.stl", tmp_path / "e.step"])
    assert not (tmp_path / "d.stl").exists()


def test_cli_build_reports_the_failed_export(tmp_path, monkeypatch, capsys):
    import json

    from tipgeo.cli import main

    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    a, b = tmp_path / "t.stl", tmp_path / "t.step"
    assert main(["build", "bevel-14G-xi15", "--tolerance-um", "5", "-o", str(b), "-o", str(a),
                 "--json"]) == 1
    cap = capsys.readouterr()
    info = json.loads(cap.out)
    assert info["outputs"] == [str(a)] and info["failed"][0]["path"] == str(b)
    assert f"cannot write {b}" in cap.err and "tipgeo[step]" in cap.err
    assert a.exists() and not b.exists()


def test_grind_outputs_report_the_failed_mesh(build_preset, tmp_path, monkeypatch):
    from cam import GrindResult, make_program, write_grind_outputs

    tip = build_preset("bevel-14G-xi15")
    res = GrindResult(make_program(tip.spec), ground=tip)
    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    seen = []
    prog, mesh = tmp_path / "p.nc", tmp_path / "g.step"
    write_grind_outputs(res, gcode=prog, mesh=mesh,
                        on_error=lambda p, e: seen.append((p, prog.exists())))
    assert seen == [(mesh, False)]
    assert res.files == [str(prog)] and res.summary()["failed"][0]["path"] == str(mesh)
    assert prog.exists() and not mesh.exists()


def _circle3(p0, pm, p1) -> tuple[np.ndarray, float]:
    """Centre and radius of the circle through three points."""
    a = np.array([[p0[0] - pm[0], p0[1] - pm[1]], [pm[0] - p1[0], pm[1] - p1[1]]]) * 2.0
    b = np.array([p0[0] ** 2 + p0[1] ** 2 - pm[0] ** 2 - pm[1] ** 2,
                  pm[0] ** 2 + pm[1] ** 2 - p1[0] ** 2 - p1[1] ** 2])
    c = np.linalg.solve(a, b)
    return c, float(np.hypot(*(np.asarray(p0) - c)))


def _outline_area(outline) -> float:
    """Exact area of a closed outline of lines and arcs: the shoelace sum of
    its chords plus each arc's circular segment (signed by its turning)."""
    area = 0.0
    for kind, *pts in outline:
        p0, p1 = pts[0], pts[-1]
        area += 0.5 * (p0[0] * p1[1] - p1[0] * p0[1])
        if kind == "arc":
            c, r = _circle3(*pts)
            chord = float(np.hypot(p1[0] - p0[0], p1[1] - p0[1]))
            half = math.asin(min(chord / (2 * r), 1.0))
            # the mid point lies left of the chord p0→p1 for a bulge to the left
            side = ((p1[0] - p0[0]) * (pts[1][1] - p0[1]) - (p1[1] - p0[1]) * (pts[1][0] - p0[0]))
            far = np.hypot(pts[1][0] - 0.5 * (p0[0] + p1[0]), pts[1][1] - 0.5 * (p0[1] + p1[1]))
            theta = 2 * half if far <= r else 2 * math.pi - 2 * half  # the arc's angle
            seg = 0.5 * r * r * (theta - math.sin(theta))
            area -= math.copysign(seg, side)
    return area


@pytest.mark.parametrize("r_c, depth, r_s", [(0.15, 0.15, 0.015), (0.15, 0.15, 0.0),
                                             (0.15, 0.3, 0.0), (0.15, 0.3, 0.015),
                                             (0.15, 0.1, 0.015), (0.15, 0.1, 0.0)])
def test_serration_outline_is_closed_and_matches_the_profile(r_c, depth, r_s):
    from tipgeo.cutters import SerrationProfile

    prof = SerrationProfile(r_c, depth, r_s, 0.0)
    out = prof.outline(0.5)
    for piece, nxt in zip(out, out[1:] + out[:1]):
        assert math.dist(piece[-1], nxt[1]) <= 1e-15  # each piece starts where one ends
    for kind, *pts in out:
        if kind == "arc":  # every arc is the main arc (r_c) or a fillet (r_s)
            _, r = _circle3(*pts)
            assert min(abs(r - r_c), abs(r - r_s)) <= 1e-12
    a = _outline_area(out)
    assert a == pytest.approx(_poly_area(prof.polygon(1e-9, 0.5)), abs=1e-8)
    if r_s == 0 and depth == r_c:  # a half disc under a 2 r_c × 0.5 rectangle
        assert a == pytest.approx(0.5 * math.pi * r_c ** 2 + 2 * r_c * 0.5, rel=1e-13)


def _poly_area(p) -> float:
    x, y = p[:, 0], p[:, 1]
    return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_cli_gcode_sim_reports_the_failed_mesh(tmp_path, monkeypatch, capsys):
    """`gcode sim --mesh X.step` without OCP: named on stderr before the
    pictures are written, the pictures still written, exit status 1, and
    `--json` lists what was written and what failed."""
    import json

    from tipgeo.cli import main

    prog = tmp_path / "c4.pgm"
    assert main(["laser", "punch-C4", "-o", str(prog)]) == 0
    capsys.readouterr()
    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    png, mesh = tmp_path / "p.png", tmp_path / "s.step"
    assert main(["gcode", "sim", str(prog), "--spec", "punch-C4", "--png", str(png),
                 "--mesh", str(mesh), "--tolerance-um", "2", "--json"]) == 1
    cap = capsys.readouterr()
    info = json.loads(cap.out)
    assert info["failed"][0]["path"] == str(mesh)
    assert info["wrote"] == [str(png), str(tmp_path / "p-rim.png")]
    assert f"cannot write {mesh}" in cap.err
    assert png.exists() and not mesh.exists()
