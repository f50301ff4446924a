"""Exact percentiles of large deviation arrays by bucket selection (numba).

Units: those of the values (tipgeo: mm).

Why: ``numpy.percentile`` copies its input and partitions it for every call;
the statistics of a 10⁷-point scan call it a dozen times (signed and |d|,
overall, per face, trimmed) and that took seconds. Here one pass counts the
values into 2¹⁶ equal buckets between their minimum and maximum (a monotone
map, so the ranks are kept), a second pass gathers only the buckets that
hold the wanted ranks, which are sorted: the order statistics are the exact
sorted values, and the percentiles are numpy's ``linear`` method (the same
virtual index and interpolation), equal to ``numpy.percentile`` up to
round-off.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["percentiles"]

_BUCKETS = 1 << 16


@njit(cache=True, nogil=True)
def _order_statistics(x, ks, absolute):
    """The values of ranks ``ks`` ((m,) int, 0-based, ascending) of ``x`` (or
    of |x| when ``absolute``) in sorted order."""
    n = x.shape[0]
    out = np.empty(ks.shape[0])
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
        count[min(int((v - lo) * scale), nb - 1) + 1] += 1
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
        b = min(int((v - lo) * scale), nb - 1)
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


def percentiles(x: np.ndarray, q, *, absolute: bool = False) -> np.ndarray:
    """Percentiles of ``x`` (or of |x|), numpy's default ``linear`` method.

    Parameters
    ----------
    x : (n,) float — values (n ≥ 1), e.g. deviations in mm
    q : sequence of float — percentiles in [0, 100]
    absolute : bool — of |x| (no |x| array is made)

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
    v = _order_statistics(x, ks, absolute)
    a, b = v[np.searchsorted(ks, lo)], v[np.searchsorted(ks, hi)]
    diff = b - a
    # numpy's _lerp: from the nearer end
    return np.where(g >= 0.5, b - diff * (1.0 - g), a + diff * g)
