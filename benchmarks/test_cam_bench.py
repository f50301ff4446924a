"""Grinding: program + simulation for each thesis needle (pytest-benchmark).

Run: python -m pytest benchmarks --benchmark-only -k cam
"""

import pytest

from cam import make_program, simulate
from tipgeo import preset
from tipgeo.tolerances import tol

NEEDLES = ["bevel-14G-xi15", "bevel-14G-xi45", "bevel-14G-xi75", "twoplane-14G-xi15",
           "threeplane-14G-xi15", "lancet-14G", "conical-14G-theta15"]


@pytest.mark.parametrize("name", NEEDLES)
def test_cam_program_and_simulation(benchmark, name):
    tol.strict = False
    spec = preset(name)
    tip = benchmark(lambda: simulate(make_program(spec), spec))
    assert tip.is_watertight
