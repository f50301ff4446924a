"""A virtual profilometer: synthetic scans of a tip with known errors.

Frames and units: the part is made in the cannula frame (mm); the scan is
returned in a *scanner frame* that differs from it by a known rigid
misalignment (:class:`Misalignment`, CAD → scanner). Angles in degrees only
in the ``*_deg`` fields.

What it models:

* **the part**: the spec, optionally with the bevel angle of its planar
  cutters changed (``xi_deg``: a bevel ground at 15.0° instead of 14.5°),
  its edges rounded (``edge_radius``: a morphological opening — every convex
  edge becomes a fillet of that radius, computed on the exact surfaces) and a
  burr along part of a cutting edge (:class:`Burr`);
* **the scanner**: orthographic views (unit directions *from* the scanner
  *to* the part). A surface point is measured when some view sees it: it faces
  that view within ``max_slope_deg`` and no other part of the tip occludes it
  (ray casting on the tip mesh with open3d — float32, used for visibility
  only; every coordinate is computed in double precision on the exact
  surfaces; a tip without them — serrations — is sampled on its fine mesh,
  ``tol.inspect.synth_chordal`` from the surface). Noise is Gaussian along
  the line of sight.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import SpecError, UnsupportedCutter
from ..tolerances import tol
from .exact import ExactSolid
from .scanio import write_ply

if TYPE_CHECKING:
    from ..spec import TipSpec

__all__ = ["Misalignment", "Burr", "SynthScan", "synthetic_scan", "default_views",
           "actual_spec", "rigid"]


def rigid(R: FloatArray, t: ArrayLike) -> FloatArray:
    """4×4 homogeneous matrix of x ↦ R x + t."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, float)
    return T


def _rot(axis: ArrayLike, angle: float) -> FloatArray:
    """3×3 rotation by ``angle`` (rad) about ``axis``."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R: FloatArray = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    return R


@dataclass(frozen=True)
class Misalignment:
    """A rigid misalignment, CAD (cannula frame) → scanner frame.

    x_scan = R_tilt · R_z(about_axis) · x + offset, where R_tilt turns by
    ``tilt_deg`` about the horizontal direction at ``tilt_axis_deg`` from +x.

    Attributes
    ----------
    about_axis_deg, tilt_deg, tilt_axis_deg : float — degrees
    offset_mm : (3,) float — mm
    """

    about_axis_deg: float = 0.0
    tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def matrix(self) -> FloatArray:
        """4×4 CAD → scanner."""
        rz = _rot((0, 0, 1), math.radians(self.about_axis_deg))
        ta = math.radians(self.tilt_axis_deg)
        rt = _rot((math.cos(ta), math.sin(ta), 0.0), math.radians(self.tilt_deg))
        return rigid(rt @ rz, self.offset_mm)


@dataclass(frozen=True)
class Burr:
    """A burr along a cutting edge: a ridge of triangular section standing
    ``height`` (mm) off the cut face and reaching ``width`` (mm) past the wall,
    over cannula-frame angles γ in ``gamma_deg`` (degrees, from +x about +z).

    ``edge``: ``inner`` (the bore side, where grinding burrs form) or ``outer``.
    """

    gamma_deg: tuple[float, float] = (160.0, 200.0)
    height: float = 0.015
    width: float = 0.010
    edge: str = "inner"


@dataclass
class SynthScan:
    """A synthetic scan and the truth it was made from.

    Attributes
    ----------
    points : (n, 3) float — mm, scanner frame
    points_cad : (n, 3) float — the same points, noise-free, in the cannula frame
    cad_to_scan : (4, 4) float — the misalignment applied
    part : TipSpec — the spec of the part as made (bevel angle changed etc.)
    kind : (n,) int8 — 0 surface, 1 rounded edge, 2 burr
    info : dict — the parameters (JSON-ready)
    """

    points: FloatArray
    points_cad: FloatArray
    cad_to_scan: FloatArray
    part: TipSpec
    kind: IntArray
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def scan_to_cad(self) -> FloatArray:
        """4×4 scanner → CAD: what registration should find."""
        return np.asarray(np.linalg.inv(self.cad_to_scan), np.float64)

    def write(self, path: str | os.PathLike[str]) -> Path:
        """Write the scan as a binary PLY (double coordinates, mm); returns the path."""
        return write_ply(path, self.points, comments=[
            "tipgeo synthetic scan, units mm, scanner frame",
            f"part {self.info.get('part', '')}"])


def actual_spec(spec: TipSpec, *, xi_deg: float | None = None) -> TipSpec:
    """The spec with the bevel angle ξ of its planar cutters set to ``xi_deg``
    (degrees): bevel, multi-plane, and the primary plane of a lancet."""
    if xi_deg is None:
        return spec
    xi = math.radians(xi_deg)
    cut = []
    changed = False
    for c in spec.cutters:
        if c.angle_field:  # the cutter's rake-plane bevel angle ξ
            # cutters are frozen dataclasses (mypy cannot see it through Cutter)
            c, changed = replace(cast(Any, c), **{c.angle_field: xi}), True
        cut.append(c)
    if not changed:
        raise SpecError(f"xi_deg = {xi_deg:g}: the spec has no bevel, multiplane or lancet "
                        "cutter whose angle could change")
    return spec.with_(cutters=tuple(cut), name=f"{spec.name or 'tip'}-as-made-xi{xi_deg:g}")


def default_views(*, elevation_deg: float = 30.0, count: int = 8) -> FloatArray:
    """``count`` views around the axis looking down at the tip from
    ``elevation_deg`` above the horizontal, plus one straight down the axis:
    (count + 1, 3) unit directions from the scanner to the part (cannula
    frame), like a profilometer with a rotation unit."""
    e = math.radians(elevation_deg)
    a = 2 * np.pi * np.arange(count) / count
    v = np.stack([-np.cos(a) * math.cos(e), -np.sin(a) * math.cos(e),
                  np.full(count, -math.sin(e))], 1)
    return np.vstack([v, [0.0, 0.0, -1.0]])


def _check_scan_args(spec: TipSpec, points: int, noise: float, edge_radius: float) -> None:
    if not isinstance(points, (int, np.integer)) or points < 10:
        raise SpecError(f"points = {points!r}; allowed an integer ≥ 10")
    if not (np.isfinite(noise) and noise >= 0):
        raise SpecError(f"noise = {noise!r} mm; allowed ≥ 0")
    if not (np.isfinite(edge_radius) and 0 <= edge_radius < 0.5 * spec.cannula.wall):
        raise SpecError(f"edge_radius = {edge_radius!r} mm; allowed 0 ≤ value < half the wall")


def _part_solid(part: TipSpec, edge_radius: float, burr: Burr | None) -> ExactSolid | None:
    """The part's exact solid; None for a tip without face-wise exact
    surfaces (serrations), which allows neither rounded edges nor burrs."""
    try:
        return ExactSolid(part)
    except UnsupportedCutter:
        # no face-wise exact surface (serrations): the points lie on the fine
        # mesh (chordal error ``tol.inspect.synth_chordal``), its facets' normals
        if edge_radius > 0 or burr is not None:
            raise SpecError(f"edge_radius = {edge_radius!r} mm, burr = {burr!r}: rounded edges "
                            f"and burrs need the exact surfaces, which '{part.name}' lacks; "
                            "allowed: edge_radius = 0 and no burr") from None
        return None


@dataclass
class _Sampler:
    """Surface sampling of a tip: its triangles above ``z_min`` (mm) with
    their areas, the exact solid (None: the mesh), the solid eroded by the
    edge radius (None: sharp edges) and the views' ray-casting scene."""

    tri: FloatArray
    roi: IntArray
    area: FloatArray
    z_min: float
    solid: ExactSolid | None
    eroded: ExactSolid | None
    edge_radius: float
    scene: Any
    o3d: Any
    views: FloatArray
    cos_max: float

    def batch(self, count: int, rng: np.random.Generator
              ) -> tuple[FloatArray, FloatArray, IntArray]:
        """``count`` area-uniform samples, those seen by some view: points
        (mm, cannula frame), their view directions, their kinds."""
        tri = self.tri
        k = rng.choice(self.roi, count, p=self.area / self.area.sum())
        r1, r2 = rng.random(count), rng.random(count)
        s = np.sqrt(r1)
        p = tri[k, 0] * (1 - s)[:, None] + tri[k, 1] * (s * (1 - r2))[:, None] \
            + tri[k, 2] * (s * r2)[:, None]
        if self.solid is not None:
            d = self.solid.distances(p)
            p, nrm = d.closest, d.normal               # onto the exact surface
        else:
            t = tri[k]
            nrm = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), tol.tiny)
        kind = np.zeros(len(p), np.int8)
        keep = p[:, 2] >= self.z_min
        p, nrm, kind = p[keep], nrm[keep], kind[keep]
        if self.eroded is not None:
            p, nrm = self._round(p, nrm, kind, self.eroded)
        vis_view = _visible_view(self.scene, self.o3d, p, nrm, self.views, self.cos_max, rng)
        ok = vis_view >= 0
        return p[ok], self.views[vis_view[ok]], kind[ok]

    def _round(self, p: FloatArray, nrm: FloatArray, kind: IntArray,
               eroded: ExactSolid) -> tuple[FloatArray, FloatArray]:
        """Points and normals with every convex edge rounded (kind 1 there):
        the opening of the solid by a ball of the edge radius."""
        r = self.edge_radius
        de = eroded.distances(p)
        v = p - de.closest
        dist = np.linalg.norm(v, axis=1)
        moved = dist > r * (1 + tol.rel)
        u = v / np.maximum(dist, tol.tiny)[:, None]
        kind[moved] = 1
        return (np.where(moved[:, None], de.closest + r * u, p),
                np.where(moved[:, None], u, nrm))


def _sample_seen(sampler: _Sampler, want: int, points: int, rng: np.random.Generator
                 ) -> tuple[FloatArray, FloatArray, IntArray]:
    """``want`` seen surface points, their view directions and kinds."""
    got_p, got_v, got_k = [], [], []
    have = 0
    batch = int(want * 2.5) + 1000
    for _ in range(20):
        p, v, kind = sampler.batch(batch, rng)
        got_p.append(p)
        got_v.append(v)
        got_k.append(kind)
        have += len(p)
        if have >= want:
            break
    if have < want:
        raise SpecError(f"points = {points}: the views see too little of the tip "
                        f"({have} visible points); add views or lower points")
    return (np.concatenate(got_p)[:want], np.concatenate(got_v)[:want],
            np.concatenate(got_k)[:want])


def _scan_info(spec: TipSpec, part: TipSpec, n: int, noise: float, xi_deg: float | None,
               edge_radius: float, burr: Burr | None, n_burr: int, z_min: float,
               views: FloatArray, max_slope_deg: float, seed: int,
               misalignment: Misalignment | None, M: FloatArray) -> dict[str, Any]:
    """The parameters of a synthetic scan, JSON-ready."""
    return {"cad": spec.name, "part": part.name, "points": int(n),
            "noise_mm": noise, "xi_deg": xi_deg, "edge_radius_mm": edge_radius,
            "burr": None if burr is None else {"gamma_deg": list(burr.gamma_deg),
                                               "height_mm": burr.height,
                                               "width_mm": burr.width, "edge": burr.edge,
                                               "points": int(n_burr)},
            "z_min_mm": z_min, "views": views.tolist(), "max_slope_deg": max_slope_deg,
            "seed": seed,
            "misalignment": None if misalignment is None else {
                "about_axis_deg": misalignment.about_axis_deg,
                "tilt_deg": misalignment.tilt_deg,
                "tilt_axis_deg": misalignment.tilt_axis_deg,
                "offset_mm": list(misalignment.offset_mm)},
            "cad_to_scan": M.tolist(), "scan_to_cad": np.linalg.inv(M).tolist()}


def synthetic_scan(spec: TipSpec, *, points: int = 200_000, noise: float = 0.001,
                   misalignment: Misalignment | None = None, views: ArrayLike | None = None,
                   xi_deg: float | None = None, edge_radius: float = 0.0,
                   burr: Burr | None = None, z_min: float = -1.0,
                   max_slope_deg: float = 80.0, seed: int = 0) -> SynthScan:
    """Scan a tip with a virtual profilometer (see module docstring).

    Parameters
    ----------
    spec : TipSpec — the CAD tip
    points : int — points in the scan (surface + burr)
    noise : float — σ of the noise along the line of sight (mm)
    misalignment : Misalignment — CAD → scanner (default none)
    views : (k, 3) float — view directions, cannula frame (default
        :func:`default_views`)
    xi_deg : float — bevel angle the part was actually ground at (degrees)
    edge_radius : float — fillet radius of every convex edge (mm)
    burr : Burr — a burr along a cutting edge
    z_min : float — lowest z scanned (mm, cannula frame; the heel is at 0)
    max_slope_deg : float — steepest surface a view measures (degrees)
    seed : int — random seed (scans are reproducible)

    Returns
    -------
    SynthScan
    """
    from .._open3d import import_open3d
    from ..build import build_tip

    _check_scan_args(spec, points, noise, edge_radius)
    rng = np.random.default_rng(seed)
    part = actual_spec(spec, xi_deg=xi_deg)
    solid = _part_solid(part, edge_radius, burr)
    tip = build_tip(part, tolerance=tol.inspect.synth_chordal)  # sampling and visibility only
    vw = default_views() if views is None else np.asarray(views, float).reshape(-1, 3)
    vw = vw / np.linalg.norm(vw, axis=1, keepdims=True)
    o3d = import_open3d()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(tip.vertices.astype(np.float32)),
                        o3d.core.Tensor(tip.faces.astype(np.uint32)))
    cos_max = math.cos(math.radians(max_slope_deg))
    eroded = ExactSolid(part, offset=edge_radius) if edge_radius > 0 else None

    tri = tip.triangles
    zc = tri[:, :, 2].max(axis=1)
    roi = np.flatnonzero(zc >= z_min)
    area = tip.face_areas[roi]
    n_burr = 0
    burr_pts = burr_dir = np.zeros((0, 3))
    if burr is not None and solid is not None:  # a burr needs the solid (_part_solid)
        # burr points at the surface density of the rest of the scan
        dens = points / max(area.sum(), tol.inspect.area_floor) * 0.5
        burr_pts, burr_dir = _burr_points(part, solid, burr, rng, density=dens)
        n_burr = min(len(burr_pts), points // 4)
        burr_pts, burr_dir = burr_pts[:n_burr], burr_dir[:n_burr]
    sampler = _Sampler(tri, roi, area, z_min, solid, eroded, edge_radius, scene, o3d, vw,
                       cos_max)
    p, v, kind = _sample_seen(sampler, points - n_burr, points, rng)
    if n_burr:
        # burrs are seen from the view best facing them (no occlusion test)
        p = np.vstack([p, burr_pts])
        v = np.vstack([v, -burr_dir])
        kind = np.concatenate([kind, np.full(n_burr, 2, np.int8)])
    perm = rng.permutation(len(p))
    p, v, kind = p[perm], v[perm], kind[perm]
    noisy = p + rng.normal(0.0, noise, len(p))[:, None] * v if noise > 0 else p.copy()
    M = (misalignment or Misalignment()).matrix()
    scan = noisy @ M[:3, :3].T + M[:3, 3]
    info = _scan_info(spec, part, len(p), noise, xi_deg, edge_radius, burr, n_burr, z_min, vw,
                      max_slope_deg, seed, misalignment, M)
    return SynthScan(scan, p, M, part, kind, info)


def _visible_view(scene: Any, o3d: Any, p: FloatArray, nrm: FloatArray, views: FloatArray,
                  cos_max: float, rng: np.random.Generator) -> IntArray:
    """Index of a (random) view that sees each point, −1 where none does."""
    n = len(p)
    seen = np.zeros((n, len(views)), bool)
    lift = tol.inspect.ray_lift  # start rays just off the surface (float32 only decides visibility)
    for j, v in enumerate(views):
        facing = nrm @ (-v) >= cos_max
        idx = np.flatnonzero(facing)
        if not len(idx):
            continue
        o = p[idx] - v * lift
        rays = np.hstack([o, np.broadcast_to(-v, o.shape)]).astype(np.float32)
        occ = scene.test_occlusions(o3d.core.Tensor(rays)).numpy()
        seen[idx[~occ], j] = True
    r = rng.random((n, len(views))) * seen
    out = np.argmax(r, axis=1)
    return np.where(seen.any(axis=1), out, -1)


def _burr_points(part: TipSpec, solid: ExactSolid, burr: Burr, rng: np.random.Generator,
                 density: float) -> tuple[FloatArray, FloatArray]:
    """Points on the exposed face of a burr ridge and its outward direction
    (cannula frame)."""
    if burr.edge not in ("inner", "outer"):
        raise SpecError(f"burr.edge = {burr.edge!r}; allowed 'inner' or 'outer'")
    if not (burr.height > 0 and burr.width > 0):
        raise SpecError("burr height and width must be > 0 mm")
    cn = part.cannula
    r = cn.r_i if burr.edge == "inner" else cn.r_o
    g0, g1 = (math.radians(a) for a in burr.gamma_deg)
    length = abs(g1 - g0) * r * 2.0  # generous: the edge also climbs in z
    span = math.hypot(burr.height, burr.width)
    count = max(int(density * length * span), 16)
    g = g0 + (g1 - g0) * rng.random(count)
    zs = [c.edge_z(g, r, cn) for c in part.cutters]
    exact = [z for z in zs if z is not None]
    if len(exact) < len(zs):
        raise SpecError("burrs need cutters with an exact edge (planar, conical, helical)")
    z = np.min(exact, axis=0)
    e = np.stack([r * np.cos(g), r * np.sin(g), z], 1)
    vals = solid.face_values(e)
    cut_faces = [k for k, lab in enumerate(solid.labels) if lab.startswith("cut:")]
    kc = np.asarray(cut_faces)[np.argmax(vals[:, cut_faces], axis=1)]
    n_c = np.empty_like(e)
    for k in np.unique(kc):
        s = kc == k
        n_c[s] = solid.faces[k].eval(e[s], 0.0)[1]
    radial = e.copy()
    radial[:, 2] = 0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    n_w = -radial if burr.edge == "inner" else radial
    s = rng.random(count)[:, None]
    out = burr.width * n_c + burr.height * n_w   # normal of the exposed face
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return e + (1 - s) * burr.height * n_c + s * burr.width * n_w, out
