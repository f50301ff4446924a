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

from .._jit import njit
from ..arrays import ArrayLike, FloatArray, IntArray

__all__ = ["by_group", "group_blocks", "histogram_counts", "moments", "percentiles",
           "within_band"]

_BUCKETS = 1 << 12   # the count table stays in the L1 cache


@njit(cache=True, nogil=True)
def _last_at_most(cum: IntArray, n: int, key: int) -> int:
    """The last index b < n with ``cum[b] <= key`` (``cum`` ascending), −1
    when none: ``np.searchsorted(cum[:n], key, side="right") - 1`` — written
    out, as numba's searchsorted loads numba's whole numpy-math module (and
    scipy.linalg with it) with the cached kernel, a tenth of a CPU second."""
    lo, hi = 0, n
    while lo < hi:
        mid = (lo + hi) // 2
        if cum[mid] <= key:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1


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
        b = _last_at_most(count, count.shape[0], ks[j])
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


# -----------------------------------------------------------------------------
# every block of a deviation report in three passes
#
# A "block" (count, moments, signed and |x| percentiles) of each group —
# all values, each face, the trimmed band — used to take about six passes a
# group over a copy of its values; here three passes over the values in
# place serve every group at once. The arithmetic per group is that of
# :func:`moments` and :func:`percentiles` on the group's values in input
# order (sums in blocks of 1024 of the group's own values, the same buckets
# and the same exact order statistics), so the figures are the same bit for bit.

_BLOCK = 1024


@njit(cache=True, nogil=True)
def _group_moments(x: FloatArray, gid: IntArray, gmap: IntArray, ngroup: int, trim: bool,
                   centre: float, half: float, band: float) -> tuple[FloatArray, IntArray]:
    """Pass 1: per group (0 all, 1.. faces, last trimmed when ``trim``) Σx,
    Σ|x|, Σx², min, max (columns of the float result) and count, count
    within ±band (columns of the int result)."""
    G = ngroup + 2 if trim else ngroup + 1
    f = np.zeros((G, 5))
    c = np.zeros((G, 2), np.int64)
    part = np.zeros((G, 3))
    inblk = np.zeros(G, np.int64)
    for g in range(G):
        f[g, 3] = np.inf
        f[g, 4] = -np.inf
    grp = np.empty(3, np.int64)
    for i in range(x.shape[0]):
        v = x[i]
        a = abs(v)
        m = 1
        grp[0] = 0
        if gid.shape[0]:
            grp[1] = 1 + gmap[gid[i]]
            m = 2
        if trim and abs(v - centre) <= half:
            grp[m] = G - 1
            m += 1
        for j in range(m):
            g = grp[j]
            part[g, 0] += v
            part[g, 1] += a
            part[g, 2] += v * v
            if a <= band:
                c[g, 1] += 1
            f[g, 3] = min(f[g, 3], v)
            f[g, 4] = max(f[g, 4], v)
            c[g, 0] += 1
            inblk[g] += 1
            if inblk[g] == _BLOCK:
                f[g, 0] += part[g, 0]
                f[g, 1] += part[g, 1]
                f[g, 2] += part[g, 2]
                part[g, 0] = part[g, 1] = part[g, 2] = 0.0
                inblk[g] = 0
    for g in range(G):
        if inblk[g]:
            f[g, 0] += part[g, 0]
            f[g, 1] += part[g, 1]
            f[g, 2] += part[g, 2]
    return f, c


@njit(cache=True, nogil=True)
def _group_spread(x: FloatArray, gid: IntArray, gmap: IntArray, trim: bool, centre: float,
                  half: float, mean: FloatArray, lo: FloatArray, scale: FloatArray,
                  nb: IntArray) -> tuple[FloatArray, IntArray]:
    """Pass 2: per group Σ(x − mean)² (blocked as pass 1) and the bucket
    counts of x and of |x| (kinds 0 and 1: ``lo``, ``scale``, ``nb`` per
    kind, one bucketing for every group: the order statistics are exact for
    any buckets that hold the values; nb 0: not counted), cumulated:
    count[g, k, b] is the number of the group's values in buckets before b.
    The whole's counts are the sum of its groups' when there are groups."""
    G = mean.shape[0]
    ss = np.zeros(G)
    part = np.zeros(G)
    inblk = np.zeros(G, np.int64)
    count = np.zeros((G, 2, _BUCKETS + 1), np.int64)
    grp = np.empty(3, np.int64)
    faces = gid.shape[0] > 0
    for i in range(x.shape[0]):
        v = x[i]
        m = 1
        grp[0] = 0
        if faces:
            grp[1] = 1 + gmap[gid[i]]
            m = 2
        if trim and abs(v - centre) <= half:
            grp[m] = G - 1
            m += 1
        for j in range(m):
            g = grp[j]
            w = v - mean[g]
            part[g] += w * w
            inblk[g] += 1
            if inblk[g] == _BLOCK:
                ss[g] += part[g]
                part[g] = 0.0
                inblk[g] = 0
        bs = _bucket(v, lo[0], scale[0], nb[0]) + 1 if nb[0] else 0
        ba = _bucket(abs(v), lo[1], scale[1], nb[1]) + 1 if nb[1] else 0
        for j in range(1 if faces else 0, m):
            count[grp[j], 0, bs] += 1
            count[grp[j], 1, ba] += 1
    if faces:
        for g in range(1, G - 1 if trim else G):
            for k in range(2):
                for b in range(_BUCKETS + 1):
                    count[0, k, b] += count[g, k, b]
    for g in range(G):
        if inblk[g]:
            ss[g] += part[g]
        for k in range(2):
            for b in range(nb[k]):
                count[g, k, b + 1] += count[g, k, b]
    return ss, count


@njit(cache=True, nogil=True)
def _group_wanted(nb: IntArray, count: IntArray,
                  ks: IntArray) -> tuple[IntArray, IntArray, int]:
    """The bucket of every wanted rank (``kb``, −1: none) and each wanted
    bucket's slot in one gather buffer (``want``, −1: not wanted), and the
    buffer's length (see :func:`_group_gather`)."""
    G, r = count.shape[0], ks.shape[2]
    want = np.full((G, 2, _BUCKETS), -1, np.int64)
    kb = np.full((G, 2, r), -1, np.int64)
    total = 0
    for g in range(G):
        for k in range(2):
            for j in range(r if nb[k] else 0):
                if ks[g, k, j] < 0:
                    continue
                b = _last_at_most(count[g, k], nb[k] + 1, ks[g, k, j])
                kb[g, k, j] = b
                if want[g, k, b] < 0:
                    want[g, k, b] = total
                    total += count[g, k, b + 1] - count[g, k, b]
    return want, kb, total


@njit(cache=True, nogil=True)
def _group_pick(buf: FloatArray, want: IntArray, kb: IntArray, count: IntArray,
                ks: IntArray) -> FloatArray:
    """Each wanted bucket sorted once, the ranks read from it."""
    G, r = count.shape[0], ks.shape[2]
    out = np.zeros((G, 2, r))
    done = np.zeros((G, 2, _BUCKETS), np.bool_)
    for g in range(G):
        for k in range(2):
            for j in range(r):
                b = kb[g, k, j]
                if b < 0:
                    continue
                s = want[g, k, b]
                e = s + count[g, k, b + 1] - count[g, k, b]
                if not done[g, k, b]:
                    buf[s:e] = np.sort(buf[s:e])
                    done[g, k, b] = True
                out[g, k, j] = buf[s + ks[g, k, j] - count[g, k, b]]
    return out


@njit(cache=True, nogil=True)
def _group_spread_gather(x: FloatArray, gid: IntArray, gmap: IntArray, trim: bool,
                         centre: float, half: float, mean: FloatArray, lo: FloatArray,
                         scale: FloatArray, nb: IntArray,
                         ks: IntArray) -> tuple[FloatArray, FloatArray]:
    """Passes 2 and 3 in one compiled call (:func:`_group_spread`, then
    :func:`_group_gather` on its counts; one kernel to load, not two):
    per group Σ(x − mean)² and the values of ranks ``ks``."""
    ss, count = _group_spread(x, gid, gmap, trim, centre, half, mean, lo, scale, nb)
    return ss, _group_gather(x, gid, gmap, trim, centre, half, lo, scale, nb, count, ks)


@njit(cache=True, nogil=True)
def _group_gather(x: FloatArray, gid: IntArray, gmap: IntArray, trim: bool, centre: float,
                  half: float, lo: FloatArray, scale: FloatArray, nb: IntArray,
                  count: IntArray, ks: IntArray) -> FloatArray:
    """Pass 3: the values of ranks ``ks`` ((G, 2, r) int, ascending along r;
    −1: none) of each group and kind (x, |x|), by gathering only the buckets
    that hold them (as :func:`_order_statistics`; buckets as in
    :func:`_group_spread`)."""
    G = count.shape[0]
    want, kb, total = _group_wanted(nb, count, ks)
    buf = np.empty(total)
    fill = np.zeros((G, 2, _BUCKETS), np.int64)
    grp = np.empty(3, np.int64)
    for i in range(x.shape[0]):
        v = x[i]
        m = 1
        grp[0] = 0
        if gid.shape[0]:
            grp[1] = 1 + gmap[gid[i]]
            m = 2
        if trim and abs(v - centre) <= half:
            grp[m] = G - 1
            m += 1
        for k in range(2):
            if not nb[k]:
                continue
            u = abs(v) if k else v
            b = _bucket(u, lo[k], scale[k], nb[k])
            for j in range(m):
                slot = want[grp[j], k, b]
                if slot >= 0:
                    buf[slot + fill[grp[j], k, b]] = u
                    fill[grp[j], k, b] += 1
    return _group_pick(buf, want, kb, count, ks)


def _ranks(n: int, q: FloatArray) -> tuple[IntArray, IntArray, IntArray, FloatArray]:
    """numpy's ``linear`` method for n values: the ranks below and above
    each percentile's virtual index, the distinct ranks wanted, the weight."""
    h = (n - 1) * q
    lo = np.clip(np.floor(h), 0, n - 1).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    return lo, hi, np.unique(np.concatenate([lo, hi])), h - np.floor(h)


def _lerp(v: FloatArray, ks: IntArray, lo: IntArray, hi: IntArray, g: FloatArray) -> FloatArray:
    a, b = v[np.searchsorted(ks, lo)], v[np.searchsorted(ks, hi)]
    diff = b - a
    # numpy's _lerp: from the nearer end
    out: FloatArray = np.where(g >= 0.5, b - diff * (1.0 - g), a + diff * g)
    return out


def group_blocks(x: FloatArray, gid: IntArray | None, gmap: IntArray, ngroup: int,
                 band: float, *, trim: tuple[float, float] | None = None,
                 q: ArrayLike = (5.0, 95.0), q_abs: ArrayLike = (95.0,)) -> list[dict[str, Any]]:
    """:func:`moments` and :func:`percentiles` (of x and of |x|) of several
    groups of ``x`` in three compiled passes, the same figures bit for bit
    as those functions give on each group's values in input order.

    Parameters
    ----------
    x : (n,) float — values (e.g. deviations, mm)
    gid : (n,) int or None — each value's id; its group is ``gmap[gid]``
        (0..ngroup-1); None: no groups but the whole
    band : float — the moments' ``within`` count is of |x| ≤ band
    trim : (centre, half), optional — one more group: the values with
        |x − centre| ≤ half
    q, q_abs : percentiles (0..100) of x and of |x|

    Returns
    -------
    list of dict — the whole, then each group, then the trimmed one: the
    keys of :func:`moments` and ``p`` (percentiles of x), ``p_abs`` (of |x|);
    a group with no value has ``count`` 0 only
    """
    x = np.ascontiguousarray(x, float)
    g_ids = np.zeros(0, np.int64) if gid is None else np.ascontiguousarray(gid)
    gm = np.ascontiguousarray(gmap, np.int64)
    ng = int(ngroup) if gid is not None else 0
    tr = trim is not None
    centre, half = (float(trim[0]), float(trim[1])) if trim is not None else (0.0, 0.0)
    f, c = _group_moments(x, g_ids, gm, ng, tr, centre, half, float(band))
    G = len(c)
    qs = (np.asarray(q, float) / 100.0, np.asarray(q_abs, float) / 100.0)
    mean = np.zeros(G)
    plan: list[list[tuple[IntArray, IntArray, IntArray, FloatArray]]] = []
    for g in range(G):
        n = int(c[g, 0])
        plan.append([_ranks(n, qs[k]) for k in range(2)] if n else [])
        if n:
            mean[g] = f[g, 0] / n
    # one bucketing for all groups, from the whole's bounds: (min, max) of x
    # and (0, max |x|), as the report's percentiles() calls were given
    lo, scale = np.zeros(2), np.zeros(2)
    nb = np.zeros(2, np.int64)
    for k, (b0, b1) in enumerate(((float(f[0, 3]), float(f[0, 4])),
                                  (0.0, max(-f[0, 3], f[0, 4])))):
        if b1 > b0:
            nb[k] = min(_BUCKETS, int(c[0, 0]))
            # Python floats: a span beyond the float range gives ∞ quietly
            lo[k], scale[k] = b0, int(nb[k]) / (float(b1) - float(b0))
    r = max((len(p[2]) for pl in plan for p in pl), default=1)
    ks = np.full((G, 2, r), -1, np.int64)
    for g, pl in enumerate(plan):
        for k, p in enumerate(pl):
            ks[g, k, :len(p[2])] = p[2]
    ss, vals = _group_spread_gather(x, g_ids, gm, tr, centre, half, mean, lo, scale, nb, ks)
    out: list[dict[str, Any]] = []
    for g in range(G):
        n = int(c[g, 0])
        if not n:
            out.append({"count": 0})
            continue
        mn, mx = float(f[g, 3]), float(f[g, 4])
        res: dict[str, Any] = {
            "count": n, "mean": f[g, 0] / n, "std": float(np.sqrt(ss[g] / n)),
            "rms": float(np.sqrt(f[g, 2] / n)), "mean_abs": f[g, 1] / n, "min": mn, "max": mx,
            "within": int(c[g, 1])}
        for k, key in enumerate(("p", "p_abs")):
            lo_r, hi_r, kk, w = plan[g][k]
            v = vals[g, k, :len(kk)] if nb[k] else np.full(len(kk), (mn, 0.0)[k])
            res[key] = _lerp(v, kk, lo_r, hi_r, w)
        out.append(res)
    return out
