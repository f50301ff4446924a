"""Instrument height maps and CSV/TXT exports as scans.

Every format round-trips a known analytic height map — a tilted plane plus a
sphere cap, 53 × 37 pixels of 1.25 × 1.5 µm (odd width: AL3D row padding),
two invalid pixels — written by a writer that follows the format's
specification, read back through :func:`load_scan`, and compared with the
surface within the file's own precision, stated per format:

- X3P ``D`` (float64 m), DataList text, SDF (float64): ≤ 1e-15 mm (a few
  float64 ulps of 0.25 mm);
- X3P ``F``, AL3D (float32 m): bit for bit the float32 value of the height in
  m, hence within half a float32 ulp (2⁻³⁶ m = 1.46e-8 mm at 0.25 mm);
- X3P ``I``/``L``, SUR (integers times a z step): within half the step
  (+ 1e-15 mm of float arithmetic);
- lateral spacing and offsets: exact where the file stores decimal text or
  float64, the float32 value where it stores float32 (SUR).

The files written by surfalize's own writers (.sflz, .tmd) and a Sensofar
.plu laid out as surfalize's reader expects are read through surfalize, and
surfalize's reading of the files written here is cross-checked.
"""

from __future__ import annotations

import hashlib
import json
import struct
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tipgeo.errors import MissingToolError
from tipgeo.inspect import heightmap as hmod
from tipgeo.inspect.heightmap import (
    LENGTH_UNITS,
    read_height_map,
    surfalize_available,
    to_mm,
    write_al3d,
    write_sdf,
    write_sur,
    write_x3p,
)
from tipgeo.inspect.scanio import ScanError, load_scan

NY, NX = 37, 53
DX, DY = 0.00125, 0.0015           # mm
X0, Y0 = 0.1, -0.2                 # mm
BAD = [(3, 5), (20, 40)]

needs_surfalize = pytest.mark.skipif(not surfalize_available(), reason="surfalize not installed")


def surface() -> np.ndarray:
    """Tilted plane + sphere cap (R 20 µm), mm; two NaN pixels."""
    x = np.arange(NX) * DX
    y = np.arange(NY)[:, None] * DY
    cap = np.sqrt(np.maximum(0.02**2 - (x - 0.03) ** 2 - (y - 0.027) ** 2, 0.0))
    z = 0.02 * x - 0.01 * y + cap - 0.25
    for i, j in BAD:
        z[i, j] = np.nan
    return z


Z = surface()
OK = np.isfinite(Z)


def f32_mm(z_mm):
    """What a float32-in-metres format stores, back in mm."""
    return np.float32(z_mm / 1000.0).astype(np.float64) * 1000.0


def _check_points(s, hm_z, dx, dy, x0=0.0, y0=0.0):
    """The scan's points are the valid pixels at (x0 + j·dx, y0 + i·dy, z)."""
    ii, jj = np.nonzero(np.isfinite(hm_z))
    want = np.column_stack([x0 + jj * dx, y0 + ii * dy, hm_z[ii, jj]])
    assert np.array_equal(s.points, want)
    assert s.meta["invalid_pixels"] == int((~np.isfinite(hm_z)).sum())
    assert s.meta["grid"] == list(hm_z.shape) and s.meta["pixels"] == hm_z.size
    json.dumps(s.meta)                                    # the report can carry it


# -----------------------------------------------------------------------------
# 1. formats read by tipgeo: exactness per format
def test_x3p_float64_round_trips_exactly(tmp_path):
    f = write_x3p(tmp_path / "d.x3p", Z, DX, DY, x0_mm=X0, y0_mm=Y0)
    hm = read_height_map(f)
    assert (hm.dx, hm.dy, hm.x0, hm.y0) == (DX, DY, X0, Y0)       # decimal text: exact
    assert np.array_equal(np.isnan(hm.z), ~OK)
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 1e-15
    s = load_scan(f)
    _check_points(s, hm.z, DX, DY, X0, Y0)
    assert s.meta["invalid_pixels"] == 2 and s.meta["units_from"] == "file"
    assert s.meta["file_units"] == "m" and s.meta["spacing_mm"] == [DX, DY]
    # the same file with the heights as text Datum elements
    f2 = write_x3p(tmp_path / "t.x3p", Z, DX, DY, data_list=True)
    assert np.array_equal(read_height_map(f2).z, hm.z, equal_nan=True)


def test_x3p_float32_is_the_float32_of_the_height_in_metres(tmp_path):
    hm = read_height_map(write_x3p(tmp_path / "f.x3p", Z, DX, DY, dtype="F"))
    assert np.array_equal(hm.z[OK], f32_mm(Z[OK]))
    # half a float32 ulp at 0.25 mm: 2⁻³⁶ m = 1.46e-8 mm
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 2.0**-36 * 1000
    assert hm.invalid == 2


@pytest.mark.parametrize("dtype, levels", [("I", 2 * 32766), ("L", 2 * (2**31 - 2))])
def test_x3p_integers_round_to_half_the_increment(tmp_path, dtype, levels):
    hm = read_height_map(write_x3p(tmp_path / f"{dtype}.x3p", Z, DX, DY, dtype=dtype))
    step_mm = (np.nanmax(Z) - np.nanmin(Z)) / levels
    assert float(hm.meta["z_increment_m"]) * 1000 == pytest.approx(step_mm, rel=1e-12)
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 0.5 * step_mm + 1e-15
    assert np.array_equal(np.isnan(hm.z), ~OK)          # the validity bit mask


def test_x3p_validity_mask_drops_a_finite_pixel(tmp_path):
    f = write_x3p(tmp_path / "v.x3p", np.nan_to_num(Z, nan=-0.25), DX, DY, valid_mask=True)
    with zipfile.ZipFile(f) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    mask = np.ones(NY * NX, bool)
    mask[[i * NX + j for i, j in BAD]] = False
    bits = np.packbits(mask, bitorder="little").tobytes()
    xml = members["main.xml"].decode()
    old = xml.split("<MD5ChecksumValidPoints>")[1].split("<")[0]
    members["main.xml"] = xml.replace(old, hashlib.md5(bits).hexdigest()).encode()
    members["bindata/valid.bin"] = bits
    with zipfile.ZipFile(f, "w") as zf:
        for n, b in members.items():
            zf.writestr(n, b)
    hm = read_height_map(f)
    assert hm.invalid == 2 and np.array_equal(np.isnan(hm.z), ~OK)


def test_al3d_is_float32_metres_with_padded_rows(tmp_path):
    f = write_al3d(tmp_path / "a.al3d", Z, DX, DY)
    hm = read_height_map(f)
    assert (hm.dx, hm.dy) == (DX, DY)                     # pixel sizes as decimal text
    assert np.array_equal(hm.z[OK], f32_mm(Z[OK]))          # NX = 53: rows padded to 8 bytes
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 2.0**-36 * 1000
    assert np.array_equal(np.isnan(hm.z), ~OK)            # the invalid-pixel value 3e15
    _check_points(load_scan(f), hm.z, DX, DY)


@pytest.mark.parametrize("unit, bits, compressed", [("um", 32, False), ("mm", 16, True),
                                                    ("nm", 32, True)])
def test_sur_heights_within_half_the_z_step(tmp_path, unit, bits, compressed):
    k = float(1 / LENGTH_UNITS[unit])                       # mm -> unit
    f = write_sur(tmp_path / "s.sur", Z, DX * k, DY * k, unit=unit, bits=bits,
                  compressed=compressed, x0=X0 * k, y0=Y0 * k)
    hm = read_height_map(f)
    z_step_mm = to_mm(hm.meta["z_spacing"], unit)
    levels = 2 * (32767 - 16) if bits == 16 else 2 * (2**31 - 17)
    assert z_step_mm <= 1.0001 * (np.nanmax(Z) - np.nanmin(Z)) / levels + 1e-300
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 0.5 * z_step_mm * 1.0001 + 1e-15
    assert np.array_equal(np.isnan(hm.z), ~OK)            # the non-measured code Zmin − 2
    # the header stores float32 lengths in its unit
    assert hm.dx == to_mm(float(np.float32(DX * k)), unit)
    assert hm.x0 == to_mm(float(np.float32(X0 * k)), unit)
    assert abs(hm.dx - DX) <= 1e-7 * DX and abs(hm.y0 - Y0) <= 1e-7 * abs(Y0)
    assert hm.meta["file_units"] == unit
    _check_points(load_scan(f), hm.z, hm.dx, hm.dy, hm.x0, hm.y0)


@pytest.mark.parametrize("binary", [True, False])
def test_sdf_float64_round_trips(tmp_path, binary):
    f = write_sdf(tmp_path / "s.sdf", Z, DX, DY, binary=binary)
    hm = read_height_map(f)
    assert (hm.dx, hm.dy) == (DX, DY) if not binary else (
        abs(hm.dx - DX) <= 1e-18 and abs(hm.dy - DY) <= 1e-18)
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= 1e-15
    assert np.array_equal(np.isnan(hm.z), ~OK)            # type minimum / BAD


def test_al3d_repeatability_plane_hides_unrepeatable_depths(tmp_path):
    codes = np.zeros(Z.shape, np.uint8)
    codes[10, 11] = codes[30, 52] = 200                   # above the filter value
    codes[3, 5] = 250                                     # already invalid
    f = write_al3d(tmp_path / "r.al3d", Z, DX, DY, repeatability_codes=codes,
                   filter_value=100.0, shift=0.5, minimum=1.0)
    hm = read_height_map(f)
    assert hm.invalid == 4 and hm.meta["unrepeatable_pixels"] == 2
    assert np.isnan(hm.z[10, 11]) and np.isnan(hm.z[30, 52])
    s = load_scan(f)
    assert s.meta["invalid_pixels"] == 4 and len(s) == NX * NY - 4
    if surfalize_available():            # surfalize applies the same filter
        import surfalize

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            theirs = surfalize.Surface.load(f)
        assert np.array_equal(np.isnan(theirs.data), np.isnan(hm.z))


def test_compact_storage_of_a_height_map(tmp_path):
    f = write_x3p(tmp_path / "d.x3p", Z, DX, DY)
    s = load_scan(f, compact=True)
    full = load_scan(f)
    assert s.local.dtype == np.float32
    assert np.max(np.abs(s.points - full.points)) <= s.rounding_mm <= 2.0**-21


# -----------------------------------------------------------------------------
# 2. surfalize: its readers on files written here, its writers read back
@needs_surfalize
@pytest.mark.parametrize("name", ["d.x3p", "a.al3d", "b.sdf", "u.sur"])
def test_surfalize_reads_our_files_alike(tmp_path, name):
    """Cross-check: surfalize's own readers give the same heights and spacing
    (µm, converted here) as tipgeo's readers on these files."""
    import surfalize

    p = tmp_path / name
    {"d.x3p": lambda: write_x3p(p, Z, DX, DY), "a.al3d": lambda: write_al3d(p, Z, DX, DY),
     "b.sdf": lambda: write_sdf(p, Z, DX, DY),
     "u.sur": lambda: write_sur(p, Z, DX * 1000, DY * 1000, unit="um")}[name]()
    ours = read_height_map(p)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # 'different pixel size in x and y'
        theirs = surfalize.Surface.load(p)
    assert np.array_equal(np.isnan(theirs.data), np.isnan(ours.z))
    assert np.nanmax(np.abs(theirs.data / 1000.0 - ours.z)) <= 1e-15
    assert theirs.step_x / 1000.0 == pytest.approx(ours.dx, rel=1e-15)
    assert theirs.step_y / 1000.0 == pytest.approx(ours.dy, rel=1e-15)


@needs_surfalize
@pytest.mark.parametrize("ext, kw", [(".x3p", {}), (".x3p", {"dtype": "F"}), (".al3d", {}),
                                     (".sur", {}), (".sur", {"compressed": True}),
                                     (".sdf", {}), (".sdf", {"binary": False})])
def test_our_readers_read_surfalizes_files(tmp_path, ext, kw):
    """The other direction: files written by surfalize's writers (an
    independent implementation of each specification) read by tipgeo, within
    what each file stores: float64 m (x3p D, sdf binary); float32 m (x3p F,
    al3d); 10 decimals of the value scaled to one leading digit (sdf ASCII);
    int32 over the range with a float32 step and a float32 offset in µm (sur:
    half a step + the float32 rounding of the offset, 2⁻¹⁷ µm at 240 µm)."""
    import surfalize

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surf = surfalize.Surface(Z * 1000.0, DX * 1000.0, DY * 1000.0)
        p = tmp_path / f"s{ext}"
        surf.save(p, **kw)
    hm = read_height_map(p)
    assert np.array_equal(np.isnan(hm.z), ~OK)
    err = np.max(np.abs(hm.z[OK] - Z[OK]))
    tol = {".x3p": 1e-15 if not kw else 2.0**-36 * 1000, ".al3d": 2.0**-36 * 1000,
           ".sdf": 1e-15 if not kw else 1e-11, ".sur": 2.0**-17 / 1000 + 1e-11}[ext]
    assert err <= tol, (ext, kw, err)
    lat = 1e-15 * DX if ext != ".sur" else 2.0**-24 * DX       # float32 µm spacing in SUR
    assert abs(hm.dx - DX) <= lat and abs(hm.dy - DY) <= lat * DY / DX


@needs_surfalize
def test_sur_offset_in_another_unit_is_read_right(tmp_path):
    """A SUR in mm (or nm) with a z offset: heights = raw·Δz + offset, both in
    the Δz unit. (surfalize 0.19 adds the offset unconverted to its µm
    heights — 48.5 µm off here in mm, 48.5 mm in nm; tipgeo reads SUR itself.)"""
    f = write_sur(tmp_path / "m.sur", Z, DX, DY, unit="mm")
    hm = read_height_map(f)
    assert hm.meta["z_offset"] == pytest.approx(-0.2395, abs=1e-3)
    assert np.nanmax(np.abs(hm.z - Z)) <= 1e-10


@needs_surfalize
@pytest.mark.parametrize("ext, kw, ztol, xytol", [
    (".sflz", {"dtype": "<f8"}, 1e-15, 1e-18),       # float64 µm
    (".sflz", {}, 1e-11, 1e-18),                     # uint32 over the range: ≤ half a step
    (".tmd", {}, 1e-8, 1e-12),                       # float32 µm: ≤ half a float32 ulp
])
def test_surfalize_formats_read_through_it(tmp_path, ext, kw, ztol, xytol):
    import surfalize

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surf = surfalize.Surface(Z * 1000.0, DX * 1000.0, DY * 1000.0)
    p = tmp_path / f"s{ext}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surf.save(p, **kw)
    s = load_scan(p)
    hm = read_height_map(p)
    assert abs(hm.dx - DX) <= xytol and abs(hm.dy - DY) <= xytol
    assert hm.invalid == 2 and s.meta["invalid_pixels"] == 2
    assert np.max(np.abs(hm.z[OK] - Z[OK])) <= ztol
    assert s.meta["reader"].startswith("surfalize")
    _check_points(s, hm.z, hm.dx, hm.dy)


def _write_plu(path: Path, z_um: np.ndarray, step_um: float) -> None:
    """A Sensofar .plu laid out as surfalize's reader reads it: date block,
    comment, calibration record, measurement configuration, float32 µm heights
    (1000001: not measured)."""
    ny, nx = z_um.shape
    head = b"01/01/2000 00:00".ljust(128, b"\0") + b"\0" * 260
    head += struct.pack("<IIIfffffff", ny, nx, 0, 1.0, step_um, step_um, 0.0, 0.0, 1.0, 0.0)
    head += struct.pack("<10Idf2I5b3xI", *([0] * 7), nx, ny, 0, 0.0, 0.0, 0, 0, 0, 0, 0, 0, 0,
                        0)
    data = np.where(np.isfinite(z_um), z_um, 1000001.0).astype("<f4")
    path.write_bytes(head + data.tobytes())


@needs_surfalize
def test_plu_through_surfalize(tmp_path):
    p = tmp_path / "s.plu"
    step_um = 1.25
    _write_plu(p, Z * 1000.0, step_um)
    s = load_scan(p)
    hm = read_height_map(p)
    assert hm.dx == hm.dy == float(np.float32(step_um)) / 1000.0
    assert hm.invalid == 2
    zf = np.float32(Z * 1000.0).astype(np.float64) / 1000.0     # float32 µm
    assert np.array_equal(hm.z[OK], zf[OK])
    _check_points(s, hm.z, hm.dx, hm.dy)


def test_surfalize_formats_need_it(tmp_path, monkeypatch):
    p = tmp_path / "s.plu"
    _write_plu(p, Z * 1000.0, 1.25)
    monkeypatch.setitem(sys.modules, "surfalize", None)
    monkeypatch.setitem(sys.modules, "surfalize.file", None)
    with pytest.raises(MissingToolError, match=r"surfalize.*pip install"):
        load_scan(p)
    assert read_height_map(write_x3p(tmp_path / "d.x3p", Z, DX, DY)).invalid == 2


@needs_surfalize
def test_surfalize_garbage_is_a_one_line_scan_error(tmp_path):
    for ext in (".plu", ".vk4", ".os3d", ".sflz", ".zon", ".dat"):
        p = tmp_path / f"junk{ext}"
        p.write_bytes(b"\x00\x01junk" * 7)
        with pytest.raises(ScanError) as e:
            load_scan(p)
        msg = str(e.value)
        assert "\n" not in msg and f"junk{ext}" in msg


# -----------------------------------------------------------------------------
# 3. bounds and malformed files
def _x3p_xml(sx=5, sy=4, ftype="SUR", dtype="D", extra=""):
    return (f'<?xml version="1.0"?><p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">'
            f"<Record1><FeatureType>{ftype}</FeatureType><Axes>"
            "<CX><AxisType>I</AxisType><Increment>1e-6</Increment></CX>"
            "<CY><AxisType>I</AxisType><Increment>1e-6</Increment></CY>"
            f"<CZ><AxisType>A</AxisType><DataType>{dtype}</DataType></CZ></Axes></Record1>"
            f"<Record3><MatrixDimension><SizeX>{sx}</SizeX><SizeY>{sy}</SizeY><SizeZ>1</SizeZ>"
            "</MatrixDimension><DataLink><PointDataLink>bindata/data.bin</PointDataLink>"
            f"{extra}</DataLink></Record3></p:ISO5436_2>")


def _zip(path, members):
    with zipfile.ZipFile(path, "w") as zf:
        for k, v in members.items():
            zf.writestr(k, v)
    return path


def test_oversized_maps_are_refused_from_their_headers(tmp_path):
    """10¹² pixels announced in a small file: refused before any allocation."""
    big = 1_000_000
    cases = {
        "big.x3p": lambda p: _zip(p, {"main.xml": _x3p_xml(big, big), "bindata/data.bin": b""}),
        "big.al3d": lambda p: write_al3d(p, Z, DX, DY),
        "big.sdf": lambda p: p.write_bytes(b"bISO-2.0" + struct.pack(
            "<10s12s12sIIddddBBB", b"x", b"0" * 12, b"0" * 12, big, big, 1e-6, 1e-6, 1e-6,
            -1.0, 0, 7, 0) + b"\0" * 64),
        "big.csv": lambda p: p.write_text("dx = 1 um\ndy = 1 um\nrows = 1000000\n"
                                          + ";".join(["1"] * 200) + "\n"),
    }
    for name, make in cases.items():
        p = tmp_path / name
        make(p)
        if name == "big.al3d":
            raw = bytearray(p.read_bytes())
            k = raw.index(b"Cols\0")
            raw[k + 20:k + 50] = str(big).encode().ljust(30, b"\0")
            k = raw.index(b"Rows\0")
            raw[k + 20:k + 50] = str(big).encode().ljust(30, b"\0")
            p.write_bytes(bytes(raw))
        with pytest.raises(ScanError, match=r"1,000,000.*pixels; allowed at most 100,000,000"):
            load_scan(p)
    sur = bytearray(write_sur(tmp_path / "t.sur", Z, 1.25, 1.5).read_bytes())
    struct.pack_into("<ii", sur, 108, big, big)                       # points per line, lines
    (tmp_path / "big.sur").write_bytes(bytes(sur))
    with pytest.raises(ScanError, match="allowed at most 100,000,000"):
        load_scan(tmp_path / "big.sur")


@pytest.mark.parametrize("name, members, match", [
    ("nomain.x3p", {"x.txt": "x"}, "no member 'main.xml'"),
    ("badxml.x3p", {"main.xml": "<p:ISO5436_2><Record1>"}, r"not well-formed XML \(line 1"),
    ("dtd.x3p", {"main.xml": '<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "b">]><x/>'},
     "declares a DTD"),
    ("prf.x3p", {"main.xml": _x3p_xml(ftype="PRF")}, "FeatureType is a profile"),
    ("size.x3p", {"main.xml": _x3p_xml(), "bindata/data.bin": b"\0" * 24},
     r"'bindata/data.bin' holds 24 bytes; expected 160"),
    ("md5.x3p", {"main.xml": _x3p_xml(extra="<MD5ChecksumPointData>00</MD5ChecksumPointData>"),
                 "bindata/data.bin": b"\0" * 160}, "MD5ChecksumPointData says 00"),
    ("type.x3p", {"main.xml": _x3p_xml(dtype="Q")}, "DataType = 'Q'; allowed: I, L, F, D"),
])
def test_malformed_x3p_errors_name_the_part(tmp_path, name, members, match):
    p = _zip(tmp_path / name, members)
    with pytest.raises(ScanError, match=match) as e:
        load_scan(p)
    assert "\n" not in str(e.value) and name in str(e.value)


def test_malformed_binary_maps_name_the_part(tmp_path):
    (tmp_path / "zip.x3p").write_bytes(b"PK\x03\x04 broken")
    a = write_al3d(tmp_path / "a.al3d", Z, DX, DY).read_bytes()
    (tmp_path / "trunc.al3d").write_bytes(a[:-200])
    (tmp_path / "magic.al3d").write_bytes(b"Alic0na" + a[7:])
    s = bytearray(write_sur(tmp_path / "s.sur", Z, 1.25, 1.5).read_bytes())
    (tmp_path / "trunc.sur").write_bytes(bytes(s[:-10]))
    s2 = bytearray(s)
    s2[212:228] = b"furlong".ljust(16, b"\0")                        # unit of the z step
    (tmp_path / "unit.sur").write_bytes(bytes(s2))
    (tmp_path / "magic.sdf").write_bytes(b"cISO-1.0" + b"\0" * 100)
    (tmp_path / "few.sdf").write_text("aISO-1.0\nNumPoints = 3\nNumProfiles = 2\nXscale = 1e-6\n"
                                      "Yscale = 1e-6\nZscale = 1e-6\n*\n1 2 3 4 5\n*\n*\n")
    cases = {"zip.x3p": "not a zip archive", "trunc.al3d": "depth image at DepthImageOffset",
             "magic.al3d": "not an AL3D file", "trunc.sur": "truncated",
             "unit.sur": "unit of the z step: unit 'furlong' is not a length unit",
             "magic.sdf": "not an ISO 25178-71 SDF", "few.sdf": "holds 5 values; expected "
                                                                "NumPoints × NumProfiles = 6"}
    for name, match in cases.items():
        with pytest.raises(ScanError, match=match) as e:
            load_scan(tmp_path / name)
        assert "\n" not in str(e.value) and name in str(e.value)


_GOOD = {}


def _good_file(ext: str) -> bytes:
    if ext not in _GOOD:
        with tempfile.TemporaryDirectory() as tmp:
            p = Path(tmp) / f"g{ext}"
            z = Z[:9, :11]
            {".x3p": lambda: write_x3p(p, z, DX, DY), ".al3d": lambda: write_al3d(p, z, DX, DY),
             ".sur": lambda: write_sur(p, z, 1.25, 1.5, compressed=True),
             ".sdf": lambda: write_sdf(p, z, DX, DY)}[ext]()
            _GOOD[ext] = p.read_bytes()
    return _GOOD[ext]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from([".x3p", ".al3d", ".sur", ".sdf"]),
       st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 255)), max_size=6),
       st.one_of(st.none(), st.integers(0, 1 << 16)))
def test_corrupt_height_maps_give_a_map_or_a_one_line_scan_error(ext, flips, cut):
    """Bytes changed, the file cut short: a height map (some corruptions
    leave a readable file) or a one-line ScanError naming the file — never
    another exception."""
    b = bytearray(_good_file(ext))
    for pos, val in flips:
        b[pos % len(b)] = val
    if cut is not None:
        b = b[:cut % (len(b) + 1)]
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / f"c{ext}"
        p.write_bytes(bytes(b))
        try:
            s = load_scan(p)
        except ScanError as e:
            assert "\n" not in str(e) and f"c{ext}" in str(e)
            return
    assert len(s) >= 1 and np.all(np.isfinite(s.points))


# -----------------------------------------------------------------------------
# 4. CSV / TXT
def _write(tmp_path, name, text, encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding))
    return p


@pytest.mark.parametrize("text, want, units", [
    ("x [µm];y [µm];z [µm]\n1,5;2,0;3,5\n4,5;5,0;6,5\n",
     [[1.5, 2.0, 3.5], [4.5, 5.0, 6.5]], "um"),
    ("X (mm),Y (mm),Z (mm)\n1.5,2.0,3.5\n4.5,5.0,6.5\n", [[1.5, 2.0, 3.5], [4.5, 5.0, 6.5]],
     "mm"),
    ("# exported\nz_um\tx_um\ty_um\n3.5\t1.5\t2\n6.5\t4.5\t5\n",
     [[1.5, 2.0, 3.5], [4.5, 5.0, 6.5]], "um"),
    ("x y z\n[mm] [mm] [nm]\n1 2 3000\n", [[1.0, 2.0, 0.003]], None),
    ("1,5 2,0 3,5\n4,5 5,0 6,5\n", [[1.5, 2.0, 3.5], [4.5, 5.0, 6.5]], "mm"),
    ('"x";"y";"z"\n"1,5";"2";"3"\n', [[1.5, 2.0, 3.0]], "mm"),
    ("x|y|z\n1|2|3\n", [[1.0, 2.0, 3.0]], "mm"),
    ("x;y;z;unit\n1;2;3;mm\n4000;5000;6000;µm\n1;1;1;in\n",
     [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [25.4, 25.4, 25.4]], None),
])
def test_csv_point_lists(tmp_path, text, want, units):
    s = load_scan(_write(tmp_path, "p.csv", text))
    if units == "um":
        want = np.array(want) / 1000.0
    elif units == "mm":
        want = np.array(want)
    assert np.array_equal(s.points, np.asarray(want, float))
    assert s.meta["layout"] == "points"


def test_csv_rows_with_no_data_are_dropped_and_counted(tmp_path):
    s = load_scan(_write(tmp_path, "n.csv", "x,y,z\n1,2,3\n4,,6\n7,8,BAD\n9,9,NaN\n1,1,1\n"))
    assert np.array_equal(s.points, [[1.0, 2.0, 3.0], [1.0, 1.0, 1.0]])
    assert s.meta["invalid_points"] == 3


@pytest.mark.parametrize("head", [
    "Spacing X = 0,5 µm\nSpacing Y = 0,25 µm\nZ unit: µm\n",
    "# dx = 0.5 um\n# dy = 0.25 um\n# unit = um\n",
    '"XY Calibration";"0,5";"µm"\n"Y step";"0,25";"µm"\n"Height unit";"µm"\n',
    "pixel size x [um]: 0.5\npixel size y [um]: 0.25\nheight unit = micron\n",
])
def test_csv_grids_with_spacing_keys(tmp_path, head):
    # with the Keyence-style key the lateral step applies to both axes, then dy overrides
    sep = ";" if ";" in head or "," in head.split("\n")[0] else " "
    dec = "," if "0,5" in head else "."
    rows = [["1,0", "2,0", "3,0", "4,0"], ["5,0", "NaN", "7,0", "8,0"]] if dec == "," else \
        [["1.0", "2.0", "3.0", "4.0"], ["5.0", "NaN", "7.0", "8.0"]]
    text = head + "\n".join(sep.join(r) for r in rows) + "\n"
    s = load_scan(_write(tmp_path, "g.csv", text))
    assert s.meta["layout"] == "grid" and s.meta["grid"] == [2, 4]
    assert s.meta["invalid_pixels"] == 1
    dx = 0.0005
    dy = 0.00025
    assert s.meta["spacing_mm"] == [dx, dy]               # decimal text scaled exactly
    json.dumps(s.meta)
    want = [[0, 0, 1], [dx, 0, 2], [2 * dx, 0, 3], [3 * dx, 0, 4], [0, dy, 5], [2 * dx, dy, 7],
            [3 * dx, dy, 8]]
    assert np.array_equal(s.points, np.array(want, float) * [1, 1, 1e-3])


@pytest.mark.parametrize("sep, dec, enc", [(",", ".", "cp1252"), (";", ",", "utf-8")])
def test_a_vendor_style_height_export(tmp_path, sep, dec, enc):
    """A microscope's CSV height export: quoted metadata rows, a calibration
    row with its unit, a unit row, a title row, then the matrix (an empty
    field: not measured)."""
    q = lambda *f: sep.join(f'"{x}"' for x in f)           # noqa: E731
    n = (lambda v: v.replace(".", ",")) if dec == "," else (lambda v: v)
    text = "\n".join([q("File name", "sample.vk4"), q("Measurement date", "2023/01/01 12:00"),
                      q("Objective lens", "50x"), q("XY calibration", n("0.139"), "µm"),
                      q("Output image data", "Height"), q("Unit", "µm"), '""', q("Height"),
                      q(n("12.3"), n("12.4"), n("12.5")), q(n("12.6"), "", n("12.8"))]) + "\n"
    s = load_scan(_write(tmp_path, "k.csv", text, enc))
    assert s.meta["grid"] == [2, 3] and s.meta["invalid_pixels"] == 1
    assert s.meta["spacing_mm"] == [0.000139, 0.000139]   # the decimal 0.139 µm, exactly
    d = 0.000139
    assert np.array_equal(s.points, np.array([[0, 0, 12.3], [d, 0, 12.4], [2 * d, 0, 12.5],
                                              [0, d, 12.6], [2 * d, d, 12.8]]) / [1, 1, 1000])


def test_grid_spacing_from_the_caller_and_layout(tmp_path):
    p = _write(tmp_path, "m.txt", "0.1 0.2 0.3\n0.4 0.5 0.6\n")
    pts = load_scan(p).points                              # a plain x y z list by default
    assert np.array_equal(pts, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    s = load_scan(p, spacing_mm=(0.01, 0.02))
    assert np.array_equal(s.points, [[0, 0, 0.1], [0.01, 0, 0.2], [0.02, 0, 0.3],
                                     [0, 0.02, 0.4], [0.01, 0.02, 0.5], [0.02, 0.02, 0.6]])
    with pytest.raises(ScanError, match="needs its lateral spacing"):
        load_scan(p, layout="grid")


def test_encodings(tmp_path):
    text = "X [µm]\tY [µm]\tZ [µm]\r\n1000\t2000\t3000\r\n"
    for enc in ("utf-8", "utf-8-sig", "utf-16", "latin-1", "cp1252"):
        s = load_scan(_write(tmp_path, f"e-{enc}.txt", text, enc))
        assert np.array_equal(s.points, [[1.0, 2.0, 3.0]]), enc


@pytest.mark.parametrize("text, match", [
    ("x [furlong];y;z\n1;2;3\n", r"line 1: column 'x \[furlong\]': unit 'furlong' is not a "
                                 r"length unit; allowed: m, cm, mm, µm"),
    ("dx = 1 parsec\ndy = 1 um\n1;2\n3;4\n", r"line 1: dx = 1 parsec: unit 'parsec'"),
    ("z unit = bananas\n1 2 3\n", r"line 1: z unit = 'bananas' is not a length unit"),
    ("x;y;z\n1;2;3\n4;5\n", r"line 3 has 2 ';'-separated fields; expected 3 \(as on line 2\)"),
    ("x;y;z\n1;2;3\n4;5;six\n", r"line 3, column 3: 'six' is not a number"),
    ("1;2\n3;4\n", r"2 value column\(s\).*needs x, y, z"),
    ("x;y;z;unit\n1;2;3;mm\n4;5;6;furlongs\n", r"line 3, column 4: unit 'furlongs'"),
    ("dx = 1 um\n1 2 3\n4 5 6\n", "only one of dx/dy is given"),
])
def test_csv_errors_are_one_line_and_name_file_and_line(tmp_path, text, match):
    p = _write(tmp_path, "bad.csv", text)
    with pytest.raises(ScanError, match=match) as e:
        load_scan(p)
    assert "\n" not in str(e.value) and "bad.csv" in str(e.value)


# -----------------------------------------------------------------------------
# 5. property-based: any dialect gives the points, or a one-line ScanError
_UNIT_SPELLINGS = {"mm": ["mm", "MM", "millimetre"], "um": ["µm", "um", "μm", "micron"],
                   "nm": ["nm"], "m": ["m"], "in": ["in", "inch"]}
_finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_subnormal=False)


@st.composite
def dialects(draw):
    n = draw(st.integers(1, 25))
    pts = draw(st.lists(st.tuples(_finite, _finite, _finite), min_size=n, max_size=n))
    sep = draw(st.sampled_from([",", ";", "\t", " ", "  ", "|"]))
    dec = draw(st.sampled_from([".", ","])) if sep != "," else "."
    unit = draw(st.sampled_from(sorted(_UNIT_SPELLINGS)))
    spelled = draw(st.sampled_from(_UNIT_SPELLINGS[unit]))
    header = draw(st.sampled_from(["none", "bracket", "paren", "suffix", "plain", "keyed"]))
    order = draw(st.permutations([0, 1, 2]))
    comments = draw(st.lists(st.sampled_from(["# comment", "// exported by X", "% note",
                                              "! hi"]), max_size=3))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    quote = draw(st.booleans()) and sep != " " and sep != "  "
    return pts, sep, dec, unit, spelled, header, list(order), comments, eol, quote


def _fmt(v, dec):
    t = repr(float(v))
    return t.replace(".", ",") if dec == "," else t


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dialects())
def test_any_dialect_reads_the_points_exactly(d):
    pts, sep, dec, unit, spelled, header, order, comments, eol, quote = d
    names = ["x", "y", "z"]
    q = (lambda s: f'"{s}"') if quote else (lambda s: s)
    lines = list(comments)
    file_unit = unit
    if header == "bracket":
        lines.append(sep.join(q(f"{names[k]} [{spelled}]") for k in order))
    elif header == "paren":
        lines.append(sep.join(q(f"{names[k].upper()} ({spelled})") for k in order))
    elif header == "suffix":
        if unit == "m" or " " in sep:
            file_unit = "mm"                                   # 'x_m' is a name, not a unit
            lines.append(sep.join(q(names[k]) for k in order))
        else:
            lines.append(sep.join(q(f"{names[k]}_{spelled}") for k in order))
    elif header == "plain":
        file_unit = "mm"
        lines.append(sep.join(q(names[k]) for k in order))
    elif header == "keyed":
        lines.insert(0, f"unit = {spelled}")
        lines.append(sep.join(q(names[k]) for k in order))
    else:
        file_unit = "mm"
        order = [0, 1, 2]
    for p in pts:
        lines.append(sep.join(q(_fmt(p[k], dec)) for k in order))
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "p.csv"
        f.write_bytes(eol.join(lines).encode("utf-8") + eol.encode())
        s = load_scan(f)
    want = np.column_stack([to_mm(np.array([p[k] for p in pts]), file_unit) for k in range(3)])
    assert np.array_equal(s.points, want)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dialects(), st.lists(st.tuples(st.integers(0, 10_000), st.sampled_from(
    ["", ";", ",", "x", "1e", "[", "]", "°", "\t", "\n", " mm", "µ", '"', "=", "NaN", ":"])),
    max_size=4))
def test_mangled_files_give_points_or_a_one_line_scan_error(d, edits):
    pts, sep, dec = d[0], d[1], d[2]
    text = "x;y;z\n" if sep == ";" else ""
    text += "\n".join(sep.join(_fmt(v, dec) for v in p) for p in pts) + "\n"
    for pos, ins in edits:
        k = pos % (len(text) + 1)
        text = text[:k] + ins + text[k:]
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "m.csv"
        f.write_text(text, encoding="utf-8")
        try:
            s = load_scan(f)
        except ScanError as e:
            msg = str(e)
            assert "\n" not in msg and "m.csv" in msg
            return
    assert s.points.ndim == 2 and s.points.shape[1] == 3 and len(s) >= 1
    assert np.all(np.isfinite(s.points))


def test_point_limit_applies_to_text(tmp_path, monkeypatch):
    from tipgeo.inspect import scanio, textscan

    monkeypatch.setattr(scanio, "MAX_SCAN_POINTS", 5)
    p = _write(tmp_path, "l.csv", "x;y;z\n" + "1;2;3\n" * 6)
    with pytest.raises(ScanError, match="more than 5 points"):
        load_scan(p)
    monkeypatch.setattr(textscan, "MAX_SCAN_POINTS", 5)
    with pytest.raises(ScanError, match="more than 5 pixels"):
        scanio.read_table_grid(p, textscan.sniff_table(p, layout="grid", spacing_mm=1.0),
                               max_pixels=5)
    assert hmod.MAX_SCAN_POINTS == 100_000_000
