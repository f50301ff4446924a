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
