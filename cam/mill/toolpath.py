"""Three-axis toolpaths for a tip standing tip-up (thesis §3.2), from the
tip's cut faces with OpenCAMLib's drop-cutter.

Frames and units: :mod:`cam.mill.machine` (cannula frame; program frame =
cannula frame turned by the clocking angle about z; mm, rad inside, feeds
mm/min).

What is planned
---------------
- **Height field.** The CAD cut surface z = Z(x, y) over the annulus
  r_i ≤ r ≤ r_o is solved from the cutters' exact implicit functions
  (:meth:`~tipgeo.cutters.base.Cutter.implicit`); a face whose normal has
  n_z < ``tol.cam.mill_normal_z`` is refused (not a height field from +Z).
- **Clocking.** Raster lines run along program +X. The needle is turned in
  its collet so that, over the annulus, the worst ratio between the spacing
  of neighbouring passes measured on the surface and in plan,
  √((1 + |∇Z|²)/(1 + (∇Z·X)²)), is smallest: the lines follow the fall
  line of a bevel.
- **Finishing.** Passes at a step-over s (plan, a multiple of the axis
  resolution) so that the scallop the simulator measures — the cusp between
  passes *plus* the Z round-up to the axis grid, up to one resolution step
  vertically, res·n_z normal to the surface — stays within 0.95 h
  (``tol.cam.mill_scallop_share``; the rest is for the mesh and the chords)
  at every sample of the annulus: for a ball, at each sample the passes lie
  s·q apart on the surface (q the local surface/plan ratio) and leave
  (R − √(R² − (sq)²/4))·(1 + R/ρ), ρ the radius of the surface across the
  passes where it is convex (:func:`_ball_stepover`); for a bull nose or a
  flat end the largest s whose scallop on the surface's steepest planes, with
  the round-up added, stays within 0.95 h, from the tool's swept profile
  (:func:`planar_stepover`: a flat end along a slope g leaves g(R − √(R² −
  s²/4)), across a slope c terraces of s·c). A target the round-up alone
  exceeds somewhere (res·n_z ≥ 0.95 h) is refused. What the plan does not
  model — the facets of the 1 µm mesh the drop-cutter follows and the chords
  between kept points, 0.3 µm on the helical needle measured with a 0.1 µm
  axis grid — is left to the other 5 % and to the round-up seldom reaching
  its bound at a cusp's crest; the simulation measures the result
  (:attr:`cam.mill.MillResult.verdict`). The helical needle at its 2 µm
  default: before the round-up was budgeted, step-over 104 µm (plane cusp
  1.80 µm) measured 2.52 µm (2.19 µm on a 0.1 µm grid); now 82 µm, planned
  1.87 µm, measured 1.90 µm. Every pass runs across the
  whole annulus grown by the tool
  radius R; cutter-location points are dropped (OpenCAMLib ``BatchDropCutter``)
  onto the cut faces of the tip mesh built at ``tol.cam.mill_mesh``, first every
  32 resolution steps, then halving until the straight move between kept points
  lies within ``tol.cam.mill_chord`` (where the path bends down: a gouge) or
  ``tol.cam.mill_chord_up`` (where it bends up: material left), normal to
  the surface, of the dropped point between (down to one resolution step). X
  and Y lie on the 0.002 mm grid; Z is rounded *up* to it, so rounding never
  gouges.
- **Roughing.** Z-level passes, ``stepdown`` apart from the stock top, along
  lines ``rough_stepover`` apart; each follows max(level, Z_a) with Z_a the
  drop-cutter of a tool grown by the allowance a (the real tool's tip raised
  by a): a stays on the finished surface, measured normal to it.
- **Lead-in/out and heights.** Passes start and end with the tool clear of the
  wall (its footprint outside the annulus: no contact at any height), after a
  straight lead of ``lead`` mm; the tool rapids to the safe height
  ``z_top + safe`` between passes, rapids down to ``approach`` above a start in
  the clear (or above the stock top elsewhere) and plunges at the plunge feed.
  The stock is the tube faced off at ``z_top`` = the tip's highest point +
  ``top_stock``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np

from tipgeo import progress as pg
from tipgeo.arrays import ArrayLike, BoolArray, FloatArray, IntArray
from tipgeo.errors import SpecError
from tipgeo.tolerances import tol

from ..machine import CamError
from .machine import DEFAULT_TOOL, EndMill, MillMachine

if TYPE_CHECKING:
    from tipgeo.cannula import Cannula
    from tipgeo.spec import TipSpec

__all__ = ["MillParams", "MillSetup", "Pass", "MillToolpath", "cad_height", "plan_toolpaths",
           "planar_stepover", "to_program", "to_cannula", "ProgressFn"]

#: A progress printer: takes one line of text.
ProgressFn = Callable[[str], None]

#: The finest scallop target a plan takes (mm: 0.1 µm).
MIN_SCALLOP = 1.0e-4


@dataclass(frozen=True, kw_only=True)
class MillParams:
    """Milling parameters (mm, mm/min, rpm).

    Feeds: the thesis prints 0.08 mm/min, which would take days; we assume
    0.0075 mm per tooth × 2 flutes × 10,000 rpm = 150 mm/min finishing (carbide
    in stainless tube), roughing 200 mm/min, plunging 50 mm/min.
    """

    scallop: float = 2.0e-3
    allowance: float = 0.05
    stepdown: float = 0.3
    rough_stepover: float = 0.6
    rough_sample: float = 0.05
    rough: bool = True
    spindle_rpm: float = 10000.0
    finish_feed: float = 150.0
    rough_feed: float = 200.0
    plunge_feed: float = 50.0
    top_stock: float = 0.1
    safe: float = 2.0
    approach: float = 0.2
    lead: float = 0.1
    coolant: bool = True
    program_number: int = 1402

    def __post_init__(self) -> None:
        try:
            from tipgeo import validate as v

            v.real("scallop", self.scallop, lo=MIN_SCALLOP, hi=0.1, unit="mm")
            v.real("allowance", self.allowance, lo=0.0, hi=1.0, unit="mm")
            v.real("stepdown", self.stepdown, lo=0.01, hi=5.0, unit="mm")
            v.real("rough_stepover", self.rough_stepover, lo=0.01, hi=10.0, unit="mm")
            v.real("rough_sample", self.rough_sample, lo=0.002, hi=1.0, unit="mm")
            for k in ("top_stock", "safe", "approach", "lead"):
                v.real(k, getattr(self, k), lo=0.0, hi=50.0, lo_open=True, unit="mm")
            v.integer("program_number", self.program_number, lo=1, hi=99999)
        except SpecError as e:
            raise CamError(str(e)) from None


@dataclass(frozen=True)
class MillSetup:
    """Where the needle stands and how the passes lie (mm, rad).

    clocking : rad — the cannula direction γ that lies along program +X
    z_top : mm — the faced stock top; z_safe : mm — rapid height
    stepover : mm — finishing step-over in plan; ratio — its worst surface/plan ratio
    r_o, r_i : mm — the wall's radii
    """

    clocking: float
    z_top: float
    z_safe: float
    stepover: float
    ratio: float
    r_o: float
    r_i: float


@dataclass
class Pass:
    """One cutting pass: ``points`` (n, 3) mm in the program frame (tool tip),
    cut at ``feed`` mm/min; ``kind`` ``rough`` or ``finish``; ``clear_start``
    when its first point has the tool clear of the wall (rapid down to it)."""

    kind: str
    points: FloatArray
    feed: float
    clear_start: bool = True


@dataclass
class MillToolpath:
    """The planned passes with their set-up, tool, machine and parameters."""

    name: str
    setup: MillSetup
    tool: EndMill
    machine: MillMachine
    params: MillParams
    passes: list[Pass]
    stats: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """Plain numbers (report units: mm, deg, µm)."""
        s = self.setup
        fin = [p for p in self.passes if p.kind == "finish"]
        return {"name": self.name, "tool": self.tool.describe(),
                "clocking_deg": math.degrees(s.clocking), "z_top_mm": s.z_top,
                "z_safe_mm": s.z_safe, "stepover_mm": s.stepover,
                "stepover_ratio": s.ratio, "scallop_um": self.params.scallop * 1e3,
                "finish_passes": len(fin),
                "rough_passes": len(self.passes) - len(fin),
                "points": int(sum(len(p.points) for p in self.passes)), **self.stats}


def progress_say(progress: ProgressFn | None = None) -> ProgressFn:
    """The progress-line callable: ``progress`` when a caller gives one (a
    library user's printer), else :func:`tipgeo.progress.note` (shown when
    progress is on, see :mod:`tipgeo.progress`)."""
    return progress if progress is not None else pg.note


def to_program(p: ArrayLike, clocking: float) -> FloatArray:
    """Cannula-frame points (n, 3) → program frame (mm)."""
    c, s = math.cos(clocking), math.sin(clocking)
    p = np.asarray(p, float)
    out: FloatArray = p.copy()
    out[..., 0] = c * p[..., 0] + s * p[..., 1]
    out[..., 1] = -s * p[..., 0] + c * p[..., 1]
    return out


def to_cannula(p: ArrayLike, clocking: float) -> FloatArray:
    """Program-frame points (n, 3) → cannula frame (mm)."""
    return to_program(p, -clocking)


@overload
def cad_height(spec: TipSpec, x: ArrayLike, y: ArrayLike, *,
               normals: Literal[False] = False) -> FloatArray: ...


@overload
def cad_height(spec: TipSpec, x: ArrayLike, y: ArrayLike, *,
               normals: Literal[True]) -> tuple[FloatArray, FloatArray]: ...


def cad_height(spec: TipSpec, x: ArrayLike, y: ArrayLike, *,
               normals: bool = False) -> FloatArray | tuple[FloatArray, FloatArray]:
    """The CAD cut surface z = Z(x, y) (mm, cannula frame) over points of
    the annulus, from the cutters' exact implicit functions (Newton in z);
    with ``normals`` also the unit outward normals (n, 3).

    Raises :class:`CamError` when a cutter has no exact surface or its face
    is not a height field from +Z there.
    """
    x = np.asarray(x, float).ravel()
    y = np.asarray(y, float).ravel()
    can = spec.cannula
    best = np.full(len(x), np.inf)
    nrm = np.zeros((len(x), 3))
    for c in spec.cutters:
        if c.needs_previous or c.process not in ("grind", "mill"):
            raise CamError(f"cutter '{c.name}' ({c.kind}) is not a height field from +Z "
                           "(it cuts into the wall); a three-axis mill with the tip up "
                           "needs cut faces z = Z(x, y)")
        z = np.full(len(x), float(c.z_upper(can)))
        pts = np.stack([x, y, z], 1)
        for _ in range(60):
            pts[:, 2] = z
            try:
                f, g = c.implicit(pts, can)
            except NotImplementedError:
                raise CamError(f"cutter '{c.name}' ({c.kind}) has no exact surface to mill "
                               "from") from None
            if np.any(g[:, 2] <= 0):
                k = int(np.argmin(g[:, 2]))
                raise CamError(f"cutter '{c.name}': the cut face is not a height field from "
                               f"+Z at (x, y) = ({x[k]:.4f}, {y[k]:.4f}) mm (normal z "
                               f"component {g[k, 2]:.3g} ≤ 0)")
            step = f / g[:, 2]
            z = z - step
            if np.max(np.abs(step)) < tol.cam.mill_height:
                break
        else:
            raise CamError(f"cutter '{c.name}': the cut height did not converge")
        pts[:, 2] = z
        f, g = c.implicit(pts, can)
        n = g / np.linalg.norm(g, axis=1, keepdims=True)
        low = z < best
        best = np.where(low, z, best)
        nrm[low] = n[low]
    if normals:
        return best, nrm
    return best


def _annulus_samples(can: Cannula, rings: int = 9,
                     around: int = 720) -> tuple[FloatArray, FloatArray]:
    """Cannula-frame sample points (x, y) (mm) over the wall's annulus:
    ``rings`` radii × ``around`` angles."""
    r = np.linspace(can.r_i, can.r_o, rings)
    g = np.linspace(0.0, 2 * math.pi, around, endpoint=False)
    rr, gg = np.meshgrid(r, g)
    return (rr * np.cos(gg)).ravel(), (rr * np.sin(gg)).ravel()


def _ratio(grad: FloatArray, clocking: ArrayLike) -> FloatArray:
    """Worst surface/plan spacing ratio of passes along direction
    ``clocking`` (array of rad): √((1 + |g|²)/(1 + (g·d)²))."""
    c = np.atleast_1d(clocking)
    d = np.stack([np.cos(c), np.sin(c)], 1)
    ga = grad @ d.T
    g2 = np.sum(grad ** 2, axis=1)[:, None]
    out: FloatArray = np.sqrt((1 + g2) / (1 + ga ** 2)).max(axis=0)
    return out


def _clocking(spec: TipSpec) -> tuple[float, float, FloatArray]:
    """The clocking (rad in [0, π)) whose worst surface/plan ratio of the
    passes over the annulus is smallest, that ratio, and the surface's
    gradients at the annulus samples (a CamError where the surface is too
    steep for a three-axis mill)."""
    x, y = _annulus_samples(spec.cannula)
    _, n = cad_height(spec, x, y, normals=True)
    nz = n[:, 2]
    if nz.min() < tol.cam.mill_normal_z:
        k = int(np.argmin(nz))
        raise CamError(f"the cut surface is not a height field from +Z: its normal at (x, y) "
                       f"= ({x[k]:.4f}, {y[k]:.4f}) mm is {math.degrees(math.asin(nz[k])):.3g}° "
                       f"from the horizontal; a three-axis mill needs at least "
                       f"{math.degrees(math.asin(tol.cam.mill_normal_z)):.3g}°")
    grad = -n[:, :2] / nz[:, None]
    coarse = np.radians(np.arange(0.0, 180.0, 1.0))
    r = _ratio(grad, coarse)
    c0 = coarse[int(np.argmin(r))]
    fine = c0 + np.radians(np.arange(-1.0, 1.0001, 0.02))
    rf = _ratio(grad, fine)
    k = int(np.argmin(rf))
    return float(np.mod(fine[k], math.pi)), float(rf[k]), grad


def _skirts(tri: FloatArray, verts: FloatArray, faces: IntArray) -> FloatArray:
    """Strips continuing the cut faces across their boundary (the rims, where
    the mesh's polygon lies inside the true circle by up to its chordal
    tolerance): each boundary edge extended by ``SKIRT`` mm in its triangle's
    plane. The tool then cannot roll over a polygon corner into the rim; it
    cuts air beyond the wall instead."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, inv, cnt = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    k = np.flatnonzero(cnt[inv.ravel()] == 1)
    t, s_ = np.divmod(k, 3)
    a = verts[faces[t, s_]]
    b = verts[faces[t, (s_ + 1) % 3]]
    c = verts[faces[t, (s_ + 2) % 3]]
    n = np.cross(tri[t, 1] - tri[t, 0], tri[t, 2] - tri[t, 0])
    o = np.cross(b - a, n)
    o /= np.linalg.norm(o, axis=1, keepdims=True)
    o *= np.where(np.sum(o * (c - a), axis=1) > 0, -1.0, 1.0)[:, None]   # away from the face
    a2, b2 = a + SKIRT * o, b + SKIRT * o
    out: FloatArray = np.stack([np.stack([a, b, b2], 1), np.stack([a, b2, a2], 1)],
                               1).reshape(-1, 3, 3)
    return out


#: Width (mm) of the strips that continue the cut faces across the rims.
SKIRT = 0.02


class _Surface:
    """An OpenCAMLib STL surface of the tip's cut faces (program frame); the
    Python objects are kept alive with it."""

    def __init__(self, spec: TipSpec, clocking: float, tolerance: float) -> None:
        import opencamlib as ocl

        from tipgeo import build_tip

        tip = build_tip(spec, tolerance=tolerance)
        cut = np.array([str(lab).startswith("cut:") for lab in tip.labels])
        tri = tip.triangles[cut]
        tri = np.concatenate([tri, _skirts(tri, tip.vertices, tip.faces[cut])])
        tri = to_program(tri.reshape(-1, 3), clocking).reshape(-1, 3, 3)
        self.triangles = tri
        self.z_min = float(tip.bounds[0, 2])
        self.z_max = float(tip.bounds[1, 2])
        self.stl = ocl.STLSurf()
        self._keep: list[Any] = []
        for a, b, c in tri:
            t = ocl.Triangle(ocl.Point(*a), ocl.Point(*b), ocl.Point(*c))
            self._keep.append(t)
            self.stl.addTriangle(t)

    def drop(self, cutter: Any, xy: FloatArray) -> FloatArray:
        """Drop-cutter tip heights (mm) at program-frame points (n, 2);
        NaN where the cutter touches nothing."""
        import opencamlib as ocl

        if len(xy) == 0:
            return np.zeros(0)
        floor = self.z_min - 100.0
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(self.stl)
        bdc.setCutter(cutter)
        bdc.setThreads(max(1, min(2, os.cpu_count() or 1)))
        keep: list[Any] = []
        for x, y in xy:
            p = ocl.CLPoint(float(x), float(y), floor)
            keep.append(p)
            bdc.appendPoint(p)
        bdc.run()
        z = np.array([p.z for p in bdc.getCLPoints()], float)
        out: FloatArray = np.where(z <= floor + 1.0, np.nan, z)
        return out


def _runs(mask: BoolArray) -> list[tuple[int, int]]:
    """(start, end) inclusive index runs where ``mask`` is True."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1),
                                             np.flatnonzero(d == -1) - 1)]


def _contact(x: ArrayLike, y: float, r_lo: float, r_hi: float) -> BoolArray:
    """Where a tool at (x, y) (mm, program frame) has its axis strictly
    between the radii ``r_lo`` and ``r_hi`` (mm)."""
    r = np.hypot(x, y)
    out: BoolArray = (r < r_hi) & (r > r_lo)
    return out


def _ceil(z: FloatArray, res: float) -> FloatArray:
    """``z`` (mm) rounded up to the axis grid ``res`` (a value an ulp above
    a grid point stays on it)."""
    out: FloatArray = np.ceil(z / res - tol.cam.mill_grid) * res
    return out


#: The finishing runs of each line: (y, [(x (m,), z (m,)), …]) (mm, program frame).
FinishLines = list[tuple[float, list[tuple[FloatArray, FloatArray]]]]


def _finish_lines(surf: _Surface, cutter: Any, ys: FloatArray, x_half: float, r_lo: float,
                  r_hi: float, res: float, chord: float, chord_up: float,
                  bar: Any = None) -> tuple[FinishLines, int]:
    """Adaptive drop-cutter along each line y = const (program frame).

    Returns ([(y, [(x (m,), z (m,)), …]), …] per line — runs of the line where
    the tool touches the tip, x on the resolution grid and z rounded up to
    it —, drop-cutter calls). ``bar`` (a :func:`tipgeo.progress.bar`) is
    given the count of passes (runs) and advanced as each is refined."""
    coarse = 32
    runs: list[tuple[float, dict[int, float]]] = []     # (y, grid index j → z)
    pending: list[tuple[int, int]] = []                  # (run, grid index j)
    for y in ys:
        jmax = int(math.floor(x_half / res)) + 1
        j = np.arange(-jmax, jmax + 1)
        inside = _contact(j * res, float(y), r_lo, r_hi)
        for a, b in _runs(inside):
            idx = np.arange(a, b + 1)
            keep = idx[(j[idx] % coarse == 0) | (idx == a) | (idx == b)]
            runs.append((float(y), {}))
            pending += [(len(runs) - 1, int(j[i])) for i in keep]
    calls = 0
    if bar is not None:
        bar.total = len(runs)           # passes: the runs of the lines on the tip
    done = 0
    rounds = 0
    while pending:
        xy = np.array([(jj * res, runs[ri][0]) for ri, jj in pending])
        zs = surf.drop(cutter, xy)
        calls += len(pending)
        rounds += 1
        for (ri, jj), zz in zip(pending, zs):
            runs[ri][1][jj] = float(zz)
        pending = []
        for ri, r_ in enumerate(runs):
            js = np.array(sorted(r_[1]))
            if len(js) < 3:
                continue
            z = np.array([r_[1][jj] for jj in js])
            x = js * res
            hgt = np.diff(x)
            slope = np.diff(z) / hgt
            curv = np.zeros(len(z))
            curv[1:-1] = 2.0 * np.diff(slope) / (hgt[:-1] + hgt[1:])   # signed: z''
            curv[0], curv[-1] = curv[1], curv[-2]
            # predicted sag of each straight move between kept points, measured
            # normal to the surface (the vertical sag times n_z ≤ 1/√(1 + slope²)
            # of the move): what the deviation map and the gouge bound see.
            # Where the path bends down (z'' < 0) the chord lies under it and
            # would gouge: ``chord``; where it bends up (z'' > 0, mostly the
            # creases between the mesh's facets) it leaves material: ``chord_up``
            scale = hgt ** 2 / 8.0 / np.sqrt(1.0 + slope ** 2)
            down = scale * np.maximum(np.maximum(-curv[:-1], -curv[1:]), 0.0)
            up = scale * np.maximum(np.maximum(curv[:-1], curv[1:]), 0.0)
            bad = ~np.isfinite(down) | ~np.isfinite(up) | (down > chord) | (up > chord_up)
            split = bad & (np.diff(js) >= 2)
            pending += [(ri, int((a + b) // 2)) for a, b in zip(js[:-1][split], js[1:][split])]
        if bar is not None:
            now = len(runs) - len({ri for ri, _ in pending})
            bar.update(now - done)
            done = now
            bar.set_postfix_str(f"round {rounds}, {calls} points")
    out: dict[float, list[tuple[FloatArray, FloatArray]]] = {}
    for y_, zj in runs:
        js = np.array(sorted(zj))
        z = np.array([zj[jj] for jj in js])
        good = np.isfinite(z)
        if good.any():
            out.setdefault(y_, []).append((js[good] * res, _ceil(z[good], res)))
    return [(y, out.get(float(y), [])) for y in ys], calls


def _grid_values(lo: float, hi: float, step: float, res: float) -> FloatArray:
    """Multiples of ``step`` (itself a multiple of ``res``) covering (lo, hi)."""
    k0 = math.ceil(lo / step)
    k1 = math.floor(hi / step)
    out: FloatArray = np.round(np.arange(k0, k1 + 1) * step / res) * res
    return out


def _with_leads(x: FloatArray, z: FloatArray, y: float, r_hi: float, lead: float, res: float,
                feed: float, kind: str) -> Pass:
    """A pass from a run: straight leads at the run's end heights out to
    points where the tool is clear (outside the footprint circle, or the next
    clear grid point in the bore)."""
    xs, zs = [float(a) for a in x], [float(a) for a in z]

    # lead-in / lead-out along X to the clear side
    def clear_x(x_end: float, direction: float) -> float:
        xe = x_end + direction * res
        if math.hypot(xe, y) >= r_hi:   # outer side: go on by ``lead``
            return x_end + direction * (res + math.ceil(lead / res) * res)
        return xe
    x_in = clear_x(xs[0], -1.0)
    x_out = clear_x(xs[-1], 1.0)
    pts = [(x_in, y, zs[0])] + list(zip(xs, [y] * len(xs), zs)) + [(x_out, y, zs[-1])]
    return Pass(kind, np.round(np.array(pts) / res) * res, feed, True)


def _envelope(tool: EndMill, g_along: FloatArray, w: FloatArray) -> FloatArray:
    """(k, m) min over d of [T(√(d² + w²)) + g d]: the height of the tool's
    swept lower envelope over a plane rising at g along the pass, at lateral
    offsets w (relative; T the tool's profile above its tip, mm)."""
    R, r = tool.radius, tool.corner
    a = R - r
    # d over the chord |d| ≤ √(R² − w²) where the tool covers the column,
    # ends included (a flat end's minimum lies on them)
    d = np.linspace(-1.0, 1.0, 801)[None, None, :] * np.sqrt(
        np.clip(R * R - w ** 2, 0.0, None))[None, :, None]
    rho = np.minimum(np.sqrt(d ** 2 + w[None, :, None] ** 2), R)
    e = np.clip(rho - a, 0.0, None)
    T = np.where(np.abs(w)[None, :, None] <= R, r - np.sqrt(np.clip(r * r - e * e, 0.0, None)),
                 np.inf)
    out: FloatArray = np.min(T + g_along[:, None, None] * d, axis=2)
    return out


def planar_stepover(tool: EndMill, grad: FloatArray, clocking: float, h: float, *,
                    lift: float = 0.0) -> float:
    """The largest plan step-over (mm) whose scallop between neighbouring
    passes along ``clocking`` stays within ``h`` (mm, normal to the surface)
    on every plane of gradient ``grad`` (n, 2) — the tool's swept lower
    envelope E(w) = −c w + min_d [T(√(d² + w²)) + g d] (g, c the slopes
    along and across the passes, w sampled every R/200), the scallop the
    height above min E where E(w) meets E(w − s) between two passes'
    contacts, times the plane's n_z. For bull-nose and flat end mills, whose profile T has a flat
    bottom and a corner (ball mills: the closed form of the module
    docstring). ``lift`` (mm, vertical) is added to every plane's scallop
    before the n_z: the Z round-up to the axis resolution."""
    dvec = np.array([math.cos(clocking), math.sin(clocking)])
    along = grad @ dvec
    cross = grad @ np.array([-dvec[1], dvec[0]])
    nz = 1.0 / np.sqrt(1.0 + np.sum(grad ** 2, 1))
    # the worst planes: steepest along, steepest across, and a spread between
    pick = np.unique(np.concatenate([np.argsort(np.abs(along))[-8:],
                                     np.argsort(np.abs(cross))[-8:],
                                     np.linspace(0, len(grad) - 1, 24).astype(int)]))
    g, c, n = np.abs(along[pick]), np.abs(cross[pick]), nz[pick]
    R = tool.radius

    w = np.linspace(-R, 2.6 * R, 721)                  # steps of R/200
    E = _envelope(tool, g, w) - c[:, None] * w[None, :]
    E -= np.nanmin(np.where(np.isfinite(E), E, np.nan), axis=1, keepdims=True)
    k0 = np.argmin(E, axis=1)                           # where each pass touches its plane

    def scallop(s: float) -> float:
        worst = 0.0
        for e, k, nz_ in zip(E, k0, n):
            fin = np.isfinite(e)
            es = np.interp(w - s, w, np.where(fin, e, 0.0))   # the neighbouring pass, s across
            es[np.interp(w - s, w, fin.astype(float), left=0.0) < 1.0] = np.inf
            sel = slice(k, int(np.searchsorted(w, w[k] + s, side="right")))
            m = np.minimum(e[sel], es[sel])
            top = float(m[np.isfinite(m)].max()) if np.isfinite(m).any() else 0.0
            # the cusp where the two envelopes cross, interpolated between samples
            diff = e[sel] - es[sel]
            ok = np.isfinite(diff[:-1]) & np.isfinite(diff[1:]) & (diff[:-1] < 0) & (diff[1:] >= 0)
            for j in np.flatnonzero(ok):
                f = -diff[j] / (diff[j + 1] - diff[j])
                top = max(top, float(e[sel][j] + f * (e[sel][j + 1] - e[sel][j])))
            # where one pass's footprint ends (a flat end's rim), the other's
            # height at the last point both cover
            a_, b_ = e[sel], es[sel]
            for x_, y_ in ((a_, b_), (b_[::-1], a_[::-1])):
                end = np.isfinite(x_[:-1]) & ~np.isfinite(x_[1:]) & np.isfinite(y_[:-1])
                if end.any():
                    top = max(top, float(y_[:-1][end].max()))
            worst = max(worst, (top + lift) * nz_)
        return worst

    lo, hi = 0.0, 1.6 * R
    if scallop(hi) <= h:
        return hi
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if scallop(mid) <= h:
            lo = mid
        else:
            hi = mid
    return lo


def _cross_curvature(spec: TipSpec, x: FloatArray, y: FloatArray, clocking: float,
                     grad: FloatArray) -> FloatArray:
    """Normal curvature (1/mm; < 0 convex: the surface falls away from the
    tool) of the CAD cut surface at cannula-frame points (x, y), in the
    direction across passes along ``clocking`` (in the tangent plane, at right
    angles to the passes), from the gradients 2 µm either side. Points within
    2 µm of a ridge between faces (the normal turns by more than 1° between
    the probes) get 0: a ridge is not a curvature (the deviation statistics
    leave ridges out)."""
    e = 2e-3
    gs, ns = [], []
    for dx, dy in ((e, 0.0), (-e, 0.0), (0.0, e), (0.0, -e)):
        _, n = cad_height(spec, x + dx, y + dy, normals=True)
        ns.append(n)
        gs.append(-n[:, :2] / n[:, 2:3])
    hxx, hxy = (gs[0][:, 0] - gs[1][:, 0]) / (2 * e), (gs[0][:, 1] - gs[1][:, 1]) / (2 * e)
    hyy = (gs[2][:, 1] - gs[3][:, 1]) / (2 * e)
    n0 = np.column_stack([-grad, np.ones(len(grad))])
    n0 /= np.linalg.norm(n0, axis=1, keepdims=True)
    cos1 = math.cos(math.radians(1.0))
    ridge = np.any([np.sum(n * n0, axis=1) < cos1 for n in ns], axis=0)
    d = np.array([math.cos(clocking), math.sin(clocking), 0.0])
    t = np.column_stack([np.broadcast_to(d[:2], grad.shape), grad @ d[:2]])
    c = np.cross(n0, t)
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    w = np.sqrt(1.0 + np.sum(grad ** 2, axis=1))
    k = (hxx * c[:, 0] ** 2 + 2 * hxy * c[:, 0] * c[:, 1] + hyy * c[:, 1] ** 2) / w
    out: FloatArray = np.where(ridge, 0.0, k)
    return out


def _ball_stepover(spec: TipSpec, R: float, grad: FloatArray, clocking: float,
                   budget: FloatArray, lift: FloatArray) -> tuple[float, Callable[[float], float]]:
    """The plan step-over (mm) of a ball mill of radius R whose cusp stays
    within ``budget`` (n,) mm normal to the surface at each annulus sample of
    :func:`_clocking` (gradients ``grad``), and the scallop it plans (mm): the
    largest cusp plus ``lift`` (the Z round-up, normal to the surface).

    At a sample the passes lie s·q apart on the surface (q the local
    surface/plan ratio); a ball leaves R − √(R² − (sq)²/4) between them on a
    plane, and (1 + R/ρ) times that where the surface is convex across the
    passes with radius ρ (the cusp of two balls on a cylinder of radius ρ:
    (sq)²/8 · (1/R + 1/ρ) to leading order)."""
    x, y = _annulus_samples(spec.cannula)
    kappa = _cross_curvature(spec, x, y, clocking, grad)
    grow = 1.0 + R * np.maximum(-kappa, 0.0)
    q = _ratio_each(grad, clocking)
    hc = np.minimum(budget / grow, R)
    s_surf = 2.0 * np.sqrt(np.clip(2.0 * R * hc - hc * hc, 0.0, None))
    s = float(np.min(s_surf / q))

    def planned(step: float) -> float:
        ss = step * q
        return float(np.max((R - np.sqrt(np.clip(R * R - ss * ss / 4.0, 0.0, None))) * grow
                            + lift))

    return s, planned


def _ratio_each(grad: FloatArray, clocking: float) -> FloatArray:
    """Surface/plan spacing ratio of passes along ``clocking`` (rad) at each
    gradient (n, 2): √((1 + |g|²)/(1 + (g·d)²))."""
    d = np.array([math.cos(clocking), math.sin(clocking)])
    out: FloatArray = np.sqrt((1.0 + np.sum(grad ** 2, axis=1)) / (1.0 + (grad @ d) ** 2))
    return out


def plan_toolpaths(spec: TipSpec, *, tool: EndMill | None = None,
                   machine: MillMachine | None = None, params: MillParams | None = None,
                   progress: ProgressFn | None = None) -> MillToolpath:
    """Roughing and finishing passes that mill ``spec`` tip-up on ``machine``
    (see the module docstring).

    Parameters
    ----------
    spec : TipSpec — cut faces that are height fields from +Z (bevel,
        multi-plane, lancet, conical, helical)
    tool : EndMill — default the thesis's Ø 1.588 mm carbide ball mill
    machine : MillMachine — default the Haas VF-2
    params : MillParams — scallop, allowance, feeds …
    progress : callable(str), optional — progress lines; default: notes
        through :mod:`tipgeo.progress` (bars are shown there either way)

    Raises
    ------
    CamError — not a height field, scallop unreachable, tool reach, travel,
        spindle or feed limits (naming the axis or parameter, value and limit).

    The stages: the machine's limits on the request (:func:`_check_request`),
    the clocking and the finishing step-over (:func:`_finish_stepover`), the
    set-up (stock top, safe height), roughing (:func:`_rough_passes`),
    finishing (:func:`_finish_passes`), and the tool's reach and the travels
    on the passes (:func:`_check_passes`).
    """
    tool = tool or DEFAULT_TOOL
    mach = machine or MillMachine()
    prm = params or MillParams()
    say = progress_say(progress)
    _check_request(mach, prm)
    res = mach.resolution
    can = spec.cannula
    clock, _, grad = _clocking(spec)
    step = _finish_stepover(spec, tool, prm, res, grad, clock)
    with pg.stage("mill: tip mesh for the drop-cutter"):
        surf = _Surface(spec, clock, tol.cam.mill_mesh)
    z_top = float(_ceil(np.array([surf.z_max + prm.top_stock]), res)[0])
    setup = MillSetup(clock, z_top, float(_ceil(np.array([z_top + prm.safe]), res)[0]),
                      step.stepover, step.ratio, can.r_o, can.r_i)
    stats: dict[str, Any] = {"scallop_planned_um": step.planned * 1e3,
                             "scallop_rounding_um": step.rounding * 1e3}
    passes: list[Pass] = []
    if prm.rough and prm.allowance > 0:
        passes += _rough_passes(spec, tool, prm, setup, res, say, stats)
    passes += _finish_passes(surf, tool, prm, setup, res, say, stats)
    _check_passes(passes, setup, tool, mach)
    return MillToolpath(spec.name or "tip", setup, tool, mach, prm, passes, stats)


def _check_request(mach: MillMachine, prm: MillParams) -> None:
    """The spindle speed and the feeds of ``prm`` inside the machine's ranges,
    or a CamError naming them."""
    mach.check_spindle(prm.spindle_rpm)
    for k in ("finish_feed", "rough_feed", "plunge_feed"):
        mach.check_feed(k, getattr(prm, k))


@dataclass(frozen=True)
class _Step:
    """The finishing step-over (mm, plan, on the axis grid), its worst
    surface/plan ratio, the scallop it plans and the Z round-up's share of
    it (mm, normal to the surface)."""

    stepover: float
    ratio: float
    planned: float
    rounding: float


def _finish_stepover(spec: TipSpec, tool: EndMill, prm: MillParams, res: float,
                     grad: FloatArray, clock: float) -> _Step:
    """The finishing step-over for the scallop target ``prm.scallop`` with
    the Z round-up to the axis resolution ``res`` (mm) budgeted (see the
    module docstring); a CamError when the target cannot be held."""
    h = prm.scallop
    ratio = float(_ratio(grad, np.array([clock]))[0])
    nz = 1.0 / np.sqrt(1.0 + np.sum(grad ** 2, axis=1))
    share = tol.cam.mill_scallop_share
    budget = share * h - res * nz          # normal to the surface, each sample
    if budget.min() <= 0.0:
        k = int(np.argmin(budget))
        raise CamError(f"scallop = {h * 1e3:g} µm cannot be held: Z is rounded up to the axis "
                       f"resolution {res:g} mm, which alone leaves up to {res * nz[k] * 1e3:.3g} "
                       f"µm normal to the surface where its normal has n_z = {nz[k]:.3g}; "
                       f"allowed scallop > {res * nz.max() / share * 1e3:.3g} µm")
    planned: Callable[[float], float] | None = None
    if tool.kind == "ball":
        s, planned = _ball_stepover(spec, tool.corner, grad, clock, budget, res * nz)
    else:   # bull nose, flat end: the scallop of the tool's swept profile on planes
        s = planar_stepover(tool, grad, clock, share * h, lift=res)
    s = min(s, 0.8 * tool.diameter)
    s = math.floor(s / res + tol.cam.mill_grid) * res
    if s < res:
        raise CamError(f"scallop = {h * 1e3:g} µm needs a step-over below the axis resolution "
                       f"{res:g} mm with this tool (corner radius {tool.corner:g} mm)")
    # bull nose and flat end: bounded by share · h
    return _Step(float(s), ratio, planned(s) if planned else share * h, float(res * nz.max()))


def _rough_passes(spec: TipSpec, tool: EndMill, prm: MillParams, setup: MillSetup,
                  res: float, say: ProgressFn, stats: dict[str, Any]) -> list[Pass]:
    """Z-level roughing passes (see the module docstring): lines
    ``rough_stepover`` apart, the drop-cutter of the tool grown by the
    allowance along them, cut level by level ``stepdown`` apart from the
    stock top."""
    a = prm.allowance
    can = spec.cannula
    Ra = tool.radius + a
    with pg.stage("mill: roughing mesh"):
        rsurf = _Surface(spec, setup.clocking, 10 * tol.cam.mill_mesh)
    step = max(res, math.floor(prm.rough_stepover / res) * res)
    dx = max(res, math.floor(prm.rough_sample / res) * res)
    lines: list[tuple[float, FloatArray, BoolArray]] = []
    for y in _grid_values(-(can.r_o + Ra), can.r_o + Ra, step, res):
        xh = math.sqrt(max((can.r_o + Ra) ** 2 - y * y, 0.0))
        x = _grid_values(-xh - dx, xh + dx, dx, res)
        lines.append((float(y), x, _contact(x, float(y), can.r_i - Ra, can.r_o + Ra)))
    xy = np.concatenate([np.stack([x[m], np.full(m.sum(), y)], 1) for y, x, m in lines])
    say(f"roughing: {len(xy)} drop-cutter points")
    with pg.stage("mill: roughing drop-cutter"):
        zall = rsurf.drop(tool.ocl_cutter(a), xy) + a
    stats["rough_drop_points"] = int(len(xy))
    zr_lines = []
    off = 0
    for _y, x, m in lines:
        z = np.full(len(x), np.nan)
        z[m] = zall[off:off + m.sum()]
        off += int(m.sum())
        zr_lines.append(z)
    passes: list[Pass] = []
    prev = setup.z_top
    for lev in _rough_levels(setup.z_top, float(np.nanmin(zall)), prm.stepdown):
        for (y, x, m), z in zip(lines, zr_lines):
            passes += _level_passes(x, y, z, m, m & (z < prev - tol.cam.mill_level), lev,
                                    res, prm.rough_feed)
        prev = lev
    return passes


def _rough_levels(z_top: float, zmin: float, stepdown: float) -> list[float]:
    """The roughing levels (mm): ``stepdown`` apart below ``z_top``, the last
    at ``zmin``."""
    levels = []
    lev = z_top
    while lev > zmin:
        lev = max(lev - stepdown, zmin)
        levels.append(lev)
    return levels


def _level_passes(x: FloatArray, y: float, z: FloatArray, inside: BoolArray, todo: BoolArray,
                  lev: float, res: float, feed: float) -> list[Pass]:
    """The roughing passes of one line y = const at level ``lev``: each run
    of ``todo`` columns, one grid point wider each side, at max(level, the
    allowance surface ``z``) rounded up to the grid (mm); a pass starts
    clear where its first column is not ``inside`` the tool's contact."""
    passes = []
    for i0, i1 in _runs(todo):
        j0, j1 = max(i0 - 1, 0), min(i1 + 1, len(x) - 1)
        zz = np.maximum(lev, z[j0:j1 + 1])
        xx = x[j0:j1 + 1]
        # clear ends: at the neighbouring pass height
        if np.isnan(zz[0]):
            zz[0] = zz[1]
        if np.isnan(zz[-1]):
            zz[-1] = zz[-2]
        zz = _ceil(zz, res)
        passes.append(Pass("rough", np.stack([xx, np.full(len(xx), y), zz], 1), feed,
                           not bool(inside[j0])))
    return passes


def _finish_passes(surf: _Surface, tool: EndMill, prm: MillParams, setup: MillSetup,
                   res: float, say: ProgressFn, stats: dict[str, Any]) -> list[Pass]:
    """The finishing passes: lines ``setup.stepover`` apart across the
    annulus grown by the tool radius, refined by the adaptive drop-cutter
    (:func:`_finish_lines`), with leads to the clear side."""
    R = tool.radius
    r_lo, r_hi = setup.r_i - R, setup.r_o + R
    s = setup.stepover
    ys = _grid_values(-r_hi, r_hi, s, res)
    say(f"finishing: {len(ys)} passes, step-over {s * 1e3:.0f} µm "
        f"(scallop {prm.scallop * 1e3:g} µm)")
    with pg.bar(len(ys), "mill: finishing drop-cutter", unit="pass") as bar:
        lines, calls = _finish_lines(surf, tool.ocl_cutter(), ys, r_hi, r_lo, r_hi, res,
                                     tol.cam.mill_chord, tol.cam.mill_chord_up, bar=bar)
    stats["finish_drop_points"] = int(calls)
    passes = [_with_leads(x, z, y, r_hi, prm.lead, res, prm.finish_feed, "finish")
              for y, runs in lines for x, z in runs]
    if not passes:
        raise CamError("no finishing pass touches the tip")
    return passes


def _check_passes(passes: list[Pass], setup: MillSetup, tool: EndMill,
                  mach: MillMachine) -> None:
    """The tool's reach below the stock top and the machine's travels (with
    the safe height) over every point of ``passes``, or a CamError naming the
    axis, the value and the limit."""
    zlow = min(float(p.points[:, 2].min()) for p in passes if p.kind == "finish")
    depth = setup.z_top - zlow
    if depth > tool.reach:
        raise CamError(f"axis Z: the tool must reach {depth:.3f} mm below the stock top; its "
                       f"reach is {tool.reach:g} mm (tool reach limit)")
    allp = np.concatenate([p.points for p in passes])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    hi[2] = setup.z_safe
    mach.check_travel(lo, hi)
