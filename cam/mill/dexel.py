"""Dexel kernels of the milling simulator (numba): the lowest point of an
end mill swept along straight moves, over vertical columns.

Program frame, mm. The tool is described by its radius R and corner radius
r (ball r = R, bull nose 0 < r < R, flat end r = 0); with its tip (lowest
point) at height z over the axis, its lower surface at horizontal distance ρ
from the axis is z + T(ρ), T(ρ) = 0 for ρ ≤ a = R − r (the flat bottom) and
T(ρ) = r − √(r² − (ρ − a)²) for a < ρ ≤ R (the corner). Above it the tool
(the cylinder of its flutes and the shank) is taken as removing everything.

Each column gets the exact lowest point of every move — no sampling of the
path:

- **ball**: the ball centred R above the tip sweeps a capsule; over a vertical
  line it is one interval whose lower end is on the cylinder about the
  segment (the lower root of a quadratic in z, kept when its foot lies in the
  segment) or on an end sphere (:func:`capsule_bottom`).
- **flat end**: the disc of radius R at the tip's height covers the column for
  the positions u along the move with |q − c(u)| ≤ R, an interval; the height
  is linear in u, so the lowest is at one end of it (:func:`tool_bottom`).
- **bull nose**: along the move, g(u) = z(u) + T(ρ(u)) with ρ(u) the distance
  from the column to the tool axis; ρ is convex in u and T convex and
  non-decreasing, so g is convex: its minimum over the interval where ρ ≤ R
  is found by bisection on the monotone g′ to 2⁻⁶⁰ of the interval.

Columns visit only the moves whose footprint meets their tile, in order of a
lower bound of their height over the tile (the lowest tip height plus T at
the tile's smallest distance from the move), and stop at the first move whose
bound lies above the lowest height found: the result is the same as visiting
every move.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from tipgeo.arrays import BoolArray, FloatArray, IntArray
from tipgeo.tolerances import tol

__all__ = ["capsule_bottom", "tool_bottom", "tile_moves", "column_heights"]


#: Read once: numba compiles module globals in as constants (see
#: :class:`tipgeo.tolerances.CamTolerances`).
_HORIZONTAL = tol.cam.dexel_horizontal
_VERTICAL = tol.cam.dexel_vertical


@nb.njit(cache=True, fastmath=False)
def capsule_bottom(qx: float, qy: float, ax: float, ay: float, az: float, bx: float, by: float,
                   bz: float, R: float) -> float:
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
    if a <= _HORIZONTAL:
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
def _corner(rho: float, R: float, r: float) -> float:
    """T(ρ): height of the tool's lower surface above its tip at distance ρ
    from the axis (+inf beyond R)."""
    a = R - r
    if rho <= a:
        return 0.0
    if rho > R:
        return math.inf
    e = rho - a
    return r - math.sqrt(max(r * r - e * e, 0.0))


@nb.njit(cache=True)
def tool_bottom(qx: float, qy: float, ax: float, ay: float, az: float, bx: float, by: float,
                bz: float, R: float, r: float) -> float:
    """Lowest z over (qx, qy) of the end mill (radius R, corner radius r)
    swept with its tip from (ax, ay, az) to (bx, by, bz); +inf when the
    column misses it (see the module docstring)."""
    if r >= R:
        return capsule_bottom(qx, qy, ax, ay, az + R, bx, by, bz + R, R)
    ex, ey = bx - ax, by - ay
    L = math.sqrt(ex * ex + ey * ey)
    if L <= _VERTICAL:                               # a vertical move
        d = math.sqrt((qx - ax) ** 2 + (qy - ay) ** 2)
        return min(az, bz) + _corner(d, R, r)
    ex, ey = ex / L, ey / L
    u0 = (qx - ax) * ex + (qy - ay) * ey             # the column's foot along the move
    d = abs(-(qx - ax) * ey + (qy - ay) * ex)        # its distance from the move's line
    if d > R:
        return math.inf
    w = math.sqrt(R * R - d * d)
    lo, hi = max(0.0, u0 - w), min(L, u0 + w)
    if lo > hi:
        return math.inf
    m = (bz - az) / L
    if r <= 0.0:                                     # flat: linear in u on [lo, hi]
        return az + m * (lo if m >= 0.0 else hi)
    a = R - r
    # g(u) = az + m u + T(√(d² + (u − u0)²)) is convex: bisection on g′
    u_lo, u_hi = lo, hi
    for _ in range(60):
        u = 0.5 * (u_lo + u_hi)
        du = u - u0
        rho = math.sqrt(d * d + du * du)
        gp = m
        if rho > a and rho > 0.0:
            e = rho - a
            s2 = r * r - e * e
            if s2 <= 0.0:
                gp = math.inf if du > 0 else -math.inf
            else:
                gp = m + e / math.sqrt(s2) * du / rho
        if gp > 0.0:
            u_hi = u
        else:
            u_lo = u
    best = math.inf
    for u in (lo, hi, 0.5 * (u_lo + u_hi)):
        du = u - u0
        z = az + m * u + _corner(math.sqrt(d * d + du * du), R, r)
        if z < best:
            best = z
    return best


@nb.njit(cache=True)
def _footprints(A: FloatArray, B: FloatArray, R: float, x0: float, y0: float, tile: float,
                nx: int, ny: int) -> IntArray:
    """(n, 4) tile index ranges i0, i1, j0, j1 of each move's footprint box
    (empty when i0 > i1 or j0 > j1)."""
    n = A.shape[0]
    out = np.empty((n, 4), np.int64)
    for k in range(n):
        out[k, 0] = max(int((min(A[k, 0], B[k, 0]) - R - x0) // tile), 0)
        out[k, 1] = min(int((max(A[k, 0], B[k, 0]) + R - x0) // tile), nx - 1)
        out[k, 2] = max(int((min(A[k, 1], B[k, 1]) - R - y0) // tile), 0)
        out[k, 3] = min(int((max(A[k, 1], B[k, 1]) + R - y0) // tile), ny - 1)
    return out


@nb.njit(cache=True)
def _segment_distance(px: float, py: float, ax: float, ay: float, bx: float,
                      by: float) -> float:
    """Distance (mm) from (px, py) to the segment (ax, ay)–(bx, by)."""
    ex, ey = bx - ax, by - ay
    L2 = ex * ex + ey * ey
    t = 0.0
    if L2 > 0.0:
        t = min(max(((px - ax) * ex + (py - ay) * ey) / L2, 0.0), 1.0)
    dx, dy = px - ax - t * ex, py - ay - t * ey
    return math.sqrt(dx * dx + dy * dy)


@nb.njit(cache=True, parallel=True)
def tile_moves(A: FloatArray, B: FloatArray, R: float, r: float, x0: float, y0: float,
               tile: float, nx: int, ny: int,
               need: BoolArray) -> tuple[IntArray, IntArray, FloatArray]:
    """CSR lists of the moves (rows of ``A``, ``B``: tool tips) whose
    footprint meets each needed tile (``need``: (nx·ny,) bool) of an
    nx × ny tiling from (x0, y0), each list sorted by the lower bound of the
    move's height over the tile. Returns (start, idx, bound)."""
    n = A.shape[0]
    fp = _footprints(A, B, R, x0, y0, tile, nx, ny)
    half = 0.5 * tile * math.sqrt(2.0)
    counts = np.zeros(nx * ny + 1, np.int64)
    for k in range(n):
        for j in range(fp[k, 2], fp[k, 3] + 1):
            for i in range(fp[k, 0], fp[k, 1] + 1):
                t = j * nx + i
                if need[t]:
                    counts[t + 1] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    idx = np.empty(start[-1], np.int64)
    for k in range(n):
        for j in range(fp[k, 2], fp[k, 3] + 1):
            for i in range(fp[k, 0], fp[k, 1] + 1):
                t = j * nx + i
                if need[t]:
                    idx[fill[t]] = k
                    fill[t] += 1
    bound = np.empty(start[-1])
    for t in nb.prange(nx * ny):
        s0, s1 = start[t], start[t + 1]
        if s1 == s0:
            continue
        cx = x0 + ((t % nx) + 0.5) * tile
        cy = y0 + ((t // nx) + 0.5) * tile
        b = np.empty(s1 - s0)
        for s in range(s0, s1):
            k = idx[s]
            dmin = max(_segment_distance(cx, cy, A[k, 0], A[k, 1], B[k, 0], B[k, 1]) - half, 0.0)
            zt = min(A[k, 2], B[k, 2])
            if dmin > R:
                b[s - s0] = math.inf
            else:
                b[s - s0] = zt + _corner(dmin, R, r)
        order = np.argsort(b)
        seg = idx[s0:s1].copy()
        for q in range(s1 - s0):
            idx[s0 + q] = seg[order[q]]
            bound[s0 + q] = b[order[q]]
    return start, idx, bound


@nb.njit(cache=True, parallel=True)
def column_heights(qx: FloatArray, qy: FloatArray, A: FloatArray, B: FloatArray, R: float,
                   r: float, z_top: float, start: IntArray, idx: IntArray, bound: FloatArray,
                   x0: float, y0: float, tile: float, nx: int, ny: int) -> FloatArray:
    """Milled height of each column (qx, qy): min(z_top, lowest swept tool)."""
    m = qx.shape[0]
    out = np.empty(m)
    for c in nb.prange(m):
        i = int((qx[c] - x0) // tile)
        j = int((qy[c] - y0) // tile)
        best = z_top
        if 0 <= i < nx and 0 <= j < ny:
            t = j * nx + i
            for s in range(start[t], start[t + 1]):
                if bound[s] >= best:
                    break
                k = idx[s]
                z = tool_bottom(qx[c], qy[c], A[k, 0], A[k, 1], A[k, 2],
                                B[k, 0], B[k, 1], B[k, 2], R, r)
                if z < best:
                    best = z
        out[c] = best
    return out
