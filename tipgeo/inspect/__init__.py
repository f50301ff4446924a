"""Scan-to-CAD inspection of needle tips.

A scan (point cloud or mesh, any frame) is registered onto the CAD tip — a
spec, measured against its exact surfaces, or a mesh — in stages that survive
the cylinder's symmetry; then every point gets its signed deviation (exact in
double precision, signs decided robustly at the knife edge), statistics per
CAD face, measured geometry (diameters, bevel angles, tip position, cutting
angles) and a report (JSON, coloured PLY, PNG map and histogram, Markdown).
A virtual profilometer makes synthetic scans with known errors.

Robustness: degenerate scans (too few points, all at one place, on a line;
for registration on a plane; non-finite or absurdly large coordinates) and
scans that do not match the CAD (inlier share, fitness, fitted diameters:
:mod:`tipgeo.inspect.checks`) are :class:`ScanError`; large scans are read
in chunks and kept in float32 offsets from a float64 origin (rounding
≤ 2⁻²¹ mm), every deviation computed in float64.

Frames and units: scans in their scanner frame, results in the cannula frame
(+z along the axis towards the tip); mm and rad inside, µm and degrees in
reports. open3d is imported only here (scan reading, ray casting), through
:func:`tipgeo._open3d.import_open3d`.

The batch, the edge scan, the report writer and the virtual profilometer
load on first use of their names (``from tipgeo.inspect import run_batch``
works as ever): a single compare needs none of them.
"""

from typing import TYPE_CHECKING as _TYPE_CHECKING

from .._lazy import lazy_attributes as _lazy_attributes
from ..tolerances import InspectSettings
from .acceptance import AcceptanceRule, Band, judge, load_acceptance
from .cad import CadModel, load_cad
from .checks import check_geometry, check_match
from .compare import (
    Comparison,
    Decided,
    Deviated,
    Loaded,
    Placed,
    Reported,
    Verified,
    compare,
    crop,
    default_rule,
    estimate_normals,
    remove_outliers,
    stage_decide,
    stage_deviate,
    stage_load,
    stage_register,
    stage_report,
    stage_verify,
    voxel_down_sample,
)
from .deviation import STAT_KEYS, statistics
from .exact import Distances, ExactSolid, UnsupportedCutter
from .measure import fit_plane, measure
from .meshdist import MeshSolid, closest_on_triangles
from .register import Registration, fit_cylinder, register
from .scanio import SCAN_FORMATS, Scan, ScanError, load_scan, write_ply

if _TYPE_CHECKING:  # pragma: no cover - the names load on first access (below)
    from .batch import BatchResult, run_batch
    from .edgescan import MeasuredEdges, measure_edges, plot_measured_edges
    from .report import COLORMAP, deviation_colours, write_report
    from .synth import Burr, Misalignment, SynthScan, actual_spec, default_views, synthetic_scan

#: name → the submodule that defines it, imported on first access
_LAZY_NAMES = {
    "BatchResult": "batch", "run_batch": "batch",
    **{name: "edgescan" for name in ("MeasuredEdges", "measure_edges", "plot_measured_edges")},
    **{name: "report" for name in ("COLORMAP", "deviation_colours", "write_report")},
    **{name: "synth" for name in ("Burr", "Misalignment", "SynthScan", "actual_spec",
                                  "default_views", "synthetic_scan")},
}


__getattr__, __dir__ = _lazy_attributes(__name__, globals(), _LAZY_NAMES)


__all__ = ["CadModel", "load_cad", "check_geometry", "check_match", "Comparison", "compare",
           "crop", "estimate_normals",
           "remove_outliers", "voxel_down_sample", "STAT_KEYS", "statistics", "Distances",
           "ExactSolid", "UnsupportedCutter", "fit_plane", "measure", "MeshSolid",
           "closest_on_triangles", "Registration", "fit_cylinder", "register", "COLORMAP",
           "deviation_colours", "write_report", "SCAN_FORMATS", "Scan", "ScanError",
           "load_scan", "write_ply", "InspectSettings", "Burr", "Misalignment",
           "SynthScan", "actual_spec", "default_views", "synthetic_scan",
           "MeasuredEdges", "measure_edges", "plot_measured_edges", "AcceptanceRule", "Band",
           "judge", "load_acceptance", "BatchResult", "run_batch",
           "Loaded", "Placed", "Deviated", "Verified", "Decided", "Reported", "stage_load",
           "stage_register", "stage_deviate", "stage_verify", "stage_decide", "stage_report",
           "default_rule"]
