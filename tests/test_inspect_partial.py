"""Issue 17: registration of partial scans — the tip alone, one side of the
tube, the bevel face with a rim of wall — with no false warning (the outer
cylinder is fitted to the arc of wall that is there, large flat faces left
out of that fit), the pose checked against the virtual profilometer's truth;
a multi-plane tip's face and rim give the pose up to the tip's own symmetry,
which is reported; what the scan cannot fix to 0.01° (the back of a tube: the
turn about the axis from the bevel's outline alone) is reported as the pose's
uncertainty, and its fit has one optimum; gross outliers in a scan that is registered are warned
about with the figures, and the trimmed statistics stay at the noise.

Each case: a 20,000-point synthetic scan of the 14G bevel (σ = 1 µm),
misaligned 20° about the axis, tilted 1°, shifted 0.1 mm (60,000 before a
bevel slab is cut out of it)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.inspect import (
    ExactSolid,
    Misalignment,
    compare,
    fit_plane,
    load_cad,
    register,
    synthetic_scan,
)

SPEC = "bevel-14G-xi14.5"
MIS = Misalignment(20.0, 1.0, 30.0, (0.1, 0.0, 0.05))


def _ring(az_deg, el_deg):
    az, el = np.radians(az_deg), np.radians(el_deg)
    return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                            np.full(len(az), np.sin(el))])


def _errors(res, s):
    T, Tt = res.registration.transform, s.scan_to_cad
    dR = T[:3, :3] @ Tt[:3, :3].T
    ang = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1.0, 1.0)))
    return ang, np.linalg.norm(T[:3, 3] - Tt[:3, 3])


def _bevel_slab(s, half_width, spec=SPEC, face="cut"):
    """The scan's points within ``half_width`` mm of the plane of the face
    labelled ``face``: the face and a rim of the walls around it."""
    D = ExactSolid(preset(spec)).distances(s.points_cad)
    on = np.asarray(D.label_of()).astype(str) == face if face != "cut" else \
        np.char.startswith(np.asarray(D.label_of()).astype(str), "cut")
    n, off, _, _ = fit_plane(s.points_cad[on])
    return np.abs(s.points_cad @ n - off) < half_width


# (case, scan options, points kept, rotation bound °, translation bound mm)
CASES = {
    "tip only (z ≥ 6 mm of 8.15)": (dict(z_min=6.0), None, 0.01, 0.001),
    "bevel side only": (dict(views=_ring([160.0, 180.0, 200.0], 60.0)), None, 0.01, 0.001),
    "bevel face + 0.2 mm rim": (dict(z_min=0.0), 0.2, 0.01, 0.001),
    "bevel face + 0.1 mm rim": (dict(z_min=0.0), 0.1, 0.01, 0.001),
    # the back of the tube, no bevel face: the turn about the axis and the
    # axial shift come from the bevel's outline alone. The information the
    # 20,000 points hold there fixes the turn to ±0.018° (1σ, the Cramér–Rao
    # bound the registration reports), so the 0.01° is out of reach
    # of any estimator on this scan: 0.0084° and 2.2 µm here; over seeds 1–8
    # median 0.018°, worst 0.039° (it was worst 0.096° before the outline fit)
    "back half, no bevel face": (dict(views=_ring([-30.0, 0.0, 30.0], 30.0)), None, 0.02,
                                 0.003),
}
BACK = "back half, no bevel face"


@functools.cache
def _scan(case):
    opts, slab = CASES[case][:2]
    s = synthetic_scan(preset(SPEC), points=20_000 if slab is None else 60_000, noise=0.001,
                       misalignment=MIS, seed=3, **opts)
    return s, (s.points if slab is None else s.points[_bevel_slab(s, slab)])


@pytest.mark.parametrize("case", list(CASES))
def test_partial_scan_registers_without_false_warnings(case):
    """The pose within the bound; the reported 1σ uncertainty of the
    rotation says whether the scan fixes it to the issue's 0.01°: well below
    (a third of it) where a face shows, above it for the back of the tube."""
    max_deg, max_mm = CASES[case][2:]
    s, pts = _scan(case)
    res = compare(pts, preset(SPEC), pictures=False)
    assert res.warnings == []
    assert res.match["ok"]
    ang, off = _errors(res, s)
    assert ang <= max_deg and off <= max_mm
    unc = res.registration.to_dict()["uncertainty"]
    if case == BACK:
        # the outline alone: the turn is the weak direction, the tilt is not
        assert 0.01 < unc["turn_about_axis_deg"] < 0.03
        assert max(unc["rotation_deg"][:2]) < 0.001
    else:
        assert max(unc["rotation_deg"]) < 0.01 / 3


def test_an_outline_only_pose_has_one_optimum():
    """The back of the tube: before the outline was fitted as a blurred step,
    the fit stopped wherever the outline first covered every point — the
    registration's own random subsets (its seed) moved the turn by 0.39° and
    the axial shift by 26 µm. Now every seed reaches the same pose (to the
    ICP's convergence, 1e-7 rad and 1e-6 mm)."""
    s, pts = _scan(BACK)
    cad = load_cad(preset(SPEC))
    T = [register(pts, cad, seed=k).transform for k in (0, 1)]
    dR = T[1][:3, :3] @ T[0][:3, :3].T
    assert math.degrees(math.acos(min(1.0, (np.trace(dR) - 1) / 2))) < 1e-4
    assert np.linalg.norm(T[1][:3, 3] - T[0][:3, 3]) < 1e-4


def test_a_multiplane_face_and_rim_give_the_pose_up_to_the_symmetry():
    """One of the three planes of a 3-fold tip with a 0.1 mm rim: the three
    planes are alike, so the pose is found up to a turn of 120° about the
    axis — within 0.01° of the truth modulo that turn — and the report says
    so (no warning: it changes no deviation)."""
    spec = "threeplane-14G-xi15"
    s = synthetic_scan(preset(spec), points=60_000, noise=0.001, misalignment=MIS, seed=3,
                       z_min=0.0)
    res = compare(s.points[_bevel_slab(s, 0.1, spec, "cut:multiplane.0")], preset(spec),
                  pictures=False)
    assert res.warnings == [] and res.match["ok"]
    sym = res.registration.to_dict()["symmetry"]
    assert sym["order"] == 3 and sym["turn_deg"] == pytest.approx(120.0, abs=1e-12)
    assert "up to a turn of 120°" in sym["note"]
    T, Tt = res.registration.transform, s.scan_to_cad
    errs = []
    for k in range(3):
        c, si = math.cos(2 * math.pi * k / 3), math.sin(2 * math.pi * k / 3)
        Rz = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]])
        dR = Rz @ T[:3, :3] @ Tt[:3, :3].T
        errs.append(math.degrees(math.acos(min(1.0, (np.trace(dR) - 1) / 2))))
    assert min(errs) <= 0.01
    assert sorted(errs)[1] > 100.0  # the other two are the symmetric poses


def test_gross_outliers_in_a_registered_scan_warn_and_trim():
    """5 % of the points 1–2 mm off the tube (radially): the pose is still
    within 0.01° and 1 µm, the comparison warns with the figures (share,
    count, cut-off), and with the cut-off widened to take them in, the full
    RMS blows up while the trimmed one stays at the noise (σ = 1 µm along the
    line of sight: the RMS of the comparison that left them out)."""
    s = synthetic_scan(preset(SPEC), points=20_000, noise=0.001, misalignment=MIS, seed=4)
    rng = np.random.default_rng(5)
    k = 1000
    q = s.points_cad[:k].copy()
    rho = np.hypot(q[:, 0], q[:, 1])[:, None]
    q[:, :2] += q[:, :2] / rho * rng.uniform(1.0, 2.0, (k, 1))
    pts = s.points.copy()
    pts[:k] = q @ s.cad_to_scan[:3, :3].T + s.cad_to_scan[:3, 3]
    res = compare(pts, preset(SPEC), pictures=False)
    ang, off = _errors(res, s)
    assert ang <= 0.01 and off <= 0.001
    msg = [w for w in res.warnings if "farther than" in w]
    assert len(msg) == 1 and "5.00 %" in msg[0] and "1,000 of 20,000" in msg[0]
    assert "0.5 mm" in msg[0]
    assert res.dropped["far"] == k
    clean_rms = res.stats["all"]["rms_um"]   # the noise along the normals
    assert 0.4 < clean_rms < 1.0
    wide = compare(pts, res.cad, pictures=False, max_distance=3.0, register_scan=False,
                   init_transform=res.registration.transform)   # the same pose
    assert not any("farther than" in w for w in wide.warnings)
    assert wide.stats["all"]["rms_um"] > 200
    tr = wide.stats["trimmed"]
    assert tr["rms_um"] == pytest.approx(clean_rms, rel=0.1)
    assert tr["trimmed_share"] == pytest.approx(0.05, abs=0.005)


@functools.cache
def _wide_scan():
    """60,000 points from z = −1 mm (below the heel at 0) to the tip."""
    return synthetic_scan(preset(SPEC), points=60_000, noise=0.001, misalignment=MIS, seed=3,
                          z_min=-1.0)


def test_a_side_only_scan_registers_up_to_what_it_leaves_free():
    """The tube alone (the points below z = −0.2 mm, no cut face, no
    outline): its axis onto the CAD's, the turn about it and the shift along
    it reported free — not refused, not slid up into the bevel (which made
    it a 66 µm RMS "misfit" called ambiguous) — and a pass: the tube's
    deviations do not depend on what is free."""
    s = _wide_scan()
    m = s.points_cad[:, 2] < -0.2
    res = compare(s.points[m], preset(SPEC), pictures=False)
    reg = res.registration
    assert reg.search.get("tube_only") is True
    free = " ".join(reg.fixed_directions)
    assert "rotation about the axis" in free and "translation along the axis" in free
    assert any(w.startswith("free: rotation about the axis and translation along the axis")
               for w in reg.warnings)
    assert res.stats["all"]["rms_um"] < 1.0          # σ = 1 µm along the line of sight
    # the axis is the true one (to 0.01°), whatever the free turn and shift
    ez = np.array([0.0, 0.0, 1.0])
    a_true = s.scan_to_cad[:3, :3].T @ ez
    a_reg = reg.transform[:3, :3].T @ ez
    assert math.degrees(math.acos(min(1.0, abs(a_true @ a_reg)))) < 0.01
    assert res.verdict.ok, res.verdict.reasons


def test_a_face_only_scan_registers_by_its_outline():
    """The bevel face alone (the points on it, off its edges: a plane) was
    refused ("the points lie on a plane"). Its outline against the walls
    fixes the pose up to the face's own half-turn symmetry about its normal
    (an elliptic ring), which is reported free; the pose is within 0.01° and
    1 µm of the truth or of that half turn."""
    s = _wide_scan()
    D = ExactSolid(preset(SPEC)).distances(s.points_cad)
    lab = np.asarray(D.label_of()).astype(str)
    m = np.char.startswith(lab, "cut") & (D.feature == 0)
    res = compare(s.points[m], preset(SPEC), pictures=False)
    reg = res.registration
    assert reg.search.get("face_only") == "cut:bevel"
    assert any("a turn of 180.0° about its normal" in f for f in reg.fixed_directions)
    assert res.stats["all"]["rms_um"] < 1.0
    assert res.verdict.ok, res.verdict.reasons
    T, Tt = reg.transform, s.scan_to_cad
    n = ExactSolid(preset(SPEC)).distances(s.points_cad[m][:1]).normal[0]
    c = s.points_cad[m].mean(axis=0)
    errs = []
    for k in (0, 1):
        H = np.eye(4)   # a half turn about the face normal through its centroid
        R = _half(n) if k else np.eye(3)
        H[:3, :3], H[:3, 3] = R, c - R @ c
        E = H @ T @ np.linalg.inv(Tt)
        ang = math.degrees(math.acos(min(1.0, (np.trace(E[:3, :3]) - 1) / 2)))
        errs.append((ang, float(np.abs(apply_(E, s.points_cad[m]) - s.points_cad[m]).max())))
    best = min(errs)
    assert best[0] <= 0.01 and best[1] <= 0.001


def _half(n):
    n = n / np.linalg.norm(n)
    return 2 * np.outer(n, n) - np.eye(3)


def apply_(T, p):
    return p @ T[:3, :3].T + T[:3, 3]


@functools.cache
def _window_scan():
    """A 150,000-point scan of the 14G bevel (ξ = 15°, σ = 2 µm) in a pose
    (35° about the axis, 1° of tilt, (0.1, −0.1, 0.2) mm), and its points in
    the CAD frame by the scanner's truth."""
    from tipgeo.inspect.register import apply

    g = synthetic_scan(preset("bevel-14G-xi15"), points=150_000, noise=0.002, seed=7,
                       misalignment=Misalignment(35.0, 1.0, 60.0, (0.1, -0.1, 0.2)))
    return g.points, apply(g.scan_to_cad, g.points)


@pytest.mark.parametrize(("z_lo", "z_hi"), [(-1.0, 0.5), (2.5, 4.0)])
def test_a_window_short_of_the_tip_registers_and_passes(z_lo, z_hi):
    """A profilometer's field on the heel (the tube and the bevel's lowest
    0.5 mm) or on the middle of the face (z 2.5–4 mm of a 7.4 mm bevel),
    without the tip: the search that hangs the scan's top on the CAD's top
    finds no pose (best scores 0.16–0.19 mm), so turns and shifts are
    searched together. Before that, the heel window registered 2.5 mm off
    (RMS 84 µm) and the middle one right but from starts that left it
    "not certain": both failed. Now the pose is the scanner's to 1 µm at
    every point and the verdict passes."""
    from tipgeo.inspect.register import apply

    pts, truth = _window_scan()
    keep = (truth[:, 2] > z_lo) & (truth[:, 2] < z_hi)
    res = compare(pts[keep], preset("bevel-14G-xi15"), pictures=False)
    err = np.abs(apply(res.registration.transform, pts[keep]) - truth[keep]).max()
    assert err < 0.001
    # the deviations are those at the scanner's pose (the noise), to 0.01 µm
    at_truth = load_cad(preset("bevel-14G-xi15")).distances(truth[keep]).distance
    rms_truth = float(np.sqrt(np.mean(at_truth ** 2))) * 1e3
    assert res.stats["all"]["rms_um"] == pytest.approx(rms_truth, abs=0.01)
    assert any(k.startswith("window_turns") for k in res.registration.search)
    assert res.verdict.ok, res.verdict.line()
    # the pass says what the window does not show: most of the rim
    assert any(s.startswith("rim edge (the scan covers") for s in res.verdict.not_judged)
    assert "; not judged: rim edge" in res.verdict.line()
