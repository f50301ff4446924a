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
