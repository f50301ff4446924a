"""``tipgeo report`` / :func:`tipgeo.report.html_report` (issue 29) without a
browser: the page is self-contained (no external reference), its figures
hold the right geometry (edges on the tip's surface, the program's moves, the
scan's deviations), the display decimation follows its rule and never
touches the statistics, and bad input is refused before anything is
written. The browser checks are in test_report_browser.py."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from reportdata import external_refs, figures, links

from tipgeo.cli import main
from tipgeo.presets import preset
from tipgeo.report import REPORT_EXTS, html_report, read_compare_folder
from tipgeo.report.sections import display_sample


def _fig(text, kind):
    figs = figures(text)
    ids = [k for k in figs if k.startswith(f"tg-{kind}-")]
    assert len(ids) == 1, (kind, list(figs))
    return ids[0], figs[ids[0]]


@pytest.fixture(scope="module")
def bevel_page(tmp_path_factory):
    out = tmp_path_factory.mktemp("rep") / "bevel.html"
    info = html_report(["bevel-14G-xi15"], out)
    return info, out.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def compare_dir(tmp_path_factory):
    """A compare run of a bevel scan with a 30 µm burr along the outer edge."""
    d = tmp_path_factory.mktemp("cmp")
    scan = d / "scan.ply"
    assert main(["scan-synth", "bevel-14G-xi15", "-o", str(scan), "--points", "20000",
                 "--burr-um", "30", "60", "--burr-gamma-deg", "150", "210", "--quiet"]) == 0
    main(["compare", str(scan), "bevel-14G-xi15", "--out-dir", str(d / "out"), "--no-pictures",
          "--quiet", "--allow-mismatch"])
    return d / "out"


def test_the_page_loads_nothing_from_anywhere(bevel_page):
    info, text = bevel_page
    assert external_refs(text) == []  # no script/link/img src or href but in-page anchors
    assert text.count("<script") >= 3 and "Plotly.newPlot" in text
    assert info["bytes"] == len(text.encode("utf-8"))
    assert info["sources"] == ["spec"]


def test_cutting_edges_lie_on_the_tip_and_span_the_bevel(bevel_page):
    """The 3D edges (cannula frame) lie on the built tip's surface, on their
    walls' radii, and the outer edge rises 2 r_o / tan ξ (closed form)."""
    import trimesh

    from tipgeo.build import build_tip

    _, text = bevel_page
    _, fig = _fig(text, "tip3d")
    spec = preset("bevel-14G-xi15")
    tip = build_tip(spec)
    mesh = trimesh.Trimesh(tip.vertices, tip.faces, process=False)
    edges = {t["name"]: t for t in fig["data"] if t.get("name", "").endswith("cutting edge")}
    assert set(edges) == {"outer cutting edge", "inner cutting edge"}
    for wall, r in (("outer", spec.cannula.r_o), ("inner", spec.cannula.r_i)):
        t = edges[f"{wall} cutting edge"]
        p = np.column_stack([t["x"], t["y"], t["z"]]).astype(float)
        assert len(p) == 1441
        np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 1]), r, atol=2e-6)
        _, dist, _ = trimesh.proximity.closest_point(mesh, p[::20])
        assert dist.max() < 2e-4  # on the mesh within its chords (0.05 µm tolerance, 672 around)
    zo = np.asarray(edges["outer cutting edge"]["z"], float)
    assert zo.max() - zo.min() == pytest.approx(2 * spec.cannula.r_o /
                                                math.tan(math.radians(15.0)), abs=1e-5)


def test_angle_plots_are_linked_to_the_3d_edge(bevel_page):
    _, text = bevel_page
    tip_id, tip = _fig(text, "tip3d")
    ang_id, ang = _fig(text, "angles")
    (link,) = [x for x in links(text) if x["kind"] == "edge-hover"]
    assert (link["src"], link["dst"]) == (ang_id, tip_id)
    assert tip["data"][link["marker"]]["name"] == "hovered point"
    for t in ang["data"]:
        edge = tip["data"][t["meta"]]
        assert edge["name"] == t["name"].replace(" edge", " cutting edge")
        idx = np.asarray(t["customdata"])
        assert idx.min() == 0 and idx.max() == len(edge["x"]) - 1
    # λ against γ of the outer edge: sin λ = sin ξ·|sin γ|-type closed form is not needed;
    # the plotted values are the angle report's own (peak 75° = 90° − ξ for the bevel)
    lam = [t for t in ang["data"] if t["xaxis"] == "x" and t["name"] == "outer edge"][0]
    y = np.asarray(lam["y"], float)
    assert np.nanmax(y) == pytest.approx(75.0, abs=1e-3)


def test_tables_carry_units(bevel_page):
    _, text = bevel_page
    for head in ("l_c (mm)", "λ max (deg)", "gamma (deg)", "theta_i (deg)"):
        assert f">{head}</th>" in text


def test_display_sample_rule():
    """Beyond the limit: every point outside the band (largest first, at most
    half the limit), then the rest evenly spaced; sorted, no repeats."""
    rng = np.random.default_rng(0)
    d = rng.normal(0, 1.0, 50_000)
    d[rng.choice(50_000, 300, replace=False)] = 40.0
    idx = display_sample(d, band=10.0, limit=5_000)
    assert np.all(np.diff(idx) > 0)
    assert set(np.flatnonzero(np.abs(d) > 10)) <= set(idx)
    assert len(idx) == 5_000
    rest = np.flatnonzero(np.abs(d) <= 10)
    pos = np.searchsorted(rest, idx[np.abs(d[idx]) <= 10])
    assert np.diff(pos).max() <= 11 and pos[0] == 0 and pos[-1] == len(rest) - 1  # evenly
    assert np.array_equal(display_sample(d[:4000], 10.0, limit=5_000), np.arange(4000))
    many = np.full(20_000, 50.0)
    many[::2] = 60.0
    idx = display_sample(many, band=10.0, limit=1_000)
    assert np.sum(many[idx] == 60.0) >= 500  # the largest first


def test_compare_page_statistics_use_every_point(compare_dir, tmp_path):
    data, pts, dev, face, labels = read_compare_folder(compare_dir)
    assert len(pts) == data["compared_points"] == len(dev)
    out = tmp_path / "c.html"
    html_report([compare_dir], out)
    text = out.read_text(encoding="utf-8")
    assert external_refs(text) == []
    _, cloud = _fig(text, "cloud")
    _, hist = _fig(text, "histogram")
    bars = hist["data"][0]
    assert int(np.sum(bars["y"])) == len(dev)  # the histogram counts every point
    cd = np.asarray(bars["customdata"], float)
    lo, hi = cd[:, 0], cd[:, 1]
    np.testing.assert_allclose(lo[1:], hi[:-1])
    for k in np.flatnonzero(np.asarray(bars["y"]) > 0)[:5]:  # each bar counts its range
        assert int(cd[k, 2]) == int(np.sum((dev * 1e3 >= lo[k]) & (dev * 1e3 < hi[k])))
    shown = np.asarray(cloud["data"][0]["marker"]["color"], float)
    assert len(shown) == len(dev)  # 20 000 ≤ the display limit: every point drawn
    np.testing.assert_allclose(np.sort(shown), np.sort(dev * 1e3).astype(np.float32),
                               rtol=1e-6, atol=1e-4)
    st = data["deviation"]["all"]
    assert f"<td class=\"\">{int(st['count'])}</td>" in text
    assert ("PASS" in text) == bool(data["verdict"]["ok"])
    assert any(x["kind"] == "hist-pick" for x in links(text))


def test_mill_run_toolpath(tmp_path):
    """A milling run: every move of the program drawn once by kind, the slider's
    path is the moves' end points turned back to the cannula frame."""
    from cam.mill import MillParams, mill
    from cam.mill.simulate import read_gcode
    from tipgeo.edges import rotate_z

    spec = preset("bevel-14G-xi14.5")
    res = mill(spec, params=MillParams(scallop=0.02, rough=False), simulate_tip=False,
               compare=False)
    out = tmp_path / "m.html"
    info = html_report([spec, res], out)
    assert info["sources"] == ["spec", "mill"]
    text = out.read_text(encoding="utf-8")
    _, fig = _fig(text, "toolpath")
    moves = read_gcode(res.gcode)
    n = len(moves.start)
    counts = [int(t["name"].split(": ")[1].split(" ")[0].replace(",", ""))
              for t in fig["data"] if t.get("name", "").endswith(" moves")]
    assert sum(counts) == n
    (lk,) = [x for x in links(text) if x["kind"] == "toolpath"]
    path = np.column_stack([lk["path"]["x"], lk["path"]["y"], lk["path"]["z"]])
    assert len(path) == n + 1
    want = rotate_z(np.asarray(moves.end, float), res.toolpath.setup.clocking)
    np.testing.assert_allclose(path[1:], want, atol=6e-6)
    assert fig["data"][lk["marker"]]["name"] == "tool tip"


def test_cli_report_and_refusals(tmp_path, capsys):
    out = tmp_path / "r.html"
    assert main(["report", "bevel-14G-xi15", "-o", str(out), "--json", "--quiet"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert Path(info["output"]) == out and out.stat().st_size == info["bytes"]
    for argv, word in ((["report", "no-such-tip", "-o", str(tmp_path / "x.html")], "SOURCE"),
                       (["report", str(tmp_path), "-o", str(tmp_path / "y.html")], "SOURCE"),
                       (["report", "bevel-14G-xi15", "-o", str(tmp_path / "z.txt")], "--output")):
        assert main([*argv, "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.html"]  # nothing else written


def test_build_html_flag(tmp_path, capsys):
    out = tmp_path / "b.html"
    assert main(["build", "bevel-14G-xi15", "-o", str(tmp_path / "b.stl"), "--html", str(out),
                 "--quiet"]) == 0
    assert "wrote " + str(out) in capsys.readouterr().out
    assert "tip3d" in out.read_text(encoding="utf-8")
    assert main(["build", "bevel-14G-xi15", "-o", str(tmp_path / "c.stl"), "--html",
                 str(tmp_path / "c.png"), "--quiet"]) == 2


def test_extensions_agree():
    from tipgeo.cli.report import HTML_EXTS

    assert tuple(HTML_EXTS) == tuple(REPORT_EXTS)


def test_fem_folder(tmp_path):
    """A ``tipgeo fem`` folder: the FEM curve, eq. 4.22 beside it and their
    difference (mN) as plotted are the run's own numbers."""
    d = np.linspace(0.0, 0.3, 11)
    run = {"name": "punch-plain", "model": "axisymmetric", "depth_mm": 0.3,
           "curve": [{"depth_mm": float(x), "force_N": float(0.08 * x + 0.01 * x * x),
                      "analytical_N": float(0.079 * x)} for x in d],
           "verdict": {"ok": True, "subject": "FEM", "checks": [], "reasons": []}}
    (tmp_path / "fem").mkdir()
    (tmp_path / "fem" / "punch-plain_axisymmetric.json").write_text(json.dumps(run))
    (tmp_path / "fem" / "other.json").write_text('{"not": "a run"}')
    out = tmp_path / "f.html"
    info = html_report([tmp_path / "fem"], out)
    assert info["sources"] == ["fem-folder"]
    text = out.read_text(encoding="utf-8")
    _, fig = _fig(text, "fem-force")
    fem, ana, diff = fig["data"]
    assert ana["name"] == "analytical eq. 4.22"
    np.testing.assert_allclose(fem["y"], 0.08 * d + 0.01 * d * d, rtol=1e-12)
    np.testing.assert_allclose(diff["y"], (0.001 * d + 0.01 * d * d) * 1e3, atol=1e-12)


def test_study_folder(tmp_path):
    """A ``tipgeo optimize`` folder: each fitted response over the variable
    from sweep.csv, the optima's built values as stars, the optima table."""
    f = tmp_path / "study"
    f.mkdir()
    xi = np.arange(15.0, 80.0, 5.0)
    rows = ["index,status,xi_deg,lambda_max_deg,error"] + \
        [f"{k},ok,{x},{90 - x},"for k, x in enumerate(xi)] + [f"{len(xi)},failed,80,,boom"]
    (f / "sweep.csv").write_text("\n".join(rows) + "\n")
    rep = {"name": "bevel-study", "variables": [{"name": "xi_deg", "min": 15, "max": 75}],
           "responses": {"recorded": ["lambda_max_deg"], "fitted": ["lambda_max_deg"]},
           "optima": [{"objective": "max-lambda", "x": {"xi_deg": 15.0},
                       "responses": {"lambda_max_deg": {"predicted": 74.99, "actual": 75.0,
                                                        "error_frac": 1e-4,
                                                        "inside95": True}}}],
           "surrogate": {"loo": {}}, "verdict": {"ok": True, "subject": "study", "checks": [],
                                                "reasons": []}}
    (f / "report.json").write_text(json.dumps(rep))
    out = tmp_path / "s.html"
    assert html_report([f], out)["sources"] == ["study-folder"]
    text = out.read_text(encoding="utf-8")
    assert "No GP drawn" in text  # no surrogate.json
    _, fig = _fig(text, "responses")
    sweep, star = fig["data"]
    np.testing.assert_allclose(sweep["x"], xi)  # the failed design is left out
    np.testing.assert_allclose(sweep["y"], 90 - xi)
    assert (star["x"], star["y"]) == ([15.0], [75.0]) and star["name"] == "max-lambda"
    assert ">GP predicted</th>" in text


def test_grind_html_flag(tmp_path, capsys):
    """``grind --html``: the set-up per face of the program (ξ of the spec)
    and the simulated ground tip beside the CAD."""
    out = tmp_path / "g.html"
    assert main(["grind", "bevel-14G-xi15", "--html", str(out), "--quiet"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    text = out.read_text(encoding="utf-8")
    assert external_refs(text) == []
    _, fig = _fig(text, "ground")
    assert {t["scene"] for t in fig["data"]} == {"scene", "scene2"}
    assert ">xi (deg)</th>" in text and '<td class="">15</td>' in text


def test_study_folder_gp_is_the_studys_own(tmp_path):
    """With surrogate.json the page draws the study's GP, rebuilt from its
    hyperparameters: it interpolates the designs (no nugget) and gives the
    optimum's recorded prediction; a surrogate.json that does not reproduce
    it is not drawn."""
    from tipgeo.optimize.gp import GaussianProcess

    f = tmp_path / "study"
    f.mkdir()
    xi = np.array([15.0, 25.0, 35.0, 50.0, 60.0, 75.0])
    lc = 2 * 1.054 / np.sin(np.radians(xi))
    (f / "sweep.csv").write_text("index,status,xi_deg,l_c_mm\n" + "".join(
        f"{k},ok,{float(x)!r},{float(y)!r}\n" for k, (x, y) in enumerate(zip(xi, lc))))
    g = GaussianProcess(kernel="matern52", starts=4, seed=0).fit(((xi - 15) / 60)[:, None], lc)
    x_opt = 42.0
    pred = float(np.ravel(g.predict(np.array([[(x_opt - 15) / 60]]), noise=True))[0])
    sur = {"mode": "independent", "bounds": [[15.0, 75.0]], "calibrate": False,
           "models": [{"responses": ["l_c_mm"], "kernel": "matern52",
                       "omega": [float(w) for w in np.ravel(g.fit_.omega)], "nugget": 0.0}],
           "loo": {}}
    (f / "surrogate.json").write_text(json.dumps(sur))
    rep = {"name": "s", "variables": [{"name": "xi_deg", "min": 15.0, "max": 75.0}],
           "responses": {"recorded": ["l_c_mm"], "fitted": ["l_c_mm"]},
           "optima": [{"objective": "o", "x": {"xi_deg": x_opt},
                       "responses": {"l_c_mm": {"predicted": pred, "actual": 3.0}}}]}
    (f / "report.json").write_text(json.dumps(rep))
    html_report([f], tmp_path / "a.html")
    _, fig = _fig((tmp_path / "a.html").read_text(encoding="utf-8"), "responses")
    mean = next(t for t in fig["data"] if t["name"] == "GP mean")
    xg, mg = np.asarray(mean["x"], float), np.asarray(mean["y"], float)
    for x, y in zip(xi, lc):  # interpolates every design (grid step 0.2° hits them)
        k = int(np.argmin(np.abs(xg - x)))
        assert xg[k] == pytest.approx(x, abs=1e-9) and mg[k] == pytest.approx(y, rel=1e-6)
    rep["optima"][0]["responses"]["l_c_mm"]["predicted"] = pred + 0.5
    (f / "report.json").write_text(json.dumps(rep))
    html_report([f], tmp_path / "b.html")
    text = (tmp_path / "b.html").read_text(encoding="utf-8")
    assert "No GP drawn" in text and '"GP mean"' not in text


def test_laser_html_moves_on_the_outer_wall(tmp_path, capsys):
    """``laser punch-C2 --html``: the program written, simulated against its
    spec and drawn in the cannula frame — every beam-on point lies in the
    plane tangent to the outer wall at γ = C of one of the spec's 16 notch
    angles (w·p = r_o within 1e-6 mm), and the first beam-on move starts at
    u = X − X0, z = z_rim(γ) − (Y − Y0) (origin 0, 0); the verdict PASS; no
    network reference."""
    from gcode.pipeline import laser_check

    spec = preset("punch-C2")
    pgm, out = tmp_path / "p.pgm", tmp_path / "p.html"
    assert main(["laser", "punch-C2", "-o", str(pgm), "--html", str(out), "--quiet"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    text = out.read_text(encoding="utf-8")
    assert external_refs(text) == []  # no src/href loads anything (the browser test: no request)
    assert "PASS laser-cut serrations vs spec" in text
    _, fig = _fig(text, "toolpath")
    (on,) = [t for t in fig["data"] if t.get("name", "").startswith("beam on: ")]
    p = np.column_stack([on["x"], on["y"], on["z"]]).astype(float)
    p = p[np.isfinite(p).all(axis=1)]
    segs = laser_check(pgm.read_text(encoding="utf-8")).toolpath.segments
    beam = [s for s in segs if s.beam]
    assert on["name"] == f"beam on: {len(beam):,} moves"
    cs = sorted({round(s.c0, 9) for s in beam})
    assert len(cs) == 16
    g = np.radians(cs)
    w = np.stack([np.cos(g), np.sin(g)], 1)  # (16, 2) outward normals
    r_o, r_i = spec.cannula.r_o, spec.cannula.r_i
    dots = p[:, :2] @ w.T
    near = np.argmax(dots, axis=1)  # the notch plane a point lies in (22.5° apart: no tie)
    np.testing.assert_allclose(dots[np.arange(len(p)), near], r_o, atol=1e-6)
    assert np.all(np.abs(p[:, :2] @ np.stack([-np.sin(g), np.cos(g)], 1).T)[
        np.arange(len(p)), near] < r_i)
    # the first beam-on move: its start point, by the ablation's mapping
    s0 = beam[0]
    g0 = math.radians(s0.c0)
    z_rim = min(float(np.min(np.atleast_1d(z))) for z in
                (c.edge_z(np.array([g0]), r_i, spec.cannula) for c in spec.cutters
                 if c.process != "laser") if z is not None)
    u, z = s0.start[0], z_rim - s0.start[1]
    want = u * np.array([-math.sin(g0), math.cos(g0), 0]) + np.array([0, 0, z]) + \
        r_o * np.array([math.cos(g0), math.sin(g0), 0])
    np.testing.assert_allclose(p[0], want, atol=1e-6)
    (lk,) = [x for x in links(text) if x["kind"] == "toolpath"]
    assert len(lk["path"]["x"]) == len(segs) + 1 and lk["path"]["names"] == \
        ["rapid", "beam off", "beam on"]
    _, sim = _fig(text, "ablated")
    assert {t["scene"] for t in sim["data"]} == {"scene", "scene2"}


def test_appendix_c_html_fails(tmp_path, capsys):
    """The printed Appendix C program against punch-C2: the page carries the
    FAIL verdict the command exits 1 with; ``--html`` without ``--spec`` or
    on ``gcode check`` is a one-line error, exit 2, nothing written."""
    pgm = Path(__file__).resolve().parents[1] / "samples" / "appendix_c.pgm"
    out = tmp_path / "a.html"
    assert main(["gcode", "sim", str(pgm), "--spec", "punch-C2", "--origin-mm", "-0.15", "0",
                 "--html", str(out), "--quiet"]) == 1
    capsys.readouterr()
    text = out.read_text(encoding="utf-8")
    assert external_refs(text) == []
    assert "FAIL laser-cut serrations vs spec: " in text and "cut beyond CAD" in text
    _fig(text, "toolpath")
    for argv in (["gcode", "sim", str(pgm)], ["gcode", "check", str(pgm), "--spec", "punch-C2"]):
        assert main([*argv, "--html", str(tmp_path / "b.html"), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--html" in err[0]
    assert sorted(q.name for q in tmp_path.iterdir()) == ["a.html"]
