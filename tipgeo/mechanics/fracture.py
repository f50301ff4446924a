"""Fracture (rupture) forces of a cannula from the slice/push ratio, friction
and the included angle (thesis §2.2.1, eq. 2.7–2.17; §3.1.5, eq. 3.19–3.20).

Units: R (strain energy release rate) in N/mm (1 J/m² = 1e-3 N/mm), lengths
in mm, forces in N, angles in rad. Frame: the analysis frame of
:mod:`tipgeo.angles` (+z along the axis towards the tip, γ from the heel).

Work balance (Atkins): with w = π d_i = 2π r_i the contact length and the
tangential force F_H = k F_V,

    F_V = R w / D,   F_H = k R w / D,
    D = 1 + k² − μ_d √((k cos θ)² + 1) / (cos θ (μ_d cos ε cos θ + sin θ)),
    ε = arctan(k cos θ)                                   (eq. 2.14, 2.16, 2.17)

Along an edge (eq. 3.19, and eq. 3.20 as corrected in the errata, = 3.19 × k)
the local k(γ) replaces k and a geometric factor G (0.3–0.4, thesis §3.1.5)
scales the contact length: F_⊥ = G R w / D, F_∥ = k F_⊥.

Derived facts used by the code and tested:

* D > 0 for every k ≥ 0 exactly when 0 < θ < arctan(1/μ_d): with
  A = cos θ (μ_d cos θ + sin θ) and √(1 + k² cos²θ) ≥ 1,
  D ≥ (1 − μ_d / A) + k² (1 − μ_d cos²θ / A); the first bracket is > 0
  ⟺ cot θ > μ_d (and is D itself at k = 0), the second is ≥ 0 for any
  acute θ. Outside that range the model has no finite positive force, and
  the functions here raise :class:`SpecError`.
* The code evaluates D·v_⊥² in terms of v_∥ and v_⊥, so k = ∞ (the edge
  moving along itself) gives F_⊥ = F_∥ = 0, the limit of eq. 3.19–3.20.
* Since F_H = k F_V, F_Vrup = F_Hrup at k = 1 whatever R, μ_d and θ: the
  "optimal slice/push ratio" of §2.2.1 from the fracture forces alone is 1.
  The thesis's remark that tougher or higher-friction tissue moves it up
  needs the cutting (friction) forces too — see
  :func:`tipgeo.mechanics.cutting.optimal_slice_push_ratio`.

Which θ along an edge: eq. 3.19 needs the wedge the tissue is split by. The
included angle of the outer edge (eq. 3.14) is obtuse near a bevel's heel,
where the inner edge does the cutting, and passes through 90° on the flanks,
where D → −∞ (the rake-face slip dv / cos θ of eq. 2.11 diverges): with
θ(γ) the edge means have poles and do not converge as the grid is refined.
The along-edge model therefore uses one θ per tip, by default the acute
included angle at the tip (the edge's highest point, which meets the tissue
first) — ξ for a bevel, the cone angle for a conical tip — or the value
given; the geometry enters through k(γ) and G.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ..tolerances import tol
from ._common import J_PER_M2, finite_array
from .slicepush import EdgeGeometry, slice_push

__all__ = ["rupture_forces", "fracture_denominator", "max_included_angle", "edge_forces",
           "EdgeForces", "mean_forces_vs_speed_ratio", "DEFAULT_G"]

#: Geometric factor G of eq. 3.19–3.20: the thesis gives 0.3–0.4 (§3.1.5);
#: the middle of that range.
DEFAULT_G = 0.35

MuD = float | Callable[[FloatArray], FloatArray]


def max_included_angle(mu_d: float) -> float:
    """The largest θ (rad, exclusive) for which the fracture model has a
    positive force at every k: arctan(1/μ_d) (π/2 for μ_d = 0)."""
    mu_d = v.real("mu_d", mu_d, lo=0.0)
    return 0.5 * math.pi if mu_d == 0 else math.atan(1.0 / mu_d)


def _theta(theta: float, mu_max: float) -> float:
    th = v.angle("theta", theta, lo=0.0, hi=0.5 * math.pi, lo_open=True, hi_open=True)
    lim = max_included_angle(mu_max)
    if th >= lim:
        raise SpecError(f"theta = {th:.6g} rad ({math.degrees(th):.6g}°) is out of range for "
                        f"mu_d = {mu_max:.6g}: the fracture model (eq. 2.16) needs "
                        f"0 < θ < arctan(1/μ_d) = {math.degrees(lim):.6g}°")
    return th


def _mu_values(mu_d: MuD, k: FloatArray) -> FloatArray:
    """μ_d at each k (constant, or a callable of k evaluated where k is finite)."""
    if callable(mu_d):
        mu = np.zeros_like(k)
        fin = np.isfinite(k)
        mu[fin] = np.asarray(mu_d(k[fin]), float)
        return finite_array("mu_d(k)", mu, lo=0.0)
    return np.full_like(k, v.real("mu_d", mu_d, lo=0.0))


def fracture_denominator(v_par: ArrayLike, v_perp: ArrayLike, theta: float,
                         mu: float | FloatArray) -> FloatArray:
    """D · v_⊥² of eq. 2.16 written with the velocity components
    (|v_∥|, v_⊥ in any common unit; θ rad; μ_d scalar or per point)."""
    a = np.abs(np.asarray(v_par, float))
    b = np.asarray(v_perp, float)
    c, s = math.cos(theta), math.sin(theta)
    a2 = b * b + (a * c) ** 2
    out: FloatArray = b * b + a * a - mu * b * a2 / (c * (mu * c * b + s * np.sqrt(a2)))
    return out


def _unit_forces(v_par: ArrayLike, v_perp: ArrayLike, theta: float, mu: float | FloatArray
                 ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(F_⊥, F_∥, F_⊥ / v_⊥) per unit R·w·G; the last is the size of the
    resultant per unit |v| along v (finite where v_⊥ = 0)."""
    a = np.abs(np.asarray(v_par, float))
    b = np.asarray(v_perp, float)
    den = fracture_denominator(a, b, theta, mu)
    return b * b / den, a * b / den, b / den


def rupture_forces(k: ArrayLike, *, R: float, d_i: float, theta: float,
                   mu_d: MuD) -> tuple[FloatArray, FloatArray]:
    """Fracture forces F_Vrup and F_Hrup of a cannula (eq. 2.14, 2.16, 2.17).

    Parameters
    ----------
    k : float or (m,) — slice/push ratio(s), k ≥ 0 (inf allowed: forces 0)
    R : float — strain energy release rate, N/mm (45 J/m² = 0.045 N/mm)
    d_i : float — inner diameter, mm (contact length w = π d_i)
    theta : float — included angle, rad, 0 < θ < arctan(1/μ_d)
    mu_d : float or callable — dynamic friction coefficient (≥ 0), or
        μ_d(k) (e.g. :meth:`FrictionRegression.mu_d`, eq. 2.25)

    Returns
    -------
    (F_V, F_H) : arrays (N), axial and tangential, same shape as ``k``
    """
    kk = np.asarray(k, float)
    if np.any(np.isnan(kk)) or np.any(kk < 0):
        bad = kk[np.isnan(kk) | (kk < 0)].reshape(-1)[0]
        raise SpecError(f"k = {bad} is out of range; allowed k ≥ 0 (inf allowed)")
    R = v.real("R", R, lo=0.0, lo_open=True, unit="N/mm")
    d_i = v.length("d_i", d_i)
    flat = kk.reshape(-1)
    mu = _mu_values(mu_d, flat)
    th = _theta(theta, float(mu.max()) if mu.size else 0.0)
    fin = np.isfinite(flat)
    fv, fh = np.zeros_like(flat), np.zeros_like(flat)
    f1, f2, _ = _unit_forces(flat[fin], np.ones(int(fin.sum())), th, mu[fin])
    w = math.pi * d_i
    fv[fin], fh[fin] = R * w * f1, R * w * f2
    return fv.reshape(kk.shape), fh.reshape(kk.shape)


@dataclass
class EdgeForces:
    """Fracture forces along one edge at one rotation/translation ratio S.

    Arrays on the edge's uniform γ grid (rad, analysis frame); forces in N.
    ``F_axial`` and ``F_tangential`` project F_⊥ u_⊥ + F_∥ u_∥ (u_⊥, u_∥ the
    directions of v_⊥ and v_∥) on +z and on e_γ = (−sin γ, cos γ, 0): for a
    conical tip they are eq. 2.16 and 2.17 times G at k = S. Since
    F_∥ = k F_⊥ the resultant is (F_⊥ / v_⊥) v — along the velocity — so the
    tangential part is always S times the axial part. Means are over γ
    (thesis §3.1.5: "the average value of the forces as a function of the
    angle").
    """

    name: str
    S: float
    R: float
    mu_d: str
    G: float
    theta: float
    wall: str
    gamma: FloatArray
    k: FloatArray
    F_perp: FloatArray
    F_par: FloatArray
    F_axial: FloatArray
    F_tangential: FloatArray
    means: dict[str, float] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """Inputs and results in report units (deg, J/m², N)."""
        i = int(np.argmax(self.F_perp))
        return {"name": self.name, "S": self.S, "wall": self.wall,
                "R_J_m2": self.R / J_PER_M2, "mu_d": self.mu_d, "G": self.G,
                "theta_deg": math.degrees(self.theta),
                "mean_F_perp_N": self.means["perp"], "mean_F_par_N": self.means["par"],
                "mean_F_axial_N": self.means["axial"],
                "mean_F_tangential_N": self.means["tangential"],
                "max_F_perp_N": float(self.F_perp[i]),
                "gamma_of_max_F_perp_deg": math.degrees(float(self.gamma[i])),
                "k_min": float(np.min(self.k)), "k_max": float(np.max(self.k))}

    def table(self, step_deg: float = 1.0) -> dict[str, list[float]]:
        """Values every ``step_deg`` degrees (nearest grid points)."""
        step = v.real("step_deg", step_deg, lo=1e-3, hi=90.0)
        gd = np.degrees(self.gamma)
        want = np.arange(0.0, 360.0 - tol.grid_end_deg, step)
        idx = np.unique(np.clip(np.searchsorted(gd, want), 0, len(gd) - 1))
        return {"gamma_deg": gd[idx].tolist(),
                "k": [float(x) if np.isfinite(x) else None for x in self.k[idx]],
                "F_perp_N": self.F_perp[idx].tolist(), "F_par_N": self.F_par[idx].tolist(),
                "F_axial_N": self.F_axial[idx].tolist(),
                "F_tangential_N": self.F_tangential[idx].tolist()}


def _forces_at(geom: EdgeGeometry, S: float, R: float, mu_d: MuD, G: float,
               theta: float | None
               ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, float]:
    sp = slice_push(geom.gamma, geom.tangent, S)
    mu = _mu_values(mu_d, sp.k)
    th = _theta(geom.theta_tip if theta is None else theta, float(mu.max()))
    fperp, fpar, along_v = _unit_forces(sp.v_parallel, sp.v_perpendicular, th, mu)
    scale = R * 2.0 * math.pi * geom.r_i * G
    # F_⊥ u_⊥ + F_∥ u_∥ = (F_⊥ / v_⊥)(v_⊥ u_⊥ + v_∥ t) = (F_⊥ / v_⊥) v, and
    # v / v_a = (−S sin γ, S cos γ, 1): axial part F_⊥/v_⊥, tangential S times it.
    f_axial = scale * along_v
    return sp.k, scale * fperp, scale * fpar, f_axial, S * f_axial, th


def _geom(geom: object) -> None:
    if not isinstance(geom, EdgeGeometry):
        raise SpecError(f"geom = {type(geom).__name__} is not an EdgeGeometry; make one with "
                        "tipgeo.mechanics.edge_geometry(spec)")


def _inputs(R: float, G: float, S: float) -> tuple[float, float, float]:
    return (v.real("R", R, lo=0.0, lo_open=True, unit="N/mm"),
            v.real("G", G, lo=0.0, lo_open=True),
            v.real("S", S))


def edge_forces(geom: EdgeGeometry, S: float, *, R: float, mu_d: MuD, G: float = DEFAULT_G,
                theta: float | None = None) -> EdgeForces:
    """Fracture forces F_⊥(γ), F_∥(γ) along an edge (eq. 3.19–3.23).

    Parameters
    ----------
    geom : EdgeGeometry — from :func:`tipgeo.mechanics.edge_geometry`
    S : float — rotation/translation ratio v_r / v_a
    R : float — strain energy release rate, N/mm
    mu_d : float or callable — dynamic friction coefficient, or μ_d(k)
        evaluated at the local k(γ)
    G : float — geometric factor (thesis: 0.3–0.4; 10 % less for its
        helical needle)
    theta : float, optional — included angle, rad (default: the acute
        included angle at the tip, ``geom.theta_tip``)

    Returns
    -------
    EdgeForces (N; γ in rad)
    """
    _geom(geom)
    R, G, S = _inputs(R, G, S)
    k, fperp, fpar, fax, ftan, th = _forces_at(geom, S, R, mu_d, G, theta)
    means = {"perp": float(fperp.mean()), "par": float(fpar.mean()),
             "axial": float(fax.mean()), "tangential": float(ftan.mean())}
    desc = getattr(mu_d, "__qualname__", None) if callable(mu_d) else None
    return EdgeForces(name=geom.name, S=S, R=R,
                      mu_d=f"{mu_d:g}" if not callable(mu_d) else (desc or "μ_d(k)"), G=G,
                      theta=th, wall=geom.wall, gamma=geom.gamma, k=k, F_perp=fperp,
                      F_par=fpar, F_axial=fax, F_tangential=ftan, means=means)


def mean_forces_vs_speed_ratio(geom: EdgeGeometry, S_values: ArrayLike, *, R: float,
                               mu_d: MuD, G: float = DEFAULT_G,
                               theta: float | None = None) -> dict[str, FloatArray]:
    """Means over γ of F_⊥, F_∥ and their axial/tangential projections for
    each S (like thesis Fig. 3.12b).

    Returns
    -------
    dict with ``S`` and ``perp``, ``par``, ``axial``, ``tangential`` (N)
    """
    _geom(geom)
    S_arr = finite_array("S_values", S_values).reshape(-1)
    R, G, _ = _inputs(R, G, 0.0)
    out = {key: np.empty(len(S_arr)) for key in ("perp", "par", "axial", "tangential")}
    for j, S in enumerate(S_arr):
        _, fperp, fpar, fax, ftan, _ = _forces_at(geom, float(S), R, mu_d, G, theta)
        out["perp"][j], out["par"][j] = fperp.mean(), fpar.mean()
        out["axial"][j], out["tangential"][j] = fax.mean(), ftan.mean()
    out["S"] = S_arr
    return out
