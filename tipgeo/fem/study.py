"""Whole finite-element studies: build the model of a tip, write its decks,
run ccx, read and check the force curve and stresses, write CSV/JSON/PNG;
the mesh-convergence study; the comparison with the analytical insertion
force of :mod:`tipgeo.mechanics.insertion` (eq. 4.18–4.22).

Units at this level: depths in mm, forces in N (the whole needle, positive
when it pushes), stresses in MPa inside and kPa in pictures, element sizes in
mm inside and µm in file names and reports. Frame: the model frame of
:mod:`tipgeo.fem.model`.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import re
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress as pg
from .. import validate as v
from ..arrays import ArrayLike, FloatArray, IntArray
from ..atomic import staging_dir, write_bytes_atomic, write_text_atomic
from ..errors import FemError, SpecError
from ..jsonio import dumps
from ..paths import inside
from ..tip import Tip
from ..tolerances import tol
from .model import FemModel
from .results import FrdResults, max_principal, read_dat_totals, read_frd
from .run import CcxRun, require_ccx, run_ccx

if TYPE_CHECKING:
    from ..spec import TipSpec
    from ..verdict import Verdict
    from .meshconv import Companion

__all__ = ["MODEL_KINDS", "FemResult", "build_model", "run_model", "run_fem",
           "convergence_study", "convergence_verdict", "richardson", "analytical_force",
           "is_monotonic"]

#: Model kinds of :func:`build_model`.
MODEL_KINDS = ("axisymmetric", "3d")


def build_model(tip: Tip | TipSpec, kind: str, *, depth: float, tissue: str = "pvc-sp0",
                mesh: float | None = None, friction: float | None = None,
                material_model: str = "arruda-boyce", nu: float | None = None,
                output_depths: tuple[float, ...] = (), **kw: Any) -> FemModel:
    """The ``axisymmetric`` or ``3d`` model of ``tip`` (a Tip or a spec)."""
    from ..build import build_tip

    if kind not in MODEL_KINDS:
        raise SpecError(f"model = {kind!r} is not valid; expected one of: "
                        + ", ".join(MODEL_KINDS))
    if not isinstance(tip, Tip):
        tip = build_tip(tip)
    if kind == "axisymmetric":
        from .axisym import axisymmetric_model

        return axisymmetric_model(tip, depth=depth, tissue=tissue, material_model=material_model,
                                  nu=0.475 if nu is None else nu, friction=friction,
                                  mesh=0.025 if mesh is None else mesh,
                                  output_depths=output_depths, **kw)
    if kw.get("cut", "none") != "none":
        raise SpecError(f"cut = {kw['cut']!r} is for the axisymmetric model only; the 3d "
                        "model has no cut")
    kw.pop("cut", None)
    from .solid import indentation_model

    return indentation_model(tip, depth=depth, tissue=tissue, material_model=material_model,
                             nu=0.475 if nu is None else nu, friction=friction,
                             mesh=0.1 if mesh is None else mesh, output_depths=output_depths,
                             **kw)


def is_monotonic(force: ArrayLike) -> bool:
    """Whether ``force`` never falls below an earlier value by more than
    ``tol.fem.monotone`` of its peak."""
    f = np.asarray(force, dtype=float)
    if len(f) < 2:
        return True
    slack = tol.fem.monotone * max(float(np.max(np.abs(f))), tol.tiny)
    return bool(np.all(f >= np.maximum.accumulate(f) - slack))


def analytical_force(model: FemModel, depth: ArrayLike, *, beta: float | None = None,
                     d_i: float | None = None) -> FloatArray:
    """The analytical axial force (eq. 4.18–4.22, N) for the model's tissue
    law at ``depth`` (mm): column of radius β d_i / 2, initial length the
    block height."""
    from ..mechanics.insertion import DEFAULT_BETA, insertion_force

    d_i = float(model.info["inner_diameter_mm"]) if d_i is None else d_i
    H = float(model.info["block_mm"][-1])
    return 0.0 + insertion_force(model.material.law, np.asarray(depth, dtype=float), d_i=d_i,
                                 l_init=H, beta=DEFAULT_BETA if beta is None else beta)


@dataclass
class FemResult:
    """A checked run: the force curve and where everything went.

    Attributes
    ----------
    model : FemModel
    depth : (k,) float — needle depth, mm (starts at 0)
    force : (k,) float — whole-needle axial force, N (push positive)
    run : CcxRun or None (decks only)
    files : list of Path written
    stress : dict depth (mm) → (max principal at the peak node (MPa), its
        position (2 or 3,) mm deformed, the edge's tensile peak (MPa))

    Notes
    -----
    A run ccx stopped before the requested depth (an increment below its
    minimum, too many cutbacks) is kept when :func:`run_model` is asked to
    (its default): ``depth`` ends where the last output was written,
    :attr:`reached_depth` is where the last increment converged, and
    :attr:`verdict` fails naming both.
    """

    model: FemModel
    depth: FloatArray = field(default_factory=lambda: np.zeros(0))
    force: FloatArray = field(default_factory=lambda: np.zeros(0))
    run: CcxRun | None = None
    files: list[Path] = field(default_factory=list)
    stress: dict[float, dict[str, Any]] = field(default_factory=dict)
    #: the discretisation error at every depth (:func:`tipgeo.fem.meshconv.mesh_error_table`),
    #: None for a run without companion meshes
    convergence: dict[str, Any] | None = None

    @property
    def monotonic(self) -> bool:
        return is_monotonic(self.force)

    @property
    def requested_depth(self) -> float:
        """The depth asked for (mm)."""
        return float(self.model.depth)

    @property
    def reached_depth(self) -> float | None:
        """Where the last converged increment left the needle (mm; None
        without a run)."""
        return None if self.run is None else float(self.run.reached * self.model.depth)

    @property
    def verdict(self) -> Verdict | None:
        """:class:`tipgeo.verdict.Verdict`: the run reached the requested depth
        (to ``tol.fem.step_end`` of the step) and, with companion meshes, its
        force at the final depth is within ``tol.fem.convergence_change`` of
        the mesh limit (:func:`tipgeo.fem.meshconv.mesh_check`); None for
        decks only (nothing was run, nothing judged)."""
        if self.run is None:
            return None
        from ..verdict import Check, Verdict

        req, got = self.requested_depth, self.reached_depth
        ok = self.run.complete
        why = "" if ok else (f"the run stopped at depth {got:.4g} mm of the requested {req:g} mm"
                             + (f" (ccx: {self.run.stopped})" if self.run.stopped else ""))
        checks = [Check("depth_mm", ok, got, f"depth_mm ≥ {req:g} (the requested depth)", why)]
        if self.convergence is not None:
            from .meshconv import mesh_check

            checks.append(mesh_check(self.convergence))
        return Verdict.of(f"FEM {self.model.kind} {self.model.name} to {req:g} mm", checks)

    @property
    def peak_force(self) -> float:
        return float(np.max(self.force)) if len(self.force) else math.nan

    def to_dict(self) -> dict[str, Any]:
        m = self.model
        d = {"model": m.kind, "name": m.name, "depth_mm": m.depth,
             "element_size_um": m.info.get("element_size_um"), "info": m.public_info(),
             "force_scale": m.force_scale, "files": [str(p) for p in self.files]}
        if self.run is not None:
            ana = analytical_force(m, self.depth)
            d.update({"wall_s": round(self.run.wall_s, 3), "cpu_s": round(self.run.cpu_s, 3),
                      "reached_depth_mm": self.reached_depth, "stopped": self.run.stopped,
                      "increments": self.run.increments, "cutbacks": self.run.cutbacks,
                      "warnings": self.run.warnings[:20], "monotonic": self.monotonic,
                      "peak_force_N": self.peak_force,
                      "curve": self._curve_rows(ana),
                      "eq_4_22_at_end": ({"depth_mm": float(self.depth[-1]),
                                          "force_N": float(self.force[-1]),
                                          "eq_4_22_N": float(ana[-1]),
                                          "gap_percent": 100.0 * (float(self.force[-1])
                                                                  / float(ana[-1]) - 1.0),
                                          "mesh_error_percent": self._end_error()}
                                         if len(self.depth) > 1 and ana[-1] > 0 else None),
                      "mesh_convergence": self.convergence,
                      "stress": {f"{k:g}": s for k, s in self.stress.items()},
                      "verdict": None if self.verdict is None else self.verdict.to_dict()})
        return d

    def _curve_rows(self, ana: FloatArray) -> list[dict[str, Any]]:
        """The curve as rows (mm, N), each with its mesh error (percent, None
        where there is none) when the run has companion meshes."""
        err = {} if self.convergence is None else {
            round(r["depth_mm"], 12): r for r in self.convergence["rows"]}
        rows = []
        for a, b, c in zip(self.depth, self.force, ana):
            row: dict[str, Any] = {"depth_mm": float(a), "force_N": float(b),
                                   "analytical_N": float(c)}
            if self.convergence is not None:
                e = err.get(round(float(a), 12))
                row.update(mesh_error_percent=None if e is None else e["error_percent"],
                           mesh_status=None if e is None else e["status"])
            rows.append(row)
        return rows

    def _end_error(self) -> float | None:
        """The mesh error (percent) of the force at the final depth; None
        without companion meshes or an estimate there."""
        end = None if self.convergence is None else self.convergence["at_end"]
        return None if end is None else end["error_percent"]

    def summary(self) -> dict[str, Any]:
        """The same as :meth:`to_dict` (the name every make-stage result has)."""
        return self.to_dict()


def _curve_csv(depth: FloatArray, force: FloatArray, ana: FloatArray) -> str:
    s = io.StringIO()
    w = csv.writer(s, lineterminator="\n")
    w.writerow(["depth_mm", "force_N", "analytical_force_N"])
    for a, b, c in zip(depth, force, ana):
        w.writerow([f"{a:.6f}", f"{b:.9g}", f"{c:.9g}"])
    return s.getvalue()


def _tissue_tris(model: FemModel) -> IntArray:
    tris: list[IntArray] = []
    for b in model.blocks:
        if b.part != "tissue":
            continue
        if b.etype == "CAX3":
            tris.append(b.conn)
        elif b.etype == "CAX4":
            tris += [b.conn[:, [0, 1, 2]], b.conn[:, [0, 2, 3]]]
    return np.vstack(tris) - 1


def folded_elements(model: FemModel, X: FloatArray) -> int:
    """Tissue elements of a 2D model folded in the deformed positions ``X``
    ((nodes, ≥ 2) mm, model frame): a corner whose signed area (the cross
    product of its two edges) has turned against its sign in the reference
    mesh, or is zero. Stresses in a folded element are not to be read
    (ccx goes on while its integration points stay positive). 3D models: 0
    (not checked)."""
    if model.dim != 2:
        return 0
    folded = 0
    for b in model.blocks:
        if b.part != "tissue" or b.etype not in ("CAX3", "CAX4"):
            continue
        c = b.conn - 1
        k = c.shape[1]

        def corners(P: FloatArray, c: IntArray = c, k: int = k) -> FloatArray:
            a = P[c][:, :, :2]
            e1 = np.roll(a, -1, axis=1) - a
            e0 = a - np.roll(a, 1, axis=1)
            out: FloatArray = e0[:, :, 0] * e1[:, :, 1] - e0[:, :, 1] * e1[:, :, 0]
            return out.reshape(-1, k)

        ref = np.sign(corners(model.nodes))
        now = corners(X)
        folded += int(np.count_nonzero(np.any(now * ref <= 0.0, axis=1)))
    return folded


def _stress_pictures(model: FemModel, frd: FrdResults, out: Path, stem: str,
                     reached: float = math.inf
                     ) -> tuple[list[Path], dict[float, dict[str, Any]]]:
    """Max principal stress contours (2D: the r–Y plane; 3D: the symmetry
    plane X = 0) at each output depth the run reached (mm), and the stress
    summary."""
    files: list[Path] = []
    summary: dict[float, dict[str, Any]] = {}
    pos = np.full(int(frd.node_ids.max()) + 1, -1)
    pos[frd.node_ids] = np.arange(len(frd.node_ids))
    from .plots import plot_stress_contour

    tissue = model.part_nodes("tissue")
    for d in model.output_depths:
        if d > reached + tol.fem.depth_reached:  # the run stopped before it
            continue
        t = d / model.depth
        nid, u = frd.field_at("DISP", t)
        sid, s = frd.field_at("STRESS", t)
        X = model.nodes.copy()
        X[nid - 1] += u[:, :model.dim]
        s1 = np.full(len(model.nodes), np.nan)
        s1[sid - 1] = max_principal(s[:, :6])
        ts = s1[tissue - 1]
        k = int(np.nanargmax(ts))
        edge = np.asarray(model.info["edge_r_mm"], dtype=float)
        near = tissue[np.linalg.norm(X[tissue - 1][:, [0, 1]] - np.array(
            [edge.mean(), -d]), axis=1) <= 4 * float(model.info["element_size_um"]) * 1e-3 + 0.05]
        summary[d] = {"max_principal_MPa": float(ts[k]),
                      "at_mm": [float(x) for x in X[tissue[k] - 1]],
                      "max_principal_near_edge_MPa": float(np.nanmax(s1[near - 1]))
                      if len(near) and model.dim == 2 else math.nan,
                      "folded_elements": folded_elements(model, X)}
        if model.dim == 2:
            tris = _tissue_tris(model)
            needle = model.info.get("_needle_section")
            ndl = None if needle is None else np.asarray(needle) + np.array([0.0, -d])
            r0 = float(edge.mean())
            win = (max(0.0, r0 - 0.8), r0 + 0.8, -d - 1.0, -d + 0.6)
            xy, vals = X[:, :2], np.nan_to_num(s1)
        else:
            tri3, plane = model.info.get("_symmetry_tris"), model.info.get("symmetry_plane")
            if not tri3:
                continue
            tris = np.asarray(tri3) - 1
            xy = X[:, [0, 1]] if plane == "Z" else X[:, [2, 1]]
            vals = np.nan_to_num(s1)
            ndl = None
            r0 = float(edge.mean())
            win = (max(-r0 - 0.8, float(np.min(xy[:, 0]))), r0 + 0.8, -d - 1.0, -d + 0.6)
        files.append(plot_stress_contour(
            xy, tris, vals, inside(out, stem, f"_s1_{d:g}mm.png"), needle=ndl, window=win,
            title=f"{model.name}: max principal stress at depth {d:g} mm "
                  f"({model.info['element_size_um']:g} µm elements)",
            xlabel="r (mm)" if model.dim == 2 else
            f"{'X' if model.info.get('symmetry_plane') == 'Z' else 'Z'} (mm, on the symmetry "
            f"plane {model.info.get('symmetry_plane')} = 0)"))
    return files, summary


def run_model(model: FemModel, out_dir: str | Path, *, stem: str | None = None,
              deck_only: bool = False, abaqus: bool = False, time_limit_s: float = 600.0,
              threads: int = 1, progress: Callable[[str], None] | None = None,
              pictures: bool = True, partial: bool = True,
              companions: list[Companion] | None = None) -> FemResult:
    """Write ``model``'s decks to ``out_dir`` and (unless ``deck_only``) run
    ccx, check it, and write the curve (CSV, JSON, PNG) and the stress
    contours at ``model.output_depths``.

    Files: ``STEM.inp`` (CalculiX), ``STEM_abaqus.inp`` (with ``abaqus``),
    ``STEM.dat``, ``STEM.frd``, ``STEM.log`` (ccx's), ``STEM_force.csv``,
    ``STEM.json``, ``STEM_force.png``, ``STEM_s1_<d>mm.png``. ccx runs in a
    temporary folder outside ``out_dir`` (the system's, removed afterwards,
    whatever happens); the decks and results reach ``out_dir`` only once the
    run has been checked, each written atomically. A failed run leaves
    nothing in ``out_dir`` (a folder this call created is removed again) and
    raises :class:`~tipgeo.errors.FemError` quoting ccx's own line.

    With ``partial`` (the default) a run that stopped converging before the
    requested depth is kept and written up to where it stopped, with a
    failing :attr:`FemResult.verdict`; without it, it is a FemError.
    ``progress`` (a callable taking a line) gets the run's lines; without one
    they go to :mod:`tipgeo.progress` (a stage with the increment and depth
    from ccx's ``.sta``). ``companions`` (coarser runs of the same model,
    coarse first) give the result's discretisation error
    (:func:`tipgeo.fem.meshconv.mesh_error_table`), their curves drawn
    beside its own.
    """
    out = Path(out_dir)
    stem = stem or f"{model.name}_{model.kind}"
    inside(out, stem, ".inp")  # refuses a name that would leave out_dir, before any work
    res = FemResult(model)
    deck = model.ccx_deck()
    decks = [(f"{stem}.inp", deck)]
    if abaqus:
        decks.append((f"{stem}_abaqus.inp", model.abaqus_deck()))
    if deck_only:
        out.mkdir(parents=True, exist_ok=True)
        res.files += [write_text_atomic(inside(out, n), t) for n, t in decks]
        return res
    require_ccx()
    say = progress or pg.note
    # staging in the system's temporary folder; a killed run's is removed by the next
    with staging_dir(tempfile.gettempdir(), "tipgeo.ccx") as tmp:
        job = Path(tmp) / "job.inp"
        job.write_text(deck)
        t0 = time.monotonic()
        say(f"ccx: {model.n_elements} elements, {len(model.nodes)} nodes, "
            f"{model.info.get('element_size_um')} µm at the edge")
        with pg.stage(f"ccx {stem}") as bar:
            def on_increment(st: float, n: int) -> None:
                bar.set_postfix_str(f"increment {n}, depth {st * model.depth:.4f} of "
                                    f"{model.depth:g} mm")
                if progress is not None:
                    progress(f"ccx: increment {n}, depth {st * model.depth:.4f} mm "
                             f"({time.monotonic() - t0:.0f} s)")

            try:
                run = run_ccx(job, time_limit_s=time_limit_s, threads=threads,
                              progress=on_increment, partial=partial)
            except FemError as e:  # ccx's output goes with its temporary folder
                msg = re.sub(r";? ?job\.log has (its|the whole) output", "", str(e))
                raise type(e)(msg.replace("job.", f"{stem}.")) from e
        if run.stopped:
            say(f"ccx stopped at depth {run.reached * model.depth:.4f} mm of {model.depth:g} mm: "
                f"{run.stopped}")
        t, f = read_dat_totals(job.with_suffix(".dat"))
        if len(t) == 0:
            raise FemError(f"ccx wrote no reaction-force totals of set NEEDLE to {stem}.dat")
        frd = read_frd(job.with_suffix(".frd")) if model.output_depths else None
        created = not out.exists()
        out.mkdir(parents=True, exist_ok=True)
        try:
            res.files += [write_text_atomic(inside(out, n), t_) for n, t_ in decks]
            for ext in (".log", ".dat", ".frd"):
                res.files.append(write_bytes_atomic(inside(out, stem, ext),
                                                    job.with_suffix(ext).read_bytes()))
        except BaseException:
            _remove(res.files, out if created else None)
            raise
    res.run = run
    try:
        _finish(res, frd, t, f, out, stem, pictures, companions)
    except BaseException:
        _remove(res.files, out if created else None)
        raise
    return res


def _finish(res: FemResult, frd: FrdResults | None, t: FloatArray, f: FloatArray, out: Path,
            stem: str, pictures: bool, companions: list[Companion] | None = None) -> None:
    """The force curve, stresses, pictures and JSON of a checked run."""
    model = res.model
    res.depth = np.r_[0.0, t * model.depth]
    res.force = np.r_[0.0, -f[:, 1] * model.force_scale]
    if companions is not None:
        from .meshconv import mesh_error_table

        res.convergence = mesh_error_table(res.depth, res.force,
                                           float(model.info["element_size_um"]) * 1e-3,
                                           companions)
    if frd is not None and res.run is not None:
        reached = res.run.reached * model.depth + tol.fem.depth_reached
        pngs, res.stress = (_stress_pictures(model, frd, out, stem, reached)
                            if pictures else ([], {}))
        res.files += pngs
    ana = analytical_force(model, res.depth)
    res.files.append(write_text_atomic(inside(out, stem, "_force.csv"),
                                       _curve_csv(res.depth, res.force, ana)))
    if pictures:
        from .plots import plot_force_curves

        res.files.append(plot_force_curves(
            [(f"FEM {model.kind}, {model.info['element_size_um']:g} µm", res.depth, res.force,
              "-o"), ("analytical eq. 4.22 (β = 2.5)", res.depth, ana, "--"),
             *[(f"companion mesh {c.size * 1e3:.4g} µm", c.depth, c.force, ":")
               for c in companions or [] if len(c.depth) > 1]],
            inside(out, stem, "_force.png"),
            title=f"{model.name} into {model.material.name} ({model.material.model}), "
                  f"μ = {model.friction:.3g}"))
    res.files.append(write_text_atomic(inside(out, stem, ".json"), dumps(res.to_dict())))


def _remove(files: list[Path], folder: Path | None) -> None:
    """Remove ``files`` and, when given, ``folder`` if that leaves it empty."""
    for p in files:
        Path(p).unlink(missing_ok=True)
    files.clear()
    if folder is not None:
        with contextlib.suppress(OSError):
            folder.rmdir()


def run_fem(spec: Tip | TipSpec, *, model: str = "axisymmetric", depth: float, out_dir: str | Path,
            tissue: str = "pvc-sp0", friction: float | None = None, mesh: float | None = None,
            deck_only: bool = False, abaqus: bool = False, time_limit_s: float = 600.0,
            output_depths: tuple[float, ...] | None = None,
            progress: Callable[[str], None] | None = None, partial: bool = True,
            pictures: bool = True, companions: bool = False, **kw: Any) -> FemResult:
    """Build, write and (unless ``deck_only``) run the ``model`` of tip
    ``spec`` pushed ``depth`` mm into ``tissue`` (see :func:`run_model`).
    Stresses are written at ``output_depths`` (default: the final depth and,
    when deeper than 1 mm, 1 mm). Without ccx (and not ``deck_only``) it
    raises :class:`~tipgeo.fem.run.CcxMissing` before meshing.

    With ``companions`` (the CLI's default) the same model also runs at two
    coarser element sizes, 2·h and √2·h (mm), with the run's contact
    stiffness, far size and slave side held, in ``out_dir/mesh_<size>um``;
    the result's :attr:`FemResult.convergence` then gives Richardson's
    discretisation error at every depth of the curve and its verdict checks
    it at the final depth (:mod:`tipgeo.fem.meshconv`)."""
    depth = v.real("depth", depth, lo=0.0, lo_open=True, unit="mm")
    if not deck_only:
        require_ccx()
    if output_depths is None:
        output_depths = tuple(sorted({depth, *([1.0] if depth > 1.0 else [])}))
    if companions and not deck_only and not isinstance(spec, Tip):
        from ..build import build_tip

        spec = build_tip(spec)  # once for the three runs
    m = build_model(spec, model, depth=depth, tissue=tissue, mesh=mesh, friction=friction,
                    output_depths=output_depths, **kw)
    runs = None
    if companions and not deck_only:
        runs = _run_companions(spec, m, out_dir, tissue=tissue, friction=friction,
                               time_limit_s=time_limit_s, progress=progress, **kw)
    try:
        res = run_model(m, out_dir, deck_only=deck_only, abaqus=abaqus,
                        time_limit_s=time_limit_s, progress=progress, partial=partial,
                        pictures=pictures, companions=runs)
        res.files += [p for c in runs or [] for p in c.files]
        return res
    except BaseException:
        for c in runs or []:
            _remove(c.files, _companion_dir(out_dir, c.size))
        raise


def _run_companions(tip: Tip | TipSpec, main: FemModel, out_dir: str | Path, *,
                    progress: Callable[[str], None] | None, **kw: Any) -> list[Companion]:
    """The two coarser companion runs of ``main`` (coarse first), each in
    ``out_dir/mesh_<size>um``; a run ccx stops short is kept (its reach
    recorded), one that fails outright is recorded with ccx's message."""
    from .meshconv import Companion, companion_sizes, held_options

    h = float(main.info["element_size_um"]) * 1e-3
    fixed = held_options(main)
    kw = {k: x for k, x in kw.items() if k not in fixed}
    out: list[Companion] = []
    bar = pg.bar(2, "fem: companion meshes", unit="mesh")
    try:
        for size in companion_sizes(h):
            c = Companion(size)
            bar.set_postfix_str(f"{size * 1e3:.4g} µm")
            try:
                r = run_fem(tip, model=main.kind, depth=main.depth,
                            out_dir=_companion_dir(out_dir, size),
                            mesh=size, output_depths=(), progress=progress, pictures=False,
                            **fixed, **kw)
            except FemError as e:
                c.error = str(e)
            else:
                assert r.run is not None  # run_fem ran ccx
                c.depth, c.force, c.files = r.depth, r.force, r.files
                c.reached, c.cpu_s = float(r.reached_depth or 0.0), r.run.cpu_s
                c.elements = r.model.n_elements
            out.append(c)
            bar.update()
    except BaseException:  # interrupted: nothing of the companions is left behind
        for c in out:
            _remove(c.files, _companion_dir(out_dir, c.size))
        raise
    finally:
        bar.close()
    return out


def _companion_dir(out_dir: str | Path, size: float) -> Path:
    """Where the companion run at element size ``size`` (mm) writes."""
    return Path(out_dir) / f"mesh_{size * 1e3:.4g}um"


def richardson(values: tuple[float, float, float], ratio: float) -> dict[str, float | None]:
    """Observed order and extrapolated limit of three results on meshes
    refined by a constant ``ratio`` (coarse to fine): p = ln(e₁/e₂)/ln r
    with e₁ = f₂ − f₁, e₂ = f₃ − f₂, and f∞ = f₃ + e₂/(rᵖ − 1). Both None when
    the changes differ in sign or vanish (no asymptotic convergence)."""
    f1, f2, f3 = (float(x) for x in values)
    e1, e2 = f2 - f1, f3 - f2
    if e1 == 0.0 or e2 == 0.0 or (e1 > 0) != (e2 > 0) or ratio <= 1.0:
        return {"order": None, "extrapolated": None}
    p = math.log(e1 / e2) / math.log(ratio)
    if p <= 0.0:
        return {"order": p, "extrapolated": None}
    return {"order": p, "extrapolated": f3 + e2 / (ratio ** p - 1.0)}


def convergence_verdict(study: dict[str, Any], target_change: float | None = None
                        ) -> Verdict:
    """:class:`tipgeo.verdict.Verdict` of a :func:`convergence_study` result:
    the relative change of the force at depth from the middle to the finest
    mesh within ``target_change`` (a fraction; default the study's own
    ``target_change_percent``, else ``tol.fem.convergence_change``)."""
    from ..verdict import Verdict, check_max

    if target_change is None:
        pct = study.get("target_change_percent")
        target_change = tol.fem.convergence_change if pct is None else pct / 100.0
    rows = study["rows"]
    ch = rows[-1]["change_percent"]
    what = (f"force change from {rows[-2]['element_size_um']:g} to "
            f"{rows[-1]['element_size_um']:g} µm (%)")
    return Verdict.of(f"mesh convergence of the force at {study['depth_mm']:g} mm",
                      [check_max("finest_change_percent", None if ch is None else abs(ch),
                                 100.0 * target_change, what=what)])


def convergence_study(spec: Tip | TipSpec, *, model: str = "axisymmetric", depth: float,
                      meshes: tuple[float, ...], out_dir: str | Path,
                      tissue: str = "pvc-sp0", friction: float | None = None,
                      time_limit_s: float = 1800.0,
                      progress: Callable[[str], None] | None = None,
                      target_change: float | None = None, **kw: Any) -> dict[str, Any]:
    """Run the same insertion, to the same ``depth``, at three element sizes
    of the contact zone (mm, coarse to fine) and report the force of each at
    that depth (its peak: the curves rise), the relative change from the
    previous size, the forces at ten common depths, and the Richardson
    estimate (observed order, extrapolated force) when the sizes halve —
    each beside the analytical column force of eq. 4.22 at that depth
    (``eq_4_22_N``; ``gap_to_eq_4_22_percent`` per mesh and for the
    extrapolated force, and the finest mesh's estimated discretisation error
    ``finest_error_estimate_percent``).

    Only the contact zone is refined: the far-field element size and the
    contact penalty stiffness are those of the coarsest mesh for all three (a
    penalty that scales with 1/h would change the model with the mesh; the
    coarsest's, the softest, is the one all three meshes converge with), and
    an axisymmetric model's ``slave="auto"`` is resolved once, at the finest
    mesh (:func:`~tipgeo.fem.axisym.auto_slave`), for all three.
    Every run must reach ``depth`` (an incomplete run is an error).

    The result holds ``verdict`` (:func:`convergence_verdict`, as a dict):
    whether the finest change, middle to finest mesh, is within
    ``target_change`` (a fraction; default ``tol.fem.convergence_change``)."""
    if len(meshes) != 3:
        raise SpecError(f"meshes = {meshes}: expected three element sizes")
    meshes = tuple(v.real("mesh", h, lo=0.001, hi=0.5, unit="mm") for h in meshes)
    if not meshes[0] > meshes[1] > meshes[2]:
        raise SpecError(f"meshes = {[h * 1e3 for h in meshes]} µm: expected coarse to fine")
    target = tol.fem.convergence_change if target_change is None else v.real(
        "target_change", target_change, lo=0.0, lo_open=True, hi=1.0)
    require_ccx()
    probe = build_model(spec, model, depth=depth, tissue=tissue, mesh=meshes[0],
                        friction=friction, **kw)
    fixed: dict[str, Any] = {"contact_stiffness": probe.penalty}
    if model == "axisymmetric":
        fixed["far"] = float(probe.info["element_size_far_um"]) * 1e-3
        if kw.get("cut", "none") == "none" and kw.get("slave", "auto") == "auto":
            from .axisym import auto_slave

            # one contact for all three: the finest mesh's (the default's at 25 µm)
            kw = {**kw, "slave": auto_slave(probe.info["_needle_section"], meshes[-1])}
    grid = np.linspace(0.1, 1.0, 10) * depth
    rows: list[dict[str, Any]] = []
    curves: list[FloatArray] = []
    bar = pg.bar(len(meshes), "fem: convergence study", unit="mesh")
    for h in meshes:
        sub = Path(out_dir) / f"mesh_{h * 1e3:g}um"
        bar.set_postfix_str(f"{h * 1e3:g} µm")
        try:
            r = run_fem(spec, model=model, depth=depth, out_dir=sub, tissue=tissue,
                        friction=friction, mesh=h, time_limit_s=time_limit_s, progress=progress,
                        output_depths=(depth,), partial=False, **fixed, **kw)
        except BaseException:
            bar.close()
            raise
        bar.update()
        assert r.run is not None  # run_fem ran ccx (not deck_only)
        f_end = float(np.interp(depth, r.depth, r.force))
        curves.append(np.interp(grid, r.depth, r.force))
        prev = rows[-1]["force_at_depth_N"] if rows else None
        rows.append({"element_size_um": h * 1e3, "elements": r.model.n_elements,
                     "nodes": len(r.model.nodes), "force_at_depth_N": f_end,
                     "peak_force_N": r.peak_force, "increments": r.run.increments,
                     "cpu_s": round(r.run.cpu_s, 2), "wall_s": round(r.run.wall_s, 2),
                     "change_percent": None if prev is None else 100.0 * (f_end - prev) / prev})
    bar.close()
    ratios = meshes[0] / meshes[1], meshes[1] / meshes[2]
    f1, f2, f3 = (float(row["force_at_depth_N"]) for row in rows)
    rich: dict[str, float | None] = richardson((f1, f2, f3), ratios[0]) \
        if abs(ratios[0] - ratios[1]) <= tol.fem.ratio_equal * ratios[0] else {
            "order": None, "extrapolated": None}
    # eq. 4.22 (the analytical column, β = 2.5) beside every mesh and the
    # Richardson limit: the gap a finer mesh would not close
    ana = float(analytical_force(probe, np.array([depth]))[0])
    for row in rows:
        row["gap_to_eq_4_22_percent"] = 100.0 * (row["force_at_depth_N"] / ana - 1.0)
    limit = rich.get("extrapolated")
    if limit is not None:
        rich["gap_to_eq_4_22_percent"] = 100.0 * (limit / ana - 1.0)
        rich["finest_error_estimate_percent"] = 100.0 * (
            rows[-1]["force_at_depth_N"] / limit - 1.0)
    out = {"model": model, "depth_mm": depth, "tissue": tissue, "eq_4_22_N": ana,
           "far_element_um": probe.info.get("element_size_far_um"),
           "contact_stiffness_MPa_per_mm": fixed["contact_stiffness"], "rows": rows,
           "richardson": rich,
           "curves": {"depth_mm": grid.tolist(),
                      **{f"{h * 1e3:g}um": c.tolist() for h, c in zip(meshes, curves)}},
           "target_change_percent": 100.0 * target}
    out["verdict"] = convergence_verdict(out).to_dict()
    write_text_atomic(Path(out_dir) / "convergence.json", dumps(out))
    return out
