"""Compiled passes of the binary scan reader (numba): a chunk's bounds and its
conversion to mm offsets from an origin, column by column.

Units: file units in, mm out (``factor``); float64 arithmetic throughout,
stored as the buffer's dtype (float32 offsets or float64).
"""

from __future__ import annotations

import numpy as np

from .._jit import njit
from ..arrays import AnyArray, FloatArray

__all__ = ["chunk_bounds", "store_offsets"]


@njit(cache=True, nogil=True)
def chunk_bounds(x: AnyArray, y: AnyArray,
                 z: AnyArray) -> tuple[int, float, FloatArray, FloatArray]:
    """Non-finite points, the largest |coordinate| and the per-axis minimum
    and maximum of the finite points of a chunk given as three columns
    ((m,) float each).

    Returns
    -------
    nbad : int; biggest : float; lo : (3,) float; hi : (3,) float
    """
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    nbad = 0
    big = 0.0
    for i in range(x.shape[0]):
        a, b, c = np.float64(x[i]), np.float64(y[i]), np.float64(z[i])
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c)):
            nbad += 1
            continue
        big = max(big, abs(a), abs(b), abs(c))
        lo[0], hi[0] = min(lo[0], a), max(hi[0], a)
        lo[1], hi[1] = min(lo[1], b), max(hi[1], b)
        lo[2], hi[2] = min(lo[2], c), max(hi[2], c)
    return nbad, big, lo, hi


@njit(cache=True, nogil=True)
def store_offsets(x: AnyArray, y: AnyArray, z: AnyArray, factor: float, origin: FloatArray,
                  out: AnyArray, start: int) -> float:
    """``out[start + i] = (x, y, z)[i] · factor − origin`` in float64, stored
    as ``out``'s dtype ((n, 3) float32 or float64); returns the largest
    |offset| (mm)."""
    span = 0.0
    for i in range(x.shape[0]):
        a = np.float64(x[i]) * factor - origin[0]
        b = np.float64(y[i]) * factor - origin[1]
        c = np.float64(z[i]) * factor - origin[2]
        span = max(span, abs(a), abs(b), abs(c))
        out[start + i, 0] = a
        out[start + i, 1] = b
        out[start + i, 2] = c
    return span
