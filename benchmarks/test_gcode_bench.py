"""Laser programs: parse + interpret, and ablation (pytest-benchmark).

Run: python -m pytest benchmarks --benchmark-only -k gcode
"""

import time
from pathlib import Path

import pytest

from gcode.ablation import ablate
from gcode.emitter import LaserParams, emit_program
from gcode.errors import GCodeError
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


# -- cost bounds: refusing hostile programs (gcode.lexer / parser / interpreter) ----------
# Each default bound is chosen so that reaching it costs at most about 4-5 s of CPU on
# the reference 2-core machine; these benchmarks reach each one from the cheapest and
# the costliest direction measured (see gcode.interpreter.Limits, gcode.parser). They
# time CPU (time.process_time), what the bounds are about, not wall time.
HEAVY = "+".join(["1"] * 199)          # the deepest expression chain MAX_EXPR_DEPTH allows
HOSTILE = {
    # parse
    "5MB-expression": ("$a = " + "+".join(["1"] * 2_500_000), "MAX_LINE_LENGTH = 4096"),
    "parse-max_tokens": ("G1\n" * 125_001, "max_tokens = 250000"),
    "parse-max_statements": ("END\n" * 200_001, "max_statements = 200000"),
    "parse-max_lines": ("\n" * 1_000_001, "max_lines = 1000000"),
    # empty macros nested: 4004 replacements a line, refused at 1 000 000 in all
    "parse-macro-expansions": ("#define E\n#define D " + "E " * 1000 + "\n#define C D D D D\n"
                               + "$x = 1 C\n" * 300, "MAX_PROGRAM_EXPANSIONS"),
    # interpret (nested loops, so no REPEAT is refused before its passes run)
    "max_repeat": ("$a = 0\nREPEAT 100000000\n$a = $a + 1\nEND REPEAT\n",
                   "max_repeat = 1000000"),
    "max_statements": ("$a = 0\nREPEAT 100000\nREPEAT 100\n$a = $a + 1\nEND REPEAT\n"
                       "END REPEAT\n", "max_statements = 1000000"),
    "max_operations": (f"REPEAT 2000\nREPEAT 10\n$a = {HEAVY}\nEND REPEAT\nEND REPEAT\n",
                       "max_operations = 4000000"),
    "max_segments": ("G91 F1\nT1\nG41 X0.01\nREPEAT 20000\nREPEAT 10\nG03 X0 Y0 I0.5 J0\n"
                     "END REPEAT\nEND REPEAT\n", "max_segments = 100000"),
}


def _refused(text):
    try:
        interpret(parse(text))
    except GCodeError as err:
        return str(err)
    raise AssertionError("the program was not refused")


@pytest.mark.benchmark(timer=time.process_time)
@pytest.mark.parametrize("which", list(HOSTILE))
def test_gcode_refuse_hostile(benchmark, which):
    text, match = HOSTILE[which]
    message = benchmark.pedantic(_refused, args=(text,), rounds=2, iterations=1)
    assert match in message


@pytest.mark.benchmark(timer=time.process_time)
def test_gcode_largest_accepted_toolpath(benchmark):
    # 99 999 compensated arcs: the most moves the default max_segments lets through
    text = "G91 F1\nT1\nG41 X0.01\nREPEAT 99998\nG03 X0 Y0 I0.5 J0\nEND REPEAT\n"
    tp = benchmark.pedantic(lambda: interpret(parse(text)), rounds=1, iterations=1)
    assert len(tp.segments) == 99_999
