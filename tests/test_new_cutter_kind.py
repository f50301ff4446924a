"""A new tip kind is one cutter class and nothing else: a two-plane "chisel"
defined only in this file builds, round-trips through TOML, is analysed
(exact edges against the closed form), and is measured by ``tipgeo compare``
against its exact surfaces."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest

from tipgeo import Cannula, TipSpec, build_tip, dumps_spec, loads_spec
from tipgeo.cutters import CUTTER_KINDS, PlanarCutter, Plane, check_name
from tipgeo.cutters.toml import round_for_toml
from tipgeo.validate import angle


@dataclass(frozen=True, kw_only=True)
class ChiselCutter(PlanarCutter):
    """Two planes whose heels face each other across the tube: bevel angle
    ``xi_a`` with its heel at γ = 0, ``xi_b`` with its heel at γ = π (rad);
    both heels at z = 0, the ridge where they meet (cannula frame, mm)."""

    xi_a: float
    xi_b: float
    name: str = "chisel"
    kind = "chisel"
    angle_field = "xi_a"
    toml_keys = {"xi_a_deg": "first plane's bevel angle, (0, 90)",
                 "xi_b_deg": "second plane's bevel angle, (0, 90)"}

    def __post_init__(self):
        for f in ("xi_a", "xi_b"):
            angle(f, getattr(self, f), lo=0.0, hi=0.5 * math.pi, lo_open=True, hi_open=True)
        check_name(self.name)

    @classmethod
    def from_dict(cls, t):
        return cls(xi_a=t.deg("xi_a_deg", required=True), xi_b=t.deg("xi_b_deg", required=True),
                   name=t.str("name", "chisel"))

    def to_dict(self):
        return {"xi_a_deg": round_for_toml(math.degrees(self.xi_a)),
                "xi_b_deg": round_for_toml(math.degrees(self.xi_b))}

    def planes(self, cannula):
        r = cannula.r_o
        return [Plane(self.xi_a, 0.0, r / math.tan(self.xi_a), f"{self.label}.a"),
                Plane(self.xi_b, math.pi, r / math.tan(self.xi_b), f"{self.label}.b")]

    def face_labels(self):
        return (f"{self.label}.a", f"{self.label}.b")


C14 = Cannula.from_gauge(14)
SPEC = TipSpec(cannula=C14, cutters=[ChiselCutter(xi_a=math.radians(15), xi_b=math.radians(20))],
               name="chisel-14G")


def test_the_kind_registered_itself():
    assert CUTTER_KINDS["chisel"] is ChiselCutter


def test_it_round_trips_through_toml():
    text = dumps_spec(SPEC)
    assert 'kind = "chisel"' in text and "xi_a_deg = 15.0" in text and "xi_b_deg = 20.0" in text
    assert loads_spec(text) == SPEC
    with pytest.raises(Exception, match=r"cutters\[0\]\.xi_b_deg"):
        loads_spec(text.replace("xi_b_deg = 20.0", "xi_b_deg = 95.0"))


def test_it_builds_watertight_with_both_faces():
    tip = build_tip(SPEC)
    assert tip.is_watertight and tip.genus == 1
    assert {"cut:chisel.a", "cut:chisel.b"} <= set(tip.present_labels())
    # the ridge: both planes meet above the axis at z where the heights agree
    za = C14.r_o / math.tan(math.radians(15))
    zb = C14.r_o / math.tan(math.radians(20))
    x_ridge = (za - zb) / (1 / math.tan(math.radians(15)) + 1 / math.tan(math.radians(20)))
    z_ridge = za - x_ridge / math.tan(math.radians(15))
    assert tip.bounds[1, 2] == pytest.approx(z_ridge, abs=1e-9)


def test_it_is_analysed_exactly():
    from tipgeo.angles import analyze

    rep = analyze(SPEC, method="exact")
    g = np.radians(np.linspace(1.0, 359.0, 359))
    z = rep.dense("outer", 7200)
    zz = np.interp(g, z["gamma"], z["z"])
    # outer edge: the lower of the two planes' bevel profiles (Table 3.1 form)
    ra = C14.r_o * (1 - np.cos(g)) / math.tan(math.radians(15))
    rb = (C14.r_o / math.tan(math.radians(20)) + C14.r_o * np.cos(g) / math.tan(math.radians(20))
          - 0.0)
    want = np.minimum(ra, rb)
    assert np.abs(zz - want).max() < 1e-6
    assert len(rep.outer.edge.kinks) == 2                      # the two ends of the ridge


def test_tipgeo_compare_measures_it_against_its_exact_surfaces(tmp_path, capsys):
    from tipgeo.cli import main
    from tipgeo.inspect import synthetic_scan

    (tmp_path / "chisel.toml").write_text(dumps_spec(SPEC))
    scan = synthetic_scan(SPEC, points=20_000, noise=0.001, seed=3)
    scan.write(tmp_path / "scan.ply")
    assert main(["compare", str(tmp_path / "scan.ply"), str(tmp_path / "chisel.toml"),
                 "--json", "--no-pictures", "--quiet"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["cad"]["method"].startswith("exact")
    assert set(rep["deviation"]["regions"]) >= {"cut:chisel.a", "cut:chisel.b"}
    # the scanner's σ = 1 µm along the line of sight, seen along the normals
    assert 0.5 < rep["deviation"]["all"]["rms_um"] < 1.0
    xi = {k: v["xi_deg"] for k, v in rep["measured"]["faces"].items()}
    assert xi["cut:chisel.a"] == pytest.approx(15.0, abs=0.05)
    assert xi["cut:chisel.b"] == pytest.approx(20.0, abs=0.05)
