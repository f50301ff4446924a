"""``tipgeo demo``: every thesis needle, and what each stage makes of it."""

from __future__ import annotations

import argparse
import sys

from ..jsonio import dumps as _dumps
from .common import SubParsers, deprecated, tolerance_arg

__all__ = ["register", "cmd_demo"]


class _Notes:
    """A file-like ``log`` for :func:`tipgeo.demo.run_demo`: its lines go to
    :func:`tipgeo.progress.note` (silent with --quiet)."""

    def __init__(self) -> None:
        self._buf = ""

    def write(self, text: str) -> int:
        from .. import progress

        self._buf += text
        *lines, self._buf = self._buf.split("\n")
        for line in lines:
            progress.note(line)
        return len(text)

    def flush(self) -> None:
        pass


def cmd_demo(args: argparse.Namespace) -> int:
    from ..demo import run_demo

    summary = run_demo(args.out_dir, tolerance=tolerance_arg(args), log=_Notes(),
                       pictures=not args.no_pictures)
    leaky = [r["name"] for r in summary["tips"] if not r["watertight"]]
    if leaky:
        print(f"tipgeo: fail: not watertight: {', '.join(leaky)}", file=sys.stderr)
    if args.json:
        print(_dumps(summary))
    else:
        print("name                  triangles  volume_mm3  build_s  watertight")
        for r in summary["tips"]:
            print(f"{r['name']:<22}{r['triangles']:>9}  {r['volume_mm3']:10.5f}  "
                  f"{r['build_seconds']:7.3f}  {r['watertight']}")
        print(f"wrote {summary['out']}")
    return 1 if leaky else 0


def register(sub: SubParsers) -> None:
    """Add this stage's commands to the ``tipgeo`` sub-command parsers."""
    d = sub.add_parser("demo", help="build every thesis needle: meshes, pictures, summary")
    d.add_argument("--out-dir", default="tipgeo-demo", metavar="DIR",
                   help="output folder (default ./tipgeo-demo)")
    d.add_argument("--tolerance-um", type=float, default=None, metavar="N",
                   help="chordal tolerance of the meshes, µm")
    d.add_argument("--no-pictures", action="store_true", help="skip the PNG previews")
    deprecated(d, "--out", "--out-dir")
    d.set_defaults(func=cmd_demo)
