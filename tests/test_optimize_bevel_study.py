"""The shipped bevel study (``bevel-study``) optimises out of the box, checked
against the bevel's closed forms; responses constant over the design are not
fitted, an objective on one is named flat; the study's verdict.

A one-plane bevel of bevel angle ξ has (tipgeo.closedforms, thesis Table 3.2)
θ_min = ξ at the tip, λ_max = 90° − ξ at γ = ±90°, λ_min = α_min = 0 (at the
heel and γ = ±90°) and l_c the perimeter of the ellipse of semi-axes r_o/sin ξ
and r_o. Each analysis costs ~0.1 s: the whole shipped study (13 points, three
objectives, no build, no pictures) runs in a few seconds.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from tipgeo.closedforms import bevel_edge_length
from tipgeo.optimize import SerialExecutor, load_config, loads_config, run_study, study_preset
from tipgeo.optimize.presets import BEVEL_STUDY_TOML, STUDIES, resolve_study
from tipgeo.optimize.responses import THESIS
from tipgeo.optimize.study import constant_responses, flat_message

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
R_O = 2.108 / 2  # 14G outer radius (mm)


def l_c(xi_deg):
    return float(bevel_edge_length(R_O, math.radians(xi_deg)))


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    cfg = study_preset("bevel-study")
    out = tmp_path_factory.mktemp("bevel-study")
    rep = run_study(cfg, out, executor=SerialExecutor(), cache=False, progress=False,
                    build=False, plots=False, log=lambda s: None)
    return cfg, rep


def test_the_sample_is_the_built_in_study():
    assert (SAMPLES / "bevel-study.toml").read_text(encoding="utf-8") == BEVEL_STUDY_TOML
    assert list(STUDIES) == ["helical-study", "bevel-study"]
    cfg = load_config(SAMPLES / "bevel-study.toml")
    assert resolve_study("bevel-study").variables == cfg.variables
    assert [(v.path, v.lo, v.hi) for v in cfg.variables] == [("cutters[0].xi_deg", 15.0, 75.0)]
    assert cfg.responses == THESIS  # all seven recorded ...
    assert cfg.modelled == ("l_c_mm", "lambda_max_deg", "theta_min_deg")  # ... three modelled


def test_the_bevel_study_converges_and_every_optimum_is_verified(shipped):
    cfg, rep = shipped
    assert rep["verdict"]["ok"], rep["verdict"]["reasons"]
    assert rep["verdict"]["reasons"] == []
    assert rep["sweep"]["ok"] == 13 and rep["infill"]["converged"]
    # λ_min and α_min are 0 wherever ξ is: not fitted, listed as constant
    assert rep["responses"]["constant"] == {"lambda_min_deg": 0.0, "alpha_min_deg": 0.0}
    assert rep["responses"]["fitted"] == ["l_c_mm", "lambda_max_deg", "theta_min_deg"]
    assert rep["responses"]["not_fitted"] == ["theta_max_deg", "alpha_max_deg"]
    assert set(rep["surrogate"]["loo"]) == {"l_c_mm", "lambda_max_deg", "theta_min_deg"}
    assert rep["surrogate"]["constant"] == {"lambda_min_deg": 0.0, "alpha_min_deg": 0.0}
    assert [o["objective"] for o in rep["optima"]] == [o.name for o in cfg.objectives]
    for o in rep["optima"]:
        assert o["status"] == "ok" and "flat_terms" not in o
        xi = o["x"]["xi_deg"]
        assert 15.0 <= xi <= 75.0
        act = {k: r["actual"] for k, r in o["responses"].items()}
        # the real analysis at the optimum is the closed form (measured: 2e-12 mm, 1e-14°)
        assert act["theta_min_deg"] == pytest.approx(xi, abs=1e-9)
        assert act["lambda_max_deg"] == pytest.approx(90.0 - xi, abs=1e-9)
        assert act["l_c_mm"] == pytest.approx(l_c(xi), rel=1e-9)
        # and the GP is within the infill threshold (1 % of each range) there
        for r in o["responses"].values():
            assert r["error_frac"] <= 0.01


def _scaled(xi):
    """The objectives' scaled terms on the training set's ranges (13 grid
    points with both ends: l_c from l_c(75°) to l_c(15°), θ_min and λ_max over
    60°): s_lc, and s_θ = s_λ = (ξ − 15°)/60°."""
    lo, hi = l_c(75.0), l_c(15.0)
    return (l_c(xi) - lo) / (hi - lo), (xi - 15.0) / 60.0


def test_the_optima_are_optimal_by_the_closed_forms(shipped):
    _, rep = shipped
    opt = {o["objective"]: o for o in rep["optima"]}
    # θ_min and λ_max both want the smallest ξ: the box's edge
    first = opt["min-theta-max-lambda"]
    assert first["x"]["xi_deg"] == pytest.approx(15.0, abs=1e-9)
    assert first["on_box_edge"] == [{"variable": "xi_deg", "side": "min"}]
    # the compromises: the objective (closed forms) at the GP's optimum is within
    # 1e-4 of its true minimum over the box (measured 4e-6 weighted, 9e-8 Pareto;
    # ξ* = 33.34° and 32.46°, flat there: the location is not asserted)

    def weighted(xi):
        s_l, s_t = _scaled(xi)
        return 0.5 * s_l + 0.5 * s_t

    def nearest_ideal(xi):
        s_l, s_t = _scaled(xi)
        return math.sqrt(0.5 * s_l ** 2 + 0.5 * s_t ** 2)

    for name, f in (("min-lc-max-lambda", weighted), ("min-lc-min-theta", nearest_ideal)):
        best = minimize_scalar(f, bounds=(15.0, 75.0), method="bounded",
                               options={"xatol": 1e-10})
        xi = opt[name]["x"]["xi_deg"]
        assert 15.0 < xi < 75.0 and opt[name]["on_box_edge"] == []
        assert f(xi) - best.fun <= 1e-4, (name, xi, best.x)
    assert opt["min-lc-min-theta"]["pareto_points"] >= 2


# -- constant responses and flat objectives -------------------------------------------------
FLAT = """
name = "bevel-flat"
base = "bevel-14G-xi15"
[[variables]]
name = "xi_deg"
path = "cutters[0].xi_deg"
min = 15.0
max = 45.0
[design]
levels = 3
[sweep]
workers = 1
cache = false
[surrogate]
starts = 2
[infill]
rounds = 2
[[objectives]]
name = "max-rake"
terms = [{ response = "alpha_min_deg", goal = "max" }]
[[objectives]]
name = "sharp-and-raked"
combine = "pareto"
terms = [{ response = "theta_min_deg", goal = "min" }, { response = "alpha_min_deg", goal = "max" }]
"""


@pytest.fixture(scope="module")
def flat_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("flat")
    cfg = loads_config(FLAT)
    rep = run_study(cfg, out, executor=SerialExecutor(), cache=False, progress=False,
                    build=True, plots=True, log=lambda s: None)
    return cfg, out, rep


def test_an_objective_on_a_constant_response_is_named_flat(flat_study):
    cfg, out, rep = flat_study
    assert rep["responses"]["constant"] == {"lambda_min_deg": 0.0, "alpha_min_deg": 0.0}
    assert rep["responses"]["fitted"] == ["theta_min_deg"]
    flat, partly = rep["optima"]
    msg = "response alpha_min_deg is constant (0.0) over the design: the objective is flat"
    assert flat["status"] == "flat" and flat["error"] == msg
    assert flat["flat_terms"] == {"alpha_min_deg": msg} and flat["x"] == {}
    assert not (out / "optimum-max-rake.toml").exists()
    # the other objective is optimised on its varying term: θ_min = ξ, smallest at 15°
    assert partly["status"] == "ok" and partly["combine"] == "pareto"
    assert partly["x"]["xi_deg"] == pytest.approx(15.0, abs=1e-9)
    assert partly["responses"]["theta_min_deg"]["actual"] == pytest.approx(15.0, abs=1e-9)
    assert partly["constant_responses"]["alpha_min_deg"]["actual"] == pytest.approx(0.0,
                                                                                    abs=1e-9)
    assert partly["build"]["watertight"]
    assert (out / "optimum-sharp-and-raked.toml").exists()
    assert (out / "surface-theta_min_deg.png").exists()
    assert not (out / "surface-alpha_min_deg.png").exists()
    v = rep["verdict"]
    assert v["ok"] is False
    assert v["reasons"] == [
        "objective max-rake is flat: response alpha_min_deg is constant (0.0) over the design",
        "objective sharp-and-raked is partly flat: response alpha_min_deg is constant (0.0) "
        "over the design (optimised on its other terms)"]


def test_no_response_left_to_fit_is_no_crash(tmp_path):
    text = FLAT.replace("[sweep]", '[analysis]\nresponses = ["alpha_min_deg"]\n[sweep]')
    text = text[:text.index("[[objectives]]\nname = \"sharp")]
    rep = run_study(loads_config(text), tmp_path, executor=SerialExecutor(), cache=False,
                    progress=False, build=False, plots=True, log=lambda s: None)
    assert rep["responses"]["fitted"] == [] and rep["surrogate"]["loo"] == {}
    assert [o["status"] for o in rep["optima"]] == ["flat"]
    assert rep["verdict"]["ok"] is False and len(rep["verdict"]["reasons"]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json", "surrogate.json",
                                                         "sweep.csv"]


def test_infill_not_converged_fails_the_verdict(tmp_path):
    """No infill round allowed and a threshold no 3-point GP of l_c meets."""
    text = FLAT.replace("rounds = 2", "rounds = 0\nthreshold = 1e-6")
    text = text.replace('response = "alpha_min_deg", goal = "max" }]\n[[objectives]]',
                        'response = "l_c_mm", goal = "min" }, '
                        '{ response = "theta_min_deg", goal = "min" }]\n[[objectives]]')
    text = text[:text.index("[[objectives]]\nname = \"sharp")]
    rep = run_study(loads_config(text), tmp_path, executor=SerialExecutor(), cache=False,
                    progress=False, build=False, plots=False, log=lambda s: None)
    (o,) = rep["optima"]
    assert o["status"] == "ok" and not rep["infill"]["converged"]
    (reason,) = rep["verdict"]["reasons"]
    assert reason.startswith("infill not converged after 1 round(s) (max-rake: l_c_mm off by ")
    err = o["responses"]["l_c_mm"]["error_frac"]
    assert err > 1e-6 and f"{err:.2%}" in reason


def test_constant_responses_are_round_off_wide():
    """Constant: a range within 1e-9 of max(1, |y|) (a bevel's λ_min ≈ 1e-14°)."""
    from tipgeo.optimize import run_sweep

    cfg = loads_config(FLAT)
    sw = run_sweep(cfg, executor=SerialExecutor(), cache=False, progress=False)
    lam = sw.responses(["lambda_min_deg"])[:, 0]
    assert np.all(np.abs(lam) < 1e-12)  # round-off, not exactly 0
    assert constant_responses(sw) == {"lambda_min_deg": 0.0, "alpha_min_deg": 0.0}
    assert constant_responses(sw, ["theta_min_deg", "l_c_mm"]) == {}
    sw.results[0] = {"status": "failed", "error": "x", "responses": {}}
    sw.results[1] = {"status": "failed", "error": "x", "responses": {}}
    assert constant_responses(sw) == {}  # one configuration says nothing


@pytest.mark.parametrize("value, text", [(0.0, "0.0"), (45.00000000000001, "45.0"),
                                         (1.5e-14, "1.5e-14"), (-2.25, "-2.25")])
def test_flat_message_names_the_response_and_value(value, text):
    assert flat_message("alpha_min_deg", value, all_flat=True) == (
        f"response alpha_min_deg is constant ({text}) over the design: the objective is flat")


# -- which responses are modelled (config parsing) ------------------------------------------
_NAMES = list(THESIS)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(used=st.lists(st.sampled_from(_NAMES), min_size=1, max_size=3, unique=True),
       sur=st.none() | st.lists(st.sampled_from(_NAMES), min_size=1, max_size=4, unique=True),
       plots=st.none() | st.lists(st.sampled_from(_NAMES), min_size=1, max_size=3,
                                  unique=True),
       infill=st.none() | st.lists(st.sampled_from(_NAMES), min_size=1, max_size=3,
                                   unique=True))
def test_modelled_is_the_objectives_responses_and_those_asked_for(used, sur, plots, infill):
    def arr(xs):
        return "[" + ", ".join(f'"{x}"' for x in xs) + "]"

    if sur is not None:
        sur = list(dict.fromkeys(sur + used))  # objectives' responses must be modelled
    avail = sur if sur is not None else _NAMES
    plots = None if plots is None else [p for p in plots if p in avail] or None
    infill = None if infill is None else [p for p in infill if p in avail] or None
    text = FLAT[:FLAT.index("[[objectives]]")]
    text = text.replace("[surrogate]", "[surrogate]" + (f"\nresponses = {arr(sur)}"
                                                        if sur is not None else ""))
    text = text.replace("[infill]", "[infill]" + (f"\nresponses = {arr(infill)}"
                                                  if infill is not None else ""))
    if plots is not None:
        text += f"[plots]\nresponses = {arr(plots)}\n"
    text += "[[objectives]]\nname = \"o\"\nterms = [" + ", ".join(
        f'{{ response = "{u}" }}' for u in used) + "]\n"
    cfg = loads_config(text)
    want = set(used) | set(sur or ()) | set(plots or ()) | set(infill or ())
    assert cfg.modelled == tuple(r for r in avail if r in want)
    assert cfg.objective_responses == tuple(used)
    # with no objectives: every response that may be modelled
    bare = loads_config(text[:text.index("[[objectives]]")])
    assert bare.modelled == tuple(avail)
