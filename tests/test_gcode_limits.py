"""Cost bounds and physically meaningless values of the AeroBasic pipeline
(gcode.lexer, gcode.parser, gcode.interpreter): hostile programs are refused
cheaply with a located GCodeError that names the bound or word, its value
and what is allowed; legitimate programs stay far inside every bound.

No test here measures time (timings: benchmarks/test_gcode_bench.py); work
done is shown by where the error is raised, by counts, or by tracemalloc.
"""

import math
import tracemalloc
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcode import GCodeError, Limits, interpret, parse
from gcode.emitter import emit_program
from gcode.interpreter import ARC_TOLERANCE, MAX_ANGLE_DEG, MAX_POSITION_MM
from gcode.lexer import MAX_LINE_LENGTH, MAX_LINE_TOKENS, iter_lines, split_lines, tokenize_line
from gcode.parser import (
    DEFAULT_MAX_LINES,
    DEFAULT_MAX_STATEMENTS,
    DEFAULT_MAX_TOKENS,
    is_statement,
    parse_expression,
)
from tipgeo import preset

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
FIVE_MB = "$a = " + "+".join(["1"] * 2_500_000)     # 5 000 004 characters, 5 000 001 tokens


def run(text, **kw):
    return interpret(parse(text), **kw)


def raises(text, match, line=None, column=None, **kw):
    """The GCodeError that interpreting ``text`` raises (at line/column)."""
    with pytest.raises(GCodeError, match=match) as info:
        run(text, **kw)
    err = info.value
    if line is not None:
        assert err.line == line, str(err)
    if column is not None:
        assert err.column == column, str(err)
    return err


def peak_bytes(fn):
    """Peak of the memory allocated while ``fn()`` runs (tracemalloc)."""
    tracemalloc.start()
    try:
        fn()
    finally:
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    return peak


# -- line length and tokens per line ------------------------------------------------------
def test_five_megabyte_expression_is_refused_without_lexing_it():
    def attempt():
        with pytest.raises(GCodeError, match="MAX_LINE_LENGTH") as info:
            parse(FIVE_MB)
        return info.value

    err = attempt()
    assert (err.line, err.column) == (1, MAX_LINE_LENGTH + 1)
    assert f"line of {len(FIVE_MB)} characters" in str(err)
    assert f"MAX_LINE_LENGTH = {MAX_LINE_LENGTH}" in str(err)
    assert err.text == FIVE_MB[MAX_LINE_LENGTH:MAX_LINE_LENGTH + 20]
    # no token was made and the line was not even copied (it was 900 MB)
    assert peak_bytes(attempt) < 200_000


@pytest.mark.parametrize("where", ["first", "middle", "last"])
def test_long_line_anywhere_is_located(where):
    long = "G1 X1 ; " + "c" * MAX_LINE_LENGTH
    lines = {"first": [long, "G1", "G1"], "middle": ["G1", long, "G1"],
             "last": ["G1", "G1", long]}[where]
    with pytest.raises(GCodeError, match="longer than MAX_LINE_LENGTH") as info:
        parse("\r\n".join(lines))
    assert info.value.line == lines.index(long) + 1
    assert info.value.column == MAX_LINE_LENGTH + 1


def test_line_length_boundary_comment_included():
    ok = "G1 X1 ;" + "c" * (MAX_LINE_LENGTH - 7)
    assert len(ok) == MAX_LINE_LENGTH and len(parse(ok).body) == 1
    assert is_statement(ok)
    with pytest.raises(GCodeError, match=f"line of {MAX_LINE_LENGTH + 1} characters"):
        parse(ok + "c")
    with pytest.raises(GCodeError, match="MAX_LINE_LENGTH"):
        tokenize_line(ok + "c")
    assert not is_statement(ok + "c")
    with pytest.raises(GCodeError, match="MAX_LINE_LENGTH"):
        parse_expression("1+" * MAX_LINE_LENGTH + "1")


def test_lexer_stops_at_the_first_token_beyond_the_limit():
    line = "1+" * 200_000 + "1"
    with pytest.raises(GCodeError, match="more than 10 tokens") as info:
        tokenize_line(line, 7, max_length=len(line), max_tokens=10)
    # the 11th token starts at index 10: nothing after it was looked at
    assert (info.value.line, info.value.column, info.value.text) == (7, 11, "1")
    assert peak_bytes(lambda: pytest.raises(GCodeError, tokenize_line, line,
                                            max_length=len(line), max_tokens=10)) < 50_000


def test_tokens_per_line_boundary():
    ok = "G44" + " X" * (MAX_LINE_TOKENS - 2)            # G, 44 and the bare axes
    assert len(tokenize_line(ok)) == MAX_LINE_TOKENS
    assert len(parse(ok).body[0].words) == MAX_LINE_TOKENS - 1
    with pytest.raises(GCodeError, match=f"more than {MAX_LINE_TOKENS} tokens") as info:
        parse("G1\n" + ok + " Y")
    assert (info.value.line, info.value.column, info.value.text) == (2, len(ok) + 2, "Y")
    assert f"MAX_LINE_TOKENS = {MAX_LINE_TOKENS}" in str(info.value)


def test_legitimate_programs_are_far_inside_the_line_bounds():
    texts = [(SAMPLES / "appendix_c.pgm").read_text(), (SAMPLES / "punch-C2.pgm").read_text()]
    texts += [emit_program(preset(f"punch-C{k}")) for k in range(1, 6)]
    for text in texts:
        lines = split_lines(text)
        assert max(map(len, lines)) <= MAX_LINE_LENGTH // 20
        assert max(len(tokenize_line(line)) for line in lines) <= MAX_LINE_TOKENS // 20
        # and far inside the program bounds: a hundredth of each default would do
        parse(text, max_statements=DEFAULT_MAX_STATEMENTS // 1000,
              max_tokens=DEFAULT_MAX_TOKENS // 1000, max_lines=DEFAULT_MAX_LINES // 10_000)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(alphabet="ab \r\n\ufeff;", max_size=12), max_size=8))
def test_iter_lines_splits_like_split_lines(pieces):
    text = "".join(pieces)
    assert list(iter_lines(text)) == split_lines(text)


# -- program bounds of parse() ---------------------------------------------------------------
def test_parse_bounds_are_exact_and_located():
    text = "G1 X1\n\n; c\nSECONDS\nN10\n$a = 1+2"     # 6 lines, 3 statements, 12 tokens
    parse(text, max_lines=6, max_statements=3, max_tokens=12)
    with pytest.raises(GCodeError, match=r"more than 5 lines \(max_lines = 5\)") as info:
        parse(text, max_lines=5)
    assert (info.value.line, info.value.column) == (6, 1)
    with pytest.raises(GCodeError, match=r"more than 2 statements \(max_statements = 2\)") as info:
        parse(text, max_statements=2)
    assert (info.value.line, info.value.column, info.value.text) == (6, 1, "$a = 1+2")
    with pytest.raises(GCodeError, match=r"more than 11 tokens \(max_tokens = 11\)") as info:
        parse(text, max_tokens=11)
    assert (info.value.line, info.value.column, info.value.text) == (6, 8, "2")
    with pytest.raises(GCodeError, match=r"max_tokens = 5\)") as info:   # the 6th token
        parse(text, max_tokens=5)
    assert (info.value.line, info.value.column, info.value.text) == (5, 1, "N")


def test_parse_bounds_hold_in_lenient_mode():
    with pytest.raises(GCodeError, match="max_statements = 1"):
        parse("M3\nM4", lenient=True, max_statements=1)
    with pytest.raises(GCodeError, match="MAX_LINE_LENGTH"):
        parse("M3 " * MAX_LINE_LENGTH, lenient=True)


@pytest.mark.parametrize("name", ["max_statements", "max_tokens", "max_lines"])
@pytest.mark.parametrize("bad, exc", [(-1, ValueError), (1.5, TypeError), (True, TypeError),
                                      ("10", TypeError), (None, TypeError)])
def test_parse_bounds_are_validated(name, bad, exc):
    with pytest.raises(exc, match=rf"{name} must be a whole number ≥ 0, not {bad!r}"):
        parse("G1", **{name: bad})


def test_parse_default_bounds():
    # reaching them is measured in benchmarks/test_gcode_bench.py (a few seconds each)
    assert (DEFAULT_MAX_STATEMENTS, DEFAULT_MAX_TOKENS, DEFAULT_MAX_LINES) == (
        200_000, 250_000, 1_000_000)
    assert (MAX_LINE_LENGTH, MAX_LINE_TOKENS) == (4096, 1024)


LINES = [("G1 X1", 4, True), ("$a = 1+2", 5, True), ("SECONDS", 1, True),
         ("DVAR $a, $b", 4, True), ("G03 X-($r*2) Y0 I-$r J0", 16, True), ("N20 G1", 4, True),
         ("N10", 2, False), ("", 0, False), ("; comment", 0, False), ("   // G1 X1", 0, False)]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(LINES), min_size=1, max_size=30), st.sampled_from(["\n", "\r\n"]))
def test_parse_bounds_are_exact(lines, eol):
    text = eol.join(line for line, _, _ in lines)
    n_lines = len(lines)
    n_tokens = sum(k for _, k, _ in lines)
    statement_lines = [i + 1 for i, (_, _, is_stmt) in enumerate(lines) if is_stmt]
    token_lines = [i + 1 for i, (_, k, _) in enumerate(lines) if k]
    exact = parse(text, max_lines=n_lines, max_tokens=n_tokens,
                  max_statements=len(statement_lines))
    assert exact == parse(text)
    assert len(exact.body) == len(statement_lines)
    with pytest.raises(GCodeError, match=f"max_lines = {n_lines - 1}") as info:
        parse(text, max_lines=n_lines - 1)
    assert info.value.line == n_lines
    if statement_lines:
        with pytest.raises(GCodeError,
                           match=f"max_statements = {len(statement_lines) - 1}") as info:
            parse(text, max_statements=len(statement_lines) - 1)
        assert info.value.line == statement_lines[-1]
    if token_lines:
        with pytest.raises(GCodeError, match=f"max_tokens = {n_tokens - 1}") as info:
            parse(text, max_tokens=n_tokens - 1)
        assert info.value.line == token_lines[-1]


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200), st.integers(0, 5), st.integers(0, 20), st.integers(0, 5))
def test_any_text_under_any_bounds_parses_or_raises_gcode_error(text, stmts, tokens, lines):
    try:
        prog = parse(text, max_statements=stmts, max_tokens=tokens, max_lines=lines)
    except GCodeError:
        return
    assert len(split_lines(text)) <= lines and len(prog.body) <= stmts


# -- feeds and other modal values that may be unset -------------------------------------------
@pytest.mark.parametrize("block", ["LINEAR C1 E5", "G01 X1", "G1 X0", "G02 X0 Y0 I1 J0",
                                   "CCW X0 Y0 I0 J1", "G01 C22.5 E5"])
def test_feed_move_before_any_f_is_located_error(block):
    err = raises(f"G91\n  {block}\n", r"no feed rate \(F\) has been programmed yet", 2, 3)
    assert err.text == block


def test_feed_moves_with_f_and_rapids_without():
    tp = run("G00 C10\nRAPID X1\nF2\nLINEAR C1 E5\nG01 X2\n")
    assert [s.kind for s in tp.segments] == ["rapid", "rapid", "line", "line"]
    assert tp.segments[2].feed == 2.0 and tp.segments[2].rotary_feed == 5.0
    assert run("LINEAR C1 F1 E5").segments[0].c1 == 1.0       # F in the same block


@pytest.mark.parametrize("word, match", [
    ("F0", r"F0: the feed rate F must be > 0"), ("F-1", r"F-1: the feed rate F must be > 0"),
    ("E0", r"E0: the rotary feed rate E must be > 0"),
    ("E-2.5", r"E-2.5: the rotary feed rate E must be > 0"),
    ("T1.5", r"T1.5: the tool number T must be a whole number ≥ 0"),
    ("T-1", r"T-1: the tool number T must be a whole number ≥ 0"),
    ("T7", r"T7: no such tool"),
])
def test_bad_word_values(word, match):
    err = raises(f"G90\nG01 X1 {word}\n", match, 2, 8)
    assert err.text == word


def test_current_tool_missing_from_the_tool_table():
    raises("F1\nG01 X1\n", r"T0, the current tool, is not in the tool table \(have T1\)", 2,
           tool_radii={1: 0.01})
    assert len(run("T1\nF1\nG01 X1\n", tool_radii={1: 0.01}).segments) == 1


@pytest.mark.parametrize("table, match", [
    ({1: -0.01}, r"the radius of T1, -0.01, must be a finite number ≥ 0"),
    ({1: math.nan}, r"the radius of T1, nan"), ({1: "x"}, r"the radius of T1, 'x'"),
    ({"a": 0.1}, r"tool number 'a' must be a whole number ≥ 0"),
    ({-1: 0.1}, r"tool number -1"), ({True: 0.1}, r"tool number True"),
])
def test_tool_table_is_validated(table, match):
    with pytest.raises(ValueError, match=match):
        run("G1", tool_radii=table)


@pytest.mark.parametrize("speed", [0, -1.0, math.inf, math.nan, "10", True])
def test_rapid_speed_is_validated(speed):
    with pytest.raises(ValueError, match="rapid_speed must be a finite number > 0"):
        run("G1", rapid_speed=speed)


@pytest.mark.parametrize("pso, match", [
    ("PSOPULSE X TIME 10 5 CYCLES 0", r"CYCLES 0: the pulse count must be a whole number ≥ 1"),
    ("PSOPULSE X TIME 10 5 CYCLES -5", r"CYCLES -5"),
    ("PSOPULSE X TIME 10 5 CYCLES 2.5", r"CYCLES 2.5"),
    ("PSOPULSE X TIME 10 5 CYCLES", r"CYCLES needs a pulse count"),
    ("PSOPULSE X TIME 10 20", r"TIME 10 20: need period > 0 and 0 < on ≤ period"),
])
def test_bad_pulse_settings(pso, match):
    raises(f"G91\n{pso}\n", match, 2, 1)


# -- arcs -------------------------------------------------------------------------------------
@pytest.mark.parametrize("prog", ["F1\nG02 X0 Y0 I0 J0", "F1\nG91\nG03 X0 Y0 I0 J0",
                                  "F1\nG90\nG01 X1 Y1\nG02 X1 Y1 I0 J0", "F1\nG02 I0",
                                  "F1\nG02 X0 Y0 I1e-7 J0"])
def test_zero_radius_arc_is_an_error(prog):
    err = raises(prog, r"arc radius [0-9.e-]+ mm: I\S+ J\S+ put the centre on the start point; "
                 r"the radius must exceed 1e-06 mm \(ARC_TOLERANCE\)",
                 line=prog.count("\n") + 1, column=1)
    assert err.text == prog.rsplit("\n", 1)[-1]


def test_arc_just_above_the_tolerance_and_full_circles_are_fine():
    tp = run(f"F1\nG02 X0 Y0 I{10 * ARC_TOLERANCE} J0\nG03 I0.5\n")
    assert [s.kind for s in tp.segments] == ["arc", "arc"]
    assert tp.segments[1].radius == 0.5 and tp.segments[1].sweep == pytest.approx(2 * math.pi)


def test_arc_end_off_its_circle_states_the_tolerance():
    err = raises("F1\nG03 X1 Y0 I0.3 J0", r"arc end is 400 µm off its circle \(radius 0.3 mm "
                 r"at the start, 0.7 mm at the end; the tolerance is 0.001 µm, ARC_TOLERANCE\)",
                 2, 1)
    assert err.text == "G03 X1 Y0 I0.3 J0"
    tp = run(f"F1\nG03 X{1 + ARC_TOLERANCE / 2} Y0 I0.5 J0")   # within the tolerance
    assert tp.segments[0].kind == "arc"
    with pytest.raises(GCodeError, match="tolerance is 0.002 µm"):   # relative above 1 mm
        run("F1\nG03 X4.001 Y0 I2 J0")


def test_arc_that_compensation_collapses_may_have_zero_radius():
    # Appendix C's roughing radius passes through 0 (0.150 - 150 x 0.001 = -1.4e-16 mm);
    # under G41 on a CCW arc the beam sits at the centre whatever the radius
    text = "T1\nG91\nF1\nG01 G41 X0.05\nG03 X0 Y0 I0 J0\nG01 G40 X0.05\n"
    tp = run(text)
    assert any("collapses to its centre" in w for w in tp.warnings)
    raises(text.replace("G41", "G42"), "arc radius 0 mm", 5)      # offset outwards: no
    raises(text.replace("T1", "T0"), "arc radius 0 mm", 5)        # no tool radius: no


# -- positions out of range -------------------------------------------------------------------
@pytest.mark.parametrize("prog, line, match", [
    ("G00 X2e6", 1, r"X position 2e\+06 mm is beyond ±1e\+06 mm \(MAX_POSITION_MM\)"),
    ("ENGLISH\nG00 Y1e307", 2, r"Y position inf mm is beyond ±1e\+06 mm"),
    ("G91\nREPEAT 3\nG00 Z6e5\nEND REPEAT", 3, r"Z position 1.2e\+06 mm"),
    ("G92 X-2e6", 1, r"X position -2e\+06 mm"),
    ("G00 C1e10", 1, r"C position 1e\+10° is beyond ±1e\+09° \(MAX_ANGLE_DEG\)"),
    ("F1\nG02 X0 Y0 I2e6 J0", 2, r"arc centre X position 2e\+06 mm"),
])
def test_positions_out_of_range(prog, line, match):
    raises(prog, match, line, 1)


def test_position_bounds():
    assert MAX_POSITION_MM == 1e6 and MAX_ANGLE_DEG == 1e9
    tp = run("G00 X1e6 C-1e9\nG00 X-1e6")
    assert tp.segments[1].end == (-1e6, 0.0)


# -- interpreter limits -----------------------------------------------------------------------
def test_default_limits():
    assert Limits() == Limits(max_repeat=1_000_000, max_statements=1_000_000,
                              max_segments=100_000, max_operations=4_000_000)


@pytest.mark.parametrize("name", ["max_repeat", "max_statements", "max_segments",
                                  "max_operations"])
@pytest.mark.parametrize("bad, exc", [(-1, ValueError), (2.0, TypeError), (False, TypeError),
                                      (None, TypeError)])
def test_limits_are_validated(name, bad, exc):
    with pytest.raises(exc, match=rf"{name} must be a whole number ≥ 0, not {bad!r}"):
        Limits(**{name: bad})


def test_interpret_needs_a_limits():
    with pytest.raises(TypeError, match="limits must be a gcode.Limits, not dict"):
        run("G1", limits={"max_statements": 3})


def test_appendix_c_is_far_inside_the_limits():
    prog = parse((SAMPLES / "appendix_c.pgm").read_text())
    interpret(prog, limits=Limits(max_statements=13_541, max_operations=75_864,
                                  max_segments=9_616, max_repeat=80))
    for name, used in [("max_statements", 13_541), ("max_operations", 75_864),
                       ("max_segments", 9_616), ("max_repeat", 80)]:
        with pytest.raises(GCodeError, match=f"{name} = {used - 1}"):
            interpret(prog, limits=Limits(**{name: used - 1}))
        assert getattr(Limits(), name) >= 10 * used


def test_runaway_repeat_is_refused_before_its_loop():
    # the user's example: refused by max_repeat at once
    raises("$a = 0\nREPEAT 100000000\n$a = $a + 1\nEND REPEAT", r"REPEAT count 100000000 "
           r"exceeds max_repeat = 1000000", 2, 1)
    # a count within max_repeat whose passes would certainly exceed max_statements: refused
    # at the REPEAT line, so before a single pass ran (a pass would fail at line 3)
    raises("$a = 0\nREPEAT 600000\n$a = $a + 1\n$a = $a - 1\nEND REPEAT",
           r"REPEAT 600000 × 2 statements would execute more than 1000000 statements "
           r"\(max_statements = 1000000; runaway loop\?\)", 2, 1)
    raises("REPEAT 100000\n$a = 1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1+1\nEND REPEAT",
           r"REPEAT 100000 × 41 operations would execute more than 4000000 operations "
           r"\(max_operations = 4000000; runaway loop\?\)", 1, 1)


def test_statement_and_operation_limits_are_located():
    raises("G91\n" * 10, r"more than 5 statements executed \(max_statements = 5; runaway "
           r"loop\?\)", 6, 1, limits=Limits(max_statements=5))
    raises("$a = 1+1\n" * 10, r"more than 10 operations executed \(max_operations = 10; "
           r"runaway loop\?\)", 4, 1, limits=Limits(max_operations=10))
    # in nested loops the inner REPEAT is refused at the pass that would go beyond
    raises("$a = 0\nREPEAT 1000\nREPEAT 10\n$a = $a + 1\nEND REPEAT\nEND REPEAT",
           r"REPEAT 10 × 1 statements would execute more than 5000 statements", 3, 1,
           limits=Limits(max_statements=5000))


def test_empty_repeats_cost_nothing():
    # a million empty passes of each of a thousand empty REPEATs: no pass is run
    tp = run("REPEAT 1000\nREPEAT 1000000\nEND REPEAT\nEND REPEAT\nREPEAT 0\nG01 X1\nEND REPEAT",
             limits=Limits(max_statements=1002, max_operations=1002))
    assert tp.segments == []


def counts(a, b):
    """Statements, operations, moves and largest REPEAT count run by ``nested(a, b)``."""
    return 3 + a * (1 + b), 6 + a * (1 + 4 * b), a * b, max(a, b) if a else 0


def nested(a, b):
    return (f"G91 F1\n$x = 0\nREPEAT {a}\nREPEAT {b}\nG01 X0.001\nEND REPEAT\nEND REPEAT\n")


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 30), st.integers(0, 30))
def test_interpreter_limits_are_exact(a, b):
    prog = parse(nested(a, b))
    stmts, ops, moves, repeat = counts(a, b)
    exact = Limits(max_statements=stmts, max_operations=ops, max_segments=moves,
                   max_repeat=repeat)
    assert len(interpret(prog, limits=exact).segments) == moves
    for name, used in [("max_statements", stmts), ("max_operations", ops),
                       ("max_segments", moves), ("max_repeat", repeat)]:
        if used == 0:
            continue
        with pytest.raises(GCodeError, match=f"{name} = {used - 1}"):
            interpret(prog, limits=Limits(**{name: used - 1}))


def test_skipped_statements_are_charged_their_tokens():
    # lenient mode skips a line the lexer rejects, but the tokens lexed before the
    # foreign character still count: 1021 + 1021 > 2000
    line = "G44" + " X" * 1019 + " %"
    with pytest.raises(GCodeError, match=r"more than 2000 tokens \(max_tokens = 2000\)") as info:
        parse(f"{line}\n{line}\n", lenient=True, max_tokens=2000)
    # the 2001st token is the 980th of line 2: the 978th X, at column 3 + 2 * 978
    assert (info.value.line, info.value.column, info.value.text) == (2, 1959, "X")
    assert len(parse(f"{line}\n{line}\n", lenient=True, max_tokens=2042).warnings) == 2


def test_tokenize_line_into_a_list_keeps_the_tokens_made_before_an_error():
    out = ["already there"]
    with pytest.raises(GCodeError, match="unexpected character"):
        tokenize_line("G1 X1 %", out=out)
    assert [t if isinstance(t, str) else t.text for t in out] == ["already there", "G", "1",
                                                                  "X", "1"]
    with pytest.raises(GCodeError, match=r"more than 2 tokens \(MAX_LINE_TOKENS = 2\)"):
        tokenize_line("G1 X1", max_tokens=2, out=out)
