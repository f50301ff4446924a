"""Build time of every admitted point of the helical study's box (pytest-benchmark).

Run: python -m pytest benchmarks/test_helical_box_bench.py --benchmark-only -s

The 1° grid over ψ 5–25°, φ 5–20° (21 × 16 = 336 points) of
``samples/helical-study.toml``: each point is validated (refused points name
their geometric reason) and every admitted one is built at the default
tolerance; the CPU seconds (``time.process_time``, all threads) of each
build are recorded. Issue 13 asks for every admitted point to build
watertight in under 2 s; the worst point, its time and the buildable fraction
are printed and stored in ``extra_info`` (timings are never asserted: the
machine may be shared).
"""

import time

import numpy as np

from tipgeo.build import build_tip
from tipgeo.errors import SpecError
from tipgeo.optimize import study_preset
from tipgeo.tolerances import tol


def _scan():
    cfg = study_preset("helical-study")
    build_tip(cfg.spec([10.0, 13.5]))  # imports and first-call costs out of the way
    rows = []
    for psi in np.arange(5.0, 25.5, 1.0):
        for phi in np.arange(5.0, 20.5, 1.0):
            t0 = time.process_time()
            try:
                spec = cfg.spec([psi, phi])
            except SpecError as e:
                rows.append({"psi": psi, "phi": phi, "ok": False, "reason": str(e)})
                continue
            t1 = time.process_time()
            tip = build_tip(spec)
            t2 = time.process_time()
            rows.append({"psi": psi, "phi": phi, "ok": True, "validate_s": t1 - t0,
                         "build_s": t2 - t1, "watertight": bool(tip.is_watertight),
                         "triangles": int(len(tip.faces))})
    return rows


def test_helical_box_builds(benchmark):
    tol.strict = False
    rows = benchmark.pedantic(_scan, rounds=1, iterations=1)
    ok = [r for r in rows if r["ok"]]
    assert len(rows) == 21 * 16
    assert all(r["watertight"] for r in ok)
    worst = max(ok, key=lambda r: r["build_s"])
    worst_total = max(ok, key=lambda r: r["build_s"] + r["validate_s"])
    reasons = {}
    for r in rows:
        if not r["ok"]:
            key = ("folds over" if "folds over" in r["reason"] else
                   "too steep" if "meets the tube wall" in r["reason"] else
                   "grid cap" if "would need a grid" in r["reason"] else "other")
            reasons[key] = reasons.get(key, 0) + 1
    info = {"points": len(rows), "buildable": len(ok), "fraction": len(ok) / len(rows),
            "worst_build_s": worst["build_s"], "worst_at": [worst["psi"], worst["phi"]],
            "worst_validate_plus_build_s": worst_total["build_s"] + worst_total["validate_s"],
            "median_build_s": float(np.median([r["build_s"] for r in ok])),
            "refused": reasons}
    benchmark.extra_info.update(info)
    print(f"\nhelical box: {len(ok)}/{len(rows)} buildable ({len(ok) / len(rows):.1%}); "
          f"worst build {worst['build_s']:.3f} s CPU at ψ {worst['psi']:g}°, "
          f"φ {worst['phi']:g}° ({worst['triangles']} triangles); worst validate + build "
          f"{info['worst_validate_plus_build_s']:.3f} s; median build "
          f"{info['median_build_s']:.3f} s; refused: {reasons}")
