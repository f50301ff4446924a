"""The laser pipeline as one call: a program is parsed and interpreted
(length, time, pulses), and — given the punch it cuts — simulated back into a
tip by ablation and compared with the spec's serrations.

Machine frame and units as in :mod:`gcode.ablation` (mm, degrees in programs;
the simulated tip in the cannula frame). Used by ``tipgeo gcode`` and
``tipgeo demo``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import ast
from .errors import GCodeError
from .interpreter import Limits, Toolpath, interpret
from .parser import parse

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec
    from tipgeo.verdict import Verdict

    from .ablation import AblationResult, Comparison

__all__ = ["LaserCheck", "laser_check", "make_limits", "read_program", "write_laser_outputs"]


#: Largest program file read (bytes): a tip's laser program is a few kB to a few MB.
MAX_PROGRAM_BYTES = 16 << 20


def read_program(path: str | Path) -> str:
    """The UTF-8 text of a program file. A missing or unreadable file, one
    over :data:`MAX_PROGRAM_BYTES`, or one that is not a regular file (a
    FIFO, a device: a read could block or never end; checked before a byte
    is read) is a one-line GCodeError."""
    from tipgeo.errors import SpecError
    from tipgeo.tomlio import read_text_file

    try:
        return read_text_file(path, "program", max_bytes=MAX_PROGRAM_BYTES)
    except SpecError as e:
        raise GCodeError(str(e)) from None


@dataclass
class LaserCheck:
    """What :func:`laser_check` found.

    Attributes
    ----------
    program : gcode.ast.Program
    toolpath : Toolpath — the interpreted moves (beam radius compensated)
    ablation : AblationResult or None — the simulated tip (cannula frame)
    comparison : dict or None — :func:`gcode.ablation.compare_with_cutter`
    verdict : Verdict or None — the comparison judged (property; None
        without a spec with serrations)
    files : list of str — files written by :func:`write_laser_outputs`
    failed : list of dict — files it could not write: ``path``, ``error``
    """

    program: ast.Program
    toolpath: Toolpath
    ablation: AblationResult | None = None
    comparison: Comparison | None = None
    files: list[str] = field(default_factory=list)
    failed: list[dict[str, str]] = field(default_factory=list)

    @property
    def verdict(self) -> Verdict | None:
        """:class:`tipgeo.verdict.Verdict` of the simulated part against the
        serration spec; None when nothing was compared (no spec, or a spec
        without serrations).

        Rules (b = ``tol.gcode.laser_band``, 1 µm; t = the meshes' chordal
        tolerance, which every vertex-sampled distance includes):

        - ``notches``: the program cuts as many notches as the spec has;
        - ``material_left_um`` ≤ b + t: the part stands nowhere outside CAD;
        - ``overcut_um`` ≤ b + t: nor is it cut away anywhere inside it;
        - ``hausdorff_um`` ≤ b + t: the larger of the two, unsigned;
        - ``radius_error_um`` ≤ b + t: each notch's fitted radius;
        - ``spacing_error_deg`` ≤ b / r_i in degrees: the notches' centres,
          b along the inner rim (only with two notches or more).
        """
        c = self.comparison
        if c is None:
            return None
        import math

        from tipgeo.tolerances import tol
        from tipgeo.verdict import Verdict, check_max, check_true

        b = tol.gcode.laser_band
        lim = round((b + c["tolerance_mm"]) * 1e3, 6)
        n_sim, n_cad = c["notches_sim"], c["notches_cad"]
        checks = [check_true("notches", n_sim == n_cad, f"notches = {n_cad} (the spec's)",
                             f"the program cuts {n_sim} notches; the spec has {n_cad}"),
                  check_max("material_left_um", c["material_left_mm"] * 1e3, lim,
                            what="material left outside CAD (µm)"),
                  check_max("overcut_um", c["overcut_mm"] * 1e3, lim,
                            what="cut beyond CAD (µm)"),
                  check_max("hausdorff_um", c["hausdorff_mm"] * 1e3, lim,
                            what="Hausdorff distance vs CAD (µm)")]
        err = c["radius_mm"]["fitted_max_error"]
        checks.append(check_max("radius_error_um", None if err is None else err * 1e3, lim,
                                what="notch radius error (µm)"))
        if n_cad > 1:
            checks.append(check_max("spacing_error_deg", c["spacing_deg"]["fitted_max_error"],
                                    round(math.degrees(b / c["inner_radius_mm"]), 6),
                                    what="notch spacing error (°)"))
        return Verdict.of("laser-cut serrations vs spec", checks)

    def summary(self, *, source: str = "") -> dict[str, Any]:
        """The report (mm, s, degrees): toolpath, every warning, the
        statements that moved nothing (with what they did and how often),
        the last values written to outputs and system variables, ablation,
        comparison."""
        out: dict[str, Any] = {"program": source, "statements": len(self.program.body),
                               "subroutines": [s.name for s in self.program.subroutines],
                               "toolpath": self.toolpath.summary(),
                               "warnings": list(self.toolpath.warnings),
                               "warnings_total": len(self.toolpath.warnings),
                               "no_motion": list(self.toolpath.no_motion),
                               "io": dict(self.toolpath.io)}
        if self.ablation is not None:
            res = self.ablation
            out["ablation"] = {"notches": res.notches, "c_angles_deg": res.c_angles_deg,
                               "slugs_removed": res.slugs_removed,
                               "triangles": int(len(res.tip.faces)),
                               "watertight": res.tip.is_watertight}
        verdict = self.verdict
        if self.comparison is not None and verdict is not None:
            out["comparison"] = self.comparison
            out["verdict"] = verdict.to_dict()
        if self.files:
            out["pictures"] = [f for f in self.files if f.lower().endswith(".png")]
        out["wrote"] = list(self.files)
        if self.failed:
            out["failed"] = list(self.failed)
        return out


def make_limits(**bounds: int | None) -> Limits:
    """:class:`Limits` from keyword bounds (None keeps the default); a bound
    that is not a whole number ≥ 0 is a GCodeError naming it."""
    kw = {k: v for k, v in bounds.items() if v is not None}
    try:
        return Limits(**kw)
    except (TypeError, ValueError) as e:
        raise GCodeError(f"interpreter limit: {e}") from None


def laser_check(program: str | ast.Program, *, beam_diameter: float = 0.020,
                spec: TipSpec | None = None,
                origin: tuple[float, float] = (0.0, 0.0), tolerance: float | None = None,
                lenient: bool = False, limits: Limits | None = None,
                max_tokens: int | None = None,
                default_feed: float | None = None) -> LaserCheck:
    """Parse and interpret a laser program, and — with ``spec``, the punch it
    cuts — simulate it by ablation and compare it with the spec's serrations.

    Parameters
    ----------
    program : str or gcode.ast.Program — AeroBasic text, or a parsed program
    beam_diameter : float — mm; tool T1's radius is half of it (G41/G42)
    spec : TipSpec, optional — the punch to cut (then the ablation runs)
    origin : (X0, Y0) — program coordinates of the first serration's centre
        on the rim (mm)
    tolerance : float, optional — chordal tolerance of the simulated tip (mm)
    lenient : bool — skip unsupported statements with a warning
    limits : Limits, optional — interpreter bounds (statements executed, REPEAT
        count, moves, operations; :func:`make_limits`)
    max_tokens : int, optional — the parser's token bound (default
        :data:`gcode.parser.DEFAULT_MAX_TOKENS`)
    default_feed : float, optional — mm/s for a feed move before any F (with
        a warning; see :func:`gcode.interpreter.interpret`)

    Raises
    ------
    GCodeError — a program error, quoting its line and column.
    """
    if isinstance(program, str):
        try:
            prog = (parse(program, lenient=lenient) if max_tokens is None else
                    parse(program, lenient=lenient, max_tokens=max_tokens))
        except (TypeError, ValueError) as e:
            if isinstance(e, GCodeError):
                raise
            raise GCodeError(f"parser limit: {e}") from None
    else:
        prog = program
    tp = interpret(prog, tool_radii={0: 0.0, 1: beam_diameter / 2},
                   limits=Limits() if limits is None else limits, default_feed=default_feed)
    res = LaserCheck(prog, tp)
    if spec is not None:
        from tipgeo import progress as pg

        from .ablation import ablate, compare_with_cutter

        x0, y0 = origin
        ablation = ablate(tp, spec, beam_diameter=beam_diameter, origin=(x0, y0),
                          tolerance=tolerance)
        res.ablation = ablation
        if any(c.process == "laser" for c in spec.cutters):
            with pg.stage("laser: compare with the spec"):
                res.comparison = compare_with_cutter(ablation, spec,
                                                     beam_diameter=beam_diameter)
    return res


def write_laser_outputs(res: LaserCheck, spec: TipSpec | None = None, *,
                        mesh: str | Path | None = None, plot: str | Path | None = None,
                        rim: str | Path | None = None,
                        on_error: Callable[[Path, Exception], None] | None = None,
                        ) -> list[str]:
    """Write the simulated tip (any :mod:`tipgeo.io` format) and the toolpath
    picture, and with ``spec`` and a simulation the unwrapped rim picture
    (``rim``, default ``<plot>-rim.png``), each atomically.

    The mesh export is checked first (:func:`tipgeo.io.check_export`: e.g. a
    STEP file without OCP). If it cannot be written, ``on_error(path, exc)``
    is called before any file is written, the pictures are still written and
    ``res.failed`` records it; with ``on_error`` ``None`` the error is raised
    before anything is written.
    """
    from tipgeo.io import guarded_export

    ablation = res.ablation
    if mesh is not None:
        if ablation is None:
            raise GCodeError("mesh: nothing was simulated (give the punch's spec)")
        if not guarded_export(ablation.tip, mesh, failed=res.failed, on_error=on_error,
                              dry_run=True):
            mesh = None
    wrote: list[str] = []
    if plot is not None:
        from .plots import plot_toolpath

        plot_toolpath(res.toolpath, plot)
        wrote.append(str(plot))
        if rim is None:
            rim = Path(plot).with_name(Path(plot).stem + "-rim.png")
    if rim is not None and ablation is not None and spec is not None:
        from .plots import plot_rim

        plot_rim(ablation.tip, spec, rim)
        wrote.append(str(rim))
    if mesh is not None and ablation is not None and guarded_export(
            ablation.tip, mesh, failed=res.failed, on_error=on_error):
        wrote.append(str(mesh))
    res.files += wrote
    return wrote
