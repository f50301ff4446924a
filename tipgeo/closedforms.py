"""Closed-form cutting geometry of simple tips, with their sources.

Frame and units: cannula frame (+z along the axis towards the tip), γ about
+z measured from the heel (γ = 0 where the outer edge is lowest, γ = π at the
tip of a bevel), z measured from the outer heel; mm and radians.

Angles (thesis §2.1, §3.1.2–3.1.4):

- λ, the inclination angle: between the edge tangent t and the xy-plane;
- θ, the included angle: θ = π − arccos(n_r · n_c) (eq. 3.14) with the
  rake-face normal n_r (outward from the material) and the cylinder normal
  n_c = [cos γ, sin γ, 0] — the material wedge at the *outer* edge. At the
  inner edge the wedge is measured against the bore's outward normal −n_c:
  θ_i = arccos(n_r · n_c);
- α, the rake angle: α = arccos(a·b / |a||b|), a = t × n_r, b = t × [0, 0, 1]
  (eq. 3.15–3.17).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from scipy.special import ellipe

from .arrays import FloatArray

__all__ = ["bevel_theta", "bevel_theta_inner", "bevel_lambda", "bevel_alpha", "bevel_z",
           "bevel_dz", "bevel_edge_length", "multiplane_theta", "multiplane_lambda",
           "multiplane_local_gamma", "conical_theta", "conical_theta_outer", "conical_lambda",
           "conical_alpha", "Angles"]

#: γ (rad) or any other argument the result follows: a float gives a float,
#: an array (float64, any shape) an array of the same shape.
Angles = TypeVar("Angles", float, FloatArray)


def _like(arg: Angles, value: FloatArray) -> Angles:
    """``value`` as ``arg`` came: a float for a float, else the array."""
    if isinstance(arg, (float, int)):  # numpy scalars too
        return float(value)
    return value


def _a(x: float | FloatArray) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


def bevel_theta(gamma: Angles, xi: float) -> Angles:
    """θ(γ) = π − arccos(cos ξ cos γ) at the outer edge of a one-plane bevel
    (eq. 2.1 / Table 3.2, ERRATA.md): ξ at the tip, π − ξ at the heel."""
    return _like(gamma, np.pi - np.arccos(np.cos(xi) * np.cos(_a(gamma))))


def bevel_theta_inner(gamma: Angles, xi: float) -> Angles:
    """θ_i(γ) = arccos(cos ξ cos γ): the wedge at the inner edge (against the
    bore's normal −n_c); ξ at the heel, π − ξ at the tip."""
    return _like(gamma, np.arccos(np.cos(xi) * np.cos(_a(gamma))))


def bevel_lambda(gamma: Angles, xi: float) -> Angles:
    """λ(γ) = arcsin(|cot ξ sin γ| / √(1 + cot²ξ sin²γ)) (eq. 2.2, Table 3.2);
    the same on the outer and inner edges."""
    c = np.cos(xi) / np.sin(xi)
    s = np.abs(c * np.sin(_a(gamma)))
    return _like(gamma, np.arcsin(s / np.sqrt(1.0 + s * s)))


def bevel_alpha(gamma: Angles, xi: float) -> Angles:
    """α(γ) = arccos √(cos²γ sin²ξ + sin²γ) (Table 3.2): π/2 − ξ at the heel
    and the tip, 0 at γ = ±π/2."""
    g = _a(gamma)
    v = np.cos(g) ** 2 * np.sin(xi) ** 2 + np.sin(g) ** 2
    return _like(gamma, np.arccos(np.sqrt(np.clip(v, 0.0, 1.0))))


def bevel_z(gamma: Angles, radius: float, xi: float, r_heel: float | None = None) -> Angles:
    """Edge height z(γ) = (r_heel − r cos γ) cot ξ on the cylinder of
    ``radius`` r, z measured from the outer heel (r_heel = r_o; default r,
    which gives Table 3.1's r(1 − cos γ) cot ξ: the inner profile there is
    measured from its own lowest point, i.e. without (r_o − r_i) cot ξ)."""
    r_heel = radius if r_heel is None else r_heel
    return _like(gamma, (r_heel - radius * np.cos(_a(gamma))) * np.cos(xi) / np.sin(xi))


def bevel_dz(gamma: Angles, radius: float, xi: float) -> Angles:
    """z′(γ) = r sin γ cot ξ (Table 3.1)."""
    return _like(gamma, radius * np.sin(_a(gamma)) * np.cos(xi) / np.sin(xi))


def bevel_edge_length(radius: float, xi: float) -> float:
    """Edge length l_c of a bevel on a cylinder of ``radius``: the ellipse
    with semi-axes r and r / sin ξ, perimeter 4 a E(1 − b²/a²) (scipy's
    complete elliptic integral of the second kind, parameter m)."""
    a = radius / np.sin(xi)
    return float(4.0 * a * ellipe(1.0 - (radius / a) ** 2))


def multiplane_theta(xi: Angles, planes: int) -> Angles:
    """Included angle between adjacent planes of a symmetric P_l-plane tip
    (eq. 2.3): θ = π − arccos(cos²ξ cos φ + sin²ξ), φ = 2π/P_l — the dihedral
    angle at the ridge where the edge passes from one plane to the next."""
    phi = 2 * np.pi / planes
    x = _a(xi)
    return _like(xi, np.pi - np.arccos(np.cos(x) ** 2 * np.cos(phi) + np.sin(x) ** 2))


def multiplane_local_gamma(gamma: Angles, planes: int, rotation: float = 0.0) -> Angles:
    """γ measured from the heel of the plane that owns it, in (−π/P_l, π/P_l]."""
    span = 2 * np.pi / planes
    g = np.asarray(gamma, float) - rotation
    return _like(gamma, g - span * np.round(g / span))


def multiplane_lambda(gamma: Angles, xi: float, planes: int, rotation: float = 0.0) -> Angles:
    """λ on each plane's span (eq. 2.4): the bevel's λ of the local γ."""
    return bevel_lambda(multiplane_local_gamma(gamma, planes, rotation), xi)


def conical_theta(theta: Angles) -> Angles:
    """Conical tips: the wedge at the sharp inner edge equals the cone angle θ
    (§2.1.1, Fig. 2.2); λ = 0."""
    return _like(theta, _a(theta))


def conical_theta_outer(theta: Angles) -> Angles:
    """Conical tips: eq. 3.14 at the outer (heel) circle, π − θ."""
    return _like(theta, np.pi - _a(theta))


def conical_lambda(gamma: Angles) -> Angles:
    """λ = 0: the conical edge is perpendicular to the axis."""
    return _like(gamma, np.zeros(np.shape(gamma)))


def conical_alpha(theta: Angles) -> Angles:
    """α = π/2 − θ along a conical edge (t horizontal, eq. 3.15–3.17)."""
    return _like(theta, 0.5 * np.pi - _a(theta))
