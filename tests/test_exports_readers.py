"""The files tipgeo writes, opened by the programs users open them with:
3MF by lib3mf in strict mode, GLB checked against the glTF 2.0 rules a Python
check can hold (through pygltflib), every ISO program parsed by pygcode.

Tolerances (mm, cannula frame): lib3mf hands vertices back as float32, so each
coordinate within ``|x| · 2⁻²⁴`` (half a float32 ulp) of the double; GLB
float32 likewise; ISO words are written with 4 decimals, so within 5e-5 (mm or
deg) of the program rows.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo import preset
from tipgeo.errors import SpecError
from tipgeo.io import export_tip, load_tip
from tipgeo.io.gltf import gltf_transform

F32_REL = 2.0 ** -24
ISO_WORD = 5e-5  # half the last written decimal (mm or deg)


@pytest.fixture(scope="module")
def tips(build_preset):
    return {n: build_preset(n) for n in ("bevel-14G-xi15", "lancet-14G")}


# -- 3MF ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bevel-14G-xi15", "lancet-14G"])
def test_3mf_reads_in_lib3mf_strict_mode(tips, name, tmp_path):
    lib3mf = pytest.importorskip("lib3mf")
    tip = tips[name]
    p = export_tip(tip, tmp_path / "t.3mf")
    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    reader = model.QueryReader("3mf")
    reader.SetStrictModeActive(True)
    reader.ReadFromFile(str(p))  # raises Lib3MFException on any strict-mode violation
    assert reader.GetWarningCount() == 0
    assert model.GetUnit() == lib3mf.ModelUnit.MilliMeter
    objs = model.GetMeshObjects()
    assert objs.Count() == 1 and objs.MoveNext()
    obj = objs.GetCurrentMeshObject()
    assert obj.GetName() == name and obj.IsValid()
    assert obj.GetVertexCount() == len(tip.vertices)
    assert obj.GetTriangleCount() == len(tip.faces)
    v = np.array([pt.Coordinates[:] for pt in obj.GetVertices()], dtype=np.float64)
    assert np.all(np.abs(v - tip.vertices) <= np.abs(tip.vertices) * F32_REL + 1e-300)
    f = np.array([t.Indices[:] for t in obj.GetTriangleIndices()], dtype=np.int64)
    np.testing.assert_array_equal(f, tip.faces)
    items = model.GetBuildItems()
    assert items.Count() == 1
    # and the exact doubles come back through tipgeo's own reader
    r = load_tip(p)
    assert np.abs(r.vertices - tip.vertices).max() <= 1e-12
    assert r.volume == pytest.approx(tip.volume, rel=1e-12)


def test_3mf_is_deterministic_and_declares_no_extensions(tips, tmp_path):
    import zipfile

    a = export_tip(tips["bevel-14G-xi15"], tmp_path / "a.3mf").read_bytes()
    b = export_tip(tips["bevel-14G-xi15"], tmp_path / "b.3mf").read_bytes()
    assert a == b
    with zipfile.ZipFile(tmp_path / "a.3mf") as z:
        model = z.read("3D/3dmodel.model").decode("ascii")
    assert "xmlns:" not in model and "UUID" not in model and model.count("<item ") == 1


# -- GLB ---------------------------------------------------------------------------
_COMPONENT_SIZE = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_SIZE = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_DTYPE = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}


def _accessor_data(gltf, blob: bytes, k: int) -> np.ndarray:
    acc = gltf.accessors[k]
    view = gltf.bufferViews[acc.bufferView]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    n = acc.count * _TYPE_SIZE[acc.type]
    return np.frombuffer(blob, dtype=_DTYPE[acc.componentType], count=n,
                         offset=start).reshape(acc.count, -1)


def check_glb_rules(path) -> tuple[object, bytes]:
    """The glTF 2.0 rules (the Khronos validator's) that hold for a one-mesh
    GLB: header and chunks, asset version, buffer and view bounds, accessor
    alignment and bounds, POSITION min/max equal to the data, indices in
    range, triangles, the scene graph. Returns the pygltflib document and its
    binary chunk."""
    import pygltflib

    raw = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", raw, 0)
    assert (magic, version, length) == (b"glTF", 2, len(raw))
    json_len, json_type = struct.unpack_from("<II", raw, 12)
    assert json_type == 0x4E4F534A and json_len % 4 == 0
    json.loads(raw[20:20 + json_len])  # valid JSON
    bin_len, bin_type = struct.unpack_from("<II", raw, 20 + json_len)
    assert bin_type == 0x004E4942 and bin_len % 4 == 0
    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    assert gltf.asset.version == "2.0"
    assert len(gltf.buffers) == 1 and gltf.buffers[0].uri is None
    assert gltf.buffers[0].byteLength <= len(blob) <= gltf.buffers[0].byteLength + 3
    for view in gltf.bufferViews:
        assert view.buffer == 0 and view.byteLength > 0
        assert (view.byteOffset or 0) + view.byteLength <= gltf.buffers[0].byteLength
    for acc in gltf.accessors:
        view = gltf.bufferViews[acc.bufferView]
        size = _COMPONENT_SIZE[acc.componentType]
        assert ((view.byteOffset or 0) + (acc.byteOffset or 0)) % size == 0
        assert (acc.byteOffset or 0) + acc.count * size * _TYPE_SIZE[acc.type] <= \
            view.byteLength
    assert gltf.scene is not None and gltf.scene < len(gltf.scenes)
    for node in gltf.scenes[gltf.scene].nodes:
        assert 0 <= node < len(gltf.nodes)
    assert len(gltf.meshes) == 1
    (prim,) = gltf.meshes[0].primitives
    assert prim.mode in (None, 4)  # TRIANGLES
    pos_acc = gltf.accessors[prim.attributes.POSITION]
    assert pos_acc.type == "VEC3" and pos_acc.componentType == 5126
    pos = _accessor_data(gltf, blob, prim.attributes.POSITION)
    # the validator demands exact POSITION bounds
    assert pos_acc.min == pos.min(axis=0).tolist() and pos_acc.max == pos.max(axis=0).tolist()
    idx_acc = gltf.accessors[prim.indices]
    assert idx_acc.type == "SCALAR" and idx_acc.componentType in (5121, 5123, 5125)
    assert idx_acc.count % 3 == 0
    idx = _accessor_data(gltf, blob, prim.indices).ravel()
    assert idx.max() < pos_acc.count
    tri = idx.reshape(-1, 3)
    assert np.all((tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2]))
    return gltf, blob


@pytest.mark.parametrize("units, up", [("m", "y"), ("mm", "y"), ("m", "z"), ("mm", "z")])
def test_glb_follows_gltf_rules_units_and_up_axis(tips, units, up, tmp_path):
    pytest.importorskip("pygltflib")
    tip = tips["lancet-14G"]
    kw = {} if (units, up) == ("m", "y") else {"gltf_units": units, "gltf_up": up}
    p = export_tip(tip, tmp_path / "t.glb", **kw)
    gltf, blob = check_glb_rules(p)
    info = gltf.meshes[0].extras["tipgeo"]
    assert info["units"] == units and info["up_axis"] == "+" + up
    assert gltf.scenes[gltf.scene].extras["tipgeo"]["units"] == units
    assert info["label_names"] == list(tip.label_names)
    # file coordinates: the cannula frame turned (needle along +y) and scaled
    pos = _accessor_data(gltf, blob, gltf.meshes[0].primitives[0].attributes.POSITION)
    scale = 1e-3 if units == "m" else 1.0
    x, y, z = tip.vertices.T
    want = np.column_stack([x, z, -y] if up == "y" else [x, y, z]) * scale
    assert np.all(np.abs(pos - want) <= np.abs(want) * F32_REL)
    # the extras' matrix maps the file back to the cannula frame in mm
    back = np.asarray(info["to_cannula_mm"]).reshape(4, 4)
    np.testing.assert_allclose(back @ gltf_transform(units, up), np.eye(4), atol=1e-12)
    # the needle stands along the viewer's up axis: its height is the tip's length
    axis = 1 if up == "y" else 2
    assert (pos[:, axis].max() - pos[:, axis].min()) / scale == pytest.approx(
        np.ptp(tip.vertices[:, 2]), rel=1e-6)
    # tipgeo reads it back in the cannula frame, in mm, labels intact
    r = load_tip(p)
    assert np.all(np.abs(r.vertices - tip.vertices) <= 2e-6 * np.abs(tip.vertices).max())
    assert list(r.labels) == list(tip.labels)
    assert r.volume == pytest.approx(tip.volume, rel=1e-5)


def test_glb_units_contradiction_and_bad_options(tips, tmp_path):
    tip = tips["bevel-14G-xi15"]
    p = export_tip(tip, tmp_path / "t.glb")
    with pytest.raises(SpecError, match=r"units = 'mm' contradicts.*'m'"):
        load_tip(p, units="mm")
    assert load_tip(p, units="m").volume == pytest.approx(tip.volume, rel=1e-5)
    for kw, match in (({"gltf_units": "cm"}, "gltf_units = 'cm'.*allowed: 'm', 'mm'"),
                      ({"gltf_up": "x"}, "gltf_up = 'x'.*allowed: 'y', 'z'")):
        with pytest.raises(SpecError, match=match):
            export_tip(tip, tmp_path / "u.glb", **kw)
    assert not (tmp_path / "u.glb").exists()


# -- ISO programs ------------------------------------------------------------------
GRINDABLE = ["bevel-14G-xi15", "bevel-14G-xi75", "conical-14G-theta15", "twoplane-14G-xi15",
             "threeplane-14G-xi15", "lancet-14G"]


def check_iso_program(text: str) -> list:
    """Parse every line of an ISO program with pygcode and check the frame a
    controller expects; returns the parsed lines."""
    from pygcode import Line

    text.encode("ascii")  # ASCII only (UnicodeEncodeError otherwise)
    lines = text.split("\n")
    assert lines[-1] == "" and lines[0] == "%" and lines[-2] == "%"
    body = lines[1:-2]
    parsed = [Line(s) for s in body]
    first = parsed[0].block.gcodes
    assert [type(g).__name__ for g in first] == ["GCodeProgramName"]
    assert 1 <= int(first[0].word.value) <= 9999
    safety = {str(g) for g in parsed[1].block.gcodes}
    assert {"G17", "G21", "G40", "G49", "G80", "G90", "G94"} <= safety
    assert [str(g) for g in parsed[-1].block.gcodes] == ["M30"]
    assert [str(g) for g in parsed[-2].block.gcodes] == ["M05"]
    for s, ln in zip(body, parsed):
        if "(" in s:
            c = s[s.index("("):]
            # one comment, closed, nothing nested, no ';' or '%' inside
            assert c.count("(") == 1 and c.endswith(")") and c.count(")") == 1
            assert ";" not in c and "%" not in c
            assert ln.comment is not None and ln.comment.text == c[1:-1]
        assert ";" not in s
        assert ln.block.text.strip() == s[:s.index("(")].strip() if "(" in s else s.strip()
    return parsed


@pytest.mark.parametrize("name", GRINDABLE)
def test_grinder_iso_program_parses_with_pygcode(name):
    pytest.importorskip("pygcode")
    from cam import make_program

    prog = make_program(preset(name))
    parsed = check_iso_program(prog.to_gcode())
    moves = []
    for ln in parsed:
        for g in ln.block.gcodes:
            if type(g).__name__ in ("GCodeRapidMove", "GCodeLinearMove"):
                moves.append((str(g.word), {k: float(w.value) for k, w in g.params.items()}))
    assert len(moves) == len(prog.rows)
    for (word, p), r in zip(moves, prog.rows):
        assert word == ("G00" if r["feed"] is None else "G01")
        for axis, key in (("X", "t2"), ("Z", "t1"), ("A", "r3"), ("C", "r4"), ("B", "r5")):
            assert math.isclose(p[axis], r[key], abs_tol=ISO_WORD)


def test_comments_are_made_safe():
    from cam.iso import iso_comment

    c = iso_comment("machine: grinder (thesis §2.3.1.2); ξ = 15° — ok % µm\nnext")
    assert c == "(machine: grinder [thesis sec. 2.3.1.2], xi = 15 deg - ok pct um next)"
    c.encode("ascii")


def test_program_number_is_checked():
    from cam import CamError, make_program

    prog = make_program(preset("bevel-14G-xi15"))
    assert prog.to_gcode(program_number=42).split("\n")[1].startswith("O0042 (")
    for bad in (0, 10000, 1.5, True):
        with pytest.raises(CamError, match="program_number"):
            prog.to_gcode(program_number=bad)


def test_cli_grind_writes_a_parseable_program(tmp_path):
    pytest.importorskip("pygcode")
    from tipgeo.cli import main

    out = tmp_path / "p.nc"
    assert main(["grind", "threeplane-14G-xi15", "--gcode", str(out)]) == 0
    check_iso_program(out.read_text(encoding="ascii"))


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=80))
def test_any_comment_text_becomes_one_parseable_ascii_comment(text):
    from pygcode import Line

    from cam.iso import iso_comment

    c = iso_comment(text)
    c.encode("ascii")
    assert c.startswith("(") and c.endswith(")") and c.count("(") == 1 and c.count(")") == 1
    assert not set(";%\n\r\t") & set(c)
    line = Line(f"G00 X1.0000 {c}")
    assert line.comment is not None and line.comment.text == c[1:-1]
    assert [str(g) for g in line.block.gcodes] == ["G00 X1"]
