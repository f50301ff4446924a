"""Designs of experiments over a box: full grid, Latin hypercube, Sobol, and
a maximin design over the box's admissible part.

Units: the design is returned in the variables' own units (those of their
spec keys: mm for ``*_mm``, degrees for ``*_deg``); integer spec fields are
rounded to the nearest integer. Distances between design points are measured
on the unit box, u = (x − lo)/(hi − lo) per variable (the surrogate's inputs).

The ``maximin`` design
----------------------
Part of a box may hold configurations that are refused at validation (a
helicoid that folds over inside the tube): grid, LHS and Sobol points there
are wasted. ``maximin`` places exactly ``points`` admissible points:

1. candidates: the full grid of k levels per variable, k = ⌈candidates^(1/d)⌉
   (bounds included, so the box's edges and corners can be chosen; by
   default k = 4·⌈points^(1/d)⌉ + 1, :func:`default_candidates`);
2. each candidate is screened by the caller's ``feasible`` (the spec's
   validation — geometric and cheap, no build); the admissible share of the
   candidates estimates the buildable fraction of the box. A sweep
   (:func:`~tipgeo.optimize.sweep.design_points`) screens coarse to fine: with
   an odd number of levels per variable it validates every other node first,
   then only the nodes whose enclosing coarse cell has both verdicts; a node
   whose coarse cell agrees takes that verdict, and any such node the design
   chooses is validated before it is used (re-selecting if it is refused), so
   every design point is admissible;
3. a greedy farthest-point start (the admissible candidate farthest from the
   admissible centroid, then repeatedly the one farthest from those chosen);
4. point exchange (Morris & Mitchell 1995) from that start and from
   ``MAXIMIN_STARTS − 1`` seeded random ones: in seeded random order, each
   design point moves to the unused admissible candidate that most lowers
   φ_p = (Σ_{i<j} d_ij^−p)^(1/p), p = :data:`MAXIMIN_P`, until a pass changes
   nothing; the lowest φ_p wins. φ_p with a large p ranks designs by their
   smallest pairwise distance, then by how few pairs are that close.

The result is deterministic for a given seed (it draws the random starts and
orders the exchange).
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..arrays import ArrayLike, FloatArray, IntArray
from ..errors import SpecError
from ..tolerances import tol

if TYPE_CHECKING:
    from .config import Variable
    from .objective import Feasible

__all__ = ["DESIGN_METHODS", "MAXIMIN_P", "make_design", "unit_design", "candidate_pool",
           "candidate_levels", "candidate_pool_size", "default_candidates", "maximin_select",
           "min_distance", "fill_distance"]

#: Design methods and what they need.
DESIGN_METHODS = {"grid": "levels per variable (full factorial)",
                  "lhs": "points (Latin hypercube, seeded)",
                  "sobol": "points (scrambled Sobol sequence, seeded; powers of 2 balance best)",
                  "maximin": "points (maximin over the admissible candidates of a grid of "
                             "about `candidates` points, seeded)"}

#: Exponent p of the Morris–Mitchell criterion φ_p used by ``maximin``.
MAXIMIN_P = 50.0
#: Most exchange passes of ``maximin`` (each pass tries every design point).
MAXIMIN_PASSES = 100
#: Exchange runs of ``maximin``: the greedy farthest-point start and seeded random ones.
MAXIMIN_STARTS = 8


def default_candidates(points: int, dims: int) -> int:
    """Default candidate count of a ``maximin`` design: a grid of
    4·⌈points^(1/d)⌉ + 1 levels per variable, so that the nodes of a plain grid
    of ``points`` points (when there is one) are among the candidates — for
    25 points in 2 variables, 21 × 21."""
    k = 4 * int(math.ceil(points ** (1.0 / dims) - tol.rel)) + 1
    return int(k ** dims)


def unit_design(method: str, dims: int, *, levels: int | Sequence[int] | None = None,
                points: int | None = None, seed: int = 0,
                candidates: int | None = None) -> FloatArray:
    """Design points in the unit box [0, 1]^dims.

    Parameters
    ----------
    method : ``grid`` | ``lhs`` | ``sobol`` | ``maximin``
    dims : int — number of variables (≥ 1)
    levels : int or sequence of int — grid levels per variable (≥ 2 each)
    points : int — number of points for ``lhs``, ``sobol``, ``maximin`` (≥ 2)
    seed : int — random seed (``lhs``, ``sobol``, ``maximin``)
    candidates : int — ``maximin``: about this many grid candidates (default
        :func:`default_candidates`); here every candidate is admissible

    Returns
    -------
    (n, dims) float in [0, 1]; a grid varies its last variable fastest.
    """
    if method not in DESIGN_METHODS:
        raise SpecError(f"design.method = {method!r} is not valid; expected one of: "
                        + ", ".join(DESIGN_METHODS))
    if method == "maximin":
        if points is None:
            raise SpecError("design.points is missing; method 'maximin' needs a number of points")
        pool = _pool_unit(dims, default_candidates(points, dims) if candidates is None
                          else candidates)
        chosen: FloatArray = pool[maximin_select(pool, points, seed=seed)]
        return chosen
    if method == "grid":
        lv = [levels] * dims if isinstance(levels, int) else list(levels or [])
        if len(lv) != dims:
            raise SpecError(f"design.levels = {levels!r} gives {len(lv)} level counts for "
                            f"{dims} variables; expected one integer or {dims}")
        axes = [np.linspace(0.0, 1.0, k) for k in lv]
        grid: FloatArray = np.array(list(itertools.product(*axes)), float).reshape(-1, dims)
        return grid
    if points is None:
        raise SpecError(f"design.points is missing; method '{method}' needs a number of points")
    from scipy.stats import qmc

    if method == "lhs":
        lhs: FloatArray = qmc.LatinHypercube(dims, seed=seed).random(points)
        return lhs
    with warnings.catch_warnings():  # balance note for non-powers of 2; documented above
        warnings.simplefilter("ignore", UserWarning)
        sobol: FloatArray = qmc.Sobol(dims, scramble=True, seed=seed).random(points)
        return sobol


def make_design(variables: Sequence[Variable], method: str, *,
                levels: int | Sequence[int] | None = None, points: int | None = None,
                seed: int = 0, candidates: int | None = None,
                feasible: Feasible | None = None) -> FloatArray:
    """Design points in the variables' units.

    Parameters
    ----------
    variables : sequence of :class:`~tipgeo.optimize.config.Variable`
        Each with ``lo``, ``hi``, ``levels`` (grid; overrides ``levels``) and
        ``integer``.
    method, levels, points, seed, candidates : see :func:`unit_design`
    feasible : callable (m, d) -> (m,) bool, optional
        ``maximin``: which candidates (variables' units) are admissible
        (e.g. :func:`~tipgeo.optimize.study.feasibility`); default: all.

    Returns
    -------
    (n, d) float — one row per configuration
    """
    if method == "maximin":
        if points is None:
            raise SpecError("design.points is missing; method 'maximin' needs a number of points")
        pool = candidate_pool(variables, default_candidates(points, len(variables))
                              if candidates is None else candidates)
        ok = (np.ones(len(pool), bool) if feasible is None
              else np.asarray(feasible(pool), bool).reshape(len(pool)))
        chosen: FloatArray = pool[ok][maximin_select(_to_unit(variables, pool[ok]), points,
                                                     seed=seed)]
        return chosen
    if method == "grid":
        levels = _grid_levels(variables, levels)
    return _from_unit(variables, unit_design(method, len(variables), levels=levels,
                                             points=points, seed=seed))


def _grid_levels(variables: Sequence[Variable],
                 levels: int | Sequence[int] | None) -> list[int]:
    """Grid levels per variable: a variable's own, else ``levels`` (one for
    all, or one per variable)."""
    if levels is not None and not isinstance(levels, int):
        levels = list(levels)
        if len(levels) != len(variables):
            raise SpecError(f"design.levels = {levels!r} gives {len(levels)} level counts "
                            f"for {len(variables)} variables; expected one per variable")
    per = levels if isinstance(levels, list) else [levels] * len(variables)
    out = [v.levels if v.levels is not None else k for v, k in zip(variables, per)]
    if any(k is None for k in out):
        raise SpecError("design.levels is missing; a grid needs levels (per variable or "
                        "in [design])")
    return [int(k) for k in out if k is not None]


def _to_unit(variables: Sequence[Variable], X: ArrayLike) -> FloatArray:
    lo = np.array([v.lo for v in variables], float)
    hi = np.array([v.hi for v in variables], float)
    U: FloatArray = (np.asarray(X, float) - lo) / (hi - lo)
    return U


def _from_unit(variables: Sequence[Variable], U: ArrayLike) -> FloatArray:
    """Unit-box rows ``U`` in the variables' units, integer variables rounded."""
    lo = np.array([v.lo for v in variables], float)
    hi = np.array([v.hi for v in variables], float)
    X: FloatArray = lo + np.asarray(U, float) * (hi - lo)
    for j, v in enumerate(variables):
        if v.integer:
            X[:, j] = np.round(X[:, j])
    return X


def _levels(dims: int, candidates: int) -> int:
    if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) \
            or candidates < 2:
        raise SpecError(f"design.candidates = {candidates!r} is out of range; allowed an "
                        "integer ≥ 2")
    k = max(2, int(math.ceil(candidates ** (1.0 / dims) - tol.rel)))
    return k


def _pool_unit(dims: int, candidates: int) -> FloatArray:
    k = _levels(dims, candidates)
    return unit_design("grid", dims, levels=k)


def candidate_levels(variables: Sequence[Variable], candidates: int) -> list[int]:
    """Levels per variable of :func:`candidate_pool`."""
    k = _levels(len(variables), candidates)
    return [min(k, int(round(v.hi - v.lo)) + 1) if v.integer else k for v in variables]


def candidate_pool_size(variables: Sequence[Variable], candidates: int) -> int:
    """Rows of :func:`candidate_pool` (without building it)."""
    return math.prod(candidate_levels(variables, candidates))


def candidate_pool(variables: Sequence[Variable], candidates: int) -> FloatArray:
    """The ``maximin`` candidates: a full grid of about ``candidates`` points.

    Parameters
    ----------
    variables : sequence of Variable (``lo``, ``hi``, ``integer``)
    candidates : int — k = ⌈candidates^(1/d)⌉ levels per variable (an integer
        variable: at most one level per integer in its range)

    Returns
    -------
    (m, d) float — variables' units, bounds included, the last variable
    varying fastest; no repeated rows (an integer variable has at most one
    level per integer, so its rounded levels are distinct)
    """
    return _from_unit(variables, unit_design("grid", len(variables),
                                             levels=candidate_levels(variables, candidates)))


def _dist_to(U: FloatArray, x: FloatArray) -> FloatArray:
    d: FloatArray = np.sqrt(((U - x) ** 2).sum(1))
    return d


def min_distance(U: ArrayLike) -> float:
    """Smallest pairwise distance of the rows of ``U`` ((n, d) float, unit box)."""
    A: FloatArray = np.asarray(U, float)
    return float(min(_dist_to(A[i + 1:], A[i]).min() for i in range(len(A) - 1)))


def fill_distance(U: ArrayLike, region: ArrayLike) -> float:
    """Largest distance from a point of ``region`` ((m, d), unit box) to its
    nearest row of ``U`` ((n, d)): the covering radius of the design."""
    A: FloatArray = np.asarray(U, float)
    R: FloatArray = np.asarray(region, float)
    near = np.full(len(R), np.inf)
    for u in A:
        near = np.minimum(near, _dist_to(R, u))
    return float(near.max())


def maximin_select(U: ArrayLike, points: int, *, seed: int = 0,
                   starts: int | None = None) -> IntArray:
    """Indices of ``points`` rows of ``U`` forming a maximin design (see the
    module docstring: farthest-point starts, then φ_p point exchange).

    Parameters
    ----------
    U : (m, d) float — admissible candidates on the unit box, distinct rows
    points : int — design size, 2 ≤ points ≤ m
    seed : int — draws the random starts and orders the exchange passes
    starts : int — exchange runs (the greedy start and starts − 1 random
        ones; default :data:`MAXIMIN_STARTS`); the lowest φ_p wins

    Returns
    -------
    (points,) int — indices into U, sorted

    Memory and time are O(m) per exchange step: no m × m distance matrix.
    """
    A: FloatArray = np.asarray(U, float)
    m = len(A)
    if not 2 <= points <= m:
        raise SpecError(f"design.points = {points} is out of range; only {m} admissible "
                        f"candidates; allowed 2–{m} (raise design.candidates, or shrink the "
                        "box to its buildable part)")
    rng = np.random.default_rng(seed)
    best: IntArray | None = None
    best_v = np.inf
    greedy = _greedy(A, points)
    ref = min_distance(A[greedy])  # distances are scaled by it: terms (ref/d)^p stay finite
    if not ref > 0:
        raise SpecError("design candidates repeat a point; allowed distinct candidates")
    for s in range(MAXIMIN_STARTS if starts is None else starts):
        start = greedy.copy() if s == 0 else rng.choice(m, points, replace=False)
        sel, v = _exchange(A, start, rng, ref)
        if best is None or v < best_v * (1 - tol.maximin_improve):
            best, best_v = sel, v
    if best is None:
        raise SpecError(f"maximin starts = {starts}; allowed at least 1")
    return np.sort(best)


def _greedy(U: FloatArray, points: int) -> IntArray:
    """Farthest-point sequence from the candidate farthest from the centroid."""
    sel = [int(np.argmax(((U - U.mean(0)) ** 2).sum(1)))]
    near = _dist_to(U, U[sel[0]])
    for _ in range(points - 1):
        near[sel] = -1.0
        j = int(np.argmax(near))
        sel.append(j)
        near = np.minimum(near, _dist_to(U, U[j]))
    return np.array(sel)


def _terms(U: FloatArray, x: FloatArray, ref: float) -> FloatArray:
    """(ref/d)^p from every candidate to ``x`` (0 at ``x`` itself)."""
    d = _dist_to(U, x)
    with np.errstate(divide="ignore", over="ignore"):
        t: FloatArray = (ref / d) ** MAXIMIN_P
    t[d == 0] = 0.0
    return t


def _phi(U: FloatArray, sel: IntArray, ref: float) -> float:
    """Σ_{i<j} (ref/d_ij)^p of the design ``sel`` (φ_p^p, scaled)."""
    return float(sum(_terms(U[sel[i + 1:]], U[sel[i]], ref).sum()
                     for i in range(len(sel) - 1)))


def _exchange(U: FloatArray, start: IntArray, rng: np.random.Generator,
              ref: float) -> tuple[IntArray, float]:
    """Point exchange lowering φ_p. Row k of ``E`` holds (ref/d)^p from design
    point k to every candidate, so a trial move of point i to each candidate
    costs one sum over the other rows (summed afresh: subtracting row i from
    a running total would cancel catastrophically next to point i)."""
    sel = np.array(start)
    n = len(sel)
    E = np.array([_terms(U, U[k], ref) for k in sel])
    current = _phi(U, sel, ref)
    for _ in range(MAXIMIN_PASSES):
        moved = False
        for i in rng.permutation(n):
            gain = np.delete(E, i, axis=0).sum(0)  # Σ over the others, per candidate
            stay = gain[sel[i]]
            gain[sel] = np.inf
            c = int(np.argmin(gain))
            if not gain[c] < stay * (1 - tol.maximin_improve):
                continue
            sel[i] = c
            E[i] = _terms(U, U[c], ref)
            current = _phi(U, sel, ref)
            moved = True
        if not moved:
            break
    return sel, current
