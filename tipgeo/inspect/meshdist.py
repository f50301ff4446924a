"""Exact signed distance to a triangle mesh, in double precision.

Frame and units: those of the mesh (tipgeo: cannula frame, mm).

Distances: the closest point on every candidate triangle is computed in
double precision (Ericson's Voronoi-region test) by the compiled kernel of
:mod:`tipgeo.inspect.nearest`. Candidates come from a bounding-box tree over
sub-triangles (a facet whose box is fat — an oblique bevel facet — is
bisected until its box is thin; a long facet along an axis, like a fine
tube's 10 mm × 20 µm ones, keeps its tight box), walked nearest box first
from the bound its spatial predecessor's triangle gives, and pruned only by
boxes strictly farther than the best triangle so far: no triangle that could
be nearest is skipped, so the answer is exact, not approximate. (open3d's
float32 closest-point query is off by micrometres on such facets.)

Signs: from the angle-weighted pseudo-normal of the feature the closest point
lies on (Bærentzen & Aanæs 2005): the face normal inside a triangle, the sum
of both facets' normals on an edge, the angle-weighted vertex normal at a
corner. At a knife edge, where a bevel facet and a bore facet tie as nearest,
the sign comes from the edge's pseudo-normal, never from whichever facet came
first. The mesh must be closed and consistently oriented (a built tip is).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..arrays import AnyArray, BoolArray, FloatArray, IntArray
from ..errors import TipGeoError
from ..tolerances import tol
from .exact import Distances

__all__ = ["MeshSolid", "brute_force_distances", "closest_on_triangles"]


def closest_on_triangles(p: FloatArray, a: FloatArray, b: FloatArray,
                         c: FloatArray) -> tuple[FloatArray, FloatArray]:
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

    def put(mask: BoolArray, uu: FloatArray | float, vv: FloatArray | float,
            ww: FloatArray | float) -> None:
        m = mask & ~done
        u[m], v[m], w[m] = _at(uu, m), _at(vv, m), _at(ww, m)
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


def brute_force_distances(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unsigned distance of every point to the nearest of all triangles,
    by :func:`closest_on_triangles` against each triangle in turn (float64):
    the reference the compiled kernel is tested and benchmarked against.

    Parameters
    ----------
    points : (n, 3) float — mm
    triangles : (m, 3, 3) float — mm

    Returns
    -------
    (n,) float — mm
    """
    p = np.asarray(points, float)
    best = np.full(len(p), np.inf)
    for t in np.asarray(triangles, float):
        q, _ = closest_on_triangles(p, *(np.broadcast_to(t[i], p.shape) for i in range(3)))
        best = np.minimum(best, np.linalg.norm(p - q, axis=1))
    return best


def _at(x: FloatArray | float, m: BoolArray) -> FloatArray | float:
    """``x[m]`` of an array, a scalar (or 0-d array) as it is."""
    if isinstance(x, np.ndarray) and x.ndim:
        return x[m]
    return x


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    out: FloatArray = np.einsum("ij,ij->i", x, y)
    return out


def _check_hint(hint: Any, n: int, subs: int) -> None:
    """A :meth:`MeshSolid.distances` hint: (n,) C-contiguous int64, every
    entry < ``subs`` (the sub-triangles); ValueError otherwise."""
    if not (isinstance(hint, np.ndarray) and hint.dtype == np.int64 and hint.shape == (n,)
            and hint.flags.c_contiguous and hint.flags.writeable):
        raise ValueError(f"hint: expected a writeable C-contiguous ({n},) int64 array, got "
                         f"{getattr(hint, 'dtype', type(hint).__name__)} "
                         f"{getattr(hint, 'shape', '')}")
    if n and int(hint.max()) >= subs:
        raise ValueError(f"hint: index {int(hint.max())} past the {subs} sub-triangles "
                         "(a hint from another CAD?)")


def _split_fat(v: FloatArray, f: IntArray, cell: float) -> tuple[FloatArray, IntArray]:
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


#: no first guesses (:meth:`MeshSolid.distances` without a hint)
_NO_SEED = np.empty(0, np.int64)


class _Tree:
    """A balanced bounding-box tree over sub-triangles, stored as an implicit
    complete binary tree (node i has children 2i+1 and 2i+2): each node's
    range of sub-triangles is sorted along the longest axis of their box
    centres and halved (object median), leaves of at most ``LEAF``."""

    LEAF = 4

    def __init__(self, sub: FloatArray, parent: IntArray) -> None:
        lo, hi = sub.min(axis=1), sub.max(axis=1)
        c = 0.5 * (lo + hi)
        n = len(sub)
        perm = np.arange(n)
        levels = [np.array([[0, n]])]
        while (levels[-1][:, 1] - levels[-1][:, 0]).max() > self.LEAF:
            r = levels[-1]
            node = np.repeat(np.arange(len(r)), r[:, 1] - r[:, 0])
            cc = c[perm]
            span = (np.maximum.reduceat(cc, r[:, 0], axis=0)
                    - np.minimum.reduceat(cc, r[:, 0], axis=0))
            axis = np.argmax(span, axis=1)
            perm = perm[np.lexsort((cc[np.arange(n), axis[node]], node))]
            mid = (r[:, 0] + r[:, 1]) // 2
            levels.append(np.stack([np.stack([r[:, 0], mid], 1),
                                    np.stack([mid, r[:, 1]], 1)], 1).reshape(-1, 2))
        # ranges are never empty: sizes at a level differ by at most one and
        # the last split was of ranges longer than LEAF
        tlo, thi = lo[perm], hi[perm]
        self.parent = parent[perm]
        # one row per sub-triangle: its box, then its corners (what the
        # kernel reads together, in one or two cache lines)
        self.T = np.ascontiguousarray(np.hstack([tlo, thi, sub[perm].reshape(-1, 9)]))
        self.box = np.ascontiguousarray(np.hstack([
            np.concatenate([np.minimum.reduceat(tlo, r[:, 0], axis=0) for r in levels]),
            np.concatenate([np.maximum.reduceat(thi, r[:, 0], axis=0) for r in levels])]))
        self.first_leaf = len(self.box) - len(levels[-1])
        self.start = np.ascontiguousarray(levels[-1][:, 0])
        self.stop = np.ascontiguousarray(levels[-1][:, 1])
        self._grid(tlo, thi)

    def _grid(self, lo: FloatArray, hi: FloatArray) -> None:
        """Uniform cells listing every sub-triangle whose box, grown by the
        reach (half a cell), touches the cell: a point whose nearest triangle
        in its cell's list lies within the reach needs no tree walk. The
        cell grows until the grid has at most ``tol.inspect.grid_cells``
        cells and ``tol.inspect.grid_entries`` entries; past that, no grid."""
        st = tol.inspect
        cell = st.grid_cell
        self.cell, self.reach2 = 1.0, 0.0
        self.origin, self.dims = np.zeros(3), np.zeros(3, np.int64)
        self.cstart: IntArray = np.zeros(1, np.int64)
        self.cprim: IntArray = np.zeros(0, np.int32)
        self.clb: AnyArray = np.zeros(0, np.float32)   # the lists unsorted
        ext = (hi.max(axis=0) - lo.min(axis=0)) if len(lo) else np.zeros(3)
        for _ in range(8):
            reach = 0.5 * cell
            # the lists are built a hair wider than the reach tested, so a
            # point rounded into the neighbouring cell still finds them all
            grow = reach * (1 + st.grid_grow_rel) + tol.tiny
            origin = lo.min(axis=0) - grow - cell
            dims = np.floor((ext + 2 * grow) / cell).astype(np.int64) + 3
            i0 = np.floor((lo - grow - origin) / cell).astype(np.int64)
            i1 = np.floor((hi + grow - origin) / cell).astype(np.int64)
            n3 = i1 - i0 + 1
            cnt = n3.prod(axis=1)
            if dims.prod() <= st.grid_cells and cnt.sum() <= st.grid_entries:
                break
            cell *= 2
        else:
            return
        from .nearest import grid_lists

        self.cstart, self.cprim = grid_lists(self.T, origin, cell, dims, grow)
        self.cell, self.reach2, self.origin, self.dims = cell, reach * reach, origin, dims
        self.margin = grow - reach

    def sort_lists(self) -> None:
        """Sort each cell's list by its lower bound
        (:func:`~tipgeo.inspect.nearest.sort_lists`), once: a search then
        stops at the first entry beyond its best. Worth it for a large
        query only: 22 ms for the 14G bevel's 1.8·10⁶ entries, −7 % of the
        exact search's CPU time at 10⁷ points (2.27–2.31 → 2.12–2.14 s)."""
        if len(self.clb) or not len(self.cprim):
            return
        from .nearest import sort_lists

        self.clb = sort_lists(self.T, self.origin, self.cell, self.dims, self.margin,
                              self.cstart, self.cprim)

    @property
    def args(self) -> tuple[Any, ...]:
        """The tree and grid arguments of
        :func:`~tipgeo.inspect.nearest.nearest_signed_into` (from ``box`` to
        ``reach2``)."""
        return (self.box, self.first_leaf, self.start, self.stop, self.T, self.origin,
                self.cell, self.dims, self.cstart, self.cprim, self.clb, self.reach2)


class MeshSolid:
    """Exact signed distances to a closed, labelled triangle mesh.

    Parameters
    ----------
    tip : Tip
        Vertices (mm), faces (outward, counter-clockwise), labels.
    cell : float
        Longest sub-triangle edge of the candidate index (mm; speed only).
    """

    def __init__(self, tip: Any, *, cell: float | None = None) -> None:
        self.tip = tip
        self.v = np.ascontiguousarray(tip.vertices, float)
        self.f = np.ascontiguousarray(tip.faces, np.int64)
        self.PT = np.ascontiguousarray(self.v[self.f].reshape(-1, 9))  # corners a, b, c
        self.labels = tuple(tip.label_names)
        self.label_ids = np.asarray(tip.label_ids)
        self.cell = float(cell or tol.inspect.mesh_cell)
        self._index: _Tree | None = None
        self._pseudo()

    def _pseudo(self) -> None:
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

    def _build(self) -> _Tree:
        """The candidate index, built on first use."""
        if self._index is None:
            sub, parent = _split_fat(self.v, self.f, self.cell)
            self._index = _Tree(sub, parent)
        return self._index

    @staticmethod
    def _bits(n: int) -> int:
        """Morton bits per axis of the spatial order of n points: about 3 to
        23 cells a point (8**bits cells, at most 8**7: a 16 MB counting
        table for compare's chunks of up to 5.2·10⁵ points). Cells finer
        than the points put consecutive points closer, so each search starts
        from a nearer triangle (measured on a 10⁶-point scan: 2.5 → 1.9 exact
        triangle tests a point from 1 to 8 cells a point; the exact search
        of compare's deviation pass, min of 3–6 runs, chunks of 2¹⁸ points
        at bits 7 instead of 6: 0.215 → 0.205 CPU s at 10⁶ points, 2.29 →
        2.22–2.32 at 10⁷; chunks keeping 2.55·10⁵ points, which the earlier
        floor put at bits 5 (0.13 cells a point): 3.06–3.36 → 2.56–2.61)."""
        return int(min(7, max(1, np.round(np.log2(max(n, 2)) / 3) + 1)))

    def distances(self, points: np.ndarray, cap: float | None = None, *,
                  hint: IntArray | None = None) -> Distances:
        """Exact signed distance, closest point, normal and face of every point.

        Parameters
        ----------
        points : (n, 3) float — mm
        cap : float, optional — mm: the fields are exact for the points with
            |d| < cap; the others get those of a triangle at least ``cap``
            away (|d| ≥ cap), their searches stopped there
        hint : (n,) int64, optional — speed only: each point's nearest
            sub-triangle from an earlier call on the same points (−1 at
            first), updated in place; a point moved a little starts its
            search there (ICP's iterations). The nearest distances are the
            same with or without it (to the round-off of one closest-point
            evaluation where an edge's two triangles tie).
        """
        p = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 3))
        n = len(p)
        if hint is not None:
            _check_hint(hint, n, len(self._build().T))
        # the points' copy (not returned) in float32 and the faces in int16,
        # as compare's deviation pass has them: one compiled signature of
        # the kernel serves both (each one more is 11 ms to load per process)
        out = (np.empty((n, 3), np.float32), np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
               np.empty(n, np.int16), np.empty(n, np.int8), np.empty(n, np.int64))
        # far = ∞: every point, in input order (the kernel's one search)
        done, _ = self._search(p, np.arange(n), far=math.inf, near=0.0, out=out, cur=0,
                               cap2=math.inf if cap is None else cap * cap,
                               seed=_NO_SEED if hint is None else hint)
        assert done == n
        _, d, q, normal, face, feature, _ = out
        return Distances(d, q, normal, face.astype(np.int64), feature, self.labels)

    def distances_into(self, points: AnyArray, rows: IntArray, *, far: float, near: float,
                       out: tuple[AnyArray, ...], cur: int,
                       tri: AnyArray | None = None,
                       work: tuple[AnyArray, AnyArray] | None = None) -> tuple[int, int]:
        """:meth:`distances` of the points (mm), appended to a scan's result
        arrays from row ``cur`` on where |d| ≤ ``far`` (mm), with no
        temporary per point (what ``compare`` uses).

        Parameters
        ----------
        points : (n, 3) float64 — mm, cannula frame
        rows : (n,) int — their rows in the scan
        far : float — points farther from the mesh are left out (mm)
        near : float — the count returned is of points within it (mm)
        out : tuple — (points (m, 3) float32, distance (m,) float64, closest
            (m, 3) float32, normal (m, 3) float32, face (m,) int, feature (m,)
            int8, rows (m,) int); closest and normal with no rows: not
            written (:meth:`closest_normals` gives them later)
        tri : (m,) int, optional — receives each kept point's triangle
        work : (int64, float64) arrays, optional — work buffers of at least
            :meth:`work_sizes` of the chunk (a caller running chunk after
            chunk passes the same ones: no fresh memory per chunk)

        Returns
        -------
        cur : int — rows filled; near_count : int — points with |d| ≤ ``near``
        """
        p = np.ascontiguousarray(points, float)
        if work is not None and (len(work[0]) < self.work_sizes(len(p))[0]
                                 or len(work[1]) < self.work_sizes(len(p))[1]):
            raise ValueError("distances_into: work buffers smaller than work_sizes()")
        return self._search(p, rows, far=far, near=near, out=out, cur=cur, tri=tri, work=work)

    def _search(self, p: AnyArray, rows: IntArray, *, far: float, near: float,
                out: tuple[AnyArray, ...], cur: int, tri: AnyArray | None = None,
                work: tuple[AnyArray, AnyArray] | None = None, cap2: float = math.inf,
                seed: AnyArray = _NO_SEED) -> tuple[int, int]:
        """The one compiled call behind :meth:`distances` and
        :meth:`distances_into` (spatial order, exact nearest search, signed
        distances): :func:`~tipgeo.inspect.nearest.nearest_signed_into` on
        ``p`` ((n, 3) float64, mm)."""
        from .nearest import nearest_signed_into

        index = self._build()
        P, dist, clo, nrm, face, feat, out_rows = out
        iw, fw = work if work is not None else self.work_buffers(len(p))
        run: Callable[..., tuple[int, int]] = nearest_signed_into
        done = run(
            p, rows, self._bits(len(p)), *index.args, index.parent, self.PT, self.f, self.fn,
            self.en, self.vn, tol.inspect.feature_eps, self.label_ids, far, near, P, dist, clo,
            nrm, np.empty(0, np.int32) if tri is None else tri, face, feat, out_rows, cur, iw, fw,
            cap2, seed)
        return done

    def prepare(self, points: int) -> None:
        """Get ready for a query of ``points`` points in all: from
        ``tol.inspect.sorted_lists_points`` on, the grid's lists are sorted
        by their lower bounds (:meth:`_Tree.sort_lists`); the same
        distances either way (to round-off where triangles tie)."""
        if points >= tol.inspect.sorted_lists_points:
            self._build().sort_lists()

    def work_sizes(self, n: int) -> tuple[int, int]:
        """Lengths of the (int64, float64) work buffers of
        :meth:`distances_into` for chunks of up to ``n`` points."""
        from .nearest import work_sizes

        return work_sizes(n, self._bits(n))

    def work_buffers(self, n: int) -> tuple[AnyArray, AnyArray]:
        """Work buffers for :meth:`distances_into` on chunks of up to ``n``
        points (any chunk of at most n points fits: the sizes grow with n)."""
        a, b = self.work_sizes(n)
        return np.empty(a, np.int64), np.empty(b)

    def closest_normals(self, x: AnyArray, rows: IntArray, T: FloatArray, tri: IntArray,
                        dtype: Any = np.float32) -> tuple[AnyArray, AnyArray]:
        """Closest points and normals (as :meth:`distances` gives them) of the
        points ``T`` applied to ``x[rows]``, given their triangles ``tri``
        (from :meth:`distances_into`): the same values bit for bit as when the
        points went through it, the rigid transform done by the same
        arithmetic.

        Parameters
        ----------
        x : (n, 3) float — points (mm, e.g. a scan's offsets)
        rows : (k,) int — which; T : (4, 4) float — into the mesh's frame
        tri : (k,) int — their triangles
        dtype : the result's float type

        Returns
        -------
        closest, normal : (k, 3) — mm, mesh frame; unit
        """
        from .nearest import signed_rows

        clo = np.empty((len(rows), 3), dtype)
        nrm = np.empty((len(rows), 3), dtype)
        signed_rows(x, rows, np.ascontiguousarray(T[:3, :3], float),
                    np.ascontiguousarray(T[:3, 3], float), tri, self.PT, self.f, self.fn,
                    self.en, self.vn, tol.inspect.feature_eps, clo, nrm)
        return clo, nrm

    def bound(self, points: np.ndarray, cap: float | None = None) -> np.ndarray:
        """Signed distance (mm; exact here, the name matches
        :class:`ExactSolid`). With ``cap`` (mm) exact where |d| < cap, and
        |value| ≥ cap elsewhere — all that a distance clipped at ``cap``
        needs, and the far points' searches stop there."""
        return self.distances(points, cap).distance
