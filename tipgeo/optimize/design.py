"""Designs of experiments over a box: full grid, Latin hypercube, Sobol.

Units: the design is returned in the variables' own units (those of their
spec keys: mm for ``*_mm``, degrees for ``*_deg``); integer spec fields are
rounded to the nearest integer.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from ..errors import SpecError

__all__ = ["DESIGN_METHODS", "make_design", "unit_design"]

#: Design methods and what they need.
DESIGN_METHODS = {"grid": "levels per variable (full factorial)",
                  "lhs": "points (Latin hypercube, seeded)",
                  "sobol": "points (scrambled Sobol sequence, seeded; powers of 2 balance best)"}


def unit_design(method: str, dims: int, *, levels=None, points: int | None = None,
                seed: int = 0) -> np.ndarray:
    """Design points in the unit box [0, 1]^dims.

    Parameters
    ----------
    method : ``grid`` | ``lhs`` | ``sobol``
    dims : int — number of variables (≥ 1)
    levels : int or sequence of int — grid levels per variable (≥ 2 each)
    points : int — number of points for ``lhs`` and ``sobol`` (≥ 2)
    seed : int — random seed (``lhs``, ``sobol``)

    Returns
    -------
    (n, dims) float in [0, 1]; a grid varies its last variable fastest.
    """
    if method not in DESIGN_METHODS:
        raise SpecError(f"design.method = {method!r} is not valid; expected one of: "
                        + ", ".join(DESIGN_METHODS))
    if method == "grid":
        lv = [levels] * dims if isinstance(levels, int) else list(levels or [])
        if len(lv) != dims:
            raise SpecError(f"design.levels = {levels!r} gives {len(lv)} level counts for "
                            f"{dims} variables; expected one integer or {dims}")
        axes = [np.linspace(0.0, 1.0, k) for k in lv]
        return np.array(list(itertools.product(*axes)), float).reshape(-1, dims)
    if points is None:
        raise SpecError(f"design.points is missing; method '{method}' needs a number of points")
    from scipy.stats import qmc

    if method == "lhs":
        return qmc.LatinHypercube(dims, seed=seed).random(points)
    with warnings.catch_warnings():  # balance note for non-powers of 2; documented above
        warnings.simplefilter("ignore", UserWarning)
        return qmc.Sobol(dims, scramble=True, seed=seed).random(points)


def make_design(variables, method: str, *, levels=None, points: int | None = None,
                seed: int = 0) -> np.ndarray:
    """Design points in the variables' units.

    Parameters
    ----------
    variables : sequence of :class:`~tipgeo.optimize.config.Variable`
        Each with ``lo``, ``hi``, ``levels`` (grid; overrides ``levels``) and
        ``integer``.
    method, levels, points, seed : see :func:`unit_design`

    Returns
    -------
    (n, d) float — one row per configuration
    """
    if method == "grid":
        if levels is not None and not isinstance(levels, int):
            levels = list(levels)
            if len(levels) != len(variables):
                raise SpecError(f"design.levels = {levels!r} gives {len(levels)} level counts "
                                f"for {len(variables)} variables; expected one per variable")
        per = levels if isinstance(levels, list) else [levels] * len(variables)
        levels = [v.levels if v.levels is not None else k for v, k in zip(variables, per)]
        if any(k is None for k in levels):
            raise SpecError("design.levels is missing; a grid needs levels (per variable or "
                            "in [design])")
    u = unit_design(method, len(variables), levels=levels, points=points, seed=seed)
    lo = np.array([v.lo for v in variables])
    hi = np.array([v.hi for v in variables])
    x = lo + u * (hi - lo)
    for k, v in enumerate(variables):
        if v.integer:
            x[:, k] = np.round(x[:, k])
    return x
