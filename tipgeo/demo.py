"""``tipgeo demo``: build every thesis needle and write what a user looks at.

For each preset: the spec (TOML), the mesh (STL and labelled PLY), a picture
(PNG) and a row of the summary (``summary.json``, ``summary.csv``); then the
cutting angles of every preset (``angles.csv``, ``angles.json``) and plots of
the angle curves overlaid (``angles-*.png``, like thesis Figs. 3.5–3.10).
For the serrated punches: the AeroBasic laser programs (``punch-C*.pgm``),
and for C2 the simulated cut (``punch-C2-laser-sim.stl``) with its toolpath and
rim pictures. For the needles the grinder makes: the axis program, its G-code
and set-up sheet (``*.grind.json``, ``*.grind.nc``, ``*.setup.md``), each
simulated and compared with the CAD tip. Later features add their own outputs
here. Lengths in mm, angles
in degrees.
"""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

from ._atomic import write_text_atomic
from .build import build_tip
from .io import export_tip
from .jsonio import dumps as _dumps
from .presets import preset, preset_names
from .spec import save_spec

__all__ = ["run_demo"]


#: Groups of samples whose angle curves are overlaid in one picture.
ANGLE_GROUPS = {
    "angles-helical-vs-bevel": ["helical-14G", "bevel-14G-xi14.5"],
    "angles-bevels": ["bevel-14G-xi15", "bevel-14G-xi45", "bevel-14G-xi75"],
    "angles-multiplane": ["bevel-14G-xi15", "twoplane-14G-xi15", "threeplane-14G-xi15",
                          "lancet-14G"],
    "angles-conical-and-punch": ["conical-14G-theta15", "punch-plain", "punch-C2"],
}


def _angle_outputs(out: Path, names, pictures: bool, log) -> list[str]:
    """Angle tables (CSV) of every sample, and the overlaid angle plots."""
    from .angles import analyze

    reports = {n: analyze(preset(n), method="fourier") for n in names}
    text = ""
    for k, rep in enumerate(reports.values()):
        t = rep.to_csv(1.0)
        text += t if k == 0 else t.split("\n", 1)[1]
    write_text_atomic(out / "angles.csv", text)
    files = [str(out / "angles.csv")]
    summaries = {n: r.summary() for n, r in reports.items()}
    write_text_atomic(out / "angles.json", _dumps(summaries) + "\n")
    files.append(str(out / "angles.json"))
    if pictures:
        from .plot import plot_angles

        for fname, group in ANGLE_GROUPS.items():
            reps = [reports[n] for n in group if n in reports]
            if reps:
                files.append(str(plot_angles(reps, out / f"{fname}.png")))
    if log is not None:
        print(f"angles: {len(reports)} tips analysed, {len(files)} files", file=log, flush=True)
    return files


def _laser_outputs(out: Path, names, pictures: bool, log) -> list[dict]:
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
        write_text_atomic(out / f"{name}.pgm", text)
        sim = name == "punch-C2"
        res = laser_check(text, beam_diameter=laser.beam_diameter, spec=spec if sim else None)
        row = {"name": name, "program": str(out / f"{name}.pgm"), **res.toolpath.summary()}
        if sim:
            row["comparison"] = res.comparison
            write_laser_outputs(res, spec, mesh=out / f"{name}-laser-sim.stl",
                                plot=out / f"{name}-toolpath.png" if pictures else None,
                                rim=out / f"{name}-rim.png" if pictures else None)
        rows.append(row)
        if log is not None:
            print(f"laser: {name}: {row['segments']} moves, {row['time_s']:.0f} s, "
                  f"{row['pulses']} pulses", file=log, flush=True)
    return rows


def _grind_outputs(out: Path, names, log) -> list[dict]:
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
        write_grind_outputs(res, program=out / f"{name}.grind.json",
                            gcode=out / f"{name}.grind.nc", sheet=out / f"{name}.setup.md")
        worst = res.worst_angle_diff_deg()[0]
        haus = res.comparison["hausdorff_mm"]
        rows.append({"name": name, "ground": True, "time_s": res.program.summary()["time_s"],
                     "hausdorff_um": haus * 1e3, "angles_max_diff_deg": worst})
        if log is not None:
            print(f"grind: {name}: Hausdorff {haus * 1e3:.2e} µm, angles "
                  f"within {worst:.1e}°", file=log, flush=True)
    return rows


def _inspect_outputs(out: Path, pictures: bool, log) -> dict:
    """One scan-to-CAD comparison (:func:`tipgeo.inspect.demo.run_inspect_demo`)."""
    from .inspect.demo import run_inspect_demo

    row = run_inspect_demo(out / "inspect", points=100_000, log=log, pictures=pictures)
    if log is not None:
        print(f"inspect: bevel ground at 15.0°, measured ξ {row['xi_measured_deg']:.4f}°, "
              f"registration residual {row['registration_residual_deg']:.4f}°",
              file=log, flush=True)
    return row


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
    angle_files = _angle_outputs(out, names, pictures, log)
    laser_files = _laser_outputs(out, names, pictures, log)
    grind_rows = _grind_outputs(out, names, log)
    from .mechanics import demo_outputs as _mechanics_outputs

    mechanics_files = _mechanics_outputs(out, log=log, pictures=pictures)
    from .optimize import demo_outputs as _optimize_outputs

    optimize_files = _optimize_outputs(
        out, log=None if log is None else (lambda msg: print(msg, file=log, flush=True)))
    inspect_row = _inspect_outputs(out, pictures, log)
    summary = {"out": str(out), "tolerance_um": None if tolerance is None else tolerance * 1e3,
               "tips": rows, "angles": angle_files, "laser": laser_files,
               "grinding": grind_rows, "mechanics": mechanics_files,
               "optimize": optimize_files, "inspect": inspect_row}
    write_text_atomic(out / "summary.json", _dumps(summary) + "\n")
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out / "summary.csv", buf.getvalue())
    return summary
