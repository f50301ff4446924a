"""Sliver removal along the curve between two labelled faces (issue 27 item 4).

A vertex on the curve where two faces with exact surfaces meet may collapse
along that curve, checked against both surfaces (:mod:`tipgeo.slivers`);
:func:`tipgeo.slivers._onto_curve` projects a point onto such a curve.
Known answers: a cylinder ρ = r meets the plane z = 0 in the circle of
radius r; the plane x = 0 meets the plane z = 0 in the y axis.
"""

from __future__ import annotations

import numpy as np
import pytest

from tipgeo.slivers import _onto_curve, aspect_ratios, remove_slivers
from tipgeo.tolerances import MAX_ASPECT_RATIO


def _cylinder(r):
    def fn(p):
        rho = np.hypot(p[:, 0], p[:, 1])
        return rho - r, np.stack([p[:, 0] / rho, p[:, 1] / rho, 0 * rho], 1)
    return fn


def _plane_z(p):
    return p[:, 2].copy(), np.tile([0.0, 0.0, 1.0], (len(p), 1))


def _plane_x(p):
    return p[:, 0].copy(), np.tile([1.0, 0.0, 0.0], (len(p), 1))


def test_onto_curve_circle_and_line():
    # onto the circle ρ = 1, z = 0: (x, y)/ρ at z = 0 (Gauss–Newton, to 1e-12)
    q = (1.3, 0.4, 0.2)
    x = _onto_curve(q, _cylinder(1.0), _plane_z, 1e-9)
    assert x is not None
    rho = np.hypot(1.3, 0.4)
    assert x == pytest.approx((1.3 / rho, 0.4 / rho, 0.0), abs=1e-10)
    # onto the y axis (x = z = 0): the foot of the perpendicular, one step
    y = _onto_curve((0.3, -2.0, 0.7), _plane_x, _plane_z, 1e-12)
    assert y == pytest.approx((0.0, -2.0, 0.0), abs=1e-15)
    # two parallel planes (no curve): refused
    assert _onto_curve((0.3, 0.0, 0.7), _plane_z,
                       lambda p: (p[:, 2] - 1.0, np.tile([0.0, 0.0, 1.0], (len(p), 1))),
                       1e-9) is None


def _zip(inner, outer):
    """Triangles between two rings of vertex indices (each with its angle
    list), advancing the one whose next angle comes first; both closed."""
    (ia, ga), (ob, gb) = inner, outer
    i = j = 0
    out = []
    n, m = len(ia), len(ob)
    while i < n or j < m:
        gi = ga[(i + 1) % n] + (2 * np.pi if i + 1 >= n else 0)
        gj = gb[(j + 1) % m] + (2 * np.pi if j + 1 >= m else 0)
        if j >= m or (i < n and gi <= gj):
            out.append([ia[i % n], ia[(i + 1) % n], ob[j % m]])
            i += 1
        else:
            out.append([ia[i % n], ob[(j + 1) % m], ob[j % m]])
            j += 1
    return out


def _band_and_annulus(n=48, delta=2e-3):
    """Label 0: a band of the cylinder ρ = 1 from z = 0 to z = h; label 1:
    an annulus of the plane z = 0 from ρ = 0.8 to 1. They meet on the circle
    ρ = 1, z = 0, sampled at n even angles plus one at ``delta`` × the
    spacing past the first: the two triangles on that short curve edge and
    the fans around it are needles. Open mesh, every curve edge on one face
    of each label."""
    g = 2 * np.pi * np.arange(n) / n
    gc = np.sort(np.r_[g, g[0] + delta * 2 * np.pi / n])
    h = 2 * np.pi / n
    top = [[np.cos(a), np.sin(a), h] for a in g]
    curve = [[np.cos(a), np.sin(a), 0.0] for a in gc]
    hole = [[0.8 * np.cos(a), 0.8 * np.sin(a), 0.0] for a in g]
    verts = np.array(top + curve + hole)
    it, ic, ih = np.arange(n), n + np.arange(len(gc)), n + len(gc) + np.arange(n)
    band = _zip((ic, gc), (it, g))
    ann = [t[::-1] for t in _zip((ic, gc), (ih, g))]
    faces = np.array(band + ann)
    labels = np.r_[np.zeros(len(band), int), np.ones(len(ann), int)]
    return verts, faces, labels, ic


def test_collapse_along_a_curved_feature_curve():
    verts, faces, labels, ic = _band_and_annulus()
    n_curve = len(ic)
    before = aspect_ratios(verts, faces).max()
    # the chordal limit of the input's own circle chords: r (1 − cos(π/n))
    limit = 1.01 * (1 - np.cos(np.pi / 48))
    exact = {0: _cylinder(1.0), 1: _plane_z}
    v, f, lab = remove_slivers(verts, faces, labels, bound=MAX_ASPECT_RATIO,
                               max_deviation=1e-12, exact=exact, limit=limit)
    assert before > 500
    assert aspect_ratios(v, f).max() <= MAX_ASPECT_RATIO
    # the short curve edge is gone: one curve vertex fewer; every curve
    # vertex still on both surfaces (the circle) to rounding
    on0 = np.unique(f[lab == 0])
    on1 = np.unique(f[lab == 1])
    curve = np.intersect1d(on0, on1)
    assert len(curve) == n_curve - 1
    assert np.abs(np.hypot(v[curve, 0], v[curve, 1]) - 1.0).max() <= 1e-12
    assert np.abs(v[curve, 2]).max() == 0.0
    # every edge midpoint and centroid within the limit of its label's surface
    for k, fn in exact.items():
        t = v[f[lab == k]]
        pts = np.concatenate([0.5 * (t + np.roll(t, 1, axis=1)), t.mean(1, keepdims=True)], 1)
        assert np.abs(fn(pts.reshape(-1, 3))[0]).max() <= limit
    # without the exact surfaces, the same budget moves nothing on the curve
    v1, f1, _ = remove_slivers(verts, faces, labels, bound=MAX_ASPECT_RATIO,
                               max_deviation=1e-12)
    assert aspect_ratios(v1, f1).max() > MAX_ASPECT_RATIO


def test_curve_edge_split_lands_on_the_curve():
    # a curve edge (cylinder face 0 | plane face 1) split at its chord's
    # middle, then settled: the new vertex lies on the circle ρ = 1, z = 0
    # (both exact surfaces, to 1e-9 mm: Gauss–Newton to 1e-6 × the limit),
    # each face keeps its label and the star stays within the limit
    from tipgeo.slivers import _arrays, _Mesh, _mid

    verts, faces, labels, ic = _band_and_annulus()
    limit = 1.01 * (1 - np.cos(np.pi / 48))  # the input's own circle chords
    exact = {0: _cylinder(1.0), 1: _plane_z}
    m = _Mesh(verts, faces, labels, (), exact, limit)
    a, b = int(ic[5]), int(ic[6])
    mid = _mid(m.p[a], m.p[b])
    assert 1.0 - np.hypot(mid[0], mid[1]) == pytest.approx(1 - np.cos(np.pi / 48), rel=1e-9)
    w = m.split(a, b, mid)
    assert w is not None and m.labels_at(w) == {0, 1}
    assert m.settle(w)
    x = np.asarray(m.p[w])
    assert abs(np.hypot(x[0], x[1]) - 1.0) <= 1e-9 and abs(x[2]) <= 1e-9
    # ic[5], ic[6] at 4 and 5 spacings (ic[1] is the extra point): between them
    assert np.arctan2(x[1], x[0]) == pytest.approx(4.5 * 2 * np.pi / 48, abs=1e-9)
    v, f, lab = _arrays(m)
    assert np.bincount(lab).tolist() == (np.bincount(labels) + 1).tolist()
    for k, fn in exact.items():
        t = v[f[lab == k]]
        pts = np.concatenate([0.5 * (t + np.roll(t, 1, axis=1)), t.mean(1, keepdims=True)], 1)
        assert np.abs(fn(pts.reshape(-1, 3))[0]).max() <= limit
