"""Needle-grinding CAM: frames, eq. 2.35–2.38, programs, simulation vs CAD."""

import json
import math

import numpy as np
import pytest

from cam import CamError, Machine, compare_with_cad, make_program, simulate
from cam.machine import f_surf, face_plane, plane_2_36, wheel_from_needle
from tipgeo import BevelCutter, Cannula, TipSpec, preset
from tipgeo.cli import main

PHI = math.radians(10.0)


@pytest.mark.parametrize("xi_deg", [15.0, 45.0, 75.0])
def test_eq_2_35_reduces_to_two_lines_at_y0(xi_deg):
    """At Y = 0 eq. 2.35 is the union of eq. 2.36 as printed (the far
    generator, at ϕ_g + φ) and the near generator through O, at ξ = ϕ_g − φ
    (eq. 2.37) — the plane the wheel grinds."""
    phi_g = math.radians(xi_deg) + PHI
    H = 46.0 / math.sin(PHI)
    rng = np.random.default_rng(1)
    X = rng.uniform(-3, 3, 200)
    # points on the near generator: Z = X cot(ϕ_g − φ)
    Zn = X / math.tan(phi_g - PHI)
    assert np.abs(f_surf(X, 0 * X, Zn, PHI, H, phi_g)).max() < 1e-9
    far, near = plane_2_36(X, Zn, PHI, H, phi_g)
    assert np.abs(near).max() < 1e-9
    # eq. 2.36 as printed: where |…|'s argument X cos φ + Z sin φ − H sin φ is
    # positive (beyond the spindle axis) its points satisfy eq. 2.35; its angle
    # to Z is ϕ_g + φ
    s, c, t = math.sin(PHI), math.cos(PHI), math.tan(phi_g)
    Zf = np.linspace(-5 * H, 5 * H, 4001)
    Xf = (2 * H * s - Zf * (c * t + s)) / (c - s * t)
    beyond = Xf * c + Zf * s - H * s > 0
    assert beyond.sum() > 100
    Xf, Zf = Xf[beyond], Zf[beyond]
    assert np.abs(f_surf(Xf, 0 * Xf, Zf, PHI, H, phi_g)).max() < 1e-9 * H
    assert np.abs(plane_2_36(Xf, Zf, PHI, H, phi_g)[0]).max() < 1e-9 * H
    slope = np.polyfit(Zf, Xf, 1)[0]
    far_deg = math.degrees(phi_g + PHI)
    assert math.degrees(math.atan(abs(slope))) == pytest.approx(min(far_deg, 180 - far_deg),
                                                               abs=1e-9)
    # off Y = 0 the cone leaves the plane: not a plane in Y
    assert abs(f_surf(1.0, 1.0, 1.0 / math.tan(phi_g - PHI), PHI, H, phi_g)) > 1e-4


def test_frame_table_eq_2_31_to_2_34():
    phi_g = math.radians(25)
    H = 200.0
    o = wheel_from_needle(np.zeros(3), PHI, H, phi_g)[0]
    x0 = -H * math.sin(PHI)
    assert o == pytest.approx([x0, 0.0, x0 / math.tan(phi_g)], abs=1e-12)
    # O lies on the wheel cone Z* = −ρ*/tan ϕ_g (eq. 2.30) at ρ* = H sin φ
    assert o[2] == pytest.approx(-math.hypot(o[0], o[1]) / math.tan(phi_g), abs=1e-12)
    # the rotation part is orthonormal: distances are kept
    p = np.array([[1.0, 2.0, 3.0], [-0.5, 0.1, 4.0]])
    q = wheel_from_needle(p, PHI, H, phi_g)
    assert np.linalg.norm(q[0] - q[1]) == pytest.approx(np.linalg.norm(p[0] - p[1]), rel=1e-14)


def test_face_plane_is_the_cad_plane():
    xi, beta, h = math.radians(15), 1.0, 3.9
    m, d = face_plane(phi=PHI, phi_g=xi + PHI, r3=0.0, r4=beta + math.pi, t1=-h, t2=0.0)
    want = [math.cos(xi) * math.cos(beta), math.cos(xi) * math.sin(beta), math.sin(xi)]
    assert m == pytest.approx(want, abs=1e-14)
    assert d == pytest.approx(h * math.sin(xi), abs=1e-14)


@pytest.mark.parametrize("name, hausdorff_bound", [
    ("bevel-14G-xi15", 2e-3), ("bevel-14G-xi45", 2e-3), ("bevel-14G-xi75", 2e-3),
    ("twoplane-14G-xi15", 2e-3), ("threeplane-14G-xi15", 2e-3), ("lancet-14G", 2e-3),
    ("conical-14G-theta15", 5e-3),
])
def test_simulated_grind_matches_cad(name, hausdorff_bound):
    spec = preset(name)
    prog = make_program(spec)
    ground = simulate(prog, spec)
    assert ground.is_watertight and ground.genus == 1
    cmp = compare_with_cad(ground, spec)
    # measured: ~1e-14 mm and ~1e-11°: the kinematic chain is exact
    assert cmp["hausdorff_mm"] < min(hausdorff_bound, 1e-9)
    for wall in ("outer", "inner"):
        for v in cmp["angles_max_diff_deg"][wall].values():
            assert v < min(0.05, 1e-8)
        assert cmp[f"l_c_{wall}_mm"]["ground"] == pytest.approx(
            cmp[f"l_c_{wall}_mm"]["cad"], rel=1e-9)


def test_program_contents_and_outputs():
    spec = preset("threeplane-14G-xi15")
    prog = make_program(spec, feed=0.1)
    s = prog.summary()
    assert s["faces"] == 3
    r4s = sorted(round(f["r4_deg"], 6) for f in s["setup"])
    assert r4s == [60.0, 180.0, 300.0]
    assert {round(f["r5_phi_g_deg"], 9) for f in s["setup"]} == {25.0}
    feed_rows = [r for r in prog.rows if r["feed"] is not None]
    assert len(feed_rows) == 3 and all(r["t1"] == pytest.approx(-RO_COT15) for r in feed_rows)
    # time: 3 feeds of 0.5 mm at 0.1 mm/s plus rapids at 5 mm/s
    assert prog.rows[-1]["t"] == pytest.approx(3 * 5.0 + 3 * 0.1 + 0.0, rel=1e-9)
    data = json.loads(prog.to_json())
    assert data["units"]["t1"] == "mm" and len(data["rows"]) == len(prog.rows)
    g = prog.to_gcode()
    import re

    assert "B25.0000" in g and "F6.000" in g and not re.search(r"\d[eE][-+]?\d", g)
    sheet = prog.setup_sheet()
    assert "| cut:multiplane.0 |" in sheet and "OC" in sheet
    csv = prog.to_csv().splitlines()
    assert csv[0] == "t,t1,t2,r3,r4,r5,spindle_rpm,needle_rpm,feed"
    assert len(csv) == 1 + len(prog.rows)


RO_COT15 = 1.054 / math.tan(math.radians(15))


def test_conical_spins_the_needle():
    prog = make_program(preset("conical-14G-theta15"), needle_rpm=1000)
    assert any(r["needle_rpm"] == 1000 for r in prog.rows if r["feed"])


@pytest.mark.parametrize("kw, match", [
    ({"feed": 1.0}, "feed = 1 mm/s is outside"),
    ({"feed": 0.01}, "feed"),
    ({"needle_rpm": 5000}, "needle_rpm"),
])
def test_bad_requests_name_the_limit(kw, match):
    with pytest.raises(CamError, match=match):
        make_program(preset("bevel-14G-xi15"), **kw)


def test_unreachable_angles_and_kinds():
    blunt = TipSpec(cannula=Cannula.from_gauge(14), cutters=[BevelCutter(xi=math.pi / 2)])
    with pytest.raises(CamError, match=r"r5 = ϕ_g = 100°.*\[10.5, 95\]"):
        make_program(blunt)
    with pytest.raises(CamError, match="flat land"):
        make_program(preset("punch-plain"))
    from tipgeo import ConicalCutter, SerrationCutter

    serrated = TipSpec(cannula=Cannula.biopsy_punch(), cutters=[
        ConicalCutter(theta=math.radians(13)), SerrationCutter(arc_radius=0.1, count=8)])
    with pytest.raises(CamError, match="serration"):
        make_program(serrated)
    with pytest.raises(CamError, match="helical"):
        make_program(preset("helical-14G"))
    tight = Machine(t1=Machine().t1.__class__(-2.0, 5.0, 1e-4))
    with pytest.raises(CamError, match=r"axis t1 = .* outside its travel \[-2, 5\] mm"):
        make_program(preset("bevel-14G-xi15"), machine=tight)


def test_machine_from_toml(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text('contact_radius = 40.0\nfeed_max_mm_min = 18.0\n[r5]\nlo = 12.0\nhi = 60.0\n'
                 'resolution = 0.001\n')
    m = Machine.from_toml(p)
    assert m.contact_radius == 40.0 and m.r5.hi == 60.0
    assert m.feed_max == pytest.approx(0.3, rel=1e-12)       # 18 mm/min
    assert m.H == pytest.approx(40.0 / math.sin(PHI))
    with pytest.raises(CamError, match="r5"):
        make_program(preset("bevel-14G-xi75"), machine=m)
    (tmp_path / "bad.toml").write_text("colour = 1\n")
    with pytest.raises(CamError, match="colour"):
        Machine.from_toml(tmp_path / "bad.toml")


def test_cli_grind(tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["grind", "lancet-14G", "-o", str(out), "--gcode", str(tmp_path / "p.nc"),
                 "--sheet", str(tmp_path / "s.md"), "--mesh", str(tmp_path / "g.stl"),
                 "--compare"]) == 0
    text = capsys.readouterr().out
    assert "Hausdorff" in text and "faces 3" in text
    assert json.loads(out.read_text())["summary"]["faces"] == 3
    assert (tmp_path / "g.stl").stat().st_size > 1000
    assert main(["grind", "punch-C2", "-o", str(out)]) == 2
    assert "flat land" in capsys.readouterr().err


# -- verdicts -------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["lancet-14G", "conical-14G-theta15"])
def test_grind_verdict_passes_when_the_ground_tip_is_cad(name):
    """The simulated ground tip of the program is CAD to round-off: Hausdorff
    far below the 0.15 µm bound (t1/t2 resolution 0.1 µm + the meshes'
    0.05 µm chordal tolerance), λ θ α of the exact ground faces far within
    the 0.001° of the rotary axes."""
    from cam import grind

    res = grind(preset(name))
    v = res.verdict
    assert v.ok, v.reasons
    assert v.checks[0].name == "hausdorff_um" and v.checks[0].rule == "hausdorff_um ≤ 0.15"
    assert v.checks[0].value < 1e-6
    assert {c.rule.split(" ≤ ")[1] for c in v.checks[1:]} == {"0.001"}
    assert len(v.checks) == 7
    assert res.summary()["verdict"] == v.to_dict()


def test_grind_verdict_fails_against_another_tip():
    """The 15° bevel's program judged against the 14.5° bevel's CAD: the
    faces differ by 0.5°, and the verdict says so with the figures."""
    from cam import grind

    res = grind(preset("bevel-14G-xi15"), compare=False)
    assert res.verdict is None and "verdict" not in res.summary()
    res.comparison = compare_with_cad(res.ground, preset("bevel-14G-xi14.5"))
    v = res.verdict
    assert not v.ok
    failed = {c.name for c in v.failed}
    assert "hausdorff_um" in failed and "outer_theta_diff_deg" in failed
    assert any(r.startswith("Hausdorff distance ground vs CAD (µm) = ") for r in v.reasons)
    assert res.comparison["angles_max_diff_deg"]["outer"]["theta"] == pytest.approx(0.5,
                                                                                    abs=0.05)
