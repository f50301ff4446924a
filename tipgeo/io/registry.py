"""The registry of file formats: one writer and/or one reader per extension.

Each format module (:mod:`tipgeo.io.stl`, :mod:`tipgeo.io.ply`, …) registers
its functions when it is imported, like trimesh's ``exchange`` modules;
:mod:`tipgeo.io` imports them in a fixed order and derives
:data:`~tipgeo.io.SUPPORTED_EXPORTS` and :data:`~tipgeo.io.SUPPORTED_IMPORTS`
from :data:`EXPORTERS` and :data:`IMPORTERS` (registration order).

A writer is called as ``writer(tip, tmp, opts)`` by
:func:`~tipgeo.io.export_tip` once the tip, the path and the options are
checked: it writes ``tip`` (mm, cannula frame: +z along the needle axis towards
the tip, heel at z = 0) to the temporary file ``tmp``; the atomic rename over
the target is :func:`~tipgeo.io.export_tip`'s job. A reader is called as
``reader(path)`` by :func:`~tipgeo.io.load_tip` for an existing, non-empty file
and returns a :class:`LoadedMesh` in the file's own length unit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..arrays import AnyArray

if TYPE_CHECKING:
    from ..tip import Tip


__all__ = [
    "EXPORTERS",
    "GLTF_UNITS",
    "GLTF_UP",
    "STEP_FORMS",
    "IMPORTERS",
    "PRECHECKS",
    "ExportOptions",
    "LoadedMesh",
    "Reader",
    "Writer",
    "register_exporter",
    "register_importer",
]


#: GLB ``gltf_units`` choices and their size in mm.
GLTF_UNITS: dict[str, float] = {"m": 1.0e3, "mm": 1.0}
#: GLB ``gltf_up`` choices: the file axis the needle axis (+z of the cannula
#: frame) maps to.
GLTF_UP: tuple[str, ...] = ("y", "z")
#: STEP ``step_form`` choices (:mod:`tipgeo.io.step`).
STEP_FORMS: tuple[str, ...] = ("auto", "exact", "faceted")


@dataclass(frozen=True)
class ExportOptions:
    """The checked options of :func:`~tipgeo.io.export_tip`, passed to every
    writer: ``binary`` (STL, PLY), the object ``name``, the INP ``ref_point``
    (``'centroid'``, ``'top'`` or a point in mm), the GLB ``gltf_units``
    (``'m'`` or ``'mm'``) and ``gltf_up`` (``'y'``: the needle axis along +y,
    or ``'z'``: the cannula frame as it is), the STEP ``step_form``
    (``'auto'``, ``'exact'`` or ``'faceted'``)."""

    binary: bool
    name: str
    ref_point: str | tuple[float, float, float]
    gltf_units: str = "m"
    gltf_up: str = "y"
    step_form: str = "auto"


@dataclass
class LoadedMesh:
    """A triangle mesh as a reader returns it: vertices in the file's unit and
    the cannula frame, faces indexing them, the labels if the file carries any
    (``label_ids`` ``None`` otherwise) and the unit the file declares."""

    vertices: AnyArray
    faces: AnyArray
    label_ids: AnyArray | None = None
    label_names: tuple[str, ...] = ()
    name: str | None = None
    #: the length unit the file declares itself (a key of
    #: :data:`~tipgeo.io.UNITS`), ``None`` when it declares none
    units: str | None = None


#: ``writer(tip, tmp, opts)``: write ``tip`` to the temporary file ``tmp``.
Writer = Callable[["Tip", Path, "ExportOptions"], None]
#: ``reader(path)``: read the mesh in ``path``.
Reader = Callable[[Path], LoadedMesh]

#: Writers by lower-case extension (with the dot), in registration order.
EXPORTERS: dict[str, Writer] = {}
#: Pre-flight checks by extension: ``check(tip, opts)`` raises what the
#: writer would (a missing package, a form the tip lacks) without writing.
PRECHECKS: dict[str, Callable[[Tip, ExportOptions], None]] = {}
#: Readers by lower-case extension (with the dot), in registration order.
IMPORTERS: dict[str, Reader] = {}


def _check_ext(ext: object) -> str:
    if not (isinstance(ext, str) and len(ext) > 1 and ext.startswith(".")
            and ext == ext.lower() and ext.count(".") == 1):
        raise ValueError(f"extension {ext!r} is invalid; expected a lower-case extension "
                         f"with one leading dot, e.g. '.stl'")
    return ext


def register_exporter(ext: str, writer: Writer,
                      precheck: Callable[[Tip, ExportOptions], None] | None = None
                      ) -> Writer:
    """Register ``writer`` for files ending in ``ext`` (e.g. ``'.stl'``), and
    its cheap pre-flight ``precheck`` if it has one; a writer already
    registered for ``ext`` is replaced. Returns ``writer``."""
    EXPORTERS[_check_ext(ext)] = writer
    if precheck is None:
        PRECHECKS.pop(ext, None)
    else:
        PRECHECKS[ext] = precheck
    return writer


def register_importer(ext: str, reader: Reader) -> Reader:
    """Register ``reader`` for files ending in ``ext`` (e.g. ``'.stl'``); a
    reader already registered for ``ext`` is replaced. Returns ``reader``."""
    IMPORTERS[_check_ext(ext)] = reader
    return reader
