"""Tip identity along the rim (issue 25, item 3): the rim's edge — its
height profile z(γ) against the CAD's exact rim — and the notches counted
along it against the CAD's serration count n_s.

Scans: 40,000 points from the virtual profilometer (σ = 1 µm), misaligned
20° about the axis, tilted 1°, shifted 0.1 mm."""

from __future__ import annotations

import functools

import pytest

from tipgeo import preset
from tipgeo.inspect import Misalignment, compare, synthetic_scan

MIS = Misalignment(20.0, 1.0, 30.0, (0.1, 0.0, 0.05))


@functools.cache
def _compare(scan, cad):
    pts = synthetic_scan(preset(scan), points=40_000, noise=0.001, misalignment=MIS,
                         seed=3).points
    return compare(pts, preset(cad), pictures=False)


def _check(res, name):
    (c,) = [c for c in res.identity.checks if c.name == name]
    return c


def test_the_same_bevel_passes_the_rim_checks():
    res = _compare("bevel-14G-xi15", "bevel-14G-xi15")
    edge = res.identity.figures["rim_edge"]
    # the scan's rim is the CAD's to the noise (σ = 1 µm; 2.9 µm RMS measured)
    assert edge["residual_rms_um"] < 6.0
    assert edge["scale"] == pytest.approx(1.0, abs=0.01)
    assert edge["rim_span_mm"]["scan"] == pytest.approx(edge["rim_span_mm"]["cad"], abs=0.01)
    assert _check(res, "identity:rim_edge").ok
    assert res.identity.figures["notches"] == {"scan": 0, "cad": 0, "prominence_um": 20.0}
    assert res.identity.ok and res.verdict.ok


@pytest.mark.parametrize("scan", ["twoplane-14G-xi15", "threeplane-14G-xi15", "lancet-14G"])
def test_another_edge_on_a_bevel_cad_fails_the_rim_edge(scan):
    """Two planes, three planes, a lancet's secondaries: the rim's profile is
    off the one-plane bevel's by 247, 262 and 94 µm RMS (measured)."""
    res = _compare(scan, "bevel-14G-xi15")
    c = _check(res, "identity:rim_edge")
    assert not c.ok
    assert c.reason.startswith("not this tip: the rim's edge differs from the CAD's")
    assert res.identity.figures["rim_edge"]["residual_rms_um"] > 50.0
    assert not res.verdict.ok


def test_the_same_serrated_punch_passes_with_its_count():
    res = _compare("punch-C2", "punch-C2")
    assert res.identity.figures["notches"]["scan"] == 16
    assert res.identity.figures["notches"]["cad"] == 16
    assert _check(res, "identity:serrations").ok and res.identity.ok
    # a punch's level rim is left to the serration check
    assert any(s.startswith("rim edge (the CAD's rim is level") for s in res.identity.not_judged)


@pytest.mark.parametrize(("scan", "cad", "n_scan", "n_cad"), [
    ("punch-C2", "punch-C3", 16, 9),
    ("punch-C3", "punch-C2", 9, 16),
    ("punch-plain", "punch-C2", 0, 16),
])
def test_another_notch_count_fails_naming_both(scan, cad, n_scan, n_cad):
    res = _compare(scan, cad)
    c = _check(res, "identity:serrations")
    assert not c.ok
    assert f"the scan has {n_scan} notches along the rim, the CAD {n_cad}" in c.reason
    assert res.identity.figures["notches"]["scan"] == n_scan
    assert not res.verdict.ok


def test_a_serrated_scan_on_a_plain_punch_fails_with_its_notches():
    res = _compare("punch-C2", "punch-plain")
    c = _check(res, "identity:serrations")
    assert not c.ok
    assert res.identity.figures["notches"]["scan"] == 16       # C2's
    assert "the scan has 16 notches along the rim, the CAD 0" in c.reason
