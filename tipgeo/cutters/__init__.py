"""Cutters: parametric surfaces that shape a tip (one module per kind).

Every cutter follows the protocol of :mod:`tipgeo.cutters.base`.
"""

# isort: off
# The kinds register as their modules load; this order is the order users see
# them listed in (bevel, multiplane, lancet, conical, helical, serration, mesh).
from . import planar, conical, helical, serration, custom  # noqa: F401
# isort: on
from .base import CUTTER_KINDS, Cutter, check_name, cutter_kind, register_cutter
from .conical import ConicalCutter
from .custom import MeshCutter, SDFCutter
from .helical import HelicalCutter, old_thesis_helical, thesis_helical
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
from .surfaces import ConeSurface, HeightSurface, ImplicitSurface, NotchPrism, Surface
from .toml import CutterTable

__all__ = ["Cutter", "CUTTER_KINDS", "register_cutter", "cutter_kind", "check_name",
           "CutterTable", "ConeSurface", "HeightSurface", "ImplicitSurface", "NotchPrism",
           "Surface",
           "PlanarCutter", "PlaneSetCutter", "BevelCutter", "MultiPlaneCutter", "LancetCutter",
           "Plane", "ConicalCutter", "HelicalCutter", "SerrationCutter", "SerrationProfile",
           "MeshCutter", "SDFCutter", "SERRATION_PRESETS", "multiplane_xi_for_theta",
           "thesis_helical",
           "old_thesis_helical"]
