"""Fast self-intersection finder for triangle meshes (issue 27 item 4).

What MeshLab's "select self-intersecting faces", open3d's
``get_self_intersecting_triangles`` and trimesh report, in O(n log n)
instead of O(n²):

1. candidate pairs: the axis-aligned box of every triangle is entered into
   a uniform grid (cell ≈ half the median longest box side); two triangles are a
   candidate when their boxes overlap, each pair counted once (in the first
   cell both boxes share);
2. every candidate is tested with sign-of-volume predicates (orient3d in
   float64): two triangles that are not coplanar cross when an edge of one
   meets the other; coplanar ones are tested in the plane (edge crossings and
   vertex containment).

Adjacent triangles are handled as a *crossing*, not a contact:

- sharing an edge ``ab`` (third vertices c and d): they cross only when they
  are coplanar and c, d lie on the same side of ``ab`` (one folded onto the
  other);
- sharing one vertex ``v`` (triangles ``vab`` and ``vcd``): they cross when
  the edge ``ab`` meets ``vcd`` or ``cd`` meets ``vab`` (then the two
  triangles overlap beyond v); coplanar ones when their interiors overlap.

open3d skips every pair that shares a vertex; :func:`self_intersections`
returns both kinds, separately.

Predicates are float64, not adaptive-exact: a sign is taken as zero below
``tol.mesh_coplanar_rel × (size of the two triangles)³`` (coplanarity, 1e-13)
and exact zero otherwise, so contacts closer than about that share of the triangles' size may be
classified either way.

Frame and units: any (tipgeo: cannula frame, mm).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np

from ._jit import njit
from .arrays import FloatArray, IntArray
from .tolerances import tol

__all__ = ["self_intersections", "crossing_pairs", "tolerant_intersections", "near_pairs",
           "count_tolerant"]

_F = TypeVar("_F", bound=Callable[..., Any])


def _jit(fn: _F) -> _F:
    """``numba.njit(cache=True)`` with the function's own signature for
    the type checker (numba has no types)."""
    return cast(_F, njit(cache=True)(fn))


@_jit
def _orient(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float,
           c0: float, c1: float, c2: float, d0: float, d1: float, d2: float) -> float:
    # sign of det[b-a, c-a, d-a]
    bx, by, bz = b0 - a0, b1 - a1, b2 - a2
    cx, cy, cz = c0 - a0, c1 - a1, c2 - a2
    dx, dy, dz = d0 - a0, d1 - a1, d2 - a2
    return bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx)


@_jit
def _o(P: FloatArray, i: int, j: int, k: int, m: int) -> float:
    return _orient(P[i, 0], P[i, 1], P[i, 2], P[j, 0], P[j, 1], P[j, 2],
                   P[k, 0], P[k, 1], P[k, 2], P[m, 0], P[m, 1], P[m, 2])


@_jit
def _seg_tri(P: FloatArray, p: int, q: int, a: int, b: int, c: int, eps: float) -> bool:
    """Closed segment pq meets the closed triangle abc."""
    s1 = _o(P, a, b, c, p)
    s2 = _o(P, a, b, c, q)
    if abs(s1) <= eps and abs(s2) <= eps:
        return _seg_tri2(P, p, q, a, b, c)  # the segment lies in the plane
    if (s1 > 0 and s2 > 0) or (s1 < 0 and s2 < 0):
        return False
    t1 = _o(P, p, q, a, b)
    t2 = _o(P, p, q, b, c)
    t3 = _o(P, p, q, c, a)
    if (t1 >= 0 and t2 >= 0 and t3 >= 0) or (t1 <= 0 and t2 <= 0 and t3 <= 0):
        return True
    return False


@_jit
def _axes(P: FloatArray, a: int, b: int, c: int) -> tuple[int, int]:
    """The two coordinate axes of the projection along the dominant normal."""
    nx = ((P[b, 1] - P[a, 1]) * (P[c, 2] - P[a, 2]) - (P[b, 2] - P[a, 2]) * (P[c, 1] - P[a, 1]))
    ny = ((P[b, 2] - P[a, 2]) * (P[c, 0] - P[a, 0]) - (P[b, 0] - P[a, 0]) * (P[c, 2] - P[a, 2]))
    nz = ((P[b, 0] - P[a, 0]) * (P[c, 1] - P[a, 1]) - (P[b, 1] - P[a, 1]) * (P[c, 0] - P[a, 0]))
    if abs(nx) >= abs(ny) and abs(nx) >= abs(nz):
        return 1, 2
    if abs(ny) >= abs(nz):
        return 2, 0
    return 0, 1


@_jit
def _seg_tri2(P: FloatArray, p: int, q: int, a: int, b: int, c: int) -> bool:
    """Closed segment pq meets the closed triangle abc, both in one plane."""
    ax, ay = _axes(P, a, b, c)
    if _inside2(P, ax, ay, p, a, b, c, False) or _inside2(P, ax, ay, q, a, b, c, False):
        return True
    return (_seg_seg2(P, ax, ay, p, q, a, b, False) or _seg_seg2(P, ax, ay, p, q, b, c, False)
            or _seg_seg2(P, ax, ay, p, q, c, a, False))


@_jit
def _o2(P: FloatArray, ax: int, ay: int, i: int, j: int, k: int) -> float:
    r: float = ((P[j, ax] - P[i, ax]) * (P[k, ay] - P[i, ay])
            - (P[j, ay] - P[i, ay]) * (P[k, ax] - P[i, ax]))
    return r


@_jit
def _seg_seg2(P: FloatArray, ax: int, ay: int, a: int, b: int, c: int, d: int,
              proper: bool) -> bool:
    d1 = _o2(P, ax, ay, a, b, c)
    d2 = _o2(P, ax, ay, a, b, d)
    d3 = _o2(P, ax, ay, c, d, a)
    d4 = _o2(P, ax, ay, c, d, b)
    if proper:
        return d1 * d2 < 0 and d3 * d4 < 0
    return d1 * d2 <= 0 and d3 * d4 <= 0 and not (d1 == 0 and d2 == 0)


@_jit
def _inside2(P: FloatArray, ax: int, ay: int, p: int, a: int, b: int, c: int,
             strict: bool) -> bool:
    s1 = _o2(P, ax, ay, a, b, p)
    s2 = _o2(P, ax, ay, b, c, p)
    s3 = _o2(P, ax, ay, c, a, p)
    if strict:
        return (s1 > 0 and s2 > 0 and s3 > 0) or (s1 < 0 and s2 < 0 and s3 < 0)
    return (s1 >= 0 and s2 >= 0 and s3 >= 0) or (s1 <= 0 and s2 <= 0 and s3 <= 0)


@_jit
def _coplanar_overlap(P: FloatArray, t: IntArray, u: IntArray, nshared: int) -> bool:
    """Interiors of coplanar triangles t, u overlap (projected on the plane
    of the dominant normal axis)."""
    ax, ay = _axes(P, t[0], t[1], t[2])
    proper = nshared > 0
    for i in range(3):
        for j in range(3):
            a, b = t[i], t[(i + 1) % 3]
            c, d = u[j], u[(j + 1) % 3]
            if a == c or a == d or b == c or b == d:
                continue
            if _seg_seg2(P, ax, ay, a, b, c, d, proper):
                return True
    for i in range(3):
        p = t[i]
        if p != u[0] and p != u[1] and p != u[2]:
            if _inside2(P, ax, ay, p, u[0], u[1], u[2], proper):
                return True
        p = u[i]
        if p != t[0] and p != t[1] and p != t[2]:
            if _inside2(P, ax, ay, p, t[0], t[1], t[2], proper):
                return True
    return False


@_jit
def _pt_tri_d2(P: FloatArray, p: int, a: int, b: int, c: int) -> float:
    """Squared distance from vertex p to the triangle abc (Ericson §5.1.5)."""
    abx, aby, abz = P[b, 0] - P[a, 0], P[b, 1] - P[a, 1], P[b, 2] - P[a, 2]
    acx, acy, acz = P[c, 0] - P[a, 0], P[c, 1] - P[a, 1], P[c, 2] - P[a, 2]
    apx, apy, apz = P[p, 0] - P[a, 0], P[p, 1] - P[a, 1], P[p, 2] - P[a, 2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    bpx, bpy, bpz = P[p, 0] - P[b, 0], P[p, 1] - P[b, 1], P[p, 2] - P[b, 2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    cpx, cpy, cpz = P[p, 0] - P[c, 0], P[p, 1] - P[c, 1], P[p, 2] - P[c, 2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    if d1 <= 0 and d2 <= 0:
        v, w = 0.0, 0.0
    elif d3 >= 0 and d4 <= d3:
        v, w = 1.0, 0.0
    elif vc <= 0 and d1 >= 0 and d3 <= 0:
        v, w = d1 / (d1 - d3), 0.0
    elif d6 >= 0 and d5 <= d6:
        v, w = 0.0, 1.0
    elif vb <= 0 and d2 >= 0 and d6 <= 0:
        v, w = 0.0, d2 / (d2 - d6)
    elif va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        v = 1.0 - w
    else:
        den = 1.0 / (va + vb + vc)
        v, w = vb * den, vc * den
    qx = P[a, 0] + v * abx + w * acx
    qy = P[a, 1] + v * aby + w * acy
    qz = P[a, 2] + v * abz + w * acz
    dist2: float = (P[p, 0] - qx) ** 2 + (P[p, 1] - qy) ** 2 + (P[p, 2] - qz) ** 2
    return dist2


@_jit
def _seg_seg_d2(P: FloatArray, p1: int, q1: int, p2: int, q2: int) -> float:
    """Squared distance between segments p1q1 and p2q2 (Ericson §5.1.9)."""
    d1 = P[q1] - P[p1]
    d2 = P[q2] - P[p2]
    r = P[p1] - P[p2]
    a = d1 @ d1
    e = d2 @ d2
    f = d2 @ r
    if a <= 0 and e <= 0:
        rr: float = r @ r
        return rr
    if a <= 0:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1 @ r
        if e <= 0:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1 @ d2
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0 else 0.0
            t = (b * s + f) / e
            if t < 0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    g = P[p1] + d1 * s - P[p2] - d2 * t
    gg: float = g @ g
    return gg


@_jit
def _near(P: FloatArray, t: IntArray, u: IntArray, d2max: float) -> bool:
    """Triangles t and u (sharing no vertex) come closer than √d2max."""
    for k in range(3):
        if _pt_tri_d2(P, t[k], u[0], u[1], u[2]) < d2max:
            return True
        if _pt_tri_d2(P, u[k], t[0], t[1], t[2]) < d2max:
            return True
    for i in range(3):
        for j in range(3):
            if _seg_seg_d2(P, t[i], t[(i + 1) % 3], u[j], u[(j + 1) % 3]) < d2max:
                return True
    return False


@_jit
def _shared(t: IntArray, u: IntArray) -> int:
    """How many vertices triangles t and u share."""
    n = 0
    for a in range(3):
        for b in range(3):
            if t[a] == u[b]:
                n += 1
    return n


@_jit
def _coplanar_eps(P: FloatArray, t: IntArray, u: IntArray, rel: float) -> float:
    """The coplanarity threshold of the pair: ``rel × size³`` (signed volume),
    size = the longest side of the pair's box."""
    lo = np.empty(3)
    hi = np.empty(3)
    for k in range(3):
        lo[k] = min(P[t[0], k], P[t[1], k], P[t[2], k], P[u[0], k], P[u[1], k], P[u[2], k])
        hi[k] = max(P[t[0], k], P[t[1], k], P[t[2], k], P[u[0], k], P[u[1], k], P[u[2], k])
    s: float = max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
    return rel * s * s * s


@_jit
def _coplanar(P: FloatArray, t: IntArray, u: IntArray, eps: float) -> bool:
    """Every vertex of u within ``eps`` (signed volume) of t's plane."""
    for k in range(3):
        if abs(_o(P, t[0], t[1], t[2], u[k])) > eps:
            return False
    return True


@_jit
def _others(t: IntArray, v: int) -> IntArray:
    """The two vertices of triangle t other than v."""
    out = np.empty(2, np.int64)
    m = 0
    for k in range(3):
        if t[k] != v:
            out[m] = t[k]
            m += 1
    return out


@_jit
def _vertex_pair(P: FloatArray, t: IntArray, u: IntArray, eps: float) -> bool:
    """Triangles t, u sharing one vertex (not coplanar) cross: the edge of
    one opposite the shared vertex meets the other."""
    v = t[0]
    for k in range(3):
        if t[k] == u[0] or t[k] == u[1] or t[k] == u[2]:
            v = t[k]
    ta = _others(t, v)
    ua = _others(u, v)
    return (_seg_tri(P, ta[0], ta[1], u[0], u[1], u[2], eps)
            or _seg_tri(P, ua[0], ua[1], t[0], t[1], t[2], eps))


@_jit
def _disjoint_pair(P: FloatArray, t: IntArray, u: IntArray, eps: float, gap2: float) -> bool:
    """Triangles t, u sharing no vertex cross (an edge of one meets the
    other) or, with ``gap2 > 0``, come closer than √gap2."""
    if gap2 > 0 and _near(P, t, u, gap2):
        return True
    for k in range(3):
        if _seg_tri(P, t[k], t[(k + 1) % 3], u[0], u[1], u[2], eps):
            return True
        if _seg_tri(P, u[k], u[(k + 1) % 3], t[0], t[1], t[2], eps):
            return True
    return False


@_jit
def _pair(P: FloatArray, F: IntArray, i: int, j: int, rel: float, gap2: float) -> bool:
    """Faces i and j cross (see the module docstring for adjacent ones)."""
    t = F[i]
    u = F[j]
    nshared = _shared(t, u)
    if nshared == 3:
        return True  # the same triangle twice (duplicate face)
    eps = _coplanar_eps(P, t, u, rel)
    if _coplanar(P, t, u, eps):
        return _coplanar_overlap(P, t, u, nshared)
    if nshared == 2:
        return False  # not coplanar: they meet along the shared edge only
    if nshared == 1:
        return _vertex_pair(P, t, u, eps)
    return _disjoint_pair(P, t, u, eps, gap2)


@_jit
def _bin(lo: FloatArray, hi: FloatArray, cell: float,
         ) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Every triangle's box into the cubic cells of side ``cell`` it covers:
    (cell counts per axis, each box's first cell, cell keys sorted, the
    triangle of each key)."""
    m = lo.shape[0]
    org = np.empty(3)
    dims = np.empty(3, np.int64)
    for k in range(3):
        org[k] = lo[:, k].min()
        dims[k] = int((hi[:, k].max() - org[k]) / cell) + 1
    c0 = np.empty((m, 3), np.int64)
    c1 = np.empty((m, 3), np.int64)
    total = 0
    for i in range(m):
        n = 1
        for k in range(3):
            c0[i, k] = int((lo[i, k] - org[k]) / cell)
            c1[i, k] = int((hi[i, k] - org[k]) / cell)
            n *= c1[i, k] - c0[i, k] + 1
        total += n
    keys = np.empty(total, np.int64)
    tris = np.empty(total, np.int64)
    w = 0
    for i in range(m):
        for x in range(c0[i, 0], c1[i, 0] + 1):
            for y in range(c0[i, 1], c1[i, 1] + 1):
                for z in range(c0[i, 2], c1[i, 2] + 1):
                    keys[w] = (x * dims[1] + y) * dims[2] + z
                    tris[w] = i
                    w += 1
    order = np.argsort(keys, kind="mergesort")
    return dims, c0, keys[order], tris[order]


@_jit
def _candidates(lo: FloatArray, hi: FloatArray, cell: float, gap: float) -> IntArray:
    """(k, 2) triangle pairs whose boxes come within ``gap`` of each other,
    each pair once (in the first grid cell both boxes cover), in the order
    found."""
    dims, c0, keys, tris = _bin(lo, hi, cell)
    total = len(keys)
    out = []
    s = 0
    while s < total:
        e = s
        while e < total and keys[e] == keys[s]:
            e += 1
        key = keys[s]
        cz = key % dims[2]
        cy = (key // dims[2]) % dims[1]
        cx = key // (dims[2] * dims[1])
        for a in range(s, e):
            i = tris[a]
            for b in range(a + 1, e):
                j = tris[b]
                if (lo[i, 0] > hi[j, 0] + gap or lo[j, 0] > hi[i, 0] + gap
                        or lo[i, 1] > hi[j, 1] + gap or lo[j, 1] > hi[i, 1] + gap
                        or lo[i, 2] > hi[j, 2] + gap or lo[j, 2] > hi[i, 2] + gap):
                    continue
                # count the pair once: in the first cell both boxes cover
                if (max(c0[i, 0], c0[j, 0]) != cx or max(c0[i, 1], c0[j, 1]) != cy
                        or max(c0[i, 2], c0[j, 2]) != cz):
                    continue
                out.append((i, j))
        s = e
    return _pairs_array(out)


@_jit
def _pairs_array(out: list[tuple[int, int]]) -> IntArray:
    res = np.empty((len(out), 2), np.int64)
    for k in range(len(out)):
        res[k, 0] = out[k][0]
        res[k, 1] = out[k][1]
    return res


@_jit
def _find(P: FloatArray, F: IntArray, lo: FloatArray, hi: FloatArray, cell: float,
          rel: float, gap: float) -> IntArray:
    cand = _candidates(lo, hi, cell, gap)
    out = []
    for k in range(cand.shape[0]):
        i, j = cand[k, 0], cand[k, 1]
        if _pair(P, F, i, j, rel, gap * gap):
            out.append((min(i, j), max(i, j)))
    return _pairs_array(out)


def _cell_size(lo: FloatArray, hi: FloatArray) -> float:
    """Grid cell of the pair search: half the median longest side of the
    boxes (a built tip's wall triangles are long and narrow: cells as long
    as they are would hold hundreds of triangles each)."""
    return 0.5 * float(np.median((hi - lo).max(axis=1)))


def self_intersections(vertices: FloatArray, faces: IntArray, *,
                       coplanar_rel: float | None = None, gap: float = 0.0) -> IntArray:
    """(k, 2) int64 index pairs ``i < j`` of faces that cross, sorted.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions (any unit; tipgeo: mm, cannula frame).
    faces : (m, 3) int
        Triangles (indices into ``vertices``).
    coplanar_rel : float, optional
        Two triangles count as coplanar when every vertex of one is within
        ``coplanar_rel × size³`` (signed volume) of the other's plane
        (default ``tol.mesh_coplanar_rel``, 1e-13).
    gap : float
        Also report pairs sharing no vertex that come closer than ``gap``
        (same unit as the vertices): near-contacts, which float checks with
        a tolerance (open3d's Möller test, MeshLab) report as crossings.

    Returns
    -------
    IntArray
        Pairs of faces whose intersection is more than what they share: a
        real crossing (pairs sharing an edge or a vertex included, see the
        module docstring). Empty for a mesh without self-intersections.
    """
    P = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if len(F) < 2:
        return np.empty((0, 2), np.int64)
    t = P[F]
    lo = np.ascontiguousarray(t.min(axis=1) - 0.5 * gap)
    hi = np.ascontiguousarray(t.max(axis=1) + 0.5 * gap)
    size = _cell_size(lo, hi)
    span = float((hi.max(0) - lo.min(0)).max())
    cell = max(size, span / 512.0, tol.tiny)
    rel = tol.mesh_coplanar_rel if coplanar_rel is None else coplanar_rel
    res = _find(P, F, lo, hi, cell, float(rel), float(gap))
    if len(res):
        res = np.unique(res, axis=0)
    return res


def crossing_pairs(vertices: FloatArray, faces: IntArray, *, gap: float = 0.0,
                   ) -> tuple[IntArray, IntArray]:
    """The crossings of :func:`self_intersections` split as
    ``(disjoint, adjacent)``: pairs that share no vertex (what open3d and
    MeshLab report) and pairs that share a vertex or an edge (folds)."""
    pairs = self_intersections(vertices, faces, gap=gap)
    F = np.asarray(faces)
    if not len(pairs):
        return pairs, pairs
    a, b = F[pairs[:, 0]], F[pairs[:, 1]]
    share = (a[:, :, None] == b[:, None, :]).any(axis=(1, 2))
    return pairs[~share], pairs[share]


# -- the tolerant test MeshLab-style checkers run (open3d) --------------------
# Möller's interval test ("A fast triangle-triangle intersection test", 1997)
# with its coplanarity tolerance: a signed plane distance (unnormalised normal)
# below OPEN3D_EPSILON counts as zero, on coordinates centred on the pair and divided
# per axis by their spread, as open3d's TriangleMesh.get_self_intersecting_
# triangles does. It reports near-coplanar non-touching pairs where one
# triangle is far smaller than the other; the build avoids them too.

#: open3d's fixed epsilon of its Möller test (``IntersectionTest::
#: TriangleTriangle3d``): a plane distance below it counts as zero. A
#: constant of the algorithm reproduced, not a setting of tipgeo's: another
#: value would no longer give open3d's answer.
OPEN3D_EPSILON = 1e-6

#: open3d's floor added to the per-axis spread by which it divides the
#: pair's coordinates (keeps a zero spread finite); reproduced as it is.
OPEN3D_SPREAD_FLOOR = 1e-12


@_jit
def _edge_edge(v0: FloatArray, v1: FloatArray, u0: FloatArray, u1: FloatArray,
               i0: int, i1: int) -> bool:
    ax, ay = v1[i0] - v0[i0], v1[i1] - v0[i1]
    bx, by = u0[i0] - u1[i0], u0[i1] - u1[i1]
    cx, cy = v0[i0] - u0[i0], v0[i1] - u0[i1]
    f = ay * bx - ax * by
    d = by * cx - bx * cy
    if (f > 0 and d >= 0 and d <= f) or (f < 0 and d <= 0 and d >= f):
        e = ax * cy - ay * cx
        if f > 0:
            if e >= 0 and e <= f:
                return True
        elif e <= 0 and e >= f:
            return True
    return False


@_jit
def _pt_in(p: FloatArray, u0: FloatArray, u1: FloatArray, u2: FloatArray,
           i0: int, i1: int) -> bool:
    a = u1[i1] - u0[i1]
    b = -(u1[i0] - u0[i0])
    c = -a * u0[i0] - b * u0[i1]
    d0 = a * p[i0] + b * p[i1] + c
    a = u2[i1] - u1[i1]
    b = -(u2[i0] - u1[i0])
    c = -a * u1[i0] - b * u1[i1]
    d1 = a * p[i0] + b * p[i1] + c
    a = u0[i1] - u2[i1]
    b = -(u0[i0] - u2[i0])
    c = -a * u2[i0] - b * u2[i1]
    d2 = a * p[i0] + b * p[i1] + c
    inside: bool = d0 * d1 > 0 and d0 * d2 > 0
    return inside


@_jit
def _coplanar_moller(n: FloatArray, V: FloatArray, U: FloatArray) -> bool:
    a0, a1, a2 = abs(n[0]), abs(n[1]), abs(n[2])
    if a0 > a1:
        i0, i1 = (1, 2) if a0 > a2 else (0, 1)
    else:
        i0, i1 = (0, 1) if a2 > a1 else (0, 2)
    for k in range(3):
        for m in range(3):
            if _edge_edge(V[k], V[(k + 1) % 3], U[m], U[(m + 1) % 3], i0, i1):
                return True
    return _pt_in(V[0], U[0], U[1], U[2], i0, i1) or _pt_in(U[0], V[0], V[1], V[2], i0, i1)


@_jit
def _interval(p0: float, p1: float, p2: float, d0: float, d1: float, d2: float,
              d0d1: float, d0d2: float) -> tuple[bool, float, float, float, float, float]:
    # returns ok, a, b, c, x0, x1 (ok False: coplanar)
    if d0d1 > 0:
        return True, p2, (p0 - p2) * d2, (p1 - p2) * d2, d2 - d0, d2 - d1
    if d0d2 > 0:
        return True, p1, (p0 - p1) * d1, (p2 - p1) * d1, d1 - d0, d1 - d2
    if d1 * d2 > 0 or d0 != 0:
        return True, p0, (p1 - p0) * d0, (p2 - p0) * d0, d0 - d1, d0 - d2
    if d1 != 0:
        return True, p1, (p0 - p1) * d1, (p2 - p1) * d1, d1 - d0, d1 - d2
    if d2 != 0:
        return True, p2, (p0 - p2) * d2, (p1 - p2) * d2, d2 - d0, d2 - d1
    return False, 0.0, 0.0, 0.0, 0.0, 0.0


@_jit
def _dot(a: FloatArray, b: FloatArray) -> float:
    """a·b summed left to right (as open3d's C macro; numpy's dot may pair
    the terms differently, which flips borderline tolerance decisions)."""
    r: float = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    return r


@_jit
def _plane_side(T: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Triangle ``T``'s normal and the distances (scaled by it) of ``P``'s
    corners to its plane, those below ``OPEN3D_EPSILON`` snapped to 0."""
    n = np.cross(T[1] - T[0], T[2] - T[0])
    e = -_dot(n, T[0])
    d = np.empty(3)
    for k in range(3):
        d[k] = _dot(n, P[k]) + e
        if abs(d[k]) < OPEN3D_EPSILON:
            d[k] = 0.0
    return n, d


@_jit
def _moller(V: FloatArray, U: FloatArray) -> bool:
    n1, du = _plane_side(V, U)
    if du[0] * du[1] > 0 and du[0] * du[2] > 0:
        return False
    n2, dv = _plane_side(U, V)
    if dv[0] * dv[1] > 0 and dv[0] * dv[2] > 0:
        return False
    dd = np.cross(n1, n2)
    idx = 0
    if abs(dd[1]) > abs(dd[idx]):
        idx = 1
    if abs(dd[2]) > abs(dd[idx]):
        idx = 2
    ok, a, b, c, x0, x1 = _interval(V[0, idx], V[1, idx], V[2, idx], dv[0], dv[1], dv[2],
                                    dv[0] * dv[1], dv[0] * dv[2])
    if not ok:
        return _coplanar_moller(n1, V, U)
    ok, d, e, f, y0, y1 = _interval(U[0, idx], U[1, idx], U[2, idx], du[0], du[1], du[2],
                                    du[0] * du[1], du[0] * du[2])
    if not ok:
        return _coplanar_moller(n1, V, U)
    xx, yy = x0 * x1, y0 * y1
    xxyy = xx * yy
    t = a * xxyy
    s0, s1 = t + b * x1 * yy, t + c * x0 * yy
    t = d * xxyy
    r0, r1 = t + e * xx * y1, t + f * xx * y0
    if s0 > s1:
        s0, s1 = s1, s0
    if r0 > r1:
        r0, r1 = r1, r0
    return not (s1 < r0 or r1 < s0)


@_jit
def _one_side(P: FloatArray, t: IntArray, u: IntArray, thr: float) -> bool:
    """Every vertex of u further than ``thr`` (signed volume, raw
    coordinates) from t's plane, all on one side."""
    ax, ay, az = P[t[0], 0], P[t[0], 1], P[t[0], 2]
    bx, by, bz = P[t[1], 0] - ax, P[t[1], 1] - ay, P[t[1], 2] - az
    cx, cy, cz = P[t[2], 0] - ax, P[t[2], 1] - ay, P[t[2], 2] - az
    nx, ny, nz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    above = 0
    below = 0
    for k in range(3):
        d = nx * (P[u[k], 0] - ax) + ny * (P[u[k], 1] - ay) + nz * (P[u[k], 2] - az)
        if d > thr:
            above += 1
        elif d < -thr:
            below += 1
    return above == 3 or below == 3


@_jit
def _spread(P: FloatArray, t: IntArray, u: IntArray, k: int) -> tuple[float, float]:
    """Mean and spread (+ open3d's floor) of the pair's six coordinates on
    axis k, summed in open3d's order (t's three, then u's)."""
    m = (P[t[0], k] + P[t[1], k] + P[t[2], k] + P[u[0], k] + P[u[1], k] + P[u[2], k]) / 6.0
    q = ((P[t[0], k] - m) ** 2 + (P[t[1], k] - m) ** 2 + (P[t[2], k] - m) ** 2
         + (P[u[0], k] - m) ** 2 + (P[u[1], k] - m) ** 2 + (P[u[2], k] - m) ** 2)
    return m, np.sqrt(q / 5.0) + OPEN3D_SPREAD_FLOOR


@_jit
def _tolerant_pair(P: FloatArray, F: IntArray, i: int, j: int) -> bool:
    t = F[i]
    u = F[j]
    for a in range(3):
        for b in range(3):
            if t[a] == u[b]:
                return False  # open3d skips pairs that share a vertex
    m0, s0 = _spread(P, t, u, 0)
    m1, s1 = _spread(P, t, u, 1)
    m2, s2 = _spread(P, t, u, 2)
    # Möller rejects at its first plane tests when one triangle lies beyond
    # the tolerance on one side of the other's plane; the distances it takes
    # are the raw ones divided by s0·s1·s2: test that first, in raw
    # coordinates, with a margin of 2 (and no allocation)
    thr = 2.0 * OPEN3D_EPSILON * s0 * s1 * s2
    if _one_side(P, t, u, thr) or _one_side(P, u, t, thr):
        return False
    V = np.empty((3, 3))
    U = np.empty((3, 3))
    for a in range(3):
        V[a, 0] = (P[t[a], 0] - m0) / s0
        V[a, 1] = (P[t[a], 1] - m1) / s1
        V[a, 2] = (P[t[a], 2] - m2) / s2
        U[a, 0] = (P[u[a], 0] - m0) / s0
        U[a, 1] = (P[u[a], 1] - m1) / s1
        U[a, 2] = (P[u[a], 2] - m2) / s2
    return _moller(V, U)


@_jit
def _find_tolerant(P: FloatArray, F: IntArray, lo: FloatArray, hi: FloatArray,
                   cell: float) -> IntArray:
    cand = _candidates(lo, hi, cell, 0.0)
    out = []
    for k in range(cand.shape[0]):
        i, j = min(cand[k, 0], cand[k, 1]), max(cand[k, 0], cand[k, 1])
        if _tolerant_pair(P, F, i, j):
            out.append((i, j))
    return _pairs_array(out)


def tolerant_intersections(vertices: FloatArray, faces: IntArray) -> IntArray:
    """(k, 2) face pairs ``i < j`` sharing no vertex that open3d's
    ``get_self_intersecting_triangles`` reports (the same tolerant Möller
    test on the same normalised coordinates, candidate pairs from the grid):
    the real crossings plus the near-coplanar pairs its tolerance takes for
    crossings. Units and frame: any."""
    P = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if len(F) < 2:
        return np.empty((0, 2), np.int64)
    t = P[F]
    lo = np.ascontiguousarray(t.min(axis=1))
    hi = np.ascontiguousarray(t.max(axis=1))
    size = _cell_size(lo, hi)
    span = float((hi.max(0) - lo.min(0)).max())
    res = _find_tolerant(P, F, lo, hi, max(size, span / 512.0, tol.tiny))
    if len(res):
        res = np.unique(res, axis=0)
    return res


# -- local re-checks (the float32 repair of tipgeo.slivers) -------------------

def _boxes(P: FloatArray, F: IntArray, grow: float) -> tuple[FloatArray, FloatArray, float]:
    """Every triangle's box grown by ``grow`` on each side, and the grid cell
    of the pair search."""
    t = P[F]
    lo = np.ascontiguousarray(t.min(axis=1) - grow)
    hi = np.ascontiguousarray(t.max(axis=1) + grow)
    size = _cell_size(lo, hi)
    span = float((hi.max(0) - lo.min(0)).max())
    return lo, hi, max(size, span / 512.0, tol.tiny)


def near_pairs(vertices: FloatArray, faces: IntArray, grow: float,
               ) -> tuple[IntArray, IntArray]:
    """For every face, the faces sharing no vertex with it whose boxes, each
    grown by ``grow`` (same unit as the vertices), overlap its own: the only
    partners :func:`tolerant_intersections` can report for it while no
    vertex moves further than ``grow``. CSR form ``(start, partners)``:
    face i's partners are ``partners[start[i]:start[i + 1]]``."""
    P = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int64)
    if len(F) < 2:
        return np.zeros(len(F) + 1, np.int64), np.empty(0, np.int64)
    lo, hi, cell = _boxes(P, F, grow)
    cand = _candidates(lo, hi, cell, 0.0)
    if len(cand):
        share = (F[cand[:, 0]][:, :, None] == F[cand[:, 1]][:, None, :]).any(axis=(1, 2))
        cand = cand[~share]
    both = np.concatenate([cand, cand[:, ::-1]])
    order = np.argsort(both[:, 0], kind="stable")
    both = both[order]
    start = np.searchsorted(both[:, 0], np.arange(len(F) + 1)).astype(np.int64)
    return start, np.ascontiguousarray(both[:, 1])


@_jit
def _count_tolerant(P: FloatArray, F: IntArray, start: IntArray, partners: IntArray,
                    which: IntArray) -> int:
    n = 0
    for a in range(which.shape[0]):
        i = which[a]
        for s in range(start[i], start[i + 1]):
            j = partners[s]
            if j < i:
                dup = False
                for b in range(which.shape[0]):
                    dup = dup or which[b] == j
                if dup:
                    continue  # both in the set: count the pair once
            if _tolerant_pair(P, F, min(i, j), max(i, j)):
                n += 1
    return n


def count_tolerant(vertices: FloatArray, faces: IntArray, near: tuple[IntArray, IntArray],
                   which: IntArray) -> int:
    """How many pairs with at least one face in ``which`` (distinct face
    indices) open3d's tolerant test reports (as :func:`tolerant_intersections`),
    the partners taken from ``near`` (:func:`near_pairs`). Units and frame: any."""
    return int(_count_tolerant(np.ascontiguousarray(vertices, dtype=np.float64),
                               np.ascontiguousarray(faces, dtype=np.int64), near[0], near[1],
                               np.ascontiguousarray(which, dtype=np.int64)))
