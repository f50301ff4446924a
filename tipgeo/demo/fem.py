"""The finite-element part of ``tipgeo demo``: the thesis's 2D axisymmetric
insertion (§4.4.1.2) of the Fig. 4.7 punch into the S/P = 0 tissue, 1 mm at
a coarse 50 µm mesh, run with CalculiX (depths in mm, forces in N)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..progress import LineSink

__all__ = ["fem_outputs", "DEMO_TIP"]

#: The preset the demo pushes into tissue.
DEMO_TIP = "punch-plain"


def fem_outputs(out_dir: Path, names: list[str], log: LineSink | None = None) -> dict[str, Any]:
    """Run the demo insertion into ``out_dir/fem`` when ``DEMO_TIP`` is among
    ``names`` and ccx is installed; returns a summary row (or why it was
    skipped)."""
    from ..fem import INSTALL_HINT, ccx_path, run_fem
    from ..presets import preset

    if DEMO_TIP not in names:
        return {"skipped": f"{DEMO_TIP} not among the demo's tips"}
    if ccx_path() is None:
        if log is not None:
            print(f"fem: skipped — {INSTALL_HINT}", file=log, flush=True)
        return {"skipped": INSTALL_HINT}
    res = run_fem(preset(DEMO_TIP), model="axisymmetric", depth=1.0, mesh=0.05,
                  out_dir=Path(out_dir) / "fem", output_depths=(0.5, 1.0))
    run = res.run
    if run is None:  # pragma: no cover - ccx_path() was found above
        raise RuntimeError("fem: CalculiX did not run")
    if log is not None:
        print(f"fem: {DEMO_TIP} 1 mm into pvc-sp0, reached {res.reached_depth:.3g} mm, "
              f"{run.increments} increments, {run.cpu_s:.1f} s CPU, peak force "
              f"{res.peak_force:.4f} N (one coarse mesh: its discretisation error is not "
              "estimated; `tipgeo fem` gives it)", file=log, flush=True)
    return {"tip": DEMO_TIP, "depth_mm": 1.0, "reached_depth_mm": res.reached_depth,
            "element_size_um": 50.0, "mesh_error_percent": None,
            "increments": run.increments, "peak_force_N": res.peak_force,
            "monotonic": res.monotonic, "cpu_s": round(run.cpu_s, 2),
            "files": [str(p) for p in res.files]}
