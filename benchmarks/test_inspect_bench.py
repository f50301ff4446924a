"""Scan-to-CAD inspection on a 1,000,000-point synthetic scan of the 14G
bevel tip (ξ = 14.5°, σ = 1 µm, misaligned 25° / 2° / 0.5 mm, 3 µm edge
rounding, a burr) — pytest-benchmark.

Run: python -m pytest benchmarks/test_inspect_bench.py --benchmark-only

Targets (issue 6, 2 cores): load + register + deviations + report < 10 s;
deviations alone < 2 s.
"""

import pytest

from tipgeo import build_tip, preset
from tipgeo.inspect import Burr, Misalignment, compare, load_cad, register, synthetic_scan
from tipgeo.inspect.meshdist import MeshSolid
from tipgeo.inspect.register import apply
from tipgeo.tolerances import tol

SPEC = "bevel-14G-xi14.5"
N = 1_000_000


@pytest.fixture(scope="module")
def scan_file(tmp_path_factory):
    tol.strict = False
    s = synthetic_scan(preset(SPEC), points=N, noise=0.001, edge_radius=0.003, burr=Burr(),
                       misalignment=Misalignment(25.0, 2.0, 40.0, (0.4, -0.2, 0.3)), seed=2)
    path = tmp_path_factory.mktemp("scan") / "scan-1M.ply"
    s.write(path)
    return path, s


def test_compare_1M_load_register_deviations_report(benchmark, scan_file, tmp_path):
    """The whole of ``tipgeo compare scan.ply spec --out DIR``: read, register,
    deviations on the exact surfaces, statistics, measured geometry, JSON,
    coloured PLY, two PNGs, Markdown."""
    path, _ = scan_file
    res = benchmark.pedantic(compare, args=(path, preset(SPEC)),
                             kwargs={"out": tmp_path / "report"}, rounds=2, iterations=1)
    assert len(res.points) == N
    assert res.registration.fitness > 0.99
    benchmark.extra_info.update({k: round(v, 3) for k, v in res.timings.items()})


def _registered(s):
    """The noisy scan moved into the cannula frame by the true transform."""
    return apply(s.scan_to_cad, s.points)


def test_deviations_1M_exact_surfaces(benchmark, scan_file):
    """Signed distances of the registered scan to the spec's exact surfaces."""
    _, s = scan_file
    cad = load_cad(preset(SPEC))
    d = benchmark(cad.distances, _registered(s))
    assert len(d.distance) == N


def test_register_1M(benchmark, scan_file):
    _, s = scan_file
    cad = load_cad(preset(SPEC))
    reg = benchmark.pedantic(register, args=(s.points, cad), rounds=3, iterations=1)
    assert reg.fitness > 0.99


def test_deviations_1M_mesh_path(benchmark, scan_file):
    """The mesh path (a CAD mesh instead of a spec, 0.05 µm tessellation):
    exact double-precision closest points from certified candidates. Its
    one-off index build (about 1 s) is left out of the figure."""
    _, s = scan_file
    mesh = MeshSolid(build_tip(preset(SPEC)))
    mesh._build()
    pts = _registered(s)
    d = benchmark.pedantic(mesh.distances, args=(pts,), rounds=2, iterations=1)
    assert len(d.distance) == N
