"""GP surrogates of several responses over a design box (thesis §3.4.2).

Inputs are scaled to the unit box, u = (x − lo)/(hi − lo) per variable, so the
roughness ω of eq. 3.26 is per unit range of each variable; predictions and
intervals are in the responses' own units (``*_mm``, ``*_deg``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import SpecError
from .gp import Z95, GaussianProcess

__all__ = ["Surrogate", "fit_surrogate"]


@dataclass
class Surrogate:
    """Gaussian-process models of ``responses`` over ``bounds``.

    Parameters
    ----------
    bounds : sequence of (lo, hi) — per variable, in its units
    responses : sequence of str — response names (columns of Y)
    mode : ``independent`` (one GP per response) | ``separable`` (eq. 3.33)
    nugget : False | True | float — see :class:`~tipgeo.optimize.gp.GaussianProcess`
    starts, seed : MLE starts and their seed
    variables : sequence of str — variable names (reports only)
    """

    bounds: list
    responses: list
    mode: str = "independent"
    nugget: bool | float = False
    starts: int = 12
    seed: int = 0
    variables: list = field(default_factory=list)
    models: list = field(default_factory=list, init=False, repr=False)

    def __post_init__(self):
        b = np.asarray(self.bounds, float).reshape(-1, 2)
        if not np.all(b[:, 1] > b[:, 0]):
            raise SpecError(f"bounds = {self.bounds!r}; allowed hi > lo for every variable")
        self._lo, self._span = b[:, 0], b[:, 1] - b[:, 0]
        if self.mode not in ("independent", "separable"):
            raise SpecError(f"mode = {self.mode!r} is not valid; expected one of: "
                            "independent, separable")
        self.responses = list(self.responses)
        self.variables = list(self.variables) or [f"x{k}" for k in range(len(b))]

    def unit(self, X) -> np.ndarray:
        """(m, d) inputs scaled to the unit box."""
        return (np.atleast_2d(np.asarray(X, float)) - self._lo) / self._span

    def fit(self, X, Y) -> Surrogate:
        """Fit by MLE on X (n, d; variables' units) and Y (n, q; responses' units)."""
        X = np.atleast_2d(np.asarray(X, float))
        Y = np.asarray(Y, float).reshape(len(X), -1)
        if Y.shape[1] != len(self.responses):
            raise SpecError(f"Y has {Y.shape[1]} columns for {len(self.responses)} responses")
        self.X_, self.Y_ = X, Y
        U = self.unit(X)
        kw = {"nugget": self.nugget, "starts": self.starts, "seed": self.seed}
        if self.mode == "separable":
            rank = np.linalg.matrix_rank(np.column_stack([np.ones(len(Y)), Y]))
            if rank < Y.shape[1] + 1:
                raise SpecError(
                    "surrogate.mode = 'separable': the responses are linearly dependent or "
                    "constant over the training set (Σ̂ of eq. 3.33 would be singular; e.g. "
                    "theta_max = 180 − theta_min); choose independent responses or "
                    "mode = 'independent'")
            self.models = [GaussianProcess(separable=True, **kw).fit(U, Y)]
        else:
            self.models = [GaussianProcess(**kw).fit(U, Y[:, j]) for j in range(Y.shape[1])]
        return self

    def predict(self, X, *, return_std: bool = False):
        """Mean (m, q) and, with ``return_std``, standard deviation (m, q)."""
        U = self.unit(X)
        if self.mode == "separable":
            return self.models[0].predict(U, return_std=return_std)
        outs = [m.predict(U, return_std=return_std) for m in self.models]
        if not return_std:
            return np.column_stack(outs)
        return np.column_stack([o[0] for o in outs]), np.column_stack([o[1] for o in outs])

    def interval95(self, X):
        """(lower, upper) of the 95 % interval (eq. 3.31–3.32), (m, q) each."""
        mean, std = self.predict(X, return_std=True)
        return mean - Z95 * std, mean + Z95 * std

    def loo(self) -> dict[str, dict[str, float]]:
        """Leave-one-out errors per response (ω kept, β̂ re-estimated).

        Returns
        -------
        name -> ``rmse`` and ``max_abs`` (response units), ``nrmse`` (rmse /
        standard deviation of the training responses; < 0.1 is a good model),
        ``coverage95`` (fraction of points inside their LOO 95 % interval).
        """
        if self.mode == "separable":
            res, std = self.models[0].loo()
        else:
            pairs = [m.loo() for m in self.models]
            res = np.column_stack([p[0] for p in pairs])
            std = np.column_stack([p[1] for p in pairs])
        out = {}
        for j, name in enumerate(self.responses):
            r = res[:, j]
            sd_y = float(np.std(self.Y_[:, j]))
            rmse = float(np.sqrt(np.mean(r ** 2)))
            out[name] = {"rmse": rmse, "max_abs": float(np.max(np.abs(r))),
                         "nrmse": rmse / sd_y if sd_y > 0 else float("nan"),
                         "coverage95": float(np.mean(np.abs(r) <= Z95 * std[:, j]))}
        self.loo_residuals_ = res
        return out

    def to_dict(self) -> dict[str, Any]:
        """Hyperparameters per model: ω (unit-box inputs), ℓ, δ, β̂, Σ̂."""
        from .gp import length_scales

        models = []
        names = [self.responses] if self.mode == "separable" else [[r] for r in self.responses]
        for m, resp in zip(self.models, names):
            f = m.fit_
            models.append({"responses": resp, "omega": f.omega.tolist(),
                           "length_scales_unit": length_scales(f.omega).tolist(),
                           "length_scales": (length_scales(f.omega) * self._span).tolist(),
                           "nugget": f.nugget, "beta": f.beta.tolist(),
                           "sigma": f.sigma.tolist(), "neg_log_likelihood_L": f.objective})
        return {"mode": self.mode, "variables": self.variables,
                "bounds": np.column_stack([self._lo, self._lo + self._span]).tolist(),
                "models": models}


def fit_surrogate(sweep, *, responses=None) -> Surrogate:
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
                  starts=sg["starts"], seed=sg["seed"], variables=[v.name for v in cfg.variables])
    return s.fit(sweep.X[ok], sweep.responses(names)[ok])
