"""Abaqus/CalculiX input (``.inp``): the tip as a rigid body of ``S3``
shell elements, in the flat keyword layout both solvers read.

Nodes in mm and the cannula frame (+z along the needle axis towards the tip,
heel at z = 0), as fixed-point numbers with 12 decimals. One ``*ELSET`` per
label present (``cut:multiplane.0`` becomes ``CUT_MULTIPLANE_0``) plus
``ALL``; the reference node is node ``n + 1``, in node set ``RefPt``, placed
by ``ref_point``; node ``n + 2`` at the same point (set ``RotPt``) carries
the rotations in CalculiX (its displacements are the rotation angles, rad);
all mesh nodes form node set ``TIP``, and ``*RIGID BODY, NSET=TIP, REF
NODE=n + 1, ROT NODE=n + 2`` makes the shells rigid (a thin ``*SHELL SECTION``
of material ``TIPGEO_RIGID`` gives them the section a solver requires).
Element normals follow the outward triangle orientation.

CalculiX 2.20 has neither ``R3D3`` nor ``*PART`` (it stops at the former and
ignores the latter with a warning) and aborts on ``*RIGID BODY, ELSET=`` over
shells, so the file uses none of them and a CalculiX model ``*INCLUDE``s it
as it is. Abaqus names the rigid body by element set: a comment line just
above gives the ``*RIGID BODY, REF NODE=n + 1, ELSET=ALL`` to put in its
place. Export only.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..arrays import IntArray
from ..tip import Tip
from ..tolerances import tol
from .common import FRAME_NOTE
from .registry import ExportOptions, register_exporter

__all__ = ["abaqus_name", "elset_names", "ref_point", "write_inp", "RIGID_MATERIAL",
           "SHELL_THICKNESS"]

#: Material of the rigid shells (steel; a rigid body ignores it).
RIGID_MATERIAL = "TIPGEO_RIGID"

#: Section thickness of the rigid shells, mm (a rigid body ignores it).
SHELL_THICKNESS = 0.01


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
    """Write ``tip`` as an input file for Abaqus and CalculiX: a rigid body of
    ``S3`` elements, one ``*ELSET`` per label present plus ``ALL``, and the
    reference node ``n + 1`` in node set ``RefPt``."""
    v, f, lab = tip.vertices, tip.faces + 1, tip.label_ids
    n, m = len(v), len(f)
    part = abaqus_name(opts.name) if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,79}",
                                                       opts.name) else opts.name
    present = [k for k in range(len(tip.label_names)) if np.any(lab == k)]
    elsets = elset_names([tip.label_names[k] for k in present])
    rx, ry, rz = ref_point(tip, opts.ref_point)
    ref_id = n + 1

    def id_lines(ids: IntArray) -> str:
        if len(ids) and ids[-1] - ids[0] + 1 == len(ids):  # contiguous: generate
            return f", GENERATE\n{ids[0]}, {ids[-1]}, 1\n"
        rows = [", ".join(map(str, ids[i:i + 16].tolist())) for i in range(0, len(ids), 16)]
        return "\n" + "\n".join(rows) + "\n"

    with open(tmp, "w", encoding="ascii", errors="replace", newline="\n") as fh:
        fh.write(f"*HEADING\n{opts.name}: rigid needle tip (tipgeo); units mm; {FRAME_NOTE}\n"
                 f"** part {part}: {n} nodes + reference and rotation nodes, {m} S3 elements "
                 "(normals outward), rigid\n"
                 f"** element sets: {', '.join(elsets)}, ALL\n*NODE\n")
        fh.write("".join(f"{i}, {x:.12f}, {y:.12f}, {z:.12f}\n"
                         for i, (x, y, z) in enumerate(v.tolist(), 1)))
        fh.write("*ELEMENT, TYPE=S3\n")
        fh.write("".join(f"{i}, {a}, {b}, {c}\n" for i, (a, b, c) in enumerate(f.tolist(), 1)))
        for k, es in zip(present, elsets, strict=True):
            fh.write(f"** label '{tip.label_names[k]}'\n*ELSET, ELSET={es}")
            fh.write(id_lines(np.flatnonzero(lab == k) + 1))
        fh.write(f"*ELSET, ELSET=ALL, GENERATE\n1, {m}, 1\n")
        fh.write(f"*NSET, NSET=TIP, GENERATE\n1, {n}, 1\n")
        fh.write(f"** reference node (translations) and CalculiX's rotation node\n*NODE\n"
                 f"{ref_id}, {rx:.12f}, {ry:.12f}, {rz:.12f}\n"
                 f"{ref_id + 1}, {rx:.12f}, {ry:.12f}, {rz:.12f}\n"
                 f"*NSET, NSET=RefPt\n{ref_id}\n*NSET, NSET=RotPt\n{ref_id + 1}\n"
                 f"*MATERIAL, NAME={RIGID_MATERIAL}\n*ELASTIC\n210000.0, 0.3\n"
                 f"*SHELL SECTION, ELSET=ALL, MATERIAL={RIGID_MATERIAL}\n"
                 f"{SHELL_THICKNESS:.6f}\n"
                 f"** Abaqus: replace the next line by *RIGID BODY, REF NODE={ref_id}, "
                 "ELSET=ALL\n"
                 f"*RIGID BODY, NSET=TIP, REF NODE={ref_id}, ROT NODE={ref_id + 1}\n")


register_exporter(".inp", write_inp)
