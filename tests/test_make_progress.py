"""Progress of the make stages through tipgeo.progress (issue 24): the mill's
drop-cutter passes and simulation, the grind simulation, the laser ablation,
the ccx run — on standard error when progress is on, nothing when it is off,
never on standard output; a caller's own ``progress`` printer still gets the
lines."""

from __future__ import annotations

import pytest

from tipgeo import build_tip, preset
from tipgeo import progress as pg


@pytest.fixture
def progress_on(monkeypatch):
    monkeypatch.setattr(pg, "_mode", "on")
    monkeypatch.setattr(pg, "DELAY_S", 0.0)


def _bevel_mill():
    from cam.mill import MillParams, mill

    return mill(preset("bevel-14G-xi14.5"), params=MillParams(scallop=0.02, rough=False),
                compare=False)


def test_mill_reports_its_stages(progress_on, capsys):
    _bevel_mill()
    out, err = capsys.readouterr()
    assert out == ""
    for what in ("finishing: ", "mill: finishing drop-cutter", "pass",
                 "mill: simulate (dexel columns)", "simulate: "):
        assert what in err, what


def test_mill_is_silent_when_progress_is_off(monkeypatch, capsys):
    monkeypatch.setattr(pg, "_mode", "off")
    _bevel_mill()
    assert capsys.readouterr() == ("", "")


def test_a_callers_printer_still_gets_the_lines(monkeypatch, capsys):
    from cam.mill import MillParams, mill

    monkeypatch.setattr(pg, "_mode", "off")
    lines = []
    mill(preset("bevel-14G-xi14.5"), params=MillParams(scallop=0.02, rough=False),
         compare=False, progress=lines.append)
    assert any(s.startswith("finishing: ") for s in lines)
    assert any(s.startswith("simulate: ") for s in lines)
    assert capsys.readouterr() == ("", "")


def test_grind_and_laser_report_their_simulations(progress_on, capsys):
    from cam import grind
    from gcode.emitter import emit_program
    from gcode.pipeline import laser_check

    grind(preset("lancet-14G"))
    spec = preset("punch-C4")
    laser_check(emit_program(spec), spec=spec)
    out, err = capsys.readouterr()
    assert out == ""
    for what in ("grind: simulate", "grind: compare with CAD", "laser: ablation",
                 "notch", "laser: compare with the spec"):
        assert what in err, what


def test_ccx_run_is_a_stage_with_its_increments(progress_on, capsys, tmp_path):
    from tipgeo.fem import ccx_path, run_model
    from tipgeo.fem.axisym import axisymmetric_model

    if ccx_path() is None:
        pytest.skip("ccx is not installed")
    m = axisymmetric_model(build_tip(preset("punch-plain")), depth=0.5, mesh=0.1,
                           block=(3.0, 3.0))
    deck = m.ccx_deck()
    m.ccx_deck = lambda: deck.replace("INC=100000", "INC=8")
    run_model(m, tmp_path, pictures=False)
    out, err = capsys.readouterr()
    assert out == ""
    assert "ccx punch-plain_axisymmetric" in err and "ccx: " in err
    assert "ccx stopped at depth 0.0500 mm of 0.5 mm" in err   # increments in mm (issue 28)
