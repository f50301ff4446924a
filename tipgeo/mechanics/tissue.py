"""Hyperelastic tissue models under incompressible uniaxial load and their
least-squares fits (thesis §4.2, eq. 4.1–4.17; ERRATA for eq. 4.10).

Units: stresses and moduli in MPa (mm–N–s, as the Abaqus decks of Appendix
B), stretches and strains dimensionless. Stretch λ along the load, the two
lateral stretches λ^(−1/2) (eq. 4.4), I₁ = λ² + 2/λ.

Uniaxial true (Cauchy) stress:

* neo-Hookean:   σ = μ (λ² − 1/λ)
* Arruda–Boyce:  U = μ Σᵢ Cᵢ / λ_m^(2i−2) (I₁^i − 3^i), i = 1…5 (eq. 4.9),
  C = 1/2, 1/20, 11/1050, 19/7000, 519/673750 (eq. 4.8),
  ∂U/∂I₁ = μ Σᵢ i Cᵢ I₁^(i−1) / λ_m^(2i−2) (eq. 4.10 as corrected),
  σ = 2 ∂U/∂I₁ (λ² − 1/λ) (eq. 4.13, B₁₁ − B₃₃ = λ² − 1/λ). As λ_m → ∞ only
  the i = 1 term is left: the neo-Hookean solid with shear modulus μ.
* Ogden (N terms):  σ = Σᵢ (2μᵢ/αᵢ)(λ^αᵢ − λ^(−αᵢ/2)) (eq. 4.17).

Initial shear modulus μ₀ (small-strain Young's modulus E₀ = 3μ₀):
Arruda–Boyce μ₀ = μ (1 + 3/(5λ_m²) + 99/(175λ_m⁴) + 513/(875λ_m⁶)
+ 42039/(67375λ_m⁸)) (= 2 ∂U/∂I₁ at I₁ = 3); Ogden μ₀ = Σ μᵢ.

Each model is a :class:`~tipgeo.mechanics.models.TissueModel`, registered by
its name (:data:`~tipgeo.mechanics.models.TISSUE_MODELS`): the fits, the CLI,
the pictures and the FEM decks find it there, and a new model is one class.

Data: engineering stress P and strain e become true stress and stretch by
σ = P (1 + e), λ = 1 + e (eq. 4.2–4.3); fits minimise the true-stress
residuals (MPa), as Fig. 4.4 plots them, and report R² and RMSE.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from .. import validate as v
from ..errors import SpecError
from ..tolerances import tol
from ._common import KPA, finite_array
from .models import Parameter, TissueModel, tissue_model

if TYPE_CHECKING:
    from ..arrays import ArrayLike, FloatArray
    from .materials import Tissue

__all__ = ["MAX_TISSUE_DATA_BYTES", "MAX_TISSUE_ROWS", "NeoHookean", "ArrudaBoyce", "Ogden",
           "AB_C", "FitResult",
           "true_from_engineering", "engineering_from_true", "fit_uniaxial",
           "fit_engineering", "synthetic_uniaxial", "read_uniaxial_csv",
           "uniaxial_csv_text", "make_model"]

#: Arruda–Boyce constants C₁…C₅ (eq. 4.8).
AB_C = (1 / 2, 1 / 20, 11 / 1050, 19 / 7000, 519 / 673750)


def _ab_series(x: FloatArray) -> FloatArray:
    """Σᵢ i Cᵢ x^(i−1) with x = I₁ / λ_m² (so that ∂U/∂I₁ = μ · this)."""
    out = np.zeros_like(x)
    for i, c in enumerate(AB_C):
        out = out + (i + 1) * c * x ** i
    return out


def _stretch(stretch: ArrayLike) -> FloatArray:
    return finite_array("stretch", stretch, lo=0.0, lo_open=True)


_MU = Parameter("mu", "mu_MPa", "μ", "MPa", lo=0.0, lo_open=True)


_LAMBDA_M = Parameter("lambda_m", "lambda_m", "λ_m", lo=1.0, lo_open=True)


@dataclass(frozen=True)
class ArrudaBoyce(TissueModel):
    """Incompressible Arruda–Boyce solid, five terms of the inverse Langevin
    series (eq. 4.8–4.13, ERRATA).

    Attributes
    ----------
    mu : float — MPa (> 0)
    lambda_m : float — locking stretch (> 1; ``math.inf`` gives neo-Hookean)
    """

    mu: float
    lambda_m: float
    name = "arruda-boyce"
    title = "Arruda–Boyce"
    parameters = (_MU, _LAMBDA_M)

    def __post_init__(self) -> None:
        object.__setattr__(self, "mu", _MU.check(self.mu))
        lm = self.lambda_m
        if not (isinstance(lm, (int, float)) and not isinstance(lm, bool) and lm == math.inf):
            lm = _LAMBDA_M.check(lm)
        object.__setattr__(self, "lambda_m", float(lm))

    @property
    def beta(self) -> float:
        """1 / λ_m² (0 for the neo-Hookean limit)."""
        return 0.0 if math.isinf(self.lambda_m) else 1.0 / self.lambda_m ** 2

    def dU_dI1(self, I1: ArrayLike) -> FloatArray:
        """∂U/∂I₁ = μ Σᵢ i Cᵢ I₁^(i−1) / λ_m^(2i−2) (MPa)."""
        return self.mu * _ab_series(self.beta * np.asarray(I1, float))

    def stress(self, stretch: ArrayLike) -> FloatArray:
        """Uniaxial true stress σ (MPa) at stretch λ (> 0)."""
        lam = _stretch(stretch)
        return 2.0 * self.dU_dI1(lam ** 2 + 2.0 / lam) * (lam ** 2 - 1.0 / lam)

    @property
    def initial_shear_modulus(self) -> float:
        """μ₀ = 2 ∂U/∂I₁ at I₁ = 3 (MPa)."""
        return float(2.0 * self.dU_dI1(3.0))

    def json_params(self) -> dict[str, Any]:
        """:meth:`params` with λ_m = ∞ (the neo-Hookean limit) as None."""
        p = self.params()
        return {**p, "lambda_m": None} if math.isinf(self.lambda_m) else p

    @classmethod
    def from_params(cls, params: dict[str, Any]) -> ArrudaBoyce:
        """The model of :meth:`params` or :meth:`json_params` (λ_m None: ∞)."""
        if "lambda_m" in params and params["lambda_m"] is None:
            params = {**params, "lambda_m": math.inf}
        return cast(ArrudaBoyce, super().from_params(params))

    @classmethod
    def fit(cls, stretch: FloatArray, stress: FloatArray,
            terms: int) -> tuple[ArrudaBoyce, dict[str, Any]]:
        """Least squares in (μ, β = 1/λ_m²), see :func:`fit_uniaxial`."""
        return _fit_ab(stretch, stress)

    def hyperelastic_card(self, D: float) -> tuple[str, tuple[float, ...]]:
        """``ARRUDA-BOYCE``: μ, λ_m, D (1/MPa)."""
        return "ARRUDA-BOYCE", (self.mu, self.lambda_m, D)

    def report_lines(self, stderr: dict[str, Any]) -> list[str]:
        """μ and λ_m with their standard errors (λ_m = ∞: neo-Hookean)."""
        lm = ("∞ (neo-Hookean)" if math.isinf(self.lambda_m) else
              f"{self.lambda_m:.6g} (± {stderr['lambda_m']:.2g})")
        return [f"  μ {self.mu:.6g} MPa (± {stderr['mu_MPa']:.2g})", "  λ_m " + lm]

    def legend(self) -> str:
        """``Arruda–Boyce μ = … MPa, λ_m = …``."""
        lm = self.lambda_m
        return (f"Arruda–Boyce μ = {self.mu:.4g} MPa, λ_m = "
                f"{'∞' if math.isinf(lm) else f'{lm:.4g}'}")


def _ogden_basis(lam: FloatArray, alpha: float) -> FloatArray:
    """(2/α)(λ^α − λ^(−α/2)), with its limit 3 ln λ as α → 0 (computed with
    expm1 so that small α loses no digits)."""
    L = np.log(lam)
    if abs(alpha) < tol.fit_zero:
        return 3.0 * L
    return 2.0 / alpha * (np.expm1(alpha * L) - np.expm1(-0.5 * alpha * L))


@dataclass(frozen=True)
class Ogden(TissueModel):
    """Incompressible Ogden solid with N terms (eq. 4.14–4.17).

    Attributes
    ----------
    mu : tuple of float — μᵢ, MPa
    alpha : tuple of float — αᵢ (dimensionless, ≠ 0)

    The initial shear modulus Σ μᵢ must be positive.
    """

    mu: tuple[float, ...]
    alpha: tuple[float, ...]
    name = "ogden"
    title = "Ogden"
    parameters = (Parameter("mu", "mu_MPa", "μ", "MPa"), Parameter("alpha", "alpha", "α"))

    def __post_init__(self) -> None:
        mu = tuple(np.atleast_1d(np.asarray(self.mu, dtype=object)).tolist())
        al = tuple(np.atleast_1d(np.asarray(self.alpha, dtype=object)).tolist())
        if not 1 <= len(mu) <= 6 or len(mu) != len(al):
            raise SpecError(f"mu, alpha: {len(mu)} and {len(al)} values; expected the same "
                            "number of terms, 1 ≤ N ≤ 6")
        p_mu, p_al = self.parameters
        mu = tuple(p_mu.check(m, f"mu[{i}]") for i, m in enumerate(mu))
        al = tuple(p_al.check(a, f"alpha[{i}]") for i, a in enumerate(al))
        for i, a in enumerate(al):
            if a == 0:
                raise SpecError(f"alpha[{i}] = 0 is not allowed; expected α ≠ 0")
        if sum(mu) <= 0:
            raise SpecError(f"mu = {mu}: the initial shear modulus Σ μᵢ = {sum(mu):.6g} MPa "
                            "must be > 0 (a stable material)")
        object.__setattr__(self, "mu", mu)
        object.__setattr__(self, "alpha", al)

    def stress(self, stretch: ArrayLike) -> FloatArray:
        """Uniaxial true stress σ (MPa) at stretch λ (> 0)."""
        lam = _stretch(stretch)
        out = np.zeros_like(lam)
        for m, a in zip(self.mu, self.alpha):
            out = out + m * _ogden_basis(lam, a)
        return out

    @property
    def initial_shear_modulus(self) -> float:
        """μ₀ = Σ μᵢ (MPa)."""
        return float(sum(self.mu))

    def params(self) -> dict[str, Any]:
        """``mu_MPa`` and ``alpha`` as lists."""
        return {"mu_MPa": list(self.mu), "alpha": list(self.alpha)}

    @classmethod
    def from_params(cls, params: dict[str, Any]) -> Ogden:
        """The model of :meth:`params`."""
        return Ogden(mu=tuple(params["mu_MPa"]), alpha=tuple(params["alpha"]))

    @classmethod
    def fit_parameter_count(cls, terms: int) -> int:
        """2N for N = ``terms`` (1–4) terms."""
        return 2 * v.integer("terms", terms, lo=1, hi=4)

    @classmethod
    def fit(cls, stretch: FloatArray, stress: FloatArray,
            terms: int) -> tuple[Ogden, dict[str, Any]]:
        """Variable projection then a joint polish, see :func:`fit_uniaxial`."""
        return _fit_ogden(stretch, stress, v.integer("terms", terms, lo=1, hi=4))

    def hyperelastic_card(self, D: float) -> tuple[str, tuple[float, ...]]:
        """``OGDEN, N=n``: μ₁, α₁, …, μₙ, αₙ, D₁, then D₂ … Dₙ = 0."""
        consts = tuple(x for m, a in zip(self.mu, self.alpha) for x in (m, a))
        return f"OGDEN, N={len(self.mu)}", consts + (D,) + (0.0,) * (len(self.mu) - 1)

    def report_lines(self, stderr: dict[str, Any]) -> list[str]:
        """One line per term: μᵢ (MPa) and αᵢ with their standard errors."""
        return [f"  μ{i} {m:.6g} MPa (± {stderr['mu_MPa'][i - 1]:.2g})  "
                f"α{i} {a:.6g} (± {stderr['alpha'][i - 1]:.2g})"
                for i, (m, a) in enumerate(zip(self.mu, self.alpha), 1)]

    def legend(self) -> str:
        """``Ogden N = n``."""
        return f"Ogden N = {len(self.alpha)}"


@dataclass(frozen=True)
class NeoHookean(TissueModel):
    """Incompressible neo-Hookean solid, U = μ/2 (I₁ − 3).

    Attributes
    ----------
    mu : float — shear modulus, MPa (> 0)
    """

    mu: float
    name = "neo-hookean"
    title = "neo-Hookean"
    parameters = (_MU,)

    def __post_init__(self) -> None:
        object.__setattr__(self, "mu", _MU.check(self.mu))

    def dU_dI1(self, I1: ArrayLike) -> FloatArray:
        """∂U/∂I₁ = μ/2 (MPa)."""
        return np.full(np.shape(I1), 0.5 * self.mu)

    def stress(self, stretch: ArrayLike) -> FloatArray:
        """Uniaxial true stress σ (MPa) at stretch λ (> 0)."""
        lam = _stretch(stretch)
        return self.mu * (lam ** 2 - 1.0 / lam)

    @property
    def initial_shear_modulus(self) -> float:
        """μ₀ (MPa)."""
        return self.mu

    @classmethod
    def fit(cls, stretch: FloatArray, stress: FloatArray,
            terms: int) -> tuple[NeoHookean, dict[str, Any]]:
        """Linear least squares in μ (MPa)."""
        return _fit_nh(stretch, stress)

    def hyperelastic_card(self, D: float) -> tuple[str, tuple[float, ...]]:
        """``NEO HOOKE``: C10 = μ/2, D1 (1/MPa)."""
        return "NEO HOOKE", (0.5 * self.mu, D)

    @classmethod
    def from_tissue(cls, tissue: Tissue) -> tuple[NeoHookean, str]:
        """The neo-Hookean solid with the initial shear modulus μ₀ of the
        tissue's Arruda–Boyce fit."""
        ab, src = ArrudaBoyce.from_tissue(tissue)
        return NeoHookean(mu=ab.initial_shear_modulus), f"{src}, μ₀ of the Arruda–Boyce fit"


def make_model(name: str, params: dict[str, Any]) -> TissueModel:
    """A model from its name and ``params()`` dictionary (for JSON round trips)."""
    return tissue_model(name).from_params(params)


# -----------------------------------------------------------------------------
def true_from_engineering(strain: ArrayLike, stress: ArrayLike
                          ) -> tuple[FloatArray, FloatArray]:
    """Stretch and true (Cauchy) stress from engineering strain and stress
    (eq. 4.2–4.3): λ = 1 + e, σ = P (1 + e). Strain > −1; stress in MPa."""
    e = finite_array("strain", strain, lo=-1.0, lo_open=True)
    p = finite_array("stress", stress, unit="MPa")
    if e.shape != p.shape:
        raise SpecError(f"strain and stress have shapes {e.shape} and {p.shape}; expected "
                        "the same")
    return 1.0 + e, p * (1.0 + e)


def engineering_from_true(stretch: ArrayLike, stress: ArrayLike
                          ) -> tuple[FloatArray, FloatArray]:
    """Engineering strain and stress from stretch and true stress (inverse of
    eq. 4.2–4.3): e = λ − 1, P = σ / λ."""
    lam = _stretch(stretch)
    s = finite_array("stress", stress, unit="MPa")
    if lam.shape != s.shape:
        raise SpecError(f"stretch and stress have shapes {lam.shape} and {s.shape}; "
                        "expected the same")
    return lam - 1.0, s / lam


@dataclass
class FitResult:
    """A least-squares fit of a model to uniaxial data (true stress, MPa).

    Attributes
    ----------
    model : TissueModel — the fitted model (NeoHookean, ArrudaBoyce, Ogden, …)
    r2 : float — 1 − SS_res / SS_tot
    rmse : float — √(SS_res / n), MPa
    n : int — data points
    stderr : dict — standard errors of the parameters (from the Jacobian at
        the optimum; inf where the parameter is not identifiable)
    stretch, stress : arrays — the data fitted (λ, σ in MPa)
    """

    model: Any
    r2: float
    rmse: float
    n: int
    stderr: dict[str, Any]
    stretch: FloatArray = field(repr=False)
    stress: FloatArray = field(repr=False)

    def summary(self) -> dict[str, Any]:
        """Model, parameters, R², RMSE (MPa), μ₀ and E₀ = 3μ₀ (kPa)."""
        p = self.model.json_params()
        mu0 = self.model.initial_shear_modulus
        return {"model": self.model.name, "params": p, "stderr": self.stderr,
                "r2": self.r2, "rmse_MPa": self.rmse, "n": self.n,
                "initial_shear_modulus_MPa": mu0, "E0_kPa": 3 * mu0 / KPA,
                "stretch_range": [float(self.stretch.min()), float(self.stretch.max())]}


def _quality(pred: FloatArray, s: FloatArray) -> tuple[float, float]:
    res = s - pred
    ss_res = float(res @ res)
    ss_tot = float(((s - s.mean()) ** 2).sum())
    return (1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan), math.sqrt(ss_res / len(s))


def _stderr(jac: FloatArray, res: FloatArray, n_par: int) -> FloatArray:
    dof = max(len(res) - n_par, 1)
    s2 = float(res @ res) / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
        se: FloatArray = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        return se
    except np.linalg.LinAlgError:
        return np.full(n_par, np.inf)


def _fit_ab(lam: FloatArray, s: FloatArray) -> tuple[ArrudaBoyce, dict[str, Any]]:
    from scipy.optimize import least_squares

    I1 = lam ** 2 + 2.0 / lam
    shape = 2.0 * (lam ** 2 - 1.0 / lam)

    def basis(beta: float) -> FloatArray:
        return shape * _ab_series(beta * I1)

    # σ is linear in μ: scan β = 1/λ_m² with μ solved exactly, then polish.
    best: tuple[float, float, float] | None = None
    for beta in np.linspace(0.0, 0.98, 50):
        b = basis(beta)
        mu = max(float(b @ s) / float(b @ b), tol.fit_zero)
        r = s - mu * b
        if best is None or r @ r < best[0]:
            best = (float(r @ r), mu, float(beta))
    assert best is not None  # fifty candidates were tried
    _, mu0, beta0 = best
    scale = max(mu0, tol.fit_zero)

    def resid(p: FloatArray) -> FloatArray:
        out: FloatArray = basis(float(p[1])) * p[0] * scale - s
        return out

    sol = least_squares(resid, [1.0, beta0], bounds=([tol.fit_zero, 0.0], [np.inf, 1.0 - tol.rel]),
                        x_scale=[1.0, 0.1], xtol=tol.fit_converge, ftol=tol.fit_converge,
                        gtol=tol.fit_converge,
                        max_nfev=2000)
    mu, beta = sol.x[0] * scale, float(sol.x[1])
    se = _stderr(sol.jac, sol.fun, 2)
    se_mu = se[0] * scale
    lam_m = math.inf if beta <= tol.fit_zero else 1.0 / math.sqrt(beta)
    se_lm = math.inf if beta <= tol.fit_zero else 0.5 * beta ** -1.5 * se[1]
    return ArrudaBoyce(mu=mu, lambda_m=lam_m), {"mu_MPa": se_mu, "lambda_m": se_lm}


def _fit_nh(lam: FloatArray, s: FloatArray) -> tuple[NeoHookean, dict[str, Any]]:
    b = lam ** 2 - 1.0 / lam
    mu = float(b @ s) / float(b @ b)
    if mu <= 0:
        raise SpecError("stress: the data give a non-positive shear modulus "
                        f"(μ = {mu:.6g} MPa); check the sign convention (tension positive)")
    r = s - mu * b
    se = math.sqrt(float(r @ r) / max(len(s) - 1, 1) / float(b @ b))
    return NeoHookean(mu=mu), {"mu_MPa": se}


#: Starting exponents for the Ogden fits (every combination of N of them).
_ALPHA_STARTS = (-8.0, -4.0, -2.0, -1.0, 1.0, 2.0, 4.0, 8.0)
#: Exponents stay within ±_ALPHA_BOUND and at least _ALPHA_GAP apart: two
#: equal exponents make a pair of terms that can cancel with any size.
_ALPHA_BOUND = 30.0
_ALPHA_GAP = 0.1


def _alphas(q: FloatArray) -> FloatArray:
    """Sorted exponents from (α₁, gap₂, …, gap_N)."""
    return np.cumsum(q)


def _fit_ogden(lam: FloatArray, s: FloatArray, n: int) -> tuple[Ogden, dict[str, Any]]:
    from scipy.optimize import least_squares

    def design(al: FloatArray) -> FloatArray:
        return np.stack([_ogden_basis(lam, a) for a in al], 1)

    def vp_resid(q: FloatArray) -> FloatArray:
        A = design(_alphas(q))
        return A @ np.linalg.lstsq(A, s, rcond=None)[0] - s

    lo = np.r_[-_ALPHA_BOUND, np.full(n - 1, _ALPHA_GAP)]
    hi = np.r_[_ALPHA_BOUND, np.full(n - 1, 2 * _ALPHA_BOUND)]
    best: tuple[float, FloatArray] | None = None
    for start in itertools.combinations(_ALPHA_STARTS, n):
        q0 = np.r_[start[0], np.diff(start)]
        sol = least_squares(vp_resid, q0, bounds=(lo, hi), xtol=tol.fit_start, ftol=tol.fit_start,
                            max_nfev=400)
        cost = float(sol.fun @ sol.fun)
        if best is None or cost < best[0]:
            best = (cost, sol.x)
    assert best is not None  # at least one combination of starts was tried
    q = best[1]
    mu = np.linalg.lstsq(design(_alphas(q)), s, rcond=None)[0]
    scale = max(float(np.abs(mu).max()), tol.fit_zero)

    def resid(p: FloatArray) -> FloatArray:
        return design(_alphas(p[n:])) @ (p[:n] * scale) - s

    sol = least_squares(resid, np.r_[mu / scale, q],
                        bounds=(np.r_[np.full(n, -np.inf), lo], np.r_[np.full(n, np.inf), hi]),
                        xtol=tol.fit_converge, ftol=tol.fit_converge, gtol=tol.fit_converge,
                        max_nfev=4000)
    mu, al = sol.x[:n] * scale, _alphas(sol.x[n:])
    # standard errors in (μ, α): the Jacobian of α = cumsum(q) is lower-triangular ones
    jac = sol.jac.copy()
    jac[:, n:] = jac[:, n:] @ np.linalg.inv(np.tril(np.ones((n, n))))
    se = _stderr(jac, sol.fun, 2 * n)
    se_mu, se_al = se[:n] * scale, se[n:]
    try:
        model = Ogden(mu=tuple(mu), alpha=tuple(al))
    except SpecError as e:
        raise SpecError(f"the Ogden fit with {n} terms is not a stable material ({e}); "
                        "use fewer terms or more data") from None
    return model, {"mu_MPa": se_mu.tolist(), "alpha": se_al.tolist()}


def fit_uniaxial(stretch: ArrayLike, stress: ArrayLike, model: str = "arruda-boyce", *,
                 terms: int = 3) -> FitResult:
    """Fit a hyperelastic model to uniaxial true stress against stretch.

    Parameters
    ----------
    stretch : (n,) float — λ (> 0)
    stress : (n,) float — true (Cauchy) stress, MPa, tension positive
    model : str — a registered tissue model (:data:`~tipgeo.mechanics.models.TISSUE_MODELS`:
        ``arruda-boyce`` | ``ogden`` | ``neo-hookean`` and any added one)
    terms : int — Ogden terms N (1–4; the thesis uses 3)

    Returns
    -------
    FitResult — fitted model, R², RMSE (MPa), standard errors

    Notes
    -----
    scipy.optimize.least_squares on the true-stress residuals. Arruda–Boyce
    is fitted in (μ, β = 1/λ_m²) with 0 ≤ β < 1, so the neo-Hookean limit
    (β = 0, λ_m = ∞) is inside the search; μ is solved exactly on a β grid for
    the start. Ogden: variable projection (μ solved linearly for given α)
    from every combination of N starting exponents in ±{1, 2, 4, 8}, then all
    2N parameters polished together; |α₁| ≤ 30 and the exponents, kept in
    increasing order, at least 0.1 apart (equal exponents would let a pair of
    terms cancel at any size). Ogden parameters of three or more terms are
    often not identifiable from one uniaxial curve (the thesis's own Table 4.1
    has a near-cancelling pair); R² and RMSE still judge the fit.
    """
    kind = tissue_model(model)
    lam = _stretch(stretch).reshape(-1)
    s = finite_array("stress", stress, unit="MPa").reshape(-1)
    if lam.shape != s.shape:
        raise SpecError(f"stretch and stress have {lam.size} and {s.size} values; expected "
                        "the same number")
    n_par = kind.fit_parameter_count(terms)
    if lam.size < n_par + 2:
        raise SpecError(f"stress: {lam.size} data points are too few for {model} "
                        f"({n_par} parameters); need at least {n_par + 2}")
    if np.ptp(lam) <= 0:
        raise SpecError("stretch: all data points have the same stretch; a fit needs a range")
    fitted, se = kind.fit(lam, s, terms)
    r2, rmse = _quality(fitted.stress(lam), s)
    return FitResult(model=fitted, r2=r2, rmse=rmse, n=int(lam.size), stderr=se,
                     stretch=lam, stress=s)


def fit_engineering(strain: ArrayLike, stress: ArrayLike, model: str = "arruda-boyce", *,
                    terms: int = 3) -> FitResult:
    """:func:`fit_uniaxial` from engineering strain and stress (MPa),
    converted with eq. 4.2–4.3."""
    lam, s = true_from_engineering(strain, stress)
    return fit_uniaxial(lam, s, model, terms=terms)


def synthetic_uniaxial(model: TissueModel, stretch: ArrayLike, *, noise: float = 0.0,
                       seed: int = 0) -> tuple[FloatArray, FloatArray]:
    """Uniaxial true stress of ``model`` at ``stretch`` plus Gaussian noise.

    Parameters
    ----------
    model : TissueModel — NeoHookean, ArrudaBoyce, Ogden, …
    stretch : (n,) float — λ
    noise : float — standard deviation of the additive noise as a fraction
        of the largest |σ| of the clean curve (0.01 = 1 %)
    seed : int — numpy random generator seed

    Returns
    -------
    (stretch, true stress in MPa)
    """
    lam = _stretch(stretch).reshape(-1)
    noise = v.real("noise", noise, lo=0.0, hi=1.0)
    clean = model.stress(lam)
    rng = np.random.default_rng(v.integer("seed", seed, lo=0))
    return lam, clean + noise * float(np.abs(clean).max()) * rng.standard_normal(lam.size)


# -----------------------------------------------------------------------------
#: Largest tissue data file read (bytes) and most data rows fitted: a uniaxial
#: test has tens to thousands of points.
MAX_TISSUE_DATA_BYTES = 8 << 20
MAX_TISSUE_ROWS = 100_000

_COLS = {"strain": ("strain", 1.0), "stretch": ("stretch", 1.0),
         "stress_mpa": ("stress", 1.0), "stress_kpa": ("stress", KPA),
         "true_stress_mpa": ("true_stress", 1.0), "true_stress_kpa": ("true_stress", KPA)}


def read_uniaxial_csv(path: str | Path) -> tuple[FloatArray, FloatArray, dict[str, Any]]:
    """Read uniaxial test data from CSV (``#`` starts a comment line).

    The header names the columns: engineering data as ``strain`` with
    ``stress_mpa`` (or ``stress_kpa``), or true data as ``stretch`` with
    ``true_stress_mpa`` (or ``true_stress_kpa``). Other columns are ignored.

    Returns
    -------
    (stretch, true stress in MPa, info) — engineering data converted by
    eq. 4.2–4.3; ``info`` says which columns were read.
    """
    from ..tomlio import read_text_file

    p = Path(path)
    # a regular file only (a FIFO or device is refused before a byte is read), size-capped
    text = read_text_file(p, "tissue data", max_bytes=MAX_TISSUE_DATA_BYTES)
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise SpecError(f"data = '{path}' has no rows")
    if len(lines) - 1 > MAX_TISSUE_ROWS:
        raise SpecError(f"data = '{path}' has {len(lines) - 1:,} data rows; allowed at most "
                        f"{MAX_TISSUE_ROWS:,} (thin the test data first)")
    rows = list(csv.reader(io.StringIO("\n".join(lines))))
    header = [h.strip().lower() for h in rows[0]]
    found = {_COLS[h][0]: (j, _COLS[h][1], h) for j, h in enumerate(header) if h in _COLS}
    if "strain" in found and "stress" in found:
        xkey, ykey, kind = "strain", "stress", "engineering"
    elif "stretch" in found and "true_stress" in found:
        xkey, ykey, kind = "stretch", "true_stress", "true"
    else:
        raise SpecError(f"data = '{path}': header {rows[0]} lacks the columns; expected "
                        "strain,stress_mpa (engineering) or stretch,true_stress_mpa (true); "
                        "_kpa variants accepted")
    xs, ys = [], []
    for r, row in enumerate(rows[1:], start=2):
        vals = []
        for key in (xkey, ykey):
            j, scale, name = found[key]
            cell = row[j].strip() if j < len(row) else ""
            try:
                val = float(cell) * scale
            except ValueError:
                raise SpecError(f"data = '{path}', data row {r - 1}, column '{name}': "
                                f"{cell!r} is not a number") from None
            if not math.isfinite(val):
                raise SpecError(f"data = '{path}', data row {r - 1}, column '{name}': "
                                f"{cell!r} is not finite; expected a finite number")
            vals.append(val)
        xs.append(vals[0])
        ys.append(vals[1])
    x, y = np.array(xs), np.array(ys)
    if kind == "engineering":
        lam, sig = true_from_engineering(x, y)
    else:
        lam, sig = _stretch(x), y
    info = {"path": str(p), "kind": kind, "columns": [found[xkey][2], found[ykey][2]],
            "rows": int(len(x))}
    return lam, sig, info


def uniaxial_csv_text(strain: ArrayLike, stress: ArrayLike, *,
                      comments: list[str] | None = None) -> str:
    """CSV text with columns ``strain,stress_mpa`` (engineering), fixed
    decimals, optional ``#`` comment lines first."""
    e = finite_array("strain", strain, lo=-1.0, lo_open=True).reshape(-1)
    p = finite_array("stress", stress, unit="MPa").reshape(-1)
    out = io.StringIO()
    for c in comments or []:
        out.write(f"# {c}\n")
    out.write("strain,stress_mpa\n")
    for a, b in zip(e, p):
        out.write(f"{a:.6f},{b:.9f}\n")
    return out.getvalue()
