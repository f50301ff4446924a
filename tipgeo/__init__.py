"""tipgeo — computational geometry and CAM of hollow-needle tips.

Frame and units everywhere: the cannula frame, +z along the needle axis
pointing to the tip, the heel (where the outer cutting edge starts) at z = 0
and γ = 0, γ measured about +z; lengths in mm, angles in radians inside the
library (``*_deg`` only in spec files, CLI and reports).

The pipeline and its entry points, stage by stage:

- **Design** — :class:`TipSpec` (a :class:`Cannula` and cutters from
  :mod:`tipgeo.cutters`; TOML through :func:`load_spec`/:func:`dumps_spec`;
  :func:`resolve_spec` takes a file or a preset name), :func:`build_tip` → a
  labelled :class:`Tip`; :mod:`tipgeo.io` writes and reads meshes
  (:func:`tipgeo.io.export_tip`, :func:`tipgeo.io.load_tip`).
- **Analyse** — :mod:`tipgeo.angles` (:func:`tipgeo.angles.analyze`: edges,
  Fourier fits, λ θ α, l_c), :mod:`tipgeo.closedforms`, :mod:`tipgeo.mechanics`
  (slice/push, fracture and insertion forces, tissue fits),
  :mod:`tipgeo.optimize` (sweeps, the GP optimiser of §3.4).
- **Make** — the top-level packages :mod:`cam` (five-axis grinding:
  :func:`cam.grind`) and :mod:`gcode` (A3200 laser programs:
  :func:`gcode.laser_check`, :func:`gcode.emit_program`).
- **Inspect** — :mod:`tipgeo.inspect` (:func:`tipgeo.inspect.compare`: scans
  registered to the CAD tip, deviations, measured geometry).

``import tipgeo`` stays light: the subpackages above load on first access
(``tipgeo.angles`` works without importing it), so do the design names
(:func:`build_tip`, the cutters, :func:`preset`, :class:`TipSpec`: manifold3d
with them), and trimesh, matplotlib, open3d and scipy only with the
functions that need them.
"""

# ruff: noqa: E402  (the one call below runs before numpy is imported)
# before numpy is first imported: one BLAS thread when tipgeo runs as a
# program (tipgeo._threads; nothing changes for a library user)
from ._threads import program_blas_threads as _program_blas_threads

_program_blas_threads()

from typing import TYPE_CHECKING as _TYPE_CHECKING
from typing import Any as _Any

from ._lazy import lazy_attributes as _lazy_attributes
from ._slots import set_mesh_reader as _set_mesh_reader
from .arrays import FloatArray as _FloatArray
from .arrays import IntArray as _IntArray
from .errors import BuildError, ExportError, InputError, ScanError, SpecError, TipGeoError
from .tip import Tip
from .tip import set_tip_writer as _set_tip_writer
from .tolerances import tol

if _TYPE_CHECKING:  # pragma: no cover - the names load on first access (below)
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
    from .presets import preset, preset_names, resolve_spec
    from .spec import TipSpec, dumps_spec, load_spec, loads_spec, save_spec

#: Public names that load their module on first access: the design layer
#: (manifold3d, the cutters, the presets) is not imported by a command that
#: never builds a tip (``tipgeo compare SCAN CAD.stl``: 0.05 CPU s).
_LAZY_NAMES = {
    "build_tip": "build", "GAUGES": "cannula", "Cannula": "cannula",
    **{name: "cutters" for name in ("BevelCutter", "ConicalCutter", "Cutter", "HelicalCutter",
                                    "LancetCutter", "MeshCutter", "MultiPlaneCutter",
                                    "SDFCutter", "SerrationCutter")},
    "preset": "presets", "preset_names": "presets", "resolve_spec": "presets",
    **{name: "spec" for name in ("TipSpec", "dumps_spec", "load_spec", "loads_spec",
                                 "save_spec")},
}

__version__ = "0.1.0"


# The I/O layer plugged into the slots of the layers below it: cutters and the
# Tip never import tipgeo.io (it imports them), so the import graph has no
# circle (tests/test_import_graph.py). Python runs this file before any
# tipgeo module, so the slots are filled before anything can use them; the
# I/O package itself still loads on first use.
def _read_mesh(path: str, units: str | None) -> tuple[_FloatArray, _IntArray]:
    """A mesh file's vertices (mm, cannula frame) and faces, for
    :meth:`MeshCutter.from_file`."""
    from .io import load_tip

    tip = load_tip(path, units=units)
    return tip.vertices, tip.faces


def _write_tip(tip: Tip, path: str, **options: _Any) -> None:
    """:meth:`Tip.export`: :func:`tipgeo.io.export_tip`."""
    from .io import export_tip

    export_tip(tip, path, **options)


_set_mesh_reader(_read_mesh)
_set_tip_writer(_write_tip)

__all__ = ["build_tip", "Cannula", "GAUGES", "Cutter", "BevelCutter", "MultiPlaneCutter",
           "LancetCutter", "ConicalCutter", "HelicalCutter", "SerrationCutter", "MeshCutter",
           "SDFCutter", "TipSpec", "load_spec", "loads_spec", "dumps_spec", "save_spec", "Tip",
           "preset", "preset_names", "resolve_spec", "tol", "TipGeoError", "SpecError",
           "InputError", "ScanError", "BuildError", "ExportError", "__version__"]

#: Subpackages and modules that load on first access (``tipgeo.angles``).
_LAZY = ("angles", "closedforms", "edges", "fourier", "io", "inspect", "mechanics", "optimize",
         "plot", "demo", "cli")


__getattr__, __dir__ = _lazy_attributes(__name__, globals(), _LAZY_NAMES, _LAZY)
