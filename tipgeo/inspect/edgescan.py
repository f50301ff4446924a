"""Cutting edges and angles measured on a scan: the outer and inner edges traced
in the point cloud, then λ, θ, α and l_c by the same analysis as the CAD's.

Frames and units: the points in the cannula frame (a registered scan: +z
along the axis towards the tip, mm); results in the CAD's *analysis frame*
(:mod:`tipgeo.edges`: turned about +z and shifted along it so that the CAD's
heel lies at γ = 0, z = 0), so measured and CAD values stand at the same γ.
mm and rad inside; µm and degrees only in :meth:`MeasuredEdges.summary`.

Method (thesis §3.1.2–3.1.4 applied to measured surfaces):

1. **Walls.** The outer and inner walls are fitted as cylinders near the
   nominal radii: ρ = R + a cos γ + b sin γ + z (c cos γ + d sin γ) (the
   radius plus a small axis offset and tilt left by the registration), by
   least squares, trimmed at ``tol.scan_edges.trim`` robust σ.
2. **Cut face, locally.** Points inside the wall (farther than the edge band
   ``edge_band`` from both fitted walls) are cut-face points: the band keeps
   the edge rounding (a fillet of radius ρ_f reaches at most 2 ρ_f from the
   wall, whatever the wedge angle) and the wall's own noise out. In a window
   about each sample γ₀ (the narrowest holding ``tol.scan_edges.
   ref_window_points`` face points) the scan's deviation from the CAD's exact
   cut surface, e = z − z_CAD(ρ, γ), is fitted with
   e = c₀ + c₁ Δs + c₂ Δρ + c₃ Δs² + c₄ Δs Δρ (Δs = R Δγ along the edge, Δρ
   from the wall), trimmed like the walls. The CAD carries the face's
   curvature, so the fit has no model bias however sharply the face turns
   (the helical tip: θ ≈ 7.6° at the point, the face twisting ~1° per degree
   of γ); what the part does differently — another grinding angle, wear, an
   offset — is the fitted deviation, measured. A CAD without exact surfaces
   (a bare mesh), or ``reference='none'``, gets free quadrics instead: height
   1, u, v, u², uv over the patch's best plane (u along its longest spread);
   on the helical tip those read θ up to 0.7° and the edge 2.5 µm off
   noise-free, from the curvature a quadric over a wide window leaves out.
3. **Edges.** Each wall's edge point at γ₀ is where the local cut surface
   meets the fitted wall's generator at γ₀ — the sharp edge the two surfaces
   define (for a rounded edge: the virtual sharp edge). Its outward normal
   is the local surface's: the CAD's normal tilted by the deviation's slopes
   (c₁ along the edge, c₂ across), or the quadric's.
4. **Rounding.** The radius of the arc that rounds the corner of the two
   fitted surfaces (tangent to both), fitted to the points within the edge
   band of the edge, each in its section across the edge: a worn or honed
   edge's radius.
5. **Angles.** The edge points of each piece (the CAD's pieces: a window
   never straddles a kink) are fitted with eq. 3.12 and analysed like the
   CAD's (:func:`tipgeo.angles.analyze_edges`): z, z′ and the tangent from
   the fit, the normals from step 3. The fit is in the CAD's series (its
   fitted w; ``cad_basis``): a noisy edge fixes w poorly (0.9972–0.99998 on
   scans of the helical inner edge, exactly 0.998), and on a full turn a
   different w moves the series' seam at the heel, which read λ up to 1.1°
   off there. The CAD's angles come from the same ``fourier`` path (exact
   edge samples, exact normals) or, for a mesh CAD, the ``mesh`` path.

Where the accuracy is stated (:meth:`MeasuredEdges.region`): farther than
``tol.scan_edges.heel_window`` = 5° in γ from the heel (γ = 0) and
``tol.scan_edges.tip_window`` = 5° from both edges' tips (γ of the CAD outer
and inner edges' highest points), one region for both edges. Nearer the tip λ
turns fastest and the eq. 3.12 fit reads it up to 0.62° off at σ = 2 µm; edge
position and θ hold everywhere, λ at the heel too (synthetic scans of the
bevel and helical 14G tips, σ = 1–2 µm, 5 µm edge rounding, 4 seeds: position
≤ 3.3 µm, λ ≤ 0.37° and θ ≤ 0.23° in the region, θ ≤ 0.25° everywhere, l_c ≤
0.04 %).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import AnyArray, ArrayLike, BoolArray, FloatArray
from ..edges import Edge, EdgePiece, rotate_z
from ..errors import SpecError
from ..plot import styled
from ..tolerances import tol
from .scanio import ScanError, check_points

if TYPE_CHECKING:
    from ..angles import AngleReport, WallAngles
    from ..spec import TipSpec

__all__ = ["MeasuredEdges", "measure_edges", "plot_measured_edges", "edges_markdown",
           "edges_text"]


@dataclass
class MeasuredEdges:
    """Edges and cutting angles measured on a scan, beside the CAD's.

    Attributes
    ----------
    measured : AngleReport — the scan's (analysis frame of the CAD)
    cad : AngleReport — the CAD's, same analysis
    samples : dict — per wall: ``gamma`` (m,) rad, ``z`` (m,) mm, ``normal``
        (m, 3) (unsmoothed), ``points`` (m,) int (points in the local fit),
        ``rms`` (m,) mm (fit residual), ``window`` (m,) rad (its width) — the
        traced edge before the Fourier fit
    walls : dict — per wall: fitted radius (mm), axis offset (mm) and tilt
        (rad) of the cylinder, its points and RMS residual (µm), and
        ``rounding``: the edge's rounding radius (µm) fitted to the points
        within the edge band of the traced edge (heel and tip windows out)
    heel : (float, float) — the CAD heel's cannula-frame γ (rad) and z (mm)
    tip_gamma, tip_gamma_inner : float — γ of the CAD outer and inner edges'
        highest points (rad; the helical 14G: 156.8° and 161.0°)
    settings : dict — window, step, edge band (mm, rad); ``referenced``:
        whether the local fits were of the deviation from the CAD's exact cut
        surface (True) or free quadrics (False); ``window_points``;
        ``cad_basis``: whether eq. 3.12 was fitted in the CAD's series
    notes : list of str
    """

    measured: AngleReport
    cad: AngleReport
    samples: dict[str, dict[str, FloatArray]]
    walls: dict[str, dict[str, Any]]
    heel: tuple[float, float]
    tip_gamma: float
    tip_gamma_inner: float
    settings: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    def region(self, gamma: ArrayLike, *, heel: float | None = None,
               tip: float | None = None) -> BoolArray:
        """(m,) bool: γ (rad) farther than ``heel`` from the heel (γ = 0) and
        ``tip`` from the tips of both edges (rad; defaults
        ``tol.scan_edges.heel_window``, ``tol.scan_edges.tip_window``) —
        where the accuracy is stated, one region for both edges."""
        st = tol.scan_edges
        h = st.heel_window if heel is None else heel
        t = st.tip_window if tip is None else tip
        g: FloatArray = np.mod(np.asarray(gamma, float), 2 * np.pi)
        d_heel = np.minimum(g, 2 * np.pi - g)
        d_tip: FloatArray = np.minimum(*(np.abs(np.angle(np.exp(1j * (g - tg))))
                                         for tg in (self.tip_gamma, self.tip_gamma_inner)))
        return (d_heel > h) & (d_tip > t)

    def differences(self, step_deg: float = 1.0) -> dict[str, AnyArray]:
        """Measured − CAD on γ = 0, step, … < 360° (degrees, µm): columns
        ``gamma_deg``, ``in_region`` and, per wall (``o``, ``i``), ``dz_um``,
        ``dlambda_deg``, ``dtheta_deg``, ``dalpha_deg``."""
        m, c = self.measured.table(step_deg), self.cad.table(step_deg)
        out = {"gamma_deg": m["gamma_deg"],
               "in_region": self.region(np.radians(m["gamma_deg"]))}
        for k, th in (("o", "theta_deg"), ("i", "theta_i_deg")):
            out[f"dz_{k}_um"] = (m[f"z_{k}_mm"] - c[f"z_{k}_mm"]) * 1e3
            out[f"dlambda_{k}_deg"] = m[f"lambda_{k}_deg"] - c[f"lambda_{k}_deg"]
            out[f"dtheta_{k}_deg"] = m[th] - c[th]
            out[f"dalpha_{k}_deg"] = m[f"alpha_{k}_deg"] - c[f"alpha_{k}_deg"]
        return out

    def summary(self) -> dict[str, Any]:
        """JSON-ready: per wall the measured and CAD l_c and angle ranges, and
        the largest |measured − CAD| away from heel and tip."""
        ms, cs = self.measured.summary(), self.cad.summary()
        d = self.differences()
        reg = d["in_region"]
        out: dict[str, Any] = {
            "frame": "CAD analysis frame: gamma from the CAD heel about +z, z from the heel",
            "method": ("cut face fitted locally (deviation from the CAD's exact cut surface) "
                       if self.settings.get("referenced") else
                       "cut face fitted locally (quadric) ")
                      + "in windows along the edge, intersected with the fitted wall; eq. 3.12 "
                      + ("fit in the CAD's series (its w)" if self.settings.get("cad_basis")
                         else "fit with its own w"),
            "settings": {"window_deg": math.degrees(self.settings["window"]),
                         "step_deg": math.degrees(self.settings["step"]),
                         "edge_band_um": self.settings["edge_band"] * 1e3,
                         "n_harmonics": self.measured.n_harmonics,
                         "reference": "cad" if self.settings.get("referenced") else "none",
                         "window_points": self.settings.get("window_points"),
                         "cad_basis": bool(self.settings.get("cad_basis")),
                         "heel_window_deg": math.degrees(tol.scan_edges.heel_window),
                         "tip_window_deg": math.degrees(tol.scan_edges.tip_window)},
            "heel_deg_mm": [math.degrees(self.heel[0]), self.heel[1]],
            "tip_gamma_deg": math.degrees(self.tip_gamma),
            "tip_gamma_inner_deg": math.degrees(self.tip_gamma_inner),
            "notes": list(self.notes)}
        for wall, k in (("outer", "o"), ("inner", "i")):
            th = "theta_deg" if k == "o" else "theta_i_deg"
            keys = (f"lambda_{k}_deg", th, f"alpha_{k}_deg")
            s = self.samples[wall]
            w = {"l_c_mm": {"measured": ms[wall]["l_c_mm"], "cad": cs[wall]["l_c_mm"],
                            "difference_percent": 100 * (ms[wall]["l_c_mm"] / cs[wall]["l_c_mm"]
                                                         - 1)},
                 "z_max_mm": {"measured": ms[wall]["z_max_mm"], "cad": cs[wall]["z_max_mm"]},
                 "wall": {kk: vv for kk, vv in self.walls[wall].items() if kk != "rounding"},
                 "edge_radius_um": (self.walls[wall].get("rounding") or {}).get(
                     "edge_radius_um"),
                 "samples": int(len(s["gamma"])),
                 "fit_rms_um": [f.rmse * 1e3 for f in self.measured.__dict__[wall].fits]}
            for key in keys:
                w[key] = {"measured": ms[wall][key], "cad": cs[wall][key]}
            for name in ("dz", "dlambda", "dtheta", "dalpha"):
                col = d[f"{name}_{k}_{'um' if name == 'dz' else 'deg'}"][reg]
                col = col[np.isfinite(col)]
                unit = "um" if name == "dz" else "deg"
                w[f"max_abs_{name}_{unit}"] = float(np.abs(col).max()) if len(col) else None
            out[wall] = w
        return out


def _robust_sigma(r: FloatArray) -> float:
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


def _fit_wall(rho: FloatArray, g: FloatArray, z: FloatArray, r0: float,
              band: float) -> tuple[FloatArray, dict[str, Any]] | None:
    """Trimmed least squares of ρ = R + a cos γ + b sin γ + z (c cos γ + d sin γ)
    over the points within ``band`` of r0, re-selected around the fit."""
    st = tol.scan_edges
    coef = np.array([r0, 0.0, 0.0, 0.0, 0.0])
    sel_band = band
    n = 0
    for _ in range(st.wall_rounds):
        pred = _wall_radius(coef, g, z)
        s = np.abs(rho - pred) < sel_band
        n = int(s.sum())
        if n < st.min_wall_points:
            return None
        c, sn = np.cos(g[s]), np.sin(g[s])
        A = np.stack([np.ones(n), c, sn, z[s] * c, z[s] * sn], 1)
        coef, *_ = np.linalg.lstsq(A, rho[s], rcond=None)
        res = rho[s] - A @ coef
        sel_band = max(st.trim * _robust_sigma(res), st.wall_band_floor)
    pred = _wall_radius(coef, g, z)
    s = np.abs(rho - pred) < sel_band
    rms = float(np.sqrt(np.mean((rho[s] - pred[s]) ** 2)))
    info = {"radius_mm": float(coef[0]), "offset_mm": [float(coef[1]), float(coef[2])],
            "tilt_rad": [float(coef[3]), float(coef[4])], "points": int(s.sum()),
            "rms_um": rms * 1e3}
    return coef, info


def _retrim(res: FloatArray, keep: BoolArray) -> tuple[BoolArray, bool]:
    """The points within ``tol.scan_edges.trim`` robust σ of a fit (its
    residuals ``res``, σ from the kept ones), and whether that is ``keep``."""
    st = tol.scan_edges
    new = np.abs(res) < st.trim * max(_robust_sigma(res[keep]), st.fit_floor)
    return new, bool(np.array_equal(new, keep))


def _wall_radius(coef: FloatArray, g: FloatArray, z: FloatArray) -> FloatArray:
    """ρ (mm) of the fitted wall cylinder at γ (rad), z (mm)."""
    c, s = np.cos(g), np.sin(g)
    r: FloatArray = coef[0] + coef[1] * c + coef[2] * s + z * (coef[3] * c + coef[4] * s)
    return r


#: A free local fit: centre (3,), frame (3, 3) rows e_u e_v n, coefficients,
#: residual RMS (mm), points kept.
_LocalFit = tuple[FloatArray, FloatArray, FloatArray, float, int]


def _local_surface(X: FloatArray, quadric: bool) -> _LocalFit | None:
    """Height-over-plane fit of a patch: (centre, frame (3, 3) rows e_u e_v n,
    coefficients, residual RMS, points kept), trimmed; None if too few.

    The plane is the patch's best plane; u runs along its longest spread, v
    across. The height is 1, u, v, u², uv: the curvature along the patch's
    long side and the twist (a helical face); the curvature along its short
    side is left out — its sagitta goes with the side's length squared, and
    a v² term's extrapolation to the wall, where the edge is taken, costs
    the most variance (on 40k-point scans of the thesis's helix at 2 µm: θ
    within 0.23° with, 0.47° without this choice; bias ≤ 0.07° noise-free)."""
    st = tol.scan_edges
    keep = np.ones(len(X), bool)
    need = 5 if quadric else 3
    for _ in range(st.fit_rounds):
        if keep.sum() < max(need * st.points_per_coefficient, need + 1):
            return None
        P = X[keep]
        c = P.mean(axis=0)
        _, vec = np.linalg.eigh(np.cov((P - c).T))
        E = vec[:, [2, 1, 0]].T
        Q = (X - c) @ E.T
        A = _design(Q[:, 0], Q[:, 1], quadric)
        coef, *_ = np.linalg.lstsq(A[keep], Q[keep, 2], rcond=None)
        res = Q[:, 2] - A @ coef
        keep, settled = _retrim(res, keep)
        if settled:
            break
    rms = float(np.sqrt(np.mean(res[keep] ** 2)))
    return c, E, coef, rms, int(keep.sum())


def _design(u: FloatArray, v: FloatArray, quadric: bool) -> FloatArray:
    one = np.ones_like(u)
    if quadric:
        return np.stack([one, u, v, u * u, u * v], 1)
    return np.stack([one, u, v], 1)


def _surface_terms(coef: FloatArray, u: float, v: float,
                   quadric: bool) -> tuple[float, float, float]:
    """Height, ∂/∂u, ∂/∂v of the fitted patch."""
    if quadric:
        h = coef[0] + coef[1] * u + coef[2] * v + coef[3] * u * u + coef[4] * u * v
        return h, coef[1] + 2 * coef[3] * u + coef[4] * v, coef[2] + coef[4] * u
    return coef[0] + coef[1] * u + coef[2] * v, coef[1], coef[2]


def _meet_wall(fit: _LocalFit, wall_coef: FloatArray, g0: float,
               quadric: bool) -> tuple[FloatArray, FloatArray] | None:
    """The point where the patch meets the wall's generator at γ₀ and the
    patch's unit normal there (analysis frame); None if it does not."""
    c, E, coef, _, _ = fit
    cg, sg = math.cos(g0), math.sin(g0)
    z = float(c[2])
    for _ in range(tol.scan_edges.newton_steps):
        R = float(_wall_radius(wall_coef, np.array([g0]), np.array([z]))[0])
        X = np.array([R * cg, R * sg, z])
        q = E @ (X - c)
        h, hu, hv = _surface_terms(coef, q[0], q[1], quadric)
        G = q[2] - h
        dG = E[2, 2] - hu * E[0, 2] - hv * E[1, 2]   # ∂G/∂z along the generator
        if abs(dG) < tol.scan_edges.grazing:
            return None                              # the patch runs along the generator
        step = G / dG
        z -= step
        if abs(step) < tol.scan_edges.newton_converge:
            break
    R = float(_wall_radius(wall_coef, np.array([g0]), np.array([z]))[0])
    X = np.array([R * cg, R * sg, z])
    q = E @ (X - c)
    _, hu, hv = _surface_terms(coef, q[0], q[1], quadric)
    n = E[2] - hu * E[0] - hv * E[1]
    return X, n / np.linalg.norm(n)


class _Reference:
    """The CAD's exact cut surface as a height field over the annulus, in the
    analysis frame: z_ref(ρ, γ) (mm) and its outward normals — what the
    CAD-referenced local fits measure the scan's deviation from."""

    def __init__(self, spec: TipSpec, heel: tuple[float, float]):
        self.cutters = tuple(spec.cutters)
        self.cannula = spec.cannula
        self.gh, self.zh = heel

    def z(self, rho: ArrayLike, gamma: ArrayLike) -> FloatArray:
        """z (mm, from the heel) of the lowest cut at radius ρ (mm) and γ (rad)."""
        from ..edges import lowest_cut

        rho = np.broadcast_to(np.asarray(rho, float), np.shape(gamma))
        z: FloatArray = lowest_cut(self.cutters, np.asarray(gamma, float) + self.gh, rho,
                                   self.cannula)[0]
        return z - self.zh

    def normals(self, rho: ArrayLike, gamma: ArrayLike, lo: float,
                hi: float) -> tuple[FloatArray, FloatArray]:
        """z (m,) and unit outward normals (m, 3) of the cut surface at (ρ, γ),
        analysis frame; γ nudged into [lo, hi] (the piece's span) so that at a
        kink the piece's own face answers."""
        from ..edges import lowest_cut

        g = np.clip(np.asarray(gamma, float), lo + tol.angle_nudge, hi - tol.angle_nudge)
        rho = np.broadcast_to(np.asarray(rho, float), g.shape)
        z, _, owner = lowest_cut(self.cutters, g + self.gh, rho, self.cannula)
        pts = np.stack([rho * np.cos(g + self.gh), rho * np.sin(g + self.gh), z], 1)
        n = np.empty_like(pts)
        for k in np.unique(owner):
            s = owner == k
            n[s] = self.cutters[k].normals(pts[s], self.cannula, self.cutters[:k])
        return z - self.zh, rotate_z(n, -self.gh)


def _deviation_fit(ds: FloatArray, dr: FloatArray,
                   e: FloatArray) -> tuple[FloatArray, float, int] | None:
    """Trimmed least squares of the deviation e (mm) from the reference over
    a window: e = c₀ + c₁ Δs + c₂ Δρ + c₃ Δs² + c₄ Δs Δρ (Δs = R Δγ along
    the edge, Δρ from the wall, mm). (coefficients,
    residual RMS, points kept) or None if too few."""
    st = tol.scan_edges
    A = np.stack([np.ones_like(ds), ds, dr, ds * ds, ds * dr], 1)
    keep = np.ones(len(e), bool)
    for _ in range(st.fit_rounds):
        if keep.sum() < max(5 * st.points_per_coefficient, 6):
            return None
        coef, *_ = np.linalg.lstsq(A[keep], e[keep], rcond=None)
        res = e - A @ coef
        keep, settled = _retrim(res, keep)
        if settled:
            break
    rms = float(np.sqrt(np.mean(res[keep] ** 2)))
    return np.asarray(coef, np.float64), rms, int(keep.sum())


def _referenced_edges(ref: _Reference, coefs: FloatArray, g0: FloatArray, R0: FloatArray,
                      wall_coef: FloatArray, lo: float,
                      hi: float) -> tuple[FloatArray, FloatArray]:
    """Edge points and normals of the referenced fits at γ₀ (m,): where the
    reference plus the fitted deviation meets the fitted wall's generator.
    z (m,) mm and unit normals (m, 3), analysis frame."""
    z = ref.z(R0, g0)
    for _ in range(tol.scan_edges.newton_steps):
        R = _wall_radius(wall_coef, g0, z)
        zr = ref.z(R, g0)
        z_new = zr + coefs[:, 0] + coefs[:, 2] * (R - R0)
        done = np.abs(z_new - z).max() < tol.scan_edges.newton_converge
        z = z_new
        if done:
            break
    R = _wall_radius(wall_coef, g0, z)
    _, n = ref.normals(R, g0, lo, hi)
    c, s = np.cos(g0), np.sin(g0)
    n_r = n[:, 0] * c + n[:, 1] * s
    n_g = -n[:, 0] * s + n[:, 1] * c
    # the reference is a graph z = f(ρ, γ): its normal ∝ (−f_ρ, −f_γ/ρ, 1);
    # the deviation's slopes add to f's
    f_r = -n_r / n[:, 2] + coefs[:, 2]
    f_s = -n_g / n[:, 2] + coefs[:, 1] * R0 / R
    m = np.stack([-f_r * c + f_s * s, -f_r * s - f_s * c, np.ones_like(g0)], 1)
    m *= np.sign(n[:, 2])[:, None]
    return z, m / np.linalg.norm(m, axis=1, keepdims=True)


def _smooth_normals(gamma: FloatArray, normal: FloatArray, n_harmonics: int) -> FloatArray:
    """The traced normals of a piece, each cylindrical component (n_r, n_γ,
    n_z) fitted over γ with eq. 3.12 like z(γ), re-normalised: the local fits'
    noise averaged along the edge."""
    from ..fourier import fit_fourier

    c, s = np.cos(gamma), np.sin(gamma)
    comp = (normal[:, 0] * c + normal[:, 1] * s, -normal[:, 0] * s + normal[:, 1] * c,
            normal[:, 2])
    nr, ng, nz = (fit_fourier(gamma, x, n=n_harmonics)(gamma) for x in comp)
    out: FloatArray = np.stack([nr * c - ng * s, nr * s + ng * c, nz], 1)
    unit: FloatArray = out / np.linalg.norm(out, axis=1, keepdims=True)
    return unit


def _dense_edge(wall_angles: WallAngles, radius: float, step: float
                ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The fitted edge on a fine γ grid: apex points (m, 3), face normals
    (m, 3), wall normals (m, 3) and γ (m,) — analysis frame."""
    edge = wall_angles.edge
    gs, ns = [], []
    for p in edge.pieces:
        g = np.arange(p.gamma[0], p.gamma[-1], step)
        nn = np.stack([np.interp(g, p.gamma, p.normal[:, j]) for j in range(3)], 1)
        gs.append(g)
        ns.append(nn / np.linalg.norm(nn, axis=1, keepdims=True))
    g = np.concatenate(gs)
    n = np.concatenate(ns)
    z = wall_angles.at(g)["z"]
    e_r = np.stack([np.cos(g), np.sin(g), np.zeros_like(g)], 1)
    A = radius * e_r
    A[:, 2] = z
    w = e_r if edge.wall == "outer" else -e_r
    return A, n, w, g


def _edge_radius(Q: FloatArray, wall_angles: WallAngles, radius: float, reach: float,
                 noise: float, region: Callable[[FloatArray], BoolArray]) -> dict[str, Any]:
    """Radius of the edge's rounding (mm): the one-parameter fit of a wedge
    rounded by ρ (the two fitted surfaces, their corner replaced by an arc
    tangent to both) to the scan points within ``reach`` of the traced edge,
    in each point's section across the edge; residuals clipped at 3
    ``noise``. Only edge points inside ``region`` (heel and tip windows out)."""
    from scipy.optimize import minimize_scalar
    from scipy.spatial import cKDTree

    st = tol.scan_edges
    A, n, w, g = _dense_edge(wall_angles, radius, st.rounding_step)
    keep = region(g)
    A, n, w = A[keep], n[keep], w[keep]
    rho = np.hypot(Q[:, 0], Q[:, 1])
    near = np.abs(rho - radius) < reach * 2
    P = Q[near]
    if not len(P) or not len(A):
        return {"edge_radius_um": None, "points": 0}
    d, i = cKDTree(A).query(P, distance_upper_bound=reach * 2)
    ok = np.isfinite(d)
    P, i = P[ok], i[ok]
    rel = P - A[i]
    a, b = w[i], n[i]
    t = np.cross(a, b)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    rel -= np.einsum("ij,ij->i", rel, t)[:, None] * t
    da, db = np.einsum("ij,ij->i", rel, a), np.einsum("ij,ij->i", rel, b)
    zone = (np.linalg.norm(rel, axis=1) < reach) & (da > -reach) & (db > -reach)
    rel, a, b, da, db = rel[zone], a[zone], b[zone], da[zone], db[zone]
    if len(rel) < st.min_window_points:
        return {"edge_radius_um": None, "points": int(len(rel))}
    c = np.einsum("ij,ij->i", a, b)
    clip = (3 * noise) ** 2

    def cost(r: float) -> float:
        # the eroded wedge's apex sits at −r/(1 + c)·(a + b); in its normal
        # cone the distance is to that apex, elsewhere to the nearer plane
        qa, qb = da + r, db + r
        al = (qa - c * qb) / (1 - c * c)
        be = (qb - c * qa) / (1 - c * c)
        apex = -(r / (1 + c))[:, None] * (a + b)
        dist = np.where((al >= 0) & (be >= 0), np.linalg.norm(rel - apex, axis=1),
                        np.maximum(qa, qb)) - r
        return float(np.minimum(dist * dist, clip).sum())

    res = minimize_scalar(cost, bounds=(0.0, reach), method="bounded",
                          options={"xatol": st.rounding_xatol})
    return {"edge_radius_um": float(res.x) * 1e3, "points": int(len(rel))}


def _cad_report(cad: Any, n_harmonics: int
                ) -> tuple[AngleReport, float, float, str, TipSpec | None]:
    """(AngleReport, r_o, r_i, name, spec or None) of the CAD: spec →
    ``fourier``, mesh → ``mesh``."""
    from ..angles import analyze
    from ..spec import TipSpec
    from ..tip import Tip
    from .cad import CadModel, load_cad

    spec: TipSpec | None
    tip: Tip | None
    if isinstance(cad, TipSpec):
        spec, tip = cad, None
    elif isinstance(cad, Tip):
        spec, tip = cad.spec, cad
    elif isinstance(cad, CadModel):
        spec, tip = cad.spec, cad.tip
    else:
        model = load_cad(cad)
        spec, tip = model.spec, model.tip
    if spec is not None:
        return (analyze(spec, method="fourier", n_harmonics=n_harmonics),
                spec.cannula.r_o, spec.cannula.r_i, spec.name or "CAD", spec)
    if not isinstance(cad, CadModel) or tip is None:
        raise SpecError("cad: a mesh without a spec needs a CadModel (its fitted radii)")
    return (analyze(tip, method="mesh", n_harmonics=n_harmonics, radii=(cad.r_o, cad.r_i)),
            cad.r_o, cad.r_i, cad.name, None)


#: One traced edge sample: γ₀ (rad), z (mm), unit normal (3,), points in the
#: local fit, its residual RMS (mm), the window's width (rad).
_Row = tuple[float, float, FloatArray, int, float, float]

_SAMPLE_KEYS = ("gamma", "z", "normal", "points", "rms", "window")


@dataclass
class _Face:
    """The cut-face points (analysis frame) sorted by γ and wrapped once each
    way, so that windows about γ = 0 and 2π see both sides: γ (rad), points
    (mm), and with a reference their radii and deviations from it (mm)."""

    g3: FloatArray
    p3: FloatArray
    rho3: FloatArray | None = None
    e3: FloatArray | None = None


@dataclass
class _Tracer:
    """What tracing an edge needs: the fitted walls' coefficients, the cut
    face, the CAD's exact cut surface (None: free local fits), the window
    (rad) and the samples' step (rad)."""

    coefs: dict[str, FloatArray]
    face: _Face
    ref: _Reference | None
    need: int
    window: float
    step: float
    quadric: bool
    n_harmonics: int

    def trace(self, wall: str, cad_edge: Edge
              ) -> tuple[list[EdgePiece], dict[str, FloatArray]]:
        """The pieces of one wall's edge (one per CAD piece) and its samples."""
        acc: dict[str, list[AnyArray]] = {k: [] for k in _SAMPLE_KEYS}
        pieces = []
        p0 = cad_edge.pieces[0]
        full = len(cad_edge.pieces) == 1 and p0.span[1] - p0.span[0] > 2 * np.pi - 2 * self.step
        for cp in cad_edge.pieces:
            rows = self._piece_rows(wall, cad_edge, cp, full)
            gam = np.array([r[0] for r in rows])
            zz = np.array([r[1] for r in rows])
            nn = np.array([r[2] for r in rows])
            pieces.append(EdgePiece(cp.face, gam, zz, None,
                                    _smooth_normals(gam, nn, self.n_harmonics)))
            for key, col in zip(_SAMPLE_KEYS,
                                (gam, zz, nn, *([r[k] for r in rows] for k in (3, 4, 5)))):
                acc[key].append(np.asarray(col))
        return pieces, {k: np.concatenate(v) for k, v in acc.items()}

    def _halves(self, g0s: FloatArray) -> FloatArray:
        """Each window's half width: the narrowest about γ₀ holding
        ``need`` face points, between window and window_max wide."""
        st = tol.scan_edges
        hw = 0.5 * self.window
        g3 = self.face.g3
        widths = np.geomspace(hw, max(hw, 0.5 * st.window_max), st.window_grid)
        cnt = np.array([np.searchsorted(g3, g0s + w_) - np.searchsorted(g3, g0s - w_)
                        for w_ in widths])
        pick = np.argmax(cnt >= self.need, axis=0)
        pick = np.where((cnt >= self.need).any(axis=0), pick, len(widths) - 1)
        return np.asarray(widths[pick], np.float64)

    def _piece_rows(self, wall: str, cad_edge: Edge, cp: EdgePiece, full: bool) -> list[_Row]:
        """The traced samples of one CAD piece (closed at 2π on a full turn)."""
        a, b = cp.span
        if full:
            g0s = np.arange(0.0, 2 * np.pi - 0.5 * self.step, self.step)
        else:   # up to the piece's ends (kinks): windows there see one side
            g0s = np.linspace(a, b, max(int(math.ceil((b - a) / self.step)), 1) + 1)
        rows: list[_Row] = []
        fits: list[tuple[float, float, tuple[FloatArray, float, int], float]] = []
        st = tol.scan_edges
        g3 = self.face.g3
        for g0, half in zip(g0s, self._halves(g0s)):
            lo, hi = np.searchsorted(g3, [g0 - half, g0 + half])
            sel = slice(lo, hi)
            inside = np.ones(hi - lo, bool) if full else (g3[sel] >= a) & (g3[sel] <= b)
            if inside.sum() < st.min_window_points:
                continue
            if self.ref is not None:
                got = self._deviation(wall, cad_edge, float(g0), sel, inside)
                if got is not None:
                    fits.append((float(g0), got[0], got[1], 2 * float(half)))
                continue
            row = self._free_row(wall, cp, float(g0), sel, inside, 2 * float(half))
            if row is not None:
                rows.append(row)
        if fits:
            rows = self._referenced_rows(wall, fits, a, b)
        if full and rows and rows[0][0] == 0.0:
            first = rows[0]
            rows.append((2 * np.pi, *first[1:]))
        if len(rows) < 2 * self.n_harmonics + 2:
            raise ScanError(f"the {wall} edge: only {len(rows)} windows of piece "
                            f"'{cp.face}' hold enough cut-face points; at least "
                            f"{2 * self.n_harmonics + 2} are needed (a denser scan, or a "
                            "wider window_deg)")
        return rows

    def _deviation(self, wall: str, cad_edge: Edge, g0: float, sel: slice, inside: BoolArray
                   ) -> tuple[float, tuple[FloatArray, float, int]] | None:
        """(R₀, deviation fit) of the window about γ₀, referenced."""
        ref, f = self.ref, self.face
        assert ref is not None and f.rho3 is not None and f.e3 is not None  # referenced
        zc = ref.z(cad_edge.radius, np.array([g0]))[0]
        R0 = float(_wall_radius(self.coefs[wall], np.array([g0]), np.array([zc]))[0])
        dg = f.g3[sel][inside] - g0
        fit = _deviation_fit(R0 * dg, f.rho3[sel][inside] - R0, f.e3[sel][inside])
        return None if fit is None else (R0, fit)

    def _free_row(self, wall: str, cp: EdgePiece, g0: float, sel: slice, inside: BoolArray,
                  width: float) -> _Row | None:
        """The sample at γ₀ from a free local fit, its normal outward."""
        fit = _local_surface(self.face.p3[sel][inside], self.quadric)
        if fit is None:
            return None
        hit = _meet_wall(fit, self.coefs[wall], g0, self.quadric)
        if hit is None:
            return None
        Xe, n = hit
        # the CAD piece's normal near γ₀ (a mesh piece has one per segment)
        nref = cp.normal[min(int(np.searchsorted(cp.gamma, g0)), len(cp.normal) - 1)]
        if n @ nref < 0:        # outward, as the CAD's
            n = -n
        return g0, float(Xe[2]), n, fit[4], fit[3], width

    def _referenced_rows(self, wall: str,
                         fits: list[tuple[float, float, tuple[FloatArray, float, int], float]],
                         a: float, b: float) -> list[_Row]:
        """The samples of a piece's referenced fits (γ₀, R₀, fit, width)."""
        assert self.ref is not None  # only referenced fits come here
        g0f = np.array([f[0] for f in fits])
        zf, nf = _referenced_edges(self.ref, np.array([f[2][0] for f in fits]), g0f,
                                   np.array([f[1] for f in fits]), self.coefs[wall], a, b)
        return [(f[0], float(zk), nk, f[2][2], f[2][1], f[3])
                for f, zk, nk in zip(fits, zf, nf)]


def _check_reference(reference: str, spec: TipSpec | None) -> None:
    if reference not in ("auto", "cad", "none"):
        raise SpecError(f"reference = {reference!r} is not valid; expected one of: auto, cad, "
                        "none")
    if reference == "cad" and spec is None:
        raise SpecError("reference = 'cad' needs a CAD with a spec (its exact cut surface); "
                        "this CAD is a bare mesh (use reference='auto' or 'none')")


def _fit_walls(rho: FloatArray, g: FloatArray, z: FloatArray, radii: tuple[float, float],
               notes: list[str]) -> tuple[dict[str, dict[str, Any]], dict[str, FloatArray]]:
    """(wall info, cylinder coefficients) of the outer and inner walls; the
    CAD radius (noted) where a wall has too few points."""
    st = tol.scan_edges
    wall_t = radii[0] - radii[1]
    walls: dict[str, dict[str, Any]] = {}
    coefs: dict[str, FloatArray] = {}
    for wall, r0 in zip(("outer", "inner"), radii):
        res = _fit_wall(rho, g, z, r0, st.wall_search * wall_t)
        if res is None:
            coefs[wall] = np.array([r0, 0.0, 0.0, 0.0, 0.0])
            walls[wall] = {"radius_mm": r0, "fitted": False}
            notes.append(f"too few {wall}-wall points to fit it; the CAD radius "
                         f"{r0:.4f} mm is used")
        else:
            coefs[wall], walls[wall] = res
            walls[wall]["fitted"] = True
    return walls, coefs


def _face_points(q: FloatArray, rho: FloatArray, g: FloatArray, coefs: dict[str, FloatArray],
                 band: float) -> tuple[FloatArray, FloatArray]:
    """The cut-face points (farther than ``band`` from both walls) and their
    γ, sorted by γ."""
    z = q[:, 2]
    ro_pt = _wall_radius(coefs["outer"], g, z)
    ri_pt = _wall_radius(coefs["inner"], g, z)
    face = (rho < ro_pt - band) & (rho > ri_pt + band)
    F, Fg = q[face], g[face]
    st = tol.scan_edges
    if len(F) < st.min_face_points:
        raise ScanError(f"{len(F)} cut-face points (inside the wall, {band * 1e3:g} µm from "
                        f"it); at least {st.min_face_points} are needed to trace the edges")
    order = np.argsort(Fg)
    return F[order], Fg[order]


def _wrapped_face(F: FloatArray, Fg: FloatArray, reference: str, spec: TipSpec | None,
                  heel: tuple[float, float], notes: list[str]
                  ) -> tuple[_Face, _Reference | None]:
    """The wrapped cut face and the CAD's exact cut surface it is measured
    from (None: free local fits)."""
    face = _Face(np.concatenate([Fg - 2 * np.pi, Fg, Fg + 2 * np.pi]),
                 np.concatenate([F, F, F]))
    if reference == "none" or spec is None:
        return face, None
    try:
        ref = _Reference(spec, heel)
        e = F[:, 2] - ref.z(np.hypot(F[:, 0], F[:, 1]), Fg)
    except SpecError:
        if reference == "cad":
            raise
        notes.append("the CAD has no exact cut surface: free local quadrics are fitted")
        return face, None
    face.e3 = np.concatenate([e, e, e])
    face.rho3 = np.tile(np.hypot(F[:, 0], F[:, 1]), 3)
    return face, ref


def _tips(cad_rep: AngleReport) -> tuple[float, float]:
    """γ (rad) of the CAD outer and inner edges' highest points."""
    tips = []
    for wall in ("outer", "inner"):
        dense = cad_rep.dense(wall, 7200)
        tips.append(float(dense["gamma"][int(np.nanargmax(dense["z"]))]))
    return tips[0], tips[1]


def measure_edges(points: ArrayLike, cad: Any, *, window_deg: float | None = None,
                  step_deg: float | None = None, edge_band: float | None = None,
                  n_harmonics: int = 5, quadric: bool = True, reference: str = "auto",
                  cad_basis: bool = True,
                  progress: Callable[[str], object] | None = None) -> MeasuredEdges:
    """Trace the cutting edges of a registered scan and measure λ, θ, α and
    l_c beside the CAD's (method in the module docstring).

    Parameters
    ----------
    points : (n, 3) float — mm, cannula frame (a registered scan, e.g.
        ``Comparison.points``)
    cad : TipSpec, Tip, CadModel, spec path or preset name — the CAD tip
    window_deg : float — width of each local cut-face fit about its γ₀
        (degrees; default ``tol.scan_edges.window``)
    step_deg : float — spacing of the edge samples (degrees; default
        ``tol.scan_edges.step``)
    edge_band : float — cut-face points within this of a wall are left out
        of the local fits (mm; default ``tol.scan_edges.edge_band``; must
        exceed twice the edge rounding radius plus a few σ of noise, and stay
        below a third of the wall)
    n_harmonics : int — harmonics of the eq. 3.12 fit (thesis: 5)
    quadric : bool — free local fits (``reference='none'``): quadrics (True)
        or planes
    reference : ``auto`` | ``cad`` | ``none`` — fit the scan's deviation from
        the CAD's exact cut surface (``cad``; ``auto`` when the CAD has a spec
        with exact cutters) or free quadrics (``none``; ``auto`` for a bare
        mesh)
    cad_basis : bool — fit the traced edge with eq. 3.12 in the CAD's series
        (its w per piece; True) or with a fitted w (False)
    progress : callable(str) — stage messages

    Returns
    -------
    MeasuredEdges

    Raises
    ------
    ScanError
        Too few wall or cut-face points to trace an edge.
    SpecError
        A parameter out of range.
    """
    from ..angles import analyze_edges
    from ..validate import integer, real

    say = progress or (lambda msg: None)
    st = tol.scan_edges
    window = math.radians(real("window_deg", window_deg, lo=0.1, hi=45.0)) \
        if window_deg is not None else st.window
    step = math.radians(real("step_deg", step_deg, lo=0.05, hi=10.0)) \
        if step_deg is not None else st.step
    n_harmonics = integer("n_harmonics", n_harmonics, lo=1, hi=50)
    P = check_points(points, "points").astype(float)
    say("analysing the CAD's edges")
    cad_rep, r_o, r_i, cad_name, spec = _cad_report(cad, n_harmonics)
    wall_t = r_o - r_i
    band = st.edge_band if edge_band is None else real("edge_band", edge_band, lo=0.0,
                                                       lo_open=True)
    if band >= wall_t / 3:
        raise SpecError(f"edge_band = {band * 1e3:g} µm; allowed 0 < value < a third of the "
                        f"wall ({wall_t / 3 * 1e3:.1f} µm)")
    _check_reference(reference, spec)
    gh, zh = cad_rep.outer.edge.heel
    q = rotate_z(P, -gh)
    q[:, 2] -= zh
    rho = np.hypot(q[:, 0], q[:, 1])
    g = np.mod(np.arctan2(q[:, 1], q[:, 0]), 2 * np.pi)
    notes: list[str] = []
    say("fitting the walls")
    walls, coefs = _fit_walls(rho, g, q[:, 2], (r_o, r_i), notes)
    F, Fg = _face_points(q, rho, g, coefs, band)
    face, ref = _wrapped_face(F, Fg, reference, spec, (gh, zh), notes)
    need = st.window_points if ref is None else st.ref_window_points
    tracer = _Tracer(coefs, face, ref, need, window, step, quadric, n_harmonics)
    samples: dict[str, dict[str, FloatArray]] = {}
    edges = []
    for wall in ("outer", "inner"):
        say(f"tracing the {wall} edge")
        cad_edge = getattr(cad_rep, wall).edge
        pieces, samples[wall] = tracer.trace(wall, cad_edge)
        edges.append(Edge(wall, float(coefs[wall][0]), pieces, [], list(cad_edge.jumps),
                          "scan", (gh, zh)))
    if any(e.jumps for e in edges):
        notes.append("vertical stretches (jumps) of the edge are taken from the CAD")
    say("fitting eq. 3.12")
    meas = analyze_edges(edges[0], edges[1], n_harmonics=n_harmonics,
                         name=f"scan of {cad_name}", basis=cad_rep if cad_basis else None)
    tip_o, tip_i = _tips(cad_rep)
    out = MeasuredEdges(meas, cad_rep, samples, walls, (gh, zh), tip_o, tip_i,
                        {"window": window, "step": step, "edge_band": band,
                         "referenced": ref is not None, "window_points": need,
                         "cad_basis": cad_basis}, notes)
    say("fitting the edge rounding")
    noise = max(min(w.get("rms_um", np.inf) for w in walls.values()) * 1e-3, st.fit_floor)
    for wall in ("outer", "inner"):
        walls[wall]["rounding"] = _edge_radius(q, getattr(meas, wall),
                                               float(coefs[wall][0]), band, noise, out.region)
    return out


def _shade_windows(ax: Any, res: MeasuredEdges) -> None:
    """Grey the γ (degrees) outside the stated region on a plot's axis."""
    g = np.linspace(0.0, 360.0, 3601)
    ax.fill_between(g, 0, 1, where=~res.region(np.radians(g)), color="0.9", zorder=0,
                    transform=ax.get_xaxis_transform(), lw=0)


@styled
def plot_measured_edges(res: MeasuredEdges, path: str | os.PathLike[str], *,
                        truth: AngleReport | None = None) -> Path:
    """A PNG: per wall the edge height z(γ) and λ, θ, α (degrees) of the scan
    beside the CAD's, over γ from the heel (degrees); the traced edge samples
    as dots; the heel and tip windows shaded. ``truth`` (an AngleReport, e.g.
    of the as-made part of a synthetic scan) is drawn dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..plot import check_picture_path, save_figure

    path = check_picture_path(path)
    fig, axes = plt.subplots(5, 2, figsize=(11, 13), sharex=True)
    rows = (("z", "z (mm)"), ("lambda", "λ (°)"), ("theta", "θ (°)"), ("alpha", "α (°)"))
    for col, wall in enumerate(("outer", "inner")):
        m, c = res.measured.dense(wall, 1441), res.cad.dense(wall, 1441)
        t = truth.dense(wall, 1441) if truth is not None else None
        gd = np.degrees(m["gamma"])
        for row, (key, label) in enumerate(rows):
            ax = axes[row, col]
            scale = (lambda x: x) if key == "z" else np.degrees
            ax.plot(gd, scale(c[key]), color="0.2", lw=1.2, label="CAD")
            if t is not None:
                ax.plot(gd, scale(t[key]), color="tab:green", lw=1.0, ls="--", label="truth")
            ax.plot(gd, scale(m[key]), color="tab:red", lw=1.0, label="scan (eq. 3.12 fit)")
            if key == "z":
                s = res.samples[wall]
                ax.plot(np.degrees(s["gamma"]), s["z"], ".", ms=2, color="tab:blue",
                        label="traced edge")
            _shade_windows(ax, res)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            if row == 0:
                w = res.summary()[wall]["l_c_mm"]
                ax.set_title(f"{wall} edge: l_c scan {w['measured']:.4f} mm, CAD "
                             f"{w['cad']:.4f} mm ({w['difference_percent']:+.3f} %)",
                             fontsize=10)
                ax.legend(fontsize=8, loc="upper left")
        ax = axes[4, col]
        ref = t if t is not None else c
        for key, colr, name in (("lambda", "tab:blue", "Δλ"), ("theta", "tab:orange", "Δθ"),
                                ("alpha", "tab:purple", "Δα")):
            ax.plot(gd, np.degrees(m[key] - ref[key]), color=colr, lw=0.9, label=name)
        ax.axhline(0, color="0.3", lw=0.6)
        ax.set_ylim(-1.0, 1.0)
        ax.set_ylabel(f"scan − {'truth' if t is not None else 'CAD'} (°)")
        az = ax.twinx()
        az.plot(gd, (m["z"] - ref["z"]) * 1e3, color="tab:red", lw=0.8, ls=":", label="Δz")
        az.set_ylim(-10, 10)
        az.set_ylabel("Δz (µm)", color="tab:red")
        _shade_windows(ax, res)
        ax.grid(alpha=0.3)
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = az.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper right", ncol=4)
        axes[-1, col].set_xlabel("γ from the heel (°)")
        axes[-1, col].set_xlim(0, 360)
    fig.suptitle(f"{res.measured.name}: measured cutting edges and angles (grey: heel and "
                 "tip windows)", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


def edges_markdown(res: MeasuredEdges) -> list[str]:
    """Markdown lines for a report: the measured edges beside the CAD's."""
    s = res.summary()
    st = s["settings"]
    L = ["", "## Cutting edges measured on the scan", "",
         f"Edges traced on the scan ({s['method']}; windows ≥ {st['window_deg']:g}° holding "
         f"{st['window_points']} cut-face points, edge band {st['edge_band_um']:g} µm, "
         f"{st['n_harmonics']} harmonics), in the CAD's analysis frame. Differences are the "
         f"largest |scan − CAD| farther than {st['heel_window_deg']:g}° from the heel and "
         f"{st['tip_window_deg']:g}° from the tips (γ = {s['tip_gamma_deg']:.2f}° outer, "
         f"{s['tip_gamma_inner_deg']:.2f}° inner).", "",
         "| edge | quantity | scan | CAD | max abs difference |", "|---|---|---|---|---|"]

    def rng(x: Sequence[float]) -> str:
        return f"{x[0]:.3f} … {x[1]:.3f}"

    for wall, k in (("outer", "o"), ("inner", "i")):
        w = s[wall]
        L.append(f"| {wall} | l_c (mm) | {w['l_c_mm']['measured']:.4f} | "
                 f"{w['l_c_mm']['cad']:.4f} | {w['l_c_mm']['difference_percent']:+.3f} % |")
        L.append(f"| {wall} | z_max (mm) | {w['z_max_mm']['measured']:.4f} | "
                 f"{w['z_max_mm']['cad']:.4f} | {w['max_abs_dz_um']:.2f} µm (z) |")
        th = "theta_deg" if k == "o" else "theta_i_deg"
        for key, name, dk in ((f"lambda_{k}_deg", "λ (°)", "max_abs_dlambda_deg"),
                              (th, "θ (°)", "max_abs_dtheta_deg"),
                              (f"alpha_{k}_deg", "α (°)", "max_abs_dalpha_deg")):
            L.append(f"| {wall} | {name} | {rng(w[key]['measured'])} | {rng(w[key]['cad'])} | "
                     f"{w[dk]:.3f}° |")
        wl = w["wall"]
        L.append(f"| {wall} | wall radius (mm) | {wl['radius_mm']:.5f} | "
                 f"{res.cad.radii[0 if k == 'o' else 1]:.5f} | |")
        er = w["edge_radius_um"]
        L.append(f"| {wall} | edge rounding radius (µm) | "
                 f"{'n/a' if er is None else f'{er:.1f}'} | 0 (sharp) | |")
    for n in s["notes"]:
        L.append(f"- note: {n}")
    return L


def edges_text(res: MeasuredEdges) -> str:
    """Plain-text lines for the CLI: l_c and angle ranges, scan beside CAD."""
    s = res.summary()
    out = [f"  cutting edges measured on the scan (analysis frame of the CAD; differences "
           f"farther than {s['settings']['heel_window_deg']:g}° from heel and "
           f"{s['settings']['tip_window_deg']:g}° from the tips):"]
    for wall, k in (("outer", "o"), ("inner", "i")):
        w = s[wall]
        th = "theta_deg" if k == "o" else "theta_i_deg"
        er = w["edge_radius_um"]
        out.append(f"    {wall}: l_c {w['l_c_mm']['measured']:.4f} mm (CAD "
                   f"{w['l_c_mm']['cad']:.4f}, {w['l_c_mm']['difference_percent']:+.3f} %), "
                   f"wall radius {w['wall']['radius_mm']:.5f} mm, edge rounding radius "
                   + ("n/a" if er is None else f"{er:.1f} µm"))
        for key, name, dk in ((f"lambda_{k}_deg", "λ", "max_abs_dlambda_deg"),
                              (th, "θ", "max_abs_dtheta_deg"),
                              (f"alpha_{k}_deg", "α", "max_abs_dalpha_deg")):
            m, c = w[key]["measured"], w[key]["cad"]
            out.append(f"      {name} {m[0]:8.3f} … {m[1]:8.3f}°  (CAD {c[0]:8.3f} … "
                       f"{c[1]:8.3f}°)  max |Δ| {w[dk]:.3f}°")
    out += [f"    note: {n}" for n in s["notes"]]
    return "\n".join(out)
