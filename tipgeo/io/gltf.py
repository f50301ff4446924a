"""Binary glTF 2.0 (``.glb``), through trimesh.

float32 vertices in mm and the cannula frame (+z along the needle axis towards
the tip, heel at z = 0), although glTF nominally uses metres and +y up. The
labels are kept in the mesh ``extras``: ``tipgeo.label_names`` and the
run-length ``tipgeo.label_runs``; the reader
(:func:`~tipgeo.io.load.read_trimesh`) restores them.
"""

from __future__ import annotations

from pathlib import Path

from ..tip import Tip
from .common import tip_scene
from .load import read_trimesh
from .registry import ExportOptions, register_exporter, register_importer

__all__ = ["write_glb"]


def write_glb(tip: Tip, tmp: Path, opts: ExportOptions) -> None:
    """Write ``tip`` as binary glTF 2.0 through trimesh, labels in the mesh
    ``extras``, no normals."""
    from trimesh.exchange.gltf import export_glb

    data = export_glb(tip_scene(tip, opts, with_labels=True), include_normals=False)
    with open(tmp, "wb") as fh:
        fh.write(data)


register_exporter(".glb", write_glb)
register_importer(".glb", read_trimesh)
