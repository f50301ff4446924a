"""The milling pipeline as one call: toolpaths → G-code → (optional) the
material-removal simulation read back from the G-code → comparison with the
CAD tip; and the files a user asks for. Used by ``tipgeo mill`` and the demo.

Frames and units: :mod:`cam.mill.machine` (mm, rad inside; µm, degrees,
mm/min and seconds in reports).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tipgeo import progress as pg
from tipgeo.tolerances import tol

from .check import check_program
from .machine import EndMill, MillMachine
from .post import post_program
from .simulate import GCodeMoves, MilledTip
from .toolpath import MillParams, MillToolpath, ProgressFn, plan_toolpaths, progress_say

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec
    from tipgeo.verdict import Verdict

__all__ = ["MillResult", "mill", "write_mill_outputs", "setup_sheet"]


@dataclass
class MillResult:
    """What :func:`mill` made: the toolpath, its G-code and its moves as
    read back and checked (:func:`cam.mill.check.check_program`), the
    simulated milled tip (:class:`cam.mill.simulate.MilledTip`), its
    comparison with CAD and the :attr:`verdict` on it; the files
    :func:`write_mill_outputs` wrote and those it could not (``failed``:
    ``path``, ``error``)."""

    toolpath: MillToolpath
    gcode: str
    milled: MilledTip | None = None
    comparison: dict[str, Any] | None = None
    cpu_s: dict[str, float] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)
    moves: GCodeMoves | None = None
    failed: list[dict[str, str]] = field(default_factory=list)

    @property
    def verdict(self) -> Verdict | None:
        """:class:`tipgeo.verdict.Verdict` of the comparison with CAD against
        the toolpath's own scallop target (:meth:`judge`); None when the run
        was not compared."""
        return self.judge()

    def judge(self, scallop_um: float | None = None) -> Verdict | None:
        """The milled part against a scallop target (µm; default the one the
        toolpath was planned for), or None without a comparison.

        Rules (figures of :func:`cam.mill.compare_milled`, over its stated
        region away from the edges and ridges):

        - ``scallop_um`` ≤ the target;
        - ``gouge_um`` ≤ ``tol.cam.mill_gouge`` (1 µm: the drop-cutter's mesh,
          see :class:`tipgeo.tolerances.CamTolerances`);
        - λ, θ and α of both edges within atan(h / s) of CAD (h the target, s
          the step-over): a surface anywhere within [0, h] of CAD — what the
          scallop rule lets through — may tilt by that much over one
          step-over, the width the edge angles are fitted over; a larger
          difference is a shape error, not the scallops.
        """
        c = self.comparison
        if c is None:
            return None
        from tipgeo.verdict import Verdict, check_max

        target = self.toolpath.params.scallop * 1e3 if scallop_um is None else float(scallop_um)
        step = self.toolpath.setup.stepover
        bound = math.degrees(math.atan(target * 1e-3 / step))
        checks = [check_max("scallop_um", c["scallop_measured_um"], target,
                            what="scallop measured (µm)"),
                  check_max("gouge_um", c["gouge_um"], tol.cam.mill_gouge * 1e3,
                            what="gouge (µm)")]
        for wall in ("outer", "inner"):
            a = c["angles"][wall]
            for k, sym in (("lambda", "λ"), ("theta", "θ"), ("alpha", "α")):
                checks.append(check_max(f"{wall}_{k}_diff_deg", a[f"{k}_max_diff_deg"],
                                        round(bound, 4),
                                        what=f"{wall} edge {sym} − CAD (°)"))
        return Verdict.of(f"milled {self.toolpath.name} vs CAD (scallop target {target:g} µm)",
                          checks)

    def summary(self) -> dict[str, Any]:
        """Toolpath, program and (if any) comparison and its verdict, in
        report units."""
        from .simulate import read_gcode

        moves = self.moves or (self.milled.moves if self.milled is not None
                               else read_gcode(self.gcode))
        out: dict[str, Any] = {"toolpath": self.toolpath.summary(),
                               "program": moves.summary(self.toolpath.machine.rapid)}
        verdict = self.verdict
        if self.comparison is not None and verdict is not None:
            out["comparison"] = self.comparison
            out["verdict"] = verdict.to_dict()
        out["cpu_s"] = dict(self.cpu_s)
        out["wrote"] = list(self.files)
        if self.failed:
            out["failed"] = list(self.failed)
        return out


def mill(spec: TipSpec, *, tool: EndMill | None = None, machine: MillMachine | None = None,
         params: MillParams | None = None, simulate_tip: bool = True, compare: bool = True,
         cell_um: tuple[float, float] = (20.0, 1.0),
         progress: ProgressFn | None = None) -> MillResult:
    """Mill ``spec`` tip-up: toolpaths, G-code checked as read back from its
    text against the machine and the tool (:func:`cam.mill.check.check_program`),
    and (by default) the milled tip simulated from the G-code text and
    compared with the CAD tip (then :attr:`MillResult.verdict` judges it).

    ``progress``: a callable taking a line (a library user's printer); by
    default the stages report through :mod:`tipgeo.progress`.

    Raises :class:`cam.CamError` naming the axis or parameter, value and limit.
    """
    from .simulate import compare_milled, simulate_mill

    cpu: dict[str, float] = {}
    t0 = time.process_time()
    tp = plan_toolpaths(spec, tool=tool, machine=machine, params=params, progress=progress)
    t1 = time.process_time()
    text = post_program(tp)
    moves = check_program(text, tp.machine, tp.tool)
    t2 = time.process_time()
    cpu["toolpath"], cpu["post"] = t1 - t0, t2 - t1
    res = MillResult(tp, text, cpu_s=cpu, moves=moves)
    if simulate_tip or compare:
        res.milled = simulate_mill(text, spec, tool=tp.tool, setup=tp.setup, cell_um=cell_um,
                                   progress=progress)
        t3 = time.process_time()
        cpu["simulate"] = t3 - t2
        if compare:
            progress_say(progress)("mill: comparing the milled tip with CAD")
            with pg.stage("mill: compare with CAD"):
                res.comparison = compare_milled(res.milled, spec, scallop=tp.params.scallop,
                                                stepover=tp.setup.stepover)
            cpu["compare"] = time.process_time() - t3
    return res


def setup_sheet(res: MillResult) -> str:
    """A Markdown set-up sheet: machine, tool, set-up, heights, feeds, time."""
    tp = res.toolpath
    st, prm, m, tool = tp.setup, tp.params, tp.machine, tp.tool
    s = res.summary()
    prog = s["program"]
    lines = [f"# Set-up sheet — milling {tp.name}", "", "## Machine", "",
             "| parameter | value |", "|---|---|"]
    lines += [f"| {a} | {b} |" for a, b in m.table()]
    lines += ["", "## Tool", "", f"T{tool.number} H{tool.number:02d}: {tool.describe()}", "",
              "## Set-up", "",
              "| item | value |", "|---|---|",
              "| holding | needle in an ER8 collet on the vice, axis vertical, tip up |",
              "| program zero (G54) | on the needle axis, at the heel's height (z = 0) |",
              f"| clocking | cannula γ = {math.degrees(st.clocking):.3f}° along +X "
              "(the raster direction) |",
              f"| stock | tube faced at Z{st.z_top:.3f} mm |",
              f"| safe height | Z{st.z_safe:.3f} mm (rapids between passes) |",
              f"| approach | rapid to {prm.approach:g} mm above a pass start, plunge at "
              f"{prm.plunge_feed:g} mm/min |",
              f"| lead-in/out | {prm.lead:g} mm straight, outside the wall (tool clear) |",
              f"| roughing | allowance {prm.allowance:g} mm, step-down {prm.stepdown:g} mm, "
              f"step-over {prm.rough_stepover:g} mm, {prm.rough_feed:g} mm/min |",
              f"| finishing | scallop {prm.scallop * 1e3:g} µm: step-over {st.stepover:.3f} mm "
              f"(surface/plan ratio {st.ratio:.4f}), {prm.finish_feed:g} mm/min |",
              f"| spindle | {prm.spindle_rpm:g} rpm, coolant {'on' if prm.coolant else 'off'} |",
              "", f"Program: {prog['lines']} lines, {prog['moves']} moves, feed path "
              f"{prog['feed_length_mm']:.1f} mm; cycle time {prog['cycle_time_s'] / 60:.1f} min "
              "(feeds as programmed, rapids at the machine's rapid rate; acceleration and tool "
              "change not counted).", ""]
    return "\n".join(lines)


def write_mill_outputs(res: MillResult, *, program: str | Path | None = None,
                       sheet: str | Path | None = None, mesh: str | Path | None = None,
                       deviation: str | Path | None = None,
                       toolpath: str | Path | None = None,
                       on_error: Callable[[Path, Exception], None] | None = None) -> list[str]:
    """Write the files of a :func:`mill` result, each atomically: the G-code,
    the Markdown set-up sheet, the milled tip mesh (any :mod:`tipgeo.io`
    format), the deviation map (PNG), the toolpath picture (PNG).

    Everything is made and checked before the first file is written: the
    texts, and the mesh export (:func:`tipgeo.io.check_export`: e.g. a STEP
    file without OCP). If the mesh cannot be written, ``on_error(path,
    exc)`` is called before any file is written, the other files are written
    and ``res.failed`` records it; with ``on_error`` ``None`` the error is
    raised before anything is written. A mesh or a deviation map asked of a
    result without a simulated tip is a :class:`cam.CamError`, before any
    file."""
    from tipgeo.atomic import write_text_atomic
    from tipgeo.io import guarded_export

    from ..machine import CamError
    from .simulate import plot_deviation, plot_toolpath

    milled = res.milled
    if milled is None and (mesh is not None or deviation is not None):
        raise CamError("the result has no simulated tip (mill(simulate_tip=True)); "
                       "nothing was written")
    texts = [(Path(p), t) for p, t in ((program, res.gcode),
                                       (sheet, setup_sheet(res) if sheet is not None else ""))
             if p is not None]
    if milled is not None and mesh is not None and not guarded_export(
            milled.tip, mesh, failed=res.failed, on_error=on_error, dry_run=True):
        mesh = None
    wrote = []
    for path, text in texts:
        write_text_atomic(path, text)
        wrote.append(str(path))
    if milled is not None and mesh is not None and guarded_export(
            milled.tip, mesh, failed=res.failed, on_error=on_error):
        wrote.append(str(mesh))
    if milled is not None and deviation is not None:
        plot_deviation(milled, deviation, title=_deviation_title(res))
        wrote.append(str(deviation))
    if toolpath is not None:
        plot_toolpath(res.toolpath, toolpath)
        wrote.append(str(toolpath))
    res.files += wrote
    return wrote


def _deviation_title(res: MillResult) -> str:
    """The deviation map's title: the tip, and the scallop and gouge measured."""
    c = res.comparison or {}
    title = f"{res.toolpath.name}: milled − CAD (µm, normal)"
    if c:
        title += (f"\nscallop {c['scallop_measured_um']:.2f} µm (target "
                  f"{c['scallop_target_um']:g}), gouge {c['gouge_um']:.2f} µm")
    return title
