"""The needle's wall profile in the (r, z) half-plane, cut from the tip
itself, for axisymmetric models.

Frame and units: cannula frame, mm. A profile is the closed polygon of the
tip's cross-section by the half-plane γ = const (ρ = r ≥ 0), as ``(n, 2)``
float — ``(r, z)`` in mm, counter-clockwise, the tip's most advanced point at
``z.max()``. A tip is axisymmetric when every cutter of its spec says so
(conical cutters, a plain cannula); a tip without a spec is checked by
comparing its sections at four azimuths.
"""

from __future__ import annotations

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ..tip import Tip
from ..tolerances import tol

__all__ = ["wall_profile", "is_axisymmetric", "clip_profile", "polygon_area", "round_corners"]


def polygon_area(p: FloatArray) -> float:
    """Signed area of a closed polygon ``(n, 2)`` (positive counter-clockwise)."""
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _section(tip: Tip, gamma: float) -> FloatArray:
    """The cross-section of ``tip`` by the half-plane at azimuth γ (rad), as
    one closed (r, z) polygon, counter-clockwise, without repeated points."""
    m = tip.to_trimesh()
    c, s = np.cos(gamma), np.sin(gamma)
    sec = m.section(plane_origin=[0.0, 0.0, 0.0], plane_normal=[-s, c, 0.0])
    if sec is None:
        raise SpecError(f"tip '{tip.spec.name if tip.spec else '?'}' has no cross-section "
                        "through its axis; an axisymmetric model needs a tube wall")
    polys = []
    for loop in sec.discrete:
        r = loop[:, 0] * c + loop[:, 1] * s
        if np.all(r > -tol.fem.profile):
            polys.append(np.column_stack([np.maximum(r, 0.0), loop[:, 2]]))
    if len(polys) != 1:
        raise SpecError(f"the tip's section at γ = {np.degrees(gamma):.6g}° has {len(polys)} "
                        "wall loops on one side of the axis; an axisymmetric model needs "
                        "exactly one (a tube wall)")
    p = polys[0]
    if np.linalg.norm(p[0] - p[-1]) <= tol.fem.profile:
        p = p[:-1]
    keep = np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > tol.fem.profile]
    p = p[keep]
    if polygon_area(p) < 0:
        p = p[::-1]
    return p


def is_axisymmetric(tip: Tip) -> bool:
    """Whether ``tip`` is a solid of revolution about +z: from its spec when
    it has one (every cutter ``axisymmetric``), else from its sections at
    γ = 0, 90°, 180°, 270° (same area and extent within ``tol.fem.profile``
    mm)."""
    if tip.spec is not None:
        return all(getattr(c, "axisymmetric", False) for c in tip.spec.cutters)
    ref = None
    for g in np.radians([0.0, 90.0, 180.0, 270.0]):
        try:
            p = _section(tip, g)
        except SpecError:
            return False
        key = np.r_[polygon_area(p), p.min(axis=0), p.max(axis=0)]
        if ref is None:
            ref = key
        elif np.max(np.abs(key - ref)) > tol.fem.axisymmetry:
            return False
    return True


def wall_profile(tip: Tip) -> FloatArray:
    """The wall profile of an axisymmetric ``tip``.

    Returns
    -------
    (n, 2) float — (r, z) in mm, cannula frame, closed polygon (last point not
    repeated), counter-clockwise.

    Raises
    ------
    SpecError
        The tip is not axisymmetric (a bevel, a helix, serrations): use the
        3D model.
    """
    if not is_axisymmetric(tip):
        name = tip.spec.name if tip.spec is not None else "imported tip"
        kinds = ", ".join(sorted({c.kind for c in tip.spec.cutters
                                  if not getattr(c, "axisymmetric", False)})) \
            if tip.spec is not None else "not a solid of revolution"
        raise SpecError(f"tip '{name}' is not axisymmetric ({kinds}); model = 'axisymmetric' "
                        "needs conical cutters or a plain cannula; use model = '3d'")
    return _section(tip, 0.0)


def clip_profile(p: FloatArray, z_min: float) -> FloatArray:
    """The part of polygon ``p`` (r, z) with z ≥ ``z_min`` (Sutherland–Hodgman
    against one half-plane), closed polygon, counter-clockwise."""
    out = []
    n = len(p)
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        ina, inb = a[1] >= z_min, b[1] >= z_min
        if ina:
            out.append(a)
        if ina != inb:
            t = (z_min - a[1]) / (b[1] - a[1])
            out.append(a + t * (b - a))
    q = np.array(out)
    keep = np.r_[True, np.linalg.norm(np.diff(q, axis=0), axis=1) > tol.fem.profile]
    q = q[keep]
    if len(q) > 1 and np.linalg.norm(q[0] - q[-1]) <= tol.fem.profile:
        q = q[:-1]
    return q


def round_corners(p: FloatArray, which: ArrayLike, radius: float, n_arc: int = 6
                  ) -> FloatArray:
    """Polygon ``p`` (k, 2) with its convex corners ``which`` (indices)
    replaced by circular arcs of ``radius`` (mm), ``n_arc`` segments each; a
    corner whose neighbouring edges are too short for the radius gets the
    largest radius they allow."""
    p = np.asarray(p, dtype=float)
    ccw = polygon_area(p) > 0
    out = []
    corners = set(int(i) for i in np.asarray(which).ravel())
    n = len(p)
    for i in range(n):
        P, A, B = p[i], p[i - 1], p[(i + 1) % n]
        if i not in corners:
            out.append(P)
            continue
        u, w = A - P, B - P
        lu, lw = np.linalg.norm(u), np.linalg.norm(w)
        u, w = u / lu, w / lw
        cross = u[0] * w[1] - u[1] * w[0]
        convex = cross < 0 if ccw else cross > 0
        half = 0.5 * np.arccos(np.clip(np.dot(u, w), -1.0, 1.0))
        if not convex or half <= tol.angle or np.pi / 2 - half <= tol.angle:
            out.append(P)
            continue
        r = min(radius, 0.45 * min(lu, lw) * np.tan(half))
        t = r / np.tan(half)
        bis = (u + w) / np.linalg.norm(u + w)
        C = P + bis * r / np.sin(half)
        a0 = np.arctan2(*(P + u * t - C)[::-1])
        a1 = np.arctan2(*(P + w * t - C)[::-1])
        da = (a1 - a0 + np.pi) % (2 * np.pi) - np.pi
        for s in np.linspace(0.0, 1.0, n_arc + 1):
            a = a0 + s * da
            out.append(C + r * np.array([np.cos(a), np.sin(a)]))
    return np.asarray(out)
