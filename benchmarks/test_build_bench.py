"""Build time of every sample at the default tolerance (pytest-benchmark).

Run: python -m pytest benchmarks --benchmark-only
"""

import pytest

from tipgeo import build_tip, preset, preset_names
from tipgeo.tolerances import tol


@pytest.mark.parametrize("name", preset_names())
def test_build(benchmark, name):
    tol.strict = False
    spec = preset(name)
    tip = benchmark(build_tip, spec)
    assert tip.volume > 0


@pytest.mark.parametrize("method", ["exact", "fourier", "mesh"])
def test_helical_edges_fit_angles(benchmark, method):
    """Edge extraction + Fourier fit + angles (table and summary) of the
    helical sample; the mesh path starts from the built tip."""
    from tipgeo.angles import analyze

    tol.strict = False
    spec = preset("helical-14G")
    src = build_tip(spec) if method == "mesh" else spec

    def run():
        rep = analyze(src, method=method)
        rep.table()
        return rep.summary()

    s = benchmark(run)
    assert s["outer"]["l_c_mm"] > 0


@pytest.mark.parametrize("blas", ["1-thread", "default-threads"])
@pytest.mark.parametrize("load", ["quiet", "busy"])
def test_fourier_angles_blas_threads(benchmark, blas, load, monkeypatch):
    """The default angle path (``fourier``: ~130 small least-squares solves per
    tip) with BLAS pinned to one thread (tipgeo's default) and with OpenBLAS's
    default threads (``TIPGEO_BLAS_THREADS=0``), on a quiet machine and with
    one busy process per core beside it."""
    import multiprocessing as mp
    import os

    from tipgeo.angles import analyze

    tol.strict = False
    monkeypatch.setenv("TIPGEO_BLAS_THREADS", "1" if blas == "1-thread" else "0")
    spec = preset("helical-14G")
    hogs = []
    if load == "busy":
        ctx = mp.get_context("spawn")
        hogs = [ctx.Process(target=_spin, daemon=True) for _ in range(os.cpu_count() or 1)]
        for h in hogs:
            h.start()
    try:
        s = benchmark.pedantic(lambda: analyze(spec, method="fourier").summary(), rounds=3,
                               iterations=1)
    finally:
        for h in hogs:
            h.terminate()
            h.join()
    assert s["outer"]["l_c_mm"] > 0


def _spin():  # pragma: no cover - runs in the load processes
    x = 0
    while True:
        x += 1
