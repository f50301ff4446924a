"""The fast self-intersection finder (tipgeo.meshcheck) against open3d's
O(n²) check and against hand-made known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from tipgeo.meshcheck import crossing_pairs, self_intersections, tolerant_intersections


def _sphere(seed, centre=(0.0, 0.0, 0.0), radius=1.0, sub=3):
    s = trimesh.creation.icosphere(subdivisions=sub, radius=radius)
    rng = np.random.default_rng(seed)
    v = s.vertices * (1.0 + 0.02 * rng.standard_normal((len(s.vertices), 1)))
    return v + np.asarray(centre), np.asarray(s.faces, np.int64)


def _o3d_pairs(v, f):
    from tipgeo._open3d import import_open3d

    o3d = import_open3d()
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v),
                                  o3d.utility.Vector3iVector(f.astype(np.int32)))
    p = np.asarray(m.get_self_intersecting_triangles()).reshape(-1, 2)
    return {tuple(sorted(map(int, x))) for x in p}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_perturbed_sphere_has_no_crossing(seed):
    v, f = _sphere(seed)
    assert len(self_intersections(v, f)) == 0
    assert _o3d_pairs(v, f) == set()


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_planted_crossings_match_open3d(seed):
    # a second, smaller perturbed sphere through the first: every pair of
    # crossing triangles between them, the same set as open3d's
    v1, f1 = _sphere(seed)
    rng = np.random.default_rng(seed)
    c = rng.standard_normal(3)
    v2, f2 = _sphere(seed + 100, centre=c / np.linalg.norm(c), radius=0.5, sub=2)
    v = np.concatenate([v1, v2])
    f = np.concatenate([f1, f2 + len(v1)])
    mine = {tuple(map(int, x)) for x in self_intersections(v, f)}
    theirs = _o3d_pairs(v, f)
    assert len(theirs) > 20
    assert mine == theirs
    assert {tuple(map(int, x)) for x in tolerant_intersections(v, f)} == theirs
    assert all((a < len(f1)) != (b < len(f1)) for a, b in mine)  # one from each sphere


def test_adjacent_triangles_count_only_real_crossings():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.5, 0.0], [0.3, 0.3, 1.0],
                  [-1, 0, 0], [0.3, 0.3, -1.0], [0.25, 0.25, 0.0]], float)
    # shared edge 0-1, folded flat onto each other: a crossing
    assert len(self_intersections(v, np.array([[0, 1, 2], [1, 0, 3]]))) == 1
    # shared edge, third vertex out of the plane: they only share the edge
    assert len(self_intersections(v, np.array([[0, 1, 2], [1, 0, 4]]))) == 0
    # shared edge, coplanar, opposite sides: a flat strip
    assert len(self_intersections(v, np.array([[0, 1, 2], [1, 0, 6 - 1]]))) == 0
    # shared vertex 0; the edge 4-6 pierces triangle 012 at (0.3, 0.3, 0)
    assert len(self_intersections(v, np.array([[0, 1, 2], [0, 4, 6]]))) == 1
    # shared vertex 0 only, the other triangle above: no crossing
    assert len(self_intersections(v, np.array([[0, 1, 2], [0, 4, 5]]))) == 0
    # no shared vertex: vertex 7 of 4-7-6 lies in 012, edge 4-6 pierces it
    disjoint, adjacent = crossing_pairs(v, np.array([[0, 1, 2], [4, 7, 6]]))
    assert len(disjoint) == 1 and len(adjacent) == 0


def test_gap_reports_near_contacts():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0],
                  [0.2, 0.2, 1e-4], [0.4, 0.2, 1e-4], [0.2, 0.4, 1e-4]], float)
    f = np.array([[0, 1, 2], [3, 4, 5]])
    assert len(self_intersections(v, f)) == 0
    assert len(self_intersections(v, f, gap=2e-4)) == 1
    assert len(self_intersections(v, f, gap=0.5e-4)) == 0


def test_tolerant_test_reproduces_open3d_false_positive():
    # a pair from an earlier punch-C3 quality mesh: a 0.4 µm-sized triangle
    # nearly in the plane of a 0.24 mm one and 7.7 µm away from it. No
    # crossing (exact rational arithmetic agrees), but open3d's tolerant
    # Möller test takes them for coplanar and overlapping;
    # tolerant_intersections reports the same pair
    v = np.array([[-1.1294809331381825, 0.13868282042357477, 0.26871117191329397],
                  [-1.0748286957701183, 0.14274032633802597, 0.5011256589028024],
                  [-1.1038237569345477, 0.15513231216391132, 0.3695976246463353],
                  [-1.075716606364875, 0.15138062224070478, 0.4924124323599421],
                  [-1.0757455779632463, 0.1511861814543615, 0.49241280837994683],
                  [-1.0756577817494355, 0.15117384250118882, 0.4927968328617806]])
    f = np.array([[0, 1, 2], [3, 4, 5]])
    assert len(self_intersections(v, f)) == 0
    assert len(self_intersections(v, f, gap=7e-3)) == 0
    assert len(self_intersections(v, f, gap=8e-3)) == 1
    assert _o3d_pairs(v, f) == {(0, 1)}
    assert tolerant_intersections(v, f).tolist() == [[0, 1]]
