"""Dexel kernels of the milling simulator (numba): the lowest point of a
swept ball over vertical columns.

Program frame, mm. A straight move of the tool tip from A to B sweeps the
ball of radius R centred R above the tip: a capsule. Over a vertical line
the capsule is one interval (a convex set); its lower end is either on the
cylinder about the segment (the lower root of a quadratic in z, kept when its
foot lies inside the segment) or on one of the end spheres. The minimum of
these candidates is the exact lower end, so each column gets the exact
lowest point of every move — no sampling of the path.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["capsule_bottom", "tile_moves", "column_heights"]


@nb.njit(cache=True, fastmath=False)
def capsule_bottom(qx, qy, ax, ay, az, bx, by, bz, R):
    """Lowest z over (qx, qy) of the ball of radius R swept with its centre
    from (ax, ay, az) to (bx, by, bz); +inf when the column misses it."""
    best = math.inf
    dxa, dya = qx - ax, qy - ay
    da2 = dxa * dxa + dya * dya
    if da2 <= R * R:
        best = az - math.sqrt(R * R - da2)
    dxb, dyb = qx - bx, qy - by
    db2 = dxb * dxb + dyb * dyb
    if db2 <= R * R:
        zb = bz - math.sqrt(R * R - db2)
        if zb < best:
            best = zb
    ux, uy, uz = bx - ax, by - ay, bz - az
    L = math.sqrt(ux * ux + uy * uy + uz * uz)
    if L <= 0.0:
        return best
    ux, uy, uz = ux / L, uy / L, uz / L
    a = 1.0 - uz * uz
    if a <= 1e-14:
        return best
    p = dxa * ux + dya * uy
    b = -2.0 * uz * p
    c = da2 - p * p - R * R
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return best
    zr = (-b - math.sqrt(disc)) / (2.0 * a)      # z − az of the lower root
    t = (p + zr * uz) / L
    if 0.0 <= t <= 1.0:
        z = az + zr
        if z < best:
            best = z
    return best


@nb.njit(cache=True)
def tile_moves(A, B, R, x0, y0, tile, nx, ny):
    """CSR lists of the moves (rows of ``A``, ``B``: ball centres) whose
    footprint box meets each tile of an nx × ny tiling from (x0, y0)."""
    n = A.shape[0]
    counts = np.zeros(nx * ny + 1, np.int64)
    for k in range(n):
        i0 = max(int((min(A[k, 0], B[k, 0]) - R - x0) // tile), 0)
        i1 = min(int((max(A[k, 0], B[k, 0]) + R - x0) // tile), nx - 1)
        j0 = max(int((min(A[k, 1], B[k, 1]) - R - y0) // tile), 0)
        j1 = min(int((max(A[k, 1], B[k, 1]) + R - y0) // tile), ny - 1)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                counts[j * nx + i + 1] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    idx = np.empty(start[-1], np.int64)
    for k in range(n):
        i0 = max(int((min(A[k, 0], B[k, 0]) - R - x0) // tile), 0)
        i1 = min(int((max(A[k, 0], B[k, 0]) + R - x0) // tile), nx - 1)
        j0 = max(int((min(A[k, 1], B[k, 1]) - R - y0) // tile), 0)
        j1 = min(int((max(A[k, 1], B[k, 1]) + R - y0) // tile), ny - 1)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                t = j * nx + i
                idx[fill[t]] = k
                fill[t] += 1
    return start, idx


@nb.njit(cache=True, parallel=True)
def column_heights(qx, qy, A, B, R, z_top, start, idx, x0, y0, tile, nx, ny):
    """Milled height of each column (qx, qy): min(z_top, lowest swept ball)."""
    m = qx.shape[0]
    out = np.empty(m)
    for c in nb.prange(m):
        i = int((qx[c] - x0) // tile)
        j = int((qy[c] - y0) // tile)
        best = z_top
        if 0 <= i < nx and 0 <= j < ny:
            t = j * nx + i
            for s in range(start[t], start[t + 1]):
                k = idx[s]
                z = capsule_bottom(qx[c], qy[c], A[k, 0], A[k, 1], A[k, 2],
                                   B[k, 0], B[k, 1], B[k, 2], R)
                if z < best:
                    best = z
        out[c] = best
    return out
