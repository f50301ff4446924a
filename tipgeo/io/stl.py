"""STL (``.stl``): binary (float32), or ASCII with ``binary=False``.

Written in the cannula frame (+z along the needle axis towards the tip, heel at
z = 0) in mm, one record per triangle with its face normal; no labels. Binary
files are read directly with numpy (no trimesh import: scan inspection starts
fast), ASCII ones through trimesh (:func:`~tipgeo.io.load.read_trimesh`);
either way bit-identical vertices are merged, in the order of first use.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..tip import Tip
from .common import FRAME_NOTE
from .load import read_trimesh
from .registry import ExportOptions, LoadedMesh, register_exporter, register_importer

__all__ = ["read_stl", "write_stl"]


def write_stl(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as binary STL (float32, 80-byte header naming the object,
    the units and the frame) or, with ``opts.binary`` false, ASCII STL."""
    tri = tip.triangles
    normals = tip.face_normals
    if opts.binary:
        header = f"tipgeo {opts.name}; units mm; {FRAME_NOTE}".encode("ascii", "replace")[:80]
        rec = np.zeros(len(tri), dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)),
                                        ("attr", "<u2")])
        rec["n"] = normals
        rec["v"] = tri
        with open(tmp, "wb") as f:
            f.write(header.ljust(80, b" "))
            f.write(np.uint32(len(tri)).astype("<u4").tobytes())
            f.write(rec.tobytes())
        return
    name = re.sub(r"\s+", "_", opts.name)
    with open(tmp, "w", encoding="ascii", errors="replace", newline="\n") as f:
        f.write(f"solid {name}\n")
        for nrm, (a, b, c) in zip(normals.tolist(), tri.tolist(), strict=True):
            f.write(f"facet normal {nrm[0]!r} {nrm[1]!r} {nrm[2]!r}\n outer loop\n"
                    f"  vertex {a[0]!r} {a[1]!r} {a[2]!r}\n  vertex {b[0]!r} {b[1]!r} {b[2]!r}\n"
                    f"  vertex {c[0]!r} {c[1]!r} {c[2]!r}\n endloop\nendfacet\n")
        f.write(f"endsolid {name}\n")


register_exporter(".stl", write_stl)
def read_stl(p: Path) -> LoadedMesh:
    """Read an STL file: a binary one (its size is 84 + 50 × the triangle
    count of its header) with numpy, float32 vertices widened to float64 and
    merged where bit-identical (order of first use); any other through
    trimesh."""
    size = p.stat().st_size
    with open(p, "rb") as fh:
        head = fh.read(84)
        n = int(np.frombuffer(head[80:84], "<u4")[0]) if len(head) == 84 else -1
        if n < 0 or size != 84 + 50 * n:
            return read_trimesh(p)
        rec = np.fromfile(fh, dtype=[("n", "<f4", (3,)), ("v", "<f4", (3, 3)),
                                     ("attr", "<u2")], count=n)
    v = rec["v"].reshape(-1, 3).astype(np.float64)
    uniq, first, inv = np.unique(v, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    return LoadedMesh(uniq[order], rank[inv.reshape(-1)].reshape(-1, 3))


register_importer(".stl", read_stl)
