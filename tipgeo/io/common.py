"""What the format modules share: the export error, the checks of tips, paths
and options, the frame note written into file headers, and the trimesh scene
the 3MF and GLB writers start from.

Frame and units: the cannula frame (+z along the needle axis towards the tip,
heel at z = 0, γ about +z from +x), lengths in mm.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from numbers import Real
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..arrays import FloatArray, IntArray
from ..errors import ExportError, SpecError
from .registry import ExportOptions

if TYPE_CHECKING:
    import trimesh

    from ..tip import Tip

__all__ = [
    "FRAME_NOTE",
    "ExportError",
    "as_path",
    "check_ref_point",
    "check_tip",
    "object_name",
    "tip_scene",
]

#: The frame, as written into file headers and comments.
FRAME_NOTE = "cannula frame: +z along the needle axis towards the tip, heel at z = 0"


def as_path(path: object) -> Path:
    """``path`` as a ``Path`` naming a file (SpecError for anything else)."""
    if isinstance(path, (str, os.PathLike)) and not isinstance(path, bytes):
        p = Path(path)
        if str(p) not in ("", "."):
            return p
    raise SpecError(f"path = {path!r} is not a file path; expected a str or os.PathLike "
                    f"naming a file")


def check_tip(tip: object) -> None:
    """SpecError unless ``tip`` is a non-empty, finite, consistently indexed
    and labelled :class:`~tipgeo.tip.Tip`."""
    # duck-typed: the writers need no more than this (and io stays free of tip)
    if not all(hasattr(tip, a) for a in ("vertices", "faces", "label_ids", "label_names",
                                         "spec", "meta")):
        raise SpecError(f"tip = {type(tip).__name__} is not a Tip")
    t = cast("Tip", tip)  # has every attribute a writer reads (checked above)
    v, f, lab = t.vertices, t.faces, t.label_ids
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise SpecError(f"tip has vertices of shape {v.shape} and faces of shape {f.shape}; "
                        f"expected (n, 3) and (m, 3) with m ≥ 1")
    if not np.all(np.isfinite(v)):
        raise SpecError("tip.vertices contain NaN or infinite values; expected finite mm")
    if f.min() < 0 or f.max() >= len(v):
        raise SpecError(f"tip.faces index vertices {int(f.min())}…{int(f.max())}; allowed "
                        f"0…{len(v) - 1}")
    _check_labels(lab, t.label_names, len(f))


def _check_labels(lab: IntArray, names: tuple[str, ...], n_faces: int) -> None:
    """SpecError unless there is one label id per face, each naming one of
    ``names``, and every name is a non-empty one-line str."""
    if lab.shape != (n_faces,) or (len(lab) and (lab.min() < 0 or lab.max() >= len(names))):
        raise SpecError(f"tip.label_ids must have shape ({n_faces},) with values in "
                        f"0…{len(names) - 1}")
    for n in names:
        if not isinstance(n, str) or not n or "\n" in n or "\r" in n:
            raise SpecError(f"label name {n!r} is invalid; expected a non-empty str without "
                            f"line breaks")


def object_name(tip: Tip, p: Path, name: object) -> str:
    """The object name to write: ``name``, else the spec name, else
    ``tip.meta['name']``, else the file stem (SpecError if invalid)."""
    if name is None:
        name = (getattr(tip.spec, "name", "") or tip.meta.get("name") or p.stem or "tip")
    if not isinstance(name, str) or not name.strip() or "\n" in name or "\r" in name:
        raise SpecError(f"name = {name!r} is invalid; expected a non-empty str without line "
                        f"breaks")
    return name.strip()


def check_ref_point(ref: object) -> str | tuple[float, float, float]:
    """``'centroid'``, ``'top'`` or three finite floats (mm); SpecError else."""
    if isinstance(ref, str):
        if ref in ("centroid", "top"):
            return ref
    else:
        try:
            vals: tuple[object, ...] = tuple(cast(Iterable[object], ref))
        except TypeError:  # not iterable
            vals = ()
        nums = [float(x) for x in vals if isinstance(x, Real) and not isinstance(x, bool)]
        if len(vals) == 3 and len(nums) == 3 and all(math.isfinite(x) for x in nums):
            return (nums[0], nums[1], nums[2])
    raise SpecError(f"ref_point = {ref!r} is invalid; allowed: 'centroid', 'top' or three finite "
                    f"numbers (x, y, z) in mm")


def tip_scene(tip: Tip, opts: ExportOptions, with_labels: bool,
              transform: FloatArray | None = None,
              info: dict[str, Any] | None = None) -> trimesh.Scene:
    """The tip as a one-mesh ``trimesh.Scene``, the mesh and its node named
    ``opts.name``: vertices in mm and the cannula frame, or mapped by the 4×4
    ``transform`` (cannula mm → file coordinates) when given. With
    ``with_labels`` the mesh metadata (glTF ``extras``) hold ``tipgeo``:
    ``info``, ``frame``, ``label_names`` and the run-length ``label_runs``
    (``[id, count, id, count, …]`` along the faces); the scene metadata hold
    ``tipgeo`` without the labels."""
    import trimesh

    meta: dict[str, Any] = {"name": opts.name}
    scene_meta: dict[str, Any] = {}
    v = tip.vertices.copy()
    if transform is not None:
        v = v @ transform[:3, :3].T + transform[:3, 3]
    if with_labels:
        lab = tip.label_ids
        starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
        counts = np.diff(np.r_[starts, len(lab)])
        head = {"units": "mm", **(info or {}), "frame": FRAME_NOTE}
        scene_meta = {"tipgeo": dict(head)}
        meta["tipgeo"] = {**head, "label_names": list(tip.label_names),
                          "label_runs": np.column_stack([lab[starts], counts]).ravel().tolist()}
    mesh = trimesh.Trimesh(v, tip.faces.copy(), process=False, metadata=meta)
    scene = trimesh.Scene(metadata=scene_meta)
    scene.add_geometry(mesh, geom_name=opts.name, node_name=opts.name)
    return scene
