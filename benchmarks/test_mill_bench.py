"""Milling the helical needle at the default 2 µm scallop: toolpaths
(OpenCAMLib) + Haas post + material-removal simulation read back from the
G-code (pytest-benchmark). Target: under 20 s on 2 cores.

Run: python -m pytest benchmarks --benchmark-only -k mill
"""

from cam.mill import MillParams, plan_toolpaths, post_program, simulate_mill
from tipgeo import preset
from tipgeo.tolerances import tol


def test_mill_helical_default_scallop(benchmark):
    tol.strict = False
    spec = preset("helical-14G")

    def run():
        tp = plan_toolpaths(spec, params=MillParams())
        return simulate_mill(post_program(tp), spec, tool=tp.tool, setup=tp.setup)

    res = benchmark.pedantic(run, rounds=1, iterations=1, warmup_rounds=1)
    assert res.tip.is_watertight
