"""The sample machine files (samples/machines/) and their loaders: the Haas
VF-2 (cam.mill.MillMachine.from_toml), the thesis's five-axis grinder
(cam.Machine.from_toml) and the A3200 laser station
(gcode.LaserParams.from_toml). Each sample equals the defaults it documents;
each loader refuses zero or negative travels and speeds, naming the key."""

from __future__ import annotations

import json
import math
from dataclasses import fields
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cam import CamError, Machine
from cam.mill import MillMachine
from gcode import GCodeError, LaserParams
from gcode.emitter import LASER_TOML_KEYS

MACHINES = Path(__file__).resolve().parent.parent / "samples" / "machines"


def _same(a, b):
    """Dataclass fields equal (floats to 1e-12 relative: the grinder's feeds
    are divided by 60 at load)."""
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, float):
            assert x == pytest.approx(y, rel=1e-12), f.name
        else:
            assert x == y, f.name


def test_haas_vf2_sample_is_the_default_machine():
    m = MillMachine.from_toml(MACHINES / "haas-vf2.toml")
    _same(m, MillMachine())
    assert (m.x.hi - m.x.lo, m.y.hi - m.y.lo, m.z.hi - m.z.lo) == (762.0, 406.0, 508.0)
    assert m.resolution == 0.002 and m.spindle_rpm_max == 12000.0


def test_grinder_sample_is_the_default_machine():
    m = Machine.from_toml(MACHINES / "grinder.toml")
    _same(m, Machine())
    assert m.feed_max == pytest.approx(0.5, rel=1e-12)      # 30 mm/min in the file


def test_laser_sample_is_the_default_station():
    p = LaserParams.from_toml(MACHINES / "a3200-laser.toml")
    _same(p, LaserParams())
    assert p.feed == pytest.approx(0.1, rel=1e-12)           # 6 mm/min in the file
    text = (MACHINES / "a3200-laser.toml").read_text()
    assert all(f"\n{k} = " in text for k in LASER_TOML_KEYS)  # every key documented


def _write(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize("text, match", [
    ("[x]\nlo = 0.0\nhi = 0.0\nresolution = 0.002\n", r"axis \[x\]: travel hi − lo = 0"),
    ("[z]\nlo = 0.0\nhi = -508.0\nresolution = 0.002\n", r"axis \[z\]: travel hi − lo = -508"),
    ("[y]\nlo = -406.0\nhi = 0.0\nresolution = 0.0\n", r"axis \[y\]: resolution = 0 .* > 0"),
    ("[y]\nlo = -406.0\nhi = 0.0\n", r"axis \[y\] = .*needs exactly the numbers lo, hi"),
    ("[x]\nlo = -1.0\nhi = inf\nresolution = 0.002\n", r"axis \[x\] hi = inf is not a finite"),
    ("spindle_rpm_max = 0\n", r"spindle_rpm_max = 0 is out of range; allowed value > 0"),
    ("spindle_rpm_min = -100.0\n", r"spindle_rpm_min = -100.0 is out of range"),
    ("rapid = -1\n", r"machine rapid = -1 is out of range; allowed value > 0 \(mm/min\)"),
    ("feed_max = true\n", r"feed_max = True is not a number"),
    ("feed_min = 500.0\nfeed_max = 100.0\n", r"feed_min = 500 is above feed_max = 100"),
    ("controller = 'fanuc-x'\n",
     r"controller = 'fanuc-x' has no post; allowed: fanuc, haas, linuxcnc"),
    ("work_offset = [1.0, 2.0]\n", r"work_offset = \[1.0, 2.0\]: needs three finite numbers"),
    ("colour = 1\n", r"key 'colour' is not known; allowed: .*spindle_rpm_max"),
])
def test_mill_machine_file_refusals(tmp_path, text, match):
    with pytest.raises(CamError, match=match):
        MillMachine.from_toml(_write(tmp_path, text))


@pytest.mark.parametrize("text, match", [
    ("[t2]\nlo = 5.0\nhi = 5.0\nresolution = 0.0001\n", r"axis \[t2\]: travel hi − lo = 0"),
    ("wheel_rpm = 0\n", r"wheel_rpm = 0 is out of range; allowed value > 0 \(rpm\)"),
    ("feed_max_mm_min = -30.0\n", r"feed_max_mm_min = -30.0 is out of range.*\(mm/min\)"),
    ("rapid_speed_mm_min = 'fast'\n", r"rapid_speed_mm_min = 'fast' is not a number"),
    ("feed_min_mm_min = 40.0\n", r"feed_min_mm_min = 40 is above feed_max_mm_min = 30"),
    ("phi_deg = 90.0\n", r"phi_deg = 90 is out of range; allowed 0 < value < 90"),
    ("contact_radius = 60.0\n", r"contact_radius = 60 mm must lie inside the wheel"),
    ("name = ''\n", r"machine name = '' must be a non-empty string"),
    ("feed_max = 0.3\nfeed_max_mm_min = 18.0\n", r"'feed_max' \(mm/s\) and 'feed_max_mm_min'"),
    ("colour = 1\n", r"key 'colour' is not known; allowed: .*feed_max_mm_min"),
])
def test_grinder_file_refusals(tmp_path, text, match):
    with pytest.raises(CamError, match=match):
        Machine.from_toml(_write(tmp_path, text))


def test_grinder_file_feeds_are_mm_per_min(tmp_path):
    m = Machine.from_toml(_write(tmp_path, "feed_max_mm_min = 18.0\n"))
    assert m.feed_max == pytest.approx(0.3, rel=1e-12)
    with pytest.warns(DeprecationWarning, match=r"'feed_max' \(mm/s\) is deprecated; use "
                                                r"'feed_max_mm_min'"):
        old = Machine.from_toml(_write(tmp_path, "feed_max = 0.3\n", "old.toml"))
    assert old.feed_max == pytest.approx(0.3, rel=1e-12)
    with pytest.raises(CamError, match=r"= 60 mm/min; range \[1.2, 18\] mm/min"):
        m.check_feed(1.0)


@pytest.mark.parametrize("text, match", [
    ("colour = 1\n", r"key 'colour' is not known; allowed: beam_diameter_um, overlap"),
    ("feed_mm_min = 0\n", r"feed_mm_min = 0 mm/min is out of range; allowed 0 < value ≤ 60000"),
    ("feed_mm_min = -6.0\n", r"feed_mm_min = -6 mm/min is out of range"),
    ("beam_diameter_um = '20'\n", r"beam_diameter_um = '20' is not a number"),
    ("finishing_passes = 2.5\n", r"finishing_passes = 2.5 is not an integer"),
    ("finishing_passes = -1\n", r"finishing_passes = -1 is out of range; allowed 0 ≤ value"),
    ("overlap = 1.0\n", r"overlap = 1 is out of range; allowed 0 ≤ value < 1"),
    ("pulse_period_us = 10.0\npulse_on_us = 12.0\n",
     r"pulse_on_us = 12 µs is out of range; allowed 0 < value ≤ 10"),
    ("pulse_on_us = 12.0\n", r"pulse_on_us = 12 is out of range; allowed 0 < value ≤ "
                             r"pulse_period_us = 10"),
    ("compensation_mm = 0.005\n", r"compensation_mm = 0.005 is out of range; allowed value > "
                                  r"the beam radius"),
    ("rotary_feed_deg_min = nan\n", r"rotary_feed_deg_min = nan is not finite"),
    ("power_w = true\n", r"power_w = True is not a number"),
    ("feed_mm_min = [6.0]\n", r"feed_mm_min = \[6.0\] is not a number"),
    ("feed_mm_min = \n", r"laser file"),
])
def test_laser_file_refusals_name_key_value_and_range(tmp_path, text, match):
    with pytest.raises(GCodeError, match=match) as e:
        LaserParams.from_toml(_write(tmp_path, text, "laser.toml"))
    assert "\n" not in str(e.value) and "laser" in str(e.value)


def test_laser_file_converts_units(tmp_path):
    p = LaserParams.from_toml(_write(tmp_path, "beam_diameter_um = 30.0\nfeed_mm_min = 12.0\n"
                                               "rotary_feed_deg_min = 600.0\n", "l.toml"))
    assert (p.beam_diameter, p.feed, p.rotary_feed) == pytest.approx((0.03, 0.2, 10.0),
                                                                     rel=1e-12)
    assert p.finishing_passes == 80                      # keys left out keep their defaults


def _toml_value(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf") if math.isinf(x) \
            else repr(x)
    if isinstance(x, int):
        return str(x)
    if isinstance(x, str):
        return json.dumps(x)
    return "[" + ", ".join(_toml_value(a) for a in x) + "]"


_scalars = st.one_of(st.floats(), st.integers(-10 ** 6, 10 ** 6), st.booleans(),
                     st.text(max_size=8), st.floats(min_value=-1e3, max_value=1e5))
_values = st.one_of(_scalars, st.lists(_scalars, max_size=3))
_keys = st.one_of(st.sampled_from(sorted(LASER_TOML_KEYS)),
                  st.from_regex(r"[a-z_]{1,12}", fullmatch=True))


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(_keys, _values, max_size=6))
def test_laser_file_loader_raises_only_its_named_error(tmp_path_factory, table):
    """Random tables, written as TOML: the loader returns LaserParams or
    raises GCodeError — one line — and nothing else."""
    d = tmp_path_factory.mktemp("laser")
    path = d / "l.toml"
    path.write_text("".join(f"{k} = {_toml_value(v)}\n" for k, v in table.items()),
                    encoding="utf-8")
    try:
        p = LaserParams.from_toml(path)
    except GCodeError as e:
        assert "\n" not in str(e)
    else:
        assert isinstance(p, LaserParams) and p.feed > 0 and p.beam_diameter > 0
    try:
        LaserParams.from_dict(table)
    except GCodeError as e:
        assert "\n" not in str(e)


def _sample_keys(name: str) -> tuple[list[str], list[str]]:
    """(scalar keys, axis table names) of a sample machine file."""
    import tomllib

    data = tomllib.loads((MACHINES / name).read_text(encoding="utf-8"))
    return (sorted(k for k, v in data.items() if not isinstance(v, dict)),
            sorted(k for k, v in data.items() if isinstance(v, dict)))


def _axis_tables(axes: list[str]):
    part = st.one_of(st.floats(), st.integers(-10 ** 400, 10 ** 400), st.booleans(),
                     st.text(max_size=4), st.floats(min_value=-1e3, max_value=1e3))
    table = st.dictionaries(st.sampled_from(["lo", "hi", "resolution", "x"]), part, max_size=4)
    return st.dictionaries(st.sampled_from(axes), table, max_size=3)


def _machine_toml(scalars: dict, tables: dict) -> str:
    text = "".join(f"{k} = {_toml_value(v)}\n" for k, v in scalars.items())
    for name, t in tables.items():
        text += f"[{name}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in t.items())
    return text


def _check_machine_file(loader, error, path, scalars, tables):
    """The loader returns a machine whose every axis has positive travel and
    resolution, or raises its one named error on one line — nothing else."""
    try:
        m = loader(path)
    except error as e:
        assert "\n" not in str(e) and str(e)
        return None
    for f in fields(m):
        v = getattr(m, f.name)
        if hasattr(v, "lo") and hasattr(v, "hi"):
            assert v.hi - v.lo > 0 and v.resolution > 0, (f.name, v)
    return m


_gkeys, _gaxes = _sample_keys("grinder.toml")
_mkeys, _maxes = _sample_keys("haas-vf2.toml")


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.one_of(st.sampled_from(_gkeys), st.from_regex(r"[a-z_]{1,12}",
                                                                        fullmatch=True)),
                       _values, max_size=5), _axis_tables(_gaxes))
def test_grinder_file_loader_raises_only_its_named_error(tmp_path_factory, scalars, tables):
    path = tmp_path_factory.mktemp("grinder") / "g.toml"
    path.write_text(_machine_toml(scalars, tables), encoding="utf-8")
    m = _check_machine_file(Machine.from_toml, CamError, path, scalars, tables)
    if m is not None:
        assert m.feed_max >= m.feed_min > 0 and m.wheel_rpm > 0 and m.rapid_speed > 0
        assert 0 < m.phi_deg < 90


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.one_of(st.sampled_from(_mkeys), st.from_regex(r"[a-z_]{1,12}",
                                                                        fullmatch=True)),
                       _values, max_size=5), _axis_tables(_maxes))
def test_mill_file_loader_raises_only_its_named_error(tmp_path_factory, scalars, tables):
    path = tmp_path_factory.mktemp("mill") / "m.toml"
    path.write_text(_machine_toml(scalars, tables), encoding="utf-8")
    m = _check_machine_file(MillMachine.from_toml, CamError, path, scalars, tables)
    if m is not None:
        assert m.feed_max >= m.feed_min > 0 and m.rapid > 0 and m.spindle_rpm_max > 0


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["grinder.toml", "haas-vf2.toml"]), st.data())
def test_one_sample_value_changed_loads_or_is_named(tmp_path_factory, name, data):
    """The sample with one value replaced by a hostile one: loads, or the
    one-line error names that key."""
    import re

    text = (MACHINES / name).read_text(encoding="utf-8")
    lines = [i for i, ln in enumerate(text.splitlines()) if re.match(r"^\w+\s*=", ln)]
    i = data.draw(st.sampled_from(lines))
    value = data.draw(st.sampled_from(["0", "-1.0", "0.0", "-1e-300", "1e400", "nan", "inf",
                                       "'x'", "true", "[]", "{}"]))
    rows = text.splitlines()
    key = rows[i].split("=", 1)[0].strip()
    rows[i] = f"{key} = {value}"
    path = tmp_path_factory.mktemp("one") / name
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    loader = Machine.from_toml if name == "grinder.toml" else MillMachine.from_toml
    try:
        loader(path)
    except CamError as e:
        assert "\n" not in str(e) and (key in str(e) or "not valid TOML" in str(e)), str(e)


@pytest.mark.parametrize("loader, text, match", [
    ("mill", "controller = []\n", r"controller = \[\] has no post; allowed: fanuc"),
    ("mill", "controller = 1\n", r"controller = 1 has no post"),
    ("mill", 'name = "a\\nG0 X0"\n', r"machine name = .* holds a control character"),
    ("grinder", 'name = "a\\u2028b"\n', r"machine name = .* holds a control character"),
    ("grinder", f'name = "{"x" * 121}"\n', r"machine name is 121 characters long; allowed at "
                                            r"most 120"),
])
def test_machine_names_and_controllers_refused(tmp_path, loader, text, match):
    cls = MillMachine if loader == "mill" else Machine
    with pytest.raises(CamError, match=match) as e:
        cls.from_toml(_write(tmp_path, text))
    assert "\n" not in str(e.value)
