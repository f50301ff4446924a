"""The making part of ``tipgeo demo``: laser programs of the serrated
punches (one simulated back into a tip) and grinding programs of the needles
the grinder makes (each simulated and compared with its CAD tip), through the
public pipelines :func:`gcode.laser_check` and :func:`cam.grind`; and the
helical needle milled on the Haas VF-2 (:func:`cam.mill.mill`), its G-code
simulated back into a tip and compared with CAD (deviation map)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..paths import inside
from ..presets import preset
from ..progress import LineSink

__all__ = ["laser_outputs", "grind_outputs", "mill_outputs"]


def laser_outputs(out: Path, names: list[str], pictures: bool,
                  log: LineSink | None) -> list[dict[str, Any]]:
    """The laser programs of the serrated punches (C1–C5), each checked by
    the interpreter; the C2 program simulated back into a tip and compared
    with its spec (toolpath and rim pictures)."""
    from gcode.emitter import LaserParams, emit_program
    from gcode.pipeline import laser_check, write_laser_outputs

    laser = LaserParams()
    rows = []
    for name in names:
        spec = preset(name)
        if not any(c.process == "laser" for c in spec.cutters):
            continue
        text = emit_program(spec, laser)
        write_text_atomic(inside(out, name, ".pgm"), text)
        sim = name == "punch-C2"
        res = laser_check(text, beam_diameter=laser.beam_diameter, spec=spec if sim else None)
        row = {"name": name, "program": str(inside(out, name, ".pgm")),
               **res.toolpath.summary()}
        if sim:
            row["comparison"] = res.comparison
            write_laser_outputs(
                res, spec, mesh=inside(out, name, "-laser-sim.stl"),
                plot=inside(out, name, "-toolpath.png") if pictures else None,
                rim=inside(out, name, "-rim.png") if pictures else None)
        rows.append(row)
        if log is not None:
            print(f"laser: {name}: {row['segments']} moves, {row['time_s']:.0f} s, "
                  f"{row['pulses']} pulses", file=log, flush=True)
    return rows


def grind_outputs(out: Path, names: list[str], log: LineSink | None) -> list[dict[str, Any]]:
    """Grinding programs (JSON, G-code, set-up sheet) of the thesis needles the
    grinder makes, each simulated and compared with its CAD tip."""
    from cam import CamError, grind, write_grind_outputs

    rows = []
    for name in names:
        spec = preset(name)
        try:
            res = grind(spec)
        except CamError as e:  # e.g. punches (flat land), helical tips: not this machine
            rows.append({"name": name, "ground": False, "reason": str(e)})
            continue
        write_grind_outputs(res, program=inside(out, name, ".grind.json"),
                            gcode=inside(out, name, ".grind.nc"),
                            sheet=inside(out, name, ".setup.md"))
        diff, comparison = res.worst_angle_diff_deg(), res.comparison
        if diff is None or comparison is None:  # pragma: no cover - grind() compares
            raise RuntimeError(f"grind: {name} was not compared with its CAD tip")
        worst = diff[0]
        haus = comparison["hausdorff_mm"]
        rows.append({"name": name, "ground": True, "time_s": res.program.summary()["time_s"],
                     "hausdorff_um": haus * 1e3, "angles_max_diff_deg": worst})
        if log is not None:
            print(f"grind: {name}: Hausdorff {haus * 1e3:.2e} µm, angles "
                  f"within {worst:.1e}°", file=log, flush=True)
    return rows




def mill_outputs(out: Path, names: list[str], pictures: bool,
                 log: LineSink | None) -> list[dict[str, Any]]:
    """The helical needle (thesis §3.2) milled tip-up at the default 2 µm
    scallop: G-code, set-up sheet, the milled tip simulated from the G-code,
    its deviation map and comparison with CAD."""
    from cam.mill import mill, write_mill_outputs

    rows = []
    for name in names:
        if name != "helical-14G":
            continue
        progress = None if log is None else (lambda m: print(f"mill: {m}", file=log, flush=True))
        res = mill(preset(name), progress=progress)
        write_mill_outputs(
            res, program=inside(out, name, ".mill.nc"), sheet=inside(out, name, ".mill.md"),
            mesh=inside(out, name, "-milled.stl"),
            deviation=inside(out, name, "-milled-deviation.png") if pictures else None,
            toolpath=inside(out, name, "-milled-toolpath.png") if pictures else None)
        s = res.summary()
        c = res.comparison
        if c is None:  # pragma: no cover - mill() compares
            raise RuntimeError(f"mill: {name} was not compared with its CAD tip")
        rows.append({"name": name, "cycle_time_s": s["program"]["cycle_time_s"],
                     "scallop_um": c["scallop_measured_um"], "gouge_um": c["gouge_um"],
                     "angles": c["angles"]["outer"], "files": list(res.files)})
        if log is not None:
            print(f"mill: {name}: scallop {c['scallop_measured_um']:.2f} µm, gouge "
                  f"{c['gouge_um']:.2f} µm, cycle {s['program']['cycle_time_s'] / 60:.1f} min",
                  file=log, flush=True)
    return rows
