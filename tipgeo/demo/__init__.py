"""``tipgeo demo``: build every thesis needle and write what a user looks at.

For each preset: the spec (TOML), the mesh (STL and labelled PLY), a picture
(PNG) and a row of the summary (``summary.json``, ``summary.csv``); then the
cutting angles of every preset (``angles.csv``, ``angles.json``) and plots of
the angle curves overlaid (``angles-*.png``, like thesis Figs. 3.5–3.10).
For the serrated punches: the AeroBasic laser programs (``punch-C*.pgm``),
and for C2 the simulated cut (``punch-C2-laser-sim.stl``) with its toolpath and
rim pictures. For the needles the grinder makes: the axis program, its G-code
and set-up sheet (``*.grind.json``, ``*.grind.nc``, ``*.setup.md``), each
simulated and compared with the CAD tip. The helical needle milled on the
Haas VF-2 (``helical-14G.mill.nc``, ``.mill.md``, ``-milled.stl``, the
deviation map ``-milled-deviation.png`` and the toolpaths
``-milled-toolpath.png``). With CalculiX installed, the 2D
axisymmetric insertion of the Fig. 4.7 punch, 1 mm into S/P = 0 tissue
(``fem/``). Later features add their own outputs here. Lengths in mm, angles
in degrees.
"""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

from ..atomic import write_text_atomic
from ..build import build_tip
from ..io import export_tip
from ..jsonio import dumps as _dumps
from ..presets import preset, preset_names
from ..spec import save_spec
from .angles import ANGLE_GROUPS

__all__ = ["run_demo", "ANGLE_GROUPS"]


def run_demo(out, *, tolerance: float | None = None, log=None, pictures: bool = True,
             names: list[str] | None = None) -> dict:
    """Build the presets ``names`` (default: all) into folder ``out``.

    Returns the summary dictionary (also written as summary.json/csv).
    Progress lines go to ``log`` (a text stream) if given.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = names or preset_names()
    rows = []
    for k, name in enumerate(names, 1):
        spec = preset(name)
        t0 = time.perf_counter()
        tip = build_tip(spec, tolerance=tolerance)
        dt = time.perf_counter() - t0
        save_spec(spec, out / f"{name}.toml")
        export_tip(tip, out / f"{name}.stl")
        export_tip(tip, out / f"{name}.ply")
        if pictures:
            from ..plot import render_tip

            render_tip(tip, out / f"{name}.png", title=f"{name}\n{spec.description}")
        s = tip.summary()
        rows.append({"name": name, "triangles": s["triangles"], "volume_mm3": s["volume_mm3"],
                     "z_max_mm": s["z_max_mm"], "build_seconds": dt,
                     "watertight": s["watertight"], "genus": s["genus"],
                     "labels": " ".join(s["labels"])})
        if log is not None:
            print(f"[{k}/{len(names)}] {name}: {s['triangles']} triangles, {dt:.3f} s",
                  file=log, flush=True)
    from . import mechanics, optimize
    from .angles import angle_outputs
    from .inspect import inspect_outputs
    from .make import grind_outputs, laser_outputs, mill_outputs

    angle_files = angle_outputs(out, names, pictures, log)
    laser_files = laser_outputs(out, names, pictures, log)
    grind_rows = grind_outputs(out, names, log)
    mill_rows = mill_outputs(out, names, pictures, log)
    mechanics_files = mechanics.demo_outputs(out, log=log, pictures=pictures)
    # the §3.4 study varies the helical needle: it runs when that needle does
    optimize_files = optimize.demo_outputs(
        out, log=None if log is None else (lambda msg: print(msg, file=log, flush=True))
    ) if "helical-14G" in names else []
    inspect_row = inspect_outputs(out, pictures, log)
    from .fem import fem_outputs

    fem_row = fem_outputs(out, names, log)
    summary = {"out": str(out), "tolerance_um": None if tolerance is None else tolerance * 1e3,
               "tips": rows, "angles": angle_files, "laser": laser_files,
               "grinding": grind_rows, "milling": mill_rows, "mechanics": mechanics_files,
               "optimize": optimize_files, "inspect": inspect_row, "fem": fem_row}
    write_text_atomic(out / "summary.json", _dumps(summary) + "\n")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out / "summary.csv", buf.getvalue())
    return summary
