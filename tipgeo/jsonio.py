"""The one JSON form of tipgeo's reports (every ``--json`` and every
``*.json`` file it writes).

Standard JSON only: NaN and ±∞ become ``null`` (a value that does not exist,
e.g. λ at a vertical stretch, or an unbounded height); numpy scalars and
arrays become numbers and lists; paths become strings; anything else its
``str``. Units are those of the keys (``*_mm``, ``*_deg``, ``*_um``).
"""

from __future__ import annotations

import json
import math
from pathlib import PurePath
from typing import Any

__all__ = ["to_jsonable", "dumps"]


def to_jsonable(obj: Any) -> Any:
    """``obj`` as plain JSON data (dicts with str keys, lists, str, int, float
    — finite only — bool, None); see the module docstring."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, PurePath):
        return str(obj)
    try:  # numpy without importing it
        import numpy as np
    except ImportError:  # pragma: no cover
        return str(obj)
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    return str(obj)


def dumps(obj: Any, *, indent: int | None = 2) -> str:
    """``obj`` as standard JSON text (:func:`to_jsonable` first)."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False)
