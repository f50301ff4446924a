"""Cutters: parametric surfaces that shape a tip (one module per kind)."""

from .base import Cutter
from .conical import ConicalCutter
from .planar import BevelCutter, LancetCutter, MultiPlaneCutter, Plane, multiplane_xi_for_theta

__all__ = ["Cutter", "BevelCutter", "MultiPlaneCutter", "LancetCutter", "Plane",
           "ConicalCutter", "multiplane_xi_for_theta"]
