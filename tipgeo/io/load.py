"""Reading meshes back: :func:`load_tip` checks the path and the units, reads
the file with the reader registered for its extension
(:data:`~tipgeo.io.registry.IMPORTERS`), checks the mesh and makes a
:class:`~tipgeo.tip.Tip` in mm; :func:`read_trimesh` is the reader of the
formats read through trimesh.

Frame and units: the mesh is taken to be in the cannula frame (+z along the
needle axis towards the tip); coordinates are scaled from ``units`` to mm.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import SpecError
from ..tip import Tip
from ..tolerances import tol
from .common import as_path
from .registry import IMPORTERS, LoadedMesh

__all__ = ["UNITS", "UNLABELLED", "labels_from_ids", "load_tip", "read_trimesh"]

#: Length units :func:`load_tip` accepts, with their size in mm.
UNITS: dict[str, float] = {"mm": 1.0, "um": 1.0e-3, "m": 1.0e3}
#: The label of every triangle of a file that carries no labels.
UNLABELLED = "unlabelled"


def load_tip(path: str | os.PathLike[str], *, units: str | None = None) -> Tip:
    """Read a triangle mesh file as a :class:`~tipgeo.tip.Tip`.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.stl``, ``.ply``, ``.obj``, ``.3mf`` or ``.glb`` file (extension
        case-insensitive, see :data:`~tipgeo.io.SUPPORTED_IMPORTS`). The mesh
        is taken to be in the cannula frame (+z along the needle axis towards
        the tip).
    units : {'mm', 'um', 'm'}, optional
        Length unit of the coordinates in the file; they are scaled to mm.
        Default: the unit the file declares (a GLB written by
        :func:`~tipgeo.io.export_tip` says ``'m'`` or ``'mm'`` in its
        ``extras``; its axes are turned back to the cannula frame too), else
        ``'mm'``. A unit given here that contradicts the file's is an error.

    Returns
    -------
    Tip
        Vertices in mm, ``source`` set to the file name, ``spec``,
        ``tolerance`` and ``segments`` ``None``. Labels are restored from a
        PLY written by :func:`~tipgeo.io.export_tip` (face property ``label``
        and ``comment label`` lines), an OBJ written by it (groups) and a GLB
        written by it (mesh ``extras``); otherwise every triangle is labelled
        :data:`UNLABELLED`. STL vertices (one triple per triangle) are merged
        where they are bit-identical, nowhere else.

    Raises
    ------
    SpecError
        Unknown extension or units, or units contradicting the unit the file
        declares; the file is missing, not a file, empty,
        unreadable, holds no triangles, has non-finite vertices or faces
        indexing missing vertices.
    """
    p = _checked_path(path, units)
    ext = p.suffix.lower()
    try:
        mesh = IMPORTERS[ext](p)
    except SpecError:
        raise
    except Exception as exc:
        raise SpecError(f"path '{p}' could not be read as {ext}: "
                        f"{type(exc).__name__}: {exc}") from exc

    if mesh.units is not None and units is not None and units != mesh.units:
        raise SpecError(f"units = {units!r} contradicts the unit the file '{p}' declares "
                        f"({mesh.units!r}); leave units out to use the file's")
    units = units or mesh.units or "mm"
    v, f = _checked_mesh(mesh, p)
    labels_from_file = mesh.label_ids is not None
    if mesh.label_ids is not None:
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


def _checked_path(path: str | os.PathLike[str], units: str | None) -> Path:
    """``path`` once it names an existing, non-empty regular file with an
    importable extension and ``units`` is known."""
    p = as_path(path)
    if units is not None and (not isinstance(units, str) or units not in UNITS):
        raise SpecError(f"units = {units!r} is not supported; allowed: "
                        f"{', '.join(repr(u) for u in UNITS)}")
    ext = p.suffix.lower()
    if ext not in IMPORTERS:
        raise SpecError(f"path '{p}' has extension '{p.suffix}'; allowed: "
                        f"{', '.join(IMPORTERS)}")
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
    return p


def _checked_mesh(mesh: LoadedMesh, p: Path) -> tuple[FloatArray, IntArray]:
    """The mesh's (n, 3) float64 vertices and (m ≥ 1, 3) int64 faces, finite
    and indexing existing vertices."""
    v = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise SpecError(f"path '{p}' holds no triangles; expected a triangle mesh")
    if not np.all(np.isfinite(v)):
        raise SpecError(f"path '{p}' has non-finite (NaN or infinite) vertex coordinates")
    if f.min() < 0 or f.max() >= len(v):
        raise SpecError(f"path '{p}': faces index vertices {int(f.min())}…{int(f.max())}; "
                        f"the file has {len(v)} vertices")
    return v, f


def labels_from_ids(ids: ArrayLike, named: dict[int, str], n_faces: int,
                    where: str) -> tuple[IntArray, tuple[str, ...]]:
    """Face labels read from a file (ids ≥ 0, one per face) and their names:
    ``named`` where given, ``label<k>`` for the other ids up to the largest.
    SpecError (naming ``where``) for a wrong count or implausible ids."""
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


# -- trimesh (STL, 3MF, GLB, foreign OBJ/PLY) --------------------------------------
def read_trimesh(p: Path) -> LoadedMesh:
    """Read ``p`` through trimesh (STL, 3MF, GLB, and OBJ or PLY files the
    direct readers do not handle): all triangle meshes of a scene, placed by
    their node transforms, joined in one mesh; labels, declared unit and the
    turn back to the cannula frame only from the ``extras`` of a GLB written
    by :func:`~tipgeo.io.export_tip`. STL vertices are merged where
    bit-identical."""
    parts = _trimesh_parts(p)
    if not parts:
        raise SpecError(f"path '{p}' holds no triangle mesh")
    vs, fs, ls, names = [], [], [], []
    offset, any_labels, name, declared = 0, False, None, set()
    for v, g, gname in parts:
        f: IntArray = np.asarray(g.faces, dtype=np.int64)
        unit, rot = _trimesh_frame(g)
        if unit is not None:
            declared.add(unit)
            v = v @ rot.T
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
    if len(declared) > 1:
        raise SpecError(f"path '{p}': its meshes declare different units "
                        f"{sorted(declared)}; expected one")
    mesh = LoadedMesh(v, f, name=name if isinstance(name, str) else None,
                      units=declared.pop() if declared else None)
    if any_labels:
        mesh.label_ids, mesh.label_names = np.concatenate(ls), tuple(names)
    return mesh


def _trimesh_parts(p: Path) -> list[tuple[FloatArray, Any, object]]:
    """The non-empty triangle meshes trimesh reads from ``p``: (vertices placed
    by their node transform, the trimesh mesh, its node's geometry name)."""
    import trimesh

    loaded = trimesh.load(str(p), file_type=p.suffix.lower()[1:], process=False)
    parts: list[tuple[FloatArray, Any, object]] = []
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
    return parts


def _trimesh_frame(g: Any) -> tuple[str | None, FloatArray]:
    """The unit a GLB written by export_tip declares and the rotation from its
    axes to the cannula frame's (``None`` and the identity otherwise)."""
    info = g.metadata.get("tipgeo") if isinstance(g.metadata, dict) else None
    if not isinstance(info, dict) or info.get("units") not in UNITS:
        return None, np.eye(3)
    unit = info["units"]
    try:
        m = np.asarray(info.get("to_cannula_mm", np.eye(4).ravel()), dtype=np.float64)
        rot = m.reshape(4, 4)[:3, :3] / UNITS[unit]
    except (TypeError, ValueError):
        return None, np.eye(3)
    if not np.allclose(rot @ rot.T, np.eye(3), atol=tol.mesh_rotation) or np.linalg.det(rot) < 0:
        raise SpecError(f"tipgeo.to_cannula_mm in the file's extras is not a rotation scaled by "
                        f"its unit {unit!r}")
    exact = np.round(rot)  # an axis permutation (what export_tip writes), exactly
    return unit, exact if np.allclose(exact, rot, atol=tol.mesh_rotation) else rot


def _trimesh_labels(g: Any, n_faces: int) -> tuple[IntArray | None, tuple[str, ...]]:
    """Labels a GLB written by export_tip keeps in the mesh extras."""
    info = g.metadata.get("tipgeo") if isinstance(g.metadata, dict) else None
    if not isinstance(info, dict):
        return None, ()
    try:
        names = tuple(str(n) for n in info["label_names"])
        runs = np.asarray(info["label_runs"], dtype=np.int64).reshape(-1, 2)
        if (runs[:, 1].sum() != n_faces or runs.min() < 0
                or runs[:, 0].max(initial=-1) >= len(names)):
            return None, ()
        return np.repeat(runs[:, 0], runs[:, 1]), names
    except (TypeError, KeyError, ValueError):
        return None, ()


def _merge_identical(v: FloatArray, f: IntArray) -> tuple[FloatArray, IntArray]:
    """Merge bit-identical vertices (STL repeats them per triangle), keeping
    the order of first use."""
    uniq, first, inv = np.unique(v, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    return uniq[order], rank[inv.reshape(-1)][f]
