"""Cutters: parametric surfaces that shape a tip (one module per kind).

Every cutter follows the protocol of :mod:`tipgeo.cutters.base`.
"""

from .base import Cutter
from .conical import ConicalCutter
from .custom import MeshCutter, SDFCutter
from .helical import HelicalCutter, thesis_helical
from .planar import (
    BevelCutter,
    LancetCutter,
    MultiPlaneCutter,
    PlanarCutter,
    Plane,
    PlaneSetCutter,
    multiplane_xi_for_theta,
)
from .serration import SERRATION_PRESETS, SerrationCutter, SerrationProfile

__all__ = ["Cutter", "PlanarCutter", "PlaneSetCutter", "BevelCutter", "MultiPlaneCutter",
           "LancetCutter", "Plane",
           "ConicalCutter", "HelicalCutter", "SerrationCutter", "SerrationProfile",
           "MeshCutter", "SDFCutter", "SERRATION_PRESETS", "multiplane_xi_for_theta",
           "thesis_helical"]
