"""The local re-check of open3d's tolerant test (tipgeo.meshcheck.near_pairs,
count_tolerant) that the float32 placement of quality meshes runs: it counts
what the whole-mesh finder reports."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from tipgeo.meshcheck import count_tolerant, near_pairs, tolerant_intersections


def _crossing_spheres(seed):
    s1 = trimesh.creation.icosphere(subdivisions=3)
    s2 = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    rng = np.random.default_rng(seed)
    c = rng.standard_normal(3)
    v = np.concatenate([s1.vertices, s2.vertices + c / np.linalg.norm(c)])
    f = np.concatenate([s1.faces, s2.faces + len(s1.vertices)]).astype(np.int64)
    return v, f


@pytest.mark.parametrize("seed", [1, 2])
def test_count_tolerant_counts_the_finders_pairs(seed):
    v, f = _crossing_spheres(seed)
    pairs = tolerant_intersections(v, f)
    near = near_pairs(v, f, 0.0)
    assert len(pairs) > 20
    # all faces: every pair once
    assert count_tolerant(v, f, near, np.arange(len(f))) == len(pairs)
    # one face: its own pairs
    for k in np.unique(pairs)[:10]:
        assert count_tolerant(v, f, near, np.array([k])) == int((pairs == k).any(1).sum())
    # a set of faces: the pairs with at least one face in it, once each
    some = np.unique(pairs[:, 0])[:15]
    assert count_tolerant(v, f, near, some) == int(np.isin(pairs, some).any(1).sum())


def test_near_pairs_are_symmetric_and_share_no_vertex():
    v, f = _crossing_spheres(3)
    start, partners = near_pairs(v, f, 1e-3)
    assert start[0] == 0 and start[-1] == len(partners) and len(start) == len(f) + 1
    rows = np.repeat(np.arange(len(f)), np.diff(start))
    got = set(zip(rows.tolist(), partners.tolist()))
    assert got == {(j, i) for i, j in got}
    shared = (f[rows][:, :, None] == f[partners][:, None, :]).any(axis=(1, 2))
    assert not shared.any()
    # every pair the finder reports is among them
    pairs = tolerant_intersections(v, f)
    assert {tuple(p) for p in pairs.tolist()} <= got
