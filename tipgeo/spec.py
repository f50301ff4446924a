"""Tip specifications: a cannula plus an ordered list of cutters.

(temporary minimal version)
"""
from __future__ import annotations

from dataclasses import dataclass

from .cannula import Cannula
from .errors import SpecError

__all__ = ["TipSpec"]


@dataclass(frozen=True, kw_only=True)
class TipSpec:
    cannula: Cannula
    cutters: tuple
    name: str = ""
    description: str = ""
    tolerance: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "cutters", tuple(self.cutters))
        if not self.cutters:
            raise SpecError("cutters = [] is empty; a tip needs at least one cutter")
