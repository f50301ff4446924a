"""Issue 28 (e): how flat an objective is at its optimum — the designs the
GP posterior cannot tell from it — on synthetic responses with a known
sharp optimum, a known ridge and a known corner."""

import math

import numpy as np
import pytest
from scipy.stats import qmc

from tipgeo.optimize.config import Objective, Term
from tipgeo.optimize.gp import Z95
from tipgeo.optimize.objective import optimize_objective, optimum_region
from tipgeo.optimize.surrogate import Surrogate

# a space-filling design (a grid repeats each a at every b: on a ridge its
# correlation matrix is near-singular and the MLE is pushed to rough fits)
GRID = qmc.Sobol(2, scramble=True, seed=3).random(32)


def _fit(fn, responses=("y",), **kw):
    Y = np.column_stack([fn(GRID[:, 0], GRID[:, 1])])
    return Surrogate(bounds=[(0.0, 1.0), (0.0, 1.0)], responses=list(responses),
                     variables=["a", "b"], **kw).fit(GRID, Y)


OBJ = Objective(name="o", terms=(Term("y", "min"),))


def test_sharp_interior_optimum():
    """y = (a − 0.3)² + (b − 0.6)²: the optimum at (0.3, 0.6), inside the box;
    the region the GP cannot tell from it is small in both variables."""
    sur = _fit(lambda a, b: (a - 0.3) ** 2 + (b - 0.6) ** 2)
    opt = optimize_objective(sur, OBJ)
    assert opt.x == pytest.approx([0.3, 0.6], abs=0.01)
    reg = optimum_region(sur, OBJ, opt.x)
    assert reg["shape"] == "sharp" and reg["flat_along"] == []
    assert reg["box_position"] == "interior" and reg["at_bounds"] == []
    for name in ("a", "b"):
        assert reg["extent_fraction"][name] < 0.25
        lo, hi = reg["extent"][name]
        assert lo <= opt.x["ab".index(name)] <= hi
    assert reg["share"] < 0.05
    assert 0.0 <= reg["std"] < 0.05
    assert reg["z"] == Z95
    # every member is within z·sd of the optimum; a member's mean is not better
    # by more than the optimiser's tolerance
    P = reg["points"]
    assert P.shape == (reg["members"] + 1, 2)


def test_ridge_is_named_flat_along_its_direction():
    """y = (a − 0.4)²: every b is optimal. The region spans all of b (share of
    range ≥ 0.9; measured 0.977) and little of a (measured 0.011): a ridge,
    flat along b — with either correlation family and with a nugget."""
    sur = _fit(lambda a, b: (a - 0.4) ** 2 + 0.0 * b)
    opt = optimize_objective(sur, OBJ)
    assert opt.x[0] == pytest.approx(0.4, abs=0.01)
    reg = optimum_region(sur, OBJ, opt.x)
    assert reg["shape"] == "ridge" and reg["flat_along"] == ["b"]
    assert reg["extent_fraction"]["b"] > 0.9
    assert reg["extent_fraction"]["a"] < 0.05
    assert reg["share"] > 0.005
    for kw in ({"kernel": "matern52"}, {"nugget": True}):
        s2 = _fit(lambda a, b: (a - 0.4) ** 2 + 0.0 * b, **kw)
        r2 = optimum_region(s2, OBJ, optimize_objective(s2, OBJ).x)
        assert r2["shape"] == "ridge" and r2["flat_along"] == ["b"], kw


def test_corner_optimum_and_max_terms():
    """y = a + b maximised: optimum at the corner (1, 1); a sharp corner."""
    sur = _fit(lambda a, b: a + b)
    obj = Objective(name="m", terms=(Term("y", "max"),))
    opt = optimize_objective(sur, obj)
    assert opt.x == pytest.approx([1.0, 1.0], abs=1e-6)
    reg = optimum_region(sur, obj, opt.x)
    assert reg["box_position"] == "corner"
    assert reg["at_bounds"] == [{"variable": "a", "side": "max"},
                                {"variable": "b", "side": "max"}]
    assert reg["shape"] == "sharp"


def test_objective_std_is_the_gp_std_scaled():
    """One term: f = (ŷ − min)/range, so sd(f) at x* = sd(ŷ)/range, the GP's own
    predictive sd (latent; no nugget here)."""
    fn = lambda a, b: np.sin(3 * a) + np.cos(2 * b)       # noqa: E731
    sur = _fit(fn)
    x = np.array([0.37, 0.81])                            # off the grid: sd > 0
    reg = optimum_region(sur, OBJ, x)
    _, sd = sur.predict(x[None], return_std=True)
    span = np.ptp(sur.Y_[:, 0])
    assert reg["std"] == pytest.approx(float(sd[0, 0]) / span, rel=1e-6)
    assert reg["std"] > 0


def test_separable_and_independent_agree_on_one_response():
    """With one response the separable model (eq. 3.33) is the same GP: the
    same region."""
    fn = lambda a, b: (a - 0.3) ** 2 + 0.5 * (b - 0.6) ** 2   # noqa: E731
    r1 = optimum_region(_fit(fn), OBJ, [0.3, 0.6])
    r2 = optimum_region(_fit(fn, mode="separable"), OBJ, [0.3, 0.6])
    assert r1["members"] == r2["members"]
    assert r1["std"] == pytest.approx(r2["std"], rel=1e-6, abs=1e-12)
    assert math.isfinite(r1["value"])


def test_region_value_is_the_objective_value():
    """``value`` is the scaled objective at x* (0 at the best training value),
    the same number the optimiser minimised."""
    sur = _fit(lambda a, b: (a - 0.3) ** 2 + (b - 0.6) ** 2)
    opt = optimize_objective(sur, OBJ)
    reg = optimum_region(sur, OBJ, opt.x)
    assert reg["value"] == pytest.approx(opt.value, abs=1e-9)   # measured 2.5e-12
