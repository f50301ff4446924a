"""STL (``.stl``): binary (float32), or ASCII with ``binary=False``.

Written in the cannula frame (+z along the needle axis towards the tip, heel at
z = 0) in mm, one record per triangle with its face normal; no labels. Read
through trimesh (:func:`~tipgeo.io.load.read_trimesh`), bit-identical vertices
merged.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..tip import Tip
from .common import FRAME_NOTE
from .load import read_trimesh
from .registry import ExportOptions, register_exporter, register_importer

__all__ = ["write_stl"]


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
register_importer(".stl", read_trimesh)
