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

__all__ = ["main"]


def _spec(arg: str):
    from .errors import SpecError
    from .presets import PRESETS, preset
    from .spec import load_spec

    p = Path(arg)
    if p.exists() or arg.endswith(".toml"):
        return load_spec(p)
    if arg in PRESETS:
        return preset(arg)
    raise SpecError(f"SPEC = '{arg}' is neither a spec file nor a preset; presets: "
                    + ", ".join(PRESETS))


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
        print(json.dumps(info, indent=2, default=str))
    else:
        print(f"{spec.name or args.spec}: {info['triangles']} triangles, volume "
              f"{info['volume_mm3']:.6f} mm³, tolerance {info['tolerance_um']:g} µm, "
              f"built in {dt:.3f} s")
        for label, n in info["labels"].items():
            print(f"  {label:<24} {n:>8} triangles")
        for o in outs:
            print(f"  wrote {o}")
    return 0


def cmd_gauges(args) -> int:
    from .cannula import GAUGE_SOURCE, gauge_table

    rows = gauge_table()
    if args.json:
        print(json.dumps({"source": GAUGE_SOURCE, "gauges": rows}, indent=2))
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
        print(json.dumps(summary, indent=2, default=str))
    else:
        print("name                  triangles  volume_mm3  build_s  watertight")
        for r in summary["tips"]:
            print(f"{r['name']:<22}{r['triangles']:>9}  {r['volume_mm3']:10.5f}  "
                  f"{r['build_seconds']:7.3f}  {r['watertight']}")
        print(f"wrote {summary['out']}")
    return 0


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
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tipgeo`` command."""
    from .errors import BuildError, SpecError, TipGeoError

    args = _parser().parse_args(argv)
    try:
        if getattr(args, "output", None) == [] and args.command == "build" and not args.png:
            raise SpecError("build needs at least one -o FILE (or --png FILE)")
        return args.func(args)
    except SpecError as e:
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
