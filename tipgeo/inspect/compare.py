"""``compare``: scan → registration → signed deviations → measured geometry
→ match check → report. The public call behind ``tipgeo compare``.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import NotThisTip, SpecError
from ..tolerances import tol
from .cad import CadModel, load_cad
from .checks import check_geometry, check_match
from .deviation import histogram, statistics, trimmed
from .exact import Distances
from .measure import measure
from .meshdist import MeshSolid
from .register import Registration, apply, register
from .scanio import Scan, ScanError, check_points, load_scan
from .transform import check_transform

__all__ = ["Comparison", "compare", "crop", "voxel_down_sample", "remove_outliers",
           "estimate_normals"]


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
    points: np.ndarray
    distances: Distances
    stats: dict[str, Any]
    measured: dict[str, Any]
    tolerance: float
    colour_scale: float
    dropped: dict[str, int] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    cpu_timings: dict[str, float] = field(default_factory=dict)
    index: np.ndarray | None = None
    colour_range: tuple[float, float] | None = None
    colormap: str = "RdYlBu_r"
    outputs: list[Path] = field(default_factory=list)
    match: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    edges: Any = None
    rule: Any = None
    verdict: Any = None
    identity: Any = None

    @property
    def colour_limits(self) -> tuple[float, float]:
        """(low, high) of the colour map (mm)."""
        if self.colour_range is None:
            return -self.colour_scale, self.colour_scale
        return self.colour_range

    @property
    def warnings(self) -> list[str]:
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
def crop(points: np.ndarray, *, z_min: float | None = None, z_max: float | None = None,
         radius: float | None = None) -> np.ndarray:
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


def voxel_down_sample(points: np.ndarray, voxel: float) -> np.ndarray:
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


def remove_outliers(points: np.ndarray, *, neighbours: int = 8, ratio: float = 3.0) -> np.ndarray:
    """(n,) bool — statistical outlier removal: keep points whose mean
    distance to their ``neighbours`` nearest points is within ``ratio``
    standard deviations of the mean."""
    from scipy.spatial import cKDTree

    if len(points) <= neighbours + 1:
        return np.ones(len(points), bool)
    d, _ = cKDTree(points).query(points, k=neighbours + 1, workers=-1)
    m = d[:, 1:].mean(axis=1)
    return m <= m.mean() + ratio * m.std()


def estimate_normals(points: np.ndarray, *, neighbours: int = 12) -> np.ndarray:
    """(n, 3) unit normals by local PCA (sign arbitrary)."""
    from .register import point_normals

    return point_normals(points, neighbours)


# -----------------------------------------------------------------------------
class _ScanDistances(Distances):
    """:class:`Distances` of a scan on the mesh path: the closest points and
    normals (two (m, 3) arrays that ``compare`` itself does not need) are
    computed on first use from each point's triangle, the same values bit
    for bit (:meth:`MeshSolid.closest_normals`)."""

    def __init__(self, distance, face, feature, labels, fill):
        self.distance, self.face, self.feature, self.labels = distance, face, feature, labels
        self._fill = fill
        self._cn = None

    def _pair(self):
        if self._cn is None:
            self._cn = self._fill()
            self._fill = None
        return self._cn

    @property
    def closest(self) -> np.ndarray:
        return self._pair()[0]

    @property
    def normal(self) -> np.ndarray:
        return self._pair()[1]


def _now() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _lap(cpu: dict, name: str, since: tuple[float, float]) -> float:
    """Wall seconds since ``since``; CPU seconds (this process) into ``cpu``."""
    cpu[name] = time.process_time() - since[1]
    return time.perf_counter() - since[0]


def _shift(v) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = v
    return T


def _deviations(model: CadModel, local: np.ndarray, T: np.ndarray, *, z_min, max_distance,
                chunk: int):
    """Signed deviations of ``local`` (offsets, any float) mapped by ``T``
    into the cannula frame, chunk by chunk in float64. Points that cannot lie
    within ``max_distance`` of the CAD (outside its bounding cylinder grown by
    it) skip the exact query; the rest are kept when |d| ≤ max_distance.

    Returns the kept points (float32), their Distances, their rows in
    ``local`` (int64, increasing: input order kept) and counts: cropped, far,
    compared (after the crop), in the envelope (the bounding cylinder grown by
    ``max_distance``), within ``tol.inspect.match_distance``."""
    m = len(local)
    mesh = model.engine if isinstance(getattr(model, "engine", None), MeshSolid) else None
    P = np.empty((m, 3), np.float32)
    rows = np.empty(m, np.int64)
    dist = np.empty(m)
    # the mesh path keeps each point's triangle instead of its closest point
    # and normal (24 bytes a point fewer to write, computed when asked for)
    k3 = 0 if mesh is not None else m
    clo = np.empty((k3, 3), np.float32)
    nrm = np.empty((k3, 3), np.float32)
    tri = np.empty(m if mesh is not None else 0, np.int32)
    face = np.empty(m, np.int16)
    feat = np.empty(m, np.int8)
    cnt = {"crop": 0, "far": 0, "compared": 0, "envelope": 0, "match": 0}
    reach = model.r_o + max_distance
    z_lo, z_hi = model.z_base - max_distance, model.z_top + max_distance
    cur = 0

    def take(mask, *arrays):
        """The rows of ``arrays`` where ``mask`` holds (no copy when all do)."""
        if mask.all():
            return arrays
        return tuple(a[mask] for a in arrays)

    from .nearest import transform_envelope

    q_buf = np.empty((min(chunk, m), 3))
    r_buf = np.empty(min(chunk, m), np.int64)
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
                out=(P, dist, clo, nrm, face, feat, rows), cur=cur, tri=tri)
            cnt["match"] += near
            continue
        D = model.distances(q)
        ad = np.abs(D.distance)
        cnt["match"] += int(np.count_nonzero(ad <= tol.inspect.match_distance))
        ok = ad <= max_distance
        k = int(np.count_nonzero(ok))
        sl = slice(cur, cur + k)
        P[sl], dist[sl], clo[sl], nrm[sl], face[sl], feat[sl], rows[sl] = take(
            ok, q, D.distance, D.closest, D.normal, D.face, D.feature, r)
        cur += k
    cnt["far"] = cnt["compared"] - cur
    if mesh is not None:
        kept, tk = rows[:cur], tri[:cur]
        D = _ScanDistances(dist[:cur], face[:cur], feat[:cur], tuple(model.labels),
                           lambda: mesh.closest_normals(local, kept, T, tk))
        return P[:cur], D, kept, cnt
    return P[:cur], Distances(dist[:cur], clo[:cur], nrm[:cur], face[:cur], feat[:cur],
                              tuple(model.labels)), rows[:cur], cnt


def compare(scan, cad, *, tolerance: float = 0.01, units: str = "mm",
            register_scan: bool = True, z_min: float | None = None,
            voxel: float | None = None, outliers: bool = False,
            max_distance: float = 0.5, colour_scale: float | None = None,
            out: str | Path | None = None, pictures: bool = True, seed: int = 0,
            progress=None, allow_mismatch: bool = False, angles: bool = False,
            edge_band: float | None = None,
            init_transform: np.ndarray | None = None,
            colour_range: tuple[float, float] | None = None,
            colormap: str | None = None, acceptance=None) -> Comparison:
    """Compare a scan with a CAD tip, and judge it.

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
    say = progress or (lambda msg: None)
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise SpecError(f"tolerance = {tolerance!r} mm; allowed > 0")
    scale = 2.5 * tolerance if colour_scale is None else float(colour_scale)
    if not (np.isfinite(scale) and scale > 0):
        raise SpecError(f"colour_scale = {colour_scale!r} mm; allowed > 0")
    if colour_range is not None:
        lo_c, hi_c = (float(x) for x in colour_range)
        if not (np.isfinite(lo_c) and np.isfinite(hi_c) and lo_c < 0 < hi_c):
            raise SpecError(f"colour_range = {tuple(colour_range)!r} mm; allowed low < 0 < high")
        colour_range = (lo_c, hi_c)
        scale = max(-lo_c, hi_c)
    if colormap is not None:
        import matplotlib

        if colormap not in matplotlib.colormaps:
            raise SpecError(f"colormap = {colormap!r} is not a matplotlib colormap; e.g. "
                            "RdYlBu_r, coolwarm, jet, viridis")
    if init_transform is not None:
        init_transform = check_transform(init_transform, "init_transform")
    if not (np.isfinite(max_distance) and max_distance > 0):
        raise SpecError(f"max_distance = {max_distance!r} mm; allowed > 0")
    if z_min is not None and not np.isfinite(z_min):
        raise SpecError(f"z_min = {z_min!r} mm; allowed a finite value")
    timings: dict[str, float] = {}
    cpu: dict[str, float] = {}
    t0 = _now()
    from .acceptance import AcceptanceRule, Band

    rule = acceptance if acceptance is not None else AcceptanceRule(Band(tolerance, 0.95))
    if isinstance(scan, Scan):
        sc = scan
    elif isinstance(scan, (str, Path)):
        say(f"reading {scan}")
        sc = load_scan(scan, units=units, compact=True)
    else:
        sc = Scan(check_points(scan, "scan"))
    timings["load_scan"] = _lap(cpu, "load_scan", t0)
    say(f"{len(sc):,} points read in {timings['load_scan']:.2f} s")
    t = _now()
    model = cad if isinstance(cad, CadModel) else load_cad(cad)
    timings["load_cad"] = _lap(cpu, "load_cad", t)
    dropped: dict[str, int] = {}
    loc, origin = sc.local, sc.origin
    src = None  # rows of loc in the scan as read (None: all, in order)
    if voxel:
        idx = voxel_down_sample(loc, voxel)
        dropped["voxel"] = int(len(loc) - len(idx))
        loc, src = loc[idx], idx
    if outliers:
        keep = remove_outliers(loc)
        dropped["outliers"] = int((~keep).sum())
        loc = loc[keep]
        src = np.flatnonzero(keep) if src is None else src[keep]
    T_init = _shift(origin) if init_transform is None else init_transform @ _shift(origin)
    where = f"scan '{sc.source}'"
    from .register import planar_cut_faces

    check_geometry(loc, model.r_o, register=register_scan, origin=origin, where=where,
                   allow_plane=bool(planar_cut_faces(model)))
    reg = None
    t = _now()
    if register_scan:
        say("registering")
        try:
            start = loc if init_transform is None else apply(init_transform @ _shift(origin), loc)
            reg = register(start, model, seed=seed, progress=lambda m: say(f"  {m}"),
                           max_diameter_error=None if allow_mismatch else
                           tol.inspect.match_diameter)
        except ScanError as e:
            if "another gauge" in str(e):
                raise NotThisTip(f"{where}: {e} (--allow-mismatch compares it anyway)") from None
            raise ScanError(f"{where}: {e}") from None
        if init_transform is None:
            T_loc = reg.transform          # offsets → cannula frame
            reg.axis["point_mm"] = (np.asarray(reg.axis["point_mm"]) + origin).tolist()
        else:
            T_loc = reg.transform @ T_init
            reg.axis["point_mm"] = apply(np.linalg.inv(init_transform),
                                         np.asarray([reg.axis["point_mm"]]))[0].tolist()
        reg.transform = T_loc @ _shift(-origin)   # scanner frame → cannula frame
    else:
        T_loc = T_init
    timings["register"] = _lap(cpu, "register", t)
    if reg:
        say(f"registered in {timings['register']:.2f} s: fitness {reg.fitness:.3f}, inlier "
            f"RMSE {reg.inlier_rmse * 1e3:.3f} µm")
    t = _now()
    say(f"deviations of {len(loc):,} points ({model.method})")
    pts, dist, rows, cnt = _deviations(model, loc, T_loc, z_min=z_min, max_distance=max_distance,
                                 chunk=tol.inspect.chunk)
    timings["deviations"] = _lap(cpu, "deviations", t)
    if z_min is not None:
        dropped["crop"] = cnt["crop"]
    if not cnt["compared"]:
        raise ScanError(f"no scan points left to compare after cropping at z_min = {z_min} mm")
    if cnt["far"]:
        dropped["far"] = cnt["far"]
    if not len(pts):
        raise ScanError(f"{where}: none of its {cnt['compared']:,} points lies within "
                        f"{max_distance} mm of the CAD surface; wrong tip, units or "
                        "registration?")
    say(f"deviations in {timings['deviations']:.2f} s")
    t = _now()
    stats = statistics(dist.distance, dist.face, tolerance, names=dist.labels)
    stats["trimmed"] = trimmed(dist.distance, tolerance, sigmas=tol.inspect.trim_sigmas)
    lo_h, hi_h = colour_range or (-scale, scale)
    stats["histogram"] = histogram(dist.distance, lo_h, hi_h, tol.inspect.histogram_bins)
    timings["statistics"] = _lap(cpu, "statistics", t)
    t = _now()
    measured = measure(pts, dist, model)
    timings["measure"] = _lap(cpu, "measure", t)
    # background far from the part (a fixture, a table) does not count against it
    share = cnt["match"] / cnt["envelope"]
    match = check_match(model, share=share, fitness=reg.fitness if reg else None,
                        registered_od=reg.axis["outer_diameter_mm"] if reg else None,
                        measured=measured)
    notes = []
    far_share = cnt["far"] / cnt["compared"]
    if far_share > tol.inspect.far_share_warn:
        notes.append(f"{100 * far_share:.2f} % of the compared points ({cnt['far']:,} of "
                     f"{cnt['compared']:,}) lie farther than {max_distance:g} mm from the CAD "
                     f"surface (more than {100 * tol.inspect.far_share_warn:g} %): gross "
                     "outliers, a fixture in the scan or a wrong registration; they are left "
                     "out of the statistics")
    if not match["ok"]:
        msg = (f"{where} does not match the CAD '{model.name}': "
               + "; ".join(match["problems"]))
        if not allow_mismatch:
            raise NotThisTip(msg + " (--allow-mismatch compares it anyway)")
        notes.append(msg + " (compared anyway: --allow-mismatch)")
    res = Comparison(sc, model, reg, pts, dist, stats, measured, tolerance, scale, dropped,
                     timings, cpu, match=match, notes=notes, rule=rule,
                     index=rows if src is None else src[rows], colour_range=colour_range,
                     colormap=colormap or "RdYlBu_r")
    if angles:
        from .edgescan import measure_edges

        t = _now()
        say("tracing the cutting edges")
        res.edges = measure_edges(pts, model, edge_band=edge_band,
                                  progress=lambda m: say(f"  {m}"))
        timings["edges"] = _lap(cpu, "edges", t)
    from .acceptance import judge
    from .identity import identify

    t = _now()
    res.identity = identify(res)
    timings["identity"] = _lap(cpu, "identity", t)
    res.verdict = judge(res, rule)
    say(res.verdict.line())
    timings["total"] = _lap(cpu, "total", t0)
    if out is not None:
        from .report import write_report

        say(f"writing the report to {out}")
        write_report(res, out, pictures=pictures)
    return res
