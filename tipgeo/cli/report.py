"""``tipgeo report``: one interactive, offline HTML page (plotly, inlined) of
specs, presets and output folders — :func:`tipgeo.report.html_report` on the
command line. Lengths mm, angles degrees, deviations µm in the page."""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterable
from typing import Any

from ..jsonio import dumps as _dumps
from .common import declare_files

__all__ = ["register", "cmd_report", "add_html_flag", "write_html", "HTML_EXTS"]

#: Extensions of an HTML report (:data:`tipgeo.report.REPORT_EXTS`; a test keeps them equal).
HTML_EXTS = (".html", ".htm")

#: The help of every command's ``--html`` (one meaning: the VOCABULARY's).
HTML_HELP = "also write an interactive offline HTML report of the result (tipgeo report)"


def cmd_report(args: argparse.Namespace) -> int:
    from ..report import html_report

    t0 = time.perf_counter()
    info = html_report(args.source, args.output, title=args.title)
    info["seconds"] = time.perf_counter() - t0
    if args.json:
        print(_dumps(info))
    else:
        print(f"wrote {info['output']} ({info['bytes'] / 1e6:.2f} MB, "
              f"{len(info['sections'])} sections, {info['seconds']:.1f} s)")
    return 0


def add_html_flag(parser: argparse.ArgumentParser) -> None:
    """Add ``--html FILE`` to a command (declare ``html`` among its outputs
    with the extensions of :data:`tipgeo.report.REPORT_EXTS`)."""
    parser.add_argument("--html", metavar="FILE", help=HTML_HELP)


def write_html(args: argparse.Namespace, sources: Iterable[Any], *,
               say: bool = True) -> str | None:
    """Write ``--html`` (if given) from ``sources``; returns its path."""
    if not getattr(args, "html", None):
        return None
    from ..report import html_report

    info = html_report(sources, args.html)
    if say and not args.json:
        print(f"  wrote {info['output']} ({info['bytes'] / 1e6:.2f} MB)")
    return str(info["output"])


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``report`` to the ``tipgeo`` sub-command parsers."""
    r = sub.add_parser("report", help="one interactive offline HTML page (3D tip, edges and "
                       "angles, deviations, FEM forces, response surfaces) of specs, presets "
                       "and output folders")
    r.add_argument("source", metavar="SOURCE", nargs="+",
                   help="a spec file (.toml), a preset name, or an output folder of "
                        "'tipgeo compare', 'tipgeo fem' or 'tipgeo optimize'")
    r.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="the HTML file (.html)")
    r.add_argument("--title", metavar="TEXT", help="the page's title")
    r.set_defaults(func=cmd_report)
    declare_files(r, inputs=("source",), outputs=("output",), exts={"output": HTML_EXTS})
