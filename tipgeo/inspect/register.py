"""Registration of a scan onto the CAD tip, in stages that survive the
cylinder's symmetry.

Frames and units: the scan in its scanner frame, the CAD in the cannula frame
(+z along the axis towards the tip); mm, rad. The result maps scanner →
cannula frame: x_cad = R x_scan + t.

Every stage works on a seeded random subset of the scan
(``tol.inspect.register_points``; fewer for the first stages).

1. **Axis**: a least-squares cylinder fit (robust loss) to the points whose
   normals are perpendicular to the principal axis and whose distance to it is
   near the nominal outer radius — on the arc of wall the scan shows, with
   large flat faces (a bevel face, ground planes) left out first, since their
   normals lie across a wrong axis too; it starts on the axis where the
   points' normal lines meet, and fits a bore seen beside the wall (through a
   bevel's opening) as the coaxial inner cylinder. It aligns the axes and
   measures the outer diameter. ICP alone cannot do what follows: a cylinder matches itself
   under any turn about and shift along its axis.
2. **Global search** of the turn about the axis (both axis directions, over
   one symmetry period: coarse every 2·``tol.inspect.search_step``, then fine
   about the best minima) with the axial offset from the tip's highest
   point: each pose is scored by the mean clipped distance to the CAD solid of
   a few hundred points drawn near the CAD's features (below them every turn
   fits alike). The bevel, planes or serrations decide.
3. **Point-to-plane ICP** (Gauss–Newton on exact closest points and normals
   of the CAD — the spec's exact surfaces where it has them — with Tukey
   weights) from the best few poses on a small subset, then to convergence on
   a larger one, then on every registration point from there; directions the
   data do not constrain (a rotationally symmetric tip's turn about its axis)
   are held fixed. Where the scan ends at the edge of a face it does not show
   (the back of a tube at the bevel's outline), that outline is fitted as a
   blurred step by maximum likelihood, not by distances to the solid, which
   only ask the outline to cover every point. A k-fold symmetric tip's pose
   is found up to a turn of 360°/k, which is reported (it changes no
   deviation), and so is each direction's 1σ uncertainty from the
   information the scan holds (the Cramér–Rao bound).

The ICP's Tukey cut-off is annealed (from ``tol.inspect.search_clip`` down
to 4.685 σ, halved each time the pose settles), so that the cut faces and the
base, which alone fix the turn and the axial shift of a scan that is mostly
tube, are not made outliers by a scale the tube sets.

Partial scans register up to what they leave free, which is reported: a scan
of the tube alone (no cut face, no outline of one) — the turn about and the
shift along the axis; a scan of one planar cut face alone (points on a
plane) is registered by its outline, up to the face's own symmetry (a
bevel's elliptic ring: a half turn about its normal).

The report gives the transform, fitness (share of points within the inlier
distance), inlier RMSE, and warnings: an ambiguous pose (a different pose fits
almost as well), an unconstrained direction, too few points.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..arrays import AnyArray, ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import TipGeoError
from ..tolerances import tol
from .scanio import ScanError

__all__ = ["Registration", "register", "fit_cylinder", "apply", "point_normals",
           "planar_cut_faces"]


def apply(T: AnyArray, points: AnyArray) -> FloatArray:
    """x ↦ R x + t for a 4×4 matrix T, on (n, 3) points (mm)."""
    out: FloatArray = points @ T[:3, :3].T + T[:3, 3]
    return out


def _rot(axis: ArrayLike, angle: float) -> FloatArray:
    a = np.asarray(axis, float)
    n = np.linalg.norm(a)
    if n == 0 or angle == 0:
        return np.eye(3)
    a = a / n
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    R: FloatArray = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    return R


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation taking unit vector a onto unit vector b."""
    v = np.cross(a, b)
    s, c = np.linalg.norm(v), float(a @ b)
    if s < tol.inspect.align_parallel:
        if c > 0:
            return np.eye(3)
        p = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
        return _rot(np.cross(a, p), math.pi)
    return _rot(v, math.atan2(s, c))


@dataclass
class Registration:
    """The result of :func:`register`.

    Attributes
    ----------
    transform : (4, 4) float — scanner → cannula frame
    fitness : float — share of registration points within ``inlier_distance``
    inlier_rmse : float — RMS distance of those points (mm)
    inlier_distance : float — mm
    axis : dict — fitted cylinder in the scanner frame (point, direction,
        outer radius, RMS of the fit)
    search : dict — the global search: best angle, runner-up, scores
    warnings : list of str
    iterations : int — ICP iterations of the chosen pose
    points : int — points used
    fixed_directions : list of str — directions held (not constrained)
    symmetry : int — the CAD tip's k-fold symmetry about its axis (0:
        continuous, 1: none): the pose is found up to a turn of 360°/k about
        the axis, which changes no deviation (reported as ``symmetry`` in
        :meth:`to_dict`)
    uncertainty : dict — standard uncertainty (1σ) of the pose from the
        Fisher information the scan holds (a Cramér–Rao bound under the noise
        model): ``rotation_deg`` about the cannula frame's x, y, z (z: the turn
        about the axis), ``translation_um`` at the points' centroid, cannula
        frame; None for a component a held direction touches (the turn of a
        rotationally symmetric tip)
    """

    transform: np.ndarray
    fitness: float
    inlier_rmse: float
    inlier_distance: float
    axis: dict[str, Any]
    search: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    iterations: int = 0
    points: int = 0
    fixed_directions: list[str] = field(default_factory=list)
    symmetry: int = 1
    uncertainty: dict[str, Any] = field(default_factory=dict)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Scanner-frame points in the cannula frame."""
        return apply(self.transform, np.asarray(points, float))

    def to_dict(self) -> dict[str, Any]:
        R = self.transform[:3, :3]
        ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2))))
        return {"transform": self.transform.tolist(),
                "rotation_angle_deg": ang,
                "translation_mm": self.transform[:3, 3].tolist(),
                "fitness": self.fitness, "inlier_rmse_mm": self.inlier_rmse,
                "inlier_distance_mm": self.inlier_distance, "axis": self.axis,
                "search": self.search, "warnings": list(self.warnings),
                "iterations": self.iterations, "points": self.points,
                "fixed_directions": list(self.fixed_directions),
                "symmetry": _symmetry_note(self.symmetry),
                "uncertainty": dict(self.uncertainty)}


def _symmetry_note(k: int) -> dict[str, Any]:
    """How far the pose is determined about the axis, for the report."""
    if k == 1:
        return {"order": 1, "turn_deg": 360.0,
                "note": "the tip has no symmetry about its axis: the pose is unique"}
    if k == 0:
        return {"order": 0, "turn_deg": 0.0,
                "note": "the tip is rotationally symmetric: the turn about the axis is free"}
    return {"order": k, "turn_deg": 360.0 / k,
            "note": f"the tip is {k}-fold symmetric: the pose is determined up to a turn of "
                    f"{360.0 / k:g}° about the axis, which changes no deviation"}


# -----------------------------------------------------------------------------
def point_normals(p: np.ndarray, k: int = 12) -> np.ndarray:
    """Unit normals (n, 3) of a point cloud by PCA over each point's ``k``
    nearest neighbours (mm, any frame; the sign is arbitrary)."""
    from .knn import knn_normals  # exact, compiled: no scipy.spatial import on this path

    return knn_normals(p, min(k, len(p)))


def fit_cylinder(points: np.ndarray, axis_dir: np.ndarray, axis_point: np.ndarray,
                 radius: float, *, scale: float = 0.005, bore: np.ndarray | None = None,
                 wall: float = 0.0,
                 converge: float | None = None) -> tuple[FloatArray, FloatArray, float, float]:
    """Least-squares cylinder through points (robust soft-L1 loss of width
    ``scale`` mm), from an initial axis and radius. With ``bore`` ((n,) bool)
    those points lie on a coaxial cylinder ``wall`` mm smaller (a tube's
    bore seen with its outer wall): one axis from both. The iterations stop
    when no parameter moves by more than ``converge`` (mm, rad; default
    ``tol.inspect.cylinder_converge``).

    Returns
    -------
    point : (3,) — the axis point closest to the points' centroid (mm)
    direction : (3,) unit
    radius : float — mm
    rms : float — RMS radial residual of the points within 3·scale (mm)
    """
    a0 = axis_dir / np.linalg.norm(axis_dir)
    e1 = np.cross(a0, [1.0, 0, 0] if abs(a0[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a0, e1)
    c0 = axis_point + a0 * ((points.mean(axis=0) - axis_point) @ a0)
    # the points in the start frame (e1, e2, a0) at c0, one column each: the
    # model below is arithmetic on three vectors (a few thousand points: a
    # 3 × n matrix product per step cost more in calls than in flops)
    u1, u2, u3 = np.ascontiguousarray(((points - c0) @ np.column_stack([e1, e2, a0])).T)
    inset = 0.0 if bore is None else wall * np.asarray(bore, float)

    def geometry(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]:
        """With u = (x0, x1, 1) (the axis in the start frame), a = u/|u|,
        c = (x2, x3, 0) and d = q − c: ρ = |d − (d·a) a| (the distance from
        the axis), t = d·a, the perpendicular's e1 and e2 parts, |u|."""
        nu = math.sqrt(1.0 + x[0] * x[0] + x[1] * x[1])
        a1, a2, a3 = x[0] / nu, x[1] / nu, 1.0 / nu
        d1, d2 = u1 - x[2], u2 - x[3]
        t = d1 * a1 + d2 * a2 + u3 * a3
        p1, p2, p3 = d1 - t * a1, d2 - t * a2, u3 - t * a3
        return np.sqrt(p1 * p1 + p2 * p2 + p3 * p3), t, p1, p2, nu

    def jacobian(geo: tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]) -> FloatArray:
        """∂r/∂x in closed form: ∂ρ/∂x0 = −(d·a)(p·e1)/(|u| ρ), ∂ρ/∂x2 =
        −(p·e1)/ρ (e2 alike), ∂r/∂x4 = −1 (p the perpendicular)."""
        rho, t, p1, p2, nu = geo
        rho = np.maximum(rho, tol.tiny)
        pe1, pe2 = p1 / rho, p2 / rho
        J = np.empty((len(rho), 5))
        J[:, 0], J[:, 1] = -t * pe1 / nu, -t * pe2 / nu
        J[:, 2], J[:, 3], J[:, 4] = -pe1, -pe2, -1.0
        return J

    # Levenberg–Marquardt on the soft-L1 loss by reweighting (weights
    # (1 + (r/scale)²)^-½, the loss's derivative): a handful of 5 × 5 solves
    x = np.array([0.0, 0.0, 0.0, 0.0, radius])
    geo = geometry(x)
    r = geo[0] - x[4] + inset
    lam = tol.inspect.lm_damping_start
    for _ in range(tol.inspect.max_iterations):
        w = 1.0 / np.sqrt(1.0 + (r / scale) ** 2)
        J = jacobian(geo)
        Jw = J * w[:, None]
        A, g = Jw.T @ J, Jw.T @ r
        cost = np.sum(2 * scale ** 2 * (np.sqrt(1 + (r / scale) ** 2) - 1))
        while True:
            dx = -np.linalg.solve(A + lam * np.diag(np.diag(A) + tol.inspect.lm_diag_floor), g)
            geo_n = geometry(x + dx)
            rn = geo_n[0] - (x[4] + dx[4]) + inset
            if np.sum(2 * scale ** 2 * (np.sqrt(1 + (rn / scale) ** 2) - 1)) <= cost \
                    or lam > 1e6:
                break
            lam *= 10
        x, r, geo, lam = x + dx, rn, geo_n, max(lam / 10, tol.inspect.lm_damping_floor)
        if np.max(np.abs(dx)) < (tol.inspect.cylinder_converge if converge is None
                                  else converge):
            break
    ok = np.abs(r) < 3 * scale
    rms = float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else float("nan")
    a = a0 + x[0] * e1 + x[1] * e2
    a = a / np.linalg.norm(a)
    point = c0 + x[2] * e1 + x[3] * e2
    point = point + a * ((points.mean(axis=0) - point) @ a)
    return point, a, float(x[4]), rms


def _cone_counts(v: FloatArray, cosc: float, block: int = 128) -> IntArray:
    """(n,) int — for each unit vector of ``v`` ((n, 3)) how many lie within
    the cone |cos| > ``cosc`` about it (itself included, either sign); by
    blocks of rows into reused buffers: no n × n matrix (1500 vectors: 18 MB
    paged in afresh on every call; :func:`_flat_patches`' first call took
    87 ms with it, 10 ms by blocks)."""
    n = len(v)
    vt = np.ascontiguousarray(v.T)
    g = np.empty((min(block, n), n))
    m = np.empty(g.shape, bool)
    out = np.empty(n, np.int64)
    for a in range(0, n, block):
        e = min(a + block, n)
        gb, mb = g[:e - a], m[:e - a]
        np.matmul(v[a:e], vt, out=gb)
        np.abs(gb, out=gb)
        np.greater(gb, cosc, out=mb)
        out[a:e] = mb.sum(axis=1)   # half the time of count_nonzero(axis=1)
    return out


def _flat_patches(p: np.ndarray, nrm: np.ndarray, r_nominal: float) -> np.ndarray:
    """(n,) bool — points on large flat faces (a bevel, a ground plane, the
    base): many normals within ``tol.inspect.flat_cone`` of one direction,
    on one plane, spread in two directions over ≥ ``tol.inspect.flat_extent``
    of the outer radius. A strip of the wall whose normals agree that well is
    a thin line, not a patch, and is kept. Their normals are perpendicular to
    a line in the face — a wrong axis — so the axis fit leaves them out."""
    st = tol.inspect
    n = len(p)
    flat = np.zeros(n, bool)
    cosc = math.cos(st.flat_cone)
    for _ in range(st.flat_faces):
        free = np.flatnonzero(~flat)
        if len(free) < 50:
            break
        # the densest normal direction, counted on a spread sample (sign free)
        probe = free[:: max(1, len(free) // 1500)]
        cnt = _cone_counts(nrm[probe], cosc)
        k = int(np.argmax(cnt))
        if cnt[k] * len(free) / len(probe) < max(st.flat_share * n, 50):
            break
        m = free[np.abs(nrm[free] @ nrm[probe[k]]) > cosc]
        c = p[m].mean(axis=0)
        _, sv, vt = np.linalg.svd(p[m] - c, full_matrices=False)
        on = m[np.abs((p[m] - c) @ vt[2]) < st.flat_distance]
        if len(on) < 50:
            break
        ext = np.linalg.svd(p[on] - p[on].mean(axis=0), compute_uv=False) / math.sqrt(len(on))
        if ext[1] < st.flat_extent * r_nominal:
            break  # a strip of the wall
        flat[on] = True
    return flat


def _axis_stage(p: np.ndarray, r_nominal: float, r_inner: float | None = None,
                nrm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The outer wall's cylinder, fitted to the arc of it that the scan shows.

    Large flat faces are left out first (:func:`_flat_patches`): their
    normals lie across any line in the face, so they would pass for wall.
    Two starting axes: the points' longest principal direction (a long
    tube), and the direction the surface normals are most nearly
    perpendicular to (a short piece — the tip alone, one side — where the
    longest extent may run across the axis). Each is refined on the points
    that look like the wall; the fit with the most wall points near the
    nominal radius wins. Points nearer the bore's radius (``r_inner``: the
    bore seen through a bevel's opening) are fitted as the bore, coaxial and
    one nominal wall thickness in, not mistaken for outer wall. ``nrm``:
    the points' :func:`point_normals`, if the caller has them."""
    cen = p.mean(axis=0)
    _, vec = np.linalg.eigh(np.cov((p - cen).T))
    nrm = point_normals(p) if nrm is None else nrm
    flat = _flat_patches(p, nrm, r_nominal)
    if np.count_nonzero(~flat) >= 20:
        p, nrm = p[~flat], nrm[~flat]
        cen = p.mean(axis=0)
    starts = [vec[:, -1]]
    a = np.linalg.eigh(nrm.T @ nrm)[1][:, 0]
    for _ in range(4):  # normals across the axis: the wall's (a bevel's are ≥ 0.2 off)
        wall = np.abs(nrm @ a) < 0.15
        if wall.sum() < 20:
            break
        a = np.linalg.eigh(nrm[wall].T @ nrm[wall])[1][:, 0]
    if abs(a @ starts[0]) < 0.999:
        starts.append(a)
    best: tuple[float, _AxisFit] | None = None
    err: ScanError | None = None
    for a0 in starts:
        try:
            fit = _axis_fit(p, nrm, cen, a0, r_nominal, first=0.3 if a0 is starts[0] else 0.15,
                            r_inner=r_inner)
        except ScanError as e:
            err = e
            continue
        score = fit[4] * (1.0 if abs(fit[2] - r_nominal) <= 0.05 * r_nominal else 0.1)
        if best is None or score > best[0]:
            best = (score, fit)
    if best is None:
        assert err is not None  # every start failed, each with a ScanError
        raise err
    point, a, radius, rms, _ = best[1]
    return point, a, radius, rms


def _axis_centre(p: FloatArray, nrm: FloatArray, a: FloatArray,
                 radii: tuple[float, ...]) -> FloatArray | None:
    """The point where the normal lines of wall-like points (normals across
    ``a``) meet the axis: each votes at its own distance ``radii`` along its
    normal, both ways; the densest cell of the votes, refined to their mean
    near it (a start for the cylinder fit that neither the scan's one-sided
    centroid nor a bore seen beside the outer wall pulls off the axis)."""
    e1 = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    wall = np.abs(nrm @ a) < 0.15
    if np.count_nonzero(wall) < 20:
        return None
    P = np.column_stack([p[wall] @ e1, p[wall] @ e2])
    N = np.column_stack([nrm[wall] @ e1, nrm[wall] @ e2])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), tol.tiny)
    votes = np.vstack([P + sg * r * N for r in radii for sg in (1.0, -1.0)])
    h = 0.02 * max(radii)
    cell = np.floor((votes - votes.min(axis=0)) / h).astype(np.int64)
    key = cell[:, 0] * (int(cell[:, 1].max()) + 1) + cell[:, 1]
    uk, cnt = np.unique(key, return_counts=True)
    c = votes[key == uk[np.argmax(cnt)]].mean(axis=0)
    for _ in range(3):
        c = votes[np.linalg.norm(votes - c, axis=1) < 2 * h].mean(axis=0)
    centre: FloatArray = c[0] * e1 + c[1] * e2 + a * float(p.mean(axis=0) @ a)
    return centre


#: An axis fit: (point (3,), direction (3,), radius, RMS (mm), wall points).
_AxisFit = tuple[FloatArray, FloatArray, float, float, int]


def _axis_fit(p: FloatArray, nrm: FloatArray, cen: FloatArray, a: FloatArray, r_nominal: float,
              first: float, r_inner: float | None = None) -> _AxisFit:
    thick = None if r_inner is None or not 0 < r_inner < r_nominal else r_nominal - r_inner
    point = _axis_centre(p, nrm, a, (r_nominal,) if thick is None or r_inner is None else
                         (r_nominal, r_inner))
    point = cen if point is None else point
    radius = r_nominal
    sel = np.ones(len(p), bool)
    passes = 4
    for it in range(passes):
        d = p - point
        rho = np.linalg.norm(d - np.outer(d @ a, a), axis=1)
        wall = np.abs(nrm @ a) < (first if it == 0 else 0.15)
        band = 0.25 * r_nominal if it == 0 else max(0.02 * r_nominal, 0.005)
        sel = wall & (np.abs(rho - radius) < band)
        bore = np.zeros(len(p), bool)
        if thick is not None:
            # nearer the bore's radius than the outer one: the bore
            bore = wall & (np.abs(rho - radius + thick) < np.minimum(band, np.abs(rho - radius)))
            sel = (sel & ~bore) | bore
        if sel.sum() < 20:
            raise ScanError(f"only {int(sel.sum())} of {len(p)} scan points look like the "
                            f"outer wall (radius {r_nominal:.4g} ± {band:.2g} mm, normals "
                            "across the axis; registration needs ≥ 20): is the scan of this "
                            "tip, in the right units, and does it show part of the outer wall?")
        idx = np.flatnonzero(sel)
        if len(idx) > 3000:  # plenty for five parameters
            idx = idx[np.linspace(0, len(idx) - 1, 3000).astype(int)]
        # the fits before the last only pick the wall points of the next
        # (a band of ≥ 5 µm): a micrometre is close enough for them
        point, a, radius, rms = fit_cylinder(p[idx], a, point, radius,
                                             scale=0.02 if it == 0 else 0.004,
                                             bore=bore[idx], wall=thick or 0.0,
                                             converge=None if it == passes - 1
                                             else tol.inspect.cylinder_converge_pick)
        if not 0.5 * r_nominal < radius < 2.0 * r_nominal:
            raise ScanError(f"the outer wall's cylinder fit ran off to radius {radius:.4g} mm "
                            f"(nominal {r_nominal:.4g} mm): does the scan show the outer wall?")
    d = p - point
    rho = np.linalg.norm(d - np.outer(d @ a, a), axis=1)
    inliers = int(np.count_nonzero((np.abs(nrm @ a) < 0.15) & (np.abs(rho - radius) < 0.005)))
    return point, a, radius, rms, inliers


def _frame(point: FloatArray, a: FloatArray, sign: float) -> FloatArray:
    """4×4 taking the fitted axis (direction a·sign) to +z through the origin."""
    R = _align(a * sign, np.array([0.0, 0.0, 1.0]))
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ point
    return T


def _feature_z(cad: Any) -> float:
    """Lowest z (cannula frame, mm) of the CAD's faces that are not the tube
    (outer and inner wall, base): below it every turn about the axis fits
    alike, so points there say nothing about the turn."""
    tip = cad.tip
    names = np.asarray(tip.label_names, dtype=object)
    cut = ~np.isin(names[tip.label_ids], ["outer", "inner", "base"])
    if not cut.any():
        return float(cad.z_base)
    return float(tip.vertices[tip.faces[cut]][..., 2].min())


def _scores(sub: FloatArray, cad: Any, angles: FloatArray, dz: float) -> FloatArray:
    """Mean clipped |distance| to the CAD of ``sub`` (on the axis) turned by
    each angle about +z and shifted by dz: one batched query."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x = np.stack([c * sub[:, 0] - s * sub[:, 1], s * sub[:, 0] + c * sub[:, 1],
                  np.broadcast_to(sub[:, 2] + dz, (len(angles), len(sub)))], 2)
    f = cad.bound(x.reshape(-1, 3), tol.inspect.search_clip).reshape(len(angles), len(sub))
    scores: FloatArray = np.mean(np.minimum(np.abs(f), tol.inspect.search_clip), axis=1)
    return scores


def _search(q_all: FloatArray, cad: Any, step: float, npts: int, rng: np.random.Generator,
            period: float, z_feature: float) -> tuple[FloatArray, FloatArray, IntArray,
                                                       FloatArray, float]:
    """The coarse pass of the search about +z for points already on the
    axis: a third of ``npts`` points scored every 2·step of turn (within one
    symmetry period) at the shift that puts the scan's top at the CAD's. The
    scored points are drawn from those near or above the CAD's features
    (``z_feature``), where the turn shows.

    Returns the coarse angles (rad) and scores (mm), the turns of the (up to
    three) best coarse minima, best first, all the drawn points (for
    :func:`_refine_turn`) and the shift (mm)."""
    z_top = np.quantile(q_all[:, 2], 0.9995)
    dz = cad.z_top - z_top
    near = q_all[:, 2] + dz >= z_feature - cad.r_o
    pool = q_all[near] if np.count_nonzero(near) >= 50 else q_all
    sub = pool[rng.choice(len(pool), min(npts, len(pool)), replace=False)]
    coarse = np.arange(0.0, period - tol.inspect.arange_margin, 2 * step)
    sc = _scores(sub[: max(len(sub) // 3, 1)], cad, coarse, dz)
    mins = np.flatnonzero((sc <= np.roll(sc, 1)) & (sc <= np.roll(sc, -1)))
    mins = mins[np.argsort(sc[mins], kind="stable")][:3]
    return coarse, sc, mins, sub, float(dz)


def _refine_turn(sub: FloatArray, cad: Any, turn: float, dz: float, step: float,
                 period: float) -> tuple[float, float, float]:
    """A coarse minimum refined: the shift searched (:func:`_dz_search`: the
    top of a sparse scan of a sharp tip is no place to hang the shift on,
    and the tube, which most points lie on, is blind to it), then the turn
    every step/2 within ±2·step at that shift. Returns (turn (rad), score
    (mm), dz (mm))."""
    dzm = _dz_search(sub, cad, turn, dz)
    return (*_fine_turn(sub, cad, turn, dzm, step, period), dzm)


def _fine_turn(sub: FloatArray, cad: Any, turn: float, dz: float, step: float,
               period: float) -> tuple[float, float]:
    """The best turn (rad) every step/2 within ±2 steps of ``turn`` at the
    shift ``dz`` (mm), and its score (mm)."""
    fine = np.asarray((turn + np.arange(-4, 5) * 0.5 * step) % period, np.float64)
    fs = _scores(sub, cad, fine, dz)
    k = int(np.argmin(fs))
    return float(fine[k]), float(fs[k])


def _dz_search(sub: FloatArray, cad: Any, angle: float, dz0: float) -> float:
    """The axial shift (mm) that best fits at ``angle``. A scan's top lies
    at or below the CAD's (sparse points, a rounded tip): when the shift
    that matches the tops (``dz0``) scores within ``tol.inspect.search_dz_keep``
    times the best of the others plus ``search_dz_floor`` (the scan shows
    its top) it is kept; else the shift is searched from
    ``search_dz_span`` outer radii below ``dz0`` to a tenth of that above,
    every ``search_dz_step`` radii, then at a tenth of the step around the
    pick — the highest shift scoring within a tenth of the score's range of
    the best (a scan that shows no cut face fits as well anywhere lower,
    where the CAD's tube still holds it)."""
    st = tol.inspect
    span, h = st.search_dz_span * cad.r_o, st.search_dz_step * cad.r_o
    grid = dz0 + np.arange(-span, 0.1 * span + tol.inspect.arange_margin, h)
    sc = _scores_dz(sub, cad, np.full(len(grid), angle), grid)
    s0 = float(_scores_dz(sub, cad, np.array([angle]), np.array([dz0]))[0])
    if s0 <= st.search_dz_keep * sc.min() + st.search_dz_floor:
        return dz0

    def pick(grid: FloatArray, sc: FloatArray) -> float:
        ok = sc <= sc.min() + 0.1 * (sc.max() - sc.min())
        return float(grid[np.flatnonzero(ok)[-1]])

    d1 = pick(grid, sc)
    fine = d1 + np.arange(-10, 11) * 0.1 * h
    return pick(fine, _scores_dz(sub, cad, np.full(len(fine), angle), fine))


def _scores_dz(sub: FloatArray, cad: Any, angles: FloatArray, dzs: FloatArray) -> FloatArray:
    """:func:`_scores` for one (angle, dz) pair per row."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x = np.stack([c * sub[:, 0] - s * sub[:, 1], s * sub[:, 0] + c * sub[:, 1],
                  sub[:, 2][None, :] + np.asarray(dzs)[:, None]], 2)
    f = cad.bound(x.reshape(-1, 3), tol.inspect.search_clip).reshape(len(angles), len(sub))
    scores: FloatArray = np.mean(np.minimum(np.abs(f), tol.inspect.search_clip), axis=1)
    return scores


def _pose(T_axis: FloatArray, angle: float, dz: float) -> FloatArray:
    Rz = _rot((0, 0, 1), angle)
    T = np.eye(4)
    T[:3, :3] = Rz
    T[2, 3] = dz
    return T @ T_axis


def _outline(cad: Any, q: FloatArray, D: Any, w: FloatArray, c: float, sigma: float,
             check_reach: bool = True) -> tuple[Any, ...] | None:
    """The points near an outline: an edge of a face the scan sees (F) with
    an analytic face it does not see (k) — the back of a tube ends at the
    bevel's edge, whose face is out of view.

    There the scan constrains the pose one-sidedly: a point pushed past the
    edge by the scanner's noise is far from the solid, while the solid may
    reach past the last points at no cost. Least squares on distances to the
    solid then stops wherever the outline first covers every point (a flat
    minimum: the turn about the axis of a scan of the back of a bevel came
    out anywhere within ±0.1°). The model that makes it well-posed: points
    lie uniformly on F up to the edge, blurred by the noise. Per point the
    normal residual is the distance to F's own surface (extended past the
    edge: the noise across the edge is the outline's business, not the
    face's), and the signed distance s = f_k of the point to k's surface
    enters through the likelihood of a blurred step, log Φ(−s/σ), with the
    face's extent paid for by the density of points just inside it
    (:func:`_outline_terms`).

    ``check_reach``: require the points within ``tol.inspect.outline_reach``
    of the edge that the band's density promises (a scan cropped farther
    short of the edge has none); an ICP run checks it until it first holds —
    later, a pose whose outline overshoots the points may have none there,
    and it is the outline's pull that brings it back.

    Returns None (no outline: every face near the points is seen, the scan
    does not reach the edge, or the CAD is a mesh), else (zone, r, n, s,
    grad_k, near, band): ``zone`` indexes the points, r and n are their
    residuals and normals on F, s and grad_k their value and gradient of k,
    ``near`` and ``band`` boolean masks of the zone (within the blur of the
    edge; the band of uniform density below it)."""
    st = tol.inspect
    fields = cad.face_fields(q)
    if fields is None:
        return None
    F, G = fields
    K = F.shape[1]
    live = (w > 0) & (D.feature == 0)
    share = np.bincount(D.face[live], minlength=K) / max(int(live.sum()), 1)
    unseen = np.flatnonzero(share < st.outline_seen)
    if not len(unseen) or len(unseen) == K:
        return None
    near_at, band_at = -st.outline_near * sigma, -st.outline_band - st.outline_near * sigma
    rows, r_z, n_z, s_z, g_z = [], [], [], [], []
    taken = np.zeros(len(q), bool)
    for k in unseen:
        s = F[:, k]
        cand = np.flatnonzero((s > band_at) & (s <= max(c, st.outline_reach)) & ~taken)
        if not len(cand):
            continue
        Fo = F[cand].copy()
        Fo[:, k] = -np.inf
        own = np.argmax(Fo, axis=1)
        f_own = Fo[np.arange(len(cand)), own]
        ok = (np.abs(f_own) < c) & ~np.isin(own, unseen)
        cand, own, f_own = cand[ok], own[ok], f_own[ok]
        if not len(cand):
            continue
        taken[cand] = True
        rows.append(cand)
        r_z.append(f_own)
        n_z.append(G[cand, own])
        s_z.append(s[cand])
        g_z.append(G[cand, k])
    if not rows:
        return None
    zone = np.concatenate(rows)
    s = np.concatenate(s_z)
    near, band = s > near_at, s <= near_at
    # the scan must reach the outline: within ``outline_reach`` of it, at
    # least half the points the band's density promises there (a scan
    # cropped short of an edge, or stopping where its views end, has none —
    # its boundary is no outline)
    rho = np.count_nonzero(band) / st.outline_band
    if rho * (st.outline_near + _STEP_MEAN) * sigma < st.outline_min_points or (
            check_reach and np.count_nonzero(s > -st.outline_reach) < 0.5 * rho * st.outline_reach):
        return None
    return (zone, np.concatenate(r_z), np.concatenate(n_z), s, np.concatenate(g_z), near, band)


def _outline_terms(outline: tuple[Any, ...], q: FloatArray, w: FloatArray, ctr: FloatArray,
                   sigma: float) -> tuple[FloatArray, FloatArray, int]:
    """Gauss–Newton terms (6 × 6 and 6) of the outline likelihood, in the
    units of the ICP's ½ Σ w r² (that is σ² × the negative log-likelihood).

    A blurred step: the density of the points' s (signed distance to the
    unseen face k) is ∝ Φ(−s/σ) (uniform on the face up to the edge, noise σ
    across it), so the negative log-likelihood is Σ −log Φ(−s_i/σ) plus the
    log of the face's extent — linearised, ρ · (the edge's shift), ρ the
    points per unit s and unit edge length, estimated point by point from
    the band of uniform density below the edge (``tol.inspect.outline_band``
    wide): −Σ_band s_i / band. The points past the edge pull it outwards,
    the points below it pull it in; at the balance the edge sits where the
    points' density says (the estimate is the maximum-likelihood one, not the
    smallest outline covering every point). σ is the ICP's robust scale
    (isotropic noise assumed)."""
    from scipy.special import log_ndtr

    zone, _, _, s, gk, near, band = outline
    wz = w[zone]
    Jk = np.hstack([np.cross(q[zone] - ctr, gk), gk])
    z = -s[near] / sigma
    lam = np.exp(-0.5 * z * z - 0.5 * math.log(2 * math.pi) - log_ndtr(z))
    a = wz[near]
    H = (Jk[near] * (a * lam * (z + lam))[:, None]).T @ Jk[near]
    g = (Jk[near] * (a * sigma * lam)[:, None]).sum(axis=0)
    g -= sigma ** 2 / tol.inspect.outline_band * (Jk[band] * wz[band][:, None]).sum(axis=0)
    return H, g, int(near.sum())


#: ∫ φ(z)²/Φ(z) dz: Fisher information on the position of a uniform density's
#: edge blurred by unit Gaussian noise, per point per unit length of density
#: (quadrature; dimensionless)
_STEP_FISHER = 0.9031972855686256
#: ∫₀^∞ Φ(−z) dz = 1/√(2π): the points a blurred step puts past its edge, in
#: units of σ × the density (dimensionless)
_STEP_MEAN = 1.0 / math.sqrt(2.0 * math.pi)


def _covariance(H: FloatArray, outline: tuple[Any, ...] | None, q: FloatArray, w: FloatArray,
                ctr: FloatArray, sigma: float, V: FloatArray) -> FloatArray:
    """(6, 6) covariance of an ICP step (rotation about ``ctr``, rad;
    translation, mm) from the Fisher information at the pose: H/σ² of the
    normal residuals (H = Σ w J Jᵀ) plus the outline's expected information
    c/(σ·band) Σ_band J_k J_kᵀ (c = ∫ φ²/Φ, :data:`_STEP_FISHER`: the
    information on the position of a blurred step per point density). Only the directions ``V``
    the step moves in; a parameter the held ones touch gets an infinite
    variance. It is the Cramér–Rao bound under the noise model (σ
    isotropic)."""
    info = H / sigma ** 2
    if outline is not None:
        zone, *_, gk, _, band = outline
        Jk = np.hstack([np.cross(q[zone][band] - ctr, gk[band]), gk[band]])
        info = info + _STEP_FISHER / (sigma * tol.inspect.outline_band) * \
            (Jk * w[zone][band][:, None]).T @ Jk
    red = V.T @ info @ V
    cov = V @ np.linalg.pinv(red) @ V.T
    held = np.diag(np.eye(6) - V @ V.T) > tol.inspect.held_share
    cov[held, held] = np.inf   # a held direction has no uncertainty to give
    return cov


def _tukey(r: FloatArray, c: float) -> FloatArray:
    """Tukey's biweight of residuals ``r`` (mm) at cut-off ``c`` (mm)."""
    u = r / c
    w: FloatArray = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
    return w


def _held(lam: FloatArray, V: FloatArray, fix_rz: bool, fix_tz: bool) -> BoolArray:
    """The eigen-directions of the Gauss–Newton matrix a step may move
    along: not degenerate, and (``fix_rz``, a rotationally symmetric tip) not
    the turn about +z, (``fix_tz``, a scan of the tube alone) not the shift
    along +z."""
    keep: BoolArray = lam > tol.inspect.degenerate * lam[-1]
    for fixed, k in ((fix_rz, 2), (fix_tz, 5)):
        if fixed:
            ez = np.zeros(6)
            ez[k] = 1.0
            keep &= np.abs(V.T @ ez) < 0.9
    return keep


def _steps_left(sw: float, st: float, prev: tuple[float, float]) -> float:
    """How many of this step are left to go (≥ 1): ICP converges linearly,
    a step shrinking by ρ per iteration leaves about ρ/(1 − ρ) of itself."""
    rho = min(max(sw / prev[0] if prev[0] > 0 else 0.0,
                  st / prev[1] if prev[1] > 0 else 0.0), 0.99)
    return max(1.0, rho / (1.0 - rho))


def _icp(p: FloatArray, cad: Any, T: FloatArray, iterations: int, *, fix_rz: bool = False,
         loose: bool = False, outlines: bool = True, anneal: float | None = None,
         fix_tz: bool = False, cap: float | None = None
         ) -> tuple[FloatArray, float, dict[str, Any]]:
    """Point-to-plane ICP (Gauss–Newton on the exact closest points and
    normals) with Tukey weights; returns T, robust σ, info. ``loose``: stop
    at ``tol.inspect.icp_loose`` (rad, mm): enough to rank start poses.
    ``anneal`` (mm, default ``tol.inspect.search_clip``): the Tukey cut-off
    starts there and halves, each time the pose has settled, down to 4.685 σ (σ the robust scale of
    the residuals) — graduated, so that the few points that fix the turn and
    the axial shift (the cut faces, the base) keep their weight while the
    tube, which most points lie on and which fits at any turn and shift, has
    already settled: a cut-off from σ alone would make the cut face's points
    outliers of the tube and hold those directions where the search left
    them. No break before the cut-off has come down.
    ``outlines``: the points near an edge of a face the scan does not show
    are fitted by the likelihood of a blurred outline (:func:`_outline`).
    ``cap`` (mm, ≥ every Tukey cut-off, i.e. ≥ ``tol.inspect.search_clip``):
    the distance queries stop there (:meth:`CadModel.distances`) — points
    farther off have no weight, and the robust scale they could move puts
    the cut-off at its ceiling either way; the pose is the same, the
    returned σ and covariance are not to be read (the loose runs' use)."""
    conv_r, conv_t = (tol.inspect.icp_loose,) * 2 if loose else \
        (tol.inspect.icp_converge_rot, tol.inspect.icp_converge_trans)
    info: dict[str, Any] = {"iterations": 0, "fixed": []}
    sigma = math.nan  # the robust scale of the residuals (mm), from the first step on
    prev = (0.0, 0.0)
    clip = tol.inspect.search_clip if anneal is None else anneal
    level = 0   # steps at this cut-off
    reached = False  # the scan reaches an outline (see _outline)
    last: tuple[Any, ...] | None = None
    # each point's nearest sub-triangle, the next iteration's first guess
    # (speed only: the distances are the same)
    hint = np.full(len(p), -1, np.int64)
    for it in range(iterations):
        q = apply(T, p)
        D = cad.distances(q, cap, hint=hint)
        r = D.distance
        n = D.normal
        med = np.median(np.abs(r))
        sigma = max(1.4826 * med, tol.inspect.sigma_floor)
        c_sigma = max(4.685 * sigma, tol.inspect.loss_floor)
        c = min(max(c_sigma, clip), tol.inspect.search_clip)
        annealing = clip > c_sigma
        w = _tukey(r, c)
        outline = _outline(cad, q, D, w, c, sigma, not reached) if outlines else None
        reached = reached or outline is not None
        if outline is not None:
            zone, r_z, n_z = outline[:3]
            r, n = r.copy(), n.copy()
            r[zone], n[zone] = r_z, n_z
            w = _tukey(r, c)
        ctr = np.average(q, axis=0, weights=w) if w.sum() > 0 else q.mean(axis=0)
        J = np.hstack([np.cross(q - ctr, n), n])
        H = (J * w[:, None]).T @ J
        g = (J * w[:, None]).T @ r
        if outline is not None:
            H_o, g_o, info["outline_points"] = _outline_terms(outline, q, w, ctr, sigma)
            H, g = H + H_o, g + g_o
        lam, V = np.linalg.eigh(H)
        if not lam[-1] > 0:
            raise ScanError("registration failed: no scan point lies within "
                            f"{c * 1e3:.3g} µm of the CAD surface; is the scan of this tip?")
        keep = _held(lam, V, fix_rz, fix_tz)
        x = -V[:, keep] @ ((V[:, keep].T @ g) / lam[keep])
        info["fixed"] = int((~keep).sum())
        # the covariance of the last step is the result's: computed once, after the loop
        last = (H - (H_o if outline is not None else 0.0), outline, q, w, ctr, sigma,
                V[:, keep])
        w_, t_ = x[:3], x[3:]
        R = _rot(w_, float(np.linalg.norm(w_)))
        step = np.eye(4)
        step[:3, :3] = R
        step[:3, 3] = ctr - R @ ctr + t_
        T = step @ T
        info["iterations"] = it + 1
        info["cutoff"] = c
        # ICP converges linearly: a step shrinking by ρ per iteration leaves
        # about ρ/(1 − ρ) of itself to go, which a weakly held direction (a
        # turn fixed by an outline alone) makes many steps
        sw, st_ = float(np.linalg.norm(w_)), float(np.linalg.norm(t_))
        left = _steps_left(sw, st_, prev)
        if sw * left < conv_r and st_ * left < conv_t and not annealing:
            break
        prev = (sw, st_)
        # the cut-off comes down once the pose has settled at this one (the
        # step moves no point by more than a tenth of it), or after six steps
        spread = math.sqrt(float(np.average(np.sum((q - ctr) ** 2, axis=1), weights=w))) \
            if w.sum() > 0 else 0.0
        level += 1
        if sw * spread + st_ < 0.1 * c or level >= 6:
            clip, level = 0.5 * clip, 0
    if last is not None:
        info["covariance"] = _covariance(*last)
    return T, sigma, info


def wall_radii(points: np.ndarray, point: np.ndarray, direction: np.ndarray,
               r_hint: float, normals: np.ndarray | None = None) -> list[float]:
    """The radii (mm, ascending) of the walls coaxial with an axis, from the
    peaks of the points' radial distances (a tube's walls are sharp peaks:
    ``tol.inspect.wall_bin`` wide, holding at least ``tol.inspect.wall_share``
    of the points within 3 ``r_hint`` of the axis); empty when no wall shows
    (a scan of the cut faces alone). With ``normals`` only points whose
    normal points at the axis (within ``tol.inspect.wall_normal``) count, so
    that a plane seen about a wrong axis is no wall, and when they are fewer
    than ``tol.inspect.wall_min_share`` of the points no wall is reported
    (the axis itself is then not to be trusted).

    Parameters
    ----------
    points : (n, 3) float — mm, any frame
    point, direction : (3,) float — the axis (direction of unit length)
    r_hint : float — mm, the CAD's outer radius (sets the range searched)
    normals : (n, 3) float, optional — unit normals of the points
    """
    d = points - point
    radial = d - np.outer(d @ direction, direction)
    r = np.linalg.norm(radial, axis=1)
    near = r < 3 * r_hint
    n_all = int(near.sum())
    if n_all < 100:
        return []
    if normals is not None:
        cos = np.abs(np.einsum("ij,ij->i", normals, radial)) / np.maximum(r, tol.tiny)
        near &= (cos > tol.inspect.wall_normal) & (np.abs(normals @ direction) < 0.15)
        if near.sum() < tol.inspect.wall_min_share * n_all:
            return []  # too little of the scan is wall about this axis to trust it
    r = r[near]
    w = tol.inspect.wall_bin
    h, edges = np.histogram(r, bins=np.arange(0.0, 3 * r_hint + w, w))
    pair = h[:-1] + h[1:]   # a wall straddling two bins counts whole
    strong = np.flatnonzero(pair >= tol.inspect.wall_share * n_all)
    walls = []
    for run in np.split(strong, np.flatnonzero(np.diff(strong) > 1) + 1):
        if len(run):
            sel = r[(r >= edges[run[0]]) & (r < edges[run[-1] + 2])]
            walls.append(float(np.median(sel)))
    return walls


def _free_axis(p: np.ndarray, nrm: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """An axis found without any radius: the direction the wall-like points'
    normals are most nearly perpendicular to, through the point nearest all
    their normal lines (a tube's walls, inner and outer, all point at it);
    returns (point, direction, the points' normals), None when too few
    points look like wall. ``nrm``: the points' :func:`point_normals`, if
    the caller has them."""
    nrm = point_normals(p) if nrm is None else nrm
    a = np.linalg.eigh(nrm.T @ nrm)[1][:, 0]
    wall = np.ones(len(p), bool)
    for _ in range(4):
        wall = np.abs(nrm @ a) < 0.15
        if wall.sum() < 20:
            return None
        a = np.linalg.eigh(nrm[wall].T @ nrm[wall])[1][:, 0]
    n = nrm[wall] - np.outer(nrm[wall] @ a, a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), tol.tiny)
    q = p[wall]
    # least squares: the point c whose offset from each q, across a, lies along its normal
    P = np.eye(3)[None] - n[:, :, None] * n[:, None, :] - np.outer(a, a)[None]
    A = P.sum(axis=0) + np.outer(a, a)
    b = np.einsum("nij,nj->i", P, q) + a * (a @ q.mean(axis=0))
    return np.linalg.solve(A, b), a, nrm


def _check_gauge(points: FloatArray, cad: Any, max_error: float,
                 nrm: FloatArray | None = None) -> None:
    """Refuse, before the costly search, a scan whose coaxial walls are not
    the CAD's: with two or more walls the outermost must be its outer wall;
    a single wall (a scan of one side) its outer or its inner wall."""
    axis = _free_axis(points, nrm)
    if axis is None:
        return
    walls = wall_radii(points, axis[0], axis[1], cad.r_o, normals=axis[2])
    if not walls:
        return
    r = walls[-1]
    if abs(r - cad.r_o) <= max_error * cad.r_o:
        return
    if len(walls) == 1 and abs(r - cad.r_i) <= max_error * cad.r_i:
        return
    raise ScanError(f"its outermost wall has diameter {2 * r:.4f} mm where the CAD's outer "
                    f"diameter is {2 * cad.r_o:.4f} mm ({100 * (r / cad.r_o - 1):+.1f} %, allowed "
                    f"±{100 * max_error:g} %): a scan of another gauge? (refused before "
                    "registration)")


def register(points: AnyArray, cad: Any, *, inlier_distance: float = 0.01,
             seed: int = 0, progress: Callable[[str], None] | None = None,
             max_diameter_error: float | None = None) -> Registration:
    """Register scan points (scanner frame, mm) onto a :class:`CadModel`.

    Parameters
    ----------
    points : (n, 3) float — mm
    cad : CadModel
    inlier_distance : float — fitness and inlier RMSE count points within this (mm)
    seed : int — subsets are drawn with this seed (results are reproducible)
    progress : callable(str), optional — stage messages
    max_diameter_error : float, optional — refuse, right after the axis fit
        and before the costly search, a scan whose outermost coaxial wall
        (:func:`wall_radii`) is off the CAD's outer diameter (and, if
        smaller, its inner one) by more than this share: a wrong gauge;
        None: only warn beyond 5 %

    Returns
    -------
    Registration

    Raises
    ------
    ScanError
        Too few points, or points on one place, a line or a plane
        (:func:`tipgeo.inspect.checks.check_geometry`); no outer wall found;
        no point near the CAD surface (the scan does not show this tip).

    Points may be float32 (offsets from an origin): only the subset the
    registration uses is taken to float64.
    """
    from .checks import check_geometry

    say = progress or (lambda msg: None)
    rng = np.random.default_rng(seed)
    p = _registration_points(points, rng)
    faces = planar_cut_faces(cad)
    geo = check_geometry(p, cad.r_o, register=True, allow_plane=bool(faces))
    if geo["rms_extent_mm"][2] < tol.inspect.min_spread_plane * cad.r_o:
        return _register_face(p, cad, faces, inlier_distance, rng, say)
    warnings: list[str] = []
    if len(p) < 200:
        warnings.append(f"only {len(p)} points: registration may be unreliable")
    # isolated points out of the axis fit and the search (a stray point can
    # pass for the tip's top); not out of ICP, whose Tukey weights take care
    # of them, since the statistical filter also takes the sparse points
    # along a scan's edges, which hold an outline-only pose
    clean = _remove_outliers(p)
    # the axis needs far fewer points than the final refinement
    p_ax = clean if len(clean) <= tol.inspect.axis_points else \
        clean[rng.choice(len(clean), tol.inspect.axis_points, replace=False)]
    nrm_ax = point_normals(p_ax)   # for the gauge check and the axis fit alike
    if max_diameter_error is not None:  # no sharp coaxial wall: no refusal here
        _check_gauge(p_ax, cad, max_diameter_error, nrm_ax)
    say(f"axis fit on {len(p_ax)} points")
    point, a, radius, rms = _axis_stage(p_ax, cad.r_o, cad.r_i, nrm_ax)
    axis = {"point_mm": point.tolist(), "direction": a.tolist(), "outer_radius_mm": radius,
            "outer_diameter_mm": 2 * radius, "fit_rms_mm": rms}
    off = abs(radius - cad.r_o) / cad.r_o
    if off > 0.05:
        warnings.append(f"fitted outer diameter {2 * radius:.4f} mm differs from the CAD's "
                        f"{2 * cad.r_o:.4f} mm by more than 5 %")
    if _tube_only(clean, point, a, radius, cad):
        return _register_tube(p, clean, cad, point, a, radius, axis, warnings, inlier_distance,
                              rng, say)
    say("global search about the axis")
    search: dict[str, Any] = {"coarse_step_deg": 2 * math.degrees(tol.inspect.search_step),
                              "fine_step_deg": 0.5 * math.degrees(tol.inspect.search_step)}
    cands = _candidate_poses(clean, cad, point, a, rng, search)
    say(f"ICP from {min(4, len(cands))} candidate poses")
    results, skipped = _ranked_starts(p, cad, cands, rng)
    best = results[0]
    T, sigma, info = _refine(p, cad, best[1], best[5], rng)
    d = cad.distances(apply(T, p)).distance
    ok = np.abs(d) <= inlier_distance
    fitness = float(ok.mean())
    rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    search.update({"candidates": len(results), "candidates_not_started": skipped,
                   "best_robust_rms_mm": best[0]})
    sym = cad.symmetry
    _runner_up(results, sym, search, warnings)
    fixed = _held_notes(sym, info, warnings)
    if fitness < 0.5:
        warnings.append(f"low fitness {fitness:.2f}: fewer than half the points lie within "
                        f"{inlier_distance * 1e3:g} µm of the CAD surface")
    search["sigma_mm"] = sigma
    if sym > 1:
        say(f"pose determined up to the tip's {sym}-fold symmetry ({360 / sym:g}° turns)")
    return Registration(T, fitness, rmse, inlier_distance, axis, search, warnings,
                        info["iterations"], len(p), fixed, sym,
                        _uncertainty(info.get("covariance"), sym))


def _registration_points(points: AnyArray, rng: np.random.Generator) -> FloatArray:
    """The (float64) subset of at most ``tol.inspect.register_points``
    points (mm) the registration works on; checked (n, 3) and finite."""
    p_all = points if isinstance(points, np.ndarray) else np.asarray(points, float)
    if p_all.ndim != 2 or p_all.shape[1] != 3:
        raise ScanError(f"points have shape {p_all.shape}; expected (n, 3)")
    n = min(len(p_all), tol.inspect.register_points)
    p = p_all[rng.choice(len(p_all), n, replace=False)] if n < len(p_all) else p_all
    p = np.asarray(p, np.float64)
    if not np.all(np.isfinite(p)):
        raise ScanError("scan points have non-finite (NaN or infinite) coordinates")
    return p


#: A start pose of the search: (score, axis sign, turn about the axis (rad), 4 × 4 transform).
_Candidate = tuple[float, float, float, FloatArray]


def _candidate_poses(clean: FloatArray, cad: Any, point: FloatArray, a: FloatArray,
                     rng: np.random.Generator, search: dict[str, Any]) -> list[_Candidate]:
    """The start poses of the global search about the fitted axis (both
    senses of it), best score first; the scores go into ``search``."""
    cands: list[_Candidate] = []
    sym = cad.symmetry
    z_feature = _feature_z(cad)
    on_axis: dict[float, tuple[FloatArray, FloatArray]] = {}
    # the coarse minima of both senses: (coarse score, sign, turn, points, shift)
    minima: list[tuple[float, float, float, FloatArray, float]] = []
    for sign in (1.0, -1.0):
        Ta = _frame(point, a, sign)
        q = apply(Ta, clean)
        on_axis[sign] = (Ta, q)
        if sym == 0:
            dz = cad.z_top - np.quantile(q[:, 2], 0.9995)
            cands.append((0.0, sign, 0.0, _pose(Ta, 0.0, dz)))
            continue
        coarse, sc, mins, sub, dz = _search(q, cad, tol.inspect.search_step,
                                            tol.inspect.search_points, rng, 2 * math.pi / sym,
                                            z_feature)
        minima += [(float(sc[m]), sign, float(coarse[m]), sub, dz) for m in mins]
        search[f"scores_{'plus' if sign > 0 else 'minus'}"] = sc.round(6).tolist()
    if minima:
        cands += _refined_minima(minima, cad, on_axis, 2 * math.pi / sym, search)
    if sym != 0 and min((c[0] for c in cands), default=math.inf) > tol.inspect.window_score:
        # no pose with the scan's top at the CAD's fits: a window short of the tip
        for sign, (Ta, q) in on_axis.items():
            found = _window_search(q, cad, rng, 2 * math.pi / sym, z_feature)
            for turn, score, dz in found:
                cands.append((score, sign, turn, _pose(Ta, turn, dz)))
            search[f"window_turns_{'plus' if sign > 0 else 'minus'}_deg"] = [
                [math.degrees(t_), s_, dz_] for t_, s_, dz_ in found]
    cands.sort(key=lambda c: c[0])
    return cands


def _far_worse(score: float, best: float) -> bool:
    """Whether a search score (mm) is so far above ``best`` (mm) that its
    pose can neither win nor make the registration ambiguous: more than
    ``tol.inspect.start_ratio`` times it and ``start_floor`` above it."""
    st = tol.inspect
    return score > st.start_ratio * best and score > best + st.start_floor


def _refined_minima(minima: list[tuple[float, float, float, FloatArray, float]], cad: Any,
                    on_axis: dict[float, tuple[FloatArray, FloatArray]], period: float,
                    search: dict[str, Any]) -> list[_Candidate]:
    """The coarse minima of both senses ((coarse score, sign, turn, points,
    shift)) refined (:func:`_refine_turn`) into candidate poses, best coarse
    score first, except those far worse than the best one — the upside-down
    tip, a turn half a period off (``tol.inspect.start_ratio``,
    ``start_floor``); the refined turns and the count left out go into
    ``search``."""
    st = tol.inspect
    first = min(m[0] for m in minima)
    refined: dict[float, list[tuple[float, float, float]]] = {1.0: [], -1.0: []}
    skipped = 0
    for c, sign, turn, sub, dz in sorted(minima, key=lambda m: m[0]):
        if _far_worse(c, first):
            skipped += 1
            continue
        refined[sign].append(_refine_turn(sub, cad, turn, dz, st.search_step, period))
    cands: list[_Candidate] = []
    for sign, found in refined.items():
        found.sort(key=lambda b: b[1])
        Ta = on_axis[sign][0]
        cands += [(score, sign, turn, _pose(Ta, turn, dz)) for turn, score, dz in found]
        search[f"best_turns_{'plus' if sign > 0 else 'minus'}_deg"] = [
            [math.degrees(t_), s_] for t_, s_, _ in found]
    search["coarse_minima_not_refined"] = skipped
    return cands


def _window_search(q_all: FloatArray, cad: Any, rng: np.random.Generator, period: float,
                   z_feature: float) -> list[tuple[float, float, float]]:
    """Turns and axial shifts searched together, for a scan (on the axis,
    mm) whose top is not the CAD's: every coarse turn at every shift that
    puts the scan's top between the CAD's lowest cut feature and the CAD's
    top (every ``tol.inspect.window_dz_step`` outer radii); at the three
    best separate (turn, shift) cells the turn refined (every step/2 within
    ±2 steps) and then the shift (every ``search_dz_step`` radii within ±1
    coarse shift step). Returns (turn (rad), score (mm), dz (mm)), best
    first."""
    st = tol.inspect
    step = st.search_step
    sub = q_all[rng.choice(len(q_all), min(st.search_points, len(q_all)), replace=False)]
    coarse_sub = sub[: max(len(sub) // 3, 1)]
    z_hi = float(np.quantile(q_all[:, 2], 0.9995))
    h = st.window_dz_step * cad.r_o
    dzs = np.arange(z_feature - z_hi, cad.z_top - z_hi + st.arange_margin, h)
    if not len(dzs):
        return []
    turns = np.arange(0.0, period - st.arange_margin, 2 * step)
    grid = np.array([_scores(coarse_sub, cad, turns, float(dz)) for dz in dzs])   # (shift, turn)
    order = np.argsort(grid, axis=None, kind="stable")
    picks: list[tuple[int, int]] = []
    for flat in order:
        i, j = divmod(int(flat), len(turns))
        # separate cells: two coarse steps apart in the turn (around the
        # period) or two in the shift
        if all(abs(i - pi) > 2 or min(abs(j - pj), len(turns) - abs(j - pj)) > 2
               for pi, pj in picks):
            picks.append((i, j))
        if len(picks) == 3:
            break
    fine_dz = np.arange(-10, 11) * 0.1 * h
    found = []
    for i, j in picks:
        turn, _ = _fine_turn(sub, cad, float(turns[j]), float(dzs[i]), step, period)
        shifts = dzs[i] + fine_dz
        ds = _scores_dz(sub, cad, np.full(len(shifts), turn), shifts)
        k = int(np.argmin(ds))
        found.append((turn, float(ds[k]), float(shifts[k])))
    found.sort(key=lambda f: f[1])
    return found


#: A start after loose ICP: (robust RMS (mm), transform, sign, turn, score, Tukey cut-off).
_Start = tuple[float, FloatArray, float, float, float, Any]


def _ranked_starts(p: FloatArray, cad: Any, cands: list[_Candidate],
                   rng: np.random.Generator) -> tuple[list[_Start], int]:
    """Loose ICP from the four best candidates on a small subset, ranked by
    the robust RMS of the residuals (mm), best first; and how many of the
    four were not started: a candidate scoring far worse than both the best
    candidate and the best pose reached so far (``tol.inspect.start_ratio``,
    ``start_floor``) — the upside-down tip, a turn half a period off. Such a
    start reaches no pose that fits as well (the test suite's winners and
    near-ties all scored within 2.9 times the best), so it can neither win
    nor make the pose ambiguous; a start is run whenever the poses reached
    fit no better than it scores."""
    st = tol.inspect
    small = p[rng.choice(len(p), min(st.icp_start_points, len(p)), replace=False)]
    results: list[_Start] = []
    top = cands[:4]
    first = min((c[0] for c in top), default=math.inf)
    skipped = 0
    for score, sign, ang, T0 in top:
        if results and _far_worse(score, max(first, min(r[0] for r in results))):
            skipped += 1
            continue
        try:
            # far points' queries capped at the clip: the same poses and scores
            T, sig, info = _icp(small, cad, T0, 30, fix_rz=(cad.symmetry == 0), loose=True,
                                cap=st.search_clip)
            d = cad.distances(apply(T, small), st.search_clip).distance
        except (ScanError, TipGeoError):
            continue  # this start is too far off to converge; the others may not be
        rrms = float(np.sqrt(np.mean(np.minimum(d * d, st.search_clip ** 2))))
        results.append((rrms, T, sign, ang, score, info.get("cutoff")))
    if not results:
        raise ScanError("registration failed: from none of the candidate poses does any scan "
                        f"point lie within {st.search_clip * 1e3:g} µm of the CAD "
                        "surface; is the scan of this tip?")
    results.sort(key=lambda r: r[0])
    return results, skipped


def _refine(p: FloatArray, cad: Any, T0: FloatArray, cutoff: Any,
            rng: np.random.Generator) -> tuple[FloatArray, float, dict[str, Any]]:
    """Gauss–Newton to convergence on a subset, then on every registration
    point from there (a few steps): the final pose is that of the full set."""
    sym = cad.symmetry
    mid = p if len(p) <= tol.inspect.icp_mid_points else \
        p[rng.choice(len(p), tol.inspect.icp_mid_points, replace=False)]
    T, sigma, info = _icp(mid, cad, T0, tol.inspect.icp_iterations, fix_rz=(sym == 0),
                          anneal=cutoff)
    if mid is not p:
        T, sigma, info2 = _icp(p, cad, T, tol.inspect.icp_iterations, fix_rz=(sym == 0),
                               anneal=info.get("cutoff"))
        info["iterations"] += info2["iterations"]
        info["fixed"] = info2["fixed"]
        info["covariance"] = info2["covariance"]
    return T, sigma, info


def _runner_up(results: list[_Start], sym: int, search: dict[str, Any],
               warnings: list[str]) -> None:
    """Ambiguity: a clearly different pose (turned more than 2°, modulo the
    tip's symmetry) that fits almost as well; into ``search`` and ``warnings``."""
    best = results[0]
    Rb = best[1][:3, :3]
    for rr, Tr, *_ in results[1:]:
        dR = Tr[:3, :3] @ Rb.T
        ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1) / 2))))
        if sym > 1:
            ang = min(ang % (360 / sym), 360 / sym - ang % (360 / sym))
        if ang > 2.0 and sym != 0:
            search["runner_up_robust_rms_mm"] = rr
            search["runner_up_angle_deg"] = ang
            if rr < tol.inspect.ambiguity_ratio * best[0]:
                warnings.append(
                    f"ambiguous registration: a pose turned {ang:.1f}° away fits almost as "
                    f"well (robust RMS {rr * 1e3:.2f} vs {best[0] * 1e3:.2f} µm); check "
                    "that the scan shows the tip's features (bevel, planes, serrations)")
            break


def _held_notes(sym: int, info: dict[str, Any], warnings: list[str]) -> list[str]:
    """The degrees of freedom held at the search result (and a warning each)."""
    fixed = []
    if sym == 0:
        fixed.append("rotation about the axis (the tip is rotationally symmetric; the "
                     "deviations do not depend on it)")
        warnings.append("rotation about the axis is not determined: the tip is rotationally "
                        "symmetric")
    elif info.get("fixed"):
        fixed.append(f"{info['fixed']} direction(s) the scan does not constrain")
        warnings.append(f"{info['fixed']} degree(s) of freedom are not constrained by the scan; "
                        "held at the search result")
    return fixed


def planar_cut_faces(cad: Any) -> dict[str, tuple[FloatArray, FloatArray]]:
    """The CAD's planar cut faces: label → (unit normal, outward; an area-
    weighted sample of up to 20,000 points on it), cannula frame, mm. A face
    is planar when its mesh vertices lie within 0.1 µm of their plane."""
    tip = cad.tip
    if tip is None:
        return {}
    cached: dict[str, tuple[FloatArray, FloatArray]] | None = getattr(cad, "_planar_cut_faces",
                                                                        None)
    if cached is not None:
        return cached
    out = {}
    names = np.asarray(tip.label_names, dtype=object)
    rng = np.random.default_rng(0)
    for k, name in enumerate(tip.label_names):
        if not str(name).startswith("cut"):
            continue
        on = np.flatnonzero(tip.label_ids == k)
        if not len(on):
            continue
        v = tip.vertices[np.unique(tip.faces[on])]
        c = v.mean(axis=0)
        _, sv, vt = np.linalg.svd(v - c, full_matrices=False)
        if sv[-1] / math.sqrt(len(v)) > tol.inspect.planar_face_rms:
            continue
        tri = tip.vertices[tip.faces[on]]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                    axis=1)
        m = min(20_000, 50 * len(on) + 2000)
        k_ = rng.choice(len(on), m, p=area / area.sum())
        r1, r2 = np.sqrt(rng.random(m)), rng.random(m)
        pts = tri[k_, 0] * (1 - r1)[:, None] + tri[k_, 1] * (r1 * (1 - r2))[:, None] + \
            tri[k_, 2] * (r1 * r2)[:, None]
        n = vt[2]
        nt = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(axis=0)
        if n @ nt < 0:
            n = -n
        out[str(names[k])] = (n, pts)
    try:
        cad._planar_cut_faces = out
    except AttributeError:
        pass
    return out


def _plane_frame(n: FloatArray) -> tuple[FloatArray, FloatArray]:
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _register_face(p: FloatArray, cad: Any, faces: dict[str, tuple[FloatArray, FloatArray]],
                   inlier_distance: float, rng: np.random.Generator,
                   say: Callable[[str], None]) -> Registration:
    """A scan of one planar cut face alone (its points on a plane): the
    plane onto one of the CAD's planar cut faces (either side), the face's
    extent onto the CAD face's — centroids together, principal axes along
    each other (four ways) — then ICP, in which the face's outline against
    the walls it ends at (:func:`_outline`) holds the turn and the shift in
    the plane. The best fit wins; each direction's 1σ uncertainty is
    reported, and what the outline does not hold (a mesh CAD has no
    analytic walls to fit it against) is named as held."""
    say("the scan lies on a plane: registered as one planar cut face, by its outline")
    cs = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - cs, full_matrices=False)
    ns = vt[2]
    small = p[rng.choice(len(p), min(tol.inspect.icp_start_points * 2, len(p)), replace=False)]
    results = []
    for label, (nc, q) in faces.items():
        cc = q.mean(axis=0)
        f1, f2 = _plane_frame(nc)
        Q = np.column_stack([(q - cc) @ f1, (q - cc) @ f2])
        wq, vq = np.linalg.eigh(Q.T @ Q / len(Q))
        for sgn in (1.0, -1.0):
            R0 = _align(ns * sgn, nc)
            P3 = (p - cs) @ R0.T
            P = np.column_stack([P3 @ f1, P3 @ f2])
            wp, vp = np.linalg.eigh(P.T @ P / len(P))
            for flip in (1.0, -1.0):
                # the scan's major axis onto the CAD face's (either way round)
                a_s = math.atan2(vp[1, 1], vp[0, 1])
                a_c = math.atan2(vq[1, 1] * flip, vq[0, 1] * flip)
                Rn = _rot(nc, a_c - a_s)
                R = Rn @ R0
                T0 = np.eye(4)
                T0[:3, :3] = R
                T0[:3, 3] = cc - R @ cs
                try:
                    T, _, info = _icp(small, cad, T0, 30, loose=True)
                except (ScanError, TipGeoError):
                    continue
                d = cad.distances(apply(T, small)).distance
                rr = float(np.sqrt(np.mean(np.minimum(d * d, tol.inspect.search_clip ** 2))))
                results.append((rr, T, label, info.get("cutoff")))
    if not results:
        raise ScanError("the scan lies on a plane, and no planar cut face of the CAD fits it "
                        "(registration of a face alone failed)")
    results.sort(key=lambda r: r[0])
    rr, T, label, cut = results[0]
    mid = p if len(p) <= tol.inspect.icp_mid_points else \
        p[rng.choice(len(p), tol.inspect.icp_mid_points, replace=False)]
    T, sigma, info = _icp(mid, cad, T, tol.inspect.icp_iterations, anneal=cut)
    if mid is not p:
        T, sigma, info2 = _icp(p, cad, T, tol.inspect.icp_iterations, anneal=info.get("cutoff"))
        info["iterations"] += info2["iterations"]
        info["fixed"] = info2["fixed"]
        info["covariance"] = info2["covariance"]
    d = cad.distances(apply(T, p)).distance
    ok = np.abs(d) <= inlier_distance
    fitness = float(ok.mean())
    rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    warnings, fixed = [], []
    if info.get("fixed"):
        fixed.append(f"{info['fixed']} in-plane direction(s) the face's outline does not hold "
                     "(a mesh CAD, or a face cut short of its outline)")
        warnings.append(f"{info['fixed']} degree(s) of freedom are not constrained by the scan; "
                        "held at the search result")
    search = {"face_only": label, "candidates": len(results), "best_robust_rms_mm": rr,
              "sigma_mm": sigma}
    Rb = T[:3, :3]
    for r2, T2, _, _ in results[1:]:
        dR = T2[:3, :3] @ Rb.T
        ang = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1) / 2))))
        if ang > 2.0 or np.linalg.norm(T2[:3, 3] - T[:3, 3]) > 0.05:
            search["runner_up_robust_rms_mm"] = r2
            search["runner_up_angle_deg"] = ang
            if r2 <= 1.02 * rr + tol.inspect.face_tie:
                # the face alone looks the same in both poses (a bevel's face is
                # an elliptic ring: a half turn about its normal maps it onto
                # itself): the scanned points' deviations are the same in both
                w_ = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
                about = "its normal" if abs(w_ @ faces[label][0]) > 0.99 * np.linalg.norm(w_) \
                    else "an axis"
                fixed.append(f"a turn of {ang:.1f}° about {about}: the face alone looks the same "
                             "(its deviations do not depend on it; the rest of the tip's do)")
                warnings.append(f"free: a turn of {ang:.1f}° about the face's normal — the face "
                                f"{label} alone looks the same turned (robust RMS "
                                f"{r2 * 1e3:.2f} vs {rr * 1e3:.2f} µm); the scanned points' "
                                "deviations do not depend on it")
                search["free"] = [f"turn of {ang:.1f}° about {about}"]
            elif r2 < tol.inspect.ambiguity_ratio * rr and cad.symmetry == 1:
                warnings.append(
                    f"ambiguous registration: a pose turned {ang:.1f}° away fits almost as "
                    f"well (robust RMS {r2 * 1e3:.2f} vs {rr * 1e3:.2f} µm); check that the "
                    "scan shows the whole face")
            break
    cs_cad = apply(T, p).mean(axis=0)
    axis = {"point_mm": cs_cad.tolist(), "direction": ns.tolist(), "outer_radius_mm": cad.r_o,
            "outer_diameter_mm": 2 * cad.r_o, "fit_rms_mm": float("nan"),
            "note": f"no wall in the scan: the face alone ({label}), registered by its outline"}
    sym = cad.symmetry
    return Registration(T, fitness, rmse, inlier_distance, axis, search, warnings,
                        info["iterations"], len(p), fixed, sym if sym != 0 else 1,
                        _uncertainty(info.get("covariance"), sym if sym != 0 else 1))


#: a scan of the tube alone: this share of its points on the two walls
TUBE_ONLY_SHARE = 0.98


def _tube_only(q: FloatArray, point: FloatArray, a: FloatArray, radius: float,
               cad: Any) -> bool:
    """Whether the scan shows the tube alone — no cut face, no outline of
    one: at least :data:`TUBE_ONLY_SHARE` of the points within
    max(10 µm, 1 % of the radius) of the fitted outer wall or of the bore
    one CAD wall thickness in, and both of the scan's ends about the axis
    square (cropped: the extreme point per 10° of turn within a quarter of
    the outer radius — the back of a tube up to a bevel's outline rises
    along it by the bevel's length: that outline fixes the turn, see
    :func:`_outline`). A scan cropped obliquely is left to the search."""
    d = q - point
    z = d @ a
    rho = np.linalg.norm(d - np.outer(z, a), axis=1)
    band = max(0.01, 0.01 * radius)
    wall = (np.abs(rho - radius) < band) | (np.abs(rho - radius + cad.r_o - cad.r_i) < band)
    if wall.mean() < TUBE_ONLY_SHARE:
        return False
    e1 = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    g = np.arctan2(d @ np.cross(a, e1), d @ e1)
    b = np.floor((g + math.pi) / math.radians(10.0)).astype(int)
    for zz in (z, -z):      # both ends cut square (a crop), neither an outline
        tops = [zz[b == k].max() for k in np.unique(b) if np.count_nonzero(b == k) >= 5]
        if len(tops) < 3 or max(tops) - min(tops) >= 0.25 * cad.r_o:
            return False
    return True


def _register_tube(p: FloatArray, clean: FloatArray, cad: Any, point: FloatArray, a: FloatArray,
                   radius: float, axis: dict[str, Any], warnings: list[str],
                   inlier_distance: float, rng: np.random.Generator,
                   say: Callable[[str], None]) -> Registration:
    """The pose of a scan of the tube alone, up to what it leaves free: its
    axis on the CAD's, its far end just below the lowest of the CAD's cut
    features (where the tube is tube at any turn and shift); the turn about
    the axis and the shift along it are free (no deviation depends on them)
    and are reported as such."""
    say("the scan shows the tube alone: the turn about and the shift along the axis are free")
    Ta = _frame(point, a, 1.0)
    q = apply(Ta, clean)
    z_feature = _feature_z(cad)
    dz = z_feature - 0.05 * cad.r_o - float(np.quantile(q[:, 2], 0.9995))
    T0 = _pose(Ta, 0.0, dz)
    mid = p if len(p) <= tol.inspect.icp_mid_points else \
        p[rng.choice(len(p), tol.inspect.icp_mid_points, replace=False)]
    T, sigma, info = _icp(mid, cad, T0, tol.inspect.icp_iterations, fix_rz=True, fix_tz=True,
                          outlines=False)
    if mid is not p:
        T, sigma, info2 = _icp(p, cad, T, tol.inspect.icp_iterations, fix_rz=True,
                               fix_tz=True, outlines=False, anneal=info.get("cutoff"))
        info["iterations"] += info2["iterations"]
        info["covariance"] = info2["covariance"]
    d = cad.distances(apply(T, p)).distance
    ok = np.abs(d) <= inlier_distance
    fitness = float(ok.mean())
    rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    free = ["rotation about the axis (the scan shows the tube alone: no deviation depends "
            "on it)", "translation along the axis (the scan shows the tube alone: placed "
            "just below the cut faces; no deviation depends on it)"]
    warnings.append("free: rotation about the axis and translation along the axis — the "
                    "scan shows the tube alone (no cut face, no outline of one); its deviations "
                    "do not depend on them")
    unc = _uncertainty(info.get("covariance"), 0)
    if unc:
        unc["translation_um"][2] = None
    search = {"tube_only": True, "sigma_mm": sigma,
              "free": ["rotation about the axis", "translation along the axis"]}
    return Registration(T, fitness, rmse, inlier_distance, axis, search, warnings,
                        info["iterations"], len(p), free, 0, unc)


def _uncertainty(cov: FloatArray | None, sym: int) -> dict[str, Any]:
    """The report's 1σ pose uncertainty from the ICP covariance (rad, mm)."""
    if cov is None:
        return {}
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    rot = [math.degrees(v) if math.isfinite(v) else None for v in sd[:3]]
    if sym == 0:
        rot[2] = None
    return {"rotation_deg": rot, "turn_about_axis_deg": rot[2],
            "translation_um": [v * 1e3 if math.isfinite(v) else None for v in sd[3:]],
            "note": "1σ from the information the scan holds about each direction (a "
                    "Cramér–Rao bound for σ-isotropic noise along the surface and across "
                    "outlines); rotations about the cannula frame's axes, translation at the "
                    "points' centroid"}


def _remove_outliers(p: np.ndarray, k: int = 8, ratio: float = 3.0) -> np.ndarray:
    """Statistical outlier removal: drop points whose mean distance to their
    k neighbours exceeds the mean by ``ratio`` standard deviations."""
    from .knn import knn  # exact, compiled: no scipy.spatial import on this path

    if len(p) <= k + 1:
        return p
    d, _ = knn(p, k + 1)
    m = d[:, 1:].mean(axis=1)
    keep = m <= m.mean() + ratio * m.std()
    kept: FloatArray = p[keep]
    return kept
