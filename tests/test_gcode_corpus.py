"""A corpus of A3200 programs in the styles people write (issue 16).

Each program under ``tests/data/a3200/`` was written for this test (none is
copied from elsewhere); its expected totals — moves, XYZ path length, time
with its dwells, beam-on length and time, statements that move nothing — are
derived by hand below from the program text, in closed form. Rapids (G0) are
timed at the interpreter's default 10 mm/s; feeds are mm/s (SECONDS).
"""

import json
import math
from pathlib import Path

import pytest

from gcode import GCodeError, interpret, parse
from gcode.pipeline import laser_check
from tipgeo.cli import main

CORPUS = Path(__file__).resolve().parent / "data" / "a3200"
RAPID = 10.0          # mm/s, interpret()'s default rapid_speed
REL = 1e-12           # relative tolerance: every total is a short sum of exact terms

# name: (moves, path mm, time s, dwell s, dwells, beam-on mm, beam-on s, no-motion records)
EXPECTED = {
    # 1 rapid to (-1, 0, 0.035); 5 passes of X+22 at F4 (beam on), Y+0.127 and X-22 at F10;
    # rapid from (-1, 0.635, 0.035) home. G359 and VELOCITY ON move nothing.
    "laser_waveguides": (
        17,
        math.hypot(1, 0.035) + 5 * (22 + 0.127 + 22) + math.hypot(1, 0.635, 0.035),
        (math.hypot(1, 0.035) + math.hypot(1, 0.635, 0.035)) / RAPID
        + 5 * (22 / 4 + 0.127 / 10 + 22 / 10),
        0.0, 0, 5 * 22.0, 5 * 22 / 4, 2),
    # Z 0.15 at F20; per layer 4 x (10 + 0.5 + 10 + 0.5) at F5, Z 0.2 and a 4 mm return at
    # F20, two 0.5 s dwells; Z 5 at F20. $DO[0].X (the pressure) set twice (two records).
    "diw_logpile": (
        1 + 2 * (16 + 2) + 1,
        0.15 + 2 * (4 * 21 + 0.2 + 4) + 5,
        0.15 / 20 + 2 * (4 * 21 / 5 + 0.2 / 20 + 4 / 20) + 5 / 20 + 4 * 0.5,
        2.0, 4, 0.0, 0.0, 2),
    # sides 3, 3, 2.75, 2.75, 2.5, … 1.75 (beam on, F2), then X1 at the redefined F4
    "macros_spiral": (
        13, 2 * (3 + 2.75 + 2.5 + 2.25 + 2 + 1.75) + 1,
        2 * (3 + 2.75 + 2.5 + 2.25 + 2 + 1.75) / 2 + 1 / 4,
        0.0, 0, 28.5, 14.25, 0),
    # pass 1: 2 x (X1, Y0.1); pass 2: 3 x 2 x X0.5; pass 3: rapid (-5, -0.2); all F1
    "raster_nested": (
        11, 2.2 + 3.0 + math.hypot(5, 0.2), 2.2 + 3.0 + math.hypot(5, 0.2) / RAPID,
        0.0, 0, 0.0, 0.0, 0),
    # rectangles 1 x 0.5, 2 x 1, 3 x 1.5 (beam on, F2) and rapids of 2, 3 and 5 mm
    "subroutine_rects": (
        15, 2 * (1.5 + 3 + 4.5) + 10, 2 * (1.5 + 3 + 4.5) / 2 + 10 / RAPID,
        0.0, 0, 18.0, 9.0, 0),
    # rapids through the 3 x 4 grid of pitch 0.2 and home; per hole dwells of 0.08,
    # 0.01 (beam on: 500 pulses of 20 us) and 0.02 s
    "percussion_dwells": (
        13,
        1.8 + 2 * math.hypot(0.6, 0.2) + math.hypot(0.6, 0.4),
        (1.8 + 2 * math.hypot(0.6, 0.2) + math.hypot(0.6, 0.4)) / RAPID + 12 * 0.11,
        12 * 0.11, 36, 0.0, 12 * 0.01, 0),
    # 1 in lines and half circles of 0.25 in at 6 in/min = 2.54 mm/s
    "slot_inches": (
        4, 2 * 25.4 + 2 * math.pi * 6.35, 20 + 5 * math.pi, 0.0, 0, 0.0, 0.0, 0),
    # X to 1, 2, 3 at F0.5; ten file/message/string/wait/critical statements
    "logging_nomotion": (3, 3.0, 6.0, 0.0, 0, 0.0, 0.0, 10),
    # lenient: three vendor commands skipped with a warning each, no move lost
    "lenient_extras": (3, 1 + math.hypot(0.5, 0.5), (1 + math.hypot(0.5, 0.5)) / 0.25,
                       0.0, 0, 0.0, 0.0, 0),
    # issue 27: task control (PROGRAM 1 RUN, WAIT on TASKSTATUS, PROGRAM PAUSE), ENABLE
    # X Y D U, FREERUN D twice, a DBLTOSTR string and G66 (7 records); X3 and Y4 at F2,
    # the 5 mm rapid home
    "task_control": (3, 3 + 4 + 5, 7 / 2 + 5 / RAPID, 0.0, 0, 0.0, 0.0, 7),
    # issue 27: X10, Y5 before any F at the default 5 mm/s (one warning), then X-2, Y-1 at F1
    "default_feed": (4, 18.0, 15 / 5 + 3 / 1, 0.0, 0, 0.0, 0.0, 0),
    # issue 27: 3 rows of X2 at F0.5 (beam on), each back by a rapid (-2, 0.1); FILEOPEN,
    # the DBLTOSTR string, FILEWRITE and FILECLOSE recorded (4 records)
    "string_log": (6, 3 * (2 + math.hypot(2, 0.1)), 3 * (2 / 0.5 + math.hypot(2, 0.1) / RAPID),
                   0.0, 0, 6.0, 12.0, 4),
}
LENIENT_ONLY = {"lenient_extras": 3}     # name: warnings
DEFAULT_FEED = {"default_feed": 5.0}     # name: default_feed (mm/s) it runs with
WARNINGS = {**LENIENT_ONLY, "default_feed": 1}


def test_the_corpus_is_complete():
    names = {p.stem for p in CORPUS.glob("*.pgm")}
    assert names == set(EXPECTED) | {"ensemble_refused"}
    for p in CORPUS.glob("*.pgm"):
        assert "corpus test" in p.read_text(encoding="ascii")    # written for this test


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus_totals(name):
    moves, path, time_s, dwell_s, dwells, on_mm, on_s, quiet = EXPECTED[name]
    text = (CORPUS / f"{name}.pgm").read_text()
    lenient = name in LENIENT_ONLY
    if lenient:
        with pytest.raises(GCodeError, match="unknown keyword"):
            parse(text)
    res = laser_check(text, lenient=lenient, default_feed=DEFAULT_FEED.get(name))
    s = res.toolpath.summary()
    assert s["segments"] == moves
    assert s["path_length_mm"] == pytest.approx(path, rel=REL)
    assert s["time_s"] == pytest.approx(time_s, rel=REL)
    assert s["dwell_time_s"] == pytest.approx(dwell_s, rel=REL, abs=0)
    assert s["dwells"] == dwells
    assert s["beam_on_length_mm"] == pytest.approx(on_mm, rel=REL, abs=0)
    assert s["beam_on_time_s"] == pytest.approx(on_s, rel=REL, abs=0)
    assert s["no_motion_statements"] == quiet
    out = res.summary()
    assert out["warnings_total"] == len(out["warnings"]) == WARNINGS.get(name, 0)


def test_corpus_effects():
    diw = interpret(parse((CORPUS / "diw_logpile.pgm").read_text()))
    assert diw.io == {"$DO[0].X": 0.0}
    assert [(r["line"], r["effect"], r["executed"]) for r in diw.no_motion] == [
        (22, "sets $DO[0].X = 1", 2), (39, "sets $DO[0].X = 0", 2)]
    # the log-pile's first move is the macro-named Z move the issue saw dropped
    assert diw.segments[0].z1 == 0.15 and diw.segments[0].line == 18
    log = interpret(parse((CORPUS / "logging_nomotion.pgm").read_text()))
    assert [r["kind"] for r in log.no_motion] == [
        "CRITICAL START", "FILEOPEN", "FILEWRITE", "MSGDISPLAY", "STRING", "FILEWRITE",
        "WAIT MOVEDONE", "FILECLOSE", "MSGCLEAR", "CRITICAL END"]
    assert [r["executed"] for r in log.no_motion] == [1, 1, 1, 1, 1, 3, 1, 1, 1, 1]
    holes = interpret(parse((CORPUS / "percussion_dwells.pgm").read_text()))
    assert holes.summary()["pulses"] == 6000         # 12 holes x 500 pulses
    assert (holes.pulse_period_us, holes.pulse_on_us) == (20.0, 10.0)
    spiral = parse((CORPUS / "macros_spiral.pgm").read_text())
    assert dict(spiral.macros)["FEED_MM_S"] == "4"


def test_ensemble_program_is_refused_naming_the_dialect():
    text = (CORPUS / "ensemble_refused.pgm").read_text()
    for lenient in (False, True):
        with pytest.raises(GCodeError, match="this is Ensemble AeroBasic, not A3200") as info:
            parse(text, lenient=lenient)
        assert (info.value.line, info.value.column, info.value.text) == (3, 1, "HEADER")


def test_cli_check_reports_the_corpus_totals(capsys):
    path = CORPUS / "diw_logpile.pgm"
    assert main(["gcode", "check", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    moves, length, time_s = EXPECTED["diw_logpile"][:3]
    assert out["toolpath"]["segments"] == moves
    assert out["toolpath"]["time_s"] == pytest.approx(time_s, rel=REL)
    assert [r["statement"] for r in out["no_motion"]] == ["PRESSURE = 1", "PRESSURE = 0"]
    assert main(["gcode", "check", str(CORPUS / "ensemble_refused.pgm")]) == 2
    assert "Ensemble AeroBasic" in capsys.readouterr().err


def test_task_control_strings_and_default_feed():
    """Issue 27's A3200 constructs: what each records, and the feed rules."""
    tc = interpret(parse((CORPUS / "task_control.pgm").read_text()))
    assert [(r["line"], r["kind"]) for r in tc.no_motion] == [
        (11, "PROGRAM RUN"), (12, "WAIT"), (13, "FREERUN"), (17, "STRING"), (18, "FREERUN"),
        (19, "PROGRAM PAUSE"), (21, "G66")]
    enable = parse((CORPUS / "task_control.pgm").read_text()).body[1]
    assert (enable.keyword, enable.args) == ("ENABLE", ("X", "Y", "D", "U"))
    assert [(s.end, s.feed) for s in tc.segments] == [((3.0, 0.0), 2.0), ((3.0, 4.0), 2.0),
                                                      ((0.0, 0.0), None)]
    log = interpret(parse((CORPUS / "string_log.pgm").read_text()))
    assert [(r["kind"], r["executed"]) for r in log.no_motion] == [
        ("FILEOPEN", 1), ("STRING", 3), ("FILEWRITE", 3), ("FILECLOSE", 1)]
    text = (CORPUS / "default_feed.pgm").read_text()
    with pytest.raises(GCodeError, match=r"no feed rate \(F\) has been programmed yet") as info:
        interpret(parse(text))
    assert info.value.line == 7
    tp = interpret(parse(text), default_feed=5.0)
    assert [s.feed for s in tp.segments] == [5.0, 5.0, 1.0, 1.0]
    assert tp.warnings == ["line 7: a G01/LINEAR move before any F: the default feed 5 mm/s "
                           "is used until an F is given"]
    for bad in (0, -1.0, float("nan"), True):
        with pytest.raises(ValueError, match="default_feed"):
            interpret(parse(text), default_feed=bad)
    # Ensemble is still refused: PROGRAM alone on its line, HEADER, DIM … AS
    for ens in ("PROGRAM\nG1 X1\nEND PROGRAM\n", "PROGRAM ' main\n", "DIM a AS DOUBLE\n"):
        with pytest.raises(GCodeError, match="this is Ensemble AeroBasic"):
            parse(ens)
