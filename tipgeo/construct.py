"""Construction solids for the tip builder: labelled manifold3d solids.

Every solid made here carries a label id on each triangle (manifold3d
``face_id``), which survives the booleans, so every triangle of a built tip
knows which surface it came from. Faces that exist only to close a
construction solid are labelled ``aux``; the builder checks that none of them
survives in a tip.

Frame and units: cannula frame (+z along the axis towards the tip, γ about +z
from +x), lengths in mm, angles in radians.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import manifold3d as m3d
import numpy as np

from .arrays import FloatArray, IntArray
from .cannula import Cannula
from .errors import BuildError, SpecError
from .tolerances import MAX_ASPECT_RATIO, MIN_TOLERANCE_FRACTION, tol

__all__ = ["Labels", "BuildContext", "segments_for", "ring_spacing", "AUX", "OUTER", "INNER",
           "BASE"]

AUX, OUTER, INNER, BASE = "aux", "outer", "inner", "base"


@dataclass
class Labels:
    """Registry of face labels: name <-> integer id stored as ``face_id``."""

    names: list[str] = field(default_factory=lambda: [OUTER, INNER, BASE, AUX])

    def id(self, name: str) -> int:
        """The id of ``name``, registering it on first use."""
        if name not in self.names:
            self.names.append(name)
        return self.names.index(name)


def segments_for(radius: float, chordal: float, symmetry: int = 1) -> int:
    """Segments around a circle of ``radius`` (mm) so that the inscribed
    polygon deviates from it by at most ``chordal`` (mm), rounded up to a
    multiple of ``tol.segment_multiple`` and of ``symmetry``."""
    if chordal >= radius:
        raise SpecError(f"tolerance = {chordal:.6g} mm is not smaller than the radius "
                        f"{radius:.6g} mm; allowed 0 < tolerance < radius")
    floor = MIN_TOLERANCE_FRACTION * 2.0 * radius
    if not chordal >= floor:  # also NaN; before the segment count (1 - tol/r may round to 1)
        raise SpecError(f"tolerance = {chordal * 1e3:.6g} µm is finer than {floor * 1e3:.3g} µm "
                        f"({MIN_TOLERANCE_FRACTION:g} × the {2 * radius:.6g} mm tube diameter); "
                        f"allowed at least {floor * 1e3:.3g} µm (raise --tolerance-um or "
                        "tolerance_um)")
    n = math.ceil(math.pi / math.acos(1.0 - chordal / radius))
    k = math.lcm(tol.segment_multiple, max(int(symmetry), 1))
    n = max(tol.min_segments, k * math.ceil(n / k))
    if n > tol.max_segments:
        raise SpecError(f"tolerance = {chordal * 1e3:.6g} µm needs {n} segments around the tube; "
                        f"allowed at most {tol.max_segments} (raise the tolerance)")
    return n


def ring_spacing(radius: float, segments: int) -> float:
    """Largest z spacing (mm) of the tube's vertex rings: a wall quad of
    width w = 2π·radius/segments and this height h = 0.9 ``MAX_ASPECT_RATIO``
    · w splits into two right triangles of aspect ratio (longest edge /
    shortest altitude) h/w + w/h, under the bound with room for the cuts
    that trim them."""
    return 0.9 * MAX_ASPECT_RATIO * 2.0 * math.pi * radius / segments


def _manifold(verts: FloatArray, tris: IntArray, face_ids: IntArray, what: str) -> m3d.Manifold:
    # nanobind wants writable, owned, C-ordered arrays
    mesh = m3d.Mesh64(np.array(verts, dtype=np.float64, order="C", copy=True),
                      np.array(tris, dtype=np.uint64, order="C", copy=True),
                      face_id=np.array(face_ids, dtype=np.uint64, order="C", copy=True))
    man = m3d.Manifold(mesh)
    if man.status() != m3d.Error.NoError or man.is_empty():
        raise BuildError(f"construction solid '{what}' is not a closed manifold ({man.status()})")
    return man


def _ring_quads(a: IntArray, b: IntArray, flip: bool) -> IntArray:
    """Triangles joining two closed vertex rings a, b (index arrays, same length)."""
    a1, b1 = np.roll(a, -1), np.roll(b, -1)
    t = np.concatenate([np.stack([a, a1, b1], 1), np.stack([a, b1, b], 1)])
    return t[:, ::-1] if flip else t


@dataclass
class BuildContext:
    """What a cutter needs to make its solid.

    Attributes
    ----------
    cannula : Cannula
    chordal : float
        Chordal tolerance (mm).
    segments : int
        Segments around the tube (tube vertices at γ = 2πk/segments).
    z_bottom : float
        Base of the tube, z = -cannula.length (mm).
    z_top : float
        Top of the uncut tube (mm), above every cutter's kept region.
    labels : Labels
    previous : tuple
        Cutters applied before the current one, in order.
    rings : bool
        Split the tube's walls and the frustums' sides into rings no farther
        apart than :func:`ring_spacing` (a mesh without long slivers, for
        exports); otherwise one band from bottom to top.
    """

    cannula: Cannula
    chordal: float
    segments: int
    z_bottom: float
    z_top: float
    labels: Labels = field(default_factory=Labels)
    previous: tuple[Any, ...] = ()  # the cutters applied before the current one
    rings: bool = False

    @property
    def margin(self) -> float:
        """Clearance of construction faces from the tube (mm)."""
        return tol.margin_ratio * self.cannula.r_o

    @property
    def reach(self) -> float:
        """Half-width of construction boxes (mm): beyond the tube."""
        return self.cannula.r_o + 2.0 * self.margin

    @property
    def z_lo(self) -> float:
        """Bottom of construction solids (mm), below the tube base."""
        return self.z_bottom - 2.0 * self.margin

    @property
    def z_hi(self) -> float:
        """Top of construction solids (mm), above the tube top."""
        return self.z_top + 2.0 * self.margin

    # -- the tube ---------------------------------------------------------
    def tube(self) -> m3d.Manifold:
        """The uncut tube r_i ≤ ρ ≤ r_o, z_bottom ≤ z ≤ z_top, labelled
        ``outer``, ``inner``, ``base`` (z = z_bottom) and ``aux`` (the top).

        With ``rings`` the walls are split into rings along z no farther
        apart than :func:`ring_spacing`, so no wall triangle is a long
        sliver."""
        n = self.segments
        g = 2.0 * np.pi * np.arange(n) / n
        c, s = np.cos(g), np.sin(g)
        zb, zt = self.z_bottom, self.z_top
        verts: list[FloatArray] = []
        rings: list[list[IntArray]] = []
        for r in (self.cannula.r_o, self.cannula.r_i):
            bands = math.ceil((zt - zb) / ring_spacing(r, n)) if self.rings else 1
            zs = np.linspace(zb, zt, max(1, bands) + 1)
            start = sum(len(v) for v in verts)
            verts += [np.stack([r * c, r * s, np.full(n, z)], 1) for z in zs]
            rings.append([start + j * n + np.arange(n) for j in range(len(zs))])
        ro_, ri_ = rings
        outer = np.concatenate([_ring_quads(a, b, False) for a, b in zip(ro_, ro_[1:])])
        inner = np.concatenate([_ring_quads(a, b, True) for a, b in zip(ri_, ri_[1:])])
        tris = [outer, inner, _ring_quads(ri_[0], ro_[0], False),
                _ring_quads(ri_[-1], ro_[-1], True)]
        lab = [self.labels.id(OUTER), self.labels.id(INNER), self.labels.id(BASE),
               self.labels.id(AUX)]
        ids = np.concatenate([np.full(len(t), k) for t, k in zip(tris, lab)])
        return _manifold(np.concatenate(verts), np.concatenate(tris), ids, "tube")

    # -- primitives for cutters --------------------------------------------
    def labelled(self, man: m3d.Manifold, classify: Callable[[FloatArray, FloatArray], IntArray],
                 what: str) -> m3d.Manifold:
        """Re-make ``man`` as an original solid whose triangles carry the label
        ids returned by ``classify(centroids, unit_normals)``."""
        mesh = man.to_mesh64()
        verts = np.asarray(mesh.vert_properties)[:, :3]
        tris = np.asarray(mesh.tri_verts).astype(np.int64)
        p = verts[tris]
        nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), tol.tiny)
        ids = np.asarray(classify(p.mean(axis=1), nrm), dtype=np.int64)
        return _manifold(verts, tris, ids, what)

    def box(self) -> m3d.Manifold:
        """Axis-aligned construction box around the tube (unlabelled)."""
        r = self.reach
        return m3d.Manifold.cube((2 * r, 2 * r, self.z_hi - self.z_lo)).translate(
            (-r, -r, self.z_lo))

    def halfspace(self, normal: FloatArray, offset: float, label: str) -> m3d.Manifold:
        """Box ∩ {p : normal·p ≤ offset}; the plane's triangles get ``label``."""
        nrm = np.asarray(normal, dtype=float)
        nrm = nrm / np.linalg.norm(nrm)
        man = self.box().trim_by_plane(tuple(-nrm), -float(offset))
        if man.is_empty():
            raise BuildError(f"plane of '{label}' leaves nothing of the tube region")
        lid, aux = self.labels.id(label), self.labels.id(AUX)
        scale = max(self.reach, abs(self.z_lo), abs(self.z_hi))

        def classify(cent: FloatArray, nr: FloatArray) -> IntArray:
            on = ((np.abs(cent @ nrm - offset) <= 1e3 * tol.plane * scale)
                  & (nr @ nrm > 1 - tol.parallel))
            return np.where(on, lid, aux)
        return self.labelled(man, classify, label)

    def frustum(self, z0: float, r0: float, z1: float, r1: float, side: str, top: str,
                phase: float = 0.0) -> m3d.Manifold:
        """Solid of revolution about +z between z0 (radius r0) and z1 (radius
        r1, may be 0), polygonal with ``segments`` sides starting at angle
        ``phase``. Side triangles get ``side``, the top cap ``top``, the
        bottom cap ``aux``. With ``rings`` the side is split into bands along
        its slant no longer than :func:`ring_spacing` at the tube's outer
        radius, so its triangles are no slivers where they cross the tube
        wall (and stay small for the boolean's bounding boxes)."""
        n = self.segments
        g = phase + 2.0 * np.pi * np.arange(n) / n
        c, s = np.cos(g), np.sin(g)
        slant = math.hypot(z1 - z0, r1 - r0)
        nb = max(1, math.ceil(slant / ring_spacing(self.cannula.r_o, n))) if self.rings else 1
        ts = np.linspace(0.0, 1.0, nb + 1)
        if not r1 > 0:
            ts = ts[:-1]  # the apex is one vertex
        zs, rs = z0 + ts * (z1 - z0), r0 + ts * (r1 - r0)
        verts = [np.stack([r * c, r * s, np.full(n, z)], 1) for r, z in zip(rs, zs)]
        rings = [j * n + np.arange(n) for j in range(len(zs))]
        sides = [_ring_quads(a, b, False) for a, b in zip(rings, rings[1:])]
        cb = len(zs) * n
        verts.append(np.array([[0.0, 0.0, z0], [0.0, 0.0, z1]]))
        b, t = rings[0], rings[-1]
        bcap = np.stack([np.full(n, cb), np.roll(b, -1), b], 1)
        if r1 > 0:
            caps = [bcap, np.stack([np.full(n, cb + 1), t, np.roll(t, -1)], 1)]
            cap_ids = [self.labels.id(AUX), self.labels.id(top)]
        else:
            sides.append(np.stack([t, np.roll(t, -1), np.full(n, cb + 1)], 1))
            caps, cap_ids = [bcap], [self.labels.id(AUX)]
        side_tris = np.concatenate(sides)
        tris = np.concatenate([side_tris] + caps)
        ids = np.concatenate([np.full(len(side_tris), self.labels.id(side))]
                             + [np.full(n, k) for k in cap_ids])
        return _manifold(np.concatenate(verts), tris, ids, side)

    def prism(self, polygon: FloatArray, thickness: float, side: str) -> m3d.Manifold:
        """Right prism over a simple CCW polygon (k, 2) in the XY plane, from
        Z = 0 to Z = thickness, vertices exactly as given (no simplification).
        Side triangles get ``side``, the caps ``aux``."""
        poly = np.asarray(polygon, dtype=float)
        k = len(poly)
        caps = np.asarray(m3d.triangulate([poly]), dtype=np.int64)
        verts = np.concatenate([np.c_[poly, np.zeros(k)],
                                np.c_[poly, np.full(k, thickness)]])
        a = np.arange(k)
        sides = _ring_quads(a, a + k, False)
        tris = np.concatenate([sides, caps[:, ::-1], caps + k])
        ids = np.concatenate([np.full(len(sides), self.labels.id(side)),
                              np.full(2 * len(caps), self.labels.id(AUX))])
        man = _manifold(verts, tris, ids, side)
        if man.volume() <= 0:
            raise BuildError(f"prism of '{side}' is inside out (polygon not CCW)")
        return man

    def annular_heightfield(self, height: Callable[[FloatArray, FloatArray], FloatArray],
                            label: str, angular: int | FloatArray,
                            radial: int) -> m3d.Manifold:
        """Solid {r_in ≤ ρ ≤ r_out, z_lo ≤ z ≤ height(x, y)} over an annulus a
        little wider than the tube wall, as a polygonal grid of ``angular`` ×
        ``radial`` vertices. ``angular``: a count (uniform angles offset half
        a tube step so no vertex coincides with a tube vertex), or the grid's
        angles themselves (rad about +z, increasing in [0, 2π): a grid
        refined where the surface curves, :mod:`tipgeo.cutters.helical`).
        The top gets ``label``."""
        ro, ri = self.cannula.r_o, self.cannula.r_i
        d = 0.1037 * (ro - ri)
        rad = np.linspace(max(ri - d, 0.5 * ri), ro + d, radial)
        if isinstance(angular, (int, np.integer)) or np.ndim(angular) == 0:
            g = (np.arange(int(angular)) + 0.5) * 2.0 * np.pi / int(angular)
        else:
            g = np.asarray(angular, dtype=float)
            if not (g.ndim == 1 and len(g) >= 3 and np.all(np.diff(g) > 0)
                    and g[0] >= 0.0 and g[-1] < 2.0 * np.pi):
                raise BuildError(f"surface '{label}': its grid angles must increase "
                                 "within [0, 2π)")
        angular = len(g)
        rr, gg = np.meshgrid(rad, g, indexing="ij")  # (radial, angular)
        x, y = rr * np.cos(gg), rr * np.sin(gg)
        z = np.asarray(height(x.ravel(), y.ravel()), dtype=float).reshape(x.shape)
        if not np.all(np.isfinite(z)):
            raise BuildError(f"surface '{label}' is undefined over part of the tube wall")
        if z.min() <= self.z_lo:
            raise BuildError(f"surface '{label}' dips below the tube base (z = {z.min():.4g} mm)")
        top = np.stack([x, y, z], -1).reshape(-1, 3)
        # the base (below the tube, never cut) needs only the inner and outer rings
        bot = np.stack([x[[0, -1]], y[[0, -1]], np.full((2, angular), self.z_lo)],
                       -1).reshape(-1, 3)
        verts = np.concatenate([top, bot])
        idx = np.arange(radial * angular).reshape(radial, angular)
        nt = radial * angular
        b_in, b_out = nt + np.arange(angular), nt + angular + np.arange(angular)
        lid, aux = self.labels.id(label), self.labels.id(AUX)
        tris = [_ring_quads(idx[j], idx[j + 1], False)[:, [0, 2, 1]]  # top, normals up
                for j in range(radial - 1)]
        ids = [np.full(2 * angular * (radial - 1), lid)]
        tris.append(_ring_quads(b_in, b_out, False))            # base, normals down
        tris.append(_ring_quads(idx[-1], b_out, True))          # outer wall
        tris.append(_ring_quads(idx[0], b_in, False))           # inner wall
        ids.append(np.full(6 * angular, aux))
        man = _manifold(verts, np.concatenate(tris), np.concatenate(ids), label)
        if man.volume() <= 0:
            raise BuildError(f"heightfield solid of '{label}' is inside out")
        return man
