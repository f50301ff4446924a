"""BLAS threads for small linear algebra.

tipgeo's least-squares solves (Fourier edge fits, tissue fits, GP fits of a few
hundred points) are tiny; with OpenBLAS's default of one thread per core each
of them pays the threads' wake-up and, on a busy machine, waits for cores held
by other work (measured: a helical tip's 130 solves went from 8.6 ms to 138 ms
each under load). :func:`small_linalg` pins BLAS to one thread for the block
it guards; ``TIPGEO_BLAS_THREADS`` overrides the count (``0`` = leave BLAS as
it is).

``tipgeo`` run as a program (the ``tipgeo`` command, ``python -m tipgeo``)
goes one step further: :func:`program_blas_threads`, called by
``tipgeo/__init__.py`` before numpy is first imported, sets
``OPENBLAS_NUM_THREADS`` to the same count, so OpenBLAS starts without its
thread pool at all. Its idle threads spin after every call and its start-up
allocates per-thread buffers: a ``tipgeo compare`` at 10⁶ points measured
1.82 CPU s with the pool, 1.69 with the pool limited by threadpoolctl and
1.55 with none (median of 8 interleaved runs each, 2 cores). Nothing is set
when the user set a BLAS thread count (``OPENBLAS_NUM_THREADS``,
``GOTO_NUM_THREADS``, ``OMP_NUM_THREADS``) or ``TIPGEO_BLAS_THREADS=0``, when
numpy is already imported, or when tipgeo is imported as a library; foreign
programs tipgeo starts (CalculiX) get the environment without it
(:func:`foreign_env`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator, Mapping

__all__ = ["small_linalg", "blas_threads", "program_blas_threads", "foreign_env",
           "is_program"]

#: the variable :func:`program_blas_threads` sets, and the value it set
_SET: dict[str, str] = {}


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


def is_program() -> bool:
    """Whether this process is the ``tipgeo`` command: the console script
    as ``__main__``, or ``python -m tipgeo`` on the original command line."""
    main = sys.modules.get("__main__")
    name = os.path.basename(getattr(main, "__file__", None) or "")
    if name in ("tipgeo", "tipgeo.exe", "tipgeo-script.py"):
        return True
    argv = list(getattr(sys, "orig_argv", ()))
    return any(a == "-m" and b == "tipgeo" for a, b in zip(argv, argv[1:]))


def program_blas_threads() -> str | None:
    """Set ``OPENBLAS_NUM_THREADS`` to :func:`blas_threads` when tipgeo runs
    as a program and numpy is not imported yet (see the module docstring);
    the value set, or None when nothing was set."""
    if "numpy" in sys.modules or not is_program():
        return None
    if any(os.environ.get(k, "").strip()
           for k in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")):
        return None
    n = blas_threads(1)
    if n is None:
        return None
    os.environ["OPENBLAS_NUM_THREADS"] = _SET["OPENBLAS_NUM_THREADS"] = str(n)
    return str(n)


def foreign_env(env: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment (default ``os.environ``) for a foreign program tipgeo
    starts: without the BLAS thread count :func:`program_blas_threads` set
    (the user's own settings stay)."""
    out = dict(os.environ if env is None else env)
    for k, v in _SET.items():
        if out.get(k) == v:
            del out[k]
    return out
