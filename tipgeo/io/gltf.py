"""Binary glTF 2.0 (``.glb``), through trimesh.

glTF's conventions are metres and +y up, and stock viewers follow them; by
default the file follows them too:

* ``gltf_units='m'``, ``gltf_up='y'`` (the default): a cannula-frame point
  ``(x, y, z)`` in mm is written as ``(x, z, -y) / 1000``: metres, the needle
  axis along +y (up), the tip at the top;
* ``gltf_units='mm'``: the same without the division (mm);
* ``gltf_up='z'``: no rotation, the cannula frame as it is.

The rotation is +90° about x seen from the file, i.e. the file's ``(X, Y, Z)``
is ``(x, z, -y)``: right-handed, a proper rotation. Vertices are float32. The
mesh ``extras`` (and the scene's) hold ``tipgeo.units`` (``'m'`` or
``'mm'``), ``tipgeo.up_axis`` (``'+y'`` or ``'+z'``: where the needle axis
points), ``tipgeo.frame`` (text), ``tipgeo.to_cannula_mm`` (the 4×4
row-major matrix taking file coordinates to the cannula frame in mm), and the
labels: ``tipgeo.label_names`` and the run-length ``tipgeo.label_runs``. The
reader (:func:`~tipgeo.io.load.read_trimesh`) applies ``to_cannula_mm`` without
its scale and restores the labels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..arrays import FloatArray
from ..errors import SpecError
from ..tip import Tip
from .common import tip_scene
from .load import read_trimesh
from .registry import GLTF_UNITS, GLTF_UP, ExportOptions, register_exporter, register_importer

__all__ = ["GLTF_UNITS", "GLTF_UP", "gltf_transform", "write_glb"]



def gltf_transform(units: str, up: str) -> FloatArray:
    """The 4×4 matrix taking cannula-frame points in mm to GLB file
    coordinates (``units``, needle axis along +``up``); see the module table."""
    if units not in GLTF_UNITS:
        raise SpecError(f"gltf_units = {units!r} is not supported; allowed: "
                        f"{', '.join(repr(u) for u in GLTF_UNITS)}")
    if up not in GLTF_UP:
        raise SpecError(f"gltf_up = {up!r} is not supported; allowed: "
                        f"{', '.join(repr(u) for u in GLTF_UP)}")
    rot = np.eye(3) if up == "z" else np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    m = np.eye(4)
    m[:3, :3] = rot / GLTF_UNITS[units]
    return m


def write_glb(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as binary glTF 2.0 through trimesh in ``opts.gltf_units``
    with the needle axis along ``opts.gltf_up``; units, up axis, frame and
    labels in the ``extras``; no normals."""
    from trimesh.exchange.gltf import export_glb

    to_file = gltf_transform(opts.gltf_units, opts.gltf_up)
    axes = ("X = x, Y = y, Z = z" if opts.gltf_up == "z"
            else "X = x, Y = z (the needle axis, towards the tip), Z = -y")
    info = {"units": opts.gltf_units, "up_axis": "+" + opts.gltf_up,
            "axes": f"file {axes} of the cannula frame",
            "to_cannula_mm": (np.linalg.inv(to_file) + 0.0).ravel().tolist()}  # no -0.0
    scene = tip_scene(tip, opts, with_labels=True, transform=to_file, info=info)
    data = export_glb(scene, include_normals=False)  # type: ignore[no-untyped-call]  # trimesh's export_glb has no annotations
    with open(tmp, "wb") as fh:
        fh.write(data)


register_exporter(".glb", write_glb)
register_importer(".glb", read_trimesh)
