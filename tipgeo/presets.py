"""The thesis's needles as named specs (the ``samples/`` folder holds them as
TOML; a test keeps both in step).

Frame and units: cannula frame, mm, radians (degrees only in names).

Notes on the thesis's wording: §2.4 calls the one-plane bevels' bevel angle ξ
"θ" (θ = 15°, 45°, 75°); likewise the "two- and three-plane θ = 15°" needles
of §2.4.2 are ground at ξ = 15° — by eq. 2.3 a three-plane tip cannot have an
included angle below 60°, so θ there is the grinding (bevel) angle.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable

from .cannula import Cannula
from .cutters import (
    SERRATION_PRESETS,
    BevelCutter,
    ConicalCutter,
    LancetCutter,
    MultiPlaneCutter,
    SerrationCutter,
    thesis_helical,
)
from .errors import SpecError
from .spec import TipSpec

__all__ = ["PRESETS", "preset", "preset_names", "resolve_spec"]

_D = math.radians
_14G = Cannula.from_gauge(14)
_PUNCH = Cannula.biopsy_punch()
#: Fig. 4.7 biopsy punch tip: θ = 13°, bevel length 0.6 mm.
_PUNCH_CONE = ConicalCutter(theta=_D(13.0), bevel_length=0.6, name="cone")


def _bevel(xi: float) -> TipSpec:
    return TipSpec(cannula=_14G, cutters=[BevelCutter(xi=_D(xi))],
                   name=f"bevel-14G-xi{xi:g}",
                   description=f"14G one-plane bevel, ξ = {xi:g}° (thesis §2.1.1, §2.4.1)")


def _punch_serrated(cid: str) -> TipSpec:
    r_c, n = SERRATION_PRESETS[cid]
    return TipSpec(cannula=_PUNCH, cutters=[
        _PUNCH_CONE, SerrationCutter(arc_radius=r_c, count=n, edge_radius=0.015)],
        name=f"punch-{cid}",
        description=f"biopsy punch with micro-serrations {cid}: r_c = {r_c * 1e3:g} µm, "
                    f"n_s = {n}, r_s = 15 µm (thesis Table 5.1)")


PRESETS: dict[str, Callable[[], TipSpec]] = {
    "bevel-14G-xi14.5": lambda: _bevel(14.5),
    "bevel-14G-xi15": lambda: _bevel(15.0),
    "bevel-14G-xi45": lambda: _bevel(45.0),
    "bevel-14G-xi75": lambda: _bevel(75.0),
    "conical-14G-theta15": lambda: TipSpec(
        cannula=_14G, cutters=[ConicalCutter(theta=_D(15.0))], name="conical-14G-theta15",
        description="14G conical tip, θ = 15° (thesis §2.1.1, §2.4.1)"),
    "twoplane-14G-xi15": lambda: TipSpec(
        cannula=_14G, cutters=[MultiPlaneCutter(xi=_D(15.0), count=2)],
        name="twoplane-14G-xi15",
        description="14G symmetric two-plane tip ground at 15° (thesis §2.1.2, §2.4.2)"),
    "threeplane-14G-xi15": lambda: TipSpec(
        cannula=_14G, cutters=[MultiPlaneCutter(xi=_D(15.0), count=3)],
        name="threeplane-14G-xi15",
        description="14G symmetric three-plane tip ground at 15° (thesis §2.1.2, §2.4.2)"),
    "lancet-14G": lambda: TipSpec(
        cannula=_14G, cutters=[LancetCutter(primary_xi=_D(15.0), secondary_xi=_D(20.0),
                                            secondary_rotation=_D(30.0))],
        name="lancet-14G",
        description="14G lancet: 15° primary bevel, 20° secondaries rotated ±30° "
                    "(a representative lancet; the thesis gives no lancet values)"),
    "helical-14G": lambda: TipSpec(
        cannula=_14G, cutters=[thesis_helical()], name="helical-14G",
        description="thesis helical needle: p_h = 100 mm, ψ = 10°, φ = 13.5° (§3.1.1); "
                    "ruling and placement calibrated against Table 3.1 (tipgeo calibrate)"),
    "punch-plain": lambda: TipSpec(
        cannula=_PUNCH, cutters=[_PUNCH_CONE], name="punch-plain",
        description="biopsy punch d_e 2.4 / d_i 2.0 mm, θ = 13°, bevel length 0.6 mm "
                    "(thesis Fig. 4.7)"),
    **{f"punch-{cid}": functools.partial(_punch_serrated, cid) for cid in SERRATION_PRESETS},
}


def preset_names() -> list[str]:
    """Names of the built-in specs."""
    return list(PRESETS)


def preset(name: str) -> TipSpec:
    """The built-in spec called ``name`` (see :func:`preset_names`)."""
    if name not in PRESETS:
        raise SpecError(f"preset = {name!r} is not known; expected one of: "
                        + ", ".join(PRESETS))
    return PRESETS[name]()


def resolve_spec(arg: TipSpec | str | os.PathLike[str]) -> TipSpec:
    """A spec from what a user typed: a :class:`TipSpec` as it is, a path to a
    spec file (``.toml``, or any existing file), or a preset name.

    Raises :class:`~tipgeo.errors.SpecError` naming ``arg`` and the presets
    when it is none of these.
    """
    from .spec import load_spec
    from .tomlio import resolve_file_or_name

    return resolve_file_or_name(arg, kind=TipSpec, load=load_spec, named=preset, names=PRESETS,
                                what="SPEC", file_word="spec file", named_as="preset",
                                listing="presets")
