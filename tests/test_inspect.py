"""Signed deviations: exact distances against an independent brute force,
robust signs at the knife edge, statistics."""

import functools
import math

import numpy as np
import pytest

from tipgeo import build_tip, preset
from tipgeo.inspect import ExactSolid, MeshSolid, statistics
from tipgeo.inspect.deviation import STAT_KEYS

# -----------------------------------------------------------------------------
# an independent brute force: every triangle of a very fine mesh, closest
# points by projection onto the plane or onto the three edge segments (not the
# Voronoi-region test the library uses), signs by the winding number.


def _seg_closest(p, a, b):
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return a + t[:, None] * ab


def _brute_unsigned(points, tris):
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    good = nn > 0
    a, b, c, n, nn = a[good], b[good], c[good], n[good], nn[good]
    out = np.empty(len(points))
    for i, p in enumerate(points):
        # projection onto the plane; inside test by edge-normal signs
        q = p - (np.einsum("ij,j->i", n, p) - np.einsum("ij,ij->i", n, a))[:, None] * n / \
            nn[:, None]
        s1 = np.einsum("ij,ij->i", np.cross(b - a, q - a), n)
        s2 = np.einsum("ij,ij->i", np.cross(c - b, q - b), n)
        s3 = np.einsum("ij,ij->i", np.cross(a - c, q - c), n)
        inside = (s1 >= 0) & (s2 >= 0) & (s3 >= 0)
        d = np.where(inside, np.linalg.norm(q - p, axis=1), np.inf)
        pp = np.broadcast_to(p, a.shape)
        for u, v in ((a, b), (b, c), (c, a)):
            d = np.minimum(d, np.linalg.norm(_seg_closest(pp, u, v) - p, axis=1))
        out[i] = d.min()
    return out


def _winding(points, tris):
    """Generalised winding number (van Oosterom & Strackee solid angles)."""
    w = np.empty(len(points))
    for i, p in enumerate(points):
        a, b, c = tris[:, 0] - p, tris[:, 1] - p, tris[:, 2] - p
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
               + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb)
        w[i] = np.sum(2 * np.arctan2(num, den)) / (4 * math.pi)
    return w


@functools.cache
def _tip(name, tolerance=None):
    return build_tip(preset(name), tolerance=tolerance, strict=False)


def _near_surface(tip, n, spread, rng, z_min=-1.0):
    """Points scattered around the tip surface (most within ``spread``)."""
    tri = tip.triangles
    sel = np.flatnonzero(tri[:, :, 2].max(axis=1) > z_min)
    area = tip.face_areas[sel]
    k = rng.choice(sel, n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    p = tri[k, 0] * (1 - s)[:, None] + tri[k, 1] * (s * (1 - r2))[:, None] \
        + tri[k, 2] * (s * r2)[:, None]
    return p + rng.normal(0, spread, p.shape)


def _near_edges(tip, n, spread, rng):
    """Points scattered around the cutting edges: vertices shared by a cut
    triangle and a wall triangle (or two cut faces), moved randomly."""
    lab = tip.labels
    cut = np.array([str(x).startswith("cut:") for x in lab])
    ids = tip.label_ids
    inc = {}
    for col in range(3):
        for v, l_ in zip(tip.faces[:, col], ids):
            inc.setdefault(int(v), set()).add(int(l_))
    cut_ids = set(np.unique(ids[cut]).tolist())
    edge_v = [v for v, s in inc.items() if len(s) >= 2 and s & cut_ids]
    k = rng.choice(edge_v, n)
    return tip.vertices[k] + rng.normal(0, spread, (n, 3))


FINE = 4e-7  # mm: the brute force's mesh lies within this of the exact surfaces


@pytest.mark.parametrize("name", ["bevel-14G-xi14.5", "threeplane-14G-xi15", "lancet-14G",
                                  "conical-14G-theta15", "punch-plain"])
def test_exact_distances_match_brute_force(name):
    """|d| within 1e-6 mm of an all-triangle brute force on a mesh built to
    0.4 nm, signs equal to the winding number's, on faces, edges and corners."""
    rng = np.random.default_rng(7)
    tip = _tip(name)
    pts = np.vstack([_near_surface(tip, 100, 0.01, rng), _near_surface(tip, 30, 0.1, rng),
                     _near_edges(tip, 100, 0.005, rng)])
    D = ExactSolid(preset(name)).distances(pts)
    fine = _tip(name, FINE).triangles
    brute = _brute_unsigned(pts, fine)
    assert np.max(np.abs(np.abs(D.distance) - brute)) <= 1e-6
    wind = _winding(pts, fine)
    assert np.all(np.sign(D.distance) == np.where(wind > 0.5, -1.0, 1.0))
    # the closest points lie on the reported faces and the distance is |p − closest|
    assert np.allclose(np.abs(D.distance), np.linalg.norm(pts - D.closest, axis=1),
                       rtol=0, atol=1e-12)
    assert set(np.unique(D.feature)) <= {0, 1, 2}
    assert (D.feature == 1).any()  # edges were exercised


def test_statistics_match_brute_force():
    """The statistics of the exact path equal those of the brute force
    (within 1e-3 µm), overall and per face."""
    rng = np.random.default_rng(11)
    name = "bevel-14G-xi14.5"
    tip = _tip(name)
    pts = _near_surface(tip, 240, 0.004, rng)
    D = ExactSolid(preset(name)).distances(pts)
    fine = _tip(name, FINE)
    brute = _brute_unsigned(pts, fine.triangles)
    sign = np.where(_winding(pts, fine.triangles) > 0.5, -1.0, 1.0)
    d_ref = sign * brute
    tol = 0.005
    got = statistics(D.distance, D.label_of(), tol)["all"]
    um = d_ref * 1e3
    ref = {"count": len(um), "mean_um": um.mean(), "std_um": um.std(),
           "rms_um": np.sqrt(np.mean(um ** 2)), "min_um": um.min(), "max_um": um.max(),
           "p5_um": np.percentile(um, 5), "p95_um": np.percentile(um, 95),
           "mean_abs_um": np.mean(np.abs(um)), "p95_abs_um": np.percentile(np.abs(um), 95),
           "within_tol_share": np.mean(np.abs(d_ref) <= tol)}
    assert set(got) == set(STAT_KEYS)
    for k in STAT_KEYS:
        assert got[k] == pytest.approx(ref[k], abs=1e-3), k
    regions = statistics(D.distance, D.label_of(), tol)["regions"]
    assert sum(b["count"] for b in regions.values()) == len(pts)
    assert set(regions) <= {"outer", "inner", "cut:bevel", "base"}


def test_mesh_path_equals_all_triangle_brute_force():
    """The mesh path (BVH candidates, certified) finds exactly the brute-force
    distance and the winding number's sign."""
    rng = np.random.default_rng(3)
    tip = _tip("bevel-14G-xi14.5")
    pts = np.vstack([_near_surface(tip, 200, 0.01, rng), _near_surface(tip, 30, 0.3, rng)])
    D = MeshSolid(tip).distances(pts)
    brute = _brute_unsigned(pts, tip.triangles)
    assert np.max(np.abs(np.abs(D.distance) - brute)) <= 1e-12
    wind = _winding(pts, tip.triangles)
    assert np.all(np.sign(D.distance) == np.where(wind > 0.5, -1.0, 1.0))


def test_mesh_and_exact_paths_differ_by_the_chordal_tolerance_only():
    rng = np.random.default_rng(5)
    tip = _tip("bevel-14G-xi14.5")  # default 0.05 µm
    pts = _near_surface(tip, 3000, 0.005, rng)
    de = ExactSolid(preset("bevel-14G-xi14.5")).distances(pts)
    dm = MeshSolid(tip).distances(pts)
    assert np.max(np.abs(de.distance - dm.distance)) <= tip.tolerance * 1.001
    assert np.mean(de.label_of() == dm.label_of()) > 0.99


def _knife(spec, wall, gamma):
    """Edge point, unit outward bisector and half wedge angle at the cutting
    edge of ``wall`` at angle gamma (cannula frame)."""
    cn, cut = spec.cannula, spec.cutters[0]
    r = cn.r_o if wall == "outer" else cn.r_i
    z = cut.edge_z(np.array([gamma]), r, cn)[0]
    e = np.array([r * math.cos(gamma), r * math.sin(gamma), z])
    n_c = cut.planes(cn)[0].normal
    rad = np.array([math.cos(gamma), math.sin(gamma), 0.0])
    n_w = rad if wall == "outer" else -rad
    bis = (n_c + n_w) / np.linalg.norm(n_c + n_w)
    half = 0.5 * (math.pi - math.acos(np.clip(n_c @ n_w, -1, 1)))
    return e, bis, half, n_c, n_w


@pytest.mark.parametrize("wall", ["outer", "inner"])
@pytest.mark.parametrize("gamma_deg", [20.0, 90.0, 150.0, 175.0, 179.5, 180.0, 200.0, 300.0])
def test_signs_at_the_knife_edge(wall, gamma_deg):
    """Inside the wedge — also exactly on its bisector, where the cut facet
    and the wall facet tie as nearest — the deviation is negative; outside,
    beyond the edge, positive and equal to the distance to the edge. Both the
    exact and the mesh path."""
    spec = preset("bevel-14G-xi14.5")
    e, bis, half, n_c, n_w = _knife(spec, wall, math.radians(gamma_deg))
    t = np.array([1e-5, 1e-4, 1e-3, 5e-3])
    inside = e - t[:, None] * bis
    outside = e + t[:, None] * bis
    ex = ExactSolid(spec)
    di, do = ex.distances(inside), ex.distances(outside)
    assert np.all(di.distance < 0)
    assert np.all(do.distance > 0)
    # on the bisector the two faces tie (for small t): analytic distances to
    # the plane and the cylinder
    plane = spec.cutters[0].planes(spec.cannula)[0]
    rho = np.hypot(inside[:, 0], inside[:, 1])
    r = spec.cannula.r_o if wall == "outer" else spec.cannula.r_i
    expect = np.minimum(plane.offset - inside @ plane.normal,
                        r - rho if wall == "outer" else rho - r)
    assert np.allclose(-di.distance, expect, rtol=1e-9, atol=1e-15)
    assert np.allclose(-di.distance[:2], t[:2] * math.sin(half), rtol=1e-3)
    assert np.allclose(do.distance, t, rtol=1e-6, atol=1e-12)
    assert np.all(do.feature == 1)
    mesh = MeshSolid(_tip("bevel-14G-xi14.5"))
    mi, mo = mesh.distances(inside), mesh.distances(outside)
    assert np.all(mi.distance[t > 1e-4] < 0) and np.all(mo.distance[t > 1e-4] > 0)
    # judged by one of the two tied facets alone, half of these points would
    # get the wrong sign: the bisector leans outside the other facet's plane
    assert np.all((inside - e) @ n_c < 0) and np.all((inside - e) @ n_w < 0)


def test_points_far_from_the_tip_and_on_the_axis():
    spec = preset("bevel-14G-xi14.5")
    ex = ExactSolid(spec)
    pts = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -5.0], [0.0, 0.0, 12.0], [-5.0, 0.0, 2.0]])
    d = ex.distances(pts)
    assert d.distance[0] == pytest.approx(spec.cannula.r_i, abs=1e-12)
    assert d.distance[1] == pytest.approx(spec.cannula.r_i, abs=1e-12)
    assert d.distance[3] == pytest.approx(5.0 - spec.cannula.r_o, abs=1e-12)
    assert np.all(np.isfinite(d.distance))


def test_contains_and_bound_are_consistent():
    rng = np.random.default_rng(2)
    spec = preset("lancet-14G")
    ex = ExactSolid(spec)
    pts = _near_surface(_tip("lancet-14G"), 2000, 0.02, rng)
    d = ex.distances(pts)
    assert np.array_equal(ex.contains(pts), d.distance <= 0)
    b = ex.bound(pts)
    assert np.all(b <= d.distance + 1e-12)
    assert np.allclose(b[d.distance <= 0], d.distance[d.distance <= 0], atol=1e-12)


def test_unsupported_cutters_fall_back_to_the_mesh():
    from tipgeo.inspect import UnsupportedCutter, load_cad

    with pytest.raises(UnsupportedCutter, match="serration"):
        ExactSolid(preset("punch-C2"))
    cad = load_cad(preset("punch-C2"))
    assert not cad.exact and cad.method.startswith("mesh")
    assert cad.symmetry == 16
    assert any("serration" in n for n in cad.notes)


def test_helicoid_distances_are_exact():
    """The helical tip's helicoid has no closed-form distance: faces by
    foot-point iteration, edges on the exact edge curve. Checked against
    independent minimisations over the heightfield z = h(x, y) and along the
    edge z(γ) (both exact in the cutter)."""
    from scipy.optimize import least_squares, minimize_scalar

    spec = preset("helical-14G")
    cut, cn = spec.cutters[0], spec.cannula
    rng = np.random.default_rng(7)
    tip = _tip("helical-14G")
    pts = np.vstack([_near_surface(tip, 60, 0.01, rng), _near_edges(tip, 60, 0.005, rng)])
    ex = ExactSolid(spec)
    assert not ex.exact  # an implicit face: iterated, not closed form
    D = ex.distances(pts)
    k = ex.labels.index(cut.label)
    face = np.flatnonzero((D.face == k) & (D.feature == 0))[:15]
    edge = np.flatnonzero(D.feature == 1)[:15]
    assert len(face) >= 5 and len(edge) >= 5
    for i in face:
        p = pts[i]

        def resid(xy, p=p):
            h = cut.height(np.array([xy[0]]), np.array([xy[1]]), cn)[0]
            return np.array([xy[0], xy[1], h]) - p

        r = least_squares(resid, D.closest[i][:2] + 1e-4, method="lm", xtol=1e-15,
                          ftol=1e-15, gtol=1e-15)
        assert abs(np.linalg.norm(r.fun) - abs(D.distance[i])) < 1e-10
    for i in edge:
        p, c = pts[i], D.closest[i]
        rho = np.hypot(c[0], c[1])
        r = cn.r_o if abs(rho - cn.r_o) < abs(rho - cn.r_i) else cn.r_i
        g0 = math.atan2(c[1], c[0])

        def g(t, p=p, r=r):
            z = cut.edge_z(np.array([t]), r, cn)[0]
            return np.sum((np.array([r * math.cos(t), r * math.sin(t), z]) - p) ** 2)

        res = minimize_scalar(g, bracket=(g0 - 1e-3, g0, g0 + 1e-3), tol=1e-15)
        assert abs(np.sqrt(res.fun) - abs(D.distance[i])) < 1e-10
