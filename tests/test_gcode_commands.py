"""The command table (gcode/commands.py) and the parser agree: every row is
accepted by the parser with the syntax-tree node its statement parser makes,
and the parser accepts no statement keyword, word letter or G code that is
not a row; the docs reproduce the table."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from gcode import ast, interpret, parse
from gcode.commands import (
    COMMANDS,
    G_CODES,
    IGNORED,
    MODELLED,
    RECORDED,
    REFUSED,
    WORD_LETTERS,
    table_markdown,
)
from gcode.errors import GCodeError
from gcode.lexer import UnsupportedError

ROOT = Path(__file__).resolve().parent.parent

#: A program using each statement parser's keywords (KW stands for the keyword)
#: and the node the keyword's statement becomes.
USES = {
    "dvar": ("KW $a", ast.DVar), "repeat": ("KW 2\nEND REPEAT", ast.Repeat),
    "for": ("KW $i = 1 TO 2\nNEXT $i", ast.For), "dwell": ("KW 0.5", ast.Dwell),
    "freerun": ("KW A 10", ast.NoMotion), "no_motion": ("KW X", ast.NoMotion),
    "pso": ("KW X OFF", ast.Pso), "block": ("F1\nKW X1", ast.Block),
    "mode": ("KW", ast.Mode), "call": ("KW S\nDFS S\nENDDFS", ast.Call),
    "dfs": ("KW S\nENDDFS", None),
}
#: Keywords whose use needs its own text (openers and closers of blocks).
SPECIAL = {
    "WHILE": ("WHILE 0\nENDWHILE", ast.While), "ENDWHILE": ("WHILE 0\nENDWHILE", ast.While),
    "IF": ("IF 1 THEN\nENDIF", ast.If), "ENDIF": ("IF 1 THEN\nENDIF", ast.If),
    "ELSEIF": ("IF 0 THEN\nELSEIF 1 THEN\nENDIF", ast.If),
    "ELSE": ("IF 0 THEN\nELSE\nENDIF", ast.If),
    "ENDREPEAT": ("REPEAT 1\nENDREPEAT", ast.Repeat), "NEXT": ("FOR $i = 0 TO 1\nNEXT", ast.For),
    "ENDDFS": ("DFS S\nENDDFS", None), "ENABLE": ("ENABLE X Y D", ast.Mode),
    "END": ("END PROGRAM", ast.Mode),
}


def _use(kw: str):
    if kw in SPECIAL:
        return SPECIAL[kw]
    text, node = USES[COMMANDS[kw].parser]
    return text.replace("KW", kw), node


@pytest.mark.parametrize("kw", sorted(k for k, c in COMMANDS.items() if c.simulated != REFUSED))
def test_every_row_is_accepted_as_its_node(kw):
    text, node = _use(kw)
    prog = parse(text)
    assert prog.warnings == ()
    if node is None:            # DFS: a subroutine, not a statement of the body
        assert [s.name for s in prog.subroutines] == ["S"]
    else:
        assert any(type(s) is node for s in prog.body), (kw, prog.body)
    assert COMMANDS[kw].simulated in (MODELLED, RECORDED, IGNORED)


@pytest.mark.parametrize("kw", sorted(k for k, c in COMMANDS.items() if c.simulated == REFUSED))
def test_refused_rows_are_refused_in_every_mode(kw):
    for lenient in (False, True):
        with pytest.raises(GCodeError, match="cannot simulate") as info:
            parse(f"{kw} X 10\n", lenient=lenient)
        assert not isinstance(info.value, UnsupportedError)


def test_recorded_rows_are_recorded_by_the_interpreter():
    for kw, c in COMMANDS.items():
        if c.simulated == RECORDED and c.parser == "no_motion":
            (rec,) = interpret(parse(f"{kw} X\n")).no_motion
            assert rec["kind"] == kw and rec["effect"] == c.effect and rec["executed"] == 1


def _candidate_words() -> set[str]:
    """Upper-case words found in the gcode package, the programs of the test
    corpora and the docs: every keyword anyone wrote down, supported or not."""
    words: set[str] = set()
    files = list((ROOT / "gcode").glob("*.py")) + list((ROOT / "tests" / "data" / "a3200")
                                                       .rglob("*.pgm"))
    files += [ROOT / "docs" / "notes" / "laser.md", ROOT / "samples" / "appendix_c.pgm"]
    for f in files:
        if f.exists():
            words |= set(re.findall(r"\b[A-Z][A-Z_]+\b", f.read_text(encoding="utf-8")))
    return words | {"AUTOFOCUS", "GOTO", "PRINT", "MOVE", "PSOFOO", "THEN", "TO", "STEP"}


def _accepted(word: str) -> bool:
    """True unless the parser calls ``word`` an unknown keyword (or Ensemble's)."""
    try:
        parse(f"{word} X\n")
    except UnsupportedError as e:
        return "unknown keyword" not in e.reason
    except GCodeError as e:     # refused as another dialect, or a known keyword used
        return "Ensemble" not in e.reason   # wrongly (REPEAT without its count …)
    return True


def test_the_parser_accepts_exactly_the_table_keywords():
    words = _candidate_words()
    assert set(COMMANDS) <= words
    accepted = {w for w in words if len(w) > 1 and _accepted(w)}
    assert accepted == set(COMMANDS), (accepted ^ set(COMMANDS))


@pytest.mark.parametrize("letter", "ABCDEFGHIJKLOPQRSTUVWXYZ")   # M, N: see below
def test_word_letters_are_the_table_rows(letter):
    text = f"G1 {letter}1\n"
    if letter in WORD_LETTERS:
        parse(text)
    else:
        with pytest.raises(UnsupportedError, match=f"{letter} words are not supported"):
            parse(text)


def test_m_and_n_words():
    assert isinstance(parse("M30\n").body[0], ast.Mode)
    assert parse("N10\n").body == ()
    with pytest.raises(UnsupportedError, match="M words other than M2 and M30"):
        parse("M3\n")


def test_g_codes_are_the_table_rows():
    for code in range(0, 400):
        if code in G_CODES:
            parse(f"G{code}\n")
        else:
            with pytest.raises(UnsupportedError, match="unsupported G code"):
                parse(f"G{code}\n")


def test_every_g_code_row_has_a_handler_and_runs():
    for code, row in G_CODES.items():
        text = {4: "G4 P0.5", 84: "G84 X Y F1", 92: "G92 X0"}.get(code, f"G{code}")
        tp = interpret(parse(f"F1\n{text}\n"))
        recorded = [r["kind"] for r in tp.no_motion]
        assert recorded == ([f"G{code}"] if row.simulated == RECORDED else [])


def test_docs_reproduce_the_table():
    text = (ROOT / "docs" / "notes" / "laser.md").read_text(encoding="utf-8")
    assert table_markdown() in text
