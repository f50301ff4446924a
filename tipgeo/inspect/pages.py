"""Memory pages of a scan's large arrays.

numpy asks Linux for transparent huge pages (``madvise(MADV_HUGEPAGE)``) on
every array of 4 MB or more. Where the kernel's ``defrag`` setting is
``madvise`` (the common default), each first touch of such an array's pages
may compact memory to find a free 2 MB page: on the development machine a
fresh 120 MB array cost 0.29 CPU s to fill with huge pages against 0.05 s with
ordinary ones, and a 10⁷-point ``compare`` (about 0.5 GB of fresh per-point
arrays, each touched once or twice, sequentially) spent 1.3 s in the kernel
with them and 0.5 s without, its user time unchanged. numpy's own switch
(the ``NUMPY_MADVISE_HUGEPAGE`` environment variable, read at import) is
turned here for the duration of one comparison only.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["ordinary_pages"]


def _setter() -> Any:
    for mod in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            fn = getattr(importlib.import_module(mod), "_set_madvise_hugepage", None)
        except ImportError:
            continue
        if fn is not None:
            return fn
    return None


@contextmanager
def ordinary_pages() -> Iterator[None]:
    """Within the block, new numpy arrays are not advised to use huge pages
    (the setting before is restored after it; no effect where numpy has no
    such switch). Results are unchanged: only where the memory comes from.
    The switch is process-wide: comparisons running at once in threads may
    each see either setting, which changes only their speed."""
    fn = _setter()
    if fn is None:
        yield
        return
    before = fn(False)
    try:
        yield
    finally:
        fn(bool(before))
