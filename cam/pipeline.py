"""The grinding pipeline as one call: program → (optional) simulation →
comparison with the CAD tip, and the files a user asks for.

Frames and units as in :mod:`cam.machine` (cannula frame; mm, rad inside,
degrees in programs and reports). Used by ``tipgeo grind`` and ``tipgeo demo``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .machine import Machine
from .program import GrindProgram, make_program
from .simulate import compare_with_cad, simulate

if TYPE_CHECKING:
    from tipgeo.spec import TipSpec
    from tipgeo.tip import Tip
    from tipgeo.verdict import Verdict

__all__ = ["GrindResult", "grind", "write_grind_outputs"]


@dataclass
class GrindResult:
    """What :func:`grind` made.

    Attributes
    ----------
    program : GrindProgram — the axis program with its set-up
    ground : Tip or None — the simulated ground tip (mm, cannula frame)
    comparison : dict or None — :func:`cam.compare_with_cad` of the ground tip
    verdict : Verdict or None — the comparison judged (property; None when
        not compared)
    files : list of str — files written by :func:`write_grind_outputs`
    failed : list of dict — files it could not write: ``path``, ``error``
    """

    program: GrindProgram
    ground: Tip | None = None
    comparison: dict[str, Any] | None = None
    files: list[str] = field(default_factory=list)
    failed: list[dict[str, str]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """Program summary, comparison (if any) and files written (report units)."""
        out: dict[str, Any] = {"program": self.program.summary()}
        verdict = self.verdict
        if self.comparison is not None and verdict is not None:
            out["comparison"] = self.comparison
            out["verdict"] = verdict.to_dict()
        out["wrote"] = list(self.files)
        if self.failed:
            out["failed"] = list(self.failed)
        return out

    @property
    def verdict(self) -> Verdict | None:
        """:class:`tipgeo.verdict.Verdict` of the ground tip against CAD;
        None when the run was not compared.

        Rules:

        - ``hausdorff_um`` ≤ the coarsest linear axis resolution (t1, t2:
          0.1 µm on the thesis's grinder) plus the chordal tolerance of the
          two meshes: a program whose axis values are right to their
          resolution leaves faces within one resolution step of CAD, and two
          tessellations of the same faces differ by at most their tolerance;
        - λ, θ, α of both edges from the ground faces analysed exactly
          (``angles_max_diff_deg``) within the coarsest rotary axis
          resolution (r3, r4, r5: 0.001°). The mesh path's differences are
          reported, not judged: they hold its own method error (0.13° on the
          lancet).
        """
        c = self.comparison
        if c is None:
            return None
        from tipgeo.verdict import Verdict, check_max

        m = self.program.machine
        tess = float(getattr(self.ground, "tolerance", None) or 0.0)
        band = (max(m.t1.resolution, m.t2.resolution) + tess) * 1e3
        turn = max(m.r3.resolution, m.r4.resolution, m.r5.resolution)
        checks = [check_max("hausdorff_um", c["hausdorff_mm"] * 1e3, round(band, 6),
                            what="Hausdorff distance ground vs CAD (µm)")]
        for wall in ("outer", "inner"):
            for k, sym in (("lambda", "λ"), ("theta", "θ"), ("alpha", "α")):
                checks.append(check_max(f"{wall}_{k}_diff_deg",
                                        c["angles_max_diff_deg"][wall][k], turn,
                                        what=f"{wall} edge {sym} − CAD (°)"))
        return Verdict.of(f"ground {self.program.name} vs CAD", checks)

    def worst_angle_diff_deg(self) -> tuple[float, float] | None:
        """Largest λ/θ/α difference ground vs CAD (deg): exact surfaces, mesh path."""
        c = self.comparison
        if c is None:
            return None
        worst = max(v for w in c["angles_max_diff_deg"].values() for v in w.values())
        worst_m = max(v for w in c["mesh_angles_max_diff_deg"].values() for v in w.values())
        return worst, worst_m


def grind(spec: TipSpec, *, machine: Machine | None = None, feed: float = 0.1,
          needle_rpm: float = 1000.0, simulate_tip: bool = True, compare: bool = True,
          tolerance: float | None = None) -> GrindResult:
    """Grind ``spec`` on ``machine``: the program, then (by default) the
    simulated ground tip and its comparison with the CAD tip.

    Parameters
    ----------
    spec : TipSpec — cutters made by grinding (bevel, multi-plane, lancet, conical)
    machine : Machine, optional — limits and set-up (default :class:`Machine`)
    feed : float — infeed (mm/s)
    needle_rpm : float — needle spin for conical faces (rpm)
    simulate_tip, compare : bool — run the simulator / the comparison
    tolerance : float, optional — chordal tolerance of the simulated tip (mm)

    Raises
    ------
    CamError — the machine cannot make the tip (naming the axis or limit).
    """
    from tipgeo import progress as pg

    prog = make_program(spec, machine=machine or Machine(), feed=feed, needle_rpm=needle_rpm)
    res = GrindResult(prog)
    if simulate_tip or compare:
        with pg.stage("grind: simulate"):
            res.ground = simulate(prog, spec, tolerance=tolerance)
        if compare:
            with pg.stage("grind: compare with CAD"):
                res.comparison = compare_with_cad(res.ground, spec)
    return res


def write_grind_outputs(res: GrindResult, *, program: str | Path | None = None,
                        gcode: str | Path | None = None, sheet: str | Path | None = None,
                        mesh: str | Path | None = None,
                        on_error: Callable[[Path, Exception], None] | None = None) -> list[str]:
    """Write the files of a :func:`grind` result, each atomically: the axis
    program (``.json`` or ``.csv`` by extension), ISO G-code, the Markdown
    set-up sheet, the simulated tip mesh (any :mod:`tipgeo.io` format).

    Every text is made (the G-code by its dialect's rules: a
    :class:`CamError` there) and the mesh export checked
    (:func:`tipgeo.io.check_export`: e.g. a STEP file without OCP) before the
    first file is written. If the mesh cannot be written, ``on_error(path,
    exc)`` is called before any file is written and the other files are
    written (``res.failed`` records it); with ``on_error`` ``None`` the error
    is raised before anything is written.
    """
    from tipgeo.atomic import write_text_atomic
    from tipgeo.io import guarded_export

    ground = res.ground
    if mesh is not None and ground is None:
        raise ValueError("mesh: the result has no simulated tip (grind(simulate_tip=True))")
    texts = []
    if program is not None:
        p = Path(program)
        texts.append((p, res.program.to_csv() if p.suffix.lower() == ".csv"
                      else res.program.to_json()))
    if gcode is not None:
        texts.append((Path(gcode), res.program.to_gcode()))
    if sheet is not None:
        texts.append((Path(sheet), res.program.setup_sheet()))
    if ground is not None and mesh is not None and not guarded_export(
            ground, mesh, failed=res.failed, on_error=on_error, dry_run=True):
        mesh = None
    wrote = []
    for path, text in texts:
        write_text_atomic(path, text)
        wrote.append(str(path))
    if ground is not None and mesh is not None and guarded_export(
            ground, mesh, failed=res.failed, on_error=on_error):
        wrote.append(str(mesh))
    res.files += wrote
    return wrote
