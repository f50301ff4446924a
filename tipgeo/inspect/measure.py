"""Geometry measured on a registered scan: diameters, bevel angles, tip
position, cutting angles.

Frame and units: the cannula frame of the CAD (the scan already registered),
mm and rad inside, ``*_deg`` / ``*_um`` in the returned dictionaries.

The part is measured against *itself*: a bevel angle is the angle between
the plane fitted to the scanned rake face and the axis of the cylinder fitted
to the scanned outer wall, so a registration compromise between a wrong bevel
and the walls does not bias it. Points within ``tol.inspect.edge_exclusion`` of
another face (edge rounding, burrs) stay out of the plane fits.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..arrays import AnyArray, BoolArray, FloatArray, IntArray
from ..tolerances import tol
from .register import fit_cylinder

__all__ = ["measure", "fit_plane"]


_ROWS = 1 << 20  # rows per chunk of the plane fit (memory only)


def _chunks(n: int) -> Iterator[slice]:
    for i in range(0, n, _ROWS):
        yield slice(i, min(n, i + _ROWS))


def fit_plane(points: np.ndarray, *, rounds: int = 4) -> tuple[np.ndarray, float, float, int]:
    """Robust least-squares plane: the smallest principal direction of the
    kept points, dropping residuals beyond 3 robust σ.

    ``points`` may be float32 (large scans): every sum is taken in float64,
    chunk by chunk, about the kept points' centroid (the 3×3 scatter matrix's
    normal direction is as accurate as an SVD's: its eigenvalue gap is the
    face's extent squared, not the noise).

    Returns
    -------
    normal : (3,) unit (sign arbitrary)
    offset : float — normal·x = offset (mm)
    rms : float — RMS residual of the kept points (mm)
    kept : int — points kept
    """
    n_pts = len(points)
    keep = np.ones(n_pts, bool)
    r = np.empty(n_pts)
    for _ in range(rounds):
        cnt = int(np.count_nonzero(keep))
        c = np.zeros(3)
        for sl in _chunks(n_pts):
            c += np.asarray(points[sl][keep[sl]], np.float64).sum(axis=0)
        c /= cnt
        M = np.zeros((3, 3))
        for sl in _chunks(n_pts):
            q = np.asarray(points[sl][keep[sl]], np.float64) - c
            M += q.T @ q
        n = np.linalg.eigh(M)[1][:, 0]
        for sl in _chunks(n_pts):
            r[sl] = (np.asarray(points[sl], np.float64) - c) @ n
        s = 1.4826 * np.median(np.abs(r[keep])) + tol.inspect.scale_floor
        new = np.abs(r) <= 3 * s
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
    rk = r[keep]
    return n, float(n @ c), float(np.sqrt(np.mean(rk ** 2))), int(keep.sum())


def _planar_faces(spec: Any) -> dict[str, Any]:
    """label -> Plane of every plane face of the spec's cutters (their
    :meth:`~tipgeo.cutters.base.Cutter.surfaces`)."""
    out: dict[str, Any] = {}
    if spec is None:
        return out
    from ..cutters import Plane

    for c in spec.cutters:
        for f in c.surfaces(spec.cannula) or ():
            if isinstance(f, Plane):
                out[f.label] = f
    return out


def _apex(planes: list[tuple[FloatArray, float]], point: FloatArray, axis: FloatArray,
          radius: float) -> FloatArray:
    """Highest point (along ``axis``) of the planes ∩ cylinder edge: for
    every γ the lowest plane bounds the edge; the apex is the highest such
    point (mm)."""
    a = axis / np.linalg.norm(axis)
    e1 = np.cross(a, [0.0, 1.0, 0.0] if abs(a[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)

    def edge(g: FloatArray) -> tuple[FloatArray, FloatArray]:
        base = point + radius * (np.cos(g)[:, None] * e1 + np.sin(g)[:, None] * e2)
        s = np.full(len(g), np.inf)
        for n, d in planes:
            if n @ a <= 0:
                n, d = -n, -d
            s = np.minimum(s, (d - base @ n) / (n @ a))
        return base + s[:, None] * a, s

    g = np.linspace(0, 2 * math.pi, 7201)
    _, s = edge(g)
    k = int(np.argmax(s))
    lo, hi = g[max(k - 1, 0)], g[min(k + 1, len(g) - 1)]
    for _ in range(60):  # golden-section refine of the maximum
        m1, m2 = lo + 0.382 * (hi - lo), lo + 0.618 * (hi - lo)
        if edge(np.array([m1]))[1][0] < edge(np.array([m2]))[1][0]:
            lo = m1
        else:
            hi = m2
    apex: FloatArray = edge(np.array([0.5 * (lo + hi)]))[0][0]
    return apex


def measure(points: AnyArray, dist: Any, cad: Any, *, min_points: int = 50,
            angles_min_points: int = 2000) -> dict[str, Any]:
    """Measure a registered scan.

    Parameters
    ----------
    points : (n, 3) float — registered scan (cannula frame, mm)
    dist : Distances — of those points to the CAD
    cad : CadModel
    min_points : int — fewest points for a fit
    angles_min_points : int — rake-face points needed for cutting angles

    Returns
    -------
    dict — ``outer``/``inner`` cylinders, ``faces`` (planes: ξ, rotation,
    flatness), ``tip`` (apex and its position error), ``cutting_angles``
    (measured vs CAD), ``notes``.
    """
    out: dict[str, Any] = {"notes": []}
    labels = tuple(dist.labels)

    def on(label: str) -> BoolArray:  # (n,) bool: points whose closest CAD face is ``label``
        if label not in labels:
            return np.zeros(len(dist.face), bool)
        mask: BoolArray = dist.face == labels.index(label)
        return mask

    d = dist.distance
    # fits take every point of a face that is not far off (robust fits drop
    # the rest): a bevel ground 0.5° off lies up to ~70 µm from the CAD plane
    half = 0.5 * (cad.r_o - cad.r_i)
    near = _Near(d, half)
    ez = np.array([0.0, 0.0, 1.0])
    axis_pt, axis_dir = np.zeros(3), ez
    wall_rows = _wall_rows(dist, labels, half)
    for wall, r_nom in (("outer", cad.r_o), ("inner", cad.r_i)):
        count, idx = wall_rows[wall]
        if count < min_points:
            out[wall] = None
            out["notes"].append(f"{wall} wall: {count} points, too few to fit")
            continue
        pt, a, r, rms = fit_cylinder(np.asarray(points[idx], np.float64), ez, np.zeros(3),
                                     r_nom, scale=0.002)
        if a @ ez < 0:
            a = -a
        out[wall] = {"diameter_mm": 2 * r, "cad_diameter_mm": 2 * r_nom,
                     "error_um": (2 * r - 2 * r_nom) * 1e3, "fit_rms_um": rms * 1e3,
                     "axis_point_mm": pt.tolist(), "axis_direction": a.tolist(),
                     "axis_tilt_deg": math.degrees(math.acos(min(1.0, a @ ez))),
                     "points": count}
        if wall == "outer":
            axis_pt, axis_dir = pt, a
    if out["outer"] is None:
        out["notes"].append("bevel angles are measured against the CAD axis (+z): the outer "
                            "wall was not fitted")
    # planar faces
    planes = _planar_faces(cad.spec)
    faces = {}
    fitted = []
    for label, plane in planes.items():
        k = cad.labels.index(label) if label in cad.labels else None
        sel = on(label) & near.mask() & (dist.feature == 0)
        if k is not None and sel.any() and not hasattr(cad.engine, "face_values"):
            # a meshed CAD (no analytic faces to measure the distance to the
            # edges by): the points whose closest CAD point is inside a face
            sel &= np.asarray(dist.feature) == 0
        elif k is not None and sel.any():
            idx = np.flatnonzero(sel)
            for ch in _chunks(len(idx)):
                ic = idx[ch]
                fv = np.abs(cad.engine.face_values(np.asarray(dist.closest[ic], np.float64)))
                fv[:, k] = np.inf
                sel[ic[fv.min(axis=1) < tol.inspect.edge_exclusion]] = False
        if sel.sum() < min_points:
            out["notes"].append(f"{label}: {int(sel.sum())} points away from its edges, too "
                                "few to fit a plane")
            continue
        n, off, rms, kept = fit_plane(points[sel])
        if n @ plane.normal < 0:
            n, off = -n, -off
        xi = math.asin(min(1.0, abs(n @ axis_dir)))
        xi_z = math.asin(min(1.0, abs(n[2])))
        # heel direction: the plane's steepest descent about the measured axis
        h = n - (n @ axis_dir) * axis_dir
        beta = math.degrees(math.atan2(h[1], h[0])) % 360
        beta_cad = math.degrees(plane.rotation) % 360
        faces[label] = {"xi_deg": math.degrees(xi), "cad_xi_deg": math.degrees(plane.xi),
                        "xi_error_deg": math.degrees(xi - plane.xi),
                        "xi_vs_cad_axis_deg": math.degrees(xi_z),
                        "rotation_deg": beta, "cad_rotation_deg": beta_cad,
                        "rotation_error_deg": (beta - beta_cad + 180) % 360 - 180,
                        "flatness_rms_um": rms * 1e3, "points": kept,
                        "normal": n.tolist(), "offset_mm": off}
        fitted.append((label, n, off, int(sel.sum())))
    out["faces"] = faces
    # included angles between fitted planes (eq. 2.3: π − arccos(n_a·n_b))
    pairs = []
    for i in range(len(fitted)):
        for j in range(i + 1, len(fitted)):
            a_, b_ = fitted[i], fitted[j]
            pa, pb = planes[a_[0]], planes[b_[0]]
            th = math.pi - math.acos(max(-1.0, min(1.0, a_[1] @ b_[1])))
            th_cad = math.pi - math.acos(max(-1.0, min(1.0, pa.normal @ pb.normal)))
            pairs.append({"faces": [a_[0], b_[0]], "theta_deg": math.degrees(th),
                          "cad_theta_deg": math.degrees(th_cad)})
    if pairs:
        out["included_angles"] = pairs
    # tip position
    out["tip"] = _tip(points, d, near, fitted, planes, axis_pt, axis_dir, out, cad)
    # cutting angles of the measured geometry (bevel tips)
    out["cutting_angles"] = _cutting_angles(cad, faces, out, angles_min_points)
    return out


class _Near:
    """The points with |d| < half (mm): the bounds, and their mask made on
    first use (the mesh path never needs it)."""

    def __init__(self, d: AnyArray, half: float) -> None:
        self.d, self.half = d, half
        self._mask: BoolArray | None = None

    def mask(self) -> BoolArray:
        if self._mask is None:
            self._mask = (self.d < self.half) & (self.d > -self.half)  # no |d| array
        return self._mask


#: rows of a wall's cylinder fit (evenly spaced among the wall's points)
_WALL_ROWS = 20000


def _wall_rows(dist: Any, labels: tuple[str, ...],
               half: float) -> dict[str, tuple[int, IntArray]]:
    """The points of each wall's fit (outer, inner): those whose closest CAD
    point lies inside the wall's faces (feature 0) with |d| < half (mm) —
    their count and their rows, at most :data:`_WALL_ROWS` evenly spaced
    ones (``flatnonzero(mask)[linspace(0, count - 1, _WALL_ROWS).astype(int)]``)
    — in two compiled passes for both and no (n,) mask."""
    from .rowsfast import count_rows, pick_rows

    walls = [w for w in ("outer", "inner") if w in labels]
    out: dict[str, tuple[int, IntArray]] = {w: (0, np.zeros(0, np.int64))
                                            for w in ("outer", "inner")}
    if not walls:
        return out
    ids = np.array([labels.index(w) for w in walls], np.int64)
    args = (np.ascontiguousarray(dist.face), ids, np.ascontiguousarray(dist.distance, float),
            float(half), np.ascontiguousarray(dist.feature))
    counts = count_rows(*args)
    ranks = np.zeros((len(walls), _WALL_ROWS), np.int64)
    for j, c in enumerate(counts):
        r = np.arange(c) if c <= _WALL_ROWS else np.linspace(0, c - 1, _WALL_ROWS).astype(int)
        ranks[j, :len(r)] = r
    nrank = np.minimum(counts, _WALL_ROWS).astype(np.int64)
    rows = pick_rows(*args, ranks, nrank)
    for j, w in enumerate(walls):
        out[w] = (int(counts[j]), rows[j, :nrank[j]])
    return out


def _highest(z: np.ndarray, near: _Near, k: int) -> np.ndarray:
    """Indices of the k highest ``z`` of the points near the surface (all
    of them when fewer; at a tie the first rows), increasing: one compiled
    pass keeping the k best."""
    from .rowsfast import top

    return top(z, near.d, near.half, k)


def _tip(points: AnyArray, d: Any, near: _Near, fitted: list[Any] | None,
         planes: dict[str, Any], axis_pt: FloatArray, axis_dir: FloatArray, out: dict[str, Any],
         cad: Any) -> dict[str, Any] | None:
    r_o = out["outer"]["diameter_mm"] / 2 if out.get("outer") else cad.r_o
    if fitted and len(fitted) == len(planes):
        apex = _apex([(n, off) for _, n, off, _ in fitted], axis_pt, axis_dir, r_o)
        cad_apex = _apex([(p.normal, p.offset) for p in planes.values()], np.zeros(3),
                         np.array([0.0, 0.0, 1.0]), cad.r_o)
        how = "fitted planes ∩ fitted outer cylinder"
    else:
        top = _highest(points[:, 2], near, 20)
        if not len(top):
            return None
        apex = np.asarray(points[top], np.float64).mean(axis=0)
        cad_apex = None
        how = "mean of the 20 highest scan points near the surface"
    res: dict[str, Any] = {"apex_mm": apex.tolist(), "method": how}
    if cad_apex is not None:
        e = apex - cad_apex
        res.update({"cad_apex_mm": cad_apex.tolist(), "error_mm": e.tolist(),
                    "error_um": float(np.linalg.norm(e) * 1e3),
                    "axial_error_um": float(e[2] * 1e3)})
    return res


def _cutting_angles(cad: Any, faces: dict[str, Any], out: dict[str, Any],
                    min_points: int) -> dict[str, Any] | None:
    """λ, θ, α and l_c of the measured bevel (fitted ξ and diameters) by the
    angle analysis, next to the CAD's."""
    from dataclasses import replace

    spec = cad.spec
    if spec is None or len(spec.cutters) != 1:
        return None
    from ..cutters import Plane

    c = spec.cutters[0]
    surfaces = list(c.surfaces(spec.cannula) or [])
    if not (c.angle_field and len(surfaces) == 1 and isinstance(surfaces[0], Plane)):
        return None  # one rake plane whose ξ the scan measured: a bevel
    f = faces.get(c.label)
    if f is None or f["points"] < min_points:
        return {"note": "too few rake-face points for cutting angles"}
    from ..angles import analyze
    from ..cannula import Cannula
    from ..spec import TipSpec

    do = out["outer"]["diameter_mm"] if out.get("outer") else 2 * cad.r_o
    di = out["inner"]["diameter_mm"] if out.get("inner") else 2 * cad.r_i
    try:
        meas = TipSpec(cannula=Cannula(outer_diameter=do, inner_diameter=di,
                                       length=spec.cannula.length),
                       cutters=(replace(c, **{c.angle_field: math.radians(f["xi_deg"])}),),
                       name="measured")
        rm = analyze(meas, method="exact").summary()
        rc = analyze(spec, method="exact").summary()
    except Exception as e:  # a failed analysis is a note, not a crash
        return {"note": f"angle analysis failed: {e}"}

    def pick(s: dict[str, Any]) -> dict[str, Any]:
        return {w: {k: s[w][k] for k in s[w] if k.endswith("_deg") or k == "l_c_mm"}
                for w in ("outer", "inner")}

    return {"method": "angle analysis (exact) of the fitted bevel and diameters",
            "measured": pick(rm), "cad": pick(rc)}
