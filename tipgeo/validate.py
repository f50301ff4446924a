"""Argument checks that raise :class:`SpecError` with the parameter, the value
and the allowed range in the message (never ``assert``)."""

from __future__ import annotations

import math
import reprlib
from numbers import Real

from .errors import SpecError

__all__ = ["real", "length", "feature_length", "angle", "integer", "brief", "finite_float"]

_BRIEF = reprlib.Repr()
_BRIEF.maxlevel = 3
_BRIEF.maxstring = 60
_BRIEF.maxother = 60
_BRIEF.maxlist = _BRIEF.maxtuple = _BRIEF.maxdict = 6


def brief(value: object) -> str:
    """A short one-line ``repr`` for error messages: long strings, deep or long
    lists and integers of many digits are abbreviated (never a recursion)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10 ** 18:
        digits = len(str(abs(value))) if abs(value) < 10 ** 4000 else None
        sign = "-" if value < 0 else ""
        return (f"{sign}{str(abs(value))[:1]}…(an integer of {digits} digits)" if digits
                else f"{sign}(an integer of more than 4000 digits)")
    try:
        return _BRIEF.repr(value).replace("\n", " ")
    except (RecursionError, ValueError):  # pragma: no cover - defensive
        return f"<{type(value).__name__}>"


def finite_float(name: str, value: object, unit: str = "") -> float:
    """``value`` as a finite float; a bool, a non-number, NaN/∞ or an integer
    beyond the float range is a :class:`SpecError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise SpecError(f"{name} = {brief(value)} is not a number; expected a real "
                        f"number{_unit(unit)}")
    try:
        v = float(value)
    except OverflowError:
        raise SpecError(f"{name} = {brief(value)} is too large for a float; allowed "
                        f"|value| < 1.8e308{_unit(unit)}") from None
    if not math.isfinite(v):
        raise SpecError(f"{name} = {v} is not finite; expected a finite number{_unit(unit)}")
    return v


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return brief(value)


def real(name: str, value: object, *, lo: float | None = None, hi: float | None = None,
         lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a finite float inside [lo, hi] (ends open as asked).

    Raises :class:`SpecError` naming ``name``, the value and the range.
    """
    v = finite_float(name, value, unit)
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


def feature_length(name: str, value: object, *, hi: float | None = None) -> float:
    """A physical length in mm, at least :data:`~tipgeo.tolerances.MIN_FEATURE_MM`
    (1 µm): smaller sizes describe nothing that can be made."""
    from .tolerances import MIN_FEATURE_MM

    return real(name, value, lo=MIN_FEATURE_MM, hi=hi, unit="mm")


def angle(name: str, value: object, *, lo: float | None = None, hi: float | None = None,
          lo_open: bool = False, hi_open: bool = False) -> float:
    """An angle in radians; the message also gives degrees."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise SpecError(f"{name} = {brief(value)} is not a finite angle; expected radians")
    v = finite_float(name, value, "radians")
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
            raise SpecError(f"{name} = {brief(value)} is not an integer")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise SpecError(f"{name} = {brief(value)} is out of range; allowed "
                        f"{_range(lo, hi, False, False)}")
    return int(value)


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _range(lo: object, hi: object, lo_open: bool, hi_open: bool) -> str:
    def f(x: object) -> str:
        return f"{x:.6g}" if isinstance(x, float) else str(x)
    if lo is not None and hi is not None:
        return f"{f(lo)} {'<' if lo_open else '≤'} value {'<' if hi_open else '≤'} {f(hi)}"
    if lo is not None:
        return f"value {'>' if lo_open else '≥'} {f(lo)}"
    if hi is not None:
        return f"value {'<' if hi_open else '≤'} {f(hi)}"
    return "any value"
