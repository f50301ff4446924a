"""Laser programs: parse + interpret, and ablation (pytest-benchmark).

Run: python -m pytest benchmarks --benchmark-only -k gcode
"""

from pathlib import Path

import pytest

from gcode.ablation import ablate
from gcode.emitter import LaserParams, emit_program
from gcode.interpreter import interpret
from gcode.parser import parse
from tipgeo import preset
from tipgeo.tolerances import tol

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


@pytest.mark.parametrize("which", ["appendix_c", "punch-C4"])
def test_gcode_parse_interpret(benchmark, which):
    text = ((SAMPLES / "appendix_c.pgm").read_text() if which == "appendix_c"
            else emit_program(preset(which)))
    tp = benchmark(lambda: interpret(parse(text), tool_radii={0: 0.0, 1: 0.01}))
    assert len(tp.segments) > 1000


def test_gcode_ablation_c4(benchmark):
    tol.strict = False
    spec = preset("punch-C4")
    laser = LaserParams()
    tp = interpret(parse(emit_program(spec, laser)), tool_radii={0: 0.0, 1: 0.01})
    res = benchmark(lambda: ablate(tp, spec, beam_diameter=laser.beam_diameter))
    assert res.notches == 5
