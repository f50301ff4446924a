"""Cutting (friction) forces after fracture and the measured force surfaces
(thesis §2.2.2, eq. 2.18–2.29; §2.5, Tables 2.5–2.7; §4.4.3, Table 4.2).

Units: lengths and displacements in mm, Young's modulus E in MPa, forces in
N, forces per unit displacement in N/mm, speeds in mm/s, R in N/mm, angles in
rad. The friction regressions and force surfaces are named presets with the
range they were measured over; a query outside it warns
(:class:`~tipgeo.mechanics.ValidityWarning`).

Model (Begg et al. via the thesis), cannula of inner/outer radius r_i, r_o
pushed x into tissue of modulus E and Poisson ratio η:

    F_N    = π (r_i + r_o) E x / (1 + η)                  (eq. 2.18)
    F_Vcut = μ_da F_N,  F_Hcut = μ_dr F_N                  (eq. 2.19, 2.21)
    μ_d    = √(μ_da² + μ_dr²)                              (eq. 2.25)
    F_V    = F_Vrup(k; μ_d) + F_Vcut,  F_H = F_Hrup + F_Hcut (eq. 2.26, 2.27)

with F_Vrup, F_Hrup from eq. 2.16–2.17 (:func:`rupture_forces`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import validate as v
from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ..tolerances import tol
from ._common import KPA, finite_array, warn_outside
from .fracture import rupture_forces

__all__ = ["FrictionRegression", "ForceSurface", "FRICTION_PRESETS", "FORCE_SURFACES",
           "friction_preset", "force_surface", "normal_force", "cutting_forces",
           "measured_cutting_force", "optimal_slice_push_ratio"]


def _poly(coefficients: tuple[float, ...], x: FloatArray) -> FloatArray:
    """The polynomial with ``coefficients`` (highest power first) at ``x``."""
    return np.asarray(np.polyval(coefficients, x), dtype=np.float64)


@dataclass(frozen=True)
class FrictionRegression:
    """Dynamic friction coefficients against the slice/push ratio k:
    μ_da(k) (axial) and μ_dr(k) (rotational) as polynomials, highest power
    first (numpy.polyval order).

    Attributes
    ----------
    name, source, tissue : str
    axial, rotational : tuple of float — polynomial coefficients
    k_range : (float, float) — k values the fit was measured over
    r2, rmse : (float, float) — the thesis's R² and RMSE (axial, rotational)
    """

    name: str
    source: str
    tissue: str
    axial: tuple[float, ...]
    rotational: tuple[float, ...]
    k_range: tuple[float, float] = (0.0, 4.0)
    r2: tuple[float, float] = (math.nan, math.nan)
    rmse: tuple[float, float] = (math.nan, math.nan)

    def _k(self, k: ArrayLike) -> FloatArray:
        kk = finite_array("k", k, lo=0.0)
        warn_outside("k", kk, *self.k_range, source=f"friction regression {self.name}",
                     stacklevel=4)
        return kk

    def mu_da(self, k: ArrayLike) -> FloatArray:
        """μ_da(k), the axial dynamic friction coefficient."""
        return _poly(self.axial, self._k(k))

    def mu_dr(self, k: ArrayLike) -> FloatArray:
        """μ_dr(k), the rotational dynamic friction coefficient."""
        return _poly(self.rotational, self._k(k))

    def mu_d(self, k: ArrayLike) -> FloatArray:
        """μ_d(k) = √(μ_da² + μ_dr²) (eq. 2.25)."""
        kk = self._k(k)
        return np.hypot(_poly(self.axial, kk), _poly(self.rotational, kk))

    def mu_d_held(self, k: ArrayLike) -> FloatArray:
        """μ_d(k) with k held inside the measured range (no warning): the
        value at the range's end beyond it. For along-edge models, where k
        runs to ∞ where the edge moves along itself and the polynomials
        would grow without bound; callers say so
        (:func:`tipgeo.mechanics.report.tip_forces` warns once)."""
        kk = np.clip(finite_array("k", k, lo=0.0), *self.k_range)
        return np.hypot(_poly(self.axial, kk), _poly(self.rotational, kk))


#: Table 4.2's k² coefficient of μ_da(k) (thesis, as printed).
TABLE_4_2_AXIAL_K2 = 0.00087

#: Friction regressions (thesis, coefficients as printed; k tested 0–4 in
#: §2.5.1: k = 0, 0.25, 0.5, 1, 1.5, 2, 3, 4).
FRICTION_PRESETS: dict[str, FrictionRegression] = {
    "table-2.5": FrictionRegression(
        name="table-2.5", source="thesis Table 2.5 (§2.5.1)",
        tissue="PVC S/P = 0.5, 14G conical θ = 15°, v_t = 1 mm/s",
        axial=(0.002418, -0.0294, 0.294), rotational=(-0.03423, 0.2181, 0.0542),
        r2=(0.925, 0.942), rmse=(0.001, 0.034)),
    "table-4.2": FrictionRegression(
        name="table-4.2", source="thesis Table 4.2 (§4.4.3)",
        tissue="PVC of the FE models (S/P = 0, Table 4.1; harder than S/P = 0.5)",
        axial=(TABLE_4_2_AXIAL_K2, -0.0194, 0.328), rotational=(-0.03382, 0.2726, 0.1243),
        r2=(0.823, 0.99), rmse=(0.018, 0.022)),
}


@dataclass(frozen=True)
class ForceSurface:
    """A measured force as a polynomial in k and one more variable.

    ``terms`` maps exponents (i, j) to the coefficient of k^i · y^j, with y in
    the table's own unit (``y_unit``); callers pass y in tipgeo's unit
    (``y_internal_unit``), converted by ``y_scale`` (table = internal ×
    y_scale).

    Attributes
    ----------
    name, quantity, source, tissue : str
    y_name : str — keyword of the second variable (``v_t`` or ``E``)
    y_unit, y_internal_unit : str
    y_scale : float
    terms : dict (i, j) → float
    k_range, y_range : (float, float) — measured ranges (internal units)
    r2, rmse : float — the thesis's fit quality (rmse in N)
    """

    name: str
    quantity: str
    source: str
    tissue: str
    y_name: str
    y_unit: str
    y_internal_unit: str
    y_scale: float
    terms: dict[tuple[int, int], float] = field(hash=False)
    k_range: tuple[float, float]
    y_range: tuple[float, float]
    r2: float
    rmse: float

    def __call__(self, k: ArrayLike, **y: ArrayLike) -> FloatArray:
        """The force (N) at slice/push ratio ``k`` and ``<y_name>=value``
        (internal units: mm/s for v_t, MPa for E). Broadcasts arrays."""
        if set(y) != {self.y_name}:
            raise SpecError(f"{self.name}: arguments {sorted(y)} are not valid; expected "
                            f"k and {self.y_name} ({self.y_internal_unit})")
        kk = finite_array("k", k, lo=0.0)
        yy = finite_array(self.y_name, y[self.y_name], lo=0.0)
        warn_outside("k", kk, *self.k_range, source=f"force surface {self.name}", stacklevel=3)
        warn_outside(self.y_name, yy, *self.y_range, unit=self.y_internal_unit,
                     source=f"force surface {self.name}", stacklevel=3)
        yt = yy * self.y_scale
        out = np.zeros(np.broadcast_shapes(kk.shape, yt.shape))
        for (i, j), c in self.terms.items():
            out = out + c * kk ** i * yt ** j
        return out


_VT: dict[str, Any] = dict(y_name="v_t", y_unit="mm/s", y_internal_unit="mm/s", y_scale=1.0,
           k_range=(0.0, 4.0), y_range=(0.5, 6.0),
           tissue="PVC S/P = 0.5, 14G conical θ = 15° (§2.5.2)")
# Table 2.7's E is in kPa (Table 2.1: 4.88–32.96 kPa); tipgeo passes MPa.
_E: dict[str, Any] = dict(y_name="E", y_unit="kPa", y_internal_unit="MPa", y_scale=1.0 / KPA,
          k_range=(0.0, 4.0), y_range=(4.88 * KPA, 32.96 * KPA),
          tissue="PVC S/P = 0, 0.25, 0.5, 1 (Table 2.1), 14G conical θ = 15°, "
                 "v_t = 1 mm/s (§2.5.3)")

#: Maximum axial (F_V) and tangential (F_H) forces (N) as measured surfaces.
FORCE_SURFACES: dict[str, ForceSurface] = {
    "table-2.6-FV": ForceSurface(
        name="table-2.6-FV", quantity="F_V", source="thesis Table 2.6", **_VT,
        terms={(0, 0): 0.888, (1, 0): -0.653, (0, 1): 0.216, (2, 0): 0.251, (1, 1): 0.047,
               (0, 2): -0.0217, (3, 0): -0.0317, (2, 1): -0.009, (1, 2): -0.0019},
        r2=0.923, rmse=0.090),
    "table-2.6-FH": ForceSurface(
        name="table-2.6-FH", quantity="F_H",
        source="thesis Table 2.6 / eq. 2.39 (ERRATA: `01258 v_t` is 0.01258 v_t)", **_VT,
        terms={(0, 0): -0.0561, (1, 0): 0.457, (0, 1): 0.01258, (2, 0): -0.0743,
               (1, 1): 0.1058, (0, 2): -0.0217},
        r2=0.977, rmse=0.108),
    "table-2.7-FV": ForceSurface(
        name="table-2.7-FV", quantity="F_V", source="thesis Table 2.7", **_E,
        terms={(0, 0): 0.1354, (1, 0): 0.0377, (0, 1): 0.0083, (2, 0): 0.0073,
               (1, 1): -0.009, (0, 2): 0.0012},
        r2=0.982, rmse=0.065),
    "table-2.7-FH": ForceSurface(
        name="table-2.7-FH", quantity="F_H", source="thesis Table 2.7", **_E,
        terms={(0, 0): 0.0905, (1, 0): 0.22, (0, 1): -0.0211, (2, 0): -0.0479,
               (1, 1): 0.0103, (0, 2): 0.001},
        r2=0.966, rmse=0.096),
}


def friction_preset(name: str) -> FrictionRegression:
    """The friction regression called ``name`` (see :data:`FRICTION_PRESETS`)."""
    if name not in FRICTION_PRESETS:
        raise SpecError(f"friction = {name!r} is not known; expected one of: "
                        + ", ".join(FRICTION_PRESETS))
    return FRICTION_PRESETS[name]


def force_surface(name: str) -> ForceSurface:
    """The force surface called ``name`` (see :data:`FORCE_SURFACES`)."""
    if name not in FORCE_SURFACES:
        raise SpecError(f"surface = {name!r} is not known; expected one of: "
                        + ", ".join(FORCE_SURFACES))
    return FORCE_SURFACES[name]


def normal_force(x: ArrayLike, *, r_i: float, r_o: float, E: float,
                 eta: float = 0.5) -> FloatArray:
    """Tissue's normal force on the cannula walls after insertion depth x
    (eq. 2.18): F_N = π (r_i + r_o) E x / (1 + η).

    Parameters
    ----------
    x : float or array — axial displacement, mm (≥ 0)
    r_i, r_o : float — inner and outer radius, mm (r_i < r_o)
    E : float — Young's modulus at small strain, MPa
    eta : float — Poisson ratio, 0 ≤ η ≤ 0.5 (0.5: incompressible, Table 2.4)

    Returns
    -------
    F_N, N
    """
    xx = finite_array("x", x, lo=0.0, unit="mm")
    r_i = v.length("r_i", r_i)
    r_o = v.length("r_o", r_o, lo=r_i)
    E = v.real("E", E, lo=0.0, lo_open=True, unit="MPa")
    eta = v.real("eta", eta, lo=0.0, hi=0.5)
    return math.pi * (r_i + r_o) * E / (1.0 + eta) * xx


def cutting_forces(k: ArrayLike, x: ArrayLike, *, R: float, r_i: float, r_o: float,
                   theta: float, E: float, friction: FrictionRegression | tuple[float, float],
                   eta: float = 0.5) -> dict[str, FloatArray]:
    """Axial and tangential insertion forces of a rotating cannula (eq.
    2.18–2.27).

    Parameters
    ----------
    k : float or array — slice/push ratio v_r / v_t (≥ 0)
    x : float or array — axial displacement after rupture, mm (≥ 0)
    R : float — strain energy release rate, N/mm
    r_i, r_o : float — mm
    theta : float — included angle, rad
    E : float — Young's modulus, MPa
    friction : FrictionRegression or (μ_da, μ_dr) — constant coefficients or
        a regression in k (``friction_preset('table-2.5')``)
    eta : float — Poisson ratio (default 0.5)

    Returns
    -------
    dict (arrays broadcast over k and x): ``mu_da``, ``mu_dr``, ``mu_d``
    (eq. 2.25), ``F_N`` (N), ``f_Vcut``, ``f_Hcut`` (N/mm, eq. 2.20),
    ``F_Vcut``, ``F_Hcut``, ``F_Vrup``, ``F_Hrup``, ``F_V``, ``F_H`` (N)
    """
    kk = finite_array("k", k, lo=0.0)
    xx = finite_array("x", x, lo=0.0, unit="mm")
    kk, xx = np.broadcast_arrays(kk, xx)
    if isinstance(friction, FrictionRegression):
        mu_da, mu_dr = friction.mu_da(kk), friction.mu_dr(kk)
    else:
        try:
            a, b = friction
        except (TypeError, ValueError):
            raise SpecError(f"friction = {friction!r} is not a FrictionRegression or a pair "
                            "(mu_da, mu_dr)") from None
        mu_da = np.full(kk.shape, v.real("friction[0] (mu_da)", a, lo=0.0))
        mu_dr = np.full(kk.shape, v.real("friction[1] (mu_dr)", b, lo=0.0))
    for name, arr in (("mu_da(k)", mu_da), ("mu_dr(k)", mu_dr)):
        if np.any(arr < 0):
            raise SpecError(f"{name} = {arr.min():.6g} is negative at k = "
                            f"{kk.reshape(-1)[np.argmin(arr.reshape(-1))]:.6g}; the "
                            "regression is used outside its range")
    mu_d = np.hypot(mu_da, mu_dr)
    per_mm = normal_force(1.0, r_i=r_i, r_o=r_o, E=E, eta=eta)
    fv_rup = np.empty(kk.shape)
    fh_rup = np.empty(kk.shape)
    for idx in np.ndindex(kk.shape):
        fv_rup[idx], fh_rup[idx] = rupture_forces(kk[idx], R=R, d_i=2 * r_i, theta=theta,
                                                  mu_d=float(mu_d[idx]))
    f_v, f_h = mu_da * per_mm, mu_dr * per_mm
    return {"mu_da": mu_da, "mu_dr": mu_dr, "mu_d": mu_d, "F_N": per_mm * xx,
            "f_Vcut": f_v, "f_Hcut": f_h, "F_Vcut": f_v * xx, "F_Hcut": f_h * xx,
            "F_Vrup": fv_rup, "F_Hrup": fh_rup, "F_V": fv_rup + f_v * xx,
            "F_H": fh_rup + f_h * xx}


def measured_cutting_force(F_final: float, F_rup: float, d_final: float,
                           d_rup: float) -> tuple[float, float]:
    """Cutting force from a measured insertion (eq. 2.28–2.29).

    Parameters
    ----------
    F_final, F_rup : float — force at the final depth and at rupture, N
    d_final, d_rup : float — the depths, mm (d_final > d_rup ≥ 0)

    Returns
    -------
    (F_cut in N, f_cut in N/mm)
    """
    F_final = v.real("F_final", F_final, unit="N")
    F_rup = v.real("F_rup", F_rup, unit="N")
    d_rup = v.real("d_rup", d_rup, lo=0.0, unit="mm")
    d_final = v.real("d_final", d_final, lo=d_rup, lo_open=True, unit="mm")
    return F_final - F_rup, (F_final - F_rup) / (d_final - d_rup)


def optimal_slice_push_ratio(x: float, *, R: float, r_i: float, r_o: float, theta: float,
                             E: float, friction: FrictionRegression | tuple[float, float],
                             eta: float = 0.5, k_max: float | None = None) -> float | None:
    """The slice/push ratio where the axial and tangential forces are equal,
    F_V(k) = F_H(k) (eq. 2.26–2.27, the intersection of §2.2.1).

    At x = 0 (fracture forces alone) this is k = 1 whatever R, μ_d and θ,
    since F_Hrup = k F_Vrup. With cutting (x > 0) the friction terms move it:
    F_V − F_H = (1 − k) F_rup(k) + (μ_da(k) − μ_dr(k)) F_N / x · x.

    Parameters
    ----------
    x : float — displacement after rupture, mm (≥ 0); the other parameters
        as :func:`cutting_forces`
    k_max : float — upper end of the search (default: the regression's range,
        or 10 for constant coefficients)

    Returns
    -------
    k (float), or None if F_V − F_H does not change sign on [0, k_max]
    """
    from scipy.optimize import brentq

    x = v.real("x", x, lo=0.0, unit="mm")
    hi = k_max if k_max is not None else (
        friction.k_range[1] if isinstance(friction, FrictionRegression) else 10.0)
    hi = v.real("k_max", hi, lo=0.0, lo_open=True)

    def gap(k: float) -> float:
        f = cutting_forces(k, x, R=R, r_i=r_i, r_o=r_o, theta=theta, E=E, friction=friction,
                           eta=eta)
        return float(f["F_V"] - f["F_H"])

    grid = np.linspace(0.0, hi, 401)
    vals = np.array([gap(k) for k in grid])
    sign = np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) <= 0)[0]
    if len(sign) == 0:
        return None
    j = int(sign[0])
    if vals[j] == 0:
        return float(grid[j])
    return float(brentq(gap, grid[j], grid[j + 1], xtol=tol.root_xtol,
                        rtol=4 * np.finfo(float).eps))
