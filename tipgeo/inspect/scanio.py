"""Reading and writing scans (point clouds and meshes).

Units: coordinates are scaled to mm on reading (``units``: ``mm``, ``um``,
``m``); the frame is whatever the scanner used (registration finds the
cannula frame).

Formats: PLY (point cloud or mesh), PCD, XYZ/TXT/PTS/XYZN (through open3d),
STL and OBJ (through trimesh; their vertices are the measured points). Errors
for missing, empty, unreadable or non-finite input are :class:`ScanError`
and name the file and the problem.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import TipGeoError

__all__ = ["Scan", "ScanError", "load_scan", "write_ply", "SCAN_FORMATS", "UNITS"]

#: Length units accepted for scan files, and their size in mm.
UNITS: dict[str, float] = {"mm": 1.0, "um": 1.0e-3, "µm": 1.0e-3, "m": 1.0e3}

#: Scan file extensions (lower case).
SCAN_FORMATS: tuple[str, ...] = (".ply", ".pcd", ".xyz", ".xyzn", ".txt", ".pts", ".stl",
                                 ".obj")


class ScanError(TipGeoError, ValueError):
    """A scan file or point array is missing, empty, unreadable or non-finite."""


@dataclass
class Scan:
    """A measured point cloud.

    Attributes
    ----------
    points : (n, 3) float — mm, scanner frame
    normals : (n, 3) float or None — unit normals from the file, if any
    source : str — file name or description
    meta : dict — format, file units, point count as read
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    source: str = "array"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        self.points = check_points(self.points, self.source)
        if self.normals is not None:
            n = np.asarray(self.normals, dtype=np.float64).reshape(-1, 3)
            if len(n) != len(self.points) or not np.all(np.isfinite(n)):
                n = None
            self.normals = n

    def __len__(self) -> int:
        return len(self.points)


def check_points(points, where: str = "points") -> np.ndarray:
    """Return ``points`` as a finite (n ≥ 1, 3) float64 array, else ScanError."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ScanError(f"{where}: not numeric point coordinates ({e})") from None
    if p.ndim != 2 or p.shape[1] != 3:
        raise ScanError(f"{where}: points have shape {p.shape}; expected (n, 3)")
    if len(p) == 0:
        raise ScanError(f"{where}: the scan is empty (0 points)")
    bad = ~np.all(np.isfinite(p), axis=1)
    if bad.any():
        raise ScanError(f"{where}: {int(bad.sum())} of {len(p)} points have non-finite "
                        "(NaN or infinite) coordinates")
    return np.ascontiguousarray(p)


def load_scan(path: str | os.PathLike[str], *, units: str = "mm") -> Scan:
    """Read a scan file.

    Parameters
    ----------
    path : str or PathLike
        ``.ply .pcd .xyz .xyzn .txt .pts .stl .obj`` (case-insensitive).
    units : {'mm', 'um', 'm'}
        Length unit of the file's coordinates; they are scaled to mm.

    Returns
    -------
    Scan

    Raises
    ------
    ScanError
        Unknown extension or units; missing, empty or unreadable file; no
        points; non-finite coordinates.
    """
    if units not in UNITS:
        raise ScanError(f"units = {units!r} is not supported; allowed: mm, um, m")
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in SCAN_FORMATS:
        raise ScanError(f"scan '{p}' has extension '{p.suffix}'; allowed: "
                        + ", ".join(SCAN_FORMATS))
    if not p.exists():
        raise ScanError(f"scan '{p}' does not exist")
    if not p.is_file():
        raise ScanError(f"scan '{p}' is not a regular file")
    if p.stat().st_size == 0:
        raise ScanError(f"scan '{p}' is empty (0 bytes)")
    try:
        if ext in (".stl", ".obj"):
            pts, nrm = _read_trimesh(p)
        elif ext == ".ply":
            pts, nrm = _read_ply_fast(p)
            if pts is None:
                pts, nrm = _read_open3d(p, ext)
        else:
            pts, nrm = _read_open3d(p, ext)
    except ScanError:
        raise
    except Exception as e:  # any reader failure is a bad file
        raise ScanError(f"scan '{p}' could not be read as {ext}: {type(e).__name__}: {e}") \
            from None
    if pts is None or len(pts) == 0:
        raise ScanError(f"scan '{p}' holds no points")
    pts = check_points(pts, f"scan '{p}'") * UNITS[units]
    return Scan(pts, nrm, source=p.name, meta={"path": str(p), "format": ext[1:],
                                                "file_units": units, "points": len(pts)})


def _read_open3d(p: Path, ext: str):
    from .._open3d import import_open3d

    o3d = import_open3d()
    fmt = {".txt": "xyz", ".pts": "pts"}.get(ext, "auto")
    pc = o3d.io.read_point_cloud(str(p), format=fmt, print_progress=False)
    pts = np.asarray(pc.points, dtype=np.float64)
    if len(pts) == 0 and ext in (".txt", ".xyz"):
        pts = _read_text(p)
        return pts, None
    nrm = np.asarray(pc.normals, dtype=np.float64) if pc.has_normals() else None
    return pts, nrm


def _read_text(p: Path) -> np.ndarray:
    try:
        a = np.loadtxt(p, comments=("#", "//"), delimiter=None, ndmin=2,
                       usecols=(0, 1, 2), dtype=np.float64)
    except ValueError:
        a = np.loadtxt(p, comments=("#", "//"), delimiter=",", ndmin=2, usecols=(0, 1, 2),
                       dtype=np.float64)
    return a


def _read_trimesh(p: Path):
    import trimesh

    g = trimesh.load(str(p), process=False, force=None)
    if isinstance(g, trimesh.Scene):
        geoms = list(g.geometry.values())
        if not geoms:
            return np.zeros((0, 3)), None
        pts = np.concatenate([np.asarray(x.vertices) for x in geoms])
        return pts, None
    pts = np.asarray(g.vertices, dtype=np.float64)
    nrm = None
    if isinstance(g, trimesh.Trimesh) and len(g.faces):
        pts, inv = np.unique(pts, axis=0, return_inverse=True)  # STL repeats corners
        del inv
    return pts, nrm


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def _read_ply_fast(p: Path):
    """Binary PLY whose first element is 'vertex' with scalar properties:
    read straight into numpy (double precision kept). Returns (None, None)
    for anything else (open3d reads those)."""
    with open(p, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ScanError(f"scan '{p}' is not a PLY file (no 'ply' magic or no end_header)")
    nl = head.find(b"\n", end)
    lines = head[:end].decode("ascii", "replace").splitlines()
    fmt = next((ln.split()[1] for ln in lines if ln.startswith("format")), "")
    if fmt not in ("binary_little_endian", "binary_big_endian"):
        return None, None
    bo = "<" if fmt == "binary_little_endian" else ">"
    elements: list[tuple[str, int, list]] = []
    for ln in lines:
        t = ln.split()
        if not t:
            continue
        if t[0] == "element":
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            if t[1] == "list" or t[1] not in _PLY_TYPES:
                if elements[-1][0] == "vertex":
                    return None, None
                continue
            elements[-1][2].append((t[2], bo + _PLY_TYPES[t[1]]))
    if not elements or elements[0][0] != "vertex":
        return None, None
    _, n, props = elements[0]
    dt = np.dtype(props)
    data = np.fromfile(p, dtype=dt, count=n, offset=nl + 1)
    if len(data) < n:
        raise ScanError(f"scan '{p}' is truncated: {len(data)} of {n} vertices")
    names = dt.names
    if not {"x", "y", "z"} <= set(names):
        raise ScanError(f"scan '{p}': the vertex element has no x, y, z properties")
    pts = np.stack([data["x"], data["y"], data["z"]], 1).astype(np.float64)
    nrm = None
    if {"nx", "ny", "nz"} <= set(names):
        nrm = np.stack([data["nx"], data["ny"], data["nz"]], 1).astype(np.float64)
    return pts, nrm


def write_ply(path: str | os.PathLike[str], points: np.ndarray, *,
              colors: np.ndarray | None = None, normals: np.ndarray | None = None,
              scalars: dict[str, np.ndarray] | None = None, comments=(),
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
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".",
                               prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii", "replace"))
            arr.tofile(fh)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
