"""Issue 28 (a): the PVC S/P = 0.5 tissue carries one consistent parameter set
— thesis Table 2.4 (R, E, η) with Table 2.5 (friction) — and its forces
match a hand computation of eq. 2.14–2.27."""

import math

import pytest

from tipgeo import SpecError
from tipgeo.mechanics import J_PER_M2, KPA, tissue
from tipgeo.mechanics.fracture import rupture_forces


def test_pvc_sp05_constants_are_table_2_4_and_2_1():
    t = tissue("pvc-sp0.5")
    # Table 2.4: R 35 J/m², E 12.9 kPa, η 0.5 — one force model's set
    assert t.R == pytest.approx(35 * J_PER_M2, rel=1e-15)
    assert t.E == pytest.approx(12.9 * KPA, rel=1e-15)
    assert t.eta == 0.5
    assert t.sources["E"].startswith("Table 2.4") and t.sources["R"] == "Table 2.4"
    assert t.sources["eta"] == "Table 2.4" and t.sources["friction"] == "Table 2.5"
    # Table 2.1's characterised modulus kept beside it, with its source
    assert t.E_characterised == pytest.approx(13.60 * KPA, rel=1e-15)
    assert t.sources["E_characterised"] == "Table 2.1"
    # Table 2.5's regressions
    assert t.friction.axial == (0.002418, -0.0294, 0.294)
    assert t.friction.rotational == (-0.03423, 0.2181, 0.0542)
    # the other phantoms keep Table 2.1's moduli
    for sp, e in (("0", 32.96), ("0.25", 20.30), ("1", 4.88)):
        assert tissue(f"pvc-sp{sp}").E == pytest.approx(e * KPA, rel=1e-15)
        assert tissue(f"pvc-sp{sp}").sources["E"] == "Table 2.1"


def test_pvc_sp05_forces_match_hand_computation():
    """14G cannula (r_i 0.8, r_o 1.054 mm), θ = 15°, k = 1, x = 10 mm.
    eq. 2.18: F_N = π (0.8 + 1.054) · 0.0129 / 1.5 · 10 = 0.500908099 N;
    Table 2.5 at k = 1: μ_da = 0.267018, μ_dr = 0.23807;
    F_Vcut = μ_da F_N = 0.1337514 N, F_Hcut = μ_dr F_N = 0.1192512 N."""
    t = tissue("pvc-sp0.5")
    th = math.radians(15.0)
    f = t.cutting_forces(1.0, 10.0, r_i=0.8, r_o=1.054, theta=th)
    F_N = math.pi * 1.854 * 0.0129 / 1.5 * 10.0
    assert F_N == pytest.approx(0.500908099058971, rel=1e-12)
    assert float(f["F_N"]) == pytest.approx(F_N, rel=1e-12)
    mu_da, mu_dr = 0.002418 - 0.0294 + 0.294, -0.03423 + 0.2181 + 0.0542
    assert float(f["F_Vcut"]) == pytest.approx(mu_da * F_N, rel=1e-12)
    assert float(f["F_Vcut"]) == pytest.approx(0.13375147, rel=1e-7)
    assert float(f["F_Hcut"]) == pytest.approx(mu_dr * F_N, rel=1e-12)
    # eq. 2.14/2.16 as printed with μ_d = √(μ_da² + μ_dr²) (eq. 2.25)
    mu = math.hypot(mu_da, mu_dr)
    eps = math.atan(math.cos(th))
    den = 2 - mu * math.sqrt(math.cos(th) ** 2 + 1) / (
        math.cos(th) * (mu * math.cos(eps) * math.cos(th) + math.sin(th)))
    F_rup = 0.035 * math.pi * 1.6 / den
    assert float(f["F_Vrup"]) == pytest.approx(F_rup, rel=1e-12)
    assert float(f["F_V"]) == pytest.approx(F_rup + mu_da * F_N, rel=1e-12)
    assert float(f["F_H"]) == pytest.approx(F_rup + mu_dr * F_N, rel=1e-12)
    # with Table 2.1's 13.60 kPa the cutting part would be 5.4 % higher
    assert 13.60 / 12.9 - 1 == pytest.approx(0.05426, abs=1e-5)
    assert rupture_forces(1.0, R=t.R, d_i=1.6, theta=th, mu_d=mu)[0] == pytest.approx(
        F_rup, rel=1e-12)


def test_cutting_forces_refuse_a_tissue_without_the_set():
    with pytest.raises(SpecError, match=r"tissue 'pvc-sp1' lacks R, eta, friction.*pvc-sp0\.5"):
        tissue("pvc-sp1").cutting_forces(0.0, 1.0, r_i=0.8, r_o=1.054, theta=0.26)
