"""Every cutter's exact edge takes one radius per γ as well as one for all
(``Cutter.edge_faces``; ``tipgeo.edges.lowest_cut``): the vectorised call
equals the scalar calls point by point. The conical cutter failed on a
radius per γ until issue 25's rim check met it (worked around there then)."""

from __future__ import annotations

import numpy as np
import pytest

from tipgeo import preset
from tipgeo.edges import lowest_cut
from tipgeo.presets import PRESETS

#: tips whose cutters all have an exact edge (the helical's is exact too)
NAMES = sorted(PRESETS)


@pytest.mark.parametrize("name", NAMES)
def test_lowest_cut_takes_a_radius_per_gamma(name):
    spec = preset(name)
    c = spec.cannula
    rng = np.random.default_rng(3)
    g = rng.uniform(0.0, 2 * np.pi, 40)
    r = rng.uniform(c.r_i, c.r_o, 40)
    z, face, owner = lowest_cut(spec.cutters, g, r, c)
    assert z.shape == face.shape == owner.shape == (40,)
    for k in range(40):
        zk, fk, ok = lowest_cut(spec.cutters, g[k], float(r[k]), c)
        # the same arithmetic on one element: equal to round-off (mm)
        assert z[k] == pytest.approx(zk[0], abs=1e-12)
        assert face[k] == fk[0] and owner[k] == ok[0]


def test_conical_edge_per_radius_is_the_cone_and_its_land():
    """Closed form: z = (r_o − ρ)/tan θ on the cone, the land's height where
    the land (bevel length) cuts lower."""
    spec = preset("conical-14G-theta15")
    cone = spec.cutters[0]
    c = spec.cannula
    rho = np.array([c.r_o, 0.5 * (c.r_o + c.r_i), c.r_i])
    z, face = cone.edge_faces(np.zeros(3), rho, c)
    expect = (c.r_o - rho) / np.tan(cone.theta)
    if cone.bevel_length is not None:
        expect = np.minimum(expect, cone.bevel_length)
    np.testing.assert_allclose(z, expect, rtol=0, atol=1e-12)
    assert set(face) <= {cone.label, cone.land_label}
    np.testing.assert_allclose(cone.edge_z(np.zeros(3), rho, c), z, rtol=0, atol=0)
