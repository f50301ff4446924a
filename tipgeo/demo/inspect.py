"""The inspection part of ``tipgeo demo``: one synthetic scan, one comparison.

A 14G bevel (ξ = 14.5° in the CAD) ground at 15.0°, edges rounded to 3 µm, a
burr on the inner edge near the tip, scanned with σ = 1 µm noise and
misaligned by 25° about the axis, 2° tilt and 0.4 mm; then ``compare``
recovers the pose, maps the deviations and measures ξ ≈ 15°.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..progress import LineSink

__all__ = ["run_inspect_demo", "inspect_outputs"]


def run_inspect_demo(out: str | Path, *, points: int = 200_000, log: LineSink | None = None,
                     pictures: bool = True) -> dict[str, Any]:
    """Write ``scan.ply`` (scanner frame), ``truth.json`` and the comparison
    report (``report.*``, ``deviations.ply``, PNGs) into ``out``; return a
    summary (measured ξ, registration error, deviation statistics)."""
    import math

    import numpy as np

    from ..atomic import write_text_atomic as _atomic_text
    from ..inspect.compare import compare
    from ..inspect.synth import Burr, Misalignment, synthetic_scan
    from ..jsonio import dumps as _dumps
    from ..presets import preset

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    spec = preset("bevel-14G-xi14.5")
    s = synthetic_scan(spec, points=points, noise=0.001, xi_deg=15.0, edge_radius=0.003,
                       burr=Burr(gamma_deg=(165.0, 195.0), height=0.015, width=0.01),
                       misalignment=Misalignment(25.0, 2.0, 40.0, (0.3, -0.2, 0.25)), seed=1)
    s.write(out / "scan.ply")
    _atomic_text(out / "truth.json", _dumps(s.info) + "\n")
    say = (lambda m: print(f"  inspect: {m}", file=log)) if log else None
    res = compare(out / "scan.ply", spec, tolerance=0.01, out=out, pictures=pictures,
                  progress=say)
    if res.registration is None:  # pragma: no cover - compare() registers a scan
        raise RuntimeError("inspect: the demo scan was not registered")
    D = res.registration.transform @ s.cad_to_scan
    face = res.measured["faces"].get("cut:bevel", {})
    return {"scan": str(out / "scan.ply"), "points": len(res.points),
            "xi_measured_deg": face.get("xi_deg"), "xi_actual_deg": 15.0,
            "xi_cad_deg": 14.5,
            "registration_residual_deg": math.degrees(
                math.acos(min(1.0, (np.trace(D[:3, :3]) - 1) / 2))),
            "deviation": res.stats["all"], "outputs": [str(p) for p in res.outputs],
            "timings_s": res.timings}


def inspect_outputs(out: Path, pictures: bool, log: LineSink | None) -> dict[str, Any]:
    """The demo's comparison, in ``out/inspect/``, with a progress line."""
    row = run_inspect_demo(out / "inspect", points=100_000, log=log, pictures=pictures)
    if log is not None:
        print(f"inspect: bevel ground at 15.0°, measured ξ {row['xi_measured_deg']:.4f}°, "
              f"registration residual {row['registration_residual_deg']:.4f}°",
              file=log, flush=True)
    return row
