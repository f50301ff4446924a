"""Exact signed distance to a tip solid described by its spec.

Frame and units: cannula frame (+z along the axis towards the tip, heel at
z = 0), mm.

A tip is tube ∩ cutters, so its solid is the intersection of half-spaces
``f_k ≤ 0``, one per analytic face: the outer cylinder ρ ≤ r_o, the bore
ρ ≥ r_i, the base z ≥ −length and every cutter face (planes of bevel,
multi-plane and lancet cutters, the cone and land of a conical cutter, the
helicoid of a helical cutter). Each ``f_k`` is the signed distance to its own
surface (exactly for planes, cylinders and cones; by foot-point iteration for
implicit surfaces), which gives exact distances to the solid:

* **inside** (every f_k ≤ 0): the distance to the boundary is min_k |f_k| —
  the complement of an intersection is the union of the complements — and the
  closest point is the foot on that face;
* **outside**: max_k f_k is a lower bound (the solid lies in every
  half-space); when the foot on the face attaining it lies in the solid, it
  is the closest point. Otherwise the closest point lies on an edge (two
  surfaces) or a vertex (three): it is found by projecting onto the curve
  f_a = f_b = 0 (Newton steps onto the curve, tangential steps towards the
  point) or solving f_a = f_b = f_c = 0, keeping candidates that lie in the
  solid and satisfy the KKT sign conditions, and taking the nearest.

The sign is the CSG sign — inside iff every f_k ≤ 0 — so it never depends on
which of two tied faces is "first": at a knife edge it is right on both sides.
Nothing is tessellated, so the mesh's chordal error never enters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..arrays import AnyArray, ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import TipGeoError, UnsupportedCutter
from ..tolerances import tol

__all__ = ["Distances", "ExactSolid", "UnsupportedCutter"]


@dataclass
class Distances:
    """Signed distances of points to a CAD solid.

    Attributes
    ----------
    distance : (n,) float — mm; > 0 outside the solid (excess material), < 0 inside
    closest : (n, 3) float — closest point on the CAD surface (mm, cannula frame)
    normal : (n, 3) float — unit outward normal at the closest point (for edge
        and vertex points the direction from the closest point to the point)
    face : (n,) int — index into ``labels`` of the face the point belongs to
    feature : (n,) int8 — 0 closest point inside a face, 1 on an edge, 2 at a vertex
    labels : tuple of str — face labels (``outer``, ``inner``, ``base``, ``cut:…``)
    """

    distance: np.ndarray
    closest: np.ndarray
    normal: np.ndarray
    face: np.ndarray
    feature: np.ndarray
    labels: tuple[str, ...]

    def label_of(self) -> AnyArray:
        """(n,) object — the face label of every point."""
        out: AnyArray = np.asarray(self.labels, dtype=object)[self.face]
        return out


# -----------------------------------------------------------------------------
# faces: f ≤ 0 inside; eval gives f (signed distance to the surface for exact
# faces) and the unit outward gradient.
class _Face:
    label: str
    exact: bool = True

    def eval(self, p: np.ndarray, off: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def value(self, p: np.ndarray, off: float) -> np.ndarray:
        return self.eval(p, off)[0]

    def foot(self, p: np.ndarray, off: float) -> np.ndarray:
        f, g = self.eval(p, off)
        out: FloatArray = p - f[:, None] * g
        return out

    def signed(self, p: np.ndarray, off: float) -> np.ndarray:
        """Signed distance to the face's surface (exact)."""
        return self.value(p, off)


class _PlaneFace(_Face):
    def __init__(self, normal: ArrayLike, offset: float, label: str) -> None:
        n = np.asarray(normal, float)
        self.n = n / np.linalg.norm(n)
        self.d = float(offset)
        self.label = label

    def value(self, p: FloatArray, off: float) -> FloatArray:
        out: FloatArray = p @ self.n - self.d + off
        return out

    def eval(self, p: FloatArray, off: float) -> tuple[FloatArray, FloatArray]:
        return self.value(p, off), np.broadcast_to(self.n, p.shape)


def _radial(p: FloatArray) -> tuple[FloatArray, FloatArray]:
    rho = np.hypot(p[:, 0], p[:, 1])
    safe = np.where(rho > 0, rho, 1.0)
    u = np.stack([np.where(rho > 0, p[:, 0] / safe, 1.0), p[:, 1] / safe,
                  np.zeros(len(p))], 1)
    return rho, u


class _CylinderFace(_Face):
    """ρ ≤ r (outer wall, ``inside=True``) or ρ ≥ r (bore)."""

    def __init__(self, radius: float, keep_inside: bool, label: str) -> None:
        self.r = float(radius)
        self.s = 1.0 if keep_inside else -1.0
        self.label = label

    def value(self, p: FloatArray, off: float) -> FloatArray:
        return self.s * (np.hypot(p[:, 0], p[:, 1]) - self.r) + off

    def eval(self, p: FloatArray, off: float) -> tuple[FloatArray, FloatArray]:
        rho, u = _radial(p)
        return self.s * (rho - self.r) + off, self.s * u


class _ConeFace(_Face):
    """ρ cos θ + z sin θ ≤ r_o cos θ (cone of half-angle θ about +z); the
    distance to the cone's line in the (ρ, z) half-plane, exact while the foot
    has ρ ≥ 0 (everywhere near a tip's faces)."""

    def __init__(self, theta: float, r_o: float, label: str) -> None:
        self.c, self.s_ = math.cos(theta), math.sin(theta)
        self.r = float(r_o)
        self.label = label

    def eval(self, p: FloatArray, off: float) -> tuple[FloatArray, FloatArray]:
        rho, u = _radial(p)
        f = rho * self.c + p[:, 2] * self.s_ - self.r * self.c + off
        g = u * self.c
        g[:, 2] = self.s_
        return f, g


class _ImplicitFace(_Face):
    """A cutter's own implicit surface (e.g. the helicoid): f/|∇f| is only a
    first-order distance, so distances come from foot-point iteration."""

    exact = False

    def __init__(self, cutter: Any, cannula: Any, label: str) -> None:
        self.cutter, self.cannula, self.label = cutter, cannula, label

    def eval(self, p: FloatArray, off: float) -> tuple[FloatArray, FloatArray]:
        f, g = self.cutter.implicit(p, self.cannula)
        nrm = np.linalg.norm(g, axis=1)
        nrm = np.where(nrm > 0, nrm, 1.0)
        return f / nrm + off, g / nrm[:, None]

    def foot(self, p: FloatArray, off: float) -> FloatArray:
        x = p.copy()
        for _ in range(3):
            f, g = self.eval(x, off)
            x = x - f[:, None] * g
        for _ in range(tol.inspect.max_iterations):
            f, g = self.eval(x, off)
            y = p - np.einsum("ij,ij->i", p - x, g)[:, None] * g  # tangent plane
            for _ in range(2):
                fy, gy = self.eval(y, off)
                y = y - fy[:, None] * gy
            step = np.linalg.norm(y - x, axis=1)
            x = y
            if step.max(initial=0.0) < tol.inspect.converge:
                break
        return x

    def signed(self, p: FloatArray, off: float) -> FloatArray:
        x = self.foot(p, off)
        f = self.value(p, off)
        out: FloatArray = np.where(f >= 0, 1.0, -1.0) * np.linalg.norm(p - x, axis=1)
        return out


def _faces_of(spec: Any) -> list[_Face]:
    """The analytic faces of a spec (labels as in the built tip), from each
    cutter's :meth:`~tipgeo.cutters.base.Cutter.surfaces`."""
    from ..cutters import ConeSurface, ImplicitSurface, Plane

    cn = spec.cannula
    faces: list[_Face] = [_CylinderFace(cn.r_o, True, "outer"),
                          _CylinderFace(cn.r_i, False, "inner"),
                          _PlaneFace((0.0, 0.0, -1.0), cn.length, "base")]
    for c in spec.cutters:
        surfaces = c.surfaces(cn)
        if not surfaces:
            raise UnsupportedCutter(
                f"cutter '{c.name}' ({c.kind}) has no face-wise exact surface; "
                "deviations are measured against the tip mesh instead")
        for f in surfaces:
            if isinstance(f, Plane):
                faces.append(_PlaneFace(f.normal, f.offset, f.label))
            elif isinstance(f, ConeSurface):
                faces.append(_ConeFace(f.theta, f.r_o, f.label))
            elif isinstance(f, ImplicitSurface):
                faces.append(_ImplicitFace(f.cutter, f.cannula, f.label))
            else:
                raise UnsupportedCutter(f"cutter '{c.name}': face {f!r} is of no known kind")
    return faces


def _rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out: FloatArray = np.einsum("ij,ij->i", a, b)
    return out


class ExactSolid:
    """The tip solid of a spec as exact analytic faces (see module docstring).

    Parameters
    ----------
    spec : TipSpec
    offset : float
        Shrink the solid by this distance (mm, ≥ 0): every face moves inwards
        (the erosion used to round edges in synthetic scans).

    Raises
    ------
    UnsupportedCutter
        A cutter (serration, mesh, SDF) has no face-wise exact surface.
    """

    def __init__(self, spec: Any, *, offset: float = 0.0) -> None:
        self.spec = spec
        self.faces = _faces_of(spec)
        self.labels = tuple(f.label for f in self.faces)
        self.offset = float(offset)
        self.exact = all(f.exact for f in self.faces)

    # -- values ---------------------------------------------------------------
    def face_values(self, points: np.ndarray) -> np.ndarray:
        """(n, K) signed distance of every point to every face's surface (mm)."""
        p = _points(points)
        return np.stack([f.signed(p, self.offset) for f in self.faces], 1)

    def face_fields(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every face's function and its unit outward gradient at every point.

        Returns
        -------
        values : (n, K) float — mm; the signed distance to each face's surface
            (first-order for implicit faces, exact for the others)
        gradients : (n, K, 3) float — unit outward normals of the faces'
            surfaces (or of their level sets through the points)
        """
        p = _points(points)
        out = [f.eval(p, self.offset) for f in self.faces]
        return np.stack([v for v, _ in out], 1), np.stack([np.asarray(g) for _, g in out], 1)

    def bound(self, points: np.ndarray) -> np.ndarray:
        """max_k f_k: the exact signed distance inside the solid, a lower bound
        of it outside (mm). Cheap: no projections (first-order for implicit
        faces)."""
        p = _points(points)
        out: FloatArray = np.max(np.stack([f.value(p, self.offset) for f in self.faces], 1),
                                 axis=1)
        return out

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool — inside or on the solid (every face function ≤ 0)."""
        return self.bound(points) <= 0.0

    # -- the query -------------------------------------------------------------
    def distances(self, points: np.ndarray) -> Distances:
        """Exact signed distance, closest point, normal and face of every point.

        Parameters
        ----------
        points : (n, 3) float — mm, cannula frame

        Returns
        -------
        Distances
        """
        p = _points(points)
        n, off = len(p), self.offset
        F = self.face_values(p)
        k = np.argmax(F, axis=1)
        fmax = F[np.arange(n), k]
        x = np.empty_like(p)
        for j, face in enumerate(self.faces):
            s = k == j
            if s.any():
                x[s] = face.foot(p[s], off)
        dist = fmax.copy()
        face_id = k.copy()
        feature = np.zeros(n, np.int8)
        # outside: is the foot on the most violated face in the solid?
        out = np.flatnonzero(fmax > 0)
        if len(out):
            G = self._values(x[out])
            G[np.arange(len(out)), k[out]] = -np.inf
            bad = G.max(axis=1) > tol.inspect.feasible
            todo = out[bad]
            if len(todo):
                viol = (F[todo] > 0) | (G[bad] > tol.inspect.feasible)
                viol[np.arange(len(todo)), k[todo]] = True
                d2, x2, f2, ft2 = self._features(p[todo], x[todo], viol)
                dist[todo], x[todo], face_id[todo], feature[todo] = d2, x2, f2, ft2
        normal = self._normals(p, x, dist, face_id, feature)
        return Distances(dist, x, normal, face_id, feature, self.labels)

    # -- internals -------------------------------------------------------------
    def _values(self, x: FloatArray) -> FloatArray:
        return np.stack([f.value(x, self.offset) for f in self.faces], 1)

    def _normals(self, p: FloatArray, x: FloatArray, dist: FloatArray, face_id: IntArray,
                 feature: IntArray) -> FloatArray:
        nrm = np.empty_like(p)
        for j, face in enumerate(self.faces):
            s = face_id == j
            if s.any():
                nrm[s] = face.eval(x[s], self.offset)[1]
        e = (feature > 0) & (np.abs(dist) > 0)
        if e.any():
            v = p[e] - x[e]
            nrm[e] = v / np.linalg.norm(v, axis=1, keepdims=True)
        return nrm

    def _features(self, p: FloatArray, seed: FloatArray,
                  viol: BoolArray) -> tuple[FloatArray, FloatArray, IntArray, IntArray]:
        """Closest points on edges/vertices for points whose face foot left the
        solid. ``viol`` (m, K) marks the faces involved per point."""
        m, K = viol.shape
        best = np.full(m, np.inf)
        bx = seed.copy()
        bface = np.zeros(m, np.int64)
        bfeat = np.ones(m, np.int8)
        # the closest point may lie inside another violated face (not only the
        # most violated one's): e.g. a point in the bore above a two-plane ridge
        for a in range(K):
            s = np.flatnonzero(viol[:, a])
            if not len(s):
                continue
            xf = self.faces[a].foot(p[s], self.offset)
            G = self._values(xf)
            G[:, a] = -np.inf
            feas = G.max(axis=1) <= tol.inspect.feasible
            d = np.linalg.norm(p[s] - xf, axis=1)
            better = feas & (d < best[s])
            sb = s[better]
            best[sb], bx[sb], bface[sb], bfeat[sb] = d[better], xf[better], a, 0
        def inside_others(x: FloatArray, own: list[int], lam: FloatArray,
                          ok: BoolArray) -> tuple[FloatArray, BoolArray]:
            """Face values at x (own faces masked) and whether x is a feasible
            closest point: inside every other face, multipliers ≥ 0."""
            G = self._values(x)
            G[:, own] = -np.inf
            return G, ok & (G.max(axis=1) <= tol.inspect.feasible) & np.all(
                lam >= -tol.inspect.multiplier, axis=1)

        def try_edge(s: IntArray, seeds: FloatArray, a: int, b: int, accelerate: bool) -> None:
            xe, lam, ok = self._edge(p[s], seeds, a, b, accelerate=accelerate)
            G, feas = inside_others(xe, [a, b], lam, ok)
            d = np.linalg.norm(p[s] - xe, axis=1)
            better = feas & (d < best[s])
            sb = s[better]
            best[sb], bx[sb] = d[better], xe[better]
            bface[sb] = np.where(lam[better, 0] >= lam[better, 1], a, b)
            bfeat[sb] = 1
            # a third face cuts the edge there: try the vertex
            third = ~feas & ok
            if third.any():
                c_of = np.argmax(np.where(np.isfinite(G), G, -np.inf), axis=1)
                for c in np.unique(c_of[third]):
                    key = tuple(sorted((a, b, int(c))))
                    sv = s[third & (c_of == c)]
                    xv, lv, okv = self._vertex(p[sv], xe[third & (c_of == c)], key)
                    _, fv = inside_others(xv, list(key), lv, okv)
                    dv = np.linalg.norm(p[sv] - xv, axis=1)
                    bv = fv & (dv < best[sv])
                    svb = sv[bv]
                    best[svb], bx[svb] = dv[bv], xv[bv]
                    bface[svb] = np.asarray(key)[np.argmax(lv[bv], axis=1)]
                    bfeat[svb] = 2

        for a in range(K):
            for b in range(a + 1, K):
                s = np.flatnonzero(viol[:, a] & viol[:, b])
                if len(s):
                    try_edge(s, seed[s], a, b, True)
        lost = np.flatnonzero(~np.isfinite(best))
        if len(lost):  # rare: the accelerated walk along an edge overshot; walk again,
            for a in range(K):  # from both faces' feet, without acceleration
                for b in range(a + 1, K):
                    s = lost[viol[lost, a] & viol[lost, b]]
                    for f in (a, b):
                        if len(s):
                            try_edge(s, self.faces[f].foot(p[s], self.offset), a, b, False)
        lost = ~np.isfinite(best)
        if lost.any():
            raise TipGeoError(f"{int(lost.sum())} point(s): no closest point on the exact "
                              "surfaces (far outside the tip?)")
        return best, bx, bface, bfeat

    def _edge(self, p: FloatArray, x: FloatArray, a: int, b: int, *,
              accelerate: bool = True) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Closest point to p on the curve f_a = f_b = 0, from seeds x.

        Alternates a Newton step onto the curve (minimum-norm correction) with
        a step along the tangent towards p; the tangential steps shrink
        geometrically (ratio ≈ curvature × distance), so each is stretched by
        Aitken's 1/(1 − ratio). Points drop out as they converge."""
        fa_, fb_ = self.faces[a], self.faces[b]
        off = self.offset
        x = x.copy()
        ok = np.ones(len(p), bool)
        act = np.arange(len(p))
        prev = np.zeros(len(p))

        def onto(xx: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
            for _ in range(3):
                fa, ga = fa_.eval(xx, off)
                fb, gb = fb_.eval(xx, off)
                aa, ab, bb = _rows(ga, ga), _rows(ga, gb), _rows(gb, gb)
                det = aa * bb - ab * ab
                good = det > tol.inspect.gram_det
                det = np.where(good, det, 1.0)
                la = (bb * fa - ab * fb) / det
                lb = (aa * fb - ab * fa) / det
                xx = xx - la[:, None] * ga - lb[:, None] * gb
            return xx, ga, gb, good

        for _ in range(tol.inspect.max_iterations):
            xa, ga, gb, good = onto(x[act])
            ok[act] &= good
            t = np.cross(ga, gb)
            t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), tol.tiny)
            h = _rows(p[act] - xa, t)
            pr = prev[act]
            with np.errstate(divide="ignore", invalid="ignore"):
                rho = np.where(np.abs(pr) > np.abs(h), h / pr, 0.0)
            rho = np.clip(np.nan_to_num(rho), -0.5, 0.9) if accelerate else 0.0 * h
            step = h / (1.0 - rho)
            if not accelerate:  # damped: at most a quarter of the distance to p
                lim = 0.25 * np.linalg.norm(p[act] - xa, axis=1)
                step = np.clip(step, -lim, lim)
            x[act] = xa + step[:, None] * t
            prev[act] = h
            done = np.abs(h) < tol.inspect.converge
            act = act[~done]
            if not len(act):
                break
        x, ga, gb, good = onto(x)
        ok &= good
        r = p - x
        aa, ab, bb = _rows(ga, ga), _rows(ga, gb), _rows(gb, gb)
        det = np.where(np.abs(aa * bb - ab * ab) > tol.inspect.gram_det, aa * bb - ab * ab, 1.0)
        ra, rb = _rows(r, ga), _rows(r, gb)
        lam = np.stack([(bb * ra - ab * rb) / det, (aa * rb - ab * ra) / det], 1)
        return x, lam, ok & np.all(np.isfinite(x), axis=1)

    def _vertex(self, p: FloatArray, x: FloatArray,
                key: tuple[int, ...]) -> tuple[FloatArray, FloatArray, BoolArray]:
        """The point where three face surfaces meet, near seeds x."""
        faces = [self.faces[i] for i in key]
        off = self.offset
        x = x.copy()
        ok = np.ones(len(p), bool)
        for _ in range(tol.inspect.max_iterations):
            ev = [f.eval(x, off) for f in faces]
            f = np.stack([e[0] for e in ev], 1)
            J = np.stack([e[1] for e in ev], 1)  # (m, 3, 3) rows = gradients
            det = np.linalg.det(J)
            ok &= np.abs(det) > tol.inspect.jacobian_det
            Js = np.where(ok[:, None, None], J, np.eye(3))
            dx = np.linalg.solve(Js, f[:, :, None])[:, :, 0]
            x = x - dx
            if np.abs(dx).max(initial=0.0) < tol.inspect.converge:
                break
        J = np.stack([f.eval(x, off)[1] for f in faces], 1)
        Js = np.where(ok[:, None, None], J, np.eye(3))
        lam = np.linalg.solve(np.transpose(Js, (0, 2, 1)), (p - x)[:, :, None])[:, :, 0]
        return x, lam, ok & np.all(np.isfinite(x), axis=1)


def _points(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        p = p.reshape(-1, 3)
    return p
