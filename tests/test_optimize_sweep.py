"""Design sweeps: designs, config validation (fuzzed), the evaluation of real
tips, failures, the content-hash cache, tables, local and Dask executors."""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tipgeo
from tipgeo.angles import analyze
from tipgeo.errors import SpecError
from tipgeo.optimize import (
    ProcessExecutor,
    ResultCache,
    SerialExecutor,
    config_from_dict,
    loads_config,
    make_design,
    read_table,
    run_sweep,
    spec_hash,
    spec_key,
    unit_design,
    write_table,
)
from tipgeo.optimize import responses as responses_mod
from tipgeo.optimize.responses import RESPONSES, THESIS, responses_from_summary
from tipgeo.tomlio import loads_toml

SAMPLES = Path(__file__).resolve().parents[1] / "samples"

HELICAL_3X3 = """
name = "h3"
base = "helical-14G"
[[variables]]
name = "psi_deg"
path = "cutters[0].helix_angle_deg"
min = 9.0
max = 11.0
[[variables]]
name = "phi_deg"
path = "cutters[0].phi_deg"
min = 12.0
max = 15.0
[design]
levels = 3
[sweep]
workers = 1
cache = false
"""


def cfg3(**changes):
    return loads_config(HELICAL_3X3, **changes)


# -- designs --------------------------------------------------------------------------
def test_grid_design_is_the_full_factorial_last_variable_fastest():
    cfg = cfg3()
    X = make_design(cfg.variables, "grid", levels=3)
    assert X.shape == (9, 2)
    assert X[:3].tolist() == [[9.0, 12.0], [9.0, 13.5], [9.0, 15.0]]
    assert sorted(set(X[:, 0])) == [9.0, 10.0, 11.0]


def test_grid_design_takes_a_level_count_per_variable():
    cfg = cfg3()
    X = make_design(cfg.variables, "grid", levels=[2, 3])
    assert X.shape == (6, 2)
    assert sorted(set(X[:, 0])) == [9.0, 11.0]
    assert sorted(set(X[:, 1])) == [12.0, 13.5, 15.0]
    with pytest.raises(SpecError, match=r"design\.levels = \[2, 3, 4\] gives 3 level counts"):
        make_design(cfg.variables, "grid", levels=[2, 3, 4])


@pytest.mark.parametrize("method", ["lhs", "sobol"])
def test_random_designs_fill_the_box_and_are_seeded(method):
    U = unit_design(method, 3, points=64, seed=4)
    assert U.shape == (64, 3)
    assert U.min() >= 0.0 and U.max() <= 1.0
    assert np.array_equal(U, unit_design(method, 3, points=64, seed=4))
    assert not np.array_equal(U, unit_design(method, 3, points=64, seed=5))
    if method == "lhs":  # one point in each of the 64 strata of every variable
        for k in range(3):
            assert sorted(np.floor(U[:, k] * 64).astype(int).tolist()) == list(range(64))
    else:  # a scrambled Sobol set of 2^6 points: 8 in each octant-row bin of 1/8
        for k in range(3):
            assert np.bincount(np.floor(U[:, k] * 8).astype(int), minlength=8).tolist() == [8] * 8


def test_integer_keys_are_rounded():
    cfg = loads_config("""
base = "punch-C2"
[[variables]]
path = "cutters[1].count"
min = 8
max = 20
[design]
method = "lhs"
points = 7
""")
    v = cfg.variables[0]
    assert v.integer and v.name == "count"
    X = make_design(cfg.variables, "lhs", points=7, seed=0)
    assert np.all(X == np.round(X)) and X.min() >= 8 and X.max() <= 20
    assert cfg.spec(X[0]).cutters[1].count == int(X[0, 0])


# -- config validation -------------------------------------------------------------
@pytest.mark.parametrize("patch, match", [
    ({"base": "nope"}, r"base = 'nope' is neither a spec file .* presets: "),
    ({"base": "missing.toml"}, r"base = 'missing.toml': spec file .* does not exist"),
    ({"variables": []}, r"variables is missing or empty"),
    ({"variables": [{"path": "cutters[0].helix_angle_deg", "min": 11, "max": 9}]},
     r"variables\[0\]\.max = 9 is out of range; allowed max > min = 11"),
    ({"variables": [{"path": "cutters[3].phi_deg", "min": 1, "max": 2}]},
     r"variables\[0\]\.path = 'cutters\[3\]\.phi_deg': the base spec has 1 cutter"),
    ({"variables": [{"path": "cutters[0].xi_deg", "min": 1, "max": 2}]},
     r"'xi_deg' is not a numeric key of a helical cutter; allowed: pitch_mm, "),
    ({"variables": [{"path": "cutters[0].phi_deg", "min": "a", "max": 2}]},
     r"variables\[0\]\.min = 'a' is not a number"),
    ({"variables": [{"path": "helix", "min": 1, "max": 2}]},
     r"variables\[0\]\.path = 'helix' is not a spec key"),
    ({"variables": [{"path": "cannula.outer_diameter_mm", "min": 2, "max": 3}]},
     r"the base cannula is given by gauge"),
    ({"variables": [{"path": "cutters[0].phi_deg", "min": 1, "max": 2, "step": 1}]},
     r"variables\[0\]\.step is not a known key; allowed keys: name, path, min, max, levels"),
    ({"design": {"method": "grid"}}, r"design\.levels is missing"),
    ({"design": {"method": "lhs", "levels": 3}}, r"design\.points is missing"),
    ({"design": {"method": "latin"}}, r"design\.method = 'latin' is not valid; expected one "
                                      r"of: grid, lhs, sobol"),
    ({"design": {"levels": 1}}, r"design\.levels = 1 is out of range; allowed an integer"),
    ({"analysis": {"responses": ["l_c"]}}, r"analysis\.responses\[0\] = 'l_c' is not valid"),
    ({"analysis": {"responses": ["mean_F_perp_N"]}}, r"is a force; it needs "
                                                     r"\[analysis\.forces\]"),
    ({"analysis": {"method": "slow"}}, r"analysis\.method = 'slow' is not valid"),
    ({"sweep": {"workers": 0}}, r"sweep\.workers = 0 is out of range"),
    ({"surrogate": {"nugget": 3}}, r"surrogate\.nugget = 3 is out of range"),
    ({"surrogate": {"mode": "joint"}}, r"surrogate\.mode = 'joint' is not valid"),
    ({"surrogate": {"kernel": "rbf"}}, r"surrogate\.kernel = 'rbf' is not valid"),
    ({"surrogate": {"response_kernels": {"l_c": "matern72"}}},
     r"surrogate\.response_kernels\.l_c is not a known key; allowed keys: "),
    ({"surrogate": {"response_kernels": {"l_c_mm": "rbf"}}},
     r"surrogate\.response_kernels\.l_c_mm = 'rbf' is not valid; expected one of: gaussian"),
    ({"surrogate": {"response_kernels": "matern72"}},
     r"surrogate\.response_kernels = 'matern72' is not a table"),
    ({"surrogate": {"mode": "separable", "response_kernels": {"l_c_mm": "matern72"}}},
     r"surrogate\.response_kernels needs mode = 'independent'"),
    ({"objectives": [{"name": "o", "terms": [{"response": "l_c_mm", "goal": "smallest"}]}]},
     r"objectives\[0\]\.terms\[0\]\.goal = 'smallest' is not valid; expected one of: min, max"),
    ({"objectives": [{"name": "o", "terms": [{"response": "inner_l_c_mm"}]}]},
     r"objectives\[0\]\.terms\[0\]\.response = 'inner_l_c_mm' is not valid"),
    ({"objectives": [{"name": "o", "combine": "pareto",
                      "terms": [{"response": "l_c_mm"}]}]}, r"needs at least two terms"),
    ({"plots": {"variables": ["psi_deg", "psi_deg"]}}, r"repeats a variable"),
    ({"colour": "red"}, r"config\.colour is not a known key"),
])
def test_config_errors_name_key_value_and_allowed(patch, match):
    data = loads_toml(HELICAL_3X3, "config")
    data.update(patch)
    with pytest.raises(SpecError, match=match):
        config_from_dict(data, base_dir=Path("/nonexistent-dir"))


def test_config_file_errors_carry_the_file_name(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(HELICAL_3X3.replace("min = 9.0", "min = 'x'"), encoding="utf-8")
    from tipgeo.optimize import load_config

    with pytest.raises(SpecError, match=r"bad\.toml: variables\[0\]\.min = 'x'"):
        load_config(p)
    with pytest.raises(SpecError, match="does not exist"):
        load_config(tmp_path / "none.toml")


_values = st.one_of(st.none(), st.booleans(), st.integers(-5, 30),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
                    st.lists(st.integers(0, 5), max_size=3))
_keys = st.sampled_from(["name", "base", "variables", "design", "analysis", "sweep",
                         "surrogate", "objectives", "plots", "bogus", "description"])
_var = st.fixed_dictionaries({}, optional={
    "path": st.sampled_from(["cutters[0].helix_angle_deg", "cutters[0].phi_deg",
                             "cannula.length_mm", "cannula.gauge", "tolerance_um",
                             "cutters[0].count", "cutters[9].phi_deg", "x", "cannula.preset"]),
    "min": _values, "max": _values, "levels": _values, "name": _values})
_table = st.dictionaries(st.sampled_from(["method", "levels", "points", "seed", "candidates",
                                          "responses",
                                          "workers", "cache", "nugget", "mode", "starts",
                                          "variables", "resolution", "harmonics", "forces"]),
                         _values, max_size=4)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(top=st.dictionaries(_keys, _values, max_size=4),
       variables=st.lists(_var, max_size=3),
       tables=st.dictionaries(st.sampled_from(["design", "analysis", "sweep", "surrogate",
                                               "plots"]), _table, max_size=3),
       base=st.sampled_from(["helical-14G", "bevel-14G-xi15", "punch-C2", "nope", 3]))
def test_config_validation_fuzz_only_raises_spec_error(top, variables, tables, base):
    data = dict(top) | {"base": base, "variables": variables} | tables
    try:
        cfg = config_from_dict(data)
    except SpecError as e:
        msg = str(e)
        assert msg and "Traceback" not in msg
        return
    # a config that validates gives specs (or SpecErrors) at its box corners
    lo = [v.lo for v in cfg.variables]
    try:
        cfg.spec(lo)
    except SpecError:
        pass


FULL = HELICAL_3X3 + """
[analysis]
method = "exact"
responses = ["l_c_mm", "theta_min_deg", "lambda_max_deg"]
[surrogate]
nugget = false
mode = "independent"
[[objectives]]
name = "o"
terms = [{ response = "theta_min_deg", goal = "min" },
         { response = "lambda_max_deg", goal = "max" }]
[plots]
variables = ["psi_deg", "phi_deg"]
responses = ["l_c_mm"]
"""
_DELETE = object()
_PATHS = [("name",), ("base",), ("description",), ("variables",), ("variables", 0, "path"),
          ("variables", 0, "min"), ("variables", 1, "max"), ("variables", 1, "levels"),
          ("variables", 0, "name"), ("design", "method"), ("design", "levels"),
          ("design", "points"), ("design", "seed"), ("design", "candidates"),
          ("analysis", "method"),
          ("analysis", "responses"), ("analysis", "harmonics"), ("analysis", "samples"),
          ("analysis", "forces"), ("sweep", "workers"), ("sweep", "cache"),
          ("surrogate", "nugget"), ("surrogate", "mode"), ("surrogate", "starts"),
          ("surrogate", "responses"), ("objectives", 0, "terms"), ("objectives", 0, "name"),
          ("objectives", 0, "terms", 0, "goal"), ("objectives", 0, "terms", 1, "response"),
          ("objectives", 0, "terms", 0, "weight"), ("objectives", 0, "combine"),
          ("plots", "variables"), ("plots", "resolution"), ("plots", "responses")]
_mut_values = st.one_of(_values, st.just(_DELETE),
                        st.sampled_from(["lhs", "sobol", "grid", "maximin", "pareto", "max",
                                         "fourier",
                                         "cutters[0].pitch_mm", "separable", "l_c_mm",
                                         ["l_c_mm"], {"speed_ratio": 0.3}, [3, 3], 1e-3,
                                         "helical-14G", "psi_deg"]))


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(muts=st.lists(st.tuples(st.sampled_from(_PATHS), _mut_values), min_size=1, max_size=3))
def test_config_validation_fuzz_mutations_of_a_valid_study(muts):
    """Start from a valid study, change one to three keys: either still valid or
    one SpecError whose message starts with the offending key."""
    import re

    data = loads_toml(FULL, "config")
    for path, value in muts:
        node = data
        try:
            for k in path[:-1]:
                node = node[k]
            if value is _DELETE:
                node.pop(path[-1], None) if isinstance(node, dict) else None
            elif isinstance(node, dict) or (isinstance(node, list) and path[-1] < len(node)):
                node[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            continue  # an earlier mutation replaced a parent table
    try:
        cfg = config_from_dict(data)
    except SpecError as e:
        assert re.match(r"^[A-Za-z_][\w\[\].]*( |:)", str(e)), str(e)
        return
    assert len(cfg.variables) >= 1
    try:
        cfg.spec([v.lo for v in cfg.variables])
    except SpecError:
        pass


# -- evaluation of real tips --------------------------------------------------------
def test_responses_of_the_thesis_needle_match_the_angle_analysis():
    spec = tipgeo.preset("helical-14G")
    want = responses_from_summary(analyze(spec, method="exact").summary())
    cfg = cfg3()
    res = run_sweep(cfg, progress=False, cache=False)
    centre = [i for i, x in enumerate(res.X) if x.tolist() == [10.0, 13.5]]
    assert len(centre) == 1
    got = res.results[centre[0]]["responses"]
    assert set(got) == set(RESPONSES) - {k for k in RESPONSES if k.endswith("_N")}
    for k in THESIS:
        assert got[k] == pytest.approx(want[k], abs=1e-12), k
    # the preset is calibrated to Table 3.1: l_c of the thesis's CAD edge
    from tipgeo.calibrate import table_3_1_edge

    g = np.linspace(0, 2 * math.pi, 100001)
    r = tipgeo.Cannula.from_gauge(14).r_o
    p = np.stack([r * np.cos(g), r * np.sin(g), table_3_1_edge(g)], 1)
    assert got["l_c_mm"] == pytest.approx(np.linalg.norm(np.diff(p, axis=0), axis=1).sum(),
                                          rel=2e-3)
    # the table's spec column rebuilds that tip
    d = json.loads(res.columns()["spec"][centre[0]])
    assert d["cutters"][0]["helix_angle_deg"] == 10.0 and d["cutters"][0]["phi_deg"] == 13.5
    # l_c grows with φ and shrinks with ψ over the study box (monotone, Fig. 3.17a)
    Y = res.responses(["l_c_mm"]).reshape(3, 3)
    assert np.all(np.diff(Y, axis=1) > 0) and np.all(np.diff(Y, axis=0) < 0)


def test_force_means_are_recorded_when_asked():
    mech = pytest.importorskip("tipgeo.mechanics")
    cfg = loads_config(HELICAL_3X3.replace("levels = 3", "levels = 2") + """
[analysis]
responses = ["l_c_mm", "mean_F_perp_N", "mean_F_axial_N", "max_F_perp_N"]
forces = { speed_ratio = 0.3, tissue = "soft-tissue-3.1.5" }
""")
    res = run_sweep(cfg, X=np.array([[10.0, 13.5], [9.0, 15.0]]), cache=False, progress=False)
    assert res.ok.all()
    want = mech.tip_forces(tipgeo.preset("helical-14G"), 0.3,
                           tissue_name="soft-tissue-3.1.5").forces.summary()
    got = res.results[0]["responses"]
    for k in ("mean_F_perp_N", "mean_F_axial_N", "max_F_perp_N"):
        assert got[k] == pytest.approx(want[k], rel=1e-12), k
    assert res.results[1]["responses"]["mean_F_perp_N"] != got["mean_F_perp_N"]
    with pytest.raises(SpecError, match=r"analysis\.forces\.tissue = 'liver' is not valid"):
        loads_config(HELICAL_3X3 + '[analysis]\nforces = { speed_ratio = 1, tissue = "liver" }')


def test_invalid_configurations_are_recorded_not_raised(tmp_path):
    cfg = loads_config(HELICAL_3X3.replace("min = 9.0", "min = 5.0")
                       .replace("max = 15.0", "max = 20.0"))
    res = run_sweep(cfg, progress=False, cache=False)
    st_ = res.status.tolist()
    assert st_.count("invalid") >= 1 and st_.count("ok") >= 1
    bad = [r for r in res.results if r["status"] == "invalid"]
    # φ = 20° leans the calibrated needle so far towards the helix axis that
    # the helicoid folds over inside the tube: refused with that reason
    assert all("folds over inside the tube" in r["error"] or "too steep or curved" in r["error"]
               for r in bad)
    Y = res.responses()
    assert np.all(np.isnan(Y[~res.ok])) and np.all(np.isfinite(Y[res.ok]))
    s = res.summary()
    assert s["invalid"] == st_.count("invalid") and len(s["failures"]) == len(bad) + \
        st_.count("failed")
    text = write_table(res, tmp_path / "t.csv").read_text()
    assert "invalid" in text and "folds over inside the tube" in text


def test_a_crashing_analysis_is_a_failed_row_and_never_cached(tmp_path, monkeypatch):
    import tipgeo.angles

    real = tipgeo.angles.analyze

    def crashing(spec, **kw):
        if abs(spec.cutters[0].phi - math.radians(13.5)) < 1e-12:
            raise MemoryError("simulated")
        return real(spec, **kw)

    monkeypatch.setattr(tipgeo.angles, "analyze", crashing)
    cache = ResultCache(tmp_path / "c")
    res = run_sweep(cfg3(), cache=cache, progress=False)
    failed = [r for r in res.results if r["status"] == "failed"]
    assert len(failed) == 3 and all(r["error"] == "MemoryError: simulated" for r in failed)
    assert res.ok.sum() == 6
    assert cache.writes == 6  # possibly transient: recomputed next time


# -- cache ------------------------------------------------------------------------------
def test_cached_sweep_reruns_without_recomputing(tmp_path, monkeypatch):
    calls = []
    real = responses_mod.evaluate_spec

    def counting(d, a):
        calls.append(d["name"])
        return real(d, a)

    monkeypatch.setattr(responses_mod, "evaluate_spec", counting)
    cfg = cfg3()
    cache = ResultCache(tmp_path / "cache")
    first = run_sweep(cfg, cache=cache, progress=False)
    assert len(calls) == 9 and first.computed == 9 and first.cached == 0
    assert cache.writes == 9
    second = run_sweep(cfg, cache=ResultCache(tmp_path / "cache"), progress=False)
    assert len(calls) == 9  # not one more evaluation
    assert second.computed == 0 and second.cached == 9
    assert second.to_csv() == first.to_csv()
    # a different analysis is a different key: recomputed
    cfg_f = loads_config(HELICAL_3X3 + '\n[analysis]\nsamples = 1800\n')
    third = run_sweep(cfg_f, cache=ResultCache(tmp_path / "cache"), progress=False)
    assert third.computed == 9 and len(calls) == 18
    # damaged entries are recomputed, not trusted
    key = first.keys[4]
    victim = tmp_path / "cache" / key[:2] / f"{key}.json"
    victim.write_text("{not json", encoding="utf-8")
    fourth = run_sweep(cfg, cache=ResultCache(tmp_path / "cache"), progress=False)
    assert fourth.computed == 1 and len(calls) == 19
    assert not list((tmp_path / "cache").rglob("*.tmp"))


def test_results_from_workers_running_other_code_are_not_cached(tmp_path, monkeypatch):
    from tipgeo.optimize import sweep as sweep_mod

    real = sweep_mod.evaluate_spec_task

    def stale_worker(d, a):
        r = real(d, a)
        r["code"] = "0" * 64  # another tipgeo version
        return r

    monkeypatch.setattr(sweep_mod, "evaluate_spec_task", stale_worker)
    cache = ResultCache(tmp_path / "c")
    res = run_sweep(cfg3(), cache=cache, progress=False)
    assert res.ok.all() and cache.writes == 0
    assert res.summary()["foreign_code"] == 9
    assert all("code" not in r for r in res.results)


def test_equal_tips_hash_equal_whatever_their_spelling():
    cfg = cfg3()
    a = cfg.spec_dict([10, 13.5])
    b = json.loads(json.dumps(a))
    b["cutters"][0]["helix_angle_deg"] = 10  # int, not float
    b["name"] = "other name"
    an = dict(cfg.analysis)
    assert spec_key(a, an) == spec_key(b, an)
    assert spec_hash(a, an) == spec_hash(b, an) != spec_key(a, an)
    b["cutters"][0]["phi_deg"] = 13.5000001
    assert spec_key(a, an) != spec_key(b, an)
    assert spec_key(a, an) != spec_key(a, an | {"harmonics": 6})
    # the table's content hash is independent of the code version; the cache key is not
    from tipgeo.optimize import cache as cache_mod

    h, k = spec_hash(a, an), spec_key(a, an)
    cache_mod.code_fingerprint.cache_clear()
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(cache_mod, "code_fingerprint", lambda: "f" * 64)
            assert spec_hash(a, an) == h and spec_key(a, an) != k
    finally:
        cache_mod.code_fingerprint.cache_clear()


def test_equal_configurations_in_one_sweep_are_computed_once(monkeypatch):
    calls = []
    real = responses_mod.evaluate_spec
    monkeypatch.setattr(responses_mod, "evaluate_spec",
                        lambda d, a: calls.append(1) or real(d, a))
    cfg = cfg3()
    X = np.array([[10.0, 13.5], [10.0, 13.5], [9.0, 10.0]])
    res = run_sweep(cfg, X=X, cache=False, progress=False)
    assert len(calls) == 2 and res.computed == 2
    assert res.results[0] == res.results[1]


# -- tables ----------------------------------------------------------------------------
def test_tables_round_trip_csv_and_parquet(tmp_path):
    res = run_sweep(cfg3(), cache=False, progress=False)
    p = write_table(res, tmp_path / "s.csv")
    t = read_table(p)
    assert t["index"] == list(range(9))
    assert t["psi_deg"] == res.columns()["psi_deg"]
    assert t["l_c_mm"] == res.columns()["l_c_mm"]  # repr floats: exact round trip
    pytest.importorskip("pyarrow")
    q = write_table(res, tmp_path / "s.parquet")
    tq = read_table(q)
    assert tq["l_c_mm"] == res.columns()["l_c_mm"]
    assert tq["spec"] == res.columns()["spec"]
    assert sorted(os.listdir(tmp_path)) == ["s.csv", "s.parquet"]  # no temp files left
    with pytest.raises(SpecError, match=r"allowed \.csv, \.parquet"):
        write_table(res, tmp_path / "s.xlsx")


class _Recorder:
    """Stands in for a tqdm bar: what the sweep told it."""

    def __init__(self, log, total, desc, unit):
        self.log, self.total, self.desc, self.unit = log, total, desc, unit
        self.n, self.postfix, self.closed = 0, "", False
        log.append(self)

    def update(self, n=1):
        self.n += n

    def set_postfix_str(self, s="", refresh=True):
        self.postfix = s

    def refresh(self):
        pass

    def close(self):
        self.closed = True


@pytest.fixture
def bars(monkeypatch):
    """Progress on, every bar recorded (tipgeo.progress.bar replaced)."""
    from tipgeo import progress

    log = []
    monkeypatch.setattr(progress, "_mode", "on")
    monkeypatch.setattr(progress, "bar",
                        lambda total, desc, *, unit="it", leave=False:
                        _Recorder(log, total, desc, unit))
    return log


def test_sweep_progress_goes_through_tipgeo_progress(bars, tmp_path):
    cache = ResultCache(tmp_path / "c")
    run_sweep(cfg3(), cache=cache, progress=True)
    (b,) = bars
    assert (b.desc, b.unit, b.total, b.n, b.closed) == ("sweep h3", "config", 9, 9, True)
    assert b.postfix == ""  # nothing cached, nothing failed
    # the cached re-run counts its cache hits on the bar
    run_sweep(cfg3(), cache=ResultCache(tmp_path / "c"), progress=True)
    assert (bars[1].n, bars[1].postfix) == (9, "9 cached")


def test_progress_false_silences_the_bars(bars):
    run_sweep(cfg3(), cache=False, progress=False)
    assert bars == []


def test_maximin_screening_shows_one_bar_cached_on_the_re_run(bars, tmp_path):
    cfg = loads_config(HELICAL_3X3.replace("[design]\nlevels = 3",
                                           "[design]\nmethod = \"maximin\"\npoints = 4\n"
                                           "candidates = 25"))
    first = run_sweep(cfg, cache=ResultCache(tmp_path / "c"), progress=True)
    screen, sweep = bars
    v = first.design["validated"]
    assert (screen.desc, screen.unit, screen.total, screen.n) == ("screen h3", "spec", v, v)
    assert screen.closed and (sweep.desc, sweep.total) == ("sweep h3", 4)
    bars.clear()
    second = run_sweep(cfg, cache=ResultCache(tmp_path / "c"), progress=True)
    assert second.design == first.design | {"seconds": second.design["seconds"]}
    screen, sweep = bars
    assert screen.n == v and screen.postfix.startswith(f"{v} cached")
    assert sweep.postfix == "4 cached" and second.computed == 0


# -- executors -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def serial_table():
    return run_sweep(cfg3(), executor=SerialExecutor(), cache=False, progress=False).to_csv()


def test_local_processes_give_the_serial_table(serial_table):
    res = run_sweep(cfg3(), executor=ProcessExecutor(2), cache=False, progress=False)
    assert res.executor == "processes" and res.workers == 2
    assert res.to_csv() == serial_table


def test_dask_cluster_gives_the_local_table(serial_table):
    distributed = pytest.importorskip("distributed")
    from tipgeo.optimize import DaskExecutor

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        res = run_sweep(cfg3(), executor=DaskExecutor(client=client), cache=False,
                        progress=False)
        assert res.executor == "dask" and res.workers == 2
        assert res.to_csv() == serial_table  # every value bit for bit


def test_dask_bad_scheduler_is_a_clear_error():
    pytest.importorskip("distributed")
    from tipgeo.optimize import DaskExecutor

    with pytest.raises(SpecError, match=r"--scheduler = 'tcp://127\.0\.0\.1:9': cannot "
                                        r"connect"):
        run_sweep(cfg3(), executor=DaskExecutor("tcp://127.0.0.1:9", timeout_s=1.0),
                  cache=False, progress=False)


def test_sample_study_config_matches_the_built_in():
    from tipgeo.optimize.presets import HELICAL_STUDY_TOML

    assert (SAMPLES / "helical-study.toml").read_text(encoding="utf-8") == HELICAL_STUDY_TOML
    from tipgeo.optimize import load_config

    cfg = load_config(SAMPLES / "helical-study.toml")
    assert [v.path for v in cfg.variables] == ["cutters[0].helix_angle_deg",
                                              "cutters[0].phi_deg"]
    assert cfg.responses == THESIS and len(cfg.objectives) == 3
    assert cfg.design["method"] == "maximin" and cfg.design["points"] == 25
    # the plain 5 × 5 grid the thesis used would waste points on refused tips
    X = make_design(cfg.variables, "grid", levels=5)
    assert len(X) == 25 and X.min(0).tolist() == [5.0, 5.0] and X.max(0).tolist() == [25.0, 20.0]
    # every configuration is a valid tip or refused at validation with the
    # geometric reason (the needle leaning too far towards the helix axis)
    refused = 0
    for x in X:
        try:
            cfg.spec(x)
        except SpecError as e:
            refused += 1
            assert x[1] > 15.0
            assert "folds over inside the tube" in str(e) or "too steep or curved" in str(e)
    assert 0 < refused < 25


# -- missing optional tools: exit code 3, the install line named ---------------------------
def test_missing_dask_is_a_missing_tool_error(monkeypatch):
    from tipgeo.errors import MissingToolError
    from tipgeo.optimize import DaskExecutor

    monkeypatch.setitem(__import__("sys").modules, "distributed", None)  # import fails
    with pytest.raises(MissingToolError, match=r'pip install "dask\[distributed\]"') as e:
        run_sweep(cfg3(), executor=DaskExecutor("tcp://127.0.0.1:9"), cache=False,
                  progress=False)
    assert isinstance(e.value, SpecError)  # as before the family existed


@pytest.mark.parametrize("op", ["write", "read"])
def test_missing_pyarrow_is_a_missing_tool_error(monkeypatch, tmp_path, op):
    from tipgeo.errors import MissingToolError

    res = run_sweep(cfg3(), X=np.array([[10.0, 13.5]]), cache=False, progress=False)
    monkeypatch.setitem(__import__("sys").modules, "pyarrow", None)
    monkeypatch.setitem(__import__("sys").modules, "pyarrow.parquet", None)
    with pytest.raises(MissingToolError, match=r"pip install pyarrow .*allowed without it: "
                                               r"\.csv") as e:
        (write_table(res, tmp_path / "s.parquet") if op == "write"
         else read_table(tmp_path / "s.parquet"))
    assert isinstance(e.value, SpecError)


# -- the content hash is cheap: no geometric check ----------------------------------------
def test_content_hash_is_the_validated_canonical_form_without_validating(monkeypatch):
    """spec_hash normalises the keys as spec_from_dict does (so a valid spec
    hashes as its spec_to_dict form) but never runs the cutters' geometric
    checks: a cached sweep or screening re-run hashes every configuration."""
    from tipgeo.cutters.helical import HelicalCutter
    from tipgeo.optimize.cache import _canonical
    from tipgeo.presets import preset, preset_names
    from tipgeo.spec import spec_from_dict, spec_to_dict

    def validated(d):
        out = spec_to_dict(spec_from_dict(d))
        out.pop("name", None)
        out.pop("description", None)
        return out

    cfg = cfg3()
    dicts = ([spec_to_dict(preset(n)) for n in preset_names()]
             + [cfg.spec_dict(x, i) for i, x in enumerate(make_design(cfg.variables, "grid",
                                                                      levels=3))])
    expected = [validated(d) for d in dicts]
    calls = []
    orig = HelicalCutter.check
    monkeypatch.setattr(HelicalCutter, "check",
                        lambda self, cannula: calls.append(1) or orig(self, cannula))
    assert [_canonical(d) for d in dicts] == expected
    # equal tips hash equal however written (10 or 10.0 degrees)
    d = spec_to_dict(preset("bevel-14G-xi15"))
    d2 = json.loads(json.dumps(d))
    d2["cutters"][0]["xi_deg"] = 15
    assert spec_hash(d, {}) == spec_hash(d2, {})
    assert calls == []


def test_cached_maximin_re_run_validates_nothing(monkeypatch, tmp_path):
    from tipgeo.cutters.helical import HelicalCutter

    cfg = loads_config(HELICAL_3X3.replace("[design]\nlevels = 3",
                                           "[design]\nmethod = \"maximin\"\npoints = 4\n"
                                           "candidates = 25"))
    first = run_sweep(cfg, cache=ResultCache(tmp_path / "c"), progress=False)
    calls = []
    orig = HelicalCutter.check
    monkeypatch.setattr(HelicalCutter, "check",
                        lambda self, cannula: calls.append(1) or orig(self, cannula))
    monkeypatch.setattr(responses_mod, "evaluate_spec",
                        lambda *a: pytest.fail("a cached configuration was analysed"))
    second = run_sweep(cfg, cache=ResultCache(tmp_path / "c"), progress=False)
    assert calls == [] and second.computed == 0 and second.cached == 4
    assert second.to_csv() == first.to_csv()
    np.testing.assert_array_equal(second.screen["grid_ok"], first.screen["grid_ok"])
