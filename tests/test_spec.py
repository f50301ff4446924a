"""Spec files: samples in step with presets, round trips, clear errors."""

import copy
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tipgeo import SpecError, dumps_spec, load_spec, loads_spec, preset, preset_names
from tipgeo.spec import CUTTER_KINDS, spec_from_dict, spec_to_dict
from tipgeo.tolerances import MAX_TIP_HEIGHT_MM

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def test_samples_are_the_presets():
    # tip specs are the TOML files with a [cannula] table (others: study configs)
    files = sorted(p.stem for p in SAMPLES.glob("*.toml") if "[cannula]" in p.read_text())
    assert files == sorted(preset_names())
    for name in files:
        assert load_spec(SAMPLES / f"{name}.toml") == preset(name)


@pytest.mark.parametrize("name", preset_names())
def test_round_trip(name):
    spec = preset(name)
    assert loads_spec(dumps_spec(spec)) == spec
    assert spec_from_dict(spec_to_dict(spec)) == spec


BEVEL = """
name = "b"
[cannula]
gauge = 14
[[cutters]]
kind = "bevel"
xi_deg = 15
"""


@pytest.mark.parametrize("text, match", [
    (BEVEL.replace("xi_deg = 15", "xi_deg = 95"), r"cutters\[0\]\.xi_deg.*95.*0 < value ≤ 90"),
    (BEVEL.replace("xi_deg = 15", "xi_deg = 0"), r"cutters\[0\]\.xi_deg"),
    (BEVEL.replace("xi_deg = 15", 'xi_deg = "15"'), r"cutters\[0\]\.xi_deg.*not a number"),
    (BEVEL.replace("xi_deg = 15", "xi = 15"), r"cutters\[0\]\.xi is not a known key.*xi_deg"),
    (BEVEL.replace("xi_deg = 15", ""), r"cutters\[0\]\.xi_deg is missing"),
    (BEVEL.replace('"bevel"', '"bevell"'),
     r"'bevell' is not a valid tip kind; expected one of: bevel, multiplane"),
    (BEVEL.replace("gauge = 14", "gauge = 40"), r"cannula\.gauge = 40.*10–30"),
    (BEVEL.replace("gauge = 14", "outer_diameter_mm = 2.0\ninner_diameter_mm = 2.5"),
     r"inner_diameter.*2\.5.*outer_diameter"),
    (BEVEL.replace("gauge = 14", "gauge = 14\nlength_mm = -3"), r"length_mm.*-3"),
    (BEVEL + "colour = 'red'\n", r"colour is not a known key"),
    (BEVEL.replace('name = "b"', 'name = "b"\ntolerance_um = 0'), r"tolerance_um = 0"),
    ("[cannula]\ngauge = 14\n", r"cutters is missing"),
    ("name = \n", r"not valid TOML"),
    (BEVEL.replace('kind = "bevel"\nxi_deg = 15',
                   'kind = "conical"\ntheta_deg = 15\nphi_g_deg = 25'),
     r"exactly one of theta_deg and phi_g_deg"),
    (BEVEL.replace('kind = "bevel"\nxi_deg = 15', 'kind = "multiplane"\ntheta_deg = 15\n'
                   'planes = 3'), r"theta.*15.*60"),
    (BEVEL.replace('kind = "bevel"\nxi_deg = 15', 'kind = "multiplane"\nxi_deg = 15\n'
                   'planes = 1'), r"cutters\[0\]\.planes.*1.*2"),
    (BEVEL + '[[cutters]]\nkind = "bevel"\nxi_deg = 30\n', r"name = 'bevel' repeats"),
])
def test_bad_specs_name_the_key(text, match):
    with pytest.raises(SpecError, match=match):
        loads_spec(text)


def test_serration_overlap_in_a_spec_names_the_count():
    text = (SAMPLES / "punch-C5.toml").read_text().replace("count = 3", "count = 12")
    with pytest.raises(SpecError, match=r"cutters\[1\].*count = 12.*overlap"):
        loads_spec(text)


def test_missing_file_is_a_spec_error(tmp_path):
    with pytest.raises(SpecError, match="does not exist"):
        load_spec(tmp_path / "nope.toml")


def test_multiplane_by_theta_and_conical_by_grinding():
    s = loads_spec(BEVEL.replace('kind = "bevel"\nxi_deg = 15',
                                 'kind = "multiplane"\ntheta_deg = 30\nplanes = 2'))
    assert math.degrees(s.cutters[0].xi) == pytest.approx(15.0)
    s = loads_spec(BEVEL.replace('kind = "bevel"\nxi_deg = 15',
                                 'kind = "conical"\nphi_g_deg = 25\nvarphi_deg = 10'))
    assert math.degrees(s.cutters[0].theta) == pytest.approx(15.0)


def test_mesh_cutter_path_is_relative_to_the_spec(tmp_path):
    import trimesh

    box = trimesh.creation.box(extents=(10, 10, 20))
    box.apply_translation((0, 0, -9))
    box.export(tmp_path / "keep.stl")
    (tmp_path / "t.toml").write_text(BEVEL.replace('kind = "bevel"\nxi_deg = 15',
                                                   'kind = "mesh"\npath = "keep.stl"'))
    spec = load_spec(tmp_path / "t.toml")
    assert spec.cutters[0].kind == "mesh"


# -- property-based: whatever the values, a spec is valid or one SpecError --------
_values = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                    st.integers(-10**6, 10**6), st.text(max_size=5), st.booleans(),
                    st.lists(st.floats(-400, 400), max_size=4), st.none())


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(preset_names()), data=st.data())
def test_fuzzed_specs_raise_only_spec_errors(name, data):
    d = spec_to_dict(preset(name))
    d = copy.deepcopy(d)
    k = data.draw(st.integers(0, len(d["cutters"]) - 1))
    cut = d["cutters"][k]
    key = data.draw(st.sampled_from(sorted(set(cut) | set(CUTTER_KINDS[cut["kind"]]))))
    value = data.draw(_values)
    if value is None:
        cut.pop(key, None)
    else:
        cut[key] = value
    try:
        spec = spec_from_dict(d)
    except SpecError as e:
        msg = str(e)
        assert f"cutters[{k}]" in msg or "cutters" in msg or key in msg, msg
    else:
        assert spec.cutters[k].kind == cut["kind"]


@settings(max_examples=200, deadline=None)
@given(xi=st.floats(allow_nan=True, allow_infinity=True))
def test_bevel_angle_range_is_exactly_0_to_90(xi):
    text = BEVEL.replace("xi_deg = 15", f"xi_deg = {xi!r}".replace("nan", "nan")
                         .replace("inf", "inf"))
    ok = math.isfinite(xi) and 0 < math.radians(xi) <= math.pi / 2
    # a tip longer than MAX_TIP_HEIGHT_MM (1 m) is no needle: ξ ≳ 0.12° on 14G
    height = 2 * 1.054 / math.tan(math.radians(xi)) if ok and xi < 90 else 0.0
    if ok and height <= 0.999 * MAX_TIP_HEIGHT_MM:
        assert loads_spec(text).cutters[0].xi == pytest.approx(math.radians(xi))
    elif not ok or height >= 1.001 * MAX_TIP_HEIGHT_MM:
        with pytest.raises(SpecError, match=r"cutters\[0\]\.xi_deg"):
            loads_spec(text)


@settings(max_examples=200, deadline=None)
@given(text=st.text(max_size=200))
def test_arbitrary_text_never_crashes_the_parser(text):
    try:
        loads_spec(text)
    except SpecError:
        pass
