"""Shared pieces of :mod:`tipgeo.mechanics`: the validity warning, unit
conversions and array checks.

Units inside the mechanics package: mm, N, s, MPa (= N/mm²) and radians. A
strain energy release rate R is in N/mm (1 J/m² = 1e-3 N/mm); Young's moduli
and stresses in MPa (1 kPa = 1e-3 MPa).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..arrays import ArrayLike, FloatArray
from ..errors import SpecError

__all__ = ["ValidityWarning", "J_PER_M2", "KPA", "warn_outside", "finite_array"]

#: 1 J/m² in N/mm (strain energy release rate, toughness).
J_PER_M2 = 1.0e-3
#: 1 kPa in MPa.
KPA = 1.0e-3


class ValidityWarning(UserWarning):
    """A query lies outside the range over which a fitted preset (regression,
    force surface) was measured; the value is an extrapolation."""


def warn_outside(name: str, values: ArrayLike, lo: float, hi: float, *, unit: str = "",
                 source: str = "", stacklevel: int = 3) -> None:
    """Warn (:class:`ValidityWarning`) if any of ``values`` lies outside
    [lo, hi]; the message names the quantity, the offending extreme and the
    preset's stated range."""
    a = np.asarray(values, float)
    if a.size == 0:
        return
    bad = (a < lo) | (a > hi)
    if np.any(bad):
        worst = a[bad][np.argmax(np.abs(a[bad] - 0.5 * (lo + hi)))]
        u = f" {unit}" if unit else ""
        frac = f" ({bad.mean():.1%} of the points)" if a.size > 1 else ""
        warnings.warn(f"{name} = {worst:.6g}{u} is outside the validity range of {source}: "
                      f"{lo:g} ≤ {name} ≤ {hi:g}{u}{frac}; the value is extrapolated",
                      ValidityWarning, stacklevel=stacklevel)


def finite_array(name: str, values: ArrayLike, *, lo: float | None = None,
                 lo_open: bool = False, unit: str = "", min_size: int = 1) -> FloatArray:
    """``values`` as a float array with every element finite (and > or ≥ lo).

    Raises :class:`SpecError` naming ``name``, the first bad index and value
    and the allowed range — never a numpy error from deep inside.
    """
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise SpecError(f"{name} = {values!r} is not an array of numbers") from None
    u = f" {unit}" if unit else ""
    if a.size < min_size:
        raise SpecError(f"{name} has {a.size} values; at least {min_size} are needed")
    flat = a.reshape(-1)
    bad = ~np.isfinite(flat)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise SpecError(f"{name}[{i}] = {flat[i]} is not finite; expected finite numbers{u}")
    if lo is not None:
        bad = flat <= lo if lo_open else flat < lo
        if np.any(bad):
            i = int(np.argmax(bad))
            raise SpecError(f"{name}[{i}] = {flat[i]:.6g}{u} is out of range; allowed value "
                            f"{'>' if lo_open else '≥'} {lo:g}{u}")
    return a
