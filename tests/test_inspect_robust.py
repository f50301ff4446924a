"""Robust inspection input: degenerate scans are one-line ScanErrors (exit 2),
scans are read in chunks into compact storage without losing precision,
scans that do not match the CAD are refused (or let through with a warning),
and a failed comparison leaves nothing in --out."""

import json
import math

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.cannula import Cannula
from tipgeo.cli import main
from tipgeo.inspect import (
    ExactSolid,
    Misalignment,
    Scan,
    ScanError,
    compare,
    load_cad,
    load_scan,
    register,
    scanio,
    synthetic_scan,
    write_ply,
)
from tipgeo.tolerances import tol

settings = tol.inspect

BEVEL = "bevel-14G-xi14.5"
MIS = Misalignment(20.0, 1.0, 30.0, (0.2, -0.1, 0.3))


@pytest.fixture(scope="module")
def scan():
    """15 000 points of the 14G bevel (σ = 1 µm), misaligned."""
    return synthetic_scan(preset(BEVEL), points=15000, noise=0.001, seed=21, misalignment=MIS)


@pytest.fixture(scope="module")
def cad():
    return load_cad(preset(BEVEL))


def _error_line(capsys, rc, *needles):
    """rc is 2 and stderr is one 'tipgeo: error:' line holding every needle."""
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tipgeo: error:"), err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def _fail_line(capsys, rc, *needles):
    """A verdict, not bad input: rc is 1, stdout says FAIL and stderr is one
    'tipgeo: fail:' line holding every needle."""
    cap = capsys.readouterr()
    assert rc == 1, cap.err
    assert "Traceback" not in cap.err
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tipgeo: fail:"), cap.err
    assert cap.out.startswith("FAIL ")
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


# -----------------------------------------------------------------------------
# 1. degenerate scans
def _degenerate(tmp_path):
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 1.0, 500)[:, None]
    files = {
        "one.ply": np.array([[0.1, 0.2, 0.3]]),
        "two.ply": np.array([[0.1, 0.2, 0.3], [1.0, 1.0, 1.0]]),
        "line.ply": np.array([0.25, 0.5, 1.0]) * t * 4.0,
        "same.ply": np.tile([[1.0, 2.0, 3.0]], (500, 1)),
        "huge.ply": np.vstack([rng.normal(size=(499, 3)), [[1e300, 0.0, 0.0]]]),
        "nan.ply": np.vstack([rng.normal(size=(300, 3)), [[np.nan, 1.0, 2.0]]]),
    }
    for name, pts in files.items():
        write_ply(tmp_path / name, pts)
    (tmp_path / "empty.xyz").write_bytes(b"")
    (tmp_path / "metres.xyz").write_text("".join(f"{x:.6f} 2 3\n" for x in
                                                 rng.uniform(2e3, 3e3, 200)) + "4000 2 3\n")
    return tmp_path


@pytest.mark.parametrize("no_register", [False, True])
@pytest.mark.parametrize("name, units, needles", [
    ("one.ply", "mm", ["'one.ply' has 1 point;", "needs at least {n} points spread over"]),
    ("two.ply", "mm", ["'two.ply' has 2 points;", "needs at least {n} points"]),
    ("line.ply", "mm", ["the 500 points lie on a line", "mm along it"]),
    ("same.ply", "mm", ["all 500 points lie at one place, (1, 2, 3) mm", "RMS spread 0 mm"]),
    ("huge.ply", "mm", ["coordinates up to 1e+300 mm; allowed |x| ≤ 1e+06 mm"]),
    ("nan.ply", "mm", ["nan.ply': 1 of 301 points have non-finite", "the first is point 301"]),
    ("empty.xyz", "mm", ["empty.xyz' is empty (0 bytes)"]),
    ("metres.xyz", "m", ["(4e+06 mm); allowed |x| ≤ 1e+06 mm"]),
])
def test_degenerate_scans_are_one_line_errors(tmp_path, capsys, name, units, needles,
                                              no_register):
    """Each of these used to end in a LinAlgError traceback, an overflow, or a
    meaningless result; now exit 2 naming the problem and the figures, with
    and without registration, and --out stays absent."""
    _degenerate(tmp_path)
    need = settings.min_points_compare if no_register else settings.min_points_register
    out = tmp_path / "rep"
    argv = ["compare", str(tmp_path / name), BEVEL, "--units", units, "--quiet",
            "--out-dir", str(out)] + (["--no-register"] if no_register else [])
    _error_line(capsys, main(argv), *[s.format(n=need) for s in needles])
    assert not out.exists()


def test_metres_overflow_names_the_file_units(tmp_path, capsys):
    _degenerate(tmp_path)
    rc = main(["compare", str(tmp_path / "metres.xyz"), BEVEL, "--units", "m", "--quiet"])
    line = _error_line(capsys, rc, "coordinates up to 4e+03 m (4e+06 mm)")
    assert "wrong --units" in line


def test_a_planar_scan_registers_by_a_planar_face_or_is_refused(scan, capsys, tmp_path):
    """The bevel face alone (issue 25: it was refused): against the bevel's
    CAD it registers by its outline, the face's half-turn symmetry reported
    free (exit 0, a pass); against a CAD with no planar cut face (the conical
    tip) registration refuses it with the figures and the way out; already in
    the cannula frame it is a legitimate partial scan and compares."""
    spec = preset(BEVEL)
    face = ExactSolid(spec).distances(scan.points_cad).label_of() == "cut:bevel"
    assert 1000 < face.sum() < 4000
    write_ply(tmp_path / "face-scanner.ply", scan.points[face])
    write_ply(tmp_path / "face-cad.ply", scan.points_cad[face])
    res = compare(tmp_path / "face-scanner.ply", spec, pictures=False)
    assert res.registration.search["face_only"] == "cut:bevel"
    assert any("about its normal" in f for f in res.registration.fixed_directions)
    assert res.verdict.ok and res.stats["all"]["rms_um"] < 1.5   # σ = 1 µm
    rc = main(["compare", str(tmp_path / "face-scanner.ply"), "conical-14G-theta15", "--quiet"])
    line = _error_line(capsys, rc, f"the {face.sum()} points lie on a plane",
                       "registration needs ≥ 0.0211 mm = 2 % of the CAD's outer radius",
                       "--no-register")
    off = float(line.split("(RMS ")[1].split(" mm")[0])
    assert off < 0.002  # the bevel is flat to the noise
    res = compare(tmp_path / "face-cad.ply", spec, register_scan=False)
    assert res.match["ok"] and res.match["inlier_share"] == 1.0
    assert res.match["diameters"] == {}  # no wall scanned: none judged
    assert set(res.stats["regions"]) == {"cut:bevel"}
    assert abs(res.stats["all"]["mean_um"]) < 0.1


def test_register_refuses_too_few_points_directly(cad):
    with pytest.raises(ScanError, match="has 3 points; registration needs at least 100"):
        register(np.random.default_rng(1).normal(size=(3, 3)), cad)
    with pytest.raises(ScanError, match="non-finite"):
        register(np.full((300, 3), np.nan), cad)


# -----------------------------------------------------------------------------
# 2. chunked reading and compact storage
def test_text_scans_parse_in_chunks_like_loadtxt(tmp_path, monkeypatch):
    """Chunks of a few hundred bytes (every line boundary case), comments,
    a header line, commas, extra columns: the same numbers as np.loadtxt."""
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(1000, 3)) * 2.0
    lines = [f"{x:.9f} {y:.9f} {z:.9f}" for x, y, z in pts]
    text = "X Y Z\n# a comment\n" + "\n".join(
        (ln.replace(" ", ",") if i % 7 == 0 else ln) + (" 255 0 0" if i % 5 == 0 else "")
        + (" // note" if i % 11 == 0 else "") for i, ln in enumerate(lines))
    (tmp_path / "s.txt").write_text(text)
    monkeypatch.setattr(scanio, "_CHUNK_BYTES", 301)
    s = load_scan(tmp_path / "s.txt")
    assert s.local.dtype == np.float64 and s.rounding_mm == 0.0
    ref = np.array([[float(v) for v in ln.split()] for ln in lines])
    assert np.array_equal(s.points, ref)
    # PTS: a count line first; XYZN: normals
    (tmp_path / "s.pts").write_text(f"{len(pts)}\n" + "\n".join(lines) + "\n")
    assert np.array_equal(load_scan(tmp_path / "s.pts").points, ref)
    nrm = rng.normal(size=(1000, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    np.savetxt(tmp_path / "s.xyzn", np.hstack([pts, nrm]), fmt="%.9f")
    sn = load_scan(tmp_path / "s.xyzn")
    assert np.allclose(sn.normals, nrm, atol=1e-9, rtol=0)


def test_text_errors_name_the_line(tmp_path):
    (tmp_path / "bad.xyz").write_text("1 2 3\n4 5 6\n7 x 9\n")
    with pytest.raises(ScanError, match=r"bad.xyz'.*'x' to float64 on line 3, column 2"):
        load_scan(tmp_path / "bad.xyz")
    (tmp_path / "two.xyz").write_text("1 2\n3 4\n")
    with pytest.raises(ScanError, match="lines have 2 value"):
        load_scan(tmp_path / "two.xyz")
    (tmp_path / "c.xyz").write_text("# nothing here\n\n")
    with pytest.raises(ScanError, match="holds no points"):
        load_scan(tmp_path / "c.xyz")


def test_binary_and_ascii_ply_vertices(tmp_path, monkeypatch):
    """Little- and big-endian binary PLY in chunks of 64 vertices, ASCII PLY
    with a face element after the vertices, a truncated file."""
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(500, 3))
    monkeypatch.setattr(scanio, "_CHUNK_ROWS", 64)
    for bo, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
        arr = np.empty(len(pts), [("x", bo + "f8"), ("y", bo + "f8"), ("z", bo + "f8"),
                                  ("q", bo + "f4")])
        arr["x"], arr["y"], arr["z"], arr["q"] = pts[:, 0], pts[:, 1], pts[:, 2], 1.0
        head = (f"ply\nformat {fmt} 1.0\nelement vertex {len(pts)}\nproperty double x\n"
                "property double y\nproperty double z\nproperty float q\nend_header\n")
        (tmp_path / "b.ply").write_bytes(head.encode() + arr.tobytes())
        assert np.array_equal(load_scan(tmp_path / "b.ply").points, pts)
    body = "\n".join(f"{x:.17g} {y:.17g} {z:.17g}" for x, y, z in pts)
    (tmp_path / "a.ply").write_text(
        f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty double x\n"
        "property double y\nproperty double z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n" + body + "\n3 0 1 2\n")
    assert np.array_equal(load_scan(tmp_path / "a.ply").points, pts)
    write_ply(tmp_path / "t.ply", pts)
    data = (tmp_path / "t.ply").read_bytes()
    (tmp_path / "t.ply").write_bytes(data[:-24 * 100 - 5])
    with pytest.raises(ScanError, match="truncated: 399 of 500 vertices"):
        load_scan(tmp_path / "t.ply")


def test_compact_storage_rounds_below_half_a_float32_ulp(tmp_path):
    """float32 offsets from a float64 origin 500 mm away: every coordinate
    within 2⁻²¹ mm of the value read; offsets of 16 mm or more stay float64."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-6.0, 6.0, (20000, 3)) + [500.0, -250.0, 125.0]
    write_ply(tmp_path / "s.ply", pts)
    s = load_scan(tmp_path / "s.ply", compact=True)
    assert s.local.dtype == np.float32
    assert s.rounding_mm == 2.0 ** -22  # half the ulp of float32 in [4, 8)
    err = np.abs(s.points - pts).max()
    assert 0 < err <= 2.0 ** -22
    assert s.meta["storage"].startswith("float32")
    wide = np.vstack([pts, [[540.0, -250.0, 125.0]]])  # 34 mm from the origin
    write_ply(tmp_path / "w.ply", wide)
    w = load_scan(tmp_path / "w.ply", compact=True)
    assert w.local.dtype == np.float64 and w.rounding_mm == 0.0
    assert np.abs(w.points - wide).max() <= 1e-13


def test_the_compact_pipeline_keeps_deviations_to_a_nanometre_fraction(tmp_path, scan, cad):
    """compare() of a file (float32 offsets, chunked float64 deviations)
    against a full float64 evaluation with the same transform: the
    deviations agree within 1e-6 mm = 0.001 µm (measured on 2·10⁷ points:
    9.4e-5 µm), and the statistics within 1e-4 µm."""
    pts = scan.points + [80.0, -40.0, 20.0]
    write_ply(tmp_path / "s.ply", pts)
    res = compare(tmp_path / "s.ply", cad)
    assert res.scan.local.dtype == np.float32 and res.points.dtype == np.float32
    assert res.distances.distance.dtype == np.float64
    assert len(res.points) == len(pts)
    T = res.registration.transform
    d64 = cad.distances(pts @ T[:3, :3].T + T[:3, 3]).distance
    assert np.abs(res.distances.distance - d64).max() <= 1e-6
    assert res.stats["all"]["rms_um"] == pytest.approx(np.sqrt(np.mean(d64 ** 2)) * 1e3,
                                                       abs=1e-4)
    assert res.registration.fitness > 0.99
    # the registration maps the scanner frame, origin included
    S = np.eye(4)
    S[:3, 3] = [80.0, -40.0, 20.0]
    D = T @ S @ scan.cad_to_scan  # CAD → scanner → shifted → (registration) CAD
    assert math.degrees(math.acos(min(1.0, (np.trace(D[:3, :3]) - 1) / 2))) < 0.05
    assert np.linalg.norm(D[:3, 3]) < 0.005


# -----------------------------------------------------------------------------
# 3. scans that do not match the CAD
@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory):
    """A sphere of the CAD's outer radius around the tip's middle: its axis
    fit passes, so only the match check can tell."""
    rng = np.random.default_rng(6)
    v = rng.normal(size=(3000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    path = tmp_path_factory.mktemp("sphere") / "sphere.ply"
    write_ply(path, v * 1.054 + [0.3, 0.2, 4.0])
    return path


def test_a_sphere_is_refused_with_the_figures(sphere_file, tmp_path, capsys):
    out = tmp_path / "rep"
    rc = main(["compare", str(sphere_file), BEVEL, "--quiet", "--out-dir", str(out)])
    line = _fail_line(capsys, rc, "'sphere.ply' does not match the CAD 'bevel-14G-xi14.5'",
                       "within 50 µm of the CAD surface (needs ≥ 50 %)",
                       "fitness", "needs ≥ 0.3)", "--allow-mismatch")
    share = float(line.split("inlier share ")[1].split(" %")[0])
    assert 10 < share < 50
    assert not out.exists()
    rc = main(["compare", str(sphere_file), BEVEL, "--quiet", "--no-register"])
    _fail_line(capsys, rc, "does not match the CAD", "inlier share")


def test_the_override_compares_a_mismatch_with_a_warning(sphere_file, tmp_path, capsys):
    out = tmp_path / "rep"
    rc = main(["compare", str(sphere_file), BEVEL, "--quiet", "--json", "--allow-mismatch",
               "--out-dir", str(out), "--no-pictures"])
    assert rc == 1  # compared, but the verdict is a fail: not this tip
    rep = json.loads(capsys.readouterr().out)
    assert rep["match"]["ok"] is False
    assert rep["verdict"]["ok"] is False
    assert rep["verdict"]["reasons"][0].startswith("the scan is not this tip")
    assert rep["match"]["inlier_share"] < 0.5
    assert any("does not match the CAD" in w and "compared anyway" in w
               for w in rep["warnings"])
    assert "match with the CAD: **no**" in (out / "report.md").read_text()
    assert sorted(p.name for p in out.iterdir()) == ["deviations.ply", "report.json",
                                                    "report.md"]


def test_another_gauge_is_refused_by_its_diameter(capsys, tmp_path):
    """A 15G tube (1.829 mm) with the same bevel, compared with the 14G CAD:
    refused by its outer wall, before the registration's search."""
    spec15 = preset(BEVEL).with_(cannula=Cannula.from_gauge(15))
    s = synthetic_scan(spec15, points=6000, noise=0.001, seed=7, misalignment=MIS)
    write_ply(tmp_path / "g15.ply", s.points)
    rc = main(["compare", str(tmp_path / "g15.ply"), BEVEL, "--quiet"])
    line = _fail_line(capsys, rc, "CAD's outer diameter is 2.1080 mm", "allowed ±5 %",
                       "refused before registration")
    od = float(line.split("outermost wall has diameter ")[1].split(" mm")[0])
    assert od == pytest.approx(1.829, rel=0.01)  # an estimate for a ±5 % decision


@pytest.mark.parametrize(("scan_gauge", "cad_gauge"), [(14, 16), (14, 12), (16, 14)])
def test_nested_gauges_are_refused_before_the_search(scan_gauge, cad_gauge, monkeypatch):
    """A 14G tube's outer wall (Ø 2.108) is nearly a 12G tube's bore and a
    16G tube's outer wall (Ø 1.651) nearly a 14G tube's bore (Ø 1.6): the
    outermost of two walls must be the CAD's outer wall. The global search is
    never reached (it would raise if called)."""
    import importlib

    reg_mod = importlib.import_module("tipgeo.inspect.register")  # the module

    spec = preset(BEVEL).with_(cannula=Cannula.from_gauge(scan_gauge))
    s = synthetic_scan(spec, points=6000, noise=0.001, seed=3, misalignment=MIS)
    cad_spec = preset(BEVEL).with_(cannula=Cannula.from_gauge(cad_gauge))

    def no_search(*a, **k):
        raise AssertionError("the global search ran")

    monkeypatch.setattr(reg_mod, "_search", no_search)
    with pytest.raises(ScanError, match="another gauge") as e:
        compare(s.points, load_cad(cad_spec))
    od = float(str(e.value).split("outermost wall has diameter ")[1].split(" mm")[0])
    # the refusal estimate (about an axis found without a radius) is good to 1 %
    assert od == pytest.approx(Cannula.from_gauge(scan_gauge).outer_diameter, rel=0.01)


def test_wall_radii_of_a_scan_are_its_two_walls(scan):
    """The coaxial walls found about the true axis are the tube's r_i and r_o."""
    from tipgeo.inspect.register import wall_radii

    c = Cannula.from_gauge(14)
    walls = wall_radii(scan.points_cad, np.zeros(3), np.array([0.0, 0.0, 1.0]), c.r_o)
    assert walls == pytest.approx([c.r_i, c.r_o], abs=0.003)


def test_a_half_tube_scan_is_accepted(scan, cad):
    """Half the tube (the side with the bevel's tip, y > 0): a legitimate
    partial scan that matches."""
    half = scan.points_cad[:, 1] > 0
    res = compare(scan.points[half], cad)
    m = res.match
    assert m["ok"] and m["inlier_share"] == 1.0 and m["fitness"] > 0.99
    assert m["diameters"]["fitted outer diameter"]["mm"] == pytest.approx(2.108, abs=1e-3)
    D = res.registration.transform @ scan.cad_to_scan
    assert math.degrees(math.acos(min(1.0, (np.trace(D[:3, :3]) - 1) / 2))) < 0.05
    assert not any("match" in w for w in res.warnings)


# -----------------------------------------------------------------------------
# nothing left behind
def test_a_failing_report_leaves_nothing_in_out(scan, tmp_path, monkeypatch):
    from tipgeo.inspect import report

    def boom(res, path):
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(report, "plot_histogram", boom)
    new = tmp_path / "a" / "b"
    with pytest.raises(OSError, match="simulated"):
        compare(scan.points, preset(BEVEL), out=new)
    assert not (tmp_path / "a").exists()
    old = tmp_path / "old"
    old.mkdir()
    (old / "keep.txt").write_text("mine")
    with pytest.raises(OSError, match="simulated"):
        compare(scan.points, preset(BEVEL), out=old)
    assert [p.name for p in old.iterdir()] == ["keep.txt"]


def test_out_that_is_a_file_is_refused_before_any_work(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    write_ply(tmp_path / "s.ply", np.zeros((3, 3)))
    rc = main(["compare", str(tmp_path / "s.ply"), BEVEL, "--out-dir", str(tmp_path / "f")])
    _error_line(capsys, rc, "--out-dir", "is a file")
    assert (tmp_path / "f").read_text() == "x"


def test_scan_objects_keep_their_api():
    s = Scan(np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.5]]))
    assert s.points.dtype == np.float64 and len(s) == 2 and s.rounding_mm == 0.0
    c = Scan(np.array([[0.5, 0.0, 0.0]], np.float32), origin=[10.0, 0.0, 0.0])
    assert np.array_equal(c.points, [[10.5, 0.0, 0.0]])
    with pytest.raises(ScanError, match=r"coordinates up to 2e\+07 mm"):
        Scan(np.array([[2e7, 0.0, 0.0]]))


def test_scan_synth_checks_its_output_folders_before_scanning(tmp_path, capsys):
    out = tmp_path / "s.ply"
    rc = main(["scan-synth", BEVEL, "-o", str(out), "--points", "1000", "--quiet",
               "--truth", str(tmp_path / "missing" / "t.json")])
    _error_line(capsys, rc, "--truth", "the folder", "does not exist")
    rc = main(["scan-synth", BEVEL, "-o", str(out), "--truth", str(out), "--quiet"])
    _error_line(capsys, rc, "--truth", "also given as --output")
    assert not out.exists()
