"""The laser program asks the serration cutter for its serrations
(SerrationCutter.serration_facts, issue 30) instead of reading its fields:
the facts are the cutter's figures (mm, rad), and a program written from
the facts alone is the program of the real spec."""

import math
from types import SimpleNamespace

import pytest

from gcode.emitter import emit_program, laser_serrations
from tipgeo import SpecError, preset
from tipgeo.cutters.serration import SerrationCutter, SerrationFacts


def test_facts_of_a_count_cutter_are_its_figures():
    f = SerrationCutter(arc_radius=0.15, count=16, edge_radius=0.015,
                        rotation=math.radians(10.0)).serration_facts()
    assert f.arc_radius == 0.15 and f.depth == 0.15          # depth defaults to r_c
    assert f.count == 16 and f.edge_radius == 0.015
    assert f.spacing == pytest.approx(2 * math.pi / 16, rel=1e-15)
    assert f.rotation == pytest.approx(math.radians(10.0), rel=1e-15)


def test_facts_of_a_spacing_cutter_count_the_whole_serrations():
    f = SerrationCutter(arc_radius=0.05, spacing=math.radians(50.0), depth=0.08).serration_facts()
    assert f.count == 7                                      # ⌊360 / 50⌋
    assert f.spacing == pytest.approx(math.radians(50.0), rel=1e-15)
    assert f.depth == 0.08


def test_the_program_is_written_from_the_facts_alone():
    """A stand-in laser cutter that offers nothing but serration_facts()
    gives the same program as the punch-C2 spec it was copied from."""
    spec = preset("punch-C2")
    facts = laser_serrations(spec)
    stand_in = SimpleNamespace(process="laser", serration_facts=lambda: facts, name="s")
    others = [c for c in spec.cutters if c.process != "laser"]
    fake = SimpleNamespace(name=spec.name, cannula=spec.cannula, cutters=others + [stand_in])
    assert emit_program(fake) == emit_program(spec)


def test_a_laser_cutter_that_tells_no_serrations_is_refused():
    spec = preset("punch-C2")
    mute = SimpleNamespace(process="laser", name="mute")
    fake = SimpleNamespace(name="x", cannula=spec.cannula, cutters=[mute])
    with pytest.raises(SpecError, match="serration_facts"):
        emit_program(fake)


def test_facts_are_frozen():
    f = SerrationFacts(arc_radius=0.1, depth=0.1, count=4, spacing=math.pi / 2, rotation=0.0,
                       edge_radius=0.0)
    with pytest.raises(AttributeError):
        f.count = 5
