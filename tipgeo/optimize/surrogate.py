"""GP surrogates of several responses over a design box (thesis §3.4.2).

Inputs are scaled to the unit box, u = (x − lo)/(hi − lo) per variable, so the
roughness ω of eq. 3.26 is per unit range of each variable; predictions and
intervals are in the responses' own units (``*_mm``, ``*_deg``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError
from .gp import KERNELS, Z95, GaussianProcess

if TYPE_CHECKING:
    from .sweep import SweepResult

__all__ = ["Surrogate", "fit_surrogate", "loo_log_density"]


@dataclass
class Surrogate:
    """Gaussian-process models of ``responses`` over ``bounds``.

    Parameters
    ----------
    bounds : sequence of (lo, hi) — per variable, in its units
    responses : sequence of str — response names (columns of Y)
    mode : ``independent`` (one GP per response) | ``separable`` (eq. 3.33)
    nugget : False | True | float — see :class:`~tipgeo.optimize.gp.GaussianProcess`
        (with a nugget, intervals are for a new analysis: its noise δ·σ̂² is
        included, as in the LOO intervals)
    kernel : str
        Correlation family of every model (``gaussian``, eq. 3.26;
        ``matern72``; ``matern52``; ``matern32``), or ``auto``: each response (the one
        separable model) gets the family with the highest leave-one-out log
        predictive density Σᵢ log N(yᵢ; ŷ₋ᵢ, s₋ᵢ²) — a proper scoring rule, which
        rewards intervals as wide as the errors, neither wider nor narrower;
        ties (within 1e-9) go to the earlier family in that list.
    response_kernels : dict, optional
        Per-response exceptions to ``kernel`` (response name → family or
        ``auto``), e.g. ``{"theta_max_deg": "matern72"}`` for one smooth
        response among kinked ones. Independent mode only (the separable model
        has one correlation for all responses).
    starts, seed : MLE starts and their seed
    variables : sequence of str — variable names (reports only)
    calibrate : bool
        Scale each response's predictive standard deviation (σ̂ of eq. 3.29,
        i.e. σ̂² by the square) so that its leave-one-out 95 % intervals hold
        the share of the training points nearest 95 % that leaves at least one
        outside (round(0.95 n), at most n − 1): the factor is set halfway
        between the k-th and (k+1)-th smallest |LOO residual| / (1.96 · LOO sd).
        Noise-free, smooth responses drive the MLE to the edge of numerical
        singularity, where σ̂² (hence every interval) is off by a response-
        dependent factor; this is the cross-validation (jackknife) calibration
        of that one factor. ω, β̂ and the mean predictions are unchanged. The
        LOO coverage of calibrated intervals is then near 95 % by
        construction: judge them on points outside the training set.
    """

    bounds: list[tuple[float, float]]
    responses: list[str]
    mode: str = "independent"
    nugget: bool | float = False
    kernel: str = "gaussian"
    response_kernels: dict[str, str] = field(default_factory=dict)
    starts: int = 12
    seed: int = 0
    variables: list[str] = field(default_factory=list)
    calibrate: bool = False
    models: list[GaussianProcess] = field(default_factory=list, init=False, repr=False)
    # set by __post_init__ and fit: the box (lo, span per variable), the family
    # per response, the training set (variables', responses' units), the
    # interval scale per response and the last LOO residuals and sd
    _lo: FloatArray = field(init=False, repr=False, compare=False)
    _span: FloatArray = field(init=False, repr=False, compare=False)
    kernels_by_response: dict[str, str] = field(default_factory=dict, init=False, repr=False,
                                                compare=False)
    X_: FloatArray = field(init=False, repr=False, compare=False)
    Y_: FloatArray = field(init=False, repr=False, compare=False)
    scale_: FloatArray = field(init=False, repr=False, compare=False)
    loo_residuals_: FloatArray = field(init=False, repr=False, compare=False)
    loo_std_: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        b = np.asarray(self.bounds, float).reshape(-1, 2)
        if not np.all(b[:, 1] > b[:, 0]):
            raise SpecError(f"bounds = {self.bounds!r}; allowed hi > lo for every variable")
        self._lo, self._span = b[:, 0], b[:, 1] - b[:, 0]
        if self.mode not in ("independent", "separable"):
            raise SpecError(f"mode = {self.mode!r} is not valid; expected one of: "
                            "independent, separable")
        if self.kernel not in (*KERNELS, "auto"):
            raise SpecError(f"kernel = {self.kernel!r} is not valid; expected one of: "
                            f"{', '.join((*KERNELS, 'auto'))}")
        self.responses = list(self.responses)
        self.kernels_by_response = {r: self.kernel for r in self.responses}
        for name, fam in dict(self.response_kernels or {}).items():
            if name not in self.responses:
                raise SpecError(f"response_kernels = {{{name!r}: ...}} names no modelled "
                                "response; expected one of: " + ", ".join(self.responses))
            if fam not in (*KERNELS, "auto"):
                raise SpecError(f"response_kernels[{name!r}] = {fam!r} is not valid; expected "
                                f"one of: {', '.join((*KERNELS, 'auto'))}")
            self.kernels_by_response[name] = fam
        if self.response_kernels and self.mode == "separable":
            raise SpecError("response_kernels (per-response families) need mode = "
                            "'independent'; the separable model (eq. 3.33) has one correlation "
                            "for all responses")
        self.variables = list(self.variables) or [f"x{k}" for k in range(len(b))]

    def unit(self, X: ArrayLike) -> FloatArray:
        """(m, d) inputs scaled to the unit box."""
        U: FloatArray = (np.atleast_2d(np.asarray(X, float)) - self._lo) / self._span
        return U

    def fit(self, X: ArrayLike, Y: ArrayLike, *, warm: Surrogate | None = None) -> Surrogate:
        """Fit by MLE on X (n, d; variables' units) and Y (n, q; responses' units).

        ``warm``: a surrogate fitted before to part of these points; its ω
        start each model's search, before ``starts`` random starts."""
        X = np.atleast_2d(np.asarray(X, float))
        Y = np.asarray(Y, float).reshape(len(X), -1)
        if Y.shape[1] != len(self.responses):
            raise SpecError(f"Y has {Y.shape[1]} columns for {len(self.responses)} responses")
        self.X_, self.Y_ = X, Y
        U = self.unit(X)
        kw: dict[str, Any] = {"nugget": self.nugget, "starts": self.starts, "seed": self.seed}
        if self.mode == "separable":
            rank = np.linalg.matrix_rank(np.column_stack([np.ones(len(Y)), Y]))
            if rank < Y.shape[1] + 1:
                raise SpecError(
                    "surrogate.mode = 'separable': the responses are linearly dependent or "
                    "constant over the training set (Σ̂ of eq. 3.33 would be singular; e.g. "
                    "theta_max = 180 − theta_min); choose independent responses or "
                    "mode = 'independent'")
            self.models = [self._fit_one(U, Y, None if warm is None else warm.models[0],
                                         self.kernel, separable=True, **kw)]
        else:
            self.models = [self._fit_one(U, Y[:, j], None if warm is None else warm.models[j],
                                         self.kernels_by_response[name], **kw)
                           for j, name in enumerate(self.responses)]
        self.scale_ = np.ones(Y.shape[1])
        if self.calibrate:
            res, std = self._loo_raw()
            self.scale_ = np.array([_interval_scale(res[:, j], std[:, j])
                                    for j in range(Y.shape[1])])
        return self

    def _fit_one(self, U: FloatArray, y: FloatArray, warm: GaussianProcess | None,
                 kernel: str, **kw: Any) -> GaussianProcess:
        """One model of family ``kernel``; with ``'auto'`` the family of highest
        LOO log predictive density (a warm start's own family is tried with its ω;
        a family must beat the best so far by ``tol.kernel_choice``)."""
        from ..tolerances import tol

        fams = KERNELS if kernel == "auto" else (kernel,)
        best: GaussianProcess | None = None
        best_lpd = -np.inf
        for fam in fams:
            init = ([warm.fit_.omega] if warm is not None and warm.fit_ is not None
                    and warm.kernel == fam else None)
            m = GaussianProcess(kernel=fam, **kw).fit(U, y, init=init)
            if len(fams) == 1:
                return m
            lpd = loo_log_density(*m.loo())
            if best is None or lpd > best_lpd + tol.kernel_choice:
                best, best_lpd = m, lpd
        assert best is not None  # KERNELS is not empty
        return best

    def _loo_raw(self) -> tuple[FloatArray, FloatArray]:
        if self.mode == "separable":
            return self.models[0].loo()
        pairs = [m.loo() for m in self.models]
        return np.column_stack([p[0] for p in pairs]), np.column_stack([p[1] for p in pairs])

    @overload
    def predict(self, X: ArrayLike, *, return_std: Literal[False] = False) -> FloatArray: ...

    @overload
    def predict(self, X: ArrayLike, *,
                return_std: Literal[True]) -> tuple[FloatArray, FloatArray]: ...

    def predict(self, X: ArrayLike, *,
                return_std: bool = False) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Mean (m, q) and, with ``return_std``, standard deviation (m, q) of a
        new analysis at X (the nugget's noise included when there is one)."""
        U = self.unit(X)
        if not return_std:
            if self.mode == "separable":
                return self.models[0].predict(U, noise=True)
            return np.column_stack([m.predict(U, noise=True) for m in self.models])
        if self.mode == "separable":
            mean, std = self.models[0].predict(U, return_std=True, noise=True)
            return mean, std * self.scale_
        outs = [m.predict(U, return_std=True, noise=True) for m in self.models]
        return (np.column_stack([o[0] for o in outs]),
                np.column_stack([o[1] for o in outs]) * self.scale_)

    def interval95(self, X: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) of the 95 % interval (eq. 3.31–3.32), (m, q) each."""
        mean, std = self.predict(X, return_std=True)
        return mean - Z95 * std, mean + Z95 * std

    def loo(self) -> dict[str, dict[str, Any]]:
        """Leave-one-out errors per response (ω kept, β̂ re-estimated).

        Returns
        -------
        name -> ``rmse`` and ``max_abs`` (response units), ``nrmse`` (rmse /
        standard deviation of the training responses; < 0.1 is a good model),
        ``coverage95`` (fraction of points inside their LOO 95 % interval),
        ``log_density`` (Σᵢ log N(yᵢ; ŷ₋ᵢ, s₋ᵢ²), the LOO log predictive
        density; higher is better), ``kernel``, ``interval_scale``.
        """
        res, std = self._loo_raw()
        std = std * self.scale_
        out: dict[str, dict[str, Any]] = {}
        for j, name in enumerate(self.responses):
            r = res[:, j]
            sd_y = float(np.std(self.Y_[:, j]))
            rmse = float(np.sqrt(np.mean(r ** 2)))
            out[name] = {"rmse": rmse, "max_abs": float(np.max(np.abs(r))),
                         "nrmse": rmse / sd_y if sd_y > 0 else float("nan"),
                         "coverage95": float(np.mean(np.abs(r) <= Z95 * std[:, j])),
                         "log_density": loo_log_density(r, std[:, j]),
                         "kernel": self.kernels[j],
                         "interval_scale": float(self.scale_[j])}
        self.loo_residuals_, self.loo_std_ = res, std
        return out

    @property
    def kernels(self) -> list[str]:
        """Correlation family per response (after ``auto`` chose)."""
        if self.mode == "separable":
            return [self.models[0].kernel] * len(self.responses)
        return [m.kernel for m in self.models]

    def to_dict(self) -> dict[str, Any]:
        """Hyperparameters per model: ω (unit-box inputs), ℓ, δ, β̂, Σ̂."""
        from .gp import length_scales

        models = []
        names = [self.responses] if self.mode == "separable" else [[r] for r in self.responses]
        for m, resp in zip(self.models, names):
            f = m.fitted
            ls = length_scales(f.omega, m.kernel)
            models.append({"responses": resp, "kernel": m.kernel, "omega": f.omega.tolist(),
                           "length_scales_unit": ls.tolist(),
                           "length_scales": (ls * self._span).tolist(),
                           "nugget": f.nugget, "beta": f.beta.tolist(),
                           "sigma": f.sigma.tolist(), "neg_log_likelihood_L": f.objective})
        return {"mode": self.mode, "variables": self.variables, "kernel": self.kernel,
                "response_kernels": dict(self.response_kernels or {}),
                "calibrate": self.calibrate,
                "interval_scale": dict(zip(self.responses, self.scale_.tolist())),
                "bounds": np.column_stack([self._lo, self._lo + self._span]).tolist(),
                "models": models}


def loo_log_density(res: ArrayLike, std: ArrayLike) -> float:
    """Σᵢ log N(resᵢ; 0, stdᵢ²): the leave-one-out log predictive density of
    residuals ``res`` with predictive standard deviations ``std`` (same units)."""
    r = np.asarray(res, float)
    sd = np.maximum(np.asarray(std, float), np.finfo(float).tiny)
    return float(np.sum(-0.5 * (r / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi)))


def _interval_scale(res: FloatArray, std: FloatArray) -> float:
    """Factor on the LOO standard deviations that puts round(0.95 n) (at most
    n − 1) of the |residuals| inside their 95 % intervals (see Surrogate)."""
    z = np.sort(np.abs(res) / np.maximum(std, np.finfo(float).tiny)) / Z95
    n = len(z)
    if n < 2 or not np.all(np.isfinite(z)):
        return 1.0
    k = min(int(np.floor(0.95 * n + 0.5)), n - 1)
    c = 0.5 * (z[k - 1] + z[k]) if k >= 1 else z[0]
    return float(c) if c > 0 else 1.0


def fit_surrogate(sweep: SweepResult, *,
                  responses: Sequence[str] | None = None) -> Surrogate:
    """Fit the config's surrogate to a sweep's successful configurations.

    Parameters
    ----------
    sweep : SweepResult
    responses : names to model (default: ``surrogate.responses`` of the config)

    Raises
    ------
    SpecError
        Fewer than two successful configurations.
    """
    cfg = sweep.config
    sg = cfg.surrogate
    names = list(responses or sg["responses"])
    ok = sweep.ok
    if ok.sum() < 2:
        raise SpecError(f"sweep '{cfg.name}': {int(ok.sum())} of {len(ok)} configurations "
                        "succeeded; the surrogate needs at least 2 (see the failures)")
    s = Surrogate(bounds=cfg.bounds, responses=names, mode=sg["mode"], nugget=sg["nugget"],
                  kernel=sg.get("kernel", "gaussian"),
                  response_kernels={k: v for k, v in sg.get("response_kernels", {}).items()
                                    if k in names},
                  starts=sg["starts"], seed=sg["seed"], variables=[v.name for v in cfg.variables],
                  calibrate=sg.get("calibrate", False))
    return s.fit(sweep.X[ok], sweep.responses(names)[ok])
