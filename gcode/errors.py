"""The G-code package's one exception type."""

from tipgeo.errors import TipGeoError

__all__ = ["GCodeError"]


class GCodeError(TipGeoError, ValueError):
    """Bad or unsupported G-code, or a program that cannot run.

    Attributes ``line`` and ``column`` (1-based, 0 when unknown) and ``text``
    (the offending source text) locate the problem; the message repeats them.
    """

    def __init__(self, message: str, line: int = 0, column: int = 0, text: str = ""):
        self.line, self.column, self.text = line, column, text
        self.reason = message
        where = f"line {line}, column {column}: " if line else ""
        what = f" — '{text}'" if text else ""
        super().__init__(f"{where}{message}{what}")


def check_limit(name: str, value: object) -> int:
    """``value`` if it is a valid cost bound (an int ≥ 0, not a bool).

    Raises
    ------
    TypeError
        Not an int.
    ValueError
        Negative.
    """
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"{name} must be a whole number ≥ 0, not {value!r}")
    if value < 0:
        raise ValueError(f"{name} must be a whole number ≥ 0, not {value!r}")
    return value
