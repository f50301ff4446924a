"""Statistics of large deviation arrays in one or two compiled passes (numba):
exact percentiles by bucket selection, moments by blocked sums.

Units: those of the values (tipgeo: mm).

Why: ``numpy.percentile`` copies its input and partitions it for every call;
the statistics of a 10⁷-point scan call it a dozen times (signed and |d|,
overall, per face, trimmed) and that took seconds. Here one pass counts the
values into 2¹² equal buckets between their minimum and maximum (a monotone
map, so the ranks are kept), a second pass gathers only the buckets that
hold the wanted ranks, which are sorted: the order statistics are the exact
sorted values, and the percentiles are numpy's ``linear`` method (the same
virtual index and interpolation), equal to ``numpy.percentile`` up to
round-off.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from ..arrays import ArrayLike, FloatArray, IntArray

__all__ = ["by_group", "histogram_counts", "moments", "percentiles", "within_band"]

_BUCKETS = 1 << 12   # the count table stays in the L1 cache


@njit(cache=True, nogil=True, inline="always")
def _bucket(v: float, lo: float, scale: float, nb: int) -> int:
    """The bucket of ``v`` in 0..nb-1, monotone in ``v``, for any scale:
    (v − lo)·scale is NaN (0·∞, ∞·0) or ∞ when the span is subnormal or
    overflows, and a float beyond int64 has no defined conversion — so
    the index is clamped as a float before it becomes an int."""
    f = (v - lo) * scale
    if f >= nb - 1:
        return nb - 1
    if f > 0.0:
        return int(f)
    return 0


@njit(cache=True, nogil=True)
def _order_statistics(x: FloatArray, ks: IntArray, absolute: bool, lo: float,
                      hi: float) -> FloatArray:
    """The values of ranks ``ks`` ((m,) int, 0-based, ascending) of ``x`` (or
    of |x| when ``absolute``) in sorted order; ``lo``, ``hi``: the least and
    the greatest value or bounds on them (NaN: found here)."""
    n = x.shape[0]
    out = np.empty(ks.shape[0])
    if not (lo <= hi):
        lo = np.inf
        hi = -np.inf
        for i in range(n):
            v = abs(x[i]) if absolute else x[i]
            lo = min(lo, v)
            hi = max(hi, v)
    if not hi > lo:
        out[:] = lo
        return out
    nb = min(_BUCKETS, n)
    scale = nb / (hi - lo)
    count = np.zeros(nb + 1, np.int64)
    for i in range(n):
        v = abs(x[i]) if absolute else x[i]
        count[_bucket(v, lo, scale, nb) + 1] += 1
    for b in range(nb):
        count[b + 1] += count[b]          # count[b]: values in buckets before b
    # the bucket of every wanted rank, and a slot in one gather buffer for it
    want = np.full(nb, -1, np.int64)
    kb = np.empty(ks.shape[0], np.int64)
    total = 0
    for j in range(ks.shape[0]):
        b = np.searchsorted(count, ks[j], side="right") - 1
        kb[j] = b
        if want[b] < 0:
            want[b] = total
            total += count[b + 1] - count[b]
    buf = np.empty(total)
    fill = np.zeros(nb, np.int64)
    for i in range(n):
        v = abs(x[i]) if absolute else x[i]
        b = _bucket(v, lo, scale, nb)
        if want[b] >= 0:
            buf[want[b] + fill[b]] = v
            fill[b] += 1
    done = np.zeros(nb, np.bool_)
    for j in range(ks.shape[0]):
        b = kb[j]
        s = want[b]
        e = s + count[b + 1] - count[b]
        if not done[b]:
            buf[s:e] = np.sort(buf[s:e])
            done[b] = True
        out[j] = buf[s + ks[j] - count[b]]
    return out


def percentiles(x: FloatArray, q: ArrayLike, *, absolute: bool = False,
                bounds: tuple[float, float] | None = None) -> FloatArray:
    """Percentiles of ``x`` (or of |x|), numpy's default ``linear`` method.

    Parameters
    ----------
    x : (n,) float — values (n ≥ 1), e.g. deviations in mm
    q : sequence of float — percentiles in [0, 100]
    absolute : bool — of |x| (no |x| array is made)
    bounds : (low, high) — the values (|x| when ``absolute``) lie in
        [low, high], when known (saves a pass; the order statistics stay
        exact for any such bounds)

    Returns
    -------
    (len(q),) float — in the units of ``x``
    """
    x = np.ascontiguousarray(x, float)
    n = len(x)
    if not n:
        raise ValueError("percentiles of an empty array")
    qs = np.asarray(q, float) / 100.0
    h = (n - 1) * qs          # numpy's virtual index for the linear method
    lo = np.clip(np.floor(h), 0, n - 1).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    g = h - np.floor(h)
    ks = np.unique(np.concatenate([lo, hi]))
    lo_v, hi_v = (np.nan, np.nan) if bounds is None else bounds
    v = _order_statistics(x, ks, absolute, float(lo_v), float(hi_v))
    a, b = v[np.searchsorted(ks, lo)], v[np.searchsorted(ks, hi)]
    diff = b - a
    # numpy's _lerp: from the nearer end
    out: FloatArray = np.where(g >= 0.5, b - diff * (1.0 - g), a + diff * g)
    return out


@njit(cache=True, nogil=True)
def _sum_blocks(x: FloatArray, absolute: bool, shift: float, square: bool) -> float:
    """Σ f(x) with f = (|x| or x − shift), squared or not, summed by blocks
    of 1024 (round-off ~ (1024 + n/1024) ε rather than n ε)."""
    total = 0.0
    n = x.shape[0]
    for s in range(0, n, 1024):
        part = 0.0
        for i in range(s, min(s + 1024, n)):
            v = abs(x[i]) if absolute else x[i] - shift
            part += v * v if square else v
        total += part
    return total


@njit(cache=True, nogil=True)
def _moments(x: FloatArray, band: float) -> tuple[float, float, float, int, float, float]:
    """Σx, Σ|x|, Σx², count of |x| ≤ band, min, max in one pass (blocked sums)."""
    s = 0.0
    sa = 0.0
    sq = 0.0
    within = 0
    lo = np.inf
    hi = -np.inf
    n = x.shape[0]
    for b in range(0, n, 1024):
        ps = 0.0
        pa = 0.0
        pq = 0.0
        for i in range(b, min(b + 1024, n)):
            v = x[i]
            a = abs(v)
            ps += v
            pa += a
            pq += v * v
            if a <= band:
                within += 1
            lo = min(lo, v)
            hi = max(hi, v)
        s += ps
        sa += pa
        sq += pq
    return s, sa, sq, within, lo, hi


def moments(x: FloatArray, band: float) -> dict[str, Any]:
    """Count, mean, population standard deviation (about the mean, a second
    pass), RMS, mean |x|, min, max and the count within ±``band`` of ``x``
    ((n,) float, n ≥ 1), in the units of ``x``."""
    x = np.ascontiguousarray(x, float)
    n = len(x)
    s, sa, sq, within, lo, hi = _moments(x, band)
    mean = s / n
    ss = _sum_blocks(x, False, mean, True)
    return {"count": n, "mean": mean, "std": float(np.sqrt(ss / n)), "rms": float(np.sqrt(sq / n)),
            "mean_abs": sa / n, "min": lo, "max": hi, "within": int(within)}


@njit(cache=True, nogil=True)
def _band(x: FloatArray, centre: float, half: float) -> FloatArray:
    # counted first: the result is allocated at its size (a full-size buffer
    # and a copy would touch twice the memory, and fresh pages cost)
    k = 0
    for i in range(x.shape[0]):
        if abs(x[i] - centre) <= half:
            k += 1
    kept = np.empty(k)
    k = 0
    for i in range(x.shape[0]):
        if abs(x[i] - centre) <= half:
            kept[k] = x[i]
            k += 1
    return kept


@njit(cache=True, nogil=True)
def _by_group(x: FloatArray, gid: IntArray, gmap: IntArray,
              ngroup: int) -> tuple[FloatArray, IntArray]:
    """The values of ``x`` grouped by ``gmap[gid]`` (0..ngroup-1), input
    order kept within a group (a stable counting sort), and each group's
    start."""
    start = np.zeros(ngroup + 1, np.int64)
    for i in range(x.shape[0]):
        start[gmap[gid[i]] + 1] += 1
    for g in range(ngroup):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        g = gmap[gid[i]]
        out[fill[g]] = x[i]
        fill[g] += 1
    return out, start


def by_group(x: np.ndarray, gid: np.ndarray, gmap: np.ndarray,
             ngroup: int) -> tuple[np.ndarray, np.ndarray]:
    """The values of ``x`` ((n,) float) grouped by ``gmap[gid]`` (``gid``:
    (n,) int; ``gmap``: int, values in 0..ngroup-1; input order kept within
    a group) and the groups' starts ((ngroup + 1,) int): group g is
    ``values[start[g]:start[g + 1]]``. One copy of ``x`` in two passes, not
    a mask and a copy per group."""
    out: tuple[FloatArray, IntArray] = _by_group(
        np.ascontiguousarray(x, float), np.ascontiguousarray(gid),
        np.ascontiguousarray(gmap, np.int64), int(ngroup))
    return out


@njit(cache=True, nogil=True)
def _hist(x: FloatArray, edges: FloatArray) -> IntArray:
    nb = edges.shape[0] - 1
    out = np.zeros(nb + 2, np.int64)   # the bins, then below and above
    first, last = edges[0], edges[nb]
    denom = last - first
    for i in range(x.shape[0]):
        v = x[i]
        if v < first:
            out[nb] += 1
        elif v > last:
            out[nb + 1] += 1
        elif v >= first and v <= last:
            # numpy's rule for equal bins: the index from the scaled offset,
            # then corrected against the edges themselves
            j = int(((v - first) / denom) * nb)
            if j == nb:
                j -= 1
            if v < edges[j]:
                j -= 1
            if v >= edges[j + 1] and j != nb - 1:
                j += 1
            out[j] += 1
    return out


def histogram_counts(x: FloatArray, lo: float, hi: float,
                     bins: int) -> tuple[IntArray, FloatArray, int, int]:
    """``numpy.histogram(x, bins, range=(lo, hi))`` (the same edges and
    counts; lo < hi finite) and the counts below lo and above hi, in one
    compiled pass and no temporary."""
    edges = np.linspace(lo, hi, bins + 1)
    c = _hist(np.ascontiguousarray(x, float), edges)
    return c[:bins], edges, int(c[bins]), int(c[bins + 1])


def within_band(x: np.ndarray, centre: float, half: float) -> np.ndarray:
    """The values of ``x`` ((n,) float) with |x − centre| ≤ half, in order."""
    out: FloatArray = _band(np.ascontiguousarray(x, float), float(centre), float(half))
    return out
