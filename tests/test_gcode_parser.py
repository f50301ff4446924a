"""AeroBasic parser, expression evaluator and line-break restoration
(gcode.parser, gcode.expr, gcode.restore) on the thesis's Appendix C."""

import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcode.ast import Assign, BinOp, Block, Mode, Neg, Num, Program, Pso, Repeat, Span, Var
from gcode.errors import GCodeError
from gcode.expr import evaluate, to_source, variables_in
from gcode.parser import MAX_NESTING, is_statement, parse, parse_expression
from gcode.restore import restore_line_breaks, unescape_markdown

ROOT = Path(__file__).resolve().parent.parent
RAW = (ROOT / "tests" / "data" / "appendix_c_thesis.md").read_text(encoding="utf-8")
SAMPLE = (ROOT / "samples" / "appendix_c.pgm").read_text(encoding="utf-8")
HEADER = "; Appendix C of the thesis, line breaks restored by gcode.restore (ERRATA.md)\n"


def words(block):
    """``[(letter, value), …]`` of a block."""
    return [(w.letter, w.value) for w in block.words]


def only(text, **kw):
    """The single statement of a one-statement program."""
    (stmt,) = parse(text, **kw).body
    return stmt


def raises_at(text, line, column, snippet, match=None):
    with pytest.raises(GCodeError, match=match) as info:
        parse(text)
    err = info.value
    assert (err.line, err.column, err.text) == (line, column, snippet), str(err)
    return err


# -- Appendix C ------------------------------------------------------------------------
def test_sample_is_the_restored_appendix():
    assert SAMPLE.startswith(HEADER)
    assert SAMPLE[len(HEADER):] == restore_line_breaks(RAW)
    assert restore_line_breaks(SAMPLE) == SAMPLE          # idempotent
    assert "\\$" not in SAMPLE and "$radius" in SAMPLE


@pytest.fixture(scope="module")
def appendix():
    return parse(SAMPLE)


def test_appendix_top_level(appendix):
    body = appendix.body
    assert appendix.warnings == ()
    kinds = [type(s).__name__ for s in body]
    assert kinds == ["DVar", "Mode"] + ["Assign"] * 10 + ["Block"] * 6 + ["Pso", "Repeat",
                                                                          "Block"]
    assert body[0].names == ("feed", "overlap", "pulse_time", "passover", "pass2", "radius",
                             "beam_dia", "overlap_r", "dist_r", "comp", "radius_i", "comp_i")
    assert body[0].span == Span(3, 1, SAMPLE.splitlines()[2])
    assert body[1] == Mode("SECONDS", (), Span(4, 1, "SECONDS"))
    assigns = {s.name: s.expr for s in body[2:12]}
    assert list(assigns) == ["beam_dia", "radius_i", "comp_i", "radius", "comp", "overlap_r",
                             "dist_r", "passover", "pass2", "feed"]
    assert assigns["dist_r"] == BinOp("*", BinOp("-", Num(1), Var("overlap_r")), Var("beam_dia"))
    assert assigns["passover"] == BinOp("/", Num(0.02), Var("dist_r"))
    assert assigns["pass2"] == Num(80) and assigns["feed"] == Num(0.1)
    env = {}
    for stmt in body[2:12]:
        env[stmt.name] = evaluate(stmt.expr, env, span=stmt.span)
    assert env["dist_r"] == pytest.approx(0.001)
    assert env["passover"] == pytest.approx(20.0)
    g92, g92c, t0, g44, t1, g91 = body[12:18]
    assert words(g92) == [("G", Num(92)), ("X", Num(-0.05)), ("Y", Num(-0.05))]
    assert g92.span == Span(15, 1, "G92 X-0.05 Y-0.05")
    assert words(g92c) == [("G", Num(92)), ("C", Num(0))]
    assert words(t0) == [("T", Num(0))] and words(t1) == [("T", Num(1))]
    assert words(g44) == [("G", Num(44)), ("X", None), ("Y", None)]
    assert [w.span for w in g44.words] == [Span(18, 1, "G44"), Span(18, 5, "X"),
                                           Span(18, 7, "Y")]
    assert words(g91) == [("G", Num(91))]
    assert body[18] == Pso("PSOPULSE", "X", ("TIME", Num(10), Num(5), "CYCLES", Num(1e7)),
                           Span(21, 1, "PSOPULSE X TIME 10 5 CYCLES 10000000"))
    assert words(body[20]) == [("T", Num(0))]


def test_appendix_repeats(appendix):
    outer = appendix.body[19]
    assert isinstance(outer, Repeat) and outer.count == Num(16)
    assert outer.span == Span(22, 1, "REPEAT 16")
    first, pso, second, g98, linear = outer.body
    assert first.count == Var("passover") and second.count == Var("pass2")
    assert pso.args == ("TIME", Num(10), Num(5), "CYCLES", Num(1e7))
    assert [type(s).__name__ for s in first.body] == (
        ["Pso"] + ["Block"] * 3 + ["Pso"] + ["Block"] * 3 + ["Assign"] * 2)
    fire, g41, g1, g03, off, g1b, g40, g0, rad, comp = first.body
    assert fire == Pso("PSOCONTROL", "X", ("FIRE",), fire.span) and off.args == ("OFF",)
    assert words(g41) == [("G", Num(1)), ("G", Num(41)), ("X", Var("comp")), ("F", Var("feed"))]
    assert words(g1) == [("G", Num(1)), ("Y", Num(0.05))]
    assert words(g03) == [("G", Num(3)), ("X", Neg(BinOp("*", Var("radius"), Num(2)))),
                          ("Y", Num(0)), ("I", Neg(Var("radius"))), ("J", Num(0))]
    assert g03.span.text == "G03 X-($radius*2) Y0 I-$radius J0"
    assert [w.span.text for w in g03.words] == ["G03", "X-($radius*2)", "Y0", "I-$radius", "J0"]
    assert words(g1b) == [("G", Num(1)), ("Y", Num(-0.05))]
    assert words(g40) == [("G", Num(40)), ("X", Var("comp"))]
    assert words(g0) == [("G", Num(0)), ("X", BinOp("-", BinOp("*", Num(2), Var("radius_i")),
                                                     BinOp("*", Num(2), Var("comp_i"))))]
    assert rad == Assign("radius", BinOp("-", Var("radius"), Var("dist_r")), rad.span)
    assert comp.name == "comp"
    assert len(second.body) == 8 and words(second.body[3])[1] == (
        "X", Neg(BinOp("*", Var("radius_i"), Num(2))))
    assert words(g98) == [("G", Num(98))]
    assert isinstance(linear, Block) and linear.keywords == ("LINEAR",)
    assert words(linear) == [("Y", Num(0)), ("C", Num(22.5)), ("F", Num(1)), ("E", Num(5))]
    assert linear.span.text == "LINEAR Y 0.0 C22.5 F1.0 E 5"


# -- restoration -----------------------------------------------------------------------
@pytest.mark.parametrize("raw, lines", [
    (r"\$passover= 0.020/\$dist_R; \$pass2= 80; 60",
     ["$passover= 0.020/$dist_R ;", "$pass2= 80 ; 60"]),
    ("G92 X-0.05 Y-0.05 ; set zero G92 C0", ["G92 X-0.05 Y-0.05 ; set zero", "G92 C0"]),
    ("G01 G41 X$comp F $feed ; G1 Y0.05 ; G03 X-($radius*2) Y0 I-$radius J0 ;",
     ["G01 G41 X$comp F $feed ;", "G1 Y0.05 ;", "G03 X-($radius*2) Y0 I-$radius J0 ;"]),
    ("G1 Y -0.05 G40 X$comp G0 X (2*$radius_i-2*$comp_i) $radius = $radius - $dist_R "
     "$comp = $comp - $dist_R",
     ["G1 Y -0.05", "G40 X$comp", "G0 X (2*$radius_i-2*$comp_i)", "$radius = $radius - $dist_R",
      "$comp = $comp - $dist_R"]),
    ("G98 LINEAR Y 0.0 C22.5 F1.0 E 5", ["G98", "LINEAR Y 0.0 C22.5 F1.0 E 5"]),
    ("REPEAT 16 ; Make serrations all around the circumference",
     ["REPEAT 16 ; Make serrations all around the circumference"]),
    ("T1; load the laser beam: tool table available from CNC operator interface,",
     ["T1 ; load the laser beam: tool table available from CNC operator interface,"]),
    ("PSOPULSE X TIME 10 5 CYCLES 10000000; original 40 20 REPEAT 3 ; x END REPEAT",
     ["PSOPULSE X TIME 10 5 CYCLES 10000000 ; original 40 20", "REPEAT 3 ; x", "END REPEAT"]),
    ("G44 X Y ; activate possible compensation on x and y axe T0",
     ["G44 X Y ; activate possible compensation on x and y axe", "T0"]),
    ("; END OF PROGRAM G1 is fast", ["; END OF PROGRAM G1 is fast"]),
    ("dvar \\$a, \\$b SECONDS \\$a = 1 // c \\$b = 2", ["dvar $a, $b", "SECONDS", "$a = 1 // c",
                                                        "$b = 2"]),
    ("\n\n  \n", []),
])
def test_restore_examples(raw, lines):
    out = restore_line_breaks(raw)
    assert out.splitlines() == lines
    assert restore_line_breaks(out) == out
    assert all(is_statement(line) or line.startswith(";") for line in lines)


def test_unescape_markdown():
    assert unescape_markdown(r"\$a = 1 \* 2 \\ x") == r"$a = 1 * 2 \ x"


# -- words, statements, spans ----------------------------------------------------------
@pytest.mark.parametrize("text, expected", [
    ("G1 X$comp", ("X", Var("comp"))),
    ("G1 F $feed", ("F", Var("feed"))),
    ("G1 Y -0.05", ("Y", Num(-0.05))),
    ("G1 Y- 0.05", ("Y", Num(-0.05))),
    ("G1 X-0.05", ("X", Num(-0.05))),
    ("G1 X+0.5", ("X", Num(0.5))),
    ("G1 C22.5", ("C", Num(22.5))),
    ("G1 F1.0", ("F", Num(1.0))),
    ("G1 X1e-3", ("X", Num(0.001))),
    ("G1 X.5", ("X", Num(0.5))),
    ("G1 X1.", ("X", Num(1.0))),
    ("G1 E 5", ("E", Num(5))),
    ("G1 X-($radius*2)", ("X", Neg(BinOp("*", Var("radius"), Num(2))))),
    ("G1 I-$radius", ("I", Neg(Var("radius")))),
    ("G1 X--1", ("X", Neg(Num(-1)))),
    ("G0 X (2*$radius_i-2*$comp_i)",
     ("X", BinOp("-", BinOp("*", Num(2), Var("radius_i")), BinOp("*", Num(2), Var("comp_i"))))),
])
def test_word_forms(text, expected):
    assert words(only(text))[1] == expected


def test_glued_block_and_spans():
    block = only("  G1X1Y-2 F$feed ; comment")
    assert words(block) == [("G", Num(1)), ("X", Num(1)), ("Y", Num(-2)), ("F", Var("feed"))]
    assert block.span == Span(1, 3, "G1X1Y-2 F$feed")
    assert [w.span for w in block.words] == [Span(1, 3, "G1"), Span(1, 5, "X1"),
                                             Span(1, 7, "Y-2"), Span(1, 11, "F$feed")]


def test_bare_words_and_keywords():
    block = only("G44 X Y")
    assert words(block) == [("G", Num(44)), ("X", None), ("Y", None)]
    block = only("linear Y0 c22.5 f1.0 E 5")
    assert block.keywords == ("LINEAR",)
    assert only("G2 CW X1 Y1 I1 J0").keywords == ("CW",)
    assert [w.letter for w in only("RAPID Z1 A2 B3 K1").words] == ["Z", "A", "B", "K"]


def test_case_insensitive():
    prog = parse("DVAR $Feed $COMP\ng01 g41 x$Comp f $FEED\nseconds\nenable x, y\n"
                 "psoControl x Fire\nrepeat $Feed\nend repeat\n$Feed = 2\nEnd")
    dvar, block, sec, enable, pso, rep, assign, end = prog.body
    assert dvar.names == ("feed", "comp")
    assert words(block) == [("G", Num(1)), ("G", Num(41)), ("X", Var("comp")), ("F", Var("feed"))]
    assert sec.keyword == "SECONDS" and enable == Mode("ENABLE", ("X", "Y"), enable.span)
    assert (pso.command, pso.axis, pso.args) == ("PSOCONTROL", "X", ("FIRE",))
    assert rep.count == Var("feed") and rep.body == ()
    assert assign.name == "feed" and end == Mode("END", (), Span(9, 1, "End"))


def test_comments_blank_lines_and_line_numbers():
    prog = parse("// header\n\n   \nG90 // absolute\n;only\nN10 G1 X1 ; c\nN20\n$a=1//2")
    g90, g1, assign = prog.body
    assert g90.span == Span(4, 1, "G90")
    assert words(g1) == [("G", Num(1)), ("X", Num(1))] and g1.span == Span(6, 1, "N10 G1 X1")
    assert assign.expr == Num(1)


def test_modes_and_pso():
    for kw in ("SECONDS", "MINUTES", "METRIC", "ENGLISH", "ABSOLUTE", "INCREMENTAL", "END"):
        assert only(kw) == Mode(kw, (), Span(1, 1, kw))
    assert only("PSOOUTPUT X CONTROL 1 0").args == ("CONTROL", Num(1), Num(0))
    assert only("PSODISTANCE X FIXED ($a*2), 3").args == ("FIXED", BinOp("*", Var("a"), Num(2)),
                                                          Num(3))
    assert only("PSOWINDOW X 1 RANGE -1 1").args == (Num(1), "RANGE", Num(-1), Num(1))
    assert only("PSOTRACK X RESET 0").command == "PSOTRACK"


def test_nested_repeats_and_endrepeat():
    prog = parse("REPEAT 2\n  REPEAT 3\n    G1 X1\n  ENDREPEAT\n  G1 Y1\nEND   REPEAT\nG0 X0")
    outer, g0 = prog.body
    inner, g1y = outer.body
    assert outer.count == Num(2) and inner.count == Num(3) and len(inner.body) == 1
    assert inner.span == Span(2, 3, "REPEAT 3") and words(g1y)[1] == ("Y", Num(1))
    assert words(g0) == [("G", Num(0)), ("X", Num(0))]


@pytest.mark.parametrize("code", ["0", "00", "1", "01", "2", "02", "3", "03", "4", "17", "40",
                                  "41", "42", "44", "70", "71", "75", "76", "90", "91", "92",
                                  "98", "108", "109", "359", "360", "361"])
def test_allowed_g_codes(code):
    assert words(only(f"G{code}"))[0] == ("G", Num(float(int(code))))


# -- expressions -----------------------------------------------------------------------
@pytest.mark.parametrize("text, value", [
    ("2+3*4", 14.0), ("-(1-3)*2", 4.0), ("1/4/2", 0.125), ("10-4-3", 3.0), ("(2+3)*4", 20.0),
    ("-2*-3", 6.0), ("+-+2", -2.0), ("2*$a+$b/4", 2 * 1.5 + 0.5), ("1e-3*1000", 1.0),
])
def test_expression_values(text, value):
    assert evaluate(parse_expression(text), {"a": 1.5, "b": 2.0}) == pytest.approx(value)


def test_expression_helpers():
    expr = parse_expression("-($radius*2) + 3 / (1 - $b)")
    assert variables_in(expr) == {"radius", "b"}
    assert to_source(expr) == "-($radius * 2) + 3 / (1 - $b)"
    assert parse_expression(to_source(expr)) == expr


def test_evaluate_errors():
    prog = parse("G1 X0\n  $a = 1/($b-$b)\nG1 X$nope")
    assign = prog.body[1]
    with pytest.raises(GCodeError, match="division by zero") as info:
        evaluate(assign.expr, {"b": 2.0}, span=assign.span)
    assert (info.value.line, info.value.column, info.value.text) == (2, 3, "$a = 1/($b-$b)")
    word = prog.body[2].words[1]
    with pytest.raises(GCodeError, match=r"unknown variable \$nope") as info:
        evaluate(word.value, {"a": 1.0}, span=word.span)
    assert (info.value.line, info.value.column, info.value.text) == (3, 4, "X$nope")
    with pytest.raises(GCodeError, match="unknown variable \\$x"):
        evaluate(Var("x"), {})
    with pytest.raises(GCodeError, match="out of range"):
        evaluate(parse_expression("1e300*1e300"), {})
    with pytest.raises(GCodeError, match="not finite"):
        evaluate(Var("a"), {"a": math.inf})


# -- errors ----------------------------------------------------------------------------
def test_unknown_g_code():
    err = raises_at("G1 X0\n  G18 X1", 2, 3, "G18", "unsupported G code")
    assert "line 2, column 3" in str(err)
    raises_at("G1 G 5", 1, 4, "G 5", "unsupported G code")
    raises_at("G1.5", 1, 1, "G1.5", "unsupported G code")
    raises_at("G$a", 1, 1, "G$a", "plain number")
    raises_at("G X1", 1, 1, "G", "plain number")


def test_unsupported_words_and_keywords():
    raises_at("G1 X1 M3", 1, 7, "M3", "M words")
    raises_at("M3", 1, 1, "M3", "M words other than M2 and M30")
    raises_at("M2 X1", 1, 1, "M2", "must stand alone")
    raises_at("G1 S100", 1, 4, "S100", "S words")
    raises_at("G0\nWAITFOR 100", 2, 1, "WAITFOR", "unknown keyword")
    raises_at("G1 XY", 1, 4, "XY", "unknown keyword")
    raises_at("G1 X1 # 3", 1, 7, "#", "unexpected character")


def test_syntax_errors():
    raises_at("$a = 1.2.3", 1, 6, "1.2.3", "malformed number")
    raises_at("G1 X1..2", 1, 5, "1..2", "malformed number")
    raises_at("G1 X1e5.3", 1, 5, "1e5.3", "malformed number")
    raises_at("G1 X1e999", 1, 5, "1e999", "out of range")
    raises_at("$a = (1+2", 1, 6, "(", "never closed")
    raises_at("G1 X-($r*2", 1, 6, "(", "never closed")
    raises_at("$a = 1+2)", 1, 9, ")", "unbalanced")
    raises_at("G1 X1)", 1, 6, ")", "unbalanced")
    raises_at("$a = 2 *", 1, 8, "*", "expected a value")
    raises_at("$a = ", 1, 4, "=", "expected an expression")
    raises_at("$a 3", 1, 4, "3", "expected '='")
    raises_at("$a = 1 2", 1, 8, "2", "unexpected")
    raises_at("$ = 1", 1, 1, "$", "variable name")
    raises_at("G1 F", 1, 4, "F", "needs a value")
    raises_at("12 G1", 1, 1, "12", "expected a statement")
    raises_at("DVAR", 1, 1, "DVAR", "at least one")
    raises_at("SECONDS 3", 1, 9, "3", "unexpected")
    raises_at("PSOCONTROL FIRE", 1, 12, "FIRE", "axis")
    raises_at("G1 N10 X1", 1, 4, "N10", "line number")


def test_repeat_structure_errors():
    raises_at("G1\nREPEAT 3\nG1 X1", 2, 1, "REPEAT 3", "without END REPEAT")
    raises_at("REPEAT 2\n REPEAT 3\nEND REPEAT", 1, 1, "REPEAT 2", "without END REPEAT")
    raises_at("REPEAT 2\n REPEAT 3\n", 2, 2, "REPEAT 3", "without END REPEAT")  # innermost
    raises_at("G1\n  END REPEAT ; done", 2, 3, "END REPEAT", "without REPEAT")
    raises_at("ENDREPEAT", 1, 1, "ENDREPEAT", "without REPEAT")
    raises_at("REPEAT", 1, 1, "REPEAT", "needs a count")
    raises_at("REPEAT 2\nEND REPEAT X", 2, 12, "X", "unexpected")


def test_lenient_skips_unsupported_statements():
    text = "G1 X1\nM3 S100\n  G18\nSPINDLE ON\nG1 X3"
    prog = parse(text, lenient=True)
    assert [words(b)[1] for b in prog.body] == [("X", Num(1)), ("X", Num(3))]
    assert len(prog.warnings) == 3
    assert "line 2, column 1" in prog.warnings[0] and "M3" in prog.warnings[0]
    assert "line 3, column 3" in prog.warnings[1] and "G18" in prog.warnings[1]
    assert "line 4, column 1" in prog.warnings[2] and "SPINDLE" in prog.warnings[2]
    with pytest.raises(GCodeError):
        parse(text)
    # a move that cannot be evaluated is never skipped, not even in lenient mode
    for move, col, what in [("G1 X2 WAITFOR", 7, "WAITFOR"), ("G01 Z Tip_Plate_Distance", 7,
                                                             "Tip_Plate_Distance"),
                            ("G18 X1", 1, "G18"), ("LINEAR Y1 S3", 11, "S3")]:
        with pytest.raises(GCodeError, match="error even in lenient mode") as info:
            parse(f"G1 X1\n{move}\n", lenient=True)
        assert (info.value.line, info.value.column, info.value.text) == (2, col, what)
    with pytest.raises(GCodeError, match="malformed"):       # syntax errors still raise
        parse("G1 X1.2.3", lenient=True)
    with pytest.raises(GCodeError, match="unexpected character"):  # structure is never skipped
        parse("REPEAT 2 %\nEND REPEAT", lenient=True)


# -- bounds ----------------------------------------------------------------------------
def test_deep_parentheses():
    with pytest.raises(GCodeError, match="nested deeper") as info:
        parse("$a = " + "(" * 500 + "1" + ")" * 500)   # within MAX_LINE_TOKENS
    assert (info.value.line, info.value.column, info.value.text) == (1, 6 + MAX_NESTING, "(")
    with pytest.raises(GCodeError, match="nested deeper"):
        parse("G1 X" + "(" * 1000)
    ok = "(" * MAX_NESTING + "1" + ")" * MAX_NESTING
    assert evaluate(parse_expression(ok), {}) == 1.0


def test_long_chains_and_many_statements():
    with pytest.raises(GCodeError, match="deeper than"):
        parse("$a = " + "-" * 1000 + "1")
    with pytest.raises(GCodeError, match="deeper than"):
        parse("$a = " + "1+" * 500 + "1")
    assert evaluate(parse_expression("1+" * 150 + "1"), {}) == 151.0
    with pytest.raises(GCodeError, match="REPEAT nested deeper") as info:
        parse("REPEAT 2\n" * 100 + "END REPEAT\n" * 100)
    assert info.value.line == MAX_NESTING + 1
    with pytest.raises(GCodeError, match="more than 3 statements") as info:
        parse("G1\nG1\n\nG1\nG1 X4\nG1", max_statements=3)
    assert (info.value.line, info.value.column, info.value.text) == (5, 1, "G1 X4")
    assert len(parse("G1 X1\n" * 20_000).body) == 20_000


# -- property tests --------------------------------------------------------------------
def parses_or_gcode_error(text, **kw):
    try:
        prog = parse(text, **kw)
    except GCodeError as err:
        assert isinstance(err.line, int) and isinstance(err.column, int)
        assert isinstance(err.text, str)
        return None
    assert isinstance(prog, Program)
    return prog


FAST = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FAST
@given(st.text())
def test_any_text_parses_or_raises_gcode_error(text):
    parses_or_gcode_error(text)
    parses_or_gcode_error(text, lenient=True)
    assert isinstance(is_statement(text), bool)
    restored = restore_line_breaks(text)
    assert isinstance(restored, str)


VOCABULARY = ["G1", "G01", "G 2", "G03", "G17", "G41", "G44", "G92", "G98", "X", "Y", "Z", "X-",
              "F", "E", "I", "J", "T1", "M3", "N10", "0", "1.5", "-0.05", ".5", "1e-3", "1.2.3",
              "$a", "$radius", "$", "=", "+", "-", "*", "/", "(", ")", ",", "REPEAT",
              "END REPEAT", "ENDREPEAT", "END", "DVAR", "SECONDS", "ENABLE", "LINEAR", "CW",
              "PSOPULSE", "PSOCONTROL", "FIRE", "TIME", "; comment", "// c", ";", "\n", "\n",
              "\n", " ", "\t", "é", "%"]


@FAST
@given(st.lists(st.sampled_from(VOCABULARY), max_size=40), st.booleans())
def test_token_soup_parses_or_raises_gcode_error(tokens, spaced):
    text = (" " if spaced else "").join(tokens)
    prog = parses_or_gcode_error(text)
    lenient = parses_or_gcode_error(text, lenient=True)
    if prog is not None:
        assert lenient == prog
    restored = restore_line_breaks(text)
    assert restore_line_breaks(restored) == restored


VARIABLES = {"a": 1.5, "radius": 0.15, "comp_i": -0.05, "z": 0.0}

leaves = st.one_of(
    st.floats(min_value=0, max_value=1e6, allow_nan=False, allow_infinity=False).map(Num),
    st.sampled_from(sorted(VARIABLES)).map(Var),
)
expressions = st.recursive(
    leaves,
    lambda sub: st.one_of(sub.map(Neg),
                          st.tuples(st.sampled_from("+-*/"), sub, sub).map(lambda t: BinOp(*t))),
    max_leaves=25,
)


def reference(expr):
    """Direct evaluation with Python arithmetic (None when undefined)."""
    if isinstance(expr, Num):
        return expr.value
    if isinstance(expr, Var):
        return VARIABLES[expr.name]
    if isinstance(expr, Neg):
        value = reference(expr.operand)
        return None if value is None else -value
    left, right = reference(expr.left), reference(expr.right)
    if left is None or right is None or (expr.op == "/" and right == 0):
        return None
    value = {"+": left + right, "-": left - right, "*": left * right}.get(expr.op)
    value = left / right if value is None else value
    return value if math.isfinite(value) else None


def loose_source(expr):
    """Fully parenthesised source, spaced differently from to_source."""
    if isinstance(expr, Num):
        return repr(expr.value)
    if isinstance(expr, Var):
        return f"${expr.name.upper()}"
    if isinstance(expr, Neg):
        return f"-({loose_source(expr.operand)})"
    return f"({loose_source(expr.left)}{expr.op}{loose_source(expr.right)})"


@settings(max_examples=300, deadline=None)
@given(expressions)
def test_print_parse_evaluate_round_trip(expr):
    expected = reference(expr)
    for source in (to_source(expr), loose_source(expr)):
        parsed = parse_expression(source)
        assert variables_in(parsed) == variables_in(expr)
        stmt = only(f"$out = {source}")
        if expected is None:
            with pytest.raises(GCodeError):
                evaluate(parsed, VARIABLES)
        else:
            assert evaluate(parsed, VARIABLES) == expected
            assert evaluate(stmt.expr, VARIABLES, span=stmt.span) == expected
