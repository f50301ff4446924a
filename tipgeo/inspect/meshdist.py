"""Exact signed distance to a triangle mesh, in double precision.

Frame and units: those of the mesh (tipgeo: cannula frame, mm).

Distances: the closest point on every candidate triangle is computed in
double precision (Ericson's Voronoi-region test). Candidates come from a
bounding-box tree over sub-triangles (a facet whose box is fat — an oblique
bevel facet — is bisected until its box is thin; a long facet along an axis,
like a fine tube's 10 mm × 20 µm ones, keeps its tight box). Every point's
search radius is the exact distance to the triangle owning the nearest of a
set of surface samples; a point whose radius fits the uniform grid (cells
listing every sub-triangle within reach) takes its cell's list, any other
walks the tree. Either way no triangle closer than that radius is skipped, so
the answer is exact, not approximate. (open3d's float32 closest-point query
is off by micrometres on such facets.)

Signs: from the angle-weighted pseudo-normal of the feature the closest point
lies on (Bærentzen & Aanæs 2005): the face normal inside a triangle, the sum
of both facets' normals on an edge, the angle-weighted vertex normal at a
corner. At a knife edge, where a bevel facet and a bore facet tie as nearest,
the sign comes from the edge's pseudo-normal, never from whichever facet came
first. The mesh must be closed and consistently oriented (a built tip is).
"""

from __future__ import annotations

import numpy as np

from ..errors import TipGeoError
from ..tolerances import tol
from .exact import Distances

__all__ = ["MeshSolid", "closest_on_triangles"]


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest points on triangles (a, b, c) to points p, row by row.

    Parameters
    ----------
    p, a, b, c : (n, 3) float

    Returns
    -------
    q : (n, 3) float — closest points
    bary : (n, 3) float — barycentric weights of a, b, c (exact 0 and 1 in
        edge and vertex regions)
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    n = len(p)
    u = np.empty(n)
    v = np.empty(n)
    w = np.empty(n)
    done = np.zeros(n, bool)

    def put(mask, uu, vv, ww):
        m = mask & ~done
        u[m], v[m], w[m] = (uu[m] if np.ndim(uu) else uu), (vv[m] if np.ndim(vv) else vv), \
            (ww[m] if np.ndim(ww) else ww)
        done[m] = True

    put((d1 <= 0) & (d2 <= 0), 1.0, 0.0, 0.0)                       # vertex a
    put((d3 >= 0) & (d4 <= d3), 0.0, 1.0, 0.0)                      # vertex b
    put((d6 >= 0) & (d5 <= d6), 0.0, 0.0, 1.0)                      # vertex c
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d1 / (d1 - d3)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - t, t, 0.0)       # edge ab
        t = d2 / (d2 - d6)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - t, 0.0, t)       # edge ac
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), 0.0, 1 - t, t)  # edge bc
        den = va + vb + vc
        vv, ww = vb / den, vc / den
    put(np.ones(n, bool), 1 - vv - ww, vv, ww)                      # face
    bary = np.stack([u, v, w], 1)
    q = a * u[:, None] + b * v[:, None] + c * w[:, None]
    return q, bary


def _dot(x, y):
    return np.einsum("ij,ij->i", x, y)


def _split_fat(v: np.ndarray, f: np.ndarray, cell: float):
    """Sub-triangles whose bounding boxes are thin (second-largest extent ≤
    ``cell``), by longest-edge bisection, with their parent triangle's index.
    A long facet along an axis keeps a tight box and is not split."""
    tri = v[f]
    parent = np.arange(len(f))
    done_t, done_p = [], []
    while len(tri):
        ext = np.sort(tri.max(axis=1) - tri.min(axis=1), axis=1)
        fat = ext[:, 1] > cell
        done_t.append(tri[~fat])
        done_p.append(parent[~fat])
        tri, parent = tri[fat], parent[fat]
        if not len(tri):
            break
        e = np.stack([np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1),
                      np.linalg.norm(tri[:, 2] - tri[:, 1], axis=1),
                      np.linalg.norm(tri[:, 0] - tri[:, 2], axis=1)], 1)
        k = np.argmax(e, axis=1)
        idx = (np.arange(3)[None, :] + k[:, None]) % 3   # longest edge first
        tri = np.take_along_axis(tri, idx[:, :, None], axis=1)
        m = 0.5 * (tri[:, 0] + tri[:, 1])
        tri = np.concatenate([np.stack([tri[:, 0], m, tri[:, 2]], 1),
                              np.stack([m, tri[:, 1], tri[:, 2]], 1)])
        parent = np.concatenate([parent, parent])
    return np.concatenate(done_t), np.concatenate(done_p)


class _BVH:
    """A balanced bounding-box tree over sub-triangles (Morton order, split
    in halves), queried for all points at once, level by level."""

    LEAF = 4

    def __init__(self, sub: np.ndarray, parent: np.ndarray):
        lo, hi = sub.min(axis=1), sub.max(axis=1)
        c = 0.5 * (lo + hi)
        span = np.maximum(c.max(axis=0) - c.min(axis=0), tol.tiny)
        q = np.clip(((c - c.min(axis=0)) / span * 1023).astype(np.int64), 0, 1023)
        order = np.argsort(_morton(q), kind="stable")
        self.lo, self.hi, self.parent = lo[order], hi[order], parent[order]
        self.tri = sub[order]
        self.cen = c[order]
        n = len(order)
        # levels of ranges: level L has nodes [start, stop) halving the parent's
        levels = [np.array([[0, n]])]
        while (levels[-1][:, 1] - levels[-1][:, 0]).max() > self.LEAF:
            r = levels[-1]
            mid = (r[:, 0] + r[:, 1]) // 2
            levels.append(np.stack([np.stack([r[:, 0], mid], 1),
                                    np.stack([mid, r[:, 1]], 1)], 1).reshape(-1, 2))
        self.levels = levels
        self.boxes = []
        for r in levels:
            bl = np.minimum.reduceat(self.lo, r[:, 0], axis=0)
            bh = np.maximum.reduceat(self.hi, r[:, 0], axis=0)
            # reduceat over empty ranges is undefined; ranges are never empty here
            self.boxes.append((bl, bh))

    def greedy(self, p: np.ndarray) -> np.ndarray:
        """Primitives of the leaf reached by always descending into the nearer
        child box: (n, LEAF) primitive indices (−1 where a leaf is smaller)."""
        node = np.zeros(len(p), np.int64)
        for bl, bh in self.boxes[1:]:
            kids = node[:, None] * 2 + np.array([0, 1])
            d = np.maximum(np.maximum(bl[kids] - p[:, None], p[:, None] - bh[kids]), 0.0)
            node = kids[np.arange(len(p)), np.argmin(np.einsum("ijk,ijk->ij", d, d), axis=1)]
        r = self.levels[-1][node]
        prim = r[:, :1] + np.arange(self.LEAF)[None, :]
        return np.where(prim < r[:, 1:], prim, -1)

    def candidates(self, p: np.ndarray, ub: np.ndarray):
        """Pairs (point, primitive) whose boxes lie within ``ub`` of the point."""
        pts = np.arange(len(p))
        nodes = np.zeros(len(p), np.int64)
        ub2 = ub * ub
        for L, (bl, bh) in enumerate(self.boxes):
            if L:
                pts = np.repeat(pts, 2)
                nodes = np.repeat(nodes * 2, 2)
                nodes[1::2] += 1
            q = p[pts]
            d = bl[nodes] - q
            np.maximum(d, q - bh[nodes], out=d)
            np.maximum(d, 0.0, out=d)
            keep = np.einsum("ij,ij->i", d, d) <= ub2[pts]
            pts, nodes = pts[keep], nodes[keep]
        r = self.levels[-1][nodes]
        cnt = r[:, 1] - r[:, 0]
        pp = np.repeat(pts, cnt)
        start = np.repeat(r[:, 0] - np.cumsum(cnt) + cnt, cnt)
        prim = np.arange(len(pp)) + start
        q = p[pp]
        d = np.maximum(np.maximum(self.lo[prim] - q, q - self.hi[prim]), 0.0)
        keep = np.einsum("ij,ij->i", d, d) <= ub[pp] ** 2
        return pp[keep], prim[keep]


def _morton(q: np.ndarray) -> np.ndarray:
    def spread(x):
        x = x & 0x3FF
        x = (x | (x << 16)) & 0x030000FF
        x = (x | (x << 8)) & 0x0300F00F
        x = (x | (x << 4)) & 0x030C30C3
        x = (x | (x << 2)) & 0x09249249
        return x
    return spread(q[:, 0]) | (spread(q[:, 1]) << 1) | (spread(q[:, 2]) << 2)


class _Grid:
    """Uniform cells listing every sub-triangle whose box, grown by
    ``reach``, touches the cell: for a point whose search radius is at most
    ``reach``, its own cell's list holds every candidate."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, cell: float, reach: float,
                 max_entries: int = 8_000_000):
        self.cell, self.reach = cell, reach
        glo, ghi = lo - reach, hi + reach
        self.origin = glo.min(axis=0) - cell
        i0 = np.floor((glo - self.origin) / cell).astype(np.int64)
        i1 = np.floor((ghi - self.origin) / cell).astype(np.int64)
        self.dims = i1.max(axis=0) + 2
        n3 = i1 - i0 + 1
        cnt = n3.prod(axis=1)
        self.ok = int(cnt.sum()) <= max_entries
        if not self.ok:
            return
        prim = np.repeat(np.arange(len(lo)), cnt)
        local = np.arange(len(prim)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        nx, ny = np.repeat(n3[:, 0], cnt), np.repeat(n3[:, 1], cnt)
        ix = np.repeat(i0[:, 0], cnt) + local % nx
        iy = np.repeat(i0[:, 1], cnt) + (local // nx) % ny
        iz = np.repeat(i0[:, 2], cnt) + local // (nx * ny)
        key = (iz * self.dims[1] + iy) * self.dims[0] + ix
        order = np.argsort(key, kind="stable")
        key, self.prim = key[order], prim[order].astype(np.int32)
        self.keys, self.start, self.count = np.unique(key, return_index=True,
                                                      return_counts=True)

    def lookup(self, q: np.ndarray):
        """(start, count) of each point's cell list; count 0 outside the grid."""
        i = np.floor((q - self.origin) / self.cell).astype(np.int64)
        inside = np.all((i >= 0) & (i < self.dims), axis=1)
        key = (i[:, 2] * self.dims[1] + i[:, 1]) * self.dims[0] + i[:, 0]
        pos = np.clip(np.searchsorted(self.keys, key), 0, len(self.keys) - 1)
        hit = inside & (self.keys[pos] == key)
        return np.where(hit, self.start[pos], 0), np.where(hit, self.count[pos], 0)


class MeshSolid:
    """Exact signed distances to a closed, labelled triangle mesh.

    Parameters
    ----------
    tip : Tip
        Vertices (mm), faces (outward, counter-clockwise), labels.
    cell : float
        Longest sub-triangle edge of the candidate index (mm; speed only).
    """

    def __init__(self, tip, *, cell: float | None = None):
        self.tip = tip
        self.v = np.ascontiguousarray(tip.vertices, float)
        self.f = np.ascontiguousarray(tip.faces, np.int64)
        self.labels = tuple(tip.label_names)
        self.label_ids = np.asarray(tip.label_ids)
        self.cell = float(cell or tol.inspect.mesh_cell)
        self._index = None
        self._pseudo()

    def _pseudo(self):
        v, f = self.v, self.f
        t = v[f]
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        area2 = np.linalg.norm(n, axis=1)
        self.fn = n / np.where(area2 > 0, area2, 1.0)[:, None]
        # vertex pseudo-normals: angle-weighted
        vn = np.zeros_like(v)
        for i in range(3):
            e1 = t[:, (i + 1) % 3] - t[:, i]
            e2 = t[:, (i + 2) % 3] - t[:, i]
            cosang = _dot(e1, e2) / np.maximum(
                np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), tol.tiny)
            ang = np.arccos(np.clip(cosang, -1.0, 1.0))
            np.add.at(vn, f[:, i], ang[:, None] * self.fn)
        self.vn = vn
        # edge pseudo-normals: sum of the two facets' normals; local edge i runs
        # from corner i to corner i+1
        e = np.stack([f, np.roll(f, -1, axis=1)], 2).reshape(-1, 2)
        key = np.sort(e, axis=1)
        _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inv = inv.ravel()
        if not np.all(cnt == 2):
            raise TipGeoError("the CAD mesh is not closed (an edge is not shared by exactly "
                              "two triangles); signed distances need a watertight mesh")
        acc = np.zeros((len(cnt), 3))
        np.add.at(acc, inv, np.repeat(self.fn, 3, axis=0))
        self.en = acc[inv].reshape(-1, 3, 3)  # (m, local edge, xyz)

    def _build(self):
        from scipy.spatial import cKDTree

        sub, parent = _split_fat(self.v, self.f, self.cell)
        bvh = _BVH(sub, parent)
        # surface samples for the upper bound: every triangle's centroid plus
        # area-weighted points, about four per cell² (seeded: reproducible)
        area = 0.5 * np.linalg.norm(np.cross(sub[:, 1] - sub[:, 0], sub[:, 2] - sub[:, 0]),
                                    axis=1)
        n = int(min(area.sum() / (0.5 * self.cell) ** 2, 2_000_000))
        rng = np.random.default_rng(0)
        k = rng.choice(len(sub), n, p=area / area.sum()) if n and area.sum() > 0 else \
            np.zeros(0, np.int64)
        r1, r2 = rng.random(len(k)), rng.random(len(k))
        s = np.sqrt(r1)
        pts = (sub[k, 0] * (1 - s)[:, None] + sub[k, 1] * (s * (1 - r2))[:, None]
               + sub[k, 2] * (s * r2)[:, None])
        samples = np.concatenate([sub.mean(axis=1), pts])
        owner = np.concatenate([parent, parent[k]])
        grid = _Grid(bvh.lo, bvh.hi, cell=0.05, reach=0.03)
        self._index = (bvh, cKDTree(samples), owner, grid if grid.ok else None)

    def distances(self, points: np.ndarray, *, chunk: int = 100_000) -> Distances:
        """Exact signed distance, closest point, normal and face of every point.

        Parameters
        ----------
        points : (n, 3) float — mm
        chunk : int — points per batch (bounds memory)
        """
        p = np.asarray(points, float).reshape(-1, 3)
        if self._index is None:
            self._build()
        bvh, tree, owner, grid = self._index
        # spatial order: neighbouring points walk the same boxes (cache-friendly)
        lo, span = p.min(axis=0), np.maximum(np.ptp(p, axis=0), tol.tiny)
        order_pts = np.argsort(_morton(np.clip(((p - lo) / span * 1023).astype(np.int64),
                                               0, 1023)), kind="stable")
        p_in = p
        p = p[order_pts]
        best_t = np.empty(len(p), np.int64)
        for s in range(0, len(p), chunk):
            q = p[s:s + chunk]
            # an upper bound: the exact distance to the triangle owning the
            # nearest surface sample (samples ~ one per cell² of area)
            _, i = tree.query(q, k=1, workers=-1)
            t0 = owner[i]
            tri = self.v[self.f[t0]]
            c0, _ = closest_on_triangles(q, tri[:, 0], tri[:, 1], tri[:, 2])
            ub = (np.linalg.norm(q - c0, axis=1) * (1 + tol.inspect.bound_rel)
                  + tol.inspect.bound_abs)
            pp, prim = self._candidates(q, ub, bvh, grid)
            # exact distance to each candidate sub-triangle (a subset of its
            # parent's plane, so the minimum over them is the mesh distance)
            sub = bvh.tri[prim]
            c, _ = closest_on_triangles(q[pp], sub[:, 0], sub[:, 1], sub[:, 2])
            d2 = np.einsum("ij,ij->i", q[pp] - c, q[pp] - c)
            order = np.lexsort((d2, pp))
            first = np.ones(len(order), bool)
            first[1:] = pp[order][1:] != pp[order][:-1]
            sel = order[first]
            bt = t0.copy()
            bt[pp[sel]] = bvh.parent[prim[sel]]
            best_t[s:s + chunk] = bt
        out = np.empty_like(best_t)
        out[order_pts] = best_t
        return self._finish(p_in, out)

    @staticmethod
    def _candidates(q, ub, bvh, grid):
        """(point, sub-triangle) pairs whose boxes lie within ``ub``: from the
        point's grid cell where its radius fits the grid, else from the tree."""
        if grid is None:
            return bvh.candidates(q, ub)
        start, cnt = grid.lookup(q)
        fast = (cnt > 0) & (ub <= grid.reach)
        idx = np.flatnonzero(fast)
        c = cnt[idx]
        pp = np.repeat(idx, c)
        prim = grid.prim[np.repeat(start[idx] - np.cumsum(c) + c, c) + np.arange(len(pp))]
        qq = q[pp]
        d = np.maximum(np.maximum(bvh.lo[prim] - qq, qq - bvh.hi[prim]), 0.0)
        keep = np.einsum("ij,ij->i", d, d) <= ub[pp] ** 2
        pp, prim = pp[keep], prim[keep]
        slow = np.flatnonzero(~fast)
        if len(slow):
            sp, sprim = bvh.candidates(q[slow], ub[slow])
            pp = np.concatenate([pp, slow[sp]])
            prim = np.concatenate([prim, sprim])
        return pp, prim

    def _finish(self, p, t):
        tri = self.v[self.f[t]]
        q, bary = closest_on_triangles(p, tri[:, 0], tri[:, 1], tri[:, 2])
        eps = tol.inspect.feature_eps
        zero = bary <= eps
        nz = zero.sum(axis=1)
        pn = self.fn[t].copy()
        feature = np.zeros(len(p), np.int8)
        # on an edge: the edge opposite the zero weight; local edge i = (i, i+1)
        e = nz == 1
        if e.any():
            z = np.argmax(zero[e], axis=1)          # corner with zero weight
            local = (z + 1) % 3                      # edge (z+1, z+2)
            pn[e] = self.en[t[e], local]
            feature[e] = 1
        vtx = nz >= 2
        if vtx.any():
            corner = np.argmax(bary[vtx], axis=1)
            pn[vtx] = self.vn[self.f[t[vtx], corner]]
            feature[vtx] = 2
        r = p - q
        d = np.linalg.norm(r, axis=1)
        sign = np.where(_dot(r, pn) < 0, -1.0, 1.0)
        normal = np.where(d[:, None] > 0, r / np.where(d > 0, d, 1.0)[:, None] * sign[:, None],
                          self.fn[t])
        normal[feature == 0] = self.fn[t[feature == 0]]
        return Distances(sign * d, q, normal, self.label_ids[t], feature, self.labels)

    def bound(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (exact here; the name matches :class:`ExactSolid`)."""
        return self.distances(points).distance

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool — inside or on the mesh."""
        return self.distances(points).distance <= 0
