"""Analytical insertion forces from the tissue's hyperelastic model
(thesis §4.3, eq. 4.18–4.34).

Units: lengths in mm, stresses in MPa, forces in N, torques in N·mm, twist K
in rad/mm. The tissue in front of the needle is a column of radius
r_t = β d_i / 2 (β = 2–3, eq. 4.19) and initial length l_init compressed by
the needle's advance x: axial stretch λ₃ = (l_init − x) / l_init (eq. 4.21),
lateral stretches λ₁ = λ₂ = λ₃^(−1/2). Forces returned are what the needle
pushes with (positive in compression).

Without rotation (eq. 4.18–4.22): F = −σ₁(λ₃) · π r_t², any uniaxial model.

With rotation (eq. 4.23–4.33), an I₁-only model (Arruda–Boyce, neo-Hookean)
under compression and twist θ = Θ + K Z: with W₁ = ∂U/∂I₁ and
I₁(r) = 2λ₁² + λ₃² + r²K², radial equilibrium with a free lateral surface
gives σ_rr(r) = −∫_r^{r_t} 2W₁ s K² ds and

    F_axial = 2π ∫₀^{r_t} W₁(r) (2(λ₃² − λ₁²) r − K² r³) dr,
    T       = 4π K λ₃ ∫₀^{r_t} W₁(r) r³ dr.

For constant W₁ these are eq. 4.32–4.33 exactly: F = π W₁ (2λ₃² r_t² −
2λ₁² r_t² − K² r_t⁴ / 2), T = π W₁ K λ₃ r_t⁴ (the thesis writes π μ Σ …;
its sum is ∂U/∂I₁ / μ with the ERRATA's i Cᵢ). :func:`insertion_with_rotation`
integrates with W₁(I₁(r)) (``method='integral'``, Gauss–Legendre, exact for
the polynomial Arruda–Boyce W₁) or uses the thesis's closed form with W₁ at
the axis (``method='closed-form'``). The tangential force is T / r_t, or
μ_d F as the thesis approximates it (eq. 4.34).
"""

from __future__ import annotations

import math

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ._common import finite_array
from .models import TissueModel
from .tissue import ArrudaBoyce, NeoHookean

__all__ = ["column_radius", "column_stretch", "insertion_force", "insertion_with_rotation",
           "DEFAULT_BETA"]

#: Column radius factor β of eq. 4.19 (thesis: 2–3); the middle.
DEFAULT_BETA = 2.5

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)


def column_radius(d_i: float, beta: float = DEFAULT_BETA) -> float:
    """r_t = β d_i / 2 (mm, eq. 4.19)."""
    d_i = v.length("d_i", d_i)
    beta = v.real("beta", beta, lo=0.0, lo_open=True)
    return 0.5 * beta * d_i


def column_stretch(x: ArrayLike, l_init: float) -> FloatArray:
    """λ₃ = (l_init − x) / l_init (eq. 4.21) for 0 ≤ x < l_init (mm)."""
    l_init = v.length("l_init", l_init)
    xx = finite_array("x", x, lo=0.0, unit="mm")
    if np.any(xx >= l_init):
        raise SpecError(f"x = {xx.max():.6g} mm is out of range; allowed 0 ≤ x < l_init = "
                        f"{l_init:.6g} mm")
    return (l_init - xx) / l_init


def insertion_force(model: TissueModel, x: ArrayLike, *, d_i: float, l_init: float,
                    beta: float = DEFAULT_BETA) -> FloatArray:
    """Axial force of a needle pushed x into tissue, without rotation
    (eq. 4.18–4.22).

    Parameters
    ----------
    model : a tissue model with ``stress(stretch)`` (MPa)
    x : float or array — displacement, mm (0 ≤ x < l_init)
    d_i : float — inner diameter, mm
    l_init : float — initial length of the tissue column, mm
    beta : float — column radius / inner radius (thesis 2–3)

    Returns
    -------
    F, N (positive: the needle pushes)
    """
    lam = column_stretch(x, l_init)
    r_t = column_radius(d_i, beta)
    return -model.stress(lam) * math.pi * r_t ** 2


def insertion_with_rotation(model: TissueModel, x: ArrayLike, K: float, *, d_i: float,
                            l_init: float,
                            beta: float = DEFAULT_BETA, mu_d: float | None = None,
                            method: str = "integral") -> dict[str, FloatArray]:
    """Axial force and torque of a needle pushed x into tissue while it
    twists the column by K (eq. 4.23–4.34).

    Parameters
    ----------
    model : ArrudaBoyce or NeoHookean (an I₁-only model)
    x : float or array — displacement, mm
    K : float — twist per unit length, rad/mm
    d_i, l_init, beta : as :func:`insertion_force`
    mu_d : float, optional — friction coefficient for F_H = μ_d F (eq. 4.34)
    method : ``integral`` (W₁ varies with r) | ``closed-form`` (eq. 4.32–4.33,
        W₁ at the axis)

    Returns
    -------
    dict: ``stretch``, ``F`` (N, push positive), ``T`` (N·mm), ``F_H_torque``
    = T / r_t (N) and, with ``mu_d``, ``F_H_friction`` = μ_d F (N)
    """
    if not isinstance(model, (ArrudaBoyce, NeoHookean)):
        raise SpecError(f"model = {type(model).__name__} is not an I₁-only model; the "
                        "rotation model (eq. 4.26–4.33) needs ArrudaBoyce or NeoHookean")
    if method not in ("integral", "closed-form"):
        raise SpecError(f"method = {method!r} is not valid; expected one of: integral, "
                        "closed-form")
    K = v.real("K", K, unit="rad/mm")
    lam3 = np.atleast_1d(column_stretch(x, l_init)).astype(float)
    r_t = column_radius(d_i, beta)
    lam1_sq = 1.0 / lam3
    base = 2.0 * lam1_sq + lam3 ** 2
    if method == "closed-form":
        w1 = model.dU_dI1(base)
        F = math.pi * w1 * (2 * (lam3 ** 2 - lam1_sq) * r_t ** 2 - 0.5 * K ** 2 * r_t ** 4)
        T = math.pi * w1 * K * lam3 * r_t ** 4
    else:
        r = 0.5 * r_t * (_GL_NODES + 1.0)
        wq = 0.5 * r_t * _GL_WEIGHTS
        w1 = model.dU_dI1(base[:, None] + (r * K)[None, :] ** 2)
        F = 2 * math.pi * (w1 * (2 * (lam3 ** 2 - lam1_sq)[:, None] * r - K ** 2 * r ** 3)) @ wq
        T = 4 * math.pi * K * lam3 * ((w1 * r ** 3) @ wq)
    shape = np.shape(x)
    out = {"stretch": lam3.reshape(shape), "F": (-F).reshape(shape), "T": T.reshape(shape),
           "F_H_torque": (T / r_t).reshape(shape)}
    if mu_d is not None:
        out["F_H_friction"] = v.real("mu_d", mu_d, lo=0.0) * out["F"]
    return out
