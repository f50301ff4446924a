"""The study pipeline end to end (sweep → GP → objectives → adaptive infill →
optima verified and built), the calibrated LOO intervals, the CLI and the
shipped helical study's box.

The shipped study (25 helical tips, infill, three optima built, pictures) is
timed in benchmarks/test_optimize_bench.py, never here. These tests run the
same pipeline on cheap cases: a one-variable bevel study (an analysis costs
~0.1 s) for the infill loop, edge reporting and the CLI, and a 3 × 3 grid over
the helical box for refused points.
"""

import json
import math

import numpy as np
import pytest
from scipy.special import ellipe

import tipgeo
from tipgeo.errors import SpecError
from tipgeo.optimize import (
    SerialExecutor,
    Surrogate,
    loads_config,
    read_table,
    run_study,
    study_preset,
)
from tipgeo.optimize.gp import Z95

R_O = 2.108 / 2  # 14G outer radius (mm)

# l_c falls with ξ, θ_min rises with it: "short-and-sharp" has an interior
# optimum, "shortest" sits on the box's edge ξ = 45°.
BEVEL = """
name = "bevel"
base = "bevel-14G-xi14.5"
[[variables]]
name = "xi_deg"
path = "cutters[0].xi_deg"
min = 15.0
max = 45.0
[design]
levels = 3
[analysis]
responses = ["l_c_mm", "theta_min_deg"]
[sweep]
workers = 1
cache = "cache"
[surrogate]
starts = 3
calibrate = true
[infill]
rounds = 6
threshold = 0.01
[[objectives]]
name = "short-and-sharp"
terms = [{ response = "l_c_mm", goal = "min" }, { response = "theta_min_deg", goal = "min" }]
[[objectives]]
name = "shortest"
terms = [{ response = "l_c_mm", goal = "min" }]
"""


def bevel_l_c(xi_deg):
    """Outer edge of a one-plane bevel: an ellipse of semi-axes r_o/sin ξ and
    r_o, so l_c = 4a E(1 − sin²ξ) (complete elliptic integral, parameter m)."""
    s = math.sin(math.radians(xi_deg))
    return 4 * (R_O / s) * ellipe(1 - s * s)


@pytest.fixture(scope="module")
def bevel_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("bevel")
    cfg = loads_config(BEVEL, base_dir=out)
    report = run_study(cfg, out / "study", executor=SerialExecutor(), cache=False,
                       progress=False, build=True, plots=True, log=lambda s: None)
    return out, cfg, report


def test_infill_adds_points_until_the_gp_is_right_at_every_optimum(bevel_study):
    out, cfg, rep = bevel_study
    inf = rep["infill"]
    assert inf["converged"] and 1 <= inf["added"] and inf["rounds"] <= 1 + cfg.infill["rounds"]
    hist = inf["history"]
    assert {h["round"] for h in hist} == set(range(inf["rounds"]))
    # a round adds exactly the optima that missed; the last round adds none and
    # every optimum in it is within 1 % of each response's training range
    assert [h for h in hist if h["added"]] == [h for h in hist if h["round"] < inf["rounds"] - 1
                                               and h["max_error_frac"] > 0.01]
    last = [h for h in hist if h["round"] == inf["rounds"] - 1]
    assert len(last) == 2 and all(h["max_error_frac"] <= 0.01 for h in last)
    # the added points are training points now, with their real responses
    sur = rep["surrogate"]
    assert sur["training_points"] == 3 + inf["added"]
    for p in inf["points"]:
        assert 15.0 <= p["xi_deg"] <= 45.0
    # the history's actual values are the real geometry's (closed form of l_c)
    for h in hist:
        xi = h["x"]["xi_deg"]
        assert h["responses"]["l_c_mm"]["actual"] == pytest.approx(bevel_l_c(xi), rel=1e-6)
    # the last round's errors are relative to the final training set's ranges
    for h in last:
        for name, r in h["responses"].items():
            err = abs(r["actual"] - r["predicted"])
            assert r["error_frac"] == pytest.approx(err / sur["training_ranges"][name],
                                                    rel=1e-9, abs=1e-15)


def test_optima_are_verified_built_and_edges_reported(bevel_study):
    out, cfg, rep = bevel_study
    opt = {o["objective"]: o for o in rep["optima"]}
    assert list(opt) == ["short-and-sharp", "shortest"]
    # l_c falls monotonically with ξ: the shortest edge is at the box's edge ξ = 45°
    s = opt["shortest"]
    assert s["x"]["xi_deg"] == pytest.approx(45.0, abs=1e-9)
    assert s["on_box_edge"] == [{"variable": "xi_deg", "side": "max"}]
    assert s["on_buildable_boundary"] is False
    # the compromise is inside the box, and not reported as on its edge
    c = opt["short-and-sharp"]
    assert 15.0 < c["x"]["xi_deg"] < 45.0 and c["on_box_edge"] == []
    for o in opt.values():
        assert o["status"] == "ok" and o["search"]["starts"] >= 1
        assert o["search"]["candidates"] > 1000
        b = o["build"]
        assert b["watertight"] and b["volume_mm3"] > 0 and b["cpu_seconds"] > 0
        for name, r in o["responses"].items():
            assert r["error_frac"] <= 0.01, (o["objective"], name)
            assert r["error"] == pytest.approx(r["actual"] - r["predicted"], abs=1e-12)
        assert o["responses"]["l_c_mm"]["actual"] == pytest.approx(
            bevel_l_c(o["x"]["xi_deg"]), rel=1e-6)
        spec = tipgeo.load_spec(out / "study" / f"optimum-{o['objective']}.toml")
        assert math.degrees(spec.cutters[0].xi) == pytest.approx(o["x"]["xi_deg"], abs=1e-9)
    assert rep["sweep"]["ok"] == 3
    for png in ("surface-l_c_mm.png", "surface-theta_min_deg.png", "loo.png"):
        data = (out / "study" / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, png


def test_calibrated_intervals_hold_the_stated_share_of_loo_points():
    """calibrate = true: per response, σ̂ is scaled so that round(0.95 n) of the
    n LOO residuals (at most n − 1) lie inside their 95 % intervals; the mean
    is untouched and the factor sits halfway between the neighbouring
    standardised residuals."""
    from scipy.stats import qmc

    def f(X):
        return np.column_stack([np.sin(4 * X[:, 0]) + X[:, 1] ** 2,
                                np.exp(X[:, 0] - X[:, 1])])

    for n, inside in ((20, 19), (16, 15), (25, 24)):
        X = qmc.LatinHypercube(2, seed=n).random(n)
        kw = {"bounds": [(0, 1), (0, 1)], "responses": ["a", "b"], "starts": 3}
        raw = Surrogate(**kw).fit(X, f(X))
        cal = Surrogate(calibrate=True, **kw).fit(X, f(X))
        loo = cal.loo()
        Xt = qmc.Sobol(2, seed=1).random(16)
        m0, s0 = raw.predict(Xt, return_std=True)
        m1, s1 = cal.predict(Xt, return_std=True)
        np.testing.assert_allclose(m1, m0, rtol=0, atol=1e-12)
        for j, name in enumerate(["a", "b"]):
            assert loo[name]["coverage95"] == inside / n
            np.testing.assert_allclose(s1[:, j], s0[:, j] * cal.scale_[j], rtol=1e-12)
            res, std = raw.models[j].loo()
            z = np.sort(np.abs(res) / (Z95 * std))
            assert cal.scale_[j] == pytest.approx(0.5 * (z[inside - 1] + z[inside]), rel=1e-12)
            assert loo[name]["interval_scale"] == cal.scale_[j]


# -- the helical box --------------------------------------------------------------------
def test_the_shipped_study_spans_the_whole_box():
    cfg = study_preset("helical-study")
    assert cfg.bounds == [(5.0, 25.0), (5.0, 20.0)]
    # 25 admissible points chosen among a 21 × 21 candidate grid (tests/test_optimize_design.py)
    assert cfg.design == {"method": "maximin", "levels": None, "points": 25, "seed": 0,
                          "candidates": 441}
    assert cfg.surrogate["calibrate"] is False and cfg.surrogate["kernel"] == "matern52"
    # θ_max is smooth (no kink): the likelihood prefers Matérn 7/2 (README)
    assert cfg.surrogate["response_kernels"] == {"theta_max_deg": "matern72"}
    assert cfg.infill == {"rounds": 8, "threshold": 0.01,
                          "responses": ("theta_min_deg", "lambda_max_deg", "l_c_mm")}
    # beyond φ ≈ 16° the calibrated needle leans so far that the helicoid folds
    # over inside the tube: refused at validation, with the geometric reason
    with pytest.raises(SpecError, match="folds over inside the tube"):
        cfg.spec(np.array([5.0, 20.0]))
    # near that limit the spec validates: analysis needs no mesh (issue 28), the
    # grid is chosen when a tip is built, at the tolerance asked
    cfg.spec(np.array([5.0, 16.4]))
    cfg.spec(np.array([10.0, 13.5]))  # the thesis needle validates


WIDE = """
name = "wide"
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
levels = 3
[analysis]
responses = ["l_c_mm", "theta_min_deg"]
[surrogate]
starts = 2
[infill]
rounds = 0
[[objectives]]
name = "min-lc-min-theta"
terms = [{ response = "l_c_mm", goal = "min" }, { response = "theta_min_deg", goal = "min" }]
"""


def test_shipped_study_loo_intervals_are_calibrated():
    """Issue 13: the shipped study's GP (25 maximin points; Matérn 5/2, θ_max
    Matérn 7/2) has leave-one-out 95 % intervals that hold — at most 3 of the
    25 points outside (coverage ≥ 0.88) — and are not much too wide: the RMS
    of the standardised LOO residuals z = r/s is within [0.5, 1.5] (1 for a
    calibrated model), for every response with a signal. An upper bound on
    the coverage alone would fail a calibrated model often (25 of 25 inside
    has probability 0.28 at 95 %). Measured since issue 28's helical design
    space (the box's φ edge now builds): coverage 1.0 for all five, RMS z
    0.69 (l_c), 0.81 (λ_max), 0.81 (θ_min), 0.80 (θ_max), 0.81 (α_max),
    largest |z| 1.92. λ_min ≈ 1e-7° and α_min ≈ 0.01° are round-off-level
    (NRMSE ≈ 1: their values differ between CPUs), so their coverage is not
    a property of the model."""
    from tipgeo.optimize import fit_surrogate, run_sweep
    from tipgeo.optimize.presets import study_preset

    cfg = study_preset("helical-study")
    sweep = run_sweep(cfg, executor=SerialExecutor(), cache=False, progress=False)
    assert int(sweep.ok.sum()) == 25  # all admissible, none failed
    gp = fit_surrogate(sweep)
    loo = gp.loo()
    assert loo["theta_max_deg"]["kernel"] == "matern72"
    for name in ("l_c_mm", "lambda_max_deg", "theta_min_deg", "theta_max_deg",
                 "alpha_max_deg"):
        j = gp.responses.index(name)
        z = gp.loo_residuals_[:, j] / gp.loo_std_[:, j]
        assert loo[name]["coverage95"] >= 0.88, (name, loo[name]["coverage95"])
        assert 0.5 <= float(np.sqrt(np.mean(z ** 2))) <= 1.5, (name, z)
        assert loo[name]["nrmse"] < 0.05, (name, loo[name]["nrmse"])


def test_refused_helical_points_are_reported_and_left_out_of_the_gp(tmp_path):
    cfg = loads_config(WIDE)
    rep = run_study(cfg, tmp_path, executor=SerialExecutor(), cache=False, progress=False,
                    build=False, plots=False, log=lambda s: None)
    s = rep["sweep"]
    assert (s["configurations"], s["ok"], s["invalid"], s["failed"]) == (9, 6, 3, 0)
    assert all("folds over inside the tube" in f["error"] for f in s["failures"])
    t = read_table(tmp_path / "sweep.csv")
    assert [t["phi_deg"][k] for k in range(9) if t["status"][k] != "ok"] == [20.0] * 3
    assert rep["surrogate"]["training_points"] == 6
    # rounds = 0: the optimum is verified, nothing is added
    assert rep["infill"]["added"] == 0 and len(rep["infill"]["history"]) == 1
    o = rep["optima"][0]
    x = np.array([o["x"]["psi_deg"], o["x"]["phi_deg"]])
    cfg.spec(x)  # the optimiser never proposes a refused point
    assert o["status"] == "ok" and all(math.isfinite(r["actual"])
                                       for r in o["responses"].values())
    for e in o["on_box_edge"]:  # reported edges are really on the box's edge
        i = ["psi_deg", "phi_deg"].index(e["variable"])
        assert x[i] == pytest.approx(cfg.bounds[i][0 if e["side"] == "min" else 1])


def test_edge_report_names_the_box_edge_and_why_a_step_further_is_refused():
    from tipgeo.optimize.study import edge_report, feasibility

    cfg = loads_config(WIDE)
    feasible = feasibility(cfg)
    # ψ on its lower bound; φ 0.45° further still builds (no mesh cap at
    # validation since issue 28), so it is no buildable boundary
    r = edge_report(cfg, np.array([5.0, 16.0]), feasible, step=0.03)
    assert r == {"on_box_edge": [{"variable": "psi_deg", "side": "min"}],
                 "on_buildable_boundary": False}
    # φ = 16.6° builds, a step of 0.03 of φ's range further (17.05°) folds over
    r = edge_report(cfg, np.array([5.0, 16.6]), feasible, step=0.03)
    assert r["on_buildable_boundary"] is True
    assert "meets the tube wall" in r["buildable_boundary_reason"]
    # a third of the range further (φ = 20°), past the fold: the geometric reason
    r = edge_report(cfg, np.array([25.0, 15.0]), feasible, step=1 / 3)
    assert r["on_box_edge"] == [{"variable": "psi_deg", "side": "max"}]
    assert "folds over inside the tube" in r["buildable_boundary_reason"]
    # inside, away from both
    r = edge_report(cfg, np.array([15.0, 10.0]), feasible)
    assert r == {"on_box_edge": [], "on_buildable_boundary": False}


# -- CLI ---------------------------------------------------------------------------------
def _run(argv):
    from tipgeo.cli import build_parser

    args = build_parser(argv[0]).parse_args(argv)
    return args.func(args)


def test_cli_sweep_writes_a_table_and_reuses_the_cache(tmp_path, capsys):
    cfg = tmp_path / "bevel.toml"
    cfg.write_text(BEVEL, encoding="utf-8")
    table = tmp_path / "t.csv"
    assert _run(["sweep", str(cfg), "-o", str(table), "--json", "--quiet"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["ok"] == 3 and first["computed"] == 3 and first["table"] == str(table)
    assert (tmp_path / "cache").is_dir()  # sweep.cache is relative to the config
    assert _run(["sweep", str(cfg), "-o", str(table), "--json", "--quiet"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert second["computed"] == 0 and second["cached"] == 3
    t = read_table(table)
    assert t["xi_deg"] == [15.0, 30.0, 45.0]
    assert t["l_c_mm"] == pytest.approx([bevel_l_c(x) for x in (15, 30, 45)], rel=1e-6)


def test_cli_optimize_report(tmp_path, capsys):
    cfg = tmp_path / "bevel.toml"
    cfg.write_text(BEVEL, encoding="utf-8")
    out = tmp_path / "out"
    assert _run(["optimize", str(cfg), "--out-dir", str(out), "--no-pictures", "--no-build",
                 "--json", "--quiet"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["infill"]["converged"] and rep["infill"]["added"] >= 1
    assert set(rep["surrogate"]["loo"]) == {"l_c_mm", "theta_min_deg"}
    n = rep["surrogate"]["training_points"]
    k = min(math.floor(0.95 * n + 0.5), n - 1)
    for v in rep["surrogate"]["loo"].values():  # calibrated: k of n inside
        assert v["coverage95"] == pytest.approx(k / n, abs=1e-12)
    assert all("build" not in o for o in rep["optima"])
    assert (out / "report.json").exists() and (out / "optimum-shortest.toml").exists()
    # again, in plain text: everything from the cache (the infill points too)
    assert _run(["optimize", str(cfg), "--out-dir", str(out), "--no-pictures", "--no-build"]) == 0
    text = capsys.readouterr().out
    assert "shortest (min l_c_mm, weighted): xi_deg = 45.0000" in text
    assert "on the box edge: xi_deg = max" in text
    assert "GP prediction ± 95 %" in text and "% of range" in text
    assert "infill:" in text and "converged" in text


@pytest.mark.parametrize("argv, match", [
    (["sweep", "no-such-study"], r"CONFIG = 'no-such-study' is neither a study file .* "
                                 r"built-in: helical-study"),
    (["sweep", "missing.toml"], r"config file 'missing.toml' does not exist"),
    (["sweep", "helical-study", "--workers", "0"], r"--workers = 0 is out of range"),
    (["optimize", "helical-study", "--workers", "2", "--scheduler", "tcp://x:1"],
     r"--workers and --scheduler exclude each other"),
])
def test_cli_bad_input_is_a_spec_error(argv, match):
    with pytest.raises(SpecError, match=match):
        _run(argv)


def test_the_search_refuses_unvalidated_only_where_the_grid_saw_nothing_buildable(
        monkeypatch):
    """search_feasibility: a point in a cell of the screened candidate grid with
    no admissible node is refused without validation; every other point is
    validated, so everything it admits is buildable."""
    from tipgeo.cutters.helical import HelicalCutter
    from tipgeo.optimize import run_sweep
    from tipgeo.optimize.study import feasibility, grid_verdicts, search_feasibility

    cfg = loads_config(WIDE.replace("[design]\nlevels = 3",
                                    "[design]\nmethod = \"maximin\"\npoints = 6\n"
                                    "candidates = 25"))
    sw = run_sweep(cfg, executor=SerialExecutor(), cache=False, progress=False)
    assert not sw.screen["grid_ok"].all()  # φ = 20° is past the fold
    calls = []
    orig = HelicalCutter.check
    monkeypatch.setattr(HelicalCutter, "check",
                        lambda self, cannula: calls.append(1) or orig(self, cannula))
    search = search_feasibility(cfg, feasibility(cfg), sw.screen)
    P = np.array(np.meshgrid(np.linspace(5.0, 25.0, 21), np.linspace(5.0, 20.0, 21))
                 ).reshape(2, -1).T
    X = P[~grid_verdicts(cfg, sw.screen)(P)]  # cells with no admissible node
    assert len(X) >= 10 and np.all(X[:, 1] >= 16.25)  # at or beyond the fold, all of them
    assert not search(X).any() and calls == []
    Y = np.column_stack([np.linspace(5.0, 25.0, 5), np.linspace(6.0, 14.0, 5)])
    ok = search(Y)
    assert len(calls) == 5 and ok.all()  # validated, one each
    for y in Y:
        cfg.spec(y)
    assert search_feasibility(cfg, feasibility(cfg), None) is not None


def test_optima_carry_their_region_of_indistinguishable_designs(bevel_study):
    """Issue 28: every weighted optimum states how flat its objective is
    there — the GP sd of the objective, the designs within the GP's 95 % of
    it, their extent per variable, and the optimum's place in the box. The
    bevel's l_c falls steeply with ξ (l_c ∝ ~1/sin ξ): 'shortest' sits on the
    ξ = 45° bound, sharp."""
    out, cfg, rep = bevel_study
    by = {o["objective"]: o for o in rep["optima"]}
    reg = by["shortest"]["region"]
    assert reg["box_position"] == "corner"          # one variable: its bound is a corner
    assert reg["at_bounds"] == [{"variable": "xi_deg", "side": "max"}]
    assert reg["shape"] == "sharp" and reg["flat_along"] == []
    lo, hi = reg["extent"]["xi_deg"]
    assert lo <= by["shortest"]["x"]["xi_deg"] <= hi and hi == pytest.approx(45.0, abs=1e-6)
    assert reg["extent_fraction"]["xi_deg"] == pytest.approx((hi - lo) / 30.0, rel=1e-12)
    assert reg["std"] >= 0 and reg["members"] >= 0 and reg["candidates"] == 2048
    assert "points" not in reg                       # JSON: the figures, not the cloud
    saved = json.loads((out / "study" / "report.json").read_text())
    assert saved["optima"][1]["region"]["shape"] == reg["shape"]
    for o in rep["optima"]:
        assert o["region"]["shape"] in ("sharp", "ridge", "flat")
