"""Issue 17 (speed): the compiled passes behind ``tipgeo compare`` give the
same numbers as the plain numpy they replace — percentiles equal to
``numpy.percentile`` bit for bit, moments to numpy within round-off, the
binary PLY fast path equal to the general reader bit for bit, and the
deviations written straight into the result arrays equal to
``MeshSolid.distances``. Small arrays: the file runs in a few CPU seconds."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import tipgeo.inspect.scanio as scanio
from tipgeo import build_tip, preset
from tipgeo.inspect import CadModel, compare, load_scan, write_ply
from tipgeo.inspect.meshdist import MeshSolid
from tipgeo.inspect.quantiles import moments, percentiles, within_band
from tipgeo.inspect.scanio import ScanError


@functools.cache
def _tip():
    return build_tip(preset("bevel-14G-xi14.5"), tolerance=1e-3)


def _edge_points(rng, n, noise, far):
    """Points just off the test tip's vertices and edge midpoints (``n``
    each, normal noise σ ``noise`` mm; edge and vertex features) and ``far``
    uniform in a 4 mm cube (tree walks)."""
    tip = _tip()
    v, f = tip.vertices, tip.faces
    mid = 0.5 * (v[f[:, 0]] + v[f[:, 1]])
    p = np.vstack([v[rng.integers(0, len(v), n)], mid[rng.integers(0, len(f), n)]])
    return np.vstack([p + rng.normal(0.0, noise, p.shape), rng.uniform(-2.0, 2.0, (far, 3))])


_finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(_finite, min_size=1, max_size=300),
       st.lists(st.floats(0.0, 100.0), min_size=1, max_size=5))
# a subnormal span (bucket scale overflows to ∞: 0·∞ is NaN) crashed the
# kernel on CI once hypothesis drew it
@example([0.0, 5e-324, 1e-320], [0.0, 50.0, 100.0])
@example([-1e-310, 1e-310, 0.0], [25.0, 75.0])
def test_percentiles_equal_numpy_bit_for_bit(values, q):
    x = np.asarray(values)
    assert np.array_equal(percentiles(x, q), np.percentile(x, q))
    assert np.array_equal(percentiles(x, q, absolute=True), np.percentile(np.abs(x), q))
    assert np.array_equal(percentiles(x, q, bounds=(x.min(), x.max())), np.percentile(x, q))
    # bounds need only enclose the values
    a = np.abs(x)
    assert np.array_equal(percentiles(x, q, absolute=True, bounds=(0.0, a.max() * 1.5 + 1.0)),
                          np.percentile(a, q))


@pytest.mark.parametrize("x", [[-1.7e308, 1.7e308, 0.0, 3.0],       # the span overflows to ∞
                               [1e-310, 2e-310, 3e-310, -4e-310]])  # a subnormal span
def test_percentiles_at_extreme_spans(x):
    x = np.asarray(x)
    q = [0.0, 10.0, 50.0, 90.0, 100.0]
    assert np.array_equal(percentiles(x, q), np.percentile(x, q))
    assert np.array_equal(percentiles(x, q, absolute=True), np.percentile(np.abs(x), q))


@pytest.mark.parametrize("kind", ["normal", "ties", "outlier"])
def test_percentiles_of_a_large_array(kind):
    """2·10⁵ values (many per bucket; ties; one far outlier stretching the
    buckets): still numpy's values exactly."""
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 2e-3, 200_000)
    if kind == "ties":
        x = np.round(x * 1e3) * 1e-3
    elif kind == "outlier":
        x[17] = 40.0
    q = [0.0, 5.0, 50.0, 95.0, 99.9, 100.0]
    assert np.array_equal(percentiles(x, q), np.percentile(x, q))
    assert np.array_equal(percentiles(x, q, absolute=True), np.percentile(np.abs(x), q))


def test_moments_and_band_match_numpy():
    rng = np.random.default_rng(4)
    x = rng.normal(1e-3, 2e-3, 100_003)
    m = moments(x, 0.002)
    assert m["count"] == len(x)
    assert m["mean"] == pytest.approx(np.mean(x), rel=1e-12)
    assert m["std"] == pytest.approx(np.std(x), rel=1e-12)
    assert m["rms"] == pytest.approx(np.sqrt(np.mean(x ** 2)), rel=1e-12)
    assert m["mean_abs"] == pytest.approx(np.mean(np.abs(x)), rel=1e-12)
    assert (m["min"], m["max"]) == (x.min(), x.max())
    assert m["within"] == np.count_nonzero(np.abs(x) <= 0.002)
    kept = within_band(x, 1e-3, 3e-3)
    assert np.array_equal(kept, x[np.abs(x - 1e-3) <= 3e-3])


@pytest.mark.parametrize("units", ["mm", "um", "m"])
@pytest.mark.parametrize("double", [True, False])
def test_binary_ply_fast_path_equals_the_general_reader(tmp_path, monkeypatch, units, double):
    """float64 and float32 columns, mm/µm/m (metres: the offsets outgrow
    float32 and the storage widens): the compiled pass stores the same
    offsets, origin and metadata as the numpy path."""
    rng = np.random.default_rng(5)
    pts = rng.normal(0.0, 1.0, (3001, 3)) + [5.0, -3.0, 2.0]
    f = write_ply(tmp_path / "s.ply", pts, double=double)
    monkeypatch.setattr(scanio, "_CHUNK_ROWS", 1000)      # several chunks
    fast = load_scan(f, units=units, compact=True)
    monkeypatch.setattr(scanio._Accumulator, "add_fields", lambda self, *cols: False)
    ref = load_scan(f, units=units, compact=True)
    assert fast.local.dtype == ref.local.dtype
    assert np.array_equal(fast.local, ref.local)
    assert np.array_equal(fast.origin, ref.origin)
    assert fast.meta == ref.meta


def test_binary_ply_with_a_nan_still_names_the_point(tmp_path):
    pts = np.random.default_rng(6).normal(0.0, 1.0, (50, 3))
    pts[31, 1] = np.nan
    f = write_ply(tmp_path / "bad.ply", pts)
    with pytest.raises(ScanError, match="the first is point 32"):
        load_scan(f, compact=True)


def test_deviations_written_in_place_equal_distances():
    """compare()'s mesh path (transform, envelope and signed distances into
    the result arrays) against MeshSolid.distances of the same float64
    points: equal bit for bit; points beyond max_distance left out."""
    rng = np.random.default_rng(7)
    tip = _tip()
    tri = tip.triangles
    k = rng.integers(0, len(tri), 3000)
    w = rng.dirichlet([1.0, 1.0, 1.0], 3000)
    p = np.einsum("ni,nij->nj", w, tri[k]) + tip.face_normals[k] * rng.normal(0, 0.002,
                                                                                (3000, 1))
    p[:40] += tip.face_normals[k[:40]] * 0.8            # far: left out at 0.5 mm
    res = compare(p, CadModel(tip=tip), register_scan=False)
    assert isinstance(res.cad.engine, MeshSolid)
    ref = MeshSolid(tip).distances(p)
    keep = np.abs(ref.distance) <= 0.5
    assert np.array_equal(res.index, np.flatnonzero(keep))
    assert np.array_equal(res.distances.distance, ref.distance[keep])
    assert np.array_equal(res.distances.face, ref.face[keep])
    assert np.array_equal(res.distances.feature, ref.feature[keep])
    # computed on first use from each point's triangle: the same values
    assert np.array_equal(res.distances.closest, ref.closest[keep].astype(np.float32))
    assert np.array_equal(res.distances.normal, ref.normal[keep].astype(np.float32))
    assert res.dropped["far"] == np.count_nonzero(~keep)


def test_fused_kernel_equals_separate_search_at_edges_and_vertices():
    """The one-call kernel appending the points within ``far`` to a scan's
    result arrays (``MeshSolid.distances_into``, what compare runs per
    chunk) against the same search on every point (``MeshSolid.distances``):
    the same distances, closest points, normals, faces and features bit for
    bit, on points just off the mesh's vertices and edge midpoints (edge and
    vertex features) and far off it (tree walks); distances equal an
    all-triangle brute force."""
    from tipgeo.inspect.meshdist import brute_force_distances

    rng = np.random.default_rng(11)
    tip = _tip()
    p = _edge_points(rng, 400, 0.003, 100)
    mesh = MeshSolid(tip)
    ref = mesh.distances(p)
    n = len(p)
    out = (np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
           np.empty(n, np.int64), np.empty(n, np.int8), np.empty(n, np.int64))
    far = 0.5
    cur, near = mesh.distances_into(p, np.arange(n) + 10, far=far, near=0.05, out=out, cur=0)
    keep = np.abs(ref.distance) <= far
    assert cur == np.count_nonzero(keep)
    assert near == np.count_nonzero(np.abs(ref.distance) <= 0.05)
    P, dist, clo, nrm, face, feat, rows = (a[:cur] for a in out)
    assert np.array_equal(rows, np.flatnonzero(keep) + 10)
    assert np.array_equal(P, p[keep])
    assert np.array_equal(dist, ref.distance[keep])
    assert np.array_equal(clo, ref.closest[keep])
    assert np.array_equal(nrm, ref.normal[keep])
    assert np.array_equal(face, ref.face[keep])
    assert np.array_equal(feat, ref.feature[keep])
    assert {0, 1, 2} <= set(np.unique(ref.feature[:800]).tolist())   # every feature seen
    assert np.max(np.abs(np.abs(ref.distance) - brute_force_distances(p, tip.triangles))) < 1e-12


def test_hinted_search_gives_the_same_distances_whatever_the_hint():
    """ICP's first guesses (``hint``: each point's nearest sub-triangle from
    the last iteration) only start the exact search: with the right hint,
    with one from other points (wrong for almost every point), with the
    last pose's, and capped, the distances equal the unhinted search (to
    round-off where an edge's two triangles tie) and the all-triangle brute
    force; the hint comes back as each point's own
    nearest; a malformed hint is refused by name."""
    from tipgeo.inspect.meshdist import brute_force_distances

    rng = np.random.default_rng(12)
    tip = _tip()
    p = _edge_points(rng, 300, 0.003, 100)
    mesh = MeshSolid(tip)
    ref = mesh.distances(p)
    brute = brute_force_distances(p, tip.triangles)
    hint = np.full(len(p), -1, np.int64)
    first = mesh.distances(p, hint=hint)
    assert np.array_equal(first.distance, ref.distance) and hint.min() >= 0
    again = mesh.distances(p, hint=hint)               # the right guess for every point
    assert np.array_equal(again.distance, ref.distance)
    assert np.array_equal(again.normal, ref.normal) and np.array_equal(again.face, ref.face)
    wrong = hint[rng.permutation(len(p))].copy()       # other points' triangles
    moved = p + 0.004                                  # the next ICP step's points
    assert np.array_equal(mesh.distances(p, hint=wrong).distance, ref.distance)
    # a point whose closest point is on an edge ties between the edge's two
    # triangles; the guess may pick the other one: the same distance to the
    # round-off of one closest-point evaluation (3e-17 mm seen)
    np.testing.assert_allclose(mesh.distances(moved, hint=hint.copy()).distance,
                               mesh.distances(moved).distance, rtol=0, atol=1e-15)
    capped = mesh.distances(p, 0.01, hint=wrong.copy()).distance
    near = np.abs(ref.distance) < 0.01
    assert np.array_equal(capped[near], ref.distance[near])
    assert np.all(np.abs(capped[~near]) >= 0.01)
    assert np.max(np.abs(np.abs(again.distance) - brute)) < 1e-12
    for bad in (np.zeros(len(p), np.int32), np.zeros(len(p) - 1, np.int64),
                np.full(len(p), 10 ** 9, np.int64)):
        with pytest.raises(ValueError, match="hint"):
            mesh.distances(p, hint=bad)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.05, 0.05), min_size=1, max_size=200),
       st.integers(1, 60), st.floats(-0.03, -1e-4), st.floats(1e-4, 0.03))
@example([-0.025, 0.025, 0.0, -0.0249999, 0.02499999], 50, -0.025, 0.025)   # on the edges
def test_histogram_and_grouping_equal_numpy(values, bins, lo, hi):
    """The compiled histogram against numpy.histogram (edges and counts
    equal, values on the edges included), and the one-copy grouping against
    a mask per group (the same values in the same order)."""
    from tipgeo.inspect.quantiles import by_group, histogram_counts

    x = np.asarray(values)
    counts, edges, below, above = histogram_counts(x, lo, hi, bins)
    ref, ref_edges = np.histogram(x, bins=bins, range=(lo, hi))
    assert np.array_equal(edges, ref_edges) and np.array_equal(counts, ref)
    assert (below, above) == (np.count_nonzero(x < lo), np.count_nonzero(x > hi))
    gid = (np.arange(len(x)) * 7919) % 5
    gmap = np.array([2, 0, 1, 0, 2])
    vals, start = by_group(x, gid, gmap, 3)
    for g in range(3):
        assert np.array_equal(vals[start[g]:start[g + 1]], x[gmap[gid] == g])


def test_envelope_radius_test_equals_hypot_at_the_reach():
    """transform_envelope decides by the square of the radius and falls back
    to hypot only within round-off of the reach: on points a few ulps either
    side of the reach (and far from it) it keeps exactly the points the C
    library's hypot keeps (numpy.hypot; Python's math.hypot rounds its own
    way and differs in the last bit at a few of them)."""
    from tipgeo.inspect.nearest import transform_envelope

    rng = np.random.default_rng(5)
    reach = 1.05 + 0.5
    ang = rng.uniform(0.0, 2 * np.pi, 4000)
    r = reach * (1.0 + rng.integers(-8, 9, 4000) * 2.0 ** -52)
    r[:500] = rng.uniform(0.0, 3.0, 500)
    x = np.stack([r * np.cos(ang), r * np.sin(ang), rng.uniform(-1.0, 1.0, 4000)], 1)
    R, t = np.eye(3), np.zeros(3)
    q, rows = np.empty_like(x), np.empty(len(x), np.int64)
    kept, cropped = transform_envelope(x, R, t, False, -np.inf, reach, -2.0, 2.0, q, rows, 0)
    ref = np.flatnonzero(np.hypot(x[:, 0], x[:, 1]) <= reach)
    assert cropped == 0 and 0 < len(ref) < len(x)
    assert 0 < np.count_nonzero(ref >= 500) < 3500     # points a few ulps off: both sides
    assert np.array_equal(rows[:kept], ref)
    assert np.array_equal(q[:kept], x[ref])


# -----------------------------------------------------------------------------
# the report's blocks in three passes, the row selections, the page switch
def _old_block(d, band):
    """One block by the separate functions (what the grouped passes replace)."""
    m = moments(d, band)
    p = percentiles(d, [5.0, 95.0], bounds=(m["min"], m["max"]))
    pa = percentiles(d, [95.0], absolute=True, bounds=(0.0, max(-m["min"], m["max"])))
    return m, p, pa


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 3000), st.integers(0, 2**32 - 1), st.sampled_from([1.0, 1e-9, 0.0]),
       st.booleans())
@example(1024, 0, 1.0, False)
@example(1, 1, 0.0, True)
def test_group_blocks_equal_the_separate_functions_bit_for_bit(n, seed, scale, rounded):
    from tipgeo.inspect.quantiles import by_group, group_blocks

    rng = np.random.default_rng(seed)
    d = rng.normal(0.0, 0.003, n) * scale
    if rounded:
        d = np.round(d, 4)       # ties
    ids = rng.integers(0, 5, n).astype(np.int16)
    gmap = np.array([0, 1, 2, 3, 0])
    med, half = float(np.median(d)), 0.004
    got = group_blocks(d, ids, gmap, 4, 0.002, trim=(med, half))
    vals, start = by_group(d, ids, gmap, 4)
    parts = [d] + [vals[start[g]:start[g + 1]] for g in range(4)] + \
        [within_band(d, med, half)]
    assert len(got) == len(parts)
    for g, part in zip(got, parts):
        assert g["count"] == len(part)
        if not len(part):
            continue
        m, p, pa = _old_block(part, 0.002)
        for k in ("mean", "std", "rms", "mean_abs", "min", "max", "within"):
            assert g[k] == m[k], k            # the same arithmetic: equal, not close
        assert np.array_equal(g["p"], p) and np.array_equal(g["p_abs"], pa)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 400), st.integers(0, 2**32 - 1), st.integers(1, 25))
def test_row_selections_equal_numpy(n, seed, k):
    from tipgeo.inspect.rowsfast import band_counts, count_rows, pick_rows, top_rows

    rng = np.random.default_rng(seed)
    face = rng.integers(0, 4, n).astype(np.int16)
    feat = rng.integers(0, 3, n).astype(np.int8) * (rng.random(n) < 0.3)
    d = np.round(rng.normal(0.0, 0.01, n), 3)
    z = np.round(rng.random(n), 2).astype(np.float32)      # ties in z
    half = 0.012
    near = (d < half) & (d > -half)
    labels = np.array([2, 0])
    masks = [(face == lab) & near & (feat == 0) for lab in labels]
    counts = count_rows(face, labels, d, half, feat)
    assert counts.tolist() == [int(m.sum()) for m in masks]
    ranks = np.zeros((2, 5), np.int64)
    nrank = np.minimum(counts, 5)
    for j in range(2):
        ranks[j, :nrank[j]] = np.linspace(0, counts[j] - 1, nrank[j]).astype(int)
    rows = pick_rows(face, labels, d, half, feat, ranks, nrank)
    for j in range(2):
        assert rows[j, :nrank[j]].tolist() == np.flatnonzero(masks[j])[ranks[j, :nrank[j]]].tolist()
    # the k highest z near the surface, ties to the first rows
    cand = np.flatnonzero(near)
    want = sorted(cand[np.lexsort((cand, -z[cand]))][:k].tolist())
    assert top_rows(z, d, half, k).tolist() == want
    # shares per face (interior) and of the edges
    band = np.array([0.001, 0.002, 0.005, 0.01])
    cnt, within = band_counts(d, face, feat, 4, band, 0.003, True)
    for f in range(4):
        m = (face == f) & (feat == 0)
        assert cnt[f] == m.sum() and within[f] == (np.abs(d[m]) <= band[f]).sum()
    assert cnt[4] == (feat != 0).sum() and within[4] == (np.abs(d[feat != 0]) <= 0.003).sum()


def test_ordinary_pages_restores_numpys_setting():
    from tipgeo.inspect.pages import _setter, ordinary_pages

    fn = _setter()
    if fn is None:
        pytest.skip("this numpy has no huge-page switch")
    before = fn(True)
    try:
        with ordinary_pages():
            assert fn(False) is False          # off inside
        assert fn(True) is True                # back on after
        fn(False)
        with ordinary_pages():
            pass
        assert fn(False) is False              # off stays off
    finally:
        fn(before)


@pytest.mark.parametrize("x", [[-1.7e308, 1.7e308, 0.0, 3.0], [1e-310, 2e-310, 3e-310, -4e-310],
                               [0.0, 5e-324, 1e-320], [2.5, 2.5, 2.5]])
def test_group_blocks_at_extreme_spans(x):
    from tipgeo.inspect.quantiles import group_blocks

    x = np.asarray(x)
    g = group_blocks(x, None, np.zeros(0, np.int64), 0, 0.01)[0]
    assert np.array_equal(g["p"], np.percentile(x, [5.0, 95.0]))
    assert np.array_equal(g["p_abs"], np.percentile(np.abs(x), [95.0]))


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(0, 2**32 - 1), st.integers(1, 14),
       st.sampled_from(["blob", "plane", "grid", "spread", "far"]))
def test_knn_equals_scipys_tree(n, seed, k, shape):
    from scipy.spatial import cKDTree

    from tipgeo.inspect.knn import knn

    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    if shape == "plane":
        p[:, 2] = 0.0                       # a flat cloud: one cell thick
    elif shape == "grid":
        p = np.round(p, 1)                  # equal distances and duplicates
    elif shape == "spread":
        p *= np.array([1e3, 1.0, 1e-6])     # very unequal extents
    elif shape == "far":
        p = np.round(p, 2) + 1e3            # far from the origin, on a lattice
    k = min(k, n)
    d, i = knn(p, k)
    d_ref, i_ref = cKDTree(p).query(p, k=k)
    d_ref = d_ref.reshape(n, k)
    assert np.array_equal(d, d_ref)
    # the neighbours at those distances: the same up to the order of ties
    assert np.array_equal(np.linalg.norm(p[i] - p[:, None, :], axis=2), d)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["plane", "cylinder", "blob", "line"]),
       st.floats(1e-6, 1e3))
def test_knn_normals_equal_numpys_eigh(seed, shape, scale):
    """The compiled PCA normals (3 × 3 Jacobi) against numpy's eigh of the
    same neighbourhoods: the same unit vectors up to sign, to 1e-9 wherever
    the smallest eigenvalue is apart from the next (relative gap > 1e-3);
    unit length everywhere."""
    from tipgeo.inspect.knn import knn, knn_normals

    rng = np.random.default_rng(seed)
    n, k = 400, 12
    u = rng.uniform(-1.0, 1.0, (n, 2))
    if shape == "plane":
        p = np.column_stack([u, 0.01 * rng.normal(size=n)])
    elif shape == "cylinder":
        g = np.pi * u[:, 0]
        p = np.column_stack([np.cos(g), np.sin(g), u[:, 1]]) + 0.002 * rng.normal(size=(n, 3))
    elif shape == "line":
        p = np.outer(u[:, 0], [0.3, -0.5, 0.8]) + 1e-3 * rng.normal(size=(n, 3))
    else:
        p = rng.normal(size=(n, 3))
    p = p @ np.linalg.qr(rng.normal(size=(3, 3)))[0] * scale + rng.normal(size=3) * scale
    got = knn_normals(p, k)
    assert got.shape == (n, 3)
    assert np.allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-12)
    _, idx = knn(p, k)
    nb = p[idx] - p[idx].mean(axis=1, keepdims=True)
    lam, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
    ref = vec[:, :, 0]
    apart = (lam[:, 1] - lam[:, 0]) > 1e-3 * lam[:, 2]
    err = np.minimum(np.linalg.norm(got - ref, axis=1), np.linalg.norm(got + ref, axis=1))
    assert np.all(err[apart] <= 1e-9)
    if shape in ("plane", "cylinder"):
        assert apart.mean() > 0.9              # the case the test is about


def test_knn_refuses_k_beyond_the_points():
    from tipgeo.inspect.knn import knn

    with pytest.raises(ValueError, match="k = 4"):
        knn(np.zeros((3, 3)), 4)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 400), st.integers(0, 2**31 - 1), st.sampled_from([1, 7, 128]))
def test_cone_counts_by_blocks_equal_the_full_matrix(n, seed, block):
    """The flat-patch finder's normal counts, by blocks of rows, against the
    n × n matrix they replace: the same counts."""
    import math

    from tipgeo.inspect.register import _cone_counts

    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[: n // 2] = v[0] + rng.normal(0.0, 0.05, (n // 2, 3))     # a dense direction
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    cosc = math.cos(math.radians(5.0))
    full = (np.abs(v @ v.T) > cosc).sum(axis=1)
    assert np.array_equal(_cone_counts(v, cosc, block), full)


def test_sorted_cell_lists_give_the_same_distances_and_true_lower_bounds():
    """A large deviation pass sorts each grid cell's list by its lower bound
    and stops a search at the first bound beyond its best: the distances are
    those of the unsorted lists (to the round-off of one closest-point
    evaluation where triangles tie) and of the all-triangle brute force;
    every bound is at most the squared distance from any point of its cell
    (corners and random points, the margin included) to the entry's box."""
    from tipgeo.inspect.meshdist import brute_force_distances

    rng = np.random.default_rng(31)
    tip = _tip()
    p = _edge_points(rng, 400, 0.004, 200)
    mesh = MeshSolid(tip)
    plain = mesh.distances(p)
    capped = mesh.distances(p, 0.01).distance
    index = mesh._build()
    mesh.prepare(10)                                    # below the threshold: unsorted
    assert len(index.clb) == 0
    mesh.prepare(10 ** 9)
    assert len(index.clb) == len(index.cprim) > 0
    fast = mesh.distances(p)
    np.testing.assert_allclose(fast.distance, plain.distance, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.abs(fast.distance), brute_force_distances(p, tip.triangles),
                               rtol=0, atol=1e-12)
    near = np.abs(plain.distance) < 0.01
    fast_capped = mesh.distances(p, 0.01).distance
    np.testing.assert_allclose(fast_capped[near], capped[near], rtol=0, atol=1e-15)
    assert np.all(np.abs(fast_capped[~near]) >= 0.01)
    # the bounds: sorted within each cell and below every point's box distance
    starts = index.cstart
    cells = np.flatnonzero(np.diff(starts) > 0)
    for c in rng.choice(cells, 300, replace=False):
        a, b = starts[c], starts[c + 1]
        lb = index.clb[a:b]
        assert np.all(np.diff(lb) >= 0)
        ijk = np.array([c % index.dims[0], (c // index.dims[0]) % index.dims[1],
                        c // (index.dims[0] * index.dims[1])])
        lo = index.origin + ijk * index.cell - index.margin
        size = index.cell + 2 * index.margin
        corners = lo + size * np.array([[i, j, k] for i in (0, 1) for j in (0, 1)
                                        for k in (0, 1)], float)
        q = np.vstack([corners, lo + size * rng.random((20, 3))])
        boxes = index.T[index.cprim[a:b], :6]
        gap = np.maximum(np.maximum(boxes[None, :, :3] - q[:, None],
                                    q[:, None] - boxes[None, :, 3:]), 0.0)
        assert np.all((gap ** 2).sum(axis=2) >= lb[None, :])
