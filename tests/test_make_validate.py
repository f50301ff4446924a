"""The making commands (``mill``, ``grind``, ``laser``) check everything
before they write anything (issue 30): a program that fails a check — the
simulator's reader, the machine's limits, its verdict — leaves the output
folder as it was, with the exit status of the contract (2 bad input, 1
outside its targets); the program read back holds every machine limit."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import pytest

from cam import CamError
from cam.mill import EndMill, MillMachine
from cam.mill.check import check_program
from tipgeo import Tip, TipSpec
from tipgeo.cli import main
from tipgeo.tolerances import tol

#: A coarse scallop target (µm) that keeps each plan and simulation short.
SCALLOP_UM = "60"


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder``: (size, mtime in ns)."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*"))}


@pytest.fixture
def out_dir(tmp_path: Path) -> Path:
    """An output folder holding one unrelated file (it must stay as it is)."""
    d = tmp_path / "out"
    d.mkdir()
    (d / "keep.txt").write_text("not ours\n")
    return d


def _mill_argv(d: Path, *extra: str) -> list[str]:
    return ["mill", "bevel-14G-xi14.5", "-o", str(d / "p.nc"), "--scallop-um", SCALLOP_UM,
            "--no-rough", "--sheet", str(d / "s.md"), "--png", str(d / "t.png"),
            "--quiet", *extra]


def test_mill_program_outside_the_machine_writes_nothing(out_dir, capsys):
    """A spindle speed the post rounds to a whole rpm (S100) below the
    machine's minimum (100.4 rpm): the program read back is refused before
    any file is written, exit status 2, naming the limit."""
    m = out_dir.parent / "vf2.toml"
    m.write_text("spindle_rpm_min = 100.4\n")
    before = _snapshot(out_dir)
    rc = main(_mill_argv(out_dir, "--machine", str(m), "--spindle-rpm", "100.4"))
    err = capsys.readouterr().err
    assert rc == 2
    assert "spindle = 100.0 rpm is outside the spindle's range [100.4, 12000] rpm" in err
    assert _snapshot(out_dir) == before


def test_mill_outside_its_targets_writes_nothing(out_dir, capsys, monkeypatch):
    """A part judged outside its targets (a gouge bound no cut can meet):
    exit status 1, the failing figure named, the summary on stdout with
    nothing written, and the output folder untouched."""
    monkeypatch.setattr(tol.cam, "mill_gouge", -1.0e-3)      # demands 1 µm of stock left
    before = _snapshot(out_dir)
    rc = main(_mill_argv(out_dir, "--compare", "--mesh", str(out_dir / "m.stl"),
                         "--deviation-png", str(out_dir / "d.png"), "--json"))
    cap = capsys.readouterr()
    assert rc == 1
    info = json.loads(cap.out)
    assert info["verdict"]["ok"] is False and info["wrote"] == []
    assert "gouge (µm) = 0 is above -1" in cap.err and "nothing was written" in cap.err
    assert _snapshot(out_dir) == before


def test_mill_within_its_targets_writes_everything(out_dir, capsys):
    """The same request judged within its targets writes every file asked
    for (exit status 0): the refusal above is the verdict's, not the run's."""
    rc = main(_mill_argv(out_dir, "--compare", "--json"))
    info = json.loads(capsys.readouterr().out)
    assert rc == 0 and info["verdict"]["ok"] is True
    assert sorted(Path(p).name for p in info["wrote"]) == ["p.nc", "s.md", "t.png"]
    assert sorted(p.name for p in out_dir.iterdir()) == ["keep.txt", "p.nc", "s.md", "t.png"]


def test_mill_names_the_mesh_it_cannot_write_first(out_dir, capsys, monkeypatch):
    """``--mesh X.step`` without OCP: named on stderr before any file is
    written (as ``grind`` and ``gcode sim`` do), the other files written,
    exit status 1."""
    monkeypatch.setitem(sys.modules, "OCP", None)
    monkeypatch.setitem(sys.modules, "OCP.BRep", None)
    seen: list[list[str]] = []
    import tipgeo.cli.make as make

    say = make.cannot_write

    def on_error(path: Path, exc: Exception) -> None:
        seen.append(sorted(os.listdir(out_dir)))
        say(path, exc)

    monkeypatch.setattr(make, "cannot_write", on_error)
    mesh = out_dir / "m.step"
    rc = main(_mill_argv(out_dir, "--mesh", str(mesh), "--json"))
    cap = capsys.readouterr()
    assert rc == 1
    assert seen == [["keep.txt"]]                            # told before any write
    info = json.loads(cap.out)
    assert info["failed"][0]["path"] == str(mesh) and f"cannot write {mesh}" in cap.err
    assert sorted(p.name for p in out_dir.iterdir()) == ["keep.txt", "p.nc", "s.md", "t.png"]


def test_grind_outside_its_targets_writes_nothing(out_dir, capsys, monkeypatch):
    """A ground tip judged 1 mm off CAD: exit status 1 and nothing written."""
    import cam.pipeline as cp

    real = cp.compare_with_cad

    def off(ground: Tip, spec: TipSpec, **kw: Any) -> dict[str, Any]:
        c = real(ground, spec, **kw)
        return {**c, "hausdorff_mm": c["hausdorff_mm"] + 1.0}

    monkeypatch.setattr(cp, "compare_with_cad", off)
    before = _snapshot(out_dir)
    rc = main(["grind", "bevel-14G-xi15", "-o", str(out_dir / "g.json"), "--gcode",
               str(out_dir / "g.nc"), "--sheet", str(out_dir / "g.md"), "--compare", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 1 and "Hausdorff distance ground vs CAD (µm) = 1000" in err
    assert "nothing was written" in err
    assert _snapshot(out_dir) == before


def test_laser_outside_its_targets_writes_nothing(out_dir, capsys, monkeypatch):
    """``laser --html``: the program simulated against its spec before it is
    written; a verdict outside its targets writes neither program nor report."""
    from gcode.pipeline import LaserCheck
    from tipgeo.verdict import Verdict, check_max

    monkeypatch.setattr(LaserCheck, "verdict",
                        property(lambda self: Verdict.of("laser", [check_max("overcut_um", 2.0,
                                                                             1.0)])))
    before = _snapshot(out_dir)
    rc = main(["laser", "punch-C4", "-o", str(out_dir / "c4.pgm"), "--html",
               str(out_dir / "c4.html"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 1 and "overcut_um" in err and "nothing was written" in err
    assert _snapshot(out_dir) == before


_PROGRAM = """%
O1
G17 G21 G90 G94 G40 G49 G80
T1 M06
G54
S10000 M03
G00 G43 H01 Z5.000
X0.000 Y0.000
G01 Z1.000 F50.0
X1.000 F150.0
G00 Z5.000
G28 G91 Z0.
G90
M30
%
"""


def test_check_program_reads_back_and_holds_the_limits():
    """The read-back check: a valid program passes with its moves (the G28
    return exempt from the travels); each limit is named with its line."""
    m, tool = MillMachine(), EndMill()
    moves = check_program(_PROGRAM, m, tool)
    assert len(moves.start) == 4 and moves.home is not None and moves.home[-1]
    assert moves.line is not None and list(moves.line) == [9, 10, 11, 12]
    for bad, match in (
            (_PROGRAM.replace("F150.0", "F20000.0"),
             r"line 10: F = 20000 mm/min is outside the machine's feed range \[1, 16500\]"),
            (_PROGRAM.replace("S10000", "S20000"), r"spindle = 20000(\.0)? rpm"),
            (_PROGRAM.replace("S10000 M03", "M03"), "never sets the spindle speed"),
            (_PROGRAM.replace("T1 M06", "T2 M06"), "calls T2; the tool planned for is T1"),
            (_PROGRAM.replace("X1.000 F150.0", "X400.000 F150.0"),
             r"line 10: axis X = 19.0000 mm \(program 400.0000 mm \+ work offset -381 mm\) "
             r"is outside its travel \[-762, 0\] mm"),
            (_PROGRAM.replace("G00 Z5.000\nG28", "G00 Z500.000\nG28"),
             r"line 11: axis Z = 100.0000 mm .* travel \[-508, 0\] mm"),
            (_PROGRAM.replace("G01 Z1.000", "G02 Z1.000"), "line 9: G2 is not supported")):
        with pytest.raises(CamError, match=match):
            check_program(bad, m, tool)
