"""Writing tips to files and reading meshes back.

Formats (chosen by the file extension, case-insensitive), one module each:

=========  ================================================================
``.stl``   binary STL (float32), or ASCII with ``binary=False``
           (:mod:`tipgeo.io.stl`)
``.ply``   binary little-endian PLY (double vertices, per-face ``label``
           property, label names as ``comment label <id> <name>``), or
           ASCII with ``binary=False`` (:mod:`tipgeo.io.ply`)
``.obj``   Wavefront OBJ, one group per label, full double precision
           (:mod:`tipgeo.io.obj`)
``.3mf``   3MF core package (unit ``millimeter``; no extension namespaces,
           read by lib3mf in strict mode) (:mod:`tipgeo.io.threemf`)
``.glb``   binary glTF 2.0 (through trimesh; float32; metres and the needle
           along +y by default, ``gltf_units``/``gltf_up``; units, axes and
           labels in ``extras``) (:mod:`tipgeo.io.gltf`)
``.step``  STEP AP214 solid (B-rep): exact planes, cylinders, cones and a
``.stp``   fitted B-spline helicoid for a spec's tip, or one planar face per
           triangle (``step_form``; needs ``OCP``: ``pip install
           "tipgeo[step]"``) (:mod:`tipgeo.io.step`, :mod:`tipgeo.io.brep`)
``.inp``   Abaqus input: a rigid part of ``R3D3`` elements with one element
           set per label and a reference node (:mod:`tipgeo.io.inp`)
=========  ================================================================

:func:`export_tip` writes all of them (:mod:`tipgeo.io.export`), :func:`export_many`
several at once (reporting what cannot be written before writing the others),
:func:`check_export` checks without writing;
:func:`load_tip` reads ``.stl``, ``.ply``, ``.obj``, ``.3mf`` and ``.glb``
(:mod:`tipgeo.io.load`). Each format module registers its writer and reader
in :mod:`tipgeo.io.registry` when imported; :data:`SUPPORTED_EXPORTS` and
:data:`SUPPORTED_IMPORTS` are the registered extensions, in the order the
modules are imported below. The checks the writers share are in
:mod:`tipgeo.io.common`.

Frame and units: every file is written in the cannula frame (+z along the
needle axis towards the tip, heel at z = 0, γ about +z from +x) with lengths in
mm, whatever the format's own convention, except GLB: glTF means metres and
+y up, so a GLB is written in metres with the needle axis along +y unless
``gltf_units='mm'``/``gltf_up='z'`` ask otherwise (the ``extras`` say which,
and :func:`load_tip` turns it back).

Every export is atomic: the data go to a temporary file in the target
directory, which is flushed to disk and then renamed over ``path``. A failure
leaves neither a partial file nor a temporary file behind, and leaves a file
already at ``path`` untouched.

``import tipgeo.io`` stays light: trimesh, lxml, networkx and OCP are imported
only by the writers and readers that need them.
"""

from __future__ import annotations

import os  # noqa: F401  (``tipgeo.io.os``, as before the split: tests patch os.replace here)

# isort: off
# Importing a format module registers it: this order is the order of
# SUPPORTED_EXPORTS and SUPPORTED_IMPORTS.
from . import stl, ply, obj, threemf, gltf, step, inp  # noqa: F401
# isort: on
from .common import ExportError
from .export import ExportReport, check_export, export_many, export_tip, guarded_export
from .load import UNITS, UNLABELLED, load_tip
from .registry import EXPORTERS, IMPORTERS

__all__ = [
    "SUPPORTED_EXPORTS",
    "SUPPORTED_IMPORTS",
    "UNITS",
    "UNLABELLED",
    "ExportError",
    "ExportReport",
    "check_export",
    "guarded_export",
    "export_many",
    "export_tip",
    "load_tip",
]

#: File extensions :func:`export_tip` writes.
SUPPORTED_EXPORTS: tuple[str, ...] = tuple(EXPORTERS)
#: File extensions :func:`load_tip` reads.
SUPPORTED_IMPORTS: tuple[str, ...] = tuple(IMPORTERS)

# The names of the single-module tipgeo.io, kept for the tests that reach
# into it: the writers' registry itself, and the STEP solid builder.
_WRITERS = EXPORTERS
_step_solid = step.step_solid
