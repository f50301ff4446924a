"""The helical tip over the design space (issue 28 item 1).

Exact analysis never meshes: specs the old default-tolerance mesh cap refused
(ψ = 10°, φ = 16.55°) validate and are analysed exactly; the mesh grid is
chosen, and capped, at the tolerance the build asks for, and a refusal names
a tolerance that then builds. The corners of ψ, φ ∈ {0.5°, 30°} (φ = 0 and
ψ → 0 are degenerate helicoids; the thesis placement folds over at φ = 30°, so
the corners take the helix axis D = 8 mm from the needle axis) and the
thesis's Table 3.1 tip are analysed exactly and meshed watertight.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from tipgeo.angles import analyze
from tipgeo.build import build_tip
from tipgeo.cannula import Cannula
from tipgeo.cutters.helical import thesis_helical
from tipgeo.errors import BuildError
from tipgeo.spec import TipSpec

_D = math.radians
_14G = Cannula.from_gauge(14)


def _spec(psi_deg, phi_deg, axis_offset=None):
    kw = {"helix_angle": _D(psi_deg), "phi": _D(phi_deg)}
    if axis_offset is not None:
        kw["axis_offset"] = axis_offset
    return TipSpec(cannula=_14G, cutters=[dataclasses.replace(thesis_helical(), **kw)],
                   name=f"helical-psi{psi_deg:g}-phi{phi_deg:g}")


def _check_exact(spec):
    rep = analyze(spec, method="exact")
    t = rep.table(step_deg=0.05)
    for col in ("z_o_mm", "z_i_mm", "lambda_o_deg", "lambda_i_deg", "theta_deg"):
        assert np.all(np.isfinite(t[col])), col
    assert np.all(np.abs(t["lambda_o_deg"]) <= 90.0)
    return t


def _check_mesh(spec, tolerance, table):
    tip = build_tip(spec, tolerance=tolerance)
    # the mesh's highest point is the exact edges' highest (the tip): within
    # 10 µm (a sharp point's height moves by tolerance / sin(half its angle),
    # and the table samples every 0.05°)
    z_exact = max(table["z_o_mm"].max(), table["z_i_mm"].max())
    assert abs(tip.bounds[1, 2] - z_exact) <= 0.01
    assert tip.is_watertight and tip.genus == 1
    assert tip.volume > 0
    # the helicoid's mesh lies within the tolerance of the exact surface
    cut = spec.cutters[0]
    m = tip.mask(cut.label)
    f, _ = cut.implicit(tip.triangles[m].mean(axis=1), spec.cannula)
    assert np.abs(f).max() <= tolerance * (1 + 1e-6)
    return tip


@pytest.mark.parametrize("psi,phi", [(0.5, 0.5), (0.5, 30.0), (30.0, 0.5), (30.0, 30.0)])
def test_corners_analysed_exactly_and_meshed(psi, phi):
    spec = _spec(psi, phi, axis_offset=8.0)
    _check_mesh(spec, 5e-4, _check_exact(spec))


def test_thesis_table_3_1_tip():
    spec = _spec(10.0, 13.5)
    _check_mesh(spec, 5e-5, _check_exact(spec))


def test_steep_phi_builds_at_the_default_tolerance():
    """The spec the issue quotes (refused before, its uniform grid needing
    1848×78 points): the grid refined only where the helicoid curves meets
    0.05 µm within the cap."""
    spec = _spec(10.0, 16.55)
    tip = _check_mesh(spec, 5e-5, _check_exact(spec))
    angles, radial = next(iter(spec.cutters[0]._grids.values()))
    assert len(angles) * radial <= 80_000 < 1848 * 78
    steps = np.diff(angles)
    assert steps.max() / steps.min() >= 4.0   # adapted: not a uniform grid
    assert len(angles) <= 0.5 * 1848
    assert tip.is_watertight


def test_too_fine_a_tolerance_names_one_that_builds():
    spec = _spec(10.0, 16.55)
    table = _check_exact(spec)
    with pytest.raises(BuildError) as e:
        build_tip(spec, tolerance=1e-5)
    msg = str(e.value)
    hit = re.search(r"a tolerance of about ([0-9.]+) µm", msg)
    assert hit, msg
    named = float(hit.group(1)) * 1e-3
    assert 1e-5 < named <= 1.6e-4      # within four doublings
    _check_mesh(spec, named, table)
