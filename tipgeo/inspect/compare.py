"""``compare``: scan → registration → signed deviations → measured geometry
→ match check → verdict → report. The public call behind ``tipgeo compare``.

The comparison is a pipeline of named stages, each a public function with a
result type of its own, so a caller can run, inspect or replace any one:

1. load — :func:`stage_load` → :class:`Loaded`: read the scan and the CAD,
   thin the scan (voxel, outliers), refuse a degenerate one;
2. register — :func:`stage_register` → :class:`Placed`: the transform
   scanner frame → cannula frame;
3. deviate — :func:`stage_deviate` → :class:`Deviated`: signed deviations,
   their statistics and the measured geometry;
4. verify — :func:`stage_verify` → :class:`Verified`: does the scan show the
   CAD's part (the match check);
5. decide — :func:`stage_decide` → :class:`Decided`: cutting edges
   (optional), identity, pass or fail under the acceptance rule;
6. report — :func:`stage_report` → :class:`Reported`: report.json,
   report.md, the coloured PLY and the PNGs.

The match check (verify) runs after the deviations: it uses the share of
points near the CAD surface counted in the same pass over the scan, and the
measured diameters. :meth:`Comparison.from_stages` gathers the first four
results into the :class:`Comparison` that decide and report take.

Frames and units: the scan in its scanner frame (mm after ``units``); every
result in the CAD's cannula frame; mm inside, µm and degrees in reports.

Memory: a scan file is read in chunks and kept as float32 offsets from a
float64 origin (:func:`tipgeo.inspect.load_scan` with ``compact=True``: no
coordinate moves by more than 2⁻²¹ mm ≈ 0.0005 µm). Registration works on a
float64 subset; the deviations are computed in float64, chunk by chunk, from
the stored offsets and the registration transform, and kept in float64; the
registered points, closest points and normals are kept in float32 (cannula
frame, |x| of a few mm: rounding ≤ 0.0005 µm), face ids in int16. A scan of
2·10⁷ points thus peaks at about 1.6 GB instead of 4.5 GB.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import AnyArray, BoolArray, FloatArray, IntArray
from ..errors import NotThisTip, SpecError
from ..tolerances import tol
from .cad import CadModel, load_cad
from .checks import check_geometry, check_match
from .deviation import histogram, statistics
from .exact import Distances
from .measure import measure
from .meshdist import MeshSolid
from .pages import ordinary_pages
from .register import Registration, apply, register
from .scanio import Scan, ScanError, check_points, load_scan
from .transform import check_transform

if TYPE_CHECKING:
    from ..verdict import Verdict
    from .acceptance import AcceptanceRule
    from .edgescan import MeasuredEdges
    from .identity import Identity

__all__ = ["Comparison", "compare", "crop", "voxel_down_sample", "remove_outliers",
           "estimate_normals", "Loaded", "Placed", "Deviated", "Verified", "Decided",
           "Reported", "stage_load", "stage_register", "stage_deviate", "stage_verify",
           "stage_decide", "stage_report", "default_rule"]

#: A stage message sink (``tipgeo.progress`` or ``print``).
Progress = Callable[[str], None]

#: Share of each face's points the default acceptance rule wants within ± tolerance.
DEFAULT_SHARE = 0.95

#: Half-range of the default colour map, in tolerances.
COLOUR_SCALE_PER_TOLERANCE = 2.5


@dataclass
class Comparison:
    """Everything a comparison found.

    Attributes
    ----------
    scan : Scan — as read (scanner frame)
    cad : CadModel
    registration : Registration or None — None when the scan was already in
        the cannula frame (``register=False``)
    points : (m, 3) float32 — the compared points in the cannula frame (mm)
    distances : Distances — their signed deviations
    stats : dict — :func:`tipgeo.inspect.deviation.statistics`
    measured : dict — :func:`tipgeo.inspect.measure.measure`
    tolerance : float — mm
    colour_scale : float — half-range of the colour map (mm; the larger of
        the two ends of ``colour_range``)
    index : (m,) int — row of each compared point in the scan as read (input
        order kept: increasing)
    colour_range : (2,) float — low and high end of the colour map (mm)
    colormap : str — matplotlib colormap name
    dropped : dict — points left out (crop, far from the CAD)
    timings : dict — seconds per stage (wall clock)
    cpu_timings : dict — CPU seconds of this process per stage
    outputs : list of Path
    match : dict — :func:`tipgeo.inspect.checks.check_match` (inlier share,
        fitness, diameters, problems)
    notes : list of str — further warnings (a mismatch let through)
    edges : MeasuredEdges or None — cutting edges and angles measured on the
        scan (``compare(..., angles=True)``)
    rule : AcceptanceRule — the acceptance rule (:mod:`.acceptance`)
    verdict : Verdict — pass or fail under ``rule``, with the figures and reasons
    identity : Identity — is the scan this kind of tip (:mod:`.identity`: gauge,
        cut-face shape, serrations), checked before the verdict's bands
    """

    scan: Scan
    cad: CadModel
    registration: Registration | None
    points: AnyArray
    distances: Distances
    stats: dict[str, Any]
    measured: dict[str, Any]
    tolerance: float
    colour_scale: float
    dropped: dict[str, int] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)
    index: IntArray | None = None
    colour_range: tuple[float, float] | None = None
    colormap: str = "RdYlBu_r"
    outputs: list[Path] = field(default_factory=list)
    match: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    edges: MeasuredEdges | None = None
    rule: AcceptanceRule | None = None
    verdict: Verdict | None = None
    identity: Identity | None = None

    @classmethod
    def from_stages(cls, loaded: Loaded, placed: Placed, deviated: Deviated,
                    verified: Verified, *, colour_scale: float | None = None,
                    colour_range: tuple[float, float] | None = None,
                    colormap: str | None = None) -> Comparison:
        """The comparison of the first four stages' results (before the
        verdict: ``stage_decide`` fills in ``edges``, ``identity``, ``rule``
        and ``verdict``). ``colour_scale`` (mm) defaults to 2.5 × the
        tolerance of ``deviated``; ``colour_range`` (mm, low < 0 < high)
        overrides it; ``colormap`` defaults to ``RdYlBu_r``."""
        scale, rng = _colour_options(deviated.tolerance, colour_scale, colour_range)
        if colormap is not None:
            _check_colormap(colormap)
        timings = {**loaded.timings, **placed.timings, **deviated.timings}
        cpu = {**loaded.cpu_timings, **placed.cpu_timings, **deviated.cpu_timings}
        return cls(loaded.scan, loaded.cad, placed.registration, deviated.points,
                   deviated.distances, deviated.stats, deviated.measured, deviated.tolerance,
                   scale, {**loaded.dropped, **deviated.dropped}, timings, cpu,
                   index=deviated.index, colour_range=rng, colormap=colormap or "RdYlBu_r",
                   match=verified.match, notes=list(verified.notes))

    @property
    def colour_limits(self) -> tuple[float, float]:
        """(low, high) of the colour map (mm)."""
        if self.colour_range is None:
            return -self.colour_scale, self.colour_scale
        return self.colour_range

    @property
    def warnings(self) -> list[str]:
        """The registration's, the CAD's and the comparison's warnings."""
        w = list(self.registration.warnings) if self.registration else []
        return w + list(self.cad.notes) + list(self.notes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready report."""
        return {"scan": {"source": self.scan.source, "points": len(self.scan),
                         **{k: v for k, v in self.scan.meta.items() if k != "points"}},
                "cad": self.cad.summary(),
                "compared_points": int(len(self.points)),
                "dropped_points": dict(self.dropped),
                "sign_convention": "positive: scan outside the CAD solid (excess material); "
                                   "negative: inside (missing material)",
                "tolerance_um": self.tolerance * 1e3,
                "colour_scale_um": [x * 1e3 for x in self.colour_limits],
                "colormap": self.colormap,
                "registration": self.registration.to_dict() if self.registration else None,
                "deviation": self.stats,
                "features": {"face": int(np.sum(self.distances.feature == 0)),
                             "edge": int(np.sum(self.distances.feature == 1)),
                             "vertex": int(np.sum(self.distances.feature == 2))},
                "measured": self.measured,
                "match": self.match,
                "acceptance": self.rule.to_dict() if self.rule is not None else None,
                "verdict": self.verdict.to_dict() if self.verdict is not None else None,
                "identity": self.identity.to_dict() if self.identity is not None else None,
                "warnings": self.warnings,
                **({"measured_edges": self.edges.summary()} if self.edges is not None else {}),
                "timings_s": dict(self.timings),
                "cpu_s": dict(self.cpu_timings),
                "outputs": [str(o) for o in self.outputs]}


# -----------------------------------------------------------------------------
# pre-processing
def crop(points: AnyArray, *, z_min: float | None = None, z_max: float | None = None,
         radius: float | None = None) -> BoolArray:
    """(n,) bool — points (cannula frame, mm) with z_min ≤ z ≤ z_max and
    distance to the axis ≤ radius (each bound optional)."""
    keep = np.ones(len(points), bool)
    if z_min is not None:
        keep &= points[:, 2] >= z_min
    if z_max is not None:
        keep &= points[:, 2] <= z_max
    if radius is not None:
        keep &= np.hypot(points[:, 0], points[:, 1]) <= radius
    return keep


def voxel_down_sample(points: AnyArray, voxel: float) -> IntArray:
    """Indices of one point per occupied voxel of edge ``voxel`` (mm): the
    point nearest the voxel's centroid (so no coordinate is averaged)."""
    if not voxel > 0:
        raise SpecError(f"voxel = {voxel!r} mm; allowed > 0")
    key = np.floor((points - points.min(axis=0)) / voxel).astype(np.int64)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    cen = np.zeros((len(cnt), 3))
    np.add.at(cen, inv, points)
    cen /= cnt[:, None]
    d = np.linalg.norm(points - cen[inv], axis=1)
    order = np.lexsort((d, inv))
    first = np.ones(len(order), bool)
    first[1:] = inv[order][1:] != inv[order][:-1]
    return np.sort(order[first])


def remove_outliers(points: AnyArray, *, neighbours: int = 8, ratio: float = 3.0) -> BoolArray:
    """(n,) bool — statistical outlier removal: keep points whose mean
    distance to their ``neighbours`` nearest points is within ``ratio``
    standard deviations of the mean."""
    from scipy.spatial import cKDTree

    if len(points) <= neighbours + 1:
        return np.ones(len(points), bool)
    d, _ = cKDTree(points).query(points, k=neighbours + 1, workers=-1)
    m = d[:, 1:].mean(axis=1)
    keep: BoolArray = m <= m.mean() + ratio * m.std()
    return keep


def estimate_normals(points: AnyArray, *, neighbours: int = 12) -> FloatArray:
    """(n, 3) unit normals by local PCA (sign arbitrary)."""
    from .register import point_normals

    return point_normals(points, neighbours)


# -----------------------------------------------------------------------------
class _ScanDistances(Distances):
    """:class:`Distances` of a scan on the mesh path: the closest points and
    normals (two (m, 3) arrays that ``compare`` itself does not need) are
    computed on first use from each point's triangle, the same values bit
    for bit (:meth:`MeshSolid.closest_normals`)."""

    def __init__(self, distance: FloatArray, face: IntArray, feature: IntArray,
                 labels: tuple[str, ...],
                 fill: Callable[[], tuple[AnyArray, AnyArray]],
                 fill_rows: Callable[[IntArray], tuple[AnyArray, AnyArray]]) -> None:
        self.distance, self.face, self.feature, self.labels = distance, face, feature, labels
        self._fill: Callable[[], tuple[AnyArray, AnyArray]] | None = fill
        self._fill_rows = fill_rows
        self._cn: tuple[AnyArray, AnyArray] | None = None

    def take(self, sel: IntArray) -> _ScanDistances:
        """The distances of the rows ``sel`` alone, their closest points and
        normals made on first use for those rows only (in float64)."""
        rows_of = self._fill_rows
        return _ScanDistances(self.distance[sel], self.face[sel], self.feature[sel], self.labels,
                              lambda: rows_of(sel), lambda sub: rows_of(sel[sub]))

    def _pair(self) -> tuple[AnyArray, AnyArray]:
        if self._cn is None:
            assert self._fill is not None  # set until the first call
            self._cn = self._fill()
            self._fill = None
        return self._cn

    @property
    def closest(self) -> AnyArray:  # type: ignore[override]  # a field of Distances, computed here on first use
        return self._pair()[0]

    @property
    def normal(self) -> AnyArray:  # type: ignore[override]  # a field of Distances, computed here on first use
        return self._pair()[1]


def _now() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _lap(cpu: dict[str, float], name: str, since: tuple[float, float]) -> float:
    """Wall seconds since ``since``; CPU seconds (this process) into ``cpu``."""
    cpu[name] = time.process_time() - since[1]
    return time.perf_counter() - since[0]


def _shift(v: AnyArray) -> FloatArray:
    T = np.eye(4)
    T[:3, 3] = v
    return T


def _take(mask: BoolArray, *arrays: AnyArray) -> tuple[AnyArray, ...]:
    """The rows of ``arrays`` where ``mask`` holds (no copy when all do)."""
    if mask.all():
        return arrays
    return tuple(a[mask] for a in arrays)


def _deviations(model: CadModel, local: AnyArray, T: FloatArray, *, z_min: float | None,
                max_distance: float,
                chunk: int) -> tuple[AnyArray, Distances, IntArray, dict[str, int]]:
    """Signed deviations of ``local`` (offsets, any float) mapped by ``T``
    into the cannula frame, chunk by chunk in float64. Points that cannot lie
    within ``max_distance`` of the CAD (outside its bounding cylinder grown by
    it) skip the exact query; the rest are kept when |d| ≤ max_distance.

    Returns the kept points (float32), their Distances, their rows in
    ``local`` (int64, increasing: input order kept) and counts: cropped, far,
    compared (after the crop), in the envelope (the bounding cylinder grown by
    ``max_distance``), within ``tol.inspect.match_distance``."""
    m = len(local)
    engine = getattr(model, "engine", None)
    mesh = engine if isinstance(engine, MeshSolid) else None
    P = np.empty((m, 3), np.float32)
    rows = np.empty(m, np.int64)
    dist = np.empty(m)
    # the mesh path keeps each point's triangle instead of its closest point
    # and normal (24 bytes a point fewer to write, computed when asked for)
    k3 = 0 if mesh is not None else m
    # (none on the mesh path: float64 there, the dtype of MeshSolid.distances,
    # so that both use one compiled signature of the kernel)
    clo = np.empty((k3, 3), np.float32 if k3 else np.float64)
    nrm = np.empty((k3, 3), np.float32 if k3 else np.float64)
    tri = np.empty(m if mesh is not None else 0, np.int32)
    face = np.empty(m, np.int16)
    feat = np.empty(m, np.int8)
    cnt = {"crop": 0, "far": 0, "compared": 0, "envelope": 0, "match": 0}
    reach = model.r_o + max_distance
    z_lo, z_hi = model.z_base - max_distance, model.z_top + max_distance
    cur = 0

    from .nearest import transform_envelope

    q_buf = np.empty((min(chunk, m), 3))
    r_buf = np.empty(min(chunk, m), np.int64)
    # the exact query's work buffers, reused by every chunk
    work = mesh.work_buffers(min(chunk, m)) if mesh is not None else None
    if mesh is not None:
        mesh.prepare(m)
    R, t = np.ascontiguousarray(T[:3, :3], float), np.ascontiguousarray(T[:3, 3], float)
    for i in range(0, m, chunk):
        # R x + t, the crop and the envelope in one compiled pass (float64)
        kept, cropped = transform_envelope(local[i:i + chunk], R, t, z_min is not None,
                                           -np.inf if z_min is None else float(z_min), reach,
                                           z_lo, z_hi, q_buf, r_buf, i)
        cnt["crop"] += cropped
        cnt["compared"] += min(chunk, m - i) - cropped
        cnt["envelope"] += kept
        if not kept:
            continue
        q, r = q_buf[:kept], r_buf[:kept]
        if mesh is not None:  # into the results directly
            cur, near = mesh.distances_into(
                q, r, far=max_distance, near=tol.inspect.match_distance,
                out=(P, dist, clo, nrm, face, feat, rows), cur=cur, tri=tri, work=work)
            cnt["match"] += near
            continue
        D = model.distances(q)
        ad = np.abs(D.distance)
        cnt["match"] += int(np.count_nonzero(ad <= tol.inspect.match_distance))
        ok = ad <= max_distance
        k = int(np.count_nonzero(ok))
        sl = slice(cur, cur + k)
        P[sl], dist[sl], clo[sl], nrm[sl], face[sl], feat[sl], rows[sl] = _take(
            ok, q, D.distance, D.closest, D.normal, D.face, D.feature, r)
        cur += k
    cnt["far"] = cnt["compared"] - cur
    if mesh is not None:
        kept_rows, tk, solid = rows[:cur], tri[:cur], mesh
        D = _ScanDistances(dist[:cur], face[:cur], feat[:cur], tuple(model.labels),
                           lambda: solid.closest_normals(local, kept_rows, T, tk),
                           lambda sel: solid.closest_normals(local, kept_rows[sel], T, tk[sel],
                                                             np.float64))
        return P[:cur], D, kept_rows, cnt
    return P[:cur], Distances(dist[:cur], clo[:cur], nrm[:cur], face[:cur], feat[:cur],
                              tuple(model.labels)), rows[:cur], cnt


# -----------------------------------------------------------------------------
# options, checked before any work
def _quiet(msg: str) -> None:
    """The default progress: say nothing."""


def _positive(name: str, value: float) -> float:
    if not (np.isfinite(value) and value > 0):
        raise SpecError(f"{name} = {value!r} mm; allowed > 0")
    return float(value)


def _colour_options(tolerance: float, colour_scale: float | None,
                    colour_range: tuple[float, float] | None
                    ) -> tuple[float, tuple[float, float] | None]:
    """(half-range, (low, high) or None) of the colour map (mm), checked."""
    _positive("tolerance", tolerance)
    scale = _positive("colour_scale", COLOUR_SCALE_PER_TOLERANCE * tolerance
                      if colour_scale is None else float(colour_scale))
    if colour_range is None:
        return scale, None
    lo_c, hi_c = (float(x) for x in colour_range)
    if not (np.isfinite(lo_c) and np.isfinite(hi_c) and lo_c < 0 < hi_c):
        raise SpecError(f"colour_range = {tuple(colour_range)!r} mm; allowed low < 0 < high")
    return max(-lo_c, hi_c), (lo_c, hi_c)


def _check_colormap(colormap: str) -> None:
    import matplotlib

    if colormap not in matplotlib.colormaps:
        raise SpecError(f"colormap = {colormap!r} is not a matplotlib colormap; e.g. "
                        "RdYlBu_r, coolwarm, jet, viridis")


def _check_crop(z_min: float | None, max_distance: float) -> None:
    _positive("max_distance", max_distance)
    if z_min is not None and not np.isfinite(z_min):
        raise SpecError(f"z_min = {z_min!r} mm; allowed a finite value")


def default_rule(tolerance: float) -> AcceptanceRule:
    """The acceptance rule when none is given: ± ``tolerance`` (mm) on 95 %
    of each face's points."""
    from .acceptance import AcceptanceRule, Band

    return AcceptanceRule(Band(tolerance, DEFAULT_SHARE))


# -----------------------------------------------------------------------------
# stage 1: load
@dataclass
class Loaded:
    """What :func:`stage_load` read: the scan and the CAD, ready to register.

    Attributes
    ----------
    scan : Scan — as read (scanner frame, mm)
    cad : CadModel — the CAD tip (cannula frame, mm)
    local : (m, 3) float32 or float64 — the points kept (after ``voxel`` and
        ``outliers``) as offsets from ``origin`` (mm, scanner frame axes)
    origin : (3,) float64 — mm, scanner frame
    rows : (m,) int64 or None — row of each kept point in the scan as read
        (increasing; None: every row, in order)
    dropped : dict — points left out, by reason (``voxel``, ``outliers``)
    timings, cpu_timings : dict — wall and CPU seconds of ``load_scan`` and
        ``load_cad``
    """

    scan: Scan
    cad: CadModel
    local: AnyArray
    origin: FloatArray
    rows: IntArray | None = None
    dropped: dict[str, int] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)

    @property
    def where(self) -> str:
        """The scan, named for messages."""
        return f"scan '{self.scan.source}'"


def _read_scan(scan: Scan | str | Path | AnyArray, units: str, say: Progress) -> Scan:
    if isinstance(scan, Scan):
        return scan
    if isinstance(scan, (str, Path)):
        say(f"reading {scan}")
        return load_scan(scan, units=units, compact=True)
    return Scan(check_points(scan, "scan"))


def _thin(local: AnyArray, voxel: float | None,
          outliers: bool) -> tuple[AnyArray, IntArray | None, dict[str, int]]:
    """(kept offsets, their rows or None, dropped counts)."""
    dropped: dict[str, int] = {}
    src: IntArray | None = None
    if voxel:
        idx = voxel_down_sample(local, voxel)
        dropped["voxel"] = int(len(local) - len(idx))
        local, src = local[idx], idx
    if outliers:
        keep = remove_outliers(local)
        dropped["outliers"] = int((~keep).sum())
        local = local[keep]
        src = np.flatnonzero(keep) if src is None else src[keep]
    return local, src, dropped


def stage_load(scan: Scan | str | Path | AnyArray, cad: Any, *, units: str = "mm",
               voxel: float | None = None, outliers: bool = False,
               register_scan: bool = True, progress: Progress | None = None) -> Loaded:
    """Stage 1 of :func:`compare`: read the scan and the CAD, thin the scan,
    and refuse one that no comparison can use.

    Parameters
    ----------
    scan : path, Scan or (n, 3) array — the scan (scanner frame; a file in
        ``units``: 'mm', 'um' or 'm')
    cad : TipSpec, Tip, CadModel, spec/mesh path or preset name
    voxel : float — keep one point per voxel of this edge (mm)
    outliers : bool — statistical outlier removal
    register_scan : bool — the scan will be registered (a flat scan is
        refused then unless the CAD has a planar cut face)
    progress : callable(str) — stage messages

    Raises
    ------
    ScanError — unreadable, empty, non-finite or degenerate scan
        (:func:`tipgeo.inspect.checks.check_geometry`)
    """
    from .register import planar_cut_faces

    say = progress or _quiet
    cpu: dict[str, float] = {}
    t = _now()
    sc = _read_scan(scan, units, say)
    timings = {"load_scan": _lap(cpu, "load_scan", t)}
    say(f"{len(sc):,} points read in {timings['load_scan']:.2f} s")
    t = _now()
    model = cad if isinstance(cad, CadModel) else load_cad(cad)
    timings["load_cad"] = _lap(cpu, "load_cad", t)
    loc, src, dropped = _thin(sc.local, voxel, outliers)
    res = Loaded(sc, model, loc, np.asarray(sc.origin, float), src, dropped, timings, cpu)
    check_geometry(loc, model.r_o, register=register_scan, origin=res.origin, where=res.where,
                   allow_plane=bool(planar_cut_faces(model)))
    return res


# -----------------------------------------------------------------------------
# stage 2: register
@dataclass
class Placed:
    """Where :func:`stage_register` put the scan.

    Attributes
    ----------
    registration : Registration or None — None when the scan was not
        registered; its ``transform`` maps the scanner frame to the cannula
        frame (mm)
    transform : (4, 4) float64 — the stored offsets (``Loaded.local``) →
        cannula frame (mm)
    scanner_to_cannula : (4, 4) float64 — scanner frame → cannula frame (mm)
    timings, cpu_timings : dict — wall and CPU seconds of ``register``
    """

    registration: Registration | None
    transform: FloatArray
    scanner_to_cannula: FloatArray
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)


def _registered(loaded: Loaded, init_transform: FloatArray | None, seed: int,
                allow_mismatch: bool, say: Progress) -> tuple[Registration, FloatArray]:
    """The registration (its transform and axis in the scanner frame) and
    the offsets → cannula frame transform."""
    origin, loc, where = loaded.origin, loaded.local, loaded.where
    try:
        start = loc if init_transform is None else apply(init_transform @ _shift(origin), loc)
        reg = register(start, loaded.cad, seed=seed, progress=lambda m: say(f"  {m}"),
                       max_diameter_error=None if allow_mismatch else tol.inspect.match_diameter)
    except ScanError as e:
        if "another gauge" in str(e):
            raise NotThisTip(f"{where}: {e} (--allow-mismatch compares it anyway)") from None
        raise ScanError(f"{where}: {e}") from None
    if init_transform is None:
        T_loc = reg.transform          # offsets → cannula frame
        reg.axis["point_mm"] = (np.asarray(reg.axis["point_mm"]) + origin).tolist()
    else:
        T_loc = reg.transform @ init_transform @ _shift(origin)
        reg.axis["point_mm"] = apply(np.linalg.inv(init_transform),
                                     np.asarray([reg.axis["point_mm"]]))[0].tolist()
    reg.transform = T_loc @ _shift(-origin)   # scanner frame → cannula frame
    return reg, T_loc


def stage_register(loaded: Loaded, *, register_scan: bool = True,
                   init_transform: AnyArray | None = None, seed: int = 0,
                   allow_mismatch: bool = False, progress: Progress | None = None) -> Placed:
    """Stage 2 of :func:`compare`: the rigid transform scanner frame →
    cannula frame (mm; +z along the axis toward the tip).

    Parameters
    ----------
    loaded : Loaded — from :func:`stage_load`
    register_scan : bool — False: the scan is already in the cannula frame
        (or ``init_transform`` takes it there)
    init_transform : (4, 4) float — scanner frame → cannula frame to start
        from (mm): the whole transform without registration, its starting
        pose with it
    seed : int — of the registration's random subsets
    allow_mismatch : bool — do not refuse a scan of another gauge

    Raises
    ------
    ScanError — the registration found no pose (no outer wall, a plane);
    NotThisTip — the fitted diameter is another gauge's (unless ``allow_mismatch``)
    """
    say = progress or _quiet
    T0 = None if init_transform is None else check_transform(init_transform, "init_transform")
    cpu: dict[str, float] = {}
    t = _now()
    reg: Registration | None = None
    if register_scan:
        say("registering")
        reg, T_loc = _registered(loaded, T0, seed, allow_mismatch, say)
    else:
        T_loc = _shift(loaded.origin) if T0 is None else T0 @ _shift(loaded.origin)
    timings = {"register": _lap(cpu, "register", t)}
    if reg:
        say(f"registered in {timings['register']:.2f} s: fitness {reg.fitness:.3f}, inlier "
            f"RMSE {reg.inlier_rmse * 1e3:.3f} µm")
    return Placed(reg, T_loc, T_loc @ _shift(-loaded.origin), timings, cpu)


# -----------------------------------------------------------------------------
# stage 3: deviate
@dataclass
class Deviated:
    """What :func:`stage_deviate` found: signed deviations and measured geometry.

    Attributes
    ----------
    points : (m, 3) float32 — the compared points, cannula frame (mm)
    distances : Distances — their signed deviations (mm; > 0 outside the CAD
        solid, excess material)
    index : (m,) int64 — row of each compared point in the scan as read
        (increasing)
    counts : dict — points ``crop``-ped, ``far`` from the CAD, ``compared``
        (after the crop), in the ``envelope`` (the CAD's bounding cylinder grown
        by ``max_distance``), within ``tol.inspect.match_distance`` (``match``)
    stats : dict — :func:`tipgeo.inspect.deviation.statistics` with
        ``trimmed`` and ``histogram``
    measured : dict — :func:`tipgeo.inspect.measure.measure`
    tolerance, max_distance : float — mm, as given
    dropped : dict — points left out (``crop``, ``far``)
    timings, cpu_timings : dict — ``deviations``, ``statistics``, ``measure``
    """

    points: AnyArray
    distances: Distances
    index: IntArray
    counts: dict[str, int]
    stats: dict[str, Any]
    measured: dict[str, Any]
    tolerance: float
    max_distance: float
    dropped: dict[str, int] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)

    @property
    def rms(self) -> float:
        """RMS of the signed deviations (mm)."""
        return float(np.sqrt(np.mean(np.square(self.distances.distance))))


def _dropped(cnt: dict[str, int], z_min: float | None) -> dict[str, int]:
    out: dict[str, int] = {}
    if z_min is not None:
        out["crop"] = cnt["crop"]
    if cnt["far"]:
        out["far"] = cnt["far"]
    return out


def stage_deviate(loaded: Loaded, placed: Placed, *, tolerance: float = 0.01,
                  z_min: float | None = None, max_distance: float = 0.5,
                  histogram_range: tuple[float, float] | None = None,
                  progress: Progress | None = None) -> Deviated:
    """Stage 3 of :func:`compare`: every point's signed deviation from the
    CAD (cannula frame, mm; exact in float64), their statistics per face
    and the measured geometry (diameters, cut-face angles, tip).

    Parameters
    ----------
    loaded, placed : the results of :func:`stage_load` and :func:`stage_register`
    tolerance : float — ± band of the statistics (mm)
    z_min : float — compare only points with z ≥ z_min (mm, cannula frame)
    max_distance : float — points farther than this from the CAD are left
        out as not belonging to the part (mm)
    histogram_range : (low, high) float — mm; default ± 2.5 × tolerance

    Raises
    ------
    ScanError — no point left after the crop, or none within ``max_distance``
    """
    _positive("tolerance", tolerance)
    _check_crop(z_min, max_distance)
    lo_h, hi_h = _colour_options(tolerance, None, histogram_range)[1] or (
        -COLOUR_SCALE_PER_TOLERANCE * tolerance, COLOUR_SCALE_PER_TOLERANCE * tolerance)
    say = progress or _quiet
    model, cpu = loaded.cad, dict[str, float]()
    t = _now()
    say(f"deviations of {len(loaded.local):,} points ({model.method})")
    pts, dist, rows, cnt = _deviations(model, loaded.local, placed.transform, z_min=z_min,
                                       max_distance=max_distance, chunk=tol.inspect.chunk)
    timings = {"deviations": _lap(cpu, "deviations", t)}
    if not cnt["compared"]:
        raise ScanError(f"no scan points left to compare after cropping at z_min = {z_min} mm")
    if not len(pts):
        raise ScanError(f"{loaded.where}: none of its {cnt['compared']:,} points lies within "
                        f"{max_distance} mm of the CAD surface; wrong tip, units or "
                        "registration?")
    say(f"deviations in {timings['deviations']:.2f} s")
    t = _now()
    stats = statistics(dist.distance, dist.face, tolerance, names=dist.labels,
                       trim_sigmas=tol.inspect.trim_sigmas)
    stats["histogram"] = histogram(dist.distance, lo_h, hi_h, tol.inspect.histogram_bins)
    timings["statistics"] = _lap(cpu, "statistics", t)
    t = _now()
    measured = measure(pts, dist, model)
    timings["measure"] = _lap(cpu, "measure", t)
    index = rows if loaded.rows is None else loaded.rows[rows]
    return Deviated(pts, dist, index, cnt, stats, measured, float(tolerance),
                    float(max_distance), _dropped(cnt, z_min), timings, cpu)


# -----------------------------------------------------------------------------
# stage 4: verify
@dataclass
class Verified:
    """What :func:`stage_verify` concluded: does the scan show the CAD's part.

    Attributes
    ----------
    match : dict — :func:`tipgeo.inspect.checks.check_match` (``ok``,
        inlier share, fitness, diameters, ``problems``)
    notes : list of str — warnings for the report (far points, a mismatch
        let through)
    """

    match: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """The scan matches the CAD."""
        return bool(self.match.get("ok", False))


def stage_verify(loaded: Loaded, placed: Placed, deviated: Deviated, *,
                 allow_mismatch: bool = False) -> Verified:
    """Stage 4 of :func:`compare`: the match check — at least
    ``tol.inspect.match_min_share`` of the points in the CAD's envelope within
    ``tol.inspect.match_distance`` (mm) of its surface (background far from
    the part does not count), a registration fitness of at least
    ``tol.inspect.match_min_fitness``, fitted diameters within
    ``tol.inspect.match_diameter`` of the CAD's.

    Warns (``Verified.notes``) when more than ``tol.inspect.far_share_warn``
    of the compared points lie beyond ``max_distance``.

    Raises
    ------
    NotThisTip — the scan does not match, unless ``allow_mismatch`` (then a note)
    """
    reg, cnt, model = placed.registration, deviated.counts, loaded.cad
    share = cnt["match"] / cnt["envelope"]
    match = check_match(model, share=share, fitness=reg.fitness if reg else None,
                        registered_od=reg.axis["outer_diameter_mm"] if reg else None,
                        measured=deviated.measured)
    notes = []
    far_share = cnt["far"] / cnt["compared"]
    if far_share > tol.inspect.far_share_warn:
        notes.append(f"{100 * far_share:.2f} % of the compared points ({cnt['far']:,} of "
                     f"{cnt['compared']:,}) lie farther than {deviated.max_distance:g} mm from "
                     f"the CAD surface (more than {100 * tol.inspect.far_share_warn:g} %): gross "
                     "outliers, a fixture in the scan or a wrong registration; they are left "
                     "out of the statistics")
    if not match["ok"]:
        msg = (f"{loaded.where} does not match the CAD '{model.name}': "
               + "; ".join(match["problems"]))
        if not allow_mismatch:
            raise NotThisTip(msg + " (--allow-mismatch compares it anyway)")
        notes.append(msg + " (compared anyway: --allow-mismatch)")
    return Verified(match, notes)


# -----------------------------------------------------------------------------
# stage 5: decide
@dataclass
class Decided:
    """What :func:`stage_decide` judged.

    Attributes
    ----------
    rule : AcceptanceRule — the rule applied
    verdict : Verdict — pass or fail, with each check's figure and reason
    identity : Identity — gauge, cut-face shape and serrations checks
    edges : MeasuredEdges or None — cutting edges measured on the scan (``angles``)
    timings, cpu_timings : dict — ``edges`` (when measured) and ``identity``
    """

    rule: AcceptanceRule
    verdict: Verdict
    identity: Identity
    edges: MeasuredEdges | None = None
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """The verdict is a pass."""
        return bool(self.verdict.ok)


def stage_decide(res: Comparison, rule: AcceptanceRule | None = None, *, angles: bool = False,
                 edge_band: float | None = None, progress: Progress | None = None) -> Decided:
    """Stage 5 of :func:`compare`: pass or fail of ``res`` under ``rule``
    (default ± ``res.tolerance`` on 95 % of each face's points). With
    ``angles`` the cutting edges are traced on the scan first
    (:func:`tipgeo.inspect.measure_edges`, ``edge_band`` in mm). Never a pass
    for a scan that is not this tip (:mod:`.identity`) or whose registration
    is not certain.

    ``res`` gets ``rule``, ``edges``, ``identity`` and ``verdict`` (the report
    shows them); its timings get ``edges`` and ``identity`` (seconds).
    """
    from .acceptance import judge
    from .identity import identify

    say = progress or _quiet
    res.rule = rule if rule is not None else default_rule(res.tolerance)
    if angles:
        from .edgescan import measure_edges

        t = _now()
        say("tracing the cutting edges")
        res.edges = measure_edges(res.points, res.cad, edge_band=edge_band,
                                  progress=lambda m: say(f"  {m}"))
        res.timings["edges"] = _lap(res.cpu_timings, "edges", t)
    t = _now()
    res.identity = identify(res)
    res.timings["identity"] = _lap(res.cpu_timings, "identity", t)
    res.verdict = judge(res, res.rule)
    say(res.verdict.line())
    keys = ("edges", "identity")
    return Decided(res.rule, res.verdict, res.identity, res.edges,
                   {k: res.timings[k] for k in keys if k in res.timings},
                   {k: res.cpu_timings[k] for k in keys if k in res.cpu_timings})


# -----------------------------------------------------------------------------
# stage 6: report
@dataclass
class Reported:
    """What :func:`stage_report` wrote.

    Attributes
    ----------
    folder : Path — the report folder
    outputs : list of Path — the files, in the order written
    """

    folder: Path
    outputs: list[Path]


def stage_report(res: Comparison, out: str | Path, *, pictures: bool = True,
                 progress: Progress | None = None) -> Reported:
    """Stage 6 of :func:`compare`: write report.json, report.md,
    deviations.ply and (with ``pictures``) the PNGs into the folder ``out``
    — all or nothing (:func:`tipgeo.inspect.report.write_report`)."""
    from .report import write_report

    say = progress or _quiet
    say(f"writing the report to {out}")
    return Reported(Path(out), write_report(res, out, pictures=pictures))


# -----------------------------------------------------------------------------
def compare(scan: Scan | str | Path | AnyArray, cad: Any, *, tolerance: float = 0.01,
            units: str = "mm", register_scan: bool = True, z_min: float | None = None,
            voxel: float | None = None, outliers: bool = False,
            max_distance: float = 0.5, colour_scale: float | None = None,
            out: str | Path | None = None, pictures: bool = True, seed: int = 0,
            progress: Progress | None = None, allow_mismatch: bool = False,
            angles: bool = False, edge_band: float | None = None,
            init_transform: AnyArray | None = None,
            colour_range: tuple[float, float] | None = None,
            colormap: str | None = None,
            acceptance: AcceptanceRule | None = None) -> Comparison:
    """Compare a scan with a CAD tip, and judge it: the six stages
    (:func:`stage_load` → :func:`stage_register` → :func:`stage_deviate` →
    :func:`stage_verify` → :func:`stage_decide` → :func:`stage_report`) in a row,
    every option checked before any work.

    Parameters
    ----------
    scan : path, Scan or (n, 3) array — the scan (scanner frame)
    cad : TipSpec, Tip, CadModel, spec/mesh path or preset name
    tolerance : float — ± tolerance band (mm)
    acceptance : AcceptanceRule, optional — the rule of the verdict
        (:mod:`tipgeo.inspect.acceptance`); default ± ``tolerance`` on 95 %
        of each face's points. The result's ``verdict`` is never a pass for a
        scan that is not this tip or whose registration is not certain.
    units : {'mm', 'um', 'm'} — units of a scan file
    register_scan : bool — False when the scan is already in the cannula frame
    z_min : float — compare only points with z ≥ z_min after registration (mm)
    voxel : float — thin the scan to one point per voxel first (mm)
    outliers : bool — statistical outlier removal before comparing
    max_distance : float — points farther than this from the CAD are left
        out of the statistics as not belonging to the part (mm)
    colour_scale : float — half-range of the colour map (mm; default 2.5 ×
        tolerance)
    out : path — write report.json, report.md, deviations.ply and the PNGs here
        (all or nothing: on a failure no new file is left there)
    pictures : bool — write the PNGs
    progress : callable(str) — stage messages
    allow_mismatch : bool — a scan that does not match the CAD (see Raises)
        is compared anyway, with a warning in the report
    angles : bool — also trace the cutting edges on the scan and measure λ,
        θ, α and l_c beside the CAD's (:func:`tipgeo.inspect.measure_edges`;
        ``edge_band`` (mm) passed on)
    init_transform : (4, 4) float — scanner frame → cannula frame to start
        from (mm): the whole transform without registration, its starting
        pose with it
    colour_range : (low, high) float — an asymmetric colour scale (mm,
        low < 0 < high); overrides ``colour_scale``
    colormap : str — matplotlib colormap of the pictures and the PLY
        (default ``RdYlBu_r``)

    Warnings (``Comparison.warnings``): more than
    ``tol.inspect.far_share_warn`` of the compared points beyond
    ``max_distance`` (figures given).

    Returns
    -------
    Comparison

    Raises
    ------
    ScanError
        Unreadable, empty or non-finite scan; too few points or points at one
        place, on a line or (registration) a plane; no outer wall found; and,
        unless ``allow_mismatch``, a scan that does not match the CAD: fewer
        than ``tol.inspect.match_min_share`` of the points within
        ``tol.inspect.match_distance`` of the CAD surface, a registration
        fitness below ``tol.inspect.match_min_fitness``, or a fitted diameter
        more than ``tol.inspect.match_diameter`` off the CAD's
        (:func:`tipgeo.inspect.checks.check_match`).
    """
    say = progress or _quiet
    scale, rng = _colour_options(tolerance, colour_scale, colour_range)
    if colormap is not None:
        _check_colormap(colormap)
    T0 = None if init_transform is None else check_transform(init_transform, "init_transform")
    _check_crop(z_min, max_distance)
    rule = acceptance if acceptance is not None else default_rule(tolerance)
    # fresh per-point arrays on ordinary pages, not compacted huge ones (.pages)
    with ordinary_pages():
        t0 = _now()
        loaded = stage_load(scan, cad, units=units, voxel=voxel, outliers=outliers,
                            register_scan=register_scan, progress=say)
        placed = stage_register(loaded, register_scan=register_scan, init_transform=T0,
                                seed=seed, allow_mismatch=allow_mismatch, progress=say)
        deviated = stage_deviate(loaded, placed, tolerance=tolerance, z_min=z_min,
                                 max_distance=max_distance,
                                 histogram_range=rng or (-scale, scale), progress=say)
        verified = stage_verify(loaded, placed, deviated, allow_mismatch=allow_mismatch)
        res = Comparison.from_stages(loaded, placed, deviated, verified, colour_scale=scale,
                                     colour_range=rng, colormap=colormap)
        stage_decide(res, rule, angles=angles, edge_band=edge_band, progress=say)
        res.timings["total"] = _lap(res.cpu_timings, "total", t0)
        if out is not None:
            stage_report(res, out, pictures=pictures, progress=say)
    return res
