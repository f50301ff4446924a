"""Reading and writing one cutter's TOML table (``[[cutters]]``).

Units at this boundary: lengths in mm (keys ``*_mm``), angles in degrees
(keys ``*_deg``); the cutter dataclasses hold mm and radians (cannula frame).
A cutter's :meth:`~tipgeo.cutters.base.Cutter.from_dict` reads its keys
through a :class:`CutterTable`, which converts units, names the key in every
error (``cutters[0].xi_deg = …``) and remembers which constructor argument
came from which key, so the constructor's own range errors are reported
under the key the user typed.
"""

from __future__ import annotations

import builtins
import math
from pathlib import Path
from typing import Any, Literal, overload

from ..errors import SpecError
from ..validate import brief, finite_float

__all__ = ["CutterTable", "round_for_toml"]


def round_for_toml(x: float) -> float:
    """Round a converted value so that degrees print as typed (15.0, not
    14.999999999999998)."""
    return float(f"{x:.12g}")


class CutterTable:
    """One ``[[cutters]]`` table being read (keys already checked against the
    kind's allowed keys).

    Parameters
    ----------
    where : str
        Prefix for messages, e.g. ``cutters[2]``.
    table : dict
        The parsed TOML table.
    base_dir : Path or None
        Folder that relative paths start from (the spec file's).
    """

    def __init__(self, where: str, table: dict[str, Any], base_dir: Path | None = None):
        self.where, self.table, self.base_dir = where, table, base_dir
        #: constructor argument -> TOML key, for re-labelling constructor errors
        self.keymap: dict[str, str] = {}

    def __contains__(self, key: str) -> bool:
        return key in self.table

    def key(self, key: str) -> str:
        """The full key name for messages (``cutters[0].xi_deg``)."""
        return f"{self.where}.{key}"

    def need(self, key: str) -> Any:
        """The raw value of a required key."""
        if key not in self.table:
            raise SpecError(f"{self.where}.{key} is missing; it is required")
        return self.table[key]

    def one_of(self, a: str, b: str) -> str:
        """Which of two alternative keys is given (exactly one must be)."""
        has_a, has_b = a in self.table, b in self.table
        if has_a == has_b:
            raise SpecError(f"{self.where}: give exactly one of {a} and {b}"
                            + (" (both given)" if has_a else " (neither given)"))
        return a if has_a else b

    def _arg(self, key: str, arg: str | None) -> str:
        arg = arg or key.removesuffix("_deg").removesuffix("_mm")
        self.keymap[arg] = key
        return arg

    @overload
    def deg(self, key: str, *, arg: str | None = None, default: float,
            required: bool = False) -> float: ...
    @overload
    def deg(self, key: str, *, arg: str | None = None, default: None = None,
            required: Literal[True]) -> float: ...
    @overload
    def deg(self, key: str, *, arg: str | None = None, default: None = None,
            required: bool = False) -> float | None: ...

    def deg(self, key: str, *, arg: str | None = None, default: float | None = None,
            required: bool = False) -> float | None:
        """An angle key (degrees) as radians; ``default`` (degrees) when absent."""
        if key not in self.table:
            if required:
                self.need(key)
            return None if default is None else math.radians(default)
        self._arg(key, arg)
        return math.radians(finite_float(self.key(key), self.table[key]))

    @overload
    def mm(self, key: str, *, arg: str | None = None, required: Literal[True]) -> float: ...
    @overload
    def mm(self, key: str, *, arg: str | None = None, required: bool = False) -> float | None: ...

    def mm(self, key: str, *, arg: str | None = None, required: bool = False) -> float | None:
        """A length key (mm)."""
        if key not in self.table:
            if required:
                self.need(key)
            return None
        self._arg(key, arg)
        return finite_float(self.key(key), self.table[key])

    @overload
    def int(self, key: str, *, arg: str | None = None, required: Literal[True]) -> builtins.int:
        ...
    @overload
    def int(self, key: str, *, arg: str | None = None,
            required: bool = False) -> builtins.int | None: ...

    def int(self, key: str, *, arg: str | None = None,
            required: bool = False) -> builtins.int | None:
        """An integer key."""
        if key not in self.table:
            if required:
                self.need(key)
            return None
        self._arg(key, arg)
        value = self.table[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise SpecError(f"{self.key(key)} = {brief(value)} is not an integer; expected an "
                            "integer")
        return int(value)

    @overload
    def str(self, key: builtins.str, default: builtins.str) -> builtins.str: ...
    @overload
    def str(self, key: builtins.str, default: None = None) -> builtins.str | None: ...

    def str(self, key: builtins.str,
            default: builtins.str | None = None) -> builtins.str | None:
        """A string key."""
        if key not in self.table:
            return default
        value = self.table[key]
        if not isinstance(value, str):
            raise SpecError(f"{self.key(key)} = {brief(value)} is not a string; expected a "
                            "string")
        return value

    def deg_list(self, key: builtins.str, *,
                 arg: builtins.str | None = None) -> tuple[float, ...] | None:
        """A list of angles (degrees) as radians."""
        if key not in self.table:
            return None
        self._arg(key, arg)
        vals = self.table[key]
        if not isinstance(vals, list):
            raise SpecError(f"{self.key(key)} = {brief(vals)} is not a list of numbers")
        return tuple(math.radians(finite_float(f"{self.key(key)}[{j}]", x))
                     for j, x in enumerate(vals))

    def path(self, key: builtins.str) -> Path:
        """A required file path, relative ones starting at ``base_dir``."""
        p = Path(self.str(key, "") if key in self.table else self.need(key))
        if not p.is_absolute() and self.base_dir is not None:
            p = self.base_dir / p
        return p

    def relabel(self, err: SpecError, kind: builtins.str) -> SpecError:
        """A constructor's error, re-worded to name the TOML key."""
        msg = str(err)
        if msg.startswith(self.where):
            return err
        for arg, key in self.keymap.items():
            if msg.startswith((f"{arg} =", f"{arg}[")):
                return SpecError(f"{self.where}.{key}: {msg}")
        return SpecError(f"{self.where} ({kind}): {msg}")
