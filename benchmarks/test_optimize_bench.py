"""Sweep and surrogate timings (pytest-benchmark).

Run: python -m pytest benchmarks/test_optimize_bench.py --benchmark-only

- the thesis's 25-point helical study and a 400-point (20 × 20) version of it,
  in this process and on two local processes (no cache: every tip analysed);
- a fully cached re-run of the 25 points;
- the GP fit of the seven responses and the three optimisations.
"""

import numpy as np
import pytest

from tipgeo.optimize import (
    ProcessExecutor,
    ResultCache,
    SerialExecutor,
    fit_surrogate,
    make_design,
    optimize_objective,
    run_sweep,
    study_preset,
)
from tipgeo.tolerances import tol


def _x(cfg, levels):
    return make_design(cfg.variables, "grid", levels=levels)


@pytest.mark.parametrize("levels", [5, 20], ids=["25-configs", "400-configs"])
@pytest.mark.parametrize("workers", [1, 2], ids=["serial", "2-processes"])
def test_sweep(benchmark, levels, workers):
    tol.strict = False
    cfg = study_preset("helical-study")
    X = _x(cfg, levels)
    ex = SerialExecutor() if workers == 1 else ProcessExecutor(workers)
    res = benchmark.pedantic(run_sweep, args=(cfg,), kwargs={"X": X, "executor": ex,
                                                             "cache": False,
                                                             "progress": False},
                             rounds=1, iterations=1)
    assert res.ok.sum() == len(X)
    benchmark.extra_info["configurations"] = len(X)
    benchmark.extra_info["seconds_per_configuration"] = res.seconds / len(X)


def test_sweep_cached_rerun(benchmark, tmp_path):
    tol.strict = False
    cfg = study_preset("helical-study")
    run_sweep(cfg, executor=SerialExecutor(), cache=ResultCache(tmp_path), progress=False)
    res = benchmark(run_sweep, cfg, executor=SerialExecutor(), cache=ResultCache(tmp_path),
                    progress=False)
    assert res.computed == 0 and res.cached == 25


def test_gp_fit_and_optimise(benchmark):
    tol.strict = False
    cfg = study_preset("helical-study")
    sweep = run_sweep(cfg, executor=SerialExecutor(), cache=False, progress=False)

    def run():
        sur = fit_surrogate(sweep)
        sur.loo()
        return [optimize_objective(sur, o) for o in cfg.objectives]

    opts = benchmark.pedantic(run, rounds=3, iterations=1)
    assert all(np.isfinite(o.value) for o in opts)


def test_study_demo_hook(benchmark, tmp_path_factory):
    """The demo's whole study (sweep → GP → optima built → pictures); its
    budget on two shared cores was 20 s (the test suite asserts no time)."""
    from pathlib import Path

    from tipgeo.demo.optimize import demo_outputs

    tol.strict = False
    files = benchmark.pedantic(lambda: demo_outputs(tmp_path_factory.mktemp("study")),
                               rounds=1, iterations=1)
    assert any(Path(f).name == "report.json" for f in files)
