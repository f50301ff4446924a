"""PLY (``.ply``): binary little-endian, or ASCII with ``binary=False``.

Vertices are written as doubles (exact round trip) in the cannula frame (+z
along the needle axis towards the tip, heel at z = 0) in mm; every face
carries the property ``label``, and the header has one ``comment label <id>
<name>`` line per entry of ``tip.label_names`` (plus ``comment name``,
``comment units mm`` and the frame). The reader restores those labels; a PLY it
cannot parse directly (polygons, other layouts) is read through trimesh
without labels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..arrays import AnyArray
from ..errors import SpecError
from ..tip import Tip
from .common import FRAME_NOTE, ExportError
from .load import labels_from_ids, read_trimesh
from .registry import ExportOptions, LoadedMesh, register_exporter, register_importer

__all__ = ["read_ply", "write_ply"]

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
    "int64": "i8", "uint64": "u8",
}


# -- writer ------------------------------------------------------------------------------
def write_ply(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as binary little-endian (or, with ``opts.binary`` false,
    ASCII) PLY: double vertices, a face property ``label`` and one
    ``comment label <id> <name>`` line per label name."""
    v, f, lab = tip.vertices, tip.faces, tip.label_ids
    if len(v) > np.iinfo(np.int32).max:
        raise ExportError(f"PLY export: {len(v)} vertices do not fit 32-bit indices")
    fmt = "binary_little_endian" if opts.binary else "ascii"
    lines = ["ply", f"format {fmt} 1.0", "comment tipgeo tip mesh", f"comment name {opts.name}",
             "comment units mm", f"comment {FRAME_NOTE}"]
    lines += [f"comment label {k} {n}" for k, n in enumerate(tip.label_names)]
    lines += [f"element vertex {len(v)}", "property double x", "property double y",
              "property double z", f"element face {len(f)}",
              "property list uchar int vertex_indices", "property int label", "end_header"]
    header = ("\n".join(lines) + "\n").encode("utf-8")
    with open(tmp, "wb") as fh:
        fh.write(header)
        if opts.binary:
            fh.write(v.astype("<f8").tobytes())
            rec = np.empty(len(f), dtype=[("n", "u1"), ("v", "<i4", (3,)), ("label", "<i4")])
            rec["n"] = 3
            rec["v"] = f
            rec["label"] = lab
            fh.write(rec.tobytes())
        else:
            fh.write("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in v.tolist()).encode())
            fh.write("".join(f"3 {a} {b} {c} {k}\n" for (a, b, c), k
                             in zip(f.tolist(), lab.tolist(), strict=True)).encode())


# -- reader ------------------------------------------------------------------------------
class _Unsupported(Exception):
    """The PLY layout is not one the direct reader handles: use trimesh."""


def read_ply(p: Path) -> LoadedMesh:
    """Read a PLY file directly (labels from the face property ``label`` and
    the ``comment label`` lines), or through trimesh for a layout the direct
    reader does not handle (polygons, no vertex/face elements; no labels)."""
    data = p.read_bytes()
    try:
        return _parse_ply(data, str(p))
    except _Unsupported:
        return read_trimesh(p)


#: A PLY property: (name, numpy type) or, for a list, (name, count type, item type).
_Prop = tuple[str, ...]
_Element = tuple[str, int, list[_Prop]]


@dataclass
class _PlyHeader:
    """What a PLY header says: its format, elements, label names (``comment
    label <id> <name>``), mesh name (``comment name``)."""

    fmt: str | None = None
    elements: list[_Element] = field(default_factory=list)
    named: dict[int, str] = field(default_factory=dict)
    name: str | None = None

    def comment(self, line: str, tok: list[str]) -> None:
        rest = line.split(None, 1)[1] if len(tok) > 1 else ""
        parts = rest.split(None, 2)
        if len(parts) == 3 and parts[0] == "label" and parts[1].isdigit():
            self.named[int(parts[1])] = parts[2].strip()
        elif len(parts) >= 2 and parts[0] == "name":
            self.name = rest.split(None, 1)[1].strip()

    def prop(self, tok: list[str], where: str) -> None:
        if not self.elements:
            raise SpecError(f"path '{where}': PLY property before any element")
        if tok[1] == "list":
            self.elements[-1][2].append((tok[4], _PLY_TYPES[tok[2]], _PLY_TYPES[tok[3]]))
        else:
            self.elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))

    def line(self, line: str, where: str) -> None:
        tok = line.split()
        if not tok:
            return
        if tok[0] == "format":
            self.fmt = tok[1]
        elif tok[0] == "comment":
            self.comment(line, tok)
        elif tok[0] == "element":
            self.elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            self.prop(tok, where)


_BYTE_ORDERS = {"binary_little_endian": "<", "binary_big_endian": ">"}


def _parse_ply(data: bytes, where: str) -> LoadedMesh:
    if not data.startswith(b"ply"):
        raise SpecError(f"path '{where}' is not a PLY file (it does not start with 'ply')")
    end = data.find(b"end_header")
    if end < 0:
        raise SpecError(f"path '{where}': PLY header has no 'end_header' line")
    body = data.index(b"\n", end) + 1
    h = _PlyHeader()
    for line in data[:end].decode("utf-8", "replace").splitlines()[1:]:
        h.line(line, where)
    if h.fmt == "ascii":
        arrays = _ply_ascii(data[body:], h.elements)
    elif h.fmt in _BYTE_ORDERS:
        arrays = _ply_binary(data, body, h.elements, _BYTE_ORDERS[h.fmt])
    else:
        raise SpecError(f"path '{where}': PLY format {h.fmt!r} unknown; expected ascii, "
                        f"binary_little_endian or binary_big_endian")
    return _ply_mesh(arrays, h, where)


def _ply_mesh(arrays: dict[str, AnyArray], h: _PlyHeader, where: str) -> LoadedMesh:
    """The triangle mesh (and labels) of a PLY's vertex and face elements;
    :class:`_Unsupported` for another layout."""
    if "vertex" not in arrays or "face" not in arrays:
        raise _Unsupported
    vert, face = arrays["vertex"], arrays["face"]
    if not {"x", "y", "z"} <= set(vert.dtype.names or ()):
        raise _Unsupported
    names = face.dtype.names or ()
    lists = [n for n in names if n in ("vertex_indices", "vertex_index")]
    if not lists or face[lists[0]].shape[1:] != (3,):
        raise _Unsupported  # polygons: let trimesh triangulate (labels are then dropped)
    v = np.column_stack([vert["x"], vert["y"], vert["z"]]).astype(np.float64)
    f = face[lists[0]].astype(np.int64)
    mesh = LoadedMesh(v, f, name=h.name)
    if "label" in names:
        mesh.label_ids, mesh.label_names = labels_from_ids(face["label"], h.named, len(f),
                                                           f"path '{where}'")
    return mesh


def _ply_binary(data: bytes, pos: int, elements: list[_Element],
                bo: str) -> dict[str, AnyArray]:
    out = {}
    for ename, count, props in elements:
        # list properties must hold the same count in every row (triangles)
        dtype = []
        first = pos
        for prop in props:
            if len(prop) == 3:
                cnt_t = np.dtype(bo + prop[1])
                if count == 0:
                    raise _Unsupported
                k = int(np.frombuffer(data, cnt_t, 1, first)[0])
                dtype += [(prop[0] + "__n", cnt_t), (prop[0], bo + prop[2], (k,))]
                first += cnt_t.itemsize + k * np.dtype(prop[2]).itemsize
            else:
                dtype.append((prop[0], bo + prop[1]))
                first += np.dtype(prop[1]).itemsize
        dt = np.dtype(dtype)
        if pos + dt.itemsize * count > len(data):
            raise SpecError(f"PLY element '{ename}' is truncated: {count} rows of "
                            f"{dt.itemsize} bytes do not fit the file")
        arr = np.frombuffer(data, dt, count, pos)
        for prop in props:
            if len(prop) == 3 and np.any(arr[prop[0] + "__n"] != arr[prop[0]].shape[1]):
                raise _Unsupported
        out[ename] = arr
        pos += dt.itemsize * count
    return out


def _ply_ascii(body: bytes, elements: list[_Element]) -> dict[str, AnyArray]:
    lines = body.decode("ascii", "replace").splitlines()
    out: dict[str, AnyArray] = {}
    row = 0
    for ename, count, props in elements:
        rows = [ln.split() for ln in lines[row:row + count]]
        row += count
        if len(rows) != count:
            raise SpecError(f"PLY element '{ename}' is truncated: {len(rows)} of {count} rows")
        widths = {len(r) for r in rows}
        if len(widths) > 1:
            raise _Unsupported
        dtype, col, cols = [], 0, []
        for prop in props:
            if len(prop) == 3:
                k = int(rows[0][col]) if rows else 0
                dtype += [(prop[0] + "__n", "<i8"), (prop[0], "<f8", (k,))]
                cols.append((prop[0] + "__n", col, 1))
                cols.append((prop[0], col + 1, k))
                col += 1 + k
            else:
                dtype.append((prop[0], "<f8"))
                cols.append((prop[0], col, 1))
                col += 1
        table = np.array(rows, dtype=np.float64).reshape(count, -1)
        if table.shape[1] != col:
            raise _Unsupported
        arr = np.zeros(count, dtype=dtype)
        for fname, c, k in cols:
            arr[fname] = table[:, c] if arr[fname].ndim == 1 else table[:, c:c + k]
        for prop in props:
            if len(prop) == 3 and np.any(arr[prop[0] + "__n"] != arr[prop[0]].shape[1]):
                raise _Unsupported
        out[ename] = arr
    return out


register_exporter(".ply", write_ply)
register_importer(".ply", read_ply)
