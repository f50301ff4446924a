"""The milling pipeline as one call: toolpaths → G-code → (optional) the
material-removal simulation read back from the G-code → comparison with the
CAD tip; and the files a user asks for. Used by ``tipgeo mill`` and the demo.

Frames and units: :mod:`cam.mill.machine` (mm, rad inside; µm, degrees,
mm/min and seconds in reports).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tipgeo import progress as pg
from tipgeo.tolerances import tol

from .machine import EndMill, MillMachine
from .post import post_program
from .toolpath import MillParams, MillToolpath, plan_toolpaths, progress_say

__all__ = ["MillResult", "mill", "write_mill_outputs", "setup_sheet"]


@dataclass
class MillResult:
    """What :func:`mill` made: the toolpath, its G-code, the simulated milled
    tip (:class:`cam.mill.simulate.MilledTip`), its comparison with CAD and
    the :attr:`verdict` on it."""

    toolpath: MillToolpath
    gcode: str
    milled: Any = None
    comparison: dict | None = None
    cpu_s: dict = field(default_factory=dict)
    files: list[str] = field(default_factory=list)

    @property
    def verdict(self):
        """:class:`tipgeo.verdict.Verdict` of the comparison with CAD against
        the toolpath's own scallop target (:meth:`judge`); None when the run
        was not compared."""
        return self.judge()

    def judge(self, scallop_um: float | None = None):
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

        moves = self.milled.moves if self.milled is not None else read_gcode(self.gcode)
        out: dict[str, Any] = {"toolpath": self.toolpath.summary(),
                               "program": moves.summary(self.toolpath.machine.rapid)}
        if self.comparison is not None:
            out["comparison"] = self.comparison
            out["verdict"] = self.verdict.to_dict()
        out["cpu_s"] = dict(self.cpu_s)
        out["wrote"] = list(self.files)
        return out


def mill(spec, *, tool: EndMill | None = None, machine: MillMachine | None = None,
         params: MillParams | None = None, simulate_tip: bool = True, compare: bool = True,
         cell_um: tuple[float, float] = (20.0, 1.0), progress=None) -> MillResult:
    """Mill ``spec`` tip-up: toolpaths, G-code, and (by default) the milled
    tip simulated from the G-code text and compared with the CAD tip (then
    :attr:`MillResult.verdict` judges it).

    ``progress``: a callable taking a line (a library user's printer); by
    default the stages report through :mod:`tipgeo.progress`.

    Raises :class:`cam.CamError` naming the axis or parameter, value and limit.
    """
    from .simulate import compare_milled, simulate_mill

    cpu = {}
    t0 = time.process_time()
    tp = plan_toolpaths(spec, tool=tool, machine=machine, params=params, progress=progress)
    t1 = time.process_time()
    text = post_program(tp)
    t2 = time.process_time()
    cpu["toolpath"], cpu["post"] = t1 - t0, t2 - t1
    res = MillResult(tp, text, cpu_s=cpu)
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
                       toolpath: str | Path | None = None) -> list[str]:
    """Write the files of a :func:`mill` result, each atomically: the G-code,
    the Markdown set-up sheet, the milled tip mesh (any :mod:`tipgeo.io`
    format), the deviation map (PNG), the toolpath picture (PNG)."""
    from tipgeo.atomic import write_text_atomic
    from tipgeo.io import export_tip

    from .simulate import plot_deviation, plot_toolpath

    wrote = []
    if program is not None:
        write_text_atomic(Path(program), res.gcode)
        wrote.append(str(program))
    if sheet is not None:
        write_text_atomic(Path(sheet), setup_sheet(res))
        wrote.append(str(sheet))
    if mesh is not None or deviation is not None:
        if res.milled is None:
            raise ValueError("the result has no simulated tip (mill(simulate_tip=True))")
    if mesh is not None:
        export_tip(res.milled.tip, mesh)
        wrote.append(str(mesh))
    if deviation is not None:
        c = res.comparison or {}
        title = f"{res.toolpath.name}: milled − CAD (µm, normal)"
        if c:
            title += (f"\nscallop {c['scallop_measured_um']:.2f} µm (target "
                      f"{c['scallop_target_um']:g}), gouge {c['gouge_um']:.2f} µm")
        plot_deviation(res.milled, deviation, title=title)
        wrote.append(str(deviation))
    if toolpath is not None:
        plot_toolpath(res.toolpath, toolpath)
        wrote.append(str(toolpath))
    res.files += wrote
    return wrote
