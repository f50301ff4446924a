"""Custom cutters: any user solid or signed-distance function.

Frame and units: cannula frame (+z along the axis towards the tip, the heel
at z = 0), mm. The user's solid (or SDF) is the material to *keep*; it must
cover the tube's cross-section below the cut and end it above.

A mesh-defined cutter gives only its solid (protocol item 1): analysis falls
back to the tip's mesh. An SDF cutter also gives its implicit function (by
central differences for the gradient).

Reading a mesh file is the I/O layer's job, not the cutters': the slot
(:data:`MeshReader`, :func:`set_mesh_reader`, kept in :mod:`tipgeo._slots`
and named here too) is filled by ``tipgeo/__init__.py`` — which Python runs
before any ``tipgeo`` module — with :func:`tipgeo.io.load_tip`. So ``tipgeo.cutters`` never imports
``tipgeo.io`` (which imports :mod:`tipgeo.tip`, which names
:class:`~tipgeo.spec.TipSpec`, which imports the cutters): the import graph
has no circle (``tests/test_import_graph.py``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import manifold3d as m3d
import numpy as np

from .. import validate as v
from .._slots import MeshReader, mesh_reader, set_mesh_reader
from ..arrays import ArrayLike, FloatArray, IntArray
from ..cannula import Cannula
from ..construct import AUX, BuildContext
from ..errors import SpecError
from ..tolerances import tol
from .base import Cutter, check_name

if TYPE_CHECKING:  # pragma: no cover
    from .toml import CutterTable

__all__ = ["MeshCutter", "SDFCutter", "MeshReader", "set_mesh_reader"]

class _Mesh(NamedTuple):
    """A read mesh, as :func:`_as_manifold` takes it."""

    vertices: FloatArray
    faces: IntArray


def _as_manifold(solid: Any) -> Any:
    if isinstance(solid, m3d.Manifold):
        man = solid
    else:
        try:
            verts = np.asarray(solid.vertices, dtype=np.float64)
            faces = np.asarray(solid.faces, dtype=np.uint64)
        except AttributeError:
            raise SpecError(f"solid = {type(solid).__name__} is not a manifold3d.Manifold or a "
                            "mesh with .vertices and .faces (e.g. trimesh.Trimesh)") from None
        if verts.ndim != 2 or verts.shape[1] != 3 or not np.all(np.isfinite(verts)):
            raise SpecError("solid.vertices must be a finite (n, 3) array (mm)")
        man = m3d.Manifold(m3d.Mesh64(np.array(verts, order="C"), np.array(faces, order="C")))
    if man.status() != m3d.Error.NoError or man.is_empty():
        raise SpecError(f"solid is not a closed, oriented manifold ({man.status()}); "
                        "allowed watertight solids only")
    if man.volume() <= 0:
        raise SpecError("solid has non-positive volume (inside out?); allowed positive volume")
    return man


@dataclass(frozen=True, kw_only=True, eq=False)
class MeshCutter(Cutter):
    """Keep the material inside a user solid (manifold3d.Manifold or
    trimesh.Trimesh, mm, cannula frame); faces labelled ``cut:<name>``.

    ``source`` records where the solid came from (a file path) for specs.
    """

    solid_: Any = field(repr=False)
    name: str = "custom"
    source: str | None = None
    kind = "mesh"
    toml_keys = {"path": "mesh file, relative to the spec file",
                 "units": "mm, um or m; default the file's own (a tipgeo GLB says), else mm"}

    @classmethod
    def from_dict(cls, t: CutterTable) -> Cutter:
        return cls.from_file(t.path("path"), units=t.str("units"),
                             name=t.str("name", "custom"))

    def to_dict(self) -> dict[str, Any]:
        if not self.source:
            raise SpecError(f"mesh cutter '{self.name}' has no source file; it has no TOML form")
        return {"path": self.source}

    def __post_init__(self) -> None:
        object.__setattr__(self, "solid_", _as_manifold(self.solid_))
        check_name(self.name)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], *, name: str = "custom",
                  units: str | None = None) -> MeshCutter:
        """Load the kept solid from a mesh file (STL, PLY, OBJ, …) in
        ``units`` (default: the unit the file declares, else mm; see
        :func:`tipgeo.io.load_tip`), through the installed
        :data:`MeshReader`."""
        reader = mesh_reader()
        if reader is None:  # pragma: no cover - tipgeo/__init__.py installs it
            raise RuntimeError("no mesh reader installed; import tipgeo first")
        verts, faces = reader(str(path), units)
        return cls(solid_=_Mesh(verts, faces), name=name, source=str(path))

    def face_labels(self) -> tuple[str, ...]:
        return (self.label,)

    def z_upper(self, cannula: Cannula) -> float:
        return float(self.solid_.bounding_box()[5])

    def solid(self, ctx: BuildContext) -> Any:
        lid = ctx.labels.id(self.label)
        return ctx.labelled(self.solid_, lambda c, n: np.full(len(c), lid), self.label)


@dataclass(frozen=True, kw_only=True, eq=False)
class SDFCutter(Cutter):
    """Keep the material where a signed-distance function is ≤ 0.

    Parameters
    ----------
    sdf : callable
        ``sdf(points (n, 3) mm) -> (n,)``: negative inside the kept material,
        positive outside (mm, cannula frame). Vectorised over points.
    z_range : (float, float)
        The band of z (mm) that contains the cut surface over the tube wall.
        Below it everything is kept, above it nothing.
    edge_length : float, optional
        Level-set grid edge (mm); default from the tolerance, at least
        wall/40.
    name : str
    """

    sdf: Callable[[FloatArray], ArrayLike] = field(repr=False)
    z_range: tuple[float, float]
    edge_length: float | None = None
    name: str = "sdf"
    kind = "sdf"

    def __post_init__(self) -> None:
        if not callable(self.sdf):
            raise SpecError(f"sdf = {self.sdf!r} is not callable; expected f(points) -> values")
        try:
            lo, hi = (float(z) for z in self.z_range)
        except (TypeError, ValueError):
            raise SpecError(f"z_range = {self.z_range!r} is not a pair of numbers (mm)") from None
        v.real("z_range[0]", lo, unit="mm")
        v.real("z_range[1]", hi, lo=lo, lo_open=True, unit="mm")
        object.__setattr__(self, "z_range", (lo, hi))
        if self.edge_length is not None:
            v.feature_length("edge_length", self.edge_length, hi=10.0)
        check_name(self.name)

    def face_labels(self) -> tuple[str, ...]:
        return (self.label,)

    def z_upper(self, cannula: Cannula) -> float:
        return self.z_range[1]

    def _values(self, pts: FloatArray) -> FloatArray:
        val = np.asarray(self.sdf(pts), dtype=float).reshape(-1)
        if val.shape[0] != len(pts):
            raise SpecError(f"sdf returned {val.shape[0]} values for {len(pts)} points")
        if not np.all(np.isfinite(val)):
            raise SpecError("sdf returned non-finite values; expected finite distances (mm)")
        return val

    def implicit(self, points: FloatArray, cannula: Cannula) -> tuple[FloatArray, FloatArray]:
        p = np.asarray(points, float).reshape(-1, 3)
        h = tol.fd_step
        f = self._values(p)
        g = np.stack([(self._values(p + h * e) - self._values(p - h * e)) / (2 * h)
                      for e in np.eye(3)], 1)
        return f, g

    def solid(self, ctx: BuildContext) -> Any:
        lo, hi = self.z_range
        if lo <= ctx.z_lo:
            raise SpecError(f"z_range[0] = {lo:.6g} mm is below the tube base; allowed above "
                            f"{ctx.z_lo:.6g} mm")
        r = ctx.reach
        edge = self.edge_length or max(min(math.sqrt(8 * ctx.chordal * 0.5), 0.05),
                                       ctx.cannula.wall / 40)
        pad = 2 * edge
        band = (lo - pad, hi + pad)

        def f(x: float, y: float, z: float) -> float:  # manifold3d: positive inside; clip to
            val = float(-self._values(np.array([[x, y, z]]))[0])  # the box band
            return min(val, z - band[0], band[1] - z, r - abs(x), r - abs(y))
        ls = m3d.Manifold.level_set(f, [-r - pad, -r - pad, band[0] - pad, r + pad, r + pad,
                                        band[1] + pad], edge, 0.0, ctx.chordal)
        lid, aux = ctx.labels.id(self.label), ctx.labels.id(AUX)
        below = m3d.Manifold.cube((2 * r, 2 * r, band[0] + edge - ctx.z_lo)).translate(
            (-r, -r, ctx.z_lo))
        man = (ls + below)
        return ctx.labelled(man, lambda c, n: np.where(
            (np.abs(np.abs(c[:, 0]) - r) < tol.aux_face)
            | (np.abs(np.abs(c[:, 1]) - r) < tol.aux_face)
            | (c[:, 2] < band[0] - edge) | (c[:, 2] > band[1]), aux, lid), self.label)
