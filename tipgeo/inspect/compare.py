"""``compare``: scan → registration → signed deviations → measured geometry
→ report. The public call behind ``tipgeo compare``.

Frames and units: the scan in its scanner frame (mm after ``units``); every
result in the CAD's cannula frame; mm inside, µm and degrees in reports.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SpecError
from .cad import CadModel, load_cad
from .deviation import statistics
from .exact import Distances
from .measure import measure
from .register import Registration, register
from .scanio import Scan, ScanError, check_points, load_scan

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
    points : (m, 3) float — the compared points in the cannula frame (mm)
    distances : Distances — their signed deviations
    stats : dict — :func:`tipgeo.inspect.deviation.statistics`
    measured : dict — :func:`tipgeo.inspect.measure.measure`
    tolerance : float — mm
    colour_scale : float — half-range of the colour map (mm)
    dropped : dict — points left out (crop, far from the CAD)
    timings : dict — seconds per stage
    outputs : list of Path
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
    outputs: list[Path] = field(default_factory=list)

    @property
    def warnings(self) -> list[str]:
        w = list(self.registration.warnings) if self.registration else []
        return w + list(self.cad.notes)

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
                "colour_scale_um": [-self.colour_scale * 1e3, self.colour_scale * 1e3],
                "registration": self.registration.to_dict() if self.registration else None,
                "deviation": self.stats,
                "features": {"face": int(np.sum(self.distances.feature == 0)),
                             "edge": int(np.sum(self.distances.feature == 1)),
                             "vertex": int(np.sum(self.distances.feature == 2))},
                "measured": self.measured,
                "warnings": self.warnings,
                "timings_s": dict(self.timings),
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
    from .register import _normals

    return _normals(points, neighbours)


# -----------------------------------------------------------------------------
def compare(scan, cad, *, tolerance: float = 0.01, units: str = "mm",
            register_scan: bool = True, z_min: float | None = None,
            voxel: float | None = None, outliers: bool = False,
            max_distance: float = 0.5, colour_scale: float | None = None,
            out: str | Path | None = None, pictures: bool = True, seed: int = 0,
            progress=None) -> Comparison:
    """Compare a scan with a CAD tip.

    Parameters
    ----------
    scan : path, Scan or (n, 3) array — the scan (scanner frame)
    cad : TipSpec, Tip, CadModel, spec/mesh path or preset name
    tolerance : float — ± tolerance band (mm)
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
    pictures : bool — write the PNGs
    progress : callable(str) — stage messages

    Returns
    -------
    Comparison
    """
    say = progress or (lambda msg: None)
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise SpecError(f"tolerance = {tolerance!r} mm; allowed > 0")
    scale = 2.5 * tolerance if colour_scale is None else float(colour_scale)
    if not (np.isfinite(scale) and scale > 0):
        raise SpecError(f"colour_scale = {colour_scale!r} mm; allowed > 0")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    if isinstance(scan, Scan):
        sc = scan
    elif isinstance(scan, (str, Path)):
        say(f"reading {scan}")
        sc = load_scan(scan, units=units)
    else:
        sc = Scan(check_points(scan, "scan"))
    timings["load_scan"] = time.perf_counter() - t0
    say(f"{len(sc):,} points read in {timings['load_scan']:.2f} s")
    t = time.perf_counter()
    model = cad if isinstance(cad, CadModel) else load_cad(cad)
    timings["load_cad"] = time.perf_counter() - t
    dropped: dict[str, int] = {}
    pts = sc.points
    if voxel:
        idx = voxel_down_sample(pts, voxel)
        dropped["voxel"] = int(len(pts) - len(idx))
        pts = pts[idx]
    if outliers:
        keep = remove_outliers(pts)
        dropped["outliers"] = int((~keep).sum())
        pts = pts[keep]
    reg = None
    t = time.perf_counter()
    if register_scan:
        say("registering")
        reg = register(pts, model, seed=seed, progress=lambda m: say(f"  {m}"))
        pts = reg.apply(pts)
    timings["register"] = time.perf_counter() - t
    if reg:
        say(f"registered in {timings['register']:.2f} s: fitness {reg.fitness:.3f}, inlier "
            f"RMSE {reg.inlier_rmse * 1e3:.3f} µm")
    if z_min is not None:
        keep = crop(pts, z_min=z_min)
        dropped["crop"] = int((~keep).sum())
        pts = pts[keep]
    if not len(pts):
        raise ScanError("no scan points left to compare after cropping")
    t = time.perf_counter()
    say(f"deviations of {len(pts):,} points ({model.method})")
    dist = model.distances(pts)
    timings["deviations"] = time.perf_counter() - t
    far = np.abs(dist.distance) > max_distance
    if far.any():
        dropped["far"] = int(far.sum())
        pts = pts[~far]
        dist = Distances(dist.distance[~far], dist.closest[~far], dist.normal[~far],
                         dist.face[~far], dist.feature[~far], dist.labels)
    if not len(pts):
        raise ScanError(f"no scan point lies within {max_distance} mm of the CAD surface; "
                        "wrong tip, units or registration?")
    say(f"deviations in {timings['deviations']:.2f} s")
    t = time.perf_counter()
    stats = statistics(dist.distance, dist.label_of(), tolerance)
    timings["statistics"] = time.perf_counter() - t
    t = time.perf_counter()
    measured = measure(pts, dist, model)
    timings["measure"] = time.perf_counter() - t
    res = Comparison(sc, model, reg, pts, dist, stats, measured, tolerance, scale, dropped,
                     timings)
    if out is not None:
        from .report import write_report

        t = time.perf_counter()
        say(f"writing the report to {out}")
        res.outputs = write_report(res, out, pictures=pictures)
        timings["report"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    if out is not None:
        from .report import write_json

        write_json(res, Path(out) / "report.json")  # with the final timings
    return res
