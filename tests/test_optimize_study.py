"""The thesis's 25-point helical study end to end (sweep → GP → three
objectives → the optima built and analysed), the CLI and the demo hook."""

import argparse
import json
import math

import numpy as np
import pytest

import tipgeo
from tipgeo.errors import SpecError
from tipgeo.optimize import (
    SerialExecutor,
    loads_config,
    make_design,
    read_table,
    run_study,
    study_preset,
)

# The shipped study (25 points over ψ 5–25°, φ 5–20°, three optima built) takes
# ~60 s CPU: its time is measured in benchmarks/, never here. These tests run the
# same pipeline on a 4 × 4 grid over the same box, where some points are refused.
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
levels = 4
[analysis]
responses = ["l_c_mm", "lambda_max_deg", "theta_min_deg"]
[surrogate]
starts = 4
[[objectives]]
name = "min-lc-max-lambda"
terms = [{ response = "l_c_mm", goal = "min" }, { response = "lambda_max_deg", goal = "max" }]
[[objectives]]
name = "min-lc-min-theta"
terms = [{ response = "l_c_mm", goal = "min" }, { response = "theta_min_deg", goal = "min" }]
"""
OBJECTIVES = ["min-lc-max-lambda", "min-lc-min-theta"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("wide")
    cfg = loads_config(WIDE)
    report = run_study(cfg, out, executor=SerialExecutor(), cache=False, progress=False,
                       build=False, plots=False, log=lambda s: None)
    return out, cfg, report


def test_the_shipped_study_spans_the_whole_box():
    cfg = study_preset("helical-study")
    assert cfg.bounds == [(5.0, 25.0), (5.0, 20.0)]
    assert len(make_design(cfg.variables, cfg.design["method"], levels=cfg.design["levels"])) == 25
    # beyond φ ≈ 15° the calibrated needle leans so far that the helicoid folds
    # over inside the tube: refused at validation, with the geometric reason
    with pytest.raises(SpecError, match="folds over inside the tube"):
        cfg.spec(np.array([5.0, 20.0]))
    cfg.spec(np.array([10.0, 13.5]))  # the thesis needle validates


def test_refused_points_are_reported_and_left_out_of_the_gp(study):
    out, cfg, report = study
    s = report["sweep"]
    assert s["configurations"] == 16 and s["failed"] == 0
    assert s["invalid"] >= 1 and s["ok"] + s["invalid"] == 16
    assert all(f["status"] == "invalid" and "helical cutter" in f["error"]
               for f in s["failures"])
    t = read_table(out / "sweep.csv")
    assert sorted(set(t["psi_deg"])) == pytest.approx([5.0, 35 / 3, 55 / 3, 25.0])
    assert sorted(set(t["phi_deg"])) == [5.0, 10.0, 15.0, 20.0]
    bad = [k for k in range(16) if t["status"][k] != "ok"]
    assert len(bad) == s["invalid"]
    assert all(t["phi_deg"][k] == 20.0 for k in bad)  # the folding side of the box
    # LOO over the ok rows only: finite, and interpolating the training data
    loo = report["surrogate"]["loo"]
    assert set(loo) == {"l_c_mm", "lambda_max_deg", "theta_min_deg"}
    for name, v in loo.items():
        assert all(math.isfinite(v[k]) for k in ("rmse", "max_abs", "coverage95")), name
        assert 0.0 <= v["coverage95"] <= 1.0


def test_optima_are_feasible_inside_the_box_and_verified(study):
    out, cfg, report = study
    opt = {o["objective"]: o for o in report["optima"]}
    assert list(opt) == OBJECTIVES
    t = read_table(out / "sweep.csv")
    span = {k: max(t[k][i] for i in range(16) if t["status"][i] == "ok")
            - min(t[k][i] for i in range(16) if t["status"][i] == "ok")
            for k in ("l_c_mm", "lambda_max_deg", "theta_min_deg")}
    for name, o in opt.items():
        x = np.array([o["x"]["psi_deg"], o["x"]["phi_deg"]])
        assert np.all(x >= [5.0, 5.0]) and np.all(x <= [25.0, 20.0])
        cfg.spec(x)  # validates: the optimiser never proposes a refused point
        assert o["status"] == "ok", name
        for e in o["on_box_edge"]:  # reported edges are really on the box's edge
            i = ["psi_deg", "phi_deg"].index(e["variable"])
            assert x[i] == pytest.approx(cfg.bounds[i][0 if e["side"] == "min" else 1])
        assert isinstance(o["on_buildable_boundary"], bool)
        for k, r in o["responses"].items():
            # the real geometry was analysed: the GP of 16 points is within 15 % of the range
            assert math.isfinite(r["actual"]) and abs(r["error"]) < 0.15 * span[k], (name, k)
        spec = tipgeo.load_spec(out / f"optimum-{name}.toml")
        c = spec.cutters[0]
        assert math.degrees(c.helix_angle) == pytest.approx(x[0], abs=1e-9)
        assert math.degrees(c.phi) == pytest.approx(x[1], abs=1e-9)


# -- CLI ---------------------------------------------------------------------------------
SMALL = """
name = "small"
base = "helical-14G"
[[variables]]
name = "psi_deg"
path = "cutters[0].helix_angle_deg"
min = 9.5
max = 10.5
[[variables]]
name = "phi_deg"
path = "cutters[0].phi_deg"
min = 12.0
max = 15.0
[design]
levels = 3
[analysis]
responses = ["l_c_mm", "lambda_max_deg"]
[sweep]
workers = 1
cache = "cache"
[surrogate]
starts = 4
[[objectives]]
name = "short-and-inclined"
combine = "pareto"
terms = [{ response = "l_c_mm", goal = "min" }, { response = "lambda_max_deg", goal = "max" }]
"""


def _run(argv):
    from tipgeo.cli.optimize import register

    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="command", required=True)
    register(sub)
    args = p.parse_args(argv)
    return args.func(args)


def test_cli_sweep_writes_a_table_and_reuses_the_cache(tmp_path, capsys):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL, encoding="utf-8")
    table = tmp_path / "t.csv"
    assert _run(["sweep", str(cfg), "-o", str(table), "--json", "--quiet"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["ok"] == 9 and first["computed"] == 9 and first["table"] == str(table)
    assert (tmp_path / "cache").is_dir()  # sweep.cache is relative to the config
    assert _run(["sweep", str(cfg), "-o", str(table), "--json", "--quiet"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert second["computed"] == 0 and second["cached"] == 9
    assert _run(["sweep", str(cfg), "-o", str(table), "--no-cache", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("small: 9 configurations — 9 ok, 0 invalid, 0 failed; 9 computed")
    # the calibrated helical-14G
    assert read_table(table)["l_c_mm"][4] == pytest.approx(18.185, abs=1e-3)


def test_cli_optimize_json_report(tmp_path, capsys):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL, encoding="utf-8")
    out = tmp_path / "out"
    assert _run(["optimize", str(cfg), "--out", str(out), "--no-plots", "--no-build",
                 "--json", "--quiet"]) == 0
    rep = json.loads(capsys.readouterr().out)
    o = rep["optima"][0]
    assert o["combine"] == "pareto" and o["pareto_points"] > 10 and o["status"] == "ok"
    assert abs(o["responses"]["l_c_mm"]["error"]) < 0.05  # mm; a 9-point GP
    assert set(rep["surrogate"]["loo"]) == {"l_c_mm", "lambda_max_deg"}
    assert (out / "report.json").exists() and (out / "optimum-short-and-inclined.toml").exists()
    assert "build" not in o
    assert _run(["optimize", str(cfg), "--out", str(out), "--no-plots", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "short-and-inclined (min l_c_mm & max lambda_max_deg, pareto)" in text
    assert "GP prediction ± 95 %" in text


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
