r"""Gaussian-process surrogate of thesis §3.4.1 (eq. 3.24–3.33).

Model (constant mean, Gaussian correlation by default)::

    y(x) = β + ξ₀(x),   cov(ξ₀(x), ξ₀(x′)) = σ² r(x, x′),
    h² = Σᵢ 10^ωᵢ (xᵢ − x′ᵢ)²,
    r = exp(−h²)                                    gaussian  (eq. 3.26)
    r = (1 + √7 h + 14h²/5 + 7√7h³/15) exp(−√7 h)   matern72
    r = (1 + √5 h + 5h²/3) exp(−√5 h)               matern52
    r = (1 + √3 h) exp(−√3 h)                       matern32

The Matérn correlations (ν = 7/2, 5/2, 3/2; paths three, two and one times
differentiable) are options beside the thesis's Gaussian (infinitely
differentiable): ν = 5/2 and 3/2 for responses with kinks (a min or max over
the edge changes where it is attained), ν = 7/2 for smooth responses whose
Gaussian intervals are too narrow between the training points; they share
ω, so ℓᵢ = 10^(−ωᵢ/2) is their length scale (:func:`length_scales`).

fitted by maximum likelihood with β and σ² profiled out (eq. 3.28–3.29), so
that ω (and the nugget δ, when it is fitted) minimise

    L(ω, δ) = n log σ̂² + log |C_δ|,   C_δ = C + δ I              (eq. 3.30)

from several starting points (§3.4.1: "the optimization is done numerous times
with different initial guesses"; ωᵢ ∈ [−20, 5]): a bounded Nelder–Mead search
from each Latin-hypercube start, polished by L-BFGS-B with the analytic
gradient dL = tr(W dC), W = q C⁻¹ − A Σ̂⁻¹ Aᵀ, A = C⁻¹(Y − 1β̂). Correlation
matrices too ill-conditioned to trust are excluded (``min_rcond``), which is
where smooth, noise-free responses put the optimum. Predictions are eq. 3.31
and their variance eq. 3.32, *including* the term for the uncertainty of β̂;
the 95 % interval is ŷ ± 1.96 sd.

Several responses (q of them) are fitted either as independent GPs (each with
its own ω, β, σ²) or jointly with the separable covariance Σ ⊗ r(x, x′) of
eq. 3.33 (one ω for all, a constant mean per response, Σ̂ the q × q process
covariance): then L = n log |Σ̂| + q log |C_δ|.

Inputs: the GP works on whatever coordinates it is given; the sweep passes
the design variables scaled to the unit box, u = (x − lo)/(hi − lo), so ω is
per unit range of each variable. Outputs keep their own units.

Why not scikit-learn's ``GaussianProcessRegressor``: its mean is zero (or the
sample mean with ``normalize_y``), not the generalised-least-squares β̂ of eq.
3.28, and its predictive variance lacks the β̂ term of eq. 3.32; it has no
separable multi-response form (eq. 3.33). The kernel itself is the same — an
anisotropic RBF with length scales ℓᵢ = 1/√(2·10^ωᵢ) (:func:`length_scales`) —
and the tests check this model against scikit-learn's on that mapping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, overload

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from ..tolerances import tol

__all__ = ["GaussianProcess", "FitResult", "KERNELS", "length_scales", "Z95"]

#: Correlation families (see the module docstring); ``gaussian`` is eq. 3.26.
KERNELS = ("gaussian", "matern72", "matern52", "matern32")

#: Two-sided 95 % normal quantile (eq. 3.31–3.32 intervals).
Z95 = 1.959963984540054
_LN10 = math.log(10.0)


def length_scales(omega: ArrayLike, kernel: str = "gaussian") -> FloatArray:
    """Length scales ℓᵢ equivalent to the roughness ω, as scikit-learn's kernels
    define them (same units as the GP's inputs).

    Gaussian: ``exp(−10^ω Δ²) = exp(−Δ² / (2ℓ²))``, ℓ = 1/√(2·10^ω) (RBF);
    Matérn: h = |Δ|/ℓ, ℓ = 10^(−ω/2).
    """
    w: FloatArray = 10.0 ** np.asarray(omega, float)
    return 1.0 / np.sqrt(2.0 * w) if kernel == "gaussian" else 1.0 / np.sqrt(w)


def correlation(h2: FloatArray, kernel: str = "gaussian") -> tuple[FloatArray, FloatArray]:
    """Correlation r and its derivative dr/d(h²) at squared scaled distances h².

    Parameters
    ----------
    h2 : float array — h² = Σᵢ 10^ωᵢ Δᵢ² (dimensionless)
    kernel : one of :data:`KERNELS`

    Returns
    -------
    r, dr_dh2 : arrays of h2's shape
    """
    h2 = np.maximum(h2, 0.0)
    if kernel == "gaussian":
        r = np.exp(-h2)
        return r, -r
    h = np.sqrt(h2)
    if kernel == "matern72":
        s7h = math.sqrt(7.0) * h
        e = np.exp(-s7h)
        r = (1.0 + s7h + 0.4 * s7h ** 2 + s7h ** 3 / 15.0) * e
        # dr/ds = −(s/15)(3 + 3s + s²)e^(−s), ds/dh² = 7/(2s)
        return r, -(7.0 / 30.0) * (3.0 + 3.0 * s7h + s7h ** 2) * e
    if kernel == "matern52":
        s5h = math.sqrt(5.0) * h
        e = np.exp(-s5h)
        return (1.0 + s5h + 5.0 * h2 / 3.0) * e, -(5.0 / 6.0) * (1.0 + s5h) * e
    if kernel == "matern32":
        s3h = math.sqrt(3.0) * h
        e = np.exp(-s3h)
        return (1.0 + s3h) * e, -1.5 * e
    raise SpecError(f"kernel = {kernel!r} is not valid; expected one of: {', '.join(KERNELS)}")


@dataclass(frozen=True)
class FitResult:
    """Hyperparameters and profiled estimates of a fitted GP.

    Attributes
    ----------
    omega : (d,) float — roughness parameters ω (eq. 3.26), log10 units
    nugget : float — δ (0 when off); the noise variance is δ·σ̂²
    beta : (q,) float — constant means β̂ (eq. 3.28), response units
    sigma : (q, q) float — process covariance Σ̂ (σ̂² when q = 1, eq. 3.29)
    objective : float — L at the optimum (eq. 3.30; lower is better)
    starts : int — optimiser starts tried
    """

    omega: FloatArray
    nugget: float
    beta: FloatArray
    sigma: FloatArray
    objective: float
    starts: int


@dataclass
class GaussianProcess:
    """Constant-mean GP with the Gaussian correlation of eq. 3.26 (or a Matérn).

    Parameters
    ----------
    kernel : str
        Correlation family, one of :data:`KERNELS` (default ``gaussian``,
        eq. 3.26).
    nugget : bool or float
        ``False`` (default): interpolate (δ = 0). A number: that δ, fixed.
        ``True``: δ fitted by MLE with log10 δ in ``nugget_bounds``. δ is
        relative to σ²: C_δ = C + δ I, so the noise variance is δ·σ̂².
    separable : bool
        Fit several responses (Y of shape (n, q)) jointly with the separable
        covariance Σ ⊗ r of eq. 3.33: one ω, a mean per response. Otherwise Y
        must be one response; independent models are one object each.
    starts : int
        MLE starting points (≥ 1), spread over ``start_box`` by a Latin
        hypercube; the best optimum is kept.
    omega_bounds : (lo, hi)
        Search range of every ωᵢ (thesis: [−20, 5]).
    start_box : (lo, hi)
        Where the starting ω are drawn (inputs scaled to a unit box make
        [−2, 3] the plausible range).
    nugget_bounds : (lo, hi)
        log10 δ range when the nugget is fitted.
    min_rcond : float
        Correlation matrices whose estimated reciprocal condition number falls
        below this are rejected during MLE. For smooth, noise-free responses the
        likelihood keeps improving towards ever smoother models until C is
        numerically singular; the MLE then sits on this bound (a constrained
        MLE). 1e-12 keeps interpolation round-off near 1e-11 of the response
        and the LOO intervals honest on the helical study.
    seed : int
        Seed of the starting points (the fit is deterministic).
    """

    nugget: bool | float = False
    separable: bool = False
    kernel: str = "gaussian"
    starts: int = 12
    omega_bounds: tuple[float, float] = (-20.0, 5.0)
    start_box: tuple[float, float] = (-2.0, 3.0)
    nugget_bounds: tuple[float, float] = (-12.0, 0.0)
    min_rcond: float = tol.gp_min_rcond
    seed: int = 0
    fit_: FitResult | None = field(default=None, init=False, repr=False)
    # set by fit/set_params: the training set, its pairwise squared
    # differences per input (d, n, n), and the factorisation at the fit
    X_: FloatArray = field(init=False, repr=False, compare=False)
    Y_: FloatArray = field(init=False, repr=False, compare=False)
    _D: FloatArray = field(init=False, repr=False, compare=False)
    _vector: bool = field(default=False, init=False, repr=False, compare=False)
    _cf: tuple[FloatArray, bool] = field(init=False, repr=False, compare=False)
    _Ci1: FloatArray = field(init=False, repr=False, compare=False)
    _A: FloatArray = field(init=False, repr=False, compare=False)
    _one_Ci1: float = field(default=0.0, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.nugget, bool):
            pass
        elif isinstance(self.nugget, (int, float)) and math.isfinite(self.nugget) \
                and 0 <= self.nugget < 1:
            self.nugget = float(self.nugget)
        else:
            raise SpecError(f"nugget = {self.nugget!r} is not valid; allowed false, true or a "
                            "number 0 ≤ δ < 1")
        if self.kernel not in KERNELS:
            raise SpecError(f"kernel = {self.kernel!r} is not valid; expected one of: "
                            f"{', '.join(KERNELS)}")
        if not isinstance(self.starts, int) or isinstance(self.starts, bool) \
                or not 1 <= self.starts <= 1000:
            raise SpecError(f"starts = {self.starts!r} is out of range; allowed an integer "
                            "1–1000")

    # -- fitting ----------------------------------------------------------------
    def fit(self, X: ArrayLike, Y: ArrayLike, *, init: ArrayLike | None = None) -> GaussianProcess:
        """Fit by maximum likelihood (eq. 3.27–3.30).

        Parameters
        ----------
        X : (n, d) float — training inputs (any consistent units)
        Y : (n,) or (n, q) float — training responses
        init : (k, d) float, optional — extra starting ω (e.g. a previous fit's,
            when points were added), tried before the ``starts`` random ones

        Returns
        -------
        self
        """
        from scipy.optimize import minimize
        from scipy.stats import qmc

        self._prepare(X, Y)
        d = self.X_.shape[1]
        fit_nugget = self.nugget is True
        lo, hi = self.omega_bounds
        bounds = [(lo, hi)] * d + ([tuple(self.nugget_bounds)] if fit_nugget else [])
        lhs = qmc.LatinHypercube(d + fit_nugget, seed=self.seed)
        box = np.array([self.start_box] * d + ([(-8.0, -2.0)] if fit_nugget else []))
        pts = box[:, 0] + lhs.random(self.starts) * (box[:, 1] - box[:, 0])
        if init is not None:
            w0 = np.clip(np.atleast_2d(np.asarray(init, float)), lo, hi)
            if fit_nugget:
                w0 = np.column_stack([w0, np.full(len(w0), -5.0)])
            pts = np.vstack([w0, pts])
        best = None
        nd = len(bounds)
        for p0 in pts:
            # a start in the singular (too smooth) region: roughen until C is usable
            while self._objective(p0, False) >= _BAD and np.any(p0[:d] < hi - 1.0):
                p0[:d] = np.minimum(p0[:d] + 1.0, hi)
            # Nelder–Mead first: the likelihood of smooth, noise-free data keeps
            # falling towards smoother models until C becomes singular, and a
            # simplex slides along that wall where a gradient method's line
            # search stops; then a gradient polish for interior optima.
            res = minimize(self._objective, p0, args=(False,), method="Nelder-Mead",
                           bounds=bounds, options={"xatol": tol.gp_xatol, "fatol": tol.gp_fatol,
                                                   "maxfev": 200 * nd})
            pol = minimize(self._objective, res.x, jac=True, method="L-BFGS-B", bounds=bounds)
            if pol.fun < res.fun:
                res = pol
            if best is None or res.fun < best.fun:
                best = res
        if best is None or not np.isfinite(best.fun) or best.fun >= _BAD:
            raise SpecError("the GP likelihood could not be evaluated at any starting point: "
                            "the training inputs repeat or the responses are degenerate")
        omega = best.x[:d]
        delta = 10.0 ** best.x[d] if fit_nugget else (0.0 if self.nugget is False
                                                        else float(self.nugget))
        self._set(omega, delta)
        return self

    def _corr(self, omega: FloatArray, delta: float) -> tuple[FloatArray, FloatArray]:
        """C_δ at ω and dr/dh² (n × n each)."""
        C, dC = correlation(np.tensordot(10.0 ** omega, self._D, axes=1), self.kernel)
        if delta:
            C = C + delta * np.eye(len(C))
        return C, dC

    def _delta(self, theta: FloatArray) -> float:
        d = self.X_.shape[1]
        if self.nugget is True:
            return float(10.0 ** theta[d])
        return 0.0 if self.nugget is False else float(self.nugget)

    def _objective(self, theta: FloatArray, grad: bool = True) -> Any:
        """L(ω, δ) of eq. 3.30 (separable: eq. 3.33 form) and, with ``grad``, its
        gradient."""
        d = self.X_.shape[1]
        r = self._profile(theta[:d], self._delta(theta), grad=grad)
        if not grad:
            return r[0]
        L, g_omega, g_delta = r
        assert g_omega is not None and g_delta is not None  # grad asked for
        if self.nugget is True:
            return L, np.append(g_omega, g_delta)
        return L, g_omega

    def _profile(self, omega: FloatArray, delta: float, *, keep: bool = False,
                 grad: bool = True) -> tuple[float, FloatArray | None, float | None]:
        """L, dL/dω and dL/dlog10 δ at (ω, δ); β̂ and Σ̂ profiled out."""
        from scipy.linalg import lapack

        n, q = self.Y_.shape
        d = len(omega)
        bad = (_BAD, np.zeros(d), 0.0)
        C, dC = self._corr(omega, delta)
        Lc, info = lapack.dpotrf(C, lower=1, clean=1)
        if info != 0:
            return bad
        rcond, info = lapack.dpocon(Lc, np.abs(C).sum(0).max(), uplo="L")
        if info != 0 or rcond < self.min_rcond:
            return bad
        B, _ = lapack.dpotrs(Lc, np.column_stack([np.ones(n), self.Y_]), lower=1)
        Ci1, CiY = B[:, 0], B[:, 1:]
        s1 = Ci1.sum()
        beta = CiY.sum(0) / s1  # eq. 3.28
        A = CiY - np.outer(Ci1, beta)  # C⁻¹(Y − 1β̂)
        R = self.Y_ - beta
        S = R.T @ A / n  # Σ̂ (q × q), eq. 3.29
        sign, logdetS = np.linalg.slogdet(S)
        if sign <= 0 or not np.isfinite(logdetS):
            return bad
        L = float(n * logdetS + q * 2.0 * np.log(np.diag(Lc)).sum())
        if keep:
            self._cf, self._Ci1, self._A, self._one_Ci1 = (Lc, True), Ci1, A, float(s1)
            self.fit_ = FitResult(omega=np.array(omega, float), nugget=float(delta),
                                  beta=np.asarray(beta, float), sigma=S, objective=L,
                                  starts=self.starts)
            return L, np.zeros(d), 0.0
        if not grad:
            return L, None, None
        # dL = tr(W dC) with W = q C⁻¹ − A Σ̂⁻¹ Aᵀ (β̂, Σ̂ at their optimum)
        Ci, _ = lapack.dpotrs(Lc, np.eye(n), lower=1)
        W = q * Ci - A @ np.linalg.solve(S, A.T)
        g = np.array([np.sum(W * (_LN10 * 10.0 ** omega[k] * self._D[k] * dC))
                      for k in range(d)])
        return L, g, float(_LN10 * delta * np.trace(W))

    def _set(self, omega: FloatArray, delta: float) -> None:
        L, _, _ = self._profile(np.asarray(omega, float), float(delta), keep=True)
        if L >= _BAD:
            raise SpecError(f"omega = {np.round(omega, 4).tolist()}, nugget = {delta:.3g}: "
                            "the correlation matrix is singular or too ill-conditioned "
                            f"(reciprocal condition < {self.min_rcond:g}); add a nugget")

    def _prepare(self, X: ArrayLike, Y: ArrayLike) -> None:
        Xa = np.asarray(X, float)
        Ya = np.asarray(Y, float)
        if Xa.ndim != 2:
            raise SpecError(f"X has shape {Xa.shape}; expected (n, d)")
        self._vector = Ya.ndim == 1
        Ya = Ya.reshape(len(Ya), -1)
        n = len(Xa)
        if len(Ya) != n:
            raise SpecError(f"X has {n} rows but Y has {len(Ya)}; expected the same")
        if n < 2:
            raise SpecError(f"{n} training point(s); a GP needs at least 2")
        if not (np.all(np.isfinite(Xa)) and np.all(np.isfinite(Ya))):
            raise SpecError("X or Y holds NaN or infinity; drop failed points first")
        if Ya.shape[1] > 1 and not self.separable:
            raise SpecError(f"Y has {Ya.shape[1]} responses; fit one GaussianProcess per "
                            "response, or pass separable=True (eq. 3.33)")
        self.X_, self.Y_ = Xa, Ya
        # pairwise squared differences per input, shape (d, n, n)
        self._D = (Xa[:, None, :] - Xa[None, :, :]).transpose(2, 0, 1) ** 2

    def set_params(self, X: ArrayLike, Y: ArrayLike, omega: ArrayLike,
                   nugget: float = 0.0) -> GaussianProcess:
        """Condition on (X, Y) with given ω and δ (no MLE); β̂ and Σ̂ profiled.

        Parameters
        ----------
        X : (n, d) float; Y : (n,) or (n, q) float
        omega : (d,) float — roughness (eq. 3.26); nugget : float — δ ≥ 0
        """
        self._prepare(X, Y)
        self._set(np.asarray(omega, float).reshape(self.X_.shape[1]), float(nugget))
        return self

    # -- prediction ---------------------------------------------------------------
    def _check_fitted(self) -> FitResult:
        """The fit, or a SpecError when there is none yet."""
        if self.fit_ is None:
            raise SpecError("the GP is not fitted; call fit(X, Y) first")
        return self.fit_

    @property
    def fitted(self) -> FitResult:
        """The fit's hyperparameters and estimates (a SpecError when the GP is
        not fitted yet)."""
        return self._check_fitted()

    @overload
    def predict(self, Xs: ArrayLike, *, return_std: Literal[False] = False,
                noise: bool = False) -> FloatArray: ...

    @overload
    def predict(self, Xs: ArrayLike, *, return_std: Literal[True],
                noise: bool = False) -> tuple[FloatArray, FloatArray]: ...

    def predict(self, Xs: ArrayLike, *, return_std: bool = False,
                noise: bool = False) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Predictive mean (eq. 3.31) and standard deviation (√ of eq. 3.32).

        Parameters
        ----------
        Xs : (m, d) float — inputs, same coordinates as the training X

        Returns
        -------
        mean : (m,) or (m, q) float
        std : same shape, when ``return_std`` — of the latent response, or
            with ``noise`` of a new observation (the nugget's noise variance
            δ·σ̂² added; the same as the latent one when δ = 0)
        """
        from scipy.linalg import cho_solve

        f = self._check_fitted()
        Xs = np.atleast_2d(np.asarray(Xs, float))
        diff2 = (Xs[:, None, :] - self.X_[None, :, :]) ** 2  # (m, n, d)
        r, _ = correlation(diff2 @ (10.0 ** f.omega), self.kernel)  # (m, n)
        mean = f.beta + r @ self._A
        if self._vector:
            mean = mean[:, 0]
        if not return_std:
            return mean
        Cir = cho_solve(self._cf, r.T)  # (n, m)
        h = 1.0 - self._Ci1 @ r.T
        unit = 1.0 - np.einsum("mn,nm->m", r, Cir) + h ** 2 / self._one_Ci1
        if noise:
            unit = unit + f.nugget
        var = np.maximum(unit, 0.0)[:, None] * np.diag(f.sigma)[None, :]
        std = np.sqrt(var)
        return mean, (std[:, 0] if self._vector else std)

    def covariance_with(self, Xs: ArrayLike,
                        x0: ArrayLike) -> tuple[FloatArray, FloatArray, float]:
        """Posterior (latent) variances at ``Xs`` and covariances with one
        point ``x0``, per unit σ̂² (multiply by the process variance Σ̂ of a
        response, or aᵀΣ̂a for a linear combination of responses): eq. 3.32
        generalised to two points, β̂'s uncertainty included,

            c(x, x′) = r(x, x′) − r(x)ᵀC⁻¹r(x′) + h(x) h(x′) / 1ᵀC⁻¹1,
            h(x) = 1 − 1ᵀC⁻¹r(x).

        Returns (var (m,), cov (m,), var0 float), all per unit σ̂²."""
        from scipy.linalg import cho_solve

        f = self._check_fitted()
        Xs = np.atleast_2d(np.asarray(Xs, float))
        x0 = np.atleast_2d(np.asarray(x0, float))
        w = 10.0 ** f.omega
        P = np.vstack([Xs, x0])
        r, _ = correlation(((P[:, None, :] - self.X_[None, :, :]) ** 2) @ w, self.kernel)
        Cir = cho_solve(self._cf, r.T)                     # (n, m + 1)
        h = 1.0 - self._Ci1 @ r.T                         # (m + 1,)
        r0, _ = correlation(((P - x0) ** 2) @ w, self.kernel)   # (m + 1,)
        quad = np.einsum("mn,nm->m", r, Cir)
        var = 1.0 - quad + h ** 2 / self._one_Ci1
        cov = r0 - r @ Cir[:, -1] + h * h[-1] / self._one_Ci1
        var = np.maximum(var, 0.0)
        return var[:-1], cov[:-1], float(var[-1])

    def interval(self, Xs: ArrayLike, level: float = 0.95) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) bounds of the two-sided ``level`` interval (normal)."""
        from scipy.stats import norm

        mean, std = self.predict(Xs, return_std=True)
        z = Z95 if level == 0.95 else float(norm.ppf(0.5 + level / 2))
        return mean - z * std, mean + z * std

    def loo(self) -> tuple[FloatArray, FloatArray]:
        """Leave-one-out residuals with ω, δ kept, β̂ re-estimated (closed form).

        Uses the top-left block Q of the inverse of [[C, 1], [1ᵀ, 0]]: the
        prediction error at xᵢ from the other n − 1 points is (Q y)ᵢ / Qᵢᵢ and
        its variance σ̂²/Qᵢᵢ (of the observation, nugget included).

        Returns
        -------
        residuals : (n,) or (n, q) float — y − ŷ₋ᵢ (response units)
        std : same shape — LOO predictive standard deviations
        """
        from scipy.linalg import cho_solve

        f = self._check_fitted()
        n = len(self.X_)
        Ci = cho_solve(self._cf, np.eye(n))
        Q = Ci - np.outer(self._Ci1, self._Ci1) / self._one_Ci1
        qd = np.diag(Q)
        res = (Q @ self.Y_) / qd[:, None]
        std = np.sqrt(np.outer(1.0 / qd, np.diag(f.sigma)))
        if self._vector:
            return res[:, 0], std[:, 0]
        return res, std


_BAD = 1e300
