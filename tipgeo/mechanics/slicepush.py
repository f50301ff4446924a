"""Slice/push ratio along any cutting edge (thesis §3.1.5, eq. 3.21–3.23).

Frame and units: the analysis frame of :mod:`tipgeo.angles` — +z along the
needle axis towards the tip, γ about +z from the heel (the lowest point of the
outer edge), z from the heel; mm, s, radians.

A point of the edge at γ (radius r) moves with the needle's velocity

    v = [−v_r sin γ, v_r cos γ, v_a]

(v_r the rotational speed at the edge, v_a the axial speed, both mm/s); the
rotation/translation ratio is S = v_r / v_a. With t the unit edge tangent,
v_∥ = v · t and v_⊥ = |v × t| (the rest of v), and the slice/push ratio is
k = v_∥ / v_⊥ (eq. 3.22–3.23). Writing the edge as z(γ) on its cylinder,
t = (−r sin γ, r cos γ, z′) / √(r² + z′²), which gives for any edge

    k = |S + z′/r| / |1 − S z′/r|,

and for a one-plane bevel (z′ = r sin γ cot ξ) eq. 3.23,
k = |S + cot ξ sin γ| / |1 − S cot ξ sin γ|. Where 1 = S z′/r the edge moves
along itself (v_⊥ = 0, k = ∞: pure slicing).

The tangent used is the exact one of :func:`tipgeo.angles.analyze` (or the
Fourier or mesh fit, as the report was made) — any tip, not only bevels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError

if TYPE_CHECKING:
    from ..angles import AngleReport
    from ..spec import TipSpec
    from ..tip import Tip

__all__ = ["EdgeGeometry", "SlicePush", "edge_geometry", "velocity", "slice_push",
           "bevel_slice_push_ratio", "bevel_tangent", "WALLS"]

WALLS = ("outer", "inner")


class SlicePush(NamedTuple):
    """Velocity components relative to the edge, per unit axial speed v_a.

    Attributes
    ----------
    v_parallel : (m,) float — v · t / v_a (signed: + towards increasing γ)
    v_perpendicular : (m,) float — |v × t| / v_a ≥ 0
    k : (m,) float — slice/push ratio |v_∥| / v_⊥ (inf where v_⊥ = 0)
    """

    v_parallel: FloatArray
    v_perpendicular: FloatArray
    k: FloatArray


@dataclass(frozen=True)
class EdgeGeometry:
    """One cutting edge sampled on a uniform γ grid, ready for force models.

    Attributes
    ----------
    name : str — the tip's name
    wall : str — ``outer`` or ``inner``: the edge used for tangents and θ
    radius : float — mm, the radius of that edge's wall
    r_o, r_i : float — mm, outer and inner radii of the cannula (the fracture
        models use the contact length w = 2π r_i, eq. 2.9)
    gamma : (m,) float — rad, uniform over [0, 2π), analysis frame
    z : (m,) float — mm from the heel
    dz : (m,) float — z′(γ), mm/rad
    tangent : (m, 3) float — unit tangents (−r sin γ, r cos γ, z′)/norm,
        analysis frame, oriented towards increasing γ
    theta : (m,) float — rad, included angle of this edge (eq. 3.14; the
        inner edge's wedge against the bore for ``inner``)
    theta_tip : float — rad, the acute included angle min(θ, π − θ) at the
        edge's highest point (the tip, which meets the tissue first)
    gamma_tip : float — rad, γ of that point
    method : str — how the angles were computed (``exact``, ``fourier``, ``mesh``)
    """

    name: str
    wall: str
    radius: float
    r_o: float
    r_i: float
    gamma: FloatArray
    z: FloatArray
    dz: FloatArray
    tangent: FloatArray
    theta: FloatArray
    theta_tip: float
    gamma_tip: float
    method: str


def edge_geometry(source: TipSpec | Tip | AngleReport, *, wall: str = "outer", samples: int = 3600,
                  method: str = "exact") -> EdgeGeometry:
    """Sample one cutting edge of a tip for the force models.

    Parameters
    ----------
    source : TipSpec, Tip or AngleReport
        A report is used as it is; a spec or tip is analysed with
        :func:`tipgeo.angles.analyze` (``method``).
    wall : ``outer`` (default, as thesis §3.1.5) or ``inner``
    samples : int — points of the uniform γ grid over [0, 2π)
    method : ``exact`` | ``fourier`` | ``mesh`` — for a spec or tip

    Returns
    -------
    EdgeGeometry (analysis frame, mm, rad)
    """
    from ..angles import AngleReport, analyze

    if wall not in WALLS:
        raise SpecError(f"wall = {wall!r} is not valid; expected one of: " + ", ".join(WALLS))
    samples = v.integer("samples", samples, lo=36, hi=10**6)
    rep = source if isinstance(source, AngleReport) else analyze(source, method=method)
    w = rep.outer if wall == "outer" else rep.inner
    r = float(w.edge.radius)
    g = np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False)
    vals = w.at(g)
    z = np.asarray(vals["z"], float)
    dz = np.asarray(vals["dz"], float)
    theta = np.asarray(vals["theta"], float)
    bad = ~(np.isfinite(z) & np.isfinite(dz) & np.isfinite(theta))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise SpecError(f"source: the {wall} edge of '{rep.name}' has no value at "
                        f"γ = {math.degrees(g[i]):.3f}° (method {rep.method}); "
                        f"{int(bad.sum())} of {samples} samples are missing")
    t = np.stack([-r * np.sin(g), r * np.cos(g), dz], 1)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    top = int(np.argmax(z))
    th_top = float(theta[top])
    r_o, r_i = (float(x) for x in rep.radii)
    return EdgeGeometry(name=rep.name, wall=wall, radius=r, r_o=r_o, r_i=r_i, gamma=g, z=z,
                        dz=dz, tangent=t, theta=theta,
                        theta_tip=min(th_top, math.pi - th_top), gamma_tip=float(g[top]),
                        method=rep.method)


def velocity(gamma: ArrayLike, S: float) -> FloatArray:
    """The velocity of edge points per unit axial speed, v / v_a =
    [−S sin γ, S cos γ, 1] (analysis frame; S = v_r / v_a).

    Parameters
    ----------
    gamma : (m,) float — rad
    S : float — rotation/translation ratio (dimensionless; negative turns
        the needle clockwise seen from the tip)
    """
    S = v.real("S", S)
    g = np.atleast_1d(np.asarray(gamma, float))
    return np.stack([-S * np.sin(g), S * np.cos(g), np.ones_like(g)], 1)


def slice_push(gamma: ArrayLike, tangent: ArrayLike, S: float) -> SlicePush:
    """Velocity components along and across the edge and k = v_∥ / v_⊥.

    Parameters
    ----------
    gamma : (m,) float — rad, analysis frame
    tangent : (m, 3) float — unit edge tangents (analysis frame)
    S : float — rotation/translation ratio v_r / v_a

    Returns
    -------
    SlicePush — per unit axial speed; v_⊥ from |v × t| (not the difference
    of squares, which loses digits where the edge nearly follows v)
    """
    vel = velocity(gamma, S)
    t = np.asarray(tangent, float).reshape(-1, 3)
    if len(t) != len(vel):
        raise SpecError(f"tangent has {len(t)} rows; expected one per γ ({len(vel)})")
    vpar = np.einsum("ij,ij->i", vel, t)
    vperp = np.linalg.norm(np.cross(vel, t), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(vperp > 0, np.abs(vpar) / np.where(vperp > 0, vperp, 1.0), np.inf)
    return SlicePush(vpar, vperp, k)


def bevel_tangent(gamma: ArrayLike, xi: float) -> FloatArray:
    """Unit edge tangent of a one-plane bevel (eq. 3.21 as corrected in the
    errata): t_u = [−sin γ, cos γ, sin γ cot ξ] / √(1 + cot²ξ sin²γ)."""
    xi = v.angle("xi", xi, lo=0.0, hi=0.5 * math.pi, lo_open=True)
    g = np.atleast_1d(np.asarray(gamma, float))
    c = math.cos(xi) / math.sin(xi)
    t = np.stack([-np.sin(g), np.cos(g), np.sin(g) * c], 1)
    out: FloatArray = t / np.sqrt(1.0 + (c * np.sin(g)) ** 2)[:, None]
    return out


def bevel_slice_push_ratio(gamma: ArrayLike, S: float, xi: float) -> FloatArray:
    """Eq. 3.23: k = |S + cot ξ sin γ| / |1 − S cot ξ sin γ| for a one-plane
    bevel of bevel angle ξ (rad); inf where the denominator vanishes."""
    S = v.real("S", S)
    xi = v.angle("xi", xi, lo=0.0, hi=0.5 * math.pi, lo_open=True)
    q = math.cos(xi) / math.sin(xi) * np.sin(np.asarray(gamma, float))
    num, den = np.abs(S + q), np.abs(1.0 - S * q)
    with np.errstate(divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.inf)
