"""The HTML reports in a real browser (issue 29): headless Chromium (Debian's
``chromium``, driven over its DevTools protocol by tests/cdp.py) opens the
reports of a bevel tip, a helical mill run and a compare run with every
network request blocked and recorded, and checks: no console error or
uncaught exception, no network request, every plot rendered (plotly's
``_fullData`` and its SVG layer), the WebGL canvases present and not blank
(pixel statistics of a screenshot), the tables present, the hover on an
angle plot marking the 3D edge, the slider moving the toolpath's tool tip,
and a click on a histogram bar marking its points. Skips with the install
line when no Chromium is found."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from cdp import INSTALL, Browser, find_chromium

from tipgeo.cli import main
from tipgeo.presets import preset
from tipgeo.report import html_report

CHROMIUM = find_chromium()
pytestmark = pytest.mark.skipif(CHROMIUM is None,
                                reason=f"no Chromium (install: {INSTALL})")

READY = ("window.tipgeoReport && Array.from(document.querySelectorAll('.tg-plot'))"
         ".every(d => d._fullData && d.querySelector('.main-svg'))")


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    d = tmp_path_factory.mktemp("browser")
    html_report(["bevel-14G-xi15"], d / "bevel.html")
    from cam.mill import MillParams, mill

    spec = preset("helical-14G")
    res = mill(spec, params=MillParams(scallop=0.02, rough=False), simulate_tip=True,
               compare=False, cell_um=(40.0, 4.0))
    html_report([spec, res], d / "mill.html")
    scan = d / "scan.ply"
    assert main(["scan-synth", "bevel-14G-xi15", "-o", str(scan), "--points", "20000",
                 "--burr-um", "30", "60", "--burr-gamma-deg", "150", "210", "--quiet"]) == 0
    main(["compare", str(scan), "bevel-14G-xi15", "--html", str(d / "compare.html"),
          "--no-pictures", "--quiet", "--allow-mismatch"])
    return {k: d / f"{k}.html" for k in ("bevel", "mill", "compare")}


@pytest.fixture(scope="module")
def browser():
    b = Browser(CHROMIUM, width=1300, height=900, timeout=120)
    try:
        yield b
    finally:
        b.close()


def _open(browser, path):
    browser.open(path, ready=READY, wait_s=240)
    assert browser.errors() == []
    assert browser.requests() == []  # every http(s)/ws request would be listed (and blocked)
    assert browser.eval("window.tipgeoReport.errors") == []


def _plots(browser):
    return browser.eval("""Array.from(document.querySelectorAll('.tg-plot')).map(d => ({
        id: d.id, traces: d._fullData.length, svg: !!d.querySelector('.main-svg'),
        gl: d.querySelectorAll('canvas').length, scene: !!d._fullLayout.scene}))""")


def _not_blank(browser, div_id):
    """Pixel statistics of a screenshot of one 3D plot: it shows a picture,
    not an empty box (many colours, a wide spread of grey levels)."""
    from PIL import Image

    r = browser.eval(f"""(() => {{const d = document.getElementById('{div_id}');
        d.scrollIntoView(); const r = d.getBoundingClientRect();
        return {{x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width,
                 height: r.height}}; }})()""")
    browser.drain(1.0)
    img = Image.open(io.BytesIO(browser.screenshot(clip=r))).convert("RGB")
    a = np.asarray(img, float)
    grey = a.mean(axis=2)
    colours = len(np.unique(a.reshape(-1, 3).astype(np.uint8), axis=0))
    return grey.std(), colours, img


def _check_3d(browser, plots, n3d, look: str):
    """Every 3D plot has its WebGL canvas; the one of kind ``look`` shows a
    picture (one screenshot a page: they are slow in a software renderer)."""
    scenes = [p for p in plots if p["scene"]]
    assert len(scenes) == n3d
    assert all(p["gl"] >= 1 for p in scenes), scenes  # the WebGL canvases
    (p,) = [p for p in scenes if p["id"].startswith(f"tg-{look}-")]
    std, colours, _ = _not_blank(browser, p["id"])
    assert std > 8.0 and colours > 200, (p["id"], std, colours)


def test_bevel_tip_page(browser, pages):
    _open(browser, pages["bevel"])
    plots = _plots(browser)
    assert all(p["traces"] > 0 and p["svg"] for p in plots)
    _check_3d(browser, plots, 1, "tip3d")
    assert browser.eval("document.querySelectorAll('table.tg-table').length") >= 4
    # the mouse over the λ plot at γ = 90° (a real move through the DevTools protocol)
    # marks the hovered point of the edge on the 3D plot
    link = next(x for x in browser.eval("window.tipgeoReport.links")
                if x["kind"] == "edge-hover")
    pos = browser.eval(f"""(() => {{
        const a = document.getElementById('{link['src']}'); a.scrollIntoView();
        const r = a.getBoundingClientRect(), L = a._fullLayout, t = a._fullData[0];
        return {{x: r.left + L.xaxis._offset + L.xaxis.l2p(t.x[360]),
                 y: r.top + L.yaxis._offset + L.yaxis.l2p(t.y[360])}}; }})()""")
    browser.drain(0.5)
    browser.call("Input.dispatchMouseEvent", session=True, type="mouseMoved", x=pos["x"],
                 y=pos["y"])
    browser.drain(1.5)
    got = browser.eval(f"""(() => {{
        const a = document.getElementById('{link['src']}'),
              t = document.getElementById('{link['dst']}'), h = a._hoverdata[0];
        const m = t._fullData[{link['marker']}], e = t._fullData[h.data.meta], i = h.customdata;
        return {{m: [m.x[0], m.y[0], m.z[0]], e: [e.x[i], e.y[i], e.z[i]], g: e.customdata[i],
                 text: document.getElementById('{link['readout']}').textContent}}; }})()""")
    np.testing.assert_allclose(got["m"], got["e"], rtol=0, atol=1e-9)
    assert abs(got["g"] - 90.0) < 1.0 and "edge: γ" in got["text"]


def test_helical_mill_page(browser, pages):
    _open(browser, pages["mill"])
    plots = _plots(browser)
    assert all(p["traces"] > 0 and p["svg"] for p in plots)
    _check_3d(browser, plots, 3, "toolpath")  # the tip, the toolpath, CAD beside the part
    link = next(x for x in browser.eval("window.tipgeoReport.links")
                if x["kind"] == "toolpath")
    n = len(link["path"]["x"]) - 1
    for k in (n // 3, n):
        got = browser.eval(f"""(() => {{
            const s = document.getElementById('{link['slider']}');
            s.value = {k}; s.dispatchEvent(new Event('input'));
            const d = document.getElementById('{link['div']}');
            return [d._fullData[{link['marker']}].x[0], d._fullData[{link['done']}].x.length,
                    document.getElementById('{link['readout']}').textContent]; }})()""")
        assert got[0] == pytest.approx(link["path"]["x"][k], abs=1e-12)
        assert got[1] == k + 1 and got[2].startswith(f"move {k} of {n}")
    assert browser.eval("document.querySelectorAll('table.tg-table').length") >= 4


def test_compare_page(browser, pages):
    _open(browser, pages["compare"])
    plots = _plots(browser)
    assert all(p["traces"] > 0 and p["svg"] for p in plots)
    _check_3d(browser, plots, 1, "cloud")
    assert "PASS" in browser.eval("document.querySelector('.tg-verdict').textContent") or \
        "FAIL" in browser.eval("document.querySelector('.tg-verdict').textContent")
    link = next(x for x in browser.eval("window.tipgeoReport.links")
                if x["kind"] == "hist-pick")
    # a real click (mouse events through the DevTools protocol) on the tallest bar
    pos = browser.eval(f"""(() => {{
        const h = document.getElementById('{link['hist']}'); h.scrollIntoView();
        const b = h._fullData[0], L = h._fullLayout, r = h.getBoundingClientRect();
        let k = 0; for (let i = 0; i < b.y.length; i++) if (b.y[i] > b.y[k]) k = i;
        return {{k: k, cd: b.customdata[k],
                 x: r.left + L.xaxis._offset + L.xaxis.l2p(L.xaxis.d2l(b.x[k])),
                 y: r.top + L.yaxis._offset + L.yaxis.l2p(L.yaxis.d2l(b.y[k] / 2))}}; }})()""")
    browser.drain(0.5)
    for t in ("mouseMoved", "mousePressed", "mouseReleased"):
        browser.call("Input.dispatchMouseEvent", session=True, type=t, x=pos["x"], y=pos["y"],
                     button="none" if t == "mouseMoved" else "left", clickCount=1)
        browser.drain(0.3)
    lo, hi = pos["cd"][0], pos["cd"][1]
    got = browser.eval(f"""(() => {{
        const c = document.getElementById('{link['cloud']}');
        const d = c._fullData[{link['src']}].marker.color;
        let n = 0; for (let i = 0; i < d.length; i++) if (d[i] >= {lo} && d[i] < {hi}) n++;
        return [c._fullData[{link['sel']}].x.length, n,
                document.getElementById('{link['readout']}').textContent]; }})()""")
    assert got[0] == got[1] > 0, got
    assert json.dumps(got[2]).count("points of the scan") == 1
