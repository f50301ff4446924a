"""Compiled exact closest-point kernel for triangle meshes (numba).

Frame and units: those of the mesh (tipgeo: cannula frame, mm); everything
in float64.

Why a compiled kernel: a scan has 10⁶–10⁷ points and a CAD mesh thousands of
triangles; vectorised numpy over (point, candidate) pairs spends its time in
temporaries (about 9 CPU s at 10⁶ points), libigl's double-precision AABB
tree took 4.6 CPU s on the 14G case and open3d's raycasting scene is float32
(off by up to 7.7 µm on sliver facets). numba ships wheels for every platform
tipgeo supports, so the kernel installs with plain pip and needs no compiler;
it is compiled once per machine and cached (``cache=True``).

Exactness: a bounding-volume tree over sub-triangles (every sub-triangle a
subset of its parent's plane), walked nearest box first and pruned only by a
box strictly farther than the best distance found, so no triangle that could
be nearest is skipped; the distance to each candidate is Ericson's
Voronoi-region closest point in float64. The result is the brute-force
minimum over all triangles up to the round-off of one closest-point
evaluation (~1e-16 mm).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..arrays import AnyArray, IntArray
from ..tolerances import tol

__all__ = ["grid_lists", "nearest_signed_into", "signed_rows", "sort_lists",
           "transform_envelope", "work_sizes"]


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _bary(px: float, py: float, pz: float, T: AnyArray, k: int,
          o: int) -> tuple[float, float, float]:
    """Closest point on the triangle stored flat in row ``k`` of ``T`` from
    column ``o`` on (a, b, c: nine floats) to p: barycentric weights (u, v, w)
    of a, b, c, in the region order of
    :func:`tipgeo.inspect.meshdist.closest_on_triangles` (exact 0 and 1 in
    edge and vertex regions)."""
    ax, ay, az = T[k, o], T[k, o + 1], T[k, o + 2]
    bx, by, bz = T[k, o + 3], T[k, o + 4], T[k, o + 5]
    cx, cy, cz = T[k, o + 6], T[k, o + 7], T[k, o + 8]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / (d1 - d3)
        return 1.0 - s, s, 0.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / (d2 - d6)
        return 1.0 - s, 0.0, s
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - s, s
    den = va + vb + vc
    v = vb / den
    w = vc / den
    return 1.0 - v - w, v, w


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _d2(px: float, py: float, pz: float, T: AnyArray, k: int) -> float:
    """Squared distance from p to sub-triangle ``k`` of ``T`` ((k, 15): box,
    then a, b, c); in a vertex region the vertex itself (what a·1 + b·0 +
    c·0 rounds to), so the same value as through the closest point."""
    u, v, w = _bary(px, py, pz, T, k, 6)
    if u == 1.0 and v == 0.0 and w == 0.0:
        qx, qy, qz = T[k, 6], T[k, 7], T[k, 8]
    elif v == 1.0 and u == 0.0 and w == 0.0:
        qx, qy, qz = T[k, 9], T[k, 10], T[k, 11]
    elif w == 1.0 and u == 0.0 and v == 0.0:
        qx, qy, qz = T[k, 12], T[k, 13], T[k, 14]
    else:
        qx = T[k, 6] * u + T[k, 9] * v + T[k, 12] * w
        qy = T[k, 7] * u + T[k, 10] * v + T[k, 13] * w
        qz = T[k, 8] * u + T[k, 11] * v + T[k, 14] * w
    d2: float = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
    return d2


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _box_d2(px: float, py: float, pz: float, box: AnyArray, k: int) -> float:
    """Squared distance from p to box k (row k of ``box``: lo xyz, hi xyz),
    without branches."""
    a = max(box[k, 0] - px, px - box[k, 3], 0.0)
    b = max(box[k, 1] - py, py - box[k, 4], 0.0)
    c = max(box[k, 2] - pz, pz - box[k, 5], 0.0)
    d2: float = a * a + b * b + c * c
    return d2


@njit(cache=True, fastmath=False, nogil=True)
def _walk(px: float, py: float, pz: float, box: AnyArray, first_leaf: int, start: AnyArray,
          stop: AnyArray, T: AnyArray, stack: AnyArray, bt: int, bd: float) -> int:
    """Nearest sub-triangle by the tree, from the bound (bt, bd)."""
    stack[0] = 0
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack[sp]
        # pruned only when strictly farther: ties and the true nearest stay
        if _box_d2(px, py, pz, box, node) > bd:
            continue
        if node >= first_leaf:
            leaf = node - first_leaf
            for k in range(start[leaf], stop[leaf]):
                if _box_d2(px, py, pz, T, k) > bd:
                    continue
                d = _d2(px, py, pz, T, k)
                if d < bd:
                    bd = d
                    bt = k
            continue
        c0 = 2 * node + 1
        # the nearer child on top of the stack: walked first
        if _box_d2(px, py, pz, box, c0) <= _box_d2(px, py, pz, box, c0 + 1):
            stack[sp] = c0 + 1
            stack[sp + 1] = c0
        else:
            stack[sp] = c0
            stack[sp + 1] = c0 + 1
        sp += 2
    return bt


@njit(cache=True, fastmath=False, nogil=True)
def _nearest_into(p: AnyArray, order: AnyArray, box: AnyArray, first_leaf: int,
                  start: AnyArray, stop: AnyArray, T: AnyArray, origin: AnyArray,
                  cell: float, dims: AnyArray, cstart: AnyArray, cprim: AnyArray,
                  clb: AnyArray, reach2: float, cap2: float, ps: AnyArray, bs: AnyArray,
                  best: AnyArray, seed: AnyArray) -> None:
    """Each point's nearest sub-triangle (index into ``T``) into ``best``
    ((n,) int), visiting the points in ``order`` (the previous point's
    triangle, or the point's ``seed``, bounds each search), with the work
    buffers ``ps`` ((≥ n, 3) float) and ``bs`` ((≥ n,) int) given; the
    other arguments as in :func:`nearest_signed_into`."""
    n = p.shape[0]
    seeded = seed.shape[0] > 0
    lbs = clb.shape[0] > 0
    stack = np.empty(256, np.int64)
    # the points gathered in visiting order first: one pass of independent
    # loads, then a sequential walk (about 40 % faster than reading p[order[j]]
    # inside the search)
    for j in range(n):
        i = order[j]
        ps[j, 0], ps[j, 1], ps[j, 2] = p[i, 0], p[i, 1], p[i, 2]
    prev = 0
    for j in range(n):
        px, py, pz = ps[j, 0], ps[j, 1], ps[j, 2]
        bt = prev
        if seeded and seed[order[j]] >= 0:
            bt = seed[order[j]]
        first = bt
        # beyond the cap the seed stands: at least that far (see cap2 of nearest_signed_into)
        bd = _d2(px, py, pz, T, bt)
        if bd > cap2:
            bd = cap2
        ix = int(np.floor((px - origin[0]) / cell))
        iy = int(np.floor((py - origin[1]) / cell))
        iz = int(np.floor((pz - origin[2]) / cell))
        if 0 <= ix < dims[0] and 0 <= iy < dims[1] and 0 <= iz < dims[2]:
            c = (iz * dims[1] + iy) * dims[0] + ix
            for e in range(cstart[c], cstart[c + 1]):
                # sorted lists: the rest is farther from every point of the cell
                if lbs and clb[e] > bd:
                    break
                k = cprim[e]
                # the seed is in bd already; its box never prunes it
                if _box_d2(px, py, pz, T, k) > bd or k == first:
                    continue
                d = _d2(px, py, pz, T, k)
                if d < bd:
                    bd = d
                    bt = k
        if not bd <= reach2:
            bt = _walk(px, py, pz, box, first_leaf, start, stop, T, stack, bt, bd)
        bs[j] = bt
        prev = bt
    for j in range(n):
        best[order[j]] = bs[j]


@njit(cache=True, fastmath=False, nogil=True)
def grid_lists(tbox: AnyArray, origin: AnyArray, cell: float, dims: AnyArray,
               grow: float) -> tuple[IntArray, IntArray]:
    """Each uniform-grid cell's list of the boxes (rows of ``tbox``, (k, ≥ 6):
    lo xyz, hi xyz first) that, grown by ``grow``, touch it: CSR (start
    (cells + 1,), entries), by two passes."""
    ncell = dims[0] * dims[1] * dims[2]
    start = np.zeros(ncell + 1, np.int64)
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    for pas in range(2):
        if pas == 1:
            for c in range(ncell):
                start[c + 1] += start[c]
            prim = np.empty(start[ncell], np.int32)
            fill = start[:-1].copy()
        for k in range(tbox.shape[0]):
            for a in range(3):
                lo[a] = max(0, int(np.floor((tbox[k, a] - grow - origin[a]) / cell)))
                hi[a] = min(dims[a] - 1, int(np.floor((tbox[k, a + 3] + grow - origin[a]) / cell)))
            for iz in range(lo[2], hi[2] + 1):
                for iy in range(lo[1], hi[1] + 1):
                    for ix in range(lo[0], hi[0] + 1):
                        c = (iz * dims[1] + iy) * dims[0] + ix
                        if pas == 0:
                            start[c + 1] += 1
                        else:
                            prim[fill[c]] = k
                            fill[c] += 1
    return start, prim


@njit(cache=True, fastmath=False, nogil=True)
def sort_lists(tbox: AnyArray, origin: AnyArray, cell: float, dims: AnyArray, margin: float,
               start: AnyArray, prim: AnyArray) -> AnyArray:
    """Sort each cell's list of :func:`grid_lists` (``start``, ``prim``,
    sorted in place) by its lower bounds, returned (float32, one per entry):
    the squared distance from the cell, grown by ``margin`` (a point rounded
    into the cell from just outside stays in it), to the entry's box
    (rows of ``tbox``: lo xyz, hi xyz first), rounded down. No point of the
    cell is nearer a box than its bound: a search may stop at the first
    bound beyond its best distance."""
    lb = np.empty(prim.shape[0], np.float32)
    ncell = dims[0] * dims[1] * dims[2]
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(ncell):
        a, b = start[c], start[c + 1]
        if a == b:
            continue
        lo[0] = origin[0] + (c % dims[0]) * cell - margin
        lo[1] = origin[1] + ((c // dims[0]) % dims[1]) * cell - margin
        lo[2] = origin[2] + (c // (dims[0] * dims[1])) * cell - margin
        for ax in range(3):
            hi[ax] = lo[ax] + cell + 2.0 * margin
        for e in range(a, b):
            k = prim[e]
            d2 = 0.0
            for ax in range(3):
                g = max(tbox[k, ax] - hi[ax], lo[ax] - tbox[k, ax + 3], 0.0)
                d2 += g * g
            f = np.float32(d2)
            if f > d2:  # rounded up: one float32 step down keeps it a lower bound
                f = np.nextafter(f, np.float32(0.0))
            # insertion sort: the lists are short (about 15 entries)
            j = e
            while j > a and lb[j - 1] > f:
                lb[j] = lb[j - 1]
                prim[j] = prim[j - 1]
                j -= 1
            lb[j] = f
            prim[j] = k
    return lb


@njit(cache=True, fastmath=False, nogil=True)
def _order_into(p: AnyArray, bits: int, order: AnyArray, key: AnyArray, count: AnyArray) -> None:
    """A permutation ``order`` ((n,) int) of the points (n, 3) grouping them
    by Morton cell (``bits`` per axis over their bounding box; input order
    within a cell): a counting sort, O(n + 8**bits), with the work buffers
    ``key`` ((≥ n,) int) and ``count`` ((≥ 8**bits + 1,) int, any content)."""
    n = p.shape[0]
    if n == 0:
        return
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(3):
        lo[c] = hi[c] = p[0, c]
    for i in range(n):     # one pass over the rows for the bounding box
        for c in range(3):
            lo[c] = min(lo[c], p[i, c])
            hi[c] = max(hi[c], p[i, c])
    sc = np.empty(3)
    for c in range(3):
        sc[c] = ((1 << bits) - 1) / (hi[c] - lo[c]) if hi[c] > lo[c] else 0.0
    # bit j of a cell index goes to bit 3j of the code: a table, not a loop
    spread = np.zeros(1 << bits, np.int64)
    for q in range(1 << bits):
        for j in range(bits):
            spread[q] |= ((q >> j) & 1) << (3 * j)
    count[:(1 << (3 * bits)) + 1] = 0
    top = (1 << bits) - 1
    for i in range(n):
        code = 0
        for c in range(3):
            f = (p[i, c] - lo[c]) * sc[c]   # NaN or ∞ on a subnormal span:
            q = int(f) if 0.0 < f < (1 << bits) else (0 if not f > 0.0 else top)
            code |= spread[q] << c
        key[i] = code
        count[code + 1] += 1
    for j in range(1, (1 << (3 * bits)) + 1):
        count[j] += count[j - 1]
    for i in range(n):
        order[count[key[i]]] = i
        count[key[i]] += 1


@njit(cache=True, fastmath=False, nogil=True, inline="always")
def _signed(px: float, py: float, pz: float, k: int, PT: AnyArray, f: AnyArray, fn: AnyArray,
            en: AnyArray, vn: AnyArray,
            eps: float) -> tuple[float, float, float, float, float, float, float, int]:
    """Signed distance of p to parent triangle ``k`` (corners in row k of
    ``PT``): (d, qx, qy, qz, nx, ny, nz, feature), the normal as
    :func:`nearest_signed_into` documents it; the sign from the angle-weighted
    pseudo-normal of the feature the closest point lies on."""
    u, v, w = _bary(px, py, pz, PT, k, 0)
    qx = PT[k, 0] * u + PT[k, 3] * v + PT[k, 6] * w
    qy = PT[k, 1] * u + PT[k, 4] * v + PT[k, 7] * w
    qz = PT[k, 2] * u + PT[k, 5] * v + PT[k, 8] * w
    nz = (u <= eps) + (v <= eps) + (w <= eps)
    if nz == 1:
        # the zero weight's corner is opposite the edge: local edge (z + 1) % 3
        e = 1 if u <= eps else (2 if v <= eps else 0)
        pnx, pny, pnz = en[k, e, 0], en[k, e, 1], en[k, e, 2]
        fe = 1
    elif nz >= 2:
        corner = 0
        if v > u:
            corner = 1
        if w > (v if corner == 1 else u):
            corner = 2
        c = f[k, corner]
        pnx, pny, pnz = vn[c, 0], vn[c, 1], vn[c, 2]
        fe = 2
    else:
        pnx, pny, pnz = fn[k, 0], fn[k, 1], fn[k, 2]
        fe = 0
    rx, ry, rz = px - qx, py - qy, pz - qz
    dd = np.sqrt(rx * rx + ry * ry + rz * rz)
    sign = -1.0 if rx * pnx + ry * pny + rz * pnz < 0.0 else 1.0
    if fe == 0 or not dd > 0.0:
        nx, ny, nz_ = fn[k, 0], fn[k, 1], fn[k, 2]
    else:
        s = sign / dd
        nx, ny, nz_ = rx * s, ry * s, rz * s
    return sign * dd, qx, qy, qz, nx, ny, nz_, fe


@njit(cache=True, fastmath=False, nogil=True)
def nearest_signed_into(p: AnyArray, rows: AnyArray, bits: int, box: AnyArray, first_leaf: int,
                        start: AnyArray, stop: AnyArray, T: AnyArray, origin: AnyArray,
                        cell: float, dims: AnyArray, cstart: AnyArray, cprim: AnyArray,
                        clb: AnyArray, reach2: float, parent: AnyArray, PT: AnyArray, f: AnyArray,
                        fn: AnyArray, en: AnyArray, vn: AnyArray, eps: float, label: AnyArray,
                        far: float, near: float, P: AnyArray, dist: AnyArray, clo: AnyArray,
                        nrm: AnyArray, tri: AnyArray, face: AnyArray, feat: AnyArray,
                        out_rows: AnyArray, cur: int, iw: AnyArray,
                        fw: AnyArray, cap2: float, seed: AnyArray) -> tuple[int, int]:
    """The nearest triangle of every point and its signed distance in one
    compiled call (what ``compare`` runs per chunk, and every
    :meth:`~tipgeo.inspect.meshdist.MeshSolid.distances` query): the points
    are put in spatial order (Morton cells, ``bits`` per axis: each search
    starts from its predecessor's triangle), each one's nearest sub-triangle
    found exactly (its cell's list, then the tree where the list's best lies
    beyond the reach), and those with |d| ≤ ``far`` (∞: every point, NaN
    included) are appended in input order at row ``cur`` of ``P`` (the
    point), ``dist``, ``clo`` (closest point), ``nrm`` (normal), ``face``
    (``label`` of the parent triangle), ``feat`` and ``out_rows``
    (``rows``); any float dtype for the points, closest points and normals
    (compare keeps them in float32). ``clo`` and ``nrm`` with no rows are
    not written (:func:`signed_rows` gives them later); ``tri`` with rows
    receives each point's triangle. ``iw`` (int64) and ``fw`` (float64) are
    work buffers of at least :func:`work_sizes` (reused from chunk to chunk:
    no fresh memory per call).

    Parameters
    ----------
    box : (m, 6) float — boxes (lo xyz, hi xyz) of an implicit complete
        binary tree (node i has children 2i+1, 2i+2; nodes from
        ``first_leaf`` on are leaves)
    start, stop : (m - first_leaf,) int — each leaf's range in ``T``
    T : (k, 15) float — sub-triangles in leaf order, one row each: box (lo
        xyz, hi xyz), then corners a, b, c (one row: one or two cache lines)
    origin : (3,) float; cell : float; dims : (3,) int — a uniform grid
        (``dims`` all 0: none)
    cstart : (cells + 1,) int; cprim : (e,) int — each cell's list: every
        sub-triangle whose box, grown by the reach, touches the cell
    clb : (e,) float32 or (0,) — the lists' lower bounds when they are
        sorted by them (:func:`sort_lists`): a cell's search stops at the
        first bound beyond its best distance
    reach2 : float — the reach squared: a list minimum within it is exact
    parent : (k,) int — the mesh triangle of each sub-triangle, whose
        corners are rows of ``PT`` ((m, 9) float: a, b, c)
    f : (m, 3) int — the triangles' vertex indices
    fn : (m, 3) float — unit face normals
    en : (m, 3, 3) float — edge pseudo-normals (triangle, local edge i from
        corner i to i+1, xyz)
    vn : (nv, 3) float — vertex pseudo-normals
    eps : float — a barycentric weight ≤ eps is zero (feature test)
    cap2 : float — a squared distance (mm²; ∞: none) beyond which the search
        stops: a point with a triangle nearer than √cap2 gets its nearest;
        a point with none keeps a triangle at least that far (what a
        distance clipped at √cap2 needs, at a fraction of the far points'
        tree walks)
    seed : (n,) int or (0,) — each point's first guess (an index into ``T``;
        < 0: none), e.g. its nearest sub-triangle before the last small move
        of the points, replaced by its nearest; it only sets the starting
        bound of the exact search: the same nearest distance with or
        without it

    The normal is the face normal inside a face, else the unit direction
    from the closest point to the point, signed; the feature 0 face, 1 edge,
    2 vertex.

    Returns
    -------
    cur : int — rows filled after this call
    near_count : int — points with |d| ≤ ``near``
    """
    n = p.shape[0]
    order, bs, best = iw[:n], iw[n:2 * n], iw[2 * n:3 * n]
    _order_into(p, bits, order, bs, iw[3 * n:])
    _nearest_into(p, order, box, first_leaf, start, stop, T, origin, cell, dims, cstart,
                  cprim, clb, reach2, cap2, fw[:3 * n].reshape((n, 3)), bs, best, seed)
    if seed.shape[0]:
        seed[:] = best
    nn = 0
    for i in range(p.shape[0]):
        k = parent[best[i]]
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        d, qx, qy, qz, nx, ny, nz, fe = _signed(px, py, pz, k, PT, f, fn, en, vn, eps)
        ad = abs(d)
        if ad <= near:
            nn += 1
        if not ad <= far and far != np.inf:
            continue
        P[cur, 0], P[cur, 1], P[cur, 2] = px, py, pz
        dist[cur] = d
        if clo.shape[0]:
            clo[cur, 0], clo[cur, 1], clo[cur, 2] = qx, qy, qz
            nrm[cur, 0], nrm[cur, 1], nrm[cur, 2] = nx, ny, nz
        if tri.shape[0]:
            tri[cur] = k
        face[cur] = label[k]
        feat[cur] = fe
        out_rows[cur] = rows[i]
        cur += 1
    return cur, nn


@njit(cache=True, fastmath=False, nogil=True)
def signed_rows(x: AnyArray, rows: AnyArray, R: AnyArray, t: AnyArray, tri: AnyArray,
                PT: AnyArray, f: AnyArray, fn: AnyArray, en: AnyArray, vn: AnyArray,
                eps: float, clo: AnyArray, nrm: AnyArray) -> None:
    """Closest points and normals of the points ``R x[rows] + t`` to their
    triangles ``tri`` (the arithmetic of :func:`transform_envelope` and of
    :func:`nearest_signed_into`, so the same values bit for bit), written to
    ``clo`` and ``nrm`` ((len(rows), 3), any float dtype); the other
    arguments as in :func:`nearest_signed_into`."""
    for j in range(rows.shape[0]):
        i = rows[j]
        a, b, c = np.float64(x[i, 0]), np.float64(x[i, 1]), np.float64(x[i, 2])
        qz = a * R[2, 0] + b * R[2, 1] + c * R[2, 2] + t[2]
        qx = a * R[0, 0] + b * R[0, 1] + c * R[0, 2] + t[0]
        qy = a * R[1, 0] + b * R[1, 1] + c * R[1, 2] + t[1]
        _, cx, cy, cz, nx, ny, nz, _ = _signed(qx, qy, qz, tri[j], PT, f, fn, en, vn, eps)
        clo[j, 0], clo[j, 1], clo[j, 2] = cx, cy, cz
        nrm[j, 0], nrm[j, 1], nrm[j, 2] = nx, ny, nz


def work_sizes(n: int, bits: int) -> tuple[int, int]:
    """Lengths of the int64 and float64 work buffers of
    :func:`nearest_signed_into` for chunks of up to ``n`` points ordered
    with ``bits`` Morton bits."""
    return 3 * n + (1 << (3 * bits)) + 1, 3 * n


#: tol.inspect.hypot_margin, a compile-time constant of the compiled loop below.
_HYPOT_MARGIN = tol.inspect.hypot_margin


@njit(cache=True, fastmath=False, nogil=True)
def transform_envelope(x: AnyArray, R: AnyArray, t: AnyArray, crop: bool, z_min: float,
                       reach: float, z_lo: float, z_hi: float, q: AnyArray, rows: AnyArray,
                       first: int) -> tuple[int, int]:
    """Map points by a rigid transform and keep those that may lie near the CAD.

    Parameters
    ----------
    x : (n, 3) float32 or float64 — points (offsets in the scanner frame, mm)
    R : (3, 3) float; t : (3,) float — the transform, ``q = R x + t`` (into
        the cannula frame, float64)
    crop : bool — drop points with z < ``z_min`` (counted as cropped)
    reach : float — radius of the envelope cylinder about +z (mm)
    z_lo, z_hi : float — its axial extent (mm)
    q : (≥ n, 3) float — filled with the kept points, in input order
    rows : (≥ n,) int — filled with their rows, ``first`` + index in ``x``

    Returns
    -------
    kept : int — points in the envelope (the first ``kept`` rows of q, rows)
    cropped : int — points dropped by the crop
    """
    kept = 0
    cropped = 0
    # the radius by its square, and math.hypot only within round-off of the
    # reach (the squares' relative error is below 1e-15): the same decisions
    # as hypot alone, at a quarter of the cost
    lo2 = reach * reach * (1.0 - _HYPOT_MARGIN)
    hi2 = reach * reach * (1.0 + _HYPOT_MARGIN)
    for i in range(x.shape[0]):
        a, b, c = np.float64(x[i, 0]), np.float64(x[i, 1]), np.float64(x[i, 2])
        qz = a * R[2, 0] + b * R[2, 1] + c * R[2, 2] + t[2]
        if crop and not qz >= z_min:
            cropped += 1
            continue
        if qz < z_lo or qz > z_hi:
            continue
        qx = a * R[0, 0] + b * R[0, 1] + c * R[0, 2] + t[0]
        qy = a * R[1, 0] + b * R[1, 1] + c * R[1, 2] + t[1]
        r2 = qx * qx + qy * qy
        if not r2 <= lo2 and not (r2 <= hi2 and math.hypot(qx, qy) <= reach):
            continue
        q[kept, 0], q[kept, 1], q[kept, 2] = qx, qy, qz
        rows[kept] = first + i
        kept += 1
    return kept, cropped
