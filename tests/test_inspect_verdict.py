"""The verdict of a comparison (issue 25): pass only for this tip, in one
certain pose, with each face within its band on its share of points; the
rule, figures and reasons in the report; exit 0 pass, 1 fail, 2 bad input."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tipgeo import preset
from tipgeo.cli import main
from tipgeo.errors import InputError
from tipgeo.inspect import Misalignment, synthetic_scan, write_ply
from tipgeo.inspect.acceptance import (
    AcceptanceRule,
    Band,
    _registration_certain,
    load_acceptance,
    rule_from_dict,
)

BEVEL = "bevel-14G-xi14.5"
MIS = Misalignment(10.0, 1.0, 30.0, (0.1, 0.0, 0.1))


@pytest.fixture(scope="module")
def nominal(tmp_path_factory):
    s = synthetic_scan(preset(BEVEL), points=20000, noise=0.001, seed=1, misalignment=MIS)
    p = tmp_path_factory.mktemp("scans") / "nominal.ply"
    write_ply(p, s.points)
    return p


@pytest.fixture(scope="module")
def overground(tmp_path_factory):
    """The bevel ground at 17° instead of 14.5°."""
    s = synthetic_scan(preset(BEVEL), points=20000, noise=0.001, seed=2, misalignment=MIS,
                       xi_deg=17.0)
    p = tmp_path_factory.mktemp("scans") / "overground.ply"
    write_ply(p, s.points)
    return p


def test_a_nominal_scan_passes_and_the_report_holds_the_rule(nominal, tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["compare", str(nominal), BEVEL, "--quiet", "--out-dir", str(out),
                 "--no-pictures", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    v = rep["verdict"]
    assert v["ok"] is True and v["reasons"] == []
    assert v["not_judged"] == []       # a whole tip: every face and the rim judged
    names = {c["name"] for c in v["checks"]}
    assert {"identity", "registration", "outer_within_band", "cut:bevel_within_band"} <= names
    for c in v["checks"]:
        if c["name"].endswith("_within_band"):
            assert c["value"] >= 0.95
    assert rep["acceptance"]["band_um"] == pytest.approx(10.0, rel=1e-12)
    assert json.loads((out / "report.json").read_text())["verdict"]["ok"] is True
    assert "PASS" in (out / "report.md").read_text()


def test_an_over_ground_bevel_fails_with_the_figure(overground, capsys):
    rc = main(["compare", str(overground), BEVEL, "--quiet"])
    cap = capsys.readouterr()
    assert rc == 1
    assert "FAIL" in cap.out and cap.err.startswith("tipgeo: fail:")
    assert "cut:bevel:" in cap.err and "within ±10 µm (needs ≥ 95 %)" in cap.err
    share = float(cap.err.split("cut:bevel: ")[1].split(" %")[0])
    assert share < 50.0  # most of the face is far outside the band


def test_a_scan_of_another_tip_kind_fails(tmp_path, capsys):
    """The helical needle's scan against the bevel's CAD: the tube fits, the
    cut face does not."""
    s = synthetic_scan(preset("helical-14G"), points=20000, noise=0.001, seed=3)
    p = tmp_path / "helical.ply"
    write_ply(p, s.points)
    assert main(["compare", str(p), "bevel-14G-xi15", "--quiet"]) == 1
    assert "tipgeo: fail:" in capsys.readouterr().err


def test_an_acceptance_file_sets_bands_per_face(overground, nominal, tmp_path, capsys):
    loose = tmp_path / "loose.toml"
    loose.write_text('band_um = 50\n[faces]\n"cut:*" = { band_um = 500, share = 0.9 }\n'
                     'inner = { band_um = 500 }\n')
    assert main(["compare", str(overground), BEVEL, "--quiet", "--acceptance", str(loose)]) == 0
    tight = tmp_path / "tight.toml"
    tight.write_text("band_um = 0.5\nshare = 0.99\n")
    assert main(["compare", str(nominal), BEVEL, "--quiet", "--acceptance", str(tight)]) == 1
    err = capsys.readouterr().err
    assert "within ±0.5 µm (needs ≥ 99 %)" in err


def test_a_bad_acceptance_file_is_bad_input(nominal, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("band_um = 10\nshares = 0.9\n")
    assert main(["compare", str(nominal), BEVEL, "--quiet", "--acceptance", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'shares' is not known" in err[0]


def test_edges_have_their_own_band():
    r = rule_from_dict({"band_um": 5, "faces": {"edges": {"band_um": 20}, "cut:*": {"share": 0.8}}})
    assert r.judges_edges
    assert r.band_for("edges").band == pytest.approx(0.020, rel=1e-12)
    assert r.band_for("cut:bevel") == Band(0.005, 0.8)
    assert r.band_for("outer") == Band(0.005, 0.95)


def test_an_uncertain_registration_is_never_a_pass():
    reg = SimpleNamespace(warnings=["ambiguous registration: a pose turned 16.0° away fits "
                                    "almost as well (robust RMS 3.10 vs 3.00 µm)"],
                          to_dict=lambda: {"search": {"runner_up_angle_deg": 16.0,
                                                      "runner_up_robust_rms_mm": 0.0031,
                                                      "best_robust_rms_mm": 0.0030}})
    ok, why = _registration_certain(SimpleNamespace(registration=reg))
    assert not ok and why.startswith("registration not certain") and "turned 16.0°" in why
    held = SimpleNamespace(warnings=["1 degree(s) of freedom are not constrained by the scan; "
                                     "held at the search result"], to_dict=lambda: {})
    assert not _registration_certain(SimpleNamespace(registration=held))[0]


_FACE = st.dictionaries(st.sampled_from(["band_um", "share", "x"]), st.floats(-1, 2000),
                        max_size=2)
_VALUE = st.one_of(st.floats(allow_nan=True), st.integers(-5, 10**6), st.text(max_size=5),
                   st.booleans(), st.dictionaries(st.text(max_size=6), _FACE, max_size=2))


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["band_um", "share", "min_points", "faces", "bandum"]),
                       _VALUE, max_size=4))
def test_acceptance_tables_give_a_rule_or_a_named_error(table):
    try:
        r = rule_from_dict(table)
    except InputError as e:
        assert "\n" not in str(e)
        return
    assert isinstance(r, AcceptanceRule)
    assert 0 < r.default.band <= 10.0 and 0 < r.default.share <= 1


def test_load_acceptance_reads_a_file(tmp_path):
    f = tmp_path / "a.toml"
    f.write_text("band_um = 8\nshare = 0.9\nmin_points = 50\n[faces]\nouter = { band_um = 15 }\n")
    r = load_acceptance(f)
    assert r.default == Band(0.008, 0.9) and r.min_points == 50
    assert r.band_for("outer") == Band(0.015, 0.9)
    assert "±8 µm on ≥ 90 %" in r.describe()
