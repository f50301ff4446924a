import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tipgeo import GAUGES, Cannula, SpecError
from tipgeo.cannula import GAUGE_SOURCE, gauge_table
from tipgeo.tolerances import MIN_DIAMETER_MM, MIN_FEATURE_MM


def test_gauge_table_covers_10_to_30_regular_wall():
    assert set(range(10, 31)) <= set(GAUGES)
    for de, di in GAUGES.values():
        assert 0 < di < de
    # outer diameters fall with the gauge number
    des = [GAUGES[g][0] for g in sorted(GAUGES)]
    assert all(a > b for a, b in zip(des, des[1:]))
    assert "ISO 9626" in GAUGE_SOURCE
    assert len(gauge_table()) == len(GAUGES)


def test_14G_is_the_thesis_cannula():
    c = Cannula.from_gauge(14)
    assert c.outer_diameter == 2.108 and c.inner_diameter == 1.6
    assert c.r_o == pytest.approx(1.054, abs=1e-15)
    assert c.wall == pytest.approx(0.254, abs=1e-12)
    assert Cannula.from_gauge("14G") == c


def test_biopsy_punch_fig_4_7():
    c = Cannula.biopsy_punch()
    assert (c.outer_diameter, c.inner_diameter) == (2.4, 2.0)


@pytest.mark.parametrize("kw, key", [
    ({"outer_diameter": 2.0, "inner_diameter": 2.0}, "inner_diameter"),
    ({"outer_diameter": 1.0, "inner_diameter": 1.5}, "inner_diameter"),
    ({"outer_diameter": -1.0, "inner_diameter": 0.5}, "outer_diameter"),
    ({"outer_diameter": 2.0, "inner_diameter": 0.0}, "inner_diameter"),
    ({"outer_diameter": float("nan"), "inner_diameter": 0.5}, "outer_diameter"),
    ({"outer_diameter": 2.0, "inner_diameter": 1.0, "length": 0.0}, "length"),
])
def test_bad_cannula_names_the_parameter(kw, key):
    with pytest.raises(SpecError, match=key):
        Cannula(**kw)


def test_unknown_gauge():
    with pytest.raises(SpecError, match="gauge = 40.*10–30"):
        Cannula.from_gauge(40)


@given(de=st.floats(allow_nan=True, allow_infinity=True), di=st.floats(allow_nan=True,
                                                                       allow_infinity=True))
def test_cannula_accepts_exactly_the_valid_range(de, di):
    # physical sizes only: d ≥ 0.05 mm and walls of at least 1 µm
    valid = (math.isfinite(de) and math.isfinite(di) and MIN_DIAMETER_MM <= di
             and di <= de - 2 * MIN_FEATURE_MM and de <= 100)
    if valid:
        c = Cannula(outer_diameter=de, inner_diameter=di)
        assert c.r_i < c.r_o
    else:
        with pytest.raises(SpecError):
            Cannula(outer_diameter=de, inner_diameter=di)
