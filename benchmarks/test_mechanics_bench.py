"""Speed of the mechanics models (pytest-benchmark).

Run: python -m pytest benchmarks/test_mechanics_bench.py --benchmark-only
"""

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.mechanics import (
    ArrudaBoyce,
    Ogden,
    edge_forces,
    edge_geometry,
    fit_uniaxial,
    mean_forces_vs_speed_ratio,
    synthetic_uniaxial,
)
from tipgeo.tolerances import tol

R45 = 0.045
LAM = np.r_[np.linspace(0.3, 1.0, 60), np.linspace(1.0, 1.8, 40)[1:]]


@pytest.mark.parametrize("name", ["bevel-14G-xi14.5", "helical-14G"])
def test_edge_geometry(benchmark, name):
    """Exact edge analysis + sampling on 3600 points."""
    tol.strict = False
    spec = preset(name)
    g = benchmark(edge_geometry, spec)
    assert len(g.gamma) == 3600


def test_edge_forces_one_S(benchmark):
    g = edge_geometry(preset("helical-14G"))
    ef = benchmark(edge_forces, g, 0.3, R=R45, mu_d=0.4, G=0.35)
    assert ef.means["perp"] > 0


def test_mean_forces_sweep_61_S(benchmark):
    """Fig. 3.12b: means over γ for 61 values of S."""
    g = edge_geometry(preset("helical-14G"))
    sw = benchmark(mean_forces_vs_speed_ratio, g, np.linspace(0, 3, 61), R=R45, mu_d=0.4)
    assert len(sw["perp"]) == 61


@pytest.mark.parametrize("model, true", [
    ("arruda-boyce", ArrudaBoyce(mu=0.0238, lambda_m=2.024)),
    ("ogden", Ogden(mu=(-0.004, 0.012), alpha=(-3.0, 4.0))),
    ("ogden3", Ogden(mu=(-0.0255, 0.0088, 0.0249), alpha=(-3.91, 4.74, -4.09))),
])
def test_fit(benchmark, model, true):
    """Least-squares fit to 99 noisy points (1 % noise)."""
    lam, sig = synthetic_uniaxial(true, LAM, noise=0.01, seed=0)
    name, terms = ("ogden", 3) if model == "ogden3" else (model, 2)
    fit = benchmark(fit_uniaxial, lam, sig, name, terms=terms)
    assert fit.r2 > 0.99
