"""Exact k nearest neighbours of every point of a small cloud (numba), on a
uniform grid searched ring by ring.

Units: those of the points (tipgeo: mm). What the registration uses on its
subset (about 2·10⁴ points) for outlier removal and normals; it replaces
scipy's cKDTree there, whose import (``scipy.spatial``, which imports
``scipy.special`` and ``scipy.sparse``) cost more CPU time than the
queries.

Exactness: a point's ring r of cells is searched only while a point outside
the rings searched could still be nearer than its k-th neighbour so far —
every point outside rings 0..r is at least r cell widths away, less the
round-off of the cell indices — so the
neighbours are the brute-force ones (of equal distances, the one found
first), their distances √(dx² + dy² + dz²) in float64.
"""

from __future__ import annotations

import numpy as np

from .._jit import njit
from ..arrays import AnyArray, FloatArray, IntArray

__all__ = ["knn", "knn_normals"]

#: relative shrink of the ring bound (a point rounded into the neighbouring
#: cell lies within round-off of the boundary)
_RING_SLACK = 1e-9
#: the smallest cell relative to the cloud's largest extent (grid size bound)
_MIN_CELL_REL = 1e-6
#: a floor on spans and cells (units of the points): a cloud at one place
_TINY = 1e-12
#: the 3 × 3 Jacobi's stop: the off-diagonal part's square below this share
#: of the diagonal's (round-off: the eigenvectors are then those of float64)
_JACOBI_STOP = 1e-30


@njit(cache=True, nogil=True)
def _cells(p: AnyArray, lo: FloatArray, h: float, dims: IntArray) -> tuple[IntArray, IntArray]:
    """Each point's cell (clamped to the grid) and the points by cell (CSR
    start, then the points in cell order)."""
    n = p.shape[0]
    cell = np.empty(n, np.int64)
    ncell = dims[0] * dims[1] * dims[2]
    start = np.zeros(ncell + 1, np.int64)
    for i in range(n):
        c = 0
        for a in range(2, -1, -1):
            j = int(np.floor((p[i, a] - lo[a]) / h))
            j = min(max(j, 0), dims[a] - 1)
            c = c * dims[a] + j
        cell[i] = c
        start[c + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, np.int64)
    for i in range(n):
        members[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return start, members


@njit(cache=True, nogil=True)
def _insert(bd: FloatArray, bi: IntArray, m: int, d2: float, j: int) -> int:
    """Insert (d2, j) into the sorted best list (length m, capacity len(bd)),
    after equal distances; returns the new length."""
    kk = bd.shape[0]
    if m == kk and not d2 < bd[kk - 1]:
        return m
    pos = m if m < kk else kk - 1
    while pos > 0 and bd[pos - 1] > d2:
        if pos < kk:
            bd[pos] = bd[pos - 1]
            bi[pos] = bi[pos - 1]
        pos -= 1
    bd[pos] = d2
    bi[pos] = j
    out: int = min(m + 1, kk)
    return out


@njit(cache=True, nogil=True)
def _knn(p: AnyArray, k: int, lo: FloatArray, h: float, dims: IntArray, start: IntArray,
         members: IntArray, slack: float) -> tuple[FloatArray, IntArray]:
    n = p.shape[0]
    dist = np.empty((n, k))
    idx = np.empty((n, k), np.int64)
    bd = np.empty(k)
    bi = np.empty(k, np.int64)
    c0 = np.empty(3, np.int64)
    top = max(dims[0], dims[1], dims[2])
    for i in range(n):
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        for a in range(3):
            c0[a] = min(max(int(np.floor((p[i, a] - lo[a]) / h)), 0), dims[a] - 1)
        m = 0
        r = 0
        while True:
            for iz in range(max(c0[2] - r, 0), min(c0[2] + r, dims[2] - 1) + 1):
                for iy in range(max(c0[1] - r, 0), min(c0[1] + r, dims[1] - 1) + 1):
                    for ix in range(max(c0[0] - r, 0), min(c0[0] + r, dims[0] - 1) + 1):
                        if max(abs(ix - c0[0]), abs(iy - c0[1]), abs(iz - c0[2])) != r:
                            continue          # an inner ring: searched already
                        c = (iz * dims[1] + iy) * dims[0] + ix
                        for e in range(start[c], start[c + 1]):
                            j = members[e]
                            dx, dy, dz = p[j, 0] - px, p[j, 1] - py, p[j, 2] - pz
                            m = _insert(bd, bi, m, dx * dx + dy * dy + dz * dz, j)
            reach = r * h * (1.0 - _RING_SLACK) - slack
            if (m == k and reach > 0.0 and bd[k - 1] <= reach * reach) or r >= top:
                break
            r += 1
        for j in range(k):
            dist[i, j] = np.sqrt(bd[j])
            idx[i, j] = bi[j]
    return dist, idx


@njit(cache=True, nogil=True)
def _jacobi_smallest(c: FloatArray, v: FloatArray) -> int:
    """Cyclic Jacobi on the symmetric 3 × 3 ``c`` (diagonalised in place):
    ``v`` gets the eigenvectors as columns; returns the column of the
    smallest eigenvalue (the first of equal ones). Each rotation zeroes one
    off-diagonal entry (t = sgn θ / (|θ| + √(θ² + 1)), θ = (c_qq − c_pp) /
    2 c_pq); sweeps until the off-diagonal part is below 10⁻³⁰ of the
    diagonal's square (quadratic convergence: 4–6 sweeps)."""
    for a in range(3):
        for b in range(3):
            v[a, b] = 1.0 if a == b else 0.0
    for _ in range(32):
        off = c[0, 1] * c[0, 1] + c[0, 2] * c[0, 2] + c[1, 2] * c[1, 2]
        diag = c[0, 0] * c[0, 0] + c[1, 1] * c[1, 1] + c[2, 2] * c[2, 2]
        if off <= _JACOBI_STOP * diag or off == 0.0:
            break
        for ip in range(2):
            for iq in range(ip + 1, 3):
                apq = c[ip, iq]
                if apq == 0.0:
                    continue
                theta = (c[iq, iq] - c[ip, ip]) / (2.0 * apq)
                t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                cs = 1.0 / np.sqrt(t * t + 1.0)
                sn = t * cs
                for r in range(3):
                    x, y = c[r, ip], c[r, iq]
                    c[r, ip] = cs * x - sn * y
                    c[r, iq] = sn * x + cs * y
                for r in range(3):
                    x, y = c[ip, r], c[iq, r]
                    c[ip, r] = cs * x - sn * y
                    c[iq, r] = sn * x + cs * y
                for r in range(3):
                    x, y = v[r, ip], v[r, iq]
                    v[r, ip] = cs * x - sn * y
                    v[r, iq] = sn * x + cs * y
    j = 0
    for a in range(1, 3):
        if c[a, a] < c[j, j]:
            j = a
    return j


@njit(cache=True, nogil=True)
def _pca_normals(p: AnyArray, idx: IntArray) -> FloatArray:
    """Unit normal of every point: the eigenvector of the smallest
    eigenvalue of its neighbours' (rows ``idx[i]``) centred scatter matrix."""
    n, k = idx.shape
    out = np.empty((n, 3))
    c = np.empty((3, 3))
    v = np.empty((3, 3))
    m = np.empty(3)
    for i in range(n):
        for a in range(3):
            s = 0.0
            for j in range(k):
                s += p[idx[i, j], a]
            m[a] = s / k
        for a in range(3):
            for b in range(a, 3):
                s = 0.0
                for j in range(k):
                    s += (p[idx[i, j], a] - m[a]) * (p[idx[i, j], b] - m[b])
                c[a, b] = s
                c[b, a] = s
        col = _jacobi_smallest(c, v)
        for a in range(3):
            out[i, a] = v[a, col]
    return out


@njit(cache=True, nogil=True)
def _knn_grid(p: AnyArray, k: int, lo: FloatArray, h: float, dims: IntArray,
              slack: float, normals: bool) -> tuple[FloatArray, IntArray, FloatArray]:
    """:func:`_cells`, then :func:`_knn` on them, and with ``normals`` the
    points' :func:`_pca_normals` ((0, 3) without): one compiled call (one
    kernel to load, not two or three)."""
    start, members = _cells(p, lo, h, dims)
    dist, idx = _knn(p, k, lo, h, dims, start, members, slack)
    nrm = _pca_normals(p, idx) if normals else np.empty((0, 3))
    return dist, idx, nrm


def knn(p: AnyArray, k: int) -> tuple[FloatArray, IntArray]:
    """The ``k`` nearest points of every point of ``p`` ((n, 3) float,
    k ≤ n), the point itself included (at distance 0), nearest first.

    Returns
    -------
    dist : (n, k) float — distances (units of p)
    idx : (n, k) int — rows of p
    """
    dist, idx, _ = _search(p, k, False)
    return dist, idx


def knn_normals(p: AnyArray, k: int) -> FloatArray:
    """Unit normals (n, 3) of the points ``p`` ((n, 3) float, any frame and
    units; the sign is arbitrary) by PCA over each point's ``k`` nearest
    points (itself included, k ≤ n): the eigenvector of the smallest
    eigenvalue of their centred scatter matrix (3 × 3 Jacobi, to round-off
    the one ``numpy.linalg.eigh`` gives, up to sign), in the same compiled
    call as the search."""
    return _search(p, k, True)[2]


def _search(p: AnyArray, k: int, normals: bool) -> tuple[FloatArray, IntArray, FloatArray]:
    p = np.ascontiguousarray(p, float)
    n = len(p)
    if not 1 <= k <= n:
        raise ValueError(f"knn: k = {k}; allowed 1 ≤ k ≤ {n} (the number of points)")
    lo, hi = p.min(axis=0), p.max(axis=0)
    ext = np.maximum(hi - lo, 0.0)
    # half the cell of a uniform 3D sampling at n / k points (a scan is a
    # surface: its occupied cells hold more than k points at the full size;
    # measured on a registration subset of 2·10⁴ points: 35 → 20 ms at k = 9,
    # 55 → 32 ms at k = 12; smaller cells cost more rings), but never more
    # cells than 4 n
    vol = float(np.prod(np.maximum(ext, ext.max() * 1e-3 + _TINY)))
    h = max(0.5 * (vol * k / n) ** (1.0 / 3.0), float(ext.max()) * _MIN_CELL_REL, _TINY)
    while True:
        dims = np.floor(ext / h).astype(np.int64) + 1
        if int(dims.prod()) <= 4 * n + 8:
            break
        h *= 1.5
    # a cell index is computed from rounded coordinates: a point may sit
    # that far on the other side of a cell boundary
    slack = 16 * float(np.finfo(float).eps) * float(np.abs(p).max() + np.abs(lo).max() + h)
    return _knn_grid(p, int(k), lo, float(h), dims, slack, normals)
