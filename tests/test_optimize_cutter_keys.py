"""A study's design variables are the keys each cutter kind declares
(``Cutter.optimizer_keys``): a toy kind defined only in this file is varied by
``tipgeo optimize``'s config reader with nothing in ``tipgeo/optimize`` told
about it, its alternative keys replace each other, and a key it does not
declare is refused with an error naming the key and the allowed ones."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tipgeo import Cannula, TipSpec, dumps_spec
from tipgeo.cutters import CUTTER_KINDS, PlanarCutter, Plane, check_name
from tipgeo.cutters.base import OptimizerKey
from tipgeo.cutters.toml import CutterTable, round_for_toml
from tipgeo.errors import SpecError
from tipgeo.optimize.config import loads_config

KIND = "toy-wedge"


@pytest.fixture(scope="module")
def wedge() -> Iterator[type]:
    """A one-plane cutter given by its bevel angle ``xi_deg`` or, instead, its
    ``steepness`` cot ξ (dimensionless); registered for this module only."""

    @dataclass(frozen=True, kw_only=True)
    class WedgeCutter(PlanarCutter):
        xi: float
        rotation: float = 0.0
        name: str = "wedge"
        kind = KIND
        angle_field = "xi"
        toml_keys = {"xi_deg": "bevel angle ξ, (0, 90)",
                     "steepness": "cot ξ, instead of xi_deg",
                     "rotation_deg": "heel direction about +z"}
        optimizer_keys = {"xi_deg": OptimizerKey(replaces=("steepness",)),
                          "steepness": OptimizerKey(replaces=("xi_deg",))}

        def __post_init__(self) -> None:
            check_name(self.name)

        @classmethod
        def from_dict(cls, t: CutterTable) -> WedgeCutter:
            if t.one_of("xi_deg", "steepness") == "xi_deg":
                xi = t.deg("xi_deg", required=True)
            else:
                xi = math.atan2(1.0, t.mm("steepness", arg="steepness", required=True) or 0.0)
            return cls(xi=xi or 0.0, rotation=t.deg("rotation_deg", default=0.0) or 0.0,
                       name=t.str("name", "wedge") or "wedge")

        def to_dict(self) -> dict[str, Any]:
            return {"xi_deg": round_for_toml(math.degrees(self.xi)),
                    "rotation_deg": round_for_toml(math.degrees(self.rotation))}

        def planes(self, cannula: Cannula) -> list[Plane]:
            return [Plane(self.xi, self.rotation, cannula.r_o / math.tan(self.xi), self.label)]

        def face_labels(self) -> tuple[str, ...]:
            return (self.label,)

    yield WedgeCutter
    CUTTER_KINDS.pop(KIND, None)


def _config(tmp_path: Path, wedge: type, path: str, lo: float, hi: float) -> Any:
    spec = TipSpec(cannula=Cannula.from_gauge(14), cutters=[wedge(xi=math.radians(20))],
                   name="wedge-14G")
    (tmp_path / "wedge.toml").write_text(dumps_spec(spec))
    text = (f'name = "wedge-study"\nbase = "wedge.toml"\n\n[[variables]]\npath = "{path}"\n'
            f"min = {lo}\nmax = {hi}\n\n[design]\nmethod = \"grid\"\nlevels = 3\n")
    return loads_config(text, base_dir=tmp_path)


def test_the_kind_declares_its_keys_and_optimize_knows_nothing_of_it(wedge: type) -> None:
    assert CUTTER_KINDS[KIND] is wedge
    assert list(wedge.optimizer_keys) == ["xi_deg", "steepness"]
    src = Path(__file__).parents[1] / "tipgeo" / "optimize"
    assert not any(KIND in p.read_text() for p in src.glob("*.py"))


def test_a_declared_key_is_a_design_variable(tmp_path: Path, wedge: type) -> None:
    cfg = _config(tmp_path, wedge, "cutters[0].xi_deg", 15.0, 25.0)
    (v,) = cfg.variables
    assert (v.name, v.lo, v.hi, v.integer) == ("xi_deg", 15.0, 25.0, False)
    assert cfg.spec([22.5]).cutters[0].xi == pytest.approx(math.radians(22.5), abs=1e-12)


def test_an_alternative_key_replaces_the_one_the_base_gives(tmp_path: Path, wedge: type) -> None:
    # the base spec gives xi_deg; varying steepness drops it (else: "both given")
    cfg = _config(tmp_path, wedge, "cutters[0].steepness", 1.0, 3.0)
    d = cfg.spec_dict([2.0])
    assert d["cutters"][0]["steepness"] == 2.0 and "xi_deg" not in d["cutters"][0]
    assert cfg.spec([2.0]).cutters[0].xi == pytest.approx(math.atan(0.5), abs=1e-12)


@pytest.mark.parametrize("key", ["rotation_deg", "depth_mm"])
def test_an_undeclared_key_is_refused_by_name(tmp_path: Path, wedge: type, key: str) -> None:
    # rotation_deg is a TOML key of the kind but not one it lets a study vary
    with pytest.raises(SpecError, match=(
            rf"variables\[0\]\.path = 'cutters\[0\]\.{key}': '{key}' is not a numeric key of "
            rf"a {KIND} cutter; allowed: xi_deg, steepness$")):
        _config(tmp_path, wedge, f"cutters[0].{key}", 1.0, 2.0)
