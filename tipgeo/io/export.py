"""Writing a tip to a file: :func:`export_tip` checks the tip, the path and
the options, picks the writer registered for the extension
(:data:`~tipgeo.io.registry.EXPORTERS`) and runs it through the atomic writer
:func:`tipgeo.atomic.write_atomic`.

Frame and units: the cannula frame (+z along the needle axis towards the tip,
heel at z = 0), lengths in mm, whatever the format's own convention.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..atomic import write_atomic
from ..errors import SpecError, TipGeoError
from .common import ExportError, as_path, check_ref_point, check_tip, object_name
from .registry import EXPORTERS, GLTF_UNITS, GLTF_UP, PRECHECKS, STEP_FORMS, ExportOptions

if TYPE_CHECKING:
    from ..tip import Tip

__all__ = ["ExportReport", "check_export", "export_many", "export_tip"]


def export_tip(tip: Tip, path: str | os.PathLike[str], *, binary: bool = True,
               name: str | None = None,
               ref_point: str | Sequence[float] = "centroid", gltf_units: str = "m",
               gltf_up: str = "y", step_form: str = "auto") -> Path:
    """Write a tip to a mesh, CAD or FE file, atomically.

    The format follows the extension of ``path`` (case-insensitive, one of
    :data:`~tipgeo.io.SUPPORTED_EXPORTS`). Coordinates are written in the
    cannula frame (+z along the needle axis towards the tip, heel at z = 0) in
    mm.

    Parameters
    ----------
    tip : Tip
        The tip to write (vertices in mm, cannula frame).
    path : str or os.PathLike
        Target file. Its directory must exist (none is created). A file
        already there is replaced only once the new one is complete.
    binary : bool, default True
        STL and PLY only: write the binary (default) or the ASCII variant.
        The other formats have one encoding and ignore it.
    name : str, optional
        Object, solid or part name written into the file (STL header, PLY and
        OBJ comments, 3MF/GLB object, STEP product, INP ``*Part``). Default:
        the spec name, else ``tip.meta['name']``, else the file stem.
    ref_point : {'centroid', 'top'} or sequence of 3 floats, default 'centroid'
        INP only: the reference node of the rigid body (mm, cannula frame).
        ``'centroid'`` puts it on the needle axis at the height of the volume
        centroid, ``(0, 0, z_c)``; ``'top'`` at the tip top ``(0, 0, z_max)``;
        three numbers give the point itself.
    gltf_units : {'m', 'mm'}, default 'm'
        GLB only: the length unit of the file. glTF means metres, so stock
        viewers show a ``'m'`` file at its true size; ``'mm'`` keeps the
        numbers of the cannula frame. Stated in the ``extras``.
    gltf_up : {'y', 'z'}, default 'y'
        GLB only: the file axis the needle axis points along. ``'y'`` (glTF's
        up) writes a cannula-frame point ``(x, y, z)`` as ``(x, z, -y)``, so
        viewers show the needle standing, tip up; ``'z'`` writes the cannula
        frame as it is. Stated in the ``extras``, undone by :func:`load_tip`.
    step_form : {'auto', 'exact', 'faceted'}, default 'auto'
        STEP only. ``'exact'``: the spec's solid with exact planes, cylinders
        and cones, the helicoid (any height-field cutter surface) as a bicubic
        B-spline within half the build tolerance, made by OCCT booleans of
        exact solids (:mod:`tipgeo.io.brep`); its volume is checked against
        the mesh's (within tolerance × area). ``'faceted'``: one planar face
        per triangle of the mesh. ``'auto'``: exact for a tip built from a
        spec whose every cutter has exact bounds, faceted otherwise (simulated,
        imported and custom-cutter tips).

    Returns
    -------
    pathlib.Path
        ``path`` as a ``Path``.

    Raises
    ------
    SpecError
        ``tip`` is not a non-empty finite ``Tip``; the extension is not
        supported; the parent directory does not exist; ``path`` is a
        directory; ``binary``, ``name`` or ``ref_point`` is invalid; a label
        name contains a line break.
    ExportError
        Writing failed (disk error, missing ``OCP`` for STEP, a mesh that is
        not closed for faceted STEP, ``step_form='exact'`` for a tip without
        an exact form, an OCCT boolean that fails). Subclass of :class:`~tipgeo.errors.BuildError`.
        No partial file is left behind.

    Notes
    -----
    Precision: PLY and OBJ keep every double exactly; 3MF is written as
    shortest round-trip decimals (exact); STL and GLB
    store float32 (about 1e-6 mm at 10 mm); INP uses fixed-point numbers with
    12 decimals (5e-13 mm); STEP stores doubles.

    Labels: PLY keeps them as the face property ``label`` plus one
    ``comment label <id> <name>`` header line per entry of
    ``tip.label_names``; OBJ starts a group (``g outer``, ``g cut:bevel``)
    wherever the label changes along the face list, so the face order is kept
    (``# label <id> <name>`` comments hold the exact names); GLB keeps them in
    the mesh ``extras`` (``tipgeo.label_names`` and run-length
    ``tipgeo.label_runs``); INP has one ``*Elset`` per label present
    (``cut:multiplane.0`` becomes ``CUT_MULTIPLANE_0``) plus ``ALL``. STL, 3MF
    and STEP carry no labels.

    INP: the part follows Abaqus conventions (``*Part``, ``R3D3``, ``*Rigid
    Body``); the reference node is node ``n + 1``, in node set ``RefPt``.
    Element normals follow the outward triangle orientation. CalculiX has no
    ``R3D3`` element and no ``*Part``, so the file is for Abaqus.
    """
    p, opts = _checked(tip, path, binary=binary, name=name, ref_point=ref_point,
                       gltf_units=gltf_units, gltf_up=gltf_up, step_form=step_form)
    ext = p.suffix.lower()
    writer = EXPORTERS[ext]
    try:
        write_atomic(p, lambda tmp: writer(tip, tmp, opts))
    except TipGeoError:
        raise
    except Exception as exc:
        raise ExportError(f"writing {ext} file '{p}' failed: {type(exc).__name__}: {exc}; "
                          f"nothing was written") from exc
    return p


def check_export(tip: Tip, path: str | os.PathLike[str], **options: Any) -> Path:
    """Check, without writing, that :func:`export_tip` could write ``tip`` to
    ``path`` with ``options`` (the same keywords): the tip, the path, the
    options, and the format's pre-flight check (OCP present for STEP, the
    exact form available when asked for). Returns ``path`` as a ``Path``.

    Raises
    ------
    SpecError, ExportError
        As :func:`export_tip` would, before any work.
    """
    p, opts = _checked(tip, path, **options)
    pre = PRECHECKS.get(p.suffix.lower())
    if pre is not None:
        pre(tip, opts)
    return p


def guarded_export(tip: Tip, path: str | os.PathLike[str], *, failed: list[dict[str, Any]],
                   on_error: Callable[[Path, Exception], None] | None = None,
                   dry_run: bool = False, **options: Any) -> bool:
    """Check (``dry_run``, as :func:`check_export`) or write (as
    :func:`export_tip`) the one mesh output of a command that writes several
    files (a mesh in the cannula frame, mm).

    An :class:`ExportError` is raised when ``on_error`` is ``None``; otherwise
    ``{"path", "error"}`` is appended to ``failed``, ``on_error(path, exc)``
    is called and False returned, so the command can go on with its other
    files. Returns True when the check or the write succeeded.
    """
    try:
        (check_export if dry_run else export_tip)(tip, path, **options)
    except ExportError as exc:
        if on_error is None:
            raise
        failed.append({"path": str(path), "error": str(exc)})
        on_error(Path(path), exc)
        return False
    return True


@dataclass
class ExportReport:
    """What :func:`export_many` wrote (``written``, in order) and what it
    could not (``failed``: ``(path, message)`` pairs)."""

    written: list[Path] = field(default_factory=list)
    failed: list[tuple[Path, str]] = field(default_factory=list)


def export_many(tip: Tip, paths: Sequence[str | os.PathLike[str]], *,
                on_error: Callable[[Path, Exception], None] | None = None,
                **options: Any) -> ExportReport:
    """Write ``tip`` to several files (each as :func:`export_tip` would, with
    ``options``), telling what cannot be written before writing the others.

    Every path is first checked (:func:`check_export`: options, path, a
    missing OCP for STEP …); bad input (:class:`~tipgeo.errors.SpecError`)
    is raised then, before anything is written. An export that cannot be
    made (:class:`ExportError`) is raised too when ``on_error`` is ``None``;
    otherwise ``on_error(path, exc)`` is called for every path that fails
    its check — all before the first write — and then for every write that
    fails, and the other files are written.

    Returns
    -------
    ExportReport
        The files written and the ones that failed, with the reason.
    """
    report = ExportReport()
    ok: list[Path] = []
    for path in paths:
        try:
            ok.append(check_export(tip, path, **options))
        except ExportError as exc:  # bad input (SpecError) is raised as it is
            if on_error is None:
                raise
            report.failed.append((Path(os.fspath(path)), str(exc)))
            on_error(Path(os.fspath(path)), exc)
    for p in ok:
        try:
            report.written.append(export_tip(tip, p, **options))
        except ExportError as exc:
            if on_error is None:
                raise
            report.failed.append((p, str(exc)))
            on_error(p, exc)
    return report


def _checked(tip: Tip, path: str | os.PathLike[str], *, binary: bool = True,
             name: str | None = None,
             ref_point: str | Sequence[float] = "centroid", gltf_units: str = "m",
             gltf_up: str = "y", step_form: str = "auto") -> tuple[Path, ExportOptions]:
    check_tip(tip)
    p = as_path(path)
    ext = p.suffix.lower()
    if ext not in EXPORTERS:
        raise SpecError(f"path '{p}' has extension '{p.suffix}'; allowed: "
                        f"{', '.join(EXPORTERS)}")
    parent = p.parent
    if not parent.is_dir():
        raise SpecError(f"path '{p}': parent directory '{parent}' does not exist or is not a "
                        f"directory; create it first (export_tip creates no directories)")
    if p.is_dir():
        raise SpecError(f"path '{p}' is a directory; expected a file path ending in "
                        f"{', '.join(EXPORTERS)}")
    if not isinstance(binary, bool):
        raise SpecError(f"binary = {binary!r} is not a bool; expected True or False")
    for key, val, allowed in (("gltf_units", gltf_units, GLTF_UNITS),
                              ("gltf_up", gltf_up, GLTF_UP),
                              ("step_form", step_form, STEP_FORMS)):
        if not isinstance(val, str) or val not in allowed:
            raise SpecError(f"{key} = {val!r} is not supported; allowed: "
                            f"{', '.join(repr(a) for a in allowed)}")
    opts = ExportOptions(binary=binary, name=object_name(tip, p, name),
                         ref_point=check_ref_point(ref_point), gltf_units=gltf_units,
                         gltf_up=gltf_up, step_form=step_form)
    return p, opts
