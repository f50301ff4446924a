"""Objectives composed from GP-predicted responses, their optimisation over
the design box, and the check of an optimum on the real geometry.

An objective's terms are scaled by the training range of their response,
sₖ = (ŷₖ − minₖ)/(maxₖ − minₖ) for ``min`` terms and 1 − that for ``max``
terms, so that every term is 0 at its best training value and 1 at its worst,
whatever its unit. ``weighted`` minimises Σ wₖ sₖ / Σ wₖ (eq. 3.34 for one
term); ``pareto`` keeps the non-dominated predictions over the box and picks
the one nearest the ideal point (all sₖ = 0, distance weighted by wₖ).

Search: the GP mean is evaluated on a scrambled Sobol set of the box (plus
its corners and the training points), infeasible configurations (the spec
raises :class:`~tipgeo.errors.SpecError`) are dropped, and the best few are
polished with bounded L-BFGS-B; a Pareto front is refined by resampling
around its points at shrinking scales. Coordinates are the variables' units.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import ArrayLike, BoolArray, FloatArray
from ..errors import SpecError
from ..tolerances import tol
from .config import Objective, StudyConfig, Term

if TYPE_CHECKING:
    from .surrogate import Surrogate

__all__ = ["Optimum", "scaled_terms", "optimize_objective", "pareto_front", "verify_optimum",
           "term_summary", "optimum_region", "FLAT_EXTENT", "Feasible"]

#: A feasibility test: (m, d) configurations (the variables' units) -> (m,)
#: bool, True where the spec validates (:func:`~tipgeo.optimize.study.feasibility`).
Feasible = Callable[[FloatArray], BoolArray]

#: A region of designs indistinguishable from the optimum that spans at
#: least this share of a variable's range is flat along that variable.
FLAT_EXTENT = 0.25


@dataclass
class Optimum:
    """The optimum of one objective (coordinates in the variables' units).

    Attributes
    ----------
    objective : Objective
    x : (d,) float — the optimum
    value : float — objective value (scaled, see the module docstring)
    predicted, std : dict name -> float — GP mean and standard deviation there
    front : dict or None — ``pareto``: ``x`` (k, d) and ``terms`` (k, t) of the front
    search : dict — ``candidates`` (global sample size, corners and training
        points included) and ``starts`` (local L-BFGS-B searches from distinct,
        feasible candidates; ``pareto``: refinement rounds of the front)
    """

    objective: Objective
    x: FloatArray
    value: float
    predicted: dict[str, float]
    std: dict[str, float]
    front: dict[str, FloatArray] | None = None
    verified: dict[str, Any] | None = field(default=None)
    search: dict[str, int] = field(default_factory=dict)
    region: dict[str, Any] | None = field(default=None)


def _ranges(surrogate: Surrogate, names: list[str]) -> tuple[FloatArray, FloatArray]:
    idx = [surrogate.responses.index(n) for n in names]
    Y = surrogate.Y_[:, idx]
    lo, hi = Y.min(0), Y.max(0)
    span: FloatArray = np.where(hi > lo, hi - lo, 1.0)
    return lo, span


def scaled_terms(surrogate: Surrogate, objective: Objective, mean: FloatArray) -> FloatArray:
    """(m, t) scaled term values sₖ (0 best, 1 worst over the training set)."""
    names = [t.response for t in objective.terms]
    lo, span = _ranges(surrogate, names)
    cols = [surrogate.responses.index(n) for n in names]
    s = (mean[:, cols] - lo) / span
    flip = np.array([t.goal == "max" for t in objective.terms])
    out: FloatArray = np.where(flip, 1.0 - s, s)
    return out


def _weights(objective: Objective) -> FloatArray:
    w = np.array([t.weight for t in objective.terms], float)
    out: FloatArray = w / w.sum()
    return out


def pareto_front(F: ArrayLike) -> BoolArray:
    """(m,) bool — rows of F (m, t; all minimised) that no other row dominates."""
    F = np.asarray(F, float)
    keep = np.ones(len(F), bool)
    for start in range(0, len(F), 512):
        blk = F[start:start + 512]
        le = np.all(F[None, :, :] <= blk[:, None, :], axis=2)
        lt = np.any(F[None, :, :] < blk[:, None, :], axis=2)
        keep[start:start + 512] = ~np.any(le & lt, axis=1)
    return keep


def _feasible_front(U: FloatArray, S: FloatArray, check: Callable[[FloatArray], BoolArray],
                    most: int) -> tuple[FloatArray, FloatArray]:
    """The front of the *feasible* rows (at most ``most`` points, thinned
    evenly along the first term): the non-dominated rows are checked (``check``: unit
    points -> bool), the infeasible ones dropped and the front taken again
    among the rest, until every point of it is feasible. Only front points are
    checked, each once: where the GP's best predictions lie past the buildable
    boundary, the front peels back to it instead of being lost there. Empty
    when no row is feasible."""
    alive = np.ones(len(U), bool)
    known = np.zeros(len(U), bool)
    while alive.any():
        idx = np.flatnonzero(alive)
        front = idx[pareto_front(S[idx])]
        if len(front) > most:
            front = front[np.argsort(S[front, 0], kind="stable")[
                np.linspace(0, len(front) - 1, most).astype(int)]]
        todo = front[~known[front]]
        ok = np.asarray(check(U[todo]), bool) if len(todo) else np.ones(0, bool)
        alive[todo[~ok]] = False
        known[todo[ok]] = True
        if ok.all():
            return U[front], S[front]
    return U[:0], S[:0]


def optimize_objective(surrogate: Surrogate, objective: Objective, *,
                       feasible: Feasible | None = None,
                       candidates: int = 4096, polish: int = 6, refine: int = 4,
                       max_front: int = 200, seed: int = 0) -> Optimum:
    """Minimise an objective of the surrogate's predictions over its box.

    Parameters
    ----------
    surrogate : Surrogate (fitted)
    objective : Objective
    feasible : callable (m, d) -> (m,) bool, optional
        Which configurations exist (e.g. the spec validates); default: all.
    candidates : int — Sobol points of the global stage
    polish : int — best candidates refined by L-BFGS-B (``weighted``)
    refine : int — rounds of resampling around the front (``pareto``)
    max_front : int — front points kept (thinned evenly along the first term)
    seed : int

    Returns
    -------
    Optimum
    """
    from scipy.optimize import minimize
    from scipy.stats import qmc

    lo = surrogate._lo
    span = surrogate._span
    d = len(lo)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        U = qmc.Sobol(d, scramble=True, seed=seed).random(candidates)
    corners = (np.array(np.meshgrid(*[[0.0, 1.0]] * d)).reshape(d, -1).T if d <= 12
               else np.zeros((0, d)))
    U = np.vstack([U, corners, surrogate.unit(surrogate.X_)])
    X = lo + U * span
    w = _weights(objective)

    def value(u: FloatArray) -> FloatArray:
        m = surrogate.predict(lo + np.atleast_2d(u) * span)
        out: FloatArray = scaled_terms(surrogate, objective, m) @ w
        return out

    front = None
    best_x: FloatArray | None = None
    best_v = math.inf
    if objective.combine == "pareto":
        S = scaled_terms(surrogate, objective, surrogate.predict(X))

        def check(Uc: FloatArray) -> BoolArray:
            if feasible is None:
                return np.ones(len(Uc), bool)
            return np.asarray(feasible(lo + Uc * span), bool)

        # the front of the feasible candidates, thinned before it is refined:
        # where the whole box is the front (one variable, two conflicting
        # monotone terms) the 8-fold resampling of every candidate would make
        # the dominance test quadratic in ~37 000 points
        Uf, Sf = _feasible_front(U, S, check, max_front)
        if not len(Uf):
            raise SpecError(f"objective '{objective.name}': no feasible configuration "
                            "on the front")
        # refine: resample around the front at shrinking scales, keep the
        # non-dominated feasible points
        rng = np.random.default_rng(seed)
        scale = 0.5 / len(U) ** (1.0 / d)
        for _ in range(refine):
            Un = np.clip(np.repeat(Uf, 8, axis=0)
                         + rng.normal(0.0, scale, (8 * len(Uf), d)), 0.0, 1.0)
            Sn = scaled_terms(surrogate, objective, surrogate.predict(lo + Un * span))
            Uf, Sf = _feasible_front(np.vstack([Uf, Un]), np.vstack([Sf, Sn]), check,
                                     max_front)
            scale *= 0.5
        Xf = lo + Uf * span
        # distance to the ideal point, each term scaled by its range on the front
        flo, fhi = Sf.min(0), Sf.max(0)
        Sn = (Sf - flo) / np.where(fhi > flo, fhi - flo, 1.0)
        dist = np.sqrt((w * Sn ** 2).sum(1))
        k = int(np.argmin(dist))
        order = np.argsort(Sf[:, 0])
        front = {"x": Xf[order], "terms": Sf[order]}
        best_x, best_v = Xf[k], float(dist[k])
        n_starts = refine
    else:
        # feasibility (a spec validation, ~0.1 s) is checked lazily, best candidates first
        v = value(U)
        best = np.argsort(v)
        seen: list[FloatArray] = []
        for i in best:
            if len(seen) >= polish:
                break
            if any(np.max(np.abs(U[i] - s)) < 0.02 for s in seen):
                continue
            if feasible is not None and not bool(feasible(X[i][None])[0]):
                continue
            if best_x is None:
                best_x, best_v = X[i], float(v[i])
            seen.append(U[i])
            res = minimize(lambda u: float(value(u)[0]), U[i], method="L-BFGS-B",
                           bounds=[(0.0, 1.0)] * d)
            xr = lo + np.clip(res.x, 0.0, 1.0) * span
            if res.fun < best_v and (feasible is None or bool(feasible(xr[None])[0])):
                best_x, best_v = xr, float(res.fun)
        if best_x is None:
            raise SpecError(f"objective '{objective.name}': no feasible configuration in the box")
        n_starts = len(seen)
    mean, std = surrogate.predict(best_x[None], return_std=True)
    return Optimum(objective=objective, x=np.asarray(best_x, float), value=best_v,
                   predicted=dict(zip(surrogate.responses, mean[0].tolist())),
                   std=dict(zip(surrogate.responses, std[0].tolist())), front=front,
                   search={"candidates": int(len(U)), "starts": int(n_starts)})


def verify_optimum(config: StudyConfig, optimum: Optimum, *, build: bool = True,
                   result: dict[str, Any] | None = None,
                   ranges: dict[str, float] | None = None) -> dict[str, Any]:
    """Build and analyse the optimum for real; compare with the GP.

    Parameters
    ----------
    config : StudyConfig
    optimum : Optimum
    build : bool — also build the tip mesh (watertight, volume)
    result : dict, optional — this configuration's analysis already done
        (:func:`~tipgeo.optimize.responses.evaluate_spec`'s form), not repeated
    ranges : dict name -> float, optional — each response's training range
        (max − min, its units); adds ``range`` and ``error_frac`` (|error| / range)

    Returns
    -------
    dict with ``status``, ``error``, ``x`` (name -> value), ``build`` (triangles,
    volume_mm3, watertight, cpu_seconds of the build) and ``responses``: name ->
    ``predicted``, ``std``, ``lo95``, ``hi95``, ``actual``, ``error`` (actual −
    predicted), ``inside95`` (and ``range``, ``error_frac`` with ``ranges``).
    Stored on ``optimum.verified`` as well.
    """
    from .gp import Z95
    from .responses import evaluate_spec

    x = optimum.x
    spec_dict = config.spec_dict(x)
    spec_dict["name"] = f"{config.name}-{optimum.objective.name}"
    out: dict[str, Any] = {"objective": optimum.objective.name,
                           "x": {v.name: (int(round(val)) if v.integer else float(val))
                                 for v, val in zip(config.variables, x)},
                           "spec": spec_dict}
    r = result if result is not None else evaluate_spec(spec_dict, dict(config.analysis))
    out["status"], out["error"] = r["status"], r["error"]
    if build and r["status"] == "ok":
        import time

        from ..build import build_tip
        from ..spec import spec_from_dict

        try:
            spec = spec_from_dict(spec_dict)
            t0 = time.process_time()
            tip = build_tip(spec)
            out["build"] = {"triangles": int(len(tip.faces)), "volume_mm3": float(tip.volume),
                            "watertight": bool(tip.is_watertight),
                            "cpu_seconds": time.process_time() - t0}
        except Exception as e:  # reported, not raised: the analysis may still hold
            out["build"] = {"error": f"{type(e).__name__}: {e}"}
    resp: dict[str, dict[str, Any]] = {}
    for name, pred in optimum.predicted.items():
        sd = optimum.std[name]
        act = r["responses"].get(name, math.nan) if r["status"] == "ok" else math.nan
        resp[name] = {"predicted": pred, "std": sd, "lo95": pred - Z95 * sd,
                      "hi95": pred + Z95 * sd, "actual": act, "error": act - pred,
                      # at a training point sd = 0: allow the interpolation's round-off
                      "inside95": bool(abs(act - pred) <= Z95 * sd + tol.rel * max(1.0, abs(pred)))}
        if ranges is not None and name in ranges:
            resp[name]["range"] = float(ranges[name])
            resp[name]["error_frac"] = (abs(act - pred) / ranges[name] if ranges[name] > 0
                                        else math.nan)
    out["responses"] = resp
    optimum.verified = out
    return out


def term_summary(objective: Objective) -> str:
    """``min theta_min_deg & max lambda_max_deg`` (weights shown when not 1)."""
    def one(t: Term) -> str:
        return f"{t.goal} {t.response}" + (f"×{t.weight:g}" if t.weight != 1 else "")

    return " & ".join(one(t) for t in objective.terms)


def _objective_coefficients(surrogate: Surrogate, objective: Objective) -> FloatArray:
    """(q,) a with f(x) = const + Σⱼ aⱼ ŷⱼ(x) for a ``weighted`` objective."""
    names = [t.response for t in objective.terms]
    _, span = _ranges(surrogate, names)
    a = np.zeros(len(surrogate.responses))
    for t, wk, sp in zip(objective.terms, _weights(objective), span):
        a[surrogate.responses.index(t.response)] += wk * (-1.0 if t.goal == "max" else 1.0) / sp
    return a


def _objective_covariance(surrogate: Surrogate, a: FloatArray, U: FloatArray,
                          u0: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Variance of f at unit points U, its covariance with f at u0, and its
    variance at u0 (latent GP posterior, σ̂ calibration included)."""
    scale = np.asarray(surrogate.scale_, float)
    if surrogate.mode == "separable":
        m = surrogate.models[0]
        var, cov, var0 = m.covariance_with(U, u0)
        b = a * scale
        k = float(b @ np.asarray(m.fitted.sigma) @ b)
        return k * var, k * cov, k * var0
    tot_var, tot_cov, tot_var0 = np.zeros(len(U)), np.zeros(len(U)), 0.0
    for j, m in enumerate(surrogate.models):
        if a[j] == 0.0:
            continue
        var, cov, var0 = m.covariance_with(U, u0)
        k = (a[j] * scale[j]) ** 2 * float(np.asarray(m.fitted.sigma).reshape(-1)[0])
        tot_var += k * var
        tot_cov += k * cov
        tot_var0 += k * var0
    return tot_var, tot_cov, float(tot_var0)


def optimum_region(surrogate: Surrogate, objective: Objective, x_opt: ArrayLike, *,
                   feasible: Feasible | None = None, candidates: int = 2048, seed: int = 1,
                   z: float | None = None, flat_extent: float = FLAT_EXTENT,
                   value_tol: float | None = None) -> dict[str, Any]:
    """How flat a ``weighted`` objective is at its optimum: the designs the GP
    cannot tell from it.

    The objective is linear in the predicted responses, f = c + Σⱼ aⱼ ŷⱼ
    (aⱼ = ±wⱼ / range, see the module docstring), so under the GP posterior
    f is Gaussian with the covariance of eq. 3.32 carried to two points. A
    design x is in the region when the optimum's advantage is not
    significant: E[f(x) − f(x*)] ≤ z · sd(f(x) − f(x*)) (z = 1.96: the 95 %
    one-sided level's complement, P(f(x) < f(x*)) ≥ 2.5 %), the difference's
    variance var(x) + var(x*) − 2 cov(x, x*) with the joint posterior (near
    x* it vanishes: the region is not inflated by the optimum's own
    uncertainty) — or when the advantage is below ``value_tol`` (in the
    objective's scaled units, where 1 is its training range:
    ``tol.optimum_value``, 10⁻⁴, by default), which a GP certain of a flat
    direction (sd → 0 along it) needs.
    Designs: a scrambled Sobol set of the box (``candidates``) plus x*;
    ``feasible`` (optional) drops the region's infeasible members.

    Returns
    -------
    dict — ``value`` (f at x*, scaled) and ``std`` (its posterior sd),
    ``candidates``, ``members`` and ``share`` (of the feasible candidates in
    the region, ≈ its volume share of the box), ``extent`` {variable:
    [min, max]} (variables' units) and ``extent_fraction`` {variable: share of
    its range}, ``flat_along`` (variables whose extent share ≥
    ``flat_extent``), ``shape`` (``sharp``: none; ``ridge``: some;
    ``flat``: all), ``box_position`` (``interior``, ``corner``, or
    ``boundary``: on some bounds) with ``at_bounds`` [{variable, side}],
    ``points`` (m, d) — the region's designs (for pictures), ``z``,
    ``value_tol``.
    """
    from scipy.stats import qmc

    from .gp import Z95

    if objective.combine != "weighted":
        return {"shape": None, "note": "a Pareto objective: its front shows the trade-off; no "
                                       "region of one scalar value"}
    z = Z95 if z is None else float(z)
    value_tol = tol.optimum_value if value_tol is None else float(value_tol)
    lo, span = surrogate._lo, surrogate._span
    d = len(lo)
    u0 = (np.asarray(x_opt, float).reshape(d) - lo) / span
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        U = qmc.Sobol(d, scramble=True, seed=seed).random(candidates)
    U = np.vstack([u0[None], U])
    X = lo + U * span
    a = _objective_coefficients(surrogate, objective)
    mean = scaled_terms(surrogate, objective, surrogate.predict(X)) @ _weights(objective)
    var, cov, var0 = _objective_covariance(surrogate, a, U, u0)
    dvar = np.maximum(var + var0 - 2.0 * cov, 0.0)
    inside = mean - mean[0] <= z * np.sqrt(dvar) + float(value_tol)
    inside[0] = True
    idx = np.flatnonzero(inside)
    if feasible is not None and len(idx) > 1:
        ok = np.asarray(feasible(X[idx[1:]]), bool)
        idx = np.r_[idx[:1], idx[1:][ok]]
        n_cand = candidates  # infeasible non-members are not checked (costly); share ≤ this
    else:
        n_cand = candidates
    P = X[idx]
    names = list(surrogate.variables)
    ext_lo, ext_hi = P.min(0), P.max(0)
    frac = (ext_hi - ext_lo) / span
    flat = [n for n, f in zip(names, frac) if f >= flat_extent]
    shape = "sharp" if not flat else ("flat" if len(flat) == d else "ridge")
    edge = tol.optimum_edge
    at = [{"variable": n, "side": "min" if u <= edge else "max"}
          for n, u in zip(names, u0) if u <= edge or u >= 1.0 - edge]
    pos = "interior" if not at else ("corner" if len(at) == d else "boundary")
    return {"value": float(mean[0]), "std": float(math.sqrt(max(var0, 0.0))), "z": z,
            "value_tol": float(value_tol),
            "candidates": int(n_cand), "members": int(len(idx) - 1),
            "share": float((len(idx) - 1) / n_cand),
            "extent": {n: [float(a_), float(b_)] for n, a_, b_ in zip(names, ext_lo, ext_hi)},
            "extent_fraction": {n: float(f) for n, f in zip(names, frac)},
            "flat_along": flat, "shape": shape, "box_position": pos, "at_bounds": at,
            "points": P}
