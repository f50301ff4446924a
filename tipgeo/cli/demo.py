"""``tipgeo demo``: every thesis needle, and what each stage makes of it."""

from __future__ import annotations

import sys

from ..jsonio import dumps as _dumps
from .common import tolerance_arg

__all__ = ["register", "cmd_demo"]


def cmd_demo(args) -> int:
    from ..demo import run_demo

    summary = run_demo(args.out, tolerance=tolerance_arg(args), log=sys.stderr,
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


def register(sub) -> None:
    """Add this stage's commands to the ``tipgeo`` sub-command parsers."""
    d = sub.add_parser("demo", help="build every thesis needle: meshes, pictures, summary")
    d.add_argument("--out", default="tipgeo-demo", metavar="DIR",
                   help="output folder (default ./tipgeo-demo)")
    d.add_argument("--tolerance-um", type=float, default=None, metavar="N")
    d.add_argument("--no-pictures", action="store_true", help="skip the PNG previews")
    d.add_argument("--json", action="store_true")
    d.set_defaults(func=cmd_demo)
