"""Writing tips to files and reading meshes back.

Formats (chosen by the file extension, case-insensitive):

=========  ================================================================
``.stl``   binary STL (float32), or ASCII with ``binary=False``
``.ply``   binary little-endian PLY (double vertices, per-face ``label``
           property, label names as ``comment label <id> <name>``), or
           ASCII with ``binary=False``
``.obj``   Wavefront OBJ, one group per label, full double precision
``.3mf``   3MF (through trimesh; unit ``millimeter``)
``.glb``   binary glTF 2.0 (through trimesh; float32; labels in ``extras``)
``.step``  STEP AP214 solid (B-rep), one planar face per triangle (needs
``.stp``   ``OCP``: ``pip install "tipgeo[step]"``)
``.inp``   Abaqus input: a rigid part of ``R3D3`` elements with one element
           set per label and a reference node
=========  ================================================================

Frame and units: every file is written in the cannula frame (+z along the
needle axis towards the tip, heel at z = 0, γ about +z from +x) with lengths in
mm, whatever the format's own convention (glTF nominally uses metres and +y up;
a GLB written here holds mm and +z along the needle).

Every export is atomic: the data go to a temporary file in the target
directory, which is flushed to disk and then renamed over ``path``. A failure
leaves neither a partial file nor a temporary file behind, and leaves a file
already at ``path`` untouched.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from numbers import Real
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from ._atomic import write_atomic
from .errors import BuildError, SpecError, TipGeoError
from .tip import Tip

__all__ = [
    "SUPPORTED_EXPORTS",
    "SUPPORTED_IMPORTS",
    "UNITS",
    "UNLABELLED",
    "ExportError",
    "export_tip",
    "load_tip",
]

#: File extensions :func:`export_tip` writes.
SUPPORTED_EXPORTS: tuple[str, ...] = (".stl", ".ply", ".obj", ".3mf", ".glb", ".step", ".stp",
                                      ".inp")
#: File extensions :func:`load_tip` reads.
SUPPORTED_IMPORTS: tuple[str, ...] = (".stl", ".ply", ".obj", ".3mf", ".glb")
#: Length units :func:`load_tip` accepts, with their size in mm.
UNITS: dict[str, float] = {"mm": 1.0, "um": 1.0e-3, "m": 1.0e3}
#: The label of every triangle of a file that carries no labels.
UNLABELLED = "unlabelled"

_FRAME_NOTE = "cannula frame: +z along the needle axis towards the tip, heel at z = 0"
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
    "int64": "i8", "uint64": "u8",
}


class ExportError(BuildError):
    """Writing a tip to a file failed (I/O error, missing optional package,
    a mesh the format cannot represent). Nothing was written."""


@dataclass(frozen=True)
class _Options:
    binary: bool
    name: str
    ref_point: str | tuple[float, float, float]


# ---------------------------------------------------------------------------
# export
# ---------------------------------------------------------------------------
def export_tip(tip: Tip, path: str | os.PathLike[str], *, binary: bool = True,
               name: str | None = None,
               ref_point: str | Sequence[float] = "centroid") -> Path:
    """Write a tip to a mesh, CAD or FE file, atomically.

    The format follows the extension of ``path`` (case-insensitive, one of
    :data:`SUPPORTED_EXPORTS`). Coordinates are written in the cannula frame
    (+z along the needle axis towards the tip, heel at z = 0) in mm.

    Parameters
    ----------
    tip : Tip
        The tip to write (vertices in mm, cannula frame).
    path : str or os.PathLike
        Target file. Its directory must exist (none is created). A file
        already there is replaced only once the new one is complete.
    binary : bool, default True
        STL and PLY only: write the binary (default) or the ASCII variant.
        The other formats have one encoding and ignore it.
    name : str, optional
        Object, solid or part name written into the file (STL header, PLY and
        OBJ comments, 3MF/GLB object, STEP product, INP ``*Part``). Default:
        the spec name, else ``tip.meta['name']``, else the file stem.
    ref_point : {'centroid', 'top'} or sequence of 3 floats, default 'centroid'
        INP only: the reference node of the rigid body (mm, cannula frame).
        ``'centroid'`` puts it on the needle axis at the height of the volume
        centroid, ``(0, 0, z_c)``; ``'top'`` at the tip top ``(0, 0, z_max)``;
        three numbers give the point itself.

    Returns
    -------
    pathlib.Path
        ``path`` as a ``Path``.

    Raises
    ------
    SpecError
        ``tip`` is not a non-empty finite ``Tip``; the extension is not
        supported; the parent directory does not exist; ``path`` is a
        directory; ``binary``, ``name`` or ``ref_point`` is invalid; a label
        name contains a line break.
    ExportError
        Writing failed (disk error, missing ``OCP`` for STEP, a mesh that is
        not closed for STEP). Subclass of :class:`~tipgeo.errors.BuildError`.
        No partial file is left behind.

    Notes
    -----
    Precision: PLY and OBJ keep every double exactly; 3MF is written as
    shortest round-trip decimals (exact with current trimesh); STL and GLB
    store float32 (about 1e-6 mm at 10 mm); INP uses fixed-point numbers with
    12 decimals (5e-13 mm); STEP stores doubles.

    Labels: PLY keeps them as the face property ``label`` plus one
    ``comment label <id> <name>`` header line per entry of
    ``tip.label_names``; OBJ starts a group (``g outer``, ``g cut:bevel``)
    wherever the label changes along the face list, so the face order is kept
    (``# label <id> <name>`` comments hold the exact names); GLB keeps them in
    the mesh ``extras`` (``tipgeo.label_names`` and run-length
    ``tipgeo.label_runs``); INP has one ``*Elset`` per label present
    (``cut:multiplane.0`` becomes ``CUT_MULTIPLANE_0``) plus ``ALL``. STL, 3MF
    and STEP carry no labels.

    INP: the part follows Abaqus conventions (``*Part``, ``R3D3``, ``*Rigid
    Body``); the reference node is node ``n + 1``, in node set ``RefPt``.
    Element normals follow the outward triangle orientation. CalculiX has no
    ``R3D3`` element and no ``*Part``, so the file is for Abaqus.
    """
    _check_tip(tip)
    p = _as_path(path)
    ext = p.suffix.lower()
    if ext not in _WRITERS:
        raise SpecError(f"path '{p}' has extension '{p.suffix}'; allowed: "
                        f"{', '.join(SUPPORTED_EXPORTS)}")
    parent = p.parent
    if not parent.is_dir():
        raise SpecError(f"path '{p}': parent directory '{parent}' does not exist or is not a "
                        f"directory; create it first (export_tip creates no directories)")
    if p.is_dir():
        raise SpecError(f"path '{p}' is a directory; expected a file path ending in "
                        f"{', '.join(SUPPORTED_EXPORTS)}")
    if not isinstance(binary, bool):
        raise SpecError(f"binary = {binary!r} is not a bool; expected True or False")
    opts = _Options(binary=binary, name=_object_name(tip, p, name),
                    ref_point=_check_ref_point(ref_point))
    writer = _WRITERS[ext]
    try:
        write_atomic(p, lambda tmp: writer(tip, tmp, opts))
    except TipGeoError:
        raise
    except Exception as exc:
        raise ExportError(f"writing {ext} file '{p}' failed: {type(exc).__name__}: {exc}; "
                          f"nothing was written") from exc
    return p


def _as_path(path: object) -> Path:
    if isinstance(path, (str, os.PathLike)) and not isinstance(path, bytes):
        p = Path(path)
        if str(p) not in ("", "."):
            return p
    raise SpecError(f"path = {path!r} is not a file path; expected a str or os.PathLike "
                    f"naming a file")


def _check_tip(tip: object) -> None:
    if not isinstance(tip, Tip):
        raise SpecError(f"tip = {type(tip).__name__} is not a Tip")
    v, f, lab = tip.vertices, tip.faces, tip.label_ids
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise SpecError(f"tip has vertices of shape {v.shape} and faces of shape {f.shape}; "
                        f"expected (n, 3) and (m, 3) with m ≥ 1")
    if not np.all(np.isfinite(v)):
        raise SpecError("tip.vertices contain NaN or infinite values; expected finite mm")
    if f.min() < 0 or f.max() >= len(v):
        raise SpecError(f"tip.faces index vertices {int(f.min())}…{int(f.max())}; allowed "
                        f"0…{len(v) - 1}")
    if lab.shape != (len(f),) or (len(lab) and (lab.min() < 0 or
                                                lab.max() >= len(tip.label_names))):
        raise SpecError(f"tip.label_ids must have shape ({len(f)},) with values in "
                        f"0…{len(tip.label_names) - 1}")
    for n in tip.label_names:
        if not isinstance(n, str) or not n or "\n" in n or "\r" in n:
            raise SpecError(f"label name {n!r} is invalid; expected a non-empty str without "
                            f"line breaks")


def _object_name(tip: Tip, p: Path, name: object) -> str:
    if name is None:
        name = (getattr(tip.spec, "name", "") or tip.meta.get("name") or p.stem or "tip")
    if not isinstance(name, str) or not name.strip() or "\n" in name or "\r" in name:
        raise SpecError(f"name = {name!r} is invalid; expected a non-empty str without line "
                        f"breaks")
    return name.strip()


def _check_ref_point(ref: object) -> str | tuple[float, float, float]:
    if isinstance(ref, str):
        if ref in ("centroid", "top"):
            return ref
    else:
        try:
            vals = tuple(ref)  # type: ignore[arg-type]
        except TypeError:
            vals = ()
        if (len(vals) == 3 and all(isinstance(x, Real) and not isinstance(x, bool)
                                   and math.isfinite(float(x)) for x in vals)):
            return (float(vals[0]), float(vals[1]), float(vals[2]))
    raise SpecError(f"ref_point = {ref!r} is invalid; allowed: 'centroid', 'top' or three finite "
                    f"numbers (x, y, z) in mm")


# -- STL ---------------------------------------------------------------------
def _write_stl(tip: Tip, tmp: Path, opts: _Options) -> None:
    tri = tip.triangles
    normals = tip.face_normals
    if opts.binary:
        header = f"tipgeo {opts.name}; units mm; {_FRAME_NOTE}".encode("ascii", "replace")[:80]
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


# -- PLY ---------------------------------------------------------------------
def _write_ply(tip: Tip, tmp: Path, opts: _Options) -> None:
    v, f, lab = tip.vertices, tip.faces, tip.label_ids
    if len(v) > np.iinfo(np.int32).max:
        raise ExportError(f"PLY export: {len(v)} vertices do not fit 32-bit indices")
    fmt = "binary_little_endian" if opts.binary else "ascii"
    lines = ["ply", f"format {fmt} 1.0", "comment tipgeo tip mesh", f"comment name {opts.name}",
             "comment units mm", f"comment {_FRAME_NOTE}"]
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


# -- OBJ ---------------------------------------------------------------------
_OBJ_MAGIC = "# tipgeo OBJ"


def _obj_group_names(names: Sequence[str]) -> list[str]:
    """One whitespace-free, unique group token per label."""
    out: list[str] = []
    for k, n in enumerate(names):
        g = re.sub(r"\s+", "_", n)
        out.append(g if g not in out else f"{g}~{k}")
    return out


def _write_obj(tip: Tip, tmp: Path, opts: _Options) -> None:
    v, f, lab = tip.vertices, tip.faces + 1, tip.label_ids
    groups = _obj_group_names(tip.label_names)
    with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(f"{_OBJ_MAGIC} mesh: one group per label\n# name {opts.name}\n"
                 f"# units mm; {_FRAME_NOTE}\n")
        fh.write("".join(f"# label {k} {n}\n" for k, n in enumerate(tip.label_names)))
        fh.write("o " + re.sub(r"\s+", "_", opts.name) + "\n")
        fh.write("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v.tolist()))
        # a `g` line wherever the label changes: keeps the face order
        starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        ends = np.r_[starts[1:], len(lab)]
        for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
            fh.write(f"g {groups[lab[s]]}\n")
            fh.write("".join(f"f {a} {b} {c}\n" for a, b, c in f[s:e].tolist()))


# -- 3MF, GLB (trimesh) --------------------------------------------------------
def _tip_trimesh(tip: Tip, opts: _Options, with_labels: bool):
    import trimesh

    meta: dict[str, Any] = {"name": opts.name}
    if with_labels:
        lab = tip.label_ids
        starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        counts = np.diff(np.r_[starts, len(lab)])
        meta["tipgeo"] = {"units": "mm", "frame": _FRAME_NOTE,
                          "label_names": list(tip.label_names),
                          "label_runs": np.column_stack([lab[starts], counts]).ravel().tolist()}
    mesh = trimesh.Trimesh(tip.vertices.copy(), tip.faces.copy(), process=False, metadata=meta)
    scene = trimesh.Scene()
    scene.add_geometry(mesh, geom_name=opts.name, node_name=opts.name)
    return scene


def _write_3mf(tip: Tip, tmp: Path, opts: _Options) -> None:
    try:  # trimesh's 3MF code needs both, and fails obscurely without them
        import lxml.etree  # noqa: F401
        import networkx  # noqa: F401
    except ImportError as exc:
        raise ExportError(f"3MF export needs the packages lxml and networkx ({exc}); "
                          f"install them with: pip install lxml networkx") from exc
    from trimesh.exchange.threemf import export_3MF

    data = export_3MF(_tip_trimesh(tip, opts, with_labels=False))
    with open(tmp, "wb") as fh:
        fh.write(data)


def _write_glb(tip: Tip, tmp: Path, opts: _Options) -> None:
    from trimesh.exchange.gltf import export_glb

    data = export_glb(_tip_trimesh(tip, opts, with_labels=True), include_normals=False)
    with open(tmp, "wb") as fh:
        fh.write(data)


# -- STEP ----------------------------------------------------------------------
def _ocp() -> SimpleNamespace:
    """The OCP classes the STEP writer uses (ExportError if OCP is missing)."""
    try:
        from OCP.BRep import BRep_Builder
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeShapeOnMesh
        from OCP.gp import gp_Pnt
        from OCP.IFSelect import IFSelect_RetDone
        from OCP.Interface import Interface_Static
        from OCP.Message import Message, Message_Gravity
        from OCP.Poly import Poly_Triangle, Poly_Triangulation
        from OCP.StepBasic import StepBasic_Product
        from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
        from OCP.TCollection import TCollection_HAsciiString
        from OCP.TopAbs import TopAbs_FACE
        from OCP.TopExp import TopExp_Explorer
        from OCP.TopoDS import TopoDS_Shell, TopoDS_Solid
    except ImportError as exc:
        raise ExportError(f"STEP export needs the OpenCASCADE bindings OCP, which are not "
                          f"installed ({exc}); install them with: pip install \"tipgeo[step]\""
                          ) from exc
    return SimpleNamespace(
        BRep_Builder=BRep_Builder, BRepBuilderAPI_MakeShapeOnMesh=BRepBuilderAPI_MakeShapeOnMesh,
        gp_Pnt=gp_Pnt, IFSelect_RetDone=IFSelect_RetDone, Interface_Static=Interface_Static,
        Message=Message, Message_Gravity=Message_Gravity, Poly_Triangle=Poly_Triangle,
        Poly_Triangulation=Poly_Triangulation, StepBasic_Product=StepBasic_Product,
        STEPControl_AsIs=STEPControl_AsIs, STEPControl_Writer=STEPControl_Writer,
        TCollection_HAsciiString=TCollection_HAsciiString, TopAbs_FACE=TopAbs_FACE,
        TopExp_Explorer=TopExp_Explorer, TopoDS_Shell=TopoDS_Shell, TopoDS_Solid=TopoDS_Solid)


def _step_solid(tip: Tip):
    """The tip as an OCCT solid bounded by one planar face per triangle, the
    faces pointing outwards (mm, cannula frame).

    ``BRepBuilderAPI_MakeShapeOnMesh`` shares the edges of neighbouring
    triangles by construction, so the faces form a closed shell without
    ``BRepBuilderAPI_Sewing`` (which is slow on large meshes).
    """
    occ = _ocp()
    if not tip.is_watertight:
        raise ExportError("STEP export needs a closed, consistently oriented triangle mesh; "
                          "this tip has open or non-manifold edges")
    v, f = tip.vertices, tip.faces + 1
    if tip.volume < 0:  # inside out: flip, so the faces point outwards
        f = f[:, ::-1]
    tri = occ.Poly_Triangulation(len(v), len(f), False)
    for i, (x, y, z) in enumerate(v.tolist(), 1):
        tri.SetNode(i, occ.gp_Pnt(x, y, z))
    for i, (a, b, c) in enumerate(f.tolist(), 1):
        tri.SetTriangle(i, occ.Poly_Triangle(a, b, c))
    maker = occ.BRepBuilderAPI_MakeShapeOnMesh(tri)
    maker.Build()
    if not maker.IsDone():
        raise ExportError("STEP export: OCCT could not build faces from the triangles")
    builder = occ.BRep_Builder()
    shell = occ.TopoDS_Shell()
    builder.MakeShell(shell)
    n_faces = 0
    explorer = occ.TopExp_Explorer(maker.Shape(), occ.TopAbs_FACE)
    while explorer.More():
        builder.Add(shell, explorer.Current())
        n_faces += 1
        explorer.Next()
    if n_faces != len(f):
        raise ExportError(f"STEP export: OCCT made {n_faces} faces from {len(f)} triangles "
                          f"(degenerate triangles?); the shell would not close")
    shell.Closed(True)
    solid = occ.TopoDS_Solid()
    builder.MakeSolid(solid)
    builder.Add(solid, shell)  # the faces keep the (outward) triangle orientation
    return solid


def _write_step(tip: Tip, tmp: Path, opts: _Options) -> None:
    occ = _ocp()
    static = occ.Interface_Static
    # silence OCCT's console chatter while we work; OCCT's STEP settings are
    # global too: set ours and restore the caller's afterwards
    levels = [(pr, pr.GetTraceLevel()) for pr in occ.Message.DefaultMessenger_s().Printers()]
    saved_unit = static.CVal_s("write.step.unit")
    saved_pcurves = static.IVal_s("write.surfacecurve.mode")
    try:
        for printer, _ in levels:
            printer.SetTraceLevel(occ.Message_Gravity.Message_Fail)
        solid = _step_solid(tip)
        # No p-curves (write.surfacecurve.mode 0): planar faces do not need
        # them; leaving them out makes the file 2.3x smaller and 40 % faster.
        static.SetCVal_s("write.step.unit", "MM")
        static.SetIVal_s("write.surfacecurve.mode", 0)
        writer = occ.STEPControl_Writer()
        if writer.Transfer(solid, occ.STEPControl_AsIs) != occ.IFSelect_RetDone:
            raise ExportError("STEP export: OCCT could not translate the solid")
        model = writer.Model()
        name = occ.TCollection_HAsciiString(opts.name)
        for i in range(1, model.NbEntities() + 1):  # the one PRODUCT comes first
            entity = model.Value(i)
            if isinstance(entity, occ.StepBasic_Product):
                entity.SetId(name)
                entity.SetName(name)
                break
        if writer.Write(str(tmp)) != occ.IFSelect_RetDone:
            raise ExportError(f"STEP export: OCCT could not write '{tmp}'")
    finally:
        if saved_unit:
            static.SetCVal_s("write.step.unit", saved_unit)
        static.SetIVal_s("write.surfacecurve.mode", saved_pcurves)
        for printer, level in levels:
            printer.SetTraceLevel(level)


# -- Abaqus INP ------------------------------------------------------------------
def _abaqus_name(label: str) -> str:
    s = re.sub(r"_+", "_", re.sub(r"[^A-Z0-9]", "_", label.upper())).strip("_")
    if not s or not s[0].isalpha():
        s = "L_" + s
    return s[:80]


def _inp_elset_names(labels: Sequence[str]) -> list[str]:
    used = {"ALL"}
    out = []
    for n in labels:
        base = _abaqus_name(n)
        s, k = base, 2
        while s in used:
            s = f"{base[:76]}_{k}"
            k += 1
        used.add(s)
        out.append(s)
    return out


def _ref_point(tip: Tip, ref: str | tuple[float, float, float]) -> tuple[float, float, float]:
    if not isinstance(ref, str):
        return ref
    z_max = float(tip.vertices[:, 2].max())
    if ref == "top":
        return (0.0, 0.0, z_max)
    # volume centroid (signed tetrahedra from the mean vertex), projected on the axis
    o = tip.vertices.mean(axis=0)
    t = tip.triangles - o
    vol6 = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    if abs(vol6.sum()) > 1e-300:
        zc = float((vol6 * t[:, :, 2].sum(axis=1)).sum() / (4.0 * vol6.sum()) + o[2])
    else:  # not a closed solid: area centroid
        a = tip.face_areas
        zc = float((a * tip.triangles[:, :, 2].mean(axis=1)).sum() / max(a.sum(), 1e-300))
    return (0.0, 0.0, zc)


def _write_inp(tip: Tip, tmp: Path, opts: _Options) -> None:
    v, f, lab = tip.vertices, tip.faces + 1, tip.label_ids
    n, m = len(v), len(f)
    part = _abaqus_name(opts.name) if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,79}",
                                                       opts.name) else opts.name
    present = [k for k in range(len(tip.label_names)) if np.any(lab == k)]
    elsets = _inp_elset_names([tip.label_names[k] for k in present])
    rx, ry, rz = _ref_point(tip, opts.ref_point)
    ref_id = n + 1

    def id_lines(ids: np.ndarray) -> str:
        if len(ids) and ids[-1] - ids[0] + 1 == len(ids):  # contiguous: generate
            return f", generate\n{ids[0]}, {ids[-1]}, 1\n"
        rows = [", ".join(map(str, ids[i:i + 16].tolist())) for i in range(0, len(ids), 16)]
        return "\n" + "\n".join(rows) + "\n"

    with open(tmp, "w", encoding="ascii", errors="replace", newline="\n") as fh:
        fh.write(f"*Heading\n{opts.name}: rigid needle tip (tipgeo); units mm; {_FRAME_NOTE}\n"
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


_WRITERS: dict[str, Callable[[Tip, Path, _Options], None]] = {
    ".stl": _write_stl,
    ".ply": _write_ply,
    ".obj": _write_obj,
    ".3mf": _write_3mf,
    ".glb": _write_glb,
    ".step": _write_step,
    ".stp": _write_step,
    ".inp": _write_inp,
}


# ---------------------------------------------------------------------------
# import
# ---------------------------------------------------------------------------
@dataclass
class _Mesh:
    vertices: np.ndarray
    faces: np.ndarray
    label_ids: np.ndarray | None = None
    label_names: tuple[str, ...] = ()
    name: str | None = None


def load_tip(path: str | os.PathLike[str], *, units: str = "mm") -> Tip:
    """Read a triangle mesh file as a :class:`~tipgeo.tip.Tip`.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.stl``, ``.ply``, ``.obj``, ``.3mf`` or ``.glb`` file (extension
        case-insensitive, see :data:`SUPPORTED_IMPORTS`). The mesh is taken to
        be in the cannula frame (+z along the needle axis towards the tip).
    units : {'mm', 'um', 'm'}, default 'mm'
        Length unit of the coordinates in the file; they are scaled to mm.

    Returns
    -------
    Tip
        Vertices in mm, ``source`` set to the file name, ``spec``,
        ``tolerance`` and ``segments`` ``None``. Labels are restored from a
        PLY written by :func:`export_tip` (face property ``label`` and
        ``comment label`` lines), an OBJ written by it (groups) and a GLB
        written by it (mesh ``extras``); otherwise every triangle is labelled
        :data:`UNLABELLED`. STL vertices (one triple per triangle) are merged
        where they are bit-identical, nowhere else.

    Raises
    ------
    SpecError
        Unknown extension or units; the file is missing, not a file, empty,
        unreadable, holds no triangles, has non-finite vertices or faces
        indexing missing vertices.
    """
    p = _as_path(path)
    if not isinstance(units, str) or units not in UNITS:
        raise SpecError(f"units = {units!r} is not supported; allowed: "
                        f"{', '.join(repr(u) for u in UNITS)}")
    ext = p.suffix.lower()
    if ext not in SUPPORTED_IMPORTS:
        raise SpecError(f"path '{p}' has extension '{p.suffix}'; allowed: "
                        f"{', '.join(SUPPORTED_IMPORTS)}")
    if not p.exists():
        raise SpecError(f"path '{p}' does not exist")
    if not p.is_file():
        raise SpecError(f"path '{p}' is not a regular file")
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise SpecError(f"path '{p}' cannot be read: {exc}") from exc
    if size == 0:
        raise SpecError(f"path '{p}' is empty (0 bytes); expected a {ext} mesh")
    try:
        mesh = _READERS[ext](p)
    except SpecError:
        raise
    except Exception as exc:
        raise SpecError(f"path '{p}' could not be read as {ext}: "
                        f"{type(exc).__name__}: {exc}") from exc

    v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise SpecError(f"path '{p}' holds no triangles; expected a triangle mesh")
    if not np.all(np.isfinite(v)):
        raise SpecError(f"path '{p}' has non-finite (NaN or infinite) vertex coordinates")
    if f.min() < 0 or f.max() >= len(v):
        raise SpecError(f"path '{p}': faces index vertices {int(f.min())}…{int(f.max())}; "
                        f"the file has {len(v)} vertices")
    labels_from_file = mesh.label_ids is not None
    if labels_from_file:
        lab = np.asarray(mesh.label_ids, dtype=np.int64)
        names = tuple(mesh.label_names)
    else:
        lab, names = np.zeros(len(f), dtype=np.int64), (UNLABELLED,)
    meta: dict[str, Any] = {"path": str(p), "format": ext[1:], "file_units": units,
                            "labels_from_file": labels_from_file}
    if mesh.name:
        meta["name"] = mesh.name
    return Tip(vertices=v * UNITS[units], faces=f, label_ids=lab, label_names=names,
               source=p.name, meta=meta)


def _labels_from_ids(ids: np.ndarray, named: dict[int, str], n_faces: int,
                     where: str) -> tuple[np.ndarray, tuple[str, ...]]:
    ids = np.asarray(ids).astype(np.int64).reshape(-1)
    if len(ids) != n_faces:
        raise SpecError(f"{where}: {len(ids)} face labels for {n_faces} faces")
    if len(ids) and ids.min() < 0:
        raise SpecError(f"{where}: negative face label {int(ids.min())}; expected ids ≥ 0")
    top = max([int(ids.max()) if len(ids) else -1, *named.keys()]) + 1
    if top > 1_000_000:
        raise SpecError(f"{where}: face label id {top - 1} is implausibly large; "
                        f"allowed 0…999999")
    return ids, tuple(named.get(k, f"label{k}") for k in range(top))


# -- PLY -----------------------------------------------------------------------
class _Unsupported(Exception):
    """The PLY layout is not one the direct reader handles: use trimesh."""


def _read_ply(p: Path) -> _Mesh:
    data = p.read_bytes()
    try:
        return _parse_ply(data, str(p))
    except _Unsupported:
        return _read_trimesh(p)


def _parse_ply(data: bytes, where: str) -> _Mesh:
    if not data.startswith(b"ply"):
        raise SpecError(f"path '{where}' is not a PLY file (it does not start with 'ply')")
    end = data.find(b"end_header")
    if end < 0:
        raise SpecError(f"path '{where}': PLY header has no 'end_header' line")
    body = data.index(b"\n", end) + 1
    header = data[:end].decode("utf-8", "replace").splitlines()
    fmt = None
    elements: list[tuple[str, int, list[tuple]]] = []
    named: dict[int, str] = {}
    name = None
    for line in header[1:]:
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "comment":
            rest = line.split(None, 1)[1] if len(tok) > 1 else ""
            parts = rest.split(None, 2)
            if len(parts) == 3 and parts[0] == "label" and parts[1].isdigit():
                named[int(parts[1])] = parts[2].strip()
            elif len(parts) >= 2 and parts[0] == "name":
                name = rest.split(None, 1)[1].strip()
        elif tok[0] == "element":
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            if not elements:
                raise SpecError(f"path '{where}': PLY property before any element")
            if tok[1] == "list":
                elements[-1][2].append((tok[4], _PLY_TYPES[tok[2]], _PLY_TYPES[tok[3]]))
            else:
                elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))
    order = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": None}
    if fmt not in order:
        raise SpecError(f"path '{where}': PLY format {fmt!r} unknown; expected ascii, "
                        f"binary_little_endian or binary_big_endian")
    arrays = (_ply_binary(data, body, elements, order[fmt]) if fmt != "ascii"
              else _ply_ascii(data[body:], elements))
    if "vertex" not in arrays or "face" not in arrays:
        raise _Unsupported
    vert, face = arrays["vertex"], arrays["face"]
    if not {"x", "y", "z"} <= set(vert.dtype.names or ()):
        raise _Unsupported
    lists = [n for n in face.dtype.names if n in ("vertex_indices", "vertex_index")]
    if not lists or face[lists[0]].shape[1:] != (3,):
        raise _Unsupported  # polygons: let trimesh triangulate (labels are then dropped)
    v = np.column_stack([vert["x"], vert["y"], vert["z"]]).astype(np.float64)
    f = face[lists[0]].astype(np.int64)
    mesh = _Mesh(v, f, name=name)
    if "label" in face.dtype.names:
        mesh.label_ids, mesh.label_names = _labels_from_ids(face["label"], named, len(f),
                                                            f"path '{where}'")
    return mesh


def _ply_binary(data: bytes, pos: int, elements, bo: str) -> dict[str, np.ndarray]:
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


def _ply_ascii(body: bytes, elements) -> dict[str, np.ndarray]:
    lines = body.decode("ascii", "replace").splitlines()
    out, row = {}, 0
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


# -- OBJ -------------------------------------------------------------------------
def _read_obj(p: Path) -> _Mesh:
    with open(p, "rb") as fh:
        first = fh.readline()
    if not first.decode("utf-8", "replace").startswith(_OBJ_MAGIC):
        return _read_trimesh(p)  # not ours: no labels
    text = p.read_text(encoding="utf-8", errors="replace")
    named: dict[int, str] = {}
    name = None
    vs: list[str] = []
    faces: list[list[int]] = []
    fl: list[int] = []
    group = None
    for ln, line in enumerate(text.splitlines(), 1):
        if not line or line.startswith("#"):
            parts = line[1:].split(None, 2)
            if len(parts) == 3 and parts[0] == "label" and parts[1].isdigit():
                named[int(parts[1])] = parts[2].strip()
            elif len(parts) >= 2 and parts[0] == "name":
                name = line[1:].split(None, 1)[1].strip()
            continue
        tag, _, rest = line.partition(" ")
        if tag == "v":
            vs.append(rest)
        elif tag == "f":
            idx = []
            for t in rest.split():
                k = int(t.split("/", 1)[0])
                idx.append(k - 1 if k > 0 else len(vs) + k)
            if len(idx) < 3:
                raise SpecError(f"path '{p}' line {ln}: face with {len(idx)} vertices")
            for j in range(1, len(idx) - 1):  # fan-triangulate polygons
                faces.append([idx[0], idx[j], idx[j + 1]])
                fl.append(-1 if group is None else group)
        elif tag == "g":
            group = _obj_group_id(rest.strip(), named)
    if not vs:
        raise SpecError(f"path '{p}' has no vertices")
    vals = np.array(" ".join(vs).split(), dtype=np.float64)
    if len(vals) != 3 * len(vs):
        raise SpecError(f"path '{p}': vertex lines must hold exactly x y z")
    mesh = _Mesh(vals.reshape(-1, 3), np.array(faces, dtype=np.int64).reshape(-1, 3), name=name)
    labels = np.array(fl, dtype=np.int64)
    if len(labels) and labels.min() >= 0:
        mesh.label_ids, mesh.label_names = _labels_from_ids(labels, named, len(labels),
                                                            f"path '{p}'")
    return mesh


def _obj_group_id(token: str, named: dict[int, str]) -> int:
    groups = _obj_group_names([named.get(k, f"label{k}") for k in range(max(named, default=-1)
                                                                          + 1)])
    if token in groups:
        return groups.index(token)
    named[len(groups)] = token  # a group without a `# label` line: a new label
    return len(groups)


# -- trimesh (STL, 3MF, GLB, foreign OBJ/PLY) --------------------------------------
def _read_trimesh(p: Path) -> _Mesh:
    import trimesh

    loaded = trimesh.load(str(p), file_type=p.suffix.lower()[1:], process=False)
    parts: list[tuple[np.ndarray, Any, str | None]] = []
    if isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            transform, gname = loaded.graph[node]
            g = loaded.geometry[gname]
            if isinstance(g, trimesh.Trimesh) and len(g.faces):
                v = np.asarray(g.vertices, dtype=np.float64)
                if not np.array_equal(transform, np.eye(4)):
                    v = trimesh.transform_points(v, transform)
                parts.append((v, g, gname))
    elif isinstance(loaded, trimesh.Trimesh):
        parts.append((np.asarray(loaded.vertices, dtype=np.float64), loaded, None))
    if not parts:
        raise SpecError(f"path '{p}' holds no triangle mesh")
    vs, fs, ls, names = [], [], [], []
    offset, any_labels, name = 0, False, None
    for v, g, gname in parts:
        f = np.asarray(g.faces, dtype=np.int64)
        lab, lnames = _trimesh_labels(g, len(f))
        any_labels |= lab is not None
        if lab is None:
            lab, lnames = np.zeros(len(f), dtype=np.int64), (UNLABELLED,)
        remap = []
        for ln in lnames:
            if ln not in names:
                names.append(ln)
            remap.append(names.index(ln))
        vs.append(v)
        fs.append(f + offset)
        ls.append(np.asarray(remap, dtype=np.int64)[lab])
        offset += len(v)
        name = name or g.metadata.get("name") or gname
    v, f = np.concatenate(vs), np.concatenate(fs)
    if p.suffix.lower() == ".stl":
        v, f = _merge_identical(v, f)
    mesh = _Mesh(v, f, name=name if isinstance(name, str) else None)
    if any_labels:
        mesh.label_ids, mesh.label_names = np.concatenate(ls), tuple(names)
    return mesh


def _trimesh_labels(g, n_faces: int) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Labels a GLB written by export_tip keeps in the mesh extras."""
    info = g.metadata.get("tipgeo") if isinstance(g.metadata, dict) else None
    try:
        names = tuple(str(n) for n in info["label_names"])
        runs = np.asarray(info["label_runs"], dtype=np.int64).reshape(-1, 2)
        if (runs[:, 1].sum() != n_faces or runs.min() < 0
                or runs[:, 0].max(initial=-1) >= len(names)):
            return None, ()
        return np.repeat(runs[:, 0], runs[:, 1]), names
    except (TypeError, KeyError, ValueError):
        return None, ()


def _merge_identical(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical vertices (STL repeats them per triangle), keeping
    the order of first use."""
    uniq, first, inv = np.unique(v, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    return uniq[order], rank[inv.reshape(-1)][f]


_READERS: dict[str, Callable[[Path], _Mesh]] = {
    ".stl": _read_trimesh,
    ".ply": _read_ply,
    ".obj": _read_obj,
    ".3mf": _read_trimesh,
    ".glb": _read_trimesh,
}
