"""The A3200 AeroBasic that people write (issue 16): preprocessor macros,
system variables and I/O, DVAR separators, WHILE, IF/ELSEIF/ELSE, DFS and
CALL with arguments, dwells counted in the time, no-motion statements, the
Ensemble dialect refused, and lenient mode that never drops a move.

Expected values are exact or closed form; no test measures time.
"""

import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcode import GCodeError, Limits, interpret, parse
from gcode.ast import (
    Assign,
    Call,
    Compare,
    Dwell,
    FunctionMacro,
    If,
    Logic,
    Mode,
    NoMotion,
    Not,
    Num,
    Span,
    SysAssign,
    Var,
    While,
)
from gcode.expr import evaluate, to_source
from gcode.parser import parse_expression
from gcode.pipeline import laser_check
from tipgeo.cli import main


def run(text, **kw):
    return interpret(parse(text), **kw)


def located(text, line, column, snippet, match, **kw):
    with pytest.raises(GCodeError, match=match) as info:
        run(text, **kw)
    err = info.value
    assert (err.line, err.column, err.text) == (line, column, snippet), str(err)
    return err


# -- preprocessor ----------------------------------------------------------------------
def test_define_substitutes_object_like_macros():
    prog = parse("#define Tip_Plate_Distance 0.5 ; mm\n#define SPEED (2*FAST)\n"
                 "#define FAST 1.5\nF SPEED\nG01 Z Tip_Plate_Distance\n")
    # SPEED was defined before FAST: replacements are rescanned where they are used
    assert dict(prog.macros) == {"Tip_Plate_Distance": "0.5", "SPEED": "(2*FAST)",
                                 "FAST": "1.5"}
    f, g01 = prog.body
    # the span keeps the source text and columns of the line as written
    assert g01.span.text == "G01 Z Tip_Plate_Distance"
    assert g01.words[1].span.text == "Z Tip_Plate_Distance"
    assert g01.words[1].value == Num(0.5)
    assert f.words[0].value.right == Num(1.5)
    tp = interpret(prog)
    assert tp.segments[0].feed == 3.0 and tp.summary()["time_s"] == 0.5 / 3.0
    # a macro that names itself is not expanded again (C semantics): FOO stays a name
    with pytest.raises(GCodeError, match="expected a number") as info:
        parse("#define FOO (FOO+1)\n$a = FOO\n")
    assert (info.value.line, info.value.column) == (2, 6)


def test_macro_errors_keep_the_position_of_the_use():
    # the word F needs a value: reported at the macro's use, with its source text
    err = located("#define FEED F\nG1 X1 FEED\n", 2, 7, "FEED", "needs a value")
    assert "line 2, column 7" in str(err)
    located("#define ZAP $nope\nF1\nG01 X1 Y ZAP\n", 3, 8, "Y ZAP", r"unknown variable \$nope")
    # a foreign character in a replacement is refused where it is defined
    located("#define Q  %\nG1 X1 Q\n", 1, 12, "%", "unexpected character")


def test_macros_are_not_expanded_in_variables_strings_comments_or_other_names():
    prog = parse('#define a 7\n$a = 1 ; a\nMSGDISPLAY 1, "a"\n')
    assign = prog.body[0]
    assert assign == Assign("a", Num(1), assign.span)
    assert isinstance(prog.body[1], NoMotion)
    with pytest.raises(GCodeError, match="unknown keyword 'ab'|expected a number"):
        parse('#define a 7\n$b = ab\n')


def test_undef_and_refused_directives():
    with pytest.raises(GCodeError, match="the F word needs a value"):
        parse("#define SPEED 2\n#undef SPEED\nF SPEED\n")
    for directive in ("#include \"setup.pgm\"", "#ifdef FAST", "  # if 1"):
        with pytest.raises(GCodeError, match="is not supported .only #define and #undef."):
            parse(directive + "\n", lenient=True)     # what it selects could move: never skipped
    with pytest.raises(GCodeError, match="after macro expansion"):
        parse("#define A $" + "v" * 1500 + "\n$x = A+A+A\n")
    # empty macros nested in each other: a billion replacements of nothing, refused cheaply
    nest = "#define E\n#define D " + "E " * 1000 + "\n#define C " + "D " * 1000 + "\n"
    with pytest.raises(GCodeError, match=r"more than 4096 macro replacements") as info:
        parse(nest + "$x = 1 C\n")
    assert (info.value.line, info.value.column) == (4, 8)


def test_function_like_macros_expand_their_arguments_first():
    prog = parse("#define SQ(x) ((x)*(x))\n#define MV(a, b) G01 X (a) Y (b)\n#define K 3\n"
                 "#define NONE() F 2\nNONE()\nMV(SQ(K), SQ(1+1)) ; (3)^2, (1+1)^2\n"
                 "MV(SQ(K) - (1+2), -1)\n$SQ = 5\n")
    assert dict(prog.macros)["MV"] == FunctionMacro(("a", "b"), "G01 X (a) Y (b)")
    tp = interpret(prog)
    # (1+1)*(1+1) = 4, not 1+1*1+1 = 3: the parentheses of the body are kept
    assert tp.segments[0].feed == 2.0 and tp.segments[0].end == (9.0, 4.0)
    assert tp.segments[1].end == (6.0, -1.0)
    assert prog.body[1].span == Span(6, 1, "MV(SQ(K), SQ(1+1))")
    # a function-like name without '(' is left alone (C): here an unknown word
    with pytest.raises(GCodeError, match="unknown keyword 'SQ'") as info:
        parse("#define SQ(x) ((x)*(x))\nG01 X1 Y SQ\n")
    assert (info.value.line, info.value.column) == (2, 10)
    assert parse("#define SQ(x) ((x)*(x))\n$SQ = 2\n").body[0].name == "sq"  # any case


@pytest.mark.parametrize("text, line, col, match", [
    ("#define SQ(x) x\n$a = SQ(1, 2)\n", 2, 6, r"takes 1 argument\(s\) \(x\), 2 given"),
    ("#define SQ(x) x\n$a = SQ(1\n", 2, 8, r"not closed with '\)' on this line"),
    ("#define SQ(x, x) x\n", 1, 15, "parameter x is named twice"),
    ("#define SQ(x y) x\n", 1, 12, "expected a parameter name"),
    ("#define SQ(x) #x\n", 1, 15, "unexpected character '#'"),
    ("#define SQ(x) x\n#define Z $nope\nG01 X SQ(Z)\n", 3, 5, r"unknown variable \$nope"),
])
def test_function_like_macro_errors_are_located(text, line, col, match):
    with pytest.raises(GCodeError, match=match) as info:
        run(text)
    assert (info.value.line, info.value.column) == (line, col), str(info.value)


@given(a=st.integers(-999, 999), b=st.integers(-999, 999),
       spaces=st.sampled_from(["", " ", "\t", "  "]))
def test_function_like_macro_property(a, b, spaces):
    """ADD(a, b) with any spacing gives a + b; the arguments are substituted
    as wholes (SUB(a, b) with a negative b is still a − b)."""
    text = (f"#define ADD(p,{spaces}q) ((p)+(q))\n#define SUB(p, q) ((p)-(q))\nF 1\n"
            f"G01 X ADD({spaces}{a},{spaces}{b}{spaces}) Y SUB({a}, {b})\n")
    seg = interpret(parse(text)).segments[0]
    assert seg.end == (float(a + b), float(a - b))


def test_macro_replacements_are_bounded_for_the_whole_program(monkeypatch):
    import gcode.parser as parser

    nest = "#define E\n#define D " + "E " * 1000 + "\n"
    parse(nest + "$x = 1 D\n" * 9)                  # 9 x 1001 replacements
    monkeypatch.setattr(parser, "MAX_PROGRAM_EXPANSIONS", 9000)
    with pytest.raises(GCodeError, match=r"more than 9000 macro replacements in the program "
                       r"\(MAX_PROGRAM_EXPANSIONS\)") as info:
        parse(nest + "$x = 1 D\n" * 9)
    assert (info.value.line, info.value.column) == (11, 8)   # the 9th use: 9009 > 9000


NAMES_OK = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{2,10}", fullmatch=True).filter(
    lambda n: n.upper() not in {"AND", "NOT", "END", "DVAR", "THEN", "ELSE", "CALL", "DFS"})


@settings(max_examples=100, deadline=None)
@given(NAMES_OK, st.floats(-1e3, 1e3, allow_nan=False).map(lambda v: round(v, 6)),
       st.integers(0, 6))
def test_a_macro_runs_like_its_text_and_errors_point_at_its_use(name, value, pad):
    text = f"#define {name} {value!r}\nF1\n{' ' * pad}G01 X {name} Y1\n"
    macro, literal = run(text), run(f"; no macro\nF1\n{' ' * pad}G01 X {value!r} Y1\n")
    assert macro.segments == literal.segments
    with pytest.raises(GCodeError, match="needs a value") as info:
        parse(f"#define {name} F\nG1 X1 {name}\n")
    assert (info.value.line, info.value.column, info.value.text) == (2, 7, name)


# -- system variables and I/O ------------------------------------------------------------
@pytest.mark.parametrize("text, name, index, key", [
    ("$DO[0].X = 1", "do", (Num(0), "X"), "$DO[0].X"),
    ("$do[1].y=0", "do", (Num(1), "Y"), "$DO[1].Y"),
    ("$AO[0].X = 2.5", "ao", (Num(0), "X"), "$AO[0].X"),
    ("$DO0.0=0", "do0", (".0",), "$DO0.0"),
    ("$DO = 3", "do", (), "$DO"),
    ("$global[2] = 4", "global", (Num(2),), "$GLOBAL[2]"),
])
def test_system_variables_are_no_motion_with_their_effect(text, name, index, key):
    (stmt,) = parse(text).body
    assert isinstance(stmt, SysAssign) and (stmt.name, stmt.index) == (name, index)
    tp = run(text)
    assert tp.segments == [] and key in tp.io
    (rec,) = tp.no_motion
    assert rec["line"] == 1 and rec["statement"] == text and rec["executed"] == 1
    assert rec["effect"] == f"sets {key} = {tp.io[key]:.12g}"


def test_outputs_switched_in_a_loop_record_the_last_value():
    tp = run("$i = 0\nREPEAT 4\n$DO[$i].X = $i * 2\n$i = $i + 1\nEND REPEAT\n")
    assert tp.io == {"$DO[0].X": 0.0, "$DO[1].X": 2.0, "$DO[2].X": 4.0, "$DO[3].X": 6.0}
    (rec,) = tp.no_motion
    assert rec["executed"] == 4 and rec["effect"] == "sets $DO[3].X = 6"


# -- DVAR ----------------------------------------------------------------------------------
SEPARATORS = st.sampled_from([" ", "\t", ",", ", ", " ,", " , ", ",\t", "  "])
NAMES = st.lists(st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True), min_size=1,
                 max_size=8)


@settings(max_examples=100, deadline=None)
@given(NAMES, st.lists(SEPARATORS, min_size=8, max_size=8), st.sampled_from(["DVAR", "dvar",
                                                                             "DVar"]),
       st.sampled_from(["", ",", " ; declared", " // declared"]))
def test_dvar_in_every_separator_style(names, seps, head, tail):
    text = head + " " + "".join(f"${n}{seps[i]}" for i, n in enumerate(names[:-1])) \
        + f"${names[-1]}{tail}"
    (stmt,) = parse(text).body
    assert stmt.names == tuple(n.lower() for n in names)
    tp = run(text + "\n" + "".join(f"G0 X${n}\n" for n in names))
    assert [s.end for s in tp.segments] == [(0.0, 0.0)] * len(names)   # declared: 0


def test_dvar_arrays():
    assert parse("DVAR $pts[100], $n").body[0].names == ("pts", "n")


# -- conditions, WHILE, IF ---------------------------------------------------------------
@pytest.mark.parametrize("text, value", [
    ("1 < 2", 1.0), ("2 <= 2", 1.0), ("3 > 4", 0.0), ("3 >= 4", 0.0), ("1 == 1", 1.0),
    ("1 <> 1", 0.0), ("1 != 2", 1.0), ("1 < 2 AND 2 < 1", 0.0), ("1 < 2 OR 2 < 1", 1.0),
    ("NOT 1 < 2", 0.0), ("NOT NOT 3", 1.0), ("(1 < 2) AND (3 > 2)", 1.0),
    ("1 + 2 * 3 == 7", 1.0), ("($a > 1) * 5", 5.0),
])
def test_condition_values(text, value):
    p = parse(f"IF {text} THEN\nENDIF").body[0]
    assert evaluate(p.branches[0][0], {"a": 2.0}) == value


def test_equals_compares_only_in_a_condition():
    (stmt,) = parse("WHILE $a = 1\nENDWHILE").body
    assert stmt.cond == Compare("==", Var("a"), Num(1))
    with pytest.raises(GCodeError, match="unexpected '='"):
        parse("$b = $a = 1")


VARIABLES = {"a": 1.5, "b": -2.0, "z": 0.0}
leaves = st.one_of(st.integers(-3, 3).map(lambda k: Num(float(k))),
                   st.sampled_from(sorted(VARIABLES)).map(Var))
conditions = st.recursive(
    leaves,
    lambda sub: st.one_of(
        sub.map(Not),
        st.tuples(st.sampled_from(["==", "<>", "<", ">", "<=", ">="]), sub, sub).map(
            lambda t: Compare(*t)),
        st.tuples(st.sampled_from(["AND", "OR"]), sub, sub).map(lambda t: Logic(*t))),
    max_leaves=12)


def reference(node):
    if isinstance(node, Num):
        return node.value
    if isinstance(node, Var):
        return VARIABLES[node.name]
    if isinstance(node, Not):
        return float(reference(node.operand) == 0)
    a, b = reference(node.left), reference(node.right)
    if isinstance(node, Logic):
        return float((a != 0 and b != 0) if node.op == "AND" else (a != 0 or b != 0))
    return float({"==": a == b, "<>": a != b, "<": a < b, ">": a > b, "<=": a <= b,
                  ">=": a >= b}[node.op])


@settings(max_examples=300, deadline=None)
@given(conditions)
def test_conditions_print_parse_and_evaluate_like_python(cond):
    source = to_source(cond)
    assert evaluate(parse_expression(source), VARIABLES) == reference(cond)
    (stmt,) = parse(f"IF {source} THEN\nELSE\nENDIF").body
    assert evaluate(stmt.branches[0][0], VARIABLES) == reference(cond)


@settings(max_examples=100, deadline=None)
@given(st.integers(-5, 5), st.integers(-5, 5))
def test_if_elseif_else_take_one_branch(a, b):
    text = (f"$a = {a}\n$b = {b}\nF1\nIF $a > $b THEN\nG01 X1\nELSEIF $a = $b THEN\n"
            "G01 X2\nG01 X3\nELSE\nG01 Y1\nEND IF\n")
    tp = run(text)
    expected = [(1.0, 0.0)] if a > b else [(2.0, 0.0), (3.0, 0.0)] if a == b else [(0.0, 1.0)]
    assert [s.end for s in tp.segments] == expected


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 40), st.integers(1, 5))
def test_while_runs_until_its_condition_fails(n, step):
    tp = run(f"DVAR $i\nF1\nG91\nWHILE $i < {n} DO\nG01 X1\n$i = $i + {step}\nENDWHILE\n")
    passes = -(-n // step)
    assert len(tp.segments) == passes
    assert tp.summary()["path_length_mm"] == float(passes)


def test_while_runaway_is_bounded_and_located():
    located("$i = 0\nWHILE 1\nENDWHILE\n", 2, 1, "WHILE 1", "max_statements = 1000",
            limits=Limits(max_statements=1000))
    located("WHILE 1 > 0\n$a = 1\nENDWHILE\n", 1, 1, "WHILE 1 > 0", "max_operations = 500",
            limits=Limits(max_operations=500))


@pytest.mark.parametrize("text, line, col, snippet, match", [
    ("IF 1 THEN\nELSE\nELSE\nENDIF", 3, 1, "ELSE", "ELSE after ELSE"),
    ("ELSE\n", 1, 1, "ELSE", "ELSE without IF"),
    ("IF 1 THEN\nELSEIF 2\nENDIF", 2, 1, "ELSEIF", "needs THEN"),
    ("IF 1\nENDIF", 1, 1, "IF", "needs THEN"),
    ("IF 1 THEN G1 X1\nENDIF", 1, 11, "G", "ends its line"),
    ("WHILE 1\nEND REPEAT", 2, 1, "END REPEAT", "cannot close the WHILE of line 1"),
    ("REPEAT 2\nENDWHILE", 2, 1, "ENDWHILE", "cannot close the REPEAT of line 1"),
    ("IF 1 THEN\n", 1, 1, "IF 1 THEN", "IF without ENDIF"),
    ("WHILE\n", 1, 1, "WHILE", "needs a condition"),
])
def test_block_structure_errors(text, line, col, snippet, match):
    with pytest.raises(GCodeError, match=match) as info:
        parse(text, lenient=True)
    assert (info.value.line, info.value.column, info.value.text) == (line, col, snippet)


# -- DFS and CALL --------------------------------------------------------------------------
def test_call_with_arguments_defined_after_the_program_end():
    text = ("F2\nG91\nCall Zig P1 Q0.5\nCALL zig P 2, Q $p0\nEND PROGRAM\n"
            "DFS ZIG\n  G01 X$p\n  G01 Y$q\nENDDFS\n")
    prog = parse(text.replace("$p0", "0.25"))
    assert [s.name for s in prog.subroutines] == ["ZIG"]
    assert prog.body[2] == Call("ZIG", (("P", Num(1)), ("Q", Num(0.5))), prog.body[2].span)
    tp = interpret(prog)
    assert [s.end for s in tp.segments] == [(1, 0), (1, 0.5), (3, 0.5), (3, 0.75)]
    assert tp.summary()["time_s"] == pytest.approx((1 + 0.5 + 2 + 0.25) / 2, abs=1e-15)
    # arguments are local: the caller's $p is restored after the call
    tp = run("$p = 9\nCALL S P1\n$x = $p\nG0 X$x\nEND\nDFS S\nENDDFS\n")
    assert tp.segments[0].end == (9.0, 0.0)


def test_subroutine_names_with_digits_and_underscores():
    tp = run("F1\nCALL line_2 P3\nEND PROGRAM\nDFS Line_2\nG01 X$p\nENDDFS\n")
    assert tp.segments[0].end == (3.0, 0.0)


@pytest.mark.parametrize("text, line, match", [
    ("CALL NOPE\n", 1, r"no subroutine DFS NOPE in this program \(have none\)"),
    ("CALL R\nDFS R\nCALL R\nENDDFS\n", 3, r"nested deeper than 64 \(MAX_CALL_DEPTH"),
])
def test_call_errors(text, line, match):
    with pytest.raises(GCodeError, match=match) as info:
        run(text)
    assert info.value.line == line


@pytest.mark.parametrize("text, line, match", [
    ("DFS A\nENDDFS\nDFS a\nENDDFS\n", 4, "defined twice"),
    ("REPEAT 2\nDFS A\nENDDFS\nEND REPEAT\n", 2, "DFS inside REPEAT"),
    ("ENDDFS\n", 1, "ENDDFS without DFS"),
    ("CALL A P\n", 1, "needs a value"),
    ("CALL A 3\n", 1, "letter words"),
])
def test_subroutine_structure_errors(text, line, match):
    with pytest.raises(GCodeError, match=match) as info:
        parse(text)
    assert info.value.line == line


# -- dwells ------------------------------------------------------------------------------
def test_dwells_are_counted_in_the_time():
    text = ("SECONDS\nF0.5\nG4 P 50\nG01 X1\nPSOCONTROL X FIRE\nDWELL 0.25\nG04 P0.5\n"
            "PSOCONTROL X OFF\n$t = 2\nDWELL $t/4\n")
    prog = parse(text)
    assert isinstance(prog.body[5], Dwell)
    tp = interpret(prog)
    s = tp.summary()
    assert tp.dwells == [(50.0, False, 3), (0.25, True, 6), (0.5, True, 7), (0.5, False, 10)]
    assert s["dwells"] == 4 and s["dwell_time_s"] == 51.25
    assert s["time_s"] == 51.25 + 1 / 0.5
    assert s["beam_on_time_s"] == 0.75                      # the beam fired while dwelling
    # a dwell is in seconds whatever the feed time base
    assert run("MINUTES\nDWELL 3\n").summary()["time_s"] == 3.0


def test_dwells_count_as_moves_and_outputs_are_bounded(monkeypatch):
    import gcode.interpreter as interpreter

    located("F1\nREPEAT 10\nG01 X1\nDWELL 0.1\nEND REPEAT\n", 4, 1, "DWELL 0.1",
            r"more than 15 moves and dwells \(max_segments = 15\)",
            limits=Limits(max_segments=15))
    monkeypatch.setattr(interpreter, "MAX_IO_NAMES", 5)
    located("$i = 0\nREPEAT 10\n$DO[$i].X = 1\n$i = $i + 1\nEND REPEAT\n", 3, 1,
            "$DO[$i].X = 1", r"more than 5 different outputs")


@pytest.mark.parametrize("text, match", [
    ("G4", "G4 needs P"), ("G1 P2", "P is the dwell time of G4"),
    ("G4 P1 X2", "no axis words"), ("DWELL -1", "must be ≥ 0"), ("G4 P-0.5", "must be ≥ 0"),
    ("DWELL", "needs a time"),
])
def test_dwell_errors(text, match):
    with pytest.raises(GCodeError, match=match) as info:
        run(text)
    assert info.value.line == 1


# -- statements that move nothing, and moves that cannot be simulated --------------------
@pytest.mark.parametrize("text, kind", [
    ("VELOCITY ON", "VELOCITY ON"), ("ROUNDING OFF", "ROUNDING OFF"), ("G359", "G359"),
    ("G108", "G108"), ("Critical Start", "CRITICAL START"), ("CRITICAL END", "CRITICAL END"),
    ("FILECLOSE $fileHandle", "FILECLOSE"), ('FILEWRITE $h "x; y"', "FILEWRITE"),
    ('MSGDISPLAY 1, "layer ", $n', "MSGDISPLAY"), ("WAIT MOVEDONE X Y", "WAIT MOVEDONE"),
    ("FREERUN A 0.5", "FREERUN"), ("FREERUN A STOP", "FREERUN"), ('$name = "abc"', "STRING"),
    ("FREERUN X 10", "FREERUN"), ('PROGRAM 1 RUN "other.pgm"', "PROGRAM RUN"),
    ("PROGRAM PAUSE", "PROGRAM PAUSE"), ("PROGRAM STOP", "PROGRAM STOP"),
    ("WAIT ((TASKSTATUS(1, DATAITEM_TaskState) == TASKSTATE_Idle)) -1", "WAIT"),
    ("G66", "G66"), ('$s = "x = " + DBLTOSTR(1.25, 3)', "STRING"),
    ("$s = DBLTOSTR(1.5, 2)", "STRING"), ('$s = FORMAT("%f", DBLV 1)', "STRING"),
    ('FARCALL "test.pgm"', "FARCALL"), ("$z = AXISSTATUS(Z, DATAITEM_PositionCommand)", "STATUS"),
])
def test_no_motion_statements_are_parsed_and_reported(text, kind):
    tp = run(f"F1\n{text}\nG01 X1\n")
    assert len(tp.segments) == 1 and tp.warnings == []
    (rec,) = tp.no_motion
    assert (rec["line"], rec["statement"], rec["kind"], rec["executed"]) == (2, text, kind, 1)


def test_reading_inputs_is_refused_and_arm_fires():
    with pytest.raises(GCodeError, match="reading an input") as info:
        parse("WHILE $DI[0].X == 0\nENDWHILE\n")
    assert (info.value.line, info.value.column, info.value.text) == (1, 7, "$DI")
    tp = run("F1\nPSOCONTROL X ARM\nG01 X2\nPSOCONTROL X OFF\nG01 X3\n")
    assert [s.beam for s in tp.segments] == [True, False]


def test_units_and_time_codes():
    tp = run("G70\nF1\nG01 X1\nG71\nG75\nG01 X2\n")
    assert tp.segments[0].end == (25.4, 0.0)
    # F1 was given in inches per second: 25.4 mm per time unit, now minutes
    assert tp.segments[1].feed == pytest.approx(25.4 / 60, rel=1e-15)


@pytest.mark.parametrize("text, match", [
    ("HOME X Y", "HOME moves axes"),
    ("MOVEINC X 1 10", "MOVEINC moves axes"),
])
def test_moves_that_cannot_be_simulated_are_errors_in_every_mode(text, match):
    for lenient in (False, True):
        with pytest.raises(GCodeError, match=match) as info:
            parse(f"G90\n{text}\n", lenient=lenient)
        assert info.value.line == 2


def test_program_end_words():
    for end in ("M2", "M02", "M30", "N10 M30"):
        prog = parse(f"F1\nG01 X1\n{end}\nG01 X2\n")
        assert isinstance(prog.body[2], Mode) and prog.body[2].keyword == "END"
        assert len(interpret(prog).segments) == 1


# -- Ensemble ------------------------------------------------------------------------------
@pytest.mark.parametrize("text, line, col, what", [
    ("HEADER\n  DEFINE SPEED 10\nEND HEADER\nPROGRAM\n  G1 X1\nEND PROGRAM\n", 1, 1, "HEADER"),
    ("' an Ensemble program\nPROGRAM\nG1 X1\nEND PROGRAM\n", 2, 1, "PROGRAM"),
    ("  DIM speed AS DOUBLE\n", 1, 3, "DIM speed AS"),
    ("dim pts(10) as double\n", 1, 1, "dim pts(10) as"),
])
def test_ensemble_is_refused_naming_the_dialect(text, line, col, what):
    for lenient in (False, True):
        with pytest.raises(GCodeError, match="this is Ensemble AeroBasic, not A3200") as info:
            parse(text, lenient=lenient)
        assert (info.value.line, info.value.column, info.value.text) == (line, col, what)


def test_apostrophe_comments_and_end_program_are_a3200_too():
    tp = run("' set-up\nF1 ' feed\nG01 X1\nEND PROGRAM\n")
    assert len(tp.segments) == 1


# -- lenient mode lists every warning ----------------------------------------------------
def test_every_warning_counted_is_listed(tmp_path, capsys):
    text = "F1\n" + "SPINDLE ON\n" * 53 + "G01 X1\n"
    res = laser_check(text, lenient=True)
    out = res.summary()
    assert out["warnings_total"] == 53 == len(out["warnings"])
    assert out["toolpath"]["warnings"] == 53
    prog = tmp_path / "p.pgm"
    prog.write_text(text)
    assert main(["gcode", "check", str(prog), "--lenient"]) == 0
    assert capsys.readouterr().out.count("warning: line") == 53


def test_gcode_check_reports_no_motion_statements(tmp_path, capsys):
    prog = tmp_path / "p.pgm"
    prog.write_text("F1\n$DO[0].X = 1\nG359\nG01 X1\nG4 P2\n$DO[0].X = 0\n")
    assert main(["gcode", "check", str(prog)]) == 0
    text = capsys.readouterr().out
    assert "no motion: line 2: $DO[0].X = 1 — sets $DO[0].X = 1 (executed 1×)" in text
    assert "no motion: line 3: G359 — wait mode: no wait (G359)" in text
    assert "dwells: 1, 2.000 s (in the time)" in text
    assert main(["gcode", "check", str(prog), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["line"] for r in out["no_motion"]] == [2, 3, 6]
    assert out["io"] == {"$DO[0].X": 0.0}
    assert out["toolpath"]["time_s"] == 3.0


# -- fuzzing the new statements ----------------------------------------------------------
VOCABULARY = ["#define A 1", "#define", "#undef A", "#include", "A", "WHILE", "ENDWHILE",
              "END WHILE", "IF", "THEN", "ELSEIF", "ELSE", "ENDIF", "END IF", "DFS", "ENDDFS",
              "CALL", "S", "P1", "Q", "DWELL", "G4", "P", "FREERUN", "HOME", "VELOCITY ON",
              "ROUNDING", "Critical Start", "FILECLOSE", '"s;"', '"', "$DO[0].X", "$DO0.0", "[",
              "]", ".", "<", "<=", "==", "<>", "=", "AND", "OR", "NOT", "M2", "M30", "END PROGRAM",
              "HEADER", "DIM", "AS", "'", "G1", "X1", "F1", "$a", "1", "-", "(", ")", "\n", "\n",
              "\n", " ", "G359", "DVAR", ","]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(VOCABULARY), max_size=40), st.booleans())
def test_new_statements_parse_run_or_raise_gcode_error(tokens, spaced):
    text = (" " if spaced else "").join(tokens)
    limits = Limits(max_statements=2000, max_operations=20_000, max_segments=500)
    for lenient in (False, True):
        try:
            prog = parse(text, lenient=lenient)
        except GCodeError as err:
            assert isinstance(err.line, int) and isinstance(err.column, int)
            continue
        try:
            tp = interpret(prog, limits=limits)
        except GCodeError:
            continue
        s = tp.summary()
        assert math.isfinite(s["time_s"]) and s["time_s"] >= s["dwell_time_s"] >= 0
        assert s["warnings"] == len(prog.warnings) + sum("collapses" in w for w in tp.warnings)


def test_while_and_if_nodes():
    prog = parse("WHILE $i < 2 DO\n$i = $i + 1\nENDWHILE\nIF NOT $i THEN\nELSE\nENDIF")
    w, i = prog.body
    assert isinstance(w, While) and w.cond == Compare("<", Var("i"), Num(2))
    assert isinstance(i, If) and i.branches == ((Not(Var("i")), ()), (None, ()))


# -- issue 27: string functions, FOR, G84, status reads ------------------------------------
@pytest.mark.parametrize("expr, value", [
    ('"row " + DBLTOSTR(2, 0)', "row 2"), ("DBLTOSTR(0.25, 3)", "0.250"),
    ("DBLTOSTR(-1.5, 0)", "-2"), ('STRUPR("ab" + "c")', "ABC"), ('STRLWR("AbC")', "abc"),
    ("DBLTOSTR($x * 2, 2)", "2.50"), ('"" + ""', ""),
])
def test_string_functions_are_evaluated(expr, value):
    tp = run(f"DVAR $x $s\n$x = 1.25\n$s = {expr}\n")
    assert tp.strings == {"s": value}
    (rec,) = [r for r in tp.no_motion if r["kind"] == "STRING"]
    assert rec["effect"] == f"sets the string $s = {value!r}"


@pytest.mark.parametrize("expr, value", [
    ('STRLEN("abcd")', 4.0), ('STRLEN(DBLTOSTR(12.5, 2))', 5.0), ('STRTODBL(" 2.5e1 ")', 25.0),
    ('STRLEN("ab") + STRLEN("c")', 3.0),
])
def test_string_functions_with_numbers_set_numbers(expr, value):
    tp = run(f"$n = {expr}\nF1\nG01 X$n\n")
    assert tp.segments[0].end == (value, 0.0) and tp.strings == {}


@pytest.mark.parametrize("text, match", [
    ('$s = "a" + 1', "joins two strings"), ("$s = DBLTOSTR(1, 1.5)", "whole number 0–15"),
    ('$s = STRTODBL("x1")', "not a number"), ('$s = STRLEN(2)', "must be a string"),
    ('$s = "a"\n$t = $s * 2', "unknown variable"),
])
def test_string_errors_are_located(text, match):
    with pytest.raises(GCodeError, match=match) as info:
        run(text)
    assert info.value.line == text.count("\n") + 1


def test_for_next_loops_with_step_and_zero_passes():
    tp = run("F1\nFOR $i = 1 TO 3\nG01 X$i\nNEXT $i\nFOR $j = 10 TO 0 STEP -5\nG01 Y$j\n"
             "NEXT\nFOR $k = 2 TO 1\nG01 X99\nNEXT $k\n")
    assert [s.end for s in tp.segments] == [(1, 0), (2, 0), (3, 0), (3, 10), (3, 5), (3, 0)]
    with pytest.raises(GCodeError, match="STEP 0 never ends"):
        run("FOR $i = 0 TO 1 STEP 0\nNEXT $i\n")
    with pytest.raises(GCodeError, match="FOR without NEXT"):
        parse("FOR $i = 0 TO 1\n")
    with pytest.raises(GCodeError, match="NEXT without FOR"):
        parse("NEXT $i\n")
    with pytest.raises(GCodeError, match="needs TO"):
        parse("FOR $i = 0 1\nNEXT\n")


def test_g84_turns_the_xy_frame_and_back():
    a = math.radians(90.0)
    tp = run("F1\nG84 X Y F90\nG01 X1\nG91\nG01 Y1\nG90\nG84 X Y\nG01 X2 Y0\n")
    ends = [s.end for s in tp.segments]
    assert ends[0] == pytest.approx((math.cos(a), math.sin(a)), abs=1e-15)
    assert ends[1] == pytest.approx((-1.0, 1.0), abs=1e-15)
    assert ends[2] == (2.0, 0.0)
    assert tp.segments[0].feed == 1.0        # G84's F is the angle, not a feed
    with pytest.raises(GCodeError, match="G84 turns the XY frame"):
        run("G84 X1 Y F5\n")


def test_status_reads_make_the_variable_unknown():
    tp = run("DVAR $z\n$z = AXISSTATUS(Z, DATAITEM_ProgramPositionCommand)\n")
    assert tp.no_motion[0]["kind"] == "STATUS"
    with pytest.raises(GCodeError, match=r"unknown variable \$z"):
        run("DVAR $z\n$z = AXISSTATUS(Z, DATAITEM_ProgramPositionCommand)\nF1\nG01 Z$z\n")


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-1e6, 1e6, allow_nan=False), n=st.integers(0, 9))
def test_dbltostr_round_trips_through_strtodbl(x, n):
    """STRTODBL(DBLTOSTR(x, n)) is x to within half a unit of the n-th decimal,
    and STRLEN counts the characters DBLTOSTR wrote."""
    tp = run(f"$x = {x!r}\n$s = DBLTOSTR($x, {n})\n$y = STRTODBL($s)\n$k = STRLEN($s)\n"
             "F1\nG01 X$y Y$k\n")
    y, k = tp.segments[0].end
    assert abs(y - x) <= 0.5 * 10.0 ** -n * (1 + 1e-9) + abs(x) * 1e-15
    assert k == len(tp.strings["s"]) == len(f"{x:.{n}f}")


@settings(max_examples=60, deadline=None)
@given(a=st.integers(-20, 20), b=st.integers(-20, 20), step=st.integers(-5, 5).filter(bool))
def test_for_runs_as_many_passes_as_a_python_range(a, b, step):
    tp = run(f"$n = 0\nFOR $i = {a} TO {b} STEP {step}\n$n = $n + 1\nNEXT $i\nF1\nG01 X$n\n")
    stop = b + (1 if step > 0 else -1)
    assert tp.segments[0].end[0] == len(range(a, stop, step))
