"""The HTML report (issue 29) of a compare run on a 1,000,000-point synthetic
scan of the 14G bevel (σ = 1 µm, a 30 µm burr along the outer edge) —
pytest-benchmark.

Run: python -m pytest benchmarks/test_report_bench.py --benchmark-only

Targets (issue 29, 2 cores): ``tipgeo report <compare folder>`` under 10 s
and the page under 15 MB (recorded in extra_info: bytes, displayed points);
the 3D cloud is decimated for display only (tipgeo.report.sections.
display_sample), the histogram and tables count every point.

Also: the report of a helical-14G milling run (default parameters, the
simulated part, compared with CAD) — its size and time.
"""

import pytest

from tipgeo import preset
from tipgeo.inspect import Burr, compare, synthetic_scan
from tipgeo.report import html_report
from tipgeo.report.sections import DISPLAY_POINTS

N = 1_000_000


@pytest.fixture(scope="module")
def compare_folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("rep")
    s = synthetic_scan(preset("bevel-14G-xi15"), points=N, noise=0.001,
                       burr=Burr(height=0.03, width=0.06), seed=3)
    s.write(d / "scan-1M.ply")
    compare(d / "scan-1M.ply", preset("bevel-14G-xi15"), out=d / "cmp", pictures=False)
    return d / "cmp"


def test_report_of_a_1M_point_compare(benchmark, compare_folder, tmp_path):
    out = tmp_path / "c.html"
    info = benchmark.pedantic(html_report, args=([compare_folder], out), rounds=2,
                              iterations=1)
    assert info["bytes"] < 15e6
    benchmark.extra_info.update({"bytes": info["bytes"], "points": N,
                                 "displayed_points": DISPLAY_POINTS})


def test_report_of_a_helical_mill_run(benchmark, tmp_path):
    from cam.mill import mill

    spec = preset("helical-14G")
    res = mill(spec, simulate_tip=True, compare=True)
    out = tmp_path / "m.html"
    info = benchmark.pedantic(html_report, args=([spec, res], out), rounds=2, iterations=1)
    benchmark.extra_info.update({"bytes": info["bytes"]})
