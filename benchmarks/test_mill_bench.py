"""Milling the helical needle at the default 2 µm scallop: toolpaths
(OpenCAMLib) + Haas post + material-removal simulation read back from the
G-code (pytest-benchmark). Target: under 20 s on 2 cores.

Each stage's wall and CPU seconds go into the benchmark's ``extra_info``
(CPU is the honest figure on a shared machine), with the program's cycle
time on the VF-2.

Run: python -m pytest benchmarks --benchmark-only -k mill
"""

import time

from cam.mill import MillParams, plan_toolpaths, post_program, simulate_mill
from tipgeo import preset
from tipgeo.tolerances import tol


def test_mill_helical_default_scallop(benchmark):
    tol.strict = False
    spec = preset("helical-14G")
    stages = {}

    def clock():
        return time.perf_counter(), time.process_time()

    def run():
        t0 = clock()
        tp = plan_toolpaths(spec, params=MillParams())
        t1 = clock()
        text = post_program(tp)
        t2 = clock()
        res = simulate_mill(text, spec, tool=tp.tool, setup=tp.setup)
        t3 = clock()
        for name, a, b in (("toolpath", t0, t1), ("post", t1, t2), ("simulate", t2, t3)):
            stages[f"{name}_wall_s"] = b[0] - a[0]
            stages[f"{name}_cpu_s"] = b[1] - a[1]
        stages["cycle_time_s"] = res.moves.cycle_time(tp.machine.rapid)
        stages["finish_drop_points"] = tp.stats["finish_drop_points"]
        return res

    res = benchmark.pedantic(run, rounds=1, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(stages)
    print(stages)
    assert res.tip.is_watertight
