"""Issue 17: the compiled exact mesh-distance kernel (grid and tree paths
against an all-triangle brute force), gross-outlier warning and
--max-distance-mm, |d| and trimmed statistics, histogram data, per-point
export, 4×4 transform files, colour range and colormap, --batch.

Small synthetic scans on a coarse mesh (768 triangles): the whole file runs
in a few CPU seconds."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from tipgeo import build_tip, preset
from tipgeo.cli import main
from tipgeo.errors import SpecError
from tipgeo.inspect import compare, deviation_colours, write_ply
from tipgeo.inspect.deviation import histogram, trimmed
from tipgeo.inspect.meshdist import MeshSolid, brute_force_distances
from tipgeo.inspect.register import apply
from tipgeo.inspect.transform import read_transform, write_transform
from tipgeo.io import export_tip
from tipgeo.tolerances import tol

SPEC = "bevel-14G-xi14.5"


@functools.cache
def _tip():
    return build_tip(preset(SPEC), tolerance=1e-3)


def _surface(n, rng, sigma=0.002):
    """Points on the mesh (area-weighted, away from no feature in
    particular) moved along their facet normal by N(0, sigma) (mm)."""
    tip = _tip()
    tri = tip.triangles
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    k = rng.choice(len(tri), n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    p = (tri[k, 0] * (1 - s)[:, None] + tri[k, 1] * (s * (1 - r2))[:, None]
         + tri[k, 2] * (s * r2)[:, None])
    return p + tip.face_normals[k] * rng.normal(0.0, sigma, n)[:, None]


def _rigid(angle_deg, axis, shift):
    a = np.radians(angle_deg)
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
    T[:3, 3] = shift
    return T


@pytest.mark.parametrize("grid", [True, False])
def test_kernel_equals_all_triangle_brute_force(grid, monkeypatch):
    """Near points (grid lists), far points and points off the grid (tree
    walk), in a shuffled order: |d| equals the brute force to 1e-12 mm, and
    the grid-less kernel agrees."""
    rng = np.random.default_rng(11)
    tip = _tip()
    near = _surface(1500, rng)
    far = _surface(200, rng, sigma=0.0) + rng.normal(0.0, 0.4, (200, 3))
    out = rng.uniform(-6.0, 12.0, (100, 3))
    pts = rng.permutation(np.vstack([near, far, out]))
    if not grid:
        monkeypatch.setattr(tol.inspect, "grid_cells", 1)
    m = MeshSolid(tip)
    d = m.distances(pts)
    assert (m._index.dims.prod() > 1) == grid
    assert np.max(np.abs(np.abs(d.distance) - brute_force_distances(pts, tip.triangles))) <= 1e-12
    assert np.allclose(np.linalg.norm(pts - d.closest, axis=1), np.abs(d.distance),
                       rtol=0, atol=1e-12)


def _scan(rng, n=4000, outliers=0.0):
    p = _surface(n, rng)
    k = int(round(outliers * n))
    if k:
        # gross outliers 1–2 mm off the surface along its normal
        q = _surface(k, rng, sigma=0.0)
        rad = np.hypot(q[:, 0], q[:, 1])[:, None]
        q[:, :2] += q[:, :2] / rad * rng.uniform(1.0, 2.0, (k, 1))
        p[:k] = q
    return p


def test_gross_outliers_warn_with_figures_and_max_distance():
    rng = np.random.default_rng(2)
    clean = compare(_scan(rng), _tip(), register_scan=False)
    assert not any("farther than" in w for w in clean.warnings)
    res = compare(_scan(np.random.default_rng(2), outliers=0.05), _tip(), register_scan=False)
    msg = [w for w in res.warnings if "farther than" in w]
    assert len(msg) == 1 and "5.00 %" in msg[0] and "200 of 4,000" in msg[0]
    assert res.dropped["far"] == 200
    # taken in with a 3 mm cut-off: no warning, the full RMS blows up, the
    # trimmed one stays at the noise (σ = 2 µm)
    wide = compare(_scan(np.random.default_rng(2), outliers=0.05), _tip(),
                   register_scan=False, max_distance=3.0)
    assert not any("farther than" in w for w in wide.warnings)
    assert wide.stats["all"]["rms_um"] > 200
    tr = wide.stats["trimmed"]
    assert 1.8 < tr["rms_um"] < 2.2
    assert tr["trimmed_share"] == pytest.approx(0.05, abs=0.01)


def test_abs_trimmed_and_histogram_blocks():
    d = np.array([-3.0, -1.0, 0.0, 1.0, 2.0, 40.0]) * 1e-3
    res = compare(_scan(np.random.default_rng(4), n=600), _tip(), register_scan=False)
    st = res.stats["all"]
    dd = res.distances.distance
    assert st["mean_abs_um"] == pytest.approx(np.mean(np.abs(dd)) * 1e3, rel=1e-12)
    assert st["p95_abs_um"] == pytest.approx(np.percentile(np.abs(dd), 95) * 1e3, rel=1e-12)
    h = histogram(d, -0.0025, 0.0025, 5)
    assert h["counts"] == [0, 1, 1, 1, 1] and h["below"] == 1 and h["above"] == 1
    assert h["edges_um"] == pytest.approx([-2.5, -1.5, -0.5, 0.5, 1.5, 2.5], abs=1e-12)
    t = trimmed(d, 0.01, sigmas=3.5)   # median 0.5 µm, MAD 1.5 µm: 40 µm is out
    assert t["count"] == 5 and t["trimmed_share"] == pytest.approx(1 / 6)
    hist = res.stats["histogram"]
    assert sum(hist["counts"]) + hist["below"] + hist["above"] == len(dd)


def test_trimmed_band_of_a_large_scan_from_a_strided_sample():
    """From 2¹⁹ deviations on, median and MAD come from every k-th one
    (k = n // 2¹⁸): the band of 10⁶ Gaussian deviations (σ = 2 µm, median
    0.3 µm) is still the noise's — the median's standard error on 3.3·10⁵
    of them is 0.0043 µm, the robust σ's about as much: asserted to 6 of
    them — and the rule names the stride."""
    rng = np.random.default_rng(11)
    d = rng.normal(0.0003, 0.002, 1_000_000)
    d[::50] += 0.05                              # 2 % gross outliers, 50 µm off
    t = trimmed(d, 0.01, sigmas=3.5)
    assert "every 3rd point" in t["rule"]
    # 98 % of the mass in the core: the median sits at Φ⁻¹(0.5 / 0.98) =
    # 0.02558 σ above its centre, the MAD is 0.69086 σ (0.98 (Φ(m + t) −
    # Φ(m − t)) = 1/2), so the robust σ is 1.4826 × 0.69086 = 1.02427 σ, and
    # the band of 3.5 robust σ leaves 0.0339 % of the core out
    assert t["median_um"] == pytest.approx(0.3 + 2.0 * 0.02558, abs=0.025)
    assert t["robust_sigma_um"] == pytest.approx(2.0 * 1.02427, abs=0.025)
    assert t["trimmed_share"] == pytest.approx(0.02 + 0.98 * 0.000339, abs=1e-4)
    small = trimmed(d[:200_000], 0.01, sigmas=3.5)
    assert "every point" in small["rule"]


@pytest.mark.parametrize("ext", [".csv", ".ply"])
def test_per_point_export_keeps_input_order(ext, tmp_path):
    rng = np.random.default_rng(5)
    pts = _scan(rng, n=1500)
    res = compare(pts, _tip(), register_scan=False, z_min=4.0)
    from tipgeo.inspect.report import write_points

    f = write_points(res, tmp_path / f"points{ext}")
    if ext == ".csv":
        got = np.loadtxt(f, delimiter=",", skiprows=2)
        idx, xyz, dev, face = got[:, 0].astype(int), got[:, 1:4], got[:, 4], got[:, 5]
    else:
        raw = f.read_bytes()
        body = raw[raw.index(b"end_header\n") + len(b"end_header\n"):]
        arr = np.frombuffer(body, dtype=[("index", "<i8"), ("x", "<f8"), ("y", "<f8"),
                                         ("z", "<f8"), ("deviation_mm", "<f8"),
                                         ("face", "<i4"), ("feature", "<i1")])
        idx, dev, face = arr["index"], arr["deviation_mm"], arr["face"]
        xyz = np.column_stack([arr["x"], arr["y"], arr["z"]])
    keep = np.flatnonzero(pts[:, 2] >= 4.0)
    assert np.array_equal(idx, keep)                        # input order, cropped rows out
    assert np.array_equal(dev, res.distances.distance)      # float64, bit for bit
    assert np.max(np.abs(xyz - pts[idx])) <= 2.0 ** -20     # float32 storage of the points
    assert np.array_equal(face, res.distances.face)


def test_transform_file_round_trip_and_init_transform(tmp_path):
    T = _rigid(7.3, (0.2, 1.0, 0.4), (0.11, -0.02, 0.3))
    f = write_transform(tmp_path / "T.txt", T)
    assert np.array_equal(read_transform(f), T)
    bad = tmp_path / "bad.txt"
    bad.write_text("1 0 0 0\n0 2 0 0\n0 0 1 0\n0 0 0 1\n")
    with pytest.raises(SpecError, match="not a rigid transform"):
        read_transform(bad)
    bad.write_text("1 0 0\n0 1 0\n")
    with pytest.raises(SpecError, match="expected 4 rows of 4"):
        read_transform(bad)
    rng = np.random.default_rng(6)
    pts = _scan(rng, n=800)
    scanner = apply(np.linalg.inv(T), pts)          # the part as the scanner saw it
    ref = compare(pts, _tip(), register_scan=False)
    res = compare(scanner, _tip(), register_scan=False, init_transform=read_transform(f))
    assert np.max(np.abs(res.distances.distance - ref.distances.distance)) <= 1e-9


def test_colour_range_and_colormap():
    import matplotlib

    lut = (np.asarray(matplotlib.colormaps["coolwarm"](np.linspace(0, 1, 256)))[:, :3] * 255
           + 0.5).astype(np.uint8)
    c = deviation_colours(np.array([-0.005, -0.0025, 0.0, 0.010, 0.020, 0.5]), 0.020,
                          low=-0.005, cmap="coolwarm")
    assert np.array_equal(c[0], lut[0]) and np.array_equal(c[4], lut[255])
    assert np.array_equal(c[5], lut[255])                        # saturated
    assert np.array_equal(c[2], lut[128]) and np.array_equal(c[1], lut[64])
    # each side its own slope: +10 of +20 µm is 0.75 of the map, index ⌊0.75·255 + 0.5⌋
    assert np.array_equal(c[3], lut[191])
    pts = _scan(np.random.default_rng(7), n=300)
    res = compare(pts, _tip(), register_scan=False, colour_range=(-0.005, 0.020),
                  colormap="coolwarm")
    d = res.to_dict()
    assert d["colour_scale_um"] == pytest.approx([-5.0, 20.0]) and d["colormap"] == "coolwarm"
    with pytest.raises(SpecError, match="colour_range"):
        compare(pts, _tip(), register_scan=False, colour_range=(0.001, 0.02))
    with pytest.raises(SpecError, match="colormap"):
        compare(pts, _tip(), register_scan=False, colormap="no-such-map")


def test_cli_options_and_batch(tmp_path, capsys):
    cad = export_tip(_tip(), tmp_path / "cad.stl")
    rng = np.random.default_rng(8)
    good = write_ply(tmp_path / "a.ply", _scan(rng, n=500))
    noisy = write_ply(tmp_path / "b.ply", _scan(rng, n=500, outliers=0.05))
    wrong = write_ply(tmp_path / "c.ply", rng.uniform(20.0, 21.0, (500, 3)))
    T = _rigid(0.0, (0, 0, 1), (0.0, 0.0, 0.0))
    tfile = write_transform(tmp_path / "init.txt", T)
    rc = main(["compare", str(good), str(cad), "--no-register", "--quiet", "--json",
               "--max-distance-mm", "0.2", "--export", str(tmp_path / "p.csv"),
               "--init-transform", str(tfile), "--matrix-out", str(tmp_path / "M.txt"),
               "--scale-range-um", "-4", "12", "--colormap", "viridis"])
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["colour_scale_um"] == [-4.0, 12.0] and rep["colormap"] == "viridis"
    assert {"mean_abs_um", "p95_abs_um"} <= set(rep["deviation"]["all"])
    assert np.array_equal(read_transform(tmp_path / "M.txt"), T)
    assert np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=2).shape == (500, 7)
    rc = main(["compare", str(good), str(noisy), str(wrong), str(cad), "--no-register",
               "--batch", "--quiet", "--summary", str(tmp_path / "s.json"), "--no-pictures",
               "--out-dir", str(tmp_path / "reports")])
    assert rc == 2                                   # one scan failed
    rows = json.loads((tmp_path / "s.json").read_text())["scans"]
    assert [r["status"] for r in rows] == ["ok", "ok", "error"]
    assert rows[1]["far_share"] == pytest.approx(0.05) and rows[1]["warnings"] >= 1
    assert rows[0]["warnings"] == 0 and "c.ply" in rows[2]["scan"]
    assert (tmp_path / "reports" / "a" / "report.json").is_file()
    table = capsys.readouterr().out.splitlines()
    assert table[0].startswith("scan,status,verdict,reasons,points") and len(table) == 4
    assert main(["compare", str(good), str(noisy), str(cad), "--no-register", "--quiet"]) == 2
