"""The Tip: a labelled, double-precision triangle mesh of a needle tip.

Frame and units: cannula frame (+z along the needle axis towards the tip, the
heel at z = 0, γ about +z from +x), lengths in mm.

:meth:`Tip.export` writes through the installed :data:`TipWriter`: the I/O
layer's :func:`tipgeo.io.export_tip`, plugged in by ``tipgeo/__init__.py``
(which Python runs before any ``tipgeo`` module), so this module does not
import :mod:`tipgeo.io` — which imports it (``tests/test_import_graph.py``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .arrays import AnyArray, BoolArray, FloatArray, IntArray
from .tolerances import tol

if TYPE_CHECKING:  # pragma: no cover
    import trimesh

    from .spec import TipSpec

__all__ = ["Tip", "TipWriter", "set_tip_writer"]

#: Writes a tip to a file: ``writer(tip, path, **options)``, the format from
#: the extension of ``path`` (options as :func:`tipgeo.io.export_tip`).
TipWriter = Callable[..., object]

#: The installed writer (at most one, under the key ``"writer"``).
_TIP_WRITER: dict[str, TipWriter] = {}


def set_tip_writer(writer: TipWriter) -> None:
    """Install the function :meth:`Tip.export` writes with (the I/O layer's
    :func:`tipgeo.io.export_tip`; ``tipgeo/__init__.py`` installs it).
    Replaces any earlier one."""
    if not callable(writer):
        raise TypeError(f"writer = {writer!r} is not callable")
    _TIP_WRITER["writer"] = writer


@dataclass(eq=False)
class Tip:
    """A watertight labelled tip mesh.

    Attributes
    ----------
    vertices : (n, 3) float — mm, cannula frame
    faces : (m, 3) int — vertex indices, counter-clockwise seen from outside
    label_ids : (m,) int — index into ``label_names`` per triangle
    label_names : tuple of str — ``outer``, ``inner``, ``base``, ``cut:<name>`` …
    spec : TipSpec or None — the spec the tip was built from
    tolerance : float or None — chordal tolerance it was built at (mm)
    segments : int or None — segments around the tube
    source : str — where the tip came from (``cad``, a file name, a simulator)
    """

    vertices: FloatArray
    faces: IntArray
    label_ids: IntArray
    label_names: tuple[str, ...]
    spec: TipSpec | None = None
    tolerance: float | None = None
    segments: int | None = None
    source: str = "cad"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64)
        self.label_ids = np.ascontiguousarray(self.label_ids, dtype=np.int64)
        self.label_names = tuple(self.label_names)

    # -- labels -----------------------------------------------------------
    @property
    def labels(self) -> AnyArray:
        """(m,) str — the label of every triangle."""
        names: AnyArray = np.asarray(self.label_names, dtype=object)
        return names[self.label_ids]

    def present_labels(self) -> tuple[str, ...]:
        """Labels that at least one triangle carries, in registry order."""
        used = set(np.unique(self.label_ids).tolist())
        return tuple(n for k, n in enumerate(self.label_names) if k in used)

    def label_counts(self) -> dict[str, int]:
        """Number of triangles per label."""
        ids, cnt = np.unique(self.label_ids, return_counts=True)
        return {self.label_names[i]: int(c) for i, c in zip(ids, cnt)}

    def mask(self, label: str) -> BoolArray:
        """(m,) bool — triangles carrying ``label`` (or, for ``cut:<name>``,
        also its sub-faces ``cut:<name>.<k>``)."""
        ids = [k for k, n in enumerate(self.label_names)
               if n == label or n.startswith(label + ".")]
        return np.isin(self.label_ids, ids)

    # -- geometry ---------------------------------------------------------
    @property
    def triangles(self) -> FloatArray:
        """(m, 3, 3) float — triangle corners (mm)."""
        return self.vertices[self.faces]

    @property
    def face_normals(self) -> FloatArray:
        """(m, 3) float — unit outward normals."""
        t = self.triangles
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        return np.asarray(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), tol.tiny),
                          dtype=np.float64)

    @property
    def face_areas(self) -> FloatArray:
        """(m,) float — triangle areas (mm²)."""
        t = self.triangles
        return np.asarray(
            0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1),
            dtype=np.float64)

    @property
    def volume(self) -> float:
        """Enclosed volume (mm³), by the divergence theorem in double precision."""
        t = self.triangles - self.vertices.mean(axis=0)
        return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)

    @property
    def area(self) -> float:
        """Surface area (mm²)."""
        return float(self.face_areas.sum())

    @property
    def bounds(self) -> FloatArray:
        """(2, 3) float — min and max corner (mm)."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def is_watertight(self) -> bool:
        """Every edge is shared by exactly two triangles with opposite
        orientation (closed, oriented 2-manifold)."""
        d = self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        und = np.sort(d, axis=1)
        _, inv, cnt = np.unique(und, axis=0, return_inverse=True, return_counts=True)
        if not np.all(cnt == 2):
            return False
        sign = np.where(d[:, 0] < d[:, 1], 1, -1)
        return bool(np.all(np.bincount(inv.ravel(), weights=sign) == 0))

    @property
    def euler_number(self) -> int:
        """V − E + F."""
        e = np.unique(np.sort(self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
        return int(len(np.unique(self.faces)) - len(e) + len(self.faces))

    @property
    def genus(self) -> int:
        """Genus of a connected closed surface: (2 − χ)/2 (a tube: 1)."""
        return (2 - self.euler_number) // 2

    # -- conversions --------------------------------------------------------
    def to_trimesh(self) -> trimesh.Trimesh:
        """A ``trimesh.Trimesh`` with the labels in ``face_attributes['label']``
        (ids) and ``metadata['label_names']``."""
        import trimesh

        mesh = trimesh.Trimesh(self.vertices.copy(), self.faces.copy(), process=False,
                               face_attributes={"label": self.label_ids.copy()})
        mesh.metadata["label_names"] = list(self.label_names)
        mesh.metadata["units"] = "mm"
        return mesh

    def submesh(self, label: str) -> tuple[FloatArray, IntArray]:
        """Vertices and faces (re-indexed) of the triangles carrying ``label``."""
        f = self.faces[self.mask(label)]
        used, inv = np.unique(f, return_inverse=True)
        return self.vertices[used], inv.reshape(-1, 3)

    def export(self, path: str | os.PathLike[str], **kwargs: Any) -> None:
        """Write the tip to ``path``; the format follows the extension
        (see :func:`tipgeo.io.export_tip`). Written atomically."""
        writer = _TIP_WRITER.get("writer")
        if writer is None:  # pragma: no cover - tipgeo/__init__.py installs it
            raise RuntimeError("no tip writer installed; import tipgeo first")
        writer(self, path, **kwargs)

    def summary(self) -> dict[str, Any]:
        """Plain numbers describing the tip (for reports and ``--json``)."""
        b = self.bounds
        return {
            "name": getattr(self.spec, "name", None),
            "source": self.source,
            "vertices": int(len(self.vertices)),
            "triangles": int(len(self.faces)),
            "volume_mm3": self.volume,
            "area_mm2": self.area,
            "z_min_mm": float(b[0, 2]),
            "z_max_mm": float(b[1, 2]),
            "tolerance_um": None if self.tolerance is None else self.tolerance * 1e3,
            "segments": self.segments,
            "watertight": self.is_watertight,
            "genus": self.genus,
            "labels": self.label_counts(),
        }
