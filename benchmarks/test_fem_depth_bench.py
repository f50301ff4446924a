"""How deep the uncut axisymmetric punch model goes on the default mesh
(issue 28 item 4: 3 mm at 25 µm with the default options).

Run: python -m pytest benchmarks/test_fem_depth_bench.py --benchmark-only -s

Minutes of ccx CPU (measured 2026-12-03: 3 mm reached in 67 increments, 63 s
of ccx CPU, 154 s wall on 2 shared cores). The default model has the
pre-distorted column under the front (``crush_aspect`` 3), the tissue's
nodes slave to the needle's faces (``slave="auto"`` at 25 µm) and the
friction's stick slope a tenth of the penalty; the model before issue 28
(``crush_aspect=1, slave="needle", stick_ratio=1``) stops at about 1.57 mm.
Depths in mm, forces in N (the whole needle).
"""

import numpy as np
import pytest

from tipgeo.fem import ccx_path
from tipgeo.fem.run import INSTALL_HINT

pytestmark = pytest.mark.skipif(ccx_path() is None, reason=INSTALL_HINT)

#: Forces of the default model before issue 28 where it ran (N).
BEFORE = {0.5: 0.03746, 1.0: 0.08704, 1.2: 0.11044}


def test_default_mesh_reaches_3_mm(benchmark, tmp_path):
    from tipgeo import preset
    from tipgeo.fem import build_model, run_model

    m = build_model(preset("punch-plain"), "axisymmetric", depth=3.0)  # 25 µm, defaults
    assert m.info["element_size_um"] == 25.0
    res = benchmark.pedantic(run_model, args=(m, tmp_path), kwargs={"pictures": False},
                             rounds=1, iterations=1)
    assert res.verdict.ok and res.reached_depth == pytest.approx(3.0, abs=1e-9)
    print(f"\nreached {res.reached_depth:g} mm; {res.run.increments} increments, "
          f"{res.run.cutbacks} cut back, ccx {res.run.cpu_s:.0f} s CPU")
    for d in (0.5, 1.0, 1.2, 1.5, 2.0, 3.0):
        f = float(np.interp(d, res.depth, res.force))
        was = BEFORE.get(d)
        print(f"  {d:g} mm: {f:.5f} N" + (f" ({100 * (f / was - 1):+.2f} % from {was} N "
                                           "before issue 28)" if was else ""))
        if was:  # within the mesh-convergence band (25 → 12.5 µm: −1.2 % at 0.5 mm)
            assert f == pytest.approx(was, rel=0.02)
