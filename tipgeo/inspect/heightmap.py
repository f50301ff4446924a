"""Instrument height maps: areal topography files read into a regular grid of
heights, and the grid turned into points in the instrument frame.

Formats
-------
Read here, from their specifications, with no optional dependency:

- ``.x3p`` — ISO 25178-72 (ISO 5436-2 XML in a zip: ``main.xml`` and
  ``bindata/data.bin``), surfaces (FeatureType ``SUR``) on incremental x, y
  axes, every z data type (``I`` int16, ``L`` int32, ``F`` float32, ``D``
  float64, or a text ``DataList``), the validity bit mask
  (``bindata/valid.bin``), the axis offsets; the MD5 of the point data is
  checked when the file gives it;
- ``.al3d`` — Alicona (Bruker Alicona) AL3D: tags of 52 bytes, the float32
  depth image in metres, scanlines padded to 8 bytes, the invalid-pixel value;
- ``.sur`` — Digital Surf (MountainsMap) surfaces, plain and ``DSCOMPRESSED``,
  16- or 32-bit points, the non-measured-point code (``Zmin − 2``), units
  from the header (heights ``raw·Δz + z_offset`` in the Δz unit, as Gwyddion
  reads them);
- ``.sdf`` — ISO 25178-71 surface data files, binary and ASCII, ISO-1.0 and
  ISO-2.0.

Read through the optional package surfalize (``pip install
"tipgeo[instruments]"``; :class:`~tipgeo.errors.MissingToolError` without
it): :data:`SURFALIZE_FORMATS` — Sensofar ``.plu``/``.plux``, Keyence
``.vk3``/``.vk4``/``.vk6``/``.vk7``/``.zon``, Zygo MetroPro ``.dat``, Wyko
``.opd``, OmniSurf3D ``.os3d``, Olympus ``.lext``/``.oir``/``.poir``,
NanoFocus ``.nms``, Zeta ``.zmg``, Heliotis ``.hdat``, Gwyddion ``.gwy``,
TrueMap ``.tmd`` and surfalize's own ``.sflz``. Each is read by that format's
own reader function (never surfalize's fallback that tries every reader on a
file that failed), in µm, and converted to mm here.

Frame and units
---------------
Pixel (row i, column j) of a map is the point x = x0 + j·dx, y = y0 + i·dy,
z = height, all in mm, rows and columns in the file's own order (for X3P the
ISO frame; for the image-ordered formats, row 0 is the file's first line).
Units are converted to mm exactly: a unit below the mm by a correctly rounded
division (µm: ``/1000``), above it by a multiplication by an exact integer;
header numbers given as decimal text (X3P, AL3D, SDF ASCII) are scaled in
decimal arithmetic before the one rounding to float64.

Invalid pixels (NaN, infinite, or the format's no-data code) are NaN in
:attr:`HeightMap.z` and dropped from :meth:`HeightMap.points`; their count is
:attr:`HeightMap.invalid`.

Bounds: a map of more than :data:`MAX_SCAN_POINTS` pixels is refused from
its header, before its data are read or allocated; a zip member or a
compressed stream is never inflated past the size its header announces.
Every malformed file is a one-line :class:`~tipgeo.errors.ScanError` naming
the file, the part (header key, member, line, pixel count) and what was
expected.
"""

from __future__ import annotations

import hashlib
import os
import re
import struct
import xml.etree.ElementTree as ET
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from fractions import Fraction
from pathlib import Path
from typing import IO, Any, overload

import numpy as np

from ..arrays import AnyArray, ArrayLike, BoolArray, FloatArray
from ..atomic import write_atomic
from ..errors import MissingToolError, ScanError
from ..tolerances import tol

__all__ = ["HeightMap", "read_height_map", "HEIGHT_MAP_FORMATS", "OWN_FORMATS",
           "SURFALIZE_FORMATS", "MAX_SCAN_POINTS", "MAX_SCAN_BYTES", "LENGTH_UNITS",
           "parse_unit", "to_mm", "write_x3p", "write_al3d", "write_sur", "write_sdf",
           "surfalize_available", "SURFALIZE_PIP", "SDF_ZSCALE_M"]

#: Most points (pixels) a scan may have: a height map larger than this is
#: refused from its header, before anything is allocated; a point file is
#: refused as soon as it passes it.
MAX_SCAN_POINTS = 100_000_000

#: Largest scan file read (bytes).
MAX_SCAN_BYTES = 16 << 30

#: Height-map formats read by tipgeo itself.
OWN_FORMATS: tuple[str, ...] = (".x3p", ".al3d", ".sur", ".sdf")

#: Height-map formats read through surfalize (optional).
SURFALIZE_FORMATS: tuple[str, ...] = (".plu", ".plux", ".vk3", ".vk4", ".vk6", ".vk7", ".zon",
                                      ".dat", ".opd", ".os3d", ".lext", ".oir", ".poir", ".nms",
                                      ".zmg", ".hdat", ".gwy", ".tmd", ".sflz")

#: Every height-map format.
HEIGHT_MAP_FORMATS: tuple[str, ...] = OWN_FORMATS + SURFALIZE_FORMATS

#: The command that installs surfalize.
SURFALIZE_PIP = 'pip install "tipgeo[instruments]"  (or: pip install surfalize)'

#: Length units: canonical name -> size in mm as an exact fraction.
LENGTH_UNITS: dict[str, Fraction] = {
    "m": Fraction(1000), "dm": Fraction(100), "cm": Fraction(10), "mm": Fraction(1),
    "um": Fraction(1, 1000), "nm": Fraction(1, 10**6), "pm": Fraction(1, 10**9),
    "in": Fraction(254, 10), "mil": Fraction(254, 10000),
}
_UNIT_ALIASES = {
    "µm": "um", "μm": "um", "µ": "um", "micron": "um", "microns": "um", "micrometer": "um",
    "micrometre": "um", "micrometers": "um", "micrometres": "um", "㎛": "um", "âµm": "um",
    "Âµm": "um", "mkm": "um",
    "millimeter": "mm", "millimetre": "mm", "millimeters": "mm", "millimetres": "mm",
    "nanometer": "nm", "nanometre": "nm", "nanometers": "nm", "nanometres": "nm",
    "meter": "m", "metre": "m", "meters": "m", "metres": "m",
    "centimeter": "cm", "centimetre": "cm", "inch": "in", "inches": "in", '"': "in",
    "picometer": "pm", "picometre": "pm", "å": "angstrom",
}
#: What an error message lists as allowed.
ALLOWED_UNITS_TEXT = "m, cm, mm, µm (um, micron), nm, pm, in, mil"


def parse_unit(text: str) -> str | None:
    """Canonical name (a key of :data:`LENGTH_UNITS`) of a length-unit
    string (``'µm'``, ``'um'``, ``'micron'``, ``'MM'``, ``'[mm]'``...), or None."""
    t = text.strip().strip("[]()").strip()
    if not t:
        return None
    low = t.lower()
    if low in LENGTH_UNITS:
        return low
    for cand in (t, low):
        if cand in _UNIT_ALIASES:
            u = _UNIT_ALIASES[cand]
            return u if u in LENGTH_UNITS else None
    if len(low) == 2 and low[1] == "m" and low[0] in "µμu\u00b5":
        return "um"
    return None


def _unit_or_error(text: str, where: str, part: str) -> str:
    u = parse_unit(text)
    if u is None:
        raise ScanError(f"{where}: {part}: unit '{text.strip()}' is not a length unit; allowed: "
                        f"{ALLOWED_UNITS_TEXT}")
    return u


@overload
def to_mm(values: float, unit: str) -> float: ...


@overload
def to_mm(values: AnyArray, unit: str) -> FloatArray: ...


@overload
def to_mm(values: ArrayLike, unit: str) -> float | FloatArray: ...


def to_mm(values: ArrayLike, unit: str) -> float | FloatArray:
    """``values`` (a float, or an array as float64) in ``unit`` converted to
    mm: divided by an exact integer below the mm (correctly rounded), times an
    exact integer above it."""
    f = LENGTH_UNITS[unit]
    a = np.asarray(values, np.float64)
    if f == 1:
        out = a
    elif f.numerator == 1:
        out = a / float(f.denominator)
    elif f.denominator == 1:
        out = a * float(f.numerator)
    else:
        out = a * float(f.numerator) / float(f.denominator)
    return float(out) if np.ndim(out) == 0 else out


def _decimal_to_mm(text: str, unit: str, where: str, part: str) -> float:
    """A decimal number given as text in ``unit``, in mm, rounded once."""
    try:
        d = Decimal(text.strip())
    except (InvalidOperation, ValueError):
        raise ScanError(f"{where}: {part} = '{text.strip()[:40]}' is not a number") from None
    if not d.is_finite():
        raise ScanError(f"{where}: {part} = '{text.strip()[:40]}'; expected a finite number")
    f = LENGTH_UNITS[unit]
    return float(d * f.numerator / f.denominator)


# -----------------------------------------------------------------------------
@dataclass
class HeightMap:
    """A regular grid of heights.

    Attributes
    ----------
    z : (ny, nx) float64 — heights (mm); NaN where the pixel is invalid
    dx, dy : float — lateral spacing (mm) along a row (x) and between rows (y)
    x0, y0 : float — position of pixel (0, 0) (mm)
    source : str — file name
    format : str — extension without the dot (``'x3p'``)
    meta : dict — what the file said (units, data type, instrument...)
    """

    z: FloatArray
    dx: float
    dy: float
    x0: float = 0.0
    y0: float = 0.0
    source: str = ""
    format: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        ny, nx = self.z.shape
        return ny, nx

    @property
    def pixels(self) -> int:
        return int(self.z.size)

    @property
    def invalid(self) -> int:
        """Number of invalid (non-finite) pixels."""
        return int(self.z.size - np.count_nonzero(np.isfinite(self.z)))

    def iter_points(self, rows: int = 1024) -> Iterator[FloatArray]:
        """Valid pixels as (m, 3) float64 points (mm), ``rows`` rows at a time."""
        ny, nx = self.z.shape
        x = self.x0 + np.arange(nx, dtype=np.float64) * self.dx
        for i0 in range(0, ny, rows):
            blk = self.z[i0:i0 + rows]
            ok = np.isfinite(blk)
            ii, jj = np.nonzero(ok)
            if not len(ii):
                continue
            y = self.y0 + (ii + i0).astype(np.float64) * self.dy
            yield np.column_stack([x[jj], y, blk[ok]])

    def points(self) -> FloatArray:
        """Every valid pixel as an (n, 3) float64 point (mm)."""
        parts = list(self.iter_points(rows=max(1, self.z.shape[0])))
        return parts[0] if len(parts) == 1 else (
            np.concatenate(parts) if parts else np.zeros((0, 3)))


def _checked_map(z: ArrayLike, dx: float, dy: float, x0: float, y0: float, where: str,
                 fmt: str, meta: dict[str, Any], source: str) -> HeightMap:
    """A :class:`HeightMap` of ``z`` (mm) once the spacing, offsets (mm) and
    shape are checked."""
    for name, v in (("dx", dx), ("dy", dy)):
        if not (np.isfinite(v) and v > 0):
            raise ScanError(f"{where}: lateral spacing {name} = {v!r} mm; expected a finite "
                            "number > 0")
    for name, v in (("x0", x0), ("y0", y0)):
        if not np.isfinite(v):
            raise ScanError(f"{where}: offset {name} = {v!r}; expected a finite number")
    z = np.asarray(z, np.float64)
    if z.ndim != 2 or z.size == 0:
        raise ScanError(f"{where}: height map of shape {z.shape}; expected rows × columns ≥ 1")
    return HeightMap(z, float(dx), float(dy), float(x0), float(y0), source=source, format=fmt,
                     meta=dict(meta))


def _check_pixels(nx: int, ny: int, where: str, what: str, max_pixels: int) -> None:
    if nx <= 0 or ny <= 0:
        raise ScanError(f"{where}: {what} gives {nx} × {ny} pixels; expected at least 1 × 1")
    if nx * ny > max_pixels:
        raise ScanError(f"{where}: {what} gives {nx} × {ny} = {nx * ny:,} pixels; allowed at "
                        f"most {max_pixels:,}")


# -----------------------------------------------------------------------------
def read_height_map(path: str | os.PathLike[str], *, max_pixels: int = MAX_SCAN_POINTS
                    ) -> HeightMap:
    """Read a height-map file (any of :data:`HEIGHT_MAP_FORMATS`, by its
    extension).

    Raises
    ------
    ScanError
        Unknown extension; missing, empty, malformed or oversized file.
    MissingToolError
        A format of :data:`SURFALIZE_FORMATS` while surfalize is not installed.
    """
    p = Path(path)
    ext = p.suffix.lower()
    where = f"scan '{p}'"
    if ext not in HEIGHT_MAP_FORMATS:
        raise ScanError(f"{where}: extension '{p.suffix}' is not a height-map format; allowed: "
                        + ", ".join(HEIGHT_MAP_FORMATS))
    if not p.is_file():
        raise ScanError(f"{where} does not exist or is not a regular file")
    size = p.stat().st_size
    if size == 0:
        raise ScanError(f"{where} is empty (0 bytes)")
    if size > MAX_SCAN_BYTES:
        raise ScanError(f"{where} has {size:,} bytes; allowed at most {MAX_SCAN_BYTES:,}")
    reader = {".x3p": _read_x3p, ".al3d": _read_al3d, ".sur": _read_sur,
              ".sdf": _read_sdf}.get(ext, _read_surfalize)
    try:
        with np.errstate(invalid="ignore", over="ignore"):   # a NaN payload, a huge scale
            hm = reader(p, where, max_pixels)
    except (ScanError, MissingToolError):
        raise
    except MemoryError:
        raise ScanError(f"{where}: too large to read into memory") from None
    except Exception as e:  # a reader's own failure is a malformed file
        msg = " ".join(str(e).split())[:200]
        raise ScanError(f"{where} could not be read as {ext}: {type(e).__name__}: {msg}") \
            from None
    hm.meta.setdefault("pixels", hm.pixels)
    hm.meta["invalid_pixels"] = hm.invalid
    return hm


# -----------------------------------------------------------------------------
# X3P (ISO 25178-72)
_X3P_TYPES = {"I": "<i2", "L": "<i4", "F": "<f4", "D": "<f8"}
_MAX_XML_BYTES = 256 << 20


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _child(el: ET.Element | None, name: str) -> ET.Element | None:
    if el is None:
        return None
    for c in el:
        if _local(c.tag) == name:
            return c
    return None


def _path(el: ET.Element | None, path: str) -> ET.Element | None:
    for part in path.split("/"):
        el = _child(el, part)
    return el


def _text(el: ET.Element | None, path: str) -> str | None:
    e = _path(el, path)
    if e is None or e.text is None or not e.text.strip():
        return None
    return e.text.strip()


def _member(zf: zipfile.ZipFile, name: str, where: str, expected: int | None = None,
            limit: int = _MAX_XML_BYTES) -> bytes:
    try:
        info = zf.getinfo(name)
    except KeyError:
        raise ScanError(f"{where}: the archive has no member '{name}'") from None
    want = limit if expected is None else expected
    if expected is not None and info.file_size != expected:
        raise ScanError(f"{where}: member '{name}' holds {info.file_size:,} bytes; expected "
                        f"{expected:,}")
    if info.file_size > want:
        raise ScanError(f"{where}: member '{name}' holds {info.file_size:,} bytes; allowed at "
                        f"most {want:,}")
    try:
        with zf.open(info) as fh:
            data = fh.read(want + 1)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError,
            RuntimeError) as e:
        raise ScanError(f"{where}: member '{name}' cannot be read ({type(e).__name__}: "
                        f"{' '.join(str(e).split())[:120]})") from None
    if len(data) > want or (expected is not None and len(data) != expected):
        raise ScanError(f"{where}: member '{name}' inflates to {len(data):,}+ bytes; expected "
                        f"{want:,}")
    return data


def _x3p_number(root: ET.Element, path: str, where: str, default: str | None = None) -> Decimal:
    t = _text(root, path)
    if t is None:
        if default is None:
            raise ScanError(f"{where}: main.xml has no {path}")
        t = default
    try:
        d = Decimal(t)
    except (InvalidOperation, ValueError):
        raise ScanError(f"{where}: main.xml {path} = '{t[:40]}' is not a number") from None
    if not d.is_finite():
        raise ScanError(f"{where}: main.xml {path} = '{t[:40]}'; expected a finite number")
    return d


def _x3p_int(root: ET.Element, path: str, where: str) -> int:
    t = _text(root, path)
    if t is None or not re.fullmatch(r"\+?\d{1,12}", t):
        raise ScanError(f"{where}: main.xml {path} = {t!r}; expected a whole number ≥ 1")
    return int(t)


def _x3p_root(xml: bytes, where: str) -> ET.Element:
    """The parsed main.xml of a surface (no DTD, no entities)."""
    head = xml[:4096].upper()
    if b"<!DOCTYPE" in head or b"<!ENTITY" in xml.upper():
        raise ScanError(f"{where}: main.xml declares a DTD or entities; an ISO 25178-72 "
                        "main.xml has none")
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as e:
        line, col = getattr(e, "position", (0, 0))
        raise ScanError(f"{where}: main.xml is not well-formed XML (line {line}, column "
                        f"{col})") from None
    if _local(root.tag) != "ISO5436_2":
        raise ScanError(f"{where}: main.xml root element is <{_local(root.tag)}>; expected "
                        "<ISO5436_2>")
    ftype = _text(root, "Record1/FeatureType")
    if ftype != "SUR":
        what = {"PRF": "a profile", "PCL": "a point cloud"}.get(ftype or "", repr(ftype))
        raise ScanError(f"{where}: Record1/FeatureType is {what}; only surfaces (SUR) are "
                        "read")
    return root


def _x3p_lateral(root: ET.Element, where: str, a: str) -> tuple[float, float]:
    """(increment, offset) of incremental axis ``a`` (CX or CY), in mm."""
    t = _text(root, f"Record1/Axes/{a}/AxisType")
    if t != "I":
        raise ScanError(f"{where}: Record1/Axes/{a}/AxisType = {t!r}; only incremental "
                        "('I') x and y axes (a regular grid) are read")
    inc = _x3p_number(root, f"Record1/Axes/{a}/Increment", where)
    if inc <= 0:
        raise ScanError(f"{where}: Record1/Axes/{a}/Increment = {inc}; expected > 0 (m)")
    off = _x3p_number(root, f"Record1/Axes/{a}/Offset", where, "0")
    return float(inc * 1000), float(off * 1000)


def _x3p_z_axis(root: ET.Element, where: str) -> tuple[str, Decimal, Decimal]:
    """(data type, increment in m, offset in m) of the z axis."""
    zt = _text(root, "Record1/Axes/CZ/AxisType")
    if zt != "A":
        raise ScanError(f"{where}: Record1/Axes/CZ/AxisType = {zt!r}; expected 'A' "
                        "(absolute heights)")
    dt = _text(root, "Record1/Axes/CZ/DataType")
    if dt is None or dt not in _X3P_TYPES:
        raise ScanError(f"{where}: Record1/Axes/CZ/DataType = {dt!r}; allowed: I, L, F, D")
    zinc = _x3p_number(root, "Record1/Axes/CZ/Increment", where, "1")
    zoff = _x3p_number(root, "Record1/Axes/CZ/Offset", where, "0")
    return dt, zinc, zoff


def _x3p_size(root: ET.Element, where: str, max_pixels: int) -> tuple[int, int]:
    """(SizeX, SizeY) of a single-layer matrix within ``max_pixels``."""
    nx = _x3p_int(root, "Record3/MatrixDimension/SizeX", where)
    ny = _x3p_int(root, "Record3/MatrixDimension/SizeY", where)
    nz = _x3p_int(root, "Record3/MatrixDimension/SizeZ", where)
    if nz != 1:
        raise ScanError(f"{where}: Record3/MatrixDimension/SizeZ = {nz}; only single-layer "
                        "surfaces (1) are read")
    _check_pixels(nx, ny, where, "Record3/MatrixDimension", max_pixels)
    return nx, ny


def _x3p_linked(zf: zipfile.ZipFile, link: ET.Element, dt: str, n: int,
                where: str) -> tuple[FloatArray, BoolArray | None]:
    """The raw values of a binary point-data member (MD5 checked when given)
    and the validity mask of its valid-points member, if any."""
    name = _text(link, "PointDataLink")
    if name is None:
        raise ScanError(f"{where}: Record3/DataLink has no PointDataLink")
    dtype = np.dtype(_X3P_TYPES[dt])
    data = _member(zf, name, where, expected=n * dtype.itemsize)
    md5 = _text(link, "MD5ChecksumPointData")
    if md5 is not None and hashlib.md5(data).hexdigest() != md5.lower():
        raise ScanError(f"{where}: the MD5 of '{name}' is {hashlib.md5(data).hexdigest()}"
                        f"; Record3/DataLink/MD5ChecksumPointData says {md5.lower()} "
                        "(corrupt point data)")
    raw = np.frombuffer(data, dtype).astype(np.float64)
    vname = _text(link, "ValidPointsLink")
    if vname is None:
        return raw, None
    bits = _member(zf, vname, where, expected=(n + 7) // 8)
    valid = np.unpackbits(np.frombuffer(bits, np.uint8), count=n,
                          bitorder="little").astype(bool)
    return raw, valid


def _x3p_listed(root: ET.Element, n: int, where: str) -> FloatArray:
    """The raw values of a text ``DataList`` (an empty Datum: NaN)."""
    lst = _path(root, "Record3/DataList")
    if lst is None:
        raise ScanError(f"{where}: Record3 has neither DataLink nor DataList")
    vals: list[float] = []
    for d in lst:
        if _local(d.tag) != "Datum":
            continue
        t = (d.text or "").strip()
        try:
            vals.append(float(t) if t else np.nan)
        except ValueError:
            raise ScanError(f"{where}: Record3/DataList Datum {len(vals) + 1} = "
                            f"'{t[:40]}' is not a number") from None
        if len(vals) > n:
            break
    if len(vals) != n:
        raise ScanError(f"{where}: Record3/DataList holds {len(vals):,}"
                        f"{'+' if len(vals) > n else ''} Datum values; expected "
                        f"SizeX × SizeY = {n:,}")
    return np.asarray(vals, np.float64)


def _x3p_extra_meta(zf: zipfile.ZipFile, root: ET.Element, xml: bytes, where: str,
                    meta: dict[str, Any]) -> None:
    """The main.xml checksum's verdict and the instrument, into ``meta``."""
    ck = _text(root, "Record4/ChecksumFile")
    if ck is not None and ck in zf.namelist():
        got = _member(zf, ck, where, limit=4096).decode("latin-1").split()
        meta["main_xml_md5"] = ("ok" if got and got[0].lower()
                                == hashlib.md5(xml).hexdigest() else "mismatch")
    inst = _path(root, "Record2/Instrument")
    if inst is not None:
        meta["instrument"] = " ".join(filter(None, (_text(inst, k) for k in
                                                   ("Manufacturer", "Model", "Serial"))))


def _read_x3p(p: Path, where: str, max_pixels: int) -> HeightMap:
    try:
        zf = zipfile.ZipFile(p)
    except (zipfile.BadZipFile, OSError) as e:
        raise ScanError(f"{where} is not an X3P file: not a zip archive ({e}); an X3P is a zip "
                        "holding main.xml") from None
    with zf:
        xml = _member(zf, "main.xml", where)
        root = _x3p_root(xml, where)
        meta: dict[str, Any] = {"file_units": "m", "revision": _text(root, "Record1/Revision")}
        (dx, x0), (dy, y0) = _x3p_lateral(root, where, "CX"), _x3p_lateral(root, where, "CY")
        dt, zinc, zoff = _x3p_z_axis(root, where)
        nx, ny = _x3p_size(root, where, max_pixels)
        link = _path(root, "Record3/DataLink")
        if link is not None:
            raw, valid = _x3p_linked(zf, link, dt, nx * ny, where)
        else:
            raw, valid = _x3p_listed(root, nx * ny, where), None
        # heights in m = offset + increment × raw; in mm: the increment and the
        # offset scaled in decimal (one rounding each), × raw, + offset
        if zinc == 1 and zoff == 0:
            z = raw * 1000.0              # an exact integer factor: correctly rounded
        else:
            z = float(zoff * 1000) + float(zinc * 1000) * raw
        if valid is not None:
            z[~valid] = np.nan
        z[~np.isfinite(z)] = np.nan
        meta.update(data_type=dt, z_increment_m=str(zinc), z_offset_m=str(zoff))
        _x3p_extra_meta(zf, root, xml, where, meta)
    return _checked_map(z.reshape(ny, nx), dx, dy, x0, y0, where, "x3p", meta, p.name)


def write_x3p(path: str | os.PathLike[str], z_mm: ArrayLike, dx_mm: float, dy_mm: float, *,
              x0_mm: float = 0.0, y0_mm: float = 0.0, dtype: str = "D",
              z_increment_m: float | None = None, z_offset_m: float | None = None,
              valid_mask: bool | None = None, data_list: bool = False,
              comment: str = "written by tipgeo") -> Path:
    """Write an ISO 25178-72 X3P surface (atomically).

    ``z_mm`` (ny, nx) heights in mm (NaN: invalid); lateral spacing and
    offsets in mm, written in m as decimal text (exact). ``dtype`` 'D'
    (float64, default), 'F' (float32), 'I' (int16) or 'L' (int32): the
    integer types store round((z − offset)/increment) with ``z_increment_m``
    and ``z_offset_m`` (default: the range over the type's span about its
    middle) and a validity bit mask;
    ``valid_mask`` forces that mask for float types too. ``data_list``: the
    heights as text ``Datum`` elements (repr, exact) instead of a binary
    member.
    """
    z = np.asarray(z_mm, np.float64)
    ny, nx = z.shape
    dt = dtype.upper()
    if dt not in _X3P_TYPES:
        raise ValueError(f"dtype {dtype!r}; allowed D, F, I, L")
    zm = z / 1000.0
    ok = np.isfinite(zm)
    zinc, zoff = Decimal(1), Decimal(0)
    if dt in "IL":
        imax = 32767 if dt == "I" else 2**31 - 1
        lo, hi = (float(zm[ok].min()), float(zm[ok].max())) if ok.any() else (0.0, 0.0)
        if z_offset_m is None:
            z_offset_m = 0.5 * (lo + hi)
        if z_increment_m is None:
            z_increment_m = max(hi - lo, tol.inspect.x3p_min_span_m) / (2 * (imax - 1))
        zoff, zinc = Decimal(repr(float(z_offset_m))), Decimal(repr(float(z_increment_m)))
        raw = np.where(ok, np.round((zm - float(zoff)) / float(zinc)), 0)
        info = np.iinfo(np.dtype(_X3P_TYPES[dt]))
        if ok.any() and (raw.min() < info.min or raw.max() > info.max):
            raise ValueError("heights out of the integer type's range for this increment")
        vals = raw.astype(_X3P_TYPES[dt])
        valid_mask = True
    else:
        vals = zm.astype(_X3P_TYPES[dt])
    xml = ['<?xml version="1.0" encoding="UTF-8" standalone="no"?>',
           '<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" '
           'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">',
           "<Record1><Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType><Axes>"]
    for a, step, off in (("CX", dx_mm, x0_mm), ("CY", dy_mm, y0_mm)):
        inc = Decimal(repr(float(step))) / 1000
        o = Decimal(repr(float(off))) / 1000
        xml.append(f"<{a}><AxisType>I</AxisType><DataType>D</DataType><Increment>{inc}"
                   f"</Increment><Offset>{o}</Offset></{a}>")
    xml.append(f"<CZ><AxisType>A</AxisType><DataType>{dt}</DataType><Increment>{zinc}"
               f"</Increment><Offset>{zoff}</Offset></CZ></Axes></Record1>")
    xml.append("<Record2><Date>2000-01-01T00:00:00+00:00</Date><Instrument><Manufacturer>"
               "tipgeo</Manufacturer><Model>synthetic</Model><Serial>0</Serial><Version>1"
               "</Version></Instrument><CalibrationDate>2000-01-01T00:00:00+00:00"
               "</CalibrationDate><ProbingSystem><Type>Software</Type><Identification>"
               f"tipgeo</Identification></ProbingSystem><Comment>{comment}</Comment></Record2>")
    xml.append(f"<Record3><MatrixDimension><SizeX>{nx}</SizeX><SizeY>{ny}</SizeY>"
               "<SizeZ>1</SizeZ></MatrixDimension>")
    members: dict[str, bytes] = {}
    if data_list:
        xml.append("<DataList>" + "".join(
            f"<Datum>{repr(float(v)) if np.isfinite(v) else ''}</Datum>"  # shortest exact
            for v in vals.ravel())
            + "</DataList>")
    else:
        data = vals.tobytes()
        members["bindata/data.bin"] = data
        link = ("<DataLink><PointDataLink>bindata/data.bin</PointDataLink>"
                f"<MD5ChecksumPointData>{hashlib.md5(data).hexdigest().upper()}"
                "</MD5ChecksumPointData>")
        if valid_mask:
            bits = np.packbits(ok.ravel(), bitorder="little").tobytes()
            members["bindata/valid.bin"] = bits
            link += ("<ValidPointsLink>bindata/valid.bin</ValidPointsLink>"
                     f"<MD5ChecksumValidPoints>{hashlib.md5(bits).hexdigest().upper()}"
                     "</MD5ChecksumValidPoints>")
        xml.append(link + "</DataLink>")
    xml.append("</Record3><Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>"
               "</p:ISO5436_2>")
    main = ("\n".join(xml) + "\n").encode("utf-8")

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("main.xml", main)
            for k, v in members.items():
                zf.writestr(k, v)
            zf.writestr("md5checksum.hex", f"{hashlib.md5(main).hexdigest()} *main.xml\n")

    write_atomic(Path(path), write)
    return Path(path)


# -----------------------------------------------------------------------------
# AL3D (Alicona)
_AL3D_MAGIC = b"AliconaImaging\x00\r\n"
_AL3D_INVALID = float(np.float32(3.0e15))
_MAX_TAGS = 4096


def _al3d_stride(nx: int, itemsize: int) -> int:
    return -(-nx * itemsize // 8) * 8


def _read_al3d(p: Path, where: str, max_pixels: int) -> HeightMap:
    size = p.stat().st_size
    with open(p, "rb") as fh:
        if fh.read(17) != _AL3D_MAGIC:
            raise ScanError(f"{where} is not an AL3D file (no 'AliconaImaging' magic)")
        tags: dict[str, str] = {}

        def tag(i: int) -> tuple[str, str]:
            b = fh.read(52)
            if len(b) < 52:
                raise ScanError(f"{where}: header tag {i + 1} is truncated")
            if b[50:52] != b"\r\n":
                raise ScanError(f"{where}: header tag {i + 1} does not end in CR LF")
            k = b[:20].split(b"\0", 1)[0].decode("latin-1").strip()
            v = b[20:50].split(b"\0", 1)[0].decode("latin-1").strip()
            return k, v

        k, v = tag(0)
        if k != "Version":
            raise ScanError(f"{where}: first header tag is '{k}'; expected 'Version'")
        tags[k] = v
        k, v = tag(1)
        if k != "TagCount" or not v.isdigit() or int(v) > _MAX_TAGS:
            raise ScanError(f"{where}: second header tag is {k} = '{v}'; expected TagCount = a "
                            f"number ≤ {_MAX_TAGS}")
        for i in range(int(v)):
            k, val = tag(i + 2)
            tags[k] = val

        def num(key: str) -> int:
            if key not in tags:
                raise ScanError(f"{where}: header tag {key} is missing")
            try:
                return int(tags[key])
            except ValueError:
                raise ScanError(f"{where}: header tag {key} = '{tags[key]}' is not a "
                                "whole number") from None

        nx, ny = num("Cols"), num("Rows")
        _check_pixels(nx, ny, where, "header tags Cols × Rows", max_pixels)
        dx = _decimal_to_mm(tags.get("PixelSizeXMeter", ""), "m", where, "PixelSizeXMeter")
        dy = _decimal_to_mm(tags.get("PixelSizeYMeter", ""), "m", where, "PixelSizeYMeter")
        off = num("DepthImageOffset")
        stride = _al3d_stride(nx, 4)
        need = off + stride * (ny - 1) + nx * 4
        if off < 17 or need > size:
            raise ScanError(f"{where}: depth image at DepthImageOffset = {off} needs {need:,} "
                            f"bytes (Rows × padded row of {stride} bytes); the file has {size:,}")
        fh.seek(off)
        buf = fh.read(stride * ny)
    if len(buf) < stride * ny:
        buf = buf + b"\0" * (stride * ny - len(buf))   # the last row's padding may be absent
    raw = np.ndarray((ny, nx), "<f4", buffer=buf, strides=(stride, 4)).astype(np.float64)
    inv = _AL3D_INVALID
    if "InvalidPixelValue" in tags:
        try:
            inv = float(tags["InvalidPixelValue"])
        except ValueError:
            raise ScanError(f"{where}: header tag InvalidPixelValue = "
                            f"'{tags['InvalidPixelValue']}' is not a number") from None
        if not np.isfinite(inv):
            inv = _AL3D_INVALID
    bad = ~(raw < inv) | ~np.isfinite(raw)
    z = raw * 1000.0
    z[bad] = np.nan
    meta = {"file_units": "m", "data_type": "float32", "invalid_value": inv,
            "version": tags.get("Version")}
    rep = _al3d_unrepeatable(p, tags, nx, ny, size, where)
    if rep is not None:
        meta["unrepeatable_pixels"] = int(np.count_nonzero(rep & ~bad))
        z[rep] = np.nan
    return _checked_map(z, dx, dy, 0.0, 0.0, where, "al3d", meta, p.name)


def _al3d_unrepeatable(p: Path, tags: dict[str, str], nx: int, ny: int, size: int,
                       where: str) -> BoolArray | None:
    """Pixels whose depth repeatability exceeds the file's filter value, or
    None when the file has no repeatability plane. The repeatability is
    ``code · DepthResShiftVal + DepthResMinVal`` (÷√8 on both sides of the
    test) from uint8 texture plane ``DepthImageResPtr``; the Alicona software
    hides these pixels by default (``DepthResFilterVal``)."""
    keys = ("DepthImageResPtr", "DepthResFilterVal", "TextureImageOffset")
    if not all(tags.get(k, "").strip() for k in keys):
        return None
    try:
        plane, off = int(tags["DepthImageResPtr"]), int(tags["TextureImageOffset"])
        limit = float(tags["DepthResFilterVal"])
        shift = float(tags.get("DepthResShiftVal", "0") or 0)
        lo = float(tags.get("DepthResMinVal", "0") or 0)
    except ValueError:
        raise ScanError(f"{where}: header tags {', '.join(keys)}, DepthResShiftVal, "
                        "DepthResMinVal must be numbers") from None
    if off == 0:
        return None
    stride = _al3d_stride(nx, 1)
    start = off + plane * stride * ny
    if plane < 0 or start + stride * (ny - 1) + nx > size:
        raise ScanError(f"{where}: repeatability plane DepthImageResPtr = {plane} at "
                        f"TextureImageOffset = {off} lies past the end of the file ({size:,} "
                        "bytes)")
    with open(p, "rb") as fh:
        fh.seek(start)
        buf = fh.read(stride * ny)
    buf = buf + b"\0" * (stride * ny - len(buf))
    codes = np.ndarray((ny, nx), np.uint8, buffer=buf, strides=(stride, 1))
    return codes * shift + lo > limit


def write_al3d(path: str | os.PathLike[str], z_mm: ArrayLike, dx_mm: float, dy_mm: float, *,
               repeatability_codes: ArrayLike | None = None, filter_value: float = 0.0,
               shift: float = 1.0, minimum: float = 0.0) -> Path:
    """Write an Alicona AL3D depth image (float32 metres; NaN → the invalid
    value 3e15), pixel sizes as decimal text in m (exact), scanlines padded
    to 8 bytes; with ``repeatability_codes`` ((ny, nx) uint8), a texture
    plane of them and the tags that make the reader hide the pixels whose
    ``code·shift + minimum > filter_value``."""
    z = np.asarray(z_mm, np.float64)
    ny, nx = z.shape
    tags = [("Version", "1"), ("TagCount", "0"), ("Cols", str(nx)), ("Rows", str(ny)),
            ("PixelSizeXMeter", str(Decimal(repr(float(dx_mm))) / 1000)),
            ("PixelSizeYMeter", str(Decimal(repr(float(dy_mm))) / 1000)),
            ("InvalidPixelValue", repr(_AL3D_INVALID)), ("IconOffset", "0"),
            ("NumberOfPlanes", "0" if repeatability_codes is None else "1"),
            ("TextureImageOffset", "0"), ("DepthImageOffset", "0")]
    if repeatability_codes is not None:
        tags += [("DepthImageResPtr", "0"), ("DepthResFilterVal", repr(float(filter_value))),
                 ("DepthResShiftVal", repr(float(shift))), ("DepthResMinVal",
                                                             repr(float(minimum)))]
    tags[1] = ("TagCount", str(len(tags) - 2))
    hdr_len = 17 + 52 * len(tags)
    off = -(-hdr_len // 8) * 8 + 8
    tags[tags.index(("DepthImageOffset", "0"))] = ("DepthImageOffset", str(off))
    tex_off = off + _al3d_stride(nx, 4) * ny
    if repeatability_codes is not None:
        tags[tags.index(("TextureImageOffset", "0"))] = ("TextureImageOffset", str(tex_off))
    head = bytearray(_AL3D_MAGIC)
    for k, v in tags:
        kb, vb = k.encode("latin-1"), v.encode("latin-1")
        if len(kb) > 20 or len(vb) > 30:
            raise ValueError(f"AL3D tag {k} = {v} does not fit")
        head += kb.ljust(20, b"\0") + vb.ljust(30, b"\0") + b"\r\n"
    head += b"\0" * (off - len(head))
    stride = _al3d_stride(nx, 4) // 4
    img = np.zeros((ny, stride), "<f4")
    d = np.where(np.isfinite(z), z / 1000.0, _AL3D_INVALID)
    img[:, :nx] = d

    tex = b""
    if repeatability_codes is not None:
        codes = np.zeros((ny, _al3d_stride(nx, 1)), np.uint8)
        codes[:, :nx] = np.asarray(repeatability_codes, np.uint8)
        tex = codes.tobytes()

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(bytes(head))
            fh.write(img.tobytes())
            fh.write(tex)

    write_atomic(Path(path), write)
    return Path(path)


# -----------------------------------------------------------------------------
# SUR (Digital Surf)
_SUR_HEADER = struct.Struct(
    "<12s h h h h 30s 30s h h h h h f 4x h i i i i i f f f 16s 16s 16s 16s 16s 16s 16s 16s 16s"
    " f f f h h h 12x h h h h h h h f I 6x h h 128s f f f f f 13s 13s")
_SUR_FIELDS = ("code format n_objects version studiable name_object name_operator p_size "
               "acquisition range non_measured absolute gauge bits min_point max_point nx ny "
               "n_total spacing_x spacing_y spacing_z name_x name_y name_z unit_step_x "
               "unit_step_y unit_step_z unit_x unit_y unit_z ratio_x ratio_y ratio_z replica "
               "inverted leveled sec min hour day month year wday duration compressed_size "
               "len_comment len_private client offset_x offset_y offset_z spacing_t offset_t "
               "name_t unit_t").split()
assert _SUR_HEADER.size == 512


def _sur_str(b: bytes) -> str:
    return b.split(b"\0", 1)[0].decode("latin-1").strip()


def _sur_header(hb: bytes, where: str) -> tuple[str, dict[str, Any]]:
    """(numpy byte order, header fields) of a SUR file's 512-byte header,
    checked: a surface, 16 or 32 bits, not inverted."""
    if len(hb) < 512 or hb[:12] not in (b"DIGITAL SURF", b"DSCOMPRESSED"):
        raise ScanError(f"{where} is not a Digital Surf SUR file (no 'DIGITAL SURF' or "
                        "'DSCOMPRESSED' code, or under 512 bytes)")
    bo = ">" if struct.unpack("<h", hb[12:14])[0] == 257 else "<"   # 257: Macintosh
    s = struct.Struct(bo + _SUR_HEADER.format[1:])
    h = dict(zip(_SUR_FIELDS, s.unpack(hb)))
    if h["version"] != 1:
        raise ScanError(f"{where}: header version_number = {h['version']}; expected 1")
    if h["studiable"] not in (2, 16):
        raise ScanError(f"{where}: header studiable type = {h['studiable']}; only surfaces "
                        "(2, and 16: a surface with its RGB/intensity layers) are read")
    if h["bits"] not in (16, 32):
        raise ScanError(f"{where}: header bits per point = {h['bits']}; expected 16 or 32")
    if h["inverted"] not in (0,):
        raise ScanError(f"{where}: header 'inverted' = {h['inverted']}; only surfaces that "
                        "are not inverted (0) are read")
    return bo, h


def _sur_inflate(fh: IO[bytes], bo: str, nbytes: int, itemsize: int, size: int,
                 where: str) -> bytes:
    """The point data of a DSCOMPRESSED file: its directory of zlib streams,
    each inflated to no more than the size the directory gives."""
    cnt_b = fh.read(4)
    if len(cnt_b) < 4:
        raise ScanError(f"{where} is truncated: no compressed-data directory")
    cnt = struct.unpack(bo + "I", cnt_b)[0]
    if not 1 <= cnt <= 4096:
        raise ScanError(f"{where}: compressed-data directory count = {cnt}; expected "
                        "1 to 4096")
    dirs = [struct.unpack(bo + "2I", fh.read(8)) for _ in range(cnt)]
    if sum(r for r, _ in dirs) != nbytes:
        raise ScanError(f"{where}: compressed streams hold {sum(r for r, _ in dirs):,} "
                        f"bytes once inflated; expected {nbytes:,} (points × "
                        f"{itemsize})")
    if sum(c for _, c in dirs) > size:
        raise ScanError(f"{where}: compressed streams of {sum(c for _, c in dirs):,} "
                        f"bytes in a file of {size:,}")
    parts = []
    for i, (rawlen, ziplen) in enumerate(dirs):
        if rawlen == 0:        # max_length 0 would mean 'unbounded'
            fh.seek(ziplen, 1)
            continue
        d = zlib.decompressobj()
        try:
            out = d.decompress(fh.read(ziplen), rawlen)
        except zlib.error as e:
            raise ScanError(f"{where}: compressed stream {i + 1} is corrupt ({e})") \
                from None
        if len(out) != rawlen or d.unconsumed_tail:
            raise ScanError(f"{where}: compressed stream {i + 1} inflates to "
                            f"{len(out):,}{'+' if d.unconsumed_tail else ''} bytes; "
                            f"expected {rawlen:,}")
        parts.append(out)
    return b"".join(parts)


def _read_sur(p: Path, where: str, max_pixels: int) -> HeightMap:
    size = p.stat().st_size
    with open(p, "rb") as fh:
        bo, h = _sur_header(fh.read(512), where)
        code = h["code"]
        nx, ny = h["nx"], h["ny"]
        _check_pixels(nx, ny, where, "header points per line × lines", max_pixels)
        n = nx * ny
        if h["n_total"] != n:
            raise ScanError(f"{where}: header total points = {h['n_total']}; expected points per "
                            f"line × lines = {n}")
        units = {k: _unit_or_error(_sur_str(h[f"unit_step_{k}"]) or "um", where,
                                   f"header unit of the {k} step")
                 for k in ("x", "y", "z")}
        fh.seek(512 + max(h["len_comment"], 0) + max(h["len_private"], 0))
        dtype = np.dtype(bo + ("i2" if h["bits"] == 16 else "i4"))
        nbytes = n * dtype.itemsize
        if code == b"DIGITAL SURF":
            buf = fh.read(nbytes)
            if len(buf) < nbytes:
                raise ScanError(f"{where} is truncated: {len(buf):,} bytes of point data; "
                                f"expected {nbytes:,}")
        else:
            buf = _sur_inflate(fh, bo, nbytes, dtype.itemsize, size, where)
    raw = np.frombuffer(buf, dtype).reshape(ny, nx)
    z = to_mm(raw.astype(np.float64) * float(np.float32(h["spacing_z"]))
              + float(np.float32(h["offset_z"])), units["z"])
    if h["non_measured"] == 1:
        z[raw == h["min_point"] - 2] = np.nan
    dx = to_mm(float(np.float32(h["spacing_x"])), units["x"])
    dy = to_mm(float(np.float32(h["spacing_y"])), units["y"])
    x0 = to_mm(float(np.float32(h["offset_x"])), units["x"])
    y0 = to_mm(float(np.float32(h["offset_y"])), units["y"])
    meta = {"file_units": units["z"], "lateral_units": units["x"], "bits": h["bits"],
            "compressed": code == b"DSCOMPRESSED", "z_spacing": float(np.float32(h["spacing_z"])),
            "z_offset": float(np.float32(h["offset_z"])),
            "operator": _sur_str(h["name_operator"]), "object": _sur_str(h["name_object"])}
    return _checked_map(z, dx, dy, x0, y0, where, "sur", meta, p.name)


def write_sur(path: str | os.PathLike[str], z_mm: ArrayLike, dx: float, dy: float, *,
              unit: str = "um", bits: int = 32, compressed: bool = False, x0: float = 0.0,
              y0: float = 0.0,
              z_spacing: float | None = None, z_offset: float | None = None) -> Path:
    """Write a Digital Surf SUR surface. Lengths (``dx``, ``dy``, offsets,
    ``z_spacing``, ``z_offset``) in ``unit`` (the header's unit strings), all
    rounded to float32 as the header stores them; heights stored as
    ``round((z − z_offset)/z_spacing)`` in 16 or 32 bits, NaN as the
    non-measured code ``Zmin − 2``."""
    u = {"um": "µm"}.get(unit, unit)
    f = LENGTH_UNITS[unit]
    z = np.asarray(z_mm, np.float64) * float(f.denominator) / float(f.numerator)  # in unit
    ny, nx = z.shape
    ok = np.isfinite(z)
    lo, hi = (float(z[ok].min()), float(z[ok].max())) if ok.any() else (0.0, 0.0)
    imax = 32767 if bits == 16 else 2**31 - 1
    zmin_code = -imax + 2                       # leaves Zmin − 2 free for non-measured points
    if z_offset is None:
        z_offset = float(np.float32(0.5 * (lo + hi)))
    if z_spacing is None:       # the smallest float32 step that spans the range
        need = max(hi - float(np.float32(z_offset)), float(np.float32(z_offset)) - lo,
                   tol.inspect.sur_min_span) / (imax - 16)
        z32 = np.float32(need)
        z_spacing = float(z32 if float(z32) >= need else np.nextafter(z32, np.float32(np.inf)))
    zs, zo = float(np.float32(z_spacing)), float(np.float32(z_offset))
    raw = np.where(ok, np.round((z - zo) / zs), zmin_code - 2)
    if ok.any() and (raw[ok].min() < zmin_code or raw[ok].max() > imax):
        raise ValueError("heights out of the integer range for this z_spacing")
    raw = raw.astype("<i2" if bits == 16 else "<i4")
    vals: dict[str, Any] = dict.fromkeys(_SUR_FIELDS, 0)
    vals.update(code=b"DSCOMPRESSED" if compressed else b"DIGITAL SURF", format=0, n_objects=1,
                version=1, studiable=2, name_object=b"", name_operator=b"tipgeo",
                non_measured=int(not ok.all()), bits=bits,
                min_point=zmin_code, max_point=imax, nx=nx, ny=ny, n_total=nx * ny,
                spacing_x=dx, spacing_y=dy, spacing_z=zs, name_x=b"X", name_y=b"Y",
                name_z=b"Z", ratio_x=1.0, ratio_y=1.0, ratio_z=1.0,
                client=b"", offset_x=x0, offset_y=y0, offset_z=zo, name_t=b"", unit_t=b"",
                year=2000, month=1, day=1)
    for k in ("x", "y", "z"):
        vals[f"unit_step_{k}"] = vals[f"unit_{k}"] = u.encode("latin-1")
    data = raw.tobytes()
    if compressed:
        zd = zlib.compress(data)
        body = struct.pack("<3I", 1, len(data), len(zd)) + zd
        vals["compressed_size"] = len(body)
    else:
        body = data
    head = _SUR_HEADER.pack(*(vals[k] for k in _SUR_FIELDS))

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(head)
            fh.write(body)

    write_atomic(Path(path), write)
    return Path(path)


# -----------------------------------------------------------------------------
# SDF (ISO 25178-71)
#: Default z scale of a written SDF (m): 1 µm, the heights' unit.
SDF_ZSCALE_M = 1.0e-6
_SDF_TYPES = {3: "<f4", 4: "<i1", 5: "<i2", 6: "<i4", 7: "<f8"}
_SDF_KEYS = ("ManufacID", "CreateDate", "ModDate", "NumPoints", "NumProfiles", "Xscale",
             "Yscale", "Zscale", "Zresolution", "Compression", "DataType", "CheckType")


def _sdf_binary(fh: IO[bytes], wide: bool, size: int, where: str,
                max_pixels: int) -> tuple[FloatArray, BoolArray, int, int, float, float]:
    """(heights in mm, invalid mask, nx, ny, dx, dy) of a binary SDF (ISO-1.0,
    or ISO-2.0 with ``wide`` counts) read from just past its magic."""
    hs = struct.Struct("<10s12s12s" + ("II" if wide else "HH") + "ddddBBB")
    hb = fh.read(hs.size)
    if len(hb) < hs.size:
        raise ScanError(f"{where}: binary SDF header is truncated ({len(hb)} of "
                        f"{hs.size} bytes)")
    h = dict(zip(_SDF_KEYS, hs.unpack(hb)))
    nx, ny, dtc = h["NumPoints"], h["NumProfiles"], h["DataType"]
    _check_pixels(nx, ny, where, "header NumPoints × NumProfiles", max_pixels)
    if dtc not in _SDF_TYPES:
        raise ScanError(f"{where}: header DataType = {dtc}; allowed 3 (float32), "
                        "4 (int8), 5 (int16), 6 (int32), 7 (float64)")
    if h["Compression"] != 0:
        raise ScanError(f"{where}: header Compression = {h['Compression']}; only "
                        "uncompressed (0) data are defined")
    dtype = np.dtype(_SDF_TYPES[dtc])
    need = 8 + hs.size + nx * ny * dtype.itemsize
    if need > size:
        raise ScanError(f"{where} is truncated: {size:,} bytes; NumPoints × NumProfiles"
                        f" × {dtype.itemsize} needs {need:,}")
    raw = np.frombuffer(fh.read(nx * ny * dtype.itemsize), dtype)
    bad = raw == (np.finfo(dtype).min if dtype.kind == "f" else np.iinfo(dtype).min)
    zs, xs, ys = (float(h[k]) for k in ("Zscale", "Xscale", "Yscale"))
    z = raw.astype(np.float64) * zs * 1000.0
    return z, bad, nx, ny, xs * 1000.0, ys * 1000.0


def _sdf_ascii_header(text: str, where: str) -> dict[str, str]:
    """The ``Key = value`` lines of an ASCII SDF header (lines from 2)."""
    h = {}
    for ln, line in enumerate(text.splitlines(), 2):
        if not line.strip():
            continue
        k, sep, v = line.partition("=")
        if not sep:
            raise ScanError(f"{where}: line {ln}: '{line.strip()[:40]}'; expected "
                            "'Key = value'")
        h[k.strip()] = v.strip()
    for k in ("NumPoints", "NumProfiles", "Xscale", "Yscale", "Zscale"):
        if k not in h:
            raise ScanError(f"{where}: header key {k} is missing")
    return h


def _sdf_ascii_values(toks: list[str], where: str) -> FloatArray:
    """The data record's values (``BAD``: NaN)."""
    vals = np.empty(len(toks))
    for i, t in enumerate(toks):
        if t.upper() == "BAD":
            vals[i] = np.nan
            continue
        try:
            vals[i] = float(t)
        except ValueError:
            raise ScanError(f"{where}: data value {i + 1} = '{t[:40]}' is not a number "
                            "or BAD") from None
    return vals


def _sdf_ascii(fh: IO[bytes], size: int, where: str,
               max_pixels: int) -> tuple[FloatArray, BoolArray, int, int, float, float]:
    """(heights in mm, invalid mask, nx, ny, dx, dy) of an ASCII SDF read
    from just past its magic; header numbers scaled in decimal."""
    text = fh.read(min(size, MAX_SCAN_BYTES)).decode("latin-1")
    parts = text.split("*")
    if len(parts) < 2:
        raise ScanError(f"{where}: ASCII SDF without the '*' that ends its header")
    h = _sdf_ascii_header(parts[0], where)
    try:
        nx, ny = int(h["NumPoints"]), int(h["NumProfiles"])
    except ValueError:
        raise ScanError(f"{where}: header NumPoints = '{h['NumPoints']}', NumProfiles = "
                        f"'{h['NumProfiles']}'; expected whole numbers") from None
    _check_pixels(nx, ny, where, "header NumPoints × NumProfiles", max_pixels)
    toks = parts[1].split()
    if len(toks) != nx * ny:
        raise ScanError(f"{where}: the data record holds {len(toks):,} values; expected "
                        f"NumPoints × NumProfiles = {nx * ny:,}")
    vals = _sdf_ascii_values(toks, where)
    zdec = _decimal_to_mm(h["Zscale"], "m", where, "Zscale")
    z = vals * zdec
    dx = _decimal_to_mm(h["Xscale"], "m", where, "Xscale")
    dy = _decimal_to_mm(h["Yscale"], "m", where, "Yscale")
    return z, ~np.isfinite(z), nx, ny, dx, dy


def _read_sdf(p: Path, where: str, max_pixels: int) -> HeightMap:
    size = p.stat().st_size
    with open(p, "rb") as fh:
        magic = fh.read(8)
        if magic in (b"bISO-1.0", b"bISO-2.0"):
            z, bad, nx, ny, dx, dy = _sdf_binary(fh, magic == b"bISO-2.0", size, where,
                                                 max_pixels)
            kind = "binary"
        elif magic in (b"aISO-1.0", b"aISO-2.0"):
            z, bad, nx, ny, dx, dy = _sdf_ascii(fh, size, where, max_pixels)
            kind = "ascii"
        else:
            raise ScanError(f"{where} is not an ISO 25178-71 SDF file (magic "
                            f"{magic[:8]!r}; expected aISO-1.0, bISO-1.0, aISO-2.0 or bISO-2.0)")
    z = np.where(bad, np.nan, z)
    meta = {"file_units": "m", "encoding": kind, "magic": magic.decode("latin-1")}
    return _checked_map(z.reshape(ny, nx), dx, dy, 0.0, 0.0, where, "sdf", meta, p.name)


def write_sdf(path: str | os.PathLike[str], z_mm: ArrayLike, dx_mm: float, dy_mm: float, *,
              binary: bool = True, zscale_m: float = SDF_ZSCALE_M) -> Path:
    """Write an ISO 25178-71 SDF (ISO-1.0): binary float64 values of
    z/``zscale_m`` (NaN: the type's minimum), or ASCII with each value as
    its shortest exact decimal (NaN: ``BAD``)."""
    z = np.asarray(z_mm, np.float64)
    ny, nx = z.shape
    vals = (z / 1000.0) / zscale_m
    xs, ys = dx_mm / 1000.0, dy_mm / 1000.0
    if binary:
        head = b"bISO-1.0" + struct.pack("<10s12s12sHHddddBBB", b"tipgeo", b"010120000000",
                                         b"010120000000", nx, ny, xs, ys, zscale_m, -1.0, 0, 7,
                                         0)
        body = np.where(np.isfinite(vals), vals, np.finfo(np.float64).min).astype("<f8")
        blob = head + body.tobytes()
    else:
        lines = ["aISO-1.0", "ManufacID = tipgeo", "CreateDate = 010120000000",
                 "ModDate = 010120000000", f"NumPoints = {nx}", f"NumProfiles = {ny}",
                 f"Xscale = {Decimal(repr(float(dx_mm))) / 1000}",
                 f"Yscale = {Decimal(repr(float(dy_mm))) / 1000}",
                 f"Zscale = {zscale_m!r}", "Zresolution = -1", "Compression = 0",
                 "DataType = 7", "CheckType = 0", "*"]
        flat = [repr(float(v)) if np.isfinite(v) else "BAD" for v in vals.ravel()]
        lines += [" ".join(flat[i:i + 10]) for i in range(0, len(flat), 10)]
        lines += ["*", "Comment = tipgeo", "*"]
        blob = ("\r\n".join(lines) + "\r\n").encode("ascii")

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(blob)

    write_atomic(Path(path), write)
    return Path(path)


# -----------------------------------------------------------------------------
# formats read by surfalize
def surfalize_available() -> bool:
    """True when surfalize can be imported."""
    try:
        import surfalize.file  # noqa: F401
    except Exception:
        return False
    return True


def _read_surfalize(p: Path, where: str, max_pixels: int) -> HeightMap:
    ext = p.suffix.lower()
    try:
        import surfalize.file as sf
    except Exception as e:
        raise MissingToolError(f"{where}: reading {ext} height maps needs surfalize, which "
                               f"cannot be imported ({type(e).__name__}: {e}); install it "
                               f"with: {SURFALIZE_PIP}") from None
    handler = sf.common.FileHandler
    reader = getattr(handler, "_readers_by_suffix", {}).get(ext)
    if reader is None:
        raise ScanError(f"{where}: this surfalize version has no {ext} reader")
    import warnings

    with open(p, "rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = reader(fh, read_image_layers=False, encoding="auto")
    data = np.asarray(raw.data)
    if data.ndim != 2:
        raise ScanError(f"{where}: surfalize read an array of shape {data.shape}; expected "
                        "rows × columns")
    ny, nx = data.shape
    _check_pixels(nx, ny, where, "the height map read", max_pixels)
    z = np.asarray(data, np.float64) / 1000.0           # µm → mm, correctly rounded
    z[~np.isfinite(z)] = np.nan
    dx, dy = float(raw.step_x) / 1000.0, float(raw.step_y) / 1000.0
    import surfalize

    meta = {"file_units": "um (surfalize)", "reader": f"surfalize {surfalize.__version__}"}
    return _checked_map(z, dx, dy, 0.0, 0.0, where, ext[1:], meta, p.name)
