"""Checks that a scan can be compared with the CAD, and that it matches it.

Frames and units: mm; figures in messages in mm, µm and %.

* :func:`check_geometry` — before any fit: enough points, and spread over
  more than a point or a line (for registration: off a plane too). Each
  failure is a :class:`~tipgeo.inspect.ScanError` naming the figures.
* :func:`check_match` — after registration and deviations: the share of
  points near the CAD surface, the registration fitness and the fitted
  diameters against the CAD's. A scan of another part (a sphere, another
  gauge) fails them; a partial scan of the right part (half the tube, the
  bevel face alone) passes, since every figure is relative to what the scan
  shows: the share counts only points in the CAD's envelope (its bounding
  cylinder grown by the comparison's ``max_distance``; background farther
  away is not the part), and a wall that was not scanned is not fitted, and
  not judged. Diameters are those fitted to the registered walls
  (:func:`tipgeo.inspect.measure.measure`); the registration's own outer
  diameter (from its first, axis stage: rough on a scan of the tip alone) is
  judged only when the outer wall could not be fitted.

Thresholds: :class:`~tipgeo.inspect.settings.InspectSettings`
(``min_points_*``, ``min_*_spread``, ``match_*``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..arrays import AnyArray, FloatArray
from ..tolerances import tol
from .scanio import ScanError

__all__ = ["check_geometry", "check_match", "spread"]


def spread(points: AnyArray, origin: AnyArray | None = None, *,
           sample: int = 200_000) -> tuple[FloatArray, FloatArray]:
    """RMS extents (s1 ≥ s2 ≥ s3, mm) of points along their principal axes,
    and their centroid; from at most ``sample`` evenly spaced points, in
    float64."""
    n = len(points)
    idx = np.linspace(0, n - 1, min(n, sample)).astype(np.int64) if n > sample else slice(None)
    p = np.asarray(points[idx], np.float64)
    c = p.mean(axis=0)
    s = np.linalg.svd(p - c, compute_uv=False) / np.sqrt(len(p))
    s = np.concatenate([s, np.zeros(3 - len(s))])
    if origin is not None:
        c = c + np.asarray(origin, np.float64)
    return s, c


def check_geometry(points: AnyArray, r_o: float, *, register: bool,
                   origin: AnyArray | None = None,
                   where: str = "scan", allow_plane: bool = False) -> dict[str, Any]:
    """Refuse a scan that no comparison (``register=False``) or registration
    can use.

    Parameters
    ----------
    points : (n, 3) float — mm (offsets from ``origin`` if given)
    r_o : float — the CAD's outer radius (mm): the scale of every threshold
    register : bool — the scan is to be registered (needs more)
    allow_plane : bool — points on a plane are registered (a scan of a planar
        cut face alone, registered by its outline: the CAD has such a face)

    Returns
    -------
    dict — ``points``, ``rms_extent_mm`` (s1, s2, s3), ``centroid_mm``

    Raises
    ------
    ScanError
        Too few points; all points at one place; on a line; (registration)
        on a plane.
    """
    n = len(points)
    what = "registration" if register else "a comparison"
    need = tol.inspect.min_points_register if register else tol.inspect.min_points_compare
    if n < need:
        raise ScanError(f"{where} has {n} point{'s' if n != 1 else ''}; {what} needs at least "
                        f"{need} points spread over the tube")
    s, c = spread(points, origin)
    at = "(" + ", ".join(f"{x:.4g}" for x in c) + ") mm"
    if s[0] < tol.inspect.min_spread_point * r_o:
        raise ScanError(f"{where}: all {n} points lie at one place, {at} (RMS spread "
                        f"{s[0]:.2g} mm; {what} needs ≥ {tol.inspect.min_spread_point * r_o:.2g} "
                        "mm, points spread over the tube)")
    if s[1] < tol.inspect.min_spread_line * s[0]:
        raise ScanError(f"{where}: the {n} points lie on a line (RMS {s[1]:.2g} mm off it, "
                        f"{s[0]:.3g} mm along it; {what} needs ≥ "
                        f"{100 * tol.inspect.min_spread_line:g} % of the length off the line, "
                        "points spread over the tube)")
    if register and not allow_plane and s[2] < tol.inspect.min_spread_plane * r_o:
        raise ScanError(f"{where}: the {n} points lie on a plane (RMS {s[2]:.2g} mm off it; "
                        f"registration needs ≥ {tol.inspect.min_spread_plane * r_o:.3g} mm = "
                        f"{100 * tol.inspect.min_spread_plane:g} % of the CAD's outer radius, "
                        "i.e. part of the outer wall); a scan already in the cannula frame "
                        "can be compared without registration (--no-register)")
    return {"points": int(n), "rms_extent_mm": s.tolist(), "centroid_mm": c.tolist()}


def check_match(cad: Any, *, share: float, fitness: float | None, registered_od: float | None,
                measured: dict[str, Any]) -> dict[str, Any]:
    """Does the (registered) scan show the CAD's part?

    Parameters
    ----------
    cad : CadModel
    share : float — share of the compared points in the CAD's envelope within
        ``tol.inspect.match_distance`` of the CAD surface
    fitness : float or None — the registration's fitness (share within its
        inlier distance); None without registration
    registered_od : float or None — the outer diameter fitted by the
        registration (mm); judged only without a measured outer wall
    measured : dict — :func:`tipgeo.inspect.measure.measure` (its fitted
        outer and inner cylinders, where the scan shows enough of them)

    Returns
    -------
    dict — the figures, the thresholds, ``problems`` (list of str) and ``ok``
    """
    st = tol.inspect
    problems: list[str] = []
    rel = st.match_diameter
    out: dict[str, Any] = {"inlier_share": share, "match_distance_mm": st.match_distance,
                           "min_inlier_share": st.match_min_share, "fitness": fitness,
                           "min_fitness": st.match_min_fitness, "diameter_tolerance": rel,
                           "diameters": {}}
    if share < st.match_min_share:
        problems.append(f"inlier share {100 * share:.1f} % within {st.match_distance * 1e3:g} "
                        f"µm of the CAD surface (needs ≥ {100 * st.match_min_share:g} %)")
    if fitness is not None and fitness < st.match_min_fitness:
        problems.append(f"registration fitness {fitness:.3f} (share within the inlier "
                        f"distance; needs ≥ {st.match_min_fitness:g})")
    diams = []
    for wall, r in (("outer", cad.r_o), ("inner", cad.r_i)):
        m = measured.get(wall)
        if m:
            diams.append((f"fitted {wall} diameter", m["diameter_mm"], 2 * r))
    if registered_od is not None and not measured.get("outer"):
        diams.append(("outer diameter fitted by the registration", registered_od, 2 * cad.r_o))
    for name, got, want in diams:
        ok = bool(np.isfinite(got)) and abs(got - want) <= rel * want
        out["diameters"][name] = {"mm": got, "cad_mm": want, "ok": ok}
        if not ok:
            problems.append(f"{name} {got:.4g} mm vs CAD {want:.4g} mm (allowed "
                            f"±{100 * rel:g} %)")
    out["problems"] = problems
    out["ok"] = not problems
    return out
