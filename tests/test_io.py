"""Export and import of tips (tipgeo.io): round trips, file layouts, atomic
writes and error messages.

Tolerances (mm, cannula frame):

* PLY, OBJ (doubles written as shortest round-trip decimals or raw float64)
  and 3MF (trimesh writes shortest round-trip decimals): vertices within
  ``EXACT = 1e-12`` mm, volume within 1e-12 relative;
* STL and GLB store float32: every corner within ``F32 = 1e-5`` mm; the volume
  within ``area · max|x| · 2⁻²⁴`` (each vertex moves at most half a float32
  ulp, i.e. ``|x| · 2⁻²⁴``);
* INP numbers have 12 fixed decimals: within 1e-12 mm.
"""

from __future__ import annotations

import math
import os
import re
import stat
import sys

import numpy as np
import pytest

import tipgeo.io as tio
from tipgeo.build import build_tip
from tipgeo.cannula import Cannula
from tipgeo.cutters import BevelCutter, MultiPlaneCutter
from tipgeo.errors import BuildError, SpecError
from tipgeo.io import SUPPORTED_EXPORTS, SUPPORTED_IMPORTS, ExportError, export_tip, load_tip
from tipgeo.spec import TipSpec
from tipgeo.tip import Tip

EXACT = 1e-12  # mm
F32 = 1e-5  # mm


@pytest.fixture(scope="module")
def tip() -> Tip:
    return build_tip(TipSpec(cannula=Cannula.from_gauge(14),
                             cutters=[BevelCutter(xi=math.radians(15))], name="bevel15"))


@pytest.fixture(scope="module")
def tip3() -> Tip:
    """Three-plane tip: labels with dots (cut:multiplane.0 …) and a name with a space."""
    return build_tip(TipSpec(cannula=Cannula.from_gauge(14),
                             cutters=[MultiPlaneCutter(xi=math.radians(20), count=3)],
                             name="three plane"))


def _f32_volume_tol(t: Tip) -> float:
    return t.area * float(np.abs(t.vertices).max()) * 2.0 ** -24


def _listing(d) -> list[str]:
    return sorted(os.listdir(d))


# -- public surface -------------------------------------------------------------
def test_supported_extensions():
    assert SUPPORTED_EXPORTS == (".stl", ".ply", ".obj", ".3mf", ".glb", ".step", ".stp", ".inp")
    assert set(SUPPORTED_IMPORTS) <= set(SUPPORTED_EXPORTS)
    assert set(SUPPORTED_EXPORTS) == set(tio._WRITERS)
    assert issubclass(ExportError, BuildError)
    assert set(tio.__all__) >= {"export_tip", "load_tip", "SUPPORTED_EXPORTS", "ExportError"}


# -- exact formats: PLY and OBJ ----------------------------------------------------
@pytest.mark.parametrize("ext, binary", [(".ply", True), (".ply", False), (".obj", True)])
@pytest.mark.parametrize("which", ["tip", "tip3"])
def test_exact_round_trip_restores_labels(ext, binary, which, request, tmp_path):
    t = request.getfixturevalue(which)
    p = export_tip(t, str(tmp_path / f"t{ext}"), binary=binary)
    assert p == tmp_path / f"t{ext}"
    r = load_tip(p)
    assert r.vertices.shape == t.vertices.shape
    assert np.abs(r.vertices - t.vertices).max() <= EXACT
    np.testing.assert_array_equal(r.faces, t.faces)
    assert r.label_names == t.label_names
    np.testing.assert_array_equal(r.label_ids, t.label_ids)
    assert list(r.labels) == list(t.labels)
    assert r.volume == pytest.approx(t.volume, rel=EXACT)
    assert r.is_watertight
    assert r.source == f"t{ext}"
    assert r.meta["labels_from_file"] is True
    assert r.meta["name"] == t.spec.name
    assert r.spec is None


def test_ply_header(tip, tmp_path):
    p = export_tip(tip, tmp_path / "t.ply")
    data = p.read_bytes()
    header = data[:data.index(b"end_header\n") + len(b"end_header\n")].decode()
    lines = header.splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    assert "comment units mm" in lines
    for k, name in enumerate(tip.label_names):
        assert f"comment label {k} {name}" in lines
    assert "property double x" in lines
    assert "property list uchar int vertex_indices" in lines
    assert "property int label" in lines
    n, m = len(tip.vertices), len(tip.faces)
    assert f"element vertex {n}" in lines and f"element face {m}" in lines
    # 3 doubles per vertex; count byte + 3 int32 + int32 label per face
    assert len(data) == len(header.encode()) + 24 * n + 17 * m


def test_obj_groups(tip3, tmp_path):
    p = export_tip(tip3, tmp_path / "t.obj")
    lines = p.read_text().splitlines()
    groups = {ln[2:] for ln in lines if ln.startswith("g ")}
    assert groups == set(tip3.present_labels())
    assert sum(ln.startswith("f ") for ln in lines) == len(tip3.faces)
    v_lines = [ln for ln in lines if ln.startswith("v ")]
    assert len(v_lines) == len(tip3.vertices)
    # full double precision: every coordinate parses back to the same double
    parsed = np.array([ln.split()[1:] for ln in v_lines], dtype=np.float64)
    np.testing.assert_array_equal(parsed, tip3.vertices)
    assert "o three_plane" in lines


# -- float32 formats: STL and GLB; 3MF ---------------------------------------------
def test_stl_binary_size_and_round_trip(tip, tmp_path):
    p = export_tip(tip, tmp_path / "t.stl")
    m = len(tip.faces)
    assert p.stat().st_size == 84 + 50 * m
    data = p.read_bytes()
    assert not data.startswith(b"solid")  # readers must not take it for ASCII
    assert int.from_bytes(data[80:84], "little") == m
    r = load_tip(p)
    assert len(r.faces) == m
    # STL keeps the triangle order and corner order: compare corner by corner
    assert np.abs(r.triangles - tip.triangles).max() <= F32
    assert len(r.vertices) == len(tip.vertices)  # identical corners merged again
    assert r.is_watertight
    assert abs(r.volume - tip.volume) <= _f32_volume_tol(tip)
    assert set(r.labels) == {"unlabelled"}
    assert r.meta["labels_from_file"] is False


def test_stl_ascii_round_trip_is_exact(tip, tmp_path):
    p = export_tip(tip, tmp_path / "t.stl", binary=False)
    assert p.read_text().startswith("solid bevel15\n")
    r = load_tip(p)
    assert len(r.faces) == len(tip.faces)
    assert np.abs(r.triangles - tip.triangles).max() <= EXACT
    assert r.volume == pytest.approx(tip.volume, rel=EXACT)


def test_glb_round_trip_restores_labels(tip3, tmp_path):
    p = export_tip(tip3, tmp_path / "t.glb")
    assert p.read_bytes()[:4] == b"glTF"
    r = load_tip(p)
    assert r.vertices.shape == tip3.vertices.shape
    assert np.abs(r.vertices - tip3.vertices).max() <= F32
    np.testing.assert_array_equal(r.faces, tip3.faces)
    assert abs(r.volume - tip3.volume) <= _f32_volume_tol(tip3)
    assert list(r.labels) == list(tip3.labels)
    assert r.label_names == tip3.label_names


def test_3mf_round_trip(tip, tmp_path):
    pytest.importorskip("lxml")  # trimesh reads 3MF through lxml
    p = export_tip(tip, tmp_path / "t.3mf")
    r = load_tip(p)
    assert r.vertices.shape == tip.vertices.shape
    assert np.abs(r.vertices - tip.vertices).max() <= EXACT
    np.testing.assert_array_equal(r.faces, tip.faces)
    assert r.volume == pytest.approx(tip.volume, rel=EXACT)
    assert set(r.labels) == {"unlabelled"}
    assert r.meta["name"] == "bevel15"


def test_extension_is_case_insensitive_and_tip_export(tip, tmp_path):
    p = tmp_path / "T.STL"
    tip.export(p)
    assert p.stat().st_size == 84 + 50 * len(tip.faces)
    assert len(load_tip(p).faces) == len(tip.faces)


# -- Abaqus INP -----------------------------------------------------------------------
def _parse_inp(text: str) -> list[tuple[str, dict[str, str], list[list[str]]]]:
    """Keyword blocks: (keyword, {param: value}, data rows); comments dropped."""
    blocks = []
    for line in text.splitlines():
        if line.startswith("**"):
            continue
        if line.startswith("*"):
            parts = [s.strip() for s in line[1:].split(",")]
            params = {}
            for s in parts[1:]:
                k, _, val = s.partition("=")
                params[k.strip().lower()] = val.strip()
            blocks.append((parts[0].lower(), params, []))
        elif line.strip():
            blocks[-1][2].append([s.strip() for s in line.split(",") if s.strip()])
    return blocks


def _elset_members(params, rows) -> list[int]:
    if "generate" in params:
        out = []
        for a, b, c in rows:
            out += list(range(int(a), int(b) + 1, int(c)))
        return out
    return [int(x) for row in rows for x in row]


@pytest.mark.parametrize("ref_point", ["centroid", "top", (0.1, -0.2, 3.0)])
def test_inp_rigid_part(tip3, tmp_path, ref_point):
    p = export_tip(tip3, tmp_path / "t.inp", ref_point=ref_point)
    text = p.read_text()
    assert "e+" not in text and "e-" not in text  # fixed-point numbers only
    blocks = _parse_inp(text)
    keys = [b[0] for b in blocks]
    assert keys[0] == "heading" and keys[-1] == "rigid body"
    assert "part" not in keys and "end part" not in keys  # CalculiX has no *PART
    assert "** part THREE_PLANE:" in text
    n, m = len(tip3.vertices), len(tip3.faces)

    nodes = [r for k, _, rows in blocks if k == "node" for r in rows]
    assert len(nodes) == n + 2  # the mesh nodes, the reference and rotation nodes
    xyz = np.array([r[1:] for r in nodes[:n]], dtype=np.float64)
    assert [int(r[0]) for r in nodes] == list(range(1, n + 3))
    assert np.abs(xyz - tip3.vertices).max() <= EXACT
    for r in nodes:  # every coordinate in fixed notation with 12 decimals
        assert all(re.fullmatch(r"-?\d+\.\d{12}", s) for s in r[1:])

    (elem,) = [b for b in blocks if b[0] == "element"]
    assert elem[1]["type"] == "S3"  # CalculiX has no R3D3
    conn = np.array(elem[2], dtype=np.int64)
    assert conn.shape == (m, 4)
    np.testing.assert_array_equal(conn[:, 0], np.arange(1, m + 1))
    np.testing.assert_array_equal(conn[:, 1:], tip3.faces + 1)  # 1-based

    elsets = {b[1]["elset"]: _elset_members(b[1], b[2]) for b in blocks if b[0] == "elset"}
    assert set(elsets) == {"OUTER", "INNER", "BASE", "CUT_MULTIPLANE_0", "CUT_MULTIPLANE_1",
                           "CUT_MULTIPLANE_2", "ALL"}
    assert elsets["ALL"] == list(range(1, m + 1))
    for es, label in [("OUTER", "outer"), ("INNER", "inner"), ("BASE", "base"),
                      ("CUT_MULTIPLANE_1", "cut:multiplane.1")]:
        assert elsets[es] == (np.flatnonzero(tip3.labels == label) + 1).tolist()
    assert max(len(r) for b in blocks if b[0] == "elset" for r in b[2]) <= 16

    nsets = {b[1]["nset"]: b for b in blocks if b[0] == "nset"}
    assert set(nsets) == {"TIP", "RefPt", "RotPt"}
    assert nsets["RefPt"][2] == [[str(n + 1)]] and nsets["RotPt"][2] == [[str(n + 2)]]
    assert nodes[n][1:] == nodes[n + 1][1:]
    assert _elset_members(nsets["TIP"][1], nsets["TIP"][2]) == list(range(1, n + 1))
    ref = np.array(nodes[n][1:], dtype=np.float64)
    if ref_point == "top":
        expected = (0.0, 0.0, tip3.bounds[1, 2])
    elif ref_point == "centroid":
        expected = (0.0, 0.0, float(tip3.vertices[:, 2].mean()))  # only checked loosely
    else:
        expected = ref_point
    tol = 2.0 if ref_point == "centroid" else EXACT
    assert np.abs(ref - expected).max() <= tol
    (rigid,) = [b for b in blocks if b[0] == "rigid body"]
    assert rigid[1] == {"nset": "TIP", "ref node": str(n + 1), "rot node": str(n + 2)}
    assert f"** Abaqus: replace the next line by *RIGID BODY, REF NODE={n + 1}, ELSET=ALL" \
        in text.splitlines()
    (sec,) = [b for b in blocks if b[0] == "shell section"]
    assert sec[1] == {"elset": "ALL", "material": "TIPGEO_RIGID"}


def test_inp_centroid_is_volume_centroid(tmp_path):
    # a closed box [0, 2] x [0, 2] x [1, 3]: volume centroid at z = 2
    import trimesh

    box = trimesh.creation.box(bounds=[[0, 0, 1], [2, 2, 3]])
    t = Tip(box.vertices, box.faces, np.zeros(len(box.faces), int), ("outer",))
    assert t.is_watertight and t.volume == pytest.approx(8.0)
    text = export_tip(t, tmp_path / "box.inp").read_text()
    ref_line = text.splitlines()[text.splitlines().index("*NSET, NSET=RefPt") - 2]
    assert ref_line == f"{len(t.vertices) + 1}, 0.000000000000, 0.000000000000, 2.000000000000"


# -- STEP ------------------------------------------------------------------------------
def test_step_faceted_solid(tip, tmp_path, capfd):
    pytest.importorskip("OCP")
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    capfd.readouterr()
    pcurves = Interface_Static.IVal_s("write.surfacecurve.mode")
    p = export_tip(tip, tmp_path / "t.step", step_form="faceted")
    assert capfd.readouterr().out == ""  # OCCT's console output silenced
    assert Interface_Static.IVal_s("write.surfacecurve.mode") == pcurves  # global restored
    text = p.read_text(errors="replace")
    assert text.startswith("ISO-10303-21;")
    assert "PRODUCT('bevel15','bevel15'" in text
    reader = STEPControl_Reader()
    assert reader.ReadFile(str(p)) == IFSelect_RetDone
    reader.TransferRoots()
    shape = reader.OneShape()

    def count(kind):
        e, n = TopExp_Explorer(shape, kind), 0
        while e.More():
            n += 1
            e.Next()
        return n

    assert count(TopAbs_SOLID) == 1
    assert count(TopAbs_FACE) == len(tip.faces)
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    assert props.Mass() == pytest.approx(tip.volume, rel=1e-9)  # closed and outward
    # .stp is the same writer (its default form for a spec's tip is the exact one)
    assert export_tip(tip, tmp_path / "t.STP").read_bytes()[:13] == b"ISO-10303-21;"


def test_step_solid_faces_point_outwards(tip):
    # the STEP reader repairs orientation on reading, so check the solid itself:
    # OCCT's volume is negative for an inside-out solid
    pytest.importorskip("OCP")
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    flipped = Tip(tip.vertices, tip.faces[:, ::-1], tip.label_ids, tip.label_names)
    for t in (tip, flipped):
        props = GProp_GProps()
        BRepGProp.VolumeProperties_s(tio._step_solid(t), props)
        assert props.Mass() == pytest.approx(tip.volume, rel=1e-9)


def test_step_without_ocp_names_the_extra(tip, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    with pytest.raises(ExportError, match=r'pip install "tipgeo\[step\]"'):
        export_tip(tip, tmp_path / "t.step")
    assert _listing(tmp_path) == []


def test_step_rejects_open_mesh(tip, tmp_path):
    pytest.importorskip("OCP")
    open_tip = Tip(tip.vertices, tip.faces[1:], tip.label_ids[1:], tip.label_names)
    with pytest.raises(ExportError, match="closed"):
        export_tip(open_tip, tmp_path / "t.step")
    assert _listing(tmp_path) == []


# -- atomic writes ------------------------------------------------------------------------
def _failing_writer(real):
    def write(t, tmp, opts):
        real(t, tmp, opts)
        data = tmp.read_bytes()
        tmp.write_bytes(data[: len(data) // 2])  # half a file on disk ...
        raise RuntimeError("simulated disk failure")  # ... then the writer dies
    return write


@pytest.mark.parametrize("ext", [".ply", ".stl", ".inp"])
def test_failed_write_leaves_nothing(tip, tmp_path, monkeypatch, ext):
    monkeypatch.setitem(tio._WRITERS, ext, _failing_writer(tio._WRITERS[ext]))
    target = tmp_path / f"t{ext}"
    with pytest.raises(ExportError, match="simulated disk failure") as exc:
        export_tip(tip, target)
    assert str(target) in str(exc.value)
    assert isinstance(exc.value.__cause__, RuntimeError)
    assert _listing(tmp_path) == []


def test_failed_write_keeps_existing_file(tip, tmp_path, monkeypatch):
    target = tmp_path / "t.ply"
    target.write_bytes(b"previous content")
    os.chmod(target, 0o640)
    before = target.stat()
    monkeypatch.setitem(tio._WRITERS, ".ply", _failing_writer(tio._WRITERS[".ply"]))
    with pytest.raises(BuildError):
        export_tip(tip, target)
    assert target.read_bytes() == b"previous content"
    assert target.stat().st_mtime_ns == before.st_mtime_ns
    assert _listing(tmp_path) == ["t.ply"]


def test_failed_rename_and_interrupt_clean_up(tip, tmp_path, monkeypatch):
    target = tmp_path / "t.stl"
    target.write_bytes(b"old")

    def no_replace(src, dst):
        raise OSError(28, "No space left on device")

    with monkeypatch.context() as mp:
        mp.setattr(tio.os, "replace", no_replace)
        with pytest.raises(ExportError, match="No space left"):
            export_tip(tip, target)
    assert _listing(tmp_path) == ["t.stl"] and target.read_bytes() == b"old"

    def interrupted(t, tmp, opts):
        tmp.write_bytes(b"partial")
        raise KeyboardInterrupt

    monkeypatch.setitem(tio._WRITERS, ".stl", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export_tip(tip, target)
    assert _listing(tmp_path) == ["t.stl"] and target.read_bytes() == b"old"


def test_overwrite_keeps_mode_and_new_file_honours_umask(tip, tmp_path):
    target = tmp_path / "t.obj"
    target.write_text("old")
    os.chmod(target, 0o640)
    export_tip(tip, target)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert target.read_text().startswith("# tipgeo OBJ")
    umask = os.umask(0o022)
    os.umask(umask)
    fresh = export_tip(tip, tmp_path / "fresh.inp")
    assert stat.S_IMODE(fresh.stat().st_mode) == 0o666 & ~umask
    assert _listing(tmp_path) == ["fresh.inp", "t.obj"]


# -- export argument errors ------------------------------------------------------------------
def test_unknown_extension(tip, tmp_path):
    with pytest.raises(SpecError, match=r"'\.foo'.*allowed: \.stl, \.ply") as exc:
        export_tip(tip, tmp_path / "x.foo")
    assert "x.foo" in str(exc.value)
    with pytest.raises(SpecError, match="extension ''"):
        export_tip(tip, tmp_path / "noext")
    assert _listing(tmp_path) == []


def test_missing_parent_directory(tip, tmp_path):
    target = tmp_path / "missing" / "t.stl"
    with pytest.raises(SpecError, match="does not exist") as exc:
        export_tip(tip, target)
    assert str(target.parent) in str(exc.value)
    assert not (tmp_path / "missing").exists()


@pytest.mark.parametrize("kwargs, match", [
    ({"binary": "yes"}, "binary = 'yes'"),
    ({"ref_point": "tip"}, "ref_point = 'tip'.*'centroid', 'top'"),
    ({"ref_point": (0.0, math.nan, 1.0)}, "ref_point"),
    ({"name": ""}, "name = ''"),
])
def test_bad_arguments(tip, tmp_path, kwargs, match):
    with pytest.raises(SpecError, match=match):
        export_tip(tip, tmp_path / "t.inp", **kwargs)
    assert _listing(tmp_path) == []


def test_bad_inputs(tip, tmp_path):
    (tmp_path / "d.stl").mkdir()
    with pytest.raises(SpecError, match="is a directory"):
        export_tip(tip, tmp_path / "d.stl")
    with pytest.raises(SpecError, match="not a Tip"):
        export_tip(tip.to_trimesh(), tmp_path / "t.stl")
    bad = Tip(tip.vertices.copy(), tip.faces, tip.label_ids, tip.label_names)
    bad.vertices[0, 0] = math.inf
    with pytest.raises(SpecError, match="finite"):
        export_tip(bad, tmp_path / "t.stl")
    with pytest.raises(SpecError, match="label name"):
        export_tip(Tip(tip.vertices, tip.faces, tip.label_ids, ("a\nb",) * 5), tmp_path / "t.ply")
    assert _listing(tmp_path) == ["d.stl"]


# -- import --------------------------------------------------------------------------------------
def test_units_scale_to_mm(tip, tmp_path):
    p = export_tip(tip, tmp_path / "t.ply")
    for units, scale in [("mm", 1.0), ("um", 1e-3), ("m", 1e3)]:
        r = load_tip(p, units=units)
        np.testing.assert_allclose(r.vertices, tip.vertices * scale, rtol=EXACT, atol=0)
        assert r.meta["file_units"] == units
    with pytest.raises(SpecError, match=r"units = 'cm'.*'mm', 'um', 'm'"):
        load_tip(p, units="cm")


def test_load_errors(tmp_path):
    with pytest.raises(SpecError, match="does not exist"):
        load_tip(tmp_path / "none.stl")
    (tmp_path / "empty.ply").write_bytes(b"")
    with pytest.raises(SpecError, match="empty"):
        load_tip(tmp_path / "empty.ply")
    (tmp_path / "junk.ply").write_bytes(b"not a mesh at all\n")
    with pytest.raises(SpecError, match="junk.ply"):
        load_tip(tmp_path / "junk.ply")
    (tmp_path / "junk.glb").write_bytes(b"\x00" * 64)
    with pytest.raises(SpecError, match="junk.glb"):
        load_tip(tmp_path / "junk.glb")
    with pytest.raises(SpecError, match=r"'\.step'.*allowed: \.stl"):
        load_tip(tmp_path / "x.step")
    (tmp_path / "dir.stl").mkdir()
    with pytest.raises(SpecError, match="not a regular file"):
        load_tip(tmp_path / "dir.stl")


def _ascii_ply(verts: str, faces: str, n_v: int, n_f: int) -> bytes:
    return (f"ply\nformat ascii 1.0\nelement vertex {n_v}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {n_f}\n"
            f"property list uchar int vertex_indices\nend_header\n{verts}{faces}").encode()


def test_load_rejects_non_finite_and_bad_indices(tmp_path):
    p = tmp_path / "nan.ply"
    p.write_bytes(_ascii_ply("0 0 0\n1 0 nan\n0 1 0\n", "3 0 1 2\n", 3, 1))
    with pytest.raises(SpecError, match="non-finite"):
        load_tip(p)
    p = tmp_path / "idx.ply"
    p.write_bytes(_ascii_ply("0 0 0\n1 0 0\n0 1 0\n", "3 0 1 7\n", 3, 1))
    with pytest.raises(SpecError, match="3 vertices"):
        load_tip(p)
    p = tmp_path / "nan.obj"
    p.write_text("# tipgeo OBJ\nv 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SpecError, match="non-finite"):
        load_tip(p)


def test_load_foreign_files(tip, tmp_path):
    # a quad PLY (not triangles): read through trimesh, triangulated, unlabelled
    quad = tmp_path / "quad.ply"
    quad.write_bytes(_ascii_ply("0 0 0\n1 0 0\n1 1 0\n0 1 0\n", "4 0 1 2 3\n", 4, 1))
    r = load_tip(quad)
    assert len(r.faces) == 2 and set(r.labels) == {"unlabelled"}
    # trimesh's own PLY (float32, int64 `label`, no names) and OBJ (no tipgeo header)
    mesh = tip.to_trimesh()
    mesh.export(tmp_path / "tm.ply")
    r = load_tip(tmp_path / "tm.ply")
    np.testing.assert_array_equal(r.label_ids, tip.label_ids)
    assert r.label_names[: 5] == ("label0", "label1", "label2", "label3", "label4")
    assert np.abs(r.vertices - tip.vertices).max() <= F32
    mesh.export(tmp_path / "tm.obj")
    r = load_tip(tmp_path / "tm.obj")
    assert len(r.faces) == len(tip.faces) and set(r.labels) == {"unlabelled"}
    assert abs(r.volume - tip.volume) <= 1e-6 * tip.volume
