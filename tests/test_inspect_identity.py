"""Tip identity before any verdict (issue 25, item 3): a scan of another
kind of tip — a helical needle, a two-plane tip, a serrated punch where
the CAD is plain, a plain punch where it is serrated, another gauge — fails
with what differs named; the right tip passes.

Scans: 10,000 points (20,000 of the punches) from the virtual profilometer (σ = 1 µm), misaligned
20° about the axis, tilted 1°, shifted 0.1 mm."""

from __future__ import annotations

import functools

import pytest

from tipgeo import preset
from tipgeo.cannula import Cannula
from tipgeo.errors import NotThisTip
from tipgeo.inspect import Misalignment, compare, load_cad, synthetic_scan
from tipgeo.spec import TipSpec

MIS = Misalignment(20.0, 1.0, 30.0, (0.1, 0.0, 0.05))


@functools.cache
def _scan(spec_name):
    n = 20_000 if spec_name.startswith("punch") else 10_000   # the notches need the density
    return synthetic_scan(preset(spec_name), points=n, noise=0.001, misalignment=MIS,
                          seed=3).points


def _identity_failures(res):
    return [c for c in res.identity.checks if not c.ok]


def test_the_right_tip_passes_identity():
    res = compare(_scan("bevel-14G-xi15"), preset("bevel-14G-xi15"), pictures=False)
    assert res.identity.ok and res.verdict.ok
    fig = res.identity.figures
    # one plane, to the noise (σ = 1 µm along the line of sight)
    assert fig["cut_region_plane_rms_um"]["scan"] < 1.5
    assert fig["outer_diameter_mm"]["scan"] == pytest.approx(2.108, abs=0.002)
    assert fig["rim_places"]["below_cad"] == [] and fig["rim_places"]["above_cad"] == []


@pytest.mark.parametrize(("scan", "rms_min_um"), [("helical-14G", 30.0),
                                                  ("twoplane-14G-xi15", 100.0)])
def test_another_cut_on_a_bevel_cad_is_not_this_tip(scan, rms_min_um):
    """The helical cut's and the two planes' points between the walls are
    no plane (94 and 656 µm plane-fit RMS at 20,000 points) where the CAD's bevel is one."""
    res = compare(_scan(scan), preset("bevel-14G-xi15"), pictures=False)
    assert not res.verdict.ok
    bad = _identity_failures(res)
    assert bad and bad[0].name == "identity:cut_face_planar"
    assert "not this tip: the scan's cut face is not one plane" in bad[0].reason
    assert res.identity.figures["cut_region_plane_rms_um"]["scan"] > rms_min_um
    assert any(r.startswith("not this tip") for r in res.verdict.reasons)


def test_a_serrated_punch_on_a_plain_cad_is_not_this_tip():
    res = compare(_scan("punch-C2"), preset("punch-plain"), pictures=False)
    bad = _identity_failures(res)
    assert [c.name for c in bad] == ["identity:serrations"]
    assert "the rim lies below the CAD's in" in bad[0].reason and "serrations?" in bad[0].reason
    assert not res.verdict.ok
    # the notches are C2's: 150 µm arcs cut ~50 µm deep into the rim's points
    places = res.identity.figures["rim_places"]["below_cad"]
    assert len(places) >= 8
    assert 30.0 < max(p["depth_um"] for p in places) < 160.0


def test_a_plain_punch_on_a_serrated_cad_is_not_this_tip():
    res = compare(_scan("punch-plain"), preset("punch-C2"), pictures=False)
    bad = _identity_failures(res)
    assert [c.name for c in bad] == ["identity:serrations"]
    assert "of the CAD's 16 serrations are filled in the scan" in bad[0].reason
    assert len(res.identity.figures["rim_places"]["above_cad"]) >= 8
    assert not res.verdict.ok


def test_another_serration_count_is_not_this_tip():
    """C3 (9 serrations) against C2's CAD (16): notches where the CAD has
    none and the CAD's notches filled."""
    res = compare(_scan("punch-C3"), preset("punch-C2"), pictures=False)
    bad = _identity_failures(res)
    assert [c.name for c in bad] == ["identity:serrations"]
    assert "the rim lies below the CAD's" in bad[0].reason
    assert "serrations are filled in the scan" in bad[0].reason


def test_another_gauge_is_not_this_tip():
    """A 14G bevel against the same bevel on a 16G tube: refused before
    registration, the diameters named."""
    spec16 = TipSpec(cannula=Cannula.from_gauge(16), cutters=preset("bevel-14G-xi15").cutters,
                     name="bevel-16G-xi15")
    with pytest.raises(NotThisTip) as e:
        compare(_scan("bevel-14G-xi15"), load_cad(spec16), pictures=False)
    msg = str(e.value)
    assert "outer diameter" in msg and "another gauge" in msg
    assert f"{2 * Cannula.from_gauge(16).r_o:.4f} mm" in msg
