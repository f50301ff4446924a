"""The ``maximin`` design: exactly the requested number of admissible points,
spread over the admissible part of the box, deterministic for a seed; its
coarse-to-fine screening in a sweep; bad input named.

Geometry is cheap here: the pure-design tests use an analytic admissible
region (a disk cut out of the box), the sweep tests a 5 × 5 candidate grid
over the helical box (25 spec validations, ~0.05 s each) or a validator
replaced by a known region.
"""

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tipgeo.errors import SpecError
from tipgeo.optimize import SerialExecutor, config_from_dict, loads_config, make_design, run_sweep
from tipgeo.optimize import sweep as sweep_mod
from tipgeo.optimize.design import (
    candidate_pool,
    default_candidates,
    fill_distance,
    maximin_select,
    min_distance,
    unit_design,
)
from tipgeo.optimize.sweep import design_points
from tipgeo.tomlio import loads_toml

HELICAL = """
name = "mm"
base = "helical-14G"
[[variables]]
name = "psi_deg"
path = "cutters[0].helix_angle_deg"
min = 5.0
max = 25.0
[[variables]]
name = "phi_deg"
path = "cutters[0].phi_deg"
min = 5.0
max = 20.0
[design]
method = "maximin"
points = 6
candidates = 25
seed = 3
[analysis]
responses = ["l_c_mm"]
[sweep]
workers = 1
cache = false
"""


def _vars():
    return loads_config(HELICAL).variables


def _unit(X, variables):
    lo = np.array([v.lo for v in variables])
    hi = np.array([v.hi for v in variables])
    return (X - lo) / (hi - lo)


def _outside_disk(X):
    """Admissible: outside the disk of radius 0.35 about (0.7, 0.8) of the unit box."""
    U = _unit(np.asarray(X, float), _vars())
    return np.hypot(U[:, 0] - 0.7, U[:, 1] - 0.8) > 0.35


# -- the design itself ---------------------------------------------------------------
def test_unconstrained_maximin_of_a_square_number_is_the_plain_grid():
    # the 5 × 5 grid (spacing 1/4) is the maximin design of 25 points in the
    # square; its nodes are among the default 21 × 21 candidates
    assert default_candidates(25, 2) == 441
    U = unit_design("maximin", 2, points=25, seed=0)
    assert len(U) == 25 and len({tuple(u) for u in U}) == 25
    assert min_distance(U) == pytest.approx(0.25, abs=1e-12)
    assert min_distance(unit_design("grid", 2, levels=5)) == pytest.approx(0.25, abs=1e-12)


@pytest.mark.parametrize("points", [9, 25, 40])
def test_points_are_admissible_exact_in_number_and_fill_the_admissible_region(points):
    V = _vars()
    X = make_design(V, "maximin", points=points, seed=1, feasible=_outside_disk)
    assert X.shape == (points, 2)
    assert np.all(_outside_disk(X))
    assert len({tuple(x) for x in X}) == points
    pool = candidate_pool(V, default_candidates(points, 2))
    assert all(any(np.array_equal(x, p) for p in pool) for x in X)  # candidates only
    # against the plain grid of about as many nodes, with its refused nodes dropped:
    # the maximin design keeps every point and covers the admissible region closer
    k = round(points ** 0.5)
    G = make_design(V, "grid", levels=k)
    G = G[_outside_disk(G)]
    region = _unit(pool[_outside_disk(pool)], V)
    assert len(G) < points
    assert fill_distance(_unit(X, V), region) < fill_distance(_unit(G, V), region)


def test_deterministic_for_a_seed():
    V = _vars()
    a = make_design(V, "maximin", points=12, seed=7, feasible=_outside_disk)
    b = make_design(V, "maximin", points=12, seed=7, feasible=_outside_disk)
    assert np.array_equal(a, b)
    c = [make_design(V, "maximin", points=12, seed=s, feasible=_outside_disk)
         for s in range(4)]
    assert all(np.all(_outside_disk(x)) for x in c)


def test_integer_variables_take_one_candidate_per_integer_at_most():
    from tipgeo.optimize.config import Variable

    V = [Variable("count", "cutters[1].count", 2.0, 5.0, integer=True),
         Variable("xi_deg", "cutters[0].xi_deg", 10.0, 40.0)]
    pool = candidate_pool(V, 36)
    assert pool.shape == (4 * 6, 2)
    assert sorted(set(pool[:, 0].tolist())) == [2.0, 3.0, 4.0, 5.0]
    X = make_design(V, "maximin", points=5, candidates=36)
    assert len({tuple(x) for x in X}) == 5 and np.all(X[:, 0] == np.round(X[:, 0]))


def test_too_few_admissible_candidates_names_the_parameter():
    U = unit_design("grid", 2, levels=3)
    with pytest.raises(SpecError, match=r"design\.points = 10 is out of range; only 9 "):
        maximin_select(U, 10)
    with pytest.raises(SpecError, match=r"design\.points = 3 is out of range"):
        make_design(_vars(), "maximin", points=3, candidates=9,
                    feasible=lambda X: np.arange(len(X)) < 2)


# -- in a sweep: real validation, coarse to fine ---------------------------------------
def test_helical_sweep_uses_only_admissible_points_and_reports_the_refused_share(
        tmp_path, monkeypatch):
    from tipgeo.optimize import ResultCache
    from tipgeo.optimize import responses as responses_mod

    # the analyses are not under test: each row just rebuilds its spec (validation)
    def validate_only(spec_dict, analysis):
        from tipgeo.spec import spec_from_dict

        try:
            spec_from_dict(spec_dict)
        except SpecError as e:
            return {"status": "invalid", "error": str(e), "responses": {}}
        return {"status": "ok", "error": "", "responses": {"l_c_mm": 1.0}}

    monkeypatch.setattr(responses_mod, "evaluate_spec", validate_only)
    cfg = loads_config(HELICAL)
    cache = ResultCache(tmp_path)
    res = run_sweep(cfg, executor=SerialExecutor(), cache=cache, progress=False)
    # every design point admissible: none refused
    assert len(res.X) == 6 and len({tuple(x) for x in res.X}) == 6 and bool(res.ok.all())
    d = res.summary()["design"]
    assert (d["method"], d["points"], d["candidates"], d["levels"]) == ("maximin", 6, 25,
                                                                       [5, 5])
    # the verdicts, coarse nodes validated and the rest inferred, against all 25
    pool = candidate_pool(cfg.variables, 25)
    truth = np.array([_validates(cfg, x) for x in pool])
    assert d["admissible"] == int(truth.sum()) and 0 < d["admissible"] < 25
    assert d["buildable_fraction"] == pytest.approx(truth.mean(), abs=1e-15)
    assert d["validated"] < 25
    refused = sum(g["count"] for g in d["refusals"])
    assert refused > 0 and refused + d["refused_inferred"] == 25 - d["admissible"]
    assert all("folds over inside the tube" in g["example"] or "would need a grid" in
               g["example"] for g in d["refusals"])
    assert res.screen["ok"].shape == (d["validated"],)
    # every node's verdict, for the pictures: each candidate answers its own
    from tipgeo.optimize.study import grid_verdicts

    assert np.array_equal(grid_verdicts(cfg, res.screen)(pool), truth)
    # the same design again, every verdict from the cache
    hits = cache.hits
    X2, d2 = design_points(cfg, executor=SerialExecutor(), cache=cache)
    assert np.array_equal(X2, res.X) and d2["admissible"] == d["admissible"]
    assert cache.hits - hits == d["validated"]


def _validates(cfg, x) -> bool:
    try:
        cfg.spec(x)
        return True
    except SpecError:
        return False


def test_a_wrong_inferred_verdict_never_reaches_the_design(monkeypatch):
    """Refused pockets at nodes whose coarse cell is all admissible are inferred
    admissible; the design validates what it chooses and never keeps them."""
    cfg = loads_config(HELICAL.replace("points = 6", "points = 40")
                       .replace("candidates = 25", "candidates = 81"))
    calls = []

    def fake(spec_dict):
        c = spec_dict["cutters"][0]
        i = round((c["helix_angle_deg"] - 5.0) / 2.5)  # 9 levels over 5–25°
        j = round((c["phi_deg"] - 5.0) / 15.0 * 8)
        calls.append((i, j))
        bad = i % 2 == 1 and j % 2 == 1  # the pockets: odd-odd nodes
        return {"status": "invalid" if bad else "ok", "error": "pocket" if bad else ""}

    monkeypatch.setattr(sweep_mod, "validate_spec_task", fake)
    X, d = design_points(cfg, executor=SerialExecutor(), cache=False)
    ij = {(round((x[0] - 5.0) / 2.5), round((x[1] - 5.0) / 15.0 * 8)) for x in X}
    assert len(X) == 40 and len(ij) == 40
    assert not any(i % 2 and j % 2 for i, j in ij)
    assert ij <= set(calls)  # every design point was validated
    assert d["validated"] < 81


def test_grid_nodes_are_screened_in_full_when_levels_are_even(monkeypatch):
    cfg = loads_config(HELICAL.replace("candidates = 25", "candidates = 16"))
    n = []
    monkeypatch.setattr(sweep_mod, "validate_spec_task",
                        lambda s: n.append(1) or {"status": "ok", "error": ""})
    X, d = design_points(cfg, executor=SerialExecutor(), cache=False)
    assert d["levels"] == [4, 4] and len(n) == 16 == d["validated"] and len(X) == 6


# -- config validation ------------------------------------------------------------------
@pytest.mark.parametrize("design, match", [
    ({"method": "maximin"}, r"design\.points is missing"),
    ({"method": "maximin", "points": 6, "levels": 3}, r"design\.levels is not used"),
    ({"method": "grid", "levels": 3, "candidates": 100}, r"design\.candidates is not used by "
                                                          r"method 'grid'"),
    ({"method": "maximin", "points": 6, "candidates": 1}, r"design\.candidates = 1 is out of "
                                                          r"range; allowed an integer 2–100000"),
    ({"method": "maximin", "points": 6, "candidates": 10**6}, r"design\.candidates = 1000000 "
                                                              r"is out of range"),
    ({"method": "maximin", "points": 6, "candidates": "many"}, r"design\.candidates = "),
    ({"method": "maximin", "points": 30, "candidates": 25}, r"design\.candidates = 25 gives a "
                                                            r"grid of 25 candidates for "
                                                            r"design\.points = 30"),
])
def test_bad_design_keys_name_the_key_value_and_allowed(design, match):
    data = loads_toml(HELICAL, "config")
    data["design"] = design
    with pytest.raises(SpecError, match=match):
        config_from_dict(data)


def test_default_candidates_are_recorded():
    data = loads_toml(HELICAL, "config")
    del data["design"]["candidates"]
    cfg = config_from_dict(data)
    assert cfg.design == {"method": "maximin", "levels": None, "points": 6, "seed": 3,
                          "candidates": 169}  # (4·⌈√6⌉ + 1)² = 13²


_vals = st.one_of(st.none(), st.booleans(), st.integers(-3, 2 * 10**5),
                  st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6),
                  st.lists(st.integers(0, 5), max_size=2))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(design=st.dictionaries(st.sampled_from(["method", "points", "candidates", "seed",
                                               "levels"]),
                              st.one_of(_vals, st.sampled_from(["maximin", "grid", "lhs"])),
                              max_size=5))
def test_design_table_fuzz_valid_or_one_error_naming_the_key(design):
    data = loads_toml(HELICAL, "config")
    data["design"] = design
    try:
        cfg = config_from_dict(data)
    except SpecError as e:
        assert re.match(r"^design\.(method|points|candidates|seed|levels)(\[\d+\])?[ =]",
                        str(e)), str(e)
        return
    d = cfg.design
    if d["method"] == "maximin":
        assert isinstance(d["candidates"], int) and 2 <= d["candidates"] <= 100_000
        assert d["points"] <= len(candidate_pool(cfg.variables, d["candidates"]))
    else:
        assert d["candidates"] is None


def test_candidate_grid_spans_the_box_bounds_included():
    V = _vars()
    pool = candidate_pool(V, 441)
    assert pool.shape == (441, 2)
    assert pool.min(0).tolist() == [5.0, 5.0] and pool.max(0).tolist() == [25.0, 20.0]
    # the last variable varies fastest, as in a grid design
    assert np.array_equal(pool, make_design(V, "grid", levels=21))
    assert pool[1] == pytest.approx([5.0, 5.75], abs=1e-12)
