"""BLAS threads for small linear algebra.

tipgeo's least-squares solves (Fourier edge fits, tissue fits, GP fits of a few
hundred points) are tiny; with OpenBLAS's default of one thread per core each
of them pays the threads' wake-up and, on a busy machine, waits for cores held
by other work (measured: a helical tip's 130 solves went from 8.6 ms to 138 ms
each under load). :func:`small_linalg` pins BLAS to one thread for the block
it guards; ``TIPGEO_BLAS_THREADS`` overrides the count (``0`` = leave BLAS as
it is).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

__all__ = ["small_linalg", "blas_threads"]


def blas_threads(default: int = 1) -> int | None:
    """The BLAS thread count to use: ``TIPGEO_BLAS_THREADS`` if set (``0`` =
    unchanged, returned as None), else ``default``."""
    raw = os.environ.get("TIPGEO_BLAS_THREADS", "").strip()
    if not raw:
        return default
    try:
        n = int(raw)
    except ValueError:
        return default
    return None if n <= 0 else n


@contextlib.contextmanager
def small_linalg(threads: int | None = 1) -> Iterator[None]:
    """Run the block with BLAS limited to ``threads`` (None: unchanged);
    a no-op when threadpoolctl is missing."""
    n = blas_threads(threads) if threads is not None else None
    if n is None:
        yield
        return
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        yield
        return
    with threadpool_limits(limits=n, user_api="blas"):
        yield
