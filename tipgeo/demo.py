"""``tipgeo demo``: build every thesis needle and write what a user looks at.

For each preset: the spec (TOML), the mesh (STL and labelled PLY), a picture
(PNG) and a row of the summary (``summary.json``, ``summary.csv``). Later
features add their own outputs here. Lengths in mm.
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
import time
from pathlib import Path

from .build import build_tip
from .io import export_tip
from .presets import preset, preset_names
from .spec import save_spec

__all__ = ["run_demo"]


def _atomic_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


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
            from .plot import render_tip

            render_tip(tip, out / f"{name}.png", title=f"{name}\n{spec.description}")
        s = tip.summary()
        rows.append({"name": name, "triangles": s["triangles"], "volume_mm3": s["volume_mm3"],
                     "z_max_mm": s["z_max_mm"], "build_seconds": dt,
                     "watertight": s["watertight"], "genus": s["genus"],
                     "labels": " ".join(s["labels"])})
        if log is not None:
            print(f"[{k}/{len(names)}] {name}: {s['triangles']} triangles, {dt:.3f} s",
                  file=log, flush=True)
    summary = {"out": str(out), "tolerance_um": None if tolerance is None else tolerance * 1e3,
               "tips": rows}
    _atomic_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    _atomic_text(out / "summary.csv", buf.getvalue())
    return summary
