"""Issue 28 (b): Appendix C's roughing radius, notch by notch.

The thesis's program decrements ``$radius`` and ``$comp`` by ``$dist_R``
(1 µm) on each of the 20 roughing passes of a notch and never sets them back
before the next notch. That is the printed program's bug, not the
simulator's: the simulator runs the program as written, so the roughing
arcs of notch n run from 140 − 20(n−1) µm (beam-centre radius, 10 µm beam
radius inside the programmed 150 µm) down through 0 and, negative, out again
to the far side, and the 15th and 16th notches cut 19.05 and 19.95 µm beyond
CAD at the rim. With the two lines that reset the variables at the start of
each notch, every notch is cut alike and within 2 µm of CAD.
"""

from pathlib import Path

import pytest

from gcode.ablation import notch_arcs
from gcode.pipeline import laser_check, read_program
from tipgeo import preset

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "appendix_c.pgm"
NOTCH_START = "REPEAT 16 ; Make serrations all around the circumference\n"
RESET = "$radius = $radius_i\n$comp = $comp_i\n"


def _check(text):
    return laser_check(text, spec=preset("punch-C2"), origin=(-0.15, 0.0))


@pytest.fixture(scope="module")
def printed():
    return _check(read_program(SAMPLE))


@pytest.fixture(scope="module")
def reset():
    text = read_program(SAMPLE)
    assert text.count(NOTCH_START) == 1
    return _check(text.replace(NOTCH_START, NOTCH_START + RESET))


def test_printed_program_never_resets_the_roughing_radius(printed):
    arcs = notch_arcs(printed.toolpath)
    assert [a["c_deg"] for a in arcs] == pytest.approx([22.5 * k for k in range(16)], abs=1e-9)
    # the finishing passes ($radius_i, never changed) give the largest arc,
    # 150 − 10 µm, in every notch but the last
    for a in arcs[:15]:
        assert a["max_radius_mm"] == pytest.approx(0.140, abs=1e-9)
    # the roughing radius carries over: its smallest arc falls by 20 passes ×
    # 1 µm per notch, 121, 101, … 21 µm, until it passes through the beam radius
    for n in range(6):
        assert arcs[n]["min_radius_mm"] == pytest.approx(0.121 - 0.020 * n, abs=1e-9)
    # by the 16th notch $radius is −0.169 mm: its roughing arcs lie beyond
    # the programmed 150 µm (beam centre at 159 µm)
    assert arcs[15]["max_radius_mm"] == pytest.approx(0.159, abs=1e-9)
    per = printed.comparison["per_notch"]
    assert len(per) == 16
    over_um = [p["overcut_mm"] * 1e3 for p in per]
    # notches 1–14 within the meshes' chordal tolerance; 15 and 16 overcut
    assert max(over_um[:14]) < 0.1
    assert over_um[14] == pytest.approx(19.05, abs=0.1)
    assert over_um[15] == pytest.approx(19.95, abs=0.1)
    assert max(over_um) == pytest.approx(printed.comparison["overcut_mm"] * 1e3, rel=1e-12)
    # every notch's finished radius is still right: $radius_i is not touched
    for p in per:
        assert p["radius_error_mm"] < 1e-4 and p["material_left_mm"] < 1e-4
    assert not printed.verdict.ok
    assert {k.name for k in printed.verdict.failed} == {"overcut_um", "hausdorff_um"}


def test_program_with_the_reset_cuts_every_notch_within_2_um(reset):
    arcs = notch_arcs(reset.toolpath)
    assert len(arcs) == 16
    for a in arcs:           # every notch cut alike: 20 roughing + 80 finishing arcs
        assert a["arcs"] == 100
        assert a["min_radius_mm"] == pytest.approx(0.121, abs=1e-9)
        assert a["max_radius_mm"] == pytest.approx(0.140, abs=1e-9)
    per = reset.comparison["per_notch"]
    assert [p["c_deg"] for p in per] == pytest.approx([22.5 * k for k in range(16)], abs=1e-9)
    for p in per:
        assert p["overcut_mm"] < 2e-3 and p["material_left_mm"] < 2e-3
        assert p["radius_error_mm"] < 2e-3
    assert reset.comparison["slugs_removed"] == 16
    assert reset.verdict.ok, reset.verdict.reasons
