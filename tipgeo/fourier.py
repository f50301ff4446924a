"""Fourier fits of edge profiles z(γ) — the thesis's eq. 3.12 — with a fitted
base frequency w and the analytic derivative (ERRATA.md's corrected eq. 3.13).

    z(γ)  = a₀ + Σₖ aₖ cos(k w γ) + bₖ sin(k w γ)
    z′(γ) = Σₖ k w (−aₖ sin(k w γ) + bₖ cos(k w γ))

γ in radians (measured from the heel), z in mm.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from . import validate as v
from .arrays import ArrayLike, FloatArray
from .errors import SpecError
from .tolerances import tol

__all__ = ["FourierFit", "fit_fourier"]


@dataclass(frozen=True)
class FourierFit:
    """A fitted profile (γ in rad, z in mm).

    Attributes
    ----------
    a0 : float
    a, b : (n,) float — cosine and sine coefficients (mm)
    w : float — base frequency (1/rad)
    r2 : float — coefficient of determination on the fitted data
    rmse : float — root-mean-square residual (mm)
    gamma_range : (float, float) — the fitted γ interval (rad)
    """

    a0: float
    a: FloatArray
    b: FloatArray
    w: float
    r2: float
    rmse: float
    gamma_range: tuple[float, float]

    @property
    def n(self) -> int:
        """Number of harmonics."""
        return len(self.a)

    def __call__(self, gamma: ArrayLike) -> FloatArray:
        """z(γ) (mm)."""
        g = np.asarray(gamma, float)
        k = np.arange(1, self.n + 1)
        kwg = np.multiply.outer(g, k * self.w)
        return np.asarray(self.a0 + np.cos(kwg) @ self.a + np.sin(kwg) @ self.b,
                          dtype=np.float64)

    def derivative(self, gamma: ArrayLike) -> FloatArray:
        """z′(γ) (mm/rad), ERRATA.md's eq. 3.13."""
        g = np.asarray(gamma, float)
        k = np.arange(1, self.n + 1)
        kw = k * self.w
        kwg = np.multiply.outer(g, kw)
        return np.asarray((-np.sin(kwg)) @ (kw * self.a) + np.cos(kwg) @ (kw * self.b),
                          dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers (for JSON)."""
        return {"a0": self.a0, "a": self.a.tolist(), "b": self.b.tolist(), "w": self.w,
                "r2": self.r2, "rmse_mm": self.rmse,
                "gamma_range_deg": [float(np.degrees(x)) for x in self.gamma_range]}


def _design(g: FloatArray, n: int, w: float) -> FloatArray:
    kwg = np.multiply.outer(g, w * np.arange(1, n + 1))
    return np.concatenate([np.ones((len(g), 1)), np.cos(kwg), np.sin(kwg)], axis=1)


def _solve(g: FloatArray, z: FloatArray, n: int, w: float) -> tuple[FloatArray, float]:
    A = _design(g, n, w)
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    res = z - A @ coef
    return np.asarray(coef, dtype=np.float64), float(res @ res)


def _search_w(g: FloatArray, zz: FloatArray, n: int, span: float) -> float:
    """The base frequency w (1/rad) by variable projection over a grid of
    [0.2, 1.5]·2π/span, every local minimum refined (see :func:`fit_fourier`)."""
    w0 = 2 * np.pi / span
    grid = w0 * np.geomspace(0.2, 1.5, 40)
    grss = np.array([_solve(g, zz, n, wi)[1] for wi in grid])
    # refine every local minimum of the grid, keep the best; among equally
    # good w (a series with w/2 can mimic one with w) keep the largest
    tss0 = float(((zz - zz.mean()) ** 2).sum())
    left = np.r_[np.inf, grss[:-1]]
    right = np.r_[grss[1:], np.inf]
    at = np.flatnonzero((grss <= left) & (grss <= right) & ((grss < left) | (grss < right)))
    minima = [int(k) for k in at[np.argsort(grss[at])][:n + 1]]  # w/k mimics w: n valleys + 1
    cand: list[tuple[float, float]] = []
    # a constant profile: w = 2π/span
    if tss0 <= tol.fourier_constant * g.size or len(minima) == 0:
        cand.append((w0, _solve(g, zz, n, w0)[1]))
        minima = []
    for k in minima:
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        r = minimize_scalar(lambda x: _solve(g, zz, n, x)[1], bounds=(lo, hi),
                            method="bounded", options={"xatol": tol.fourier_xatol * w0})
        cand.append((float(r.x), float(r.fun)) if r.fun <= grss[k] else
                    (float(grid[k]), float(grss[k])))
    best = min(c[1] for c in cand)
    floor = best * (1 + tol.fourier_tie) + tol.fourier_floor * tss0
    return max(c[0] for c in cand if c[1] <= floor)


def fit_fourier(gamma: ArrayLike, z: ArrayLike, *, n: int = 5,
                w: float | None = None) -> FourierFit:
    """Least-squares fit of z(γ) with ``n`` harmonics.

    Parameters
    ----------
    gamma : (m,) float — rad
    z : (m,) float — mm
    n : int — harmonics (thesis: 5)
    w : float, optional — fix the base frequency; default: fitted (variable
        projection: the coefficients are linear; w is searched on a grid over
        [0.2, 1.5]·2π/span and every local minimum refined; among equally good
        w the largest — the most compact series — is kept).
    """
    n = v.integer("n", n, lo=1, hi=50)
    g = np.asarray(gamma, float).ravel()
    zz = np.asarray(z, float).ravel()
    if g.shape != zz.shape:
        raise SpecError(f"gamma and z differ in length ({g.size} vs {zz.size})")
    if g.size < 2 * n + 2:
        raise SpecError(f"{g.size} points cannot fit n = {n} harmonics; allowed n ≤ "
                        f"{(g.size - 2) // 2}")
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(zz))):
        raise SpecError("gamma and z must be finite")
    span = float(g.max() - g.min())
    if span <= 0:
        raise SpecError("gamma spans no interval")
    refine = w is None      # a given w stays fixed
    if refine:
        w = _search_w(g, zz, n, span)
    else:
        w = v.real("w", w, lo=0.0, lo_open=True)
    coef, rss = _solve(g, zz, n, w)
    # Gauss–Newton on (coefficients, w) jointly: the scalar search stops at
    # √ε in w because the residual is flat there; two or three steps reach ε
    for _ in range(6 if refine else 0):
        ks = np.arange(1, n + 1)
        kwg = np.multiply.outer(g, ks * w)
        dzdw = (np.sin(kwg) * (-g[:, None] * ks)) @ coef[1:n + 1] + \
            (np.cos(kwg) * (g[:, None] * ks)) @ coef[n + 1:]
        J = np.concatenate([_design(g, n, w), dzdw[:, None]], axis=1)
        res = zz - _design(g, n, w) @ coef
        step, *_ = np.linalg.lstsq(J, res, rcond=None)
        w_new = w + step[-1]
        if not w_new > 0:
            break
        coef_new, rss_new = _solve(g, zz, n, w_new)
        if rss_new >= rss:
            break
        w, coef, rss = w_new, coef_new, rss_new
    tss = float(((zz - zz.mean()) ** 2).sum())
    r2 = 1.0 - rss / tss if tss > 0 else 1.0
    return FourierFit(float(coef[0]), coef[1:n + 1].copy(), coef[n + 1:].copy(), float(w),
                      float(r2), float(np.sqrt(rss / g.size)), (float(g.min()), float(g.max())))
