"""tipgeo — computational geometry and CAM of hollow-needle tips.

Frame and units everywhere: the cannula frame, +z along the needle axis
pointing to the tip, the heel (where the outer cutting edge starts) at z = 0
and γ = 0, γ measured about +z; lengths in mm, angles in radians inside the
library (``*_deg`` only in spec files, CLI and reports).

``import tipgeo`` stays light: trimesh, matplotlib and open3d are imported
only by the functions that need them.
"""

from .build import build_tip
from .cannula import GAUGES, Cannula
from .cutters import (
    BevelCutter,
    ConicalCutter,
    Cutter,
    HelicalCutter,
    LancetCutter,
    MeshCutter,
    MultiPlaneCutter,
    SDFCutter,
    SerrationCutter,
)
from .errors import BuildError, SpecError, TipGeoError
from .presets import preset, preset_names
from .spec import TipSpec, dumps_spec, load_spec, loads_spec, save_spec
from .tip import Tip
from .tolerances import tol

__version__ = "0.1.0"

__all__ = ["build_tip", "Cannula", "GAUGES", "Cutter", "BevelCutter", "MultiPlaneCutter",
           "LancetCutter", "ConicalCutter", "HelicalCutter", "SerrationCutter", "MeshCutter",
           "SDFCutter", "TipSpec", "load_spec", "loads_spec", "dumps_spec", "save_spec", "Tip",
           "preset", "preset_names", "tol", "TipGeoError", "SpecError", "BuildError",
           "__version__"]
