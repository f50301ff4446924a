"""Cannulas (straight hollow tubes) and the needle gauge table.

Frame and units: the cannula frame has +z along the needle axis pointing to the
tip, the origin on the axis at the height of the heel (where the outer cutting
edge starts, z = 0), +x towards the heel of an unrotated cutter (γ = 0).
The straight tube occupies ``-length ≤ z`` up to wherever the cutters end it.
Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import validate as v
from .errors import SpecError
from .tolerances import MIN_DIAMETER_MM, MIN_FEATURE_MM

__all__ = ["Cannula", "GAUGES", "GAUGE_SOURCE", "gauge_table"]

#: Source of :data:`GAUGES`.
GAUGE_SOURCE = (
    "Nominal regular-wall hypodermic tubing dimensions (Birmingham/Stubs iron wire "
    "gauge outer diameters), as tabulated in Wikipedia's 'Needle gauge' chart "
    "(inch values converted, mm as printed there). ISO 9626:2016 gives the "
    "tolerance ranges around these nominals. 14G (2.108/1.600 mm) is the "
    "cannula of the thesis (§2.3.1)."
)

#: gauge -> (nominal outer diameter mm, nominal inner diameter mm), regular wall.
GAUGES: dict[int, tuple[float, float]] = {
    10: (3.404, 2.692),
    11: (3.048, 2.388),
    12: (2.769, 2.159),
    13: (2.413, 1.803),
    14: (2.108, 1.600),
    15: (1.829, 1.372),
    16: (1.651, 1.194),
    17: (1.473, 1.067),
    18: (1.270, 0.838),
    19: (1.067, 0.686),
    20: (0.9081, 0.603),
    21: (0.8192, 0.514),
    22: (0.7176, 0.413),
    23: (0.6414, 0.337),
    24: (0.5652, 0.311),
    25: (0.5144, 0.260),
    26: (0.4636, 0.260),
    27: (0.4128, 0.210),
    28: (0.3620, 0.184),
    29: (0.3366, 0.184),
    30: (0.3112, 0.159),
}


@dataclass(frozen=True, kw_only=True)
class Cannula:
    """A straight hollow tube (mm, cannula frame).

    Parameters
    ----------
    outer_diameter : float
        d_e (mm), > inner_diameter.
    inner_diameter : float
        d_i (mm), 0 < d_i < d_e.
    length : float
        Length of straight tube kept below the heel (mm): the base face of the
        tip mesh lies at z = -length.
    name : str
        Free label, e.g. ``"14G"``.
    """

    outer_diameter: float
    inner_diameter: float
    length: float = 10.0
    name: str = ""

    def __post_init__(self) -> None:
        de = v.length("outer_diameter", self.outer_diameter, lo=MIN_DIAMETER_MM,
                      lo_open=False, hi=100.0)
        di = v.length("inner_diameter", self.inner_diameter, lo=MIN_DIAMETER_MM,
                      lo_open=False, hi=100.0)
        if not di <= de - 2 * MIN_FEATURE_MM:
            raise SpecError(
                f"inner_diameter = {di:.6g} mm must be smaller than outer_diameter = {de:.6g} mm "
                f"by two walls of at least {MIN_FEATURE_MM * 1e3:g} µm (allowed "
                f"{MIN_DIAMETER_MM:g} ≤ inner_diameter ≤ outer_diameter − "
                f"{2 * MIN_FEATURE_MM:g} mm)")
        v.length("length", self.length, lo=MIN_FEATURE_MM, lo_open=False, hi=1000.0)
        object.__setattr__(self, "outer_diameter", de)
        object.__setattr__(self, "inner_diameter", di)
        object.__setattr__(self, "length", float(self.length))

    @property
    def r_o(self) -> float:
        """Outer radius r_no (mm)."""
        return 0.5 * self.outer_diameter

    @property
    def r_i(self) -> float:
        """Inner radius r_ni (mm)."""
        return 0.5 * self.inner_diameter

    @property
    def wall(self) -> float:
        """Wall thickness (mm)."""
        return self.r_o - self.r_i

    @classmethod
    def from_gauge(cls, gauge: int, *, length: float = 10.0) -> Cannula:
        """The regular-wall cannula of a needle gauge (10G–30G, :data:`GAUGES`)."""
        if isinstance(gauge, str):
            g = gauge.strip().upper().rstrip("G")
            gauge = int(g) if g.isdigit() else gauge
        if gauge not in GAUGES:
            raise SpecError(f"gauge = {gauge!r} is not in the gauge table; allowed "
                            f"{min(GAUGES)}–{max(GAUGES)}")
        de, di = GAUGES[gauge]
        return cls(outer_diameter=de, inner_diameter=di, length=length, name=f"{gauge}G")

    @classmethod
    def biopsy_punch(cls, *, length: float = 5.0) -> Cannula:
        """The biopsy punch of thesis Fig. 4.7 / §5.1.2: d_e 2.4 mm, d_i 2.0 mm."""
        return cls(outer_diameter=2.4, inner_diameter=2.0, length=length, name="biopsy punch")


def gauge_table() -> list[dict[str, float]]:
    """Rows of the gauge table: gauge, outer/inner diameter and wall (mm)."""
    return [{"gauge": g, "outer_diameter_mm": de, "inner_diameter_mm": di,
             "wall_mm": round((de - di) / 2, 6)} for g, (de, di) in GAUGES.items()]
