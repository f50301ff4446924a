"""Abaqus input (``.inp``): a rigid part of ``R3D3`` elements.

Nodes in mm and the cannula frame (+z along the needle axis towards the tip,
heel at z = 0), as fixed-point numbers with 12 decimals. The part follows
Abaqus conventions (``*Part``, ``R3D3``, ``*Rigid Body``): one ``*Elset`` per
label present (``cut:multiplane.0`` becomes ``CUT_MULTIPLANE_0``) plus ``ALL``;
the reference node is node ``n + 1``, in node set ``RefPt``, placed by
``ref_point``. Element normals follow the outward triangle orientation.
CalculiX has no ``R3D3`` element and no ``*Part``, so the file is for Abaqus.
Export only.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..tip import Tip
from ..tolerances import tol
from .common import FRAME_NOTE
from .registry import ExportOptions, register_exporter

__all__ = ["abaqus_name", "elset_names", "ref_point", "write_inp"]


def abaqus_name(label: str) -> str:
    """``label`` as an Abaqus name: upper case, ``_`` for other characters,
    starting with a letter, at most 80 characters."""
    s = re.sub(r"_+", "_", re.sub(r"[^A-Z0-9]", "_", label.upper())).strip("_")
    if not s or not s[0].isalpha():
        s = "L_" + s
    return s[:80]


def elset_names(labels: Sequence[str]) -> list[str]:
    """One unique Abaqus element-set name per label (never ``ALL``)."""
    used = {"ALL"}
    out = []
    for n in labels:
        base = abaqus_name(n)
        s, k = base, 2
        while s in used:
            s = f"{base[:76]}_{k}"
            k += 1
        used.add(s)
        out.append(s)
    return out


def ref_point(tip: Tip, ref: str | tuple[float, float, float]) -> tuple[float, float, float]:
    """The reference node (mm, cannula frame) for a checked ``ref_point``:
    the point itself, ``(0, 0, z_max)`` for ``'top'``, or ``(0, 0, z_c)``
    with z_c the volume centroid height (area centroid for an open mesh)."""
    if not isinstance(ref, str):
        return ref
    z_max = float(tip.vertices[:, 2].max())
    if ref == "top":
        return (0.0, 0.0, z_max)
    # volume centroid (signed tetrahedra from the mean vertex), projected on the axis
    o = tip.vertices.mean(axis=0)
    t = tip.triangles - o
    vol6 = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    if abs(vol6.sum()) > tol.tiny:
        zc = float((vol6 * t[:, :, 2].sum(axis=1)).sum() / (4.0 * vol6.sum()) + o[2])
    else:  # not a closed solid: area centroid
        a = tip.face_areas
        zc = float((a * tip.triangles[:, :, 2].mean(axis=1)).sum() / max(a.sum(), tol.tiny))
    return (0.0, 0.0, zc)


def write_inp(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as an Abaqus input file: a rigid ``*Part`` of ``R3D3``
    elements, one ``*Elset`` per label present plus ``ALL``, and the
    reference node ``n + 1`` in node set ``RefPt``."""
    v, f, lab = tip.vertices, tip.faces + 1, tip.label_ids
    n, m = len(v), len(f)
    part = abaqus_name(opts.name) if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,79}",
                                                       opts.name) else opts.name
    present = [k for k in range(len(tip.label_names)) if np.any(lab == k)]
    elsets = elset_names([tip.label_names[k] for k in present])
    rx, ry, rz = ref_point(tip, opts.ref_point)
    ref_id = n + 1

    def id_lines(ids: np.ndarray) -> str:
        if len(ids) and ids[-1] - ids[0] + 1 == len(ids):  # contiguous: generate
            return f", generate\n{ids[0]}, {ids[-1]}, 1\n"
        rows = [", ".join(map(str, ids[i:i + 16].tolist())) for i in range(0, len(ids), 16)]
        return "\n" + "\n".join(rows) + "\n"

    with open(tmp, "w", encoding="ascii", errors="replace", newline="\n") as fh:
        fh.write(f"*Heading\n{opts.name}: rigid needle tip (tipgeo); units mm; {FRAME_NOTE}\n"
                 f"** {n} nodes + 1 reference node, {m} R3D3 elements (normals outward)\n"
                 f"** element sets: {', '.join(elsets)}, ALL\n"
                 f"*Part, name={part}\n*Node\n")
        fh.write("".join(f"{i}, {x:.12f}, {y:.12f}, {z:.12f}\n"
                         for i, (x, y, z) in enumerate(v.tolist(), 1)))
        fh.write("*Element, type=R3D3\n")
        fh.write("".join(f"{i}, {a}, {b}, {c}\n" for i, (a, b, c) in enumerate(f.tolist(), 1)))
        for k, es in zip(present, elsets, strict=True):
            fh.write(f"** label '{tip.label_names[k]}'\n*Elset, elset={es}")
            fh.write(id_lines(np.flatnonzero(lab == k) + 1))
        fh.write(f"*Elset, elset=ALL, generate\n1, {m}, 1\n")
        fh.write(f"** reference node\n*Node\n{ref_id}, {rx:.12f}, {ry:.12f}, {rz:.12f}\n"
                 f"*Nset, nset=RefPt\n{ref_id}\n"
                 f"*Rigid Body, ref node=RefPt, elset=ALL\n*End Part\n")


register_exporter(".inp", write_inp)
