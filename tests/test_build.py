"""Built tips: watertight, labelled, and matching closed-form geometry."""

import math

import numpy as np
import pytest
from scipy.special import ellipe

from tipgeo import (
    BevelCutter,
    BuildError,
    Cannula,
    ConicalCutter,
    LancetCutter,
    MultiPlaneCutter,
    SpecError,
    TipSpec,
    build_tip,
    preset,
    preset_names,
)
from tipgeo.tolerances import DEFAULT_CHORDAL_MM

C14 = Cannula.from_gauge(14)
RO, RI, L = C14.r_o, C14.r_i, C14.length


def edge_vertices(tip, wall="outer"):
    """Vertices shared by a wall triangle and a cut triangle (mm)."""
    cut = np.zeros(len(tip.faces), bool)
    for name in tip.present_labels():
        if name.startswith("cut:"):
            cut |= tip.mask(name)
    a = np.unique(tip.faces[tip.mask(wall)])
    b = np.unique(tip.faces[cut])
    return tip.vertices[np.intersect1d(a, b)]


def hausdorff(tip_a, pts_b):
    """Largest distance from points to tip_a's surface (mm)."""
    import trimesh

    mesh = trimesh.Trimesh(tip_a.vertices, tip_a.faces, process=False)
    _, d, _ = trimesh.proximity.closest_point(mesh, pts_b)
    return float(d.max())


def rotz(p, a):
    c, s = math.cos(a), math.sin(a)
    return p @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T


# -- every sample ------------------------------------------------------------
@pytest.mark.parametrize("name", preset_names())
def test_every_sample_builds_watertight_and_labelled(name, build_preset):
    tip = build_preset(name)
    spec = preset(name)
    assert tip.is_watertight
    assert tip.genus == 1
    assert tip.volume > 0
    expected = {"outer", "inner", "base"} | {lab for c in spec.cutters for lab in c.face_labels()}
    present = set(tip.present_labels())
    assert present == expected, (present, expected)
    import trimesh

    tm = tip.to_trimesh()
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume == pytest.approx(tip.volume, rel=1e-12)
    # every wall vertex lies on the polygonal wall: between the facet's
    # distance r cos(π/n) and the corner radius r, so within the tolerance
    c = spec.cannula
    for label, r in (("outer", c.r_o), ("inner", c.r_i)):
        v = tip.vertices[np.unique(tip.faces[tip.mask(label)])]
        rho = np.hypot(v[:, 0], v[:, 1])
        assert rho.max() <= r + 1e-12
        assert rho.min() >= r * math.cos(math.pi / tip.segments) - 1e-12
        assert r - rho.min() <= tip.tolerance
    vb = tip.vertices[np.unique(tip.faces[tip.mask("base")])]
    assert np.abs(vb[:, 2] + c.length).max() < 1e-12
    assert isinstance(tm, trimesh.Trimesh)


@pytest.mark.parametrize("name", preset_names())
def test_cut_faces_lie_on_the_exact_surfaces(name, build_preset):
    """Every vertex of each cut label satisfies that cutter's exact implicit
    f = 0: to 1e-9 mm on planes (flat facets are exact), to the chordal
    tolerance on curved surfaces (cone, helicoid, serration arcs)."""
    tip = build_preset(name)
    spec = preset(name)
    for k, cutter in enumerate(spec.cutters):
        v = tip.vertices[np.unique(tip.faces[tip.mask(cutter.label)])]
        assert len(v) > 0
        if cutter.kind == "serration":
            f, _ = cutter.implicit(v, spec.cannula, previous=spec.cutters[:k])
        else:
            f, _ = cutter.implicit(v, spec.cannula)
        flat = cutter.kind in ("bevel", "multiplane", "lancet")
        bound = 1e-9 if flat else tip.tolerance * (1 + 1e-6)
        assert np.abs(f).max() <= bound, (cutter.kind, np.abs(f).max())


# -- one-plane bevel ---------------------------------------------------------
XIS = [10, 14.5, 15, 30, 45, 75, 90]


@pytest.mark.parametrize("xi_deg", XIS)
def test_bevel_volume_matches_the_analytic_volume(xi_deg):
    xi = math.radians(xi_deg)
    tip = build_tip(TipSpec(cannula=C14, cutters=[BevelCutter(xi=xi)]))
    cot = 0.0 if xi_deg == 90 else 1 / math.tan(xi)
    # plane height is linear, so the volume is the annulus area times the mean height
    exact = math.pi * (RO ** 2 - RI ** 2) * (L + RO * cot)
    assert tip.volume == pytest.approx(exact, rel=1e-4)
    # and the polygonal annulus gives it to round-off
    n = tip.segments
    poly = 0.5 * n * math.sin(2 * math.pi / n) * (RO ** 2 - RI ** 2) * (L + RO * cot)
    assert tip.volume == pytest.approx(poly, rel=1e-12)


@pytest.mark.parametrize("xi_deg", XIS)
def test_bevel_heel_to_tip_height(xi_deg):
    xi = math.radians(xi_deg)
    tip = build_tip(TipSpec(cannula=C14, cutters=[BevelCutter(xi=xi)]))
    e = edge_vertices(tip, "outer")
    cot = 0.0 if xi_deg == 90 else 1 / math.tan(xi)
    assert e[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert e[:, 2].max() - e[:, 2].min() == pytest.approx(2 * RO * cot, abs=1e-3 * 1e-3)
    # heel at γ = 0 (+x), tip at γ = π
    if xi_deg < 90:
        heel = e[np.argmin(e[:, 2])]
        top = e[np.argmax(e[:, 2])]
        assert heel[:2] == pytest.approx([RO, 0.0], abs=1e-9)
        assert top[:2] == pytest.approx([-RO, 0.0], abs=1e-9)


def test_bevel_edge_vertices_follow_table_3_1():
    """z_o(γ) = r_o (1 − cos γ) cot ξ at every outer-edge vertex."""
    xi = math.radians(15)
    tip = build_tip(TipSpec(cannula=C14, cutters=[BevelCutter(xi=xi)]))
    e = edge_vertices(tip, "outer")
    g = np.arctan2(e[:, 1], e[:, 0])
    z = RO * (1 - np.cos(g)) / math.tan(xi)
    assert np.abs(e[:, 2] - z).max() < 1e-9


def test_bevel_rotation_moves_the_heel():
    tip = build_tip(TipSpec(cannula=C14, cutters=[BevelCutter(xi=math.radians(30),
                                                              rotation=math.pi / 2)]))
    e = edge_vertices(tip, "outer")
    assert e[np.argmin(e[:, 2]), :2] == pytest.approx([0.0, RO], abs=1e-9)


# -- multi-plane ---------------------------------------------------------------
@pytest.mark.parametrize("planes", [2, 3, 4, 5])
def test_multiplane_maps_onto_itself_under_rotation(planes):
    tip = build_tip(TipSpec(cannula=C14, cutters=[MultiPlaneCutter(xi=math.radians(15),
                                                                   count=planes)]))
    # the builder makes the segment count a multiple of P_l: exact symmetry
    assert tip.segments % planes == 0
    rot = rotz(tip.vertices, 2 * math.pi / planes)
    assert hausdorff(tip, rot) < 1e-9 < tip.tolerance
    # and each plane carries the same share of the rake face
    areas = [tip.face_areas[tip.mask(f"cut:multiplane.{k}")].sum() for k in range(planes)]
    assert np.ptp(areas) < 1e-12 * max(areas)


def test_multiplane_edge_heights_eq_2_4():
    """On each plane's span the edge follows the bevel profile of that plane:
    z = r cot ξ (1 − cos(γ − β_k)) with all heels at z = 0."""
    xi = math.radians(15)
    cut = MultiPlaneCutter(xi=xi, count=3)
    tip = build_tip(TipSpec(cannula=C14, cutters=[cut]))
    e = edge_vertices(tip, "outer")
    g = np.arctan2(e[:, 1], e[:, 0])
    beta = np.array(cut.heel_directions())
    d = np.angle(np.exp(1j * (g[:, None] - beta[None, :])))
    local = d[np.arange(len(g)), np.argmin(np.abs(d), axis=1)]
    z = RO * (1 - np.cos(local)) / math.tan(xi)
    assert np.abs(e[:, 2] - z).max() < 1e-9
    assert e[:, 2].min() == pytest.approx(0.0, abs=1e-12)


def test_two_plane_theta_from_eq_2_3():
    from tipgeo.cutters import multiplane_xi_for_theta

    # two planes: θ = 2ξ
    assert math.degrees(multiplane_xi_for_theta(math.radians(30), 2)) == pytest.approx(15)
    xi = multiplane_xi_for_theta(math.radians(75), 3)
    phi = 2 * math.pi / 3
    theta = math.pi - math.acos(math.cos(xi) ** 2 * math.cos(phi) + math.sin(xi) ** 2)
    assert math.degrees(theta) == pytest.approx(75, abs=1e-9)
    with pytest.raises(SpecError, match="theta"):
        multiplane_xi_for_theta(math.radians(15), 3)  # three planes: θ ≥ 60°


def test_asymmetric_multiplane():
    rots = tuple(math.radians(a) for a in (0, 100, 220))
    cut = MultiPlaneCutter(xi=math.radians(20), rotations=rots)
    tip = build_tip(TipSpec(cannula=C14, cutters=[cut]))
    assert set(tip.present_labels()) >= {f"cut:multiplane.{k}" for k in range(3)}
    e = edge_vertices(tip, "outer")
    assert e[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(SpecError, match="rotations"):
        MultiPlaneCutter(xi=0.3, rotations=(0.0, 0.0))


# -- lancet -------------------------------------------------------------------
def test_lancet_keeps_the_point_and_is_mirror_symmetric(build_preset):
    tip = build_preset("lancet-14G")
    xi1 = math.radians(15)
    top = tip.vertices[np.argmax(tip.vertices[:, 2])]
    assert top == pytest.approx([-RO, 0.0, 2 * RO / math.tan(xi1)], abs=1e-9)
    mirrored = tip.vertices * np.array([1.0, -1.0, 1.0])
    assert hausdorff(tip, mirrored) < tip.tolerance
    a_plus = tip.face_areas[tip.mask("cut:lancet.plus")].sum()
    a_minus = tip.face_areas[tip.mask("cut:lancet.minus")].sum()
    assert a_plus == pytest.approx(a_minus, rel=1e-9)


def test_lancet_secondaries_must_stay_above_the_heel():
    with pytest.raises(SpecError, match="secondary_xi"):
        LancetCutter(primary_xi=math.radians(30), secondary_xi=math.radians(10),
                     secondary_rotation=math.radians(20))


# -- conical ------------------------------------------------------------------
def test_conical_volume_and_height():
    theta = math.radians(15)
    tip = build_tip(TipSpec(cannula=C14, cutters=[ConicalCutter(theta=theta)]))
    t = math.tan(theta)
    h = (RO - RI) / t
    cone = math.pi * ((RO ** 2 - RI ** 2) * h - RO * t * h ** 2 + t ** 2 * h ** 3 / 3)
    exact = math.pi * (RO ** 2 - RI ** 2) * L + cone
    assert tip.volume == pytest.approx(exact, rel=1e-4)
    assert tip.bounds[1, 2] == pytest.approx(h, abs=1e-9)
    e = edge_vertices(tip, "outer")
    assert np.abs(e[:, 2]).max() < 1e-9  # the heel circle at z = 0


def test_conical_from_grinding_eq_2_37():
    c = ConicalCutter.from_grinding(phi_g=math.radians(25), varphi=math.radians(10))
    assert math.degrees(c.theta) == pytest.approx(15)
    with pytest.raises(SpecError, match="phi_g"):
        ConicalCutter.from_grinding(phi_g=math.radians(5), varphi=math.radians(10))


def test_punch_land_and_bevel_length(build_preset):
    tip = build_preset("punch-plain")
    assert tip.bounds[1, 2] == pytest.approx(0.6, abs=1e-12)
    v = tip.vertices[np.unique(tip.faces[tip.mask("cut:cone.land")])]
    rho = np.hypot(v[:, 0], v[:, 1])
    assert np.abs(v[:, 2] - 0.6).max() < 1e-12
    assert rho.max() == pytest.approx(1.2 - 0.6 * math.tan(math.radians(13)), abs=1e-9)
    assert rho.min() == pytest.approx(1.0, abs=1e-9)


# -- helical ------------------------------------------------------------------
def test_helical_thesis_example(build_preset):
    """Highest point near γ = 157° (ERRATA.md) and l_c that of the thesis's
    CAD edge (Table 3.1, which the preset is calibrated to)."""
    from tipgeo.calibrate import table_3_1_edge

    spec = preset("helical-14G")
    h = spec.cutters[0]
    g = np.linspace(0, 2 * math.pi, 200001)
    z = h.edge_z(g, RO, C14)
    gamma_top = math.degrees(g[np.argmax(z)])
    assert abs(gamma_top - 157) < 2.0
    assert z.min() == pytest.approx(0.0, abs=1e-9)
    # γ = 0 and γ = 360° are one point: compare the wrapped angle
    heel = (math.degrees(g[np.argmin(z)]) + 180.0) % 360.0 - 180.0
    assert heel == pytest.approx(0.0, abs=0.01)
    pts = np.stack([RO * np.cos(g), RO * np.sin(g), z], 1)
    lc = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    zt = table_3_1_edge(g)
    table_lc = np.linalg.norm(np.diff(np.stack([pts[:, 0], pts[:, 1], zt], 1), axis=0),
                              axis=1).sum()
    assert lc == pytest.approx(table_lc, rel=2e-3)  # measured 18.185 vs 18.174 mm
    # the bevel of equal l_c the thesis compared it with (§3.1.1): within 1 %
    xi = math.radians(14.5)
    a = RO / math.sin(xi)
    bevel_lc = 4 * a * ellipe(1 - (RO / a) ** 2)
    assert lc == pytest.approx(bevel_lc, rel=1e-2)
    # the asymmetric tip: not where the bevel's is
    assert abs(gamma_top - 180) > 10
    # the mesh's outer edge follows the exact helicoid
    tip = build_preset("helical-14G")
    e = edge_vertices(tip, "outer")
    ze = h.edge_z(np.arctan2(e[:, 1], e[:, 0]), RO, C14)
    assert np.abs(e[:, 2] - ze).max() < 20 * DEFAULT_CHORDAL_MM


def test_helical_placement_too_close_is_an_error():
    from tipgeo import HelicalCutter

    with pytest.raises(SpecError, match="helix_position"):
        TipSpec(cannula=C14, cutters=[HelicalCutter(pitch=100, helix_angle=0.1, phi=0.2,
                                                    helix_position=0.5)])


# -- serrations ---------------------------------------------------------------
@pytest.mark.parametrize("cid", ["C1", "C2", "C3", "C4", "C5"])
def test_serrations_count_depth_and_symmetry(cid, build_preset):
    import trimesh

    tip = build_preset(f"punch-{cid}")
    cut = preset(f"punch-{cid}").cutters[1]
    sub = trimesh.Trimesh(*tip.submesh("cut:serrations"), process=True)
    assert len(sub.split(only_watertight=False)) == cut.n
    # notch bottoms: depth below the rim (0.6 mm) on the inner wall
    v = tip.vertices[np.unique(tip.faces[tip.mask("cut:serrations")])]
    assert v[:, 2].min() == pytest.approx(0.6 - cut.depth, abs=2 * DEFAULT_CHORDAL_MM)
    assert tip.segments % cut.n == 0
    rot = rotz(tip.vertices, cut.rho)
    assert hausdorff(tip, rot) < 1e-9


def test_overlapping_serrations_are_an_error():
    from tipgeo import SerrationCutter

    punch = Cannula.biopsy_punch()
    cone = ConicalCutter(theta=math.radians(13), bevel_length=0.6)
    with pytest.raises(SpecError, match=r"count = 16.*overlap.*count ≤ 4"):
        TipSpec(cannula=punch, cutters=[cone, SerrationCutter(arc_radius=0.6, count=16,
                                                              edge_radius=0.015)])
    with pytest.raises(SpecError, match="spacing"):
        TipSpec(cannula=punch, cutters=[cone, SerrationCutter(
            arc_radius=0.15, spacing=math.radians(10))])
    with pytest.raises(SpecError, match="preceding cutter"):
        TipSpec(cannula=punch, cutters=[SerrationCutter(arc_radius=0.1, count=4)])


# -- custom -------------------------------------------------------------------
def test_mesh_cutter_from_trimesh():
    import trimesh

    box = trimesh.creation.box(extents=(10, 10, 20))
    box.apply_translation((0, 0, -10 + 1.25))
    from tipgeo import MeshCutter

    tip = build_tip(TipSpec(cannula=C14, cutters=[MeshCutter(solid_=box, name="flat")]))
    assert tip.bounds[1, 2] == pytest.approx(1.25, abs=1e-12)
    assert "cut:flat" in tip.present_labels()
    assert tip.volume == pytest.approx(math.pi * (RO ** 2 - RI ** 2) * (L + 1.25), rel=1e-4)


def test_sdf_cutter_reproduces_a_bevel():
    from tipgeo import SDFCutter

    b = BevelCutter(xi=math.radians(45))
    p = b.planes(C14)[0]
    n, d = p.normal, p.offset
    s = SDFCutter(sdf=lambda q: q @ n - d, z_range=(-0.05, 2.15), edge_length=0.05)
    tip = build_tip(TipSpec(cannula=C14, cutters=[s]), tolerance=1e-3)
    ref = build_tip(TipSpec(cannula=C14, cutters=[b]), tolerance=1e-3)
    assert tip.is_watertight and tip.genus == 1
    v = tip.vertices[np.unique(tip.faces[tip.mask("cut:sdf")])]
    assert np.abs(v @ n - d).max() < 1e-3
    assert tip.volume == pytest.approx(ref.volume, rel=1e-4)


def test_a_cutter_that_splits_the_ring_is_a_build_error():
    import trimesh

    from tipgeo import MeshCutter

    half = trimesh.creation.box(extents=(10, 10, 40))
    half.apply_translation((5.0 + 0.5, 0, 0))  # keeps only x > 0.5, cuts nothing across
    with pytest.raises(BuildError, match="genus 0.*closed ring"):
        build_tip(TipSpec(cannula=C14, cutters=[MeshCutter(solid_=half)]))


def test_tolerance_sets_the_resolution():
    coarse = build_tip(preset("bevel-14G-xi15"), tolerance=1e-3)
    fine = build_tip(preset("bevel-14G-xi15"))
    assert coarse.segments < fine.segments
    n = fine.segments
    assert RO * (1 - math.cos(math.pi / n)) <= DEFAULT_CHORDAL_MM
    with pytest.raises(SpecError, match="tolerance"):
        build_tip(preset("bevel-14G-xi15"), tolerance=-1)
