"""The ``tipgeo`` command line: thin wrappers around library calls.

Lengths in mm, angles in degrees, tolerances in µm at this boundary. Plain,
scriptable output on stdout; progress and errors on stderr; ``--json`` where
a machine reads it. Exit status 0 on success, 2 on bad input, 1 on a failed
build or write.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from .jsonio import dumps as _dumps

__all__ = ["main", "declare_files", "check_files", "PICTURE_EXTS"]

from .plot import PICTURE_EXTS  # the formats every --plot/--png accepts


def declare_files(parser, *, inputs=(), outputs=(), pictures=(), exts=None, derived=None,
                  blas_threads: int | None = 1) -> None:
    """Declare a sub-command's file arguments (by ``dest``) for :func:`check_files`.

    ``inputs`` are read, ``outputs`` written (``pictures`` too, limited to
    :data:`PICTURE_EXTS`); ``exts`` maps an output's dest to its allowed
    extensions; ``derived(args)`` lists files a command writes beside the
    named ones. ``blas_threads`` pins BLAS for the command (None: unchanged).
    """
    parser.set_defaults(_inputs=tuple(inputs), _outputs=tuple(outputs) + tuple(pictures),
                        _exts={**{p: PICTURE_EXTS for p in pictures}, **(exts or {})},
                        _derived=derived, _blas_threads=blas_threads)


def _values(args, dest) -> list[str]:
    v = getattr(args, dest, None)
    if v is None:
        return []
    return [str(x) for x in (v if isinstance(v, (list, tuple)) else [v]) if str(x) != "-"]


def _same(a: Path, b: Path) -> bool:
    import os

    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_files(args) -> None:
    """Refuse, before any work, outputs with a wrong extension, an output named
    twice, and an output that is one of the command's own inputs."""
    from .errors import SpecError

    outs: list[tuple[str, Path]] = []
    for dest in getattr(args, "_outputs", ()):
        allowed = getattr(args, "_exts", {}).get(dest)
        opt = "--" + dest.replace("_", "-")
        for v in _values(args, dest):
            p = Path(v)
            if allowed and p.suffix.lower() not in allowed:
                raise SpecError(f"{opt} = '{v}' has extension '{p.suffix or '(none)'}'; "
                                f"allowed: {', '.join(allowed)}")
            if p.is_dir():
                raise SpecError(f"{opt} = '{v}' is a directory; expected a file path")
            outs.append((opt, p))
    derived = getattr(args, "_derived", None)
    if derived is not None:
        outs += [("(derived)", Path(x)) for x in derived(args)]
    for i, (opt, p) in enumerate(outs):
        for opt2, q in outs[:i]:
            if _same(p, q):
                raise SpecError(f"{opt} = '{p}' is also given as {opt2} = '{q}'; allowed each "
                                "output file once")
    for dest in getattr(args, "_inputs", ()):
        for v in _values(args, dest):
            src = Path(v)
            if not src.is_file():
                continue  # a preset name, or missing (the command reports it)
            for opt, p in outs:
                if _same(src, p):
                    raise SpecError(f"{opt} = '{p}' is the command's input {dest.upper()}; "
                                    "allowed an output that is not one of its inputs "
                                    "(nothing was written)")


def _spec(arg: str):
    from .presets import resolve_spec

    return resolve_spec(arg)


def _tolerance(args) -> float | None:
    from .errors import SpecError

    if args.tolerance_um is None:
        return None
    if not 0 < args.tolerance_um <= 100:
        raise SpecError(f"--tolerance-um = {args.tolerance_um:g} is out of range; allowed "
                        "0 < value ≤ 100")
    return args.tolerance_um * 1e-3


def cmd_build(args) -> int:
    from .build import build_tip
    from .io import export_tip

    spec = _spec(args.spec)
    t0 = time.perf_counter()
    tip = build_tip(spec, tolerance=_tolerance(args))
    dt = time.perf_counter() - t0
    outs = [export_tip(tip, o) for o in args.output]
    if args.png:
        from .plot import render_tip

        outs.append(render_tip(tip, args.png))
    info = tip.summary() | {"build_seconds": dt, "outputs": [str(o) for o in outs]}
    if args.json:
        print(_dumps(info))
    else:
        print(f"{spec.name or args.spec}: {info['triangles']} triangles, volume "
              f"{info['volume_mm3']:.6f} mm³, tolerance {info['tolerance_um']:g} µm, "
              f"built in {dt:.3f} s")
        for label, n in info["labels"].items():
            print(f"  {label:<24} {n:>8} triangles")
        for o in outs:
            print(f"  wrote {o}")
    return 0


def _angle_source(arg: str, args):
    """A spec/preset, or a mesh file labelled by geometry (needs diameters)."""
    from .edges import label_by_geometry
    from .errors import SpecError
    from .io import SUPPORTED_IMPORTS, load_tip

    if Path(arg).suffix.lower() in SUPPORTED_IMPORTS:
        if args.diameters_mm is None:
            raise SpecError(f"'{arg}' is a mesh: give --diameters-mm DE DI (its outer and inner "
                            "diameters; axis along +z through the origin unless --axis)")
        de, di = args.diameters_mm
        if not 0 < di < de:
            raise SpecError(f"--diameters-mm = {de:g} {di:g}; allowed 0 < DI < DE")
        ax = args.axis or [0, 0, 0, 0, 0, 1]
        tip = label_by_geometry(load_tip(arg), r_o=de / 2, r_i=di / 2, axis_point=ax[:3],
                                axis_dir=ax[3:])
        return tip, (de / 2, di / 2), Path(arg).stem
    spec = _spec(arg)
    return spec, None, spec.name or Path(arg).stem


def cmd_angles(args) -> int:
    from .angles import analyze

    reports = []
    for k, arg in enumerate(args.spec, 1):
        src, radii, name = _angle_source(arg, args)
        method = args.method or ("mesh" if radii is not None else "fourier")
        rep = analyze(src, method=method, n_harmonics=args.harmonics, radii=radii, name=name)
        reports.append(rep)
        if len(args.spec) > 1:
            print(f"[{k}/{len(args.spec)}] {name}", file=sys.stderr, flush=True)
    if args.csv:
        from ._atomic import write_text_atomic

        text = reports[0].to_csv(args.step_deg)
        for r in reports[1:]:
            text += r.to_csv(args.step_deg).split("\n", 1)[1]
        write_text_atomic(Path(args.csv), text)
    if args.plot:
        from .plot import plot_angles

        plot_angles(reports, args.plot)
    if args.json:
        data = [json.loads(r.to_json(args.step_deg)) for r in reports]
        print(_dumps(data if len(data) > 1 else data[0]))
        return 0
    for r in reports:
        s = r.summary()
        print(f"{r.name} (method {r.method}, {r.n_harmonics} harmonics)")
        for wall, key in (("outer", "o"), ("inner", "i")):
            w = s[wall]
            th = w["theta_deg"] if key == "o" else w["theta_i_deg"]
            print(f"  {wall:<5} l_c {w['l_c_mm']:9.5f} mm  top z {w['z_max_mm']:8.5f} mm at "
                  f"γ {w['gamma_of_z_max_deg']:7.2f}°  λ {w[f'lambda_{key}_deg'][0]:6.2f}…"
                  f"{w[f'lambda_{key}_deg'][1]:6.2f}°  θ {th[0]:6.2f}…{th[1]:6.2f}°  "
                  f"α {w[f'alpha_{key}_deg'][0]:6.2f}…{w[f'alpha_{key}_deg'][1]:6.2f}°")
            for p in w["pieces"]:
                if "fit" in p:
                    f = p["fit"]
                    print(f"        fit {p['face']:<22} R² {f['r2']:.9f}  RMSE "
                          f"{f['rmse_mm'] * 1e3:8.4f} µm  w {f['w']:.6f}")
            for kk in w["kinks"]:
                print(f"        kink at γ {kk['gamma_deg']:7.2f}°: θ {kk['theta_deg']:.4f}° "
                      f"({kk['faces'][0]} | {kk['faces'][1]})")
            if w["jumps"]:
                print(f"        {len(w['jumps'])} vertical stretches")
    for o in (args.csv, args.plot):
        if o:
            print(f"wrote {o}")
    return 0


def _laser_params(args):
    from gcode.emitter import LaserParams

    kw = {}
    for opt, key, scale in (("beam_diameter_um", "beam_diameter", 1e-3),
                            ("overlap", "overlap", 1.0),
                            ("roughing_depth_um", "roughing_depth", 1e-3),
                            ("finishing_passes", "finishing_passes", None),
                            ("feed_mm_s", "feed", 1.0),
                            ("pulse_period_us", "pulse_period_us", 1.0),
                            ("pulse_on_us", "pulse_on_us", 1.0),
                            ("compensation_mm", "compensation", 1.0)):
        val = getattr(args, opt, None)
        if val is not None:
            kw[key] = val if scale is None else val * scale
    return LaserParams(**kw)


def _write_text(path, text: str) -> None:
    from ._atomic import write_text_atomic

    write_text_atomic(Path(path), text)


def cmd_laser(args) -> int:
    from gcode.emitter import emit_program

    spec = _spec(args.spec)
    text = emit_program(spec, _laser_params(args))
    if args.output == "-":
        sys.stdout.write(text)
    else:
        _write_text(args.output, text)
        print(f"wrote {args.output} ({len(text.splitlines())} lines)")
    return 0


def cmd_gcode(args) -> int:
    from gcode.pipeline import laser_check, make_limits, read_program, write_laser_outputs

    beam = (args.beam_diameter_um or 20.0) * 1e-3
    spec = _spec(args.spec) if args.action == "sim" else None
    limits = make_limits(max_statements=args.max_statements, max_repeat=args.max_repeat,
                         max_segments=args.max_moves, max_operations=args.max_operations)
    res = laser_check(read_program(args.program), beam_diameter=beam, spec=spec,
                      origin=tuple(args.origin), tolerance=_tolerance(args),
                      lenient=args.lenient, limits=limits, max_tokens=args.max_tokens)
    write_laser_outputs(res, spec, mesh=args.mesh if args.action == "sim" else None,
                        plot=args.plot)
    out = res.summary(source=args.program)
    prog, tp, s = res.program, res.toolpath, out["toolpath"]
    if args.json:
        print(_dumps(out))
        return 0
    print(f"{args.program}: {len(prog.body)} statements, {s['segments']} moves")
    print(f"  path {s['path_length_mm']:.4f} mm, beam on {s['beam_on_length_mm']:.4f} mm, "
          f"time {s['time_s']:.2f} s (beam on {s['beam_on_time_s']:.2f} s), "
          f"pulses {s['pulses'] if s['pulses'] is not None else 'n/a'}")
    print(f"  C positions firing: {len(s['c_angles_with_beam_deg'])} "
          f"{[round(c, 4) for c in s['c_angles_with_beam_deg']][:24]}")
    for w in tp.warnings[:10]:
        print(f"  warning: {w}")
    if len(tp.warnings) > 10:
        print(f"  … {len(tp.warnings) - 10} more warnings")
    if "ablation" in out:
        a = out["ablation"]
        print(f"  ablation: {a['notches']} notches, {a['slugs_removed']} slugs fell out, "
              f"watertight {a['watertight']}")
    if "comparison" in out:
        c = out["comparison"]
        print(f"  vs spec: radius {c['radius_mm']['fitted_mean'] * 1e3:.3f} µm fitted "
              f"(spec {c['radius_mm']['spec'] * 1e3:.3f}, max error "
              f"{c['radius_mm']['fitted_max_error'] * 1e3:.3f} µm), spacing max error "
              f"{c['spacing_deg']['fitted_max_error']}°, Hausdorff "
              f"{c['hausdorff_mm'] * 1e3:.3f} µm")
    for o in res.files:
        print(f"  wrote {o}")
    return 0


def cmd_grind(args) -> int:
    from cam import Machine, grind, write_grind_outputs

    spec = _spec(args.spec)
    machine = Machine.from_toml(args.machine) if args.machine else Machine()
    res = grind(spec, machine=machine, feed=args.feed, needle_rpm=args.needle_rpm,
                simulate_tip=bool(args.simulate or args.report), compare=args.report,
                tolerance=_tolerance(args))
    write_grind_outputs(res, program=args.output, gcode=args.gcode, sheet=args.sheet,
                        mesh=args.simulate)
    out = res.summary()
    if args.json:
        print(_dumps(out))
        return 0
    s = out["program"]
    print(f"{s['name']}: faces {s['faces']}, {s['rows']} program rows, time {s['time_s']:.1f} s, "
          f"feed {s['feed_mm_s']:g} mm/s")
    for f in s["setup"]:
        print(f"  {f['face']:<22} ξ {f['xi_deg']:8.4f}°  r5=ϕ_g {f['r5_phi_g_deg']:8.4f}°  "
              f"r4 {f['r4_deg']:8.4f}°  t1 {f['t1_mm']:8.4f} mm  OC {f['OC_mm']:.3f} mm"
              + (f"  spin {f['spin_rpm']:.0f} rpm" if f["spin_rpm"] else ""))
    if res.comparison is not None:
        worst, worst_m = res.worst_angle_diff_deg()
        print(f"  ground vs CAD: Hausdorff {res.comparison['hausdorff_mm'] * 1e3:.4f} µm, angles "
              f"within {worst:.2e}° (exact surfaces), {worst_m:.3f}° (mesh path)")
    for w in res.files:
        print(f"  wrote {w}")
    return 0


def cmd_gauges(args) -> int:
    from .cannula import GAUGE_SOURCE, gauge_table

    rows = gauge_table()
    if args.json:
        print(_dumps({"source": GAUGE_SOURCE, "gauges": rows}))
        return 0
    print("gauge  d_e_mm  d_i_mm  wall_mm")
    for r in rows:
        print(f"{r['gauge']:>4}G  {r['outer_diameter_mm']:6.4f}  {r['inner_diameter_mm']:6.4f}"
              f"  {r['wall_mm']:7.4f}")
    print(f"# {GAUGE_SOURCE}")
    return 0


def cmd_samples(args) -> int:
    from .presets import preset, preset_names
    from .spec import dumps_spec, save_spec

    if args.write:
        out = Path(args.write)
        out.mkdir(parents=True, exist_ok=True)
        for n in preset_names():
            print(save_spec(preset(n), out / f"{n}.toml"))
        return 0
    if args.name:
        sys.stdout.write(dumps_spec(preset(args.name)))
        return 0
    for n in preset_names():
        print(f"{n:<22} {preset(n).description}")
    return 0


def cmd_demo(args) -> int:
    from .demo import run_demo

    summary = run_demo(args.out, tolerance=_tolerance(args), log=sys.stderr,
                       pictures=not args.no_pictures)
    if args.json:
        print(_dumps(summary))
    else:
        print("name                  triangles  volume_mm3  build_s  watertight")
        for r in summary["tips"]:
            print(f"{r['name']:<22}{r['triangles']:>9}  {r['volume_mm3']:10.5f}  "
                  f"{r['build_seconds']:7.3f}  {r['watertight']}")
        print(f"wrote {summary['out']}")
    return 0


def _export_exts() -> tuple[str, ...]:
    from .io import SUPPORTED_EXPORTS

    return SUPPORTED_EXPORTS


def _gcode_derived(args) -> list[str]:
    """``gcode sim --plot FILE`` also writes FILE-rim.png."""
    if args.action == "sim" and args.plot:
        p = Path(args.plot)
        return [str(p.with_name(p.stem + "-rim.png"))]
    return []


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="tipgeo", description="Geometry and CAM of hollow-needle "
                                "tips (mm, degrees; needle axis +z towards the tip).")
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="build a tip from a TOML spec (or preset name)")
    b.add_argument("spec", metavar="SPEC", help="spec file (.toml) or preset name")
    b.add_argument("-o", "--output", action="append", default=[], metavar="FILE",
                   help="mesh file; format from the extension (.stl .ply .obj .3mf .glb "
                        ".step .inp); repeatable")
    b.add_argument("--tolerance-um", type=float, default=None, metavar="N",
                   help="chordal tolerance in µm (default 0.05)")
    b.add_argument("--png", metavar="FILE", help="also write a picture of the tip")
    b.add_argument("--json", action="store_true", help="machine-readable summary")
    b.set_defaults(func=cmd_build)
    declare_files(b, inputs=("spec",), outputs=("output",), pictures=("png",),
                  exts={"output": _export_exts()})
    a = sub.add_parser("angles", help="cutting edges and angles (λ, θ, α, l_c) of tips")
    a.add_argument("spec", metavar="SPEC", nargs="+",
                   help="spec file, preset name, or mesh file (.stl .ply .obj .3mf .glb)")
    a.add_argument("--method", choices=("exact", "fourier", "mesh"), default=None,
                   help="default: fourier (the thesis's path) for specs, mesh for mesh files")
    a.add_argument("--harmonics", type=int, default=5, metavar="N",
                   help="Fourier harmonics (default 5, eq. 3.12)")
    a.add_argument("--step-deg", type=float, default=1.0, metavar="S",
                   help="γ step of the table (default 1°)")
    a.add_argument("--csv", metavar="FILE", help="write the table (all tips)")
    a.add_argument("--plot", metavar="FILE", help="write the angle plots (PNG)")
    a.add_argument("--json", action="store_true", help="summary and table as JSON")
    a.add_argument("--diameters-mm", type=float, nargs=2, metavar=("DE", "DI"),
                   help="outer and inner diameter of a mesh file's tube")
    a.add_argument("--axis", type=float, nargs=6, metavar=("X", "Y", "Z", "DX", "DY", "DZ"),
                   help="a mesh file's needle axis: a point and the direction to the tip")
    a.set_defaults(func=cmd_angles)
    declare_files(a, inputs=("spec",), outputs=("csv",), pictures=("plot",))
    la = sub.add_parser("laser", help="write the AeroBasic laser program of a serration spec")
    la.add_argument("spec", metavar="SPEC", help="spec file or preset with a serration cutter")
    la.add_argument("-o", "--output", required=True, metavar="FILE",
                    help="program file (.pgm), or - for stdout")
    for opt, hlp in (("--beam-diameter-um", "beam diameter (20)"),
                     ("--overlap", "pass overlap (0.95)"),
                     ("--roughing-depth-um", "radial roughing depth (20)"),
                     ("--feed-mm-s", "feed (0.1)"),
                     ("--pulse-period-us", "PSOPULSE period (10)"),
                     ("--pulse-on-us", "PSOPULSE on time (5)"),
                     ("--compensation-mm", "G41 lead-in (0.05)")):
        la.add_argument(opt, type=float, default=None, help=hlp)
    la.add_argument("--finishing-passes", type=int, default=None, help="(80)")
    la.set_defaults(func=cmd_laser)
    declare_files(la, inputs=("spec",), outputs=("output",))
    gc = sub.add_parser("gcode", help="check or simulate an AeroBasic laser program")
    gc.add_argument("action", choices=("check", "sim"))
    gc.add_argument("program", metavar="PROGRAM")
    gc.add_argument("--spec", default="punch-plain",
                    help="the punch to cut (spec or preset; default punch-plain)")
    gc.add_argument("--origin", type=float, nargs=2, default=(0.0, 0.0), metavar=("X0", "Y0"),
                    help="program coordinates of the first serration's centre on the rim")
    gc.add_argument("--beam-diameter-um", type=float, default=None,
                    help="beam diameter (20); T1's radius is half of it")
    gc.add_argument("--tolerance-um", type=float, default=None)
    gc.add_argument("--lenient", action="store_true",
                    help="skip unsupported statements with a warning")
    gc.add_argument("--plot", metavar="FILE", help="toolpath picture (and FILE-rim.png)")
    gc.add_argument("--mesh", metavar="FILE", help="write the ablated tip (sim)")
    gc.add_argument("--json", action="store_true")
    for opt, hlp in (("--max-statements", "statements executed (1000000)"),
                     ("--max-repeat", "largest REPEAT count (1000000)"),
                     ("--max-moves", "programmed moves (100000)"),
                     ("--max-operations", "expression and word operations (4000000)"),
                     ("--max-tokens", "tokens in the program file (250000)")):
        gc.add_argument(opt, type=int, default=None, metavar="N",
                        help=f"bound: {hlp}; each default costs at most ~5 s to reach")
    gc.set_defaults(func=cmd_gcode)
    declare_files(gc, inputs=("program", "spec"), outputs=("mesh",), pictures=("plot",),
                  exts={"mesh": _export_exts()}, derived=_gcode_derived)
    gr = sub.add_parser("grind", help="five-axis grinding program, set-up and simulation")
    gr.add_argument("spec", metavar="SPEC")
    gr.add_argument("-o", "--output", metavar="FILE", help="axis program (.json or .csv)")
    gr.add_argument("--gcode", metavar="FILE", help="ISO G-code rendering")
    gr.add_argument("--sheet", metavar="FILE", help="Markdown set-up sheet")
    gr.add_argument("--simulate", metavar="FILE", help="write the simulated ground tip mesh")
    gr.add_argument("--report", action="store_true", help="compare the simulation with CAD")
    gr.add_argument("--machine", metavar="TOML", help="machine limits and set-up overrides")
    gr.add_argument("--feed", type=float, default=0.1, help="infeed, mm/s (0.1)")
    gr.add_argument("--needle-rpm", type=float, default=1000.0,
                    help="needle spin for conical tips (1000)")
    gr.add_argument("--tolerance-um", type=float, default=None)
    gr.add_argument("--json", action="store_true")
    gr.set_defaults(func=cmd_grind)
    declare_files(gr, inputs=("spec", "machine"), outputs=("output", "gcode", "sheet", "simulate"),
                  exts={"output": (".json", ".csv"), "simulate": _export_exts()})
    g = sub.add_parser("gauges", help="the needle gauge table")
    g.add_argument("--json", action="store_true")
    g.set_defaults(func=cmd_gauges)
    s = sub.add_parser("samples", help="list the built-in specs, print one, or write all")
    s.add_argument("name", nargs="?", help="print this preset's TOML")
    s.add_argument("--write", metavar="DIR", help="write every preset as DIR/<name>.toml")
    s.set_defaults(func=cmd_samples)
    d = sub.add_parser("demo", help="build every thesis needle: meshes, pictures, summary")
    d.add_argument("--out", default="tipgeo-demo", metavar="DIR",
                   help="output folder (default ./tipgeo-demo)")
    d.add_argument("--tolerance-um", type=float, default=None, metavar="N")
    d.add_argument("--no-pictures", action="store_true", help="skip the PNG previews")
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=cmd_demo)
    from .cli_mechanics import register as _register_mechanics

    _register_mechanics(sub)
    from .cli_optimize import register as _register_optimize

    _register_optimize(sub)
    from .cli_inspect import register as _register_inspect

    _register_inspect(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tipgeo`` command."""
    from cam.machine import CamError
    from gcode.errors import GCodeError

    from .errors import BuildError, SpecError, TipGeoError

    args = _parser().parse_args(argv)
    try:
        if getattr(args, "output", None) == [] and args.command == "build" and not args.png:
            raise SpecError("build needs at least one -o FILE (or --png FILE)")
        check_files(args)
        from ._threads import small_linalg

        with small_linalg(getattr(args, "_blas_threads", 1)):
            return args.func(args)
    except (SpecError, GCodeError, CamError) as e:
        print(f"tipgeo: error: {e}", file=sys.stderr)
        return 2
    except (BuildError, TipGeoError) as e:
        print(f"tipgeo: failed: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"tipgeo: failed: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
