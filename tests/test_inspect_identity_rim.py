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
    notches = res.identity.figures["notches"]
    assert (notches["scan"], notches["cad"]) == (0, 0)
    # the prominence asked of a notch: 20 µm, or 8 × the rim profile's own noise
    assert notches["prominence_um"] >= 20.0
    assert res.identity.ok and res.verdict.ok


@pytest.mark.parametrize("scan", ["twoplane-14G-xi15", "threeplane-14G-xi15", "lancet-14G"])
def test_another_edge_on_a_bevel_cad_fails_the_rim_edge(scan):
    """Two planes, three planes, a lancet's secondaries: the rim's profile is
    off the one-plane bevel's by 47, 51 and 94 µm RMS (measured; the two-
    and three-plane scans registered with one of their planes on the
    bevel's, the search for a window short of the tip finding that pose:
    247 and 262 µm before it), more than twice the check's 20 µm."""
    res = _compare(scan, "bevel-14G-xi15")
    c = _check(res, "identity:rim_edge")
    assert not c.ok
    assert c.reason.startswith("not this tip: the rim's edge differs from the CAD's")
    assert res.identity.figures["rim_edge"]["residual_rms_um"] > 40.0
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


def test_a_dense_face_only_scan_of_the_bevel_is_this_tip():
    """The bevel's cut face alone, densely scanned (6,400 of a 60,000-point
    scan, σ = 2 µm): its rim profile — the highest point of each 1° bin —
    carries the points' noise over the face normal's z share (about 4 × σ
    on a 15° bevel) and picked at its top; a fixed 20 µm prominence counted
    3 noise dips as notches ("not this tip", exit 1) on this correct scan.
    The prominence now is at least 8 × the profile's own robust σ."""
    import numpy as np

    from tipgeo.inspect.cad import load_cad
    from tipgeo.inspect.identity import (
        NOTCH_NOISE,
        NOTCH_STRAY,
        _filled,
        _profile_sigma,
        _rim_profile,
        _rim_zone,
    )
    from tipgeo.inspect.register import apply

    spec = preset("bevel-14G-xi15")
    s = synthetic_scan(spec, points=60_000, noise=0.002, seed=6)
    d = load_cad(spec).distances(apply(s.scan_to_cad, s.points))
    cut = np.isin(d.face, [k for k, nm in enumerate(d.labels) if nm.startswith("cut")])
    res = compare(s.points[cut], spec, pictures=False)
    assert res.registration.search.get("face_only") == "cut:bevel"
    notches = res.identity.figures["notches"]
    zs, zc, _ = _rim_profile(res, _rim_zone(res))
    sigma = _profile_sigma(_filled(zc - zs))
    assert 0.002 < sigma < 0.008                  # 2–8 µm: the face's z noise, not 1 µm
    assert notches["prominence_um"] == pytest.approx(NOTCH_NOISE * sigma * 1e3, rel=1e-9)
    assert notches["scan"] <= NOTCH_STRAY
    assert _check(res, "identity:serrations").ok and res.identity.ok and res.verdict.ok


def test_profile_sigma_is_the_noise_not_the_notches():
    """The profile's robust σ: of white noise, its σ (5 % over 3,600 bins);
    unmoved by notches 3–5 bins wide in a tenth of the bins, or by a smooth
    slope."""
    import numpy as np

    from tipgeo.inspect.identity import _profile_sigma

    rng = np.random.default_rng(2)
    z = rng.normal(0.0, 0.004, 3600)
    assert _profile_sigma(z) == pytest.approx(0.004, rel=0.05)
    notched = z.copy()
    for start in range(0, 3600, 50):
        notched[start:start + 4] += 0.1
    assert _profile_sigma(notched) == pytest.approx(0.004, rel=0.1)
    sloped = z + np.sin(np.linspace(0, 2 * np.pi, 3600, endpoint=False)) * 0.5
    assert _profile_sigma(sloped) == pytest.approx(0.004, rel=0.1)


def test_notches_cut_into_a_bevel_rim_still_fail_on_the_plain_bevel():
    """The noise-scaled prominence does not hide real notches: a bevel with
    eight serration arcs 50 µm deep cut into its rim, scanned (σ = 1 µm)
    and compared with the plain bevel, counts notches above the plain
    CAD's none (4 measured at 27 µm prominence) and fails identity."""
    from tipgeo import loads_spec

    text = (
        'name = "bevel-serrated"\n[cannula]\ngauge = 14\nlength_mm = 10.0\n'
        '[[cutters]]\nkind = "bevel"\nname = "bevel"\nxi_deg = 15.0\n'
        '[[cutters]]\nkind = "serration"\nname = "serrations"\narc_radius_mm = 0.15\n'
        'count = 8\ndepth_mm = 0.05\nedge_radius_mm = 0.015\n')
    pts = synthetic_scan(loads_spec(text), points=40_000, noise=0.001, misalignment=MIS,
                         seed=3).points
    res = compare(pts, preset("bevel-14G-xi15"), pictures=False, allow_mismatch=True)
    c = _check(res, "identity:serrations")
    assert not c.ok and "notches" in c.reason
    assert res.identity.figures["notches"]["scan"] >= 3
    assert not res.identity.ok and not res.verdict.ok
