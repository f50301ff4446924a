"""The thesis's 25-point helical study end to end (sweep → GP → three
objectives → the optima built and analysed), the CLI and the demo hook."""

import argparse
import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from tipgeo.demo.optimize import demo_outputs
from tipgeo.errors import SpecError
from tipgeo.optimize import read_table, study_preset
from tipgeo.optimize.responses import THESIS, evaluate_spec

OBJECTIVES = ["min-theta-max-lambda", "min-lc-max-lambda", "min-lc-min-theta"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    root = tmp_path_factory.mktemp("demo")
    files = demo_outputs(root)
    out = root / "helical-study"
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    return out, files, report


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", head[16:24])


def test_demo_writes_the_study(study):
    # its time is measured in benchmarks/test_optimize_bench.py, never here
    out, files, report = study
    names = sorted(Path(f).name for f in files)
    for n in ["sweep.csv", "surrogate.json", "report.json", "loo.png",
              "surface-l_c_mm.png", "surface-lambda_max_deg.png"]:
        assert n in names
    for o in OBJECTIVES:
        assert f"optimum-{o}.toml" in names
    for f in files:
        assert Path(f).exists() and Path(f).parent == out
    w, h = _png_size(out / "surface-l_c_mm.png")
    assert w > 1200 and h > 450
    assert not list(out.glob(".*tmp"))


def test_sweep_of_the_thesis_study(study):
    out, _, report = study
    s = report["sweep"]
    assert s["configurations"] == 25 and s["ok"] == 25 and s["computed"] == 25
    t = read_table(out / "sweep.csv")
    assert sorted(set(t["psi_deg"])) == [9.0, 9.5, 10.0, 10.5, 11.0]
    assert sorted(set(t["phi_deg"])) == [10.0, 11.75, 13.5, 15.25, 17.0]
    i = [k for k in range(25) if t["psi_deg"][k] == 10.0 and t["phi_deg"][k] == 13.5][0]
    assert t["l_c_mm"][i] == pytest.approx(18.058, abs=1e-3)  # the thesis needle


def test_loo_error_is_reported_for_every_response(study):
    _, _, report = study
    loo = report["surrogate"]["loo"]
    assert list(loo) == list(THESIS)
    for name in THESIS:
        assert all(math.isfinite(loo[name][k]) for k in ("rmse", "max_abs", "coverage95"))
    # the informative outputs are predicted to a fraction of a per mille of their spread
    assert loo["l_c_mm"]["rmse"] < 5e-3  # mm
    for name in ("l_c_mm", "lambda_max_deg", "theta_min_deg", "theta_max_deg",
                 "alpha_max_deg"):
        assert loo[name]["nrmse"] < 2e-3, name
    # λ_min and α_min are zero up to the dense grid's resolution: nothing to predict
    for name in ("lambda_min_deg", "alpha_min_deg"):
        assert loo[name]["max_abs"] < 0.05
    models = report["surrogate"]["models"]
    assert len(models) == 7 and all(m["nugget"] == 0.0 for m in models)
    assert all(-20 <= w <= 5 for m in models for w in m["omega"])


def test_three_objectives_of_table_3_4(study):
    _, _, report = study
    opt = {o["objective"]: o for o in report["optima"]}
    assert list(opt) == OBJECTIVES
    # min θ & max λ: both improve towards small ψ and large φ — the box corner
    x1 = opt["min-theta-max-lambda"]["x"]
    assert x1["psi_deg"] == pytest.approx(9.0, abs=1e-9)
    assert x1["phi_deg"] == pytest.approx(17.0, abs=1e-9)
    # the other two trade l_c against λ or θ: small ψ, an interior φ
    for name in OBJECTIVES[1:]:
        x = opt[name]["x"]
        assert x["psi_deg"] == pytest.approx(9.0, abs=1e-6)
        assert 11.0 < x["phi_deg"] < 13.0
    for name, o in opt.items():
        assert o["status"] == "ok", name
        r = o["responses"]
        # GP prediction against the real geometry, at the optimum
        assert abs(r["l_c_mm"]["error"]) < 0.01, name  # mm
        for k in ("lambda_max_deg", "theta_min_deg", "theta_max_deg", "alpha_max_deg"):
            assert abs(r[k]["error"]) < 0.005, (name, k)  # degrees


def test_optima_are_optimal_on_the_real_geometry(study):
    """The weighted objective evaluated on real analyses (not the GP) is no
    better at neighbours of the reported optimum than at it."""
    out, _, report = study
    cfg = study_preset("helical-study")
    t = read_table(out / "sweep.csv")
    rng = {k: (min(t[k]), max(t[k]) - min(t[k])) for k in ("l_c_mm", "lambda_max_deg",
                                                           "theta_min_deg")}

    def F(obj, x):
        r = evaluate_spec(cfg.spec_dict(x), dict(cfg.analysis))["responses"]
        s = []
        for term in obj.terms:
            lo, span = rng[term.response]
            v = (r[term.response] - lo) / span
            s.append(1 - v if term.goal == "max" else v)
        return float(np.mean(s))

    for o in report["optima"][1:]:
        obj = cfg.objective(o["objective"])
        x = np.array([o["x"]["psi_deg"], o["x"]["phi_deg"]])
        f0 = F(obj, x)
        for dx in ([0.0, 0.15], [0.0, -0.15], [0.15, 0.0]):  # ψ = 9 is the box's edge
            assert f0 <= F(obj, x + np.array(dx)) + 2e-4, (o["objective"], dx)


def test_optimum_spec_files_rebuild_the_optimum(study):
    import tipgeo

    out, _, report = study
    o = report["optima"][1]
    spec = tipgeo.load_spec(out / f"optimum-{o['objective']}.toml")
    c = spec.cutters[0]
    assert math.degrees(c.helix_angle) == pytest.approx(o["x"]["psi_deg"], abs=1e-9)
    assert math.degrees(c.phi) == pytest.approx(o["x"]["phi_deg"], abs=1e-9)
    assert o["build"]["watertight"] is True and o["build"]["triangles"] > 1000


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
    assert read_table(table)["l_c_mm"][4] == pytest.approx(18.058, abs=1e-3)


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
