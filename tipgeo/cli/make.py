"""``tipgeo laser``, ``gcode``, ``grind``, ``mill``: the making stage on the
command line (laser programs for the A3200, five-axis grinding, three-axis
milling on the Haas VF-2; mm, degrees, µm, feeds mm/min for milling)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..jsonio import dumps as _dumps
from .common import (
    cannot_write,
    declare_files,
    deprecated,
    export_exts,
    feed_mm_min_arg,
    spec_arg,
    tolerance_arg,
    verdict_status,
    write_text,
)

if TYPE_CHECKING:
    from cam import GrindResult
    from cam.mill import EndMill, MillMachine, MillParams, MillResult
    from gcode.emitter import LaserParams
    from gcode.pipeline import LaserCheck
    from tipgeo.verdict import Verdict

__all__ = ["register", "cmd_laser", "cmd_gcode", "cmd_grind", "cmd_mill"]

#: µm per mm (flags in µm, lengths in mm inside).
UM_PER_MM = 1e3


def _laser_params(args: argparse.Namespace) -> LaserParams:
    """The laser station (``--machine`` file, else the defaults) with the
    flags given on top of it."""
    import dataclasses

    from gcode.emitter import LaserParams

    base = LaserParams.from_toml(args.machine) if args.machine else LaserParams()
    kw: dict[str, Any] = {}
    for opt, key, scale in (("beam_diameter_um", "beam_diameter", 1 / UM_PER_MM),
                            ("overlap", "overlap", 1.0),
                            ("roughing_depth_um", "roughing_depth", 1 / UM_PER_MM),
                            ("finishing_passes", "finishing_passes", None),
                            ("pulse_period_us", "pulse_period_us", 1.0),
                            ("pulse_on_us", "pulse_on_us", 1.0),
                            ("compensation_mm", "compensation", 1.0)):
        val = getattr(args, opt, None)
        if val is not None:
            kw[key] = val if scale is None else val * scale
    feed = feed_mm_min_arg("--feed-mm-min", args.feed_mm_min)
    if feed is not None:
        kw["feed"] = feed
    return dataclasses.replace(base, **kw) if kw else base


def _not_written(verdict: Verdict) -> int:
    """A made program outside its targets: the failing figures on stderr,
    nothing written, exit status 1."""
    print(f"tipgeo: fail: {'; '.join(verdict.reasons) or 'outside its targets'} (nothing "
          "was written: a program outside its targets is not written)", file=sys.stderr)
    return 1


def _failed(verdict: Verdict | None) -> bool:
    return verdict is not None and not verdict.ok


def cmd_laser(args: argparse.Namespace) -> int:
    """``tipgeo laser``: the AeroBasic program of a serration spec, checked
    by the interpreter (and, with ``--html``, simulated and judged against
    its spec) before it is written."""
    from gcode.emitter import emit_program
    from gcode.pipeline import laser_check

    from ..errors import InputError

    spec = spec_arg(args.spec)
    params = _laser_params(args)
    if args.output == "-" and (args.html or args.json):
        raise InputError("--html needs -o FILE (the program it simulates is written there), "
                         "not -o -" if args.html else "-o - writes the program on stdout; with "
                         "--json, stdout holds the JSON: give -o FILE")
    text = emit_program(spec, params)
    # the program as it will be written, interpreted (and simulated for --html)
    res = laser_check(text, beam_diameter=params.beam_diameter,
                      spec=spec if args.html else None)
    verdict = res.verdict if args.html else None
    if _failed(verdict):
        assert verdict is not None
        return _not_written(verdict)
    if args.output == "-":
        sys.stdout.write(text)
        return 0
    write_text(args.output, text)
    html = None
    if args.html:
        from ..report import LaserSource
        from .report import write_html

        src = LaserSource(res, name=f"{spec.name}: {Path(args.output).name}")
        html = write_html(args, [spec, src], say=False)
    _print_laser(args, spec.name, text, params, html, verdict)
    return verdict_status(verdict, args)


def _print_laser(args: argparse.Namespace, name: str, text: str, params: LaserParams,
                 html: str | None, verdict: Verdict | None) -> None:
    """What ``tipgeo laser`` wrote: JSON or plain lines."""
    if args.json:
        from dataclasses import asdict

        out: dict[str, Any] = {"spec": name, "program": str(args.output),
                               "lines": len(text.splitlines()), "params": asdict(params)}
        if html:
            out["html"] = html
            out["verdict"] = verdict.to_dict() if verdict is not None else None
        print(_dumps(out))
        return
    print(f"wrote {args.output} ({len(text.splitlines())} lines)")
    if html:
        if verdict is not None:
            print(f"  {verdict.line()}")
        print(f"  wrote {html}")


def cmd_gcode(args: argparse.Namespace) -> int:
    """``tipgeo gcode check|sim``: a laser program read, interpreted within
    its bounds and (sim) simulated against a spec; every check runs before
    the simulated tip and the pictures are written."""
    from gcode.emitter import LaserParams
    from gcode.pipeline import laser_check, make_limits, read_program, write_laser_outputs

    from ..errors import InputError

    station = LaserParams.from_toml(args.machine) if args.machine else LaserParams()
    beam = station.beam_diameter if args.beam_diameter_um is None else \
        args.beam_diameter_um / UM_PER_MM
    if args.html and (args.action != "sim" or args.spec is None):
        raise InputError(f"--html = '{args.html}' needs 'gcode sim' with --spec (the part the "
                         "moves are drawn on)")
    spec = spec_arg(args.spec or "punch-plain") if args.action == "sim" else None
    limits = make_limits(max_statements=args.max_statements, max_repeat=args.max_repeat,
                         max_segments=args.max_moves, max_operations=args.max_operations)
    default_feed = feed_mm_min_arg("--default-feed-mm-min", args.default_feed_mm_min)
    res = laser_check(read_program(args.program), beam_diameter=beam, spec=spec,
                      origin=tuple(args.origin_mm), tolerance=tolerance_arg(args),
                      lenient=args.lenient, limits=limits, max_tokens=args.max_tokens,
                      default_feed=default_feed)
    write_laser_outputs(res, spec, mesh=args.mesh if args.action == "sim" else None,
                        plot=args.png, on_error=cannot_write)
    if args.html:
        from ..report import LaserSource
        from .report import write_html

        html = write_html(args, [spec, LaserSource(res, origin=tuple(args.origin_mm),
                                                   name=Path(args.program).name)], say=False)
        if html is not None:
            res.files.append(html)
    out = res.summary(source=args.program)
    verdict = res.verdict
    status = 1 if res.failed else verdict_status(verdict, args)
    if args.json:
        print(_dumps(out))
    else:
        _print_gcode(args.program, res, out)
    return status


def _um(x: float | None) -> str:
    """A length in mm as µm with 3 decimals ("n/a" for None)."""
    return "n/a" if x is None else f"{x * UM_PER_MM:.3f}"


def _print_gcode(source: str, res: LaserCheck, out: dict[str, Any]) -> None:
    """The plain-text report of ``tipgeo gcode``: the program, its moves and
    times, the ablation and the comparison with the spec, the files."""
    prog, tp, s = res.program, res.toolpath, out["toolpath"]
    print(f"{source}: {len(prog.body)} statements, {s['segments']} moves")
    print(f"  path {s['path_length_mm']:.4f} mm, beam on {s['beam_on_length_mm']:.4f} mm, "
          f"time {s['time_s']:.2f} s (beam on {s['beam_on_time_s']:.2f} s), "
          f"pulses {s['pulses'] if s['pulses'] is not None else 'n/a'}")
    if s["dwells"]:
        print(f"  dwells: {s['dwells']}, {s['dwell_time_s']:.3f} s (in the time)")
    print(f"  C positions firing: {len(s['c_angles_with_beam_deg'])} "
          f"{[round(c, 4) for c in s['c_angles_with_beam_deg']][:24]}")
    for rec in tp.no_motion:
        print(f"  no motion: line {rec['line']}: {rec['statement']} — {rec['effect']} "
              f"(executed {rec['executed']}×)")
    for w in tp.warnings:
        print(f"  warning: {w}")
    if "ablation" in out:
        a = out["ablation"]
        print(f"  ablation: {a['notches']} notches, {a['slugs_removed']} slugs fell out, "
              f"watertight {a['watertight']}")
    if "comparison" in out:
        c = out["comparison"]
        rad = c["radius_mm"]
        print(f"  vs spec: radius {_um(rad['fitted_mean'])} µm fitted (spec {_um(rad['spec'])}, "
              f"max error {_um(rad['fitted_max_error'])} µm), spacing max error "
              f"{c['spacing_deg']['fitted_max_error']}°, Hausdorff "
              f"{_um(c['hausdorff_mm'])} µm")
    _print_files(res.verdict, res.files, res.failed)


def _print_files(verdict: Verdict | None, files: list[str],
                 failed: list[dict[str, Any]]) -> None:
    """The verdict's line, the files written and those that could not be."""
    if verdict is not None:
        print(f"  {verdict.line()}")
    for o in files:
        print(f"  wrote {o}")
    for f in failed:
        print(f"  NOT written: {f['path']}")


def cmd_grind(args: argparse.Namespace) -> int:
    """``tipgeo grind``: the five-axis program, checked against the
    machine's limits, simulated and (``--compare``) judged against CAD
    before any file is written; a program outside its targets is not
    written (exit status 1)."""
    from cam import Machine, grind, write_grind_outputs

    spec = spec_arg(args.spec)
    machine = Machine.from_toml(args.machine) if args.machine else Machine()
    feed = feed_mm_min_arg("--feed-mm-min", args.feed_mm_min)
    res = grind(spec, machine=machine, feed=6.0 / 60.0 if feed is None else feed,
                needle_rpm=args.needle_rpm,
                simulate_tip=bool(args.mesh or args.compare or args.html),
                compare=args.compare, tolerance=tolerance_arg(args))
    verdict = res.verdict
    if _failed(verdict):
        _print_grind(args, res)
        assert verdict is not None
        return _not_written(verdict)
    write_grind_outputs(res, program=args.output, gcode=args.gcode, sheet=args.sheet,
                        mesh=args.mesh, on_error=cannot_write)
    if args.html:
        from .report import write_html

        html = write_html(args, [spec, res], say=False)
        if html is not None:
            res.files.append(html)
    _print_grind(args, res)
    return 1 if res.failed else verdict_status(verdict, args)


def _print_grind(args: argparse.Namespace, res: GrindResult) -> None:
    """What ``tipgeo grind`` made: JSON or plain lines."""
    out = res.summary()
    if args.json:
        print(_dumps(out))
        return
    s = out["program"]
    print(f"{s['name']}: faces {s['faces']}, {s['rows']} program rows, time {s['time_s']:.1f} s, "
          f"feed {s['feed_mm_s'] * 60:g} mm/min")
    for f in s["setup"]:
        print(f"  {f['face']:<22} ξ {f['xi_deg']:8.4f}°  r5=ϕ_g {f['r5_phi_g_deg']:8.4f}°  "
              f"r4 {f['r4_deg']:8.4f}°  t1 {f['t1_mm']:8.4f} mm  OC {f['OC_mm']:.3f} mm"
              + (f"  spin {f['spin_rpm']:.0f} rpm" if f["spin_rpm"] else ""))
    worst = res.worst_angle_diff_deg()
    if res.comparison is not None and worst is not None:
        print(f"  ground vs CAD: Hausdorff {res.comparison['hausdorff_mm'] * UM_PER_MM:.4f} µm, "
              f"angles within {worst[0]:.2e}° (exact surfaces), {worst[1]:.3f}° (mesh path)")
    _print_files(res.verdict, res.files, res.failed)


def _mill_request(args: argparse.Namespace) -> tuple[MillMachine, EndMill, MillParams]:
    """The machine, the tool and the parameters of ``tipgeo mill`` from its
    flags (the µm scallop checked in µm, so the error names what the user
    typed)."""
    from cam.mill import DEFAULT_TOOL, MillMachine, MillParams, parse_tool
    from tipgeo import validate as v

    machine = MillMachine.from_toml(args.machine) if args.machine else MillMachine()
    tool = parse_tool(args.tool) if args.tool else DEFAULT_TOOL
    scallop_um = v.real("--scallop-um", args.scallop_um, lo=0.1, hi=100.0, unit="µm")
    kw: dict[str, Any] = {"scallop": scallop_um / UM_PER_MM}
    for opt, key in (("feed_mm_min", "finish_feed"), ("rough_feed_mm_min", "rough_feed"),
                     ("spindle_rpm", "spindle_rpm"), ("allowance_mm", "allowance")):
        if getattr(args, opt) is not None:
            kw[key] = getattr(args, opt)
    if args.no_rough:
        kw["rough"] = False
    return machine, tool, MillParams(**kw)


def cmd_mill(args: argparse.Namespace) -> int:
    """``tipgeo mill``: toolpaths and the G-code, the program read back and
    checked against the machine and the tool, simulated and (``--compare``)
    judged against CAD — all before any file is written; a program outside
    its targets is not written (exit status 1)."""
    from cam.mill import mill, write_mill_outputs

    from .. import progress

    spec = spec_arg(args.spec)
    machine, tool, params = _mill_request(args)
    simulate = bool(args.mesh or args.compare or args.deviation_png or args.html)
    res = mill(spec, tool=tool, machine=machine, params=params, simulate_tip=simulate,
               compare=bool(args.compare or args.deviation_png), progress=progress.note)
    verdict = res.verdict
    if _failed(verdict):
        _print_mill(args, res)
        assert verdict is not None
        return _not_written(verdict)
    write_mill_outputs(res, program=args.output, sheet=args.sheet, mesh=args.mesh,
                       deviation=args.deviation_png, toolpath=args.png, on_error=cannot_write)
    if args.html:
        from .report import write_html

        html = write_html(args, [spec, res], say=False)
        if html is not None:
            res.files.append(html)
    _print_mill(args, res)
    return 1 if res.failed else verdict_status(verdict, args)


def _print_mill(args: argparse.Namespace, res: MillResult) -> None:
    """What ``tipgeo mill`` made: JSON or plain lines."""
    out = res.summary()
    if args.json:
        print(_dumps(out))
        return
    t, p = out["toolpath"], out["program"]
    print(f"{t['name']}: {t['tool']}; clocking {t['clocking_deg']:.2f}°, finishing step-over "
          f"{t['stepover_mm'] * UM_PER_MM:.0f} µm for a {t['scallop_um']:g} µm scallop, "
          f"{t['finish_passes']} finishing + {t['rough_passes']} roughing passes")
    print(f"  program: {p['lines']} lines, {p['moves']} moves, cycle time "
          f"{p['cycle_time_s'] / 60:.1f} min on {res.toolpath.machine.name.split(' (')[0]}")
    if res.comparison is not None:
        c = res.comparison
        a = c["angles"]["outer"]
        print(f"  milled vs CAD over {c['region']}: scallop {c['scallop_measured_um']:.3f} µm "
              f"(target {c['scallop_target_um']:g}), gouge {c['gouge_um']:.3f} µm")
        print(f"  outer edge: λ within {a['lambda_max_diff_deg']:.3f}°, θ within "
              f"{a['theta_max_diff_deg']:.3f}°, α within {a['alpha_max_diff_deg']:.3f}° "
              f"({c['gamma_compared']})")
    _print_files(res.verdict, res.files, res.failed)


def gcode_derived(args: argparse.Namespace) -> list[str]:
    """``gcode sim --png FILE`` also writes FILE-rim.png."""
    if args.action == "sim" and args.png:
        p = Path(args.png)
        return [str(p.with_name(p.stem + "-rim.png"))]
    return []


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add this stage's commands to the ``tipgeo`` sub-command parsers."""
    la = sub.add_parser("laser", help="write the AeroBasic laser program of a serration spec")
    la.add_argument("spec", metavar="SPEC", help="spec file or preset with a serration cutter")
    la.add_argument("-o", "--output", required=True, metavar="FILE",
                    help="program file (.pgm), or - for stdout")
    for opt, hlp in (("--beam-diameter-um", "beam diameter (20)"),
                     ("--overlap", "pass overlap (0.95)"),
                     ("--roughing-depth-um", "radial roughing depth (20)"),
                     ("--feed-mm-min", "feed, mm/min (6)"),
                     ("--pulse-period-us", "PSOPULSE period (10)"),
                     ("--pulse-on-us", "PSOPULSE on time (5)"),
                     ("--compensation-mm", "G41 lead-in (0.05)")):
        la.add_argument(opt, type=float, default=None, help=hlp)
    la.add_argument("--finishing-passes", type=int, default=None, help="(80)")
    la.add_argument("--machine", metavar="TOML", help="laser station file (e.g. "
                    "samples/machines/a3200-laser.toml); flags given override it")
    deprecated(la, "--feed-mm-s", "--feed-mm-min", convert=lambda v: v * 60.0,
               note=" (mm/min; the value given was converted from mm/s)")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(la)
    la.set_defaults(func=cmd_laser)
    declare_files(la, inputs=("spec", "machine"), outputs=("output", "html"),
                  exts={"html": HTML_EXTS})
    gc = sub.add_parser("gcode", help="check or simulate an AeroBasic laser program")
    gc.add_argument("action", choices=("check", "sim"))
    gc.add_argument("program", metavar="PROGRAM")
    gc.add_argument("--spec", default=None,
                    help="the punch to cut (spec or preset; default punch-plain)")
    gc.add_argument("--origin-mm", type=float, nargs=2, default=(0.0, 0.0),
                    metavar=("X0", "Y0"),
                    help="program coordinates (mm) of the first serration's centre on the rim")
    gc.add_argument("--beam-diameter-um", type=float, default=None,
                    help="beam diameter (20, or the --machine file's); T1's radius is half "
                         "of it")
    gc.add_argument("--machine", metavar="TOML", help="laser station file (its beam diameter; "
                    "e.g. samples/machines/a3200-laser.toml)")
    gc.add_argument("--tolerance-um", type=float, default=None, metavar="N",
                    help="chordal tolerance of the simulated tip's mesh, µm")
    gc.add_argument("--lenient", action="store_true",
                    help="skip unsupported statements with a warning (never a move)")
    gc.add_argument("--default-feed-mm-min", type=float, default=None, metavar="F",
                    help="feed (mm/min) for a G01/G02/G03 before any F, with a warning "
                         "naming the line; without it such a move is an error")
    gc.add_argument("--png", metavar="FILE", help="toolpath picture (and FILE-rim.png)")
    gc.add_argument("--mesh", metavar="FILE", help="write the ablated tip (sim)")
    for opt, hlp in (("--max-statements", "statements executed (1000000)"),
                     ("--max-repeat", "largest REPEAT count (1000000)"),
                     ("--max-moves", "programmed moves (100000)"),
                     ("--max-operations", "expression and word operations (4000000)"),
                     ("--max-tokens", "tokens in the program file (250000)")):
        gc.add_argument(opt, type=int, default=None, metavar="N",
                        help=f"bound: {hlp}; each default costs at most ~5 s to reach")
    deprecated(gc, "--plot", "--png")
    deprecated(gc, "--origin", "--origin-mm")
    add_html_flag(gc)
    gc.set_defaults(func=cmd_gcode)
    declare_files(gc, inputs=("program", "spec", "machine"), outputs=("mesh", "html"),
                  pictures=("png",), exts={"mesh": export_exts(), "html": HTML_EXTS},
                  derived=gcode_derived)
    gr = sub.add_parser("grind", help="five-axis grinding program, set-up and simulation")
    gr.add_argument("spec", metavar="SPEC")
    gr.add_argument("-o", "--output", metavar="FILE", help="axis program (.json or .csv)")
    gr.add_argument("--gcode", metavar="FILE", help="ISO G-code rendering")
    gr.add_argument("--sheet", metavar="FILE", help="Markdown set-up sheet")
    gr.add_argument("--mesh", metavar="FILE", help="write the simulated ground tip mesh")
    gr.add_argument("--compare", action="store_true",
                    help="compare the simulated tip with CAD (exit 1 when outside its bounds)")
    gr.add_argument("--machine", metavar="TOML", help="machine limits and set-up overrides "
                    "(e.g. samples/machines/grinder.toml)")
    gr.add_argument("--feed-mm-min", type=float, default=None, metavar="F",
                    help="infeed, mm/min (6)")
    gr.add_argument("--needle-rpm", type=float, default=1000.0,
                    help="needle spin for conical tips (1000)")
    gr.add_argument("--tolerance-um", type=float, default=None, metavar="N",
                    help="chordal tolerance of the simulated tip's mesh, µm")
    deprecated(gr, "--simulate", "--mesh")
    deprecated(gr, "--report", "--compare")
    deprecated(gr, "--feed", "--feed-mm-min", convert=lambda v: v * 60.0,
               note=" (mm/min; the value given was converted from mm/s)")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(gr)
    gr.set_defaults(func=cmd_grind)
    declare_files(gr, inputs=("spec", "machine"),
                  outputs=("output", "gcode", "sheet", "mesh", "html"),
                  exts={"output": (".json", ".csv"), "mesh": export_exts(),
                        "html": HTML_EXTS})
    mi = sub.add_parser("mill", help="three-axis milling (Haas VF-2): toolpaths, G-code, "
                        "material-removal simulation")
    mi.add_argument("spec", metavar="SPEC")
    mi.add_argument("-o", "--output", required=True, metavar="PROGRAM",
                    help="G-code program (.nc)")
    mi.add_argument("--tool", metavar="KIND:D[:R[:REACH]]",
                    help="end mill, mm: ball:1.588 (default), bull:2:0.25, flat:1")
    mi.add_argument("--scallop-um", type=float, default=2.0,
                    help="finishing scallop height target, µm (2)")
    mi.add_argument("--feed-mm-min", type=float, default=None, help="finishing feed (150)")
    mi.add_argument("--rough-feed-mm-min", type=float, default=None, help="roughing feed (200)")
    mi.add_argument("--spindle-rpm", type=float, default=None, help="spindle speed (10000)")
    mi.add_argument("--allowance-mm", type=float, default=None,
                    help="roughing stock allowance (0.05)")
    mi.add_argument("--no-rough", action="store_true", help="finishing passes only")
    mi.add_argument("--sheet", metavar="FILE", help="Markdown set-up sheet")
    mi.add_argument("--mesh", metavar="FILE", help="write the simulated milled tip mesh")
    mi.add_argument("--png", metavar="FILE",
                    help="picture of the toolpaths (plan and side view)")
    mi.add_argument("--deviation-png", metavar="FILE",
                    help="deviation map milled − CAD (µm); implies --compare")
    mi.add_argument("--compare", action="store_true",
                    help="compare the simulated tip with CAD (exit 1 when the scallop or a "
                         "gouge is outside its target)")
    mi.add_argument("--machine", metavar="TOML", help="machine limits and set-up overrides "
                    "(e.g. samples/machines/haas-vf2.toml)")
    deprecated(mi, "--simulate", "--mesh")
    deprecated(mi, "--report", "--compare")
    deprecated(mi, "--toolpath-png", "--png")
    deprecated(mi, "--deviation", "--deviation-png")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(mi)
    mi.set_defaults(func=cmd_mill)
    declare_files(mi, inputs=("spec", "machine"), outputs=("output", "sheet", "mesh", "html"),
                  pictures=("deviation_png", "png"),
                  exts={"output": (".nc", ".ngc", ".tap", ".txt"), "mesh": export_exts(),
                        "html": HTML_EXTS})
