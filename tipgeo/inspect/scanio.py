"""Reading and writing scans (point clouds, meshes, instrument height maps).

Units: coordinates are scaled to mm on reading (``units``: ``mm``, ``um``,
``m``); the frame is whatever the scanner used (registration finds the
cannula frame).

Formats: PLY (point cloud or mesh), PCD, XYZ/TXT/PTS/XYZN, STL and OBJ
(through trimesh; their vertices are the measured points); CSV/TXT exports
in any common dialect, point lists or height-map grids
(:mod:`tipgeo.inspect.textscan`); instrument height maps — ``.x3p``,
``.al3d``, ``.sur``, ``.sdf`` read by tipgeo, the vendor formats of
:data:`~tipgeo.inspect.heightmap.SURFALIZE_FORMATS` through the optional
surfalize (:mod:`tipgeo.inspect.heightmap`) — whose valid pixels become
points in the instrument frame (x, y from the lateral spacing, z the height,
mm), the count of invalid pixels in ``Scan.meta['invalid_pixels']``. XYZ/TXT/PTS/XYZN
text and PLY vertices (binary or ASCII) are read in chunks with numpy, so a
scan of 10⁷ points never sits in memory as text or as Python objects; PCD
goes through open3d. Errors for missing, empty, unreadable, non-finite or
absurdly large input are :class:`ScanError` and name the file, the value and
what is allowed.

Storage: :func:`load_scan` keeps every coordinate exactly as read (float64).
With ``compact=True`` (what :func:`tipgeo.inspect.compare` uses) the points
are kept as float32 offsets from a float64 origin (the centre of the first
chunk read) wherever the offsets stay below :data:`F32_OFFSET_LIMIT_MM`, so
that no coordinate moves by more than half a float32 ulp at 16 mm,
2⁻²¹ mm ≈ 4.8·10⁻⁴ µm; a scan reaching farther from its origin is kept in
float64 instead (exact, twice the memory).
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import AnyArray, ArrayLike, FloatArray
from ..atomic import write_atomic
from ..errors import ScanError
from .heightmap import (
    HEIGHT_MAP_FORMATS,
    MAX_SCAN_BYTES,
    MAX_SCAN_POINTS,
    HeightMap,
    read_height_map,
)
from .textscan import (
    TABLE_LAYOUTS,
    Table,
    iter_table_points,
    line_blocks,
    read_table_grid,
    sniff_table,
)

__all__ = ["Scan", "ScanError", "load_scan", "write_ply", "check_points", "SCAN_FORMATS",
           "POINT_FORMATS", "HEIGHT_MAP_FORMATS", "MAX_SCAN_POINTS", "MAX_SCAN_BYTES",
           "scan_from_height_map",
           "UNITS", "MAX_COORDINATE_MM", "F32_OFFSET_LIMIT_MM"]

#: Length units accepted for scan files, and their size in mm.
UNITS: dict[str, float] = {"mm": 1.0, "um": 1.0e-3, "µm": 1.0e-3, "m": 1.0e3}

#: Point-cloud, mesh and text scan extensions (lower case).
POINT_FORMATS: tuple[str, ...] = (".ply", ".pcd", ".xyz", ".xyzn", ".txt", ".csv", ".pts",
                                  ".stl", ".obj")

#: Every scan file extension (lower case): point formats, then height maps.
SCAN_FORMATS: tuple[str, ...] = POINT_FORMATS + HEIGHT_MAP_FORMATS

#: Largest |coordinate| a scan may have, in mm after the unit conversion (1 km:
#: far beyond any scanner's frame, far below where squares of coordinates
#: lose precision or overflow in double precision).
MAX_COORDINATE_MM = 1.0e6

#: Compact storage keeps float32 offsets only while |offset| < this (mm):
#: the rounding is then at most 2⁻²¹ mm (half a float32 ulp below 16).
F32_OFFSET_LIMIT_MM = 16.0

_CHUNK_ROWS = 1 << 20          # points per chunk of a binary PLY
_CHUNK_BYTES = 1 << 25         # bytes per chunk of a text file


class Scan:
    """A measured point cloud.

    Parameters
    ----------
    points : (n, 3) float — mm, scanner frame; with ``origin``, the offsets
        from it (float32 or float64, already checked)
    normals : (n, 3) float or None — unit normals from the file, if any
    source : str — file name or description
    meta : dict — format, file units, point count as read, storage
    origin : (3,) float, optional — see ``points``

    Attributes
    ----------
    points : (n, 3) float64 — absolute coordinates (mm); computed from
        ``origin + local`` for a compact scan (a new array each time)
    local : (n, 3) float32 or float64 — the stored offsets from ``origin``
    origin : (3,) float64 — mm
    rounding_mm : float — bound of |stored − read| per coordinate (0: exact)
    """

    def __init__(self, points: ArrayLike, normals: ArrayLike | None = None,
                 source: str = "array", meta: dict[str, Any] | None = None, *,
                 origin: ArrayLike | None = None):
        self.source = source
        self.meta = dict(meta or {})
        self._local: AnyArray
        if origin is None:
            self._local = check_points(points, source)
            self.origin = np.zeros(3)
        else:
            loc = np.asarray(points)
            if loc.dtype not in (np.float32, np.float64) or loc.ndim != 2 or loc.shape[1] != 3:
                raise ScanError(f"{source}: offsets must be an (n, 3) float32/float64 array")
            if len(loc) == 0:
                raise ScanError(f"{source}: the scan is empty (0 points)")
            self._local = loc
            self.origin = np.asarray(origin, np.float64).reshape(3)
        self.normals: AnyArray | None = None
        if normals is not None:
            n = np.asarray(normals)
            if n.dtype not in (np.float32, np.float64):
                n = n.astype(np.float64)
            n = n.reshape(-1, 3)
            if len(n) == len(self._local) and np.all(np.isfinite(n)):
                self.normals = n

    @property
    def points(self) -> FloatArray:
        if self._local.dtype == np.float64 and not self.origin.any():
            return self._local
        return self.origin + self._local.astype(np.float64)

    @points.setter
    def points(self, value: ArrayLike) -> None:
        self._local = check_points(value, self.source)
        self.origin = np.zeros(3)

    @property
    def local(self) -> AnyArray:
        return self._local

    @property
    def rounding_mm(self) -> float:
        if self._local.dtype == np.float64:
            return 0.0
        m = np.float32(max(self._local.max(initial=0.0), -self._local.min(initial=0.0)))
        return float(np.spacing(m)) / 2

    def __len__(self) -> int:
        return len(self._local)

    def __repr__(self) -> str:
        return (f"Scan({len(self):,} points, source={self.source!r}, "
                f"storage={self._local.dtype.name})")


def _coordinate_limit_error(where: str, biggest: float, unit: str = "mm",
                            factor: float = 1.0) -> ScanError:
    if unit == "mm":
        got = f"coordinates up to {biggest:.3g} mm"
    else:
        got = f"coordinates up to {biggest:.3g} {unit} ({biggest * factor:.3g} mm)"
    return ScanError(f"{where}: {got}; allowed |x| ≤ {MAX_COORDINATE_MM:.0e} mm "
                     "(wrong --units, or a corrupt file?)")


def check_points(points: ArrayLike, where: str = "points") -> FloatArray:
    """Return ``points`` as a finite (n ≥ 1, 3) float64 array with every
    |coordinate| ≤ :data:`MAX_COORDINATE_MM`, else ScanError."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as e:
        raise ScanError(f"{where}: not numeric point coordinates ({e})") from None
    if p.ndim != 2 or p.shape[1] != 3:
        raise ScanError(f"{where}: points have shape {p.shape}; expected (n, 3)")
    if len(p) == 0:
        raise ScanError(f"{where}: the scan is empty (0 points)")
    bad = ~np.all(np.isfinite(p), axis=1)
    if bad.any():
        raise ScanError(f"{where}: {int(bad.sum())} of {len(p)} points have non-finite "
                        f"(NaN or infinite) coordinates (the first is point "
                        f"{int(np.argmax(bad)) + 1})")
    biggest = float(np.abs(p).max())
    if biggest > MAX_COORDINATE_MM:
        raise _coordinate_limit_error(where, biggest)
    return np.ascontiguousarray(p)


class _Accumulator:
    """Collects point chunks (file units): counts non-finite points, tracks
    the largest |coordinate|, converts to mm and stores them (exact float64,
    or compact float32 offsets from the first chunk's centre)."""

    def __init__(self, where: str, units: str, compact: bool, capacity: int | None = None):
        self.where, self.units, self.factor = where, units, UNITS[units]
        self.compact = compact
        self.count = 0
        self.bad = 0
        self.first_bad = -1
        self.biggest = 0.0
        self.origin: FloatArray | None = None
        self.parts: list[AnyArray] = []
        self.nparts: list[AnyArray] = []
        self.normals_ok = True
        self.dtype = np.float32 if compact else np.float64
        self.buf = None
        if capacity is not None and capacity > 0:
            self.buf = np.empty((capacity, 3), self.dtype)
        self.stored = 0

    @property
    def failed(self) -> bool:
        return self.bad > 0 or self.biggest * self.factor > MAX_COORDINATE_MM

    def _check_count(self, m: int) -> None:
        if self.count + m > MAX_SCAN_POINTS:
            raise ScanError(f"{self.where}: more than {MAX_SCAN_POINTS:,} points; allowed at "
                            f"most {MAX_SCAN_POINTS:,}")

    def add(self, xyz: AnyArray, nrm: AnyArray | None = None) -> None:
        m = len(xyz)
        if not m:
            return
        self._check_count(m)
        fin = np.isfinite(xyz).all(axis=1)
        nb = m - int(np.count_nonzero(fin))
        if nb:
            if not self.bad:
                self.first_bad = self.count + int(np.argmin(fin))
            self.bad += nb
        self.count += m
        big = float(np.abs(xyz[fin]).max(initial=0.0)) if nb else float(np.abs(xyz).max())
        self.biggest = max(self.biggest, big)
        if self.failed:
            self.parts, self.nparts, self.buf = [], [], None  # nothing more is stored
            return
        mm = np.asarray(xyz, np.float64) * self.factor if self.factor != 1.0 else \
            np.asarray(xyz, np.float64)
        if self.origin is None:
            self.origin = 0.5 * (mm.min(axis=0) + mm.max(axis=0)) if self.compact \
                else np.zeros(3)
        loc = mm - self.origin if self.compact else mm
        if self.dtype == np.float32 and np.abs(loc).max() >= F32_OFFSET_LIMIT_MM:
            self._widen()
        self._store(loc)
        if nrm is not None and self.normals_ok:
            self.nparts.append(np.asarray(nrm, self.dtype))
        else:
            self.normals_ok = False
            self.nparts = []

    def add_fields(self, x: AnyArray, y: AnyArray, z: AnyArray) -> bool:
        """:meth:`add` of the columns of a binary chunk ((m,) native float32
        or float64 each) in two compiled passes, with no (m, 3) temporary;
        False (nothing done) where it does not apply: a preallocated buffer is
        needed and a chunk with a non-finite or too large coordinate goes
        through :meth:`add` (which reports it)."""
        from .scanfast import chunk_bounds, store_offsets

        cols = (x, y, z)
        if (self.buf is None or self.failed or self.stored + len(x) > len(self.buf)
                or any(c.dtype.kind != "f" or not c.dtype.isnative for c in cols)):
            return False
        if not len(x):
            return True
        self._check_count(len(x))
        nbad, biggest, lo, hi = chunk_bounds(x, y, z)
        if nbad or max(self.biggest, biggest) * self.factor > MAX_COORDINATE_MM:
            return False
        self.count += len(x)
        self.biggest = max(self.biggest, biggest)
        if self.origin is None:
            # the chunk's centre in mm: min(x·f) = min(x)·f for f > 0
            self.origin = 0.5 * (lo * self.factor + hi * self.factor) if self.compact \
                else np.zeros(3)
        span = store_offsets(x, y, z, self.factor, self.origin, self.buf, self.stored)
        if self.dtype == np.float32 and span >= F32_OFFSET_LIMIT_MM:
            self._widen()
            store_offsets(x, y, z, self.factor, self.origin, self.buf, self.stored)
        self.stored += len(x)
        self.normals_ok, self.nparts = False, []
        return True

    def _widen(self) -> None:
        """Switch the storage to float64 (points stored so far were within
        the float32 limit, so their rounding stays within its bound)."""
        self.dtype = np.float64
        if self.buf is not None:
            wide = np.empty(self.buf.shape, np.float64)
            wide[:self.stored] = self.buf[:self.stored]   # only what was filled
            self.buf = wide
        self.parts = [p.astype(np.float64) for p in self.parts]

    def _store(self, loc: AnyArray) -> None:
        if self.buf is not None and self.stored + len(loc) <= len(self.buf):
            self.buf[self.stored:self.stored + len(loc)] = loc
        else:
            if self.buf is not None:  # more points than the header said: keep them all
                self.parts.append(self.buf[:self.stored])
                self.buf = None
            self.parts.append(loc.astype(self.dtype, copy=False))
        self.stored += len(loc)

    def finish(self, meta: dict[str, Any]) -> Scan:
        where = self.where
        if self.bad:
            raise ScanError(f"{where}: {self.bad} of {self.count} points have non-finite "
                            f"(NaN or infinite) coordinates (the first is point "
                            f"{self.first_bad + 1})")
        if self.biggest * self.factor > MAX_COORDINATE_MM:
            raise _coordinate_limit_error(where, self.biggest, self.units, self.factor)
        if self.count == 0:
            raise ScanError(f"{where} holds no points")
        if self.buf is not None:
            local = self.buf[:self.stored]
        else:
            local = self.parts[0] if len(self.parts) == 1 else np.concatenate(self.parts)
            self.parts = []
        normals = None
        if self.normals_ok and self.nparts:
            normals = self.nparts[0] if len(self.nparts) == 1 else np.concatenate(self.nparts)
        meta = dict(meta, points=int(self.count), file_units=self.units,
                    storage=("float32 offsets from a float64 origin"
                             if local.dtype == np.float32 else "float64"))
        s = Scan(local, normals, source=meta.get("source", where), meta=meta,
                 origin=self.origin if self.compact else np.zeros(3))
        s.meta["rounding_mm"] = s.rounding_mm
        return s


def load_scan(path: str | os.PathLike[str], *, units: str = "mm",
              compact: bool = False, spacing_mm: float | tuple[float, float] | None = None,
              layout: str | None = None) -> Scan:
    """Read a scan file.

    Parameters
    ----------
    path : str or PathLike
        Any of :data:`SCAN_FORMATS` (case-insensitive): ``.ply .pcd .xyz
        .xyzn .txt .csv .pts .stl .obj``, and the height maps of
        :data:`HEIGHT_MAP_FORMATS` (``.x3p .al3d .sur .sdf`` and, with
        surfalize, the vendor formats). ``.txt``/``.csv`` are sniffed: a plain
        x y z list, or any dialect of :mod:`tipgeo.inspect.textscan`.
    units : {'mm', 'um', 'm'}
        Length unit of what the file leaves unstated (PLY, XYZ, a CSV without
        units); a unit the file states (X3P, AL3D, SUR, SDF, a CSV header or
        key) wins. Everything is scaled to mm.
    compact : bool
        Keep float32 offsets from a float64 origin where that rounds no
        coordinate by more than 2⁻²¹ mm (see the module docstring); default:
        every coordinate exactly as read (float64).
    spacing_mm : float or (dx, dy), optional
        Lateral spacing (mm) of a CSV/TXT height-map grid whose header gives
        none (it makes a file without x, y, z column names a grid).
    layout : {'points', 'grid'}, optional
        Force a CSV/TXT file's layout instead of sniffing it.

    Returns
    -------
    Scan
        ``meta`` has the format, the file's units and where they came from
        (``units_from``), and for a height map its ``grid`` (rows, columns),
        ``spacing_mm``, ``pixels`` and ``invalid_pixels`` (dropped: NaN or the
        format's no-data code); for a CSV/TXT point list ``invalid_points``.

    Raises
    ------
    ScanError
        Unknown extension or units; missing, empty, malformed or unreadable
        file (the message names the file, the part and what was expected);
        no points; non-finite coordinates; |coordinate| > MAX_COORDINATE_MM;
        more than :data:`MAX_SCAN_POINTS` points or pixels (a height map is
        refused from its header, before its data are read).
    MissingToolError
        A height-map format that needs surfalize while it is not installed
        (the message gives the pip line; the command line exits 3).
    """
    _check_scan_options(units, layout)
    p = Path(path)
    ext = _check_scan_file(p)
    where = f"scan '{p}'"
    meta: dict[str, Any] = {"path": str(p), "format": ext[1:], "source": p.name}
    if ext in HEIGHT_MAP_FORMATS:
        return scan_from_height_map(read_height_map(p), compact=compact, meta=meta)
    try:
        got = _read_points(p, ext, where, meta, units=units, compact=compact,
                           spacing_mm=spacing_mm, layout=layout)
    except ScanError:
        raise
    except MemoryError:
        raise ScanError(f"{where}: too large to read into memory") from None
    except Exception as e:  # any reader failure is a bad file
        raise ScanError(f"{where} could not be read as {ext}: {type(e).__name__}: {e}") \
            from None
    return got if isinstance(got, Scan) else got.finish(meta)


def _check_scan_options(units: str, layout: str | None) -> None:
    if units not in UNITS:
        raise ScanError(f"units = {units!r} is not supported; allowed: mm, um, m")
    if layout is not None and layout not in TABLE_LAYOUTS:
        raise ScanError(f"layout = {layout!r} is not supported; allowed: "
                        + ", ".join(TABLE_LAYOUTS))


def _check_scan_file(p: Path) -> str:
    """The scan's extension (lower case) once the file is known to exist,
    be a regular non-empty file of a known format and not too large."""
    ext = p.suffix.lower()
    if ext not in SCAN_FORMATS:
        raise ScanError(f"scan '{p}' has extension '{p.suffix}'; allowed: "
                        + ", ".join(SCAN_FORMATS))
    if not p.exists():
        raise ScanError(f"scan '{p}' does not exist")
    if not p.is_file():
        raise ScanError(f"scan '{p}' is not a regular file")
    size = p.stat().st_size
    if size == 0:
        raise ScanError(f"scan '{p}' is empty (0 bytes)")
    if size > MAX_SCAN_BYTES:
        raise ScanError(f"scan '{p}' has {size:,} bytes; allowed at most {MAX_SCAN_BYTES:,}")
    return ext


def _read_points(p: Path, ext: str, where: str, meta: dict[str, Any], *, units: str,
                 compact: bool, spacing_mm: float | tuple[float, float] | None,
                 layout: str | None) -> _Accumulator | Scan:
    """The points of a point-cloud, mesh or text scan (accumulated, or a
    finished Scan for a CSV/TXT table)."""
    if ext in (".stl", ".obj"):
        acc = _Accumulator(where, units, compact)
        acc.add(_read_trimesh(p))
        return acc
    if ext == ".ply":
        return _read_ply(p, where, units, compact)
    if ext in (".txt", ".csv"):
        return _read_table(p, where, meta, units=units, compact=compact,
                           spacing_mm=spacing_mm, layout=layout)
    acc = _Accumulator(where, units, compact)
    if ext in (".xyz", ".pts", ".xyzn"):
        _read_text(p, acc, normals=(ext == ".xyzn"), count_line=(ext == ".pts"))
    else:
        pts, nrm = _read_open3d(p)
        acc.add(pts, nrm)
    return acc


def _read_table(p: Path, where: str, meta: dict[str, Any], *, units: str, compact: bool,
                spacing_mm: float | tuple[float, float] | None,
                layout: str | None) -> _Accumulator | Scan:
    """A CSV/TXT scan: sniffed (:mod:`tipgeo.inspect.textscan`), or the
    plain x y z reader where no one dialect fits."""
    table = sniff_table(p, units=units, spacing_mm=spacing_mm, layout=layout)
    if table is None:            # no one dialect: the plain x y z reader
        acc = _Accumulator(where, units, compact)
        _read_text(p, acc, normals=False, count_line=False)
        meta["units_from"] = "argument"
        return acc
    if table.layout == "grid":
        hm = read_table_grid(p, table)
        return scan_from_height_map(hm, compact=compact, meta=meta)
    return _read_table_points(p, table, where, meta, compact)


def _read_table_points(p: Path, table: Table, where: str, meta: dict[str, Any],
                       compact: bool) -> Scan:
    """A CSV/TXT point list (mm), its units, columns and dropped rows in meta."""
    acc = _Accumulator(where, "mm", compact)
    invalid = 0
    for pts, bad in iter_table_points(p, table):
        invalid += bad
        acc.add(pts)
    if acc.count == 0 and not acc.failed:
        raise ScanError(f"{where} holds no valid points ({invalid} rows with "
                        "no-data fields)")
    s = acc.finish(meta)
    units_col = [table.col_units[k] or (table.z_unit if a == "z" else table.xy_unit)
                 for a, k in zip("xyz", table.xyz)]
    s.meta.update(file_units=units_col[2] if len(set(units_col)) == 1 else
                  "/".join(units_col), units_from=table.units_from,
                  invalid_points=invalid, layout="points",
                  separator=table.sep or "whitespace", decimal=table.decimal,
                  columns=[table.columns[k] or str(k + 1) for k in table.xyz])
    if table.unit_col is not None:
        s.meta["file_units"] = "per row (unit column)"
    return s


def scan_from_height_map(hm: HeightMap, *, compact: bool = False,
                         meta: dict[str, Any] | None = None) -> Scan:
    """The valid pixels of a height map as a :class:`Scan` in the instrument
    frame (x = x0 + column·dx, y = y0 + row·dy, z = height; mm), its grid,
    spacing and invalid-pixel count in ``meta``."""
    where = f"scan '{hm.source}'"
    if hm.pixels > MAX_SCAN_POINTS:
        raise ScanError(f"{where}: {hm.pixels:,} pixels; allowed at most {MAX_SCAN_POINTS:,}")
    acc = _Accumulator(where, "mm", compact, capacity=hm.pixels - hm.invalid)
    for pts in hm.iter_points(rows=max(1, (1 << 20) // max(1, hm.shape[1]))):
        acc.add(pts)
    invalid = hm.invalid
    if acc.count == 0:
        raise ScanError(f"{where}: every one of its {hm.pixels:,} pixels is invalid (no-data)")
    m = dict(meta or {"format": hm.format, "source": hm.source})
    m.update({k: v for k, v in hm.meta.items() if k not in ("header_keys",)})
    s = acc.finish(m)
    s.meta.update(file_units=hm.meta.get("file_units", "mm"),
                  units_from=hm.meta.get("units_from", "file"), layout="grid",
                  grid=list(hm.shape), spacing_mm=[hm.dx, hm.dy],
                  origin_mm=[hm.x0, hm.y0], pixels=hm.pixels, invalid_pixels=invalid)
    return s


def _read_open3d(p: Path) -> tuple[FloatArray, FloatArray | None]:
    from .._open3d import import_open3d

    o3d = import_open3d()
    pc = o3d.io.read_point_cloud(str(p), format="auto", print_progress=False)
    pts = np.asarray(pc.points, dtype=np.float64)
    nrm = np.asarray(pc.normals, dtype=np.float64) if pc.has_normals() else None
    return pts, nrm


# -----------------------------------------------------------------------------
# text: XYZ, TXT, PTS, XYZN (and the vertex lines of an ASCII PLY)
_COMMENT = re.compile(rb"^\s*(#|//|$)")
_INLINE = re.compile(rb"#|//")
_ROW = re.compile(r"at row (\d+)")


def _is_number(tok: bytes) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _parse_block(block: bytes, ncols: int, where: str, line0: int) -> FloatArray:
    """The first ``ncols`` columns of a chunk of lines, (m, ncols) float64:
    numpy's C parser on the plain chunk; comments (# and //), commas and a
    varying number of extra columns take a slower path."""
    a = None
    if b"#" not in block and b"/" not in block and b"," not in block:
        try:
            a = np.loadtxt(io.BytesIO(block), dtype=np.float64, ndmin=2)
        except ValueError:
            a = None  # ragged columns, or a bad value: the slow path names the line
        if a is not None and a.size and a.shape[1] < ncols:
            a = None
    if a is None:
        try:
            a = np.loadtxt(io.BytesIO(block.replace(b",", b" ")), dtype=np.float64,
                           comments=("#", "//"), usecols=range(ncols), ndmin=2)
        except ValueError as e:
            msg = _ROW.sub(lambda m: f"on line {line0 + int(m.group(1)) + 1}", str(e))
            raise ScanError(f"{where}: {msg}") from None
    return a[:, :ncols] if a.size else np.zeros((0, ncols))


def _text_columns(lines: list[bytes], whole: bool, count_line: bool,
                  where: str) -> tuple[int, int]:
    """(number of value columns, number of lines to skip) of a text scan from
    the lines of its head (``whole``: the head is the whole file): comment
    lines and, before the first point, one header line (a column title such
    as ``X Y Z``, or with ``count_line`` a PTS point count) are skipped."""
    header_seen = False
    skip = 0
    for i, ln in enumerate(lines if whole else lines[:-1]):
        if _COMMENT.match(ln):
            continue
        toks = _INLINE.split(ln, maxsplit=1)[0].replace(b",", b" ").split()
        numbers = [_is_number(t) for t in toks]
        if not header_seen and (not all(numbers) or (count_line and len(toks) == 1)):
            header_seen, skip = True, i + 1
            continue
        if not all(numbers):
            bad = toks[numbers.index(False)]
            raise ScanError(f"{where}: line {i + 1}: '{bad.decode('ascii', 'replace')}'"
                            " is not a number")
        if len(toks) < 3:
            raise ScanError(f"{where}: lines have {len(toks)} value(s); expected x y z "
                            "(3 or more columns)")
        return len(toks), skip
    if whole:
        raise ScanError(f"{where} holds no points")
    raise ScanError(f"{where}: no point in its first 64 KiB")


def _read_text(p: Path, acc: _Accumulator, *, normals: bool, count_line: bool,
               start: int = 0, max_rows: int | None = None,
               cols: tuple[int, int, int] = (0, 1, 2), ncols: int | None = None) -> None:
    """Parse a whitespace- or comma-separated text file in chunks into
    ``acc`` (file units). Comment lines (# or //) and, before the first
    point, one header line (a column title such as ``X Y Z``, or a PTS point
    count) are skipped; with ``ncols`` given (an ASCII PLY's vertex lines
    from byte ``start``) nothing is."""
    with open(p, "rb") as fh:
        fh.seek(start)
        head = fh.read(min(_CHUNK_BYTES, 1 << 16))
        line0 = 0
        if ncols is None:
            lines = head.split(b"\n")
            ncols, skip = _text_columns(lines, len(head) < 1 << 16, count_line, acc.where)
            if skip:
                cut = sum(len(x) + 1 for x in lines[:skip])
                head, line0 = head[cut:], skip
        normals = normals and ncols >= 6
        want = max(6 if normals else 3, max(cols) + 1)
        for rows, block in line_blocks(fh, head, chunk_bytes=_CHUNK_BYTES, max_rows=max_rows):
            a = _parse_block(block, want, acc.where, line0 + rows)
            acc.add(a[:, list(cols)], a[:, 3:6] if normals else None)


# -----------------------------------------------------------------------------
def _read_trimesh(p: Path) -> FloatArray:
    """The vertices of an STL or OBJ file (file units; a mesh's repeated
    corners once)."""
    import trimesh

    g: Any = trimesh.load(str(p), process=False, force=None)
    if isinstance(g, trimesh.Scene):
        geoms = list(g.geometry.values())
        if not geoms:
            return np.zeros((0, 3))
        return np.concatenate([np.asarray(x.vertices, np.float64) for x in geoms])
    pts = np.asarray(g.vertices, dtype=np.float64)
    if isinstance(g, trimesh.Trimesh) and len(g.faces):
        pts = np.unique(pts, axis=0)  # STL repeats corners
    return pts


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


_PlyProps = list[tuple[str, str]]


@dataclass
class _PlyHeader:
    """A PLY header: its format, its elements (name, count, scalar
    properties with their numpy type), whether the vertex element has only
    scalar properties, and the byte offset of the data."""

    fmt: str
    elements: list[tuple[str, int, _PlyProps]]
    simple: bool
    data_start: int


def _ply_elements(lines: list[str], bo: str,
                  where: str) -> tuple[list[tuple[str, int, _PlyProps]], bool]:
    """The elements of a PLY header's lines and whether the vertex element
    has only scalar properties (``bo``: numpy byte order)."""
    elements: list[tuple[str, int, _PlyProps]] = []
    simple = True
    for ln in lines:
        t = ln.split()
        if not t:
            continue
        if t[0] == "element":
            if len(t) < 3 or not re.fullmatch(r"\d+", t[2]):
                raise ScanError(f"{where}: PLY header line '{ln.strip()}'; expected "
                                "'element NAME COUNT' with a count ≥ 0")
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            if len(t) < 3 or t[1] == "list" or t[1] not in _PLY_TYPES:
                if elements[-1][0] == "vertex":
                    simple = False
                continue
            elements[-1][2].append((t[2], bo + _PLY_TYPES[t[1]]))
    return elements, simple


def _ply_header(p: Path, where: str) -> _PlyHeader:
    with open(p, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ScanError(f"{where} is not a PLY file (no 'ply' magic or no end_header)")
    nl = head.find(b"\n", end)
    if nl < 0:
        nl = len(head) - 1
    lines = head[:end].decode("ascii", "replace").splitlines()
    fmt = next((ln.split()[1] for ln in lines if ln.startswith("format") and
                len(ln.split()) > 1), "")
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise ScanError(f"{where}: PLY format '{fmt}'; allowed ascii, binary_little_endian, "
                        "binary_big_endian")
    bo = "<" if fmt == "binary_little_endian" else ">"
    elements, simple = _ply_elements(lines, bo, where)
    return _PlyHeader(fmt, elements, simple, nl + 1)


def _read_ply(p: Path, where: str, units: str, compact: bool) -> _Accumulator:
    """PLY whose first element is 'vertex' with scalar properties: binary
    vertices in chunks straight into numpy (double precision kept), ASCII ones
    by the chunked text parser; anything else through open3d."""
    h = _ply_header(p, where)
    if not h.simple or not h.elements or h.elements[0][0] != "vertex":
        acc = _Accumulator(where, units, compact)
        pts, nrm = _read_open3d(p)
        acc.add(pts, nrm)
        return acc
    _, n, props = h.elements[0]
    if n > MAX_SCAN_POINTS:
        raise ScanError(f"{where}: the PLY header gives {n:,} vertices; allowed at most "
                        f"{MAX_SCAN_POINTS:,}")
    names = [k for k, _ in props]
    if not {"x", "y", "z"} <= set(names):
        raise ScanError(f"{where}: the vertex element has no x, y, z properties")
    has_n = {"nx", "ny", "nz"} <= set(names)
    if h.fmt == "ascii":
        acc = _Accumulator(where, units, compact)
        _read_ply_ascii(p, acc, h.data_start, n, names, has_n)
        return acc
    acc = _Accumulator(where, units, compact, capacity=n)
    _read_ply_binary(p, acc, h.data_start, n, props, has_n)
    return acc


def _read_ply_ascii(p: Path, acc: _Accumulator, start: int, n: int, names: list[str],
                    has_n: bool) -> None:
    """The ``n`` vertex lines of an ASCII PLY from byte ``start`` into ``acc``."""
    cols = (names.index("x"), names.index("y"), names.index("z"))
    if has_n and [names.index(c) for c in ("nx", "ny", "nz")] != [3, 4, 5]:
        has_n = False
    if n:
        _read_text(p, acc, normals=has_n, count_line=False, start=start, max_rows=n,
                   cols=cols, ncols=len(names))
    if acc.count < n and not acc.failed:
        raise ScanError(f"{acc.where} is truncated: {acc.count} of {n} vertices")


def _read_ply_binary(p: Path, acc: _Accumulator, start: int, n: int, props: _PlyProps,
                     has_n: bool) -> None:
    """The ``n`` vertices of a binary PLY from byte ``start`` into ``acc``,
    in chunks of :data:`_CHUNK_ROWS`."""
    where = acc.where
    dt = np.dtype(props)
    avail = (p.stat().st_size - start) // dt.itemsize
    if avail < n:
        raise ScanError(f"{where} is truncated: {max(avail, 0)} of {n} vertices")
    # one chunk buffer read into again and again: a fresh array per chunk
    # would be fresh pages each time (the allocator maps blocks this large
    # anew), and first touches of fresh pages cost more than the copy
    chunk = np.empty(min(_CHUNK_ROWS, n), dt)
    with open(p, "rb") as fh:
        fh.seek(start)
        done = 0
        while done < n:
            k = min(_CHUNK_ROWS, n - done)
            data = chunk[:k]
            got = fh.readinto(data.view(np.uint8).data) // dt.itemsize
            if got < k:
                raise ScanError(f"{where} is truncated: {done + got} of {n} vertices")
            if not has_n and acc.add_fields(data["x"], data["y"], data["z"]):
                done += k
                continue
            xyz = np.stack([data["x"], data["y"], data["z"]], 1).astype(np.float64)
            nrm = np.stack([data["nx"], data["ny"], data["nz"]], 1) if has_n else None
            acc.add(xyz, nrm)
            done += k


def write_ply(path: str | os.PathLike[str], points: ArrayLike, *,
              colors: ArrayLike | None = None, normals: ArrayLike | None = None,
              scalars: dict[str, ArrayLike] | None = None, comments: Iterable[str] = (),
              double: bool = True) -> Path:
    """Write a binary little-endian PLY point cloud, atomically.

    Parameters
    ----------
    points : (n, 3) float — mm
    colors : (n, 3) uint8, optional
    normals : (n, 3) float, optional
    scalars : dict of name -> (n,) float, optional — extra float properties
        (e.g. ``deviation_mm``)
    comments : iterable of str — header comment lines
    double : bool — coordinates as ``double`` (else ``float``)
    """
    path = Path(path)
    pts = np.asarray(points, np.float64)
    ft = "<f8" if double else "<f4"
    fields = [("x", ft), ("y", ft), ("z", ft)]
    if normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    if colors is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    for k in (scalars or {}):
        fields.append((k, "<f4"))
    arr = np.empty(len(pts), dtype=fields)
    arr["x"], arr["y"], arr["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if normals is not None:
        arr["nx"], arr["ny"], arr["nz"] = np.asarray(normals).T
    if colors is not None:
        c = np.asarray(colors, np.uint8)
        arr["red"], arr["green"], arr["blue"] = c[:, 0], c[:, 1], c[:, 2]
    for k, v in (scalars or {}).items():
        arr[k] = v
    names = {"<f8": "double", "<f4": "float", "u1": "uchar"}
    header = ["ply", "format binary_little_endian 1.0", *(f"comment {c}" for c in comments),
              f"element vertex {len(pts)}",
              *(f"property {names[t]} {n}" for n, t in fields), "end_header"]
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii", "replace"))
            arr.tofile(fh)

    write_atomic(path, write)
    return path
