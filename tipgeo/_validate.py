"""Argument checks that raise :class:`SpecError` with the parameter, the value
and the allowed range in the message (never ``assert``)."""

from __future__ import annotations

import math
from numbers import Real

from .errors import SpecError

__all__ = ["real", "length", "angle", "integer"]


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return repr(value)


def real(name: str, value: object, *, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a finite float inside [lo, hi] (ends open as asked).

    Raises :class:`SpecError` naming ``name``, the value and the range.
    """
    if isinstance(value, bool) or not isinstance(value, Real):
        raise SpecError(f"{name} = {value!r} is not a number; expected a real number{_unit(unit)}")
    v = float(value)
    if not math.isfinite(v):
        raise SpecError(f"{name} = {v} is not finite; expected a finite number{_unit(unit)}")
    bad = (lo is not None and (v < lo or (lo_open and v == lo))) or (
        hi is not None and (v > hi or (hi_open and v == hi)))
    if bad:
        raise SpecError(f"{name} = {_fmt(v)}{unit and ' ' + unit} is out of range; allowed "
                        f"{_range(lo, hi, lo_open, hi_open)}{_unit(unit)}")
    return v


def length(name: str, value: object, *, lo: float = 0.0, hi: float | None = None,
           lo_open: bool = True, hi_open: bool = False) -> float:
    """A length in mm, by default strictly positive."""
    return real(name, value, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, unit="mm")


def angle(name: str, value: object, *, lo: float | None = None, hi: float | None = None,
          lo_open: bool = False, hi_open: bool = False) -> float:
    """An angle in radians; the message also gives degrees."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(float(value)):
        raise SpecError(f"{name} = {value!r} is not a finite angle; expected radians")
    v = float(value)
    bad = (lo is not None and (v < lo or (lo_open and v == lo))) or (
        hi is not None and (v > hi or (hi_open and v == hi)))
    if bad:
        lo_d = None if lo is None else math.degrees(lo)
        hi_d = None if hi is None else math.degrees(hi)
        raise SpecError(f"{name} = {v:.6g} rad ({math.degrees(v):.6g}°) is out of range; allowed "
                        f"{_range(lo_d, hi_d, lo_open, hi_open)} degrees")
    return v


def integer(name: str, value: object, *, lo: int | None = None, hi: int | None = None) -> int:
    """An integer inside [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise SpecError(f"{name} = {value!r} is not an integer")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise SpecError(f"{name} = {value} is out of range; allowed {_range(lo, hi, False, False)}")
    return int(value)


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _range(lo, hi, lo_open, hi_open) -> str:
    def f(x):
        return f"{x:.6g}" if isinstance(x, float) else str(x)
    if lo is not None and hi is not None:
        return f"{f(lo)} {'<' if lo_open else '≤'} value {'<' if hi_open else '≤'} {f(hi)}"
    if lo is not None:
        return f"value {'>' if lo_open else '≥'} {f(lo)}"
    if hi is not None:
        return f"value {'<' if hi_open else '≤'} {f(hi)}"
    return "any value"
