"""``tipgeo build``, ``gauges``, ``samples``: the design stage on the command line
(lengths mm, angles degrees, tolerances µm at this boundary)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..jsonio import dumps as _dumps
from ..paths import inside
from .common import (
    SubParsers,
    cannot_write,
    declare_files,
    deprecated,
    export_exts,
    spec_arg,
    tolerance_arg,
)

__all__ = ["register", "cmd_build", "cmd_gauges", "cmd_samples"]


def cmd_build(args: argparse.Namespace) -> int:
    from .. import progress
    from ..build import build_tip
    from ..io import export_many

    spec = spec_arg(args.spec)
    tolerance = tolerance_arg(args)
    t0 = time.perf_counter()
    with progress.stage(f"building {spec.name or args.spec}"):
        tip = build_tip(spec, tolerance=tolerance, quality=args.mesh_quality)
    dt = time.perf_counter() - t0

    report = export_many(tip, args.output, on_error=cannot_write, gltf_units=args.gltf_units,
                         gltf_up=args.gltf_up, step_form=args.step_form)
    outs: list[Path | str | None] = list(report.written)
    if args.png:
        from ..plot import render_tip

        outs.append(render_tip(tip, args.png))
    if args.html:
        from .report import write_html

        outs.append(write_html(args, [tip], say=False))
    info = tip.summary() | {"mesh_quality": bool(args.mesh_quality), "build_seconds": dt,
                            "outputs": [str(o) for o in outs],
                            "failed": [{"path": str(p), "error": m} for p, m in report.failed]}
    status = 1 if report.failed else 0
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
        for p, _ in report.failed:
            print(f"  NOT written: {p}")
    return status


def cmd_gauges(args: argparse.Namespace) -> int:
    from ..cannula import GAUGE_SOURCE, gauge_table

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


def cmd_samples(args: argparse.Namespace) -> int:
    from ..presets import preset, preset_names
    from ..spec import dumps_spec, save_spec

    if args.out_dir:
        out = Path(args.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        wrote = [str(save_spec(preset(n), inside(out, n, ".toml"))) for n in preset_names()]
        if args.json:
            print(_dumps({"out_dir": str(out), "wrote": wrote}))
        else:
            print("\n".join(wrote))
        return 0
    if args.name:
        text = dumps_spec(preset(args.name))
        if args.json:
            print(_dumps({"name": args.name, "description": preset(args.name).description,
                          "toml": text}))
        else:
            sys.stdout.write(text)
        return 0
    if args.json:
        print(_dumps({"samples": [{"name": n, "description": preset(n).description}
                                  for n in preset_names()]}))
        return 0
    for n in preset_names():
        print(f"{n:<22} {preset(n).description}")
    return 0


def register(sub: SubParsers) -> None:
    """Add this stage's commands to the ``tipgeo`` sub-command parsers."""
    b = sub.add_parser("build", help="build a tip from a TOML spec (or preset name)")
    b.add_argument("spec", metavar="SPEC", help="spec file (.toml) or preset name")
    b.add_argument("-o", "--output", action="append", default=[], metavar="FILE",
                   help="mesh file; format from the extension (.stl .ply .obj .3mf .glb "
                        ".step .inp); repeatable")
    b.add_argument("--tolerance-um", type=float, default=None, metavar="N",
                   help="chordal tolerance in µm (default 0.05)")
    b.add_argument("--mesh-quality", action="store_true",
                   help="mesh for other programs: no triangle with an aspect ratio above 50 "
                        "where local edits reach it, no self-intersection (also for "
                        "MeshLab's/open3d's checks), same chordal tolerance; about 3x the "
                        "triangles and 1-10 s")
    b.add_argument("--gltf-units", choices=("m", "mm"), default="m",
                   help="GLB length unit: m (glTF's, viewers show true size; default) or mm")
    b.add_argument("--gltf-up", choices=("y", "z"), default="y",
                   help="GLB axis of the needle: y (glTF's up, tip up in viewers; default) or "
                        "z (the cannula frame as it is)")
    b.add_argument("--step-form", choices=("auto", "exact", "faceted"), default="auto",
                   help="STEP: exact surfaces (planes, cylinders, cones, B-spline helicoid), "
                        "faceted (a plane per triangle), or auto (exact where the cutters "
                        "allow; default)")
    b.add_argument("--png", metavar="FILE", help="also write a picture of the tip")
    b.add_argument("--json", action="store_true", help="machine-readable summary")
    from .report import HTML_EXTS, add_html_flag

    add_html_flag(b)
    b.set_defaults(func=cmd_build)
    declare_files(b, inputs=("spec",), outputs=("output", "html"), pictures=("png",),
                  exts={"output": export_exts(), "html": HTML_EXTS})
    g = sub.add_parser("gauges", help="the needle gauge table")
    g.add_argument("--json", action="store_true")
    g.set_defaults(func=cmd_gauges)
    s = sub.add_parser("samples", help="list the built-in specs, print one, or write all")
    s.add_argument("name", nargs="?", help="print this preset's TOML")
    s.add_argument("--out-dir", metavar="DIR", help="write every preset as DIR/<name>.toml")
    deprecated(s, "--write", "--out-dir")
    s.set_defaults(func=cmd_samples)
