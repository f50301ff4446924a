"""Issue 28 (d): thesis §3.1.5 and Fig. 3.12 — the helical needle against the
ξ = 14.5° bevel in the along-edge fracture model (eq. 3.19–3.23), with the
thesis's inputs: R = 45 J/m², μ_d = 0.4, G 0.35 (and × 0.9 for the helical
needle), one θ for both needles, means over γ.

The thesis's statements: "helical needles and bevel needles present similar
force behavior at different ratios S. Helical needles have the potential to
lower the tangential fracture forces for S > 2 and increase the
perpendicular fracture forces for S > 0.5"; F_⊥ is largest at the heel
(γ = 0) and at the tip (γ = 180° bevel, 157° helical) at S = 0.3.
"""

import math

import numpy as np
import pytest

from tipgeo import SpecError
from tipgeo.mechanics.report import TABLE_3_3, helical_vs_bevel, table_3_3_prediction

S_GRID = np.round(np.arange(0.1, 5.0 + 1e-9, 0.05), 10)


@pytest.fixture(scope="module")
def fig312():
    return helical_vs_bevel(0.3, S_GRID)


def _change(e, bev, q):
    return e.sweep[q] / bev.sweep[q] - 1.0


def test_similar_mean_forces_across_S(fig312):
    """'similar force behavior': the helical means within 19 % of the bevel's
    at every S = 0.1–5 (measured: same G −9.2…+17.6 %, G × 0.9 −18.3…+5.9 %),
    the same shape in S (the F_∥ means peak at S = 0.85–1.15, the F_⊥ means rise with S)."""
    bev, same, thin = fig312
    for e in (same, thin):
        for q in ("perp", "par"):
            assert np.all(np.abs(_change(e, bev, q)) < 0.19), (e.label, q)
    for e in (bev, same, thin):
        j = int(np.argmax(e.sweep["par"]))
        assert 0.5 <= e.sweep["S"][j] <= 1.5
        assert np.all(np.diff(e.sweep["perp"]) > 0)          # F_⊥ means rise with S


def test_helical_lower_tangential_for_S_above_2(fig312):
    """F_∥ (tangent to the edge): the helical mean below the bevel's for every
    S > 2 (measured −9.2 … −4.0 % with the same G, where it falls below from
    S = 1.2; −18.3 … −10.7 % with G × 0.9)."""
    bev, same, thin = fig312
    above = S_GRID > 2.0
    for e in (same, thin):
        assert np.all(_change(e, bev, "par")[above] < 0), e.label
    d = _change(same, bev, "par")
    assert np.all(d[S_GRID >= 1.2] < 0) and np.all(d[S_GRID <= 1.15] > 0)


def test_helical_higher_perpendicular_for_S_above_half(fig312):
    """F_⊥: with the same G the helical mean is above the bevel's at every
    S > 0.5 (+3.6 … +17.6 % over 0.1–5). With the thesis's G × 0.9 it is
    above only for 0.2 ≤ S ≤ 1.65 — so the thesis's statement for all S > 0.5
    holds for the geometry alone (same G), not with its 10 % smaller G."""
    bev, same, thin = fig312
    d = _change(same, bev, "perp")
    assert np.all(d[S_GRID > 0.5] > 0.03)
    t = _change(thin, bev, "perp")
    assert np.all(t[(S_GRID >= 0.2) & (S_GRID <= 1.65)] > 0)
    assert np.all(t[S_GRID >= 1.7] < 0)
    np.testing.assert_allclose(thin.sweep["perp"], 0.9 * same.sweep["perp"], rtol=1e-12)


def test_fig_312a_peaks_at_heel_and_tip(fig312):
    """S = 0.3: F_⊥ largest near the heel and at the tip (the k → 0 points lie
    4.5° past them: cot ξ |sin γ| = S), the helical tip's near 157°."""
    bev, same, _ = fig312
    for e, tip in ((bev, 180.0), (same, 157.0)):
        g = np.degrees(e.forces.gamma)
        f = e.forces.F_perp
        top = f.max()
        near_heel = (g < 15.0) | (g > 345.0)
        near_tip = np.abs(g - tip) < 15.0
        assert f[near_heel].max() > 0.99 * top
        assert f[near_tip].max() > 0.99 * top
        assert f[~(near_heel | near_tip)].max() < 0.99 * top


def test_own_theta_is_the_input_that_differed():
    """Each needle at its own acute θ at the tip (helical 7.58°, bevel 14.5°)
    puts the helical needle 19–55 % above at every S: the disagreement
    tipgeo had. With one θ for both the result hardly depends on its value."""
    bev, same, thin = helical_vs_bevel(0.3, S_GRID, theta="own")
    assert math.degrees(same.forces.theta) == pytest.approx(7.58, abs=0.01)
    for q in ("perp", "par"):
        d = _change(thin, bev, q)
        assert np.all(d > 0.19) and np.all(d < 0.56)
    with pytest.raises(SpecError, match="theta = 'tip' is not valid"):
        helical_vs_bevel(0.3, S_GRID, theta="tip")


def test_table_3_3_prediction_beside_the_measurement():
    """Table 3.3 (S = 0: −20.53 %, S = 2: −20.07 % in axial force at 23 mm).
    The fracture model at those S: same G +1.9 % / +6.7 %, G × 0.9 −8.3 % /
    −4.0 %. It does not reach the measured −20 %: the measurement includes
    shaft friction and cutting over 23 mm, which the fracture model leaves
    out."""
    rows = table_3_3_prediction()
    assert [r["S"] for r in rows] == [0.0, 2.0]
    assert [r["measured_delta_percent"] for r in rows] == [-20.53, -20.07]
    for r in rows:
        m = TABLE_3_3[r["S"]]
        assert 100 * (m["helical_N"] / m["bevel_N"] - 1) == pytest.approx(
            r["measured_delta_percent"], abs=0.1)
    assert rows[0]["model_delta_percent_same_G"] == pytest.approx(1.90, abs=0.05)
    assert rows[1]["model_delta_percent_same_G"] == pytest.approx(6.65, abs=0.05)
    assert rows[0]["model_delta_percent_thesis_G"] == pytest.approx(-8.29, abs=0.05)
    assert rows[1]["model_delta_percent_thesis_G"] == pytest.approx(-4.01, abs=0.05)
    # G × 0.9 scales every helical force: (1 + same) × 0.9 = 1 + thesis
    for r in rows:
        assert 1 + r["model_delta_percent_thesis_G"] / 100 == pytest.approx(
            0.9 * (1 + r["model_delta_percent_same_G"] / 100), rel=1e-12)


def test_cli_prints_table_3_3_beside_the_model(capsys):
    import json

    from tipgeo.cli import main

    assert main(["forces", "bevel-14G-xi14.5", "helical-14G", "-S", "2", "--theta-deg",
                 "14.5", "--table-3-3"]) == 0
    text = capsys.readouterr().out
    assert "  S 2: measured -20.07 %, model -4.01 % (helical G × 0.9), +6.65 % (same G)" in text
    assert main(["forces", "bevel-14G-xi14.5", "-S", "2", "--table-3-3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["S"] for r in out["table_3_3"]] == [0.0, 2.0]
